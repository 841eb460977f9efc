/*
 * gv_foc.c - golden vectors and Cortex-M4 costs of the STM32G474 port's
 * hardware-independent kernels (issue 11):
 *   foc_step        one FOC current-loop period (stateful sequence)
 *   foc_svm         space-vector modulation
 *   ssi_decode      output-encoder frame decoding (CRC-6)
 *   enc_update      16-bit quadrature counter unwrapping (stateful)
 *   isr_worst_case  cost only (its vectors are the encoder sequence again):
 *                   one 10 kHz control period of the drive with EVERY
 *                   compensator of the app's compensator bank enabled
 *                   (cb_enable = HD_CB_ALL) in PTP mode, plus the port work
 *                   of that period: 2 FOC periods (20 kHz PWM: encoder update,
 *                   electrical angle, 2 ADC conversions, hd_foc_step) and the
 *                   output-encoder frame decode.  The app is set up exactly as
 *                   control_step_full (gv_comp_bank.c): the same Preisach table
 *                   installed (the inverse runs), LuGre observer gain 30,
 *                   TE gain 2^20, ramps of 4 periods (every weight fully on),
 *                   16 periods of moving encoders before the measured one.
 *                   Backstepping is ON: in this firmware the backstepping law
 *                   runs AFTER the position/velocity PID (the PID output is the
 *                   blend base and keeps the cascade warm for a bumpless
 *                   switch-off), so "every compensator on" is the superset and
 *                   the more expensive of the two alternatives; the PID-only
 *                   alternative is kernel isr_worst_case_pid.
 *                   Register accesses, the SPI transfer and interrupt entry
 *                   are NOT included (see tests/bench/50_isr_load.py).
 *   isr_worst_case_pid  the same without backstepping (cost only).
 *   isr_worst_case_exc  the same period in the excitation mode (a multisine of 4
 *                   lines added to the held position) instead of PTP, per tick
 *                   (cost only).
 *   isr_worst_case_semi_t2  the same period semi-closed (fb_config 1, the compliance
 *                   compensator on too) with the twist torque of the Preisach inverse
 *                   estimated from the motor side (pr_t_src 2, hd_gear_torque), per
 *                   tick (cost only).
 *   isr_worst_case_fe_<kind>  isr_worst_case's worst tick (3) with the online
 *                   Stribeck identification on (fe_enable 1): the period of an
 *                   observation without a sample (observe), with one (sample: an
 *                   established visit paired with the other direction), the step's
 *                   last period with the estimate fed into the Stribeck FF, the weight
 *                   ramping (feed), and a period between them with a step queued for
 *                   the background (wait) (cost only).
 *   isr_worst_case_exc_fe_<kind>, isr_worst_case_semi_t2_fe_<kind>  the excitation and the
 *                   semi-closed (pr_t_src 2) periods with the online identification on, per
 *                   tick: the observation (observe), with a sample (sample, semi-closed: the
 *                   PTP move's reference is steady) and the feed's period (feed) (cost only).
 *   fe_background_step  the background's work of one step at its longest
 *                   (hd_app_background until false: the sample above, the last
 *                   candidate's residual and the close of a fit) (cost only).
 * The app step uses the stub hal of gv_app.c (linked into the same images).
 */
#include "gv.h"
#include "hal.h"
#include "hd_app.h"
#include "hd_foc.h"
#include "hd_encoder.h"
#include "hd_ssi.h"
#include "hd_fixed.h"
#include "hd_fric_est.h"
#include "hd_stribeck.h"

/* ---- foc_step ------------------------------------------------------------------------ */

static void foc_cfg(hd_foc_cfg_t *c)
{
    (void)hd_foc_design(c, 300, 300000, 900, 20000);
}

static void gen_foc(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_range(r, -30 * 65536, 30 * 65536);          /* ia */
    in[1] = hd_gv_rand_range(r, -30 * 65536, 30 * 65536);          /* ib */
    in[2] = hd_gv_u2s(hd_gv_rand32(r));                            /* theta */
    in[3] = hd_gv_rand_range(r, -5 * 65536, 5 * 65536);            /* id_ref */
    in[4] = hd_gv_rand_range(r, -25 * 65536, 25 * 65536);          /* iq_ref */
    in[5] = (idx % 61u == 7u) ? 0 : hd_gv_rand_range(r, 10 * 65536, 60 * 65536);   /* vbus, sometimes 0 */
    if (idx % 97u == 3u) {                                          /* edge values */
        in[0] = hd_gv_rand_edge32(r);
        in[1] = hd_gv_rand_edge32(r);
        in[4] = hd_gv_rand_edge32(r);
    }
}

static void run_foc(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_foc_t s;
    hd_foc_cfg_t c;
    hd_foc_in_t x;
    hd_foc_out_t y;
    uint32_t k;
    foc_cfg(&c);
    hd_foc_reset(&s);
    for (k = 0; k < count; k++) {
        const int32_t *v = &in[6u * k];
        int32_t *o = &out[7u * k];
        x.ia = v[0];
        x.ib = v[1];
        x.theta_e = hd_gv_s2u(v[2]);
        x.id_ref = v[3];
        x.iq_ref = v[4];
        x.vbus = v[5];
        hd_foc_step(&s, &c, &x, &y);
        o[0] = y.duty[0];
        o[1] = y.duty[1];
        o[2] = y.duty[2];
        o[3] = s.vd;
        o[4] = s.vq;
        o[5] = s.id;
        o[6] = s.iq;
    }
}

