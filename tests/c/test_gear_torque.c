/*
 * test_gear_torque.c - the motor-side transmitted-torque estimate (hd_gear_torque.h)
 * and its use in the bank's twist prediction (pr_t_src 2): the hysteresis branch
 * a stop keeps after a move up differs from the one after a move down.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "hd_fixed.h"
#include "hd_gear_torque.h"
#include "hd_comp_bank.h"

#define TEST_PI 3.14159265358979323846
#define NM(x) ((int32_t)llround((x) * 65536.0))
#define DEGS(x) ((int32_t)llround((x) / 360.0 * 4294967296.0))

static hd_gear_torque_cfg_t cfg;
static hd_gear_torque_t gt;

static int setUp(void **state)
{
    (void)state;
    cfg.jm = NM(1.5);               /* N^2 J_m, kg m^2 */
    cfg.vs = DEGS(1.0);             /* hand-over between 2 and 1 deg/s */
    cfg.step_hz = 1250;
    hd_gear_torque_reset(&gt);
    return 0;
}

static int tearDown(void **state)
{
    (void)state;
    return 0;
}

static double nm(int32_t q16) { return q16 / 65536.0; }

/* While the reference moves faster than 2 vs: torque - motor friction - J_m a, with a the
 * change of the velocity feedback over one step (none on the first step after a reset). */
static void test_moving_is_motor_side(void **state)
{
    (void)state;
    const double a = 2.0;                                        /* rad/s^2 */
    const int32_t v0 = DEGS(10.0);
    const int32_t v1 = v0 + (int32_t)llround(a / 1250.0 / (2.0 * TEST_PI) * 4294967296.0);
    double t = nm(hd_gear_torque_step(&gt, &cfg, NM(30.0), NM(20.0), DEGS(10.0), v0, NM(5.0)));
    print_message("first step %.5f N.m (expected 10: no acceleration yet)\n", t);
    assert_true(fabs(t - 10.0) < 1e-4);
    t = nm(hd_gear_torque_step(&gt, &cfg, NM(30.0), NM(20.0), DEGS(10.0), v1, NM(5.0)));
    print_message("accelerating %.5f N.m (expected %.5f)\n", t, 10.0 - 1.5 * a);
    assert_true(fabs(t - (10.0 - 1.5 * a)) < 2e-3);
    /* the same backwards: a negative velocity growing in size (a = -2 rad/s^2) */
    hd_gear_torque_reset(&gt);
    (void)hd_gear_torque_step(&gt, &cfg, NM(-30.0), NM(-20.0), DEGS(-10.0), -v0, NM(5.0));
    t = nm(hd_gear_torque_step(&gt, &cfg, NM(-30.0), NM(-20.0), DEGS(-10.0), -v1, NM(5.0)));
    print_message("backwards %.5f N.m (expected %.5f)\n", t, -10.0 + 1.5 * a);
    assert_true(fabs(t - (-10.0 + 1.5 * a)) < 2e-3);
    assert_int_equal(gt.w, HD_Q30_ONE);
}

/* At rest the command holds the motor's stiction, unknown: the estimate is the model's, whatever
 * the command; between 2 vs and vs it hands over linearly. */
static void test_rest_is_model_and_hand_over(void **state)
{
    (void)state;
    int32_t t = hd_gear_torque_step(&gt, &cfg, NM(40.0), NM(0.0), 0, 0, NM(3.0));
    assert_int_equal(t, NM(3.0));
    assert_int_equal(gt.w, 0);
    t = hd_gear_torque_step(&gt, &cfg, NM(40.0), NM(0.0), DEGS(1.0), 0, NM(3.0));
    assert_int_equal(t, NM(3.0));                                /* at vs: still the model */
    t = hd_gear_torque_step(&gt, &cfg, NM(13.0), NM(0.0), DEGS(-1.5), 0, NM(3.0));
    print_message("at 1.5 vs: %.5f N.m (expected 8)\n", nm(t));
    assert_true(fabs(nm(t) - 8.0) < 1e-4);
    t = hd_gear_torque_step(&gt, &cfg, NM(13.0), NM(0.0), DEGS(2.0), 0, NM(3.0));
    assert_true(fabs(nm(t) - 13.0) < 1e-4);
}

/* Saturation at the word's edges: a velocity jump across the whole word gives an inertia torque far
 * beyond the word, and the estimate saturates instead of wrapping to the other sign. */
