/*
 * hd_ssi.c - BiSS-C style absolute encoder frame decoding (see hd_ssi.h).
 */
#include <stddef.h>
#include "hd_ssi.h"

/* CRC-6 x^6 + x + 1 six bits at a time: crc' = T[crc ^ next 6 data bits], T[x] =
 * the register x clocked through 6 zero bits (the chunk width equals the CRC width).
 * Leading zero bits leave the zero register at 0, so the data (masked to nbits)
 * is processed from the chunk holding its top bit.  Same result as the bitwise
 * long division (test_port_ssi.c compares both). */
static const uint8_t hd_ssi_crc6_tab[64] = {
    0x00u, 0x03u, 0x06u, 0x05u, 0x0Cu, 0x0Fu, 0x0Au, 0x09u, 0x18u, 0x1Bu, 0x1Eu, 0x1Du, 0x14u, 0x17u, 0x12u, 0x11u,
    0x30u, 0x33u, 0x36u, 0x35u, 0x3Cu, 0x3Fu, 0x3Au, 0x39u, 0x28u, 0x2Bu, 0x2Eu, 0x2Du, 0x24u, 0x27u, 0x22u, 0x21u,
    0x23u, 0x20u, 0x25u, 0x26u, 0x2Fu, 0x2Cu, 0x29u, 0x2Au, 0x3Bu, 0x38u, 0x3Du, 0x3Eu, 0x37u, 0x34u, 0x31u, 0x32u,
    0x13u, 0x10u, 0x15u, 0x16u, 0x1Fu, 0x1Cu, 0x19u, 0x1Au, 0x0Bu, 0x08u, 0x0Du, 0x0Eu, 0x07u, 0x04u, 0x01u, 0x02u};

uint32_t hd_ssi_crc6(uint32_t data, uint32_t nbits)
{
    /* the data masked to n <= 32 bits fits one word: 32-bit shifts only */
    const uint32_t n = (nbits > 32u) ? 32u : nbits;
    const uint32_t d = data & (uint32_t)(((uint64_t)1 << n) - 1u);
    uint32_t crc = 0u;
    uint32_t sh = ((n + 5u) / 6u) * 6u;
    if (sh > 30u) {                                   /* n 31, 32: the top chunk holds 1 or 2 bits */
        crc = hd_ssi_crc6_tab[d >> 30];
        sh = 30u;
    }
    while (sh > 0u) {
        sh -= 6u;
        crc = hd_ssi_crc6_tab[crc ^ ((d >> sh) & 0x3Fu)];
    }
    return crc;
}

/* hd_ssi_crc6(d, 26) unrolled: the chunks at bits 24 (2 bits), 18, 12, 6, 0 */
static inline uint32_t ssi_crc6_26(uint32_t d)
{
    uint32_t crc = hd_ssi_crc6_tab[(d >> 24) & 0x3u];
    crc = hd_ssi_crc6_tab[crc ^ ((d >> 18) & 0x3Fu)];
    crc = hd_ssi_crc6_tab[crc ^ ((d >> 12) & 0x3Fu)];
    crc = hd_ssi_crc6_tab[crc ^ ((d >> 6) & 0x3Fu)];
    return hd_ssi_crc6_tab[crc ^ (d & 0x3Fu)];
}

uint32_t hd_ssi_encode(uint32_t position, uint32_t error, uint32_t warning)
{
    const uint32_t d26 = ((position & 0xFFFFFFu) << 2) | ((error != 0u) ? 0u : 2u) |
                         ((warning != 0u) ? 0u : 1u);
    return (d26 << 6) | ((~hd_ssi_crc6(d26, 26u)) & 0x3Fu);
}

/* the 32 data bits of a frame: CRC check, then the reading (hd_ssi_decode_data) */
static inline int32_t ssi_data(uint32_t data, hd_ssi_reading_t *r)
{
    const uint32_t d26 = data >> 6;
    const uint32_t crc = (~data) & 0x3Fu;
    if (ssi_crc6_26(d26) != crc) {
        return HD_SSI_ERR_CRC;
    }
    r->position = d26 >> 2;
    r->error = ((d26 & 2u) != 0u) ? 0u : 1u;
    r->warning = ((d26 & 1u) != 0u) ? 0u : 1u;
    return HD_SSI_OK;
}

