/*
 * test_comp_misc.c - Stribeck, LuGre, Maxwell-slip, TE and backstepping
 * compensators and the bumpless blend (double references: tests/python/test_comp_ref.py).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <math.h>
#include <cmocka.h>

#include "hd_fixed.h"
#include "hd_stribeck.h"
#include "hd_lugre.h"
#include "hd_maxwell.h"
#include "hd_te_comp.h"
#include "hd_backstep.h"

#define NM(x) ((int32_t)((x) * 65536))
#define DEGS 11930465   /* 1 deg/s in 2^-32 turn/s */

static int setUp(void **state) { *state = NULL; return 0; }
static int tearDown(void **state) { (void)state; return 0; }

static void test_blend_ramp_is_bumpless(void **state)
{
    hd_stribeck_cfg_t c = { { NM(5), NM(8), DEGS, NM(100) }, { NM(5), NM(8), DEGS, NM(100) },
                            2u, DEGS / 1000, 1 << 30, NM(100), 0u, 0 };
    hd_stribeck_t s;
    int32_t prev = 0;
    uint32_t k;
    (void)state;
    hd_stribeck_init(&s, 100u, false);
    assert_int_equal(hd_stribeck_step(&s, &c, 2 * DEGS, 0), 0);
    hd_stribeck_set_enabled(&s, true);
    for (k = 0; k < 100u; k++) {
        const int32_t t = hd_stribeck_step(&s, &c, 2 * DEGS, 0);
        assert_true(t >= prev && t - prev <= s.tau_raw / 100 + 2);
        prev = t;
    }
    assert_int_equal(prev, s.tau_raw);
    hd_stribeck_set_enabled(&s, false);
    for (k = 0; k < 100u; k++) {
        prev = hd_stribeck_step(&s, &c, 2 * DEGS, 0);
    }
    assert_int_equal(prev, 0);
}

static void test_stribeck_odd_and_breakaway(void **state)
{
    hd_stribeck_cfg_t c = { { NM(5), NM(8), DEGS, NM(100) }, { NM(5), NM(8), DEGS, NM(100) },
                            2u, DEGS / 1000, 1 << 30, NM(100), 0u, 0 };
    int32_t v;
    (void)state;
    for (v = -3 * DEGS; v <= 3 * DEGS; v += DEGS / 7) {
        assert_int_equal(hd_stribeck_map(&c, v), -hd_stribeck_map(&c, -v));
    }
    assert_int_equal(hd_stribeck_map(&c, 0), 0);
    assert_true(abs(hd_stribeck_map(&c, DEGS / 1000) - NM(8)) < NM(0.01));   /* at eps: full static level */
    c.delta = 1u;
    assert_true(abs(hd_stribeck_g(&c.pos, 1u, DEGS) - (NM(5) + (int32_t)(NM(3) * 0.36787944117))) <= 2);
}

/* the reciprocal form of |v|/vs (hd_stribeck_step/map) against the division form (shape_q30):
 * within 2 LSB (Q30) of exp() over every vs scale, both exponents, the whole velocity range */
static void test_stribeck_recip_matches_division(void **state)
{
    static const int32_t vs_list[] = { 1, 2, 3, 7, 1000, 65535, 65536, 65537, DEGS / 1000, DEGS, 3 * DEGS + 1,
                                       0x40000000, INT32_MAX };
    static const int32_t v_list[] = { 0, 1, -1, 2, 1000, -12345, DEGS / 1000, DEGS / 3, DEGS, -DEGS, 5 * DEGS,
                                      0x3FFFFFFF, INT32_MAX, INT32_MIN, -INT32_MAX };
    uint32_t i, j, d;
    hd_stribeck_recip_t r;
    (void)state;
    for (i = 0; i < sizeof vs_list / sizeof vs_list[0]; i++) {
        hd_stribeck_recip(&r, vs_list[i]);
        assert_true(r.m > (1u << 30) && r.m <= (1u << 31));
        for (j = 0; j < sizeof v_list / sizeof v_list[0]; j++) {
            for (d = 1u; d <= 2u; d++) {
                const int32_t a = hd_stribeck_shape_recip_q30(v_list[j], &r, d);
                const int32_t b = hd_stribeck_shape_q30(v_list[j], vs_list[i], d);
                assert_true(abs(a - b) <= 2);
            }
        }
    }
    hd_stribeck_recip(&r, 0);
    assert_int_equal(hd_stribeck_shape_recip_q30(DEGS, &r, 2u), 0);
}

/* A slow sinusoid near its velocity peak is not a cruise: the tracking procedure streams
 * v = 0.01 deg/s x sin(2 pi t / 4 s) with one set-point per SYNC (10 periods).  Near the peak
 * v_ref moves by far less than 64 LSB per period, but by hundreds of LSB over a 20 ms window;
 * taking it for a cruise switched the feed-forward from the estimate to the reference and back
 * (a 60 arcsec error spike at each velocity peak).  A constant rate with the trajectory
 * generator's 1 LSB jitter still cruises after cruise_ticks periods. */
static void test_stribeck_sinusoid_peak_is_no_cruise(void **state)
{
    hd_stribeck_cfg_t c = { { NM(5), NM(8), DEGS, NM(100) }, { NM(5), NM(8), DEGS, NM(100) },
                            2u, DEGS / 1000, 0, NM(100), 200u, 0 };
    hd_stribeck_t s;
    const double vpk = 0.01 * DEGS, w = 2.0 * 3.14159265358979 / 4.0;
    uint32_t k, n_cruise = 0u;
    int32_t v = 0;
    (void)state;
    hd_stribeck_init(&s, 0u, true);
    for (k = 0; k < 20000u; k++) {                    /* 2 s centred on the velocity peak (t = 1 s) */
        if (k % 10u == 0u) {
            v = (int32_t)lround(vpk * sin(w * (0.5 + 1e-4 * (double)k)));
        }
        (void)hd_stribeck_step(&s, &c, v, -DEGS);
        n_cruise += s.cruise;
    }
    assert_int_equal(n_cruise, 0u);
    /* constant 0.01 deg/s with +-1 LSB jitter: a cruise from period 201 of the run on */
    hd_stribeck_init(&s, 0u, true);
    for (k = 0; k < 1000u; k++) {
        (void)hd_stribeck_step(&s, &c, DEGS / 100 + (int32_t)(k & 1u), -DEGS);
        assert_int_equal(s.cruise, (k >= 200u) ? 1u : 0u);
    }
    assert_true(s.tau > 0);                          /* the reference's direction, not the estimate's */
}

