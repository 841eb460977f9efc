/*
 * test_comp_preisach.c - discrete Preisach model (hd_preisach.h).
 * setUp builds a table (integer density, sealed) and a PRNG; tearDown frees it.
 * Properties: online == brute-force relay sum EXACTLY on random histories
 * (L = 8/32/64, sub_bits 0..2, dead-band 0 and 2), wiping-out, congruency of
 * minor loops, inverse round trip within half a lattice step, refusal of a bad
 * table (previous stays in force), stack overflow safety net; the inverse's
 * memoised bisection equals the peek-at-every-point bisection it replaced, and
 * spread over calls (hd_preisach_inv_search, any budget) it gives the same
 * index and memory as in one call.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdbool.h>
#include <stdlib.h>
#include <cmocka.h>

#include "hd_preisach.h"

typedef struct {
    hd_preisach_table_t t;
    hd_preisach_t on;
    hd_preisach_bf_t bf;
    hd_preisach_inv_t inv;
    uint64_t rng;
} fx_t;

static uint32_t rnd(fx_t *f)
{
    f->rng ^= f->rng >> 12;
    f->rng ^= f->rng << 25;
    f->rng ^= f->rng >> 27;
    return (uint32_t)((f->rng * 0x2545F4914F6CDD1DULL) >> 32);
}

/* E[i][j] = sum over cells j <= b < a <= i of mu(a, b), mu = 100 + 3 (a - b) + noise >= 0 */
static void build(fx_t *f, uint32_t levels, uint32_t sub_bits, uint32_t version)
{
    int64_t mu[64][64];
    uint32_t i, j, a, b;
    for (a = 1; a < levels; a++) {
        for (b = 0; b < a; b++) {
            mu[a][b] = 100 + 3 * (int64_t)(a - b) + (int64_t)(rnd(f) % 50u);
        }
    }
    f->t.levels = levels;
    f->t.sub_bits = sub_bits;
    f->t.in_shift = 4u;
    f->t.u0 = -1000;
    f->t.unit = HD_PREISACH_UNIT_GENERIC;
    f->t.version = version;
    for (i = 0; i < levels; i++) {
        for (j = 0; j <= i; j++) {
            int64_t s = 0;
            for (a = j + 1; a <= i; a++) {
                for (b = j; b < a; b++) {
                    s += mu[a][b];
                }
            }
            f->t.e[i * (i + 1) / 2 + j] = (int32_t)s;
        }
    }
    hd_preisach_seal(&f->t);
}

static int setUp(void **state)
{
    fx_t *f = calloc(1, sizeof(fx_t));
    if (f == NULL) {
        return -1;
    }
    f->rng = 0x9E3779B97F4A7C15ULL;
    *state = f;
    return 0;
}

static int tearDown(void **state)
{
    free(*state);
    return 0;
}

static void check_equal(fx_t *f, uint32_t levels, uint32_t sub, uint32_t db, uint32_t n)
{
    uint32_t k;
    int32_t p;
    int32_t ptop;
    build(f, levels, sub, 1u);
    assert_int_equal(hd_preisach_check(&f->t), HD_PREISACH_OK);
    ptop = hd_preisach_p_top(&f->t);
    hd_preisach_init(&f->on, &f->t, db, 0u, true);
    hd_preisach_bf_init(&f->bf, &f->t, db);
    assert_true(f->on.y == f->bf.y);
    p = ptop / 2;
    for (k = 0; k < n; k++) {
        /* random walk with occasional big jumps and saturation visits */
        const uint32_t r = rnd(f);
        if ((r & 63u) == 0u) {
            p = (int32_t)(rnd(f) % (uint32_t)(ptop + 1));
        } else {
            p += (int32_t)(r % 9u) - 4;
        }
        p = (p < -3) ? -3 : ((p > ptop + 3) ? ptop + 3 : p);
        {
            const int64_t y1 = hd_preisach_step_p(&f->on, &f->t, p);
            const int64_t y2 = hd_preisach_bf_step_p(&f->bf, &f->t, p);
            if (y1 != y2) {
                fail_msg("L=%u sub=%u db=%u step %u p=%d: online %lld != brute %lld", levels, sub, db,
                         k, p, (long long)y1, (long long)y2);
            }
        }
    }
    assert_int_equal(f->on.merges, 0);
}

