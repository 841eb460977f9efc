/*
 * gv_fric_est.c - golden-vector kernels of the online Stribeck identification
 * (hd_fric_est.h).  One vector is one constant-velocity leg of a motion profile
 * (speeds ascending over a ladder, both directions, torque from an integer
 * Stribeck map plus noise); run() steps the estimator 64 times per leg (a stop,
 * then the leg with velocity and torque jitter) and outputs the estimate after
 * it, so the bins, the grid fit, its excitation checks, the common-mode scale and
 * unbalance (established bins from the second cycle of legs) and the publication are
 * all exercised.  cost(): one step (a bin update and a quarter of a fit
 * candidate over 24 valid bins) in each pass: snapshot of half the bins
 * (fric_est_legs), the solution, the residual, and the step that closes a fit.
 * fric_est_stale_feed: the feed's stale-level rule (hd_fric_est_fed_scale) and the fed map.
 */
#include "gv.h"
#include "hd_fixed.h"
#include "hd_fric_est.h"
#include "hd_stribeck.h"

#define DEGS 11930465          /* 1 deg/s, 2^-32 turn/s */
#define NM(x) ((int32_t)((x) * 65536))
#define FE_LEG_STEPS 64u
#define FE_STOP_STEPS 8u

/* the axis the legs see: fc 7.4 / 7.0, fs 10.6 / 10.0 N.m, vs 1.15 deg/s, fv 33.3 N.m/(turn/s) */
static const hd_stribeck_cfg_t fe_map = {
    { 484966, 694682, 13720035, 2182349 },
    { 458752, 655360, 13720035, 2182349 },
    2u, 0, 1 << 30, 100 << 16, 0u, 0
};

/* ladder of 8 speeds, 0.02 .. 10 deg/s (x ~2.43) */
static const int32_t fe_speeds[8] = {
    DEGS / 50, DEGS / 20, DEGS / 8, DEGS / 3, (DEGS * 4) / 5, 2 * DEGS, 5 * DEGS, 10 * DEGS
};

static void fe_cfg_init(hd_fric_est_cfg_t *c)
{
    /* v_min 0.005 deg/s, vs_lo 0.05 deg/s, dv_max 64, settle 4, forget 32, n_min 8, keep 8, max age 1500 */
    (void)hd_fric_est_config(c, DEGS / 200, DEGS / 20, 64, 4u, 32u, 8u, 8u, 1500u, NM(100), NM(3000));
}

static void gen_leg(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const int32_t v = fe_speeds[(idx >> 1) & 7u];
    in[0] = ((idx & 1u) != 0u) ? -v : v;
    in[1] = hdf_add_sat(hd_stribeck_map(&fe_map, in[0]), hd_gv_rand_range(r, -NM(0.05), NM(0.05)));
    in[2] = (int32_t)hd_gv_rand32(r);       /* jitter seed */
}

static void run_legs(const int32_t *in, int32_t *out, uint32_t count)
{
    static hd_fric_est_t e;
    hd_fric_est_cfg_t c;
    const hd_stribeck_dir_t init[HD_FE_NDIR] = {{NM(1), NM(2), DEGS, NM(10)}, {NM(1), NM(2), DEGS, NM(10)}};
    uint32_t k;
    uint32_t s;
    fe_cfg_init(&c);
    hd_fric_est_init(&e, init, 16u, false);
    for (k = 0; k < count; k++) {
        const int32_t v = in[3u * k];
        const int32_t t = in[3u * k + 1u];
        uint32_t x = hd_gv_s2u(in[3u * k + 2u]);
        for (s = 0; s < FE_LEG_STEPS; s++) {
            x = x * 1664525u + 1013904223u;       /* LCG: jitter of the measured velocity and torque */
            if (s < FE_STOP_STEPS) {
                hd_fric_est_step(&e, &c, 0, 0, 0, true);
            } else {
                const int32_t jv = (int32_t)((x >> 20) & 0xFFu) - 128;         /* +-128/1024 of v */
                const int32_t jt = (int32_t)((x >> 8) & 0xFFFu) - 2048;        /* +-0.03 N.m */
                hd_fric_est_step(&e, &c, v, hdf_add_sat(v, (int32_t)(((int64_t)v * jv) / 1024)),
                                 hdf_add_sat(t, jt), true);
            }
        }
        out[12u * k] = e.est[0].fc;
        out[12u * k + 1u] = e.est[0].fs;
        out[12u * k + 2u] = e.est[0].vs;
        out[12u * k + 3u] = e.est[0].fv;
        out[12u * k + 4u] = e.est[1].fc;
        out[12u * k + 5u] = e.est[1].fs;
        out[12u * k + 6u] = e.est[1].vs;
        out[12u * k + 7u] = e.est[1].fv;
        out[12u * k + 8u] = (int32_t)(e.conf[0] + 1000u * e.conf[1]);
        out[12u * k + 9u] = (int32_t)(e.samples + 65536u * (e.fits[0] & 0x7FFFu));
        out[12u * k + 10u] = e.scale;            /* the common mode (from the second cycle of legs) */
        out[12u * k + 11u] = e.bias;
    }
}

