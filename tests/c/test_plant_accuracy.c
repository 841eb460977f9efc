/*
 * test_plant_accuracy.c - simulated axis: the fast evaluation paths against libm and
 * the one-sub-step integrator against a reference run with 16 sub-steps, every effect on
 * (docs/plant.md, "Integrator" and "Verification").
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

#define PI 3.14159265358979323846

static hd_plant *new_plant(const hd_plant_params *prm, uint64_t seed)
{
    hd_plant *p = calloc(1, sizeof *p);
    char msg[200] = "";
    int rc;
    assert_non_null(p);
    rc = hd_plant_init(p, prm, seed, msg, sizeof msg);
    if (rc != 0) fprintf(stderr, "init: %s\n", msg);
    assert_int_equal(rc, 0);
    return p;
}

/* The reference axis with every effect on (cubic stiffness too) and 0.5 deg base rocking at 1 Hz. */
static void every_effect(hd_plant_params *prm)
{
    hd_plant_defaults_reference(prm);
    prm->cubic_enabled = 1;
    prm->base_enabled = 1;
    prm->base_amp_rad = 0.5 * PI / 180.0;
    prm->base_freq_Hz = 1.0;
}

/* Current command: rest, a 3 A step at 10 ms, then 1 A at 7 Hz on top (reversals). */
static double current_cmd(long k)
{
    const double t = (double)k * 1e-4;
    return k < 100 ? 0.0 : 3.0 + sin(2.0 * PI * 7.0 * t);
}

static void run_states(int substeps, long n, double *th_l, double *w_m)
{
    hd_plant_params prm;
    hd_plant_input in;
    hd_plant *p;
    long k;
    every_effect(&prm);
    prm.substeps = substeps;
    p = new_plant(&prm, 11u);
    memset(&in, 0, sizeof in);
    for (k = 0; k < n; k++) {
        in.current_cmd_A = current_cmd(k);
        hd_plant_step(p, &in, 1e-4);
        th_l[k] = p->out.load_angle_rad;
        w_m[k] = p->out.motor_velocity_rad_s;
    }
    free(p);
}

/* One RK4 sub-step per 100 us period (the default) against 16 sub-steps, every effect on:
 * the documented tolerance for one sub-step is 1e-3 of the peak. */
static void test_one_substep_vs_reference(void **state)
{
    enum { N = 5000 };
    static double a_th[N], a_w[N], r_th[N], r_w[N];
    double pk_th = 0.0, pk_w = 0.0, d_th = 0.0, d_w = 0.0;
    long k;
    (void)state;
    run_states(1, N, a_th, a_w);
    run_states(16, N, r_th, r_w);
    for (k = 0; k < N; k++) {
        if (fabs(r_th[k]) > pk_th) pk_th = fabs(r_th[k]);
        if (fabs(r_w[k]) > pk_w) pk_w = fabs(r_w[k]);
        if (fabs(a_th[k] - r_th[k]) > d_th) d_th = fabs(a_th[k] - r_th[k]);
        if (fabs(a_w[k] - r_w[k]) > d_w) d_w = fabs(a_w[k] - r_w[k]);
    }
    printf("# 1 vs 16 sub-steps, every effect on, 0.5 s: load angle max error %.3e rad (%.2e of peak %.3e), "
           "motor velocity %.3e rad/s (%.2e of peak %.3e)\n", d_th, d_th / pk_th, pk_th, d_w, d_w / pk_w, pk_w);
    assert_true(pk_th > 1e-2);
    assert_true(pk_w > 1.0);
    assert_true(d_th / pk_th < 1e-3);
    assert_true(d_w / pk_w < 1e-3);
}

/* Static friction map (no LuGre) on a spinning motor: the reported friction equals the
 * closed form Fc + (Fs - Fc) exp(-(v/vs)^2) + sigma2 v by libm at every period (the plant
 * takes the exponential from an anchor and a short series; it must not drift). */
