/*
 * gv_fixed_inline.c - golden-vector kernels of the inline fast paths hdf_* of
 * hd_fixed.h.  On the Cortex-M4 several of them have an inline-assembly body
 * (QADD, QSUB, flag-based 64-bit saturation, rounding shift by a constant);
 * the host runs the portable C bodies, so these kernels prove that both
 * bodies give the same bits.  Shift counts must be constants for the M4
 * bodies: the runners dispatch every count 0..63 to a call with a literal
 * (hdf_asr64_rnd_var: the count known at run time only).  The 32-bit DSP
 * forms (SMMULR, SMMLAR, SMULL + SMLAL, two SMLAL, SSAT) are compared the same way.
 */
#include "gv.h"
#include "hd_fixed.h"

#define GV_N 1024u

static volatile int32_t cv_a = 0x12345678;
static volatile int32_t cv_b = -0x2468ACE;
static volatile int64_t cv_a64 = 0x0123456789ABCDEFLL;
static volatile int64_t cv_b64 = -0x00000A5A5A5A5A5ALL;
static volatile int32_t sink32;
static volatile int64_t sink64;

/* ---- generators ------------------------------------------------------ */

static void gen_e32x2(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_edge32(r);
    in[1] = hd_gv_rand_edge32(r);
}
/* one in four near a 32-bit limit (the saturation boundary), else edge-biased */
static void gen_sat32(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    int64_t x = hd_gv_rand_edge64(r);
    if ((idx % 4u) == 0u) {
        const int64_t d = (int64_t)(hd_gv_rand32(r) % 5u) - 2;
        x = ((idx % 8u) == 0u) ? (int64_t)INT32_MAX + d : (int64_t)INT32_MIN + d;
    }
    hd_gv_put64(in, x);
}
/* one in four at the overflow boundary: a + b (idx % 16 < 8) or a - b near
 * INT64_MAX / INT64_MIN, +-2 */
static void gen_e64x2(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const int64_t a = hd_gv_rand_edge64(r);
    int64_t b = hd_gv_rand_edge64(r);
    if ((idx % 4u) == 0u) {
        const int64_t d = (int64_t)(hd_gv_rand32(r) % 5u) - 2;
        const bool to_max = (idx % 8u) == 0u;
        const bool add = (idx % 16u) < 8u;
        if (add && to_max && a >= 0) {
            b = INT64_MAX - a;                  /* a + b = INT64_MAX */
        } else if (add && !to_max && a < 0) {
            b = INT64_MIN - a;                  /* a + b = INT64_MIN */
        } else if (!add && to_max && a >= 0) {
            b = a - INT64_MAX;                  /* a - b = INT64_MAX */
        } else if (!add && !to_max && a < 0) {
            b = a - INT64_MIN;                  /* a - b = INT64_MIN */
        }
        if ((d > 0 && b <= INT64_MAX - d) || (d < 0 && b >= INT64_MIN - d)) {
            b += d;
        }
    }
    hd_gv_put64(in, a);
    hd_gv_put64(in + 2, b);
}
/* shift 0..63 (idx < 64 walks every shift once); one in four x within 2^s of
 * INT64_MAX (the rounding offset overflows) or of INT64_MIN */
static void gen_e64_s63(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t s = (idx < 64u) ? idx : hd_gv_rand32(r) % 64u;
    int64_t x = hd_gv_rand_edge64(r);
    if ((idx % 4u) == 1u) {
        const uint64_t m = (s >= 63u) ? (uint64_t)INT64_MAX : (((uint64_t)1 << s) - 1u);
        const int64_t d = (int64_t)(hd_gv_rand64(r) & m);
        x = ((idx % 8u) == 1u) ? INT64_MAX - d : INT64_MIN + d;
    }
    hd_gv_put64(in, x);
    in[2] = (int32_t)s;
}
/* hdf_asr32_rnd_fit: s 1..32 (idx < 32 walks every s once), x = v 2^s + frac with
 * v an edge-biased int32 and 0 <= frac < 2^s (one in four frac = 2^(s-1): the tie),
 * so the rounded quotient fits an int32 (frac < 2^(s-1) for v = INT32_MAX) */
static void gen_rnd_fit(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t s = 1u + ((idx < 32u) ? idx : hd_gv_rand32(r) % 32u);
    const int32_t v = hd_gv_rand_edge32(r);
    uint64_t frac = hd_gv_rand64(r) & (((uint64_t)1 << s) - 1u);
    if ((idx % 4u) == 1u) {
        frac = (uint64_t)1 << (s - 1u);
    }
    if (v == INT32_MAX) {
        frac &= ((uint64_t)1 << (s - 1u)) - 1u;
    }
    hd_gv_put64(in, (int64_t)v * (int64_t)((uint64_t)1 << s) + (int64_t)frac);
    in[2] = (int32_t)s;
}
static void gen_mul_q(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_edge32(r);
    in[1] = hd_gv_rand_edge32(r);
    in[2] = (int32_t)((idx < 63u) ? idx : hd_gv_rand32(r) % 63u);
}

