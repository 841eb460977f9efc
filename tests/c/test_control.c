/*
 * test_control.c - unit tests of the baseline controllers in firmware/core:
 * PID (hd_pid), velocity observer (hd_vel_observer), biquads (hd_biquad),
 * trajectory generator (hd_trajectory), excitation (hd_excitation),
 * capture buffer (hd_capture).  Double precision is used here only as the
 * reference; the firmware under test is integer-only.
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
#include "hd_pid.h"
#include "hd_vel_observer.h"
#include "hd_biquad.h"
#include "hd_trajectory.h"
#include "hd_excitation.h"
#include "hd_capture.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#define TURN_DEG 360.0
#define DEG_S_TO_VEL(d) ((int32_t)llround((d) / TURN_DEG * 4294967296.0))

/* ---------------------------------------------------------------- PID ---- */

static hd_pid_cfg_t pcfg(int32_t kp, int32_t ki, int32_t kd, uint32_t shift, int32_t lim)
{
    hd_pid_cfg_t c = {kp, ki, kd, HD_Q30_ONE, shift, -lim, lim};
    return c;
}

static void test_pid_p_rounding(void **st)
{
    (void)st;
    hd_pid_t s;
    hd_pid_cfg_t c = pcfg(3 << 15, 0, 0, 16, 1 << 30);   /* kp = 1.5 */
    hd_pid_reset(&s);
    assert_int_equal(hd_pid_step(&s, &c, 1001, 0, 0), 1502);  /* 1501.5 rounds away */
    assert_int_equal(hd_pid_step(&s, &c, -1001, 0, 0), -1502);
    assert_int_equal(hd_pid_step(&s, &c, 0, 0, 77), 77);      /* feed-forward passes */
}

static void test_pid_integrator_precision(void **st)
{
    (void)st;
    hd_pid_t s;
    /* ki_dt = 0.25 in Q16: I term after k steps of e = 1 is k/4, kept exactly */
    hd_pid_cfg_t c = pcfg(0, 1 << 14, 0, 16, 1 << 30);
    hd_pid_reset(&s);
    int32_t out = 0;
    for (int i = 0; i < 4000; i++) {
        out = hd_pid_step(&s, &c, 1, 0, 0);
    }
    assert_int_equal(out, 1000);    /* sub-LSB increments accumulate, not lost */
}

static void test_pid_antiwindup(void **st)
{
    (void)st;
    hd_pid_t s;
    hd_pid_cfg_t c = pcfg(1 << 16, 1 << 16, 0, 16, 100);
    hd_pid_reset(&s);
    for (int i = 0; i < 10000; i++) {
        assert_true(hd_pid_step(&s, &c, 1000, 0, 0) <= 100);
    }
    assert_true(s.saturated);
    assert_true(s.integ <= ((int64_t)100 << 16));
    /* error reverses: the output leaves saturation at once (no wound-up integral) */
    int32_t out = hd_pid_step(&s, &c, -50, 0, 0);
    assert_true(out < 100);
    for (int i = 0; i < 5; i++) {
        out = hd_pid_step(&s, &c, -50, 0, 0);
    }
    assert_true(out < 0);
}

static void test_pid_derivative_on_measurement(void **st)
{
    (void)st;
    hd_pid_t s;
    hd_pid_cfg_t c = pcfg(0, 0, 1 << 16, 16, 1 << 30);   /* kd_fs = 1: D = -dmeas */
    hd_pid_reset(&s);
    assert_int_equal(hd_pid_step(&s, &c, 0, 0, 0), 0);
    assert_int_equal(hd_pid_step(&s, &c, 100000, 0, 0), 0);   /* no kick on a reference step */
    assert_int_equal(hd_pid_step(&s, &c, 100000, 500, 0), -500);
    /* with a filter (alpha = 0.5) the derivative of a measurement step decays */
    c.d_alpha = HD_Q30_ONE / 2;
    hd_pid_reset(&s);
    (void)hd_pid_step(&s, &c, 0, 0, 0);
    assert_int_equal(hd_pid_step(&s, &c, 0, 1000, 0), -500);
    assert_int_equal(hd_pid_step(&s, &c, 0, 1000, 0), -250);
}

/* Without a D gain the derivative filter is not run: it rests at 0, so a D gain
 * switched on later starts from rest (a measurement that moved while kd_fs was 0
 * leaves no filtered history behind) and the first D term is the new step only. */
static void test_pid_derivative_rests_without_gain(void **st)
{
    (void)st;
    hd_pid_t s;
    hd_pid_cfg_t c = pcfg(0, 0, 0, 16, 1 << 30);
    c.d_alpha = HD_Q30_ONE / 2;
    hd_pid_reset(&s);
    for (int32_t k = 0; k < 50; k++) {
        assert_int_equal(hd_pid_step(&s, &c, 0, 1000 * k, 0), 0);
    }
    assert_true(s.dfilt == 0);
    c.kd_fs = 1 << 16;                                            /* D = -filtered dmeas */
    assert_int_equal(hd_pid_step(&s, &c, 0, 49000, 0), 0);        /* no step: still at rest */
    assert_int_equal(hd_pid_step(&s, &c, 0, 50000, 0), -500);     /* alpha 0.5 of a fresh 1000 step */
}

static void test_pid_extremes_no_ub(void **st)
{
    (void)st;
    hd_pid_t s;
    hd_pid_cfg_t c = pcfg(INT32_MAX, INT32_MAX, INT32_MAX, 0, INT32_MAX);
    c.out_min = INT32_MIN;
    hd_pid_reset(&s);
    const int32_t v[] = {INT32_MIN, INT32_MAX, 0, -1, 1, INT32_MIN, INT32_MAX};
    for (int k = 0; k < 200; k++) {
        int32_t out = hd_pid_step(&s, &c, v[k % 7], v[(k * 3 + 1) % 7], v[(k * 5 + 2) % 7]);
        assert_true(out >= c.out_min && out <= c.out_max);
    }
}

/* ----------------------------------------------------------- observer ---- */

