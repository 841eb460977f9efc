/*
 * hd_stab.h - inertial stabilisation estimator: the payload's inertial
 * pointing angle from the payload rate gyro, and the base rate from the gyro
 * and the output encoder (docs/control.md, "Stabilisation").
 *
 * Signals (one period T = 1/HD_LOOP_HZ):
 *   gyro     inertial rate of the payload (load rate + base rate), 2^-32 turn/s
 *   pos_out  output-encoder angle = payload relative to the base, Q32.32 turns
 *   rate_cmd commanded inertial rate (scan), 2^-32 turn/s
 *
 *   g         = gyro - bias - b_hat                      corrected rate
 *   ang      += g                                        inertial angle estimate
 *   ref      += rate_cmd                                 inertial angle reference
 *   (blend, fc > 0: r = 1e4 pos_out - ang; r_f += alpha (r - r_f);
 *                   ang += kp T r_f;  b_hat -= ki T r_f  with kp = 2 wc, ki = wc^2)
 *   th_b      = ang / 1e4 - pos_out                      base-angle estimate
 *   w_b       = tracking observer(th_b): vel + Kp e       base-rate estimate (full rate of the
 *                                                        observer: no first-order lag)
 *   err       = (ref - ang) / 1e4                        inertial angle error -> position loop
 *   vff       = rate_cmd - w_b                           relative velocity feed-forward
 *   vff_db    = (rate_cmd - observer integrator state) shrunk toward 0 by ff_db (dead band):
 *               velocity for the friction feed-forward (smoother than vff);
 *               with the base at rest w_b is gyro noise (~1e-5 rad/s at 100 Hz), and a
 *               friction model fed with it would chatter between +-Fc
 *
 * The angle states `ang`, `ref` are int64 sums of the gyro words, unit
 * S = 2^-32 turn/s x T = 2^-32 turn / 1e4 (2.33e-14 turn): integration is exact
 * (no rounding accumulates) and holds +-2.1e5 turns.  S -> 2^-32 turn is one
 * multiply by 1/1e4 (Q44, rel. error 2.5e-10, never accumulated).
 *
 * Drift: without an absolute attitude reference the integrated gyro drifts
 * with the residual bias (0.5 deg/h = 0.5 arcsec/s on the reference gyro).
 * Two means: `bias` (constant, calibrated with the base at rest) and the
 * complementary blend: at very low frequency (wc = 2 pi fc, fc ~ 0.002 Hz)
 * the estimate is pulled toward the encoder angle (relative to the base) and
 * the residual bias is estimated (PI correction, zero error to a constant
 * bias).  This assumes that the base rocks about a constant mean attitude;
 * the base rocking leaks into the estimate by |L(jw)| ~ 2 wc wr / w^2 (wr the
 * innovation low-pass), 2e-4 at 1 Hz with fc 0.002 Hz and fr 0.05 Hz.
 * fc = 0 disables the blend (pure gyro integration; drift = bias error x t).
 *
 * Formats:
 *   bias          int32 2^-32 turn/s
 *   blend_kp      int32, kp T in Q40 (2 wc T)
 *   blend_ki      int32, ki T^2 2^32 in Q32 (b_hat in 2^-64 turn/s per S of r_f)
 *   alpha         int32 Q30, 1 - exp(-2 pi fr T)
 *   b_hat         int64 2^-64 turn/s, clamped to +-bias_max (2^-32 turn/s)
 *   r_f           int64 S
 *   observer      hd_vel_observer (Q32.32 turns in, 2^-48 turn/s state)
 */
#ifndef HD_STAB_H
#define HD_STAB_H

#include <stdint.h>
#include "hd_units.h"
#include "hd_vel_observer.h"

typedef struct {
    int32_t bias;            /* constant gyro bias, 2^-32 turn/s */
    int32_t blend_kp;        /* Q40, 2 wc T (0 = blend off) */
    int32_t blend_ki;        /* Q32, wc^2 T^2 2^32 */
    int32_t alpha;           /* Q30, innovation low-pass */
    int32_t bias_max;        /* |b_hat| limit, 2^-32 turn/s */
    int32_t ff_db;           /* dead band of vff_db, 2^-32 turn/s */
    hd_velobs_cfg_t obs;     /* base-rate observer */
} hd_stab_cfg_t;

typedef struct {
    int64_t ang;             /* inertial angle estimate, S */
    int64_t ref;             /* inertial angle reference, S */
    int64_t r_f;             /* low-passed innovation, S */
    int64_t b_hat;           /* estimated residual bias, 2^-64 turn/s */
    hd_velobs_t obs;         /* base-angle tracking observer */
    /* outputs of the last step */
    int32_t err;             /* ref - ang, 2^-32 turn (saturated) */
    int32_t base_rate;       /* base-rate estimate, 2^-32 turn/s */
    int32_t vff;             /* rate_cmd - base_rate, 2^-32 turn/s (saturated) */
    int32_t vff_db;          /* friction-FF velocity (dead band ff_db removed), 2^-32 turn/s */
    int32_t rate;            /* corrected gyro rate g, 2^-32 turn/s */
} hd_stab_t;

/** Parameters in table units -> cfg.  fc_q16, fr_q16, bw_q16 in Hz (Q16), zeta Q16,
 *  bias, bias_max and ff_db 2^-32 turn/s.  fc is limited to 0.01 Hz (gain format). */
void hd_stab_design(hd_stab_cfg_t *c, int32_t bias, int32_t fc_q16, int32_t fr_q16, int32_t bias_max,
                    int32_t bw_q16, int32_t zeta_q16, int32_t ff_db);

/** Start: estimate = encoder angle, reference = estimate, base rate from gyro - v_rel
 *  (v_rel: payload rate relative to the base, 2^-32 turn/s).  The bias estimate is kept
 *  (hd_stab_init clears it). */
void hd_stab_start(hd_stab_t *s, const hd_stab_cfg_t *c, hd_angle_t pos_out, hd_vel_out_t gyro,
                   hd_vel_out_t v_rel);
/** Power-up: everything 0. */
void hd_stab_init(hd_stab_t *s);
/** One period. */
void hd_stab_step(hd_stab_t *s, const hd_stab_cfg_t *c, hd_vel_out_t gyro, hd_angle_t pos_out,
                  hd_vel_out_t rate_cmd);
/** Inertial angle estimate in Q32.32 turns (rounded). */
hd_angle_t hd_stab_angle(const hd_stab_t *s);

#endif
