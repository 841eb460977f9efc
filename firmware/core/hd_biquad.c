/*
 * hd_biquad.c - direct form I biquads with full-precision feedback, Q2.30 coefficients.
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
    s->x1 = 0;
    s->x2 = 0;
    s->y1 = 0;
    s->y2 = 0;
    s->e1 = 0;
    s->e2 = 0;
}

/* One section on an input already within +-HD_BIQUAD_SIG_MAX (formats and range:
 * hd_biquad.h).  Every product is a 32 x 32-bit multiply-accumulate into one int64
 * (SMLAL); the two roundings are the inline shifts of hd_fixed.h.  Its output lies
 * within +-HD_BIQUAD_SIG_MAX too, so a chain clamps only its own input. */
static inline int32_t biquad_section(hd_biquad_state_t *s, const hd_biquad_coef_t *c, int32_t x)
{
    /* the residuals' feedback: |a e| < 2^31 2^29, the sum < 2^61; rounded to < 2^32 */
    int64_t r = (int64_t)c->a1 * s->e1;
    r += (int64_t)c->a2 * s->e2;
    /* |each product| <= 2^31 2^29 = 2^60: five and the residual term stay below 2^63 */
    int64_t acc = (int64_t)c->b0 * x;
    acc += (int64_t)c->b1 * s->x1;
    acc += (int64_t)c->b2 * s->x2;
    acc += (int64_t)c->a1 * (int32_t)(-s->y1);             /* |y| <= 2^29: the negation fits */
    acc += (int64_t)c->a2 * (int32_t)(-s->y2);
    acc -= hdf_asr64_rnd(r, 30u);
    const int64_t yr = hdf_asr64_rnd(acc, 30u);              /* |.| < 2^33 */
    const uint32_t ylo = hdf__lo(yr);
    int32_t y;
    int32_t e;
    /* |yr| <= SIG_MAX in 32-bit words: yr is an int32 (its high word is the sign of the
     * low one) and the low word + SIG_MAX lies in [0, 2 SIG_MAX] (else, mod 2^32, above) */
    if (hdf__hi(yr) != (uint32_t)(0u - (ylo >> 31)) ||
        ylo + (uint32_t)HD_BIQUAD_SIG_MAX > 2u * (uint32_t)HD_BIQUAD_SIG_MAX) {
        y = (yr > 0) ? HD_BIQUAD_SIG_MAX : -HD_BIQUAD_SIG_MAX;
        e = 0;                                              /* limited: the residual is dropped */
    } else {
        y = hdf__s32(ylo);
        /* acc - y 2^30 lies in [-2^29, 2^29]: its low word is the value (mod 2^32 exact) */
        const uint32_t u = (uint32_t)((uint64_t)acc & 0xFFFFFFFFu) - ((uint32_t)y << 30);
        e = (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u;
    }
    s->x2 = s->x1;
    s->x1 = x;
    s->y2 = s->y1;
    s->y1 = y;
    s->e2 = s->e1;
    s->e1 = e;
    return y;
}

int32_t hd_biquad_step(hd_biquad_state_t *s, const hd_biquad_coef_t *c, int32_t x)
{
    return biquad_section(s, c, hdf_clamp32(x, -HD_BIQUAD_SIG_MAX, HD_BIQUAD_SIG_MAX));
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
    if (c->n == 0u) {
        return x;                       /* no section: the input itself, not clamped */
    }
    const uint32_t n = (c->n < HD_BIQUAD_MAX) ? c->n : HD_BIQUAD_MAX;
    /* each section's output is within the signal limit: the next one's input needs no clamp */
    x = hdf_clamp32(x, -HD_BIQUAD_SIG_MAX, HD_BIQUAD_SIG_MAX);
    for (i = 0; i < n; i++) {
        x = biquad_section(&s->s[i], &c->c[i], x);
    }
    return x;
}