static void observer_run(double deg_s, double bw_hz, double *mean_err_rel, double *rms_deg_s)
{
    hd_velobs_t s;
    hd_velobs_cfg_t c;
    hd_velobs_design(&c, (int32_t)lround(2 * M_PI * bw_hz * 65536), 65536);
    const double v_turn = deg_s / TURN_DEG;
    hd_velobs_reset(&s, 0);
    const int n_settle = 20000, n = 100000;
    double sum = 0, sum2 = 0;
    for (int k = 0; k < n_settle + n; k++) {
        double th = v_turn * k * 1e-4 + 0.123456;
        /* 24-bit absolute encoder quantisation */
        int64_t counts = (int64_t)floor(th * 16777216.0);
        hd_velobs_step(&s, &c, counts * 256);
        if (k >= n_settle) {
            double v = hd_velobs_vel_out(&s) / 4294967296.0 * TURN_DEG;
            sum += v;
            sum2 += (v - deg_s) * (v - deg_s);
        }
    }
    *mean_err_rel = fabs(sum / n - deg_s) / deg_s;
    *rms_deg_s = sqrt(sum2 / n);
}

static void test_observer_low_speed(void **st)
{
    (void)st;
    double rel, rms;
    observer_run(0.001, 20.0, &rel, &rms);
    printf("# observer 20 Hz, 0.001 deg/s on 24-bit encoder: mean error %.3g %%, rms %.3g deg/s\n",
           rel * 100, rms);
    assert_true(rel < 0.02);
    observer_run(0.01, 20.0, &rel, &rms);
    printf("# observer 20 Hz, 0.01 deg/s: mean error %.3g %%, rms %.3g deg/s\n", rel * 100, rms);
    assert_true(rel < 0.01);
    observer_run(60.0, 20.0, &rel, &rms);
    assert_true(rel < 1e-4);
}

static void test_observer_exact_ramp(void **st)
{
    (void)st;
    hd_velobs_t s;
    hd_velobs_cfg_t c;
    hd_velobs_design(&c, (int32_t)lround(2 * M_PI * 50 * 65536), 65536);
    hd_velobs_reset(&s, 0);
    /* unquantised ramp of 1193 LSB/s (0.0001 deg/s): velocity converges exactly */
    const int64_t v = 1193;
    for (int64_t k = 1; k <= 200000; k++) {
        hd_velobs_step(&s, &c, (v * k) / 10000);
    }
    assert_true(llabs((long long)hd_velobs_vel_out(&s) - v) <= 2);
    /* motor shaft speed 20 turn/s does not overflow */
    hd_velobs_reset(&s, 0);
    for (int64_t k = 1; k <= 20000; k++) {
        hd_velobs_step(&s, &c, (int64_t)20 * 4294967296LL * k / 10000);
    }
    double vm = (double)hd_velobs_vel48(&s) / 281474976710656.0;
    assert_true(fabs(vm - 20.0) < 1e-6);
}

/* A jump far beyond the 32-bit error's range (2^-5 turn): err still reports the
 * whole error, the estimate moves at the limit's rate, settles on the new angle
 * without overflow and the velocity returns to 0; and err is the error rounded
 * half away from zero (ties of frac = 1/2 included). */
static void test_observer_large_error(void **st)
{
    (void)st;
    hd_velobs_t s;
    hd_velobs_cfg_t c;
    hd_velobs_design(&c, (int32_t)lround(2 * M_PI * 20 * 65536), 65536);
    hd_velobs_reset(&s, 0);
    const int64_t jump = (int64_t)1 << 30;                     /* 0.25 turn, 2^-32 turn */
    hd_velobs_step(&s, &c, jump);
    assert_int_equal(s.err, (int32_t)jump);
    for (int k = 0; k < 30000; k++) {
        hd_velobs_step(&s, &c, jump);
    }
    assert_true(llabs((long long)(s.theta - jump)) <= 1);
    assert_true(llabs((long long)hd_velobs_vel_out(&s)) <= 2);
    /* err = round_half_away((d 2^16 - frac) / 2^16) for every frac around a tie */
    const int32_t fr[] = {0, 1, 32767, 32768, 32769, 65535};
    const int64_t dd[] = {-3, -1, 0, 1, 2, 1000};
    for (unsigned i = 0; i < sizeof fr / sizeof fr[0]; i++) {
        for (unsigned j = 0; j < sizeof dd / sizeof dd[0]; j++) {
            hd_velobs_t t;
            hd_velobs_reset(&t, 0);
            t.frac = fr[i];
            hd_velobs_step(&t, &c, dd[j]);
            assert_int_equal(t.err, hd_asr32_rnd(dd[j] * 65536 - fr[i], 16u));
        }
    }
}

/* ------------------------------------------------------------ biquad ----- */

static hd_biquad_coef_t q30(double b0, double b1, double b2, double a1, double a2)
{
    hd_biquad_coef_t c = {(int32_t)lround(b0 * 1073741824.0), (int32_t)lround(b1 * 1073741824.0),
                          (int32_t)lround(b2 * 1073741824.0), (int32_t)lround(a1 * 1073741824.0),
                          (int32_t)lround(a2 * 1073741824.0)};
    return c;
}

static double sine_gain(const hd_biquad_coef_t *c, double f, double amp)
{
    hd_biquad_state_t s;
    hd_biquad_reset(&s);
    double peak = 0;
    int n = 40000;
    for (int k = 0; k < n; k++) {
        int32_t x = (int32_t)lround(amp * sin(2 * M_PI * f * k * 1e-4));
        int32_t y = hd_biquad_step(&s, c, x);
        if (k > n / 2 && fabs((double)y) > peak) {
            peak = fabs((double)y);
        }
    }
    return peak / amp;
}

static void test_biquad_identity_and_dc(void **st)
{
    (void)st;
    hd_biquad_coef_t id;
    hd_biquad_state_t s;
    hd_biquad_identity(&id);
    hd_biquad_reset(&s);
    for (int32_t x = -1000; x < 1000; x += 7) {
        assert_int_equal(hd_biquad_step(&s, &id, x), x);
    }
    hd_biquad_coef_t lp = q30(0.06745527, 0.13491055, 0.06745527, -1.1429805, 0.4128016);
    hd_biquad_reset(&s);
    int32_t y = 0;
    for (int k = 0; k < 2000; k++) {
        y = hd_biquad_step(&s, &lp, 1000000);
    }
    assert_true(abs(y - 1000000) <= 2);
}