static void test_online_equals_bruteforce(void **state)
{
    fx_t *f = *state;
    check_equal(f, 8u, 0u, 0u, 3000u);
    check_equal(f, 32u, 0u, 0u, 2000u);
    check_equal(f, 32u, 0u, 2u, 2000u);
    check_equal(f, 64u, 0u, 1u, 600u);
    check_equal(f, 16u, 2u, 0u, 1500u);
    check_equal(f, 32u, 1u, 2u, 800u);
}

static void test_saturation_and_wiping_out(void **state)
{
    fx_t *f = *state;
    int32_t ptop;
    int64_t ysat;
    int64_t y_a;
    build(f, 32u, 0u, 1u);
    ptop = hd_preisach_p_top(&f->t);
    hd_preisach_init(&f->on, &f->t, 0u, 0u, true);
    ysat = f->on.y;
    assert_true(ysat == -(int64_t)hd_preisach_everett(&f->t, ptop, 0));
    assert_true(hd_preisach_step_p(&f->on, &f->t, ptop) == -ysat);
    /* history 20 -> 5 -> 15 -> 10; then going above 20 wipes out everything in between */
    hd_preisach_init(&f->on, &f->t, 0u, 0u, true);
    (void)hd_preisach_step_p(&f->on, &f->t, 25);
    y_a = hd_preisach_step_p(&f->on, &f->t, 28);       /* on the ascending major branch */
    hd_preisach_init(&f->on, &f->t, 0u, 0u, true);
    (void)hd_preisach_step_p(&f->on, &f->t, 20);
    (void)hd_preisach_step_p(&f->on, &f->t, 5);
    (void)hd_preisach_step_p(&f->on, &f->t, 15);
    (void)hd_preisach_step_p(&f->on, &f->t, 10);
    assert_int_equal(f->on.n_max, 3);                   /* sentinel, 20, 15 */
    assert_true(hd_preisach_step_p(&f->on, &f->t, 28) == y_a);
    assert_int_equal(f->on.n_max, 1);
    assert_int_equal(f->on.n_min, 1);
}

static void test_congruency(void **state)
{
    fx_t *f = *state;
    /* minor loop between 10 and 18 reached from two different histories:
     * same loop shape (output differences), different vertical position */
    static const int32_t h1[] = { 30, 2, 20, 10 };
    static const int32_t h2[] = { 25, 6, 22, 10 };
    int64_t d1[16];
    int64_t d2[16];
    int64_t base;
    uint32_t k;
    int32_t p;
    build(f, 32u, 0u, 1u);
    hd_preisach_init(&f->on, &f->t, 0u, 0u, true);
    for (k = 0; k < 4u; k++) {
        (void)hd_preisach_step_p(&f->on, &f->t, h1[k]);
    }
    base = f->on.y;
    for (k = 0, p = 11; p <= 18; p++, k++) {
        d1[k] = hd_preisach_step_p(&f->on, &f->t, p) - base;
    }
    for (p = 17; p >= 10; p--, k++) {
        d1[k] = hd_preisach_step_p(&f->on, &f->t, p) - base;
    }
    hd_preisach_init(&f->on, &f->t, 0u, 0u, true);
    for (k = 0; k < 4u; k++) {
        (void)hd_preisach_step_p(&f->on, &f->t, h2[k]);
    }
    assert_true(f->on.y != base);
    base = f->on.y;
    for (k = 0, p = 11; p <= 18; p++, k++) {
        d2[k] = hd_preisach_step_p(&f->on, &f->t, p) - base;
    }
    for (p = 17; p >= 10; p--, k++) {
        d2[k] = hd_preisach_step_p(&f->on, &f->t, p) - base;
    }
    for (k = 0; k < 16u; k++) {
        assert_true(d1[k] == d2[k]);
    }
    assert_true(d1[15] == 0);                           /* the loop closes (return-point memory) */
}

