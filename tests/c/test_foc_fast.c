/*
 * test_foc_fast.c - the 32-bit forms of the port's period (hd_foc.c range analysis):
 *
 *  - the DSP helpers hdf_smmulr, hdf_smmlar, hdf_dot2_rnd32, hdf_dot2_64, hdf_ssat against their
 *    definitions evaluated in 128-bit arithmetic (edges and random words);
 *  - the current loop's table sine (hd_foc_sincos) against double precision;
 *  - hd_foc_step's Clarke + Park against double precision, its current saturation,
 *    and its duties against the reference modulation hd_foc_svm (64-bit ratios, exact
 *    1 / vbus) fed with the step's limited voltage;
 *  - the 32-bit ADC scaling against the 64-bit product hd_mul_q;
 *  - the 32-bit CRC-6 of hd_ssi against a bitwise polynomial division for every width, and
 *    the frame decode for streams of every length of 1 .. 8 bytes.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <cmocka.h>

#include "hd_fixed.h"
#include "hd_foc.h"
#include "hd_ssi.h"

#define PI_D 3.14159265358979323846
#define Q16 65536.0
#define Q31 2147483648.0

static uint64_t rs = 0x9E3779B97F4A7C15ull;
static uint32_t rnd(void)
{
    rs ^= rs << 13;
    rs ^= rs >> 7;
    rs ^= rs << 17;
    return (uint32_t)(rs >> 16);
}
static int32_t s32(uint32_t u) { return (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u; }
static int32_t rnd_range(int32_t lo, int32_t hi) { return lo + (int32_t)(rnd() % (uint32_t)(hi - lo + 1)); }

/* edge-biased word: one in four from the edge list, else random (sometimes shifted down) */
static int32_t edge_word(void)
{
    static const int32_t edge[] = {INT32_MIN, INT32_MIN + 1, -65536, -2, -1, 0, 1, 2, 65536, INT32_MAX - 1, INT32_MAX};
    const uint32_t k = rnd();
    if ((k & 3u) == 0u) {
        return edge[(k >> 2) % (sizeof edge / sizeof edge[0])];
    }
    return s32(rnd() ^ (rnd() << 16)) / (int32_t)(1 + ((k >> 8) & 0xFFu));
}

/* the high word of a 128-bit value taken modulo 2^64, as the instruction returns it */
static int32_t hi_word_mod64(__int128 v)
{
    const uint64_t w = (uint64_t)(unsigned __int128)v;
    return s32((uint32_t)(w >> 32));
}

static void test_dsp_helpers(void **st)
{
    (void)st;
    for (int k = 0; k < 400000; k++) {
        const int32_t a = edge_word(), b = edge_word(), c = edge_word(), d = edge_word();
        const __int128 ab = (__int128)a * b;
        /* SMMULR: floor((a b + 2^31) / 2^32), exact (no wrap) */
        const __int128 r1 = (ab + ((__int128)1 << 31)) >> 32;
        assert_int_equal(hdf_smmulr(a, b), (int32_t)r1);
        /* SMMLAR: the high word of c 2^32 + a b + 2^31, modulo 2^32 */
        const __int128 r2 = ((__int128)c * ((__int128)1 << 32) + ab + ((__int128)1 << 31)) >> 32;
        assert_int_equal(hdf_smmlar(c, a, b), s32((uint32_t)(unsigned __int128)r2));
        /* two SMLAL on 2^31: the high word of (a b + c d + 2^31) mod 2^64 */
        assert_int_equal(hdf_dot2_rnd32(a, b, c, d), hi_word_mod64(ab + (__int128)c * d + ((__int128)1 << 31)));
        /* SMULL + SMLAL: (a b + c d) mod 2^64 */
        {
            const unsigned __int128 w = (unsigned __int128)(ab + (__int128)c * d);
            const uint64_t u = (uint64_t)w;
            assert_true(hdf_dot2_64(a, b, c, d) == ((u > (uint64_t)INT64_MAX) ? -(int64_t)(~u) - 1 : (int64_t)u));
        }
        /* SSAT to n bits */
        const uint32_t n = 1u + rnd() % 32u;
        const int64_t lim = ((int64_t)1 << (n - 1u));
        const int64_t ref = (a > lim - 1) ? lim - 1 : ((a < -lim) ? -lim : a);
        assert_int_equal(hdf_ssat(a, n), (int32_t)ref);
    }
    /* the extremes: both products 2^62 wrap the 64-bit sum as SMLAL does */
    assert_int_equal(hdf_dot2_rnd32(INT32_MIN, INT32_MIN, INT32_MIN, INT32_MIN), INT32_MIN);
    assert_int_equal(hdf_smmulr(INT32_MIN, INT32_MIN), 1 << 30);
    assert_int_equal(hdf_ssat(INT32_MIN, 28u), -(1 << 27));
    assert_int_equal(hdf_ssat(INT32_MAX, 28u), (1 << 27) - 1);
}

