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