static void test_inverse_round_trip(void **state)
{
    fx_t *f = *state;
    int32_t ptop;
    int64_t ysat;
    int64_t yd;
    int64_t maxstep = 0;
    uint32_t k;
    int32_t a;
    build(f, 32u, 2u, 1u);
    ptop = hd_preisach_p_top(&f->t);
    /* largest output change for one lattice step from any state: 2 * max dE */
    for (a = 1; a <= ptop; a++) {
        const int64_t d = (int64_t)hd_preisach_everett(&f->t, a, 0) - hd_preisach_everett(&f->t, a - 1, 0);
        maxstep = (2 * d > maxstep) ? 2 * d : maxstep;
    }
    hd_preisach_inv_init(&f->inv, &f->t, 0u, 0u, true);
    ysat = -f->inv.fwd.y;
    yd = 0;
    for (k = 0; k < 3000u; k++) {
        int64_t y;
        int32_t p;
        yd += (int64_t)(int32_t)(rnd(f) % 2001u) - 1000 + 0 * ysat;
        yd += ((rnd(f) & 255u) == 0u) ? (int64_t)(int32_t)(rnd(f) % 40001u) - 20000 : 0;
        if (yd > ysat * 9 / 10) {
            yd = ysat * 9 / 10;
        }
        if (yd < -ysat * 9 / 10) {
            yd = -ysat * 9 / 10;
        }
        p = hd_preisach_inv_step_p(&f->inv, &f->t, yd);
        y = f->inv.fwd.y;
        if (llabs(y - yd) > maxstep / 2 + 1) {
            fail_msg("step %u: y_d %lld y %lld (p %d), step %lld", k, (long long)yd, (long long)y, p,
                     (long long)maxstep);
        }
    }
}

/* The inverse as it was before the trial points were memoised: bisection with
 * hd_preisach_peek_p at every point (and again at the two ends), then
 * hd_preisach_step_p at the chosen point.  The firmware must give the same p
 * and the same memory, period by period. */
