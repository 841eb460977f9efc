/*
 * gv_fixed.c - golden-vector kernels of the fixed-point base library: one
 * kernel per hd_fixed.h function, named after it.  Inputs are edge-biased
 * random values (hd_gv_rand_edge32/64); int64 values travel as two words.
 * Each kernel also has a cost() with a representative call for
 * `make bench` (build/bench/cm4_cost.json).
 */
#include "gv.h"
#include "hd_fixed.h"

#define GV_N 1024u

/* Inputs of the cost() calls come from volatiles so that nothing is folded. */
static volatile int32_t cv_a = 0x12345678;
static volatile int32_t cv_b = -0x2468ACE;
static volatile int64_t cv_a64 = 0x0123456789ABCDEFLL;
static volatile int64_t cv_b64 = -0x00000A5A5A5A5A5ALL;
static volatile uint32_t cv_s = 17u;
static volatile int32_t sink32;
static volatile int64_t sink64;

static uint32_t rand_shift(hd_gv_rng_t *r, uint32_t max)
{
    return hd_gv_rand32(r) % (max + 1u);
}

/* ---- generators ------------------------------------------------------ */

static void gen_e32(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_edge32(r);
}
static void gen_e32x2(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_edge32(r);
    in[1] = hd_gv_rand_edge32(r);
}
static void gen_e32x3(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_edge32(r);
    in[1] = hd_gv_rand_edge32(r);
    in[2] = hd_gv_rand_edge32(r);
}
static void gen_e64(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    hd_gv_put64(in, hd_gv_rand_edge64(r));
}
static void gen_e64x2(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    hd_gv_put64(in, hd_gv_rand_edge64(r));
    hd_gv_put64(in + 2, hd_gv_rand_edge64(r));
}
static void gen_e64x3(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    hd_gv_put64(in, hd_gv_rand_edge64(r));
    hd_gv_put64(in + 2, hd_gv_rand_edge64(r));
    hd_gv_put64(in + 4, hd_gv_rand_edge64(r));
}
/* int64, shift 0..63 (idx < 64 walks every shift once) */
static void gen_e64_s63(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    hd_gv_put64(in, hd_gv_rand_edge64(r));
    in[2] = (int32_t)((idx < 64u) ? idx : rand_shift(r, 63u));
}
static void gen_satn(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    hd_gv_put64(in, hd_gv_rand_edge64(r));
    in[2] = (int32_t)((idx < 63u) ? idx + 1u : rand_shift(r, 62u) + 1u);
}
static void gen_shl32(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_edge32(r);
    in[1] = (int32_t)((idx < 32u) ? idx : rand_shift(r, 31u));
}
static void gen_mul_q(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_edge32(r);
    in[1] = hd_gv_rand_edge32(r);
    /* mostly the formats in use (Q30, Q16, Q15), else any 0..62 */
    switch (idx % 4u) {
    case 0u:
        in[2] = 30;
        break;
    case 1u:
        in[2] = 16;
        break;
    case 2u:
        in[2] = 15;
        break;
    default:
        in[2] = (int32_t)rand_shift(r, 62u);
        break;
    }
}
static void gen_mul64x32_q(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    hd_gv_put64(in, hd_gv_rand_edge64(r));
    in[2] = hd_gv_rand_edge32(r);
    in[3] = (int32_t)(((idx % 2u) == 0u) ? 32u : rand_shift(r, 62u));
}
static void gen_mac64(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    hd_gv_put64(in, hd_gv_rand_edge64(r));
    in[2] = hd_gv_rand_edge32(r);
    in[3] = hd_gv_rand_edge32(r);
}
static void gen_div_q(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_edge32(r);
    in[1] = hd_gv_rand_edge32(r);
    in[2] = (int32_t)(((idx % 2u) == 0u) ? 16u : rand_shift(r, 31u));
}
static void gen_exp(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    /* 3 in 4 inside the live range [0, 22) in Q16, else anything */
    in[0] = ((idx % 4u) != 3u) ? hd_gv_rand_range(r, 0, (22 << 16) - 1) : hd_gv_rand_edge32(r);
}
static void gen_sign(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    if ((idx % 2u) == 0u) {
        /* inside the smooth band of a positive eps */
        const int32_t eps = hd_gv_rand_range(r, 1, INT32_MAX);
        in[1] = eps;
        in[0] = hd_gv_rand_range(r, -eps, eps);
    } else {
        in[0] = hd_gv_rand_edge32(r);
        in[1] = hd_gv_rand_edge32(r);
    }
}

