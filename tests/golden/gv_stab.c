/*
 * gv_stab.c - golden-vector kernels of the inertial stabilisation estimator
 * (firmware/core/hd_stab.h): design from table-unit parameters, and the step
 * with the blend on (every path) and off.  The stateful kernel starts once and
 * steps once per vector.
 */
#include "gv.h"
#include "hd_fixed.h"
#include "hd_stab.h"

#define GV_N 512u

static volatile int32_t cv_gyro = 1234567;
static volatile int32_t cv_pos_lo = 76543210;
static volatile int32_t sink32;

/* ---- design: bias, fc, fr, bias_max, bw, zeta, ff_db -> cfg words ------------ */

static void gen_design(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = hd_gv_rand_edge32(r);                       /* bias */
    in[1] = hd_gv_rand_range(r, 0, 655);                /* fc <= 0.01 Hz (Q16) */
    in[2] = hd_gv_rand_range(r, 66, 655360);            /* fr 0.001 .. 10 Hz */
    in[3] = hd_gv_rand_range(r, -1000, 42949673);       /* bias_max */
    in[4] = hd_gv_rand_range(r, 65536, 65536000);       /* bw 1 .. 1000 Hz */
    in[5] = hd_gv_rand_range(r, 19661, 196608);         /* zeta 0.3 .. 3 */
    in[6] = hd_gv_rand_range(r, -5, 42949673);          /* ff_db */
    if ((idx & 15u) == 0u) {
        in[1] = 0;                                      /* blend off */
    }
}

static void run_design(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    for (k = 0; k < count; k++) {
        const int32_t *x = &in[7u * k];
        int32_t *y = &out[8u * k];
        hd_stab_cfg_t c;
        hd_stab_design(&c, x[0], x[1], x[2], x[3], x[4], x[5], x[6]);
        y[0] = c.bias;
        y[1] = c.blend_kp;
        y[2] = c.blend_ki;
        y[3] = c.alpha;
        y[4] = c.bias_max;
        y[5] = c.ff_db;
        y[6] = c.obs.kp_dt;
        y[7] = c.obs.ki_dt;
    }
}

/* ---- step: gyro, pos_out (two words), rate_cmd -> err, vff, vff_db, base_rate, ang --- */

/* reference design: bias 0.5 deg/h, blend fc 0.005 Hz / fr 0.05 Hz, bias_max 10 deg/h,
 * observer 100 Hz zeta 1, dead band 1e-5 turn/s; the blend gains are exaggerated
 * (fc 0.01 Hz) in the second kernel so that its rounding paths are hit */
static hd_stab_cfg_t cfg_for(int32_t fc_q16)
{
    hd_stab_cfg_t c;
    hd_stab_design(&c, 1664, fc_q16, 3277, 119305, 6553600, 65536, 42950);
    return c;
}

static void gen_step(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    /* a rocking payload: the angle walks, the gyro carries rate + noise, with edges */
    const int64_t pos = (int64_t)hd_gv_rand_range(r, -200000000, 200000000) * 64;
    in[0] = hd_gv_rand_range(r, -300000000, 300000000);
    hd_gv_put64(&in[1], pos);
    in[3] = hd_gv_rand_range(r, -2000000, 2000000);
    if ((idx & 31u) == 7u) {
        in[0] = hd_gv_rand_edge32(r);
        hd_gv_put64(&in[1], hd_gv_rand_edge64(r));
    }
    if ((idx & 31u) == 19u) {
        in[3] = hd_gv_rand_edge32(r);
    }
}

static void run_step_cfg(const int32_t *in, int32_t *out, uint32_t count, int32_t fc_q16)
{
    const hd_stab_cfg_t c = cfg_for(fc_q16);
    hd_stab_t s;
    uint32_t k;
    hd_stab_init(&s);
    hd_stab_start(&s, &c, hd_gv_get64(&in[1]), in[0], 1000);
    for (k = 0; k < count; k++) {
        const int32_t *x = &in[4u * k];
        int32_t *y = &out[7u * k];
        hd_stab_step(&s, &c, x[0], hd_gv_get64(&x[1]), x[3]);
        y[0] = s.err;
        y[1] = s.vff;
        y[2] = s.vff_db;
        y[3] = s.base_rate;
        hd_gv_put64(&y[4], hd_stab_angle(&s));
        y[6] = hd_sat32(hd_asr64_rnd(s.b_hat, 24u));
    }
}

static void run_step_blend(const int32_t *in, int32_t *out, uint32_t count)
{
    run_step_cfg(in, out, count, 655);
}

static void run_step_pure(const int32_t *in, int32_t *out, uint32_t count)
{
    run_step_cfg(in, out, count, 0);
}

static void cost_step(void)
{
    const hd_stab_cfg_t c = cfg_for(131);
    hd_stab_t s;
    hd_stab_init(&s);
    hd_gv_cost_mark();
    hd_stab_step(&s, &c, cv_gyro, (hd_angle_t)cv_pos_lo, 0);
    hd_gv_cost_mark();
    sink32 = s.vff;
}

static void cost_step_pure(void)
{
    const hd_stab_cfg_t c = cfg_for(0);
    hd_stab_t s;
    hd_stab_init(&s);
    hd_gv_cost_mark();
    hd_stab_step(&s, &c, cv_gyro, (hd_angle_t)cv_pos_lo, 0);
    hd_gv_cost_mark();
    sink32 = s.vff;
}

const hd_gv_kernel_t hd_gv_stab_kernels[] = {
    {"stab_design", 7u, 8u, 256u, gen_design, run_design, NULL},
    {"stab_step_blend", 4u, 7u, GV_N, gen_step, run_step_blend, cost_step},
    {"stab_step", 4u, 7u, GV_N, gen_step, run_step_pure, cost_step_pure},
};
const uint32_t hd_gv_stab_count = sizeof hd_gv_stab_kernels / sizeof hd_gv_stab_kernels[0];