/* The table sine: linear interpolation of 512 entries per turn, error <= (2 pi / 512)^2 / 8
 * of the amplitude (1.9e-5, 40,425.9 LSB of Q31) + the rounding of the two entries and of
 * the interpolation (1.5 LSB). */
static void test_foc_sincos(void **st)
{
    double worst = 0;
    (void)st;
    for (uint32_t k = 0; k < 1200000u; k++) {
        const uint32_t th = (k < 4096u) ? k << 20 : (rnd() ^ (rnd() << 16));    /* nodes: k % 8 == 0 */
        int32_t s, c;
        hd_foc_sincos(th, &s, &c);
        const double a = th / 4294967296.0 * 2 * PI_D;
        worst = fmax(worst, fmax(fabs(s - sin(a) * Q31), fabs(c - cos(a) * Q31)));
        if (k < 4096u && (k % 8u) == 0u) {
            /* table nodes: the entry itself, within its rounding */
            assert_true(fabs(s - sin(a) * Q31) <= 1.0 && fabs(c - cos(a) * Q31) <= 1.0);
        }
    }
    printf("# table sine: max error %.0f LSB of Q31 (%.2e)\n", worst, worst / Q31);
    assert_true(worst <= 40425.9 + 1.5);
    assert_true(worst >= 20000.0);      /* the interpolation error is there: the bound is tight */
}

static void foc_setup(hd_foc_t *s, hd_foc_cfg_t *c)
{
    hd_foc_reset(s);
    assert_int_equal(hd_foc_design(c, 300, 300000, 900, 20000), 0);
}

/* Clarke + Park of hd_foc_step: within 1 LSB + the sine's 1.9e-5 of the current's magnitude
 * of the double-precision transforms; currents beyond +-2,048 A saturate (SSAT 28). */
static void test_foc_step_transforms(void **st)
{
    hd_foc_t s;
    hd_foc_cfg_t c;
    hd_foc_in_t in;
    hd_foc_out_t out;
    double worst = 0;
    (void)st;
    foc_setup(&s, &c);
    for (int k = 0; k < 200000; k++) {
        in.ia = rnd_range(-1000 * 65536, 1000 * 65536);
        in.ib = rnd_range(-1000 * 65536, 1000 * 65536);
        in.theta_e = rnd() ^ (rnd() << 16);
        in.id_ref = 0;
        in.iq_ref = 0;
        in.vbus = 48 * 65536;
        hd_foc_step(&s, &c, &in, &out);
        const double a = in.theta_e / 4294967296.0 * 2 * PI_D;
        const double al = in.ia, be = (in.ia + 2.0 * in.ib) / sqrt(3.0);
        const double d = al * cos(a) + be * sin(a), q = be * cos(a) - al * sin(a);
        const double mag = sqrt(al * al + be * be);
        const double e = fmax(fabs(s.id - d), fabs(s.iq - q));
        worst = fmax(worst, e / (1.0 + 1.9e-5 * mag));
        assert_true(e <= 1.0 + 1.9e-5 * mag);
    }
    printf("# step Clarke + Park: worst error / (1 LSB + 1.9e-5 |i|) = %.3f\n", worst);
    /* saturation of the phase currents at [-2^27, 2^27) */
    {
        int32_t id1, iq1;
        in.ia = INT32_MAX;
        in.ib = INT32_MIN;
        in.theta_e = 0x12345678u;
        hd_foc_step(&s, &c, &in, &out);
        id1 = s.id;
        iq1 = s.iq;
        in.ia = (1 << 27) - 1;
        in.ib = -(1 << 27);
        hd_foc_step(&s, &c, &in, &out);
        assert_int_equal(s.id, id1);
        assert_int_equal(s.iq, iq1);
    }
}

