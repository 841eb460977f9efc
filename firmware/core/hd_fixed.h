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

/* ---- nonlinear functions -------------------------------------------- */

/** exp(-x) for x >= 0 given in Q16 (x < 0 is treated as 0, returns 1.0);
 *  result in Q30, monotone non-increasing in x, 0 for x >= ~21.5.
 *  Accuracy and cost: see docs/fixed-point.md. */
int32_t hd_exp_neg_q16(int32_t x_q16);

/** sin and cos of an angle given as a fraction of a turn: 2^32 == one turn,
 *  so the uint32 wraps exactly once per turn (meant to wrap).  Results in Q30.
 *  Accuracy and cost: see docs/fixed-point.md. */
void hd_sincos_turn(uint32_t angle, int32_t *sin_q30, int32_t *cos_q30);

/** Smooth sign: with t = x / eps (eps > 0, same units as x), returns in Q30
 *  s(t) = t*(3 - t^2)/2 for |t| <= 1 and sign(t) otherwise: C1-continuous,
 *  odd, slope 1.5/eps at zero, exactly +-1 beyond +-eps.  eps <= 0 gives the
 *  plain sign (0 at 0). */
int32_t hd_sign_smooth_q30(int32_t x, int32_t eps);

/** floor(sqrt(x)) for x >= 0. Exact. */
uint32_t hd_isqrt64(uint64_t x);

#endif /* HD_FIXED_H */
