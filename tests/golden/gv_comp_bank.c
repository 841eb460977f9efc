/*
 * gv_comp_bank.c - golden vectors and Cortex-M4 cost of one full control
 * period with every compensator of the bank on (hd_app_step with cb_enable =
 * all: Stribeck, LuGre with observer, Maxwell-slip, Preisach inverse with a
 * table, TE, backstepping, DOB), kernel `control_step_full`; kernels
 * `control_step_semi` and `control_step_dual`: the same period in the semi-closed
 * and dual-loop feedback configurations (fb_config 1, 2) with the compliance twist
 * on as well, the position loop closed on the motor-side estimate of the output.
 * The hal stub is the one of gv_app.c (gv_app_stub_*).
 */
#include "gv.h"
#include "hal.h"
#include "hd_app.h"
#include "hd_sched.h"

void gv_app_stub_sensors(uint32_t motor_raw, uint32_t output_raw);
int32_t gv_app_stub_torque(void);

static hd_app_t gv_full;
static hd_preisach_table_t gv_tab;

/* A small twist -> torque table: linear (K = 2 N.m per lattice unit) plus a
 * saturating hysteresis term, L = 16, 2 sub-steps, lattice step 2^10 (2^-32 turn). */
static void make_table(void)
{
    uint32_t i, j;
    gv_tab.version = 1u;
    gv_tab.levels = 16u;
    gv_tab.sub_bits = 1u;
    gv_tab.in_shift = 10u;
    gv_tab.u0 = -(int32_t)(15u << 10);
    gv_tab.unit = HD_PREISACH_UNIT_GENERIC;
    for (i = 0; i < 16u; i++) {
        for (j = 0; j <= i; j++) {
            const int32_t d = (int32_t)(i - j);
            gv_tab.e[i * (i + 1u) / 2u + j] = d * 65536 + ((d < 4) ? d * d * 4096 : 65536);
        }
    }
    hd_preisach_seal(&gv_tab);
}

static void gen_full(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t out_cnt = 1000u + idx / 2u + (hd_gv_rand32(r) & 1u);
    const uint32_t mot_cnt = (idx * 781u + (hd_gv_rand32(r) & 7u)) & 0x1FFFFu;
    in[0] = (int32_t)mot_cnt;
    in[1] = (int32_t)(out_cnt & 0xFFFFFFu);
}

static void start_fb(uint32_t mot, uint32_t out, int32_t fb, uint32_t enable)
{
    gv_app_stub_sensors(mot, out);
    hd_app_init(&gv_full);
    (void)hd_app_param_set(&gv_full, HD_P_FAULT_ENABLE, 0);
    (void)hd_app_param_set(&gv_full, HD_P_FB_CONFIG, fb);
    (void)hd_app_param_set(&gv_full, HD_P_FB_DUAL_FC, 50 << 16);   /* fast blend: 256 periods see it act */
    (void)hd_app_param_set(&gv_full, HD_P_LUG_K_OBS, 30 << 16);
    (void)hd_app_param_set(&gv_full, HD_P_TE_K1, 1 << 20);
    (void)hd_app_param_set(&gv_full, HD_P_CB_RAMP_TICKS, 4);
    make_table();
    (void)hd_app_comp_table(&gv_full, &gv_tab);
    hd_app_step(&gv_full);
    (void)hd_app_move_to(&gv_full, gv_full.pos_out + ((hd_angle_t)1 << 24));
    (void)hd_app_set_mode(&gv_full, HD_MODE_PTP);
    (void)hd_app_param_set(&gv_full, HD_P_CB_ENABLE, (int32_t)enable);
}

static void start(uint32_t mot, uint32_t out)
{
    start_fb(mot, out, HD_FB_FULL_CLOSED, HD_CB_ALL);
}

static void run_full(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    start((uint32_t)in[0], (uint32_t)in[1]);
    for (k = 0; k < count; k++) {
        gv_app_stub_sensors((uint32_t)in[2u * k], (uint32_t)in[2u * k + 1u]);
        hd_app_step(&gv_full);
        out[4u * k] = gv_app_stub_torque();
        out[4u * k + 1u] = gv_full.cb.out.tff;
        out[4u * k + 2u] = gv_full.cb.out.dvel;
        out[4u * k + 3u] = gv_full.cb.u_bs;
    }
}

/* Cost kernels of one tick of the bank's schedule (hd_sched.h): the app is stepped on
 * (encoders advancing 5 motor / 1 output count per period from mot / out) until its next
 * period is tick `tick` of the cycle; *mot / *out are then the last inputs.  Returns 1
 * then, 0 if it never got there (the caller then makes no cost marks and
 * tools/cm4_cost.py fails on the mark count: a tick is never silently skipped). */
