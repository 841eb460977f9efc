/*
 * test_fixed.c - unit tests of the fixed-point base library (hd_fixed.h).
 *
 * Style: every test gets a fresh fixture from setUp() (a seeded PRNG) and
 * tearDown() releases it, as in Unity.  For every helper:
 *   - exhaustive edge cases: INT32/INT64 MIN/MAX, -1, 0, 1, powers of two and
 *     their neighbours, ties at exactly 0.5 LSB, shift 0 and the max shift;
 *   - HD_TEST_N (10^6) random cases (edge-biased) against a wider-precision
 *     reference (__int128; libm double for exp/sin/cos/smooth sign, whose
 *     documented max error in LSB is asserted here and printed as
 *     "# measured ..." so docs/fixed-point.md can quote it).
 * The reference implementations below are written differently from the
 * library on purpose (128-bit arithmetic, floor/ceil formulas).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <cmocka.h>

#include "hd_fixed.h"

#define HD_TEST_N 1000000u

/* Documented accuracy bounds (docs/fixed-point.md), LSB of the Q30 result
 * against the exact real value. */
#define EXP_MAX_LSB      1.10
#define SINCOS_MAX_LSB   1.00
#define SIGN_MAX_LSB     1.00

typedef __int128 i128;
#define TWO30 1073741824.0
#define PI_D 3.14159265358979323846

/* ---- fixture: PRNG ----------------------------------------------------- */

typedef struct {
    uint64_t s;
} fixture_t;

static uint64_t rnd64(fixture_t *f)
{
    /* xorshift64* */
    f->s ^= f->s >> 12;
    f->s ^= f->s << 25;
    f->s ^= f->s >> 27;
    return f->s * 0x2545F4914F6CDD1DULL;
}

static const int64_t edge64[] = {
    INT64_MIN, INT64_MIN + 1, INT64_MIN + 2, -4611686018427387905LL, -4611686018427387904LL,
    -4611686018427387903LL, -4294967297LL, -4294967296LL, -4294967295LL,
    -2147483649LL, -2147483648LL, -2147483647LL, -1073741825LL, -1073741824LL,
    -65537, -65536, -65535, -32768, -3, -2, -1, 0, 1, 2, 3, 32768, 65535, 65536, 65537,
    1073741824LL, 1073741825LL, 2147483647LL, 2147483648LL, 2147483649LL, 4294967295LL,
    4294967296LL, 4294967297LL, 4611686018427387903LL, 4611686018427387904LL,
    INT64_MAX - 2, INT64_MAX - 1, INT64_MAX
};
#define N_EDGE64 (sizeof edge64 / sizeof edge64[0])

static const int32_t edge32[] = {
    INT32_MIN, INT32_MIN + 1, INT32_MIN + 2, -1073741825, -1073741824, -1073741823,
    -65537, -65536, -65535, -32769, -32768, -32767, -3, -2, -1, 0, 1, 2, 3,
    32767, 32768, 32769, 65535, 65536, 65537, 1073741823, 1073741824, 1073741825,
    INT32_MAX - 2, INT32_MAX - 1, INT32_MAX
};
#define N_EDGE32 (sizeof edge32 / sizeof edge32[0])

/* 25 %: an edge value or a power of two +-1; else uniform. */
static int64_t rand_e64(fixture_t *f)
{
    uint64_t r = rnd64(f);
    switch (r & 7u) {
    case 0:
        return edge64[(r >> 8) % N_EDGE64];
    case 1: {
        uint32_t k = (uint32_t)((r >> 8) % 63u);
        int64_t v = (int64_t)((uint64_t)1 << k) + (int64_t)((r >> 16) % 3u) - 1;
        return ((r >> 20) & 1u) ? -v : v;
    }
    default:
        /* uniform over a random bit width, so small values occur too */
        {
            uint32_t w = (uint32_t)((r >> 8) % 64u) + 1u;
            uint64_t u = rnd64(f);
            if (w < 64u) {
                int64_t m = (int64_t)(u & (((uint64_t)1 << w) - 1u));
                return ((r >> 20) & 1u) ? -m : m;
            }
            return (int64_t)u;
        }
    }
}

