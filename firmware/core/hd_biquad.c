/*
 * hd_biquad.c - transposed direct form II biquads, 64-bit state, Q2.30 coefficients.
 */
#include "hd_biquad.h"
#include "hd_fixed.h"

/* ---- inline copies of the hd_fixed.h helpers used per period ---------------
 * Same C code as firmware/core/hd_fixed.c (bit-identical results); inlined so
 * that the shift counts, which are constants at the call sites, fold into a
 * few instructions on the Cortex-M4 instead of a call with variable 64-bit
 * shifts.  See docs/fixed-point.md for the contracts. */
#define FX_INLINE static inline __attribute__((always_inline))
FX_INLINE uint64_t bq_mag64(int64_t x)
{
    return (x < 0) ? ((uint64_t)0 - (uint64_t)x) : (uint64_t)x;
}
FX_INLINE int64_t bq_neg_mag(uint64_t m)
{
    return (m == 0u) ? 0 : (-(int64_t)(m - 1u) - 1);
}
FX_INLINE int64_t bq_signed_sat64(uint64_t m, bool neg)
{
    if (neg) {
        return (m >= ((uint64_t)1 << 63)) ? INT64_MIN : bq_neg_mag(m);
    }
    return (m > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)m;
}
FX_INLINE uint64_t bq_ushr_rnd(uint64_t m, uint32_t s)
{
    if (s == 0u) {
        return m;
    }
    return (m >> s) + ((m >> (s - 1u)) & 1u);
}
FX_INLINE int32_t bq_sat32(int64_t x)
{
    if (x > (int64_t)INT32_MAX) {
        return INT32_MAX;
    }
    if (x < (int64_t)INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)x;
}
FX_INLINE int64_t bq_add64_sat(int64_t a, int64_t b)
{
    if (b > 0 && a > INT64_MAX - b) {
        return INT64_MAX;
    }
    if (b < 0 && a < INT64_MIN - b) {
        return INT64_MIN;
    }
    return a + b;
}
FX_INLINE int64_t bq_sub64_sat(int64_t a, int64_t b)
{
    if (b < 0 && a > INT64_MAX + b) {
        return INT64_MAX;
    }
    if (b > 0 && a < INT64_MIN + b) {
        return INT64_MIN;
    }
    return a - b;
}
FX_INLINE int64_t bq_clamp64(int64_t x, int64_t lo, int64_t hi)
{
    if (x < lo) {
        return lo;
    }
    if (x > hi) {
        return hi;
    }
    return x;
}
FX_INLINE int64_t bq_asr64_floor(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;
    }
    if (x >= 0) {
        return (int64_t)((uint64_t)x >> s);
    }
    return -1 - (int64_t)((uint64_t)(-1 - x) >> s);
}
FX_INLINE int64_t bq_asr64_rnd(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;
    }
    if (s == 0u) {
        return x;
    }
    if (x >= 0) {
        return (int64_t)bq_ushr_rnd((uint64_t)x, s);
    }
    return -(int64_t)bq_ushr_rnd(bq_mag64(x), s);
}
FX_INLINE int32_t bq_asr32_rnd(int64_t x, uint32_t s)
{
    return bq_sat32(bq_asr64_rnd(x, s));
}
FX_INLINE int64_t bq_shl64_sat(int64_t x, uint32_t s)
{
    if (x == 0) {
        return 0;
    }
    if (s >= 63u) {
        return (x > 0) ? INT64_MAX : INT64_MIN;
    }
    {
        const int64_t lim = (int64_t)((uint64_t)INT64_MAX >> s);
        if (x > lim) {
            return INT64_MAX;
        }
        if (x < -lim - 1) {
            return INT64_MIN;
        }
        return x * (int64_t)((uint64_t)1 << s);
    }
}
FX_INLINE int32_t bq_mul_q(int32_t a, int32_t b, uint32_t q)
{
    const int64_t p = (int64_t)a * (int64_t)b;
    if (q > 62u) {
        q = 62u;
    }
    return bq_asr32_rnd(p, q);
}
FX_INLINE int64_t bq_mul64x32_q(int64_t a, int32_t b, uint32_t q)
{
    if (a >= (int64_t)INT32_MIN && a <= (int64_t)INT32_MAX) {
        /* |a*b| <= 2^62: the 64-bit product is exact, round half away as below */
        return bq_asr64_rnd((int64_t)(int32_t)a * (int64_t)b, (q > 62u) ? 62u : q);
    }
    const bool neg = (a < 0) != (b < 0);
    const uint64_t ua = bq_mag64(a);
    const uint32_t ub = (uint32_t)bq_mag64(b);
    const uint64_t al = (uint64_t)(uint32_t)ua;
    const uint64_t ah = ua >> 32;
    const uint64_t plo = al * (uint64_t)ub;
    const uint64_t pmid = ah * (uint64_t)ub;
    uint64_t lo = plo + (pmid << 32);
    uint64_t hi = (pmid >> 32) + ((lo < plo) ? 1u : 0u);
    uint64_t m;
    if (q > 62u) {
        q = 62u;
    }
    if (q > 0u) {
        const uint64_t half = (uint64_t)1 << (q - 1u);
        const uint64_t lo2 = lo + half;
        hi += (lo2 < lo) ? 1u : 0u;
        lo = lo2;
        m = (lo >> q) | (hi << (64u - q));
        hi >>= q;
    } else {
        m = lo;
    }
    if (hi != 0u) {
        return neg ? INT64_MIN : INT64_MAX;
    }
    return bq_signed_sat64(m, neg);
}
FX_INLINE int64_t bq_mac64(int64_t acc, int32_t a, int32_t b)
{
    return bq_add64_sat(acc, (int64_t)a * (int64_t)b);
}

void hd_biquad_identity(hd_biquad_coef_t *c)
{
    c->b0 = HD_Q30_ONE;
    c->b1 = 0;
    c->b2 = 0;
    c->a1 = 0;
    c->a2 = 0;
}

void hd_biquad_reset(hd_biquad_state_t *s)
{
    s->s1 = 0;
    s->s2 = 0;
}

int32_t hd_biquad_step(hd_biquad_state_t *s, const hd_biquad_coef_t *c, int32_t x)
{
    /* acc = b0 x + s1 keeps 30 fractional bits; the FULL-precision acc (not the
     * rounded y) is fed back, so the output rounding is not amplified by 1/A(z)
     * (which is large for a narrow notch). */
    const int64_t acc = bq_mac64(s->s1, c->b0, x);
    const int32_t y = bq_asr32_rnd(acc, 30u);
    int64_t s1 = bq_mac64(s->s2, c->b1, x);
    s1 = bq_sub64_sat(s1, bq_mul64x32_q(acc, c->a1, 30u));
    int64_t s2 = bq_mac64(0, c->b2, x);
    s2 = bq_sub64_sat(s2, bq_mul64x32_q(acc, c->a2, 30u));
    s->s1 = s1;
    s->s2 = s2;
    return y;
}

void hd_biquad_chain_reset(hd_biquad_chain_t *s)
{
    uint32_t i;
    for (i = 0; i < HD_BIQUAD_MAX; i++) {
        hd_biquad_reset(&s->s[i]);
    }
}

int32_t hd_biquad_chain_step(hd_biquad_chain_t *s, const hd_biquad_chain_cfg_t *c, int32_t x)
{
    uint32_t i;
    const uint32_t n = (c->n < HD_BIQUAD_MAX) ? c->n : HD_BIQUAD_MAX;
    for (i = 0; i < n; i++) {
        x = hd_biquad_step(&s->s[i], &c->c[i], x);
    }
    return x;
}
