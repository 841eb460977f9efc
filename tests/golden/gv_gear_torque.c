/*
 * gv_gear_torque.c - golden-vector kernel of the motor-side transmitted-torque
 * estimate (hd_gear_torque.h): one stateful step per vector, inputs the applied
 * torque, the motor friction, the model torque and the two velocities (edge
 * values among them), outputs the estimate and the hand-over weight.
 */
#include "gv.h"
#include "hd_fixed.h"
#include "hd_gear_torque.h"

#define DEGS 11930465          /* 1 deg/s, 2^-32 turn/s */

static const hd_gear_torque_cfg_t gt_cfg = { 97345 /* 1.4854 kg m^2 */, 21474836 /* 1.8 deg/s */, 1250 };

static volatile int32_t cv_t = 30 << 16;
static volatile int32_t cv_f = 20 << 16;
static volatile int32_t cv_v = 40 * DEGS;
static volatile int32_t cv_m = 5 << 16;
static volatile int32_t sink32;

static void gen_gt(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t edge = ((idx & 15u) == 0u) ? 1u : 0u;
    in[0] = (edge != 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -(80 << 16), 80 << 16);   /* t_applied */
    in[1] = hd_gv_rand_range(r, -(30 << 16), 30 << 16);                               /* f_motor */
    in[2] = (edge != 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -60 * DEGS, 60 * DEGS); /* v_ref */
    in[3] = ((idx & 7u) == 3u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -60 * DEGS, 60 * DEGS);   /* v_fb */
    in[4] = hd_gv_rand_range(r, -(40 << 16), 40 << 16);                               /* t_model */
}

static void run_gt(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_gear_torque_t s;
    uint32_t k;
    hd_gear_torque_reset(&s);
    for (k = 0; k < count; k++) {
        const int32_t *x = &in[5u * k];
        out[2u * k] = hd_gear_torque_step(&s, &gt_cfg, x[0], x[1], x[2], x[3], x[4]);
        out[2u * k + 1u] = s.w;
    }
}

static void cost_gt(void)
{
    hd_gear_torque_t s;
    hd_gear_torque_reset(&s);
    (void)hd_gear_torque_step(&s, &gt_cfg, 0, 0, 0, 0, 0);
    hd_gv_cost_mark();
    sink32 = hd_gear_torque_step(&s, &gt_cfg, cv_t, cv_f, cv_v / 20, cv_v, cv_m);
    hd_gv_cost_mark();
}

const hd_gv_kernel_t hd_gv_gear_torque_kernels[] = {
    {"gear_torque_step", 5u, 2u, 512u, gen_gt, run_gt, cost_gt},
};
const uint32_t hd_gv_gear_torque_count = sizeof hd_gv_gear_torque_kernels / sizeof hd_gv_gear_torque_kernels[0];
