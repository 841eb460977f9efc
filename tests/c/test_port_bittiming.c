/*
 * test_port_bittiming.c - CAN bit timing from the kernel clock (hd_bittiming.h):
 * several clocks and bitrates give an exact bitrate, a sample point in the
 * window, register images as RM0440 defines them; impossible requests are
 * refused; the checker rejects every corrupted timing.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <cmocka.h>

#include "hd_bittiming.h"

static const hd_bt_limits_t *L = &hd_bt_fdcan_nominal;

static void expect_ok(uint32_t clk, uint32_t br, uint32_t spmin, uint32_t spmax, hd_bt_t *t)
{
    assert_int_equal(hd_bittiming_calc(clk, br, 875u, spmin, spmax, L, t), 0);
    assert_int_equal(hd_bittiming_check(t, clk, br, spmin, spmax, L), 0);
    /* exact: clock = bitrate * brp * n_tq */
    assert_true((uint64_t)br * t->brp * t->n_tq == (uint64_t)clk);
    assert_int_equal(t->n_tq, 1u + t->tseg1 + t->tseg2);
    assert_true(t->sp_permille >= spmin && t->sp_permille <= spmax);
    assert_true(t->sjw >= 1u && t->sjw <= t->tseg2);
    assert_true(t->tseg2 >= 2u);
    printf("# %9u Hz %7u bit/s: brp %3u, %3u tq (1+%u+%u), sjw %u, sample point %u.%u %%\n",
           clk, br, t->brp, t->n_tq, t->tseg1, t->tseg2, t->sjw, t->sp_permille / 10u, t->sp_permille % 10u);
}

static void test_drive_clock_1mbit(void **st)
{
    hd_bt_t t;
    (void)st;
    /* the drive: FDCAN kernel clock = HSE 24 MHz */
    expect_ok(24000000u, 1000000u, 800u, 875u, &t);
    assert_int_equal(t.brp, 1u);
    assert_int_equal(t.n_tq, 24u);
    assert_int_equal(t.tseg1, 20u);
    assert_int_equal(t.tseg2, 3u);
    assert_int_equal(t.sp_permille, 875u);
    assert_int_equal(hd_bittiming_fdcan_nbtp(&t), (2u << 25) | (0u << 16) | (19u << 8) | 2u);
    /* the drive: FDCAN kernel clock = PCLK1 170 MHz (HSE 8 or 24 MHz -> PLL) */
    expect_ok(170000000u, 1000000u, 800u, 875u, &t);
    assert_int_equal(t.n_tq, 170u);
    assert_int_equal(t.tseg2, 22u);
    assert_int_equal(t.sp_permille, 871u);
    /* 8 MHz at 1 Mbit/s: 8 tq give 75 % (tseg2 >= 2 tq for the information
     * processing time), outside the window: refused */
    assert_int_equal(hd_bittiming_calc(8000000u, 1000000u, 875u, 800u, 875u, L, &t), -1);
    expect_ok(8000000u, 500000u, 800u, 875u, &t);
    assert_int_equal(t.n_tq, 16u);
    assert_int_equal(t.sp_permille, 875u);
}

static void test_many_clocks(void **st)
{
    static const uint32_t clk[] = {16000000u, 20000000u, 24000000u, 40000000u,
                                   80000000u, 160000000u, 170000000u};
    static const uint32_t br[] = {1000000u, 500000u, 250000u, 125000u};
    hd_bt_t t;
    uint32_t i, j;
    (void)st;
    for (i = 0; i < sizeof clk / sizeof clk[0]; i++) {
        for (j = 0; j < sizeof br / sizeof br[0]; j++) {
            expect_ok(clk[i], br[j], 800u, 875u, &t);
        }
    }
    /* 170 MHz PCLK at 1 Mbit/s: 87.5 % is not reachable, the closest below */
    expect_ok(170000000u, 1000000u, 800u, 875u, &t);
    assert_true(t.sp_permille >= 860u);
}

static void test_impossible(void **st)
{
    hd_bt_t t = {0u, 0u, 0u, 0u, 0u, 0u};
    (void)st;
    /* fewer than 8 tq per bit */
    assert_int_equal(hd_bittiming_calc(7000000u, 1000000u, 875u, 800u, 875u, L, &t), -1);
    /* no exact division: 1 Mbit/s from 25.5 MHz, 1 Mbit/s from 10 MHz with a tight window */
    assert_int_equal(hd_bittiming_calc(25500000u, 1000000u, 875u, 800u, 875u, L, &t), -1);
    assert_int_equal(hd_bittiming_calc(10000000u, 3000000u, 875u, 800u, 875u, L, &t), -1);
    /* a window no n_tq reaches: 8 tq -> sample points 750, 875; ask for 880..890 */
    assert_int_equal(hd_bittiming_calc(8000000u, 1000000u, 885u, 880u, 890u, L, &t), -1);
    /* zero / nonsense arguments */
    assert_int_equal(hd_bittiming_calc(0u, 1000000u, 875u, 800u, 875u, L, &t), -1);
    assert_int_equal(hd_bittiming_calc(24000000u, 0u, 875u, 800u, 875u, L, &t), -1);
    assert_int_equal(hd_bittiming_calc(24000000u, 1000000u, 875u, 900u, 800u, L, &t), -1);
    /* 1 kbit/s from 170 MHz needs a prescaler > 512 with <= 385 tq */
    assert_int_equal(hd_bittiming_calc(170000000u, 1000u, 875u, 800u, 875u, L, &t), -1);
    assert_int_equal(t.brp, 0u);     /* untouched on failure */
}

static void test_check_rejects_corruption(void **st)
{
    hd_bt_t t, b;
    (void)st;
    assert_int_equal(hd_bittiming_calc(24000000u, 1000000u, 875u, 800u, 875u, L, &t), 0);
    b = t; b.brp++;                     assert_int_equal(hd_bittiming_check(&b, 24000000u, 1000000u, 800u, 875u, L), -1);
    b = t; b.tseg1++;                   assert_int_equal(hd_bittiming_check(&b, 24000000u, 1000000u, 800u, 875u, L), -1);
    b = t; b.tseg1++; b.n_tq++;         assert_int_equal(hd_bittiming_check(&b, 24000000u, 1000000u, 800u, 875u, L), -1);
    b = t; b.sjw = b.tseg2 + 1u;        assert_int_equal(hd_bittiming_check(&b, 24000000u, 1000000u, 800u, 875u, L), -1);
    b = t; b.sjw = 0u;                  assert_int_equal(hd_bittiming_check(&b, 24000000u, 1000000u, 800u, 875u, L), -1);
    b = t;                              assert_int_equal(hd_bittiming_check(&b, 24000000u, 500000u, 800u, 875u, L), -1);
    b = t;                              assert_int_equal(hd_bittiming_check(&b, 24000000u, 1000000u, 880u, 900u, L), -1);
    b = t; b.brp = 513u;                assert_int_equal(hd_bittiming_check(&b, 24000000u, 1000000u, 800u, 875u, L), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_drive_clock_1mbit),
        cmocka_unit_test(test_many_clocks),
        cmocka_unit_test(test_impossible),
        cmocka_unit_test(test_check_rejects_corruption),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
