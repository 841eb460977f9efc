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