/* The step's modulation (Q27 ratios by SMMULR on the normalised 1 / vbus, inverse Park by two
 * SMLAL, duties two bits below the reference's) against hd_foc_svm, the 64-bit reference with
 * the exact 1 / vbus, fed with the step's limited (vd, vq) rotated in double precision: within
 * 2 duty LSB, over bus voltages of 1 .. 8,192 V (the reciprocal by one division and a Newton
 * step) and every angle, limited or not. */
static void test_foc_step_duties_match_svm(void **st)
{
    hd_foc_t s;
    hd_foc_cfg_t c;
    hd_foc_in_t in;
    hd_foc_out_t out;
    int32_t ref[3];
    int32_t worst = 0;
    (void)st;
    foc_setup(&s, &c);
    for (int k = 0; k < 200000; k++) {
        hd_foc_reset(&s);
        in.ia = rnd_range(-20 * 65536, 20 * 65536);
        in.ib = rnd_range(-20 * 65536, 20 * 65536);
        in.theta_e = rnd() ^ (rnd() << 16);
        in.id_ref = rnd_range(-30 * 65536, 30 * 65536);
        in.iq_ref = rnd_range(-30 * 65536, 30 * 65536);
        in.vbus = ((k % 4) == 0) ? rnd_range(65536, (1 << 29) - 1) : rnd_range(65536, 200 * 65536);
        hd_foc_step(&s, &c, &in, &out);
        const double a = in.theta_e / 4294967296.0 * 2 * PI_D;
        const double va = s.vd * cos(a) - s.vq * sin(a), vb = s.vd * sin(a) + s.vq * cos(a);
        hd_foc_svm((int32_t)lround(va), (int32_t)lround(vb), in.vbus, ref);
        for (int i = 0; i < 3; i++) {
            const int32_t d = abs(out.duty[i] - ref[i]);
            worst = (d > worst) ? d : worst;
            assert_true(out.duty[i] >= 0 && out.duty[i] <= HD_FOC_DUTY_ONE);
        }
    }
    printf("# step duties vs hd_foc_svm: max difference %d duty LSB\n", (int)worst);
    assert_true(worst <= 2);
    /* below 1 V the modulation is that of 1 V: duties within range, no wrap */
    in.vbus = 1000;
    in.iq_ref = 30 * 65536;
    hd_foc_step(&s, &c, &in, &out);
    for (int i = 0; i < 3; i++) {
        assert_true(out.duty[i] >= 0 && out.duty[i] <= HD_FOC_DUTY_ONE);
    }
}

/* ADC scaling by one SMMULR: the 64-bit rounded product for every 16-bit difference and
 * gains up to 0.125 A per LSB (the same value, but for negative ties: half up, not half away),
 * saturated outside [-2^16, 2^16) LSB and for gains of 2^27 and more. */
