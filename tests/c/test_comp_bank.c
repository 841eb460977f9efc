/*
 * test_comp_bank.c - the compensator bank in the drive app (sanitized build):
 * configuration from the parameter table, Preisach table install (bad images
 * refused, the old table kept), bumpless switching of every compensator while
 * running (closed loop on a simple rigid axis with Coulomb friction, in this
 * file), and the friction feed-forward doing its job (it takes over the
 * velocity integrator's work).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "hd_app.h"
#include "hd_fixed.h"

/* ---- a rigid output-referred axis with Coulomb + viscous friction (double, test only) ---- */
#define N_RATIO 100
#define TEST_PI 3.14159265358979323846
static struct {
    double th, w;           /* output angle rad, rad/s */
    double fc, fv, j;       /* N.m, N.m s/rad, kg m^2 */
    hd_hal_command_t cmd;
    uint32_t tick;
} P;

uint32_t hd_hal_tick(void) { return P.tick; }
void hd_hal_read_sensors(hd_hal_sensors_t *s)
{
    const double turns = P.th / (2.0 * TEST_PI);
    const double mt = turns * N_RATIO;
    s->motor_enc_raw = (uint32_t)(int64_t)floor((mt - floor(mt)) * 131072.0);
    s->output_enc_raw = (uint32_t)((int64_t)floor(turns * 16777216.0) & 0xFFFFFF);
    s->current = 0;
    s->gyro_rate = 0;
    s->valid = HD_HAL_VALID_ALL;
}
void hd_hal_write_command(const hd_hal_command_t *c) { P.cmd = *c; P.tick++; }
bool hd_hal_can_send(const hd_can_frame_t *f) { (void)f; return false; }
bool hd_hal_can_recv(hd_can_frame_t *f) { (void)f; return false; }
uint32_t hd_hal_nvm_size(void) { return 4096u; }
uint32_t hd_hal_nvm_page_size(void) { return 2048u; }
int32_t hd_hal_nvm_read(uint32_t o, void *b, uint32_t n) { (void)o; memset(b, 0xFF, n); return 0; }
int32_t hd_hal_nvm_write(uint32_t o, const void *b, uint32_t n) { (void)o; (void)b; (void)n; return -1; }
int32_t hd_hal_nvm_erase(uint32_t o, uint32_t n) { (void)o; (void)n; return -1; }

static void plant_step(void)
{
    const double t = P.cmd.enable ? P.cmd.torque / 65536.0 * N_RATIO : 0.0;
    const double h = 1e-4 / 10;
    for (int i = 0; i < 10; i++) {
        double f;
        if (fabs(P.w) < 1e-7 && fabs(t) <= P.fc) { P.w = 0; continue; }
        f = (P.w > 0 ? P.fc : (P.w < 0 ? -P.fc : (t > 0 ? P.fc : -P.fc))) + P.fv * P.w;
        const double w1 = P.w + h * (t - f) / P.j;
        if ((P.w > 0 && w1 < 0) || (P.w < 0 && w1 > 0)) P.w = 0; else P.w = w1;
        P.th += h * P.w;
    }
}

static hd_app_t app;

static void start_rate(double deg_s)
{
    memset(&P, 0, sizeof P);
    P.fc = 8.0; P.fv = 5.0; P.j = 1.3;
    hd_app_init(&app);
    assert_int_equal(hd_app_param_set(&app, HD_P_FAULT_ENABLE, 0), 0);
    /* the compensators' friction model = this axis (8 N.m Coulomb, 5 N.m s/rad) */
    static const hd_param_id_t T8[] = {HD_P_STR_FC_POS, HD_P_STR_FS_POS, HD_P_STR_FC_NEG, HD_P_STR_FS_NEG,
                                       HD_P_LUG_FC, HD_P_LUG_FS};
    for (size_t i = 0; i < sizeof T8 / sizeof T8[0]; i++) assert_int_equal(hd_app_param_set(&app, T8[i], 8 << 16), 0);
    const int32_t fv = (int32_t)llround(5.0 * 2.0 * TEST_PI * 65536.0);
    assert_int_equal(hd_app_param_set(&app, HD_P_STR_FV_POS, fv), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_STR_FV_NEG, fv), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_LUG_SIGMA2, fv), 0);
    hd_app_step(&app); plant_step();
    hd_app_set_rate(&app, (hd_vel_out_t)llround(deg_s / 360.0 * 4294967296.0));
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_RATE), 0);
}

static double err_arcsec(void)
{
    return (double)(app.tel.pos_ref - app.tel.pos_out) / 4294967296.0 * 1296000.0;
}

static void test_config_defaults(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    hd_params_defaults(p);
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    assert_int_equal(c.enable, 0u);
    assert_true(c.mx.compliance > 0);
    assert_true(c.dpos_alpha > 0 && c.dpos_alpha < HD_Q30_ONE);
    /* inconsistent backstepping bounds are refused through the app, old value kept */
    hd_app_init(&app);
    const int32_t old = hd_app_param_get(&app, HD_P_BS_MIN1);
    assert_int_equal(hd_app_param_set(&app, HD_P_BS_MIN1, hd_app_param_get(&app, HD_P_BS_MAX1) + 1), -1);
    assert_int_equal(hd_app_param_get(&app, HD_P_BS_MIN1), old);
}

static void test_table_install(void **st)
{
    (void)st;
    static hd_preisach_table_t t;
    memset(&t, 0, sizeof t);
    t.version = 3u; t.levels = 4u; t.sub_bits = 0u; t.in_shift = 4u; t.u0 = -24; t.unit = 0u;
    for (uint32_t i = 0; i < 4u; i++)
        for (uint32_t j = 0; j < i; j++) t.e[i * (i + 1u) / 2u + j] = (int32_t)(i - j) * 1000;
    hd_preisach_seal(&t);
    hd_app_init(&app);
    assert_int_equal(app.cb.table_ok, 0u);
    assert_int_equal(hd_app_comp_table(&app, &t), HD_PREISACH_OK);
    assert_int_equal(app.cb.table_ok, 1u);
    t.e[1] ^= 1;                                   /* CRC no longer matches */
    t.version = 4u;
    assert_int_equal(hd_app_comp_table(&app, &t), HD_PREISACH_E_CRC);
    assert_int_equal(app.cb.table.version, 3u);    /* old table in force */
}

