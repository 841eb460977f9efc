/* hd_backstep.c - adaptive backstepping position controller (contract: hd_backstep.h).
 *
 * Range analysis of the law's parameter terms (phi^T theta_hat, every period):
 *   theta_hat_i is clamped to [th_min_i, th_max_i] 2^32 (Q16.48, the bounds int32 Q15.16),
 *   so th_q16_i = round(theta_hat_i / 2^32) lies in [th_min_i, th_max_i]: an int32 Q15.16
 *   (|rounding error| <= 2^-17 N.m, half an LSB of the output).
 *   phi_0 = s(w), phi_1 = shape s(w): |.| <= 2^30 (Q30); phi_2 = w / 4: |.| <= 2^29.
 *   Each product th_q16_i phi_i (Q15.16 x Q30 = Q46) is below 2^31 2^30 = 2^61 in
 *   magnitude, the sum of the three below 3 2^61 < 2^63: exact in an int64 (three SMLALs
 *   on the Cortex-M4), rounded once to Q15.16 (|result| < 2^33, then added with
 *   saturation).  phi_3 = 1: th_q16_3 itself.  Against the Q16.48 products rounded one by
 *   one (the earlier form) the law's output differs by at most 2 LSB (3e-5 N.m).
 *   The estimates change only at init, preload and adaptation: th_q16 is formed there,
 *   so the held ticks of the schedule (hd_sched.h) do no 64 x 32-bit products. */
#include "hd_backstep.h"
#include "hd_fixed.h"
#include "hd_stribeck.h"

static int64_t hd__th_lo(const hd_backstep_cfg_t *c, uint32_t i)
{
    return (int64_t)c->th_min[i] * ((int64_t)1 << 32);
}

static int64_t hd__th_hi(const hd_backstep_cfg_t *c, uint32_t i)
{
    const int64_t hi = (int64_t)c->th_max[i] * ((int64_t)1 << 32);
    const int64_t lo = hd__th_lo(c, i);
    return (hi < lo) ? lo : hi;
}

/* th_q16 of the present estimates (range analysis at the top: each fits an int32) */
static void hd__th_round(hd_backstep_t *s)
{
    uint32_t i;
    for (i = 0; i < HD_BS_NP; i++) {
        s->th_q16[i] = hdf_asr32_rnd(s->th[i], 32u);
    }
}

/* Projection of parameter i onto its box; moving: the axis can stick (hd__wide).
 * While it can, T_load's box (i = 3) is the configured one widened on both sides
 * by the largest static friction the friction boxes admit, th_max_0 + th_max_1 (Fc + (Fs - Fc)).
 * Why: when the axis sticks at a reversal the friction regressor's sign s(omega) is about 0
 * (omega is noise about 0), so the static friction the axis must break shows up in e2 and only
 * T_load's integral can supply it; the parameter T_load stands for is then the load plus up to
 * Fs.  A box sized for the load alone clamps T_load whenever the load is comparable with the
 * breakaway (an unbalance that appears): the position error grows until the law's e1 terms
 * break the axis away (a reversal peak twice the nominal one), and with a small friction model
 * the cascade winds up into a torque-saturation fault.  At rest (omega_d = 0) the configured
 * box stays: there T_load is the hold's integral action, and a wider box lets it hunt against
 * the static friction (measured: final errors of 20-110 arcsec after point-to-point moves).
 * Above 4 w_s the axis slides and cannot stick; there the wider box would only let T_load wind
 * up on the rigid model's mismatch during fast moves (measured: positioning A 0.33 instead of
 * 0.19 arcsec under a friction drift).  The widening follows the reason it exists, the
 * regressor's sign about 0 at a stuck axis: while the reference cruises the regressor takes the
 * reference's sign and its friction terms carry the breakaway, and an axis moving faster than
 * w_s slides.  In both, T_load, the law's 25 Hz integral on e2, would only swing through the
 * widened box (up to 6 Fs of the model wide): on the CSF-17-50 axis a 20 Hz limit cycle of
 * +-1000 arcsec at the 0.01 deg/s sinusoid, and 4-25x the gyro mode's stabilisation error. */
