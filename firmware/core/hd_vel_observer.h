/*
 * hd_vel_observer.h - low-speed velocity estimator: a type-2 tracking loop
 * (PLL / tracking observer) on a multi-turn encoder angle.
 *
 *   e      = theta_meas - theta_hat                      (2^-36 turn, int32, incl. frac;
 *                                                         |e| limited to 2^-5 turn)
 *   vel   += ki_dt * e                                   (Ki = w^2,       T = 1/HD_LOOP_HZ)
 *   theta_hat += T * vel + kp_dt * e                     (Kp = 2 zeta w)
 *
 * Formats:
 *   theta_meas, theta_hat  int64 Q32.32 turns; theta_hat carries 16 more
 *                          fractional bits in `frac` (unit 2^-48 turn, [0, 2^16))
 *                          so that 0.0001 deg/s (0.12 LSB of Q32.32 per period)
 *                          still advances the estimate exactly.
 *   vel                    int64, 2^-48 turn/s (16 bits finer than the output
 *                          velocity format; holds +-32768 turn/s, so the same
 *                          observer serves the motor shaft).
 *   kp_dt, ki_dt           int32 Q16 (dimensionless Kp*T; Ki*T in 1/s).
 *   e                      int32, 2^-36 turn: the error rounded from 2^-48 turn
 *                          (d 2^16 - frac) and limited to +-2^-5 turn (11.25 deg),
 *                          so each gain product is one 32 x 32-bit multiply; a
 *                          larger error (start-up, a jump) moves the estimate at
 *                          the limit's rate until it is back in range.
 *   err                    the unlimited error rounded to 2^-32 turn (saturated).
 * Outputs: hd_velobs_vel_out() rounds vel to 2^-32 turn/s (saturated int32),
 * hd_velobs_vel48() gives the full int64.
 *
 * Bandwidth and noise: see docs/control.md (24-bit encoder at 10 kHz: the raw
 * difference quantum is 0.21 deg/s; a 20 Hz observer brings the quantisation
 * noise of the estimate to ~1e-3 deg/s RMS with a still axis).
 */
#ifndef HD_VEL_OBSERVER_H
#define HD_VEL_OBSERVER_H

#include <stdint.h>
#include "hd_units.h"
#include "hd_fixed.h"

typedef struct {
    int32_t kp_dt;   /* Q16, 2*zeta*w*T */
    int32_t ki_dt;   /* Q16, w^2*T [1/s] */
} hd_velobs_cfg_t;

typedef struct {
    hd_angle_t theta;  /* Q32.32 turns */
    int32_t    frac;   /* 2^-48 turn, [0, 65536) */
    int64_t    vel;    /* 2^-48 turn/s */
    int32_t    err;    /* last error, 2^-32 turn */
} hd_velobs_t;

/* T = 1e-4 s in Q44: 2^44 / 10000 = 1759218604.4416 -> 1759218604 (rel. error 2.5e-10;
 * the loop closes on the measurement, so this only scales the gains by that much). */
#define HD_VELOBS_T_Q44 1759218604
#define HD_VELOBS_T_SHIFT 44u

/* the error's 32-bit form: 2^-36 turn, so int32 holds +-2^-5 turn (11.25 deg) */
#define HD_VELOBS_E_SHIFT 12u                         /* 2^-48 -> 2^-36 turn */
#define HD_VELOBS_E_UNIT (1 << (16u - HD_VELOBS_E_SHIFT))    /* 2^-32 turn in 2^-36 turn */
#define HD_VELOBS_E_HALF (1u << (HD_VELOBS_E_SHIFT - 1u))    /* the rounding offset */
#define HD_VELOBS_D_MAX ((INT64_C(1) << 27) - 1)      /* |d| clamp, 2^-32 turn */

/* The step (hd_velobs_step_inline, hd_velobs_step_vel_inline); keep_err (a constant) 0:
 * the caller never reads err, so it is not formed (theta, frac and vel are the same words). */
