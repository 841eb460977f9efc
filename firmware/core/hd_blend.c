/* hd_blend.c - bumpless weight ramp (contract: hd_blend.h). */
#include "hd_blend.h"
#include "hd_fixed.h"

void hd_blend_init(hd_blend_t *b, uint32_t ramp_ticks, bool enabled)
{
    b->ramp_ticks = ramp_ticks;
    b->target = enabled ? HD_Q30_ONE : 0;
    b->w = b->target;
}

void hd_blend_set_enabled(hd_blend_t *b, bool enabled)
{
    b->target = enabled ? HD_Q30_ONE : 0;
}

int32_t hd_blend_ramp(hd_blend_t *b)
{
    int32_t step;
    const int32_t tgt = (b->target > 0) ? HD_Q30_ONE : 0;

    if ((b->ramp_ticks == 0u) || (b->w == tgt)) {
        b->w = tgt;
        return b->w;
    }
    /* ceil(2^30 / ramp_ticks) >= 1 */
    step = (int32_t)((((uint32_t)1 << 30) + b->ramp_ticks - 1u) / b->ramp_ticks);
    if (b->w < tgt) {
        b->w = (tgt - b->w <= step) ? tgt : b->w + step;
    } else if (b->w > tgt) {
        b->w = (b->w - tgt <= step) ? tgt : b->w - step;
    }
    return b->w;
}


int64_t hd_blend_mix64(const hd_blend_t *b, int64_t off, int64_t on)
{
    if (b->w >= HD_Q30_ONE) {
        return on;
    }
    return hdf_add64_sat(off, hdf_mul64x32_q(hdf_sub64_sat(on, off), b->w, 30u));
}