static void test_edges_saturate(void **state)
{
    (void)state;
    (void)hd_gear_torque_step(&gt, &cfg, 0, 0, INT32_MAX, INT32_MAX, 0);
    int32_t t = hd_gear_torque_step(&gt, &cfg, INT32_MAX, 0, INT32_MAX, INT32_MIN, 0);
    assert_int_equal(t, INT32_MAX);             /* - J a with a hugely negative: positive, saturated */
    t = hd_gear_torque_step(&gt, &cfg, INT32_MIN, 0, INT32_MIN, INT32_MAX, 0);
    assert_int_equal(t, INT32_MIN);             /* the opposite jump */
}

/* In the bank (semi-closed, hysteretic torque -> twist image of relays 2 N.m wide): a move up ends
 * with the deceleration's negative torque swing, a move down with a positive one, both stop at the
 * same model torque (0 N.m) while the command holds an arbitrary stiction torque.  With the motor-side
 * estimate (pr_t_src 2) a stop after a move up keeps the negative remanence of the deceleration's
 * swing and one after a move down the positive one, as the gear does (docs/compensators.md section
 * 13).  The model estimate (pr_t_src 1) sees the friction of the motion's direction instead and
 * ends each stop on the other branch. */
static int64_t stop_after(uint32_t src, double v_deg_s, double swing_nm)
{
    static hd_preisach_table_t t;
    int32_t p[HD_PARAM_COUNT];
    static hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    const double lsb_per_nm = 1.0 / 31000.0 / (2.0 * TEST_PI) * 4294967296.0;
    memset(&t, 0, sizeof t);
    t.version = 1u; t.levels = 17u; t.sub_bits = 2u; t.in_shift = 14u; t.u0 = -(8 << 16);
    t.unit = HD_PREISACH_UNIT_TORQUE_TWIST;
    for (uint32_t i = 0; i < t.levels; i++)
        for (uint32_t j = 0; j < i; j++)
            t.e[i * (i + 1u) / 2u + j] = (int32_t)llround(lsb_per_nm * ((double)(i - j) + fmax((double)(i - j) - 2.0, 0.0)) / 2.0);
    hd_preisach_seal(&t);
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) p[i] = hd_param_table[i].def;   /* the defaults */
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_PREISACH;
    p[HD_P_FB_CONFIG] = 1;
    p[HD_P_CB_RAMP_TICKS] = 1;
    p[HD_P_PR_T_SRC] = (int32_t)src;
    p[HD_P_PR_MOTOR_SHARE] = 0;            /* the motor friction model subtracts nothing here */
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_init(&b, &c);
    assert_int_equal(hd_comp_bank_install_table(&b, &t), HD_PREISACH_OK);
    memset(&in, 0, sizeof in);
    in.vel_ref = DEGS(v_deg_s);
    in.vel_fb = in.vel_ref;
    hd_comp_bank_end(&b, NM(swing_nm));                           /* the end of the move's deceleration */
    for (int k = 0; k < 4000; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    in.vel_ref = 0;
    in.vel_fb = 0;
    hd_comp_bank_end(&b, NM(6.0));                                /* at rest: the motor's stiction, ignored */
    for (int k = 0; k < 4000; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    assert_true(llabs(b.pr_test) < 64);                           /* the model's 0 N.m */
    return o.dpos;
}

static void test_branch_after_up_and_down_moves(void **state)
{
    (void)state;
    const double lsb_per_nm = 1.0 / 31000.0 / (2.0 * TEST_PI) * 4294967296.0;
    const int64_t up2 = stop_after(2u, 10.0, -6.0);
    const int64_t dn2 = stop_after(2u, -10.0, 6.0);
    const int64_t up1 = stop_after(1u, 10.0, -6.0);
    const int64_t dn1 = stop_after(1u, -10.0, 6.0);
    print_message("pr_t_src 2: twist after up %lld, after down %lld LSB; pr_t_src 1: %lld / %lld (1 N.m = %.0f LSB)\n",
                  (long long)up2, (long long)dn2, (long long)up1, (long long)dn1, lsb_per_nm);
    assert_true((double)(dn2 - up2) > 1.5 * lsb_per_nm);            /* the remanence of +-6 N.m swings */
    assert_true(up2 < 0 && dn2 > 0);
    assert_true((double)(up1 - dn1) > 1.5 * lsb_per_nm);            /* the model: the motion's friction */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_moving_is_motor_side, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_rest_is_model_and_hand_over, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_edges_saturate, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_branch_after_up_and_down_moves, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
