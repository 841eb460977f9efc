/*
 * hd_foc.h - field-oriented current loop of the PMSM: Clarke / Park
 * transforms, two PI current controllers with anti-windup and a voltage
 * vector limit, inverse Park and space-vector modulation (min/max zero-sequence
 * injection).  Struct + step(), no globals, integer only.
 *
 * Formats (docs/stm32g474.md, section "FOC"):
 *   phase / dq current      Q15.16 A        (int32, hd_current_t)
 *   voltage                 Q15.16 V        (int32)
 *   electrical angle        uint32, 2^32 == one electrical turn (wraps, meant)
 *   sin / cos               Q31 in the step (hd_foc_sincos: 512-entry table, linear
 *                           interpolation, 1.9e-5, for a 12-bit loop); Q30 arguments of
 *                           the public transforms below
 *   kp                      Q15.16 V/A
 *   ki_ts = Ki * Ts         Q15.16 V/(A period)
 *   integrator              int32, 2^-24 V  (8 more fractional bits than the output;
 *                           holds +-128 V)
 *   duty                    Q16, 0 .. 65536 == 0 .. 100 % high-side on time
 *
 * One step (called once per PWM period, Ts = 1 / f_pwm):
 *   1. Clarke:  i_alpha = ia,  i_beta = (ia + 2 ib) / sqrt(3)   (ia + ib + ic = 0)
 *   2. Park:    id =  i_alpha cos + i_beta sin,  iq = -i_alpha sin + i_beta cos
 *   3. PI on d and q:  v = kp e + I,  I += ki_ts e;  the voltage vector is
 *      limited to the linear SVM range |v| <= vmax = vbus * vmax_k, vmax_k = m_max / sqrt(3),
 *      d axis first (vd clamped to +-vmax, vq to +-sqrt(vmax^2 - vd^2), the
 *      square root only evaluated when the vector leaves the circle);
 *      anti-windup: each integrator is clamped to its axis limit, so it never
 *      holds more than the usable voltage yet keeps tracking what a saturated
 *      axis needs (e.g. the back-EMF): recovery from saturation takes a few
 *      periods (test_foc.c: < 1 ms at 3000 rpm).
 *   4. inverse Park, inverse Clarke to va, vb, vc, zero-sequence injection
 *      v0 = -(max + min) / 2 (equivalent to SVM), duty = 1/2 + (vx + v0) / vbus,
 *      computed on modulation ratios (vd / vbus, vq / vbus, one 1/vbus per step)
 *      rotated by the inverse Park.
 * hd_foc_step computes in 32-bit words with the Cortex-M4 DSP forms (SMMULR,
 * SMMLAR, SMLAL, SSAT: the hdf_ helpers of hd_fixed.h); the range analysis with
 * every Q-format is the comment at the top of hd_foc.c.  Phase currents
 * saturate at +-2,048 A, the bus voltage at 8,192 V, and below 1 V the
 * modulation is that of 1 V.  The public transforms and hd_foc_svm are the
 * 64-bit references (tests/c/test_foc_fast.c compares the step with them).
 * Every narrowing rounds to nearest (half up in the transforms and the SVM)
 * and saturates.
 *
 * The controller computes in period k the duties applied in period k + 1
 * (the PWM preload), so the loop sees one period of transport delay plus the
 * zero-order hold.  With the crossover parameter of hd_foc_design at fs / 22
 * (900 Hz at fs = 20 kHz) the closed-loop -3 dB bandwidth is ~2 kHz with no
 * resonance peak (the discrete loop's bandwidth is ~2.2x the nominal
 * crossover; 1333 Hz would give 3.5 kHz and +1.3 dB peaking).
 * tests/c/test_foc.c measures it against a simulated PMSM.
 */
#ifndef HD_FOC_H
#define HD_FOC_H

#include <stdint.h>
#include "hd_units.h"
#include "hd_fixed.h"

#define HD_FOC_DUTY_ONE 65536   /* Q16 duty 100 % */

typedef struct {
    int32_t kp;         /* Q15.16 V/A */
    int32_t ki_ts;      /* Q15.16 V/(A period) */
    int32_t vmax_k;     /* Q30 usable phase amplitude per volt of bus, m_max / sqrt(3) with the
                         * modulation limit m_max in (0, 1] (e.g. 0.95); clamped to 1 / sqrt(3) */
} hd_foc_cfg_t;

typedef struct {
    int32_t integ_d;    /* 2^-24 V, |.| <= min(vmax, 128 V) */
    int32_t integ_q;    /* 2^-24 V */
    /* last step, telemetry (Q15.16) */
    int32_t id, iq;     /* measured dq current, A */
    int32_t vd, vq;     /* limited dq voltage, V */
    uint32_t limited;   /* 1 if the voltage vector was limited in the last step */
} hd_foc_t;

