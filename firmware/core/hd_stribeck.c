/* hd_stribeck.c - Stribeck friction feed-forward (contract: hd_stribeck.h). */
#include "hd_stribeck.h"
#include "hd_fixed.h"

/* x = r^delta in Q16 from r = |v|/vs in Q8.24, then exp(-x) in Q30 */
static int32_t shape_from_r24(int32_t r24, uint32_t delta)
{
    int32_t x16;
    if (delta == 1u) {
        x16 = hdf_asr32_rnd((int64_t)r24, 8u);
    } else {
        x16 = hdf_mul_q(r24, r24, 32u);               /* Q24*Q24 -> Q16 */
    }
    return hd_exp_neg_q16(x16);
}

int32_t hd_stribeck_shape_q30(int32_t v, int32_t vs, uint32_t delta)
{
    if (vs <= 0) {
        return 0;
    }
    return shape_from_r24(hd_div_q(hdf_abs_sat(v), vs, 24u), delta);   /* |v|/vs, Q8.24, saturated */
}

int32_t hd_stribeck_g(const hd_stribeck_dir_t *p, uint32_t delta, int32_t v)
{
    const int32_t e = hd_stribeck_shape_q30(v, p->vs, delta);
    const int32_t dfs = hdf_sub_sat(p->fs, p->fc);
    return hdf_add_sat(p->fc, hdf_mul_q(dfs, e, 30u));
}

int32_t hd_stribeck_shape_inv_q30(int32_t v, int32_t vs, uint32_t delta, const hd_divinv_t *inv_vs)
{
    if (vs <= 0) {
        return 0;
    }
    /* hd_div_q(|v|, vs, 24): round(|v| 2^24 / vs) (|v| 2^24 < 2^55), saturated to int32 */
    return shape_from_r24(hdf_sat32(hd_divinv_rnd((int64_t)hdf_abs_sat(v) * 16777216, inv_vs)), delta);
}

int32_t hd_stribeck_g_inv(const hd_stribeck_dir_t *p, uint32_t delta, int32_t v, const hd_divinv_t *inv_vs)
{
    const int32_t e = hd_stribeck_shape_inv_q30(v, p->vs, delta, inv_vs);
    return hdf_add_sat(p->fc, hdf_mul_q(hdf_sub_sat(p->fs, p->fc), e, 30u));
}

void hd_stribeck_recip(hd_stribeck_recip_t *r, int32_t vs)
{
    r->vs = vs;
    if (vs <= 0) {
        r->m = 0u;
        r->sh = 31u;
        return;
    }
    /* sh = 31 + floor(log2 vs) (31..61): 2^sh / vs in (2^30, 2^31], exact rounding */
    r->sh = 31u + (31u - (uint32_t)__builtin_clz((uint32_t)vs));
    r->m = (uint32_t)hd_div64_rnd((int64_t)1 << r->sh, (int64_t)vs);
}

int32_t hd_stribeck_shape_recip_q30(int32_t v, const hd_stribeck_recip_t *r, uint32_t delta)
{
    uint64_t prod;
    uint32_t s;
    if (r->vs <= 0) {
        return 0;
    }
    /* r24 = round(|v| m / 2^(sh - 24)), sh - 24 in [7, 37]; |v| m < 2^62 */
    prod = (uint64_t)(uint32_t)hdf_abs_sat(v) * (uint64_t)r->m;
    s = r->sh - 24u;
    prod = (prod + ((uint64_t)1 << (s - 1u))) >> s;
    return shape_from_r24((prod > (uint64_t)INT32_MAX) ? INT32_MAX : (int32_t)prod, delta);
}

/* the map with the reciprocals of both directions and smooth-sign width eps (0 = hard sign) */
static int32_t map_recip(const hd_stribeck_cfg_t *c, const hd_stribeck_recip_t *rp,
                         const hd_stribeck_recip_t *rn, int32_t v, int32_t eps)
{
    const hd_stribeck_dir_t *p = (v >= 0) ? &c->pos : &c->neg;
    const int32_t e = hd_stribeck_shape_recip_q30(v, (v >= 0) ? rp : rn, c->delta);
    const int32_t g = hdf_add_sat(p->fc, hdf_mul_q(hdf_sub_sat(p->fs, p->fc), e, 30u));
    const int32_t sg = hd_sign_smooth_q30(v, eps);
    const int32_t coul = hdf_mul_q(sg, g, 30u);
    const int32_t visc = hdf_mul_q(p->fv, v, 32u);    /* Q16 * 2^-32 turn/s -> Q16 */
    return hdf_add_sat(coul, visc);
}

int32_t hd_stribeck_map(const hd_stribeck_cfg_t *c, int32_t v)
{
    hd_stribeck_recip_t r;
    hd_stribeck_recip(&r, (v >= 0) ? c->pos.vs : c->neg.vs);
    return map_recip(c, &r, &r, v, c->eps_v);
}

