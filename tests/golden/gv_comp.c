/*
 * gv_comp.c - golden-vector kernels of the compensators (issue 5):
 * Stribeck, LuGre, Maxwell-slip, TE, adaptive backstepping, Preisach online
 * (L32/L64), Preisach brute force (L32/L64, the same integers) and the
 * Preisach inverse.  Stateful kernels initialise in run() and step once per
 * vector.  Each has a cost() of one step; `make bench` reports the Preisach
 * online/brute-force ratio (tests/bench/30_preisach_ratio.py).
 * Tables and the large Preisach states are static (test image only).
 */
#include "gv.h"
#include "hd_fixed.h"
#include "hd_stribeck.h"
#include "hd_lugre.h"
#include "hd_maxwell.h"
#include "hd_te_comp.h"
#include "hd_backstep.h"
#include "hd_preisach.h"

#define DEGS 11930465          /* 1 deg/s, 2^-32 turn/s */
#define NM(x) ((int32_t)((x) * 65536))

static volatile int32_t cv_v = 3 * DEGS;
static volatile int32_t cv_w = -DEGS / 3;
static volatile int32_t cv_p = 17;
static volatile int32_t sink32;

/* ---- Stribeck ------------------------------------------------------------ */

static const hd_stribeck_cfg_t st_cfg = {
    { 655360, 1048576, 11930465, 6553600 },    /* fc 10, fs 16 N.m, vs 1 deg/s, fv 100 N.m/(turn/s) */
    { 720896, 1179648, 8947849, 7864320 },     /* asymmetric negative side */
    2u, 11930, 1 << 29, 100 << 16, 0u, 0
};

/* the same with cruise detection (str_cruise_ticks 8) and the estimate outside a cruise */
static const hd_stribeck_cfg_t st_cruise_cfg = {
    { 655360, 1048576, 11930465, 6553600 },
    { 720896, 1179648, 8947849, 7864320 },
    2u, 11930, 0, 100 << 16, 8u, 0
};

/* the same with the steady-motion switch (str_steady_vs 0.5 vs) on top of the cruise test */
static const hd_stribeck_cfg_t st_steady_cfg = {
    { 655360, 1048576, 11930465, 6553600 },
    { 720896, 1179648, 8947849, 7864320 },
    2u, 11930, 0, 100 << 16, 8u, 1 << 15
};

static void gen_two_vel(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = ((idx & 3u) == 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -5 * DEGS, 5 * DEGS);
    in[1] = hd_gv_rand_range(r, -5 * DEGS, 5 * DEGS);
}

static void run_stribeck_cfg(const hd_stribeck_cfg_t *c, const int32_t *in, int32_t *out, uint32_t count)
{
    hd_stribeck_t s;
    uint32_t k;
    hd_stribeck_init(&s, 64u, false);
    for (k = 0; k < count; k++) {
        if (k == 16u) {
            hd_stribeck_set_enabled(&s, true);
        }
        out[2u * k] = hd_stribeck_step(&s, c, in[2u * k], in[2u * k + 1u]);
        out[2u * k + 1u] = s.v;
    }
}

static void run_stribeck(const int32_t *in, int32_t *out, uint32_t count)
{
    run_stribeck_cfg(&st_cfg, in, out, count);
}

static void run_stribeck_cruise(const int32_t *in, int32_t *out, uint32_t count)
{
    run_stribeck_cfg(&st_cruise_cfg, in, out, count);
}

static void run_stribeck_steady(const int32_t *in, int32_t *out, uint32_t count)
{
    run_stribeck_cfg(&st_steady_cfg, in, out, count);
}

/* v_ref constant over runs of 16 vectors (odd runs with +-1 LSB jitter, every 4th run 0 or a ramp),
 * v_est random: the cruise counter starts, completes and resets */
static void gen_cruise_vel(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t run = idx >> 4;
    const int32_t level = (int32_t)((run * 2654435761u) % (uint32_t)(10 * DEGS)) - 5 * DEGS;
    if ((run & 3u) == 3u) {
        in[0] = ((run & 4u) != 0u) ? 0 : level + (int32_t)(idx & 15u) * 1000;
    } else {
        in[0] = level + (((run & 1u) != 0u) ? (int32_t)(idx & 1u) : 0);
    }
    in[1] = hd_gv_rand_range(r, -5 * DEGS, 5 * DEGS);
}

