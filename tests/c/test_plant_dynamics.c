/*
 * test_plant_dynamics.c - verification of the simulated harmonic-drive axis:
 * torsional modes, locked-output stiffness and hysteresis, transmission error,
 * energy conservation and sub-step convergence (docs/plant.md, "Verification").
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
#include "hd_plant_preisach.h"

#define PI 3.141592653589793
#define ARCMIN 2.908882086657216e-4

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

static void init(fixture *f)
{
    char msg[200] = "";
    int rc = hd_plant_init(&f->plant, &f->prm, 1u, msg, sizeof msg);
    if (rc != 0) fprintf(stderr, "init: %s\n", msg);
    assert_int_equal(rc, 0);
    memset(&f->in, 0, sizeof f->in);
}

/* Frequency of free oscillation of the twist from its zero crossings (linear interpolation). */
static double twist_frequency(fixture *f, double dt, long steps)
{
    double prev = f->plant.out.twist_rad, prev_t = 0.0, first = -1.0, last = -1.0;
    long k, crossings = 0;
    hd_plant_step(&f->plant, &f->in, dt);
    prev = f->plant.out.twist_rad;
    prev_t = f->plant.out.t_s;
    for (k = 1; k < steps; k++) {
        const hd_plant_output *o = hd_plant_step(&f->plant, &f->in, dt);
        if ((prev < 0.0) != (o->twist_rad < 0.0)) {
            double tc = prev_t + (o->t_s - prev_t) * prev / (prev - o->twist_rad);
            if (first < 0.0) first = tc;
            last = tc;
            crossings++;
        }
        prev = o->twist_rad;
        prev_t = o->t_s;
    }
    assert_true(crossings > 10);
    return 0.5 * (double)(crossings - 1) / (last - first);
}

/* Free torsional oscillation of the two-mass model: resonance within 0.1 %. */
static void test_free_oscillation_resonance(void **state)
{
    fixture *f = *state;
    double K = f->prm.k1_Nm_per_rad, N = f->prm.ratio, jm = f->prm.jm_kgm2, jl = f->prm.jl_kgm2;
    double fr = sqrt(K * (1.0 / jl + 1.0 / (N * N * jm))) / (2.0 * PI), fm;
    init(f);
    /* zero momentum: th_l = -phi0 * (N^2 jm)/(N^2 jm + jl) style split not needed, both at rest */
    hd_plant_set_state(&f->plant, 0.0, 0.0, -1e-4, 0.0);
    fm = twist_frequency(f, 1e-4, 10000);
    printf("# resonance: closed form %.6f Hz, simulated %.6f Hz, error %.2e\n", fr, fm, fm / fr - 1.0);
    assert_true(fabs(fm / fr - 1.0) < 1e-3);
}

/* Anti-resonance sqrt(K/J_L): the load oscillating against a (practically) fixed motor. */
static void test_free_oscillation_antiresonance(void **state)
{
    fixture *f = *state;
    double K = f->prm.k1_Nm_per_rad, jl = f->prm.jl_kgm2, fa = sqrt(K / jl) / (2.0 * PI), fm, fl;
    f->prm.jm_kgm2 = 1e3;          /* N^2 J_m = 1e7 kg.m^2: the motor is a fixed wall */
    init(f);
    hd_plant_set_state(&f->plant, 0.0, 0.0, -1e-4, 0.0);
    fm = twist_frequency(f, 1e-4, 10000);
    printf("# anti-resonance: closed form %.6f Hz, simulated %.6f Hz, error %.2e\n", fa, fm, fm / fa - 1.0);
    assert_true(fabs(fm / fa - 1.0) < 1e-3);
    /* locked output (brake): motor-side mode sqrt(K/(N^2 J_m)) with the reference J_m */
    f->prm.jm_kgm2 = 8e-5;
    init(f);
    hd_plant_set_brake(&f->plant, 1);
    hd_plant_set_state(&f->plant, 1e-2, 0.0, 0.0, 0.0);
    fl = twist_frequency(f, 1e-4, 10000);
    fa = sqrt(K / (f->prm.ratio * f->prm.ratio * f->prm.jm_kgm2)) / (2.0 * PI);
    printf("# locked-output mode: closed form %.6f Hz, simulated %.6f Hz\n", fa, fl);
    assert_true(fabs(fl / fa - 1.0) < 1e-3);
    assert_true(f->plant.out.load_angle_rad == 0.0);
}