HD_FX_INLINE void hd__velobs_step(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas,
                                  const uint32_t keep_err)
{
    /* error against the estimate theta, 2^-32 turn */
    /* the saturating difference (ADDS/ADCS and the overflow flag on the M4): the plain
     * difference wherever that fits, so no range test of the angles is needed */
    const int64_t d = hdf_sub64_sat(theta_meas, s->theta);
    /* err = round(d - frac 2^-16) in 2^-32 turn: d, less one when frac > 1/2 (or is
     * 1/2 and d <= 0: the tie goes away from zero) */
    if (keep_err != 0u) {
        s->err = hdf_sub_sat(hdf_sat32(d), (s->frac > 32768 || (s->frac == 32768 && d <= 0)) ? 1 : 0);
    }
    /* e = d - frac (2^-48 turn) in 2^-36 turn as an int32: |d| clamped to 2^27 - 1
     * (2^-5 turn; a larger error moves the estimate at that error's rate), so
     * |d 2^16 - frac| < 2^43 and the rounded e < 2^31 */
    /* in 32 bits: with x = dc 2^16 - frac and dc 2^16 a multiple of 2^12, round(x / 2^12)
     * (ties away from 0) = dc 2^4 + floor((2^11 - frac - [x < 0]) / 2^12), the floor taken
     * on the value + 2^16 (> 0, a logical shift: 0 .. 2^4) less 2^4; |dc| < 2^27, so
     * dc 2^4 - 2^4 and the sum stay within int32 */
    const int32_t dc = (int32_t)hdf_clamp64(d, -HD_VELOBS_D_MAX, HD_VELOBS_D_MAX);
    const uint32_t neg = (dc < 0 || (dc == 0 && s->frac > 0)) ? 1u : 0u;
    const int32_t e = (dc * HD_VELOBS_E_UNIT - HD_VELOBS_E_UNIT) +
        (int32_t)((HD_VELOBS_E_HALF + 65536u - (uint32_t)s->frac - neg) >> HD_VELOBS_E_SHIFT);
    /* vel [2^-48 turn/s] += (Ki T)[Q16 1/s] * e [2^-36 turn] / 2^4: a 32 x 32 product */
    s->vel = hdf_add64_sat(s->vel, hdf_asr64_rnd((int64_t)c->ki_dt * e, 16u - HD_VELOBS_E_SHIFT));
    /* angle advance in 2^-48 turn: T * vel + (Kp T) * e + frac (|(Kp T) e / 2^4| < 2^59) */
    int64_t adv = hdf_mul64x32_q(s->vel, HD_VELOBS_T_Q44, HD_VELOBS_T_SHIFT);
    adv = hdf_add64_sat(adv, hdf_asr64_rnd((int64_t)c->kp_dt * e, 16u - HD_VELOBS_E_SHIFT) + (int64_t)s->frac);
    const int64_t whole = hdf_asr64_floor(adv, 16u);
    s->frac = (int32_t)(adv - whole * 65536);
    s->theta = hdf_add64_sat(s->theta, whole);
}

/** hd_velobs_step inlined into the caller: the same words without the call. */
HD_FX_INLINE void hd_velobs_step_inline(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas)
{
    hd__velobs_step(s, c, theta_meas, 1u);
}

/** hd_velobs_step_inline for a caller that reads the angle and velocity but never
 *  err (the control period's motor observer): err keeps its last value (0 after
 *  hd_velobs_reset / hd_velobs_start); theta, frac and vel are the same words. */
HD_FX_INLINE void hd_velobs_step_vel_inline(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas)
{
    hd__velobs_step(s, c, theta_meas, 0u);
}

/** One period with the measured multi-turn angle. */
void hd_velobs_step(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas);
/** Start at angle theta with velocity 0. */
void hd_velobs_reset(hd_velobs_t *s, hd_angle_t theta);
/** Start at angle theta with velocity vel48 (2^-48 turn/s): an observer switched on
 *  while the axis moves starts from another estimate of the same velocity. */
void hd_velobs_start(hd_velobs_t *s, hd_angle_t theta, int64_t vel48);
/** Velocity in 2^-32 turn/s, rounded and saturated. */
hd_vel_out_t hd_velobs_vel_out(const hd_velobs_t *s);
/** Velocity in 2^-48 turn/s (inline: the control period reads it twice). */
static inline int64_t hd_velobs_vel48(const hd_velobs_t *s)
{
    return s->vel;
}
/** Gains for bandwidth w (rad/s, given in Q16) and damping zeta (Q16): kp_dt = 2 zeta w T, ki_dt = w^2 T. */
void hd_velobs_design(hd_velobs_cfg_t *c, int32_t w_q16, int32_t zeta_q16);

#endif
