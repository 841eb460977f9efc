/*
 * hd_vel_observer.c - type-2 tracking observer (formats: see hd_vel_observer.h).
 */
#include "hd_vel_observer.h"
#include "hd_fixed.h"

/* ---- inline copies of the hd_fixed.h helpers used per period ---------------
 * Same C code as firmware/core/hd_fixed.c (bit-identical results); inlined so
 * that the shift counts, which are constants at the call sites, fold into a
 * few instructions on the Cortex-M4 instead of a call with variable 64-bit
 * shifts.  See docs/fixed-point.md for the contracts. */
#define FX_INLINE static inline __attribute__((always_inline))
FX_INLINE uint64_t vobs_mag64(int64_t x)
{
    return (x < 0) ? ((uint64_t)0 - (uint64_t)x) : (uint64_t)x;
}
FX_INLINE int64_t vobs_neg_mag(uint64_t m)
{
    return (m == 0u) ? 0 : (-(int64_t)(m - 1u) - 1);
}
FX_INLINE int64_t vobs_signed_sat64(uint64_t m, bool neg)
{
    if (neg) {
        return (m >= ((uint64_t)1 << 63)) ? INT64_MIN : vobs_neg_mag(m);
    }
    return (m > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)m;
}
FX_INLINE uint64_t vobs_ushr_rnd(uint64_t m, uint32_t s)
{
    if (s == 0u) {
        return m;
    }
    return (m >> s) + ((m >> (s - 1u)) & 1u);
}
FX_INLINE int32_t vobs_sat32(int64_t x)
{
    if (x > (int64_t)INT32_MAX) {
        return INT32_MAX;
    }
    if (x < (int64_t)INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)x;
}
FX_INLINE int64_t vobs_add64_sat(int64_t a, int64_t b)
{
    if (b > 0 && a > INT64_MAX - b) {
        return INT64_MAX;
    }
    if (b < 0 && a < INT64_MIN - b) {
        return INT64_MIN;
    }
    return a + b;
}
FX_INLINE int64_t vobs_sub64_sat(int64_t a, int64_t b)
{
    if (b < 0 && a > INT64_MAX + b) {
        return INT64_MAX;
    }
    if (b > 0 && a < INT64_MIN + b) {
        return INT64_MIN;
    }
    return a - b;
}
FX_INLINE int64_t vobs_clamp64(int64_t x, int64_t lo, int64_t hi)
{
    if (x < lo) {
        return lo;
    }
    if (x > hi) {
        return hi;
    }
    return x;
}
FX_INLINE int64_t vobs_asr64_floor(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;
    }
    if (x >= 0) {
        return (int64_t)((uint64_t)x >> s);
    }
    return -1 - (int64_t)((uint64_t)(-1 - x) >> s);
}
FX_INLINE int64_t vobs_asr64_rnd(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;
    }
    if (s == 0u) {
        return x;
    }
    if (x >= 0) {
        return (int64_t)vobs_ushr_rnd((uint64_t)x, s);
    }
    return -(int64_t)vobs_ushr_rnd(vobs_mag64(x), s);
}
FX_INLINE int32_t vobs_asr32_rnd(int64_t x, uint32_t s)
{
    return vobs_sat32(vobs_asr64_rnd(x, s));
}
FX_INLINE int64_t vobs_shl64_sat(int64_t x, uint32_t s)
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
FX_INLINE int32_t vobs_mul_q(int32_t a, int32_t b, uint32_t q)
{
    const int64_t p = (int64_t)a * (int64_t)b;
    if (q > 62u) {
        q = 62u;
    }
    return vobs_asr32_rnd(p, q);
}
FX_INLINE int64_t vobs_mul64x32_q(int64_t a, int32_t b, uint32_t q)
{
    if (a >= (int64_t)INT32_MIN && a <= (int64_t)INT32_MAX) {
        /* |a*b| <= 2^62: the 64-bit product is exact, round half away as below */
        return vobs_asr64_rnd((int64_t)(int32_t)a * (int64_t)b, (q > 62u) ? 62u : q);
    }
    const bool neg = (a < 0) != (b < 0);
    const uint64_t ua = vobs_mag64(a);
    const uint32_t ub = (uint32_t)vobs_mag64(b);
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
    return vobs_signed_sat64(m, neg);
}
FX_INLINE int64_t vobs_mac64(int64_t acc, int32_t a, int32_t b)
{
    return vobs_add64_sat(acc, (int64_t)a * (int64_t)b);
}