static int32_t rand_e32(fixture_t *f)
{
    uint64_t r = rnd64(f);
    if ((r & 7u) == 0u) {
        return edge32[(r >> 8) % N_EDGE32];
    }
    if ((r & 7u) == 1u) {
        uint32_t k = (uint32_t)((r >> 8) % 31u);
        int32_t v = (int32_t)(1u << k) + (int32_t)((r >> 16) % 3u) - 1;
        return ((r >> 20) & 1u) ? -v : v;
    }
    {
        uint32_t w = (uint32_t)((r >> 8) % 32u) + 1u;
        uint32_t u = (uint32_t)(rnd64(f) >> 32);
        if (w < 32u) {
            int32_t m = (int32_t)(u & ((1u << w) - 1u));
            return ((r >> 20) & 1u) ? -m : m;
        }
        return (int32_t)u;
    }
}

static int setUp(void **state)
{
    static fixture_t fx;
    fx.s = 0x9E3779B97F4A7C15ULL;
    *state = &fx;
    return 0;
}

static int tearDown(void **state)
{
    *state = NULL;
    return 0;
}

/* ---- 128-bit references --------------------------------------------------- */

static i128 ref_sat(i128 v, i128 lo, i128 hi)
{
    return v < lo ? lo : (v > hi ? hi : v);
}

static i128 sat32(i128 v) { return ref_sat(v, INT32_MIN, INT32_MAX); }
static i128 sat64(i128 v) { return ref_sat(v, INT64_MIN, INT64_MAX); }

/* floor(v / 2^s) via truncating division and a correction. */
static i128 ref_floor_div_pow2(i128 v, unsigned s)
{
    i128 d = (i128)1 << s;
    i128 q = v / d;
    if (q * d != v && v < 0) {
        q -= 1;
    }
    return q;
}

/* round half away from zero of n / d (d != 0): floor((2|n| + |d|) / (2|d|)). */
static i128 ref_div_rnd(i128 n, i128 d)
{
    int neg = (n < 0) != (d < 0);
    i128 an = n < 0 ? -n : n;
    i128 ad = d < 0 ? -d : d;
    i128 m = (2 * an + ad) / (2 * ad);
    return neg ? -m : m;
}

static i128 ref_rnd_pow2(i128 v, unsigned s)
{
    return ref_div_rnd(v, (i128)1 << s);
}

static void fail_i128(const char *what, i128 got, i128 want, long long a, long long b, unsigned s)
{
    print_error("%s(a=%lld, b=%lld, s=%u): got %lld want %lld\n", what, a, b, s,
                (long long)got, (long long)want);
    fail();
}

#define CHECK(what, got, want, a, b, s) do { \
        i128 g_ = (i128)(got), w_ = (i128)(want); \
        if (g_ != w_) fail_i128(what, g_, w_, (long long)(a), (long long)(b), (unsigned)(s)); \
    } while (0)

/* ---- saturation --------------------------------------------------------------- */

