/*
 * hd_le32.h - little-endian 32-bit words in byte buffers and serial-number order:
 * the byte order of every stored record (parameter store, flash record store, table
 * store) whatever the CPU's, and which of two wrapping sequence numbers is newer.
 */
#ifndef HD_LE32_H
#define HD_LE32_H

#include <stdint.h>

static inline void hd_put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)((v >> 24) & 0xFFu);
}

static inline uint32_t hd_get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/** 1 if sequence a is newer than b (serial-number arithmetic, RFC 1982: 0 < a - b < 2^31). */
static inline int hd_seq_newer(uint32_t a, uint32_t b)
{
    const uint32_t d = a - b;
    return d != 0u && d < 0x80000000u;
}

/** Sequence number for a new record of a two-slot store: base + 1, unless that would
 *  not be newer than the record that survives the save (keep_seq, if keep_valid; e.g.
 *  after a boot that fell back to defaults with base 0), then keep_seq + 1. */
static inline uint32_t hd_seq_next(uint32_t base, int keep_valid, uint32_t keep_seq)
{
    if (keep_valid && ((base + 1u) - keep_seq) - 1u >= 0x7FFFFFFFu) {
        base = keep_seq;
    }
    return base + 1u;
}

#endif