typedef struct {
    int32_t ia, ib;     /* measured phase currents, Q15.16 A (ic = -ia - ib) */
    uint32_t theta_e;   /* electrical angle, 2^32 == one turn */
    int32_t id_ref;     /* Q15.16 A */
    int32_t iq_ref;     /* Q15.16 A */
    int32_t vbus;       /* DC link, Q15.16 V (> 0; <= 0 gives 50 % duties, zero voltage) */
} hd_foc_in_t;

typedef struct {
    int32_t duty[3];    /* Q16 duty of phases a, b, c, [0, 65536] */
} hd_foc_out_t;

/** sin and cos of an electrical angle (2^32 == one turn) in Q31, |.| <= 2^31 - 1, by linear
 *  interpolation of a 512-entry table (the current loop's form: error <= 1.9e-5 + 1.5 LSB). */
void hd_foc_sincos(uint32_t theta_e, int32_t *sin_q31, int32_t *cos_q31);
/** Clarke transform (balanced three-phase): alpha, beta in Q15.16 A. */
void hd_foc_clarke(int32_t ia, int32_t ib, int32_t *i_alpha, int32_t *i_beta);
/** Park: (alpha, beta) -> (d, q) with sin, cos in Q30. */
void hd_foc_park(int32_t a, int32_t b, int32_t sin_q30, int32_t cos_q30, int32_t *d, int32_t *q);
/** Inverse Park: (d, q) -> (alpha, beta). */
void hd_foc_ipark(int32_t d, int32_t q, int32_t sin_q30, int32_t cos_q30, int32_t *a, int32_t *b);
/** 1 / vbus for the modulation: round(2^46 / vbus) (Q30 per Q15.16 V), the same value as
 *  hd_div_q(HD_Q16_ONE, vbus, 30) for every vbus; for 1 V <= vbus < 128 V (the bus range)
 *  by three 32-bit divisions instead of a 64-bit one. */
int32_t hd_foc_inv_vbus(int32_t vbus);
/** Space-vector modulation: (v_alpha, v_beta) Q15.16 V and vbus -> three Q16 duties. */
void hd_foc_svm(int32_t v_alpha, int32_t v_beta, int32_t vbus, int32_t duty[3]);

/** Reset the integrators and telemetry. */
void hd_foc_reset(hd_foc_t *s);
/** One PWM period (see the header comment). */
void hd_foc_step(hd_foc_t *s, const hd_foc_cfg_t *c, const hd_foc_in_t *in, hd_foc_out_t *out);

/** PI gains by pole-zero cancellation: kp = 2 pi fc L, ki = 2 pi fc R, ki_ts = ki / fs.
 *  r_mohm: phase resistance mOhm; l_nh: phase inductance nH; fc_hz crossover;
 *  fs_hz: loop rate.  Returns 0, or -1 for non-positive arguments (cfg untouched). */
int32_t hd_foc_design(hd_foc_cfg_t *c, int32_t r_mohm, int32_t l_nh, int32_t fc_hz, int32_t fs_hz);

/** ADC sample to phase current, Q15.16 A: (raw - offset) * gain, gain_q30 in A per LSB
 *  as Q30 (e.g. 33 A / 2048 LSB = 17301504), rounded half up.  32-bit: raw - offset is
 *  saturated to [-2^16, 2^16) LSB (SSAT 17: any ADC of up to 16 bits) and the gain to
 *  [-2^27, 2^27) (0.125 A per LSB); then (d 2^14) (gain 2^4) / 2^32 = d gain / 2^14 is one
 *  SMMULR, both factors within int32, |result| <= 2^29.  Inline (the port calls it twice
 *  per FOC period). */
HD_FX_INLINE int32_t hd_foc_adc_current(int32_t raw, int32_t offset, int32_t gain_q30)
{
    return hdf_smmulr(hdf_ssat(hdf_sub_sat(raw, offset), 17u) * 16384, hdf_ssat(gain_q30, 28u) * 16);
}

/** Electrical angle from a single-turn encoder count in [0, 2^bits) (1 <= bits <= 32):
 *  mech = count * 2^(32 - bits), theta_e = mech * pole_pairs + offset (mod 2^32, meant).
 *  Inline (once per FOC period). */
HD_FX_INLINE uint32_t hd_foc_elec_angle(uint32_t count, uint32_t bits, uint32_t pole_pairs, uint32_t offset)
{
    const uint32_t b = (bits < 1u) ? 1u : ((bits > 32u) ? 32u : bits);
    const uint32_t mech = (b == 32u) ? count : (count << (32u - b));
    return mech * pole_pairs + offset;     /* modulo 2^32: the angle wraps, meant */
}

#endif