static void test_biquad_notch_depth(void **st)
{
    (void)st;
    hd_biquad_coef_t nt = q30(0.98883244, -1.97420856, 0.98635076, -1.97420856, 0.9751832);
    double g50 = sine_gain(&nt, 50.0, 1e6);
    double g5 = sine_gain(&nt, 5.0, 1e6);
    double g500 = sine_gain(&nt, 500.0, 1e6);
    printf("# notch 50 Hz: gain %.4f at 50 Hz, %.4f at 5 Hz, %.4f at 500 Hz\n", g50, g5, g500);
    assert_true(g50 < 0.12);
    assert_true(fabs(g5 - 1.0) < 0.03);
    assert_true(fabs(g500 - 1.0) < 0.03);
}

/* The section is the exact filter to within the output rounding: against a
 * double-precision direct form I of the same quantised coefficients, a narrow
 * notch (1/A(z) gain in the hundreds) and the low-pass, driven by random
 * torques, stay within 1 LSB (full-precision feedback: the rounding of y is not
 * recirculated); and a signal beyond the section limit is held at +-2^29. */
static void test_biquad_full_precision(void **st)
{
    (void)st;
    const hd_biquad_coef_t cs[2] = {q30(0.98883244, -1.97420856, 0.98635076, -1.97420856, 0.9751832),
                                    q30(0.06745527, 0.13491055, 0.06745527, -1.1429805, 0.4128016)};
    for (int j = 0; j < 2; j++) {
        const hd_biquad_coef_t *c = &cs[j];
        const double b0 = c->b0 / 1073741824.0, b1 = c->b1 / 1073741824.0, b2 = c->b2 / 1073741824.0;
        const double a1 = c->a1 / 1073741824.0, a2 = c->a2 / 1073741824.0;
        hd_biquad_state_t s;
        hd_biquad_reset(&s);
        double x1 = 0, x2 = 0, y1 = 0, y2 = 0, worst = 0;
        uint32_t seed = 12345u;
        for (int k = 0; k < 20000; k++) {
            seed = seed * 1664525u + 1013904223u;
            const int32_t x = (int32_t)(seed >> 8) - (1 << 23) + (int32_t)lround(3e6 * sin(0.0314 * k));
            const double yd = b0 * x + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
            x2 = x1; x1 = x; y2 = y1; y1 = yd;
            const double err = fabs((double)hd_biquad_step(&s, c, x) - yd);
            worst = (err > worst) ? err : worst;
        }
        printf("# biquad %d: max |y - exact| %.3f LSB\n", j, worst);
        assert_true(worst <= 1.0);
    }
    hd_biquad_coef_t id;
    hd_biquad_state_t s;
    hd_biquad_identity(&id);
    hd_biquad_reset(&s);
    assert_int_equal(hd_biquad_step(&s, &id, INT32_MAX), HD_BIQUAD_SIG_MAX);
    assert_int_equal(hd_biquad_step(&s, &id, INT32_MIN), -HD_BIQUAD_SIG_MAX);
    assert_int_equal(hd_biquad_step(&s, &id, -12345), -12345);
}

static void test_biquad_chain_extremes(void **st)
{
    (void)st;
    hd_biquad_chain_cfg_t c;
    hd_biquad_chain_t s;
    c.n = 2;
    c.c[0] = q30(1.9999, -1.9999, 1.9999, -1.9999, 0.9999);
    c.c[1] = q30(-2.0, 1.9999, -2.0, 1.5, 0.9);
    hd_biquad_chain_reset(&s);
    for (int k = 0; k < 5000; k++) {
        (void)hd_biquad_chain_step(&s, &c, (k & 1) ? INT32_MAX : INT32_MIN);
    }
    c.n = 0;
    assert_int_equal(hd_biquad_chain_step(&s, &c, 12345), 12345);
}

/* -------------------------------------------------------- trajectory ----- */

static hd_traj_cfg_t tcfg_ref(void)
{
    /* reference axis: 60 deg/s, 100 deg/s^2, 1000 deg/s^3 */
    hd_traj_cfg_t c = {.vmax = (int32_t)llround(60.0 / 360 * 4294967296.0),
                       .amax = (int32_t)llround(100.0 / 360 * 16777216.0),
                       .jmax = (int32_t)llround(1000.0 / 360 * 65536.0)};
    return c;
}

static void run_ptp(hd_angle_t start, hd_angle_t target, const hd_traj_cfg_t *c, uint32_t *ticks)
{
    hd_traj_t s;
    hd_traj_reset(&s, start);
    assert_int_equal(hd_traj_ptp(&s, c, target), 0);
    /* limits hold up to the residual spread (< V/K, documented) and output rounding */
    const double vmax = c->vmax * 1.0005 + 4, amax = c->amax * 1.001 + 2;
    uint32_t k = 0;
    hd_angle_t prev = start;
    while (!hd_traj_done(&s)) {
        hd_traj_step(&s, c);
        if (!(fabs((double)s.vel) <= vmax)) {
            printf("# k=%u vel=%d vmax=%d tj=%u ta=%u tv=%u j=%lld R=%lld\n", k, s.vel, c->vmax, s.tj, s.ta, s.tv, (long long)s.j48, (long long)s.cruise_r);
        }
        assert_true(fabs((double)s.vel) <= vmax);
        assert_true(fabs((double)s.acc) <= amax);
        /* never overshoots */
        if (target >= start) {
            assert_true(s.pos >= prev - 1 && s.pos <= target);
        } else {
            assert_true(s.pos <= prev + 1 && s.pos >= target);
        }
        prev = s.pos;
        k++;
        assert_true(k < 50000000u);
    }
    assert_true(s.p48 == target * 65536);          /* exact landing */
    assert_true(s.pos == target);
    hd_traj_step(&s, c);
    assert_true(s.pos == target && s.vel == 0 && s.acc == 0);
    *ticks = k;
}

static void test_traj_ptp_exact(void **st)
{
    (void)st;
    hd_traj_cfg_t c = tcfg_ref();
    uint32_t k;
    const int64_t T = 4294967296LL;
    run_ptp(0, T / 4, &c, &k);                       /* 90 deg */
    printf("# PTP 90 deg: %u periods (%.3f s)\n", k, k * 1e-4);
    assert_true(k > 15000 && k < 25000);             /* ~1.5 s cruise + ramps */
    run_ptp(T / 4, -T / 8, &c, &k);
    run_ptp(12345, 12345 + 1, &c, &k);               /* 1 LSB */
    run_ptp(0, -(T / 360 / 3600), &c, &k);           /* 1 arcsec */
    run_ptp(0, 7 * T + 987654321, &c, &k);           /* several turns */
    hd_traj_cfg_t slow = {.vmax = DEG_S_TO_VEL(0.01), .amax = 1000, .jmax = 100};
    run_ptp(0, T / 36000, &slow, &k);                /* 0.01 deg at 0.01 deg/s */
}

