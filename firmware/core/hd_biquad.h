/*
 * hd_biquad.h - second-order IIR sections (notch, low-pass) and a chain of them.
 *
 * Direct form I with full-precision feedback, one 64-bit accumulator:
 *     acc = b0 x + b1 x1 + b2 x2 - a1 y1 - a2 y2 - round((a1 e1 + a2 e2) / 2^30)
 *                                                    (signal-LSB * 2^30)
 *     y   = round(acc / 2^30), limited to +-HD_BIQUAD_SIG_MAX
 *     e   = acc - y 2^30                             (|e| <= 2^29; 0 when y is limited)
 * x, y: int32 in the caller's signal format (e.g. Q15.16 N.m); the input is
 * limited to +-HD_BIQUAD_SIG_MAX as well.  b0..b2, a1, a2: Q2.30 (int32, range
 * [-2, 2)); a0 = 1 implied.  The state is the last two inputs, the last two
 * outputs and their rounding residuals e: y + e / 2^30 is the unrounded output,
 * so the feedback sees the full-precision past output (the rounding of y is not
 * fed back, so a narrow notch, whose 1/A(z) gain is in the hundreds, does not
 * amplify it); only the residual term's own rounding (<= 0.5 LSB of 2^-30)
 * enters the loop.
 * Range (docs/firmware.md, "Range analysis"): |x|, |y| <= 2^29 and |coefficient|
 * <= 2^31 make each product < 2^60 and the residual term < 2^32, so the sum of
 * the five products and that term stays below 2^63: the accumulator is plain
 * 64-bit arithmetic (SMLAL on the Cortex-M4) with no saturation.
 * Coefficients are designed and quantised on the host (host/hdservo/filters.py),
 * which checks that the quantised poles lie inside the unit circle.
 * A section with b0 = 1, the rest 0 is a pass-through (for |x| <= 2^29).
 */
#ifndef HD_BIQUAD_H
#define HD_BIQUAD_H

#include <stdint.h>

#define HD_BIQUAD_MAX 4   /* sections per chain */

typedef struct {
    int32_t b0, b1, b2, a1, a2;   /* Q2.30 */
} hd_biquad_coef_t;

/* signal limit of a section, 2^29 (8192 N.m in Q15.16, far above any torque limit) */
#define HD_BIQUAD_SIG_MAX ((int32_t)1 << 29)

typedef struct {
    int32_t x1, x2;               /* last two inputs, signal format, |.| <= 2^29 */
    int32_t y1, y2;               /* last two outputs (rounded), |.| <= 2^29 */
    int32_t e1, e2;               /* their residuals, signal-LSB * 2^-30, |.| <= 2^29 */
} hd_biquad_state_t;

typedef struct {
    uint32_t n;                               /* sections in use, 0..HD_BIQUAD_MAX */
    hd_biquad_coef_t c[HD_BIQUAD_MAX];
} hd_biquad_chain_cfg_t;

typedef struct {
    hd_biquad_state_t s[HD_BIQUAD_MAX];
} hd_biquad_chain_t;

/** Pass-through coefficients (b0 = 1). */
void hd_biquad_identity(hd_biquad_coef_t *c);
void hd_biquad_reset(hd_biquad_state_t *s);
int32_t hd_biquad_step(hd_biquad_state_t *s, const hd_biquad_coef_t *c, int32_t x);
void hd_biquad_chain_reset(hd_biquad_chain_t *s);
int32_t hd_biquad_chain_step(hd_biquad_chain_t *s, const hd_biquad_chain_cfg_t *c, int32_t x);

#endif