static volatile int32_t vol_in[6];
static volatile int32_t vol_out;

static void cost_foc(void)
{
    hd_foc_t s;
    hd_foc_cfg_t c;
    hd_foc_in_t x;
    hd_foc_out_t y;
    foc_cfg(&c);
    hd_foc_reset(&s);
    vol_in[0] = 3 * 65536; vol_in[1] = -2 * 65536; vol_in[2] = 0x12345678; vol_in[3] = 0;
    vol_in[4] = 5 * 65536; vol_in[5] = 48 * 65536;
    x.ia = vol_in[0]; x.ib = vol_in[1]; x.theta_e = hd_gv_s2u(vol_in[2]);
    x.id_ref = vol_in[3]; x.iq_ref = vol_in[4]; x.vbus = vol_in[5];
    hd_gv_cost_mark();
    hd_foc_step(&s, &c, &x, &y);
    hd_gv_cost_mark();
    vol_out = y.duty[0];
}

/* ---- foc_svm -------------------------------------------------------------------------- */

static void gen_svm(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_range(r, -40 * 65536, 40 * 65536);
    in[1] = hd_gv_rand_range(r, -40 * 65536, 40 * 65536);
    in[2] = hd_gv_rand_range(r, -1 * 65536, 70 * 65536);
    if (idx % 31u == 5u) {
        in[0] = hd_gv_rand_edge32(r);
        in[1] = hd_gv_rand_edge32(r);
        in[2] = hd_gv_rand_edge32(r);
    }
}

static void run_svm(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    for (k = 0; k < count; k++) {
        hd_foc_svm(in[3u * k], in[3u * k + 1u], in[3u * k + 2u], &out[3u * k]);
    }
}

static void cost_svm(void)
{
    int32_t d[3];
    vol_in[0] = 10 * 65536; vol_in[1] = -7 * 65536; vol_in[2] = 48 * 65536;
    const int32_t a = vol_in[0], b = vol_in[1], v = vol_in[2];
    hd_gv_cost_mark();
    hd_foc_svm(a, b, v, d);
    hd_gv_cost_mark();
    vol_out = d[0];
}

/* ---- ssi_decode ------------------------------------------------------------------------- */

static void gen_ssi(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t d = hd_ssi_encode(hd_gv_rand32(r) & 0xFFFFFFu, (idx % 7u) == 0u, (idx % 5u) == 0u);
    const uint32_t flip = ((idx % 3u) == 0u) ? (1u << (hd_gv_rand32(r) % 32u)) : 0u;
    in[0] = hd_gv_u2s(d ^ flip);
    in[1] = (int32_t)(hd_gv_rand32(r) % 8u);        /* latency bits */
}

static int32_t ssi_one(uint32_t data, uint32_t lat, int32_t *o)
{
    uint8_t buf[6] = {0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu};
    hd_ssi_reading_t rd = {0u, 0u, 0u};
    uint32_t pos = 1u + lat;            /* idle 1 bit, ack + lat zeros */
    uint32_t i;
    for (i = 1u; i <= pos; i++) {
        buf[i >> 3] = (uint8_t)(buf[i >> 3] & ~(0x80u >> (i & 7u)));
    }
    pos++;                              /* start bit 1 */
    buf[pos >> 3] = (uint8_t)(buf[pos >> 3] & ~(0x80u >> (pos & 7u)));   /* cds 0 */
    pos++;
    for (i = 0; i < 32u; i++, pos++) {
        if (((data >> (31u - i)) & 1u) == 0u) {
            buf[pos >> 3] = (uint8_t)(buf[pos >> 3] & ~(0x80u >> (pos & 7u)));
        }
    }
    const int32_t rc = hd_ssi_decode(buf, 6u, 48u, &rd);
    o[0] = rc;
    o[1] = (int32_t)rd.position;
    o[2] = (int32_t)rd.error;
    o[3] = (int32_t)rd.warning;
    return rc;
}

static void run_ssi(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    for (k = 0; k < count; k++) {
        (void)ssi_one(hd_gv_s2u(in[2u * k]), (uint32_t)in[2u * k + 1u], &out[4u * k]);
    }
}

static void cost_ssi(void)
{
    uint8_t buf[6] = {0xA0u, 0x00u, 0x00u, 0x00u, 0x00u, 0x3Fu};
    hd_ssi_reading_t rd;
    buf[1] = (uint8_t)vol_in[0];
    hd_gv_cost_mark();
    const int32_t rc = hd_ssi_decode(buf, 6u, 48u, &rd);
    hd_gv_cost_mark();
    vol_out = rc;
}

/* ---- enc_update -------------------------------------------------------------------------- */

static void gen_enc(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_range(r, -3000, 3000);       /* true step this period */
}