static void cost_stribeck(void)
{
    hd_stribeck_t s;
    hd_stribeck_init(&s, 0u, true);
    (void)hd_stribeck_step(&s, &st_cfg, cv_v, cv_w);     /* reciprocals of vs computed here, once */
    hd_gv_cost_mark();
    sink32 = hd_stribeck_step(&s, &st_cfg, cv_v, cv_w);
    hd_gv_cost_mark();
}

/* ---- LuGre ---------------------------------------------------------------- */

static const hd_lugre_cfg_t lg_cfg = {
    { 524288, 786432, 11930465, 0 }, 2u, 48640000, 39321600, 9830400, 3276800, 200 << 16
};

static void gen_lugre(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = ((idx & 7u) == 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -20 * DEGS, 20 * DEGS);
    hd_gv_put64(&in[1], (int64_t)hd_gv_rand_range(r, -4000000, 4000000));
}

static void run_lugre(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_lugre_t s;
    uint32_t k;
    hd_lugre_init(&s, 0u, true);
    for (k = 0; k < count; k++) {
        out[3u * k] = hd_lugre_step(&s, &lg_cfg, in[3u * k], hd_gv_get64(&in[3u * k + 1u]));
        hd_gv_put64(&out[3u * k + 1u], s.z);
    }
}

static void cost_lugre(void)
{
    hd_lugre_t s;
    hd_lugre_init(&s, 0u, true);
    hd_gv_cost_mark();
    sink32 = hd_lugre_step(&s, &lg_cfg, cv_v, (int64_t)cv_w);
    hd_gv_cost_mark();
}

/* ---- Maxwell-slip ------------------------------------------------------------ */

static const hd_maxwell_cfg_t mx_cfg = {
    8u,
    { 2560000, 5120000, 3840000, 2560000, 1280000, 1280000, 640000, 320000 },
    { 6628, 13256, 26512, 53024, 79536, 106048, 145816, 198840 },   /* 2..60 arcsec */
    90071993, 500 << 16          /* 1/K1 (3.1e4 N.m/rad) in 2^-44 turn/N.m */
};

static void gen_step(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = ((idx & 31u) == 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -20000, 20000);
}

static void run_maxwell(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_maxwell_t s;
    int64_t x = 0;
    uint32_t k;
    hd_maxwell_init(&s, 0u, true);
    for (k = 0; k < count; k++) {
        x += in[k];
        hd_gv_put64(&out[3u * k], hd_maxwell_step(&s, &mx_cfg, x));
        out[3u * k + 2u] = s.tau;
    }
}

static void cost_maxwell(void)
{
    hd_maxwell_t s;
    hd_maxwell_init(&s, 0u, true);
    (void)hd_maxwell_step(&s, &mx_cfg, 0);
    hd_gv_cost_mark();
    sink32 = (int32_t)hd_maxwell_step(&s, &mx_cfg, (int64_t)cv_v);
    hd_gv_cost_mark();
}

/* ---- TE ------------------------------------------------------------------------ */

static const hd_te_cfg_t te_cfg = {
    4u, { 2u, 1u, 4u, 6u, 0u, 0u, 0u, 0u }, { 33140, 9942, 6628, 3314, 0, 0, 0, 0 },
    { 0u, 1073741824u, 3000000000u, 123456789u, 0u, 0u, 0u, 0u }, 49920000, 50 << 16, 0u
};

/* TE model and slope in the short form (fit32, hd_te_comp.h) at the edges of its ranges:
 * amplitudes of +-2^30, the largest order 2^28 */
static const hd_te_cfg_t te_fit_cfg = {
    4u, { 2u, 268435456u, 1u, 1000u, 0u, 0u, 0u, 0u }, { 1073741824, -1073741824, 1073741824, -33140, 0, 0, 0, 0 },
    { 0u, 1073741824u, 3000000000u, 123456789u, 0u, 0u, 0u, 0u }, 49920000, 50 << 16, 1u
};

static void run_te_slope(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    for (k = 0; k < count; k++) {
        int32_t slope;
        hd_gv_put64(&out[3u * k], hd_te_model_slope(&te_fit_cfg, hd_gv_get64(&in[2u * k]), &slope));
        out[3u * k + 2u] = slope;
    }
}

