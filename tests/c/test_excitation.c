/*
 * test_excitation.c - the multisine generator (hd_excitation.h) gives, period by
 * period, the words of its definition: each line's phase floor(x 2^32 / den) of
 * i t / period minus the Schroeder phase i (i - 1) / (2 n), each formed here by
 * its own 64-bit division, for line counts 1 .. 64 and periods on both sides of
 * 2^16 (the generator forms them by exact sums).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "hd_fixed.h"
#include "hd_excitation.h"

static int setUp(void **state)
{
    (void)state;
    return 0;
}

static int tearDown(void **state)
{
    (void)state;
    return 0;
}

/* floor(num 2^32 / den), num < den, by the 64-bit division */
static uint32_t ref_frac(uint64_t num, uint64_t den)
{
    return (uint32_t)((num << 32) / den);
}

/* the multisine's word at period k by the definition (hd_excitation.h) */
static int32_t ref_multisine(const hd_exc_cfg_t *c, uint32_t k)
{
    const uint64_t t = k % c->period;
    int64_t sum = 0;
    uint64_t i;
    for (i = 1; i <= c->n; i++) {
        const uint32_t ph = ref_frac((i * t) % c->period, c->period);
        const uint32_t sch = ref_frac((i * (i - 1u)) % (2u * c->n), 2u * c->n);
        int32_t sv, cv;
        hd_sincos_turn_fast(ph - sch, &sv, &cv);
        sum = hd_add64_sat(sum, (int64_t)hd_mul_q(c->amp, sv, 30u));
    }
    return hd_add_sat(hd_sat32(sum), c->offset);
}

static void check_cfg(uint32_t n, uint32_t period, int32_t amp, uint32_t steps, uint32_t k0)
{
    hd_exc_cfg_t c = {0};
    hd_exc_t s;
    uint32_t k;
    c.kind = (int32_t)HD_EXC_MULTISINE;
    c.amp = amp;
    c.offset = -3;
    c.n = n;
    c.period = period;
    assert_int_equal(hd_exc_start(&s, &c), 0);
    s.k = k0;                   /* start deep in a long period: large t and i t */
    for (k = 0; k < steps; k++) {
        const int32_t want = ref_multisine(&c, k0 + k);
        const int32_t got = hd_exc_step(&s, &c);
        if (got != want) {
            fail_msg("n %u period %u k %u: %d, definition %d", (unsigned)n, (unsigned)period,
                     (unsigned)(k0 + k), (int)got, (int)want);
        }
    }
}

static void test_multisine_words_of_the_definition(void **state)
{
    static const uint32_t periods[] = {2u, 3u, 7u, 50u, 97u, 1000u, 65535u, 65536u, 65537u, 1000003u};
    static const uint32_t lines[] = {1u, 2u, 3u, 4u, 5u, 7u, 16u, 33u, 64u};
    uint32_t a, b;
    (void)state;
    for (a = 0; a < sizeof periods / sizeof periods[0]; a++) {
        for (b = 0; b < sizeof lines / sizeof lines[0]; b++) {
            const uint32_t p = periods[a];
            const uint32_t n = lines[b];
            if ((uint64_t)n * p > 0x7FFFFFFFu) {
                continue;
            }
            check_cfg(n, p, 1 << 20, (p < 300u) ? 2u * p + 3u : 300u, 0u);
            if (p > 300u) {
                check_cfg(n, p, 0x7FFFFFFF / (int32_t)n, 300u, p - 150u);
            }
        }
    }
}

/* the lines' sum saturates like the definition's when the amplitude is large */
static void test_multisine_saturates(void **state)
{
    (void)state;
    check_cfg(8u, 40u, 0x7FFFFFFF, 80u, 0u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_multisine_words_of_the_definition, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_multisine_saturates, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
