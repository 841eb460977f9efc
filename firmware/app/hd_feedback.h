/*
 * hd_feedback.h - feedback configuration of the position loop (parameter
 * fb_config, docs/control.md "Feedback configurations").
 *
 *   HD_FB_FULL_CLOSED  position on the output encoder; velocity as vel_fb_src says
 *                      (the compensator bank's position corrections become a
 *                      motor-side velocity lead, hd_comp_bank.h)
 *   HD_FB_SEMI_CLOSED  position = motor angle / N - offset, velocity = motor
 *                      encoder / N; the output encoder is only measured
 *   HD_FB_DUAL_LOOP    velocity = motor encoder / N; position = complementary
 *                      blend: the output encoder below fb_dual_fc, the motor-side
 *                      estimate (motor angle / N - offset) above it
 * offset = the compensator bank's predicted (motor angle / N - output angle):
 * its position corrections dpos (TE, Maxwell-slip / Preisach lost motion,
 * compliance twist), so the estimate is the motor angle / N plus the predicted
 * output offset TE - twist - hysteresis.
 *
 * Mode entry is bumpless: the references start at the feedback (hd_fb_enter), and
 * the step between the offset the bank last predicted and its first prediction
 * after the entry is held in a bias that fades with a time constant of
 * 2^HD_FB_BIAS_SHIFT periods (102 ms), so the compensators' correction moves the
 * axis smoothly instead of stepping the position error.
 *
 * Formats (hd_units.h):
 *   pos_mot        Q32.32 motor turns;   mo, est, pos_fb, offset  Q32.32 output turns
 *   mo_rem         pos_mot - N mo in [0, N), 2^-32 motor turn (so mo tracks
 *                  floor(pos_mot / N) exactly, one 32-bit division per period)
 *   corr           dual loop: low-passed (pos_out - est), 2^-48 turn
 *   dual_alpha     Q30, 1 - exp(-2 pi fc T)
 * Cost: full closed adds nothing to the period; semi-closed and dual-loop one
 * UDIV (hd_fb_motor) plus a few adds (and one 64x32 product for the dual blend).
 * No 64-bit division anywhere: motor / N is done in 16-bit chunks of 32-bit
 * divisions (N < 2^16; gear_ratio <= 1000).
 */
#ifndef HD_FEEDBACK_H
#define HD_FEEDBACK_H

#include <stdint.h>
#include "hd_units.h"

/* fade of the entry bias: 2^-10 per period, time constant 1024 periods (102 ms) */
#define HD_FB_BIAS_SHIFT 10u

typedef enum {
    HD_FB_FULL_CLOSED = 0,
    HD_FB_SEMI_CLOSED = 1,
    HD_FB_DUAL_LOOP = 2
} hd_fb_config_t;

typedef struct {
    uint32_t kind;           /* hd_fb_config_t */
    int32_t  n;              /* gear ratio, >= 1 */
    int32_t  dual_alpha;     /* Q30 */
} hd_fb_cfg_t;

typedef struct {
    hd_angle_t mot_prev;     /* motor angle of the last hd_fb_motor / reset */
    hd_angle_t mo;           /* floor(pos_mot / N), Q32.32 output turns */
    int32_t    mo_rem;       /* pos_mot - N mo, in [0, N) */
    hd_angle_t offset;       /* last predicted offset (motor / N - output) */
    hd_angle_t est;          /* last motor-side output estimate mo - offset */
    int64_t    corr;         /* dual loop: low-passed pos_out - est, 2^-48 turn */
    hd_angle_t pos_fb;       /* last loop position feedback */
    int64_t    bias;         /* entry bias (fading), 2^-48 turn */
    uint32_t   primed;       /* 0 until the first hd_fb_step after an entry */
} hd_fb_t;

/** Config: kind (hd_fb_config_t), gear ratio 1 <= n < 2^16, dual-loop crossover fc (Q16 Hz, > 0).
 *  0 ok, -1 bad (cfg untouched). */
int32_t hd_fb_design(hd_fb_cfg_t *c, int32_t kind, int32_t n, int32_t dual_fc_q16);
/** Restart the motor-side tracking at pos_mot, offset 0, the
 *  feedback at pos_out.  At power-up and when kind or N change. */
void hd_fb_reset(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_mot, hd_angle_t pos_out);
/** Once per period (semi-closed and dual-loop): advance mo by the motor step since
 *  the last call (|step| < 2^31 per period; a larger one restarts the tracking). */
void hd_fb_motor(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_mot);
/** Entering a closed-loop mode: the position at which the references start so that
 *  the first position error is 0 (full closed: pos_out; semi-closed: the estimate with
 *  the last offset; dual-loop: pos_out, the blend state set to match).  Sets pos_fb. */
hd_angle_t hd_fb_enter(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_out);
/** Where hd_fb_enter() would start the references now (no state change). */
hd_angle_t hd_fb_entry_position(const hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_out);
/** The loop's position feedback of this period from the output encoder and the
 *  predicted offset (Q32.32 turns). */
hd_angle_t hd_fb_step(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_out, hd_angle_t offset);

#endif