static bool hd__cruise(int32_t wd_prev, const hd_backstep_in_t *in);

/* the axis can stick: the reference moves at most 4 w_s fast and does not cruise (the regressor
 * takes the axis' velocity), and the axis moves at most w_s fast */
static bool hd__wide(const hd_backstep_cfg_t *c, int32_t wd_prev, const hd_backstep_in_t *in)
{
    const int64_t ws4 = 4 * (int64_t)c->w_s;
    const int64_t a = (in->omega_d < 0) ? -(int64_t)in->omega_d : (int64_t)in->omega_d;
    const int64_t b = (in->omega < 0) ? -(int64_t)in->omega : (int64_t)in->omega;
    return (in->omega_d != 0) && (a <= ws4) && (b <= (int64_t)c->w_s) && !hd__cruise(wd_prev, in);
}

static int64_t hd__project(const hd_backstep_cfg_t *c, uint32_t i, int64_t v, bool moving)
{
    int64_t lo = hd__th_lo(c, i);
    int64_t hi = hd__th_hi(c, i);
    if (i == 3u && moving) {
        /* the sum of two Q15.16 bounds is < 2^32; in Q48 it may exceed int64: saturated */
        const int64_t fs = hdf_shl64_sat((int64_t)((c->th_max[0] > 0) ? c->th_max[0] : 0) +
                                         (int64_t)((c->th_max[1] > 0) ? c->th_max[1] : 0), 32u);
        lo = hdf_sub64_sat(lo, fs);
        hi = hdf_add64_sat(hi, fs);
    }
    return hdf_clamp64(v, lo, hi);
}

void hd_backstep_init(hd_backstep_t *s, const hd_backstep_cfg_t *c, const int32_t th0[HD_BS_NP],
                      uint32_t ramp_ticks, bool enabled)
{
    uint32_t i;
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    for (i = 0; i < HD_BS_NP; i++) {
        s->th[i] = hdf_clamp64((int64_t)th0[i] * ((int64_t)1 << 32), hd__th_lo(c, i), hd__th_hi(c, i));
        s->phi[i] = 0;
    }
    s->e1 = 0;
    s->e2 = 0;
    s->u_bs = 0;
    s->u = 0;
    s->saturated = 0u;
    s->shape = HD_Q30_ONE;
    s->wd_prev = 0;
    s->wide = 0u;
    hd_divinv_init(&s->inv_ws, 0u);
    hd__th_round(s);
}

/* the reciprocal of w_s, recomputed only when the parameter changed */
static void hd__inv_ws(hd_backstep_t *s, const hd_backstep_cfg_t *c)
{
    if (c->w_s > 0 && s->inv_ws.d != (uint32_t)c->w_s) {
        hd_divinv_init(&s->inv_ws, (uint32_t)c->w_s);
    }
}