/* cruise detection: the reference velocity after cruise_ticks constant periods, the estimate
 * otherwise; the vs reciprocal follows a parameter change at once */
static void test_stribeck_cruise_and_vs_change(void **state)
{
    hd_stribeck_cfg_t c = { { NM(5), NM(8), DEGS, NM(100) }, { NM(5), NM(8), DEGS, NM(100) },
                            2u, DEGS / 1000, 0, NM(100), 10u, 0 };
    hd_stribeck_t s;
    uint32_t k;
    int32_t t;
    (void)state;
    hd_stribeck_init(&s, 0u, true);
    for (k = 0; k < 10u; k++) {                      /* first period after rest + 9 constant: estimate */
        assert_true(hd_stribeck_step(&s, &c, DEGS / 100, -DEGS) < 0);
        assert_int_equal(s.cruise, 0u);
    }
    assert_true(hd_stribeck_step(&s, &c, DEGS / 100 + 1, -DEGS) > 0);   /* 10th constant period: cruise */
    assert_int_equal(s.cruise, 1u);
    assert_int_equal(s.v, DEGS / 100 + 1);
    assert_true(hd_stribeck_step(&s, &c, DEGS / 100 + 1000, -DEGS) < 0);  /* a step: not constant */
    assert_int_equal(s.cruise_n, 0u);
    assert_true(hd_stribeck_step(&s, &c, 0, -DEGS) < 0);                   /* rest */
    /* a cruise below eps_v: the full static level (hard sign), not the smooth sign's fraction */
    for (k = 0; k < 11u; k++) {
        t = hd_stribeck_step(&s, &c, DEGS / 10000, 0);
    }
    assert_int_equal(s.cruise, 1u);
    assert_true(abs(t - NM(8)) < NM(0.01));
    assert_true(hd_stribeck_map(&c, DEGS / 10000) < NM(2));     /* smooth sign: 0.15 of the level */
    /* vs change: the step's map follows (same result as a fresh map) */
    c.cruise_ticks = 0u;
    c.pos.vs = DEGS / 7;
    c.neg.vs = DEGS / 7;
    t = hd_stribeck_step(&s, &c, 0, DEGS / 5);
    assert_int_equal(t, hd_stribeck_map(&c, DEGS / 5));
    assert_int_equal(s.rp.vs, DEGS / 7);
}

/* steady motion: at |v_ref| >= steady_vs * vs of its direction, once the axis follows, the map
 * follows the reference although the reference changes every period (no cruise) and the axis
 * sticks or slips back; at a start or reversal, below that speed and with steady_vs 0 the
 * estimate, as before */
static void test_stribeck_steady_motion_takes_the_reference(void **state)
{
    hd_stribeck_cfg_t c = { { NM(5), NM(8), DEGS, NM(100) }, { NM(5), NM(8), DEGS / 2, NM(100) },
                            2u, DEGS / 1000, 0, NM(100), 200u, 1 << 15 };   /* steady at 0.5 vs */
    hd_stribeck_t s;
    uint32_t k;
    int32_t t;
    (void)state;
    hd_stribeck_init(&s, 0u, true);
    /* the reference at 0.6 deg/s while the axis is still at rest (a start): the estimate */
    t = hd_stribeck_step(&s, &c, 6 * (DEGS / 10), 0);
    assert_int_equal(s.steady, 0u);
    assert_int_equal(t, hd_stribeck_map(&c, 0));
    /* the axis follows (0.6 deg/s >= 0.5 vs): steady from here */
    t = hd_stribeck_step(&s, &c, 6 * (DEGS / 10), 6 * (DEGS / 10));
    assert_int_equal(s.steady, 1u);
    for (k = 0; k < 300u; k++) {                     /* a sine's flank: +1000 LSB per period */
        const int32_t vr = (int32_t)(6 * (DEGS / 10)) + (int32_t)(k * 1000u);
        t = hd_stribeck_step(&s, &c, vr, -DEGS / 100);
        assert_int_equal(s.cruise, 0u);
        assert_int_equal(s.steady, 1u);
        assert_int_equal(s.v, vr);
        assert_int_equal(t, hd_stribeck_map(&c, vr));
        assert_true(t > 0);                          /* the reference's direction, not the estimate's */
    }
    /* 0.4 deg/s < 0.5 vs_pos: the estimate (near rest, at reversals) */
    t = hd_stribeck_step(&s, &c, 4 * (DEGS / 10), -DEGS / 100);
    assert_int_equal(s.steady, 0u);
    assert_int_equal(t, hd_stribeck_map(&c, -DEGS / 100));
    /* negative direction, its own vs (0.5 deg/s): steady from 0.25 deg/s, once the axis follows;
     * a reversal (the axis still sliding the old way) is not steady */
    t = hd_stribeck_step(&s, &c, -3 * (DEGS / 10), DEGS / 100);
    assert_int_equal(s.steady, 0u);
    assert_true(t > 0);
    t = hd_stribeck_step(&s, &c, -3 * (DEGS / 10), -DEGS / 4);
    assert_int_equal(s.steady, 1u);
    assert_true(t < 0);
    t = hd_stribeck_step(&s, &c, -3 * (DEGS / 10), DEGS / 100);   /* slips back: still steady */
    assert_int_equal(s.steady, 1u);
    assert_true(t < 0);
    t = hd_stribeck_step(&s, &c, 3 * (DEGS / 10), -DEGS / 4);     /* v_ref reverses: the estimate */
    assert_int_equal(s.steady, 0u);
    assert_true(t < 0);
    t = hd_stribeck_step(&s, &c, -2 * (DEGS / 10), -DEGS / 4);
    assert_int_equal(s.steady, 0u);
    assert_int_equal(t, hd_stribeck_map(&c, -DEGS / 4));
    /* steady_vs 0: off, the estimate at any speed */
    c.steady_vs = 0;
    t = hd_stribeck_step(&s, &c, 6 * DEGS, -DEGS / 100);
    assert_int_equal(s.steady, 0u);
    assert_int_equal(t, hd_stribeck_map(&c, -DEGS / 100));
}

