/*
 * hd_backstep.h - adaptive backstepping position controller with
 * projection-bounded adaptation of friction and load torque
 * (docs/compensators.md section 6; harmonic-drive.md 8.3).
 *
 * Rigid output-referred plant  theta' = omega,  J omega' = u - phi(omega)^T theta - ...
 *   e1     = theta - theta_d                       (clamped to +-e1_max)
 *   alpha1 = omega_d - c1 e1
 *   e2     = omega - alpha1
 *   alpha1'= acc_d - c1 (omega - omega_d)
 *   u      = J (alpha1' - c2 e2) - ke e1 + phi^T theta_hat
 *   theta_hat' = -Gamma phi e2, projected onto [th_min, th_max] per parameter; while the
 *            axis can stick (0 < |omega_d| <= 4 w_s, the reference not cruising, |omega| <= w_s)
 *            T_load's box is widened on both sides by
 *            th_max_0 + th_max_1 (the largest static friction: when the axis sticks at a
 *            reversal the friction regressor is about 0 and T_load carries the breakaway)
 *   phi    = [ s(w), exp(-(w/w_s)^2) s(w), w [turn/s], 1 ],  w = omega_d while the reference
 *            cruises (omega_d != 0, changed by at most HD_BS_WD_STEADY since the last step),
 *            else omega;  s = hd_sign_smooth_q30(w, eps_w); theta = [Fc, Fs - Fc, Fv, T_load]
 *            (at a slow cruise the sign of the measured velocity follows its noise, the
 *            friction terms would average out and T_load would have to hold the friction
 *            besides the load; at rest and at reversals the axis' own velocity is the
 *            friction's direction)
 * Lyapunov V = ke e1^2/2 + J e2^2/2 + sum (theta_i - theta_hat_i)^2 / (2 Gamma_i)
 *   => V' = -ke c1 e1^2 - J c2 e2^2 <= 0 inside the bounds (projection only removes
 *      terms of the right sign when theta lies in the box).
 * Discretisation: explicit Euler, T = 1/HD_LOOP_HZ; adaptation frozen while the
 * output is clamped (anti-windup) or the controller is blended out.
 *
 * Formats:
 *   theta, theta_d     int64 Q32.32 turns; e1, e1_max int32 2^-32 turn
 *   omega, omega_d, alpha1, e2, eps_w, w_s   int32 2^-32 turn/s
 *   acc_d, alpha1'     int32 2^-24 turn/s^2
 *   c1, c2             Q15.16 1/s
 *   j                  Q15.16 N.m per (turn/s^2)  (= 2 pi J[kg m^2])
 *   ke                 Q23.8 N.m/turn
 *   phi_i              Q30 (phi_3 = omega in turn/s)
 *   theta_hat_i        int64 Q16.48 (N.m; N.m/(turn/s) for i = 2): wide state; the law
 *                      uses it rounded to Q15.16 (th_q16, formed when theta_hat changes)
 *   th_min, th_max     Q15.16, same units (T_load: the load's box, widened as above)
 *   gamma_dt_i         Q7.24, Gamma_i * T with Gamma_i in [theta_i] / (turn * unit phi):
 *                      each period  theta_hat_i -= round(gamma_dt_i * pe_i / 2^8)  (Q48),
 *                      pe_i = round(phi_i * e2 / 2^30) in 2^-32 turn/s
 *   u, u_max, u_base   Q15.16 N.m (output torque)
 */
#ifndef HD_BACKSTEP_H
#define HD_BACKSTEP_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"
#include "hd_blend.h"
#include "hd_fixed.h"

#define HD_BS_NP 4u
#define HD_BS_WD_STEADY 64     /* omega_d change per period of a cruising reference, 2^-32 turn/s */

