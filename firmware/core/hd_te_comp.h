/*
 * hd_te_comp.h - transmission-error (kinematic error) compensation from
 * identified harmonics of the wave-generator (motor) angle.
 *
 *   TE(theta_m) = sum_h amp_h * sin(2 pi (order_h * theta_m + phase_h))     theta_m in turns
 *   TE = theta_L - theta_M / N (output minus output-referred motor angle)
 * Outputs:
 *   dth = -TE          position-command correction (semi-closed loop): add to the
 *                      output-referred motor position command so that the
 *                      output, not the motor, lands on the reference
 *   tau = -k1 * TE     optional torque feed-forward (full closed loop): cancels the
 *                      ripple torque K1*TE that the error pushes through the gear
 *                      stiffness (quasi-static, valid well below the torsional mode)
 *
 * Formats:
 *   theta_m           int64 Q32.32 motor turns; only the fraction of a turn
 *                     (uint32, wraps once per turn, meant) is used, and
 *                     order * fraction + phase is computed modulo one turn
 *                     exactly in uint32 arithmetic
 *   order_h           uint32 harmonic order per WG revolution (2 = dominant line)
 *   amp_h             int32, 2^-32 turn at the output (1 arcsec = 3314 LSB)
 *   phase_h           uint32 turn fraction (2^32 = 1 turn)
 *   k1                Q23.8 N.m/turn (K1 = 3.1e4 N.m/rad -> 1.95e5 N.m/turn)
 *   dth               int64 Q32.32 turns;  tau, tau_max Q15.16 N.m
 * sin by hd_sincos_turn_fast (Q30, ~4e-8); the sum of amp*sin is accumulated exactly in
 * int64 and rounded once.
 */
#ifndef HD_TE_COMP_H
#define HD_TE_COMP_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"
#include "hd_blend.h"

#define HD_TE_N_MAX 8u

/* Ranges of the short form of hd_te_model_slope (hd_te_cfg_ranges): at most
 * HD_TE_FIT32_N harmonics, |amp| <= 2^30 (a quarter turn), order <= 2^28.  Then
 * |amp sin| <= 2^60 and the sum of four < 2^63; round(amp cos / 2^30) fits an int32
 * (|.| <= 2^30) and order times it <= 2^58, the sum of four < 2^63: no sum saturates,
 * so the plain int64 sums are the saturating ones, word for word.  The drive's
 * parameters (te_amp* <= 0.01 turn, te_order* <= 1000, four harmonics) lie inside. */
#define HD_TE_FIT32_N 4u
#define HD_TE_FIT32_AMP (1 << 30)
#define HD_TE_FIT32_ORDER (1u << 28)

typedef struct {
    uint32_t n;                      /* harmonics in use, <= HD_TE_N_MAX */
    uint32_t order[HD_TE_N_MAX];
    int32_t  amp[HD_TE_N_MAX];       /* 2^-32 turn */
    uint32_t phase[HD_TE_N_MAX];     /* 2^32 = 1 turn */
    int32_t  k1;                     /* Q23.8 N.m/turn; 0 = no torque feed-forward */
    int32_t  tau_max;                /* Q15.16 N.m, > 0 */
    uint32_t fit32;                  /* 1: within HD_TE_FIT32_* (hd_te_cfg_ranges), so the model's
                                      * sums need no saturation (same words, shorter code); 0: the
                                      * general form */
} hd_te_cfg_t;

typedef struct {
    hd_blend_t blend;
    int64_t te;                      /* last TE model value, 2^-32 turn (unweighted) */
    hd_angle_t dth;                  /* weighted correction, Q32.32 turns */
    int32_t tau;                     /* weighted torque feed-forward, Q15.16 N.m */
} hd_te_comp_t;

/** Set c->fit32 from the harmonics in c (call after filling n, order and amp). */
void hd_te_cfg_ranges(hd_te_cfg_t *c);
/** TE model at motor angle theta_m, 2^-32 turn. */
int64_t hd_te_model(const hd_te_cfg_t *c, hd_angle_t theta_m);
void hd_te_comp_init(hd_te_comp_t *s, uint32_t ramp_ticks, bool enabled);
void hd_te_comp_set_enabled(hd_te_comp_t *s, bool enabled);
/** One period: returns the weighted position correction dth (s->tau holds the torque). */
hd_angle_t hd_te_comp_step(hd_te_comp_t *s, const hd_te_cfg_t *c, hd_angle_t theta_m);
/** TE model at theta_m (the same value as hd_te_model) and its slope dTE/dtheta in
 *  2^-32 turn per motor turn (2 pi sum order amp cos, saturated to int32), for a
 *  first-order prediction TE(theta) ~ TE(theta_m) + slope (theta - theta_m). */
int64_t hd_te_model_slope(const hd_te_cfg_t *c, hd_angle_t theta_m, int32_t *slope);
/** hd_te_comp_step with the slope of the returned correction (-w dTE/dtheta, 2^-32 turn
 *  per motor turn) in *slope_w: a caller that evaluates TE every n periods predicts the
 *  correction in between from the motor angle's change (hd_comp_bank.c). */
hd_angle_t hd_te_comp_step_slope(hd_te_comp_t *s, const hd_te_cfg_t *c, hd_angle_t theta_m, int32_t *slope_w);

#endif
