/*
 * test_plant_drift.c - simulated axis: parameter drifts during a run ([inertia_drift],
 * [stiffness_drift], [gravity_drift], the return leg of [friction_drift]).  Each drifting
 * quantity is measured against the same plant without the drift, with the state reset
 * every period so that only the parameter differs.
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

#include "hd_plant.h"

#define DT 1e-4

typedef struct {
    hd_plant_params prm;
    hd_plant plant, ref;
    hd_plant_input in;
} fixture;

static int setUp(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (f == NULL) return -1;
    hd_plant_defaults_minimal(&f->prm);
    f->prm.current_loop_enabled = 0;
    *state = f;
    return 0;
}

static int tearDown(void **state)
{
    free(*state);
    return 0;
}

static void init(hd_plant *p, const hd_plant_params *q)
{
    char msg[200] = "";
    int rc = hd_plant_init(p, q, 1u, msg, sizeof msg);
    if (rc != 0) fprintf(stderr, "init: %s\n", msg);
    assert_int_equal(rc, 0);
}

static void set(hd_plant_params *q, const char *name, double v)
{
    assert_int_equal(hd_plant_param_set(q, name, v), 0);
}

/* Ramp weight in force during the period that ended after k steps (set at its start). */
static double weight(long k, double t0, double ramp)
{
    const double x = ((double)(k - 1) * DT - t0) / ramp;
    return x <= 0.0 ? 0.0 : (x >= 1.0 ? 1.0 : x);
}

/* [inertia_drift]: a load torque from rest accelerates the load 1/s(t) times as fast. */
static void test_inertia_drift(void **state)
{
    fixture *f = *state;
    long k;
    f->prm.stiffness_enabled = 0;                    /* load alone */
    init(&f->ref, &f->prm);
    set(&f->prm, "inertia_drift.enabled", 1.0);
    set(&f->prm, "inertia_drift.t_start_s", 0.2);
    set(&f->prm, "inertia_drift.ramp_s", 0.4);
    set(&f->prm, "inertia_drift.scale", 2.0);
    init(&f->plant, &f->prm);
    memset(&f->in, 0, sizeof f->in);
    f->in.load_torque_Nm = 1.0;
    for (k = 1; k <= 8000; k++) {
        hd_plant_set_state(&f->plant, 0.0, 0.0, 0.0, 0.0);
        hd_plant_set_state(&f->ref, 0.0, 0.0, 0.0, 0.0);
        hd_plant_step(&f->plant, &f->in, DT);
        hd_plant_step(&f->ref, &f->in, DT);
        if (k % 500 == 0) {
            const double s = 1.0 + weight(k, 0.2, 0.4);
            const double r = f->ref.out.load_velocity_rad_s / f->plant.out.load_velocity_rad_s;
            assert_true(f->ref.out.load_velocity_rad_s > 0.0);
            assert_true(fabs(r - s) < 1e-9);
        }
    }
    assert_true(fabs(f->plant.prm.jl_kgm2 - 2.0 * f->ref.prm.jl_kgm2) < 1e-15 * f->ref.prm.jl_kgm2);
}

/* [stiffness_drift]: the spring torque at a held twist follows s(t) = 1 -> 0.8. */
static void test_stiffness_drift(void **state)
{
    fixture *f = *state;
    const double phi = 1e-4;
    long k;
    f->prm.jm_kgm2 = 1e3;                            /* heavy sides: the twist stays put */
    f->prm.jl_kgm2 = 1e3;                            /* within a period */
    init(&f->ref, &f->prm);
    set(&f->prm, "stiffness_drift.enabled", 1.0);
    set(&f->prm, "stiffness_drift.t_start_s", 0.1);
    set(&f->prm, "stiffness_drift.ramp_s", 0.5);
    set(&f->prm, "stiffness_drift.scale", 0.8);
    init(&f->plant, &f->prm);
    memset(&f->in, 0, sizeof f->in);
    for (k = 1; k <= 8000; k++) {
        /* motor at phi (output side) ahead of the load, everything at rest */
        hd_plant_set_state(&f->plant, phi * f->prm.ratio, 0.0, 0.0, 0.0);
        hd_plant_set_state(&f->ref, phi * f->prm.ratio, 0.0, 0.0, 0.0);
        hd_plant_step(&f->plant, &f->in, DT);
        hd_plant_step(&f->ref, &f->in, DT);
        if (k % 500 == 0) {
            const double s = 1.0 - 0.2 * weight(k, 0.1, 0.5);
            const double r = f->plant.out.transmitted_torque_Nm / f->ref.out.transmitted_torque_Nm;
            assert_true(fabs(f->ref.out.transmitted_torque_Nm) > 0.1);
            assert_true(fabs(r - s) < 2e-3);
        }
    }
}