static void test_lugre_steady_state_and_hold(void **state)
{
    hd_lugre_cfg_t c = { { NM(8), NM(12), DEGS, 0 }, 2u, (int32_t)(1.9e5 * 256), NM(600), 0, 0, NM(200) };
    hd_lugre_t s;
    uint32_t k;
    int32_t t = 0;
    (void)state;
    hd_lugre_init(&s, 0u, true);
    for (k = 0; k < 3000u; k++) {
        t = hd_lugre_step(&s, &c, 10 * DEGS, 0);
    }
    assert_true(abs(t - hd_stribeck_g(&c.g, 2u, 10 * DEGS)) <= 2);
    /* v = 0: bristles hold, torque constant */
    t = hd_lugre_step(&s, &c, 0, 0);
    assert_int_equal(hd_lugre_step(&s, &c, 0, 0), t);
}

static void test_maxwell_saturation(void **state)
{
    hd_maxwell_cfg_t c;
    hd_maxwell_t s;
    int64_t x = 0;
    int64_t sum = 0;
    uint32_t i;
    (void)state;
    c.n = 4u;
    for (i = 0; i < HD_MAXWELL_N_MAX; i++) {
        c.k[i] = (int32_t)(1000u * 256u * (i + 1u));
        c.d[i] = (int32_t)(100000u * (i + 1u));
    }
    c.compliance = 1 << 20;
    c.tau_max = NM(1000);
    hd_maxwell_init(&s, 0u, true);
    (void)hd_maxwell_step(&s, &c, x);
    for (i = 0; i < 200u; i++) {
        x += 10000;
        (void)hd_maxwell_step(&s, &c, x);
    }
    for (i = 0; i < 4u; i++) {
        sum += (int64_t)c.k[i] * c.d[i];
    }
    assert_int_equal(s.tau, hd_asr32_rnd(sum, 24u));
    assert_true(s.dth == hd_mul64x32_q(s.tau, c.compliance, 28u));
    for (i = 0; i < 400u; i++) {
        x -= 10000;
        (void)hd_maxwell_step(&s, &c, x);
    }
    assert_int_equal(s.tau, -hd_asr32_rnd(sum, 24u));
}

static void test_te_single_harmonic(void **state)
{
    hd_te_cfg_t c = { 1u, { 2u }, { 100000 }, { 0u }, 256 * 1000, NM(100), 0u };
    hd_te_comp_t s;
    (void)state;
    hd_te_comp_init(&s, 0u, true);
    /* theta_m = 1/8 turn: sin(2 * 2pi/8) = 1 */
    assert_true(hd_te_comp_step(&s, &c, (int64_t)1 << 29) == -100000);
    assert_true(s.te == 100000);
    /* whole turns do not matter */
    assert_true(hd_te_comp_step(&s, &c, ((int64_t)7 << 32) + ((int64_t)1 << 29)) == -100000);
}

/* LuGre over n periods in parts (the bank's schedule): prep_g, prep_exp_n and finish_n in
 * separate calls are exactly step_n; step_n with n = 1 is the single-period step; with n = 8 the
 * bristles reach the same steady state as eight single-period steps do. */
static void test_lugre_parts_equal_step(void **state)
{
    hd_lugre_cfg_t c = { { NM(8), NM(12), DEGS, 0 }, 2u, (int32_t)(1.9e5 * 256), NM(600), NM(3), 30 << 16, NM(200) };
    hd_lugre_t a, b, one, ref;
    uint32_t k;
    uint64_t r = 12345u;
    (void)state;
    hd_lugre_init(&a, 2u, true);
    hd_lugre_init(&b, 2u, true);
    hd_lugre_init(&one, 0u, true);
    hd_lugre_init(&ref, 0u, true);
    for (k = 0; k < 3000u; k++) {
        r = r * 6364136223846793005ULL + 1442695040888963407ULL;
        const int32_t v = (int32_t)((int64_t)(r >> 40) - (1 << 23)) * 64 + ((k % 500u < 250u) ? 5 * DEGS : -5 * DEGS);
        const hd_angle_t e = (hd_angle_t)(int32_t)(r >> 48) - 32768;
        hd_lugre_prep_g(&a, &c, v);
        hd_lugre_prep_exp_n(&a, &c, 8u);
        const int32_t ta = hd_lugre_finish_n(&a, &c, e, 8u);
        assert_int_equal(ta, hd_lugre_step_n(&b, &c, v, e, 8u));
        assert_true(a.z == b.z && a.dz == b.dz && a.tau_raw == b.tau_raw);
        assert_int_equal(hd_lugre_step_n(&one, &c, v, e, 1u), hd_lugre_step(&ref, &c, v, e));
        assert_true(one.z == ref.z);
    }
    /* steady state at 10 deg/s: one step of 8 periods ends where 8 single steps do */
    hd_lugre_init(&a, 0u, true);
    hd_lugre_init(&b, 0u, true);
    for (k = 0; k < 400u; k++) {
        (void)hd_lugre_step_n(&a, &c, 10 * DEGS, 0, 8u);
        for (uint32_t j = 0; j < 8u; j++) {
            (void)hd_lugre_step(&b, &c, 10 * DEGS, 0);
        }
    }
    print_message("z after 400 x 8 periods: %lld vs %lld (Q48)\n", (long long)a.z, (long long)b.z);
    assert_true(llabs((long long)(a.z - b.z)) <= llabs((long long)b.z) / 1000000);
    assert_true(abs(a.tau_raw - b.tau_raw) <= 2);
}