static void test_sat_and_clamp(void **state)
{
    fixture_t *f = *state;
    uint32_t i, j, k;
    for (i = 0; i < N_EDGE64; i++) {
        int64_t x = edge64[i];
        CHECK("hd_sat32", hd_sat32(x), sat32(x), x, 0, 0);
        for (k = 1; k <= 63; k++) {
            i128 hi = ((i128)1 << (k - 1)) - 1;
            CHECK("hd_satn", hd_satn(x, k), ref_sat(x, -hi - 1, hi), x, 0, k);
        }
        for (j = 0; j < N_EDGE64; j++) {
            int64_t lo = edge64[i] < edge64[j] ? edge64[i] : edge64[j];
            int64_t hi = edge64[i] < edge64[j] ? edge64[j] : edge64[i];
            for (k = 0; k < N_EDGE64; k++) {
                CHECK("hd_clamp64", hd_clamp64(edge64[k], lo, hi), ref_sat(edge64[k], lo, hi), edge64[k], lo, 0);
            }
        }
    }
    for (i = 0; i < N_EDGE32; i++) {
        for (j = 0; j < N_EDGE32; j++) {
            int32_t lo = edge32[i] < edge32[j] ? edge32[i] : edge32[j];
            int32_t hi = edge32[i] < edge32[j] ? edge32[j] : edge32[i];
            for (k = 0; k < N_EDGE32; k++) {
                CHECK("hd_clamp32", hd_clamp32(edge32[k], lo, hi), ref_sat(edge32[k], lo, hi), edge32[k], lo, 0);
            }
        }
    }
    /* satn boundaries: n = 1 gives [-1, 0], n = 63 gives [-2^62, 2^62 - 1] */
    assert_true(hd_satn(5, 1) == 0 && hd_satn(-5, 1) == -1);
    assert_true(hd_satn(INT64_MAX, 63) == ((int64_t)1 << 62) - 1);
    assert_true(hd_satn(INT64_MIN, 63) == -((int64_t)1 << 62));
    assert_true(hd_satn(INT64_MIN, 64) == INT64_MIN);   /* n >= 64: no-op (clamped) */
    for (i = 0; i < HD_TEST_N; i++) {
        int64_t x = rand_e64(f);
        uint32_t n = (uint32_t)(rnd64(f) % 63u) + 1u;
        i128 hi = ((i128)1 << (n - 1)) - 1;
        int32_t a = rand_e32(f), b = rand_e32(f), c = rand_e32(f);
        int32_t lo32 = a < b ? a : b, hi32 = a < b ? b : a;
        CHECK("hd_sat32", hd_sat32(x), sat32(x), x, 0, 0);
        CHECK("hd_satn", hd_satn(x, n), ref_sat(x, -hi - 1, hi), x, 0, n);
        CHECK("hd_clamp32", hd_clamp32(c, lo32, hi32), ref_sat(c, lo32, hi32), c, lo32, 0);
    }
}

/* ---- add / sub / neg / abs ------------------------------------------------------ */

static void check_addsub32(int32_t a, int32_t b)
{
    CHECK("hd_add_sat", hd_add_sat(a, b), sat32((i128)a + b), a, b, 0);
    CHECK("hd_sub_sat", hd_sub_sat(a, b), sat32((i128)a - b), a, b, 0);
    CHECK("hd_neg_sat", hd_neg_sat(a), sat32(-(i128)a), a, 0, 0);
    CHECK("hd_abs_sat", hd_abs_sat(a), sat32(a < 0 ? -(i128)a : (i128)a), a, 0, 0);
}

static void check_addsub64(int64_t a, int64_t b)
{
    CHECK("hd_add64_sat", hd_add64_sat(a, b), sat64((i128)a + b), a, b, 0);
    CHECK("hd_sub64_sat", hd_sub64_sat(a, b), sat64((i128)a - b), a, b, 0);
    CHECK("hd_neg64_sat", hd_neg64_sat(a), sat64(-(i128)a), a, 0, 0);
    CHECK("hd_abs64_sat", hd_abs64_sat(a), sat64(a < 0 ? -(i128)a : (i128)a), a, 0, 0);
}

static void test_add_sub_neg_abs(void **state)
{
    fixture_t *f = *state;
    uint32_t i, j;
    for (i = 0; i < N_EDGE32; i++) {
        for (j = 0; j < N_EDGE32; j++) {
            check_addsub32(edge32[i], edge32[j]);
        }
    }
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE64; j++) {
            check_addsub64(edge64[i], edge64[j]);
        }
    }
    assert_int_equal(hd_neg_sat(INT32_MIN), INT32_MAX);
    assert_int_equal(hd_abs_sat(INT32_MIN), INT32_MAX);
    assert_true(hd_neg64_sat(INT64_MIN) == INT64_MAX);
    assert_true(hd_abs64_sat(INT64_MIN) == INT64_MAX);
    assert_int_equal(hd_add_sat(INT32_MAX, 1), INT32_MAX);
    assert_int_equal(hd_sub_sat(INT32_MIN, 1), INT32_MIN);
    for (i = 0; i < HD_TEST_N; i++) {
        check_addsub32(rand_e32(f), rand_e32(f));
        check_addsub64(rand_e64(f), rand_e64(f));
    }
}

/* ---- shifts --------------------------------------------------------------------- */

