/*
 * hd_lugre.h - LuGre dynamic friction model / observer for friction compensation
 * (Canudas de Wit, Olsson, Astrom, Lischinsky 1995).
 *
 * Continuous model (output-referred, z = mean bristle deflection in turns):
 *   dz/dt = v - sigma0 |v| z / g(v) - k_obs * e        (k_obs = 0: open-loop model)
 *   g(v)  = fc + (fs - fc) exp(-|v/vs|^delta)           (force units, hd_stribeck_g)
 *   F     = sigma0 z + sigma1 dz/dt + sigma2 v
 * e is the position tracking error theta - theta_d (Canudas de Wit 1995 observer:
 * the k*e term makes the estimate-error system passive / the closed loop stable).
 *
 * Discretisation (exact for v constant over the period T = 1/HD_LOOP_HZ):
 *   z_ss  = sgn(v) g(v) / sigma0
 *   a     = sigma0 |v| T / g(v)
 *   z'    = z_ss + (z_k - z_ss) exp(-a)                 (unconditionally stable, stiff-safe)
 *   z_k+1 = z' - k_obs T e_k                            (observer term, operator splitting)
 *   F_k   = sigma0 z_k+1 + sigma1 (z_k+1 - z_k)/T + sigma2 v_k
 * The sigma1 term uses the mean dz/dt over the period (consistent with the exact
 * update); at v = 0 the bristles hold (a = 0).
 *
 * Formats:
 *   v                    2^-32 turn/s (output velocity)          int32
 *   e                    Q32.32 turns (angle)                     int64
 *   z                    Q16.48 turns (2^-48 turn = 3.6e-15 rad)  int64 state
 *   g.fc, g.fs           Q15.16 N.m  (g(v) is clamped to >= 1 LSB)
 *   g.vs                 2^-32 turn/s; g.fv unused (sigma2 is the viscous term)
 *   sigma0               Q23.8 N.m/turn   (1 LSB = 6.2e-4 N.m/rad; max 5.2e6 N.m/rad)
 *   sigma1, sigma2       Q15.16 N.m/(turn/s)
 *   k_obs                Q15.16 1/s
 *   1 - exp(-a)          Q46, full relative precision at small a (see hd_lugre.c)
 * The divisions by the parameters sigma0 and g.vs go through reciprocals kept in the
 * state (hd_divinv_t, recomputed only when the parameter changed): the same values
 * as the divisions, without a 64-bit long division per period.
 *   tau, tau_max         Q15.16 N.m
 */
#ifndef HD_LUGRE_H
#define HD_LUGRE_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"
#include "hd_blend.h"
#include "hd_stribeck.h"
#include "hd_fixed.h"

typedef struct {
    hd_stribeck_dir_t g;   /* Stribeck curve g(v) (symmetric); g.fv ignored */
    uint32_t delta;        /* Stribeck exponent, 1 or 2 (LuGre default 2) */
    int32_t  sigma0;       /* Q23.8 N.m/turn, > 0 */
    int32_t  sigma1;       /* Q15.16 N.m/(turn/s) */
    int32_t  sigma2;       /* Q15.16 N.m/(turn/s) */
    int32_t  k_obs;        /* Q15.16 1/s, >= 0 */
    int32_t  tau_max;      /* Q15.16 N.m, > 0 */
} hd_lugre_cfg_t;

typedef struct {
    hd_blend_t blend;
    int64_t z;             /* bristle deflection, Q16.48 turns */
    int64_t dz;            /* last increment, Q16.48 turns per period */
    int32_t tau_raw;       /* last unweighted friction estimate, Q15.16 N.m */
    int32_t tau;           /* last weighted output, Q15.16 N.m */
    hd_divinv_t inv_sigma0; /* reciprocal of cfg sigma0 (refreshed when it changes) */
    hd_divinv_t inv_vs;    /* reciprocal of cfg g.vs (refreshed when it changes) */
    int32_t v;             /* velocity of the step prepared (hd_lugre_prep_n) */
    int32_t g;             /* its g(v), Q15.16 N.m (>= 1) */
    int64_t zss;           /* its bristle steady state z_ss, Q48 (0 at v = 0) */
    int64_t em1;           /* its 1 - exp(-sigma0 |v| T / g), Q46 */
} hd_lugre_t;

void hd_lugre_init(hd_lugre_t *s, uint32_t ramp_ticks, bool enabled);
void hd_lugre_set_enabled(hd_lugre_t *s, bool enabled);
/** One period with velocity v (reference or estimate, caller's choice) and
 *  position error e (0 when the observer term is not used).  Returns the
 *  weighted, clamped friction compensation torque, Q15.16 N.m. */
int32_t hd_lugre_step(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v, hd_angle_t e);
/** The same step over n control periods (T = n / HD_LOOP_HZ, n divides HD_LOOP_HZ):
 *  the bristle update, the observer term and dz/T at the rate HD_LOOP_HZ / n; for a
 *  compensator evaluated every n-th period.  n = 1 is hd_lugre_step. */
int32_t hd_lugre_step_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v, hd_angle_t e, uint32_t n);
/** hd_lugre_step_n in two calls, e.g. in two control periods: the prep at velocity v
 *  (g(v), the bristles' steady state and the step's exponential factor, kept in s), then
 *  the finish with the position error e (bristle update, observer term, torque).
 *  prep then finish is exactly hd_lugre_step_n. */
void hd_lugre_prep_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v, uint32_t n);
/** hd_lugre_prep_n in two calls as well: g(v) and the bristles' steady state, then the
 *  step's exponential factor; prep_g then prep_exp_n is exactly hd_lugre_prep_n. */
void hd_lugre_prep_g(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v);
void hd_lugre_prep_exp_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, uint32_t n);
int32_t hd_lugre_finish_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_angle_t e, uint32_t n);

#endif
