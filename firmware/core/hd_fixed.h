/*
 * hd_fixed.h - fixed-point base library used by every controller.
 *
 * Conventions (DESIGN.md section 3, docs/fixed-point.md):
 *  - Qm.n: a signed integer x represents x * 2^-n.  "Q30" means n = 30 in an
 *    int32_t (range [-2, 2)), "Q16" means Q15.16 in an int32_t, etc.
 *  - Every narrowing rounds to nearest, ties away from zero ("round half away"),
 *    which is odd-symmetric: f(-x) == -f(x).  This keeps odd nonlinearities
 *    (friction, hysteresis) free of a direction bias.
 *  - Every result that can exceed its type saturates (never wraps).  The
 *    symmetric range [-INT32_MAX, INT32_MAX] is NOT enforced: INT32_MIN is a
 *    legal saturation result of the helpers unless a function says otherwise.
 *  - Right shifts of negative values are never done with `>>` on a signed type
 *    (implementation-defined in C99); the helpers below define them.
 *  - No globals, no hidden state, no float/double, no libc beyond stdint.
 *  - Shift counts and q values outside the documented ranges are clamped
 *    (s to 63, q to 62 resp. 31, n of hd_satn to [1, 64]: n >= 64 returns x),
 *    so no argument can cause undefined behaviour.
 *  - Measured accuracy of the nonlinear functions (tests/c/test_fixed.c):
 *    hd_exp_neg_q16 <= 1.06 LSB (Q30), hd_sincos_turn <= 0.92 LSB,
 *    hd_sign_smooth_q30 <= 0.875 LSB; all other helpers exact or 0.5 LSB.
 *
 * Each function documents: range, accuracy (max error in LSB of the result,
 * against the exact real-valued result) and cost (Cortex-M4 instructions per
 * call, measured by `make bench`, build/bench/cm4_cost.json).
 */
#ifndef HD_FIXED_H
#define HD_FIXED_H

#include <stdint.h>
#include <stdbool.h>

#define HD_Q30_ONE ((int32_t)1 << 30)
#define HD_Q16_ONE ((int32_t)1 << 16)
#define HD_Q15_ONE ((int32_t)1 << 15)

/* ---- saturation ------------------------------------------------------ */

/** Saturate a 64-bit value to int32. Exact. */
int32_t hd_sat32(int64_t x);
/** Saturate to the signed n-bit range [-(2^(n-1)), 2^(n-1)-1], 1 <= n <= 63. Exact. */
int64_t hd_satn(int64_t x, uint32_t n);
/** Clamp x into [lo, hi] (requires lo <= hi). Exact. */
int32_t hd_clamp32(int32_t x, int32_t lo, int32_t hi);
int64_t hd_clamp64(int64_t x, int64_t lo, int64_t hi);

/* ---- saturating add / sub / neg / abs ------------------------------- */

int32_t hd_add_sat(int32_t a, int32_t b);
int32_t hd_sub_sat(int32_t a, int32_t b);
/** -x, with -INT32_MIN saturating to INT32_MAX. */
int32_t hd_neg_sat(int32_t x);
/** |x|, with |INT32_MIN| saturating to INT32_MAX. */
int32_t hd_abs_sat(int32_t x);
int64_t hd_add64_sat(int64_t a, int64_t b);
int64_t hd_sub64_sat(int64_t a, int64_t b);
int64_t hd_neg64_sat(int64_t x);
int64_t hd_abs64_sat(int64_t x);

/* ---- shifts with defined rounding ----------------------------------- */

/** floor(x / 2^s), 0 <= s <= 63 (arithmetic shift right, defined for x < 0). */
int64_t hd_asr64_floor(int64_t x, uint32_t s);
/** round_half_away(x / 2^s), 0 <= s <= 63. Exact to 0.5 LSB. */
int64_t hd_asr64_rnd(int64_t x, uint32_t s);
/** round_half_away(x / 2^s) saturated to int32, 0 <= s <= 63. */
int32_t hd_asr32_rnd(int64_t x, uint32_t s);
/** x * 2^s saturated to int64, 0 <= s <= 63. */
int64_t hd_shl64_sat(int64_t x, uint32_t s);
/** x * 2^s saturated to int32, 0 <= s <= 31. */
int32_t hd_shl32_sat(int32_t x, uint32_t s);

/* ---- multiply ------------------------------------------------------- */

/** round_half_away(a*b / 2^q) saturated to int32; 0 <= q <= 62. Exact to 0.5 LSB. */
int32_t hd_mul_q(int32_t a, int32_t b, uint32_t q);
/** round_half_away(a*b / 2^q) saturated to int64, a 64-bit, b 32-bit (96-bit
 *  intermediate); 0 <= q <= 62. Exact to 0.5 LSB. */
int64_t hd_mul64x32_q(int64_t a, int32_t b, uint32_t q);
/** acc + a*b saturated to int64 (64-bit accumulate of a 32x32 product). Exact. */
int64_t hd_mac64(int64_t acc, int32_t a, int32_t b);

/* ---- divide --------------------------------------------------------- */

/** round_half_away(num * 2^q / den) saturated to int32; 0 <= q <= 31.
 *  den == 0 returns INT32_MAX, INT32_MIN or 0 by the sign of num. */
int32_t hd_div_q(int32_t num, int32_t den, uint32_t q);
/** round_half_away(num / den) for 64-bit operands, saturated;
 *  den == 0 returns INT64_MAX, INT64_MIN or 0 by the sign of num. */
