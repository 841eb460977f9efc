/*
 * test_stab.c - the inertial stabilisation estimator (firmware/core/hd_stab.h):
 * exact gyro integration, bias removal, inertial reference, base-rate estimate
 * against a double reference, complementary blend (bias estimate converges,
 * base rocking does not leak), dead band.  Double is the reference only.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "hd_fixed.h"
#include "hd_stab.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#define Q32 4294967296.0
#define TURN_ARCSEC 1296000.0
#define HZ(x) ((int32_t)llround((x) * 65536.0))
#define TPS(x) ((int32_t)llround((x) * Q32))          /* turn/s -> 2^-32 turn/s */

static hd_stab_cfg_t design(int32_t bias, double fc, double bw)
{
    hd_stab_cfg_t c;
    hd_stab_design(&c, bias, HZ(fc), HZ(0.05), TPS(10.0 / 360.0 / 3600.0), HZ(bw), 65536, TPS(1e-5));
    return c;
}

/* integration is exact: 0.001 deg/s for 1 s advances the angle by exactly the rate word */
static void test_stab_exact_integration(void **st)
{
    (void)st;
    const hd_stab_cfg_t c = design(0, 0.0, 100.0);
    hd_stab_t s;
    const hd_angle_t p0 = (hd_angle_t)12345 << 20;
    hd_stab_init(&s);
    hd_stab_start(&s, &c, p0, 0, 0);
    assert_true(hd_stab_angle(&s) == p0);
    for (int k = 0; k < 10000; k++) {
        hd_stab_step(&s, &c, 11930, p0, 0);
    }
    assert_true(hd_stab_angle(&s) - p0 == 11930);
    assert_int_equal(s.err, -11930);              /* reference stayed */
    /* an odd rate over a non-multiple of 1e4 periods: the sum is exact, the read-out rounds */
    hd_stab_start(&s, &c, 0, 0, 0);
    for (int k = 0; k < 12345; k++) {
        hd_stab_step(&s, &c, -777777, 0, 0);
    }
    assert_true(s.ang == -777777LL * 12345);
    assert_true(llabs(hd_stab_angle(&s) - llround(-777777.0 * 12345 / 1e4)) <= 1);
}

/* the bias parameter cancels a constant gyro offset; the reference integrates rate_cmd */
static void test_stab_bias_and_reference(void **st)
{
    (void)st;
    const int32_t b = TPS(0.5 / 360.0 / 3600.0);   /* 0.5 deg/h */
    const hd_stab_cfg_t c = design(b, 0.0, 100.0);
    hd_stab_t s;
    hd_stab_init(&s);
    hd_stab_start(&s, &c, 0, b, 0);
    for (int k = 0; k < 50000; k++) {
        hd_stab_step(&s, &c, b, 0, 0);
    }
    assert_true(hd_stab_angle(&s) == 0);
    assert_int_equal(s.err, 0);
    assert_int_equal(s.rate, 0);
    for (int k = 0; k < 20000; k++) {
        hd_stab_step(&s, &c, b, 0, 119305);       /* 0.01 deg/s commanded, payload not moving */
    }
    assert_int_equal(s.err, 2 * 119305);
}

/* base rocking 0.5 deg at 1 Hz with the payload held inertially (gyro 0, encoder = -base):
 * the base-rate estimate matches A w cos(w t) and vff = -estimate */