static void run_enc(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_enc_t e;
    uint32_t k, raw = 65000u;
    hd_enc_init(&e, raw, -5, 2500u);
    for (k = 0; k < count; k++) {
        raw = (raw + hd_gv_s2u(in[k])) & 0xFFFFu;
        out[3u * k] = hd_enc_update(&e, raw);
        out[3u * k + 1u] = hd_gv_u2s(hd_enc_single_turn(&e, 17u));
        out[3u * k + 2u] = (int32_t)e.ok;
    }
}

static void cost_enc(void)
{
    hd_enc_t e;
    hd_enc_init(&e, 100u, 0, 2500u);
    const uint32_t raw = (uint32_t)vol_in[0] & 0xFFFFu;
    hd_gv_cost_mark();
    (void)hd_enc_update(&e, raw);
    hd_gv_cost_mark();
    vol_out = (int32_t)e.count;
}

/* ---- isr_worst_case --------------------------------------------------------------------- */

static hd_app_t isr_app;
static hd_preisach_table_t isr_tab;

void gv_app_stub_sensors(uint32_t motor_raw, uint32_t output_raw);

/* the table of gv_comp_bank.c (same numbers: twist -> torque, L = 16) */
static void isr_make_table(void)
{
    uint32_t i, j;
    isr_tab.version = 1u;
    isr_tab.levels = 16u;
    isr_tab.sub_bits = 1u;
    isr_tab.in_shift = 10u;
    isr_tab.u0 = -(int32_t)(15u << 10);
    isr_tab.unit = HD_PREISACH_UNIT_GENERIC;
    for (i = 0; i < 16u; i++) {
        for (j = 0; j <= i; j++) {
            const int32_t d = (int32_t)(i - j);
            isr_tab.e[i * (i + 1u) / 2u + j] = d * 65536 + ((d < 4) ? d * d * 4096 : 65536);
        }
    }
    hd_preisach_seal(&isr_tab);
}

/* encoder inputs of period idx as in gv_comp_bank.c's gen_full */
static void isr_sensors(uint32_t idx, hd_gv_rng_t *r, uint32_t extra)
{
    const uint32_t out_cnt = 1000u + idx / 2u + (hd_gv_rand32(r) & 1u);
    const uint32_t mot_cnt = (idx * 781u + (hd_gv_rand32(r) & 7u)) & 0x1FFFFu;
    gv_app_stub_sensors((mot_cnt + 5u * extra) & 0x1FFFFu, (out_cnt + extra) & 0xFFFFFFu);
}

static void isr_port_foc(hd_foc_t *s, const hd_foc_cfg_t *c, hd_enc_t *e, uint32_t raw, int32_t ra, int32_t rb,
                         int32_t rv, int32_t iq_ref, int32_t duty[3])
{
    hd_foc_in_t x;
    hd_foc_out_t y;
    (void)hd_enc_update(e, raw);
    x.ia = hd_foc_adc_current(ra, 2048, 13107200);
    x.ib = hd_foc_adc_current(rb, 2048, 13107200);
    x.theta_e = hd_foc_elec_angle(hd_enc_single_turn(e, 17u), 17u, 8u, 0u);
    x.id_ref = 0;
    x.iq_ref = iq_ref;
    x.vbus = rv * 1056;
    hd_foc_step(s, c, &x, &y);
    duty[0] = y.duty[0];
    duty[1] = y.duty[1];
    duty[2] = y.duty[2];
}

int32_t gv_app_to_tick(hd_app_t *a, uint32_t tick, uint32_t *mot, uint32_t *out);

/* The online Stribeck identification of isr_app at a given point of a fit: every bin of the
 * positive direction valid (the map of the Stribeck parameters), `steps` estimator steps of
 * its fit done from candidate 0 (outside the marks); then either its next step due in the
 * measured period (parts == FE_OBSERVE: the observation, bins, feed), or that step done and
 * `parts` parts of its pass, the measured period running the next part. */