/* Drive the locked-output axis with output torque profile T(t) applied through the motor. */
static void hold_output_torque(fixture *f, double t_from, double t_to, double ramp_s, double hold_s)
{
    double dt = 1e-4, t;
    long k, n_r = (long)(ramp_s / dt), n_h = (long)(hold_s / dt);
    double gain = 1.0 / (f->prm.kt_Nm_per_A * f->prm.ratio);
    for (k = 0; k < n_r; k++) {
        double s = 0.5 - 0.5 * cos(PI * (double)(k + 1) / (double)n_r);
        t = t_from + (t_to - t_from) * s;
        f->in.current_cmd_A = t * gain;
        hd_plant_step(&f->plant, &f->in, dt);
    }
    f->in.current_cmd_A = t_to * gain;
    for (k = 0; k < n_h; k++) hd_plant_step(&f->plant, &f->in, dt);
}

/* Quasi-static locked-output torque: twist at T1, T2 and rated within 0.5 % of the three-slope curve. */
static void test_locked_output_three_slope(void **state)
{
    fixture *f = *state;
    hd_plant_params r;
    double phi1, phi2, phir, tw;
    hd_plant_defaults_reference(&r);
    f->prm.k1_Nm_per_rad = r.k1_Nm_per_rad;
    f->prm.k2_Nm_per_rad = r.k2_Nm_per_rad;
    f->prm.k3_Nm_per_rad = r.k3_Nm_per_rad;
    f->prm.damping_Nms_per_rad = 60.0;
    f->prm.current_loop_enabled = 1;
    init(f);
    hd_plant_set_brake(&f->plant, 1);
    phi1 = r.t1_Nm / r.k1_Nm_per_rad;
    phi2 = phi1 + (r.t2_Nm - r.t1_Nm) / r.k2_Nm_per_rad;
    phir = phi2 + (67.0 - r.t2_Nm) / r.k3_Nm_per_rad;

    hold_output_torque(f, 0.0, r.t1_Nm, 0.3, 0.3);
    tw = f->plant.out.twist_rad;
    printf("# twist at T1: %.4f arcmin (three-slope %.4f), error %.2e\n", tw / ARCMIN, phi1 / ARCMIN, tw / phi1 - 1.0);
    assert_true(fabs(tw / phi1 - 1.0) < 5e-3);
    hold_output_torque(f, r.t1_Nm, r.t2_Nm, 0.3, 0.3);
    tw = f->plant.out.twist_rad;
    printf("# twist at T2: %.4f arcmin (three-slope %.4f), error %.2e\n", tw / ARCMIN, phi2 / ARCMIN, tw / phi2 - 1.0);
    assert_true(fabs(tw / phi2 - 1.0) < 5e-3);
    hold_output_torque(f, r.t2_Nm, -67.0, 0.6, 0.3);
    tw = f->plant.out.twist_rad;
    printf("# twist at -67 N.m: %.4f arcmin (three-slope %.4f)\n", tw / ARCMIN, -phir / ARCMIN);
    assert_true(fabs(tw / -phir - 1.0) < 5e-3);
}

/* Static (spring + hysteresis) torque of the locked axis, without the damping term. */
static double static_torque(const fixture *f)
{
    const hd_plant *p = &f->plant;
    double phi = p->out.twist_rad, k1 = p->prm.k1_Nm_per_rad, k2 = p->prm.k2_Nm_per_rad, k3 = p->prm.k3_Nm_per_rad;
    double s1 = phi > p->phi1 ? p->phi1 : (phi < -p->phi1 ? -p->phi1 : phi);
    double s2 = phi > p->phi2 ? p->phi2 : (phi < -p->phi2 ? -p->phi2 : phi);
    return k3 * phi + (k1 - k2) * s1 + (k2 - k3) * s2 + p->out.hysteresis_torque_Nm;
}

