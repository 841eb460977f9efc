/*
 * hd_stab.c - inertial stabilisation estimator (contract: hd_stab.h).
 */
#include "hd_stab.h"
#include "hd_fixed.h"

#define TWO_PI_Q28      1686629713   /* round(2 pi 2^28) */
#define RECIP_LOOP_Q44  1759218604   /* round(2^44 / HD_LOOP_HZ), HD_LOOP_HZ = 10000 */

/* S (2^-32 turn / HD_LOOP_HZ) -> 2^-32 turn, rounded (exact: the Q44 reciprocal
 * is used only where |x| < 2^40, where its 2.5e-10 relative error is < 0.5 LSB) */
static int64_t s_to_q32(int64_t x)
{
    if (x > -((int64_t)1 << 40) && x < ((int64_t)1 << 40)) {
        return hd_mul64x32_q(x, RECIP_LOOP_Q44, 44u);
    }
    return hd_div64_rnd(x, HD_LOOP_HZ);
}

/* Q32.32 turns -> S (exact, saturated) */
static int64_t q32_to_s(hd_angle_t p)
{
    return hd_mul64x32_q(p, HD_LOOP_HZ, 0u);
}

/* 2 pi f T in Q(q) for f in Hz Q16, q <= 44 (f_q16 >= 0) */
static int64_t wt_q(int32_t f_q16, uint32_t q)
{
    const int64_t w = (int64_t)f_q16 * (int64_t)TWO_PI_Q28;      /* Q44 rad/s, < 2^62 */
    return hd_div64_rnd(hd_asr64_rnd(w, 44u - q), HD_LOOP_HZ);
}

void hd_stab_design(hd_stab_cfg_t *c, int32_t bias, int32_t fc_q16, int32_t fr_q16, int32_t bias_max,
                    int32_t bw_q16, int32_t zeta_q16, int32_t ff_db)
{
    c->ff_db = (ff_db < 0) ? 0 : ff_db;
    c->bias = bias;
    if (fc_q16 <= 0) {
        c->blend_kp = 0;
        c->blend_ki = 0;
    } else {
        const int64_t w32 = wt_q(fc_q16, 32u);                     /* wc T, Q32 */
        c->blend_kp = hd_sat32(2 * wt_q(fc_q16, 40u));   /* 2 wc T, Q40 */
        c->blend_ki = hd_sat32(w32 * w32);                          /* (wc T)^2 2^64 */
        if (c->blend_kp <= 0) {
            c->blend_kp = 1;
        }
    }
    {
        const int64_t x = wt_q((fr_q16 > 0) ? fr_q16 : 0, 30u);     /* 2 pi fr T, Q30 */
        c->alpha = hd_sat32(x - hd_asr64_rnd(x * x, 31u));         /* 1 - exp(-x) ~ x - x^2/2 */
        if (c->alpha <= 0) {
            c->alpha = 1;
        }
    }
    c->bias_max = (bias_max < 0) ? 0 : bias_max;
    hd_velobs_design(&c->obs, hd_mul_q(bw_q16, TWO_PI_Q28, 28u), zeta_q16);
}

void hd_stab_init(hd_stab_t *s)
{
    s->ang = 0;
    s->ref = 0;
    s->r_f = 0;
    s->b_hat = 0;
    hd_velobs_reset(&s->obs, 0);
    s->err = 0;
    s->base_rate = 0;
    s->vff = 0;
    s->vff_db = 0;
    s->rate = 0;
}

static int32_t dead_band(int32_t v, int32_t db)
{
    if (v > db) {
        return v - db;
    }
    if (v < -db) {
        return v + db;
    }
    return 0;
}

static int32_t corrected_rate(const hd_stab_t *s, const hd_stab_cfg_t *c, hd_vel_out_t gyro)
{
    const int64_t bh = hd_asr64_rnd(s->b_hat, 32u);
    return hd_sat32((int64_t)gyro - (int64_t)c->bias - bh);
}

void hd_stab_start(hd_stab_t *s, const hd_stab_cfg_t *c, hd_angle_t pos_out, hd_vel_out_t gyro,
                   hd_vel_out_t v_rel)
{
    s->ang = q32_to_s(pos_out);
    s->ref = s->ang;
    s->r_f = 0;
    s->rate = corrected_rate(s, c, gyro);
    s->base_rate = hd_sub_sat(s->rate, v_rel);
    hd_velobs_reset(&s->obs, 0);
    s->obs.vel = hd_shl64_sat(s->base_rate, 16u);     /* 2^-48 turn/s: starts converged */
    s->err = 0;
    s->vff = hd_neg_sat(s->base_rate);
    s->vff_db = dead_band(s->vff, c->ff_db);
}

void hd_stab_step(hd_stab_t *s, const hd_stab_cfg_t *c, hd_vel_out_t gyro, hd_angle_t pos_out,
                  hd_vel_out_t rate_cmd)
{
    const int64_t pos_s = q32_to_s(pos_out);
    const int32_t g = corrected_rate(s, c, gyro);
    s->rate = g;
    s->ang = hd_add64_sat(s->ang, g);
    s->ref = hd_add64_sat(s->ref, rate_cmd);
    if (c->blend_kp != 0) {
        const int64_t r = hd_sub64_sat(pos_s, s->ang);
        const int64_t bmax = hd_shl64_sat(c->bias_max, 32u);
        s->r_f = hd_add64_sat(s->r_f, hd_mul64x32_q(hd_sub64_sat(r, s->r_f), c->alpha, 30u));
        s->ang = hd_add64_sat(s->ang, hd_mul64x32_q(s->r_f, c->blend_kp, 40u));
        s->b_hat = hd_clamp64(hd_sub64_sat(s->b_hat, hd_mul64x32_q(s->r_f, c->blend_ki, 32u)), -bmax, bmax);
    }
    hd_velobs_step(&s->obs, &c->obs, s_to_q32(hd_sub64_sat(s->ang, pos_s)));
    {
        /* full observer rate d(theta_hat)/dt = vel + Kp e: no lag at low frequency (the
         * integrator state alone lags by 2 zeta / w, 1.1 deg at 1 Hz with 100 Hz) */
        const int64_t kpe = hd_mul64x32_q((int64_t)s->obs.err * HD_LOOP_HZ, c->obs.kp_dt, 16u);
        s->base_rate = hd_sat32(hd_add64_sat(hd_asr64_rnd(s->obs.vel, 16u), kpe));
        /* the friction feed-forward takes the smoother integrator state */
        s->vff_db = dead_band(hd_sub_sat(rate_cmd, hd_velobs_vel_out(&s->obs)), c->ff_db);
    }
    s->err = hd_sat32(s_to_q32(hd_sub64_sat(s->ref, s->ang)));
    s->vff = hd_sub_sat(rate_cmd, s->base_rate);
}

hd_angle_t hd_stab_angle(const hd_stab_t *s)
{
    return s_to_q32(s->ang);
}
