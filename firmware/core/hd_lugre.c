/* hd_lugre.c - LuGre friction observer (contract: hd_lugre.h). */
#include "hd_lugre.h"
#include "hd_fixed.h"

void hd_lugre_init(hd_lugre_t *s, uint32_t ramp_ticks, bool enabled)
{
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    s->z = 0;
    s->dz = 0;
    s->tau_raw = 0;
    s->tau = 0;
    s->v = 0;
    s->g = 1;
    s->zss = 0;
    s->em1 = 0;
    hd_divinv_init(&s->inv_sigma0, 0u);
    hd_divinv_init(&s->inv_vs, 0u);
}

void hd_lugre_set_enabled(hd_lugre_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

/* Normalise m > 0 so that bit 62 is its top bit; returns the left shift (0 if
 * bit 63 is set or m == 0).  One count-leading-zeros instead of a 6-step search
 * (same shift: 62 - the top bit's position). */
static uint32_t hd__norm62(uint64_t *m)
{
    const uint32_t hi = (uint32_t)(*m >> 32);
    const uint32_t lo = (uint32_t)*m;
    uint32_t lz;
    if (*m == 0u) {
        return 0u;
    }
    lz = (hi != 0u) ? (uint32_t)__builtin_clz(hi) : (32u + (uint32_t)__builtin_clz(lo));
    if (lz == 0u) {
        return 0u;
    }
    *m <<= (lz - 1u);
    return lz - 1u;
}

/*
 * 1 - exp(-a) in Q46 for a = num / (den * 2^24) (num, den > 0), i.e.
 * a = sigma0_Q8 |v|_Q32 / (g_Q16 f_s 2^24).  Full relative precision for
 * small a (slow motion, where the per-period bristle change is tiny):
 *   a < 2^-6:  a - a^2/2 + a^3/6 - a^4/24          (truncation < 1e-11 relative)
 *   a >= 2^-6: 1 - exp(-a_hi) (1 - a_lo)             a_hi = a rounded down to Q16
 *              (hd_exp_neg_q16), a_lo < 2^-16 the rest (error a_lo^2/2 < 1.2e-10)
 */
static int64_t hd__one_minus_exp_q46(uint64_t num, uint64_t den)
{
    const uint32_t sh = hd__norm62(&num);
    const uint64_t q = (num + den / 2u) / den;           /* a * 2^(24 + sh), rounded */
    uint64_t a46;
    int64_t em1;

    if (24u + sh >= 46u) {
        const uint32_t r = 24u + sh - 46u;
        a46 = (r == 0u) ? q : ((q >> r) + ((q >> (r - 1u)) & 1u));
    } else {
        const uint32_t l = 46u - 24u - sh;
        a46 = (q >= ((uint64_t)1 << (51u - l))) ? ((uint64_t)1 << 51) : (q << l);
    }
    if (a46 >= ((uint64_t)32u << 46)) {
        return (int64_t)1 << 46;                         /* exp(-32) < 2^-46 */
    }
    if (a46 < ((uint64_t)1 << 40)) {
        const uint64_t a32 = a46 >> 14;                  /* Q32, < 2^26 */
        const uint64_t a2 = (a32 * a32) >> 18;           /* Q46 */
        const uint64_t a3 = ((a2 >> 8) * a32) >> 24;     /* Q46 */
        const uint64_t a4 = ((a3 >> 8) * a32) >> 24;     /* Q46 */
        em1 = (int64_t)(a46 - a2 / 2u + a3 / 6u - a4 / 24u);
    } else {
        const int32_t e30 = hd_exp_neg_q16((int32_t)(a46 >> 30));
        const uint64_t alo = a46 & 0x3FFFFFFFu;          /* Q46, < 2^30 */
        const uint64_t e46 = (uint64_t)e30 << 16;
        const uint64_t corr = ((uint64_t)e30 * alo + ((uint64_t)1 << 29)) >> 30;
        em1 = ((int64_t)1 << 46) - (int64_t)(e46 - corr);
    }
    return em1;
}

/* x * m / 2^46 for m in [0, 2^46], rounded (two 64x32 products). */
static int64_t hd__mul_q46(int64_t x, int64_t m)
{
    const int32_t hi = (int32_t)(m >> 23);               /* < 2^24 */
    const int32_t lo = (int32_t)(m & 0x7FFFFF);
    return hdf_add64_sat(hdf_mul64x32_q(x, hi, 23u), hdf_mul64x32_q(x, lo, 46u));
}

int32_t hd_lugre_step(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v, hd_angle_t e)
{
    return hd_lugre_step_n(s, c, v, e, 1u);
}

int32_t hd_lugre_step_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v, hd_angle_t e, uint32_t n)
{
    hd_lugre_prep_n(s, c, v, n);
    return hd_lugre_finish_n(s, c, e, n);
}

