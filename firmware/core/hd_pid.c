/*
 * hd_pid.c - PID loop (formats: see hd_pid.h).
 */
#include "hd_pid.h"
#include "hd_fixed.h"

/* ---- inline copies of the hd_fixed.h helpers used per period ---------------
 * Same C code as firmware/core/hd_fixed.c (bit-identical results); inlined so
 * that the shift counts, which are constants at the call sites, fold into a
 * few instructions on the Cortex-M4 instead of a call with variable 64-bit
 * shifts.  See docs/fixed-point.md for the contracts. */
#define FX_INLINE static inline __attribute__((always_inline))
FX_INLINE uint64_t pid_mag64(int64_t x)
{
    return (x < 0) ? ((uint64_t)0 - (uint64_t)x) : (uint64_t)x;
}
FX_INLINE int64_t pid_neg_mag(uint64_t m)
{
    return (m == 0u) ? 0 : (-(int64_t)(m - 1u) - 1);
}
FX_INLINE int64_t pid_signed_sat64(uint64_t m, bool neg)
{
    if (neg) {
        return (m >= ((uint64_t)1 << 63)) ? INT64_MIN : pid_neg_mag(m);
    }
    return (m > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)m;
}
FX_INLINE uint64_t pid_ushr_rnd(uint64_t m, uint32_t s)
{
    if (s == 0u) {
        return m;
    }
    return (m >> s) + ((m >> (s - 1u)) & 1u);
}
FX_INLINE int32_t pid_sat32(int64_t x)
{
    if (x > (int64_t)INT32_MAX) {
        return INT32_MAX;
    }
    if (x < (int64_t)INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)x;
}
FX_INLINE int64_t pid_add64_sat(int64_t a, int64_t b)
{
    if (b > 0 && a > INT64_MAX - b) {
        return INT64_MAX;
    }
    if (b < 0 && a < INT64_MIN - b) {
        return INT64_MIN;
    }
    return a + b;
}
FX_INLINE int64_t pid_sub64_sat(int64_t a, int64_t b)
{
    if (b < 0 && a > INT64_MAX + b) {
        return INT64_MAX;
    }
    if (b > 0 && a < INT64_MIN + b) {
        return INT64_MIN;
    }
    return a - b;
}
FX_INLINE int64_t pid_clamp64(int64_t x, int64_t lo, int64_t hi)
{
    if (x < lo) {
        return lo;
    }
    if (x > hi) {
        return hi;
    }
    return x;
}
FX_INLINE int64_t pid_asr64_floor(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;
    }
    if (x >= 0) {
        return (int64_t)((uint64_t)x >> s);
    }
    return -1 - (int64_t)((uint64_t)(-1 - x) >> s);
}
FX_INLINE int64_t pid_asr64_rnd(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;
    }
    if (s == 0u) {
        return x;
    }
    if (x >= 0) {
        return (int64_t)pid_ushr_rnd((uint64_t)x, s);
    }
    return -(int64_t)pid_ushr_rnd(pid_mag64(x), s);
}
FX_INLINE int32_t pid_asr32_rnd(int64_t x, uint32_t s)
{
    return pid_sat32(pid_asr64_rnd(x, s));
}
FX_INLINE int64_t pid_shl64_sat(int64_t x, uint32_t s)
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
FX_INLINE int32_t pid_mul_q(int32_t a, int32_t b, uint32_t q)
{
    const int64_t p = (int64_t)a * (int64_t)b;
    if (q > 62u) {
        q = 62u;
    }
    return pid_asr32_rnd(p, q);
}
FX_INLINE int64_t pid_mul64x32_q(int64_t a, int32_t b, uint32_t q)
{
    if (a >= (int64_t)INT32_MIN && a <= (int64_t)INT32_MAX) {
        /* |a*b| <= 2^62: the 64-bit product is exact, round half away as below */
        return pid_asr64_rnd((int64_t)(int32_t)a * (int64_t)b, (q > 62u) ? 62u : q);
    }
    const bool neg = (a < 0) != (b < 0);
    const uint64_t ua = pid_mag64(a);
    const uint32_t ub = (uint32_t)pid_mag64(b);
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
    return pid_signed_sat64(m, neg);
}
FX_INLINE int64_t pid_mac64(int64_t acc, int32_t a, int32_t b)
{
    return pid_add64_sat(acc, (int64_t)a * (int64_t)b);
}