/* Width of the torque-twist loop at zero torque for a slow +-67 N.m sine cycle. */
static double hysteresis_width(fixture *f)
{
    double dt = 1e-4, amp = 67.0, fq = 0.25, gain = 1.0 / (f->prm.kt_Nm_per_A * f->prm.ratio);
    double prev_T = 0.0, prev_phi = 0.0, up = NAN, down = NAN;
    long k, n = (long)(2.0 / fq / dt);
    hd_plant_set_brake(&f->plant, 1);
    for (k = 0; k < n; k++) {
        double t = (double)(k + 1) * dt, T, phi;
        f->in.current_cmd_A = amp * sin(2.0 * PI * fq * t) * gain;
        hd_plant_step(&f->plant, &f->in, dt);
        T = static_torque(f);
        phi = f->plant.out.twist_rad;
        if (k > n / 2 && prev_T > 0.0 && T <= 0.0) down = prev_phi + (phi - prev_phi) * prev_T / (prev_T - T);
        if (k > n / 2 && prev_T < 0.0 && T >= 0.0) up = prev_phi + (phi - prev_phi) * prev_T / (prev_T - T);
        prev_T = T;
        prev_phi = phi;
    }
    assert_false(isnan(up));
    assert_false(isnan(down));
    return down - up;
}

static void set_reference_stiffness(fixture *f)
{
    hd_plant_params r;
    hd_plant_defaults_reference(&r);
    f->prm.k1_Nm_per_rad = r.k1_Nm_per_rad;
    f->prm.k2_Nm_per_rad = r.k2_Nm_per_rad;
    f->prm.k3_Nm_per_rad = r.k3_Nm_per_rad;
    f->prm.damping_Nms_per_rad = r.damping_Nms_per_rad;
}

/* Maxwell-slip: hysteresis loss = 2*sum(w)/K1 = configured 1 arcmin, within 2 %. */
static void test_hysteresis_loss_maxwell(void **state)
{
    fixture *f = *state;
    double loss = 1.0 * ARCMIN, w;
    int i;
    set_reference_stiffness(f);
    f->prm.maxwell_enabled = 1;
    f->prm.maxwell_n = 4;
    for (i = 0; i < 4; i++) {
        f->prm.maxwell_w_Nm[i] = 0.25 * 0.5 * loss * f->prm.k1_Nm_per_rad;
        f->prm.maxwell_k_Nm_per_rad[i] = f->prm.maxwell_w_Nm[i] / ((double)(i + 1) * 1e-4);
    }
    init(f);
    w = hysteresis_width(f);
    printf("# Maxwell-slip hysteresis loss: %.4f arcmin (configured %.4f), error %.2e\n", w / ARCMIN, loss / ARCMIN,
           w / loss - 1.0);
    assert_true(fabs(w / loss - 1.0) < 0.02);
}