void hd_backstep_set_enabled(hd_backstep_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

/* The Stribeck regressor's shape exp(-(omega / w_s)^2) in Q30, by the reciprocal when it
 * is set up for this w_s (the same value as the division) */
static int32_t hd__shape(const hd_divinv_t *inv_ws, const hd_backstep_cfg_t *c, hd_vel_out_t omega)
{
    return (c->w_s > 0 && inv_ws->d == (uint32_t)c->w_s) ? hd_stribeck_shape_inv_q30(omega, c->w_s, 2u, inv_ws)
                                                         : hd_stribeck_shape_q30(omega, c->w_s, 2u);
}

/* The velocity of the friction regressor: the reference velocity while the reference cruises
 * (moves at a constant velocity: unchanged within HD_BS_WD_STEADY since the last period), the
 * measured one otherwise (at rest, and while the reference accelerates or reverses: the axis
 * lags it and its own velocity says where the friction acts).  At slow rates the measured
 * velocity's noise flips its sign every few periods: the friction terms then average out, and
 * the load term T_load has to carry the friction as well as the load.  With an unbalance on top
 * that exceeds T_load's projection bound, the position error stays, the cascade's velocity PID
 * winds up and the drive trips on torque saturation. */
static bool hd__cruise(int32_t wd_prev, const hd_backstep_in_t *in)
{
    const int64_t dwd = (int64_t)in->omega_d - (int64_t)wd_prev;
    return (in->omega_d != 0) && (dwd <= HD_BS_WD_STEADY) && (dwd >= -HD_BS_WD_STEADY);
}

static int32_t hd__wr(int32_t wd_prev, const hd_backstep_in_t *in)
{
    return hd__cruise(wd_prev, in) ? in->omega_d : in->omega;
}

/* Errors, regressor (with the given Stribeck shape of hd__wr) and the law; fills e1, e2, phi. */
static int64_t hd__law(int32_t *e1o, int32_t *e2o, int32_t phi[HD_BS_NP], const int32_t th_q16[HD_BS_NP],
                       int32_t shape, int32_t wd_prev, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in)
{
    const int64_t e1max = (c->e1_max > 0) ? (int64_t)c->e1_max : (int64_t)INT32_MAX;
    const int32_t e1 = (int32_t)hdf_clamp64(hdf_sub64_sat(in->theta, in->theta_d), -e1max, e1max);
    const int32_t alpha1 = hdf_sub_sat(in->omega_d, hdf_mul_q(c->c1, e1, 16u));
    const int32_t e2 = hdf_sub_sat(in->omega, alpha1);
    const int32_t dalpha1 = hdf_sub_sat(in->acc_d, hdf_mul_q(c->c1, hdf_sub_sat(in->omega, in->omega_d), 24u));
    const int32_t wr = hd__wr(wd_prev, in);
    const int32_t sg = hd_sign_smooth_q30(wr, c->eps_w);
    int64_t u;
    int64_t ft;

    phi[0] = sg;
    phi[1] = hdf_mul_q(shape, sg, 30u);
    phi[2] = hdf_asr32_rnd((int64_t)wr, 2u);       /* 2^-32 turn/s -> Q30 turn/s */
    phi[3] = HD_Q30_ONE;
    /* J (alpha1' - c2 e2) - ke e1 */
    u = (int64_t)hdf_mul_q(c->j, hdf_sub_sat(dalpha1, hdf_mul_q(c->c2, e2, 24u)), 24u);
    u -= (int64_t)hdf_asr32_rnd((int64_t)c->ke * (int64_t)e1, 24u);
    /* phi^T theta_hat: the three products summed exactly in Q46, rounded once (range
     * analysis at the top of the file); phi_3 = 1.0: th_q16_3 itself */
    ft = (int64_t)th_q16[0] * phi[0];
    ft += (int64_t)th_q16[1] * phi[1];
    ft += (int64_t)th_q16[2] * phi[2];
    u = hdf_add64_sat(u, hdf_asr64_rnd(ft, 30u) + (int64_t)th_q16[3]);
    *e1o = e1;
    *e2o = e2;
    return u;
}

int32_t hd_backstep_law(const hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in)
{
    int32_t e1;
    int32_t e2;
    int32_t phi[HD_BS_NP];
    return hdf_sat32(hd__law(&e1, &e2, phi, s->th_q16, hd__shape(&s->inv_ws, c, hd__wr(s->wd_prev, in)), s->wd_prev, c, in));
}

void hd_backstep_preload(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in,
                         int32_t u_now)
{
    hd__inv_ws(s, c);
    s->shape = hd__shape(&s->inv_ws, c, hd__wr(s->wd_prev, in));
    const int64_t u = hd__law(&s->e1, &s->e2, s->phi, s->th_q16, s->shape, s->wd_prev, c, in);
    const int64_t du = hdf_sub64_sat((int64_t)u_now, u);              /* Q16; phi_3 = 1 */
    s->wide = hd__wide(c, s->wd_prev, in) ? 1u : 0u;
    s->th[3] = hd__project(c, 3u, hdf_add64_sat(s->th[3], hdf_shl64_sat(du, 32u)), s->wide != 0u);
    hd__th_round(s);
    s->u_bs = hdf_sat32(hd__law(&s->e1, &s->e2, s->phi, s->th_q16, s->shape, s->wd_prev, c, in));
    s->u = u_now;
}

int32_t hd_backstep_step(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in,
                         int32_t u_base)
{
    const int32_t umax = (c->u_max > 0) ? c->u_max : INT32_MAX;
    uint32_t i;
    hd__inv_ws(s, c);
    s->shape = hd__shape(&s->inv_ws, c, hd__wr(s->wd_prev, in));
    const int64_t u = hd__law(&s->e1, &s->e2, s->phi, s->th_q16, s->shape, s->wd_prev, c, in);

    s->u_bs = (int32_t)hdf_clamp64(u, -(int64_t)umax, (int64_t)umax);
    s->saturated = ((int64_t)s->u_bs != u) ? 1u : 0u;
    (void)hd_blend_update(&s->blend);
    s->u = hd_blend_mix(&s->blend, u_base, s->u_bs);
    s->wide = hd__wide(c, s->wd_prev, in) ? 1u : 0u;
    /* adaptation (for the next period): frozen while saturated or blended out */
    if (s->saturated == 0u && s->blend.w != 0) {
        for (i = 0; i < HD_BS_NP; i++) {
            const int32_t pe = hdf_mul_q(s->phi[i], s->e2, 30u);           /* 2^-32 turn/s */
            const int64_t d = hdf_asr64_rnd((int64_t)c->gamma_dt[i] * (int64_t)pe, 8u); /* Q48 */
            s->th[i] = hd__project(c, i, hdf_sub64_sat(s->th[i], d), s->wide != 0u);
        }
        hd__th_round(s);
    }
    s->wd_prev = in->omega_d;
    return s->u;
}

int32_t hd_backstep_step_held(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in,
                              int32_t u_base)
{
    const int32_t umax = (c->u_max > 0) ? c->u_max : INT32_MAX;
    const int64_t u = hd__law(&s->e1, &s->e2, s->phi, s->th_q16, s->shape, s->wd_prev, c, in);
    s->u_bs = (int32_t)hdf_clamp64(u, -(int64_t)umax, (int64_t)umax);
    s->saturated = ((int64_t)s->u_bs != u) ? 1u : 0u;
    (void)hd_blend_update(&s->blend);
    s->u = hd_blend_mix(&s->blend, u_base, s->u_bs);
    s->wd_prev = in->omega_d;
    return s->u;
}

void hd_backstep_regressor(hd_backstep_t *s, const hd_backstep_cfg_t *c, const hd_backstep_in_t *in)
{
    hd__inv_ws(s, c);
    s->shape = hd__shape(&s->inv_ws, c, hd__wr(s->wd_prev, in));
    s->wide = hd__wide(c, s->wd_prev, in) ? 1u : 0u;    /* T_load's box of this cycle's adaptation */
}

void hd_backstep_adapt(hd_backstep_t *s, const hd_backstep_cfg_t *c, uint32_t log2_n)
{
    uint32_t i;
    /* frozen while saturated or blended out, as in hd_backstep_step */
    if (s->saturated != 0u || s->blend.w == 0) {
        return;
    }
    for (i = 0; i < HD_BS_NP; i++) {
        /* 2^log2_n periods of gamma_dt: round(gamma_dt pe 2^log2_n / 2^8); |gamma_dt pe| < 2^62 */
        const int32_t pe = hdf_mul_q(s->phi[i], s->e2, 30u);
        const int64_t d = hdf_asr64_rnd((int64_t)c->gamma_dt[i] * (int64_t)pe, 8u - log2_n);
        s->th[i] = hd__project(c, i, hdf_sub64_sat(s->th[i], d), s->wide != 0u);   /* set by hd_backstep_regressor */
    }
    hd__th_round(s);
}
