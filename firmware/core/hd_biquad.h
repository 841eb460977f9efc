/*
 * hd_biquad.h - second-order IIR sections (notch, low-pass) and a chain of them.
 *
 * Transposed direct form II with 64-bit state and full-precision feedback:
 *     acc = b0*x + s1                     (signal-LSB * 2^30)
 *     y   = sat32(round(acc / 2^30))
 *     s1  = b1*x - round(a1*acc / 2^30) + s2
 *     s2  = b2*x - round(a2*acc / 2^30)
 * x, y: int32 in the caller's signal format (e.g. Q15.16 N.m).
 * b0..b2, a1, a2: Q2.30 (int32, range [-2, 2)); a0 = 1 implied.
 * s1, s2: int64 in signal-LSB * 2^30 (30 fractional bits kept between periods:
 * the rounding of y is not fed back, so a narrow notch, whose 1/A(z) gain is
 * in the hundreds, does not amplify it); saturating sums.
 * Coefficients are designed and quantised on the host (host/hdservo/filters.py),
 * which checks that the quantised poles lie inside the unit circle.
 * A section with b0 = 1, the rest 0 is a pass-through.
 */
#ifndef HD_BIQUAD_H
#define HD_BIQUAD_H

#include <stdint.h>

#define HD_BIQUAD_MAX 4   /* sections per chain */

typedef struct {
    int32_t b0, b1, b2, a1, a2;   /* Q2.30 */
} hd_biquad_coef_t;

typedef struct {
    int64_t s1, s2;               /* signal-LSB * 2^30 */
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