/* Cruise of a PTP move at the velocity limit: the cruise velocity is EXACTLY the
 * limit (whole-period ramps used to quantise it below: 19 % slow at 0.001 deg/s,
 * 50 % at 2e-5 deg/s with the reference-axis limits), and no period exceeds the
 * per-period jerk, acceleration or velocity limit. */
static void cruise_check(double rate_deg_s, const hd_traj_cfg_t *c0, double travel_s, int32_t dir)
{
    hd_traj_cfg_t c = *c0;
    c.vmax = DEG_S_TO_VEL(rate_deg_s);
    /* limits in the planner's per-period units (2^-48 turn per T, T^2, T^3) */
    const int64_t vnum = (int64_t)c.vmax * 65536;                 /* / HD_LOOP_HZ */
    const int64_t vper = vnum / HD_LOOP_HZ;
    const int64_t aper = hd_div64_rnd((int64_t)c.amax * 16777216, 100000000);
    int64_t jper = hd_div64_rnd((int64_t)c.jmax << 32, 1000000000000LL);
    jper = (jper < 1) ? 1 : jper;
    const int64_t travel = (int64_t)llround((double)c.vmax * travel_s) + 4321;   /* Q32.32, odd LSBs */
    const hd_angle_t start = 987654321, target = start + dir * travel;
    hd_traj_t s;
    hd_traj_reset(&s, start);
    assert_int_equal(hd_traj_ptp(&s, &c, target), 0);
    int64_t a_prev = 0, p_c0 = 0, p_c1 = 0;
    uint32_t k = 0, n_cruise = 0;
    const uint32_t total = 4u * s.tj + 2u * s.ta + 2u * s.tn + s.tv;
    const uint32_t na = 2u * s.tj + s.ta + s.tn;
    assert_true(s.tv > 10000u);                                   /* the move cruises */
    while (!hd_traj_done(&s)) {
        const int64_t p_before = s.p48;
        hd_traj_step(&s, &c);
        const int64_t a = s.a48 * dir, v = s.v48;                 /* a48 is the magnitude's sign-restored copy */
        assert_true(llabs(a) <= aper);
        assert_true(llabs(a - a_prev) <= jper);
        assert_true(v >= 0 && v <= vper);
        a_prev = a;
        if (k >= na && k < na + s.tv) {                           /* cruise */
            assert_true(v == vper);                               /* exactly the limit, every period */
            if (n_cruise == 0u) {
                p_c0 = p_before;
            }
            p_c1 = s.p48;
            n_cruise++;
        }
        k++;
        assert_true(k <= total);
    }
    assert_true(s.p48 == target * 65536 && s.pos == target);     /* exact landing */
    /* cruise advance = n vmax 2^16 / HD_LOOP_HZ + the residual share (<= n R / K + 1) */
    const double want = (double)n_cruise * (double)vnum / HD_LOOP_HZ;
    const double got = (double)((p_c1 - p_c0) * dir);
    const double slack = (double)n_cruise * (double)s.cruise_r / (double)total + 2.0;
    printf("# PTP at %g deg/s: cruise %u periods at %lld (limit %.3f) /period, tj %u ta %u inserted %u (level %lld), "
           "cruise rate error %.2e\n", rate_deg_s, n_cruise, (long long)vper, (double)vnum / HD_LOOP_HZ, s.tj, s.ta,
           s.tn, (long long)s.ins_a, got / want - 1.0);
    assert_true(n_cruise == s.tv);
    assert_true(got >= want - 2.0 && got <= want + slack);
}

static void test_traj_cruise_at_vmax_exactly(void **st)
{
    (void)st;
    const hd_traj_cfg_t ref = tcfg_ref();
    /* the min-rate ladder (and below), a few fast rates, both directions */
    const double rates[] = {60.0, 10.0, 1.0, 0.1, 0.01, 0.001, 0.0005, 0.0002, 0.0001, 5e-5, 2e-5, 1e-5, 3.6e-6};
    for (size_t i = 0; i < sizeof rates / sizeof rates[0]; i++) {
        cruise_check(rates[i], &ref, rates[i] >= 1.0 ? 4.0 : 12.0, (i % 2u) ? -1 : 1);
    }
    /* jerk above the acceleration limit (one-period ramps), and a slow jerk (long ramps) */
    const hd_traj_cfg_t stiff = {.vmax = 0, .amax = ref.amax, .jmax = 30000 * 65536};
    cruise_check(0.001, &stiff, 12.0, 1);
    cruise_check(7.3, &stiff, 4.0, -1);
    const hd_traj_cfg_t soft = {.vmax = 0, .amax = ref.amax, .jmax = 66};           /* 0.001 turn/s^3 */
    cruise_check(0.3, &soft, 60.0, 1);
    cruise_check(0.0001, &soft, 12.0, -1);
}

static void test_traj_rate_exact(void **st)
{
    (void)st;
    hd_traj_cfg_t c = tcfg_ref();
    hd_traj_t s;
    const int32_t v = DEG_S_TO_VEL(0.0001);           /* 1193 LSB/s */
    assert_int_equal(v, 1193);
    c.amax = 1 << 30;                                  /* immediate */
    hd_traj_reset(&s, 0);
    hd_traj_rate(&s, &c, v);
    const int64_t n = 3000000;                          /* 300 s */
    for (int64_t k = 1; k <= n; k++) {
        hd_traj_step(&s, &c);
        if (k % 100000 == 0 || k == n) {
            /* exact: p48 = floor(k v 2^16 / 10^4) */
            int64_t expect = (k * v * 65536) / 10000;
            assert_true(s.p48 == expect);
            assert_int_equal(s.vel, v);
        }
    }
    /* ramp and stop at amax */
    c = tcfg_ref();
    hd_traj_reset(&s, 0);
    hd_traj_rate(&s, &c, DEG_S_TO_VEL(10.0));
    int k = 0;
    while (s.vel != DEG_S_TO_VEL(10.0)) {
        hd_traj_step(&s, &c);
        assert_true(s.acc > 0);
        k++;
    }
    assert_true(abs(k - 1000) <= 2);                  /* 10 deg/s at 100 deg/s^2 = 0.1 s */
    hd_traj_stop(&s, &c);
    while (s.mode != HD_TRAJ_HOLD) {
        hd_traj_step(&s, &c);
    }
    assert_int_equal(s.vel, 0);
    /* negative rate, exact */
    hd_traj_reset(&s, 1000);
    c.amax = 1 << 30;
    hd_traj_rate(&s, &c, -v);
    for (int64_t kk = 1; kk <= 12345; kk++) {
        hd_traj_step(&s, &c);
    }
    int64_t num = -12345LL * v * 65536;
    int64_t fl = num / 10000 - ((num % 10000) != 0);
    assert_true(s.p48 == 1000 * 65536 + fl);
}