/* Switch each compensator (and all together) on at 1.0 s and off at 2.0 s of a
 * 0.01 deg/s move; the torque command may change per period by no more than
 * the ramp slope of the full compensator output plus what the loop does
 * without switching, and the position error must stay within 2 arcsec of the
 * run without switching. */
static void run_switch(uint32_t bits, double *max_dt, double *max_de, double *max_de_off)
{
    static double ref_e[30000], ref_t[30000];
    start_rate(0.01);
    for (int k = 0; k < 30000; k++) {
        hd_app_step(&app); plant_step();
        ref_e[k] = err_arcsec();
        ref_t[k] = app.tel.torque_cmd / 65536.0;
    }
    double ref_max = 0;
    for (int k = 9000; k < 30000; k++) if (fabs(ref_e[k]) > ref_max) ref_max = fabs(ref_e[k]);
    start_rate(0.01);
    assert_int_equal(hd_app_param_set(&app, HD_P_CB_RAMP_TICKS, 10000), 0);   /* 1 s ramps */
    *max_dt = 0; *max_de = 0; *max_de_off = 0;
    double tprev = 0;
    for (int k = 0; k < 30000; k++) {
        if (k == 10000) assert_int_equal(hd_app_param_set(&app, HD_P_CB_ENABLE, (int32_t)bits), 0);
        if (k == 20000) assert_int_equal(hd_app_param_set(&app, HD_P_CB_ENABLE, 0), 0);
        hd_app_step(&app); plant_step();
        const double tq = app.tel.torque_cmd / 65536.0;
        if (k > 9000) {
            const double d = fabs((tq - tprev) - (ref_t[k] - ref_t[k - 1]));
            if (d > *max_dt) *max_dt = d;
            /* |error| beyond the largest |error| of the run without switching (same window) */
            const double de = fabs(err_arcsec()) - ref_max;
            if (k < 20000 && de > *max_de) *max_de = de;
            if (k >= 20000 && de > *max_de_off) *max_de_off = de;
        }
        tprev = tq;
    }
}

static void test_bumpless_switching(void **st)
{
    (void)st;
    static const uint32_t sets[] = {HD_CB_STRIBECK, HD_CB_LUGRE, HD_CB_MAXWELL, HD_CB_TE, HD_CB_BACKSTEP,
                                    HD_CB_STRIBECK | HD_CB_MAXWELL | HD_CB_TE};
    for (size_t i = 0; i < sizeof sets / sizeof sets[0]; i++) {
        double dt, de, doff;
        run_switch(sets[i], &dt, &de, &doff);
        print_message("cb_enable 0x%02x: max extra torque step %.4f N.m/period, |error| beyond the unswitched "
                      "run's max: on %.3f, off %.3f arcsec\n", (unsigned)sets[i], dt, de, doff);
        /* no torque step: the extra change per period stays far below the 8 N.m the FF carries */
        assert_true(dt < 0.1);
        /* switching on/off: while a friction FF (Stribeck, LuGre) ramps, the app takes the
         * ramp's part of it, (w_k - w_k-1) x raw torque, off the velocity integrator
         * (hand-over), so the output hardly moves: before the hand-over the FF displaced the
         * integrator by dT / (ki_v Kp_p T_r) = 5.5 arcsec on (8 N.m over 1 s) and ~12.5 off;
         * now Stribeck 0.05, LuGre 1.5 on (its bristle state) / 0.05 off; Maxwell, TE < 0.25 */
        assert_true(de < 2.0);
        assert_true(doff < 1.0);
    }
}

/* At constant rate the Stribeck feed-forward carries the friction: the
 * velocity integrator's share of the torque drops to a small remainder. */
static void test_friction_ff_takes_over(void **st)
{
    (void)st;
    start_rate(0.1);
    assert_int_equal(hd_app_param_set(&app, HD_P_CB_ENABLE, (int32_t)HD_CB_STRIBECK), 0);
    for (int k = 0; k < 30000; k++) { hd_app_step(&app); plant_step(); }
    const double tq = app.tel.torque_cmd / 65536.0;
    const double ff = app.cb.out.tff / 65536.0;
    print_message("torque %.3f N.m, feed-forward %.3f N.m\n", tq, ff);
    assert_true(ff > 7.0);
    assert_true(fabs(tq - ff) < 2.5);
}

/* fe_feed: the Stribeck FF moves from the str_* map to the online estimate over fe_ramp
 * estimator steps (every fe_decim periods), and back when switched off */
static void test_online_estimate_feeds_the_ff(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t out;
    hd_stribeck_cfg_t fed;
    const int32_t v = 2 * 11930465;              /* 2 deg/s */
    int32_t prev;
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_STRIBECK;
    p[HD_P_FE_ENABLE] = 1;
    p[HD_P_FE_FEED] = 0;
    p[HD_P_FE_DECIM] = 10;
    p[HD_P_FE_RAMP] = 20;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    in.vel_ref = v;
    in.vel_fb = v;
    /* an estimate unlike the parameters (as a fit would publish it) */
    b.fe.fits[HD_FE_DIR_POS] = 1u;
    b.fe.fits[HD_FE_DIR_NEG] = 1u;
    b.fe.est[HD_FE_DIR_POS].fc = 3 << 16;
    b.fe.est[HD_FE_DIR_POS].fs = 5 << 16;
    b.fe.est[HD_FE_DIR_POS].fv = 100 << 16;
    fed = c.str;
    fed.pos = b.fe.est[HD_FE_DIR_POS];
    fed.neg = b.fe.est[HD_FE_DIR_NEG];
    fed.delta = 2u;
    const int32_t t_param = hd_stribeck_map(&c.str, v), t_est = hd_stribeck_map(&fed, v);
    assert_true(abs(t_param - t_est) > (2 << 16));
    hd_comp_bank_pre(&b, &c, &in, &out);
    assert_int_equal(out.tff, t_param);
    p[HD_P_FE_FEED] = 1;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_apply(&b, &c);
    prev = t_param;
    for (int k = 0; k < 10 * 25; k++) {
        hd_comp_bank_fric_est(&b, &c, 0, 0, 0, false);     /* no data: the estimate stays */
        while (hd_comp_bank_fric_est_work(&b)) {            /* the background, as the simulator runs it */
        }
        hd_comp_bank_pre(&b, &c, &in, &out);
        /* monotone, at most 1/20 of the difference (+ rounding) per estimator step */
        assert_true(abs(out.tff - prev) <= abs(t_est - t_param) / 20 + 2);
        assert_true((t_est < t_param) ? out.tff <= prev : out.tff >= prev);
        prev = out.tff;
    }
    assert_int_equal(out.tff, t_est);
    p[HD_P_FE_FEED] = 0;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_apply(&b, &c);
    for (int k = 0; k < 10 * 25; k++) {
        hd_comp_bank_fric_est(&b, &c, 0, 0, 0, false);
        while (hd_comp_bank_fric_est_work(&b)) {
        }
        hd_comp_bank_pre(&b, &c, &in, &out);
    }
    assert_int_equal(out.tff, t_param);
}

