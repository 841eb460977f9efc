/*
 * test_plant_friction.c - simulated axis: friction (stick below breakaway, LuGre
 * steady state = Stribeck curve), seeds, parameter table, faults.
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

typedef struct {
    hd_plant_params prm;
    hd_plant plant;
    hd_plant_input in;
} fixture;

static int setUp(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (f == NULL) return -1;
    hd_plant_defaults_minimal(&f->prm);
    *state = f;
    return 0;
}

static int tearDown(void **state)
{
    free(*state);
    return 0;
}

static void init(fixture *f, uint64_t seed)
{
    char msg[200] = "";
    int rc = hd_plant_init(&f->plant, &f->prm, seed, msg, sizeof msg);
    if (rc != 0) fprintf(stderr, "init: %s\n", msg);
    assert_int_equal(rc, 0);
    memset(&f->in, 0, sizeof f->in);
}

/* Motor alone (no gear spring) with the reference motor-side friction. */
static void motor_alone(fixture *f, int lugre)
{
    hd_plant_params r;
    hd_plant_defaults_reference(&r);
    f->prm.stiffness_enabled = 0;
    f->prm.fric_m = r.fric_m;
    f->prm.fric_m.lugre_enabled = lugre;
    f->prm.current_loop_enabled = 1;
}

/* Ramp the motor torque from its present value to tq in 0.2 s (quasi-static), then hold. */
static double run_torque(fixture *f, double tq, double seconds)
{
    long k, n = (long)(seconds / 1e-4), nr = 2000;
    double t0 = f->in.torque_cmd_Nm;
    for (k = 0; k < n; k++) {
        f->in.torque_cmd_Nm = k < nr ? t0 + (tq - t0) * (double)(k + 1) / (double)nr : tq;
        hd_plant_step(&f->plant, &f->in, 1e-4);
    }
    return f->plant.out.motor_angle_rad;
}

/* Below breakaway the axis does not slide (LuGre: presliding only, no creep; static: exactly still). */
static void test_no_sliding_below_breakaway(void **state)
{
    fixture *f = *state;
    int lugre;
    for (lugre = 1; lugre >= 0; lugre--) {
        double a1, a2, a3, fs;
        int dir;
        for (dir = 1; dir >= -1; dir -= 2) {
            motor_alone(f, lugre);
            init(f, 1u);
            fs = dir > 0 ? f->prm.fric_m.fs_pos_Nm : f->prm.fric_m.fs_neg_Nm;
            a1 = run_torque(f, 0.95 * fs * dir, 0.5);
            a2 = run_torque(f, 0.95 * fs * dir, 0.5);
            printf("# %s, %+.3f N.m (95 %% of breakaway): displacement %.3e rad, creep in the last 0.5 s %.3e rad\n",
                   lugre ? "LuGre" : "static", 0.95 * fs * dir, a2, a2 - a1);
            if (lugre) {
                /* presliding only: x = -ln(1 - F/Fs)*Fs/sigma0 = 3.0*Fs/sigma0 at 95 % */
                assert_true(fabs(a2) < 4.0 * fs / f->prm.fric_m.sigma0_Nm_per_rad);
                assert_true(fabs(a2 - a1) < 1e-9);
            } else {
                assert_true(a2 == 0.0);
            }
            a3 = run_torque(f, 1.05 * fs * dir, 0.5);
            printf("# %s, %+.3f N.m (105 %%): displacement after 0.5 s %.3e rad\n", lugre ? "LuGre" : "static",
                   1.05 * fs * dir, a3);
            assert_true(a3 * dir > 0.1);
        }
    }
}

/* LuGre steady-state friction equals the Stribeck curve within 1 % over three decades of speed. */
static double stribeck(const hd_plant_friction_params *fr, double v)
{
    double fc = v < 0.0 ? fr->fc_neg_Nm : fr->fc_pos_Nm, fs = v < 0.0 ? fr->fs_neg_Nm : fr->fs_pos_Nm;
    double g = fc + (fs - fc) * exp(-pow(fabs(v) / fr->vs_rad_s, fr->delta));
    return (v < 0.0 ? -g : g) + fr->viscous_Nms_per_rad * v;
}