/* Preisach: loss from the operator's own descending branch (T_el(phi) + y(phi) = 0), within 2 %. */
static void test_hysteresis_loss_preisach(void **state)
{
    fixture *f = *state;
    hd_plant_params r;
    double w, phi = 0.0, umax, y, expect;
    int it;
    hd_plant_defaults_reference(&r);
    set_reference_stiffness(f);
    f->prm.preisach_enabled = 1;
    f->prm.preisach_u_max_rad = r.preisach_u_max_rad;
    f->prm.preisach_t_sat_Nm = 4.0;
    f->prm.preisach_r0_rad = r.preisach_r0_rad;
    f->prm.preisach_s_rad = r.preisach_s_rad;
    init(f);
    umax = f->prm.preisach_u_max_rad;
    /* descending branch from positive saturation: P = t_sat - 2 E(u_max, u),
     * T_h = P_mean - P with P_mean = E(u, -u_max) - E(u_max, u), so
     * T_h = E(u, -u_max) + E(u_max, u) - t_sat; zero torque where K1*phi + T_h(phi) = 0 */
    for (it = 0; it < 100; it++) {
        y = f->prm.preisach_t_sat_Nm - hd_preisach_E(f->plant.everett, umax, phi, -umax)
            - hd_preisach_E(f->plant.everett, umax, umax, phi);
        phi = y / f->prm.k1_Nm_per_rad;
    }
    expect = 2.0 * phi;
    w = hysteresis_width(f);
    printf("# Preisach hysteresis loss: %.4f arcmin (operator %.4f), error %.2e\n", w / ARCMIN, expect / ARCMIN,
           w / expect - 1.0);
    assert_true(expect > 0.0);
    assert_true(fabs(w / expect - 1.0) < 0.02);
}

/* Velocity-controlled motor (test-side PI) at constant output speed. */
typedef struct { double kp, ki, integ; } vel_pi;

static double pi_step(vel_pi *c, double err, double dt)
{
    c->integ += c->ki * err * dt;
    return c->kp * err + c->integ;
}

/* TE: load - motor/N over one output revolution shows the configured harmonics within 1 %. */
static void test_transmission_error_harmonics(void **state)
{
    fixture *f = *state;
    hd_plant_params r;
    const double dt = 1e-3, w_out = 4.0 * PI / 180.0;
    double N, w_m, sum_c[2][HD_PLANT_MAX_HARM], sum_s[2][HD_PLANT_MAX_HARM], span = 0.0, th0, prev_th = 0.0, prev_e = 0.0;
    double prev_thl = 0.0;
    vel_pi c = { 0.05, 2.0, 0.0 };
    long k;
    int j, started = 0;
    hd_plant_defaults_reference(&r);
    set_reference_stiffness(f);
    f->prm.te_enabled = 1;
    memcpy(f->prm.te_wg_order, r.te_wg_order, sizeof r.te_wg_order);
    memcpy(f->prm.te_wg_amp_rad, r.te_wg_amp_rad, sizeof r.te_wg_amp_rad);
    memcpy(f->prm.te_wg_phase_rad, r.te_wg_phase_rad, sizeof r.te_wg_phase_rad);
    memcpy(f->prm.te_out_order, r.te_out_order, sizeof r.te_out_order);
    memcpy(f->prm.te_out_amp_rad, r.te_out_amp_rad, sizeof r.te_out_amp_rad);
    memcpy(f->prm.te_out_phase_rad, r.te_out_phase_rad, sizeof r.te_out_phase_rad);
    f->prm.substeps = 2;
    init(f);
    N = f->prm.ratio;
    w_m = w_out * N;
    memset(sum_c, 0, sizeof sum_c);
    memset(sum_s, 0, sizeof sum_s);
    th0 = 0.0;
    for (k = 0; k < (long)(100.0 / dt); k++) {
        const hd_plant_output *o;
        f->in.current_cmd_A = pi_step(&c, w_m - f->plant.w_m, dt) / f->prm.kt_Nm_per_A;
        o = hd_plant_step(&f->plant, &f->in, dt);
        if (!started && o->t_s >= 2.0) {       /* settle, then integrate over exactly one output revolution */
            started = 1;
            th0 = o->load_angle_rad;
            prev_thl = o->load_angle_rad;
            prev_th = o->motor_angle_rad;
            prev_e = o->load_angle_rad - o->motor_angle_rad / N;
            continue;
        }
        if (started) {
            double e = o->load_angle_rad - o->motor_angle_rad / N, thm = o->motor_angle_rad, thl = o->load_angle_rad;
            double dth = thm - prev_th;
            if (thl - th0 >= 2.0 * PI) break;
            for (j = 0; j < HD_PLANT_MAX_HARM; j++) {   /* trapezoid in motor angle */
                double n = r.te_wg_order[j], m = r.te_out_order[j];
                if (n != 0.0) {
                    sum_c[0][j] += 0.5 * dth * (e * cos(n * thm) + prev_e * cos(n * prev_th));
                    sum_s[0][j] += 0.5 * dth * (e * sin(n * thm) + prev_e * sin(n * prev_th));
                }
                if (m != 0.0) {
                    sum_c[1][j] += 0.5 * (thl - prev_thl) * (e * cos(m * thl) + prev_e * cos(m * prev_thl));
                    sum_s[1][j] += 0.5 * (thl - prev_thl) * (e * sin(m * thl) + prev_e * sin(m * prev_thl));
                }
            }
            span += dth;
            prev_th = thm;
            prev_thl = thl;
            prev_e = e;
        }
    }
    assert_true(started);
    for (j = 0; j < HD_PLANT_MAX_HARM; j++) {
        int l;
        for (l = 0; l < 2; l++) {
            double n = l == 0 ? r.te_wg_order[j] : r.te_out_order[j];
            double a = l == 0 ? r.te_wg_amp_rad[j] : r.te_out_amp_rad[j];
            double norm = l == 0 ? span : 2.0 * PI;
            double amp, w, K = f->prm.k1_Nm_per_rad, cdamp = f->prm.damping_Nms_per_rad, jl = f->prm.jl_kgm2, H;
            if (n == 0.0 || a == 0.0) continue;
            amp = 2.0 / norm * sqrt(sum_c[l][j] * sum_c[l][j] + sum_s[l][j] * sum_s[l][j]);
            /* the load follows the kinematic error through spring and inertia: |H| at the line frequency */
            w = n * (l == 0 ? w_m : w_out);
            H = sqrt((K * K + cdamp * cdamp * w * w) / ((K - jl * w * w) * (K - jl * w * w) + cdamp * cdamp * w * w));
            printf("# TE %s order %g: %.5f arcmin, configured %.5f (x|H| %.5f), error %.2e\n", l == 0 ? "WG" : "output",
                   n, amp / ARCMIN, a / ARCMIN, H, amp / (a * H) - 1.0);
            assert_true(fabs(amp / (a * H) - 1.0) < 0.01);
        }
    }
}

