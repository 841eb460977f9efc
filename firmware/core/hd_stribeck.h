/*
 * hd_stribeck.h - Stribeck friction feed-forward (static map), direction-asymmetric.
 *
 *   tau(v) = s(v) * g_d(v) + fv_d * v
 *   g_d(v) = fc_d + (fs_d - fc_d) * exp(-|v / vs_d|^delta)      d = pos (v >= 0) or neg (v < 0)
 *   s(v)   = hd_sign_smooth_q30(v, eps_v): C1 cubic t(3-t^2)/2, t = v/eps_v,
 *            exactly +-1 beyond +-eps_v, 0 at v = 0 (no chatter at reversal;
 *            tau is continuous through zero even with fs_pos != fs_neg).
 *   v      = w * v_ref + (1 - w) * v_est          (configurable source)
 *   w      = 1 while the reference cruises (below), else w_ref
 *   (in a cruise s(v) is the hard sign, eps_v = 0)
 *
 * Velocity source.  On the reference velocity (w_ref = 1) the feed-forward is
 * smooth at any constant rate, but at the end of a move it drops to 0 with the
 * reference and the axis stops wherever friction catches it.  On the measured
 * velocity (w_ref = 0) the map closes a positive feedback through the friction
 * sign: at standstill and at rates of the order of the velocity-estimate noise
 * it is a relay in the velocity loop (a ~95 Hz limit cycle of +-fs on the
 * reference axis) that dithers the axis onto its target, and it makes a slow
 * constant rate (0.001 deg/s) jerky.  With cruise_ticks > 0 the source is chosen
 * by the reference itself: the reference "cruises" when it is non-zero and has
 * kept its sign and value (|v_ref(k) - v_ref(k0)| <= HD_STRIBECK_CRUISE_DV, k0 the
 * first period of the run) for cruise_ticks consecutive periods - the constant-rate phase of a move or a
 * constant-rate command, when the friction state is known to be sliding in the
 * direction of v_ref - and then w = 1 (reference velocity) and the sign is the
 * hard sign of v_ref (no zero crossing in a cruise, so no smooth-sign reduction of
 * the friction level at rates below eps_v); at rest, while accelerating or
 * braking and in the final arrival/hold, w = w_ref and s(v) as above.  Sinusoidal
 * or gyro-driven references (STAB) never stay constant that long.  The switch is
 * immediate (no ramp): at the start and end of a cruise v_est ~ v_ref.
 * cruise_ticks = 0: w = w_ref always (no cruise detection).
 *
 * Steady motion.  A reference that keeps moving without a constant rate (a sine)
 * never cruises; on the measured velocity the map then feeds back the friction
 * sign whenever the axis sticks and slips around a moving reference (a +-20-40"
 * stick-slip oscillation at 0.3-0.6 deg/s of a 0.1 Hz sine on the reference axis).
 * With steady_vs > 0 the map also takes the reference velocity (w = 1) while
 * |v_ref| >= steady_vs * vs_d, vs_d the Stribeck velocity of v_ref's direction,
 * from the period the measured velocity passes the same threshold in v_ref's
 * direction (the axis follows) until v_ref falls below it or changes sign: the
 * axis must slide in the reference's direction to follow it, so the friction
 * state is known from the reference as in a cruise, and a stick or slip of the
 * axis within the run does not end it.  Below that speed - near rest,
 * at reversals, in the arrival and hold of a move - w = w_ref as above (the relay
 * that dithers the axis onto its target stays).  The threshold is a multiple of the
 * axis' own Stribeck velocity, so one setting serves every axis.  steady_vs = 0:
 * off (the feed-forward is bit-identical to the one without this rule).
 *
 * Formats (all parameters plain int32, output-referred):
 *   v_ref, v_est, v, vs, eps_v : output velocity, 2^-32 turn/s (hd_units.h)
 *   fc, fs, tau, tau_max       : Q15.16 N.m (fc, fs magnitudes >= 0 for both directions)
 *   fv                         : Q15.16 N.m per (turn/s)   (= 2*pi * N.m.s/rad)
 *   w_ref                      : Q30 in [0, 2^30]
 *   delta                      : 1 or 2 (anything else is treated as 2)
 *   cruise_ticks               : control periods (0 = off)
 *   steady_vs                  : Q16.16 multiple of vs, >= 0 (0 = off)
 * Discretisation: none (static map evaluated each period).
 * Internal: r = |v|/vs in Q8.24 (saturated), x = r^delta in Q16 (rounded,
 * saturated), exp(-x) by hd_exp_neg_q16 (Q30); every product by hd_mul_q
 * (round to nearest, saturate).  hd_stribeck_step() takes r from a reciprocal
 * of vs (hd_stribeck_recip_t: 31-bit mantissa m = round(2^sh / vs)) that it
 * recomputes only when vs changes, r = round(|v| m / 2^(sh-24)): one 32x32->64
 * multiply per period instead of a 64/32 division; |r - |v| 2^24 / vs| <= 1.5 LSB
 * (Q24), against <= 0.5 LSB of the division (hd_stribeck_shape_q30, still used
 * by hd_lugre and hd_backstep).  hd_stribeck_map() uses the same reciprocal, so
 * step and map agree bit for bit.  Accuracy vs the Python reference:
 * docs/compensators.md.
 */
