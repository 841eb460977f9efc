/* hd_te_comp.c - transmission-error compensation (contract: hd_te_comp.h). */
#include "hd_te_comp.h"
#include "hd_fixed.h"

#define TE_TWO_PI_Q28   1686629713      /* round(2 pi 2^28) */

int64_t hd_te_model(const hd_te_cfg_t *c, hd_angle_t theta_m)
{
    const uint32_t n = (c->n < HD_TE_N_MAX) ? c->n : HD_TE_N_MAX;
    const uint32_t frac = (uint32_t)((uint64_t)theta_m & 0xFFFFFFFFu);  /* wraps, meant */
    int64_t acc = 0;
    uint32_t h;

    for (h = 0; h < n; h++) {
        const uint32_t ang = c->order[h] * frac + c->phase[h];          /* mod 1 turn */
        int32_t sn;
        int32_t cs;
        hd_sincos_turn_fast(ang, &sn, &cs);                             /* ~4e-8 of amp */
        acc = hdf_mac64(acc, c->amp[h], sn);                             /* 2^-32 turn * Q30 */
    }
    return hdf_asr64_rnd(acc, 30u);
}

void hd_te_cfg_ranges(hd_te_cfg_t *c)
{
    uint32_t h;
    c->fit32 = (c->n <= HD_TE_FIT32_N) ? 1u : 0u;
    for (h = 0; h < HD_TE_FIT32_N && h < c->n; h++) {
        if (c->amp[h] > HD_TE_FIT32_AMP || c->amp[h] < -HD_TE_FIT32_AMP || c->order[h] > HD_TE_FIT32_ORDER) {
            c->fit32 = 0u;
        }
    }
}

int64_t hd_te_model_slope(const hd_te_cfg_t *c, hd_angle_t theta_m, int32_t *slope)
{
    const uint32_t n = (c->n < HD_TE_N_MAX) ? c->n : HD_TE_N_MAX;
    const uint32_t frac = (uint32_t)((uint64_t)theta_m & 0xFFFFFFFFu);  /* wraps, meant */
    int64_t acc = 0;
    int64_t ds = 0;
    uint32_t h;

    if (c->fit32 != 0u) {
        /* within HD_TE_FIT32_* (hd_te_comp.h): the sums below cannot saturate, so these
         * are the words of the general loop, by SMLALs and an unsaturated read-out */
        for (h = 0; h < n; h++) {
            const uint32_t ang = c->order[h] * frac + c->phase[h];
            int32_t sn;
            int32_t cs;
            hd_sincos_turn_fast(ang, &sn, &cs);
            acc += (int64_t)c->amp[h] * (int64_t)sn;
            ds += (int64_t)(int32_t)c->order[h] * (int64_t)hdf_asr32_rnd_fit((int64_t)c->amp[h] * (int64_t)cs, 30u);
        }
        *slope = hdf_sat32(hdf_mul64x32_q(ds, TE_TWO_PI_Q28, 28u));
        return hdf_asr64_rnd(acc, 30u);
    }
    for (h = 0; h < n; h++) {
        const uint32_t ang = c->order[h] * frac + c->phase[h];          /* mod 1 turn */
        int32_t sn;
        int32_t cs;
        hd_sincos_turn_fast(ang, &sn, &cs);
        acc = hdf_mac64(acc, c->amp[h], sn);                             /* as hd_te_model */
        /* d/dtheta of amp sin(2 pi (order theta + phase)) = 2 pi order amp cos: the sum of
         * order amp cos here (|amp| < 2^31, order < 2^8 in practice: no overflow of int64) */
        ds = hdf_add64_sat(ds, (int64_t)c->order[h] * hdf_asr64_rnd((int64_t)c->amp[h] * (int64_t)cs, 30u));
    }
    *slope = hdf_sat32(hdf_mul64x32_q(ds, TE_TWO_PI_Q28, 28u));
    return hdf_asr64_rnd(acc, 30u);
}

void hd_te_comp_init(hd_te_comp_t *s, uint32_t ramp_ticks, bool enabled)
{
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    s->te = 0;
    s->dth = 0;
    s->tau = 0;
}

void hd_te_comp_set_enabled(hd_te_comp_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

hd_angle_t hd_te_comp_step(hd_te_comp_t *s, const hd_te_cfg_t *c, hd_angle_t theta_m)
{
    const int32_t tmax = (c->tau_max > 0) ? c->tau_max : INT32_MAX;
    int32_t tau;

    s->te = hd_te_model(c, theta_m);
    (void)hd_blend_update(&s->blend);
    s->dth = hd_blend_mix64(&s->blend, 0, hdf_neg64_sat(s->te));
    /* tau = -k1 * TE: Q8 * 2^-32 turn = Q40 -> Q16 */
    tau = hdf_clamp32(hdf_sat32(hdf_neg64_sat(hdf_mul64x32_q(s->te, c->k1, 24u))), -tmax, tmax);
    s->tau = hd_blend_apply(&s->blend, tau);
    return s->dth;
}

hd_angle_t hd_te_comp_step_slope(hd_te_comp_t *s, const hd_te_cfg_t *c, hd_angle_t theta_m, int32_t *slope_w)
{
    const int32_t tmax = (c->tau_max > 0) ? c->tau_max : INT32_MAX;
    int32_t slope;
    int32_t tau;

    s->te = hd_te_model_slope(c, theta_m, &slope);
    (void)hd_blend_update(&s->blend);
    s->dth = hd_blend_mix64(&s->blend, 0, hdf_neg64_sat(s->te));
    /* the correction is -w TE: its slope is -w dTE/dtheta */
    *slope_w = hdf_neg_sat(hd_blend_apply(&s->blend, slope));
    tau = hdf_clamp32(hdf_sat32(hdf_neg64_sat(hdf_mul64x32_q(s->te, c->k1, 24u))), -tmax, tmax);
    s->tau = hd_blend_apply(&s->blend, tau);
    return s->dth;
}