static void test_traj_sine(void **st)
{
    (void)st;
    hd_traj_cfg_t c = tcfg_ref();
    hd_traj_t s;
    const int32_t amp = 1 << 24;                       /* 1/256 turn */
    hd_traj_reset(&s, 5000);
    assert_int_equal(hd_traj_sine(&s, 5000, amp, 1 << 16), 0);   /* 1 Hz */
    for (int k = 0; k < 2500; k++) {
        hd_traj_step(&s, &c);
    }
    assert_true(llabs((long long)(s.pos - 5000 - amp)) <= 4);      /* quarter period */
    assert_true(abs(s.vel) < amp / 1000);
    double wa = 2 * M_PI * amp;                                       /* peak velocity */
    for (int k = 0; k < 2500; k++) {
        hd_traj_step(&s, &c);
    }
    assert_true(llabs((long long)(s.pos - 5000)) <= 4);
    assert_true(fabs(-s.vel - wa) < wa * 1e-3);
    /* exact phase after many cycles of a non-integer-period frequency */
    hd_traj_reset(&s, 0);
    const int32_t f = 77777;                           /* 1.1868 Hz */
    assert_int_equal(hd_traj_sine(&s, 0, amp, f), 0);
    const uint64_t n = 1000003;
    for (uint64_t k = 0; k < n; k++) {
        hd_traj_step(&s, &c);
    }
    unsigned __int128 ph = ((unsigned __int128)n * (uint64_t)f << 48) / 10000;
    assert_true(s.phase == (uint64_t)ph);
}

/* One-direction final approach: run a move to the end and check every leg. */
typedef struct {
    uint32_t periods;        /* until hd_traj_done */
    uint32_t leg1_end;       /* period index at which the first leg ended (0: one leg) */
    uint32_t final_periods;  /* periods of the final leg (motion after the dwell) */
    hd_angle_t turn_pos;     /* position at the end of the first leg */
    int32_t final_vmax;      /* max |vel| in the final leg */
} appr_run_t;

static appr_run_t run_appr(hd_angle_t start, hd_angle_t target, const hd_traj_cfg_t *c)
{
    appr_run_t r = {0};
    hd_traj_t s;
    hd_traj_reset(&s, start);
    assert_int_equal(hd_traj_ptp(&s, c, target), 0);
    assert_true(s.goal48 == target * 65536);       /* the true target from the start */
    const int dir = c->appr_dir;
    const int wrong = (c->appr_dir != 0 && c->appr_dist > 0 && target != start &&
                       ((target < start) != (dir < 0)));
    const hd_angle_t turn = target - (hd_angle_t)dir * c->appr_dist;
    const double vmax = c->vmax * 1.0005 + 4, amax = c->amax * 1.001 + 2;
    const int32_t vlim = (c->appr_vmax > 0 && c->appr_vmax < c->vmax) ? c->appr_vmax : c->vmax;
    int leg = 1;
    uint32_t still = 0;
    hd_angle_t prev = start;
    while (!hd_traj_done(&s)) {
        hd_traj_step(&s, c);
        r.periods++;
        assert_true(fabs((double)s.vel) <= vmax);
        assert_true(fabs((double)s.acc) <= amax);
        if (!wrong) {                                 /* one leg, monotone, no overshoot */
            assert_int_equal(s.appr_leg, 0);
            if (target >= start) {
                assert_true(s.pos >= prev - 1 && s.pos <= target);
            } else {
                assert_true(s.pos <= prev + 1 && s.pos >= target);
            }
        } else if (leg == 1) {
            /* first leg: monotone towards the turning point, never beyond it */
            if (turn >= start) {
                assert_true(s.pos >= prev - 1 && s.pos <= turn);
            } else {
                assert_true(s.pos <= prev + 1 && s.pos >= turn);
            }
            assert_false(hd_traj_done(&s) && s.pos != target);
            if (s.appr_leg == 2) {                    /* first leg ended this period */
                leg = 2;
                r.leg1_end = r.periods;
                r.turn_pos = s.pos;
                assert_true(s.p48 == turn * 65536);    /* exactly at target - dir * dist */
                assert_int_equal(hd_traj_ptp(&s, c, start), -1);   /* busy: refused */
            }
        } else {
            /* dwell, then the final leg in direction dir: monotone, no overshoot */
            if (s.vel == 0 && r.final_periods == 0u) {
                still++;
                assert_true(s.pos == r.turn_pos);
            } else {
                r.final_periods++;
            }
            if (dir > 0) {
                assert_true(s.pos >= prev && s.pos <= target);
            } else {
                assert_true(s.pos <= prev && s.pos >= target);
            }
            assert_true((double)s.vel * dir >= 0.0);
            assert_true(fabs((double)s.vel) <= vlim * 1.0005 + 4);
            if (abs(s.vel) > r.final_vmax) {
                r.final_vmax = abs(s.vel);
            }
        }
        prev = s.pos;
        assert_true(r.periods < 50000000u);
    }
    if (wrong) {
        assert_int_equal(leg, 2);
        assert_true(still >= c->appr_dwell);           /* the dwell (+ the first periods of jerk) */
    }
    assert_true(s.p48 == target * 65536);               /* exact landing on the true target */
    assert_true(s.pos == target);
    hd_traj_step(&s, c);
    assert_true(s.pos == target && s.vel == 0 && s.acc == 0 && s.mode == HD_TRAJ_HOLD);
    return r;
}