/* T = 1e-4 s in Q44: 2^44 / 10000 = 1759218604.4416 -> 1759218604 (rel. error 2.5e-10;
 * the loop closes on the measurement, so this only scales the gains by that much). */
#define HD_VELOBS_T_Q44 1759218604
#define HD_VELOBS_T_SHIFT 44u

void hd_velobs_reset(hd_velobs_t *s, hd_angle_t theta)
{
    s->theta = theta;
    s->frac = 0;
    s->vel = 0;
    s->err = 0;
}

void hd_velobs_step(hd_velobs_t *s, const hd_velobs_cfg_t *c, hd_angle_t theta_meas)
{
    /* error against the full-precision estimate (theta + frac), 2^-48 turn */
    int64_t e48;
    if (theta_meas > -(INT64_C(1) << 46) && theta_meas < (INT64_C(1) << 46) &&
        s->theta > -(INT64_C(1) << 46) && s->theta < (INT64_C(1) << 46)) {
        /* |angles| < 2^46 turn * 2^-32: nothing below saturates, the same value directly */
        e48 = (theta_meas - s->theta) * 65536 - (int64_t)s->frac;
    } else {
        e48 = vobs_sub64_sat(vobs_sub64_sat(vobs_shl64_sat(theta_meas, 16u), vobs_shl64_sat(s->theta, 16u)),
                           (int64_t)s->frac);
    }
    s->err = vobs_asr32_rnd(e48, 16u);
    /* vel [2^-48 turn/s] += (Ki T)[Q16 1/s] * e [2^-48 turn] / 2^16 */
    s->vel = vobs_add64_sat(s->vel, vobs_mul64x32_q(e48, c->ki_dt, 16u));
    /* angle advance in 2^-48 turn: T * vel + (Kp T) * e */
    int64_t adv = vobs_mul64x32_q(s->vel, HD_VELOBS_T_Q44, HD_VELOBS_T_SHIFT);
    adv = vobs_add64_sat(adv, vobs_mul64x32_q(e48, c->kp_dt, 16u));
    adv = vobs_add64_sat(adv, (int64_t)s->frac);
    const int64_t whole = vobs_asr64_floor(adv, 16u);
    s->frac = (int32_t)(adv - whole * 65536);
    s->theta = vobs_add64_sat(s->theta, whole);
}

hd_vel_out_t hd_velobs_vel_out(const hd_velobs_t *s)
{
    return vobs_asr32_rnd(s->vel, 16u);
}

int64_t hd_velobs_vel48(const hd_velobs_t *s)
{
    return s->vel;
}

void hd_velobs_design(hd_velobs_cfg_t *c, int32_t w_q16, int32_t zeta_q16)
{
    /* kp_dt (Q16) = 2 zeta w T ; ki_dt (Q16) = w^2 T.  T = 1/HD_LOOP_HZ. */
    const int64_t two_zw_q16 = 2 * (int64_t)hd_mul_q(zeta_q16, w_q16, 16u);
    c->kp_dt = hd_sat32(hd_div64_rnd(two_zw_q16, HD_LOOP_HZ));
    const int64_t w2_q16 = hd_mul64x32_q((int64_t)w_q16, w_q16, 16u);
    c->ki_dt = hd_sat32(hd_div64_rnd(w2_q16, HD_LOOP_HZ));
}