static void test_stribeck_matches_libm(void **state)
{
    hd_plant_params prm, r;
    hd_plant_input in;
    hd_plant *p;
    const hd_plant_friction_params *f;
    double worst = 0.0;
    long k, n_cmp = 0;
    (void)state;
    hd_plant_defaults_minimal(&prm);
    hd_plant_defaults_reference(&r);
    prm.stiffness_enabled = 0;
    prm.fric_m = r.fric_m;
    prm.fric_m.lugre_enabled = 0;
    prm.current_loop_enabled = 1;
    p = new_plant(&prm, 3u);
    f = &prm.fric_m;
    memset(&in, 0, sizeof in);
    for (k = 0; k < 200000; k++) {
        /* slow torque sine: the motor sweeps through the Stribeck region both ways */
        const double tq = 0.14 * sin(2.0 * PI * 0.5 * (double)k * 1e-4);
        const hd_plant_output *o;
        double v, g, ref;
        in.current_cmd_A = tq / prm.kt_Nm_per_A;
        o = hd_plant_step(p, &in, 1e-4);
        v = o->motor_velocity_rad_s;
        if (v == 0.0) continue;                  /* stuck: friction balances the applied torque */
        g = v < 0.0 ? f->fc_neg_Nm + (f->fs_neg_Nm - f->fc_neg_Nm) * exp(-(v / f->vs_rad_s) * (v / f->vs_rad_s))
                    : f->fc_pos_Nm + (f->fs_pos_Nm - f->fc_pos_Nm) * exp(-(v / f->vs_rad_s) * (v / f->vs_rad_s));
        ref = (v < 0.0 ? -g : g) + f->viscous_Nms_per_rad * v;
        if (fabs(o->friction_motor_Nm - ref) / fabs(ref) > worst) worst = fabs(o->friction_motor_Nm - ref) / fabs(ref);
        n_cmp++;
    }
    printf("# Stribeck map vs libm over %ld moving periods: worst relative error %.2e\n", n_cmp, worst);
    assert_true(n_cmp > 100000);
    assert_true(worst < 1e-14);
    free(p);
}

/* TE and cogging over a long run at high motor speed (angles of hundreds of rad): the
 * harmonic sums from powers of one cos/sin equal the libm formulas, including a
 * non-integer order (its libm path) next to integer ones. */
static void harmonics_match_libm(long spin_periods, int with_non_integer, double min_angle)
{
    hd_plant_params prm;
    hd_plant_input in;
    hd_plant *p;
    double worst_cog = 0.0, worst_te = 0.0, amp_cog = 0.0, amp_te = 0.0;
    long k;
    int j;
    hd_plant_defaults_reference(&prm);
    prm.fric_m.enabled = 0;
    prm.fric_l.enabled = 0;
    prm.gravity_enabled = 0;
    if (with_non_integer) {
        prm.cog_order[2] = 2.5;
        prm.cog_amp_Nm[2] = 5e-4;
        prm.cog_phase_rad[2] = -0.7;
    }
    p = new_plant(&prm, 5u);
    for (j = 0; j < HD_PLANT_MAX_HARM; j++) {
        amp_cog += fabs(prm.cog_amp_Nm[j]);
        amp_te += fabs(prm.te_wg_amp_rad[j]) + fabs(prm.te_out_amp_rad[j]);
    }
    memset(&in, 0, sizeof in);
    for (k = 0; k < 100000; k++) {
        const hd_plant_output *o;
        double cog = 0.0, te = 0.0;
        in.current_cmd_A = k < spin_periods ? 1.0 : 0.0;  /* spin up (500: to ~40 rad/s), then coast */
        o = hd_plant_step(p, &in, 1e-4);
        for (j = 0; j < HD_PLANT_MAX_HARM; j++) {
            if (prm.cog_order[j] != 0.0)
                cog += prm.cog_amp_Nm[j] * sin(prm.cog_order[j] * o->motor_angle_rad + prm.cog_phase_rad[j]);
            if (prm.te_wg_order[j] != 0.0)
                te += prm.te_wg_amp_rad[j] * sin(prm.te_wg_order[j] * o->motor_angle_rad + prm.te_wg_phase_rad[j]);
            if (prm.te_out_order[j] != 0.0)
                te += prm.te_out_amp_rad[j] * sin(prm.te_out_order[j] * o->load_angle_rad + prm.te_out_phase_rad[j]);
        }
        if (fabs(o->cogging_torque_Nm - cog) > worst_cog) worst_cog = fabs(o->cogging_torque_Nm - cog);
        if (fabs(o->te_rad - te) > worst_te) worst_te = fabs(o->te_rad - te);
    }
    printf("# harmonics vs libm, motor at %.0f rad after 10 s at %.1f rad/s: cogging %.2e of its amplitude, TE %.2e\n",
           p->out.motor_angle_rad, p->out.motor_velocity_rad_s, worst_cog / amp_cog, worst_te / amp_te);
    assert_true(fabs(p->out.motor_angle_rad) > min_angle);
    /* angles of a few hundred rad carry ~1e-13 rad of rounding, times orders up to 72 */
    assert_true(worst_cog / amp_cog < 1e-10);
    assert_true(worst_te / amp_te < 1e-10);
    free(p);
}