/* The bank with the Stribeck FF and the online estimator on (a step every 10 periods,
 * 2 steps to settle), configured from the defaults and initialised. */
static void fe_bank_start(int32_t p[HD_PARAM_COUNT], hd_comp_bank_cfg_t *c, hd_comp_bank_t *b)
{
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_STRIBECK;
    p[HD_P_FE_ENABLE] = 1;
    p[HD_P_FE_DECIM] = 10;
    p[HD_P_FE_SETTLE] = 2;
    assert_int_equal(hd_comp_bank_config(c, p), 0);
    hd_comp_bank_init(b, c);
}

/* The control period's share of the online identification is its observation: with the
 * estimator on and steady data, hd_comp_bank_fric_est alone (the control period) neither
 * samples nor fits (the sample's 7 parts and a fit pass's up to 16 are the background's,
 * hd_comp_bank_fric_est_work: no period carries them); the background then takes the
 * queued steps' samples. */
static void test_fric_est_period_only_observes(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    const int32_t v = 2 * 11930465;              /* 2 deg/s */
    uint32_t k;
    fe_bank_start(p, &c, &b);
    for (k = 0; k < 10u * 100u; k++) {
        hd_comp_bank_fric_est(&b, &c, v, v, 7 << 16, true);
    }
    assert_int_equal(b.fe.samples, 0u);
    assert_int_equal(b.fe.fits[HD_FE_DIR_POS] + b.fe.fits[HD_FE_DIR_NEG], 0u);
    for (k = 0; k < HD_FE_NBIN; k++) {
        assert_int_equal(b.fe.bin[HD_FE_DIR_POS][k].n, 0u);
    }
    /* the observations beyond the queue were lost while no background ran (counted); with
     * the background the steady steps are sampled */
    assert_int_equal(b.fe.q_drop, 100u - HD_FE_QLEN);
    while (hd_comp_bank_fric_est_work(&b)) {
    }
    for (k = 0; k < 10u * 100u; k++) {
        hd_comp_bank_fric_est(&b, &c, v, v, 7 << 16, true);
        while (hd_comp_bank_fric_est_work(&b)) {
        }
    }
    assert_true(b.fe.samples > 50u);
    assert_int_equal(b.fe.q_drop, 100u - HD_FE_QLEN);
}

/* A parameter change that empties the bins (new binning) while the background is inside a
 * part (the control period preempted it) leaves the background's state alone and applies
 * in the first period after that part: the part never sees half-changed state. */
static void test_fric_est_change_waits_for_the_background(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    const int32_t v = 2 * 11930465;
    uint32_t k;
    fe_bank_start(p, &c, &b);
    for (k = 0; k < 10u * 100u; k++) {
        hd_comp_bank_fric_est(&b, &c, v, v, 7 << 16, true);
        while (hd_comp_bank_fric_est_work(&b)) {
        }
    }
    const uint32_t n = b.fe.samples;
    assert_true(n > 10u);
    b.fe.busy = 1u;                              /* a background part in progress */
    p[HD_P_FE_V_MIN] = p[HD_P_FE_V_MIN] * 2;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_apply(&b, &c);
    hd_comp_bank_fric_est(&b, &c, v, v, 7 << 16, true);
    assert_int_equal(b.fe.samples, n);           /* untouched */
    assert_true(b.fe_cfg.v_min != c.fe.v_min);
    assert_true(b.fe_pend != 0u);
    b.fe.busy = 0u;                              /* the part ends */
    hd_comp_bank_fric_est(&b, &c, v, v, 7 << 16, true);
    assert_int_equal(b.fe.samples, 0u);          /* the new binning: empty bins */
    assert_int_equal(b.fe_cfg.v_min, c.fe.v_min);
    assert_int_equal(b.fe_pend, 0u);
}

/* The str_* map written after the bank started (the host writes one object at a time, the
 * estimator already running): with fe_feed and no fit yet the FF is the map just written, in
 * both directions, not the defaults the estimator started from (an axis with 1/5 of the
 * default friction got 5x its friction fed forward at every reversal) */
static void test_online_feed_without_fit_is_the_written_map(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t out;
    const int32_t v = 11930465 / 4;              /* 0.25 deg/s */
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_STRIBECK;
    p[HD_P_FE_ENABLE] = 1;
    p[HD_P_FE_FEED] = 1;
    p[HD_P_FE_DECIM] = 10;
    p[HD_P_FE_RAMP] = 20;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_init(&b, &c);
    /* csf17_50-like levels: 1.4 / 1.9 N.m, vs 0.0032 turn/s, fv 8.5 N.m/(turn/s) */
    p[HD_P_STR_FC_POS] = 91750;
    p[HD_P_STR_FS_POS] = 124518;
    p[HD_P_STR_FC_NEG] = 87000;
    p[HD_P_STR_FS_NEG] = 118000;
    p[HD_P_STR_VS_POS] = 13743895;
    p[HD_P_STR_VS_NEG] = 13743895;
    p[HD_P_STR_FV_POS] = 557056;
    p[HD_P_STR_FV_NEG] = 557056;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_apply(&b, &c);
    memset(&in, 0, sizeof in);
    for (int k = 0; k < 10 * 25; k++) {
        hd_comp_bank_fric_est(&b, &c, 0, 0, 0, false);     /* no data: no fit */
        while (hd_comp_bank_fric_est_work(&b)) {
        }
    }
    for (int sg = -1; sg <= 1; sg += 2) {
        in.vel_ref = sg * v;
        in.vel_fb = sg * v;
        hd_comp_bank_pre(&b, &c, &in, &out);
        const int32_t t_param = hd_stribeck_map(&c.str, sg * v);
        assert_true(abs(t_param) > (1 << 16));
        assert_int_equal(out.tff, t_param);
    }
}

