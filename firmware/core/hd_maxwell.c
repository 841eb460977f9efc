/* hd_maxwell.c - Maxwell-slip hysteresis (contract: hd_maxwell.h). */
#include "hd_maxwell.h"
#include "hd_fixed.h"

void hd_maxwell_init(hd_maxwell_t *s, uint32_t ramp_ticks, bool enabled)
{
    uint32_t i;
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    for (i = 0; i < HD_MAXWELL_N_MAX; i++) {
        s->s[i] = 0;
    }
    s->x_prev = 0;
    s->primed = 0u;
    s->tau_raw = 0;
    s->tau = 0;
    s->dth = 0;
}

void hd_maxwell_set_enabled(hd_maxwell_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

hd_angle_t hd_maxwell_step(hd_maxwell_t *s, const hd_maxwell_cfg_t *c, hd_angle_t x)
{
    const uint32_t n = (c->n < HD_MAXWELL_N_MAX) ? c->n : HD_MAXWELL_N_MAX;
    const int32_t tmax = (c->tau_max > 0) ? c->tau_max : INT32_MAX;
    /* input increment, saturated to +-0.5 turn per period (far beyond any rate) */
    const int32_t dx = s->primed ? hdf_sat32(hdf_sub64_sat(x, s->x_prev)) : 0;
    int64_t acc = 0;
    uint32_t i;

    for (i = 0; i < n; i++) {
        const int32_t d = (c->d[i] > 0) ? c->d[i] : 0;
        /* s_i + dx, clamped to the slip limit: the anchor follows beyond it.  In 32 bits:
         * 0 <= d <= INT32_MAX, so saturating the sum to int32 first changes nothing
         * after the clamp to [-d, d] */
        s->s[i] = hdf_clamp32(hdf_add_sat(s->s[i], dx), -d, d);
        acc = hdf_mac64(acc, c->k[i], s->s[i]);                     /* Q8 * Q32 = Q40 */
    }
    s->x_prev = x;
    s->primed = 1u;
    s->tau_raw = hdf_clamp32(hdf_asr32_rnd(acc, 24u), -tmax, tmax);   /* Q40 -> Q16 */
    (void)hd_blend_update(&s->blend);
    s->tau = hd_blend_apply(&s->blend, s->tau_raw);
    /* dth = F * compliance: Q16 * Q44 = Q60 -> Q32 */
    s->dth = hdf_mul64x32_q((int64_t)s->tau, c->compliance, 28u);
    return s->dth;
}
