/*
 * hd_pid.c - PID loop (formats: see hd_pid.h).
 */
#include "hd_pid.h"
#include "hd_fixed.h"

void hd_pid_reset(hd_pid_t *s)
{
    s->integ = 0;
    s->dfilt = 0;
    s->meas_prev = 0;
    s->p = 0;
    s->i = 0;
    s->d = 0;
    s->out = 0;
    s->saturated = 0;
    s->primed = 0;
}

void hd_pid_preload(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t out_i)
{
    int32_t v = hdf_clamp32(out_i, c->out_min, c->out_max);
    s->integ = hdf_shl64_sat((int64_t)v, c->shift);
    s->i = v;
}

/* The step with the gain shift as a parameter; hd_pid_step() calls it with the
 * shifts the drive uses (16, 32) as constants so each gets its own folded copy. */
HD_FX_INLINE int32_t pid_core(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff,
                           const uint32_t shift)
{
    const int32_t e = hdf_sub_sat(ref, meas);

    /* derivative on measurement, first-order filtered, in in-LSB * 2^16 per period */
    int64_t dmeas = 0;
    if (s->primed) {
        dmeas = (int64_t)meas - (int64_t)s->meas_prev;
    }
    s->meas_prev = meas;
    s->primed = 1;
    if (c->kd_fs == 0) {
        /* no D term: the filter is not needed, so it rests at 0 (a D gain switched on
         * later starts from a filter at rest, like a reset; the measurement history
         * above stays current, so there is no derivative kick either) */
        s->dfilt = 0;
    } else if (dmeas != 0 || s->dfilt != 0) {     /* else the update leaves dfilt at 0 exactly */
        /* |dmeas| < 2^32, so dmeas * 2^16 < 2^48: the saturating shift is the product */
        const int64_t target = dmeas * 65536;
        const int64_t diff = hdf_sub64_sat(target, s->dfilt);
        /* |diff| < 2^49 so the 64x32 product fits the helper's 96-bit intermediate */
        /* d_alpha == 1.0 (no filter): the product is diff itself, exactly */
        const int64_t step = (c->d_alpha == HD_Q30_ONE) ? diff : hdf_mul64x32_q(diff, c->d_alpha, 30);
        s->dfilt = hdf_add64_sat(s->dfilt, step);
    }

    const int32_t p = hdf_mul_q(c->kp, e, shift);
    /* kd_fs == 0 (no D term): the term is 0 */
    const int32_t d = (c->kd_fs == 0) ? 0
                      : hdf_neg_sat((int32_t)hdf_sat32(hdf_mul64x32_q(s->dfilt, c->kd_fs, shift + 16u)));

    /* conditional integration: tentative update, kept unless it deepens saturation */
    /* an int32 times 2^shift, shift <= 32, stays within int64 (-2^63 at the least):
     * the saturating shift is the product (the drive's shifts 16 and 32 fold it) */
    const int64_t lim_hi = (shift <= 32u) ? (int64_t)c->out_max * ((int64_t)1 << shift)
                                          : hdf_shl64_sat((int64_t)c->out_max, shift);
    const int64_t lim_lo = (shift <= 32u) ? (int64_t)c->out_min * ((int64_t)1 << shift)
                                          : hdf_shl64_sat((int64_t)c->out_min, shift);
    int64_t integ_new = hdf_mac64(s->integ, c->ki_dt, e);
    integ_new = hdf_clamp64(integ_new, lim_lo, lim_hi);
    int32_t i_new = hdf_asr32_rnd(integ_new, shift);

    int64_t u = (int64_t)p + (int64_t)i_new + (int64_t)d + (int64_t)ff;
    if ((u > (int64_t)c->out_max && integ_new > s->integ) ||
        (u < (int64_t)c->out_min && integ_new < s->integ)) {
        integ_new = s->integ;                       /* freeze */
        i_new = hdf_asr32_rnd(integ_new, shift);
        u = (int64_t)p + (int64_t)i_new + (int64_t)d + (int64_t)ff;
    }
    s->integ = integ_new;

    const int64_t uc = hdf_clamp64(u, (int64_t)c->out_min, (int64_t)c->out_max);
    s->saturated = (uc != u) ? 1u : 0u;
    s->p = p;
    s->i = i_new;
    s->d = d;
    s->out = (int32_t)uc;
    return s->out;
}

int32_t hd_pid_step(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff)
{
    switch (c->shift) {
    case 16u:
        return pid_core(s, c, ref, meas, ff, 16u);
    case 32u:
        return pid_core(s, c, ref, meas, ff, 32u);
    default:
        return pid_core(s, c, ref, meas, ff, c->shift);
    }
}