static int32_t ref_inv_step_p(hd_preisach_inv_t *s, const hd_preisach_table_t *t, int64_t y_d)
{
    hd_preisach_t *f = &s->fwd;
    int32_t lo, hi, p;
    if (f->table_crc != t->crc || f->p_top != hd_preisach_p_top(t)) {
        (void)hd_preisach_step_p(f, t, f->p_prev);    /* resets the memory */
    }
    if (y_d == f->y) {
        return f->p_prev;
    }
    if (y_d > f->y) {
        lo = f->p_prev;
        hi = f->p_top;
        if (hi == lo || hd_preisach_peek_p(f, t, hi) < y_d) {
            p = hi;
        } else {
            while (hi - lo > 1) {
                const int32_t mid = lo + (hi - lo) / 2;
                if (hd_preisach_peek_p(f, t, mid) >= y_d) {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            p = (llabs(hd_preisach_peek_p(f, t, hi) - y_d) < llabs(hd_preisach_peek_p(f, t, lo) - y_d)) ? hi : lo;
        }
    } else {
        lo = 0;
        hi = f->p_prev;
        if (hi == lo || hd_preisach_peek_p(f, t, lo) > y_d) {
            p = lo;
        } else {
            while (hi - lo > 1) {
                const int32_t mid = lo + (hi - lo) / 2;
                if (hd_preisach_peek_p(f, t, mid) <= y_d) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            p = (llabs(hd_preisach_peek_p(f, t, lo) - y_d) < llabs(hd_preisach_peek_p(f, t, hi) - y_d)) ? lo : hi;
        }
    }
    (void)hd_preisach_step_p(f, t, p);
    return f->p_prev;
}

/* memoised inverse == peek-everywhere bisection, on random and deeply nested
 * (stack-merging) targets, several lattices and dead-bands */
static void test_inverse_equals_peek_bisection(void **state)
{
    fx_t *f = *state;
    static hd_preisach_inv_t ref;
    static const uint32_t cfg[5][3] = {{8u, 0u, 0u}, {16u, 1u, 0u}, {32u, 2u, 2u}, {64u, 0u, 0u}, {64u, 3u, 1u}};
    uint32_t c, k;
    uint32_t merged = 0u;
    for (c = 0; c < 5u; c++) {
        int64_t ysat;
        int64_t yd = 0;
        build(f, cfg[c][0], cfg[c][1], 1u);
        hd_preisach_inv_init(&f->inv, &f->t, cfg[c][2], 0u, true);
        hd_preisach_inv_init(&ref, &f->t, cfg[c][2], 0u, true);
        ysat = -f->inv.fwd.y;
        for (k = 0; k < 4000u; k++) {
            int32_t p1, p2;
            if (k < 2000u) {
                /* random walk with jumps, beyond saturation now and then */
                yd += (int64_t)(int32_t)(rnd(f) % 4001u) - 2000;
                yd += ((rnd(f) & 63u) == 0u) ? (int64_t)(rnd(f) % 3u - 1u) * ysat / 2 : 0;
                yd = (yd > ysat + 5000) ? ysat + 5000 : ((yd < -ysat - 5000) ? -ysat - 5000 : yd);
            } else {
                /* shrinking oscillation: nests deeper than the stack */
                const int64_t amp = ysat - (int64_t)(k - 2000u) * ysat / 2000;
                yd = ((k & 1u) != 0u) ? amp : -amp;
            }
            p1 = hd_preisach_inv_step_p(&f->inv, &f->t, yd);
            p2 = ref_inv_step_p(&ref, &f->t, yd);
            if (p1 != p2 || f->inv.fwd.y != ref.fwd.y || f->inv.fwd.n_max != ref.fwd.n_max ||
                f->inv.fwd.n_min != ref.fwd.n_min || f->inv.fwd.merges != ref.fwd.merges ||
                f->inv.fwd.dir != ref.fwd.dir) {
                fail_msg("L %u sub %u db %u step %u: p %d vs %d, y %lld vs %lld", cfg[c][0], cfg[c][1], cfg[c][2],
                         k, p1, p2, (long long)f->inv.fwd.y, (long long)ref.fwd.y);
            }
        }
        merged += f->inv.fwd.merges;
    }
    assert_true(merged > 0u);                            /* the merge path was exercised */
}

/* The inverse spread over calls (the bank's schedule, hd_sched.h): with a budget of 1, 2 or 3
 * trials per call the search ends with the same index and memory as the one-shot inverse at
 * the same target; a budget below 2 + log2(P) needs more than one call; the memory does not
 * change before the search ends. */
static void test_inverse_search_spread_equals_one_shot(void **state)
{
    fx_t *f = *state;
    static hd_preisach_inv_t ref;
    static const uint32_t cfg[3][3] = {{16u, 1u, 0u}, {32u, 2u, 2u}, {64u, 3u, 1u}};
    uint32_t c, k, budget;
    uint32_t spread = 0u;
    for (c = 0; c < 3u; c++) {
        for (budget = 1u; budget <= 3u; budget++) {
            int64_t yd = 0;
            int64_t ysat;
            build(f, cfg[c][0], cfg[c][1], 1u);
            hd_preisach_inv_init(&f->inv, &f->t, cfg[c][2], 0u, true);
            hd_preisach_inv_init(&ref, &f->t, cfg[c][2], 0u, true);
            ysat = -f->inv.fwd.y;
            for (k = 0; k < 1500u; k++) {
                uint32_t calls = 0u;
                int32_t p2;
                yd += (int64_t)(int32_t)(rnd(f) % 4001u) - 2000;
                yd += ((rnd(f) & 31u) == 0u) ? (int64_t)(rnd(f) % 3u - 1u) * ysat / 2 : 0;
                yd = (yd > ysat + 5000) ? ysat + 5000 : ((yd < -ysat - 5000) ? -ysat - 5000 : yd);
                const int64_t y_before = f->inv.fwd.y;
                for (;;) {
                    /* a later call's target is ignored while a search runs: pass a wrong one */
                    const bool done = hd_preisach_inv_search(&f->inv, &f->t, (calls == 0u) ? yd : -yd, budget);
                    calls++;
                    if (done) {
                        break;
                    }
                    assert_true(f->inv.fwd.y == y_before);        /* no memory change mid-search */
                    assert_true(calls < 64u);
                }
                spread += (calls > 1u) ? 1u : 0u;
                p2 = hd_preisach_inv_step_p(&ref, &f->t, yd);
                if (f->inv.fwd.p_prev != p2 || f->inv.fwd.y != ref.fwd.y || f->inv.fwd.n_max != ref.fwd.n_max ||
                    f->inv.fwd.n_min != ref.fwd.n_min || f->inv.fwd.dir != ref.fwd.dir) {
                    fail_msg("L %u sub %u budget %u step %u: p %d vs %d, y %lld vs %lld", cfg[c][0], cfg[c][1],
                             budget, k, f->inv.fwd.p_prev, p2, (long long)f->inv.fwd.y, (long long)ref.fwd.y);
                }
            }
        }
    }
    assert_true(spread > 1000u);                          /* the searches really were spread */
    /* a table change abandons the search in progress: the next call starts over on the new table */
    build(f, 16u, 1u, 1u);
    hd_preisach_inv_init(&f->inv, &f->t, 0u, 0u, true);
    assert_false(hd_preisach_inv_search(&f->inv, &f->t, -f->inv.fwd.y / 3, 1u));
    build(f, 32u, 2u, 2u);
    hd_preisach_inv_init(&ref, &f->t, 0u, 0u, true);
    while (!hd_preisach_inv_search(&f->inv, &f->t, -ref.fwd.y / 5, 1u)) {
    }
    assert_int_equal(f->inv.fwd.p_prev, hd_preisach_inv_step_p(&ref, &f->t, -ref.fwd.y / 5));
}

static void test_bad_table_refused(void **state)
{
    fx_t *f = *state;
    static hd_preisach_table_t active;
    static hd_preisach_table_t cand;
    build(f, 16u, 0u, 3u);
    assert_int_equal(hd_preisach_install(&active, &f->t), HD_PREISACH_OK);
    assert_int_equal(active.version, 3);
    cand = f->t;
    cand.version = 4u;
    cand.e[20] += 1;                                     /* content changed, CRC not */
    assert_int_equal(hd_preisach_install(&active, &cand), HD_PREISACH_E_CRC);
    assert_int_equal(active.version, 3);
    assert_int_equal(active.e[20], f->t.e[20]);
    cand = f->t;
    cand.levels = 65u;
    hd_preisach_seal(&cand);
    assert_int_equal(hd_preisach_install(&active, &cand), HD_PREISACH_E_SIZE);
    cand = f->t;
    cand.magic = 0u;
    assert_int_equal(hd_preisach_install(&active, &cand), HD_PREISACH_E_MAGIC);
    cand = f->t;
    cand.e[2] = 1;                                        /* E[1][1] */
    hd_preisach_seal(&cand);
    assert_int_equal(hd_preisach_install(&active, &cand), HD_PREISACH_E_DIAG);
    assert_int_equal(active.version, 3);
}

/* bit-serial CRC-32 (reflected 0xEDB88320, init / xorout all ones), independent of hd_crc32 */
static uint32_t ref_crc32(const uint8_t *p, uint32_t n)
{
    uint32_t c = 0xFFFFFFFFu;
    for (uint32_t i = 0; i < n; i++) {
        c ^= p[i];
        for (uint32_t k = 0; k < 8u; k++) {
            c = (c & 1u) ? (c >> 1) ^ 0xEDB88320u : c >> 1;
        }
    }
    return ~c;
}

/* the table's CRC is the CRC-32 of its image: words 0..8 and the entries, little endian
 * (the bytes a host sends, zlib.crc32 of them), for every size and content */
static void test_table_crc_is_crc32_of_image(void **state)
{
    fx_t *f = *state;
    static uint8_t img[4u * (HD_PREISACH_HDR_WORDS + HD_PREISACH_N_MAX)];
    static const uint32_t lv[3] = {2u, 16u, 64u};
    for (uint32_t c = 0; c < 3u; c++) {
        build(f, lv[c], c, 7u + c);
        uint32_t n = 0;
        for (uint32_t w = 0; w < HD_PREISACH_HDR_WORDS + f->t.n_entries; w++) {
            const uint32_t v = (w < HD_PREISACH_HDR_WORDS) ? *hd_preisach_word(&f->t, w) : (uint32_t)f->t.e[w - HD_PREISACH_HDR_WORDS];
            for (uint32_t b = 0; b < 4u; b++) {
                img[n++] = (uint8_t)(v >> (8u * b));
            }
        }
        assert_int_equal(hd_preisach_crc(&f->t), ref_crc32(img, n));
        assert_int_equal(f->t.crc, ref_crc32(img, n));
    }
}

static void test_stack_overflow_merges(void **state)
{
    fx_t *f = *state;
    int32_t ptop;
    int32_t k;
    build(f, 64u, 3u, 1u);                               /* P = 504: deeper than the stack */
    ptop = hd_preisach_p_top(&f->t);
    hd_preisach_init(&f->on, &f->t, 0u, 0u, true);
    for (k = 0; k < ptop / 2 - 1; k++) {                 /* shrinking oscillation: nests deeply */
        (void)hd_preisach_step_p(&f->on, &f->t, ptop - k);
        (void)hd_preisach_step_p(&f->on, &f->t, k);
    }
    assert_true(f->on.merges > 0u);
    assert_true(f->on.n_max <= HD_PREISACH_DEPTH && f->on.n_min <= HD_PREISACH_DEPTH);
    /* positive saturation still reached exactly */
    assert_true(hd_preisach_step_p(&f->on, &f->t, ptop) == (int64_t)hd_preisach_everett(&f->t, ptop, 0));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_online_equals_bruteforce, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_saturation_and_wiping_out, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_congruency, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_inverse_round_trip, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_inverse_equals_peek_bisection, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_inverse_search_spread_equals_one_shot, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_bad_table_refused, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stack_overflow_merges, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_table_crc_is_crc32_of_image, setUp, tearDown),
    };
    return cmocka_run_group_tests_name("comp_preisach", tests, NULL, NULL);
}