/* TE with its slope: the same model value as hd_te_model; TE(theta + d) is predicted from the
 * slope within the second-order term (2 pi order)^2 amp d^2 / 2 (+ 2 LSB); the weighted
 * correction's slope is -w dTE/dtheta. */
static void test_te_slope_predicts(void **state)
{
    hd_te_cfg_t c = { 3u, { 2u, 1u, 4u }, { 100000, -40000, 25000 }, { 0x12345678u, 0x9ABCDEF0u, 7u }, 0, NM(100), 0u };
    hd_te_comp_t s;
    uint32_t k;
    int32_t slope_w;
    (void)state;
    for (k = 0; k < 2000u; k++) {
        const hd_angle_t th = ((hd_angle_t)5 << 32) + (hd_angle_t)k * 2147483LL * 1000LL;
        int32_t slope;
        const int64_t te = hd_te_model_slope(&c, th, &slope);
        assert_true(te == hd_te_model(&c, th));
        const int64_t d = (int64_t)(k % 41u) * 4000000 - 80000000;       /* up to ~0.019 turn */
        const int64_t pred = te + (int64_t)(((__int128)d * slope) >> 32);
        const double dt = (double)d / 4294967296.0;
        const double bound = 0.5 * (2.0 * 3.14159265358979 * 4.0) * (2.0 * 3.14159265358979 * 4.0) * 165000.0 * dt * dt + 2.0;
        assert_true(fabs((double)(pred - hd_te_model(&c, th + d))) <= bound);
    }
    hd_te_comp_init(&s, 0u, true);
    const hd_angle_t th0 = (int64_t)1 << 29;
    int32_t slope0;
    (void)hd_te_model_slope(&c, th0, &slope0);
    assert_true(hd_te_comp_step_slope(&s, &c, th0, &slope_w) == -hd_te_model(&c, th0));
    assert_int_equal(slope_w, -slope0);
}

/* Closed loop on an integer rigid plant: J w' = u - Fc sgn(w) - Tl. */
static void test_backstep_closed_loop(void **state)
{
    const int32_t J = (int32_t)(1.3 * 6.283185307 * 65536);
    hd_backstep_cfg_t c = { (int32_t)(50.0 * 65536), (int32_t)(50.0 * 65536), J,
                            (int32_t)(1.3 * 6.283185307 * 2500 / 4 * 256), DEGS / 100, DEGS, 1 << 30, NM(150),
                            { 1 << 23, 1 << 23, 1 << 22, 1 << 23 }, { 0, 0, 0, NM(-20) }, { NM(30), NM(30), NM(500), NM(20) } };
    const int32_t th0[4] = { 0, 0, 0, 0 };
    hd_backstep_t s;
    hd_backstep_in_t in = { 0, 0, 0, 0, 0 };
    int64_t w48 = 0;           /* plant velocity, 2^-48 turn/s */
    int64_t th = 0;            /* plant angle Q32.32 (with 2^-16 carry in w48 integration) */
    int64_t frac = 0;
    int32_t u = 0;
    uint32_t k;
    int64_t maxerr = 0;
    (void)state;
    hd_backstep_init(&s, &c, th0, 0u, true);
    for (k = 0; k < 40000u; k++) {
        /* reference: slow sine of 0.002 turn at 0.5 Hz */
        const uint32_t ph = (uint32_t)((uint64_t)k * 214748u);   /* 0.5 Hz */
        int32_t sn, cs;
        hd_sincos_turn(ph, &sn, &cs);
        in.theta_d = hd_mul64x32_q((int64_t)8589935, sn, 30u);     /* 0.002 turn */
        in.omega_d = hd_mul_q(26986075, cs, 30);                    /* 0.002*pi turn/s */
        in.acc_d = hd_mul_q(-(int32_t)(0.002 * 9.8696 * 16777216), sn, 30);
        in.theta = th;
        in.omega = (int32_t)hd_asr64_rnd(w48, 16u);
        u = hd_backstep_step(&s, &c, &in, 0);
        {
            /* plant: a = (u - 3 N.m sgn w - 2 N.m) / J  -> 2^-48 turn/s^2 */
            const int32_t fr = (in.omega > 0) ? NM(3) : ((in.omega < 0) ? -NM(3) : 0);
            const int64_t net = (int64_t)u - fr - NM(2);
            const int64_t acc48 = hd_div64_rnd(net * ((int64_t)1 << 32), J);     /* Q16/Q16 -> 2^-32 */
            w48 += hd_div64_rnd(acc48 * 65536, 10000);
            frac += w48;                                           /* 2^-48 turn per 1/10000 s */
            th += hd_div64_rnd(frac, (int64_t)10000 << 16);
            frac -= hd_div64_rnd(frac, (int64_t)10000 << 16) * ((int64_t)10000 << 16);
        }
        if (k > 30000u) {
            const int64_t e = llabs(th - in.theta_d);
            maxerr = (e > maxerr) ? e : maxerr;
        }
    }
    /* tracking error after adaptation: < 10 arcsec (1 arcsec = 3314 LSB; without
     * adaptation the 5 N.m of friction + load leave ~320 arcsec), estimates near truth */
    print_message("# backstep closed loop: max |e1| in the last second = %.3f arcsec, "
                  "Fc_hat %.2f N.m, Tl_hat %.2f N.m\n", (double)maxerr / 3314.0,
                  (double)s.th[0] / 281474976710656.0, (double)s.th[3] / 281474976710656.0);
    assert_true(maxerr < 10 * 3314);
    assert_true(llabs(s.th[0] - ((int64_t)NM(3) << 32)) < ((int64_t)NM(0.5) << 32));
    assert_true(llabs(s.th[3] - ((int64_t)NM(2) << 32)) < ((int64_t)NM(0.5) << 32));
    /* bumpless preload: the law equals the effort applied */
    hd_backstep_preload(&s, &c, &in, u + NM(1));
    assert_true(abs(hd_backstep_law(&s, &c, &in) - (u + NM(1))) <= 1);
}

