/*
 * hd_biquad.c - transposed direct form II biquads, 64-bit state, Q2.30 coefficients.
 */
#include "hd_biquad.h"
#include "hd_fixed.h"

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
    const int64_t acc = hdf_mac64(s->s1, c->b0, x);
    const int32_t y = hdf_asr32_rnd(acc, 30u);
    int64_t s1 = hdf_mac64(s->s2, c->b1, x);
    s1 = hdf_sub64_sat(s1, hdf_mul64x32_q(acc, c->a1, 30u));
    int64_t s2 = hdf_mac64(0, c->b2, x);
    s2 = hdf_sub64_sat(s2, hdf_mul64x32_q(acc, c->a2, 30u));
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