static void test_harmonics_match_libm(void **state)
{
    (void)state;
    harmonics_match_libm(500, 1, 100.0);
}

/* The same at ~4 rad/s with integer orders only: 72 x the angle step stays below the
 * series' 0.125 rad range, so the evaluations take the Taylor series about an anchor (moved by
 * rotations, re-seeded from libm every 64 moves) instead of forming the powers. */
static void test_harmonics_rotated_match_libm(void **state)
{
    (void)state;
    harmonics_match_libm(50, 0, 20.0);
}

/* The RK stages and end evaluations take TE and cogging from Taylor series about an anchor
 * angle; with that switched off (h_rot_ok = 0, an internal flag) every evaluation forms the
 * powers of cos/sin theta again.  A spin-up through 0..~150 rad/s (offsets 72 * dtheta below
 * and above the series' 0.125 rad range, so both paths run) and reversals: both runs agree to
 * rounding (documented tolerance 1e-12 of the peak), and they are not bit-identical (the
 * series ran). */
static void test_stage_harmonics_rotation(void **state)
{
    hd_plant_params prm;
    hd_plant_input in;
    hd_plant *a, *b;
    double worst_th = 0.0, worst_w = 0.0, pk_th = 0.0, pk_w = 0.0;
    long k;
    (void)state;
    every_effect(&prm);
    a = new_plant(&prm, 4u);
    b = new_plant(&prm, 4u);
    b->h_rot_ok = 0;
    memset(&in, 0, sizeof in);
    for (k = 0; k < 20000; k++) {
        const double t = (double)k * 1e-4;
        in.current_cmd_A = k < 3000 ? 4.0 * sin(2.0 * PI * 3.0 * t) : (k < 6000 ? 6.0 : -2.0);
        hd_plant_step(a, &in, 1e-4);
        hd_plant_step(b, &in, 1e-4);
        if (fabs(b->out.motor_angle_rad) > pk_th) pk_th = fabs(b->out.motor_angle_rad);
        if (fabs(b->out.motor_velocity_rad_s) > pk_w) pk_w = fabs(b->out.motor_velocity_rad_s);
        if (fabs(a->out.motor_angle_rad - b->out.motor_angle_rad) > worst_th)
            worst_th = fabs(a->out.motor_angle_rad - b->out.motor_angle_rad);
        if (fabs(a->out.motor_velocity_rad_s - b->out.motor_velocity_rad_s) > worst_w)
            worst_w = fabs(a->out.motor_velocity_rad_s - b->out.motor_velocity_rad_s);
    }
    printf("# stage harmonics by rotation vs by powers: motor angle %.2e of peak %.3g rad, velocity %.2e of peak %.3g rad/s\n",
           worst_th / pk_th, pk_th, worst_w / pk_w, pk_w);
    assert_true(pk_w > 0.1 / (72.0 * 1e-4));        /* fast enough for the power fallback */
    assert_true(worst_th > 0.0 || worst_w > 0.0);   /* the rotation path ran */
    assert_true(worst_th / pk_th < 1e-12);
    assert_true(worst_w / pk_w < 1e-12);
    free(a);
    free(b);
}

/* The first RK stage of a period reuses the end-of-period evaluation (same state); with
 * that reuse switched off (k1_ok = 0, an internal cache flag) every stage is evaluated in
 * full.  Both runs agree to rounding, with changing motor, load and base inputs and the
 * brake engaged and released on the way. */
