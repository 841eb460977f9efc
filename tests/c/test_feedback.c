/*
 * test_feedback.c - feedback configurations of the position loop (fb_config,
 * hd_feedback.h), the compliance twist (hd_compliance.h) and the motor-side
 * estimate of the output, against a stub hal: a rigid axis seen through an
 * elastic gear with transmission error.  The motor body (J = 1.3 kg m^2
 * output-referred, gear N = 100) moves; the output encoder reads
 *     theta_l = theta_m / N + TE(theta_m) - twist(T),
 * TE one motor harmonic, twist the three-slope stiffness at the torque the gear
 * transmits (the applied output torque, quasi-static), so the output encoder and
 * motor / N differ by what the compensators predict.
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

#include "hd_app.h"
#include "hd_feedback.h"
#include "hd_compliance.h"
#include "hd_fixed.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define TURN 4294967296.0
#define ARCSEC_TURN (1.0 / 1296000.0)

/* gear of the stub (reference-axis stiffness, one TE line) */
#define K1 (31000.0 * 2 * M_PI)    /* N.m/turn */
#define K2 (50000.0 * 2 * M_PI)
#define K3 (57000.0 * 2 * M_PI)
#define T1 14.0
#define T2 48.0
#define TE_ORDER 2.0
#define TE_AMP (20.0 * ARCSEC_TURN)   /* turn */
#define TE_PHASE 0.1                  /* turn */

static struct {
    double th, w;            /* motor angle / N [turn], velocity [turn/s] */
    double j, n;
    double t_load;           /* external torque at the output, N.m */
    double t_gear;           /* torque the gear transmits (last applied), N.m */
    double out_offset;       /* turns added to the output encoder reading */
    int gear_on;             /* 1: TE and twist between motor / N and the output */
    hd_hal_command_t cmd;
    uint32_t tick;
} P;

static double twist(double t)
{
    const double a = fabs(t);
    double phi;
    if (a <= T1) phi = a / K1;
    else if (a <= T2) phi = T1 / K1 + (a - T1) / K2;
    else phi = T1 / K1 + (T2 - T1) / K2 + (a - T2) / K3;
    return t < 0 ? -phi : phi;
}

static double te(double th_m)
{
    return TE_AMP * sin(2 * M_PI * (TE_ORDER * th_m + TE_PHASE));
}

/* true output angle, turns */
static double out_true(void)
{
    return P.gear_on ? P.th + te(P.th * P.n) - twist(P.t_gear) : P.th;
}

uint32_t hd_hal_tick(void) { return P.tick; }

void hd_hal_read_sensors(hd_hal_sensors_t *s)
{
    s->motor_enc_raw = (uint32_t)((int64_t)floor(P.th * P.n * 131072.0) & 0x1FFFF);
    s->output_enc_raw = (uint32_t)((int64_t)floor((out_true() + P.out_offset) * 16777216.0) & 0xFFFFFF);
    s->current = P.cmd.current;
    s->gyro_rate = 0;
    s->valid = HD_HAL_VALID_ALL;
}

void hd_hal_write_command(const hd_hal_command_t *c)
{
    P.cmd = *c;
    const double t_out = c->enable ? c->torque / 65536.0 * P.n : 0.0;
    P.t_gear = t_out;
    for (int i = 0; i < 10; i++) {
        const double acc = (t_out + P.t_load) / P.j / (2 * M_PI);
        P.w += acc * 1e-5;
        P.th += P.w * 1e-5;
    }
    P.tick++;
}

bool hd_hal_can_send(const hd_can_frame_t *f) { (void)f; return true; }
bool hd_hal_can_recv(hd_can_frame_t *f) { (void)f; return false; }
uint32_t hd_hal_nvm_size(void) { return 4096u; }
uint32_t hd_hal_nvm_page_size(void) { return 1024u; }
int32_t hd_hal_nvm_read(uint32_t off, void *buf, uint32_t len) { (void)off; memset(buf, 0xFF, len); return 0; }
int32_t hd_hal_nvm_write(uint32_t off, const void *buf, uint32_t len) { (void)off; (void)buf; (void)len; return -1; }
int32_t hd_hal_nvm_erase(uint32_t off, uint32_t len) { (void)off; (void)len; return -1; }

static hd_app_t app;

static int setup(void **st)
{
    (void)st;
    memset(&P, 0, sizeof P);
    P.th = 0.01;
    P.j = 1.3;
    P.n = 100;
    P.gear_on = 1;
    hd_app_init(&app);
    return 0;
}