static void check_shifts(int64_t x, uint32_t s)
{
    CHECK("hd_asr64_floor", hd_asr64_floor(x, s), ref_floor_div_pow2(x, s), x, 0, s);
    CHECK("hd_asr64_rnd", hd_asr64_rnd(x, s), ref_rnd_pow2(x, s), x, 0, s);
    CHECK("hd_asr32_rnd", hd_asr32_rnd(x, s), sat32(ref_rnd_pow2(x, s)), x, 0, s);
    CHECK("hd_shl64_sat", hd_shl64_sat(x, s), sat64((i128)x * ((i128)1 << s)), x, 0, s);
    if (s <= 31u && x >= INT32_MIN && x <= INT32_MAX) {
        CHECK("hd_shl32_sat", hd_shl32_sat((int32_t)x, s), sat32((i128)x * ((i128)1 << s)), x, 0, s);
    }
}

static void test_shifts(void **state)
{
    fixture_t *f = *state;
    uint32_t i, s;
    for (i = 0; i < N_EDGE64; i++) {
        for (s = 0; s <= 63u; s++) {
            check_shifts(edge64[i], s);
        }
    }
    /* ties at exactly 0.5 LSB round away from zero, both signs, every s */
    for (s = 1; s <= 62u; s++) {
        int64_t half = (int64_t)1 << (s - 1);
        int64_t one = (int64_t)1 << s;
        assert_true(hd_asr64_rnd(half, s) == 1);
        assert_true(hd_asr64_rnd(-half, s) == -1);
        assert_true(hd_asr64_rnd(half - 1, s) == 0);
        assert_true(hd_asr64_rnd(-half + 1, s) == 0);
        assert_true(hd_asr64_rnd(3 * half, s) == 2);
        assert_true(hd_asr64_rnd(-3 * half, s) == -2);
        assert_true(hd_asr64_floor(-half, s) == -1);
        assert_true(hd_asr64_floor(-one, s) == -1);
        assert_true(hd_asr64_floor(-one - 1, s) == -2);
    }
    assert_true(hd_asr64_rnd(INT64_MIN, 63) == -1);
    assert_true(hd_asr64_rnd(INT64_MAX, 63) == 1);
    assert_true(hd_asr64_floor(INT64_MIN, 63) == -1);
    assert_true(hd_asr64_floor(-1, 63) == -1);
    assert_true(hd_asr64_rnd(INT64_MIN, 0) == INT64_MIN);
    assert_true(hd_shl64_sat(-1, 63) == INT64_MIN);
    assert_true(hd_shl64_sat(1, 63) == INT64_MAX);
    assert_int_equal(hd_shl32_sat(-1, 31), INT32_MIN);
    assert_int_equal(hd_shl32_sat(1, 31), INT32_MAX);
    for (i = 0; i < HD_TEST_N; i++) {
        check_shifts(rand_e64(f), (uint32_t)(rnd64(f) % 64u));
    }
}

/* ---- multiply ---------------------------------------------------------------- */

static void check_mul(int32_t a, int32_t b, int64_t a64, uint32_t q)
{
    i128 p = (i128)a * b;
    CHECK("hd_mul_q", hd_mul_q(a, b, q), sat32(ref_rnd_pow2(p, q)), a, b, q);
    CHECK("hd_mul64x32_q", hd_mul64x32_q(a64, b, q), sat64(ref_rnd_pow2((i128)a64 * b, q)), a64, b, q);
}

