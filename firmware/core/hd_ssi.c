/*
 * hd_ssi.c - BiSS-C style absolute encoder frame decoding (see hd_ssi.h).
 */
#include <stddef.h>
#include "hd_ssi.h"

uint32_t hd_ssi_crc6(uint32_t data, uint32_t nbits)
{
    uint32_t crc = 0u;
    uint32_t i;
    const uint32_t n = (nbits > 32u) ? 32u : nbits;
    for (i = n; i > 0u; i--) {
        const uint32_t bit = (data >> (i - 1u)) & 1u;
        const uint32_t fb = ((crc >> 5) & 1u) ^ bit;
        crc = (crc << 1) & 0x3Fu;
        if (fb != 0u) {
            crc ^= (HD_SSI_CRC_POLY & 0x3Fu);
        }
    }
    return crc;
}

uint32_t hd_ssi_encode(uint32_t position, uint32_t error, uint32_t warning)
{
    const uint32_t d26 = ((position & 0xFFFFFFu) << 2) | ((error != 0u) ? 0u : 2u) |
                         ((warning != 0u) ? 0u : 1u);
    return (d26 << 6) | ((~hd_ssi_crc6(d26, 26u)) & 0x3Fu);
}

int32_t hd_ssi_decode_data(uint32_t data, hd_ssi_reading_t *r)
{
    const uint32_t d26 = data >> 6;
    const uint32_t crc = (~data) & 0x3Fu;
    if (hd_ssi_crc6(d26, 26u) != crc) {
        return HD_SSI_ERR_CRC;
    }
    r->position = d26 >> 2;
    r->error = ((d26 & 2u) != 0u) ? 0u : 1u;
    r->warning = ((d26 & 1u) != 0u) ? 0u : 1u;
    return HD_SSI_OK;
}

static uint32_t bit_at(const uint8_t *buf, uint32_t i)
{
    return ((uint32_t)buf[i >> 3] >> (7u - (i & 7u))) & 1u;
}

int32_t hd_ssi_decode(const uint8_t *buf, uint32_t nbytes, uint32_t nbits, hd_ssi_reading_t *r)
{
    uint32_t i = 0u;
    uint32_t k;
    uint32_t data = 0u;
    if (buf == NULL || r == NULL || nbits > 8u * nbytes) {
        return HD_SSI_ERR_ARG;
    }
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
    return hd_ssi_decode_data(data, r);
}