static void run(uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        hd_app_step(&app);
    }
}

static int32_t q16(double x) { return (int32_t)llround(x * 65536.0); }
static int32_t q8(double x) { return (int32_t)llround(x * 256.0); }
static int32_t q32(double x) { return (int32_t)llround(x * TURN); }

/* the stub's gear as drive parameters: TE line, three-slope compliance; the
 * transmitted-torque estimate = the torque command low-passed (pr_t_src 0, no
 * motor-friction share) */
static void gear_params(void)
{
    assert_int_equal(hd_app_param_set(&app, HD_P_FAULT_ENABLE, 0), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_TE_N, 1), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_TE_ORDER1, 2), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_TE_AMP1, q32(TE_AMP)), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_TE_PHASE1, q32(TE_PHASE)), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_TE_K1, 0), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_CP_K1, q8(K1)), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_CP_K2, q8(K2)), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_CP_K3, q8(K3)), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_CP_T1, q16(T1)), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_CP_T2, q16(T2)), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_PR_T_SRC, 0), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_PR_MOTOR_SHARE, 0), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_CB_RAMP_TICKS, 0), 0);
}

/* ---- kernels ------------------------------------------------------------------ */

static void test_compliance_twist(void **st)
{
    (void)st;
    hd_compliance_cfg_t c;
    assert_int_equal(hd_compliance_design(&c, q8(K1), q8(K2), q8(K3), q16(T1), q16(T2)), 0);
    /* refused: slope below 2^13 N.m/turn, t2 < t1, t1 < 0; cfg untouched */
    const hd_compliance_cfg_t keep = c;
    assert_int_equal(hd_compliance_design(&c, (1 << 21) - 1, q8(K2), q8(K3), q16(T1), q16(T2)), -1);
    assert_int_equal(hd_compliance_design(&c, q8(K1), q8(K2), q8(K3), q16(T2), q16(T1)), -1);
    assert_int_equal(hd_compliance_design(&c, q8(K1), q8(K2), q8(K3), -1, q16(T2)), -1);
    assert_memory_equal(&c, &keep, sizeof c);
    /* against the double formula over the three segments, both signs */
    double worst = 0;
    for (double t = -80.0; t <= 80.0; t += 0.37) {
        const double ref = twist(t) * TURN;
        const double got = hd_compliance_twist(&c, q16(t));
        worst = fmax(worst, fabs(got - ref));
    }
    printf("# compliance twist vs double, -80..80 N.m: worst %.2f LSB (2^-32 turn)\n", worst);
    assert_true(worst < 2.0);
    /* odd, continuous at the breakpoints, monotone */
    assert_int_equal(hd_compliance_twist(&c, 0), 0);
    assert_int_equal(hd_compliance_twist(&c, -q16(30.0)), -hd_compliance_twist(&c, q16(30.0)));
    assert_true(abs(hd_compliance_twist(&c, q16(T1) + 1) - hd_compliance_twist(&c, q16(T1))) <= 2);
    assert_true(abs(hd_compliance_twist(&c, q16(T2) + 1) - hd_compliance_twist(&c, q16(T2))) <= 2);
    int32_t prev = hd_compliance_twist(&c, INT32_MIN);
    for (int64_t t = INT32_MIN; t <= INT32_MAX; t += 8191 * 4099) {
        const int32_t v = hd_compliance_twist(&c, (int32_t)t);
        assert_true(v >= prev);
        prev = v;
    }
}