static void test_first_stage_reuse(void **state)
{
    hd_plant_params prm;
    hd_plant_input in;
    hd_plant *a, *b;
    double worst = 0.0, peak = 0.0;
    long k;
    (void)state;
    every_effect(&prm);
    a = new_plant(&prm, 9u);
    b = new_plant(&prm, 9u);
    b->k1_ok = 0;
    memset(&in, 0, sizeof in);
    for (k = 0; k < 4000; k++) {
        const double t = (double)k * 1e-4;
        in.current_cmd_A = current_cmd(k);
        in.load_torque_Nm = k >= 1500 ? 2.0 : 0.0;
        in.base_rate_rad_s = 1e-3 * sin(2.0 * PI * 3.0 * t);
        in.base_accel_rad_s2 = 2.0 * PI * 3.0 * 1e-3 * cos(2.0 * PI * 3.0 * t);
        if (k == 2500 || k == 3000) {
            hd_plant_set_brake(a, k == 2500);
            hd_plant_set_brake(b, k == 2500);
        }
        hd_plant_step(a, &in, 1e-4);
        hd_plant_step(b, &in, 1e-4);
        if (fabs(b->out.motor_velocity_rad_s) > peak) peak = fabs(b->out.motor_velocity_rad_s);
        if (fabs(a->out.motor_velocity_rad_s - b->out.motor_velocity_rad_s) > worst)
            worst = fabs(a->out.motor_velocity_rad_s - b->out.motor_velocity_rad_s);
        assert_true(a->out.brake_engaged == b->out.brake_engaged);
    }
    printf("# first stage from the end-of-period evaluation vs evaluated in full: motor velocity %.2e of peak\n",
           worst / peak);
    assert_true(peak > 1.0);
    assert_true(worst / peak < 1e-12);
    free(a);
    free(b);
}

/* TE and cogging over a long run (1e6 periods, 100 s) that sweeps the motor from rest to
 * ~60 rad/s both ways: the harmonics come from Taylor series about an anchor (degree by the
 * offset, anchors moved by rotations, re-seeded from libm every 64), so every degree, the
 * re-anchoring and the fast-motion fallback all run.  At every period the reported TE and
 * cogging equal the libm formulas within the rounding of the arguments themselves:
 * |error| <= 2^-53 sum_k |a_k| (128 + 4 (|n_k theta| + |p_k|)) (128: 64 rotations of
 * about one ulp each, with margin; the libm side rounds n theta + p once or twice). */
static void test_harmonics_long_run_vs_libm(void **state)
{
    enum { N = 1000000 };
    hd_plant_params prm, r;
    hd_plant_input in;
    hd_plant *p;
    double worst_ratio = 0.0, top_w = 0.0;
    long k, slow = 0;
    int j;
    (void)state;
    hd_plant_defaults_minimal(&prm);
    hd_plant_defaults_reference(&r);
    prm.te_enabled = 1;
    prm.cogging_enabled = 1;
    memcpy(prm.te_wg_order, r.te_wg_order, sizeof r.te_wg_order);
    memcpy(prm.te_wg_amp_rad, r.te_wg_amp_rad, sizeof r.te_wg_amp_rad);
    memcpy(prm.te_wg_phase_rad, r.te_wg_phase_rad, sizeof r.te_wg_phase_rad);
    memcpy(prm.te_out_order, r.te_out_order, sizeof r.te_out_order);
    memcpy(prm.te_out_amp_rad, r.te_out_amp_rad, sizeof r.te_out_amp_rad);
    memcpy(prm.te_out_phase_rad, r.te_out_phase_rad, sizeof r.te_out_phase_rad);
    memcpy(prm.cog_order, r.cog_order, sizeof r.cog_order);
    memcpy(prm.cog_amp_Nm, r.cog_amp_Nm, sizeof r.cog_amp_Nm);
    memcpy(prm.cog_phase_rad, r.cog_phase_rad, sizeof r.cog_phase_rad);
    prm.fric_m = r.fric_m;                             /* viscous losses bound the speed */
    prm.fric_m.lugre_enabled = 0;
    p = new_plant(&prm, 2u);
    memset(&in, 0, sizeof in);
    for (k = 0; k < N; k++) {
        const double t = (double)k * 1e-4;
        const hd_plant_output *o;
        double te = 0.0, cog = 0.0, tol_te = 0.0, tol_cog = 0.0, ratio;
        /* torque sine of slowly varying amplitude: rest, creep and fast sweeps, reversals */
        in.current_cmd_A = 1.5 * sin(2.0 * PI * 0.05 * t) * sin(2.0 * PI * 0.7 * t);
        o = hd_plant_step(p, &in, 1e-4);
        for (j = 0; j < HD_PLANT_MAX_HARM; j++) {
            const double am = o->motor_angle_rad, al = o->load_angle_rad;
            if (prm.cog_order[j] != 0.0) {
                cog += prm.cog_amp_Nm[j] * sin(prm.cog_order[j] * am + prm.cog_phase_rad[j]);
                tol_cog += fabs(prm.cog_amp_Nm[j]) * (128.0 + 4.0 * (fabs(prm.cog_order[j] * am) + fabs(prm.cog_phase_rad[j])));
            }
            if (prm.te_wg_order[j] != 0.0) {
                te += prm.te_wg_amp_rad[j] * sin(prm.te_wg_order[j] * am + prm.te_wg_phase_rad[j]);
                tol_te += fabs(prm.te_wg_amp_rad[j]) * (128.0 + 4.0 * (fabs(prm.te_wg_order[j] * am) + fabs(prm.te_wg_phase_rad[j])));
            }
            if (prm.te_out_order[j] != 0.0) {
                te += prm.te_out_amp_rad[j] * sin(prm.te_out_order[j] * al + prm.te_out_phase_rad[j]);
                tol_te += fabs(prm.te_out_amp_rad[j]) * (128.0 + 4.0 * (fabs(prm.te_out_order[j] * al) + fabs(prm.te_out_phase_rad[j])));
            }
        }
        ratio = fabs(o->te_rad - te) / (tol_te * 0x1p-53);
        if (ratio > worst_ratio) worst_ratio = ratio;
        ratio = fabs(o->cogging_torque_Nm - cog) / (tol_cog * 0x1p-53);
        if (ratio > worst_ratio) worst_ratio = ratio;
        if (fabs(o->motor_velocity_rad_s) > top_w) top_w = fabs(o->motor_velocity_rad_s);
        if (fabs(o->motor_velocity_rad_s) < 0.5) slow++;
    }
    printf("# harmonics by series vs libm over %d periods (motor up to %.1f rad/s, %ld periods below 0.5 rad/s, "
           "at %.0f rad at the end): worst error %.3f of the stated bound\n", N, top_w, slow, p->out.motor_angle_rad,
           worst_ratio);
    assert_true(top_w > 0.125 / (72.0 * 1e-4));       /* beyond the series' range: the fallback ran */
    assert_true(slow > N / 50);                       /* and slow stretches: low degrees */
    assert_true(worst_ratio <= 1.0);
    free(p);
}

