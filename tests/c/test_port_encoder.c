/*
 * test_port_encoder.c - 16-bit quadrature counter to multi-turn count
 * (hd_encoder.h): wrap in both directions, direction changes, long random
 * motion against an exact int64 reference, single-turn modulo for negative
 * counts, large jumps flagged.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <cmocka.h>

#include "hd_encoder.h"

static uint64_t rng = 0x9E3779B97F4A7C15ull;
static uint32_t rnd(void)
{
    rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17;
    return (uint32_t)(rng >> 16);
}

/* the hardware counter: true position mod 2^16 */
static uint32_t timer_of(int64_t pos)
{
    return (uint32_t)((uint64_t)pos & 0xFFFFu);
}

static void test_wrap_forward_backward(void **st)
{
    hd_enc_t e;
    (void)st;
    hd_enc_init(&e, 65533u, 0, 2000u);
    assert_int_equal(hd_enc_update(&e, 65535u), 2);
    assert_int_equal(hd_enc_update(&e, 2u), 3);            /* wrap up */
    assert_true(e.count == 5);
    assert_int_equal(hd_enc_update(&e, 65534u), -4);       /* wrap down */
    assert_true(e.count == 1);
    assert_int_equal(hd_enc_update(&e, 65534u), 0);
    assert_int_equal(e.ok, 1u);
    assert_int_equal(e.jumps, 0u);
}

static void test_direction_changes_and_long_run(void **st)
{
    hd_enc_t e;
    int64_t pos = -123456789;
    uint32_t k;
    (void)st;
    hd_enc_init(&e, timer_of(pos), pos, 1700u);
    for (k = 0; k < 2000000u; k++) {
        /* velocity with frequent reversals, up to the reference motor's max (1678 counts/period) */
        const int32_t step = (int32_t)(rnd() % 3357u) - 1678;
        pos += step;
        assert_int_equal(hd_enc_update(&e, timer_of(pos) | 0xABCD0000u), step);  /* high bits ignored */
        assert_int_equal(e.ok, 1u);
    }
    assert_true(e.count == pos);
    assert_int_equal(e.jumps, 0u);
    /* many turns of 2^17 in one direction */
    for (k = 0; k < 100000u; k++) {
        pos += 1678;
        (void)hd_enc_update(&e, timer_of(pos));
    }
    assert_true(e.count == pos);
    assert_int_equal(hd_enc_single_turn(&e, 17u), (uint32_t)((uint64_t)pos & 0x1FFFFu));
}

static void test_single_turn_negative(void **st)
{
    hd_enc_t e;
    (void)st;
    hd_enc_init(&e, 0u, -1, 100u);
    assert_int_equal(hd_enc_single_turn(&e, 17u), 131071u);
    hd_enc_init(&e, 0u, -131072, 100u);
    assert_int_equal(hd_enc_single_turn(&e, 17u), 0u);
    hd_enc_init(&e, 0u, -131073, 100u);
    assert_int_equal(hd_enc_single_turn(&e, 17u), 131071u);
    hd_enc_init(&e, 0u, 131072 * 5 + 7, 100u);
    assert_int_equal(hd_enc_single_turn(&e, 17u), 7u);
    assert_int_equal(hd_enc_single_turn(&e, 32u), (uint32_t)(131072 * 5 + 7));
}

static void test_large_jumps_flagged(void **st)
{
    hd_enc_t e;
    (void)st;
    hd_enc_init(&e, 100u, 0, 2000u);
    assert_int_equal(hd_enc_update(&e, 2100u), 2000);
    assert_int_equal(e.ok, 1u);
    assert_int_equal(hd_enc_update(&e, 4101u), 2001);       /* implausible */
    assert_int_equal(e.ok, 0u);
    assert_int_equal(e.jumps, 1u);
    assert_int_equal(hd_enc_update(&e, 4101u - 30000u), -30000);
    assert_int_equal(e.jumps, 2u);
    /* a half-range jump aliases to -32768: counted, flagged */
    assert_int_equal(hd_enc_update(&e, (4101u - 30000u + 32768u) & 0xFFFFu), -32768);
    assert_int_equal(e.jumps, 3u);
    assert_int_equal(hd_enc_update(&e, (4101u - 30000u + 32768u + 10u) & 0xFFFFu), 10);
    assert_int_equal(e.ok, 1u);
    /* max_step is capped at 32767 */
    hd_enc_init(&e, 0u, 0, 100000u);
    assert_int_equal(e.max_step, 32767u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wrap_forward_backward),
        cmocka_unit_test(test_direction_changes_and_long_run),
        cmocka_unit_test(test_single_turn_negative),
        cmocka_unit_test(test_large_jumps_flagged),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