static void check_stribeck_side(fixture *f, int load_side)
{
    const hd_plant_friction_params *fr = load_side ? &f->prm.fric_l : &f->prm.fric_m;
    double J = load_side ? f->prm.jl_kgm2 : f->prm.jm_kgm2, vs = fr->vs_rad_s, worst = 0.0;
    int i, dir;
    for (dir = 1; dir >= -1; dir -= 2) {
        for (i = 0; i < 7; i++) {
            double vref = dir * vs * 0.01 * pow(10.0, 0.5 * (double)i);   /* vs/100 ... 10 vs */
            double kp = J * 2.0 * 3.141592653589793 * 300.0, ki = kp * 2.0 * 3.141592653589793 * 30.0, integ = 0.0, sf = 0.0, sv = 0.0, err;
            long k, n = 0, steps = (long)(fmax(0.6, 40.0 * fr->fs_pos_Nm / (fr->sigma0_Nm_per_rad * fabs(vref))) / 1e-4);
            init(f, 1u);
            for (k = 0; k < steps; k++) {
                double v = load_side ? f->plant.w_l : f->plant.w_m, u;
                integ += ki * (vref - v) * 1e-4;
                u = kp * (vref - v) + integ;
                if (load_side) f->in.load_torque_Nm = u; else f->in.torque_cmd_Nm = u;
                hd_plant_step(&f->plant, &f->in, 1e-4);
                if (k >= steps - 2000) {
                    sf += load_side ? f->plant.out.friction_load_Nm : f->plant.out.friction_motor_Nm;
                    sv += load_side ? f->plant.out.load_velocity_rad_s : f->plant.out.motor_velocity_rad_s;
                    n++;
                }
            }
            sf /= (double)n;
            sv /= (double)n;
            err = sf / stribeck(fr, sv) - 1.0;
            if (fabs(err) > worst) worst = fabs(err);
            if (fabs(sv / vref - 1.0) >= 1e-3 || fabs(err) >= 0.01)
                printf("# %s side v_ref %.4g: mean v %.6g, friction %.6g, Stribeck %.6g\n", load_side ? "load" : "motor",
                       vref, sv, sf, stribeck(fr, sv));
            assert_true(fabs(sv / vref - 1.0) < 1e-3);
            assert_true(fabs(err) < 0.01);
        }
    }
    printf("# LuGre steady state vs Stribeck, %s side, v = +-%.3g ... +-%.3g rad/s: worst error %.2e\n",
           load_side ? "load" : "motor", vs * 0.01, vs * 10.0, worst);
}

static void test_lugre_steady_state_stribeck(void **state)
{
    fixture *f = *state;
    hd_plant_params r;
    hd_plant_defaults_reference(&r);
    f->prm.stiffness_enabled = 0;        /* motor and load decoupled: each side alone */
    f->prm.fric_m = r.fric_m;
    f->prm.fric_l = r.fric_l;
    f->prm.current_loop_enabled = 0;     /* the test's velocity loop acts directly on the torque */
    check_stribeck_side(f, 0);
    check_stribeck_side(f, 1);
}

/* [friction_drift]: the friction at a fixed sliding velocity follows 1 -> 1.3 linearly
 * over the ramp (levels and viscous term) against the same run without drift, and is
 * untouched before the ramp. */
static void test_friction_drift_ramp(void **state)
{
    fixture *f = *state;
    hd_plant ref;
    char msg[200];
    const double w = 10.0;
    long k;
    motor_alone(f, 0);
    f->prm.current_loop_enabled = 0;
    assert_int_equal(hd_plant_init(&ref, &f->prm, 1, msg, sizeof msg), 0);
    f->prm.drift_enabled = 1;
    f->prm.drift_t_start_s = 0.5;
    f->prm.drift_ramp_s = 1.0;
    f->prm.drift_scale = 1.3;
    init(f, 1);
    for (k = 1; k <= 25000; k++) {
        hd_plant_set_state(&f->plant, 0.0, w, 0.0, 0.0);
        hd_plant_set_state(&ref, 0.0, w, 0.0, 0.0);
        hd_plant_step(&f->plant, &f->in, 1e-4);
        hd_plant_step(&ref, &f->in, 1e-4);
        if (k % 2500 == 0) {
            /* the scale in force during the period that ended at t = k 1e-4 s (set at its start) */
            const double x = ((double)(k - 1) * 1e-4 - 0.5) / 1.0;
            const double s = 1.0 + 0.3 * (x <= 0.0 ? 0.0 : (x >= 1.0 ? 1.0 : x));
            const double r = f->plant.out.friction_motor_Nm / ref.out.friction_motor_Nm;
            assert_true(fabs(ref.out.friction_motor_Nm) > 0.07);
            assert_true(fabs(r - s) < 1e-3);
            if (x <= 0.0) {
                assert_true(r == 1.0);
            }
        }
    }
}

