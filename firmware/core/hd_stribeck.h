/*
 * hd_stribeck.h - Stribeck friction feed-forward (static map), direction-asymmetric.
 *
 *   tau(v) = s(v) * g_d(v) + fv_d * v
 *   g_d(v) = fc_d + (fs_d - fc_d) * exp(-|v / vs_d|^delta)      d = pos (v >= 0) or neg (v < 0)
 *   s(v)   = hd_sign_smooth_q30(v, eps_v): C1 cubic t(3-t^2)/2, t = v/eps_v,
 *            exactly +-1 beyond +-eps_v, 0 at v = 0 (no chatter at reversal;
 *            tau is continuous through zero even with fs_pos != fs_neg).
 *   v      = w_ref * v_ref + (1 - w_ref) * v_est          (configurable source)
 *
 * Formats (all parameters plain int32, output-referred):
 *   v_ref, v_est, v, vs, eps_v : output velocity, 2^-32 turn/s (hd_units.h)
 *   fc, fs, tau, tau_max       : Q15.16 N.m (fc, fs magnitudes >= 0 for both directions)
 *   fv                         : Q15.16 N.m per (turn/s)   (= 2*pi * N.m.s/rad)
 *   w_ref                      : Q30 in [0, 2^30]
 *   delta                      : 1 or 2 (anything else is treated as 2)
 * Discretisation: none (static map evaluated each period).
 * Internal: r = |v|/vs in Q8.24 (hd_div_q), x = r^delta in Q16 (rounded,
 * saturated), exp(-x) by hd_exp_neg_q16 (Q30); every product by hd_mul_q
 * (round to nearest, saturate).  Accuracy vs the Python reference:
 * docs/compensators.md.
 */
#ifndef HD_STRIBECK_H
#define HD_STRIBECK_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"
#include "hd_blend.h"

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
    int32_t  w_ref;         /* Q30 weight of v_ref, [0, 2^30] */
    int32_t  tau_max;       /* output clamp, Q15.16 N.m, > 0 */
} hd_stribeck_cfg_t;

typedef struct {
    hd_blend_t blend;       /* on/off ramp */
    int32_t v;              /* last velocity used, 2^-32 turn/s */
    int32_t tau_raw;        /* last unweighted torque, Q15.16 N.m */
    int32_t tau;            /* last output (weighted), Q15.16 N.m */
} hd_stribeck_t;

/** exp(-|v/vs|^delta) in Q30 (vs <= 0 gives 0: pure Coulomb). */
int32_t hd_stribeck_shape_q30(int32_t v, int32_t vs, uint32_t delta);
/** g(v) = fc + (fs - fc) * exp(-|v/vs|^delta), Q15.16 N.m. */
int32_t hd_stribeck_g(const hd_stribeck_dir_t *p, uint32_t delta, int32_t v);
/** The static map tau(v) (before clamp and weight), Q15.16 N.m. */
int32_t hd_stribeck_map(const hd_stribeck_cfg_t *c, int32_t v);

void hd_stribeck_init(hd_stribeck_t *s, uint32_t ramp_ticks, bool enabled);
void hd_stribeck_set_enabled(hd_stribeck_t *s, bool enabled);
/** One period: returns the weighted, clamped feed-forward torque (Q15.16 N.m). */
int32_t hd_stribeck_step(hd_stribeck_t *s, const hd_stribeck_cfg_t *c,
                         hd_vel_out_t v_ref, hd_vel_out_t v_est);

#endif