/* Drive the bank's estimator steps (no data) until its feed ramp (fe_ramp 20) has settled. */
static void run_fe_steps(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    for (int k = 0; k < 10 * 25; k++) {
        hd_comp_bank_fric_est(b, c, 0, 0, 0, false);
        while (hd_comp_bank_fric_est_work(b)) {         /* the background, as the simulator runs it */
        }
    }
}

/* fe_feed: the reversal's torque jump is g_pos + g_neg; an unbalance present while the bins
 * filled is + d0 in one direction's estimate and - d0 in the other's.  With a fit of one
 * direction only the FF keeps the written map in both (the fit's d0 would go into the jump);
 * once both directions have a fit it feeds both, levels times fe_share (the written levels'
 * share of the total friction), shape (vs, fv) as estimated. */
static void test_online_feed_needs_both_directions_and_relays_the_share(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t out;
    hd_stribeck_cfg_t fed;
    const int32_t v = 2 * 11930465;              /* 2 deg/s */
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_STRIBECK;
    p[HD_P_FE_ENABLE] = 1;
    p[HD_P_FE_FEED] = 1;
    p[HD_P_FE_DECIM] = 10;
    p[HD_P_FE_RAMP] = 20;
    p[HD_P_FE_SHARE] = 3 << 14;                  /* 0.75 */
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    assert_int_equal(c.fe_share, 3 << 14);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    /* a fit of the positive direction only: 4 / 6 N.m (the friction + an unbalance of 2 N.m) */
    b.fe.fits[HD_FE_DIR_POS] = 3u;
    b.fe.est[HD_FE_DIR_POS].fc = 4 << 16;
    b.fe.est[HD_FE_DIR_POS].fs = 6 << 16;
    run_fe_steps(&b, &c);
    for (int sg = -1; sg <= 1; sg += 2) {
        in.vel_ref = sg * v;
        in.vel_fb = sg * v;
        hd_comp_bank_pre(&b, &c, &in, &out);
        fed = c.str;
        fed.delta = 2u;
        assert_int_equal(out.tff, hd_stribeck_map(&fed, sg * v));
    }
    /* the negative direction's fit arrives: 0.5 / 2 N.m (- 2 N.m of the unbalance) */
    b.fe.fits[HD_FE_DIR_NEG] = 1u;
    b.fe.est[HD_FE_DIR_NEG].fc = 1 << 15;
    b.fe.est[HD_FE_DIR_NEG].fs = 2 << 16;
    run_fe_steps(&b, &c);
    fed = c.str;
    fed.delta = 2u;
    fed.pos = b.fe.est[HD_FE_DIR_POS];
    fed.neg = b.fe.est[HD_FE_DIR_NEG];
    fed.pos.fc = 3 << 16;                        /* levels x 0.75 */
    fed.pos.fs = (9 << 16) / 2;
    fed.neg.fc = 3 << 13;
    fed.neg.fs = 3 << 15;
    assert_memory_equal(&b.fe_str.pos, &fed.pos, sizeof fed.pos);
    assert_memory_equal(&b.fe_str.neg, &fed.neg, sizeof fed.neg);
    for (int sg = -1; sg <= 1; sg += 2) {
        in.vel_ref = sg * v;
        in.vel_fb = sg * v;
        hd_comp_bank_pre(&b, &c, &in, &out);
        assert_int_equal(out.tff, hd_stribeck_map(&fed, sg * v));
    }
}

/* Maxwell-slip compliance format (2^-44 turn/N.m): a soft gear (5e3 N.m/rad) and a
 * stiff one (2e5 N.m/rad) both fit, within 1e-6 relative; below 2^13 N.m/turn refused. */
static void test_maxwell_stiffness_range(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    static const double k_rad[2] = {5e3, 2e5};
    hd_params_defaults(p);
    for (int i = 0; i < 2; i++) {
        const double k_turn = k_rad[i] * 2.0 * TEST_PI;
        p[HD_P_MX_STIFFNESS] = (int32_t)llround(k_turn * 256.0);
        assert_int_equal(hd_comp_bank_config(&c, p), 0);
        const double comp = (double)c.mx.compliance / 17592186044416.0;   /* 2^44 */
        assert_true(fabs(comp * k_turn - 1.0) < 1e-6);
    }
    p[HD_P_MX_STIFFNESS] = 8000 * 256;                                   /* < 2^13 N.m/turn */
    assert_int_equal(hd_comp_bank_config(&c, p), -1);
}

/* Scheduled position integral: weight 0 at and below cb_pki_vlo (the state leaks
 * to 0), 1 at and above cb_pki_vhi, monotone and continuous between; in closed
 * loop at 0.1 deg/s it integrates, and when the reference stops it hands back. */
