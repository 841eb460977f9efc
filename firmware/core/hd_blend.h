/*
 * hd_blend.h - bumpless on/off switching shared by the compensators.
 *
 * Every compensator's output passes through a linear weight ramp
 *     out = off + w * (on - off),   w in Q30, [0, 2^30]
 * (off = 0 for a feed-forward term, off = the uncompensated command for a
 * series correction).  set_enabled() only changes the target; each call of
 * hd_blend_update() (once per loop period, inside the compensator's step)
 * moves w by ceil(2^30 / ramp_ticks) towards it, so switching on or off
 * while running fades the term in or out over ramp_ticks periods
 * (ramp_ticks = 0 switches at once).  The compensator keeps integrating its
 * internal state while w = 0 so that it is warm when switched on.
 *
 * Formats: w, target Q30 (2^30 = fully on).  ramp_ticks: loop periods
 * (1e-4 s each at HD_LOOP_HZ).  Plain integer fields (parameter store /
 * CANopen writable).
 */
#ifndef HD_BLEND_H
#define HD_BLEND_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_fixed.h"

typedef struct {
    uint32_t ramp_ticks;  /* parameter: ramp length in loop periods, 0 = step */
    int32_t  target;      /* 0 or 2^30 */
    int32_t  w;           /* current weight, Q30 in [0, 2^30] */
} hd_blend_t;

/** Initialise: weight already at its target (no ramp at start-up). */
void hd_blend_init(hd_blend_t *b, uint32_t ramp_ticks, bool enabled);
/** Request on/off; the weight ramps there in later hd_blend_update() calls. */
void hd_blend_set_enabled(hd_blend_t *b, bool enabled);
/** One step of a running ramp (hd_blend_update's slow path, contains a division). */
int32_t hd_blend_ramp(hd_blend_t *b);
/** Advance the ramp by one loop period; returns the new weight (Q30).  Inline
 *  because it runs for every compensator every period and is nearly always in
 *  the steady state (w at its target), which then costs two compares. */
static inline int32_t hd_blend_update(hd_blend_t *b)
{
    const int32_t tgt = (b->target > 0) ? HD_Q30_ONE : 0;
    if ((b->ramp_ticks == 0u) || (b->w == tgt)) {
        /* no ramp, or the ramp is done (the steady state): no step, no divide */
        b->w = tgt;
        return tgt;
    }
    return hd_blend_ramp(b);
}
/** w * x, rounded to nearest (exact at w = 0 and w = 2^30); inline (every
 *  compensator output, every period; fully on it is x itself). */
static inline int32_t hd_blend_apply(const hd_blend_t *b, int32_t x)
{
    if (b->w >= HD_Q30_ONE) {
        return x;
    }
    return hdf_mul_q(x, b->w, 30u);
}
/** off + w * (on - off) for int32 signals, saturated, rounded to nearest; inline
 *  (backstepping's blend, every period; fully on it is on itself). */
static inline int32_t hd_blend_mix(const hd_blend_t *b, int32_t off, int32_t on)
{
    if (b->w >= HD_Q30_ONE) {
        return on;
    }
    return hdf_sat32((int64_t)off + hdf_mul64x32_q((int64_t)on - (int64_t)off, b->w, 30u));
}
/** off + w * (on - off) for int64 signals (angles), saturated, rounded. */
int64_t hd_blend_mix64(const hd_blend_t *b, int64_t off, int64_t on);
/** True while the weight is not 0 or is moving (output may be non-zero). */
static inline bool hd_blend_active(const hd_blend_t *b)
{
    return (b->w != 0) || (b->target != 0);
}

#endif
