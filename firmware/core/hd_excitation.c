/*
 * hd_excitation.c - deterministic excitation signals (see hd_excitation.h).
 */
#include "hd_excitation.h"
#include "hd_fixed.h"
#include "hd_units.h"

/* 10^(i/10), i = 0..9, Q16 (rounded) */
static const int32_t dec_q16[10] = {
    65536, 82505, 103868, 130762, 164622, 207243, 260904, 328458, 413504, 520570
};

static uint32_t lfsr_mask(uint32_t order)
{
    switch (order) {
    case 7: return 0x60u;
    case 9: return 0x110u;
    case 10: return 0x240u;
    case 11: return 0x500u;
    case 15: return 0x6000u;
    case 16: return 0xB400u;
    default: return 0u;
    }
}

static uint32_t vsteps_levels(const hd_exc_cfg_t *c)
{
    return c->n * c->m + 1u;
}

uint32_t hd_exc_length(const hd_exc_cfg_t *c)
{
    switch (c->kind) {
    case HD_EXC_VSTEPS:
        return 2u * vsteps_levels(c) * c->hold;
    case HD_EXC_CHIRP:
        return c->length;
    default:
        return c->length;
    }
}

int32_t hd_exc_start(hd_exc_t *s, const hd_exc_cfg_t *c)
{
    s->k = 0;
    s->idx = 0;
    s->sub = 0;
    s->cur = 0;
    s->dir = 1;
    s->lfsr = 1;
    s->phase = 0;
    s->inc = 0;
    s->dinc = 0;
    s->done = 0;
    s->out = c->offset;
    if (c->amp < 0) {
        return -1;
    }
    switch (c->kind) {
    case HD_EXC_NONE:
        return 0;
    case HD_EXC_VSTEPS:
        if (c->hold == 0u || c->n == 0u || c->n > 9u ||
            !(c->m == 1u || c->m == 2u || c->m == 5u || c->m == 10u)) {
            return -1;
        }
        return 0;
    case HD_EXC_TRAMP:
    case HD_EXC_FORC:
        if (c->rate <= 0 || (c->kind == HD_EXC_FORC && c->n == 0u)) {
            return -1;
        }
        s->dir = (c->kind == HD_EXC_FORC) ? -1 : 1;
        return 0;
    case HD_EXC_CHIRP: {
        if (c->length == 0u || c->f0_q16 <= 0 || c->f1_q16 <= 0 || c->f0_q16 >= (1 << 30) ||
            c->f1_q16 >= (1 << 30)) {
            return -1;
        }
        /* increment per period, 2^-64 turn: f_q16 * 2^48 / HD_LOOP_HZ */
        const int64_t i0 = hd_div64_rnd((int64_t)c->f0_q16 << 32, HD_LOOP_HZ);
        const int64_t i1 = hd_div64_rnd((int64_t)c->f1_q16 << 32, HD_LOOP_HZ);
        s->inc = hd_shl64_sat(i0, 16u);
        s->dinc = hd_shl64_sat(hd_div64_rnd(i1 - i0, (int64_t)c->length), 16u);
        return 0;
    }
    case HD_EXC_MULTISINE:
        if (c->period < 2u || c->n == 0u || c->n > 64u || (uint64_t)c->n * c->period > 0x7FFFFFFFu) {
            return -1;
        }
        return 0;
    case HD_EXC_PRBS:
        if (lfsr_mask(c->n) == 0u || c->hold == 0u) {
            return -1;
        }
        s->lfsr = (c->seed & ((1u << c->n) - 1u));
        if (s->lfsr == 0u) {
            s->lfsr = 1u;
        }
        return 0;
    default:
        return -1;
    }
}

/* ramp s->cur towards target at rate; returns 1 on arrival */
static int32_t ramp_to(hd_exc_t *s, int32_t target, int32_t rate)
{
    if (s->cur < target) {
        int32_t nv = hdf_add_sat(s->cur, rate);
        s->cur = (nv > target) ? target : nv;
    } else if (s->cur > target) {
        int32_t nv = hdf_sub_sat(s->cur, rate);
        s->cur = (nv < target) ? target : nv;
    }
    return (s->cur == target) ? 1 : 0;
}

static int32_t vsteps_value(hd_exc_t *s, const hd_exc_cfg_t *c)
{
    const uint32_t levels = vsteps_levels(c);
    if (s->idx >= 2u * levels) {
        s->done = 1;
        return 0;
    }
    const uint32_t lv = s->idx / 2u;
    const uint32_t e10 = lv * (10u / c->m);         /* exponent in tenths of a decade */
    int64_t v = hdf_mul64x32_q((int64_t)c->amp, dec_q16[e10 % 10u], 16u);
    uint32_t d;
    for (d = 0; d < e10 / 10u; d++) {
        v = hdf_mul64x32_q(v, 10, 0);
    }
    int32_t out = hdf_sat32(v);
    if (s->idx & 1u) {
        out = hdf_neg_sat(out);
    }
    if (++s->sub >= c->hold) {
        s->sub = 0;
        s->idx++;
    }
    return out;
}

static int32_t tramp_value(hd_exc_t *s, const hd_exc_cfg_t *c)
{
    const int32_t tgt = (s->dir > 0) ? c->amp : hdf_neg_sat(c->amp);
    if (ramp_to(s, tgt, c->rate)) {
        s->dir = -s->dir;
        if (s->dir > 0) {
            s->idx++;               /* one full cycle done at the negative peak */
            if (c->n != 0u && s->idx >= c->n) {
                s->done = 1;
            }
        }
    }
    return s->cur;
}