static void test_pki_schedule(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    hd_params_defaults(p);
    p[HD_P_CB_PKI] = 900 << 16;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    assert_true(c.pki_vlo > 0 && c.pki_vhi > c.pki_vlo);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    in.pos_ref = (hd_angle_t)1 << 20;                    /* constant error 2^-12 turn */
    int32_t wprev = -1;
    for (int64_t v = 0; v <= 2 * (int64_t)c.pki_vhi; v += c.pki_vhi / 64) {
        in.vel_ref = (hd_vel_out_t)-v;                   /* the schedule is on |v| */
        hd_comp_bank_pre(&b, &c, &in, &o);
        if (v <= c.pki_vlo) assert_int_equal(b.pki_w, 0);
        if (v >= c.pki_vhi) assert_int_equal(b.pki_w, HD_Q30_ONE);
        assert_true(b.pki_w >= wprev);
        if (wprev >= 0) assert_true(b.pki_w - wprev < HD_Q30_ONE / 20);   /* no step */
        wprev = b.pki_w;
    }
    assert_true(b.pki_i > 0 && o.dvel > 0);               /* positive error: positive velocity term */
    const int32_t dv_on = o.dvel;
    in.vel_ref = 0;                                      /* standstill: leak to 0 at cb_pki_leak (2 1/s) */
    hd_comp_bank_pre(&b, &c, &in, &o);
    assert_true(o.dvel > 0 && o.dvel <= dv_on);           /* continuous: no jump */
    for (int k = 0; k < 100000; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    assert_true(b.pki_i == 0 && o.dvel == 0);
    /* cb_pki = 0 (default): never integrates */
    p[HD_P_CB_PKI] = 0;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    in.vel_ref = 4 * c.pki_vhi;
    for (int k = 0; k < 1000; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    assert_true(b.pki_i == 0 && o.dvel == 0);
    /* inconsistent schedule refused */
    p[HD_P_CB_PKI_VLO] = p[HD_P_CB_PKI_VHI] + 1;
    assert_int_equal(hd_comp_bank_config(&c, p), -1);
}

/* Preisach torque estimate, model source (default): (1 - share) F(v_ref) + J_L a_ref,
 * independent of the torque command (the loop's reaction). */
static void test_preisach_model_torque(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    hd_comp_bank_cfg_t c;
    hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_PREISACH;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    assert_int_equal(c.pr_t_src, 1u);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    in.vel_ref = (hd_vel_out_t)llround(1.0 / 360.0 * 4294967296.0);      /* 1 deg/s */
    in.acc_ref = (hd_acc_t)llround(10.0 / 360.0 * 16777216.0);           /* 10 deg/s^2 */
    hd_comp_bank_end(&b, 50 << 16);                                      /* a large command: ignored */
    hd_comp_bank_pre(&b, &c, &in, &o);
    const double share = p[HD_P_PR_MOTOR_SHARE] / 1073741824.0;
    const double jl = p[HD_P_PR_JL] / 65536.0;
    const double expect = (1.0 - share) * b.str.tau_raw / 65536.0 + jl * 10.0 * TEST_PI / 180.0;
    print_message("model torque %.4f N.m, expected %.4f\n", b.pr_test / 65536.0, expect);
    assert_true(fabs(b.pr_test / 65536.0 - expect) < 1e-3);
}


/* The bank's Preisach twist at a transmitted torque of 3 N.m (J_L a_ref; semi-closed, so
 * dpos is the twist itself) from a linear gear spring K = 31000 N.m/rad given as either
 * image direction: a torque -> twist table (HD_PREISACH_UNIT_TORQUE_TWIST, the image
 * hdservo identify writes) runs forward, a twist -> torque table through its inverse; both
 * must predict T / K within half a lattice step.  (Running the inverse of a torque -> twist
 * image returns a torque lattice value as a "twist": 8 N.m of Q15.16 instead of 20".) */
static int64_t preisach_dpos_at_3nm(const hd_preisach_table_t *t)
{
    int32_t p[HD_PARAM_COUNT];
    static hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_PREISACH;
    p[HD_P_FB_CONFIG] = 1;                                               /* semi-closed: raw dpos */
    p[HD_P_PR_JL] = 1 << 16;                                             /* J_L 1 kg m^2 */
    p[HD_P_CB_RAMP_TICKS] = 1;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_init(&b, &c);
    assert_int_equal(hd_comp_bank_install_table(&b, t), HD_PREISACH_OK);
    memset(&in, 0, sizeof in);
    in.acc_ref = (hd_acc_t)llround(3.0 / (2.0 * TEST_PI) * 16777216.0);  /* 3 rad/s^2: 3 N.m */
    for (int k = 0; k < 4000; k++) hd_comp_bank_pre(&b, &c, &in, &o);   /* 0.4 s: the pr_fc low-pass settles */
    assert_true(llabs(b.pr_test - (3 << 16)) < 64);
    return o.dpos;
}

static void test_preisach_twist_both_directions(void **st)
{
    (void)st;
    static hd_preisach_table_t t;
    const double k_rad = 31000.0;
    const double lsb_per_nm = 1.0 / k_rad / (2.0 * TEST_PI) * 4294967296.0;   /* twist 2^-32 turn per N.m */
    const double expect = 3.0 * lsb_per_nm;
    /* torque -> twist: 17 levels of 1 N.m (in_shift 16) from -8 N.m, E = c (a - b) / 2 */
    memset(&t, 0, sizeof t);
    t.version = 1u; t.levels = 17u; t.sub_bits = 0u; t.in_shift = 16u; t.u0 = -(8 << 16);
    t.unit = HD_PREISACH_UNIT_TORQUE_TWIST;
    for (uint32_t i = 0; i < t.levels; i++)
        for (uint32_t j = 0; j < i; j++) t.e[i * (i + 1u) / 2u + j] = (int32_t)llround(lsb_per_nm * (double)(i - j) / 2.0);
    hd_preisach_seal(&t);
    const int64_t fwd = preisach_dpos_at_3nm(&t);
    print_message("torque -> twist image: dpos %lld LSB, expected %.0f\n", (long long)fwd, expect);
    assert_true(fabs((double)fwd - expect) <= 0.5 * lsb_per_nm);
    /* twist -> torque: 33 levels of 2^14 LSB of twist from -2^18, E = K' (a - b) / 2 */
    memset(&t, 0, sizeof t);
    t.version = 1u; t.levels = 33u; t.sub_bits = 0u; t.in_shift = 14u; t.u0 = -(1 << 18);
    t.unit = HD_PREISACH_UNIT_GENERIC;
    for (uint32_t i = 0; i < t.levels; i++)
        for (uint32_t j = 0; j < i; j++)
            t.e[i * (i + 1u) / 2u + j] = (int32_t)llround(65536.0 / lsb_per_nm * 16384.0 * (double)(i - j) / 2.0);
    hd_preisach_seal(&t);
    const int64_t inv = preisach_dpos_at_3nm(&t);
    print_message("twist -> torque image: dpos %lld LSB, expected %.0f\n", (long long)inv, expect);
    assert_true(fabs((double)inv - expect) <= 8192.0);
}

/* The model torque estimate holds the unbalance: at rest at an output angle of 60 deg with
 * pr_mgl 2 N.m it is 2 cos(60 deg) = 1 N.m (offset 0) and 2 cos(150 deg) (offset 0.25 turn), and the
 * compliance twist follows it (semi-closed: dpos = the twist).  Without pr_mgl the estimate
 * at rest is 0 and a position hold predicts no twist. */
static void test_twist_estimate_unbalance(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    static hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    static const double off_turn[2] = {0.0, 0.25};
    for (int i = 0; i < 2; i++) {
        hd_params_defaults(p);
        p[HD_P_CB_ENABLE] = (int32_t)HD_CB_COMPLIANCE;
        p[HD_P_FB_CONFIG] = 1;
        p[HD_P_CB_RAMP_TICKS] = 1;
        p[HD_P_PR_MGL] = 2 << 16;
        p[HD_P_PR_G_OFF] = (int32_t)llround(off_turn[i] * 4294967296.0);
        assert_int_equal(hd_comp_bank_config(&c, p), 0);
        hd_comp_bank_init(&b, &c);
        memset(&in, 0, sizeof in);
        in.pos_out = (hd_angle_t)llround(60.0 / 360.0 * 4294967296.0);
        for (int k = 0; k < 4000; k++) hd_comp_bank_pre(&b, &c, &in, &o);
        const double expect = 2.0 * cos((60.0 / 360.0 + off_turn[i]) * 2.0 * TEST_PI);
        const double twist = (double)hd_compliance_twist(&c.cp, (int32_t)llround(expect * 65536.0));
        print_message("offset %.2f turn: torque estimate %.4f N.m (expected %.4f), dpos %lld LSB (twist %.0f)\n",
                      off_turn[i], b.pr_test / 65536.0, expect, (long long)o.dpos, twist);
        assert_true(fabs(b.pr_test / 65536.0 - expect) < 1e-4);
        assert_true(fabs((double)o.dpos - twist) <= 2.0 && fabs(twist) > 1000.0);
    }
}

/* A hysteretic torque -> twist image (spring + relays 2 N.m wide, positive density): a newly
 * installed table predicts no twist at no torque (the gear demagnetised at rest), within two
 * lattice steps; from negative saturation the memory would keep that extreme's remanence at
 * every later torque above it (here -1 N.m of twist at 0 N.m). */
static void test_preisach_memory_starts_demagnetised(void **st)
{
    (void)st;
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
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_PREISACH;
    p[HD_P_FB_CONFIG] = 1;
    p[HD_P_CB_RAMP_TICKS] = 1;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_init(&b, &c);
    assert_int_equal(hd_comp_bank_install_table(&b, &t), HD_PREISACH_OK);
    memset(&in, 0, sizeof in);
    for (int k = 0; k < 100; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    print_message("twist at 0 N.m after the install: %lld LSB (lattice step %.0f)\n", (long long)o.dpos,
                  lsb_per_nm / 4.0);
    assert_true(fabs((double)o.dpos) <= lsb_per_nm / 2.0);
    /* the loop still has its width: +3 N.m and back to 0 leaves a positive remanence */
    in.acc_ref = (hd_acc_t)llround(3.0 / (2.0 * TEST_PI * 0.5) * 16777216.0);   /* pr_jl 0.5: 3 N.m */
    for (int k = 0; k < 4000; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    const int64_t at3 = o.dpos;
    in.acc_ref = 0;
    for (int k = 0; k < 4000; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    print_message("twist at 3 N.m %lld, back at 0 N.m %lld LSB\n", (long long)at3, (long long)o.dpos);
    assert_true(at3 > (int64_t)(3.0 * lsb_per_nm) && o.dpos > (int64_t)(0.5 * lsb_per_nm) && o.dpos < at3);
}

/* Output-side TE lines (te_out_*): in semi-closed the correction is -a sin(2 pi (n x + p)) at the
 * output position x the loop knows, on top of the wave-generator lines (here none), and it ramps
 * with the TE weight. */
static void test_te_output_lines(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    static hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    const double amp = 6.0 / 1296000.0, ph = 0.11;                       /* 6 arcsec, turn */
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_TE;
    p[HD_P_FB_CONFIG] = 1;
    p[HD_P_CB_RAMP_TICKS] = 1;
    p[HD_P_TE_N] = 0;
    p[HD_P_TE_OUT_ORDER1] = 1;
    p[HD_P_TE_OUT_AMP1] = (int32_t)llround(amp * 4294967296.0);
    p[HD_P_TE_OUT_PHASE1] = (int32_t)llround(ph * 4294967296.0);
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    assert_int_equal(c.te_out.n, 1u);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    for (int deg = -170; deg <= 180; deg += 35) {
        in.pos_out = (hd_angle_t)llround(deg / 360.0 * 4294967296.0) + ((hd_angle_t)3 << 32);   /* 3 turns on */
        in.pos_mot = in.pos_out * N_RATIO;
        /* TE runs once per schedule cycle (hd_sched.h): one cycle sees a step at the new position */
        for (int k = 0; k < (int)HD_SCHED_CYCLE; k++) hd_comp_bank_pre(&b, &c, &in, &o);
        const double expect = -amp * sin(2.0 * TEST_PI * (deg / 360.0 + ph)) * 4294967296.0;
        assert_true(fabs((double)o.dpos - expect) <= 2.0);
    }
    /* switched off: the correction ramps out with the wave-generator lines */
    c.enable = 0u;
    hd_comp_bank_apply(&b, &c);
    for (int k = 0; k < 2 * (int)HD_SCHED_CYCLE; k++) hd_comp_bank_pre(&b, &c, &in, &o);
    assert_int_equal(o.dpos, 0);
}

/* The schedule (hd_sched.h): the TE model runs once per cycle, in its slot, and between its
 * steps the correction follows the motor angle to within the second-order term of its slope
 * (a few LSB at this speed) instead of being held; the whole bank's outputs at the first period
 * after a start are complete (every compensator evaluated at once). */
static void test_schedule_te_once_per_cycle(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    static hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_TE;
    p[HD_P_FB_CONFIG] = 1;                       /* semi-closed: dpos is returned as it is */
    p[HD_P_CB_RAMP_TICKS] = 0;
    p[HD_P_TE_N] = 1;
    p[HD_P_TE_ORDER1] = 2;
    p[HD_P_TE_AMP1] = (int32_t)llround(12.0 / 1296000.0 * 4294967296.0);   /* 12 arcsec */
    p[HD_P_TE_PHASE1] = 0x2000000;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    const int64_t step = (int64_t)llround(0.5 / 10000.0 * 4294967296.0);   /* motor 0.5 turn/s */
    int64_t te_prev = 0;
    uint32_t changes = 0u;
    double worst = 0.0;
    for (uint32_t k = 0; k < 400u; k++) {
        in.pos_mot = ((hd_angle_t)7 << 32) + (hd_angle_t)k * step;
        const uint32_t tick = b.tick & (HD_SCHED_CYCLE - 1u);
        hd_comp_bank_pre(&b, &c, &in, &o);
        const double exact = -(double)hd_te_model(&c.te, in.pos_mot);
        if (k == 0u) {
            assert_true(fabs((double)o.dpos - exact) <= 1.0);        /* complete at the start */
        }
        if (k > 0u && b.te.te != te_prev) {
            assert_int_equal(tick, (uint32_t)HD_SLOT_TE);            /* the model ran in its slot only */
            changes++;
        }
        te_prev = b.te.te;
        worst = fmax(worst, fabs((double)o.dpos - exact));
    }
    print_message("TE between its steps vs every period: worst %.1f LSB (2^-32 turn), %u steps\n", worst, changes);
    assert_true(changes >= 400u / HD_SCHED_CYCLE - 1u);
    assert_true(worst <= 8.0);                                       /* 12" is 38,000 LSB */
}

/* The motor-side torque estimate of slot 4 (pr_t_src 2) is low-passed in the next period
 * the bank runs, before its readers (the Preisach ticks 5 .. 7, the compliance twist in
 * slot 2) and before the next estimate: slot 4 carries the estimate alone, the filter state
 * then moves once per cycle, in tick 5, by exactly the step of the estimate formed in tick 4.
 * The model's estimate (pr_t_src 1) is filtered in slot 4 itself.  A bank not run after
 * tick 4 until slot 2 filters it when it runs again, once, before the compliance twist
 * reads it. */
static void estimate_lowpass_tick(uint32_t src)
{
    int32_t p[HD_PARAM_COUNT];
    static hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    const uint32_t lp_tick = (src == 2u) ? (uint32_t)HD_SLOT_PREISACH : (uint32_t)HD_SLOT_MAXWELL_EST;
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)(HD_CB_PREISACH | HD_CB_COMPLIANCE);
    p[HD_P_PR_JL] = 1 << 16;
    p[HD_P_PR_T_SRC] = (int32_t)src;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    assert_int_equal(c.pr_t_src, src);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    uint32_t steps = 0u;
    int32_t test_k4 = 0;
    for (uint32_t n = 0; n < 200u; n++) {
        /* an acceleration that changes every period: every estimate is new */
        in.acc_ref = (hd_acc_t)llround((1.0 + 0.01 * n) / (2.0 * TEST_PI) * 16777216.0);
        const uint32_t k = b.tick & (HD_SCHED_CYCLE - 1u);
        const int64_t t_before = b.pr_t;
        const int32_t test_before = b.pr_test;
        hd_comp_bank_pre(&b, &c, &in, &o);
        if (n == 0u) {
            continue;                                   /* the first period: every part at once */
        }
        if (k == (uint32_t)HD_SLOT_MAXWELL_EST) {
            assert_true(b.pr_test != test_before);       /* the estimate itself in its slot */
            test_k4 = b.pr_test;
        } else {
            assert_int_equal(b.pr_test, test_before);
        }
        if (k == lp_tick) {
            /* the step of tick 4's estimate, as the filter's own arithmetic forms it */
            const int64_t tg = hdf_shl64_sat((int64_t)test_k4, 16u);
            const int64_t expect = hdf_add64_sat(t_before, hdf_mul64x32_q(hdf_sub64_sat(tg, t_before), c.pr_alpha, 30u));
            assert_true(b.pr_t == expect);
            assert_int_equal(b.pr_yd, hdf_sat32(hdf_asr64_rnd(expect, 16u)));
            assert_true(b.pr_t != t_before);
            steps++;
        } else {
            assert_true(b.pr_t == t_before);             /* once per cycle, in its tick only */
        }
    }
    assert_int_equal(steps, (199u - lp_tick) / HD_SCHED_CYCLE + 1u);
    /* skipped after tick 4 until tick 2 of the next cycle: filtered once, then read */
    while ((b.tick & (HD_SCHED_CYCLE - 1u)) != (uint32_t)HD_SLOT_MAXWELL_EST) {
        hd_comp_bank_pre(&b, &c, &in, &o);
    }
    const int64_t t3 = b.pr_t;
    hd_comp_bank_pre(&b, &c, &in, &o);
    const int64_t expect = hdf_add64_sat(t3, hdf_mul64x32_q(hdf_sub64_sat(hdf_shl64_sat((int64_t)b.pr_test, 16u), t3),
                                                            c.pr_alpha, 30u));
    b.tick = 2u;                                         /* ticks 5 .. 1 not run */
    hd_comp_bank_pre(&b, &c, &in, &o);
    assert_true(b.pr_t == expect);
    assert_int_equal(b.cp_dth, hd_blend_apply(&b.cp_blend, hd_compliance_twist(&c.cp, hdf_sat32(hdf_asr64_rnd(expect, 16u)))));
}

static void test_schedule_estimate_lowpass_tick(void **st)
{
    (void)st;
    estimate_lowpass_tick(2u);
    estimate_lowpass_tick(1u);
}

/* Backstepping on the schedule: the law every period (its output moves with the
 * velocity each period), the adapted parameters only in the backstepping slot,
 * by HD_SCHED_CYCLE periods' worth at once. */
static void test_schedule_backstep_adapts_in_its_slot(void **st)
{
    (void)st;
    int32_t p[HD_PARAM_COUNT];
    static hd_comp_bank_cfg_t c;
    static hd_comp_bank_t b;
    hd_comp_bank_in_t in;
    hd_comp_bank_out_t o;
    hd_params_defaults(p);
    p[HD_P_CB_ENABLE] = (int32_t)HD_CB_BACKSTEP;
    p[HD_P_CB_RAMP_TICKS] = 0;
    assert_int_equal(hd_comp_bank_config(&c, p), 0);
    hd_comp_bank_init(&b, &c);
    memset(&in, 0, sizeof in);
    in.pos_ref = (hd_angle_t)1 << 20;            /* a small position error: e2 != 0 */
    uint32_t adapts = 0u, laws = 0u;
    int32_t u_prev = 0;
    for (uint32_t k = 0; k < 64u; k++) {
        in.vel_fb = (int32_t)(1000 + 37 * (int32_t)k) << 12;
        int64_t th_before[HD_BS_NP];
        memcpy(th_before, b.bs.th, sizeof th_before);
        const uint32_t tick = b.tick & (HD_SCHED_CYCLE - 1u);
        hd_comp_bank_pre(&b, &c, &in, &o);
        const int32_t u = hd_comp_bank_post(&b, &c, &in, 0);
        if (memcmp(th_before, b.bs.th, sizeof th_before) != 0) {
            assert_int_equal(tick, (uint32_t)HD_SLOT_BACKSTEP);        /* adaptation in its slot only */
            adapts++;
        }
        if (k > 0u && u != u_prev) {
            laws++;
        }
        u_prev = u;
    }
    assert_true(adapts >= 64u / HD_SCHED_CYCLE - 1u);
    assert_int_equal(laws, 63u);                 /* the law follows the velocity every period */
}

/* The switched-off bank is skipped at the phase level (hd_app.c bank_idle, bs_idle,
 * fe_idle): a run with the skips and a run that calls hd_comp_bank_pre, _post and
 * _fric_est in every period (the flags forced to 0) are bit-identical, through a mode entry while the bank is off, switching
 * compensators on (same tick of the schedule, same state) and their ramp out; the
 * skip is in force while the bank is off and again once the ramps have settled. */
#define IDLE_RUN 26000
static void run_idle(int32_t fb_config, int force_call, int32_t *tq, int64_t *pref, uint32_t *tick,
                     uint32_t *idle_off, uint32_t *idle_end)
{
    memset(&P, 0, sizeof P);
    P.fc = 8.0; P.fv = 5.0; P.j = 1.3;
    hd_app_init(&app);
    assert_int_equal(hd_app_param_set(&app, HD_P_FAULT_ENABLE, 0), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_FB_CONFIG, fb_config), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_STR_FC_POS, 8 << 16), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_STR_FC_NEG, 8 << 16), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_CB_RAMP_TICKS, 1000), 0);
    hd_app_step(&app); plant_step();
    hd_app_set_rate(&app, (hd_vel_out_t)llround(0.05 / 360.0 * 4294967296.0));
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_RATE), 0);
    for (int k = 0; k < IDLE_RUN; k++) {
        if (k == 3001) assert_int_equal(hd_app_set_mode(&app, HD_MODE_RATE), 0);   /* loops restart */
        if (k == 5003) assert_int_equal(hd_app_param_set(&app, HD_P_CB_ENABLE,
            (int32_t)(HD_CB_STRIBECK | HD_CB_LUGRE | HD_CB_MAXWELL | HD_CB_DOB | HD_CB_BACKSTEP)), 0);
        if (k == 12000) assert_int_equal(hd_app_param_set(&app, HD_P_CB_ENABLE, 0), 0);
        if (k == 4000) *idle_off = app.cb_idle & app.bs_idle & app.fe_idle;
        if (force_call) {
            app.cb_idle = 0u;
            app.bs_idle = 0u;
            app.fe_idle = 0u;
        }
        hd_app_step(&app); plant_step();
        tq[k] = app.tel.torque_cmd;
        pref[k] = app.tel.pos_ref;
        tick[k] = app.cb.tick;
    }
    *idle_end = app.cb_idle & app.bs_idle & app.fe_idle;
}

