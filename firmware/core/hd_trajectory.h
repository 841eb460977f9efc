/*
 * hd_trajectory.h - reference generator for the output axis: jerk-limited
 * point-to-point moves, constant-rate moves (down to 0.0001 deg/s and below),
 * sinusoids.  Struct + step(), one step per control period T = 1/HD_LOOP_HZ.
 *
 * Exactness.  The position is integrated in int64 with unit 2^-48 turn
 * (16 bits finer than Q32.32; range +-32768 turns), and every per-period
 * increment that is not an integer in that unit is carried as an exact
 * remainder (numerator mod HD_LOOP_HZ), so a constant rate v gives after k
 * periods exactly floor(k * v * 2^16 / HD_LOOP_HZ) units: no drift over any
 * run length.  A point-to-point move is planned in integer per-period units
 * (jerk 2^-48 turn/T^3, accel 2^-48 turn/T^2, velocity 2^-48 turn/T) and ends
 * EXACTLY on the target.  A move long enough to reach the velocity limit cruises
 * at EXACTLY the limit: V = floor(vmax 2^16 / HD_LOOP_HZ) per period from the
 * ramps (one inserted acceleration period tops the whole-period jerk ramp up to
 * V, within the jerk and acceleration limits; hd_trajectory.c) plus the fraction
 * (vmax 2^16 mod HD_LOOP_HZ) / HD_LOOP_HZ with a remainder carry, so the cruise
 * position advances like the constant-rate mode.  The distance the plan does not
 * cover in whole periods (R < V + 1) is spread over the whole move with a
 * remainder carry (the velocity deviates from the plan by at most R/K + 1 unit,
 * K = periods of the move).
 *
 * Outputs (refreshed by every step):
 *   pos  hd_angle_t   Q32.32 turns (rounded from the 2^-48 state)
 *   vel  hd_vel_out_t 2^-32 turn/s   (feed-forward)
 *   acc  hd_acc_t     2^-24 turn/s^2 (feed-forward)
 * Limits (cfg): vmax 2^-32 turn/s, amax 2^-24 turn/s^2, jmax 2^-16 turn/s^3.
 * Sinusoid frequency: Q16.16 Hz; amplitude 2^-32 turn.  The phase is a uint64
 * (2^64 = one cycle, wraps, meant) advanced with an exact remainder carry.
 *
 * Point-to-point and sinusoid start from rest (a new PTP while moving is
 * refused with -1); constant-rate ramps its velocity at amax from the current
 * trajectory velocity.  hd_traj_stop() ramps the velocity to 0 at amax.
 *
 * One-direction final approach (cfg appr_dir = +1 / -1, appr_dist > 0; off
 * with appr_dir = 0 or appr_dist = 0): a PTP move whose direction is not
 * appr_dir is split into two normal jerk-limited legs: first to
 * target - appr_dir * appr_dist (full limits), then, after appr_dwell
 * periods at rest, the final leg of appr_dist to the target in direction
 * appr_dir with the velocity limit min(appr_vmax, vmax) (appr_vmax 0 =
 * vmax; same amax, jmax).  A move in direction appr_dir (or of length 0) is
 * planned as before, one leg.  Every move therefore ends with motion in
 * direction appr_dir - the classic lost-motion take-up of precision
 * positioners: the friction/backlash state at the stop is the same for every
 * approach.  goal48 is the true target from hd_traj_ptp() on; target48 is the
 * end of the current leg; hd_traj_done() is 1 only after the final leg, which
 * lands EXACTLY on the target like any move.  The final leg is planned inside
 * the hd_traj_step() call that ends the first leg (cfg read there).
 */
#ifndef HD_TRAJECTORY_H
#define HD_TRAJECTORY_H

#include <stdint.h>
#include "hd_units.h"

typedef enum {
    HD_TRAJ_HOLD = 0,   /* stand still at pos */
    HD_TRAJ_PTP = 1,    /* jerk-limited point-to-point */
    HD_TRAJ_RATE = 2,   /* constant rate (ramped at amax), also used to stop */
    HD_TRAJ_SINE = 3    /* center + amp * sin(2 pi f t) */
} hd_traj_mode_t;