/* ---- runners --------------------------------------------------------- */

#define RUN_BEGIN(fn, nin, nout) \
    static void fn(const int32_t *in, int32_t *out, uint32_t count) \
    { \
        uint32_t i; \
        for (i = 0; i < count; i++, in += (nin), out += (nout)) {
#define RUN_END }}

RUN_BEGIN(run_sat32, 2, 1) out[0] = hd_sat32(hd_gv_get64(in)); RUN_END
RUN_BEGIN(run_satn, 3, 2) hd_gv_put64(out, hd_satn(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_clamp32, 3, 1)
    const int32_t lo = (in[1] < in[2]) ? in[1] : in[2];
    const int32_t hi = (in[1] < in[2]) ? in[2] : in[1];
    out[0] = hd_clamp32(in[0], lo, hi);
RUN_END
RUN_BEGIN(run_clamp64, 6, 2)
    const int64_t a = hd_gv_get64(in + 2);
    const int64_t b = hd_gv_get64(in + 4);
    hd_gv_put64(out, hd_clamp64(hd_gv_get64(in), (a < b) ? a : b, (a < b) ? b : a));
RUN_END
RUN_BEGIN(run_add_sat, 2, 1) out[0] = hd_add_sat(in[0], in[1]); RUN_END
RUN_BEGIN(run_sub_sat, 2, 1) out[0] = hd_sub_sat(in[0], in[1]); RUN_END
RUN_BEGIN(run_neg_sat, 1, 1) out[0] = hd_neg_sat(in[0]); RUN_END
RUN_BEGIN(run_abs_sat, 1, 1) out[0] = hd_abs_sat(in[0]); RUN_END
RUN_BEGIN(run_add64_sat, 4, 2) hd_gv_put64(out, hd_add64_sat(hd_gv_get64(in), hd_gv_get64(in + 2))); RUN_END
RUN_BEGIN(run_sub64_sat, 4, 2) hd_gv_put64(out, hd_sub64_sat(hd_gv_get64(in), hd_gv_get64(in + 2))); RUN_END
RUN_BEGIN(run_neg64_sat, 2, 2) hd_gv_put64(out, hd_neg64_sat(hd_gv_get64(in))); RUN_END
RUN_BEGIN(run_abs64_sat, 2, 2) hd_gv_put64(out, hd_abs64_sat(hd_gv_get64(in))); RUN_END
RUN_BEGIN(run_asr64_floor, 3, 2) hd_gv_put64(out, hd_asr64_floor(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_asr64_rnd, 3, 2) hd_gv_put64(out, hd_asr64_rnd(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_asr32_rnd, 3, 1) out[0] = hd_asr32_rnd(hd_gv_get64(in), hd_gv_s2u(in[2])); RUN_END
RUN_BEGIN(run_shl64_sat, 3, 2) hd_gv_put64(out, hd_shl64_sat(hd_gv_get64(in), hd_gv_s2u(in[2]))); RUN_END
RUN_BEGIN(run_shl32_sat, 2, 1) out[0] = hd_shl32_sat(in[0], hd_gv_s2u(in[1])); RUN_END
RUN_BEGIN(run_mul_q, 3, 1) out[0] = hd_mul_q(in[0], in[1], hd_gv_s2u(in[2])); RUN_END
RUN_BEGIN(run_mul64x32_q, 4, 2) hd_gv_put64(out, hd_mul64x32_q(hd_gv_get64(in), in[2], hd_gv_s2u(in[3]))); RUN_END
RUN_BEGIN(run_mac64, 4, 2) hd_gv_put64(out, hd_mac64(hd_gv_get64(in), in[2], in[3])); RUN_END
RUN_BEGIN(run_div_q, 3, 1) out[0] = hd_div_q(in[0], in[1], hd_gv_s2u(in[2])); RUN_END
RUN_BEGIN(run_div64_rnd, 4, 2) hd_gv_put64(out, hd_div64_rnd(hd_gv_get64(in), hd_gv_get64(in + 2))); RUN_END
RUN_BEGIN(run_exp_neg_q16, 1, 1) out[0] = hd_exp_neg_q16(in[0]); RUN_END
RUN_BEGIN(run_sincos_turn, 1, 2) hd_sincos_turn(hd_gv_s2u(in[0]), &out[0], &out[1]); RUN_END
RUN_BEGIN(run_sincos_turn_fast, 1, 2) hd_sincos_turn_fast(hd_gv_s2u(in[0]), &out[0], &out[1]); RUN_END
RUN_BEGIN(run_sin_turn_fast, 1, 1) out[0] = hd_sin_turn_fast(hd_gv_s2u(in[0])); RUN_END
RUN_BEGIN(run_sign_smooth_q30, 2, 1) out[0] = hd_sign_smooth_q30(in[0], in[1]); RUN_END
RUN_BEGIN(run_isqrt64, 2, 1)
    const uint64_t x = ((uint64_t)hd_gv_s2u(in[1]) << 32) | (uint64_t)hd_gv_s2u(in[0]);
    out[0] = hd_gv_u2s(hd_isqrt64(x));
RUN_END

/* ---- cost: one representative call each ------------------------------- */

#define COST32(fn, call) \
    static void fn(void) \
    { \
        const int32_t a = cv_a, b = cv_b; \
        const int64_t a64 = cv_a64, b64 = cv_b64; \
        const uint32_t s = cv_s; \
        (void)a; (void)b; (void)a64; (void)b64; (void)s; \
        hd_gv_cost_mark(); \
        sink32 = (call); \
        hd_gv_cost_mark(); \
    }
#define COST64(fn, call) \
    static void fn(void) \
    { \
        const int32_t a = cv_a, b = cv_b; \
        const int64_t a64 = cv_a64, b64 = cv_b64; \
        const uint32_t s = cv_s; \
        (void)a; (void)b; (void)a64; (void)b64; (void)s; \
        hd_gv_cost_mark(); \
        sink64 = (call); \
        hd_gv_cost_mark(); \
    }

COST32(cost_sat32, hd_sat32(a64))
COST64(cost_satn, hd_satn(a64, 40u))
COST32(cost_clamp32, hd_clamp32(a, b, 0x10000000))
COST64(cost_clamp64, hd_clamp64(a64, b64, 0x1000000000000LL))
COST32(cost_add_sat, hd_add_sat(a, b))
COST32(cost_sub_sat, hd_sub_sat(a, b))
COST32(cost_neg_sat, hd_neg_sat(b))
COST32(cost_abs_sat, hd_abs_sat(b))
COST64(cost_add64_sat, hd_add64_sat(a64, b64))
COST64(cost_sub64_sat, hd_sub64_sat(a64, b64))
COST64(cost_neg64_sat, hd_neg64_sat(b64))
COST64(cost_abs64_sat, hd_abs64_sat(b64))
COST64(cost_asr64_floor, hd_asr64_floor(b64, s))
COST64(cost_asr64_rnd, hd_asr64_rnd(b64, s))
COST32(cost_asr32_rnd, hd_asr32_rnd(b64, s))
COST64(cost_shl64_sat, hd_shl64_sat(b, s))
COST32(cost_shl32_sat, hd_shl32_sat(b, 4u))
COST32(cost_mul_q, hd_mul_q(a, b, 30u))
COST64(cost_mul64x32_q, hd_mul64x32_q(a64, b, 32u))
COST64(cost_mac64, hd_mac64(b64, a, b))
COST32(cost_div_q, hd_div_q(b, a, 16u))
COST64(cost_div64_rnd, hd_div64_rnd(a64, b64))
COST32(cost_exp_neg_q16, hd_exp_neg_q16(a & 0x7FFFF))  /* x = 4.34 */
COST32(cost_sign_smooth_q30, hd_sign_smooth_q30(b, a))
COST32(cost_isqrt64, hd_gv_u2s(hd_isqrt64((uint64_t)a64)))

static void cost_sincos_turn(void)
{
    const uint32_t ang = hd_gv_s2u(cv_a);
    int32_t s, c;
    hd_gv_cost_mark();
    hd_sincos_turn(ang, &s, &c);
    hd_gv_cost_mark();
    sink32 = s;
    sink32 = c;
}

static void cost_sincos_turn_fast(void)
{
    const uint32_t ang = hd_gv_s2u(cv_a);
    int32_t s, c;
    hd_gv_cost_mark();
    hd_sincos_turn_fast(ang, &s, &c);
    hd_gv_cost_mark();
    sink32 = s;
    sink32 = c;
}

static void cost_sin_turn_fast(void)
{
    const uint32_t ang = hd_gv_s2u(cv_a);
    hd_gv_cost_mark();
    sink32 = hd_sin_turn_fast(ang);
    hd_gv_cost_mark();
}

/* ---- registry -------------------------------------------------------- */

const hd_gv_kernel_t hd_gv_fixed_kernels[] = {
    {"hd_sat32", 2, 1, GV_N, gen_e64, run_sat32, cost_sat32},
    {"hd_satn", 3, 2, GV_N, gen_satn, run_satn, cost_satn},
    {"hd_clamp32", 3, 1, GV_N, gen_e32x3, run_clamp32, cost_clamp32},
    {"hd_clamp64", 6, 2, GV_N, gen_e64x3, run_clamp64, cost_clamp64},
    {"hd_add_sat", 2, 1, GV_N, gen_e32x2, run_add_sat, cost_add_sat},
    {"hd_sub_sat", 2, 1, GV_N, gen_e32x2, run_sub_sat, cost_sub_sat},
    {"hd_neg_sat", 1, 1, GV_N, gen_e32, run_neg_sat, cost_neg_sat},
    {"hd_abs_sat", 1, 1, GV_N, gen_e32, run_abs_sat, cost_abs_sat},
    {"hd_add64_sat", 4, 2, GV_N, gen_e64x2, run_add64_sat, cost_add64_sat},
    {"hd_sub64_sat", 4, 2, GV_N, gen_e64x2, run_sub64_sat, cost_sub64_sat},
    {"hd_neg64_sat", 2, 2, GV_N, gen_e64, run_neg64_sat, cost_neg64_sat},
    {"hd_abs64_sat", 2, 2, GV_N, gen_e64, run_abs64_sat, cost_abs64_sat},
    {"hd_asr64_floor", 3, 2, GV_N, gen_e64_s63, run_asr64_floor, cost_asr64_floor},
    {"hd_asr64_rnd", 3, 2, GV_N, gen_e64_s63, run_asr64_rnd, cost_asr64_rnd},
    {"hd_asr32_rnd", 3, 1, GV_N, gen_e64_s63, run_asr32_rnd, cost_asr32_rnd},
    {"hd_shl64_sat", 3, 2, GV_N, gen_e64_s63, run_shl64_sat, cost_shl64_sat},
    {"hd_shl32_sat", 2, 1, GV_N, gen_shl32, run_shl32_sat, cost_shl32_sat},
    {"hd_mul_q", 3, 1, GV_N, gen_mul_q, run_mul_q, cost_mul_q},
    {"hd_mul64x32_q", 4, 2, GV_N, gen_mul64x32_q, run_mul64x32_q, cost_mul64x32_q},
    {"hd_mac64", 4, 2, GV_N, gen_mac64, run_mac64, cost_mac64},
    {"hd_div_q", 3, 1, GV_N, gen_div_q, run_div_q, cost_div_q},
    {"hd_div64_rnd", 4, 2, GV_N, gen_e64x2, run_div64_rnd, cost_div64_rnd},
    {"hd_exp_neg_q16", 1, 1, 2u * GV_N, gen_exp, run_exp_neg_q16, cost_exp_neg_q16},
    {"hd_sincos_turn", 1, 2, 2u * GV_N, gen_e32, run_sincos_turn, cost_sincos_turn},
    {"hd_sincos_turn_fast", 1, 2, 2u * GV_N, gen_e32, run_sincos_turn_fast, cost_sincos_turn_fast},
    {"hd_sin_turn_fast", 1, 1, 2u * GV_N, gen_e32, run_sin_turn_fast, cost_sin_turn_fast},
    {"hd_sign_smooth_q30", 2, 1, GV_N, gen_sign, run_sign_smooth_q30, cost_sign_smooth_q30},
    {"hd_isqrt64", 2, 1, GV_N, gen_e64, run_isqrt64, cost_isqrt64},
};
const uint32_t hd_gv_fixed_count = (uint32_t)(sizeof hd_gv_fixed_kernels / sizeof hd_gv_fixed_kernels[0]);