static void test_idle_bank_skipped_bit_identical(void **st)
{
    (void)st;
    static int32_t tq0[IDLE_RUN], tq1[IDLE_RUN];
    static int64_t pr0[IDLE_RUN], pr1[IDLE_RUN];
    static uint32_t tk0[IDLE_RUN], tk1[IDLE_RUN];
    for (int32_t fb = 0; fb <= 1; fb++) {
        uint32_t off0, end0, off1, end1;
        run_idle(fb, 1, tq0, pr0, tk0, &off0, &end0);
        run_idle(fb, 0, tq1, pr1, tk1, &off1, &end1);
        assert_int_equal(off1, 1u);           /* skipped while off */
        assert_int_equal(end1, 1u);           /* and again after the ramp out */
        int32_t tmax = 0;
        for (int k = 0; k < IDLE_RUN; k++) {
            assert_int_equal(tq0[k], tq1[k]);
            assert_true(pr0[k] == pr1[k]);
            assert_int_equal(tk0[k], tk1[k]);
            if (k > 6000 && k < 12000 && abs(tq1[k]) > tmax) tmax = abs(tq1[k]);
        }
        assert_true(tmax > 4 << 16);          /* the compensators did act in between */
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_defaults),
        cmocka_unit_test(test_fric_est_period_only_observes),
        cmocka_unit_test(test_fric_est_change_waits_for_the_background),
        cmocka_unit_test(test_table_install),
        cmocka_unit_test(test_bumpless_switching),
        cmocka_unit_test(test_friction_ff_takes_over),
        cmocka_unit_test(test_online_estimate_feeds_the_ff),
        cmocka_unit_test(test_online_feed_without_fit_is_the_written_map),
        cmocka_unit_test(test_maxwell_stiffness_range),
        cmocka_unit_test(test_pki_schedule),
        cmocka_unit_test(test_preisach_model_torque),
        cmocka_unit_test(test_preisach_twist_both_directions),
        cmocka_unit_test(test_twist_estimate_unbalance),
        cmocka_unit_test(test_preisach_memory_starts_demagnetised),
        cmocka_unit_test(test_te_output_lines),
        cmocka_unit_test(test_schedule_te_once_per_cycle),
        cmocka_unit_test(test_schedule_estimate_lowpass_tick),
        cmocka_unit_test(test_schedule_backstep_adapts_in_its_slot),
        cmocka_unit_test(test_idle_bank_skipped_bit_identical),
        cmocka_unit_test(test_online_feed_needs_both_directions_and_relays_the_share),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
