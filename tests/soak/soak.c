/*
 * soak.c - long runs (make soak: 10^8 control periods; make test: 10^7).
 *
 *   soak N [json]
 *
 * Part A, closed loop on the simulator (firmware app + plant in lock-step,
 * optimised build, "minimal" axis for speed): N control periods in velocity
 * mode, reference = bias + sine (reversals every few seconds, net drift of
 * many output turns), so the 17-bit motor encoder wraps ~10^4 times per 10^7
 * periods and the 24-bit output encoder ~10^2 times.  Every 1000 periods:
 *   - the app's unwrapped output and motor angles agree with the plant's true
 *     angles within a few encoder counts (a wrong wrap would be a full turn);
 *   - the velocity-loop integrator stays inside its anti-windup bound
 *     (|I term| <= output limit), the torque command inside torque_limit;
 *   - no fault latched, app tick == period count (uint32, wraps meant).
 * Part B, trajectory generator (firmware/core/hd_trajectory, integer only):
 *   - constant rate: after reaching the rate, the 2^-48-turn position after k
 *     periods equals p0 + floor((rem0 + k v 2^16) / HD_LOOP_HZ) exactly
 *     (checked with 128-bit arithmetic, every 2^20 periods and at the end);
 *   - point-to-point: 2000 moves of random length back and forth, each ends
 *     EXACTLY on its target (Q32.32) with velocity and acceleration 0;
 *   - sinusoid phase accumulator: phase == k inc_q + floor((k inc_r + acc0)/HZ)
 *     mod 2^64 after k periods.
 * Part C, adaptive backstepping (firmware/core/hd_backstep) under a
 * pseudo-random reference for N/10 periods: every adapted parameter stays in
 * its projection box [th_min, th_max] (T_load's widened by Fs while the reference moves
 * slowly, as hd_backstep.c says), the output within u_max.
 *
 * Prints TAP lines and figures; writes JSON with the figures if asked.
 */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "harness.h"
#include "hd_app.h"
#include "hd_backstep.h"
#include "hd_trajectory.h"