/* [gravity_drift]: an unbalance appears from zero (gravity off) to mgl_Nm over the ramp. */
static void test_gravity_drift_appears(void **state)
{
    fixture *f = *state;
    const double mgl = 3.0;
    long k;
    f->prm.stiffness_enabled = 0;
    assert_int_equal(f->prm.gravity_enabled, 0);
    set(&f->prm, "gravity_drift.enabled", 1.0);
    set(&f->prm, "gravity_drift.t_start_s", 0.3);
    set(&f->prm, "gravity_drift.ramp_s", 0.2);
    set(&f->prm, "gravity_drift.mgl_Nm", mgl);
    init(&f->plant, &f->prm);
    memset(&f->in, 0, sizeof f->in);
    for (k = 1; k <= 8000; k++) {
        hd_plant_set_state(&f->plant, 0.0, 0.0, 0.0, 0.0);   /* load horizontal: cos = 1 */
        hd_plant_step(&f->plant, &f->in, DT);
        if (k % 250 == 0) {
            const double w = weight(k, 0.3, 0.2);
            const double tg = f->plant.out.gravity_torque_Nm;
            assert_true(fabs(tg + mgl * w) < 1e-6 * mgl);
            if (w == 0.0) {
                assert_true(tg == 0.0);
            }
        }
    }
    assert_true(fabs(f->plant.out.gravity_torque_Nm + mgl) < 1e-6 * mgl);
}

/* [friction_drift] with a return leg: 1 -> 1.5 (warm-up), hold, back to 1 (cooling). */
static void test_friction_drift_return(void **state)
{
    fixture *f = *state;
    hd_plant_params r;
    const double w = 10.0;
    long k;
    int seen_top = 0;
    hd_plant_defaults_reference(&r);
    f->prm.stiffness_enabled = 0;
    f->prm.fric_m = r.fric_m;
    init(&f->ref, &f->prm);
    set(&f->prm, "friction_drift.enabled", 1.0);
    set(&f->prm, "friction_drift.t_start_s", 0.1);
    set(&f->prm, "friction_drift.ramp_s", 0.2);
    set(&f->prm, "friction_drift.scale", 1.5);
    set(&f->prm, "friction_drift.hold_s", 0.1);
    set(&f->prm, "friction_drift.return_s", 0.2);
    init(&f->plant, &f->prm);
    memset(&f->in, 0, sizeof f->in);
    for (k = 1; k <= 8000; k++) {
        hd_plant_set_state(&f->plant, 0.0, w, 0.0, 0.0);
        hd_plant_set_state(&f->ref, 0.0, w, 0.0, 0.0);
        hd_plant_step(&f->plant, &f->in, DT);
        hd_plant_step(&f->ref, &f->in, DT);
        if (k % 100 == 0) {
            const double t = (double)(k - 1) * DT;
            double x = weight(k, 0.1, 0.2);
            double s, ratio;
            if (t > 0.4) x = t >= 0.6 ? 0.0 : 1.0 - (t - 0.4) / 0.2;
            s = 1.0 + 0.5 * x;
            ratio = f->plant.out.friction_motor_Nm / f->ref.out.friction_motor_Nm;
            assert_true(fabs(f->ref.out.friction_motor_Nm) > 0.05);
            /* 3e-3: the velocity moves within the period by an amount that depends on the friction */
            assert_true(fabs(ratio - s) < 3e-3);
            if (s == 1.5) seen_top = 1;
        }
    }
    assert_true(seen_top);
    /* back to cold (the Stribeck exponential's anchor history differs: round-off only) */
    assert_true(fabs(f->plant.out.friction_motor_Nm - f->ref.out.friction_motor_Nm)
                < 1e-9 * fabs(f->ref.out.friction_motor_Nm));
}