static int32_t forc_value(hd_exc_t *s, const hd_exc_cfg_t *c)
{
    /* sub: 0 = going to -amp (start or after a reversal), 1 = going up to reversal idx+1 */
    const int32_t lo = hdf_neg_sat(c->amp);
    if (s->sub == 0u) {
        if (ramp_to(s, lo, c->rate)) {
            if (s->idx >= c->n) {
                s->done = 1;
            } else {
                s->sub = 1;
            }
        }
    } else {
        const int64_t r = (int64_t)lo + hd_div64_rnd(2 * (int64_t)c->amp * (int64_t)(s->idx + 1u), (int64_t)c->n);
        if (ramp_to(s, hdf_sat32(r), c->rate)) {
            s->idx++;
            s->sub = 0;
        }
    }
    return s->cur;
}

/* floor(num * 2^32 / den) for num < den < 2^16: long division in two 16-bit
 * digits, 32-bit UDIVs only (no __aeabi_uldivmod); exact, the same result as
 * the 64-bit division used for longer periods. */
static uint32_t frac32_16(uint32_t num, uint32_t den)
{
    const uint32_t c1 = num << 16;                     /* num < den < 2^16 */
    const uint32_t q1 = c1 / den;
    const uint32_t c0 = (c1 - q1 * den) << 16;
    return (q1 << 16) | (c0 / den);
}

/* The lines' sum; short = 1 when period < 2^16 (the line fractions by
 * frac32_16), a constant at both calls, so the test is made once per period. */
static inline __attribute__((always_inline)) int64_t multisine_sum(uint32_t t, const hd_exc_cfg_t *c,
                                                                   uint32_t short_period)
{
    /* the cfg words in locals: the sine is a call, after which the compiler
     * would load them again in every line */
    const uint32_t period = c->period;
    const uint32_t n = c->n;
    const uint32_t n2 = 2u * n;                        /* <= 128 (checked at start) */
    const int64_t amp = (int64_t)c->amp;
    int64_t sum = 0;
    uint32_t i;
    for (i = 1; i <= n; i++) {
        /* phase in turns: i t / period - (i (i - 1)) / (2 n)  (Schroeder);
         * i t < n period <= 2^31 and i (i - 1) < 2^12 (checked at start): 32-bit */
        const uint32_t num = (i * t) % period;
        const uint32_t ph = short_period ? frac32_16(num, period)
                                         : (uint32_t)(((uint64_t)num << 32) / period);
        const uint32_t sn = (i * (i - 1u)) % n2;
        const uint32_t sch = frac32_16(sn, n2);
        const int32_t sv = hd_sin_turn_fast(ph - sch);   /* uint32 phase wraps, meant; ~6e-8 of amp */
        /* 0 <= amp < 2^31 (checked at start) and |sv| <= 2^30: the rounded
         * amp sv / 2^30 is within +-(2^31 - 1), so it fits int32 without the
         * saturation of hdf_mul_q; n <= 64 such terms sum to less than 2^37 in
         * magnitude, so the int64 sum never saturates: the words of
         * hdf_mul_q and hdf_add64_sat, without their tests. */
        sum += (int64_t)hdf_asr32_rnd_fit(amp * (int64_t)sv, 30u);
    }
    return sum;
}

static int32_t multisine_value(const hd_exc_t *s, const hd_exc_cfg_t *c)
{
    const uint32_t t = s->k % c->period;
    const int64_t sum = (c->period < 65536u) ? multisine_sum(t, c, 1u) : multisine_sum(t, c, 0u);
    return hdf_sat32(sum);
}

static int32_t prbs_value(hd_exc_t *s, const hd_exc_cfg_t *c)
{
    const int32_t out = (s->lfsr & 1u) ? c->amp : hdf_neg_sat(c->amp);
    if (++s->sub >= c->hold) {
        s->sub = 0;
        const uint32_t lsb = s->lfsr & 1u;
        s->lfsr >>= 1;
        if (lsb) {
            s->lfsr ^= lfsr_mask(c->n);
        }
    }
    return out;
}

int32_t hd_exc_step(hd_exc_t *s, const hd_exc_cfg_t *c)
{
    int32_t v = 0;
    if (c->length != 0u && s->k >= c->length) {
        s->done = 1;
    }
    if (!s->done) {
        switch (c->kind) {
        case HD_EXC_VSTEPS:
            v = vsteps_value(s, c);
            break;
        case HD_EXC_TRAMP:
            v = tramp_value(s, c);
            break;
        case HD_EXC_FORC:
            v = forc_value(s, c);
            break;
        case HD_EXC_CHIRP: {
            v = hdf_mul_q(c->amp, hd_sin_turn_fast((uint32_t)(s->phase >> 32)), 30u);
            s->phase += (uint64_t)s->inc;     /* uint64 wraps once per cycle, meant */
            s->inc = hdf_add64_sat(s->inc, s->dinc);
            break;
        }
        case HD_EXC_MULTISINE:
            v = multisine_value(s, c);
            break;
        case HD_EXC_PRBS:
            v = prbs_value(s, c);
            break;
        default:
            s->done = 1;
            break;
        }
    }
    s->k++;
    s->out = hdf_add_sat(v, c->offset);
    return s->out;
}