static int n_fail;
static void tap(int ok, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
#include <stdarg.h>
static void tap(int ok, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    printf("%s - ", ok ? "ok" : "not ok");
    vprintf(fmt, ap);
    printf("\n");
    va_end(ap);
    fflush(stdout);
    if (!ok) {
        n_fail++;
    }
}

static const double TWO_PI = 6.283185307179586;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- part A --------------------------------------------------------------- */
typedef struct {
    int64_t periods;
    double sim_s, wall_s;
    double max_out_err_rad, max_mot_err_rad;
    double out_turns_travelled, mot_wraps;
    int64_t max_integ_ratio_ppm;
    int32_t fault;
    int64_t checks;
    int ok;
} part_a_t;

static int part_a(int64_t n, part_a_t *r)
{
    char err[512];
    char text[2048];
    memset(r, 0, sizeof *r);
    const double dur = (double)n / 10000.0;
    snprintf(text, sizeof text,
             "[scenario]\nname = \"soak\"\naxis = \"minimal\"\nduration_s = %.4f\nseed = 3\n"
             "log_decimation = 1000\n[controller]\nmode = \"velocity\"\n"
             "[controller.gains]\ntravel_min = -120.0\ntravel_max = 120.0\n"
             "[setpoint]\ntype = \"sine\"\ninitial_rad_s = %.6f\namplitude_rad_s = 0.5\nfrequency_Hz = 0.05\n",
             fmin(dur, 3600.0), fmin(0.3, 50.0 * TWO_PI / dur));
    static hd_scenario_t sc;
    if (hd_scenario_parse(text, strlen(text), "soak.toml", &sc, err, sizeof err) != 0) {
        tap(0, "soak A: scenario: %s", err);
        return -1;
    }
    /* scenario files stop at 3600 s; the soak runs past that on purpose
     * (the sine setpoint does not depend on the duration) */
    sc.duration_s = dur;
    hd_plant_params prm;
    if (hd_sim_scenario_params(&sc, &prm, err, sizeof err) != 0) {
        tap(0, "soak A: axis: %s", err);
        return -1;
    }
    hd_sim_t *s = hd_sim_new(&sc, &prm, err, sizeof err);
    if (s == NULL) {
        tap(0, "soak A: %s", err);
        return -1;
    }
    const hd_app_t *a = hd_sim_app(s);
    const int64_t np = hd_sim_n_periods(s) < n ? hd_sim_n_periods(s) : n;
    double row[HD_SIM_NCOL];
    const double t0 = now_s();
    double prev_load = 0.0, prev_mot = 0.0;
    /* tolerances: 3 counts of each encoder (a wrong unwrap is a whole turn) */
    const double tol_out = 3.0 * TWO_PI / (double)(1u << a->param[HD_P_OUTPUT_ENC_BITS]);
    const double tol_mot = 3.0 * TWO_PI / (double)(1u << a->param[HD_P_MOTOR_ENC_BITS]);
    int ok = 1;
    uint32_t tick0 = 0;
    for (int64_t k = 0; k < np; k++) {
        if (k == 0) {
            hd_sim_step(s, NULL);
            tick0 = a->tel.tick;   /* tick of period 0; then +1 per period */
            continue;
        }
        const int check = (k % 1000) == 999 || k == np - 1;
        hd_sim_step(s, check ? row : NULL);
        if (!check) {
            continue;
        }
        r->checks++;
        /* app unwrapped angles vs plant truth (Q32.32 turns -> rad) */
        const double out_rad = (double)a->pos_out / 4294967296.0 * TWO_PI;
        const double mot_rad = (double)a->pos_mot / 4294967296.0 * TWO_PI;
        const double eo = fabs(out_rad - row[HD_COL_LOAD_TRUE]);
        const double em = fabs(mot_rad - row[HD_COL_MOTOR_TRUE]);
        if (eo > r->max_out_err_rad) r->max_out_err_rad = eo;
        if (em > r->max_mot_err_rad) r->max_mot_err_rad = em;
        r->out_turns_travelled += fabs(row[HD_COL_LOAD_TRUE] - prev_load) / TWO_PI;
        r->mot_wraps += fabs(row[HD_COL_MOTOR_TRUE] - prev_mot) / TWO_PI;
        prev_load = row[HD_COL_LOAD_TRUE];
        prev_mot = row[HD_COL_MOTOR_TRUE];
        /* integrator inside its anti-windup bound */
        const int64_t lim = (int64_t)a->vel_cfg.out_max > -(int64_t)a->vel_cfg.out_min
                                ? (int64_t)a->vel_cfg.out_max : -(int64_t)a->vel_cfg.out_min;
        const int64_t iterm = llabs((int64_t)a->vel_pid.i);
        const int64_t ppm = lim > 0 ? iterm * 1000000 / lim : 0;
        if (ppm > r->max_integ_ratio_ppm) r->max_integ_ratio_ppm = ppm;
        const int64_t tq = llabs((int64_t)a->tel.torque_cmd);
        if (eo > tol_out || em > tol_mot || ppm > 1000000 || tq > a->param[HD_P_TORQUE_LIMIT] ||
            a->fault != HD_FAULT_NONE || a->tel.tick != (uint32_t)k + tick0) {
            if (ok) {
                fprintf(stderr, "soak A: period %" PRId64 ": out err %.3g rad, mot err %.3g rad, "
                        "I/limit %" PRId64 " ppm, |torque| %" PRId64 ", fault %d, tick %u\n",
                        k, eo, em, ppm, tq, (int)a->fault, (unsigned)a->tel.tick);
            }
            ok = 0;
        }
    }
    r->wall_s = now_s() - t0;
    r->periods = np;
    r->sim_s = (double)np / 10000.0;
    r->fault = a->fault;
    r->ok = ok;
    hd_sim_free(s);
    return 0;
}

/* ---- part B --------------------------------------------------------------- */
typedef unsigned __int128 u128;
typedef __int128 i128;

static uint64_t lcg(uint64_t *x)
{
    *x = *x * 6364136223846793005ull + 1442695040888963407ull;
    return *x >> 11;
}

static int part_b_rate(int64_t n, double *wall)
{
    hd_traj_t t;
    hd_traj_cfg_t c = {.vmax = 2147483647, .amax = 1 << 24, .jmax = 1 << 20};
    const double t0 = now_s();
    int ok = 1;
    /* three rates: 60 deg/s, 0.001 deg/s, -7.3 deg/s (2^-32 turn/s) */
    const int32_t rates[3] = {715827883, 11930, -87101108};
    for (int r = 0; r < 3 && ok; r++) {
        hd_traj_reset(&t, (hd_angle_t)r << 30);
        hd_traj_rate(&t, &c, rates[r]);
        int64_t k = 0;
        while (t.rate_cur != rates[r] && k < 100000) {
            hd_traj_step(&t, &c);
            k++;
        }
        const int64_t p0 = t.p48;
        const i128 rem0 = t.rate_rem;
        const int64_t steps = n / 3;
        for (int64_t j = 1; j <= steps; j++) {
            hd_traj_step(&t, &c);
            if ((j & 0xFFFFF) == 0 || j == steps) {
                const i128 num = rem0 + (i128)j * (i128)rates[r] * 65536;
                i128 q = num / HD_LOOP_HZ;
                if (num % HD_LOOP_HZ != 0 && num < 0) q -= 1;   /* floor */
                const int64_t want = p0 + (int64_t)q;
                if (t.p48 != want) {
                    fprintf(stderr, "soak B rate %d: after %" PRId64 " periods p48 %" PRId64 " want %" PRId64 "\n",
                            r, j, t.p48, want);
                    ok = 0;
                    break;
                }
            }
        }
    }
    *wall = now_s() - t0;
    return ok;
}

static int part_b_ptp(int32_t moves, int64_t *periods)
{
    hd_traj_t t;
    hd_traj_cfg_t c = {.vmax = 715827883 /* 60 deg/s */, .amax = 4660337 /* ~100 deg/s^2 */, .jmax = 1 << 20};
    uint64_t x = 12345;
    hd_traj_reset(&t, 0);
    int ok = 1;
    *periods = 0;
    for (int32_t m = 0; m < moves && ok; m++) {
        /* random target within +-0.4 turn, Q32.32, odd LSBs on purpose */
        const hd_angle_t target = (hd_angle_t)((int64_t)(lcg(&x) % 3435973836ull) - 1717986918) + (hd_angle_t)(lcg(&x) & 0xFF);
        if (hd_traj_ptp(&t, &c, target) != 0) {
            fprintf(stderr, "soak B ptp: move %d refused\n", m);
            ok = 0;
            break;
        }
        int64_t k = 0;
        while (t.mode == HD_TRAJ_PTP && k < 100000000) {
            hd_traj_step(&t, &c);
            k++;
        }
        hd_traj_step(&t, &c);   /* one period at rest */
        *periods += k + 1;
        if (t.pos != target || t.vel != 0 || t.acc != 0) {
            fprintf(stderr, "soak B ptp: move %d ends at %" PRId64 " (target %" PRId64 "), vel %d acc %d\n",
                    m, t.pos, target, (int)t.vel, (int)t.acc);
            ok = 0;
        }
    }
    return ok;
}

static int part_b_sine(int64_t n)
{
    hd_traj_t t;
    hd_traj_cfg_t c = {.vmax = 2147483647, .amax = 2147483647, .jmax = 2147483647};
    hd_traj_reset(&t, 0);
    if (hd_traj_sine(&t, 0, 1 << 24, (int32_t)(1.37 * 65536)) != 0) {
        return 0;
    }
    const uint64_t ph0 = t.phase;
    const u128 acc0 = t.inc_acc;
    for (int64_t j = 1; j <= n; j++) {
        hd_traj_step(&t, &c);
        if ((j & 0xFFFFF) == 0 || j == n) {
            const u128 carry = ((u128)j * t.inc_r + acc0) / HD_LOOP_HZ;
            const uint64_t want = ph0 + (uint64_t)((u128)j * t.inc_q + carry);
            if (t.phase != want) {
                fprintf(stderr, "soak B sine: after %" PRId64 " periods phase %" PRIu64 " want %" PRIu64 "\n",
                        j, t.phase, want);
                return 0;
            }
        }
    }
    return 1;
}

/* ---- part C --------------------------------------------------------------- */
static int part_c(int64_t n, int64_t *max_margin_ppm)
{
    hd_backstep_cfg_t c;
    memset(&c, 0, sizeof c);
    c.c1 = 20 << 16;
    c.c2 = 40 << 16;
    c.j = 3 << 16;
    c.ke = 1000 << 8;
    c.eps_w = 1 << 20;
    c.w_s = 1 << 22;
    c.e1_max = 1 << 22;
    c.u_max = 60 << 16;
    for (uint32_t i = 0; i < HD_BS_NP; i++) {
        c.gamma_dt[i] = 1 << 22;
        c.th_min[i] = -(int32_t)((i + 1) << 16);
        c.th_max[i] = (int32_t)((i + 2) << 16);
    }
    const int32_t th0[HD_BS_NP] = {0, 0, 0, 0};
    hd_backstep_t s;
    hd_backstep_init(&s, &c, th0, 0u, true);
    uint64_t x = 99;
    hd_backstep_in_t in;
    memset(&in, 0, sizeof in);
    *max_margin_ppm = 0;
    for (int64_t k = 0; k < n; k++) {
        /* random walk measurement, piecewise-constant reference: drives e2 both ways */
        in.omega = (int32_t)((int64_t)(lcg(&x) % 200000001ull) - 100000000) * 4;
        in.theta += in.omega / 10000;
        if ((k & 4095) == 0) {
            in.theta_d = in.theta + (hd_angle_t)((int64_t)(lcg(&x) % 2000001ull) - 1000000) * 64;
            in.omega_d = (int32_t)((int64_t)(lcg(&x) % 2000001ull) - 1000000) * 100;
        }
        const int32_t u = hd_backstep_step(&s, &c, &in, 0);
        if (u > c.u_max || u < -c.u_max) {
            fprintf(stderr, "soak C: u %d outside u_max at %" PRId64 "\n", (int)u, k);
            return 0;
        }
        for (uint32_t i = 0; i < HD_BS_NP; i++) {
            int64_t lo = (int64_t)c.th_min[i] * 4294967296LL, hi = (int64_t)c.th_max[i] * 4294967296LL;
            const int64_t awd = in.omega_d < 0 ? -(int64_t)in.omega_d : (int64_t)in.omega_d;
            if (i == 3u && in.omega_d != 0 && awd <= 4 * (int64_t)c.w_s) {
                /* a slowly moving reference: T_load's box widened by the friction boxes' Fc + (Fs - Fc) */
                const int64_t fs = ((int64_t)(c.th_max[0] > 0 ? c.th_max[0] : 0) +
                                    (int64_t)(c.th_max[1] > 0 ? c.th_max[1] : 0)) * 4294967296LL;
                lo -= fs;
                hi += fs;
            }
            if (s.th[i] < lo || s.th[i] > hi) {
                fprintf(stderr, "soak C: theta_hat[%u] = %" PRId64 " outside [%" PRId64 ", %" PRId64 "] at %" PRId64 "\n",
                        i, s.th[i], lo, hi, k);
                return 0;
            }
            /* how close to a bound (ppm of the box): shows the projection is exercised */
            const int64_t m = (int64_t)(((i128)(hi - s.th[i] < s.th[i] - lo ? hi - s.th[i] : s.th[i] - lo)) * 1000000 / (hi - lo));
            (void)m;
            if ((s.th[i] == lo || s.th[i] == hi)) {
                *max_margin_ppm += 1;   /* counts periods at a bound */
            }
        }
    }
    return 1;
}

int main(int argc, char **argv)
{
    const int64_t n = argc > 1 ? strtoll(argv[1], NULL, 10) : 10000000;
    const char *json = argc > 2 ? argv[2] : NULL;
    part_a_t a;
    if (part_a(n, &a) == 0) {
        tap(a.ok, "soak A: %" PRId64 " control periods (%.0f s simulated) closed loop on the simulator in %.1f s: "
            "output %.1f turns, motor %.0f turns travelled; max |angle - truth| out %.2g rad, motor %.2g rad; "
            "max |I|/limit %.3f; fault %d",
            a.periods, a.sim_s, a.wall_s, a.out_turns_travelled, a.mot_wraps, a.max_out_err_rad, a.max_mot_err_rad,
            (double)a.max_integ_ratio_ppm / 1e6, (int)a.fault);
    }
    double wall_rate = 0;
    const int ok_rate = part_b_rate(n, &wall_rate);
    tap(ok_rate, "soak B: trajectory constant rate, 3 x %" PRId64 " periods (60, 0.001, -7.3 deg/s): position exact "
        "(2^-48 turn) against 128-bit reference (%.1f s)", n / 3, wall_rate);
    int64_t ptp_periods = 0;
    const int ok_ptp = part_b_ptp(2000, &ptp_periods);
    tap(ok_ptp, "soak B: trajectory 2000 point-to-point moves (%" PRId64 " periods) each end exactly on target", ptp_periods);
    const int ok_sine = part_b_sine(n);
    tap(ok_sine, "soak B: sinusoid phase accumulator exact after %" PRId64 " periods", n);
    int64_t at_bound = 0;
    const int ok_bs = part_c(n / 10, &at_bound);
    tap(ok_bs, "soak C: adaptive backstepping %" PRId64 " periods: parameters inside the projection box, |u| <= u_max "
        "(%" PRId64 " parameter-periods at a bound)", n / 10, at_bound);
    if (json != NULL) {
        char tmp[1024];
        snprintf(tmp, sizeof tmp, "%s.tmp", json);
        FILE *f = fopen(tmp, "w");
        if (f != NULL) {
            fprintf(f, "{\n \"periods\": %" PRId64 ",\n \"simulated_s\": %.1f,\n \"wall_s\": %.2f,\n"
                    " \"output_turns_travelled\": %.2f,\n \"motor_turns_travelled\": %.1f,\n"
                    " \"max_output_angle_err_rad\": %.3g,\n \"max_motor_angle_err_rad\": %.3g,\n"
                    " \"max_integrator_over_limit\": %.4f,\n \"fault\": %d,\n \"closed_loop_ok\": %s,\n"
                    " \"traj_rate_periods\": %" PRId64 ",\n \"traj_rate_exact\": %s,\n \"traj_ptp_moves\": 2000,\n"
                    " \"traj_ptp_periods\": %" PRId64 ",\n \"traj_ptp_exact\": %s,\n \"traj_sine_exact\": %s,\n"
                    " \"backstep_periods\": %" PRId64 ",\n \"backstep_bounded\": %s,\n \"backstep_periods_at_bound\": %" PRId64 "\n}\n",
                    a.periods, a.sim_s, a.wall_s, a.out_turns_travelled, a.mot_wraps, a.max_out_err_rad,
                    a.max_mot_err_rad, (double)a.max_integ_ratio_ppm / 1e6, (int)a.fault, a.ok ? "true" : "false",
                    3 * (n / 3), ok_rate ? "true" : "false", ptp_periods, ok_ptp ? "true" : "false",
                    ok_sine ? "true" : "false", n / 10, ok_bs ? "true" : "false", at_bound);
            fclose(f);
            rename(tmp, json);
        }
    }
    return n_fail ? 1 : 0;
}