/* The same loop with the law every period on the held estimates and the regressor's
 * shape and the adaptation once per 8 periods (the bank's schedule, hd_sched.h): the
 * same tracking and estimates; the adaptation of 8 periods at once is 8 times one. */
static void test_backstep_held_closed_loop(void **state)
{
    const int32_t J = (int32_t)(1.3 * 6.283185307 * 65536);
    hd_backstep_cfg_t c = { (int32_t)(50.0 * 65536), (int32_t)(50.0 * 65536), J,
                            (int32_t)(1.3 * 6.283185307 * 2500 / 4 * 256), DEGS / 100, DEGS, 1 << 30, NM(150),
                            { 1 << 23, 1 << 23, 1 << 22, 1 << 23 }, { 0, 0, 0, NM(-20) }, { NM(30), NM(30), NM(500), NM(20) } };
    const int32_t th0[4] = { 0, 0, 0, 0 };
    hd_backstep_t s;
    hd_backstep_in_t in = { 0, 0, 0, 0, 0 };
    int64_t w48 = 0;           /* plant velocity, 2^-48 turn/s */
    int64_t th = 0;            /* plant angle Q32.32 (with 2^-16 carry in w48 integration) */
    int64_t frac = 0;
    int32_t u = 0;
    uint32_t k;
    int64_t maxerr = 0;
    (void)state;
    hd_backstep_init(&s, &c, th0, 0u, true);
    for (k = 0; k < 40000u; k++) {
        /* reference: slow sine of 0.002 turn at 0.5 Hz */
        const uint32_t ph = (uint32_t)((uint64_t)k * 214748u);   /* 0.5 Hz */
        int32_t sn, cs;
        hd_sincos_turn(ph, &sn, &cs);
        in.theta_d = hd_mul64x32_q((int64_t)8589935, sn, 30u);     /* 0.002 turn */
        in.omega_d = hd_mul_q(26986075, cs, 30);                    /* 0.002*pi turn/s */
        in.acc_d = hd_mul_q(-(int32_t)(0.002 * 9.8696 * 16777216), sn, 30);
        in.theta = th;
        in.omega = (int32_t)hd_asr64_rnd(w48, 16u);
        if ((k & 7u) == 0u) {
            hd_backstep_regressor(&s, &c, &in);
        }
        u = hd_backstep_step_held(&s, &c, &in, 0);
        if ((k & 7u) == 0u) {
            hd_backstep_adapt(&s, &c, 3u);
        }
        {
            /* plant: a = (u - 3 N.m sgn w - 2 N.m) / J  -> 2^-48 turn/s^2 */
            const int32_t fr = (in.omega > 0) ? NM(3) : ((in.omega < 0) ? -NM(3) : 0);
            const int64_t net = (int64_t)u - fr - NM(2);
            const int64_t acc48 = hd_div64_rnd(net * ((int64_t)1 << 32), J);     /* Q16/Q16 -> 2^-32 */
            w48 += hd_div64_rnd(acc48 * 65536, 10000);
            frac += w48;                                           /* 2^-48 turn per 1/10000 s */
            th += hd_div64_rnd(frac, (int64_t)10000 << 16);
            frac -= hd_div64_rnd(frac, (int64_t)10000 << 16) * ((int64_t)10000 << 16);
        }
        if (k > 30000u) {
            const int64_t e = llabs(th - in.theta_d);
            maxerr = (e > maxerr) ? e : maxerr;
        }
    }
    /* tracking error after adaptation: < 10 arcsec (1 arcsec = 3314 LSB; without
     * adaptation the 5 N.m of friction + load leave ~320 arcsec), estimates near truth */
    print_message("# backstep closed loop, held law, adaptation every 8 periods: max |e1| in the last second = %.3f arcsec, "
                  "Fc_hat %.2f N.m, Tl_hat %.2f N.m\n", (double)maxerr / 3314.0,
                  (double)s.th[0] / 281474976710656.0, (double)s.th[3] / 281474976710656.0);
    assert_true(maxerr < 10 * 3314);
    assert_true(llabs(s.th[0] - ((int64_t)NM(3) << 32)) < ((int64_t)NM(0.5) << 32));
    assert_true(llabs(s.th[3] - ((int64_t)NM(2) << 32)) < ((int64_t)NM(0.5) << 32));
    /* one adaptation of 8 periods moves each parameter by 8 times the one of 1 period (+-4 LSB) */
    {
        hd_backstep_t s1 = s, s8 = s;
        uint32_t moved = 0u;
        s1.saturated = 0u;
        s8.saturated = 0u;
        hd_backstep_adapt(&s1, &c, 0u);
        hd_backstep_adapt(&s8, &c, 3u);
        for (uint32_t i = 0; i < HD_BS_NP; i++) {
            const int64_t d1 = s1.th[i] - s.th[i], d8 = s8.th[i] - s.th[i];
            if (s8.th[i] != (int64_t)c.th_min[i] * 4294967296LL && s8.th[i] != (int64_t)c.th_max[i] * 4294967296LL) {
                assert_true(llabs(d8 - 8 * d1) <= 4);
                moved += (d1 != 0) ? 1u : 0u;
            }
        }
        assert_true(moved > 0u);
    }
    /* bumpless preload with the held law: the law equals the effort applied */
    hd_backstep_preload(&s, &c, &in, u + NM(1));
    assert_true(abs(hd_backstep_law(&s, &c, &in) - (u + NM(1))) <= 1);
    assert_true(abs(hd_backstep_step_held(&s, &c, &in, 0) - (u + NM(1))) <= 1);
}