/* Energy: conservative axis, no dissipation.  (a) smooth forces (cubic stiffness, TE, cogging,
 * gravity), 1e6 steps at the default 2 RK4 sub-steps per 100 us; (b) the three-slope spring, whose knees
 * are non-smooth and cost RK4 its order at each crossing: 2e5 steps at the default 2 sub-steps. */
static double energy_run(fixture *f, long steps)
{
    double e0, e, maxdev = 0.0;
    long k;
    init(f);
    /* pre-twist beyond T2 so the oscillation crosses both knees, plus a slow rotation */
    hd_plant_set_state(&f->plant, 0.0, 5.0, -2e-3, 0.05);
    e0 = hd_plant_energy(&f->plant);
    for (k = 0; k < steps; k++) {
        hd_plant_step(&f->plant, &f->in, 1e-4);
        if ((k & 255) == 0) {
            e = fabs(hd_plant_energy(&f->plant) - e0);
            if (e > maxdev) maxdev = e;
        }
    }
    e = fabs(hd_plant_energy(&f->plant) - e0);
    if (e > maxdev) maxdev = e;
    return maxdev / e0;
}

static void test_energy_conservation(void **state)
{
    fixture *f = *state;
    hd_plant_params r;
    double rel;
    const double bound_smooth = 2e-5, bound_knees = 1e-3;
    hd_plant_defaults_reference(&r);
    f->prm.stiffness_enabled = 0;
    f->prm.cubic_enabled = 1;
    f->prm.cubic_k1_Nm_per_rad = r.cubic_k1_Nm_per_rad;
    f->prm.cubic_k3_Nm_per_rad3 = r.cubic_k3_Nm_per_rad3;
    f->prm.damping_Nms_per_rad = 0.0;
    f->prm.te_enabled = 1;
    memcpy(f->prm.te_wg_order, r.te_wg_order, sizeof r.te_wg_order);
    memcpy(f->prm.te_wg_amp_rad, r.te_wg_amp_rad, sizeof r.te_wg_amp_rad);
    memcpy(f->prm.te_out_order, r.te_out_order, sizeof r.te_out_order);
    memcpy(f->prm.te_out_amp_rad, r.te_out_amp_rad, sizeof r.te_out_amp_rad);
    f->prm.cogging_enabled = 1;
    memcpy(f->prm.cog_order, r.cog_order, sizeof r.cog_order);
    memcpy(f->prm.cog_amp_Nm, r.cog_amp_Nm, sizeof r.cog_amp_Nm);
    f->prm.gravity_enabled = 1;
    f->prm.substeps = 2;
    rel = energy_run(f, 1000000);
    printf("# energy, smooth conservative axis, 1e6 steps x 2 sub-steps: max |E - E0|/E0 = %.2e (bound %.0e)\n",
           rel, bound_smooth);
    assert_true(rel < bound_smooth);

    f->prm.stiffness_enabled = 1;
    f->prm.cubic_enabled = 0;
    set_reference_stiffness(f);
    f->prm.damping_Nms_per_rad = 0.0;
    f->prm.substeps = 2;
    rel = energy_run(f, 200000);
    printf("# energy, three-slope spring + TE + cogging + gravity, 2e5 steps x 2 sub-steps: "
           "max |E - E0|/E0 = %.2e (bound %.0e)\n", rel, bound_knees);
    assert_true(rel < bound_knees);
}