#define FE_OBSERVE 0xFFFFFFFFu
#define FE_SAMPLE 0xFFFFFFFEu
#define FE_PART 0x100u
#define FE_FEED 0xFFFFFFFDu
static void isr_fe_setup(hd_app_t *a, uint32_t steps, uint32_t parts)
{
    hd_fric_est_t *e = &a->cb.fe;
    const hd_fric_est_cfg_t *c = &a->cb_cfg.fe;
    uint32_t i, k;
    for (i = 0; i < HD_FE_NBIN; i++) {
        const int32_t v = hdf_sat32((int64_t)c->v_min << (i / 2u));
        hd_fe_bin_t *b = &e->bin[HD_FE_DIR_POS][i];
        b->v = hdf_add_sat(v, ((i & 1u) != 0u) ? v / 2 : 0);
        b->f = hd_stribeck_map(&a->cb_cfg.str, b->v);
        b->n = c->n_min;
        b->stamp = e->steps;
        {
            const uint64_t r = ((uint64_t)(uint32_t)b->v << 16) / (uint32_t)c->vs_lo;
            b->r16 = (r > (uint64_t)INT32_MAX) ? INT32_MAX : (int32_t)r;
        }
    }
    e->fit_dir = HD_FE_DIR_POS;
    e->fit_j = 0u;
    e->fit_pass = 0u;
    e->fit_part = 0u;                       /* nothing of the app's own steps pending */
    e->fit_due = 0u;
    e->smp_stage = 0u;
    e->in_step = 0u;
    e->q_head = 0u;                         /* the app's observations (no background here) */
    e->q_tail = 0u;
    for (k = 0; k < steps; k++) {
        hd_fric_est_step(e, c, e->v_prev, e->v_lp, e->bin[HD_FE_DIR_POS][8].f, true);
    }
    if (parts == FE_OBSERVE || parts == FE_SAMPLE) {
        a->cb.fe_tick = 0u;                 /* the measured period is the step's first */
        return;
    }
    if (parts == FE_FEED) {
        a->cb.fe_tick = a->cb_cfg.fe_decim - 1u;   /* ... its last: the feed */
        return;
    }
    if (parts >= FE_PART) {
        /* the step's observation takes a sample of an established visit of bin 8, paired with
         * a recent visit of the other direction, both directions fitted (every part of the
         * sample on its longest path), then parts - FE_PART of its work */
        const int32_t v = e->bin[HD_FE_DIR_POS][8].v;
        e->v_prev = v;
        e->v_lp = v;
        e->steady_n = c->settle;
        e->visit = 1u;
        e->vis_bin = (uint32_t)HD_FE_DIR_POS * HD_FE_NBIN + 8u;
        e->vis_g = e->bin[HD_FE_DIR_POS][8].f;
        e->vis_n = 3u;
        e->vis_m = e->vis_g;
        e->vis_s0 = e->scale;
        e->vis_b0 = e->bias;
        e->vis_k = 3u;
        e->vis_a = e->vis_g;
        e->vis_n0 = e->bin[HD_FE_DIR_POS][8].n;
        e->oth_m[HD_FE_DIR_NEG] = hdf_neg_sat(e->vis_g);
        e->oth_g[HD_FE_DIR_NEG] = e->vis_g;
        e->oth_t[HD_FE_DIR_NEG] = e->steps + 1u;
        e->fits[HD_FE_DIR_POS] = 1u;
        e->fits[HD_FE_DIR_NEG] = 1u;
        hd_fric_est_observe(e, c, v, v, hdf_add_sat(e->vis_g, 1000), true);
        for (k = FE_PART; k < parts; k++) {
            (void)hd_fric_est_work(e, c);
        }
        a->cb.fe_tick = 1u;                 /* the measured period: between observation and feed */
        return;
    }
    hd_fric_est_observe(e, c, e->v_prev, e->v_lp, e->bin[HD_FE_DIR_POS][8].f, true);
    for (k = 0; k < parts; k++) {
        (void)hd_fric_est_work(e, c);
    }
    a->cb.fe_tick = 0u;
}

/* The online identification of isr_app taking a sample in the measured period: its step due,
 * the reference of that period steady (its own value in the last step, the low-passed
 * velocity on it, the settle count full, a visit in progress), the visited bin established
 * and a recent visit of the other direction (the common mode solves for scale and bias), a
 * fit accepted in both directions (both estimates published).  0 when the period's reference
 * is outside the bins (the caller then sets no marks: the bench fails, never under-reports). */
static hd_app_t isr_fe_probe;
static int32_t isr_fe_sample_setup(hd_app_t *a)
{
    hd_fric_est_t *e = &a->cb.fe;
    const hd_fric_est_cfg_t *c = &a->cb_cfg.fe;
    int32_t v, k;
    isr_fe_probe = *a;                       /* the measured period's reference and measured velocity */
    hd_app_step(&isr_fe_probe);
    {
        /* the reference the period's observation queued (the steadiness test is the
         * background's) */
        const hd_fric_est_t *pe = &isr_fe_probe.cb.fe;
        v = (pe->q_head != e->q_head) ? pe->q[(pe->q_head - 1u) % HD_FE_QLEN].v : 0;
    }
    k = hd_fric_est_bin_of(c, v);
    if (v <= 0 || k < 0) {
        return 0;
    }
    e->v_prev = v;
    /* the low-passed velocity lands on v after the period's measured velocity */
    e->v_lp = hdf_sat32((int64_t)v - ((int64_t)isr_fe_probe.tel.vel_out - (int64_t)v) / 31);
    e->steady_n = c->settle;
    e->visit = 1u;
    e->vis_bin = (uint32_t)HD_FE_DIR_POS * HD_FE_NBIN + (uint32_t)k;
    e->vis_g = e->bin[HD_FE_DIR_POS][k].f;
    e->vis_n = 3u;
    e->vis_m = e->vis_g;
    e->vis_s0 = e->scale;
    e->vis_b0 = e->bias;
    e->vis_k = 3u;
    e->vis_a = e->vis_g;
    e->vis_n0 = e->bin[HD_FE_DIR_POS][k].n;
    e->oth_m[HD_FE_DIR_NEG] = hdf_neg_sat(e->vis_g);
    e->oth_g[HD_FE_DIR_NEG] = e->vis_g;
    e->oth_t[HD_FE_DIR_NEG] = e->steps;
    e->fits[HD_FE_DIR_POS] = 1u;
    e->fits[HD_FE_DIR_NEG] = 1u;
    return 1;
}