/* A slow cruising reference (0.01 deg/s) with the measured velocity's noise ten times
 * larger flipping its sign every period: from the second period of the cruise the friction
 * regressor follows the reference (sign +1, Stribeck shape at the reference velocity), so
 * the friction estimate keeps carrying the friction; at rest and while the reference
 * changes it follows the measured velocity. */
static void test_backstep_regressor_follows_the_moving_reference(void **state)
{
    hd_backstep_cfg_t c = { (int32_t)(50.0 * 65536), (int32_t)(50.0 * 65536), (int32_t)(8.0 * 65536),
                            (int32_t)(4000.0 * 256), DEGS / 1000, DEGS, 1 << 30, NM(60),
                            { 1 << 23, 1 << 23, 1 << 22, 1 << 23 }, { 0, 0, 0, NM(-20) },
                            { NM(30), NM(30), NM(500), NM(20) } };
    const int32_t th0[4] = { NM(7), NM(3), NM(10), 0 };
    hd_backstep_t s;
    hd_backstep_in_t in = { 0, 0, DEGS / 100, DEGS / 100, 0 };
    uint32_t k;
    (void)state;
    hd_backstep_init(&s, &c, th0, 0u, true);
    in.omega = -DEGS / 10;
    (void)hd_backstep_step(&s, &c, &in, 0);        /* the reference just started: not a cruise */
    assert_true(s.phi[0] < -HD_Q30_ONE / 2);
    for (k = 0; k < 200u; k++) {
        in.omega = ((k & 1u) != 0u) ? DEGS / 10 : -DEGS / 10;
        (void)hd_backstep_step(&s, &c, &in, 0);
        assert_true(s.phi[0] > HD_Q30_ONE / 2);
        assert_true(s.phi[1] > HD_Q30_ONE / 2);
    }
    /* a reference that changes (a reversal): the measured velocity */
    in.omega_d = DEGS / 200;
    in.omega = -DEGS / 10;
    (void)hd_backstep_step(&s, &c, &in, 0);
    assert_true(s.phi[0] < -HD_Q30_ONE / 2);
    /* at rest (omega_d = 0) the measured velocity sets the direction */
    in.omega_d = 0;
    in.omega = -DEGS / 10;
    (void)hd_backstep_step(&s, &c, &in, 0);
    assert_true(s.phi[0] < -HD_Q30_ONE / 2);
}

/* The law's parameter terms in Q15.16 (th_q16, range analysis in hd_backstep.c): th_q16 is
 * the rounded estimate after every change (init, step's adaptation, adapt, preload), and
 * the law's output stays within 2 LSB of the form with the Q16.48 estimates, each product
 * phi_i theta_hat_i rounded on its own (recomputed here from the step's e1, e2 and phi). */
static uint32_t lcg(uint32_t *x)
{
    *x = *x * 1664525u + 1013904223u;
    return *x;
}

static void assert_th_rounded(const hd_backstep_t *s)
{
    uint32_t i;
    for (i = 0; i < HD_BS_NP; i++) {
        assert_int_equal(s->th_q16[i], hd_sat32(hd_asr64_rnd(s->th[i], 32u)));
    }
}

static void test_backstep_law_q16_terms(void **state)
{
    hd_backstep_cfg_t c = { (int32_t)(50.0 * 65536), (int32_t)(50.0 * 65536), (int32_t)(8.0 * 65536),
                            (int32_t)(4000.0 * 256), DEGS / 1000, DEGS, 1 << 30, 0,
                            { 1 << 26, 1 << 26, 1 << 25, 1 << 26 }, { -NM(300), -NM(300), -NM(3000), -NM(2000) },
                            { NM(300), NM(300), NM(3000), NM(2000) } };
    const int32_t th0[4] = { NM(7.3), NM(-2.1), NM(10.7), NM(-1.9) };
    hd_backstep_t s;
    hd_backstep_in_t in;
    uint32_t x = 12345u, k, i;
    int64_t maxdiff = 0;
    uint32_t lowbits = 0u;
    (void)state;
    hd_backstep_init(&s, &c, th0, 0u, true);
    assert_th_rounded(&s);
    for (k = 0; k < 4000u; k++) {
        in.theta_d = (int64_t)(int32_t)lcg(&x) * 64;
        in.theta = in.theta_d + (int32_t)(lcg(&x) >> 8) - (1 << 23);
        in.omega_d = (int32_t)(lcg(&x) >> 4) - (1 << 27);
        in.omega = in.omega_d + (int32_t)(lcg(&x) >> 12) - (1 << 19);
        in.acc_d = (int32_t)(lcg(&x) >> 8) - (1 << 23);
        if ((k & 7u) == 0u) {
            (void)hd_backstep_step(&s, &c, &in, 0);             /* adapts every period */
        } else if ((k & 7u) == 1u) {
            hd_backstep_adapt(&s, &c, 3u);                      /* the scheduled adaptation */
        } else if ((k & 127u) == 2u) {
            hd_backstep_preload(&s, &c, &in, NM(5));            /* moves th_3 */
        }
        assert_th_rounded(&s);
        for (i = 0; i < HD_BS_NP; i++) {
            lowbits |= (uint32_t)s.th[i];
        }
        (void)hd_backstep_step_held(&s, &c, &in, 0);
        {
            /* the Q16.48 form: J (alpha1' - c2 e2) - ke e1 + sum round(th_i phi_i / 2^62) + round(th_3 / 2^32) */
            const int32_t dalpha1 = hd_sub_sat(in.acc_d, hd_mul_q(c.c1, hd_sub_sat(in.omega, in.omega_d), 24u));
            int64_t u = (int64_t)hd_mul_q(c.j, hd_sub_sat(dalpha1, hd_mul_q(c.c2, s.e2, 24u)), 24u);
            int64_t d;
            u -= (int64_t)hd_sat32(hd_asr64_rnd((int64_t)c.ke * (int64_t)s.e1, 24u));
            for (i = 0; i < 3u; i++) {
                u = hd_add64_sat(u, hd_mul64x32_q(s.th[i], s.phi[i], 62u));
            }
            u = hd_add64_sat(u, hd_asr64_rnd(s.th[3], 32u));
            d = (int64_t)s.u_bs - hd_sat32(u);
            d = (d < 0) ? -d : d;
            maxdiff = (d > maxdiff) ? d : maxdiff;
        }
    }
    print_message("backstep law: Q15.16 terms vs Q16.48 products: max |diff| %lld LSB\n", (long long)maxdiff);
    assert_true(lowbits != 0u);        /* the adaptation left fractions below Q16 to round */
    assert_true(maxdiff <= 2);
}

