/*
 * hd_gear_torque.c - motor-side transmitted-torque estimate (contract: hd_gear_torque.h).
 */
#include "hd_gear_torque.h"
#include "hd_fixed.h"

#define GT_TWO_PI_Q28   1686629713      /* round(2 pi 2^28) */

void hd_gear_torque_reset(hd_gear_torque_t *s)
{
    s->v_prev = 0;
    s->primed = 0u;
    s->w = 0;
}

/* w = clamp((|v| - vs) / vs, 0, 1) in Q30 */
static int32_t hand_over(const hd_gear_torque_cfg_t *c, hd_vel_out_t v_ref)
{
    const int64_t av = hdf_abs64_sat((int64_t)v_ref);
    const int64_t vs = (c->vs > 0) ? (int64_t)c->vs : 1;
    if (av >= 2 * vs) {
        return HD_Q30_ONE;
    }
    if (av <= vs) {
        return 0;
    }
    return (int32_t)(((av - vs) << 30) / vs);     /* (av - vs) < vs < 2^31: no overflow, < 2^30 */
}

int32_t hd_gear_torque_step(hd_gear_torque_t *s, const hd_gear_torque_cfg_t *c, int32_t t_applied, int32_t f_motor,
                            hd_vel_out_t v_ref, hd_vel_out_t v_fb, int32_t t_model)
{
    /* acceleration over the last step, 2^-32 turn/s^2 (int64: |dv| < 2^32, step_hz < 2^31) */
    const int64_t acc = (s->primed != 0u) ? ((int64_t)v_fb - (int64_t)s->v_prev) * (int64_t)c->step_hz : 0;
    /* J a: Q16 kg m^2 x 2^-32 turn/s^2 -> Q16 turn N.m (>> 32), x 2 pi (Q28) -> Q16 N.m */
    const int64_t ja = hdf_mul64x32_q(hdf_mul64x32_q(acc, c->jm, 32u), GT_TWO_PI_Q28, 28u);
    const int32_t t_mot = hdf_sat32(hdf_sub64_sat(hdf_sub64_sat((int64_t)t_applied, (int64_t)f_motor), ja));
    s->v_prev = v_fb;
    s->primed = 1u;
    s->w = hand_over(c, v_ref);
    return hdf_add_sat(t_model, hdf_mul_q(hdf_sub_sat(t_mot, t_model), s->w, 30u));
}
