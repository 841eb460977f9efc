/*
 * gv_gear_torque.c - golden-vector kernel of the motor-side transmitted-torque
 * estimate (hd_gear_torque.h): one stateful step per vector, inputs the applied
 * torque, the motor friction, the model torque and the two velocities (edge
 * values among them), outputs the estimate and the hand-over weight.
 *
 * control_step_semi_t_src1_tick4 / control_step_semi_t_src2_tick4: the app's control step
 * in semi-closed, every compensator on (no Preisach table), PTP moving, at tick 4 of
 * the bank's schedule (the slot of the transmitted-torque estimate), with the model
 * estimate (pr_t_src 1) and the motor-side one (pr_t_src 2): their difference is what
 * the motor-side estimate adds to that period.
 */
#include "gv.h"
#include "hd_fixed.h"
#include "hd_gear_torque.h"
#include "hd_app.h"

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

/* ---- the control step with either estimate (gv_app.c stubs, gv_comp_bank.c's tick helper) ---- */

void gv_app_stub_sensors(uint32_t motor_raw, uint32_t output_raw);
int32_t gv_app_stub_torque(void);
int32_t gv_app_to_tick(hd_app_t *a, uint32_t tick, uint32_t *mot, uint32_t *out);

static hd_app_t gv_gt_app;

static void gen_enc(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = (int32_t)((idx * 781u + (hd_gv_rand32(r) & 7u)) & 0x1FFFFu);
    in[1] = (int32_t)((1000u + idx / 2u + (hd_gv_rand32(r) & 1u)) & 0xFFFFFFu);
}

static void run_src(const int32_t *in, int32_t *out, uint32_t count, int32_t src)
{
    uint32_t k;
    gv_app_stub_sensors((uint32_t)in[0], (uint32_t)in[1]);
    hd_app_init(&gv_gt_app);
    (void)hd_app_param_set(&gv_gt_app, HD_P_FAULT_ENABLE, 0);
    (void)hd_app_param_set(&gv_gt_app, HD_P_FB_CONFIG, HD_FB_SEMI_CLOSED);
    (void)hd_app_param_set(&gv_gt_app, HD_P_CB_RAMP_TICKS, 4);
    (void)hd_app_param_set(&gv_gt_app, HD_P_PR_T_SRC, src);
    hd_app_step(&gv_gt_app);
    (void)hd_app_move_to(&gv_gt_app, gv_gt_app.pos_out + ((hd_angle_t)1 << 24));
    (void)hd_app_set_mode(&gv_gt_app, HD_MODE_PTP);
    (void)hd_app_param_set(&gv_gt_app, HD_P_CB_ENABLE, (int32_t)(HD_CB_ALL | HD_CB_COMPLIANCE));
    for (k = 0; k < count; k++) {
        gv_app_stub_sensors((uint32_t)in[2u * k], (uint32_t)in[2u * k + 1u]);
        hd_app_step(&gv_gt_app);
        out[2u * k] = gv_app_stub_torque();
        out[2u * k + 1u] = gv_gt_app.cb.pr_test;
    }
}

static void run_src1(const int32_t *in, int32_t *out, uint32_t count) { run_src(in, out, count, 1); }
static void run_src2(const int32_t *in, int32_t *out, uint32_t count) { run_src(in, out, count, 2); }

static void cost_src(int32_t src)
{
    int32_t in[2 * 16];
    int32_t out[2 * 16];
    hd_gv_rng_t r;
    uint32_t i;
    r.s = 4242u;
    for (i = 0; i < 16u; i++) {
        gen_enc(i, &r, &in[2u * i]);
    }
    run_src(in, out, 16u, src);
    uint32_t mot = (uint32_t)in[30], outc = (uint32_t)in[31];
    if (gv_app_to_tick(&gv_gt_app, (uint32_t)HD_SLOT_MAXWELL_EST, &mot, &outc) == 0) {
        return;
    }
    gv_app_stub_sensors((mot + 5u) & 0x1FFFFu, (outc + 1u) & 0xFFFFFFu);
    hd_gv_cost_mark();
    hd_app_step(&gv_gt_app);
    hd_gv_cost_mark();
}

static void cost_src1(void) { cost_src(1); }
static void cost_src2(void) { cost_src(2); }

const hd_gv_kernel_t hd_gv_gear_torque_kernels[] = {
    {"gear_torque_step", 5u, 2u, 512u, gen_gt, run_gt, cost_gt},
    {"control_step_semi_t_src1_tick4", 2u, 2u, 64u, gen_enc, run_src1, cost_src1},
    {"control_step_semi_t_src2_tick4", 2u, 2u, 64u, gen_enc, run_src2, cost_src2},
};
const uint32_t hd_gv_gear_torque_count = sizeof hd_gv_gear_torque_kernels / sizeof hd_gv_gear_torque_kernels[0];