static void test_multiply(void **state)
{
    fixture_t *f = *state;
    uint32_t i, j, k, q;
    for (i = 0; i < N_EDGE32; i++) {
        for (j = 0; j < N_EDGE32; j++) {
            for (q = 0; q <= 62u; q++) {
                check_mul(edge32[i], edge32[j], edge32[i], q);
            }
        }
    }
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE32; j++) {
            for (q = 0; q <= 62u; q++) {
                check_mul(edge32[j], edge32[j], edge64[i], q);
            }
            for (k = 0; k < N_EDGE32; k++) {
                CHECK("hd_mac64", hd_mac64(edge64[i], edge32[j], edge32[k]),
                      sat64((i128)edge64[i] + (i128)edge32[j] * edge32[k]), edge64[i], edge32[j], 0);
            }
        }
    }
    /* ties: 0.5 in Q30 times 1 LSB -> exactly half an LSB */
    assert_int_equal(hd_mul_q(1, HD_Q30_ONE / 2, 30), 1);
    assert_int_equal(hd_mul_q(-1, HD_Q30_ONE / 2, 30), -1);
    assert_int_equal(hd_mul_q(3, HD_Q30_ONE / 2, 30), 2);
    assert_int_equal(hd_mul_q(-3, HD_Q30_ONE / 2, 30), -2);
    assert_int_equal(hd_mul_q(INT32_MIN, INT32_MIN, 0), INT32_MAX);
    assert_int_equal(hd_mul_q(INT32_MIN, INT32_MIN, 62), 1);
    assert_true(hd_mul64x32_q(INT64_MIN, INT32_MIN, 0) == INT64_MAX);
    assert_true(hd_mul64x32_q(INT64_MIN, INT32_MIN, 31) == INT64_MAX);
    assert_true(hd_mul64x32_q(INT64_MIN, -1, 0) == INT64_MAX);
    assert_true(hd_mul64x32_q(INT64_MIN, 1, 0) == INT64_MIN);
    assert_true(hd_mul64x32_q(INT64_MIN, INT32_MIN, 62) == ((int64_t)1 << 32));
    assert_true(hd_mac64(INT64_MAX, 1, 1) == INT64_MAX);
    assert_true(hd_mac64(INT64_MIN, -1, 1) == INT64_MIN);
    for (i = 0; i < HD_TEST_N; i++) {
        int32_t a = rand_e32(f), b = rand_e32(f);
        int64_t a64 = rand_e64(f), acc = rand_e64(f);
        check_mul(a, b, a64, (uint32_t)(rnd64(f) % 63u));
        CHECK("hd_mac64", hd_mac64(acc, a, b), sat64((i128)acc + (i128)a * b), acc, a, 0);
    }
}

/* ---- divide -------------------------------------------------------------------- */

static void check_div(int32_t n, int32_t d, int64_t n64, int64_t d64, uint32_t q)
{
    i128 w32 = (d == 0) ? (n > 0 ? INT32_MAX : (n < 0 ? INT32_MIN : 0))
                        : sat32(ref_div_rnd((i128)n * ((i128)1 << q), d));
    i128 w64 = (d64 == 0) ? (n64 > 0 ? INT64_MAX : (n64 < 0 ? INT64_MIN : 0))
                          : sat64(ref_div_rnd(n64, d64));
    CHECK("hd_div_q", hd_div_q(n, d, q), w32, n, d, q);
    CHECK("hd_div64_rnd", hd_div64_rnd(n64, d64), w64, n64, d64, 0);
}

static void test_divide(void **state)
{
    fixture_t *f = *state;
    uint32_t i, j, q;
    for (i = 0; i < N_EDGE32; i++) {
        for (j = 0; j < N_EDGE32; j++) {
            for (q = 0; q <= 31u; q++) {
                check_div(edge32[i], edge32[j], edge64[0], 1, q);
            }
        }
    }
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE64; j++) {
            check_div(0, 1, edge64[i], edge64[j], 0);
        }
    }
    /* ties: 1/2 -> 1, -1/2 -> -1, 3/2 -> 2; zero divisor by sign of num */
    assert_int_equal(hd_div_q(1, 2, 0), 1);
    assert_int_equal(hd_div_q(-1, 2, 0), -1);
    assert_int_equal(hd_div_q(3, -2, 0), -2);
    assert_int_equal(hd_div_q(5, 0, 16), INT32_MAX);
    assert_int_equal(hd_div_q(-5, 0, 16), INT32_MIN);
    assert_int_equal(hd_div_q(0, 0, 16), 0);
    assert_int_equal(hd_div_q(INT32_MIN, -1, 0), INT32_MAX);
    assert_int_equal(hd_div_q(INT32_MIN, 1, 0), INT32_MIN);
    assert_int_equal(hd_div_q(1, 3, 30), 357913941);
    assert_true(hd_div64_rnd(INT64_MIN, -1) == INT64_MAX);
    assert_true(hd_div64_rnd(INT64_MIN, 2) == INT64_MIN / 2);
    assert_true(hd_div64_rnd(-7, 2) == -4);
    assert_true(hd_div64_rnd(7, 0) == INT64_MAX);
    for (i = 0; i < HD_TEST_N; i++) {
        int32_t n = rand_e32(f), d = rand_e32(f);
        check_div(n, d, rand_e64(f), rand_e64(f), (uint32_t)(rnd64(f) % 32u));
    }
}