typedef struct {
    hd_vel_out_t vmax;   /* 2^-32 turn/s, > 0 */
    hd_acc_t     amax;   /* 2^-24 turn/s^2, > 0 */
    int32_t      jmax;   /* 2^-16 turn/s^3, > 0 */
    /* one-direction final approach (zero-initialised = off) */
    int32_t      appr_dir;   /* +1 / -1: direction of the final motion; 0 = off */
    int32_t      appr_dist;  /* final-leg length, 2^-32 turn (> 0 to be on) */
    hd_vel_out_t appr_vmax;  /* final-leg velocity limit, 2^-32 turn/s (0 = vmax) */
    uint32_t     appr_dwell; /* periods at rest between the legs */
} hd_traj_cfg_t;

typedef struct {
    int32_t  mode;        /* hd_traj_mode_t */
    int64_t  p48;         /* position, 2^-48 turn */
    int64_t  v48;         /* velocity, 2^-48 turn per period */
    int64_t  a48;         /* acceleration, 2^-48 turn per period^2 */
    /* PTP plan */
    int64_t  j48;         /* jerk magnitude, 2^-48 turn per period^3 */
    int64_t  target48;    /* 2^-48 turn */
    int32_t  dir;         /* +1 / -1 */
    uint32_t k;           /* periods since start of the move */
    uint32_t tj, ta, tv;  /* phase lengths, periods: jerk ramp, constant accel, cruise */
    uint32_t tn;          /* 1: one inserted accel period (level ins_a) lands the cruise on vmax; 0: none */
    uint32_t ins_k;       /* accel-phase index of the inserted period */
    int64_t  ins_a;       /* inserted accel level D, 2^-48 turn per period^2, 0 <= D < tj j48 */
    uint32_t vfrac;       /* cruise velocity fraction, numerator of 2^-48 turn per period / HD_LOOP_HZ */
    uint32_t vfrac_acc;   /* its accumulator, [0, HD_LOOP_HZ) */
    int64_t  cruise_r;    /* residual distance R (2^-48 turn), spread over the move */
    int64_t  cruise_acc;  /* remainder accumulator */
    /* final approach */
    int64_t  goal48;      /* true target of the move, 2^-48 turn */
    int32_t  appr_leg;    /* 0 one leg; 1 first leg (final leg pending); 2 dwell / final leg */
    uint32_t appr_wait;   /* dwell periods left before the final leg */
    /* RATE */
    int32_t  rate_target; /* 2^-32 turn/s */
    int32_t  rate_cur;    /* 2^-32 turn/s */
    int32_t  rate_dv;     /* |dv| per period, 2^-32 turn/s */
    int32_t  rate_rem;    /* position remainder numerator, [0, HD_LOOP_HZ) */
    /* SINE */
    hd_angle_t center;    /* Q32.32 turns */
    int32_t  amp;         /* 2^-32 turn */
    int32_t  w_q16;       /* 2 pi f, Q16 rad/s */
    uint64_t phase;       /* 2^64 = one cycle */
    uint64_t inc_q;       /* phase increment quotient */
    uint32_t inc_r;       /* remainder numerator (den HD_LOOP_HZ) */
    uint32_t inc_acc;
    /* outputs */
    hd_angle_t   pos;
    hd_vel_out_t vel;
    hd_acc_t     acc;
} hd_traj_t;

/** Hold at pos (Q32.32), velocity 0. */
void hd_traj_reset(hd_traj_t *s, hd_angle_t pos);
/** Plan a jerk-limited move to target. 0 = ok, -1 = not at rest or bad cfg. */
int32_t hd_traj_ptp(hd_traj_t *s, const hd_traj_cfg_t *c, hd_angle_t target);
/** Constant rate v (clamped to +-vmax), reached at amax. */
void hd_traj_rate(hd_traj_t *s, const hd_traj_cfg_t *c, hd_vel_out_t v);
/** Ramp to standstill at amax (constant-rate mode with target 0). */
void hd_traj_stop(hd_traj_t *s, const hd_traj_cfg_t *c);
/** Sinusoid about the current position: amp 2^-32 turn, f Q16.16 Hz (> 0). 0 ok, -1 not at rest. */
int32_t hd_traj_sine(hd_traj_t *s, hd_angle_t center, int32_t amp, int32_t f_q16);
/** Advance one period; updates pos/vel/acc. */
void hd_traj_step(hd_traj_t *s, const hd_traj_cfg_t *c);
/** 1 when a PTP move has finished - final approach leg included - (or in HOLD), else 0. */
int32_t hd_traj_done(const hd_traj_t *s);

#endif