/* excitation in the measured runs: a multisine of 4 lines (10 .. 900 Hz, the exc_step kernel's
 * set-up) added to the held position (hd_app_set_excitation, HD_INJ_POS_REF) */
static void isr_exc_cfg(hd_exc_cfg_t *c)
{
    c->kind = (int32_t)HD_EXC_MULTISINE;
    c->amp = 1 << 20;
    c->offset = 0;
    c->length = 0;
    c->hold = 3;
    c->n = 4u;
    c->m = 2;
    c->rate = c->amp / 20 + 1;
    c->f0_q16 = 10 << 16;
    c->f1_q16 = 900 << 16;
    c->period = 50;
    c->seed = 0x5Au;
}

/* isr_app as control_step_full at the given tick, the estimator set up; 0: no tick */
static int32_t isr_prepare(uint32_t cb_enable, uint32_t slot, uint32_t fe_steps, uint32_t fe_parts, bool exc,
                           bool semi)
{
    hd_gv_rng_t r;
    uint32_t k;
    /* the app exactly as gv_comp_bank.c's control_step_full (stub hal of gv_app.c) */
    r.s = 4242u;
    isr_sensors(0u, &r, 0u);
    hd_app_init(&isr_app);
    (void)hd_app_param_set(&isr_app, HD_P_FAULT_ENABLE, 0);
    if (semi) {
        /* semi-closed with the twist torque of the Preisach inverse from the motor side
         * (pr_t_src 2: hd_gear_torque at its tick of the schedule) */
        (void)hd_app_param_set(&isr_app, HD_P_FB_CONFIG, HD_FB_SEMI_CLOSED);
        (void)hd_app_param_set(&isr_app, HD_P_PR_T_SRC, 2);
    }
    (void)hd_app_param_set(&isr_app, HD_P_LUG_K_OBS, 30 << 16);
    (void)hd_app_param_set(&isr_app, HD_P_TE_K1, 1 << 20);
    (void)hd_app_param_set(&isr_app, HD_P_CB_RAMP_TICKS, 4);
    isr_make_table();
    (void)hd_app_comp_table(&isr_app, &isr_tab);
    hd_app_step(&isr_app);
    if (exc) {
        hd_exc_cfg_t xc;
        isr_exc_cfg(&xc);
        (void)hd_app_set_excitation(&isr_app, &xc, HD_INJ_POS_REF);
        (void)hd_app_set_mode(&isr_app, HD_MODE_EXCITATION);
    } else {
        (void)hd_app_move_to(&isr_app, isr_app.pos_out + ((hd_angle_t)1 << 24));
        (void)hd_app_set_mode(&isr_app, HD_MODE_PTP);
    }
    (void)hd_app_param_set(&isr_app, HD_P_CB_ENABLE, (int32_t)cb_enable);
    if (fe_steps != 0u) {
        if (fe_parts == FE_SAMPLE) {
            /* bins from 2^12 (1e-6 turn/s): the reference of the measured period (the start
             * of the PTP move) is binned */
            (void)hd_app_param_set(&isr_app, HD_P_FE_V_MIN, 1 << 12);
        }
        if (fe_parts == FE_FEED) {
            /* the estimate fed into the Stribeck FF, the weight ramping (every parameter mixed) */
            (void)hd_app_param_set(&isr_app, HD_P_FE_FEED, 1);
        }
        (void)hd_app_param_set(&isr_app, HD_P_FE_ENABLE, 1);
    }
    for (k = 0; k < 16u; k++) {                  /* PTP moving, every weight fully on (ramp 4) */
        isr_sensors(k, &r, 0u);
        hd_app_step(&isr_app);
    }
    {
        /* on to the tick measured (gv_comp_bank.c), then the period's encoder inputs */
        uint32_t mot = 15u * 781u, outc = 1000u + 8u;
        if (gv_app_to_tick(&isr_app, slot, &mot, &outc) == 0) {
            return 0;
        }
        gv_app_stub_sensors((mot + 5u) & 0x1FFFFu, (outc + 1u) & 0xFFFFFFu);
    }
    if (fe_steps != 0u) {
        isr_fe_setup(&isr_app, fe_steps, fe_parts);
        if (fe_parts == FE_SAMPLE && isr_fe_sample_setup(&isr_app) == 0) {
            return 0;
        }
    }
    return 1;
}