/* ---- isqrt ---------------------------------------------------------------------- */

static void check_isqrt(uint64_t x)
{
    i128 r = hd_isqrt64(x);
    if (!(r * r <= (i128)x && (r + 1) * (r + 1) > (i128)x)) {
        print_error("hd_isqrt64(%llu) = %lld\n", (unsigned long long)x, (long long)r);
        fail();
    }
}

static void test_isqrt(void **state)
{
    fixture_t *f = *state;
    uint64_t i;
    for (i = 0; i < 70000u; i++) {
        check_isqrt(i);
    }
    for (i = 1; i <= 0xFFFFFFFFu; i = i * 3u + 1u) {
        check_isqrt(i * i);
        check_isqrt(i * i - 1u);
        check_isqrt(i * i + 1u);
    }
    assert_true(hd_isqrt64(UINT64_MAX) == 0xFFFFFFFFu);
    assert_true(hd_isqrt64(0xFFFFFFFE00000001ULL) == 0xFFFFFFFFu);
    assert_true(hd_isqrt64(0xFFFFFFFE00000000ULL) == 0xFFFFFFFEu);
    for (i = 0; i < HD_TEST_N; i++) {
        uint64_t r = rnd64(f);
        check_isqrt(r >> (r & 63u));
    }
}

/* ---- nonlinear functions against libm -------------------------------------------- */

static void test_exp_neg(void **state)
{
    fixture_t *f = *state;
    double maxe = 0.0;
    int32_t x, prev = HD_Q30_ONE, worst = 0;
    uint32_t i;
    /* exhaustive over the live range [0, 22] (1.44e6 inputs) */
    for (x = 0; x <= (23 << 16); x++) {
        int32_t r = hd_exp_neg_q16(x);
        double e = fabs((double)r - exp(-(double)x / 65536.0) * TWO30);
        if (e > maxe) {
            maxe = e;
            worst = x;
        }
        if (r > prev) {
            print_error("hd_exp_neg_q16 not monotone at x=%d: %d > %d\n", x, r, prev);
            fail();
        }
        prev = r;
    }
    print_message("# measured hd_exp_neg_q16 max error %.4f LSB (Q30) at x=%d (Q16)\n", maxe, worst);
    assert_true(maxe <= EXP_MAX_LSB);
    assert_int_equal(hd_exp_neg_q16(0), HD_Q30_ONE);
    assert_int_equal(hd_exp_neg_q16(-1), HD_Q30_ONE);
    assert_int_equal(hd_exp_neg_q16(INT32_MIN), HD_Q30_ONE);
    assert_int_equal(hd_exp_neg_q16(INT32_MAX), 0);
    assert_int_equal(hd_exp_neg_q16(22 << 16), 0);
    assert_true(llabs((long long)hd_exp_neg_q16(1 << 16) - 395007542LL) <= 1);   /* e^-1 * 2^30 = 395007542.4 */
    for (i = 0; i < HD_TEST_N; i++) {
        int32_t v = rand_e32(f);
        double ex = v <= 0 ? TWO30 : exp(-(double)v / 65536.0) * TWO30;
        if (fabs((double)hd_exp_neg_q16(v) - ex) > EXP_MAX_LSB) {
            print_error("hd_exp_neg_q16(%d) = %d, exact %.3f\n", v, hd_exp_neg_q16(v), ex);
            fail();
        }
    }
}

/* hd_sincos_turn_fast (current loop): <= 64 LSB of Q30 against double, within
 * [-2^30, 2^30], exact at the quadrant points, sin odd / cos even */