/* The short form of the TE model and slope (fit32) gives the general form's words at the
 * edges of its ranges (amplitudes +-2^30, orders up to 2^28, four harmonics), and
 * hd_te_cfg_ranges takes it only inside them. */
static void test_te_fit32_same_words(void **state)
{
    hd_te_cfg_t c = { 4u, { 2u, 1u, 4u, 6u }, { 0, 0, 0, 0 }, { 0u, 0u, 0u, 0u }, 0, NM(100), 0u };
    hd_te_cfg_t g;
    uint32_t x = 777u, k, h;
    (void)state;
    for (k = 0; k < 20000u; k++) {
        for (h = 0; h < 4u; h++) {
            const uint32_t r = lcg(&x);
            c.amp[h] = ((r & 3u) == 0u) ? (((r & 4u) != 0u) ? HD_TE_FIT32_AMP : -HD_TE_FIT32_AMP)
                                        : (int32_t)(lcg(&x) >> 1) - (1 << 30);
            c.order[h] = ((r & 24u) == 0u) ? HD_TE_FIT32_ORDER : (lcg(&x) >> 4);
            c.phase[h] = lcg(&x);
        }
        c.n = 1u + (k & 3u);
        hd_te_cfg_ranges(&c);
        assert_int_equal(c.fit32, 1u);
        g = c;
        g.fit32 = 0u;
        {
            const uint64_t hi = lcg(&x);
            const int64_t th = (int64_t)((hi << 32) | lcg(&x));
            int32_t s1, s0;
            const int64_t m1 = hd_te_model_slope(&c, th, &s1);
            const int64_t m0 = hd_te_model_slope(&g, th, &s0);
            assert_true(m1 == m0);
            assert_int_equal(s1, s0);
        }
    }
    /* outside the ranges: the general form */
    c.n = 4u;
    c.amp[0] = HD_TE_FIT32_AMP + 1;
    hd_te_cfg_ranges(&c);
    assert_int_equal(c.fit32, 0u);
    c.amp[0] = -HD_TE_FIT32_AMP - 1;
    hd_te_cfg_ranges(&c);
    assert_int_equal(c.fit32, 0u);
    c.amp[0] = 0;
    c.order[3] = HD_TE_FIT32_ORDER + 1u;
    hd_te_cfg_ranges(&c);
    assert_int_equal(c.fit32, 0u);
    c.order[3] = 6u;
    c.n = 5u;
    hd_te_cfg_ranges(&c);
    assert_int_equal(c.fit32, 0u);
    c.n = 4u;
    hd_te_cfg_ranges(&c);
    assert_int_equal(c.fit32, 1u);
}

/* A slow sine on a rigid plant with static friction (the axis sticks at every reversal until the
 * torque breaks it away: Fs 10 N.m, Fc 7 N.m) under a load torque of 12 N.m, larger than the
 * breakaway, with T_load's configured box +-14 N.m: it holds the load, not the load plus Fs.
 * While the axis sticks the friction regressor's sign is 0 and only T_load's integral can
 * supply the breakaway, so while the axis can stick (the reference moves at most 4 w_s fast and
 * does not cruise, the axis at most w_s fast) T_load may leave the configured box (by
 * at most the friction boxes' Fc + (Fs - Fc)); the reversal error then stays near the one of a
 * load inside the box.  With a box of the load alone the error at the reversal against the load
 * is the one the e1 terms need to break the axis away, several times that. */
static int32_t bs_reversal_run(int32_t tl_box, double load_Nm, int64_t *th3_max)
{
    const double jt = 1.3 * 6.283185307;          /* N.m per (turn/s^2) */
    const double fs = 10.0, fc = 7.0, dt = 1.0 / HD_LOOP_HZ;
    hd_backstep_cfg_t c = { (int32_t)(50.0 * 65536), (int32_t)(50.0 * 65536), (int32_t)(jt * 65536),
                            (int32_t)(jt * 2500 / 4 * 256), DEGS / 100, DEGS, 1 << 30, NM(150),
                            { 1 << 23, 1 << 23, 1 << 22, 20 << 24 }, { 0, 0, 0, -tl_box }, { NM(30), NM(30), NM(500), tl_box } };
    const int32_t th0[4] = { NM(7), NM(3), 0, 0 };
    hd_backstep_t s;
    hd_backstep_in_t in = { 0, 0, 0, 0, 0 };
    double th = 0.0, w = 0.0;                      /* plant, turn and turn/s */
    bool stuck = true;
    int64_t maxerr = 0;
    uint32_t k;
    hd_backstep_init(&s, &c, th0, 0u, true);
    *th3_max = INT64_MIN;
    for (k = 0; k < 90000u; k++) {
        const uint32_t ph = (uint32_t)((uint64_t)k * 42950u);    /* 0.1 Hz, 1 deg: reversals at 2.5, 7.5 s */
        int32_t sn, cs;
        hd_sincos_turn(ph, &sn, &cs);
        in.theta_d = hd_mul64x32_q((int64_t)11930465, sn, 30u);
        in.omega_d = hd_mul_q(7495970, cs, 30);
        in.acc_d = hd_mul_q(-18398, sn, 30);
        in.theta = (int64_t)llround(th * 4294967296.0);
        in.omega = (int32_t)lround(w * 4294967296.0);
        {
            const double u = (double)hd_backstep_step(&s, &c, &in, 0) / 65536.0;
            const double drive = u - load_Nm;
            if (stuck && fabs(drive) <= fs) {
                w = 0.0;                                          /* static friction holds */
            } else {
                const double dir = (w != 0.0) ? ((w > 0.0) ? 1.0 : -1.0) : ((drive > 0.0) ? 1.0 : -1.0);
                const double w1 = w + (drive - fc * dir) / jt * dt;
                stuck = (w1 * dir <= 0.0);                        /* stops within the period */
                w = stuck ? 0.0 : w1;
            }
            th += w * dt;
        }
        *th3_max = (s.th[3] > *th3_max) ? s.th[3] : *th3_max;
        if (k > 50000u) {                                 /* the reversal at 7.5 s */
            const int64_t e = llabs(in.theta - in.theta_d);
            maxerr = (e > maxerr) ? e : maxerr;
        }
    }
    return (int32_t)(maxerr / 3314);          /* arcsec */
}

