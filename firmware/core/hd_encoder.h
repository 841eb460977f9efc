/*
 * hd_encoder.h - multi-turn counting of an incremental (quadrature) encoder
 * read through a free-running 16-bit hardware counter (STM32 TIMx in encoder
 * mode, ARR = 0xFFFF).
 *
 * Each update takes the counter's raw value; the step since the last update is
 * the signed 16-bit difference (mod 2^16, in [-32768, 32767]), so the count is
 * exact as long as the shaft moves less than 32768 counts between updates
 * (the reference motor at 7680 rpm with a 2^17 count/rev encoder moves 1678
 * counts per 100 us period: 19x margin).  A step larger than max_step (the
 * plausible motion per update) is counted as a jump: it is still applied
 * (modulo 2^16 nothing better is known) but the sample is flagged invalid and
 * jumps is incremented, so the app can fault.  The count is int64 (never
 * wraps in practice: 2^63 counts); the single-turn value is count mod 2^bits,
 * always in [0, 2^bits), also for negative counts.
 */
#ifndef HD_ENCODER_H
#define HD_ENCODER_H

#include <stdint.h>
#include "hd_fixed.h"

typedef struct {
    int64_t  count;      /* multi-turn count since init (plus the initial offset) */
    uint32_t last_raw;   /* last 16-bit counter value */
    uint32_t max_step;   /* plausible |step| per update, counts (<= 32767) */
    uint32_t jumps;      /* implausible steps seen */
    uint32_t ok;         /* 1 if the last update was plausible */
} hd_enc_t;

/** Start counting at `count0` with the counter currently reading raw (low 16 bits used). */
void hd_enc_init(hd_enc_t *e, uint32_t raw, int64_t count0, uint32_t max_step);
/** One update with the counter value raw; returns the signed step in counts.  Inline
 *  (once per FOC period). */
static inline int32_t hd_enc_update(hd_enc_t *e, uint32_t raw)
{
    const uint32_t r = raw & 0xFFFFu;
    const uint32_t d = (r - e->last_raw) & 0xFFFFu;          /* mod 2^16 */
    const int32_t step = (d >= 0x8000u) ? ((int32_t)d - 0x10000) : (int32_t)d;
    e->last_raw = r;
    e->count = hdf_add64_sat(e->count, step);
    const uint32_t mag = (step < 0) ? (uint32_t)(-step) : (uint32_t)step;
    if (mag > e->max_step) {
        e->jumps++;
        e->ok = 0u;
    } else {
        e->ok = 1u;
    }
    return step;
}
/** count mod 2^bits in [0, 2^bits), 1 <= bits <= 32 (inline: twice per FOC period). */
static inline uint32_t hd_enc_single_turn(const hd_enc_t *e, uint32_t bits)
{
    const uint32_t b = (bits < 1u) ? 1u : ((bits > 32u) ? 32u : bits);
    const uint64_t mask = ((uint64_t)1 << b) - 1u;
    return (uint32_t)((uint64_t)e->count & mask);   /* two's complement image: mod 2^b */
}

#endif