int32_t gv_app_to_tick(hd_app_t *a, uint32_t tick, uint32_t *mot, uint32_t *out);
int32_t gv_app_to_tick(hd_app_t *a, uint32_t tick, uint32_t *mot, uint32_t *out)
{
    uint32_t i;
    for (i = 0; i < HD_SCHED_CYCLE && (a->cb.tick & (HD_SCHED_CYCLE - 1u)) != tick; i++) {
        *mot = (*mot + 5u) & 0x1FFFFu;
        *out = (*out + 1u) & 0xFFFFFFu;
        gv_app_stub_sensors(*mot, *out);
        hd_app_step(a);
    }
    return ((a->cb.tick & (HD_SCHED_CYCLE - 1u)) == tick) ? 1 : 0;
}

static void cost_full(uint32_t slot)
{
    int32_t in[2 * 16];
    int32_t out[4 * 16];
    hd_gv_rng_t r;
    uint32_t i;
    r.s = 4242u;
    for (i = 0; i < 16u; i++) {
        gen_full(i, &r, &in[2u * i]);
    }
    run_full(in, out, 16u);          /* PTP moving, every compensator fully on (ramp 4 periods) */
    uint32_t mot = (uint32_t)in[30], outc = (uint32_t)in[31];
    if (gv_app_to_tick(&gv_full, slot, &mot, &outc) == 0) {
        return;
    }
    gv_app_stub_sensors((mot + 5u) & 0x1FFFFu, (outc + 1u) & 0xFFFFFFu);
    hd_gv_cost_mark();
    hd_app_step(&gv_full);
    hd_gv_cost_mark();
}

/* semi-closed / dual-loop: torque, position error, the loop's feedback (low word)
 * and the bank's predicted offset (low word) */
static void run_fb(const int32_t *in, int32_t *out, uint32_t count, int32_t fb)
{
    uint32_t k;
    start_fb((uint32_t)in[0], (uint32_t)in[1], fb, HD_CB_ALL | HD_CB_COMPLIANCE);
    for (k = 0; k < count; k++) {
        gv_app_stub_sensors((uint32_t)in[2u * k], (uint32_t)in[2u * k + 1u]);
        hd_app_step(&gv_full);
        out[4u * k] = gv_app_stub_torque();
        out[4u * k + 1u] = gv_full.tel.pos_err;
        out[4u * k + 2u] = hd_gv_u2s((uint32_t)(uint64_t)gv_full.tel.pos_fb);
        out[4u * k + 3u] = hd_gv_u2s((uint32_t)(uint64_t)gv_full.cb.out.dpos);
    }
}

static void run_semi(const int32_t *in, int32_t *out, uint32_t count)
{
    run_fb(in, out, count, HD_FB_SEMI_CLOSED);
}

static void run_dual(const int32_t *in, int32_t *out, uint32_t count)
{
    run_fb(in, out, count, HD_FB_DUAL_LOOP);
}

static void cost_fb(int32_t fb, uint32_t slot)
{
    int32_t in[2 * 16];
    int32_t out[4 * 16];
    hd_gv_rng_t r;
    uint32_t i;
    r.s = 4242u;
    for (i = 0; i < 16u; i++) {
        gen_full(i, &r, &in[2u * i]);
    }
    run_fb(in, out, 16u, fb);
    uint32_t mot = (uint32_t)in[30], outc = (uint32_t)in[31];
    if (gv_app_to_tick(&gv_full, slot, &mot, &outc) == 0) {
        return;
    }
    gv_app_stub_sensors((mot + 5u) & 0x1FFFFu, (outc + 1u) & 0xFFFFFFu);
    hd_gv_cost_mark();
    hd_app_step(&gv_full);
    hd_gv_cost_mark();
}

/* the first period after the loops start (mode entry, reset): the bank evaluates every
 * compensator at once (hd_comp_bank_pre, hd_sched.h), once per start */
static void cost_entry(void)
{
    int32_t in[2 * 16];
    int32_t out[4 * 16];
    hd_gv_rng_t r;
    uint32_t i;
    r.s = 4242u;
    for (i = 0; i < 16u; i++) {
        gen_full(i, &r, &in[2u * i]);
    }
    run_full(in, out, 16u);
    gv_app_stub_sensors(((uint32_t)in[30] + 5u) & 0x1FFFFu, ((uint32_t)in[31] + 1u) & 0xFFFFFFu);
    gv_full.cb.dpos_primed = 0u;            /* as the app's loop reset leaves it */
    hd_gv_cost_mark();
    hd_app_step(&gv_full);
    hd_gv_cost_mark();
}

