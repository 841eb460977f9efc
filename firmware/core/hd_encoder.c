/*
 * hd_encoder.c - 16-bit quadrature counter to multi-turn count (hd_encoder.h).
 */
#include "hd_encoder.h"
#include "hd_fixed.h"

void hd_enc_init(hd_enc_t *e, uint32_t raw, int64_t count0, uint32_t max_step)
{
    e->count = count0;
    e->last_raw = raw & 0xFFFFu;
    e->max_step = (max_step > 32767u) ? 32767u : max_step;
    e->jumps = 0u;
    e->ok = 1u;
}

int32_t hd_enc_update(hd_enc_t *e, uint32_t raw)
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