void hd_stribeck_init(hd_stribeck_t *s, uint32_t ramp_ticks, bool enabled)
{
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    s->v = 0;
    s->tau_raw = 0;
    s->tau = 0;
    s->v_anchor = 0;
    s->cruise_n = 0u;
    s->cruise = 0u;
    s->steady = 0u;
    s->v_steady = 0;
    hd_stribeck_recip(&s->rp, 0);
    hd_stribeck_recip(&s->rn, 0);
}

void hd_stribeck_set_enabled(hd_stribeck_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

int32_t hd_stribeck_step(hd_stribeck_t *s, const hd_stribeck_cfg_t *c,
                         hd_vel_out_t v_ref, hd_vel_out_t v_est)
{
    int32_t w = hdf_clamp32(c->w_ref, 0, HD_Q30_ONE);
    /* v = v_est + w (v_ref - v_est), int64 difference: no overflow */
    const int64_t dv = (int64_t)v_ref - (int64_t)v_est;
    const int32_t tmax = (c->tau_max > 0) ? c->tau_max : INT32_MAX;

    /* cruise: v_ref non-zero, of the anchor's sign and within HD_STRIBECK_CRUISE_DV of the anchor
     * (v_ref at the start of the run).  Against the anchor, not the last period: a slow sinusoid
     * changes by a few LSB per period near its peak and would pass a per-period test there */
    if (c->cruise_ticks > 0u) {
        const int64_t dev = (int64_t)v_ref - (int64_t)s->v_anchor;
        const bool same = ((v_ref > 0) && (s->v_anchor > 0)) || ((v_ref < 0) && (s->v_anchor < 0));
        if (same && dev <= HD_STRIBECK_CRUISE_DV && dev >= -HD_STRIBECK_CRUISE_DV) {
            if (s->cruise_n < c->cruise_ticks) {
                s->cruise_n++;
            }
        } else {
            s->cruise_n = 0u;
            s->v_anchor = v_ref;            /* a new run starts here */
        }
        s->cruise = (s->cruise_n >= c->cruise_ticks) ? 1u : 0u;
        if (s->cruise != 0u) {
            w = HD_Q30_ONE;
        }
    } else {
        s->cruise_n = 0u;
        s->cruise = 0u;
    }
    /* steady motion: |v_ref| >= steady_vs * vs_d, vs_d the Stribeck velocity of v_ref's direction
     * (int64: no overflow; Q16.16 product truncated - the threshold's last LSB does not matter).
     * It starts once the axis follows: v_est beyond the same threshold in v_ref's direction (after
     * a reversal or a start the axis is still stuck or sliding the old way, and the map stays on
     * the estimate); it lasts while the reference stays above the threshold in that direction,
     * whatever the measured velocity does, so a stick-slip of the axis around the moving reference
     * does not flip the friction sign.  Near rest and at reversals the measured velocity stays */
    {
        bool on = false;
        if ((c->steady_vs > 0) && (v_ref != 0)) {
            const int64_t vs_d = (v_ref > 0) ? (int64_t)c->pos.vs : (int64_t)c->neg.vs;
            const int64_t thr = vs_d * (int64_t)c->steady_vs;                /* Q16 of 2^-32 turn/s */
            const int64_t mag = (v_ref > 0) ? (int64_t)v_ref : -(int64_t)v_ref;
            const int64_t fol = (v_ref > 0) ? (int64_t)v_est : -(int64_t)v_est;   /* along v_ref */
            const bool same_run = (s->steady != 0u) && ((v_ref > 0) == (s->v_steady > 0));
            if ((vs_d > 0) && (mag * 65536 >= thr) && (same_run || (fol * 65536 >= thr))) {
                on = true;
            }
        }
        s->steady = on ? 1u : 0u;
        s->v_steady = on ? v_ref : 0;
        if (on) {
            w = HD_Q30_ONE;
        }
    }
    /* reciprocals of vs: recomputed only when the parameter changed */
    if (s->rp.vs != c->pos.vs) {
        hd_stribeck_recip(&s->rp, c->pos.vs);
    }
    if (s->rn.vs != c->neg.vs) {
        hd_stribeck_recip(&s->rn, c->neg.vs);
    }
    /* w = 1 (the default, and every cruise) or 0: the blend is v_ref or v_est itself, exactly */
    if (w == HD_Q30_ONE) {
        s->v = v_ref;
    } else if (w == 0) {
        s->v = v_est;
    } else {
        s->v = hdf_sat32((int64_t)v_est + hdf_mul64x32_q(dv, w, 30u));
    }
    /* in a cruise v = v_ref keeps its sign: full sign (no smooth-sign reduction at slow rates) */
    s->tau_raw = hdf_clamp32(map_recip(c, &s->rp, &s->rn, s->v, (s->cruise != 0u) ? 0 : c->eps_v), -tmax, tmax);
    (void)hd_blend_update(&s->blend);
    s->tau = hd_blend_apply(&s->blend, s->tau_raw);
    return s->tau;
}
