/*
 * golden_common.c - PRNG and cost marker of the golden-vector harness
 * (contract: gv.h).  Compiled for the host generator and the Cortex-M4
 * images with the firmware flags.  Not a gv_*.c module file.
 */
#include "gv.h"

uint64_t hd_gv_rand64(hd_gv_rng_t *r)
{
    /* xorshift64* (Vigna); a zero state is replaced by a fixed constant */
    uint64_t x = (r->s != 0u) ? r->s : 0x9E3779B97F4A7C15u;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    r->s = x;
    return x * 0x2545F4914F6CDD1Du;
}

uint32_t hd_gv_rand32(hd_gv_rng_t *r)
{
    return (uint32_t)(hd_gv_rand64(r) >> 32);
}

int32_t hd_gv_rand_range(hd_gv_rng_t *r, int32_t lo, int32_t hi)
{
    const uint32_t span = hd_gv_s2u(hi) - hd_gv_s2u(lo);   /* hi - lo, mod 2^32 */
    const uint32_t v = hd_gv_rand32(r);
    const uint32_t off = (span == 0xFFFFFFFFu) ? v : (v % (span + 1u));
    return hd_gv_u2s(hd_gv_s2u(lo) + off);
}

int32_t hd_gv_rand_edge32(hd_gv_rng_t *r)
{
    static const int32_t edges[] = {0, 1, -1, 2, -2, INT32_MAX, INT32_MIN, INT32_MAX - 1,
                                    INT32_MIN + 1, 65536, -65536, 1073741824, -1073741824};
    const uint64_t u = hd_gv_rand64(r);
    const uint32_t sel = (uint32_t)(u & 7u);
    if (sel == 0u) {
        return edges[(u >> 8) % (sizeof edges / sizeof edges[0])];
    }
    if (sel == 1u) {
        /* a power of two, minus one, or plus one, either sign */
        const uint32_t k = (uint32_t)((u >> 8) % 31u);
        const int32_t v = (int32_t)(1u << k) + (int32_t)((u >> 16) % 3u) - 1;
        return (((u >> 20) & 1u) != 0u) ? -v : v;
    }
    return hd_gv_u2s((uint32_t)(u >> 32));
}

int64_t hd_gv_rand_edge64(hd_gv_rng_t *r)
{
    static const int64_t edges[] = {0, 1, -1, INT64_MAX, INT64_MIN, INT64_MAX - 1, INT64_MIN + 1,
                                    (int64_t)INT32_MAX, (int64_t)INT32_MIN, (int64_t)1 << 32,
                                    -((int64_t)1 << 32), (int64_t)1 << 62, -((int64_t)1 << 62)};
    const uint64_t u = hd_gv_rand64(r);
    const uint32_t sel = (uint32_t)(u & 7u);
    if (sel == 0u) {
        return edges[(u >> 8) % (sizeof edges / sizeof edges[0])];
    }
    if (sel == 1u) {
        const uint32_t k = (uint32_t)((u >> 8) % 63u);
        const int64_t v = (int64_t)((uint64_t)1 << k) + (int64_t)((u >> 16) % 3u) - 1;
        return (((u >> 20) & 1u) != 0u) ? -v : v;
    }
    {
        /* uniform over a random bit width (1..64), either sign */
        const uint32_t w = (uint32_t)((u >> 8) % 64u) + 1u;
        const uint64_t v = hd_gv_rand64(r);
        if (w == 64u) {
            int32_t tmp[2];
            tmp[0] = hd_gv_u2s((uint32_t)(v & 0xFFFFFFFFu));
            tmp[1] = hd_gv_u2s((uint32_t)(v >> 32));
            return hd_gv_get64(tmp);
        }
        {
            const int64_t m = (int64_t)(v & (((uint64_t)1 << w) - 1u));
            return (((u >> 20) & 1u) != 0u) ? -m : m;
        }
    }
}

uint64_t hd_gv_seed(const char *name)
{
    uint64_t h = 0xCBF29CE484222325u;       /* FNV-1a 64 */
    while (*name != '\0') {
        h ^= (uint64_t)(uint8_t)*name;
        h *= 0x100000001B3u;
        name++;
    }
    return (h != 0u) ? h : 1u;
}

/* The instruction counter (tools/qemu-insncount) fires on this address:
 * keep it a real, out-of-line, empty function. */
__attribute__((noinline)) void hd_gv_cost_mark(void)
{
    __asm__ volatile("" ::: "memory");
}