static void test_stab_base_rate(void **st)
{
    (void)st;
    const hd_stab_cfg_t c = design(0, 0.0, 100.0);
    hd_stab_t s;
    const double A = 0.5 / 360.0, w = 2 * M_PI;
    double emax = 0.0;
    hd_stab_init(&s);
    hd_stab_start(&s, &c, 0, 0, -TPS(A * w));      /* at t = 0: relative rate -A w */
    for (int k = 1; k <= 30000; k++) {
        const double t = k * 1e-4;
        const hd_angle_t pos = (hd_angle_t)llround(-A * sin(w * t) * Q32);
        hd_stab_step(&s, &c, 0, pos, 0);
        const double wb = A * w * cos(w * t);
        const double e = fabs((double)s.base_rate / Q32 - wb);
        if (k > 2000) {
            emax = e > emax ? e : emax;
        }
        assert_int_equal(s.vff, -s.base_rate);
        assert_int_equal(s.err, 0);
    }
    printf("# base rate 0.5 deg 1 Hz, 100 Hz observer: max error %.3g of %.3g turn/s (%.3g)\n",
           emax, A * w, emax / (A * w));
    assert_true(emax < 2e-3 * A * w);
    /* the friction-FF velocity: the observer's integrator state, shrunk by the 1e-5 turn/s
     * dead band (here at t = 3 s, near the peak base rate) */
    {
        const int32_t v = -hd_velobs_vel_out(&s.obs);
        assert_true(llabs(v) > TPS(1e-5));
        assert_int_equal(s.vff_db, v - (v > 0 ? 1 : -1) * TPS(1e-5));
    }
    hd_stab_start(&s, &c, 0, 1000, 0);              /* 2.3e-7 turn/s: inside the dead band */
    hd_stab_step(&s, &c, 1000, 0, 0);
    assert_int_equal(s.vff_db, 0);
    assert_true(s.vff != 0);
}

/* blend: an unknown bias of 2 deg/h is estimated (PI blend at 0.01 Hz), the angle stays
 * bounded, and the base rocking leaks into the estimate by less than the design bound */
static void test_stab_blend(void **st)
{
    (void)st;
    const hd_stab_cfg_t c = design(0, 0.01, 100.0);
    const double bias = 2.0 / 360.0 / 3600.0;      /* turn/s */
    const double A = 0.5 / 360.0, w = 2 * M_PI;
    hd_stab_t s;
    double leak = 0.0;
    hd_stab_init(&s);
    hd_stab_start(&s, &c, 0, TPS(bias), 0);
    for (int k = 1; k <= 3000000; k++) {            /* 300 s */
        const double t = k * 1e-4;
        const hd_angle_t pos = (hd_angle_t)llround(-A * sin(w * t) * Q32);   /* held inertially */
        hd_stab_step(&s, &c, TPS(bias), pos, 0);
        if (k > 2900000) {
            const double e = fabs((double)hd_stab_angle(&s) / Q32) * TURN_ARCSEC;
            leak = e > leak ? e : leak;
        }
    }
    const double b_est = (double)s.b_hat / Q32 / Q32;
    printf("# blend 0.01 Hz: bias estimate %.4g of %.4g turn/s, |angle| over the last 10 s <= %.3f arcsec\n",
           b_est, bias, leak);
    assert_true(fabs(b_est - bias) < 0.02 * bias);
    /* |L(jw)| ~ 2 wc wr / w^2 = 1e-3 of 1800 arcsec, plus the decayed start */
    assert_true(leak < 3.0);
}

/* the bias estimate is clamped to bias_max; the pure-integration mode keeps b_hat at 0 */
static void test_stab_clamp(void **st)
{
    (void)st;
    const hd_stab_cfg_t c = design(0, 0.01, 100.0);
    const hd_stab_cfg_t c0 = design(0, 0.0, 100.0);
    hd_stab_t s;
    hd_stab_init(&s);
    hd_stab_start(&s, &c, 0, 0, 0);
    for (int k = 0; k < 200000; k++) {
        hd_stab_step(&s, &c, TPS(1.0 / 360.0), 0, 0);   /* 1 deg/s "bias", far above 10 deg/h */
    }
    assert_true(s.b_hat == (int64_t)c.bias_max * (int64_t)Q32);
    hd_stab_init(&s);
    hd_stab_start(&s, &c0, 0, 0, 0);
    for (int k = 0; k < 1000; k++) {
        hd_stab_step(&s, &c0, INT32_MAX, INT64_MAX, INT32_MIN);   /* edges saturate, no UB */
    }
    assert_true(s.b_hat == 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stab_exact_integration),
        cmocka_unit_test(test_stab_bias_and_reference),
        cmocka_unit_test(test_stab_base_rate),
        cmocka_unit_test(test_stab_blend),
        cmocka_unit_test(test_stab_clamp),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
