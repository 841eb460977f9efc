/*
 * hd_vel_observer.c - type-2 tracking observer (formats: see hd_vel_observer.h).
 */
#include "hd_vel_observer.h"
#include "hd_fixed.h"

/* T = 1e-4 s in Q44: 2^44 / 10000 = 1759218604.4416 -> 1759218604 (rel. error 2.5e-10;
 * the loop closes on the measurement, so this only scales the gains by that much). */
#define HD_VELOBS_T_Q44 1759218604
#define HD_VELOBS_T_SHIFT 44u

/* the error's 32-bit form: 2^-36 turn, so int32 holds +-2^-5 turn (11.25 deg) */
#define HD_VELOBS_E_SHIFT 12u                         /* 2^-48 -> 2^-36 turn */
#define HD_VELOBS_E_UNIT (1 << (16u - HD_VELOBS_E_SHIFT))    /* 2^-32 turn in 2^-36 turn */
#define HD_VELOBS_E_HALF (1u << (HD_VELOBS_E_SHIFT - 1u))    /* the rounding offset */
#define HD_VELOBS_D_MAX ((INT64_C(1) << 27) - 1)      /* |d| clamp, 2^-32 turn */

void hd_velobs_step(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas)
{
    /* error against the estimate theta, 2^-32 turn */
    /* the saturating difference (ADDS/ADCS and the overflow flag on the M4): the plain
     * difference wherever that fits, so no range test of the angles is needed */
    const int64_t d = hdf_sub64_sat(theta_meas, s->theta);
    /* err = round(d - frac 2^-16) in 2^-32 turn: d, less one when frac > 1/2 (or is
     * 1/2 and d <= 0: the tie goes away from zero) */
    s->err = hdf_sub_sat(hdf_sat32(d), (s->frac > 32768 || (s->frac == 32768 && d <= 0)) ? 1 : 0);
    /* e = d - frac (2^-48 turn) in 2^-36 turn as an int32: |d| clamped to 2^27 - 1
     * (2^-5 turn; a larger error moves the estimate at that error's rate), so
     * |d 2^16 - frac| < 2^43 and the rounded e < 2^31 */
    /* in 32 bits: with x = dc 2^16 - frac and dc 2^16 a multiple of 2^12, round(x / 2^12)
     * (ties away from 0) = dc 2^4 + floor((2^11 - frac - [x < 0]) / 2^12), the floor taken
     * on the value + 2^16 (> 0, a logical shift: 0 .. 2^4) less 2^4; |dc| < 2^27, so
     * dc 2^4 - 2^4 and the sum stay within int32 */
    const int32_t dc = (int32_t)hdf_clamp64(d, -HD_VELOBS_D_MAX, HD_VELOBS_D_MAX);
    const uint32_t neg = (dc < 0 || (dc == 0 && s->frac > 0)) ? 1u : 0u;
    const int32_t e = (dc * HD_VELOBS_E_UNIT - HD_VELOBS_E_UNIT) +
        (int32_t)((HD_VELOBS_E_HALF + 65536u - (uint32_t)s->frac - neg) >> HD_VELOBS_E_SHIFT);
    /* vel [2^-48 turn/s] += (Ki T)[Q16 1/s] * e [2^-36 turn] / 2^4: a 32 x 32 product */
    s->vel = hdf_add64_sat(s->vel, hdf_asr64_rnd((int64_t)c->ki_dt * e, 16u - HD_VELOBS_E_SHIFT));
    /* angle advance in 2^-48 turn: T * vel + (Kp T) * e + frac (|(Kp T) e / 2^4| < 2^59) */
    int64_t adv = hdf_mul64x32_q(s->vel, HD_VELOBS_T_Q44, HD_VELOBS_T_SHIFT);
    adv = hdf_add64_sat(adv, hdf_asr64_rnd((int64_t)c->kp_dt * e, 16u - HD_VELOBS_E_SHIFT) + (int64_t)s->frac);
    const int64_t whole = hdf_asr64_floor(adv, 16u);
    s->frac = (int32_t)(adv - whole * 65536);
    s->theta = hdf_add64_sat(s->theta, whole);
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