int64_t hd_div64_rnd(int64_t num, int64_t den);

/** A divisor d > 0 that stays the same over many divisions (a parameter) with its
 *  reciprocal m = floor((2^64 - 1) / d): hd_divinv_rnd divides by two 64-bit
 *  multiplications and one correction instead of a long division. */
typedef struct {
    uint32_t d;         /* the divisor, >= 1 (0: not set up) */
    uint64_t m;         /* floor((2^64 - 1) / d) */
} hd_divinv_t;
/** Set v up for divisor d (d >= 1; d == 0 leaves v unset, d = 0).  One 64-bit
 *  division: call it where the divisor changes, not per period. */
void hd_divinv_init(hd_divinv_t *v, uint32_t d);
/** hd_div64_rnd(num, v->d) (v set up, d >= 1), the same value for every num:
 *  q = floor(|num| m / 2^64) is floor(|num| / d) or one less (m d > 2^64 - 1 - d),
 *  so one remainder check corrects it. */
int64_t hd_divinv_rnd(int64_t num, const hd_divinv_t *v);

/* ---- nonlinear functions -------------------------------------------- */

/** exp(-x) for x >= 0 given in Q16 (x < 0 is treated as 0, returns 1.0);
 *  result in Q30, monotone non-increasing in x, 0 for x >= ~21.5.
 *  Accuracy and cost: see docs/fixed-point.md. */
int32_t hd_exp_neg_q16(int32_t x_q16);

/** sin and cos of an angle given as a fraction of a turn: 2^32 == one turn,
 *  so the uint32 wraps exactly once per turn (meant to wrap).  Results in Q30.
 *  Accuracy and cost: see docs/fixed-point.md. */
void hd_sincos_turn(uint32_t angle, int32_t *sin_q30, int32_t *cos_q30);
/** The same with ~24-bit accuracy (error <= 64 LSB of Q30, ~6e-8) at about a
 *  third of the cost: for the 20 kHz current loop (hd_foc), whose sensors
 *  have 12 bits.  Results in [-2^30, 2^30]. */
void hd_sincos_turn_fast(uint32_t angle, int32_t *sin_q30, int32_t *cos_q30);
/** The sine of hd_sincos_turn_fast alone (the same word, Q30). */
int32_t hd_sin_turn_fast(uint32_t angle);

/** Smooth sign: with t = x / eps (eps > 0, same units as x), returns in Q30
 *  s(t) = t*(3 - t^2)/2 for |t| <= 1 and sign(t) otherwise: C1-continuous,
 *  odd, slope 1.5/eps at zero, exactly +-1 beyond +-eps.  eps <= 0 gives the
 *  plain sign (0 at 0). */
int32_t hd_sign_smooth_q30(int32_t x, int32_t eps);

/** floor(sqrt(x)) for x >= 0. Exact. */
uint32_t hd_isqrt64(uint64_t x);

/* ---- inline fast paths (hot loops) -----------------------------------------
 * hdf_X computes exactly what hd_X computes, for every input (bit-identical,
 * tests/c/test_fixed.c compares them on edges and 10^6 random arguments), but
 * inlines into the caller, where the shift counts and q are constants, so a
 * Q-format multiply is ~15 Cortex-M4 instructions instead of a call into two
 * helpers with variable 64-bit shifts (~85).  Rounding of signed values is
 * done as floor((x + 2^(s-1) - [x < 0]) / 2^s), which equals the magnitude
 * rounding of hd_asr64_rnd; the floor shift of a negative value is written
 * with complements (never `>>` on a signed type). */
#define HD_FX_INLINE static inline __attribute__((always_inline))

/* Cortex-M4 bodies.  On ARMv7E-M with the DSP extension (the STM32G474 and the
 * emulated mps2-an386) the helpers marked "M4:" below run a short inline-assembly
 * body that computes the same bits as the portable C body: QADD / QSUB are the
 * 32-bit saturating add / sub; the 64-bit saturating add / sub use the overflow
 * flag of ADDS/ADCS; the saturation 64 -> 32 compares the high word with the
 * sign of the low word; the rounding shift by a constant 1..31 uses an
 * arithmetic shift of the high word (logical when the rounding offset
 * overflowed a positive value).  The golden vectors prove the identity: the
 * kernels hdf_* of tests/golden/gv_fixed_inline.c compare these bodies on the
 * Cortex-M4 with the portable bodies on the host over edges and random
 * arguments (every shift count).  Define HD_FX_PORTABLE to use the C bodies on
 * the M4 as well. */
#if defined(__ARM_ARCH_7EM__) && defined(__ARM_FEATURE_DSP) && !defined(HD_FX_PORTABLE)
#define HD_FX_M4 1
#else
#define HD_FX_M4 0
#endif

/* the two words of an int64 bit pattern and back (no implementation-defined conversion) */
HD_FX_INLINE uint32_t hdf__lo(int64_t x)
{
    return (uint32_t)((uint64_t)x & 0xFFFFFFFFu);
}
HD_FX_INLINE uint32_t hdf__hi(int64_t x)
{
    return (uint32_t)((uint64_t)x >> 32);
}