/* The Preisach output from a fixed memory is piecewise linear in the input:
 * hd_plant_preisach_piece gives the slope from the last input in each direction and the
 * input up to which it holds.  Over a wandering input with many nested reversals, the
 * operator evaluated inside that range equals the line to rounding (1e-12 of t_sat), and
 * the ranges are not empty (the stages use them). */
static void test_preisach_piece_is_the_operator(void **state)
{
    const double M = 5e-4, t_sat = 7.15;
    double *E = calloc((HD_PLANT_PREISACH_L + 1) * (HD_PLANT_PREISACH_L + 1), sizeof *E);
    hd_plant_preisach_state s;
    double worst = 0.0, u = 0.0;
    long k, n_cmp = 0, n_wide = 0, n_piece = 0;
    uint64_t x = 0x9E3779B97F4A7C15ull;
    (void)state;
    assert_non_null(E);
    hd_plant_preisach_everett(E, M, t_sat, 1e-4, 2e-4);
    hd_plant_preisach_reset(&s, E, M);
    for (k = 0; k < 20000; k++) {
        int dir;
        /* next input: a random walk with reversals, now and then beyond +-u_max */
        x ^= x << 13; x ^= x >> 7; x ^= x << 17;
        u += ((double)(x >> 11) * (1.0 / 9007199254740992.0) - 0.5) * 1.5e-4;
        if (u > 1.2 * M || u < -1.2 * M) u *= 0.5;
        (void)hd_plant_preisach_eval(&s, E, M, u, &s);
        for (dir = -1; dir <= 1; dir += 2) {
            double slope, bound, f;
            hd_plant_preisach_piece(&s, E, M, dir, &slope, &bound);
            n_piece++;
            if (!isfinite(bound)) { assert_true(slope == 0.0); continue; }   /* saturated side */
            assert_true(dir > 0 ? bound >= s.u_prev : bound <= s.u_prev);
            if (bound != s.u_prev) n_wide++;
            for (f = 0.125; f < 1.0; f += 0.25) {
                const double ui = s.u_prev + f * (bound - s.u_prev);
                const double y = hd_plant_preisach_eval(&s, E, M, ui, NULL);
                const double err = fabs(y - (s.y + slope * (ui - s.u_prev)));
                if (err > worst) worst = err;
                n_cmp++;
            }
        }
    }
    printf("# Preisach linear pieces vs the operator: %ld points, worst %.2e of t_sat; %.1f %% of pieces non-empty\n",
           n_cmp, worst / t_sat, 100.0 * (double)n_wide / (double)n_piece);
    assert_true(n_cmp > 100000);
    assert_true(worst / t_sat < 1e-12);
    assert_true(n_wide > n_piece / 2);
    free(E);
}