/* a: one in two a full 64-bit value (the 96-bit product path), else edge-biased;
 * q 0..62 (idx < 63 walks every q once) */
static void gen_mul64x32_q(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    int64_t a = hd_gv_rand_edge64(r);
    if ((idx % 2u) == 0u) {
        a = hdf__u2s64(hd_gv_rand64(r));
    }
    hd_gv_put64(in, a);
    in[2] = hd_gv_rand_edge32(r);
    in[3] = (int32_t)((idx < 63u) ? idx : hd_gv_rand32(r) % 63u);
}

/* the DSP forms: edge-biased words; hdf_dot2_rnd32 one in four with both products at
 * their extreme (+-2^62 each: the 64-bit sum wraps, as SMLAL does); hdf_ssat walks
 * n = 1..32 (idx < 32), one in four x at a limit +-1 */
static void gen_e32x4(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_edge32(r);
    in[1] = hd_gv_rand_edge32(r);
    in[2] = hd_gv_rand_edge32(r);
    in[3] = hd_gv_rand_edge32(r);
    if ((idx % 4u) == 2u) {
        in[0] = INT32_MIN;
        in[1] = INT32_MIN;
        in[2] = ((idx % 8u) == 2u) ? INT32_MIN : INT32_MAX;
        in[3] = INT32_MIN;
    }
}
static void gen_ssat(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t n = 1u + ((idx < 32u) ? idx : hd_gv_rand32(r) % 32u);
    in[0] = hd_gv_rand_edge32(r);
    if ((idx % 4u) == 1u) {
        const int64_t lim = ((idx % 8u) == 1u) ? ((int64_t)1 << (n - 1u)) - 1 : -((int64_t)1 << (n - 1u));
        const int64_t x = lim + (int64_t)(hd_gv_rand32(r) % 3u) - 1;
        in[0] = (x > INT32_MAX) ? INT32_MAX : ((x < INT32_MIN) ? INT32_MIN : (int32_t)x);
    }
    in[1] = (int32_t)n;
}

/* ---- constant-shift dispatch ------------------------------------------ */

#define CASES8(F, x, b) F(x, b + 0u) F(x, b + 1u) F(x, b + 2u) F(x, b + 3u) \
                        F(x, b + 4u) F(x, b + 5u) F(x, b + 6u) F(x, b + 7u)
#define CASES64(F, x) CASES8(F, x, 0u) CASES8(F, x, 8u) CASES8(F, x, 16u) CASES8(F, x, 24u) \
                      CASES8(F, x, 32u) CASES8(F, x, 40u) CASES8(F, x, 48u) CASES8(F, x, 56u)

#define RND_CASE(x, k) case (k): return hdf_asr64_rnd((x), (k));
static int64_t asr64_rnd_const(int64_t x, uint32_t s)
{
    switch (s) {
    CASES64(RND_CASE, x)
    default: return hdf_asr64_rnd(x, 63u);
    }
}
#define FLOOR_CASE(x, k) case (k): return hdf_asr64_floor((x), (k));
static int64_t asr64_floor_const(int64_t x, uint32_t s)
{
    switch (s) {
    CASES64(FLOOR_CASE, x)
    default: return hdf_asr64_floor(x, 63u);
    }
}
#define RND32_CASE(x, k) case (k): return hdf_asr32_rnd((x), (k));
static int32_t asr32_rnd_const(int64_t x, uint32_t s)
{
    switch (s) {
    CASES64(RND32_CASE, x)
    default: return hdf_asr32_rnd(x, 63u);
    }
}
#define RNDFIT_CASE(x, k) case (k): return hdf_asr32_rnd_fit((x), (k));
#define CASES32_1(F, x) CASES8(F, x, 1u) CASES8(F, x, 9u) CASES8(F, x, 17u) CASES8(F, x, 25u)
static int32_t asr32_rnd_fit_const(int64_t x, uint32_t s)
{
    switch (s) {
    CASES32_1(RNDFIT_CASE, x)
    default: return hdf_asr32_rnd_fit(x, 1u);
    }
}
#define MULQ_CASE(x, k) case (k): return hdf_mul_q((x)[0], (x)[1], (k));
static int32_t mul_q_const(const int32_t *in, uint32_t q)
{
    switch (q) {
    CASES64(MULQ_CASE, in)
    default: return hdf_mul_q(in[0], in[1], 62u);
    }
}