static void test_traj_final_approach(void **st)
{
    (void)st;
    const int64_t T = 4294967296LL;
    const int32_t as45 = (int32_t)llround(45.0 / 1296000.0 * 4294967296.0);
    hd_traj_cfg_t c = tcfg_ref();
    c.appr_dir = 1;
    c.appr_dist = as45;
    c.appr_vmax = DEG_S_TO_VEL(0.1);
    c.appr_dwell = 50;

    /* wrong side (negative move, approach +): first leg to target - 45", final leg + */
    appr_run_t r = run_appr(0, -T / 36, &c);            /* -10 deg */
    assert_true(r.leg1_end > 0u && r.turn_pos == -T / 36 - as45);
    /* the final leg is slow: 45" at <= 0.1 deg/s takes >= 0.125 s */
    assert_true(r.final_periods >= 1250u);
    assert_true(r.final_vmax > DEG_S_TO_VEL(0.09));     /* and it does cruise near appr_vmax */
    printf("# approach +, -10 deg: %u periods, first leg %u, final leg %u, peak %.4f deg/s\n", r.periods,
           r.leg1_end, r.final_periods, r.final_vmax * TURN_DEG / 4294967296.0);

    /* right side: one leg, bit-identical to the move without the approach */
    {
        hd_traj_cfg_t off = tcfg_ref();
        hd_traj_t a, b;
        hd_traj_reset(&a, 1000);
        hd_traj_reset(&b, 1000);
        assert_int_equal(hd_traj_ptp(&a, &c, T / 36), 0);
        assert_int_equal(hd_traj_ptp(&b, &off, T / 36), 0);
        while (!hd_traj_done(&b)) {
            hd_traj_step(&a, &c);
            hd_traj_step(&b, &off);
            assert_true(a.pos == b.pos && a.vel == b.vel && a.acc == b.acc && a.mode == b.mode);
        }
        assert_true(hd_traj_done(&a));
        r = run_appr(1000, T / 36, &c);
        assert_int_equal(r.leg1_end, 0u);
    }

    /* a wrong-side move shorter than the approach distance passes the target first */
    r = run_appr(0, -(T / 1296000) * 10, &c);             /* -10" */
    assert_true(r.turn_pos == -(T / 1296000) * 10 - as45);
    /* zero-length move: nothing to do, no extra leg */
    r = run_appr(777, 777, &c);
    assert_int_equal(r.leg1_end, 0u);

    /* approach -: mirrored; no dwell; appr_vmax 0 = the full vmax */
    c.appr_dir = -1;
    c.appr_dwell = 0;
    c.appr_vmax = 0;
    r = run_appr(-12345, T / 8, &c);
    assert_true(r.leg1_end > 0u && r.turn_pos == T / 8 + as45);
    r = run_appr(T / 8, -T / 8, &c);                      /* right side now */
    assert_int_equal(r.leg1_end, 0u);

    /* off: appr_dir 0 or appr_dist 0 */
    c.appr_dir = 0;
    r = run_appr(0, T / 100, &c);
    assert_int_equal(r.leg1_end, 0u);
    c.appr_dir = 1;
    c.appr_dist = 0;
    r = run_appr(0, -T / 100, &c);
    assert_int_equal(r.leg1_end, 0u);

    /* a stop (rate mode) during the first leg cancels the pending final leg */
    {
        hd_traj_t s;
        c.appr_dist = as45;
        hd_traj_reset(&s, 0);
        assert_int_equal(hd_traj_ptp(&s, &c, -T / 36), 0);
        for (int k = 0; k < 2000; k++) {
            hd_traj_step(&s, &c);
        }
        hd_traj_stop(&s, &c);
        assert_int_equal(s.appr_leg, 0);
        while (s.mode != HD_TRAJ_HOLD) {
            hd_traj_step(&s, &c);
        }
        assert_true(hd_traj_done(&s));
    }
}

/* -------------------------------------------------------- excitation ----- */

static void test_exc_vsteps(void **st)
{
    (void)st;
    hd_exc_cfg_t c;
    memset(&c, 0, sizeof c);
    c.kind = HD_EXC_VSTEPS;
    c.amp = 11930;                                     /* 0.001 deg/s */
    c.hold = 3;
    c.n = 4;
    c.m = 1;
    hd_exc_t s;
    assert_int_equal(hd_exc_start(&s, &c), 0);
    const uint32_t len = hd_exc_length(&c);
    assert_int_equal(len, 2u * 5u * 3u);
    int32_t out[40];
    for (uint32_t k = 0; k < 35; k++) {
        out[k] = hd_exc_step(&s, &c);
    }
    assert_int_equal(out[0], 11930);
    assert_int_equal(out[2], 11930);
    assert_int_equal(out[3], -11930);
    assert_int_equal(out[6], 119300);
    assert_int_equal(out[24], 119300000);              /* 4 decades up: 10 deg/s */
    assert_int_equal(out[27], -119300000);
    assert_int_equal(out[30], 0);
    assert_true(s.done);
    c.m = 10;
    assert_int_equal(hd_exc_start(&s, &c), 0);
    for (int k = 0; k < 12; k++) {
        out[k] = hd_exc_step(&s, &c);
    }
    assert_true(abs(out[6] - (int32_t)lround(11930 * pow(10, 0.1))) <= 1);
    assert_true(abs(out[9] + (int32_t)lround(11930 * pow(10, 0.1))) <= 1);
    c.m = 3;
    assert_int_equal(hd_exc_start(&s, &c), -1);
}

static void test_exc_prbs(void **st)
{
    (void)st;
    const uint32_t orders[] = {7, 9, 10, 11, 15, 16};
    for (unsigned i = 0; i < 6; i++) {
        hd_exc_cfg_t c;
        memset(&c, 0, sizeof c);
        c.kind = HD_EXC_PRBS;
        c.amp = 100;
        c.offset = 5;
        c.hold = 1;
        c.n = orders[i];
        c.seed = 1;
        hd_exc_t s;
        assert_int_equal(hd_exc_start(&s, &c), 0);
        const uint32_t start = s.lfsr, per = (1u << c.n) - 1u;
        uint32_t ones = 0, k = 0;
        do {
            int32_t v = hd_exc_step(&s, &c);
            assert_true(v == 105 || v == -95);
            ones += (v == 105);
            k++;
        } while (s.lfsr != start && k <= per);
        assert_int_equal(k, per);                      /* maximal length */
        assert_int_equal(ones, 1u << (c.n - 1));
    }
}