static void gen_angle(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    hd_gv_put64(in, hd_gv_rand_edge64(r));
}

static void run_te(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_te_comp_t s;
    uint32_t k;
    hd_te_comp_init(&s, 0u, true);
    for (k = 0; k < count; k++) {
        hd_gv_put64(&out[3u * k], hd_te_comp_step(&s, &te_cfg, hd_gv_get64(&in[2u * k])));
        out[3u * k + 2u] = s.tau;
    }
}

static void cost_te_slope(void)
{
    int32_t slope;
    hd_gv_cost_mark();
    sink32 = (int32_t)hd_te_model_slope(&te_fit_cfg, (int64_t)cv_v * 1000, &slope);
    hd_gv_cost_mark();
    sink32 += slope;
}

static void cost_te(void)
{
    hd_te_comp_t s;
    hd_te_comp_init(&s, 0u, true);
    hd_gv_cost_mark();
    sink32 = (int32_t)hd_te_comp_step(&s, &te_cfg, (int64_t)cv_v * 1000);
    hd_gv_cost_mark();
}

/* ---- adaptive backstepping -------------------------------------------------------- */

static const hd_backstep_cfg_t bs_cfg = {
    3276800, 3276800, 535284, 2613000, 119304, 11930465, 1 << 30, 150 << 16,
    { 1 << 23, 1 << 23, 1 << 22, 1 << 23 },
    { 0, 0, 0, -(20 << 16) }, { 30 << 16, 30 << 16, 500 << 16, 20 << 16 }
};

static void gen_backstep(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const int64_t thd = (int64_t)hd_gv_rand_range(r, -100000000, 100000000) * 16;
    hd_gv_put64(&in[0], thd + hd_gv_rand_range(r, -200000, 200000));
    hd_gv_put64(&in[2], thd);
    in[4] = ((idx & 15u) == 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -3 * DEGS, 3 * DEGS);
    in[5] = hd_gv_rand_range(r, -3 * DEGS, 3 * DEGS);
    in[6] = hd_gv_rand_range(r, -2000000, 2000000);
}

static void run_backstep(const int32_t *in, int32_t *out, uint32_t count)
{
    static const int32_t th0[HD_BS_NP] = { 2 << 16, 1 << 16, 10 << 16, 0 };
    hd_backstep_t s;
    uint32_t k;
    hd_backstep_init(&s, &bs_cfg, th0, 32u, true);
    for (k = 0; k < count; k++) {
        const int32_t *x = &in[7u * k];
        hd_backstep_in_t bi;
        bi.theta = hd_gv_get64(&x[0]);
        bi.theta_d = hd_gv_get64(&x[2]);
        bi.omega = x[4];
        bi.omega_d = x[5];
        bi.acc_d = x[6];
        if (k == 100u) {
            hd_backstep_preload(&s, &bs_cfg, &bi, 5 << 16);
        }
        out[5u * k] = hd_backstep_step(&s, &bs_cfg, &bi, 1 << 16);
        hd_gv_put64(&out[5u * k + 1u], s.th[0]);
        hd_gv_put64(&out[5u * k + 3u], s.th[3]);
    }
}

static void cost_backstep(void)
{
    static const int32_t th0[HD_BS_NP] = { 2 << 16, 1 << 16, 10 << 16, 0 };
    hd_backstep_t s;
    hd_backstep_in_t bi;
    hd_backstep_init(&s, &bs_cfg, th0, 0u, true);
    bi.theta = (int64_t)cv_v * 3;
    bi.theta_d = (int64_t)cv_w;
    bi.omega = cv_v;
    bi.omega_d = cv_w;
    bi.acc_d = cv_p;
    hd_gv_cost_mark();
    sink32 = hd_backstep_step(&s, &bs_cfg, &bi, 0);
    hd_gv_cost_mark();
}

/* ---- Preisach ------------------------------------------------------------------------ */

static hd_preisach_table_t pz_tab32;
static hd_preisach_table_t pz_tab64;
static hd_preisach_t pz_on;
static hd_preisach_bf_t pz_bf;
static hd_preisach_inv_t pz_inv;