/* Convergence: reference axis, torque step; halving the sub-step changes the response < tolerance. */
static double step_response(const hd_plant_params *prm, int substeps, double *out, long n)
{
    hd_plant *p = calloc(1, sizeof *p);
    hd_plant_params q = *prm;
    hd_plant_input in;
    char msg[200];
    double peak = 0.0;
    long k;
    assert_non_null(p);
    q.substeps = substeps;
    assert_int_equal(hd_plant_init(p, &q, 7u, msg, sizeof msg), 0);
    memset(&in, 0, sizeof in);
    for (k = 0; k < n; k++) {
        in.current_cmd_A = k >= 100 ? 3.0 : 0.0;
        hd_plant_step(p, &in, 1e-4);
        out[k] = p->out.load_angle_rad;
        if (fabs(out[k]) > peak) peak = fabs(out[k]);
    }
    free(p);
    return peak;
}

static void test_substep_convergence(void **state)
{
    fixture *f = *state;
    enum { N = 3000 };
    static double a[N], b[N], c[N];
    double peak, d12 = 0.0, d24 = 0.0;
    long k;
    const double tol = 1e-4;
    hd_plant_defaults_reference(&f->prm);
    peak = step_response(&f->prm, 1, a, N);
    (void)step_response(&f->prm, 2, b, N);
    (void)step_response(&f->prm, 4, c, N);
    for (k = 0; k < N; k++) {
        if (fabs(a[k] - b[k]) > d12) d12 = fabs(a[k] - b[k]);
        if (fabs(b[k] - c[k]) > d24) d24 = fabs(b[k] - c[k]);
    }
    printf("# convergence (reference axis, 3 A step, 0.3 s): peak load angle %.4e rad; max |h - h/2|: "
           "1->2 sub-steps %.3e (rel %.2e), 2->4 sub-steps %.3e (rel %.2e), tolerance %.0e\n",
           peak, d12, d12 / peak, d24, d24 / peak, tol);
    assert_true(peak > 1e-3);
    assert_true(d24 / peak < tol);
    assert_true(d12 / peak < 10.0 * tol);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_free_oscillation_resonance, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_free_oscillation_antiresonance, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_locked_output_three_slope, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_hysteresis_loss_maxwell, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_hysteresis_loss_preisach, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_transmission_error_harmonics, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_energy_conservation, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_substep_convergence, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