/* Same seed -> identical run (bit for bit); different seed -> different noise, same physics. */
static void run_ref(hd_plant *p, uint64_t seed, hd_plant_output *log, long n)
{
    hd_plant_params q;
    hd_plant_input in;
    char msg[200];
    long k;
    hd_plant_defaults_reference(&q);
    assert_int_equal(hd_plant_init(p, &q, seed, msg, sizeof msg), 0);
    memset(&in, 0, sizeof in);
    for (k = 0; k < n; k++) {
        in.current_cmd_A = 2.0 * sin(0.01 * (double)k);
        log[k] = *hd_plant_step(p, &in, 1e-4);
    }
}

static void test_seeds(void **state)
{
    fixture *f = *state;
    enum { N = 2000 };
    static hd_plant_output a[N], b[N], c[N];
    long k, diff_enc = 0, diff_gyro = 0, diff_i = 0;
    run_ref(&f->plant, 42u, a, N);
    run_ref(&f->plant, 42u, b, N);
    run_ref(&f->plant, 43u, c, N);
    assert_memory_equal(a, b, sizeof a);
    for (k = 0; k < N; k++) {
        diff_enc += a[k].enc_load_count != c[k].enc_load_count;
        diff_gyro += a[k].gyro_rad_s != c[k].gyro_rad_s;
        diff_i += a[k].current_meas_A != c[k].current_meas_A;
        /* noise never feeds back into the true states */
        assert_true(a[k].load_angle_rad == c[k].load_angle_rad);
        assert_true(a[k].motor_velocity_rad_s == c[k].motor_velocity_rad_s);
    }
    printf("# seeds 42 vs 43: %ld/%d output-encoder, %ld gyro, %ld current samples differ\n", diff_enc, N, diff_gyro,
           diff_i);
    assert_true(diff_enc > N / 4);
    assert_true(diff_gyro > N / 2);
    assert_true(diff_i > N / 2);
}

/* Parameter table: every key settable and readable, unknown keys and bad values refused. */
static void test_param_table(void **state)
{
    fixture *f = *state;
    size_t i, j, n = hd_plant_param_count();
    double v;
    char msg[200];
    assert_true(n > 100);
    for (i = 0; i < n; i++) {
        const hd_plant_param_desc *d = hd_plant_param_at(i);
        assert_non_null(d);
        assert_non_null(strchr(d->name, '.'));
        assert_true(d->offset < sizeof(hd_plant_params));
        for (j = i + 1; j < n; j++) {
            assert_string_not_equal(d->name, hd_plant_param_at(j)->name);
            assert_true(d->offset != hd_plant_param_at(j)->offset);
        }
    }
    assert_null(hd_plant_param_at(n));
    assert_int_equal(hd_plant_param_set(&f->prm, "stiffness.k1_Nm_per_rad", 2.5e4), HD_PLANT_OK);
    assert_int_equal(hd_plant_param_get(&f->prm, "stiffness.k1_Nm_per_rad", &v), HD_PLANT_OK);
    assert_true(v == 2.5e4 && f->prm.k1_Nm_per_rad == 2.5e4);
    assert_int_equal(hd_plant_param_set(&f->prm, "hysteresis_maxwell.e3_w_Nm", 1.5), HD_PLANT_OK);
    assert_true(f->prm.maxwell_w_Nm[2] == 1.5);
    assert_int_equal(hd_plant_param_set(&f->prm, "friction_load.sigma0_Nm_per_rad", 2e4), HD_PLANT_OK);
    assert_true(f->prm.fric_l.sigma0_Nm_per_rad == 2e4);
    assert_int_equal(hd_plant_param_set(&f->prm, "gyro.enabled", 1.0), HD_PLANT_OK);
    assert_int_equal(f->prm.gyro_enabled, 1);
    assert_int_equal(hd_plant_param_set(&f->prm, "integrator.substeps", 3.0), HD_PLANT_OK);
    assert_int_equal(f->prm.substeps, 3);
    assert_int_equal(hd_plant_param_set(&f->prm, "stiffness.k9_Nm_per_rad", 1.0), HD_PLANT_EUNKNOWN);
    assert_int_equal(hd_plant_param_set(&f->prm, "gyro.enabled", 0.5), HD_PLANT_ETYPE);
    assert_int_equal(hd_plant_param_set(&f->prm, "integrator.substeps", 2.5), HD_PLANT_ETYPE);
    assert_int_equal(hd_plant_param_set(&f->prm, "integrator.substeps", 0.0), HD_PLANT_ERANGE);
    assert_int_equal(hd_plant_param_set(&f->prm, "motor.jm_kgm2", -1.0), HD_PLANT_ERANGE);
    assert_int_equal(hd_plant_param_set(&f->prm, "motor.jm_kgm2", NAN), HD_PLANT_ETYPE);
    /* inconsistent set refused by init with one message line */
    f->prm.t2_Nm = 1.0;
    f->prm.t1_Nm = 14.0;
    msg[0] = '\0';
    assert_int_equal(hd_plant_init(&f->plant, &f->prm, 1u, msg, sizeof msg), HD_PLANT_EINVAL);
    assert_non_null(strstr(msg, "t2_Nm"));
}

