/*
 * hd_maxwell.h - Maxwell-slip (elasto-slide / stop-operator) hysteresis model and
 * its use for lost-motion compensation.
 *
 * N elements in parallel (N <= HD_MAXWELL_N_MAX).  Element i is a spring of
 * stiffness k_i whose free end (anchor xi_i) slips so that the deflection
 * s_i = x - xi_i never exceeds the slip limit d_i (= W_i / k_i):
 *   s_i = clamp(x - xi_i, -d_i, d_i);  xi_i = x - s_i        (exact, integer)
 *   F   = sum_i k_i s_i                                       hysteresis torque
 *   dth = F * compliance                                      lost-motion correction
 * Rate independent, wiping-out and Masing rule (stop-type Prandtl-Ishlinskii).
 *
 * Use for lost motion: x is the OUTPUT POSITION REFERENCE and dth is added to
 * the motor-side position command (output-referred; multiply by N at the
 * motor).  Chosen as a position-command correction because lost motion is a
 * kinematic lag (the output stays behind the wave generator by the hysteretic
 * twist F/K until the teeth re-engage after a reversal): correcting the
 * command removes it directly in the semi-closed (motor-encoder) loop, while a
 * torque feed-forward would have to push the gear through its own compliance
 * and would fight the position loop.  F itself is also returned: as the
 * presliding (Maxwell-slip friction) torque it can be used as torque
 * feed-forward when the output encoder closes the loop.
 *
 * Formats:
 *   x, xi_i, dth          Q32.32 turns (int64)
 *   d_i, s_i              2^-32 turn (int32, d_i >= 0: up to 0.5 turn)
 *   k_i                   Q23.8 N.m/turn (>= 0)
 *   F, tau_max            Q15.16 N.m  (F = round(sum k_i s_i / 2^24), summed exactly in int64)
 *   compliance            2^-44 turn per N.m (1/K), int32: K from 1.3e3 N.m/rad (2^13 N.m/turn)
 *                         up; 5e3 N.m/rad -> 5.6e8, K1 = 3.1e4 -> 9.0e7, 2e5 -> 1.4e7
 *                         (relative resolution better than 1e-7 over that range)
 */
#ifndef HD_MAXWELL_H
#define HD_MAXWELL_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"
#include "hd_blend.h"

#define HD_MAXWELL_N_MAX 16u

typedef struct {
    uint32_t n;                          /* elements in use, <= HD_MAXWELL_N_MAX */
    int32_t  k[HD_MAXWELL_N_MAX];        /* Q23.8 N.m/turn */
    int32_t  d[HD_MAXWELL_N_MAX];        /* slip limit, 2^-32 turn, >= 0 */
    int32_t  compliance;                 /* 2^-44 turn / N.m */
    int32_t  tau_max;                    /* Q15.16 N.m, > 0 */
} hd_maxwell_cfg_t;

typedef struct {
    hd_blend_t blend;
    int32_t s[HD_MAXWELL_N_MAX];         /* element deflections, 2^-32 turn */
    hd_angle_t x_prev;                   /* last input, Q32.32 turns */
    uint32_t primed;                     /* 0 until the first step */
    int32_t  tau_raw;                    /* last hysteresis torque F, Q15.16 N.m */
    int32_t  tau;                        /* weighted F */
    hd_angle_t dth;                      /* weighted lost-motion correction, Q32.32 turns */
} hd_maxwell_t;

/** Reset: all elements relaxed (s_i = 0) at the next input. */
void hd_maxwell_init(hd_maxwell_t *s, uint32_t ramp_ticks, bool enabled);
void hd_maxwell_set_enabled(hd_maxwell_t *s, bool enabled);
/** One period with input position x.  Returns the weighted position-command
 *  correction dth (Q32.32 turns); s->tau holds the weighted torque F. */
hd_angle_t hd_maxwell_step(hd_maxwell_t *s, const hd_maxwell_cfg_t *c, hd_angle_t x);

#endif