void hd_pid_reset(hd_pid_t *s)
{
    s->integ = 0;
    s->dfilt = 0;
    s->meas_prev = 0;
    s->p = 0;
    s->i = 0;
    s->d = 0;
    s->out = 0;
    s->saturated = 0;
    s->primed = 0;
}

void hd_pid_preload(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t out_i)
{
    int32_t v = hd_clamp32(out_i, c->out_min, c->out_max);
    s->integ = pid_shl64_sat((int64_t)v, c->shift);
    s->i = v;
}

/* The step with the gain shift as a parameter; hd_pid_step() calls it with the
 * shifts the drive uses (16, 32) as constants so each gets its own folded copy. */
FX_INLINE int32_t pid_core(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff,
                           const uint32_t shift)
{
    const int32_t e = hd_sub_sat(ref, meas);

    /* derivative on measurement, first-order filtered, in in-LSB * 2^16 per period */
    int64_t dmeas = 0;
    if (s->primed) {
        dmeas = (int64_t)meas - (int64_t)s->meas_prev;
    }
    s->meas_prev = meas;
    s->primed = 1;
    {
        const int64_t target = pid_shl64_sat(dmeas, 16);
        const int64_t diff = pid_sub64_sat(target, s->dfilt);
        /* |diff| < 2^49 so the 64x32 product fits the helper's 96-bit intermediate */
        /* d_alpha == 1.0 (no filter): the product is diff itself, exactly */
        const int64_t step = (c->d_alpha == HD_Q30_ONE) ? diff : pid_mul64x32_q(diff, c->d_alpha, 30);
        s->dfilt = pid_add64_sat(s->dfilt, step);
    }

    const int32_t p = pid_mul_q(c->kp, e, shift);
    /* kd_fs == 0 (no D term): the product is exactly 0 */
    const int32_t d = (c->kd_fs == 0) ? 0
                      : hd_neg_sat((int32_t)pid_sat32(pid_mul64x32_q(s->dfilt, c->kd_fs, shift + 16u)));

    /* conditional integration: tentative update, kept unless it deepens saturation */
    const int64_t lim_hi = pid_shl64_sat((int64_t)c->out_max, shift);
    const int64_t lim_lo = pid_shl64_sat((int64_t)c->out_min, shift);
    int64_t integ_new = pid_mac64(s->integ, c->ki_dt, e);
    integ_new = pid_clamp64(integ_new, lim_lo, lim_hi);
    int32_t i_new = pid_asr32_rnd(integ_new, shift);

    int64_t u = (int64_t)p + (int64_t)i_new + (int64_t)d + (int64_t)ff;
    if ((u > (int64_t)c->out_max && integ_new > s->integ) ||
        (u < (int64_t)c->out_min && integ_new < s->integ)) {
        integ_new = s->integ;                       /* freeze */
        i_new = pid_asr32_rnd(integ_new, shift);
        u = (int64_t)p + (int64_t)i_new + (int64_t)d + (int64_t)ff;
    }
    s->integ = integ_new;

    const int64_t uc = pid_clamp64(u, (int64_t)c->out_min, (int64_t)c->out_max);
    s->saturated = (uc != u) ? 1u : 0u;
    s->p = p;
    s->i = i_new;
    s->d = d;
    s->out = (int32_t)uc;
    return s->out;
}

int32_t hd_pid_step(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff)
{
    switch (c->shift) {
    case 16u:
        return pid_core(s, c, ref, meas, ff, 16u);
    case 32u:
        return pid_core(s, c, ref, meas, ff, 32u);
    default:
        return pid_core(s, c, ref, meas, ff, c->shift);
    }
}