int32_t hd_ssi_decode_data(uint32_t data, hd_ssi_reading_t *r)
{
    return ssi_data(data, r);
}

static uint32_t bit_at(const uint8_t *buf, uint32_t i)
{
    return ((uint32_t)buf[i >> 3] >> (7u - (i & 7u))) & 1u;
}

/* Bit-serial decoder (frames longer than 64 bits). */
static int32_t hd_ssi_decode_bits(const uint8_t *buf, uint32_t nbits, hd_ssi_reading_t *r)
{
    uint32_t i = 0u;
    uint32_t k;
    uint32_t data = 0u;
    while (i < nbits && bit_at(buf, i) != 0u) {       /* idle high */
        i++;
    }
    if (i >= nbits) {
        return HD_SSI_ERR_NO_ACK;
    }
    while (i < nbits && bit_at(buf, i) == 0u) {       /* ack + latency */
        i++;
    }
    /* i: start bit; then CDS and 32 data bits must fit */
    if (i >= nbits || nbits - i < 2u + HD_SSI_DATA_BITS) {
        return HD_SSI_ERR_NO_START;
    }
    if (bit_at(buf, i + 1u) != 0u) {
        return HD_SSI_ERR_CDS;
    }
    for (k = 0u; k < HD_SSI_DATA_BITS; k++) {
        data = (data << 1) | bit_at(buf, i + 2u + k);
    }
    return ssi_data(data, r);
}

/* leading zeros of a 64-bit word (64 for 0) */
static uint32_t clz64(uint64_t w)
{
    const uint32_t hi = (uint32_t)(w >> 32);
    const uint32_t lo = (uint32_t)w;
    if (hi != 0u) {
        return (uint32_t)__builtin_clz(hi);
    }
    return (lo != 0u) ? (32u + (uint32_t)__builtin_clz(lo)) : 64u;
}

int32_t hd_ssi_decode(const uint8_t *buf, uint32_t nbytes, uint32_t nbits, hd_ssi_reading_t *r)
{
    uint64_t w;
    uint32_t hi = 0u;
    uint32_t lo = 0u;
    uint32_t i;
    uint32_t k;
    if (buf == NULL || r == NULL || nbits > 8u * nbytes) {
        return HD_SSI_ERR_ARG;
    }
    if (nbits > 64u) {
        return hd_ssi_decode_bits(buf, nbits, r);
    }
    /* word-wise: the frame top-aligned in w (bit i of the frame = bit 63 - i of w);
     * a run that reaches past nbits fails the same tests as the bitwise count.
     * The bytes read are those of the frame (k < nbytes); a frame of 6 bytes or more
     * (the drive's 48 clocks) is gathered without a loop. */
    if (nbytes >= 6u) {
        hi = ((uint32_t)buf[0] << 24) | ((uint32_t)buf[1] << 16) | ((uint32_t)buf[2] << 8) | (uint32_t)buf[3];
        lo = ((uint32_t)buf[4] << 24) | ((uint32_t)buf[5] << 16);
        if (nbytes >= 7u) {
            lo |= (uint32_t)buf[6] << 8;
        }
        if (nbytes >= 8u) {
            lo |= (uint32_t)buf[7];
        }
    } else {
        for (k = 0u; k < nbytes; k++) {
            if (k < 4u) {
                hi |= (uint32_t)buf[k] << (24u - (8u * k));
            } else {
                lo |= (uint32_t)buf[k] << (56u - (8u * k));
            }
        }
    }
    w = ((uint64_t)hi << 32) | lo;
    i = clz64(~w);                                    /* idle high */
    if (i >= nbits) {
        return HD_SSI_ERR_NO_ACK;
    }
    i += clz64(w << i);                               /* ack + latency: i < 64 here */
    if (i >= nbits || nbits - i < 2u + HD_SSI_DATA_BITS) {
        return HD_SSI_ERR_NO_START;
    }
    w <<= i;                                          /* start bit at 63, CDS at 62, data 61..30 */
    if (((w >> 62) & 1u) != 0u) {
        return HD_SSI_ERR_CDS;
    }
    return ssi_data((uint32_t)(w >> 30), r);
}