static void test_exc_multisine_chirp(void **st)
{
    (void)st;
    hd_exc_cfg_t c;
    memset(&c, 0, sizeof c);
    c.kind = HD_EXC_MULTISINE;
    c.amp = 1 << 20;
    c.n = 10;
    c.period = 1000;
    hd_exc_t s;
    assert_int_equal(hd_exc_start(&s, &c), 0);
    static int32_t v[3000];
    double mean = 0;
    int32_t peak = 0;
    for (int k = 0; k < 3000; k++) {
        v[k] = hd_exc_step(&s, &c);
        if (k < 1000) {
            mean += v[k];
            peak = abs(v[k]) > peak ? abs(v[k]) : peak;
        }
    }
    for (int k = 0; k < 2000; k++) {
        assert_int_equal(v[k], v[k + 1000]);
    }
    assert_true(fabs(mean / 1000) < 16);
    printf("# multisine 10 comps: crest %.2f x component amplitude\n", (double)peak / c.amp);
    assert_true(peak < 5 * c.amp);                      /* Schroeder phases keep the crest low */

    memset(&c, 0, sizeof c);
    c.kind = HD_EXC_CHIRP;
    c.amp = 1 << 20;
    c.f0_q16 = 1 << 16;
    c.f1_q16 = 100 << 16;
    c.length = 100000;
    assert_int_equal(hd_exc_start(&s, &c), 0);
    int cross_a = 0, cross_b = 0;
    int32_t prev = 0;
    for (uint32_t k = 0; k < c.length + 10; k++) {
        int32_t x = hd_exc_step(&s, &c);
        if (k > 0 && ((prev < 0) != (x < 0))) {
            if (k < 10000) {
                cross_a++;
            } else if (k >= 90000 && k < 100000) {
                cross_b++;
            }
        }
        prev = x;
    }
    assert_true(s.done);
    /* first second: 1..10.9 Hz -> ~12 crossings; last: 90..100 Hz -> ~190 */
    assert_true(cross_a >= 8 && cross_a <= 16);
    assert_true(cross_b >= 180 && cross_b <= 200);
}

static void test_exc_forc_tramp(void **st)
{
    (void)st;
    hd_exc_cfg_t c;
    memset(&c, 0, sizeof c);
    c.kind = HD_EXC_FORC;
    c.amp = 1000;
    c.rate = 10;
    c.n = 4;
    hd_exc_t s;
    assert_int_equal(hd_exc_start(&s, &c), 0);
    int32_t peaks[8];
    int np = 0, k = 0;
    int32_t prev = 0, prev2 = 0;
    while (!s.done && k < 100000) {
        int32_t v = hd_exc_step(&s, &c);
        assert_true(v >= -1000 && v <= 1000);
        if (k > 1 && prev > prev2 && v < prev && np < 8) {
            peaks[np++] = prev;
        }
        prev2 = prev;
        prev = v;
        k++;
    }
    assert_true(s.done);
    assert_int_equal(np, 4);
    assert_int_equal(peaks[0], -500);
    assert_int_equal(peaks[1], 0);
    assert_int_equal(peaks[2], 500);
    assert_int_equal(peaks[3], 1000);
    assert_int_equal(prev, -1000);

    memset(&c, 0, sizeof c);
    c.kind = HD_EXC_TRAMP;
    c.amp = 300;
    c.rate = 7;
    c.n = 2;
    c.offset = 1;
    assert_int_equal(hd_exc_start(&s, &c), 0);
    int32_t mx = INT32_MIN, mn = INT32_MAX;
    k = 0;
    while (!s.done && k < 100000) {
        int32_t v = hd_exc_step(&s, &c);
        mx = v > mx ? v : mx;
        mn = v < mn ? v : mn;
        k++;
    }
    assert_int_equal(mx, 301);
    assert_int_equal(mn, -299);
    c.rate = 0;
    assert_int_equal(hd_exc_start(&s, &c), -1);
}

/* ----------------------------------------------------------- capture ----- */

static hd_capture_t cap;   /* 32 KiB: static, not on the stack */

static void test_capture_pretrigger(void **st)
{
    (void)st;
    hd_capture_cfg_t c = {2, 1, 100, 10, HD_CAP_TRIG_RISING, 0, 500};
    hd_capture_reset(&cap);
    assert_int_equal(hd_capture_arm(&cap, &c), 0);
    for (int32_t k = 0; k < 2000; k++) {
        int32_t smp[2] = {k, -k};
        hd_capture_step(&cap, smp);
    }
    assert_int_equal(cap.state, HD_CAP_DONE);
    assert_int_equal(hd_capture_frames(&cap), 100u);
    assert_int_equal(hd_capture_read(&cap, 10, 0), 500);   /* trigger frame */
    assert_int_equal(hd_capture_read(&cap, 0, 0), 490);
    assert_int_equal(hd_capture_read(&cap, 99, 0), 589);
    assert_int_equal(hd_capture_read(&cap, 99, 1), -589);
    assert_int_equal(hd_capture_read(&cap, 100, 0), 0);

    /* decimation + command trigger + ring wrap (4096 frames of 2 ch) */
    hd_capture_cfg_t d = {2, 3, 0, 4000, HD_CAP_TRIG_COMMAND, 1, 0};
    assert_int_equal(hd_capture_arm(&cap, &d), 0);
    for (int32_t k = 0; k < 30000; k++) {
        int32_t smp[2] = {k, 7};
        if (k == 20001) {
            hd_capture_trigger(&cap);
        }
        hd_capture_step(&cap, smp);
    }
    assert_int_equal(cap.state, HD_CAP_DONE);
    assert_int_equal(hd_capture_frames(&cap), 4096u);
    const int32_t t0 = hd_capture_read(&cap, 4000, 0);
    assert_true(t0 >= 20001 && t0 <= 20004 && t0 % 3 == 0);
    assert_int_equal(hd_capture_read(&cap, 3999, 0), t0 - 3);
    assert_int_equal(hd_capture_read(&cap, 0, 0), t0 - 12000);
    assert_int_equal(hd_capture_read(&cap, 4095, 0), t0 + 95 * 3);

    /* bad configurations are refused */
    hd_capture_cfg_t b = {9, 1, 0, 0, 0, 0, 0};
    assert_int_equal(hd_capture_arm(&cap, &b), -1);
    b.n_ch = 1;
    b.frames = 9000;
    assert_int_equal(hd_capture_arm(&cap, &b), -1);
    b.frames = 100;
    b.pretrig = 100;
    assert_int_equal(hd_capture_arm(&cap, &b), -1);
}