/* hd_fb_motor tracks floor(pos_mot / N) exactly over random per-period steps */
static void test_fb_motor_exact(void **st)
{
    (void)st;
    static const int32_t ns[] = {1, 7, 50, 100, 161, 1000, 65535};
    uint64_t x = 0x9E3779B97F4A7C15u;
    for (size_t k = 0; k < sizeof ns / sizeof ns[0]; k++) {
        hd_fb_cfg_t c;
        hd_fb_t s;
        assert_int_equal(hd_fb_design(&c, HD_FB_SEMI_CLOSED, ns[k], 2 << 16), 0);
        hd_angle_t pm = -((hd_angle_t)3 << 32) + 12345;
        hd_fb_reset(&s, &c, pm, 0);
        {
            int64_t q0 = pm / ns[k], r0 = pm % ns[k];
            if (r0 < 0) { q0 -= 1; r0 += ns[k]; }
            assert_true(s.mo == q0 && s.mo_rem == r0);
        }
        for (int i = 0; i < 20000; i++) {
            x ^= x << 13; x ^= x >> 7; x ^= x << 17;
            /* steps from a few LSB up to the largest a period can bring (|d| < 2^31);
             * every 64th a jump of up to 2^52 (the long form, e.g. after a re-home) */
            const int64_t d = ((i & 63) == 63) ? (int64_t)x >> 12 : (int64_t)((int32_t)(x >> 32) >> ((x >> 8) & 31u));
            pm += d;
            hd_fb_motor(&s, &c, pm);
            int64_t q = pm / ns[k], r = pm % ns[k];
            if (r < 0) { q -= 1; r += ns[k]; }
            if (s.mo != q || s.mo_rem != r) {
                fail_msg("N %d step %d: mo %lld rem %d, expected %lld %lld", ns[k], i,
                         (long long)s.mo, s.mo_rem, (long long)q, (long long)r);
            }
        }
    }
    /* semi-closed feedback = motor / N - offset; full closed = the output encoder */
    hd_fb_cfg_t c;
    hd_fb_t s;
    assert_int_equal(hd_fb_design(&c, HD_FB_SEMI_CLOSED, 100, 2 << 16), 0);
    hd_fb_reset(&s, &c, (hd_angle_t)100 << 32, 0);
    assert_int_equal(hd_fb_step(&s, &c, 999, 5000), ((hd_angle_t)1 << 32) - 5000);
    assert_int_equal(hd_fb_design(&c, HD_FB_FULL_CLOSED, 100, 2 << 16), 0);
    assert_int_equal(hd_fb_step(&s, &c, 999, 5000), 999);
    /* bad configs refused */
    assert_int_equal(hd_fb_design(&c, 3, 100, 2 << 16), -1);
    assert_int_equal(hd_fb_design(&c, HD_FB_DUAL_LOOP, 0, 2 << 16), -1);
    assert_int_equal(hd_fb_design(&c, HD_FB_DUAL_LOOP, 65536, 2 << 16), -1);
    assert_int_equal(hd_fb_design(&c, HD_FB_DUAL_LOOP, 100, 0), -1);
}

/* dual loop: the output encoder at low frequency (first order at fb_dual_fc), the
 * motor-side estimate at high frequency; entry starts at the output encoder */
static void test_fb_dual_blend(void **st)
{
    (void)st;
    hd_fb_cfg_t c;
    hd_fb_t s;
    assert_int_equal(hd_fb_design(&c, HD_FB_DUAL_LOOP, 100, 2 << 16), 0);
    hd_fb_reset(&s, &c, 0, 0);
    const hd_angle_t out = 1000000;      /* output 1e6 LSB above motor / N */
    assert_int_equal(hd_fb_enter(&s, &c, out), out);
    /* the first offset after the entry does not step the feedback (entry bias) */
    assert_int_equal(hd_fb_step(&s, &c, out, 300000), out);
    for (int i = 0; i < 40000; i++) (void)hd_fb_step(&s, &c, out, 0);
    assert_true(llabs(s.bias) < 32768 && llabs(s.pos_fb - out) <= 1);   /* faded below half an LSB */
    /* a later step of the offset prediction (e.g. a compensator switching) reaches
     * the feedback at once, and decays with the 2 Hz time constant */
    hd_angle_t fb = hd_fb_step(&s, &c, out, 500000);
    assert_true(llabs(fb - (out - 500000)) < 1000);      /* one alpha step (628 LSB) of the blend */
    int k;
    for (k = 1; k < 20000; k++) {
        fb = hd_fb_step(&s, &c, out, 500000);
        if (llabs(fb - out) < (int64_t)(500000 * exp(-1.0))) break;
    }
    /* 1 / (2 pi 2 Hz) = 796 periods */
    printf("# dual loop 2 Hz: offset step decays to 1/e in %d periods (796 expected)\n", k);
    assert_true(abs(k - 796) < 10);
    for (; k < 40000; k++) fb = hd_fb_step(&s, &c, out, 500000);
    assert_true(llabs(fb - out) <= 1);
}

/* ---- the app ------------------------------------------------------------------ */