/* E[i][j] = sum_{j <= b < a <= i} mu(a, b), mu = 1000 + 37 (a - b) + (a*b mod 97):
 * E[i][j] = E[i-1][j] + sum_{b=j}^{i-1} mu(i, b). */
static const hd_preisach_table_t *pz_table(uint32_t levels)
{
    hd_preisach_table_t *t = (levels == 64u) ? &pz_tab64 : &pz_tab32;
    uint32_t i;
    uint32_t j;
    uint32_t b;
    if (t->magic == HD_PREISACH_MAGIC && t->levels == levels) {
        return t;
    }
    t->levels = levels;
    t->sub_bits = 0u;
    t->in_shift = 10u;
    t->u0 = -(int32_t)(levels << 9);
    t->unit = HD_PREISACH_UNIT_GENERIC;
    t->version = 1u;
    for (i = 0; i < levels; i++) {
        for (j = 0; j <= i; j++) {
            int32_t e = 0;
            if (j < i) {
                e = t->e[(i - 1u) * i / 2u + j];
                for (b = j; b < i; b++) {
                    e += (int32_t)(1000u + 37u * (i - b) + (i * b) % 97u);
                }
            }
            t->e[i * (i + 1u) / 2u + j] = e;
        }
    }
    hd_preisach_seal(t);
    return t;
}

static void gen_pz_step(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    /* lattice increments: random walk, sometimes a big jump */
    in[0] = ((idx & 31u) == 31u) ? hd_gv_rand_range(r, -40, 40) : hd_gv_rand_range(r, -4, 4);
}

static void run_pz_online(const hd_preisach_table_t *t, const int32_t *in, int32_t *out, uint32_t count)
{
    const int32_t ptop = hd_preisach_p_top(t);
    int32_t p = ptop / 2;
    uint32_t k;
    hd_preisach_init(&pz_on, t, 1u, 0u, true);
    for (k = 0; k < count; k++) {
        p = hd_clamp32(p + in[k], -2, ptop + 2);
        hd_gv_put64(&out[2u * k], hd_preisach_step_p(&pz_on, t, p));
    }
}

static void run_pz_brute(const hd_preisach_table_t *t, const int32_t *in, int32_t *out, uint32_t count)
{
    const int32_t ptop = hd_preisach_p_top(t);
    int32_t p = ptop / 2;
    uint32_t k;
    hd_preisach_bf_init(&pz_bf, t, 1u);
    for (k = 0; k < count; k++) {
        p = hd_clamp32(p + in[k], -2, ptop + 2);
        hd_gv_put64(&out[2u * k], hd_preisach_bf_step_p(&pz_bf, t, p));
    }
}

static void run_pz_on32(const int32_t *in, int32_t *out, uint32_t count)
{
    run_pz_online(pz_table(32u), in, out, count);
}

static void run_pz_on64(const int32_t *in, int32_t *out, uint32_t count)
{
    run_pz_online(pz_table(64u), in, out, count);
}

static void run_pz_bf32(const int32_t *in, int32_t *out, uint32_t count)
{
    run_pz_brute(pz_table(32u), in, out, count);
}

static void run_pz_bf64(const int32_t *in, int32_t *out, uint32_t count)
{
    run_pz_brute(pz_table(64u), in, out, count);
}

/* A representative state: a few nested reversals, then one measured step. */
static void pz_prime_online(const hd_preisach_table_t *t)
{
    const int32_t ptop = hd_preisach_p_top(t);
    hd_preisach_init(&pz_on, t, 1u, 0u, true);
    (void)hd_preisach_step_p(&pz_on, t, ptop - 3);
    (void)hd_preisach_step_p(&pz_on, t, 4);
    (void)hd_preisach_step_p(&pz_on, t, ptop - 8);
    (void)hd_preisach_step_p(&pz_on, t, 10);
}

static void pz_prime_brute(const hd_preisach_table_t *t)
{
    const int32_t ptop = hd_preisach_p_top(t);
    hd_preisach_bf_init(&pz_bf, t, 1u);
    (void)hd_preisach_bf_step_p(&pz_bf, t, ptop - 3);
    (void)hd_preisach_bf_step_p(&pz_bf, t, 4);
    (void)hd_preisach_bf_step_p(&pz_bf, t, ptop - 8);
    (void)hd_preisach_bf_step_p(&pz_bf, t, 10);
}