void hd_lugre_prep_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v, uint32_t n)
{
    hd_lugre_prep_g(s, c, v);
    hd_lugre_prep_exp_n(s, c, n);
}

void hd_lugre_prep_g(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_vel_out_t v)
{
    const int32_t sigma0 = (c->sigma0 > 0) ? c->sigma0 : 1;
    int32_t g;

    /* reciprocals of the parameters: recomputed only when one changed */
    if (s->inv_sigma0.d != (uint32_t)sigma0) {
        hd_divinv_init(&s->inv_sigma0, (uint32_t)sigma0);
    }
    if (c->g.vs > 0 && s->inv_vs.d != (uint32_t)c->g.vs) {
        hd_divinv_init(&s->inv_vs, (uint32_t)c->g.vs);
    }
    g = hd_stribeck_g_inv(&c->g, c->delta, v, &s->inv_vs);

    if (g < 1) {
        g = 1;
    }
    s->v = v;
    s->g = g;
    s->zss = 0;
    if (v != 0) {
        /* z_ss = g / sigma0 in Q48: g_Q16 * 2^40 / sigma0_Q8 */
        const int64_t zmag = hd_divinv_rnd(hdf_shl64_sat((int64_t)g, 40u), &s->inv_sigma0);
        s->zss = (v > 0) ? zmag : -zmag;
    }
}

void hd_lugre_prep_exp_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, uint32_t n)
{
    /* the step's rate f_s / n (n divides HD_LOOP_HZ: checked by the caller's constant) */
    const uint32_t rate = (n > 1u) ? (uint32_t)HD_LOOP_HZ / n : (uint32_t)HD_LOOP_HZ;
    const int32_t sigma0 = (c->sigma0 > 0) ? c->sigma0 : 1;
    s->em1 = 0;
    if (s->v != 0) {
        /* a = sigma0 |v| T / g = sigma0_Q8 |v| / (g_Q16 f_s 2^24) */
        const uint64_t num = (uint64_t)sigma0 * (uint64_t)hdf_abs_sat(s->v);  /* < 2^62 */
        const uint64_t den = (uint64_t)s->g * (uint64_t)rate;
        s->em1 = hd__one_minus_exp_q46(num, den);
    }
}

int32_t hd_lugre_finish_n(hd_lugre_t *s, const hd_lugre_cfg_t *c, hd_angle_t e, uint32_t n)
{
    const uint32_t rate = (n > 1u) ? (uint32_t)HD_LOOP_HZ / n : (uint32_t)HD_LOOP_HZ;
    const int32_t sigma0 = (c->sigma0 > 0) ? c->sigma0 : 1;
    const int32_t tmax = (c->tau_max > 0) ? c->tau_max : INT32_MAX;
    int64_t z1 = s->z;
    int64_t t;

    if (s->v != 0) {
        /* z' = z + (z_ss - z) (1 - exp(-a)) */
        z1 = hdf_add64_sat(s->z, hd__mul_q46(hdf_sub64_sat(s->zss, s->z), s->em1));
    }
    if (c->k_obs != 0 && e != 0) {
        /* k T e in Q48: k_Q16 * e_Q32 / rate */
        const int64_t ke = hdf_mul64x32_q(e, c->k_obs, 0u);
        z1 = hdf_sub64_sat(z1, hdf_div64_rnd_u16(ke, rate));
    }
    s->dz = hdf_sub64_sat(z1, s->z);
    s->z = z1;

    /* F = sigma0 z + sigma1 dz/T + sigma2 v, each rounded once to Q16 */
    t = hdf_mul64x32_q(z1, sigma0, 40u);                                    /* Q48*Q8 -> Q16 */
    t = hdf_add64_sat(t, hdf_mul64x32_q(hdf_mul64x32_q(s->dz, (int32_t)rate, 0u), c->sigma1, 48u));
    t = hdf_add64_sat(t, (int64_t)hdf_mul_q(c->sigma2, s->v, 32u));
    s->tau_raw = hdf_clamp32(hdf_sat32(t), -tmax, tmax);
    (void)hd_blend_update(&s->blend);
    s->tau = hd_blend_apply(&s->blend, s->tau_raw);
    return s->tau;
}