static void test_adc_current(void **st)
{
    static const int32_t gains[] = {1, 13107200, 17301504, 33554432, (1 << 27) - 1, -13107200};
    (void)st;
    for (size_t g = 0; g < sizeof gains / sizeof gains[0]; g++) {
        for (int32_t d = -65536; d < 65536; d++) {
            const int32_t v = hd_foc_adc_current(d + 2048, 2048, gains[g]);
            const int32_t r = hd_mul_q(d, gains[g], 14u);
            const int64_t p = (int64_t)d * gains[g];
            const int tie_neg = (p < 0) && ((p & 0x3FFF) == 0x2000);
            assert_int_equal(v, tie_neg ? r + 1 : r);
        }
    }
    assert_int_equal(hd_foc_adc_current(INT32_MAX, 0, 13107200), hd_foc_adc_current(65535, 0, 13107200));
    assert_int_equal(hd_foc_adc_current(INT32_MIN, 0, 13107200), hd_foc_adc_current(-65536, 0, 13107200));
    assert_int_equal(hd_foc_adc_current(100, 0, INT32_MAX), hd_foc_adc_current(100, 0, (1 << 27) - 1));
}

/* bitwise CRC-6 (x^6 + x + 1) of the low nbits of data */
static uint32_t crc_ref(uint32_t data, uint32_t nbits)
{
    uint64_t r = (uint64_t)((nbits >= 32u) ? data : (data & ((1u << nbits) - 1u))) << 6;
    for (int i = (int)nbits + 5; i >= 6; i--) {
        if ((r >> i) & 1u) {
            r ^= (uint64_t)0x43u << (i - 6);
        }
    }
    return (uint32_t)(r & 0x3Fu);
}

static void test_ssi_crc6_every_width(void **st)
{
    (void)st;
    for (uint32_t n = 0; n <= 33u; n++) {
        for (int k = 0; k < 20000; k++) {
            const uint32_t x = (k == 0) ? 0xFFFFFFFFu : (rnd() ^ (rnd() << 16));
            assert_int_equal(hd_ssi_crc6(x, n), crc_ref(x, (n > 32u) ? 32u : n));
        }
    }
}

/* A frame (idle 1, ack 0, latency 0s, start 1, CDS 0, 32 data bits, then 1s) in a stream of
 * 1 .. 8 bytes: the bytes are gathered without a loop for 6 bytes and more, by a loop below;
 * every length that holds the frame decodes it, shorter ones fail on the framing. */
static void test_ssi_frame_every_length(void **st)
{
    (void)st;
    for (int k = 0; k < 2000; k++) {
        const uint32_t pos = rnd() & 0xFFFFFFu;
        const uint32_t data = hd_ssi_encode(pos, 0u, 0u);
        const uint32_t lat = rnd() % 5u;                  /* frame of 36 + lat <= 40 bits */
        uint8_t buf[8];
        uint32_t bit = 0u;
        for (int i = 0; i < 8; i++) {
            buf[i] = 0xFFu;
        }
#define CLR(b) (buf[(b) >> 3] = (uint8_t)(buf[(b) >> 3] & ~(0x80u >> ((b) & 7u))))
        bit = 1u;                                          /* idle 1 */
        for (uint32_t i = 0; i <= lat; i++) {
            CLR(bit);                                      /* ack + latency zeros */
            bit++;
        }
        bit++;                                             /* start 1 */
        CLR(bit);                                          /* CDS 0 */
        bit++;
        for (uint32_t i = 0; i < 32u; i++, bit++) {
            if (((data >> (31u - i)) & 1u) == 0u) {
                CLR(bit);
            }
        }
#undef CLR
        for (uint32_t nb = 1u; nb <= 8u; nb++) {
            hd_ssi_reading_t r = {0u, 0u, 0u};
            const int32_t rc = hd_ssi_decode(buf, nb, 8u * nb, &r);
            if (8u * nb >= bit) {
                assert_int_equal(rc, HD_SSI_OK);
                assert_int_equal(r.position, pos);
            } else {
                assert_true(rc == HD_SSI_ERR_NO_START || rc == HD_SSI_ERR_NO_ACK);
            }
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dsp_helpers),
        cmocka_unit_test(test_foc_sincos),
        cmocka_unit_test(test_foc_step_transforms),
        cmocka_unit_test(test_foc_step_duties_match_svm),
        cmocka_unit_test(test_adc_current),
        cmocka_unit_test(test_ssi_crc6_every_width),
        cmocka_unit_test(test_ssi_frame_every_length),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
