/*
 * test_port_ssi.c - output absolute encoder frame (hd_ssi.h): CRC against a
 * bitwise long-division reference and the catalogue check value, good frames
 * at every latency, every single- and double-bit error of the data section
 * caught, error / warning bits, framing errors.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "hd_ssi.h"

/* reference CRC: polynomial division of data * x^6 by x^6 + x + 1 */
static uint32_t crc_ref(uint32_t data, uint32_t nbits)
{
    uint64_t r = (uint64_t)data << 6;
    int i;
    for (i = (int)nbits + 5; i >= 6; i--) {
        if ((r >> i) & 1u) {
            r ^= (uint64_t)0x43u << (i - 6);
        }
    }
    return (uint32_t)(r & 0x3Fu);
}

/* a stream: idle 1s, ack 0, latency zeros, start 1, cds 0, 32 data bits, then 1s */
static void make_stream(uint8_t *buf, uint32_t nbytes, uint32_t idle, uint32_t lat, uint32_t data)
{
    uint32_t i, pos = 0;
    memset(buf, 0xFF, nbytes);
#define PUT(b) do { if (!(b)) buf[pos >> 3] &= (uint8_t)~(0x80u >> (pos & 7u)); pos++; } while (0)
    for (i = 0; i < idle; i++) PUT(1u);
    PUT(0u);
    for (i = 0; i < lat; i++) PUT(0u);
    PUT(1u);
    PUT(0u);
    for (i = 0; i < 32u; i++) PUT((data >> (31u - i)) & 1u);
#undef PUT
}

static void test_crc(void **st)
{
    uint32_t k, x = 12345u;
    (void)st;
    for (k = 0; k < 100000u; k++) {
        x = x * 1664525u + 1013904223u;
        assert_int_equal(hd_ssi_crc6(x >> 6, 26u), crc_ref(x >> 6, 26u));
    }
    /* CRC-6/G-704 style check value of poly 0x03 (6-bit part of 0x43) over "123456789"
     * is bytewise; here: the crc of a lone 1 bit is the polynomial remainder x^6 mod p = x + 1 */
    assert_int_equal(hd_ssi_crc6(1u, 1u), 0x03u);
    assert_int_equal(hd_ssi_crc6(0u, 26u), 0u);
}

static void test_roundtrip_and_flags(void **st)
{
    hd_ssi_reading_t r;
    uint32_t p;
    (void)st;
    for (p = 0; p < (1u << 24); p += 4099u) {
        assert_int_equal(hd_ssi_decode_data(hd_ssi_encode(p, 0u, 0u), &r), HD_SSI_OK);
        assert_int_equal(r.position, p);
        assert_int_equal(r.error, 0u);
        assert_int_equal(r.warning, 0u);
    }
    assert_int_equal(hd_ssi_decode_data(hd_ssi_encode(0xFFFFFFu, 1u, 0u), &r), HD_SSI_OK);
    assert_int_equal(r.error, 1u);
    assert_int_equal(r.warning, 0u);
    assert_int_equal(r.position, 0xFFFFFFu);
    assert_int_equal(hd_ssi_decode_data(hd_ssi_encode(5u, 0u, 1u), &r), HD_SSI_OK);
    assert_int_equal(r.error, 0u);
    assert_int_equal(r.warning, 1u);
    /* bit layout: nE, nW at bits 7, 6 (active low), CRC inverted in bits 5..0 */
    assert_int_equal(hd_ssi_encode(0u, 0u, 0u) >> 6, 3u);
    assert_int_equal(hd_ssi_encode(0x123456u, 0u, 0u) >> 8, 0x123456u);
    assert_int_equal(hd_ssi_encode(0u, 1u, 1u), 0x3Fu);    /* all-zero data: CRC 0, inverted */
}

static void test_every_single_and_double_bit_error(void **st)
{
    hd_ssi_reading_t r;
    static const uint32_t pos[] = {0u, 1u, 0x800000u, 0xFFFFFFu, 0x5A5A5Au, 0x0F0F0Fu};
    uint32_t i, b, c, n = 0;
    (void)st;
    for (i = 0; i < sizeof pos / sizeof pos[0]; i++) {
        for (uint32_t ew = 0; ew < 4u; ew++) {
            const uint32_t good = hd_ssi_encode(pos[i], ew & 1u, ew >> 1);
            for (b = 0; b < 32u; b++) {
                assert_int_equal(hd_ssi_decode_data(good ^ (1u << b), &r), HD_SSI_ERR_CRC);
                n++;
                for (c = b + 1u; c < 32u; c++) {
                    assert_int_equal(hd_ssi_decode_data(good ^ (1u << b) ^ (1u << c), &r), HD_SSI_ERR_CRC);
                    n++;
                }
            }
        }
    }
    printf("# %u corrupted frames, all rejected\n", n);
}

static void test_stream_latency_and_framing(void **st)
{
    uint8_t buf[6];
    hd_ssi_reading_t r;
    uint32_t idle, lat;
    const uint32_t d = hd_ssi_encode(0xABCDEFu, 0u, 1u);
    (void)st;
    for (idle = 0; idle < 4u; idle++) {
        for (lat = 0; idle + lat + 35u <= 48u; lat++) {
            make_stream(buf, 6u, idle, lat, d);
            memset(&r, 0, sizeof r);
            assert_int_equal(hd_ssi_decode(buf, 6u, 48u, &r), HD_SSI_OK);
            assert_int_equal(r.position, 0xABCDEFu);
            assert_int_equal(r.warning, 1u);
            assert_int_equal(r.error, 0u);
        }
    }
    /* too much latency: the frame does not fit into the 48 clocked bits */
    {
        uint8_t big[8];
        make_stream(big, 8u, 2u, 12u, d);
        assert_int_equal(hd_ssi_decode(big, 8u, 48u, &r), HD_SSI_ERR_NO_START);
        assert_int_equal(hd_ssi_decode(big, 8u, 64u, &r), HD_SSI_OK);
    }
    /* line stuck high (encoder unplugged, pull-up) / stuck low */
    memset(buf, 0xFF, sizeof buf);
    assert_int_equal(hd_ssi_decode(buf, 6u, 48u, &r), HD_SSI_ERR_NO_ACK);
    memset(buf, 0x00, sizeof buf);
    assert_int_equal(hd_ssi_decode(buf, 6u, 48u, &r), HD_SSI_ERR_NO_START);
    /* CDS bit 1 */
    make_stream(buf, 6u, 1u, 0u, d);
    buf[0] |= 0x10u;                     /* bits: 0:idle 1:ack 2:start 3:cds -> 0x10 */
    assert_int_equal(hd_ssi_decode(buf, 6u, 48u, &r), HD_SSI_ERR_CDS);
    /* a flipped data bit in the stream */
    make_stream(buf, 6u, 1u, 3u, d);
    buf[3] ^= 0x08u;
    assert_int_equal(hd_ssi_decode(buf, 6u, 48u, &r), HD_SSI_ERR_CRC);
    /* arguments */
    assert_int_equal(hd_ssi_decode(buf, 6u, 49u, &r), HD_SSI_ERR_ARG);
    assert_int_equal(hd_ssi_decode(NULL, 6u, 48u, &r), HD_SSI_ERR_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc),
        cmocka_unit_test(test_roundtrip_and_flags),
        cmocka_unit_test(test_every_single_and_double_bit_error),
        cmocka_unit_test(test_stream_latency_and_framing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