static void cost_isr_en(uint32_t cb_enable, uint32_t slot, uint32_t fe_steps, uint32_t fe_parts, bool exc, bool semi)
{
    hd_foc_t s;
    hd_foc_cfg_t c;
    hd_enc_t e;
    hd_ssi_reading_t rd;
    int32_t duty[3];
    uint8_t buf[6] = {0xA0u, 0x12u, 0x34u, 0x56u, 0x78u, 0x3Fu};
    foc_cfg(&c);
    hd_foc_reset(&s);
    hd_enc_init(&e, 0u, 0, 2500u);
    if (isr_prepare(cb_enable, slot, fe_steps, fe_parts, exc, semi) == 0) {
        return;                                  /* no marks: the bench fails, never under-reports */
    }
    vol_in[0] = 2100; vol_in[1] = 1990; vol_in[2] = 3000; vol_in[3] = 5 * 65536;
    const int32_t ra = vol_in[0], rb = vol_in[1], rv = vol_in[2], iq = vol_in[3];
    hd_gv_cost_mark();
    isr_port_foc(&s, &c, &e, 37u, ra, rb, rv, iq, duty);           /* FOC period 1 */
    isr_port_foc(&s, &c, &e, 74u, ra, rb, rv, iq, duty);           /* FOC period 2 */
    (void)hd_ssi_decode(buf, 6u, 48u, &rd);                         /* output encoder */
    hd_app_step(&isr_app);                                          /* control period */
    hd_gv_cost_mark();
    vol_out = duty[0] + (int32_t)rd.position;
}

/* one cost kernel per tick of the schedule (hd_sched.h); tools/cm4_cost.py takes the worst */
#define ISR_ALL ((uint32_t)HD_CB_ALL)
#define ISR_PID ((uint32_t)HD_CB_ALL & ~(uint32_t)HD_CB_BACKSTEP)
static void cost_isr_s0(void) { cost_isr_en(ISR_ALL, 0u, 0u, 0u, false, false); }
static void cost_isr_s1(void) { cost_isr_en(ISR_ALL, 1u, 0u, 0u, false, false); }
static void cost_isr_s2(void) { cost_isr_en(ISR_ALL, 2u, 0u, 0u, false, false); }
static void cost_isr_s3(void) { cost_isr_en(ISR_ALL, 3u, 0u, 0u, false, false); }
static void cost_isr_s4(void) { cost_isr_en(ISR_ALL, 4u, 0u, 0u, false, false); }
static void cost_isr_s5(void) { cost_isr_en(ISR_ALL, 5u, 0u, 0u, false, false); }
static void cost_isr_s6(void) { cost_isr_en(ISR_ALL, 6u, 0u, 0u, false, false); }
static void cost_isr_s7(void) { cost_isr_en(ISR_ALL, 7u, 0u, 0u, false, false); }
static void cost_isr_pid_s0(void) { cost_isr_en(ISR_PID, 0u, 0u, 0u, false, false); }
static void cost_isr_pid_s1(void) { cost_isr_en(ISR_PID, 1u, 0u, 0u, false, false); }
static void cost_isr_pid_s2(void) { cost_isr_en(ISR_PID, 2u, 0u, 0u, false, false); }
static void cost_isr_pid_s3(void) { cost_isr_en(ISR_PID, 3u, 0u, 0u, false, false); }
static void cost_isr_pid_s4(void) { cost_isr_en(ISR_PID, 4u, 0u, 0u, false, false); }
static void cost_isr_pid_s5(void) { cost_isr_en(ISR_PID, 5u, 0u, 0u, false, false); }
static void cost_isr_pid_s6(void) { cost_isr_en(ISR_PID, 6u, 0u, 0u, false, false); }
static void cost_isr_pid_s7(void) { cost_isr_en(ISR_PID, 7u, 0u, 0u, false, false); }
/* the worst tick of the bank (3, the TE slot) with each kind of the online estimator's work
 * in the same period (fe_decim 10 against a cycle of 8: every tick meets every step and
 * part), in the last candidate of a fit (31 x 4 steps before it) */
/* the excitation mode with every compensator on, per tick */
static void cost_isr_exc_s0(void) { cost_isr_en(ISR_ALL, 0u, 0u, 0u, true, false); }
static void cost_isr_exc_s1(void) { cost_isr_en(ISR_ALL, 1u, 0u, 0u, true, false); }
static void cost_isr_exc_s2(void) { cost_isr_en(ISR_ALL, 2u, 0u, 0u, true, false); }
static void cost_isr_exc_s3(void) { cost_isr_en(ISR_ALL, 3u, 0u, 0u, true, false); }
static void cost_isr_exc_s4(void) { cost_isr_en(ISR_ALL, 4u, 0u, 0u, true, false); }
static void cost_isr_exc_s5(void) { cost_isr_en(ISR_ALL, 5u, 0u, 0u, true, false); }
static void cost_isr_exc_s6(void) { cost_isr_en(ISR_ALL, 6u, 0u, 0u, true, false); }
static void cost_isr_exc_s7(void) { cost_isr_en(ISR_ALL, 7u, 0u, 0u, true, false); }
#define FE_J31 (31u * 4u)
static void cost_isr_semi_t2_s0(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 0u, 0u, 0u, false, true); }
static void cost_isr_semi_t2_s1(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 1u, 0u, 0u, false, true); }
static void cost_isr_semi_t2_s2(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 2u, 0u, 0u, false, true); }
static void cost_isr_semi_t2_s3(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 3u, 0u, 0u, false, true); }
static void cost_isr_semi_t2_s4(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 4u, 0u, 0u, false, true); }
static void cost_isr_semi_t2_s5(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 5u, 0u, 0u, false, true); }
static void cost_isr_semi_t2_s6(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 6u, 0u, 0u, false, true); }
static void cost_isr_semi_t2_s7(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 7u, 0u, 0u, false, true); }

