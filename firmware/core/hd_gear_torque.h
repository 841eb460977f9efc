/*
 * hd_gear_torque.h - the torque the gear transmits, estimated from the motor side
 * while the motor slides, blended into the model estimate near standstill.
 *
 * Why: the gear's twist at a stop depends on its hysteresis branch, and the
 * branch is set by the last large torque swing of the move (the deceleration and
 * the resonance it excites).  A model estimate from the reference
 * (J_L a_ref + friction + unbalance) sees neither the resonance nor the true
 * size of the swing, so its hysteresis memory ends on the wrong branch.  The
 * motor side sees them: the gear passes the motor torque less the motor's own
 * friction and inertia torque,
 *
 *   T_motor = t_applied - f_motor - J_m,out a,     a = dv_fb / T_step
 *
 * (all output-referred).  At rest the motor's stiction holds an unknown share of
 * the command, so the estimate is used only while the reference moves faster than
 * the Stribeck velocity, and hands over linearly to the model estimate between
 * 2 v_s and v_s:
 *
 *   w = clamp((|v_ref| - v_s) / v_s, 0, 1),   T = T_model + w (T_motor - T_model)
 *
 * Formats (hd_units.h):
 *   t_applied, f_motor, t_model, result   Q15.16 N.m (output side)
 *   v_ref, v_fb, vs                       2^-32 turn/s (output side)
 *   jm                                    Q15.16 kg m^2 (N^2 J_m: motor inertia, output-referred)
 *   step_hz                               steps per second (the rate of hd_gear_torque_step)
 * The acceleration a = dv step_hz is formed in int64 (2^-32 turn/s^2), the inertia
 * torque 2 pi J a in int64 and saturated once.  The velocity memory is the only state;
 * the first step after a reset has no acceleration.
 */
#ifndef HD_GEAR_TORQUE_H
#define HD_GEAR_TORQUE_H

#include <stdint.h>
#include "hd_units.h"

typedef struct {
    int32_t jm;          /* Q15.16 kg m^2, >= 0 (0: no inertia term) */
    int32_t vs;          /* 2^-32 turn/s, > 0: the hand-over starts at 2 vs and ends at vs */
    int32_t step_hz;     /* calls per second, > 0 */
} hd_gear_torque_cfg_t;

typedef struct {
    hd_vel_out_t v_prev; /* velocity feedback of the last step */
    uint32_t primed;     /* 0: no last step (no acceleration yet) */
    int32_t  w;          /* last weight of the motor-side estimate, Q30 (telemetry) */
} hd_gear_torque_t;

/** Forget the velocity memory (loops reset). */
void hd_gear_torque_reset(hd_gear_torque_t *s);
/** One step: the blended estimate (Q15.16 N.m). */
int32_t hd_gear_torque_step(hd_gear_torque_t *s, const hd_gear_torque_cfg_t *c, int32_t t_applied, int32_t f_motor,
                            hd_vel_out_t v_ref, hd_vel_out_t v_fb, int32_t t_model);

#endif