/* bit pattern -> int64 without an implementation-defined conversion */
HD_FX_INLINE int64_t hdf__u2s64(uint64_t u)
{
    return (u > (uint64_t)INT64_MAX) ? (-(int64_t)(~u) - 1) : (int64_t)u;
}
/* floor(bit pattern u as a two's complement value / 2^s), 0 <= s <= 63; m = all ones if u is negative */
HD_FX_INLINE int64_t hdf__floor_shr(uint64_t u, uint64_t m, uint32_t s)
{
    return hdf__u2s64(((u ^ m) >> s) ^ m);
}
/* M4: CMP + conditional EOR, the limit from the sign of the high word */
HD_FX_INLINE int32_t hdf_sat32(int64_t x)
{
#if HD_FX_M4
    uint32_t r = hdf__lo(x);
    __asm__("cmp %[hi], %[r], asr #31\n\t"
            "it ne\n\t"
            "eorne %[r], %[m], %[hi], asr #31"
            : [r] "+r"(r) : [hi] "r"(hdf__hi(x)), [m] "r"((uint32_t)INT32_MAX) : "cc");
    return (r > (uint32_t)INT32_MAX) ? (-(int32_t)(~r) - 1) : (int32_t)r;
#else
    return (x > (int64_t)INT32_MAX) ? INT32_MAX : ((x < (int64_t)INT32_MIN) ? INT32_MIN : (int32_t)x);
#endif
}
HD_FX_INLINE int32_t hdf_clamp32(int32_t x, int32_t lo, int32_t hi)
{
    return (x < lo) ? lo : ((x > hi) ? hi : x);
}
HD_FX_INLINE int64_t hdf_clamp64(int64_t x, int64_t lo, int64_t hi)
{
    return (x < lo) ? lo : ((x > hi) ? hi : x);
}
/* M4: QADD */
HD_FX_INLINE int32_t hdf_add_sat(int32_t a, int32_t b)
{
    int32_t r;
#if HD_FX_M4
    __asm__("qadd %0, %1, %2" : "=r"(r) : "r"(a), "r"(b));
    return r;
#endif
    if (__builtin_add_overflow(a, b, &r)) {
        r = (b > 0) ? INT32_MAX : INT32_MIN;
    }
    return r;
}
/* M4: QSUB */
HD_FX_INLINE int32_t hdf_sub_sat(int32_t a, int32_t b)
{
    int32_t r;
#if HD_FX_M4
    __asm__("qsub %0, %1, %2" : "=r"(r) : "r"(a), "r"(b));
    return r;
#endif
    if (__builtin_sub_overflow(a, b, &r)) {
        r = (b < 0) ? INT32_MAX : INT32_MIN;
    }
    return r;
}
HD_FX_INLINE int32_t hdf_neg_sat(int32_t x)
{
    return (x == INT32_MIN) ? INT32_MAX : -x;
}
HD_FX_INLINE int32_t hdf_abs_sat(int32_t x)
{
    return (x == INT32_MIN) ? INT32_MAX : ((x < 0) ? -x : x);
}
/* M4: ADDS/ADCS; on overflow (V) the limit opposite to the wrapped sign */
HD_FX_INLINE int64_t hdf_add64_sat(int64_t a, int64_t b)
{
    int64_t r;
#if HD_FX_M4
    {
        uint32_t lo = hdf__lo(a);
        uint32_t hi = hdf__hi(a);
        __asm__("adds %[lo], %[lo], %[blo]\n\t"
                "adcs %[hi], %[hi], %[bhi]\n\t"
                "itt vs\n\t"
                "asrvs %[lo], %[hi], #31\n\t"
                "eorvs %[hi], %[lo], #0x80000000"
                : [lo] "+&r"(lo), [hi] "+&r"(hi) : [blo] "r"(hdf__lo(b)), [bhi] "r"(hdf__hi(b)) : "cc");
        return hdf__u2s64(((uint64_t)hi << 32) | lo);
    }
#endif
    if (__builtin_add_overflow(a, b, &r)) {
        r = (b > 0) ? INT64_MAX : INT64_MIN;
    }
    return r;
}
/* M4: SUBS/SBCS; on overflow (V) the limit opposite to the wrapped sign */
HD_FX_INLINE int64_t hdf_sub64_sat(int64_t a, int64_t b)
{
    int64_t r;
#if HD_FX_M4
    {
        uint32_t lo = hdf__lo(a);
        uint32_t hi = hdf__hi(a);
        __asm__("subs %[lo], %[lo], %[blo]\n\t"
                "sbcs %[hi], %[hi], %[bhi]\n\t"
                "itt vs\n\t"
                "asrvs %[lo], %[hi], #31\n\t"
                "eorvs %[hi], %[lo], #0x80000000"
                : [lo] "+&r"(lo), [hi] "+&r"(hi) : [blo] "r"(hdf__lo(b)), [bhi] "r"(hdf__hi(b)) : "cc");
        return hdf__u2s64(((uint64_t)hi << 32) | lo);
    }
#endif
    if (__builtin_sub_overflow(a, b, &r)) {
        r = (b < 0) ? INT64_MAX : INT64_MIN;
    }
    return r;
}
HD_FX_INLINE int64_t hdf_neg64_sat(int64_t x)
{
    return (x == INT64_MIN) ? INT64_MAX : -x;
}
HD_FX_INLINE int64_t hdf_abs64_sat(int64_t x)
{
    return (x == INT64_MIN) ? INT64_MAX : ((x < 0) ? -x : x);
}
/* M4: (constant s in 1..31) the two words shifted, the high one arithmetically */
HD_FX_INLINE int64_t hdf_asr64_floor(int64_t x, uint32_t s)
{
#if HD_FX_M4
    if (__builtin_constant_p(s) && s >= 1u && s <= 31u) {
        uint32_t lo = hdf__lo(x);
        uint32_t hi = hdf__hi(x);
        __asm__("lsr %[lo], %[lo], %[s]\n\t"
                "orr %[lo], %[lo], %[hi], lsl %[s2]\n\t"
                "asr %[hi], %[hi], %[s]"
                : [lo] "+&r"(lo), [hi] "+&r"(hi) : [s] "i"(s), [s2] "i"(32u - s));
        return hdf__u2s64(((uint64_t)hi << 32) | lo);
    }
#endif
    return hdf__floor_shr((uint64_t)x, (x < 0) ? UINT64_MAX : (uint64_t)0, (s > 63u) ? 63u : s);
}
/* M4: (constant s in 1..62, or s in 1..31 at run time) y = x + 2^(s-1) - [x < 0] by ADDS/ADCS, then the
 * shift; y shifts arithmetically, logically when the rounding offset overflowed
 * a positive x (within 2^(s-1) of INT64_MAX: y is then an unsigned value) */
