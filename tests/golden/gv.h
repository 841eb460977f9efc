/*
 * gv.h - golden-vector kernel registry (bit-exactness host x86 vs Cortex-M4).
 *
 * Every firmware kernel (helper, filter, controller step, compensator) joins
 * the golden vectors.  A module contributes a file tests/golden/gv_<module>.c
 * that defines
 *
 *     const hd_gv_kernel_t hd_gv_<module>_kernels[];
 *     const uint32_t       hd_gv_<module>_count;
 *
 * The build collects every gv_*.c (mk/golden.mk generates the registry).
 *
 * Flow: the host generator calls gen() for each vector to make the inputs and
 * run() on the host to make the expected outputs; both are written into a C
 * data file compiled into the Cortex-M4 image, which calls run() on the same
 * inputs and compares every output word.  On mismatch it names the kernel and
 * the first differing index.
 *
 * run() receives the whole input sequence at once, so a stateful controller
 * can be exercised as a sequence of steps (initialise state, then one step per
 * vector); a stateless kernel just maps each vector.
 *
 * Files here are compiled for both targets with the firmware flags (integer
 * only, no libc beyond stdint/stdbool/stddef).
 */
#ifndef HD_GV_H
#define HD_GV_H

#include <stdint.h>

/* Deterministic PRNG for input generation (xorshift64*); same on every target. */
typedef struct {
    uint64_t s;
} hd_gv_rng_t;

uint64_t hd_gv_rand64(hd_gv_rng_t *r);
uint32_t hd_gv_rand32(hd_gv_rng_t *r);
/* Uniform in [lo, hi] (inclusive), lo <= hi. */
int32_t hd_gv_rand_range(hd_gv_rng_t *r, int32_t lo, int32_t hi);
/* A 32-bit value biased towards edge cases (0, +-1, INT32_MIN/MAX, powers of
 * two and their neighbours) about a quarter of the time, else uniform. */
int32_t hd_gv_rand_edge32(hd_gv_rng_t *r);

/* Additions (tests/golden/golden_common.c): a 64-bit edge-biased value
 * (INT64_MIN/MAX, 0, +-1, powers of two and neighbours, else uniform over a
 * random bit width) and the FNV-1a hash of a kernel name (the PRNG seed of
 * each kernel is hd_gv_seed(name), so adding a kernel never changes the
 * vectors of another). */
int64_t hd_gv_rand_edge64(hd_gv_rng_t *r);
uint64_t hd_gv_seed(const char *name);

/* Word packing without implementation-defined conversions: int64 values
 * travel as two int32 words (low word first), uint32 as its int32 image. */
static inline int32_t hd_gv_u2s(uint32_t u)
{
    return (u > (uint32_t)INT32_MAX) ? ((int32_t)(u - 0x80000000u) - INT32_MAX - 1) : (int32_t)u;
}
static inline uint32_t hd_gv_s2u(int32_t s)
{
    return (uint32_t)s;
}
static inline void hd_gv_put64(int32_t *w, int64_t v)
{
    const uint64_t u = (uint64_t)v;
    w[0] = hd_gv_u2s((uint32_t)(u & 0xFFFFFFFFu));
    w[1] = hd_gv_u2s((uint32_t)(u >> 32));
}
static inline int64_t hd_gv_get64(const int32_t *w)
{
    const uint64_t u = ((uint64_t)hd_gv_s2u(w[1]) << 32) | (uint64_t)hd_gv_s2u(w[0]);
    /* two's complement image back to int64 without a wrapping conversion */
    return (u > (uint64_t)INT64_MAX) ? ((int64_t)(u - ((uint64_t)1 << 63)) - INT64_MAX - 1) : (int64_t)u;
}

/* Called immediately before and after the measured call inside cost(); the
 * instruction counter takes the difference (see tests/golden/README.md). */
void hd_gv_cost_mark(void);

typedef struct {
    const char *name;   /* kernel name as it appears in cm4_cost.json */
    uint32_t n_in;      /* int32 words per input vector */
    uint32_t n_out;     /* int32 words per output vector */
    uint32_t count;     /* number of vectors */
    /* Host generator: fill in[0..n_in) for vector idx. */
    void (*gen)(uint32_t idx, hd_gv_rng_t *rng, int32_t *in);
    /* Run all count vectors: in has count*n_in words, out count*n_out words. */
    void (*run)(const int32_t *in, int32_t *out, uint32_t count);
    /* Optional: one representative call bracketed by hd_gv_cost_mark(). */
    void (*cost)(void);
} hd_gv_kernel_t;

#endif /* HD_GV_H */