static void test_fb_refused_while_enabled(void **st)
{
    (void)st;
    gear_params();
    run(10);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_POSITION), 0);
    run(10);
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, HD_FB_SEMI_CLOSED), -1);
    assert_int_equal(hd_app_param_get(&app, HD_P_FB_CONFIG), HD_FB_FULL_CLOSED);
    assert_int_equal(app.fb_cfg.kind, (uint32_t)HD_FB_FULL_CLOSED);
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, HD_FB_FULL_CLOSED), 0);   /* same value: fine */
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, 3), -1);                   /* out of range */
    /* a requested mode not yet entered counts as enabled too */
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_OFF), 0);
    run(2);
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, HD_FB_DUAL_LOOP), 0);
    assert_int_equal(app.fb_cfg.kind, (uint32_t)HD_FB_DUAL_LOOP);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_PTP), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, HD_FB_SEMI_CLOSED), -1);
    assert_int_equal(app.fb_cfg.kind, (uint32_t)HD_FB_DUAL_LOOP);
}

/* changing fb_config with the power stage off moves nothing, and entering a
 * position mode afterwards starts with a zero position error (bumpless) */
static void test_fb_bumpless(void **st)
{
    (void)st;
    gear_params();
    assert_int_equal(hd_app_param_set(&app, HD_P_CB_ENABLE, (int32_t)(HD_CB_TE | HD_CB_COMPLIANCE)), 0);
    run(10);
    for (int32_t kind = 0; kind <= 2; kind++) {
        assert_int_equal(hd_app_set_mode(&app, HD_MODE_OFF), 0);
        run(3);
        assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, kind), 0);
        run(1);
        assert_int_equal(P.cmd.enable, 0u);             /* the change itself drives nothing */
        assert_int_equal(P.cmd.torque, 0);
        assert_int_equal(app.tel.pos_err, 0);
        assert_int_equal(hd_app_set_mode(&app, HD_MODE_POSITION), 0);
        hd_app_step(&app);
        /* first period: the reference is the loop's feedback, and the compensators'
         * first prediction (TE here, 12") fades in through the entry bias */
        printf("# fb_config %d: first position error %.3f arcsec\n", kind,
               (double)app.tel.pos_err / TURN * 1296000.0);
        assert_true(fabs((double)app.tel.pos_err / TURN * 1296000.0) < 0.2);
        run(2000);
        printf("# fb_config %d: settled position error %.3f arcsec\n", kind, (double)app.tel.pos_err / TURN * 1296000.0);
        /* after settling: the position error is that of a held axis, whichever source */
        assert_true(fabs((double)app.tel.pos_err / TURN * 1296000.0) < 1.0);
        assert_int_equal(app.fault, HD_FAULT_NONE);
    }
}

/* the position loop's feedback source: an offset of the output encoder reading is
 * followed at once in full closed, never in semi-closed, slowly in dual-loop; the
 * velocity feedback is the motor encoder in semi-closed even with vel_fb_src = 1 */
static void test_fb_source(void **st)
{
    (void)st;
    gear_params();
    P.gear_on = 0;                       /* motor / N = output: no offsets here */
    run(10);
    double moved[3];
    for (int32_t kind = 0; kind <= 2; kind++) {
        P.out_offset = 0;
        assert_int_equal(hd_app_set_mode(&app, HD_MODE_OFF), 0);
        run(3);
        assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, kind), 0);
        assert_int_equal(hd_app_set_mode(&app, HD_MODE_POSITION), 0);
        run(2000);
        const double th0 = P.th;
        P.out_offset = 30.0 * ARCSEC_TURN;   /* the output encoder reads 30" more */
        run(300);                            /* 30 ms */
        moved[kind] = (P.th - th0) / ARCSEC_TURN;
        printf("# fb_config %d: axis moved %.2f arcsec 30 ms after a 30\" output-encoder offset\n",
               kind, moved[kind]);
    }
    assert_true(moved[0] < -10.0);                    /* full closed: follows the encoder */
    assert_true(fabs(moved[1]) < 0.2);                /* semi-closed: only measured */
    assert_true(moved[2] < -0.5 && moved[2] > -10.0); /* dual: at 2 Hz, slower than the loop */

    /* velocity feedback: vel_fb_src 1 (output encoder) applies in full closed only */
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_OFF), 0);
    run(3);
    assert_int_equal(hd_app_param_set(&app, HD_P_VEL_FB_SRC, 1), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, HD_FB_SEMI_CLOSED), 0);
    run(1);
    const int32_t v_mot = hdf_sat32(hd_div64_rnd(hd_velobs_vel48(&app.obs_mot), 100 * 65536));
    assert_int_equal(app.tel.vel_out, v_mot);
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, HD_FB_FULL_CLOSED), 0);
    run(1);
    assert_int_equal(app.tel.vel_out, app.tel.vel_out_enc);
}