HD_FX_INLINE int64_t hdf_asr64_rnd(int64_t x, uint32_t s)
{
#if HD_FX_M4
    if (__builtin_constant_p(s) && s >= 1u && s <= 31u) {
        uint32_t lo = hdf__lo(x);
        uint32_t yh;
        uint32_t t;
        __asm__("lsr %[t], %[hi], #31\n\t"
                "rsb %[t], %[t], %[h]\n\t"
                "adds %[lo], %[lo], %[t]\n\t"
                "adcs %[yh], %[hi], #0\n\t"
                "lsr %[lo], %[lo], %[s]\n\t"
                "orr %[lo], %[lo], %[yh], lsl %[s2]\n\t"
                "ite vs\n\t"
                "lsrvs %[yh], %[yh], %[s]\n\t"
                "asrvc %[yh], %[yh], %[s]"
                : [lo] "+&r"(lo), [yh] "=&r"(yh), [t] "=&r"(t)
                : [hi] "r"(hdf__hi(x)), [h] "i"((uint32_t)1 << ((s - 1u) & 31u)), [s] "i"(s),
                  [s2] "i"(32u - s)
                : "cc");
        return hdf__u2s64(((uint64_t)yh << 32) | lo);
    }
    if (__builtin_constant_p(s) && s == 32u) {
        /* the high word of y is the low word of the result; the sign word follows */
        uint32_t yh;
        uint32_t rh;
        uint32_t t;
        __asm__("lsr %[t], %[hi], #31\n\t"
                "rsb %[t], %[t], #0x80000000\n\t"
                "adds %[t], %[lo], %[t]\n\t"
                "adcs %[yh], %[hi], #0\n\t"
                "ite vs\n\t"
                "movvs %[rh], #0\n\t"
                "asrvc %[rh], %[yh], #31"
                : [yh] "=&r"(yh), [rh] "=&r"(rh), [t] "=&r"(t)
                : [lo] "r"(hdf__lo(x)), [hi] "r"(hdf__hi(x))
                : "cc");
        return hdf__u2s64(((uint64_t)rh << 32) | yh);
    }
    if (__builtin_constant_p(s) && s >= 33u && s <= 62u) {
        /* y = x - [x < 0] + 2^(s-1) (mod 2^64); the sign of x chooses the shift */
        uint32_t yh;
        uint32_t rl;
        uint32_t rh;
        uint32_t t;
        __asm__("adds %[t], %[lo], %[hi], asr #31\n\t"
                "adc %[yh], %[hi], %[hi], asr #31\n\t"
                "add %[yh], %[yh], %[h]\n\t"
                "cmp %[hi], #0\n\t"
                "itete lt\n\t"
                "asrlt %[rl], %[yh], %[k]\n\t"
                "lsrge %[rl], %[yh], %[k]\n\t"
                "asrlt %[rh], %[yh], #31\n\t"
                "movge %[rh], #0"
                : [yh] "=&r"(yh), [rl] "=&r"(rl), [rh] "=&r"(rh), [t] "=&r"(t)
                : [lo] "r"(hdf__lo(x)), [hi] "r"(hdf__hi(x)), [h] "i"((uint32_t)1 << ((s - 33u) & 31u)),
                  [k] "i"(s - 32u)
                : "cc");
        return hdf__u2s64(((uint64_t)rh << 32) | rl);
    }
    if (!__builtin_constant_p(s) && s - 1u < 31u) {
        /* a shift count known at run time only, 1..31: the same with register shifts */
        uint32_t lo = hdf__lo(x);
        uint32_t yh;
        uint32_t t;
        uint32_t u;
        __asm__("sub %[u], %[s], #1\n\t"
                "lsl %[u], %[one], %[u]\n\t"
                "sub %[t], %[u], %[hi], lsr #31\n\t"
                "adds %[lo], %[lo], %[t]\n\t"
                "adcs %[yh], %[hi], #0\n\t"
                "lsr %[lo], %[lo], %[s]\n\t"
                "rsb %[u], %[s], #32\n\t"
                "lsl %[t], %[yh], %[u]\n\t"
                "orr %[lo], %[lo], %[t]\n\t"
                "ite vs\n\t"
                "lsrvs %[yh], %[yh], %[s]\n\t"
                "asrvc %[yh], %[yh], %[s]"
                : [lo] "+&r"(lo), [yh] "=&r"(yh), [t] "=&r"(t), [u] "=&r"(u)
                : [hi] "r"(hdf__hi(x)), [s] "r"(s), [one] "r"(1u)
                : "cc");
        return hdf__u2s64(((uint64_t)yh << 32) | lo);
    }
#endif
    if (s > 63u) {
        s = 63u;
    }
    if (s == 0u) {
        return x;
    }
    {
        /* y = x + 2^(s-1) - [x < 0]: exact as a bit pattern (x >= 0: y < 2^64 unsigned;
         * x < 0: y is in the int64 range); negative only if x is */
        const uint64_t neg = (x < 0) ? UINT64_MAX : (uint64_t)0;
        const uint64_t y = (uint64_t)x + ((uint64_t)1 << (s - 1u)) + neg;
        return hdf__floor_shr(y, (uint64_t)0 - ((y & neg) >> 63), s);
    }
}
HD_FX_INLINE int32_t hdf_asr32_rnd(int64_t x, uint32_t s)
{
    return hdf_sat32(hdf_asr64_rnd(x, s));
}
/* hdf_asr32_rnd for an x whose rounded quotient is known to fit an int32 (the
 * caller's range analysis, e.g. x limited to int32 * 2^s): the low word of
 * hdf_asr64_rnd, no saturation.  M4 (constant s in 1..32): ADDS/ADC of the
 * rounding offset, then only the words of the low result word (6 instructions
 * for s < 32, 4 for s == 32, instead of 12 and 11). */
