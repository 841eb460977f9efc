/* hd_stribeck.c - Stribeck friction feed-forward (contract: hd_stribeck.h). */
#include "hd_stribeck.h"
#include "hd_fixed.h"

int32_t hd_stribeck_shape_q30(int32_t v, int32_t vs, uint32_t delta)
{
    int32_t r24;
    int32_t x16;

    if (vs <= 0) {
        return 0;
    }
    r24 = hd_div_q(hdf_abs_sat(v), vs, 24u);          /* |v|/vs, Q8.24, saturated */
    if (delta == 1u) {
        x16 = hdf_asr32_rnd((int64_t)r24, 8u);
    } else {
        x16 = hdf_mul_q(r24, r24, 32u);               /* Q24*Q24 -> Q16 */
    }
    return hd_exp_neg_q16(x16);
}

int32_t hd_stribeck_g(const hd_stribeck_dir_t *p, uint32_t delta, int32_t v)
{
    const int32_t e = hd_stribeck_shape_q30(v, p->vs, delta);
    const int32_t dfs = hdf_sub_sat(p->fs, p->fc);
    return hdf_add_sat(p->fc, hdf_mul_q(dfs, e, 30u));
}

int32_t hd_stribeck_map(const hd_stribeck_cfg_t *c, int32_t v)
{
    const hd_stribeck_dir_t *p = (v >= 0) ? &c->pos : &c->neg;
    const int32_t g = hd_stribeck_g(p, c->delta, v);
    const int32_t sg = hd_sign_smooth_q30(v, c->eps_v);
    const int32_t coul = hdf_mul_q(sg, g, 30u);
    const int32_t visc = hdf_mul_q(p->fv, v, 32u);    /* Q16 * 2^-32 turn/s -> Q16 */
    return hdf_add_sat(coul, visc);
}

void hd_stribeck_init(hd_stribeck_t *s, uint32_t ramp_ticks, bool enabled)
{
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    s->v = 0;
    s->tau_raw = 0;
    s->tau = 0;
}

void hd_stribeck_set_enabled(hd_stribeck_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

int32_t hd_stribeck_step(hd_stribeck_t *s, const hd_stribeck_cfg_t *c,
                         hd_vel_out_t v_ref, hd_vel_out_t v_est)
{
    const int32_t w = hdf_clamp32(c->w_ref, 0, HD_Q30_ONE);
    /* v = v_est + w (v_ref - v_est), int64 difference: no overflow */
    const int64_t dv = (int64_t)v_ref - (int64_t)v_est;
    const int32_t tmax = (c->tau_max > 0) ? c->tau_max : INT32_MAX;

    s->v = hdf_sat32((int64_t)v_est + hdf_mul64x32_q(dv, w, 30u));
    s->tau_raw = hdf_clamp32(hd_stribeck_map(c, s->v), -tmax, tmax);
    (void)hd_blend_update(&s->blend);
    s->tau = hd_blend_apply(&s->blend, s->tau_raw);
    return s->tau;
}