static void cost_isr_fe_observe(void) { cost_isr_en(ISR_ALL, 3u, FE_J31 + 3u, FE_OBSERVE, false, false); }
/* the estimator's kernels in the bank's worst tick (the observation lands on every tick:
 * fe_decim 10 against a cycle of 8) */
#define FE_PART_TICK 3u
/* the background's work of one step at its longest (hd_app_background until false): the
 * sample of an established visit paired with the other direction, the last candidate's
 * residual and the close of the fit with its publication */
static void cost_fe_background_step(void)
{
    if (isr_prepare(ISR_ALL, FE_PART_TICK, FE_J31 + 3u, FE_PART, false, false) == 0) {
        return;
    }
    hd_gv_cost_mark();
    while (hd_app_background(&isr_app)) {
    }
    hd_gv_cost_mark();
    vol_out = isr_app.cb.fe.est[HD_FE_DIR_POS].fc;
}
static void cost_isr_fe_sample(void) { cost_isr_en(ISR_ALL, 3u, FE_J31 + 3u, FE_SAMPLE, false, false); }
/* every mode with the online estimator on, per tick of the schedule (the observation and the
 * feed's period land on every tick: fe_decim 10 against a cycle of 8): the excitation mode and
 * the semi-closed period with pr_t_src 2 (the full-closed PTP period: the kernels above) */