/* Fault hooks and the output brake. */
static void test_faults_and_brake(void **state)
{
    fixture *f = *state;
    const hd_plant_output *o;
    int64_t c0;
    int k;
    init(f, 1u);
    hd_plant_set_brake(&f->plant, 1);
    f->in.current_cmd_A = 5.0;
    for (k = 0; k < 1000; k++) o = hd_plant_step(&f->plant, &f->in, 1e-4);
    o = &f->plant.out;
    assert_true(o->load_angle_rad == 0.0 && o->brake_engaged == 1);
    assert_true(o->twist_rad > 0.0);
    hd_plant_set_brake(&f->plant, 0);
    f->in.current_cmd_A = 0.0;
    c0 = hd_plant_step(&f->plant, &f->in, 1e-4)->enc_load_count;
    hd_plant_fault_encoder_glitch(&f->plant, HD_PLANT_ENC_LOAD, 5000);
    o = hd_plant_step(&f->plant, &f->in, 1e-4);
    assert_true(llabs(o->enc_load_count - c0 - 5000) < 200);
    o = hd_plant_step(&f->plant, &f->in, 1e-4);
    assert_true(llabs(o->enc_load_count - c0) < 200);
    hd_plant_fault_encoder_dropout(&f->plant, HD_PLANT_ENC_MOTOR, 3);
    c0 = f->plant.out.enc_motor_count;
    for (k = 0; k < 3; k++) {
        o = hd_plant_step(&f->plant, &f->in, 1e-4);
        assert_int_equal(o->enc_motor_valid, 0);
        assert_true(o->enc_motor_count == c0);
    }
    o = hd_plant_step(&f->plant, &f->in, 1e-4);
    assert_int_equal(o->enc_motor_valid, 1);
    hd_plant_fault_current_limit(&f->plant, 2.0);
    f->in.current_cmd_A = 10.0;
    o = hd_plant_step(&f->plant, &f->in, 1e-4);
    assert_int_equal(o->current_saturated, 1);
    assert_true(fabs(o->current_A - 2.0) < 1e-12);
    hd_plant_fault_current_limit(&f->plant, -1.0);
    f->in.current_cmd_A = 25.0;                      /* beyond the 20 A peak */
    o = hd_plant_step(&f->plant, &f->in, 1e-4);
    assert_true(o->current_saturated && fabs(o->current_A - 20.0) < 1e-12);
    /* load torque step: the free load accelerates at T/J_total in the rigid limit */
    init(f, 1u);
    hd_plant_fault_load_step(&f->plant, 5.0);
    for (k = 0; k < 2000; k++) o = hd_plant_step(&f->plant, &f->in, 1e-4);
    {
        double jt = f->prm.jl_kgm2 + f->prm.ratio * f->prm.ratio * f->prm.jm_kgm2;
        double expect = 0.5 * 5.0 / jt * 0.2 * 0.2;
        assert_true(fabs(o->load_angle_rad / expect - 1.0) < 0.01);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_no_sliding_below_breakaway, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_lugre_steady_state_stribeck, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_seeds, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_param_table, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_friction_drift_ramp, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_faults_and_brake, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