/* One observer step against the form with the 64-bit error (e = round((dc 2^16 - frac) /
 * 2^12), the clamped error dc in 2^-32 turn): the same state words for errors at and
 * beyond the clamp, 0, +-1, and every tie of frac (0, 2^11, 2^15, 2^16 - 1 ...). */
static void test_observer_error_words(void **st)
{
    static const int64_t ds[] = { 0, 1, -1, 2, -2, 4095, -4096, (1 << 27) - 1, -((1 << 27) - 1), 1 << 27,
                                  -(1 << 27), INT64_C(1) << 40, -(INT64_C(1) << 40), 123456789, -98765432 };
    static const int32_t fr[] = { 0, 1, 2047, 2048, 2049, 4095, 4096, 32767, 32768, 32769, 65534, 65535 };
    hd_velobs_cfg_t c;
    size_t i, j;
    (void)st;
    hd_velobs_design(&c, 2 * 62832 * 20, 65536);    /* ~20 Hz, zeta 1 */
    for (i = 0; i < sizeof ds / sizeof ds[0]; i++) {
        for (j = 0; j < sizeof fr / sizeof fr[0]; j++) {
            hd_velobs_t s;
            hd_velobs_reset(&s, (int64_t)1 << 36);
            s.frac = fr[j];
            s.vel = (int64_t)(i * 7919u) << 20;
            {
                /* the reference: hd_velobs_step with the error in int64 */
                const int64_t d = hd_sub64_sat((int64_t)s.theta + ds[i], s.theta);
                const int64_t dc = (d > (1 << 27) - 1) ? (1 << 27) - 1 : ((d < -((1 << 27) - 1)) ? -((1 << 27) - 1) : d);
                const int32_t e = (int32_t)hd_asr64_rnd(dc * 65536 - (int64_t)s.frac, 12u);
                int64_t vel = hd_add64_sat(s.vel, hd_asr64_rnd((int64_t)c.ki_dt * e, 4u));
                int64_t adv = hd_mul64x32_q(vel, 1759218604, 44u);
                int64_t whole;
                adv = hd_add64_sat(adv, hd_asr64_rnd((int64_t)c.kp_dt * e, 4u) + (int64_t)s.frac);
                whole = hd_asr64_floor(adv, 16u);
                {
                    const int64_t theta = hd_add64_sat(s.theta, whole);
                    const int32_t frac = (int32_t)(adv - whole * 65536);
                    hd_velobs_step(&s, &c, s.theta + ds[i]);
                    assert_true(s.vel == vel);
                    assert_true(s.theta == theta);
                    assert_int_equal(s.frac, frac);
                }
            }
        }
    }
}

/* The position loop's form (hd_pid_step_pi_q: no D, error form) gives the words of
 * hd_pid_step_q with kd_fs 0 and meas 0, with and without an I gain, through saturation;
 * with no I gain the output is clamp(P + ff) and the integrator stays 0. */
static void test_pid_pi_form_same_words(void **st)
{
    hd_pid_cfg_t c = { 37 << 16, 0, 0, HD_Q30_ONE, 16u, -(1 << 30), 1 << 30 };
    uint32_t x = 99u, k, pass;
    (void)st;
    for (pass = 0; pass < 2u; pass++) {
        hd_pid_t a, b;
        c.ki_dt = (pass == 0u) ? 0 : 40000;
        hd_pid_reset(&a);
        hd_pid_reset(&b);
        for (k = 0; k < 20000u; k++) {
            int32_t e, ff, ua, ub;
            x = x * 1664525u + 1013904223u;
            e = (int32_t)x >> ((k >> 10) & 15u);        /* small to edge errors */
            x = x * 1664525u + 1013904223u;
            ff = (int32_t)x >> 2;
            ua = hd_pid_step_pi_q(&a, &c, e, ff, 16u);
            ub = hd_pid_step_q(&b, &c, e, 0, ff, 16u);
            assert_int_equal(ua, ub);
            assert_true(a.integ == b.integ && a.dfilt == b.dfilt);
            assert_int_equal(a.meas_prev, b.meas_prev);
            assert_int_equal(a.primed, b.primed);
            assert_int_equal(a.saturated, b.saturated);
            assert_int_equal(a.p, b.p);
            assert_int_equal(a.i, b.i);
            assert_int_equal(a.d, b.d);
            if (pass == 0u) {
                const int64_t u = (int64_t)hd_mul_q(c.kp, e, 16u) + ff;
                const int64_t uc = (u > c.out_max) ? c.out_max : ((u < c.out_min) ? c.out_min : u);
                assert_true(a.integ == 0);
                assert_int_equal(a.i, 0);
                assert_int_equal(ua, (int32_t)uc);
                assert_int_equal(a.saturated, (uc != u) ? 1u : 0u);
            }
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pid_p_rounding),
        cmocka_unit_test(test_pid_integrator_precision),
        cmocka_unit_test(test_pid_antiwindup),
        cmocka_unit_test(test_pid_derivative_on_measurement),
        cmocka_unit_test(test_pid_derivative_rests_without_gain),
        cmocka_unit_test(test_pid_extremes_no_ub),
        cmocka_unit_test(test_observer_low_speed),
        cmocka_unit_test(test_observer_exact_ramp),
        cmocka_unit_test(test_observer_large_error),
        cmocka_unit_test(test_observer_error_words),
        cmocka_unit_test(test_pid_pi_form_same_words),
        cmocka_unit_test(test_biquad_identity_and_dc),
        cmocka_unit_test(test_biquad_notch_depth),
        cmocka_unit_test(test_biquad_full_precision),
        cmocka_unit_test(test_biquad_chain_extremes),
        cmocka_unit_test(test_traj_ptp_exact),
        cmocka_unit_test(test_traj_cruise_at_vmax_exactly),
        cmocka_unit_test(test_traj_rate_exact),
        cmocka_unit_test(test_traj_sine),
        cmocka_unit_test(test_traj_final_approach),
        cmocka_unit_test(test_exc_vsteps),
        cmocka_unit_test(test_exc_prbs),
        cmocka_unit_test(test_exc_multisine_chirp),
        cmocka_unit_test(test_exc_forc_tramp),
        cmocka_unit_test(test_capture_pretrigger),
    };
    return cmocka_run_group_tests_name("hd_control", tests, NULL, NULL);
}