static void test_sincos_fast(void **state)
{
    fixture_t *f = *state;
    double maxe = 0.0;
    uint32_t i;
    static const uint32_t special[] = {0u, 1u, 0x3FFFFFu, 0x400000u, 0x3FFFFFFFu, 0x40000000u,
                                       0x40000001u, 0x7FFFFFFFu, 0x80000000u, 0xBFFFFFFFu,
                                       0xC0000000u, 0xFFFFFFFFu, 0x20000000u, 0x15555555u};
    for (i = 0; i < HD_TEST_N + sizeof special / sizeof special[0]; i++) {
        const uint32_t a = (i < sizeof special / sizeof special[0]) ? special[i] : (uint32_t)(rnd64(f) >> 32);
        const double th = (double)a * (2.0 * PI_D / 4294967296.0);
        int32_t s, c, sn, cn;
        hd_sincos_turn_fast(a, &s, &c);
        maxe = fmax(maxe, fmax(fabs((double)s - sin(th) * TWO30), fabs((double)c - cos(th) * TWO30)));
        if (hd_sin_turn_fast(a) != s) {         /* the sine alone: the same word */
            print_error("hd_sin_turn_fast(0x%08x) = %d, hd_sincos_turn_fast sine %d\n", a, hd_sin_turn_fast(a), s);
            fail();
        }
        assert_true(s >= -(1 << 30) && s <= (1 << 30) && c >= -(1 << 30) && c <= (1 << 30));
        hd_sincos_turn_fast(0u - a, &sn, &cn);
        if (a != 0x80000000u && (sn != -s || cn != c)) {
            print_error("hd_sincos_turn_fast symmetry broken at 0x%08x\n", a);
            fail();
        }
    }
    print_message("# measured hd_sincos_turn_fast max error %.2f LSB (Q30)\n", maxe);
    assert_true(maxe <= 64.0);
    {
        static const uint32_t q[4] = {0u, 0x40000000u, 0x80000000u, 0xC0000000u};
        static const int32_t es[4] = {0, 1 << 30, 0, -(1 << 30)};
        static const int32_t ec[4] = {1 << 30, 0, -(1 << 30), 0};
        int32_t s, c;
        for (i = 0; i < 4u; i++) {
            hd_sincos_turn_fast(q[i], &s, &c);
            assert_int_equal(s, es[i]);
            assert_int_equal(c, ec[i]);
        }
    }
}

static void test_sincos(void **state)
{
    fixture_t *f = *state;
    double maxs = 0.0, maxc = 0.0;
    uint32_t i;
    static const uint32_t special[] = {0u, 1u, 0x3FFFFFu, 0x400000u, 0x3FFFFFFFu, 0x40000000u,
                                       0x40000001u, 0x7FFFFFFFu, 0x80000000u, 0xBFFFFFFFu,
                                       0xC0000000u, 0xFFFFFFFFu, 0x20000000u, 0x15555555u};
    for (i = 0; i < HD_TEST_N + sizeof special / sizeof special[0]; i++) {
        uint32_t a = (i < sizeof special / sizeof special[0]) ? special[i] : (uint32_t)(rnd64(f) >> 32);
        int32_t s, c, sn, cn;
        double th = (double)a * (2.0 * PI_D / 4294967296.0);
        double es, ec;
        hd_sincos_turn(a, &s, &c);
        es = fabs((double)s - sin(th) * TWO30);
        ec = fabs((double)c - cos(th) * TWO30);
        maxs = es > maxs ? es : maxs;
        maxc = ec > maxc ? ec : maxc;
        /* exact symmetries: sin odd, cos even (angle -a = 2^32 - a) */
        hd_sincos_turn(0u - a, &sn, &cn);
        if (a != 0x80000000u && (sn != -s || cn != c)) {
            print_error("hd_sincos_turn symmetry broken at 0x%08x\n", a);
            fail();
        }
    }
    print_message("# measured hd_sincos_turn max error sin %.4f cos %.4f LSB (Q30)\n", maxs, maxc);
    assert_true(maxs <= SINCOS_MAX_LSB && maxc <= SINCOS_MAX_LSB);
    {
        int32_t s, c;
        hd_sincos_turn(0u, &s, &c);
        assert_int_equal(s, 0);
        assert_int_equal(c, HD_Q30_ONE);
        hd_sincos_turn(0x40000000u, &s, &c);
        assert_int_equal(s, HD_Q30_ONE);
        assert_int_equal(c, 0);
        hd_sincos_turn(0x80000000u, &s, &c);
        assert_int_equal(s, 0);
        assert_int_equal(c, -HD_Q30_ONE);
        hd_sincos_turn(0xC0000000u, &s, &c);
        assert_int_equal(s, -HD_Q30_ONE);
        assert_int_equal(c, 0);
    }
}