static void test_backstep_reversal_against_a_load_beyond_the_box(void **state)
{
    int64_t th3_max, th3_ref;
    int32_t e_load, e_ref;
    (void)state;
    e_load = bs_reversal_run(NM(14), 12.0, &th3_max);
    e_ref = bs_reversal_run(NM(14), 2.0, &th3_ref);
    print_message("# backstep reversal, load 12 N.m, T_load box +-14 N.m: max |e1| %d arcsec (load 2 N.m: %d), "
                  "T_load up to %.2f N.m\n", e_load, e_ref, (double)th3_max / 281474976710656.0);
    /* T_load leaves the configured box: it carries the load plus the breakaway (22 N.m) ... */
    assert_true(th3_max > ((int64_t)NM(20) << 32));
    /* ... and the reversal against the load costs at most 1.5x the error with a load well inside
     * the box (a box of the load alone: 12x) */
    assert_true(e_load <= e_ref * 3 / 2);
    /* at rest (omega_d = 0) the configured box holds: a held error that winds T_load up stops at
     * +14 N.m (a wider box lets the hold's integral hunt against the static friction) */
    {
        const double jt = 1.3 * 6.283185307;
        hd_backstep_cfg_t c = { (int32_t)(50.0 * 65536), (int32_t)(50.0 * 65536), (int32_t)(jt * 65536),
                                (int32_t)(jt * 2500 / 4 * 256), DEGS / 100, DEGS, 1 << 30, NM(150),
                                { 1 << 23, 1 << 23, 1 << 22, 20 << 24 }, { 0, 0, 0, -NM(14) }, { NM(30), NM(30), NM(500), NM(14) } };
        const int32_t th0[4] = { NM(7), NM(3), 0, NM(13) };
        hd_backstep_t s;
        hd_backstep_in_t in = { 0, 11930465 / 60, 0, 0, 0 };     /* 1 arcmin behind, at rest */
        uint32_t k;
        hd_backstep_init(&s, &c, th0, 0u, true);
        for (k = 0; k < 2000u; k++) {
            (void)hd_backstep_step(&s, &c, &in, 0);
        }
        assert_true(s.th[3] == ((int64_t)NM(14) << 32));
        /* a slow reference that cruises (constant omega_d): the friction regressor takes its
         * sign and carries the breakaway, so the configured box holds */
        in.omega_d = DEGS / 100;
        for (k = 0; k < 2000u; k++) {
            (void)hd_backstep_step(&s, &c, &in, 0);
        }
        assert_true(s.th[3] == ((int64_t)NM(14) << 32));
        /* the reference moves slowly and changes (a reversal; the regressor takes the axis'
         * velocity) while the axis sticks: wider */
        for (k = 0; k < 2000u; k++) {
            in.omega_d = DEGS / 100 + (int32_t)((k & 1u) * 1000u);
            (void)hd_backstep_step(&s, &c, &in, 0);
        }
        assert_true(s.th[3] > ((int64_t)NM(14) << 32) && s.th[3] <= ((int64_t)NM(14 + 60) << 32));
        /* the axis slides faster than w_s: it cannot stick, the load box */
        in.omega = 2 * DEGS;
        in.omega_d = DEGS / 100;
        (void)hd_backstep_step(&s, &c, &in, 0);
        assert_true(s.th[3] <= ((int64_t)NM(14) << 32));
        /* the reference faster than 4 w_s: the load box */
        in.omega = 0;
        for (k = 0; k < 200u; k++) {
            in.omega_d = DEGS / 100 + (int32_t)((k & 1u) * 1000u);
            (void)hd_backstep_step(&s, &c, &in, 0);
        }
        assert_true(s.th[3] > ((int64_t)NM(14) << 32));
        in.omega_d = 5 * DEGS;
        (void)hd_backstep_step(&s, &c, &in, 0);
        assert_true(s.th[3] <= ((int64_t)NM(14) << 32));
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_blend_ramp_is_bumpless, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stribeck_odd_and_breakaway, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stribeck_recip_matches_division, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stribeck_cruise_and_vs_change, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stribeck_sinusoid_peak_is_no_cruise, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stribeck_steady_motion_takes_the_reference, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_lugre_steady_state_and_hold, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_maxwell_saturation, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_te_single_harmonic, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_lugre_parts_equal_step, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_te_slope_predicts, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_backstep_closed_loop, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_backstep_held_closed_loop, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_backstep_regressor_follows_the_moving_reference, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_backstep_law_q16_terms, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_te_fit32_same_words, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_backstep_reversal_against_a_load_beyond_the_box, setUp, tearDown),
    };
    return cmocka_run_group_tests_name("comp_misc", tests, NULL, NULL);
}