static void cost_pz_on(uint32_t levels)
{
    const hd_preisach_table_t *t = pz_table(levels);
    pz_prime_online(t);
    hd_gv_cost_mark();
    sink32 = (int32_t)hd_preisach_step_p(&pz_on, t, cv_p);
    hd_gv_cost_mark();
}

static void cost_pz_bf(uint32_t levels)
{
    const hd_preisach_table_t *t = pz_table(levels);
    pz_prime_brute(t);
    hd_gv_cost_mark();
    sink32 = (int32_t)hd_preisach_bf_step_p(&pz_bf, t, cv_p);
    hd_gv_cost_mark();
}

static void cost_pz_on32(void) { cost_pz_on(32u); }
static void cost_pz_on64(void) { cost_pz_on(64u); }
static void cost_pz_bf32(void) { cost_pz_bf(32u); }
static void cost_pz_bf64(void) { cost_pz_bf(64u); }

static void gen_pz_target(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = ((idx & 15u) == 15u) ? hd_gv_rand_range(r, -2000000, 2000000)
                                 : hd_gv_rand_range(r, -100000, 100000);
}

static void run_pz_inv32(const int32_t *in, int32_t *out, uint32_t count)
{
    const hd_preisach_table_t *t = pz_table(32u);
    const int64_t ymax = (int64_t)hd_preisach_everett(t, hd_preisach_p_top(t), 0);
    int64_t yd = 0;
    uint32_t k;
    hd_preisach_inv_init(&pz_inv, t, 0u, 0u, true);
    for (k = 0; k < count; k++) {
        yd = hd_clamp64(yd + in[k], -ymax, ymax);
        out[3u * k] = hd_preisach_inv_step_p(&pz_inv, t, yd);
        hd_gv_put64(&out[3u * k + 1u], pz_inv.fwd.y);
    }
}

static void cost_pz_inv32(void)
{
    const hd_preisach_table_t *t = pz_table(32u);
    hd_preisach_inv_init(&pz_inv, t, 0u, 0u, true);
    (void)hd_preisach_inv_step_p(&pz_inv, t, 100000);
    (void)hd_preisach_inv_step_p(&pz_inv, t, -50000);
    hd_gv_cost_mark();
    sink32 = hd_preisach_inv_step_p(&pz_inv, t, (int64_t)cv_v / 64);
    hd_gv_cost_mark();
}

const hd_gv_kernel_t hd_gv_comp_kernels[] = {
    { "comp_stribeck_step", 2u, 2u, 256u, gen_two_vel, run_stribeck, cost_stribeck },
    { "comp_stribeck_cruise", 2u, 2u, 256u, gen_cruise_vel, run_stribeck_cruise, NULL },
    { "comp_stribeck_steady", 2u, 2u, 256u, gen_cruise_vel, run_stribeck_steady, NULL },
    { "comp_lugre_step", 3u, 3u, 256u, gen_lugre, run_lugre, cost_lugre },
    { "comp_maxwell_step_n8", 1u, 3u, 256u, gen_step, run_maxwell, cost_maxwell },
    { "comp_te_step_h4", 2u, 3u, 256u, gen_angle, run_te, cost_te },
    { "comp_te_model_slope_fit32", 2u, 3u, 256u, gen_angle, run_te_slope, cost_te_slope },
    { "comp_backstep_step", 7u, 5u, 256u, gen_backstep, run_backstep, cost_backstep },
    { "preisach_online_L32", 1u, 2u, 512u, gen_pz_step, run_pz_on32, cost_pz_on32 },
    { "preisach_online_L64", 1u, 2u, 512u, gen_pz_step, run_pz_on64, cost_pz_on64 },
    { "preisach_bruteforce_L32", 1u, 2u, 128u, gen_pz_step, run_pz_bf32, cost_pz_bf32 },
    { "preisach_bruteforce_L64", 1u, 2u, 48u, gen_pz_step, run_pz_bf64, cost_pz_bf64 },
    { "preisach_inverse_L32", 1u, 3u, 256u, gen_pz_target, run_pz_inv32, cost_pz_inv32 },
};
const uint32_t hd_gv_comp_count = sizeof hd_gv_comp_kernels / sizeof hd_gv_comp_kernels[0];