#ifndef HD_STRIBECK_H
#define HD_STRIBECK_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"
#include "hd_blend.h"
#include "hd_fixed.h"

/** Largest deviation of v_ref from its value at the start of a run that still counts as
 *  cruising, 2^-32 turn/s (2 LSB = 1.7e-7 deg/s: the trajectory generator's cruise velocity
 *  moves by at most 1 LSB, a constant-rate command not at all; the peak of a 0.01 deg/s
 *  sinusoid of 4 s period leaves +-2 LSB within 4 ms). */
#define HD_STRIBECK_CRUISE_DV 2

typedef struct {
    int32_t fc;   /* Coulomb torque, Q15.16 N.m, >= 0 */
    int32_t fs;   /* static (breakaway) torque, Q15.16 N.m, >= 0 */
    int32_t vs;   /* Stribeck velocity, 2^-32 turn/s, > 0 */
    int32_t fv;   /* viscous coefficient, Q15.16 N.m/(turn/s) */
} hd_stribeck_dir_t;

typedef struct {
    hd_stribeck_dir_t pos;  /* used for v >= 0 */
    hd_stribeck_dir_t neg;  /* used for v < 0 (magnitudes) */
    uint32_t delta;         /* 1 or 2 */
    int32_t  eps_v;         /* smooth-sign half width, 2^-32 turn/s (0 = hard sign) */
    int32_t  w_ref;         /* Q30 weight of v_ref, [0, 2^30] (outside a cruise) */
    int32_t  tau_max;       /* output clamp, Q15.16 N.m, > 0 */
    uint32_t cruise_ticks;  /* periods of constant v_ref before w = 1; 0 = off */
    int32_t  steady_vs;     /* Q16.16: w = 1 while |v_ref| >= steady_vs * vs_d; 0 = off */
} hd_stribeck_cfg_t;

/** Reciprocal of a Stribeck velocity: 2^sh / vs ~ m, m in (2^30, 2^31] (vs > 0). */
typedef struct {
    int32_t  vs;            /* the vs it was computed for (<= 0: shape 0) */
    uint32_t m;             /* round(2^sh / vs) */
    uint32_t sh;            /* 31 + floor(log2 vs), 31..61 */
} hd_stribeck_recip_t;

typedef struct {
    hd_blend_t blend;       /* on/off ramp */
    int32_t v;              /* last velocity used, 2^-32 turn/s */
    int32_t tau_raw;        /* last unweighted torque, Q15.16 N.m */
    int32_t tau;            /* last output (weighted), Q15.16 N.m */
    int32_t v_anchor;       /* v_ref at the start of the current run, 2^-32 turn/s */
    uint32_t cruise_n;      /* consecutive cruising periods (saturates at cruise_ticks) */
    uint32_t cruise;        /* 1 = this period used the reference velocity (cruise) */
    uint32_t steady;        /* 1 = this period used the reference velocity (steady motion) */
    int32_t v_steady;       /* v_ref of the last steady period (its sign: the run's direction), 0 = none */
    hd_stribeck_recip_t rp; /* reciprocal of cfg pos.vs (refreshed when it changes) */
    hd_stribeck_recip_t rn; /* reciprocal of cfg neg.vs */
} hd_stribeck_t;

/** exp(-|v/vs|^delta) in Q30 (vs <= 0 gives 0: pure Coulomb); one 64/32 division. */
int32_t hd_stribeck_shape_q30(int32_t v, int32_t vs, uint32_t delta);
/** g(v) = fc + (fs - fc) * exp(-|v/vs|^delta), Q15.16 N.m (division form). */
int32_t hd_stribeck_g(const hd_stribeck_dir_t *p, uint32_t delta, int32_t v);
/** hd_stribeck_shape_q30 with the division by vs through its reciprocal inv_vs (set up
 *  for vs when vs > 0, hd_divinv_init): the same value for every v. */
int32_t hd_stribeck_shape_inv_q30(int32_t v, int32_t vs, uint32_t delta, const hd_divinv_t *inv_vs);
/** hd_stribeck_g with the division by vs through its reciprocal inv_vs (set up for
 *  p->vs when p->vs > 0, hd_divinv_init): the same value for every v. */
int32_t hd_stribeck_g_inv(const hd_stribeck_dir_t *p, uint32_t delta, int32_t v, const hd_divinv_t *inv_vs);

/** The reciprocal of vs (call when vs changes; contains a 64-bit division). */
void hd_stribeck_recip(hd_stribeck_recip_t *r, int32_t vs);
/** exp(-|v/vs|^delta) in Q30 from a reciprocal of vs (no division). */
int32_t hd_stribeck_shape_recip_q30(int32_t v, const hd_stribeck_recip_t *r, uint32_t delta);
/** The static map tau(v) (before clamp and weight), Q15.16 N.m (reciprocal form, = step's map). */
int32_t hd_stribeck_map(const hd_stribeck_cfg_t *c, int32_t v);

void hd_stribeck_init(hd_stribeck_t *s, uint32_t ramp_ticks, bool enabled);
void hd_stribeck_set_enabled(hd_stribeck_t *s, bool enabled);
/** One period: returns the weighted, clamped feed-forward torque (Q15.16 N.m). */
int32_t hd_stribeck_step(hd_stribeck_t *s, const hd_stribeck_cfg_t *c,
                         hd_vel_out_t v_ref, hd_vel_out_t v_est);

#endif