/* The RK stages take the hysteresis torque (Maxwell-slip + Preisach) from the linear piece
 * of the committed memory when the stage's twist lies in it; with that switched off
 * (hy_lin_ok = 0, an internal flag) every stage evaluates the operators.  Reversals of a
 * 7 Hz current on a 3 A step with every effect on: the piece serves most stages, and both
 * runs agree to rounding (1e-12 of the peak), not bit for bit (the piece ran). */
static void test_stage_hysteresis_piece(void **state)
{
    hd_plant_params prm;
    hd_plant_input in;
    hd_plant *a, *b;
    double worst_phi = 0.0, worst_th = 0.0, worst_w = 0.0, pk_phi = 0.0, pk_th = 0.0, pk_w = 0.0;
    long k, n = 20000;
    (void)state;
    every_effect(&prm);
    a = new_plant(&prm, 5u);
    b = new_plant(&prm, 5u);
    b->hy_lin_ok = 0;
    memset(&in, 0, sizeof in);
    for (k = 0; k < n; k++) {
        const double t = (double)k * 1e-4;
        in.current_cmd_A = current_cmd(k) * (1.0 - 0.8 * t);   /* shrinking loops: nested reversals */
        hd_plant_step(a, &in, 1e-4);
        hd_plant_step(b, &in, 1e-4);
        if (fabs(b->out.twist_rad) > pk_phi) pk_phi = fabs(b->out.twist_rad);
        if (fabs(b->out.hysteresis_torque_Nm) > pk_th) pk_th = fabs(b->out.hysteresis_torque_Nm);
        if (fabs(b->out.motor_velocity_rad_s) > pk_w) pk_w = fabs(b->out.motor_velocity_rad_s);
        if (fabs(a->out.twist_rad - b->out.twist_rad) > worst_phi) worst_phi = fabs(a->out.twist_rad - b->out.twist_rad);
        if (fabs(a->out.hysteresis_torque_Nm - b->out.hysteresis_torque_Nm) > worst_th)
            worst_th = fabs(a->out.hysteresis_torque_Nm - b->out.hysteresis_torque_Nm);
        if (fabs(a->out.motor_velocity_rad_s - b->out.motor_velocity_rad_s) > worst_w)
            worst_w = fabs(a->out.motor_velocity_rad_s - b->out.motor_velocity_rad_s);
    }
    printf("# stage hysteresis by linear piece vs by the operators: %.1f %% of stages by the piece; twist %.2e, "
           "hysteresis torque %.2e, motor velocity %.2e of peak\n", 100.0 * (double)a->n_hy_lin / (3.0 * (double)n),
           worst_phi / pk_phi, worst_th / pk_th, worst_w / pk_w);
    assert_int_equal(b->n_hy_lin, 0);
    assert_true(a->n_hy_lin > 3 * n / 2);                /* most stages */
    assert_true(pk_th > 1.0);                             /* the hysteresis is exercised */
    assert_true(worst_phi > 0.0 || worst_th > 0.0 || worst_w > 0.0);
    assert_true(worst_phi / pk_phi < 1e-12);
    assert_true(worst_th / pk_th < 1e-12);
    assert_true(worst_w / pk_w < 1e-12);
    free(a);
    free(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_one_substep_vs_reference),
        cmocka_unit_test(test_stribeck_matches_libm),
        cmocka_unit_test(test_harmonics_match_libm),
        cmocka_unit_test(test_harmonics_rotated_match_libm),
        cmocka_unit_test(test_first_stage_reuse),
        cmocka_unit_test(test_stage_harmonics_rotation),
        cmocka_unit_test(test_preisach_piece_is_the_operator),
        cmocka_unit_test(test_stage_hysteresis_piece),
        cmocka_unit_test(test_harmonics_long_run_vs_libm),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
