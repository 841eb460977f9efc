/*
 * hd_vel_observer.c - type-2 tracking observer (formats: see hd_vel_observer.h).
 */
#include "hd_vel_observer.h"
#include "hd_fixed.h"

/* T = 1e-4 s in Q44: 2^44 / 10000 = 1759218604.4416 -> 1759218604 (rel. error 2.5e-10;
 * the loop closes on the measurement, so this only scales the gains by that much). */
#define HD_VELOBS_T_Q44 1759218604
#define HD_VELOBS_T_SHIFT 44u

void hd_velobs_reset(hd_velobs_t *s, hd_angle_t theta)
{
    s->theta = theta;
    s->frac = 0;
    s->vel = 0;
    s->err = 0;
}

void hd_velobs_step(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas)
{
    /* error against the full-precision estimate (theta + frac), 2^-48 turn */
    int64_t e48;
    if (theta_meas > -(INT64_C(1) << 46) && theta_meas < (INT64_C(1) << 46) &&
        s->theta > -(INT64_C(1) << 46) && s->theta < (INT64_C(1) << 46)) {
        /* |angles| < 2^46 turn * 2^-32: nothing below saturates, the same value directly */
        e48 = (theta_meas - s->theta) * 65536 - (int64_t)s->frac;
    } else {
        e48 = hdf_sub64_sat(hdf_sub64_sat(hdf_shl64_sat(theta_meas, 16u), hdf_shl64_sat(s->theta, 16u)),
                           (int64_t)s->frac);
    }
    s->err = hdf_asr32_rnd(e48, 16u);
    /* vel [2^-48 turn/s] += (Ki T)[Q16 1/s] * e [2^-48 turn] / 2^16 */
    s->vel = hdf_add64_sat(s->vel, hdf_mul64x32_q(e48, c->ki_dt, 16u));
    /* angle advance in 2^-48 turn: T * vel + (Kp T) * e */
    int64_t adv = hdf_mul64x32_q(s->vel, HD_VELOBS_T_Q44, HD_VELOBS_T_SHIFT);
    adv = hdf_add64_sat(adv, hdf_mul64x32_q(e48, c->kp_dt, 16u));
    adv = hdf_add64_sat(adv, (int64_t)s->frac);
    const int64_t whole = hdf_asr64_floor(adv, 16u);
    s->frac = (int32_t)(adv - whole * 65536);
    s->theta = hdf_add64_sat(s->theta, whole);
}

hd_vel_out_t hd_velobs_vel_out(const hd_velobs_t *s)
{
    return hdf_asr32_rnd(s->vel, 16u);
}

int64_t hd_velobs_vel48(const hd_velobs_t *s)
{
    return s->vel;
}

void hd_velobs_design(hd_velobs_cfg_t *c, int32_t w_q16, int32_t zeta_q16)
{
    /* kp_dt (Q16) = 2 zeta w T ; ki_dt (Q16) = w^2 T.  T = 1/HD_LOOP_HZ. */
    const int64_t two_zw_q16 = 2 * (int64_t)hdf_mul_q(zeta_q16, w_q16, 16u);
    c->kp_dt = hdf_sat32(hd_div64_rnd(two_zw_q16, HD_LOOP_HZ));
    const int64_t w2_q16 = hdf_mul64x32_q((int64_t)w_q16, w_q16, 16u);
    c->ki_dt = hdf_sat32(hd_div64_rnd(w2_q16, HD_LOOP_HZ));
}