typedef struct {
    int32_t c1;                    /* Q15.16 1/s */
    int32_t c2;                    /* Q15.16 1/s */
    int32_t j;                     /* Q15.16 N.m/(turn/s^2) */
    int32_t ke;                    /* Q23.8 N.m/turn */
    int32_t eps_w;                 /* 2^-32 turn/s */
    int32_t w_s;                   /* 2^-32 turn/s */
    int32_t e1_max;                /* 2^-32 turn, > 0 */
    int32_t u_max;                 /* Q15.16 N.m, > 0 */
    int32_t gamma_dt[HD_BS_NP];    /* Q7.24 */
    int32_t th_min[HD_BS_NP];      /* Q15.16 */
    int32_t th_max[HD_BS_NP];      /* Q15.16 */
} hd_backstep_cfg_t;

typedef struct {
    hd_angle_t   theta;            /* measured output angle, Q32.32 turns */
    hd_angle_t   theta_d;          /* reference angle */
    hd_vel_out_t omega;            /* measured / estimated output velocity */
    hd_vel_out_t omega_d;          /* reference velocity */
    hd_acc_t     acc_d;            /* reference acceleration, 2^-24 turn/s^2 */
} hd_backstep_in_t;

typedef struct {
    hd_blend_t blend;
    int64_t th[HD_BS_NP];          /* adapted parameters, Q16.48 */
    int32_t th_q16[HD_BS_NP];      /* th rounded to Q15.16 (the law's form), refreshed with th */
    int32_t phi[HD_BS_NP];         /* last regressor, Q30 */
    int32_t e1;                    /* 2^-32 turn */
    int32_t e2;                    /* 2^-32 turn/s */
    int32_t u_bs;                  /* last backstepping output (unweighted, clamped) */
    int32_t u;                     /* last blended output */
    uint32_t saturated;            /* 1 if u_bs was clamped */
    int32_t shape;                 /* Stribeck regressor's shape exp(-(omega/w_s)^2), Q30, at its last refresh */
    hd_divinv_t inv_ws;            /* reciprocal of cfg w_s (refreshed by step / preload when it changes) */
    int32_t wd_prev;               /* omega_d of the last step (cruise test of the regressor) */
    uint32_t wide;                 /* 1: T_load's widened box in the adaptation (set by step, preload, regressor) */
} hd_backstep_t;

/** Parameters start at th0 (Q15.16, clamped into the bounds). */
void hd_backstep_init(hd_backstep_t *s, const hd_backstep_cfg_t *c, const int32_t th0[HD_BS_NP],
                      uint32_t ramp_ticks, bool enabled);
void hd_backstep_set_enabled(hd_backstep_t *s, bool enabled);
/** The control law without adaptation or state change (Q15.16 N.m, unclamped sat32). */
int32_t hd_backstep_law(const hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in);
/** Bumpless engage: set the load-torque estimate so that the law equals u_now
 *  (the control effort currently applied, e.g. the PID output), within bounds. */
void hd_backstep_preload(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in,
                         int32_t u_now);
/** One period: law + adaptation; returns u_base + w (u_bs - u_base). */
int32_t hd_backstep_step(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in,
                         int32_t u_base);

/** The law of one period with the held adapted parameters and the held Stribeck shape
 *  (hd_backstep_regressor), the sign and viscous regressors of this period's velocity; no
 *  adaptation.  Returns u_base + w (u_bs - u_base); keeps e2, phi for hd_backstep_adapt. */
int32_t hd_backstep_step_held(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in,
                              int32_t u_base);
/** Refresh the held Stribeck shape of the regressor at this period's regressor velocity
 *  (omega_d while the reference cruises, omega otherwise: see phi above) and T_load's box of
 *  the next hd_backstep_adapt (widened while the axis can stick). */
void hd_backstep_regressor(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in);
/** The adaptation of 2^log2_n periods (log2_n <= 8) at once, from the regressor and e2
 *  of the last hd_backstep_step_held (frozen while it saturated or blended out). */
void hd_backstep_adapt(hd_backstep_t *s, const hd_backstep_cfg_t *c, uint32_t log2_n);

#endif