static double ref_sign_smooth(int32_t x, int32_t eps)
{
    double t;
    if (eps <= 0) {
        return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0);
    }
    t = (double)x / (double)eps;
    if (t >= 1.0) {
        return 1.0;
    }
    if (t <= -1.0) {
        return -1.0;
    }
    return t * (3.0 - t * t) / 2.0;
}

static void test_sign_smooth(void **state)
{
    fixture_t *f = *state;
    double maxe = 0.0;
    uint32_t i;
    int32_t x, prev;
    const int32_t eps0 = 1000003;
    /* dense sweep across one eps: odd, monotone, C0 at +-eps */
    prev = hd_sign_smooth_q30(-eps0 - 10, eps0);
    assert_int_equal(prev, -HD_Q30_ONE);
    for (x = -eps0 - 9; x <= eps0 + 10; x++) {
        int32_t r = hd_sign_smooth_q30(x, eps0);
        if (r < prev || r != -hd_sign_smooth_q30(-x, eps0)) {
            print_error("hd_sign_smooth_q30 not monotone/odd at x=%d\n", x);
            fail();
        }
        prev = r;
    }
    assert_int_equal(hd_sign_smooth_q30(eps0, eps0), HD_Q30_ONE);
    assert_int_equal(hd_sign_smooth_q30(-eps0, eps0), -HD_Q30_ONE);
    assert_int_equal(hd_sign_smooth_q30(0, eps0), 0);
    assert_int_equal(hd_sign_smooth_q30(5, 0), HD_Q30_ONE);
    assert_int_equal(hd_sign_smooth_q30(-5, -3), -HD_Q30_ONE);
    assert_int_equal(hd_sign_smooth_q30(0, 0), 0);
    assert_int_equal(hd_sign_smooth_q30(INT32_MIN, INT32_MAX), -HD_Q30_ONE);
    assert_int_equal(hd_sign_smooth_q30(INT32_MIN + 1, INT32_MAX), -HD_Q30_ONE);
    assert_int_equal(hd_sign_smooth_q30(INT32_MAX - 1, INT32_MAX), hd_sign_smooth_q30(INT32_MAX - 1, INT32_MAX));
    for (i = 0; i < HD_TEST_N; i++) {
        int32_t e = rand_e32(f);
        int32_t v;
        double err;
        if ((i & 1u) && e > 0) {
            /* half the cases inside the smooth band */
            v = (int32_t)((int64_t)(rnd64(f) % (2u * (uint64_t)e + 1u)) - e);
        } else {
            v = rand_e32(f);
        }
        err = fabs((double)hd_sign_smooth_q30(v, e) - ref_sign_smooth(v, e) * TWO30);
        maxe = err > maxe ? err : maxe;
    }
    for (x = -eps0; x <= eps0; x += 7) {
        double err = fabs((double)hd_sign_smooth_q30(x, eps0) - ref_sign_smooth(x, eps0) * TWO30);
        maxe = err > maxe ? err : maxe;
    }
    print_message("# measured hd_sign_smooth_q30 max error %.4f LSB (Q30)\n", maxe);
    assert_true(maxe <= SIGN_MAX_LSB);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_sat_and_clamp, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_add_sub_neg_abs, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_shifts, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_multiply, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_divide, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_isqrt, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_exp_neg, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_sincos, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_sincos_fast, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_sign_smooth, setUp, tearDown),
    };
    return cmocka_run_group_tests_name("hd_fixed", tests, NULL, NULL);
}