HD_FX_INLINE int32_t hdf_asr32_rnd_fit(int64_t x, uint32_t s)
{
#if HD_FX_M4
    if (__builtin_constant_p(s) && s >= 1u && s <= 31u) {
        uint32_t lo = hdf__lo(x);
        uint32_t yh;
        uint32_t t;
        __asm__("lsr %[t], %[hi], #31\n\t"
                "rsb %[t], %[t], %[h]\n\t"
                "adds %[lo], %[lo], %[t]\n\t"
                "adc %[yh], %[hi], #0\n\t"
                "lsr %[lo], %[lo], %[s]\n\t"
                "orr %[lo], %[lo], %[yh], lsl %[s2]"
                : [lo] "+&r"(lo), [yh] "=&r"(yh), [t] "=&r"(t)
                : [hi] "r"(hdf__hi(x)), [h] "i"((uint32_t)1 << ((s - 1u) & 31u)), [s] "i"(s),
                  [s2] "i"(32u - s)
                : "cc");
        return (lo > (uint32_t)INT32_MAX) ? (-(int32_t)(~lo) - 1) : (int32_t)lo;
    }
    if (__builtin_constant_p(s) && s == 32u) {
        uint32_t yh;
        uint32_t t;
        __asm__("lsr %[t], %[hi], #31\n\t"
                "rsb %[t], %[t], #0x80000000\n\t"
                "adds %[t], %[lo], %[t]\n\t"
                "adc %[yh], %[hi], #0"
                : [yh] "=&r"(yh), [t] "=&r"(t)
                : [lo] "r"(hdf__lo(x)), [hi] "r"(hdf__hi(x))
                : "cc");
        return (yh > (uint32_t)INT32_MAX) ? (-(int32_t)(~yh) - 1) : (int32_t)yh;
    }
#endif
    return (int32_t)hdf_asr64_rnd(x, s);
}
/* M4: (constant s in 1..31) the shifted words; SSAT of the high word to 32 - s
 * bits tells whether x * 2^s fits (else the limit of the sign of x) */