#define SHL_CASE(x, k) case (k): return hdf_shl64_sat((x), (k));
static int64_t shl64_sat_const(int64_t x, uint32_t s)
{
    switch (s) {
    CASES64(SHL_CASE, x)
    default: return hdf_shl64_sat(x, 63u);
    }
}
#define M96_CASE(x, k) case (k): return hdf_mul64x32_q(hd_gv_get64(x), (x)[2], (k));
static int64_t mul64x32_q_const(const int32_t *in, uint32_t q)
{
    switch (q) {
    CASES64(M96_CASE, in)
    default: return hdf_mul64x32_q(hd_gv_get64(in), in[2], 62u);
    }
}

#define SSAT_CASE(x, k) case (k): return hdf_ssat((x), (k));
static int32_t ssat_const(int32_t x, uint32_t n)
{
    switch (n) {
    CASES32_1(SSAT_CASE, x)
    default: return hdf_ssat(x, 32u);
    }
}

/* ---- runners --------------------------------------------------------- */

#define RUN_BEGIN(fn, nin, nout) \
    static void fn(const int32_t *in, int32_t *out, uint32_t count) \
    { \
        uint32_t i; \
        for (i = 0; i < count; i++, in += (nin), out += (nout)) {
#define RUN_END }}

RUN_BEGIN(run_sat32, 2, 1) out[0] = hdf_sat32(hd_gv_get64(in)); RUN_END
RUN_BEGIN(run_add_sat, 2, 1) out[0] = hdf_add_sat(in[0], in[1]); RUN_END
RUN_BEGIN(run_sub_sat, 2, 1) out[0] = hdf_sub_sat(in[0], in[1]); RUN_END
RUN_BEGIN(run_add64_sat, 4, 2) hd_gv_put64(out, hdf_add64_sat(hd_gv_get64(in), hd_gv_get64(in + 2))); RUN_END
RUN_BEGIN(run_sub64_sat, 4, 2) hd_gv_put64(out, hdf_sub64_sat(hd_gv_get64(in), hd_gv_get64(in + 2))); RUN_END
RUN_BEGIN(run_asr64_rnd, 3, 2) hd_gv_put64(out, asr64_rnd_const(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_asr64_floor, 3, 2) hd_gv_put64(out, asr64_floor_const(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_asr64_rnd_var, 3, 2) hd_gv_put64(out, hdf_asr64_rnd(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_asr32_rnd, 3, 1) out[0] = asr32_rnd_const(hd_gv_get64(in), hd_gv_s2u(in[2])); RUN_END
RUN_BEGIN(run_asr32_rnd_fit, 3, 1) out[0] = asr32_rnd_fit_const(hd_gv_get64(in), hd_gv_s2u(in[2])); RUN_END
RUN_BEGIN(run_shl64_sat, 3, 2) hd_gv_put64(out, shl64_sat_const(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_mul64x32_q, 4, 2) hd_gv_put64(out, mul64x32_q_const(in, hd_gv_s2u(in[3]))); RUN_END
RUN_BEGIN(run_mul_q, 3, 1) out[0] = mul_q_const(in, hd_gv_s2u(in[2])); RUN_END
RUN_BEGIN(run_smmulr, 2, 1) out[0] = hdf_smmulr(in[0], in[1]); RUN_END
RUN_BEGIN(run_smmlar, 4, 1) out[0] = hdf_smmlar(in[2], in[0], in[1]); RUN_END
RUN_BEGIN(run_dot2_rnd32, 4, 1) out[0] = hdf_dot2_rnd32(in[0], in[1], in[2], in[3]); RUN_END
RUN_BEGIN(run_dot2_64, 4, 2) hd_gv_put64(out, hdf_dot2_64(in[0], in[1], in[2], in[3])); RUN_END
RUN_BEGIN(run_mac64, 4, 2) hd_gv_put64(out, hdf_mac64(hd_gv_get64(in), in[2], in[3])); RUN_END
RUN_BEGIN(run_ssat, 2, 1) out[0] = ssat_const(in[0], hd_gv_s2u(in[1])); RUN_END

/* ---- cost: one representative call each ------------------------------- */

#define COST(fn, sink, call) \
    static void fn(void) \
    { \
        const int32_t a = cv_a, b = cv_b; \
        const int64_t a64 = cv_a64, b64 = cv_b64; \
        (void)a; (void)b; (void)a64; (void)b64; \
        hd_gv_cost_mark(); \
        sink = (call); \
        hd_gv_cost_mark(); \
    }
COST(cost_sat32, sink32, hdf_sat32(a64))
COST(cost_add_sat, sink32, hdf_add_sat(a, b))
COST(cost_sub_sat, sink32, hdf_sub_sat(a, b))
COST(cost_add64_sat, sink64, hdf_add64_sat(a64, b64))
COST(cost_sub64_sat, sink64, hdf_sub64_sat(a64, b64))
COST(cost_asr64_rnd, sink64, hdf_asr64_rnd(b64, 16u))
static void cost_asr64_rnd_var(void)
{
    const int64_t b64 = cv_b64;
    const uint32_t sh = (uint32_t)(cv_a & 15);
    hd_gv_cost_mark();
    sink64 = hdf_asr64_rnd(b64, sh);
    hd_gv_cost_mark();
}
COST(cost_asr64_floor, sink64, hdf_asr64_floor(b64, 16u))
COST(cost_asr32_rnd, sink32, hdf_asr32_rnd(b64, 16u))
COST(cost_asr32_rnd_fit, sink32, hdf_asr32_rnd_fit(b64, 32u))
COST(cost_mul_q, sink32, hdf_mul_q(a, b, 30u))
COST(cost_shl64_sat, sink64, hdf_shl64_sat(b64, 16u))
COST(cost_mul64x32_q, sink64, hdf_mul64x32_q(a64, b, 30u))
COST(cost_smmulr, sink32, hdf_smmulr(a, b))
COST(cost_smmlar, sink32, hdf_smmlar(b, a, b))
COST(cost_dot2_rnd32, sink32, hdf_dot2_rnd32(a, b, b, a))
COST(cost_dot2_64, sink64, hdf_dot2_64(a, b, b, a))
COST(cost_ssat, sink32, hdf_ssat(a, 28u))
COST(cost_mac64, sink64, hdf_mac64(a64, a, b))

/* ---- registry -------------------------------------------------------- */

const hd_gv_kernel_t hd_gv_fixed_inline_kernels[] = {
    {"hdf_sat32", 2, 1, GV_N, gen_sat32, run_sat32, cost_sat32},
    {"hdf_add_sat", 2, 1, GV_N, gen_e32x2, run_add_sat, cost_add_sat},
    {"hdf_sub_sat", 2, 1, GV_N, gen_e32x2, run_sub_sat, cost_sub_sat},
    {"hdf_add64_sat", 4, 2, GV_N, gen_e64x2, run_add64_sat, cost_add64_sat},
    {"hdf_sub64_sat", 4, 2, GV_N, gen_e64x2, run_sub64_sat, cost_sub64_sat},
    {"hdf_asr64_rnd", 3, 2, 2u * GV_N, gen_e64_s63, run_asr64_rnd, cost_asr64_rnd},
    {"hdf_asr64_floor", 3, 2, 2u * GV_N, gen_e64_s63, run_asr64_floor, cost_asr64_floor},
    {"hdf_asr64_rnd_var", 3, 2, 2u * GV_N, gen_e64_s63, run_asr64_rnd_var, cost_asr64_rnd_var},
    {"hdf_asr32_rnd", 3, 1, 2u * GV_N, gen_e64_s63, run_asr32_rnd, cost_asr32_rnd},
    {"hdf_asr32_rnd_fit", 3, 1, 2u * GV_N, gen_rnd_fit, run_asr32_rnd_fit, cost_asr32_rnd_fit},
    {"hdf_mul_q", 3, 1, GV_N, gen_mul_q, run_mul_q, cost_mul_q},
    {"hdf_shl64_sat", 3, 2, 2u * GV_N, gen_e64_s63, run_shl64_sat, cost_shl64_sat},
    {"hdf_mul64x32_q", 4, 2, 2u * GV_N, gen_mul64x32_q, run_mul64x32_q, cost_mul64x32_q},
    {"hdf_smmulr", 2, 1, GV_N, gen_e32x2, run_smmulr, cost_smmulr},
    {"hdf_smmlar", 4, 1, GV_N, gen_e32x4, run_smmlar, cost_smmlar},
    {"hdf_dot2_rnd32", 4, 1, GV_N, gen_e32x4, run_dot2_rnd32, cost_dot2_rnd32},
    {"hdf_dot2_64", 4, 2, GV_N, gen_e32x4, run_dot2_64, cost_dot2_64},
    {"hdf_ssat", 2, 1, GV_N, gen_ssat, run_ssat, cost_ssat},
    {"hdf_mac64", 4, 2, GV_N, gen_e32x4, run_mac64, cost_mac64},
};
const uint32_t hd_gv_fixed_inline_count = sizeof hd_gv_fixed_inline_kernels / sizeof hd_gv_fixed_inline_kernels[0];