/* Default off: the drift keys at their defaults leave the run bit-identical. */
static void test_drifts_off_bit_identical(void **state)
{
    fixture *f = *state;
    hd_plant_params q;
    long k;
    hd_plant_defaults_reference(&q);
    init(&f->ref, &q);
    set(&q, "inertia_drift.scale", 2.0);     /* scales given, drifts off */
    set(&q, "stiffness_drift.scale", 0.8);
    set(&q, "gravity_drift.mgl_Nm", 5.0);
    set(&q, "friction_drift.return_s", 1.0);
    init(&f->plant, &q);
    memset(&f->in, 0, sizeof f->in);
    for (k = 0; k < 3000; k++) {
        f->in.current_cmd_A = 2.0 * sin(0.01 * (double)k);
        hd_plant_step(&f->plant, &f->in, DT);
        hd_plant_step(&f->ref, &f->in, DT);
        assert_memory_equal(&f->plant.out, &f->ref.out, sizeof f->plant.out);
    }
}

/* Every drift ramping at once on the reference axis, every effect on: the period's caches
 * (the end evaluation, the first RK stage taken from it) are kept where they stay right, so
 * a drifting axis costs one end evaluation per period like a fixed one, and its run agrees
 * to rounding (1e-12 of the peak) with the same run evaluated in full every period (caches
 * dropped before each step, as after a parameter change). */
static void test_drifts_keep_caches(void **state)
{
    fixture *f = *state;
    hd_plant_params q;
    const long n = 6000;
    double worst_w = 0.0, worst_th = 0.0, pk_w = 0.0, pk_th = 0.0;
    long k;
    hd_plant_defaults_reference(&q);
    q.cubic_enabled = 1;
    set(&q, "friction_drift.enabled", 1.0);
    set(&q, "friction_drift.ramp_s", 0.3);
    set(&q, "friction_drift.scale", 1.4);
    set(&q, "inertia_drift.enabled", 1.0);
    set(&q, "inertia_drift.t_start_s", 0.1);
    set(&q, "inertia_drift.ramp_s", 0.2);
    set(&q, "inertia_drift.scale", 2.0);
    set(&q, "stiffness_drift.enabled", 1.0);
    set(&q, "stiffness_drift.ramp_s", 0.4);
    set(&q, "stiffness_drift.scale", 0.8);
    set(&q, "gravity_drift.enabled", 1.0);
    set(&q, "gravity_drift.ramp_s", 0.4);
    set(&q, "gravity_drift.mgl_Nm", 8.0);
    init(&f->plant, &q);
    init(&f->ref, &q);
    memset(&f->in, 0, sizeof f->in);
    for (k = 0; k < n; k++) {
        f->in.current_cmd_A = 3.0 * sin(2.0 * 3.141592653589793 * 5.0 * (double)k * DT);
        f->ref.end_valid = 0;                   /* full evaluation of every stage */
        f->ref.k1_valid = 0;
        hd_plant_step(&f->plant, &f->in, DT);
        hd_plant_step(&f->ref, &f->in, DT);
        if (fabs(f->ref.out.motor_velocity_rad_s) > pk_w) pk_w = fabs(f->ref.out.motor_velocity_rad_s);
        if (fabs(f->ref.out.load_angle_rad) > pk_th) pk_th = fabs(f->ref.out.load_angle_rad);
        if (fabs(f->plant.out.motor_velocity_rad_s - f->ref.out.motor_velocity_rad_s) > worst_w)
            worst_w = fabs(f->plant.out.motor_velocity_rad_s - f->ref.out.motor_velocity_rad_s);
        if (fabs(f->plant.out.load_angle_rad - f->ref.out.load_angle_rad) > worst_th)
            worst_th = fabs(f->plant.out.load_angle_rad - f->ref.out.load_angle_rad);
    }
    printf("# every drift ramping: %.3f end evaluations per period (evaluated in full: %.3f); "
           "cached vs full: motor velocity %.2e of peak %.3g rad/s, load angle %.2e of peak %.3g rad\n",
           (double)f->plant.n_end_eval / (double)n, (double)f->ref.n_end_eval / (double)n, worst_w / pk_w, pk_w,
           worst_th / pk_th, pk_th);
    assert_true(pk_w > 1.0);
    assert_true(pk_th > 1e-3);
    assert_true(f->plant.n_end_eval <= n + 1);  /* one per period, and the first period's start */
    assert_true(worst_w / pk_w < 1e-12);
    assert_true(worst_th / pk_th < 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_inertia_drift, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stiffness_drift, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_gravity_drift_appears, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_friction_drift_return, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_drifts_off_bit_identical, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_drifts_keep_caches, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