static void cost_isr_exc_fe_observe_s0(void) { cost_isr_en(ISR_ALL, 0u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_observe_s1(void) { cost_isr_en(ISR_ALL, 1u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_observe_s2(void) { cost_isr_en(ISR_ALL, 2u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_observe_s3(void) { cost_isr_en(ISR_ALL, 3u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_observe_s4(void) { cost_isr_en(ISR_ALL, 4u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_observe_s5(void) { cost_isr_en(ISR_ALL, 5u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_observe_s6(void) { cost_isr_en(ISR_ALL, 6u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_observe_s7(void) { cost_isr_en(ISR_ALL, 7u, FE_J31 + 3u, FE_OBSERVE, true, false); }
static void cost_isr_exc_fe_feed_s0(void) { cost_isr_en(ISR_ALL, 0u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_exc_fe_feed_s1(void) { cost_isr_en(ISR_ALL, 1u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_exc_fe_feed_s2(void) { cost_isr_en(ISR_ALL, 2u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_exc_fe_feed_s3(void) { cost_isr_en(ISR_ALL, 3u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_exc_fe_feed_s4(void) { cost_isr_en(ISR_ALL, 4u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_exc_fe_feed_s5(void) { cost_isr_en(ISR_ALL, 5u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_exc_fe_feed_s6(void) { cost_isr_en(ISR_ALL, 6u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_exc_fe_feed_s7(void) { cost_isr_en(ISR_ALL, 7u, FE_J31 + 3u, FE_FEED, true, false); }
static void cost_isr_semi_t2_fe_observe_s0(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 0u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_observe_s1(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 1u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_observe_s2(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 2u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_observe_s3(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 3u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_observe_s4(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 4u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_observe_s5(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 5u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_observe_s6(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 6u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_observe_s7(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 7u, FE_J31 + 3u, FE_OBSERVE, false, true); }
static void cost_isr_semi_t2_fe_feed_s0(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 0u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_feed_s1(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 1u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_feed_s2(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 2u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_feed_s3(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 3u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_feed_s4(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 4u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_feed_s5(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 5u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_feed_s6(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 6u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_feed_s7(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 7u, FE_J31 + 3u, FE_FEED, false, true); }
static void cost_isr_semi_t2_fe_sample_s0(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 0u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_semi_t2_fe_sample_s1(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 1u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_semi_t2_fe_sample_s2(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 2u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_semi_t2_fe_sample_s3(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 3u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_semi_t2_fe_sample_s4(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 4u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_semi_t2_fe_sample_s5(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 5u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_semi_t2_fe_sample_s6(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 6u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_semi_t2_fe_sample_s7(void) { cost_isr_en(ISR_ALL | HD_CB_COMPLIANCE, 7u, FE_J31 + 3u, FE_SAMPLE, false, true); }
static void cost_isr_fe_feed(void) { cost_isr_en(ISR_ALL, FE_PART_TICK, FE_J31 + 3u, FE_FEED, false, false); }
static void cost_isr_fe_wait(void) { cost_isr_en(ISR_ALL, FE_PART_TICK, FE_J31 + 3u, FE_PART, false, false); }

const hd_gv_kernel_t hd_gv_foc_kernels[] = {
    {"foc_step", 6u, 7u, 384u, gen_foc, run_foc, cost_foc},
    {"foc_svm", 3u, 3u, 256u, gen_svm, run_svm, cost_svm},
    {"ssi_decode", 2u, 4u, 256u, gen_ssi, run_ssi, cost_ssi},
    {"enc_update", 1u, 3u, 256u, gen_enc, run_enc, cost_enc},
    {"isr_worst_case.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s0},
    {"isr_worst_case.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s1},
    {"isr_worst_case.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s2},
    {"isr_worst_case.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s3},
    {"isr_worst_case.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s4},
    {"isr_worst_case.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s5},
    {"isr_worst_case.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s6},
    {"isr_worst_case.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_s7},
    {"isr_worst_case_pid.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s0},
    {"isr_worst_case_pid.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s1},
    {"isr_worst_case_pid.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s2},
    {"isr_worst_case_pid.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s3},
    {"isr_worst_case_pid.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s4},
    {"isr_worst_case_pid.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s5},
    {"isr_worst_case_pid.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s6},
    {"isr_worst_case_pid.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_pid_s7},
    {"isr_worst_case_exc.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s0},
    {"isr_worst_case_exc.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s1},
    {"isr_worst_case_exc.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s2},
    {"isr_worst_case_exc.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s3},
    {"isr_worst_case_exc.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s4},
    {"isr_worst_case_exc.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s5},
    {"isr_worst_case_exc.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s6},
    {"isr_worst_case_exc.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_s7},
    {"isr_worst_case_semi_t2.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s0},
    {"isr_worst_case_semi_t2.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s1},
    {"isr_worst_case_semi_t2.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s2},
    {"isr_worst_case_semi_t2.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s3},
    {"isr_worst_case_semi_t2.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s4},
    {"isr_worst_case_semi_t2.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s5},
    {"isr_worst_case_semi_t2.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s6},
    {"isr_worst_case_semi_t2.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_s7},
    {"isr_worst_case_fe_observe", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_fe_observe},
    {"isr_worst_case_fe_sample", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_fe_sample},
    {"isr_worst_case_fe_feed", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_fe_feed},
    {"isr_worst_case_fe_wait", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_fe_wait},
    {"isr_worst_case_exc_fe_observe.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s0},
    {"isr_worst_case_exc_fe_observe.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s1},
    {"isr_worst_case_exc_fe_observe.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s2},
    {"isr_worst_case_exc_fe_observe.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s3},
    {"isr_worst_case_exc_fe_observe.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s4},
    {"isr_worst_case_exc_fe_observe.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s5},
    {"isr_worst_case_exc_fe_observe.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s6},
    {"isr_worst_case_exc_fe_observe.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_observe_s7},
    {"isr_worst_case_exc_fe_feed.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s0},
    {"isr_worst_case_exc_fe_feed.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s1},
    {"isr_worst_case_exc_fe_feed.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s2},
    {"isr_worst_case_exc_fe_feed.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s3},
    {"isr_worst_case_exc_fe_feed.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s4},
    {"isr_worst_case_exc_fe_feed.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s5},
    {"isr_worst_case_exc_fe_feed.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s6},
    {"isr_worst_case_exc_fe_feed.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_exc_fe_feed_s7},
    {"isr_worst_case_semi_t2_fe_observe.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s0},
    {"isr_worst_case_semi_t2_fe_observe.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s1},
    {"isr_worst_case_semi_t2_fe_observe.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s2},
    {"isr_worst_case_semi_t2_fe_observe.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s3},
    {"isr_worst_case_semi_t2_fe_observe.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s4},
    {"isr_worst_case_semi_t2_fe_observe.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s5},
    {"isr_worst_case_semi_t2_fe_observe.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s6},
    {"isr_worst_case_semi_t2_fe_observe.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_observe_s7},
    {"isr_worst_case_semi_t2_fe_feed.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s0},
    {"isr_worst_case_semi_t2_fe_feed.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s1},
    {"isr_worst_case_semi_t2_fe_feed.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s2},
    {"isr_worst_case_semi_t2_fe_feed.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s3},
    {"isr_worst_case_semi_t2_fe_feed.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s4},
    {"isr_worst_case_semi_t2_fe_feed.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s5},
    {"isr_worst_case_semi_t2_fe_feed.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s6},
    {"isr_worst_case_semi_t2_fe_feed.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_feed_s7},
    {"isr_worst_case_semi_t2_fe_sample.s0", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s0},
    {"isr_worst_case_semi_t2_fe_sample.s1", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s1},
    {"isr_worst_case_semi_t2_fe_sample.s2", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s2},
    {"isr_worst_case_semi_t2_fe_sample.s3", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s3},
    {"isr_worst_case_semi_t2_fe_sample.s4", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s4},
    {"isr_worst_case_semi_t2_fe_sample.s5", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s5},
    {"isr_worst_case_semi_t2_fe_sample.s6", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s6},
    {"isr_worst_case_semi_t2_fe_sample.s7", 1u, 3u, 4u, gen_enc, run_enc, cost_isr_semi_t2_fe_sample_s7},
    {"fe_background_step", 1u, 3u, 4u, gen_enc, run_enc, cost_fe_background_step},
};
const uint32_t hd_gv_foc_count = sizeof hd_gv_foc_kernels / sizeof hd_gv_foc_kernels[0];