/* one cost kernel per tick of the schedule (hd_sched.h); tools/cm4_cost.py takes the worst */
static void cost_full_s0(void) { cost_full(0u); }
static void cost_full_s1(void) { cost_full(1u); }
static void cost_full_s2(void) { cost_full(2u); }
static void cost_full_s3(void) { cost_full(3u); }
static void cost_full_s4(void) { cost_full(4u); }
static void cost_full_s5(void) { cost_full(5u); }
static void cost_full_s6(void) { cost_full(6u); }
static void cost_full_s7(void) { cost_full(7u); }
static void cost_semi_s0(void) { cost_fb(HD_FB_SEMI_CLOSED, 0u); }
static void cost_semi_s1(void) { cost_fb(HD_FB_SEMI_CLOSED, 1u); }
static void cost_semi_s2(void) { cost_fb(HD_FB_SEMI_CLOSED, 2u); }
static void cost_semi_s3(void) { cost_fb(HD_FB_SEMI_CLOSED, 3u); }
static void cost_semi_s4(void) { cost_fb(HD_FB_SEMI_CLOSED, 4u); }
static void cost_semi_s5(void) { cost_fb(HD_FB_SEMI_CLOSED, 5u); }
static void cost_semi_s6(void) { cost_fb(HD_FB_SEMI_CLOSED, 6u); }
static void cost_semi_s7(void) { cost_fb(HD_FB_SEMI_CLOSED, 7u); }
static void cost_dual_s0(void) { cost_fb(HD_FB_DUAL_LOOP, 0u); }
static void cost_dual_s1(void) { cost_fb(HD_FB_DUAL_LOOP, 1u); }
static void cost_dual_s2(void) { cost_fb(HD_FB_DUAL_LOOP, 2u); }
static void cost_dual_s3(void) { cost_fb(HD_FB_DUAL_LOOP, 3u); }
static void cost_dual_s4(void) { cost_fb(HD_FB_DUAL_LOOP, 4u); }
static void cost_dual_s5(void) { cost_fb(HD_FB_DUAL_LOOP, 5u); }
static void cost_dual_s6(void) { cost_fb(HD_FB_DUAL_LOOP, 6u); }
static void cost_dual_s7(void) { cost_fb(HD_FB_DUAL_LOOP, 7u); }

const hd_gv_kernel_t hd_gv_comp_bank_kernels[] = {
    {"control_step_full", 2u, 4u, 256u, gen_full, run_full, NULL},
    {"control_step_semi", 2u, 4u, 256u, gen_full, run_semi, NULL},
    {"control_step_dual", 2u, 4u, 256u, gen_full, run_dual, NULL},
    {"control_step_entry", 2u, 4u, 8u, gen_full, run_full, cost_entry},
    {"control_step_full.s0", 2u, 4u, 8u, gen_full, run_full, cost_full_s0},
    {"control_step_full.s1", 2u, 4u, 8u, gen_full, run_full, cost_full_s1},
    {"control_step_full.s2", 2u, 4u, 8u, gen_full, run_full, cost_full_s2},
    {"control_step_full.s3", 2u, 4u, 8u, gen_full, run_full, cost_full_s3},
    {"control_step_full.s4", 2u, 4u, 8u, gen_full, run_full, cost_full_s4},
    {"control_step_full.s5", 2u, 4u, 8u, gen_full, run_full, cost_full_s5},
    {"control_step_full.s6", 2u, 4u, 8u, gen_full, run_full, cost_full_s6},
    {"control_step_full.s7", 2u, 4u, 8u, gen_full, run_full, cost_full_s7},
    {"control_step_semi.s0", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s0},
    {"control_step_semi.s1", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s1},
    {"control_step_semi.s2", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s2},
    {"control_step_semi.s3", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s3},
    {"control_step_semi.s4", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s4},
    {"control_step_semi.s5", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s5},
    {"control_step_semi.s6", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s6},
    {"control_step_semi.s7", 2u, 4u, 8u, gen_full, run_semi, cost_semi_s7},
    {"control_step_dual.s0", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s0},
    {"control_step_dual.s1", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s1},
    {"control_step_dual.s2", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s2},
    {"control_step_dual.s3", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s3},
    {"control_step_dual.s4", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s4},
    {"control_step_dual.s5", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s5},
    {"control_step_dual.s6", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s6},
    {"control_step_dual.s7", 2u, 4u, 8u, gen_full, run_dual, cost_dual_s7},
};
const uint32_t hd_gv_comp_bank_count = sizeof hd_gv_comp_bank_kernels / sizeof hd_gv_comp_bank_kernels[0];