HD_FX_INLINE int64_t hdf_shl64_sat(int64_t x, uint32_t s)
{
#if HD_FX_M4
    if (__builtin_constant_p(s) && s >= 1u && s <= 31u) {
        uint32_t rl;
        uint32_t rh;
        uint32_t t;
        __asm__("ssat %[t], %[n], %[hi]\n\t"
                "lsl %[rh], %[hi], %[s]\n\t"
                "orr %[rh], %[rh], %[lo], lsr %[s2]\n\t"
                "lsl %[rl], %[lo], %[s]\n\t"
                "cmp %[t], %[hi]\n\t"
                "itt ne\n\t"
                "mvnne %[rl], %[hi], asr #31\n\t"
                "eorne %[rh], %[rl], #0x80000000"
                : [rl] "=&r"(rl), [rh] "=&r"(rh), [t] "=&r"(t)
                : [lo] "r"(hdf__lo(x)), [hi] "r"(hdf__hi(x)), [n] "i"(32u - s), [s] "i"(s), [s2] "i"(32u - s)
                : "cc");
        return hdf__u2s64(((uint64_t)rh << 32) | rl);
    }
#endif
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
HD_FX_INLINE int32_t hdf_mul_q(int32_t a, int32_t b, uint32_t q)
{
    return hdf_asr32_rnd((int64_t)a * (int64_t)b, (q > 62u) ? 62u : q);
}
/* a * b / 2^q rounded half away, saturated, for any int64 a (96-bit product as
 * t 2^32 + l with 0 <= l < 2^32, |t| < 2^63 after the rounding offset); q <= 62 */
/* M4: (constant q in 0..62) P = a b as (p2:p1:p0) by UMULL (low word x b as
 * unsigned), a correction for b < 0 and SMLAL (high word x b); P + 2^(q-1) -
 * [P < 0] shifted right by q; the limit of the sign of P when the bits above
 * the result are not its sign */
HD_FX_INLINE int64_t hdf__mul96_q(int64_t a, int32_t b, uint32_t q)
{
#if HD_FX_M4
    if (__builtin_constant_p(q) && q >= 1u && q <= 31u) {
        uint32_t p0;
        uint32_t p1;
        uint32_t p2;
        uint32_t n;
        uint32_t rl;
        uint32_t rh;
        __asm__("umull %[p0], %[p1], %[al], %[b]\n\t"
                "and %[n], %[al], %[b], asr #31\n\t"
                "subs %[p1], %[p1], %[n]\n\t"
                "sbc %[p2], %[p1], %[p1]\n\t"
                "smlal %[p1], %[p2], %[ah], %[b]\n\t"
                "asr %[n], %[p2], #31\n\t"
                "add %[rl], %[n], %[h]\n\t"
                "adds %[p0], %[p0], %[rl]\n\t"
                "adcs %[p1], %[p1], #0\n\t"
                "adc %[p2], %[p2], #0\n\t"
                "lsr %[rl], %[p0], %[q]\n\t"
                "orr %[rl], %[rl], %[p1], lsl %[q2]\n\t"
                "lsr %[rh], %[p1], %[q]\n\t"
                "orr %[rh], %[rh], %[p2], lsl %[q2]\n\t"
                "asr %[p0], %[p2], %[q]\n\t"
                "cmp %[p0], %[rh], asr #31\n\t"
                "itt ne\n\t"
                "mvnne %[rl], %[n]\n\t"
                "eorne %[rh], %[rl], #0x80000000"
                : [p0] "=&r"(p0), [p1] "=&r"(p1), [p2] "=&r"(p2), [n] "=&r"(n), [rl] "=&r"(rl), [rh] "=&r"(rh)
                : [al] "r"(hdf__lo(a)), [ah] "r"(hdf__hi(a)), [b] "r"(b), [h] "i"((uint32_t)1 << ((q - 1u) & 31u)),
                  [q] "i"(q), [q2] "i"(32u - q)
                : "cc");
        return hdf__u2s64(((uint64_t)rh << 32) | rl);
    }
    if (__builtin_constant_p(q) && q == 0u) {
        /* the product itself, saturated when (p2:p1) is not an int32 */
        uint32_t p0;
        uint32_t p1;
        uint32_t p2;
        uint32_t n;
        __asm__("umull %[p0], %[p1], %[al], %[b]\n\t"
                "and %[n], %[al], %[b], asr #31\n\t"
                "subs %[p1], %[p1], %[n]\n\t"
                "sbc %[p2], %[p1], %[p1]\n\t"
                "smlal %[p1], %[p2], %[ah], %[b]\n\t"
                "cmp %[p2], %[p1], asr #31\n\t"
                "itt ne\n\t"
                "mvnne %[p0], %[p2], asr #31\n\t"
                "eorne %[p1], %[p0], #0x80000000"
                : [p0] "=&r"(p0), [p1] "=&r"(p1), [p2] "=&r"(p2), [n] "=&r"(n)
                : [al] "r"(hdf__lo(a)), [ah] "r"(hdf__hi(a)), [b] "r"(b)
                : "cc");
        return hdf__u2s64(((uint64_t)p1 << 32) | p0);
    }
    if (__builtin_constant_p(q) && q >= 32u && q <= 62u) {
        /* P + 2^(q-1) - [P < 0]: the offset's words are (2^(q-33), 0) + [P < 0] x (-1, -1, -1)
         * (q = 32: 2^31 - [P < 0] in the low word); the result is (p2:p1) >> (q - 32), no saturation */
        uint32_t p0;
        uint32_t p1;
        uint32_t p2;
        uint32_t n;
        uint32_t rl;
        uint32_t rh;
        if (q == 32u) {
            __asm__("umull %[p0], %[p1], %[al], %[b]\n\t"
                    "and %[n], %[al], %[b], asr #31\n\t"
                    "subs %[p1], %[p1], %[n]\n\t"
                    "sbc %[p2], %[p1], %[p1]\n\t"
                    "smlal %[p1], %[p2], %[ah], %[b]\n\t"
                    "lsr %[n], %[p2], #31\n\t"
                    "rsb %[n], %[n], #0x80000000\n\t"
                    "adds %[p0], %[p0], %[n]\n\t"
                    "adcs %[rl], %[p1], #0\n\t"
                    "adc %[rh], %[p2], #0"
                    : [p0] "=&r"(p0), [p1] "=&r"(p1), [p2] "=&r"(p2), [n] "=&r"(n), [rl] "=&r"(rl), [rh] "=&r"(rh)
                    : [al] "r"(hdf__lo(a)), [ah] "r"(hdf__hi(a)), [b] "r"(b)
                    : "cc");
        } else {
            __asm__("umull %[p0], %[p1], %[al], %[b]\n\t"
                    "and %[n], %[al], %[b], asr #31\n\t"
                    "subs %[p1], %[p1], %[n]\n\t"
                    "sbc %[p2], %[p1], %[p1]\n\t"
                    "smlal %[p1], %[p2], %[ah], %[b]\n\t"
                    "asr %[n], %[p2], #31\n\t"
                    "adds %[p0], %[p0], %[n]\n\t"
                    "adcs %[p1], %[p1], %[n]\n\t"
                    "adc %[p2], %[p2], %[n]\n\t"
                    "adds %[p1], %[p1], %[h]\n\t"
                    "adc %[p2], %[p2], #0\n\t"
                    "lsr %[rl], %[p1], %[k]\n\t"
                    "orr %[rl], %[rl], %[p2], lsl %[k2]\n\t"
                    "asr %[rh], %[p2], %[k]"
                    : [p0] "=&r"(p0), [p1] "=&r"(p1), [p2] "=&r"(p2), [n] "=&r"(n), [rl] "=&r"(rl), [rh] "=&r"(rh)
                    : [al] "r"(hdf__lo(a)), [ah] "r"(hdf__hi(a)), [b] "r"(b),
                      [h] "i"((uint32_t)1 << ((q - 33u) & 31u)), [k] "i"((q - 32u) & 31u), [k2] "i"(64u - q)
                    : "cc");
        }
        return hdf__u2s64(((uint64_t)rh << 32) | rl);
    }
#endif
    {
    const int64_t hi = hdf_asr64_floor(a, 32u) * (int64_t)b;                     /* |.| <= 2^62 */
    const int64_t lo = (int64_t)((uint64_t)a & 0xFFFFFFFFu) * (int64_t)b;         /* |.| < 2^63 */
    int64_t t = hi + hdf_asr64_floor(lo, 32u);
    const uint32_t l = (uint32_t)((uint64_t)lo & 0xFFFFFFFFu);
    if (q == 0u) {
        if (t > (int64_t)INT32_MAX) {
            return INT64_MAX;
        }
        if (t < (int64_t)INT32_MIN) {
            return INT64_MIN;
        }
        return t * ((int64_t)1 << 32) + (int64_t)l;
    }
    {
        const uint64_t c = ((uint64_t)1 << (q - 1u)) - (((a < 0) != (b < 0)) ? 1u : 0u);
        const uint32_t l2 = l + (uint32_t)(c & 0xFFFFFFFFu);
        t += (int64_t)(c >> 32) + ((l2 < l) ? 1 : 0);
        if (q >= 32u) {
            return hdf_asr64_floor(t, q - 32u);
        }
        {
            const uint32_t sh = 32u - q;
            const int64_t lim = (int64_t)((uint64_t)INT64_MAX >> sh);
            if (t > lim) {
                return INT64_MAX;
            }
            if (t < -lim - 1) {
                return INT64_MIN;
            }
            return t * ((int64_t)1 << sh) + (int64_t)(l2 >> q);
        }
    }
    }
}
HD_FX_INLINE int64_t hdf_mul64x32_q(int64_t a, int32_t b, uint32_t q)
{
    const uint32_t qq = (q > 62u) ? 62u : q;
    if (a >= (int64_t)INT32_MIN && a <= (int64_t)INT32_MAX) {
#if HD_FX_M4
        /* SMULL: the compiler would multiply the sign-extended a as 64 x 64 bits */
        uint32_t l;
        uint32_t h;
        __asm__("smull %0, %1, %2, %3" : "=&r"(l), "=&r"(h) : "r"(hdf__lo(a)), "r"(b));
        return hdf_asr64_rnd(hdf__u2s64(((uint64_t)h << 32) | l), qq);
#else
        return hdf_asr64_rnd((int64_t)(int32_t)a * (int64_t)b, qq);
#endif
    }
    return hdf__mul96_q(a, b, qq);
}
/* M4: SMULL for the product (the compiler multiplies 64 x 64 bits once either
 * factor's sign word is shared with other 64-bit work of the caller), then the
 * saturating 64-bit add */
HD_FX_INLINE int64_t hdf_mac64(int64_t acc, int32_t a, int32_t b)
{
#if HD_FX_M4
    uint32_t pl;
    uint32_t ph;
    __asm__("smull %[pl], %[ph], %[x], %[y]" : [pl] "=&r"(pl), [ph] "=&r"(ph) : [x] "r"(a), [y] "r"(b));
    return hdf_add64_sat(acc, hdf__u2s64(((uint64_t)ph << 32) | pl));
#else
    return hdf_add64_sat(acc, (int64_t)a * (int64_t)b);
#endif
}
/* ---- 32-bit DSP forms ---------------------------------------------------------
 * Each computes, for every input, the bits of one Cortex-M4 DSP instruction
 * (wrapping where the instruction wraps, never undefined in C): the caller's
 * written range analysis shows that the wrap cannot happen where it is used.
 * The golden kernels hdf_smmulr, hdf_smmlar, hdf_dot2_rnd32, hdf_dot2_64 and hdf_ssat
 * (tests/golden/gv_fixed_inline.c) compare the M4 bodies with the portable
 * ones over edges and random arguments. */

/* a bit pattern as int32 (no implementation-defined conversion) */
HD_FX_INLINE int32_t hdf__s32(uint32_t u)
{
    return (u > (uint32_t)INT32_MAX) ? (-(int32_t)(~u) - 1) : (int32_t)u;
}
/** floor((a b + 2^31) / 2^32): the 64-bit product's high word rounded half up
 *  (never overflows: |a b| <= 2^62).  M4: SMMULR. */
HD_FX_INLINE int32_t hdf_smmulr(int32_t a, int32_t b)
{
#if HD_FX_M4
    int32_t r;
    __asm__("smmulr %0, %1, %2" : "=r"(r) : "r"(a), "r"(b));
    return r;
#else
    return hdf__s32((uint32_t)(((uint64_t)((int64_t)a * b) + 0x80000000u) >> 32));
#endif
}
/** acc + floor((a b + 2^31) / 2^32), modulo 2^32 (the high word of acc 2^32 + a b + 2^31):
 *  a rounded Q-format product added in one instruction.  M4: SMMLAR. */
HD_FX_INLINE int32_t hdf_smmlar(int32_t acc, int32_t a, int32_t b)
{
#if HD_FX_M4
    int32_t r;
    __asm__("smmlar %0, %1, %2, %3" : "=r"(r) : "r"(a), "r"(b), "r"(acc));
    return r;
#else
    return hdf__s32((uint32_t)((((uint64_t)(uint32_t)acc << 32) + (uint64_t)((int64_t)a * b) + 0x80000000u) >> 32));
#endif
}
/** floor((a b + c d + 2^31) / 2^32), the sum taken modulo 2^64 and the high word
 *  returned (exact when |a b + c d| < 2^63 - 2^31): a dot product of two terms
 *  rounded once, half up.  M4: the rounding offset as the accumulator's low word,
 *  two SMLAL. */
HD_FX_INLINE int32_t hdf_dot2_rnd32(int32_t a, int32_t b, int32_t c, int32_t d)
{
#if HD_FX_M4
    uint32_t lo = 0x80000000u;
    uint32_t hi = 0u;
    __asm__("smlal %[lo], %[hi], %[a], %[b]\n\t"
            "smlal %[lo], %[hi], %[c], %[d]"
            : [lo] "+&r"(lo), [hi] "+&r"(hi) : [a] "r"(a), [b] "r"(b), [c] "r"(c), [d] "r"(d));
    return hdf__s32(hi);
#else
    return hdf__s32((uint32_t)(((uint64_t)((int64_t)a * b) + (uint64_t)((int64_t)c * d) + 0x80000000u) >> 32));
#endif
}
/** a b + c d as int64, the sum taken modulo 2^64 (exact when |a b + c d| < 2^63): two
 *  products accumulated without a rounding.  M4: SMULL + SMLAL. */
HD_FX_INLINE int64_t hdf_dot2_64(int32_t a, int32_t b, int32_t c, int32_t d)
{
#if HD_FX_M4
    uint32_t lo;
    uint32_t hi;
    __asm__("smull %[lo], %[hi], %[a], %[b]\n\t"
            "smlal %[lo], %[hi], %[x], %[y]"
            : [lo] "=&r"(lo), [hi] "=&r"(hi) : [a] "r"(a), [b] "r"(b), [x] "r"(c), [y] "r"(d));
    return hdf__u2s64(((uint64_t)hi << 32) | lo);
#else
    return hdf__u2s64((uint64_t)((int64_t)a * b) + (uint64_t)((int64_t)c * d));
#endif
}
/** x saturated to the signed n-bit range [-2^(n-1), 2^(n-1) - 1], 1 <= n <= 32
 *  (n outside: clamped).  M4 (constant n, x known at run time only): SSAT; a constant
 *  x folds at compile time. */
HD_FX_INLINE int32_t hdf_ssat(int32_t x, uint32_t n)
{
#if HD_FX_M4
    if (__builtin_constant_p(n) && n >= 1u && n <= 32u && !__builtin_constant_p(x)) {
        int32_t r;
        __asm__("ssat %0, %1, %2" : "=r"(r) : "i"(n), "r"(x));
        return r;
    }
#endif
    {
        const uint32_t k = (n < 1u) ? 0u : ((n > 32u) ? 31u : n - 1u);
        const int64_t hi = ((int64_t)1 << k) - 1;
        return (x > hi) ? (int32_t)hi : ((x < -hi - 1) ? (int32_t)(-hi - 1) : x);
    }
}

/* hd_div64_rnd(num, den) for a small positive divisor, 2 <= den <= 65535 (a
 * constant such as HD_LOOP_HZ at the call site): |num| is divided in three
 * 32-bit UDIV steps (the high word, then two 16-bit digits; each dividend
 * (r 2^16 + digit) < den 2^16 <= 2^32) instead of the 64-bit long division;
 * same quotient and rounding (half away).  den == 1 returns num, other den
 * go to hd_div64_rnd.  |result| <= 2^62 + 1 for den >= 2: no saturation. */
HD_FX_INLINE int64_t hdf_div64_rnd_u16(int64_t num, uint32_t den)
{
    if (den < 2u || den > 65535u) {
        return (den == 1u) ? num : hd_div64_rnd(num, (int64_t)den);
    }
    {
        const uint64_t m = (num < 0) ? ((uint64_t)0 - (uint64_t)num) : (uint64_t)num;
        const uint32_t hi = (uint32_t)(m >> 32);
        const uint32_t lo = (uint32_t)(m & 0xFFFFFFFFu);
        const uint32_t q2 = hi / den;
        uint32_t t = ((hi - q2 * den) << 16) | (lo >> 16);
        const uint32_t q1 = t / den;
        t = ((t - q1 * den) << 16) | (lo & 0xFFFFu);
        const uint32_t q0 = t / den;
        const uint32_t r = t - q0 * den;
        uint64_t quo = ((uint64_t)q2 << 32) + ((uint64_t)q1 << 16) + q0;
        if (r >= den - r) {
            quo += 1u;
        }
        return (num < 0) ? -(int64_t)quo : (int64_t)quo;
    }
}

#endif /* HD_FIXED_H */