/* the motor-side estimate of the output: semi-closed, holding against a load, the
 * OUTPUT lands on the reference only with the TE and compliance compensators */
static void test_fb_semi_closed_estimate(void **st)
{
    (void)st;
    gear_params();
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, HD_FB_SEMI_CLOSED), 0);
    P.t_load = -20.0;                    /* 20 N.m held: twist 118" on the three slopes */
    run(10);
    const uint32_t sets[2] = {0u, HD_CB_TE | HD_CB_COMPLIANCE};
    double err[2][2];
    for (int s = 0; s < 2; s++) {
        assert_int_equal(hd_app_set_mode(&app, HD_MODE_OFF), 0);
        run(3);
        assert_int_equal(hd_app_param_set(&app, HD_P_CB_ENABLE, (int32_t)sets[s]), 0);
        assert_int_equal(hd_app_set_mode(&app, HD_MODE_POSITION), 0);
        /* two targets at different wave-generator phases */
        for (int t = 0; t < 2; t++) {
            const hd_angle_t target = app.pos_cmd + (hd_angle_t)llround((t ? 0.37 : 0.11) / 360.0 * TURN);
            hd_app_set_position(&app, target);
            run(20000);
            err[s][t] = (out_true() - (double)target / TURN) / ARCSEC_TURN;
            assert_int_equal(app.fault, HD_FAULT_NONE);
        }
        printf("# semi-closed, 20 N.m load, cb_enable %u: output error %.2f / %.2f arcsec\n",
               sets[s], err[s][0], err[s][1]);
    }
    /* without: the twist (118") and TE (up to 20") stay in the output */
    assert_true(fabs(err[0][0]) > 90.0 && fabs(err[0][1]) > 90.0);
    /* with: the estimate predicts them */
    assert_true(fabs(err[1][0]) < 1.0 && fabs(err[1][1]) < 1.0);
}

/* The output-encoder observer runs only while its velocity is used (vel_fb_src 1 in
 * full closed, STAB): off it costs nothing and reads 0; switched on while the axis
 * turns it starts at the motor side's velocity (no transient from 0), and it
 * follows the output encoder from there. */
static void test_out_observer_on_use(void **st)
{
    (void)st;
    assert_int_equal(hd_app_param_set(&app, HD_P_FAULT_ENABLE, 0), 0);
    P.gear_on = 0;
    P.w = 0.01;                                          /* 0.01 turn/s, coasting (OFF) */
    const double v_true = 0.01 * TURN;                   /* 2^-32 turn/s */
    run(3000);
    assert_int_equal(app.obs_out_run, 0u);
    assert_int_equal(app.tel.vel_out_enc, 0);
    assert_true(fabs(app.tel.vel_out - v_true) < 0.02 * v_true);   /* motor / N */
    assert_int_equal(hd_app_param_set(&app, HD_P_VEL_FB_SRC, 1), 0);
    run(1);
    assert_int_equal(app.obs_out_run, 1u);
    printf("# output observer switched on at 0.01 turn/s: first velocity %.4f turn/s\n",
           app.tel.vel_out_enc / TURN);
    assert_true(fabs(app.tel.vel_out_enc - v_true) < 0.02 * v_true);
    assert_int_equal(app.tel.vel_out, app.tel.vel_out_enc);          /* the loop's feedback */
    double worst = 0.0;
    for (int k = 0; k < 3000; k++) {
        run(1);
        const double e = fabs(app.tel.vel_out_enc - v_true);
        if (e > worst) worst = e;
    }
    printf("# output observer: worst velocity error over 0.3 s %.2f%%\n", 100.0 * worst / v_true);
    assert_true(worst < 0.05 * v_true);
    assert_int_equal(hd_app_param_set(&app, HD_P_VEL_FB_SRC, 0), 0);
    run(1);
    assert_int_equal(app.obs_out_run, 0u);
    assert_int_equal(app.tel.vel_out_enc, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_compliance_twist),
        cmocka_unit_test(test_fb_motor_exact),
        cmocka_unit_test(test_fb_dual_blend),
        cmocka_unit_test_setup(test_fb_refused_while_enabled, setup),
        cmocka_unit_test_setup(test_fb_bumpless, setup),
        cmocka_unit_test_setup(test_fb_source, setup),
        cmocka_unit_test_setup(test_fb_semi_closed_estimate, setup),
        cmocka_unit_test_setup(test_out_observer_on_use, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
