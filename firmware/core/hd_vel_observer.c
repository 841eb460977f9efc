/*
 * hd_vel_observer.c - type-2 tracking observer (formats: see hd_vel_observer.h).
 */
#include "hd_vel_observer.h"
#include "hd_fixed.h"

/* One period (the step's body is hd_velobs_step_inline, hd_vel_observer.h). */
void hd_velobs_step(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas)
{
    hd_velobs_step_inline(s, c, theta_meas);
}

void hd_velobs_reset(hd_velobs_t *s, hd_angle_t theta)
{
    s->theta = theta;
    s->frac = 0;
    s->vel = 0;
    s->err = 0;
}

void hd_velobs_start(hd_velobs_t *s, hd_angle_t theta, int64_t vel48)
{
    hd_velobs_reset(s, theta);
    s->vel = vel48;
}

hd_vel_out_t hd_velobs_vel_out(const hd_velobs_t *s)
{
    return hdf_asr32_rnd(s->vel, 16u);
}

void hd_velobs_design(hd_velobs_cfg_t *c, int32_t w_q16, int32_t zeta_q16)
{
    /* kp_dt (Q16) = 2 zeta w T ; ki_dt (Q16) = w^2 T.  T = 1/HD_LOOP_HZ. */
    const int64_t two_zw_q16 = 2 * (int64_t)hdf_mul_q(zeta_q16, w_q16, 16u);
    c->kp_dt = hdf_sat32(hd_div64_rnd(two_zw_q16, HD_LOOP_HZ));
    const int64_t w2_q16 = hdf_mul64x32_q((int64_t)w_q16, w_q16, 16u);
    c->ki_dt = hdf_sat32(hd_div64_rnd(w2_q16, HD_LOOP_HZ));
}