static volatile int32_t cv_vref = 2 * DEGS;
static volatile int32_t cv_tau = NM(8);
static hd_fric_est_t fe_cost_state;

/* every bin of the positive direction valid, the next candidate of that direction */
static void fill_bins(hd_fric_est_t *e, const hd_fric_est_cfg_t *c)
{
    const hd_stribeck_dir_t init[HD_FE_NDIR] = {{NM(1), NM(2), DEGS, NM(10)}, {NM(1), NM(2), DEGS, NM(10)}};
    uint32_t i;
    hd_fric_est_init(e, init, 0u, false);
    for (i = 0; i < HD_FE_NBIN; i++) {
        const int32_t v = hdf_sat32((int64_t)(DEGS / 200) << (i / 2u));
        hd_fe_bin_t *b = &e->bin[HD_FE_DIR_POS][i];
        b->v = v + ((i & 1u) != 0u ? v / 2 : 0);
        b->f = hd_stribeck_map(&fe_map, b->v);
        b->n = c->n_min;
        b->r16 = (int32_t)(((uint64_t)(uint32_t)b->v << 16) / (uint32_t)c->vs_lo > (uint64_t)INT32_MAX ?
                           (uint64_t)INT32_MAX : ((uint64_t)(uint32_t)b->v << 16) / (uint32_t)c->vs_lo);
    }
    e->v_prev = cv_vref;
    e->v_lp = cv_vref;
    e->steady_n = c->settle;
    e->visit = 1u;
}

/* one step in the given pass of candidate j (the passes before it run outside the marks) */
static void cost_pass(uint32_t pass, uint32_t j)
{
    hd_fric_est_cfg_t c;
    uint32_t p;
    fe_cfg_init(&c);
    fill_bins(&fe_cost_state, &c);
    fe_cost_state.fit_dir = HD_FE_DIR_POS;
    fe_cost_state.fit_j = j;
    fe_cost_state.fit_pass = 0u;
    for (p = 0; p < pass; p++) {
        hd_fric_est_step(&fe_cost_state, &c, cv_vref, cv_vref, cv_tau, true);
    }
    hd_gv_cost_mark();
    hd_fric_est_step(&fe_cost_state, &c, cv_vref, cv_vref, cv_tau, true);
    hd_gv_cost_mark();
}

static void cost_snapshot(void) { cost_pass(0u, 7u); }
static void cost_solve(void) { cost_pass(2u, 7u); }
static void cost_sse(void) { cost_pass(3u, 7u); }

static void cost_finish(void)
{
    hd_fric_est_cfg_t c;
    uint32_t j, p;
    fe_cfg_init(&c);
    fill_bins(&fe_cost_state, &c);
    fe_cost_state.fit_dir = HD_FE_DIR_POS;
    fe_cost_state.fit_pass = 0u;
    for (j = 0; j < HD_FE_NGRID; j++) {
        for (p = 0; p < ((j + 1u < HD_FE_NGRID) ? 4u : 3u); p++) {
            hd_fric_est_step(&fe_cost_state, &c, cv_vref, cv_vref, cv_tau, true);
        }
    }
    hd_gv_cost_mark();
    hd_fric_est_step(&fe_cost_state, &c, cv_vref, cv_vref, cv_tau, true);   /* last residual + the fit */
    hd_gv_cost_mark();
}

/* The feed's stale-level rule (hd_fric_est_fed_scale): one vector is an estimate (shape of both
 * directions, common-mode scale 0.5 .. 3) whose last established visit is 0 .. 9000 steps old,
 * fed in full with the share 0.944; out: the fed scale and the fed map. */
static void gen_stale(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_range(r, HD_FE_SCALE_ONE / 2, 3 * HD_FE_SCALE_ONE);
    in[1] = hd_gv_rand_range(r, 0, 9000);
    in[2] = hd_gv_rand_range(r, 0, NM(50));
    in[3] = hd_gv_rand_range(r, 0, NM(20));
    in[4] = hd_gv_rand_range(r, 0, NM(500));
}

static void run_stale(const int32_t *in, int32_t *out, uint32_t count)
{
    static hd_fric_est_t e;
    hd_stribeck_cfg_t fed;
    uint32_t k;
    uint32_t d;
    for (k = 0; k < count; k++) {
        const int32_t sc = in[5u * k], fc = in[5u * k + 2u], fs = hdf_add_sat(fc, in[5u * k + 3u]);
        const hd_stribeck_dir_t init[HD_FE_NDIR] = {{fc, fs, DEGS, in[5u * k + 4u]}, {fc, fs, DEGS / 2, in[5u * k + 4u]}};
        hd_fric_est_init(&e, init, 0u, true);
        e.scale = sc;
        for (d = 0; d < HD_FE_NDIR; d++) {
            /* the published estimate (shape x scale, bounded by tau_max 100 N.m, fv_max 3000) */
            e.fits[d] = 1u;
            e.est[d].fc = hdf_clamp32(hdf_sat32(hdf_mul64x32_q((int64_t)init[d].fc, sc, 16u)), 0, NM(100));
            e.est[d].fs = hdf_clamp32(hdf_sat32(hdf_mul64x32_q((int64_t)init[d].fs, sc, 16u)), e.est[d].fc, NM(100));
            e.est[d].fv = hdf_clamp32(hdf_sat32(hdf_mul64x32_q((int64_t)init[d].fv, sc, 16u)), 0, NM(3000));
        }
        e.steps = 100000u + hd_gv_s2u(in[5u * k + 1u]);
        e.oth_t[HD_FE_DIR_POS] = 100000u;
        e.oth_t[HD_FE_DIR_NEG] = 99950u;
        hd_fric_est_feed_share(&e, &fe_map, 61866, &fed);          /* share 0.944 */
        out[8u * k] = hd_fric_est_fed_scale(&e);
        out[8u * k + 1u] = fed.pos.fc;
        out[8u * k + 2u] = fed.pos.fs;
        out[8u * k + 3u] = fed.pos.vs;
        out[8u * k + 4u] = fed.pos.fv;
        out[8u * k + 5u] = fed.neg.fc;
        out[8u * k + 6u] = fed.neg.fs;
        out[8u * k + 7u] = fed.neg.fv;
    }
}

const hd_gv_kernel_t hd_gv_fric_est_kernels[] = {
    { "fric_est_legs", 3u, 12u, 48u, gen_leg, run_legs, cost_snapshot },
    { "fric_est_step_solve", 3u, 12u, 1u, gen_leg, run_legs, cost_solve },
    { "fric_est_step_sse", 3u, 12u, 1u, gen_leg, run_legs, cost_sse },
    { "fric_est_step_fit_finish", 3u, 12u, 1u, gen_leg, run_legs, cost_finish },
    { "fric_est_stale_feed", 5u, 8u, 64u, gen_stale, run_stale, 0 },
};
const uint32_t hd_gv_fric_est_count = sizeof hd_gv_fric_est_kernels / sizeof hd_gv_fric_est_kernels[0];
