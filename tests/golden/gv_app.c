/*
 * gv_app.c - golden vectors of one full control period (hd_app_step: encoder
 * unwrapping, observers, trajectory, position/velocity PID, torque filters,
 * limits) and its Cortex-M4 cost, kernel `control_step_baseline`; kernel
 * `control_step_hold`: the same at standstill with the Stribeck feed-forward on
 * the measured velocity and the standstill hunt breaker armed (hold_*: short
 * times so that the 1024 periods fade it out and back several times).
 *
 * The golden images have no hal.h port, so this file provides a stub hal:
 * sensors come from the current input vector, the command is recorded, NVM
 * reads as blank (defaults) and refuses writes, CAN is idle.
 */
#include "gv.h"
#include "hal.h"
#include "hd_app.h"
#include "hd_fixed.h"

static hd_app_t gv_app;
static hd_hal_sensors_t stub_sens;
static hd_hal_command_t stub_cmd;
static uint32_t stub_tick;

/* Shared with gv_comp_bank.c (one hal stub per image). */
void gv_app_stub_sensors(uint32_t motor_raw, uint32_t output_raw);
int32_t gv_app_stub_torque(void);
void gv_app_stub_sensors(uint32_t motor_raw, uint32_t output_raw)
{
    stub_sens.current = 0;
    stub_sens.gyro_rate = 0;
    stub_sens.valid = HD_HAL_VALID_ALL;
    stub_sens.motor_enc_raw = motor_raw;
    stub_sens.output_enc_raw = output_raw;
}
int32_t gv_app_stub_torque(void) { return stub_cmd.torque; }

uint32_t hd_hal_tick(void) { return stub_tick; }
void hd_hal_read_sensors(hd_hal_sensors_t *s) { *s = stub_sens; }
void hd_hal_write_command(const hd_hal_command_t *c) { stub_cmd = *c; stub_tick++; }
bool hd_hal_can_send(const hd_can_frame_t *f) { (void)f; return false; }
bool hd_hal_can_recv(hd_can_frame_t *f) { (void)f; return false; }
uint32_t hd_hal_nvm_size(void) { return 4096u; }
uint32_t hd_hal_nvm_page_size(void) { return 2048u; }
int32_t hd_hal_nvm_read(uint32_t offset, void *buf, uint32_t len)
{
    uint8_t *p = (uint8_t *)buf;
    uint32_t i;
    (void)offset;
    for (i = 0; i < len; i++) {
        p[i] = 0xFFu;
    }
    return 0;
}
int32_t hd_hal_nvm_write(uint32_t offset, const void *buf, uint32_t len)
{
    (void)offset; (void)buf; (void)len;
    return -1;
}
int32_t hd_hal_nvm_erase(uint32_t offset, uint32_t len)
{
    (void)offset; (void)len;
    return -1;
}

/* Inputs per period: motor encoder raw (17 bit), output encoder raw (24 bit).
 * The generator makes a plausible slow motion (the output advancing ~0.5 count
 * per period, the motor N = 100 times faster) with noise. */
static void gen_step(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const uint32_t out_cnt = 1000u + idx / 2u + (hd_gv_rand32(r) & 1u);
    const uint32_t mot_cnt = (idx * 781u + (hd_gv_rand32(r) & 7u)) & 0x1FFFFu;
    in[0] = (int32_t)mot_cnt;
    in[1] = (int32_t)(out_cnt & 0xFFFFFFu);
}

static void run_step(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    stub_tick = 0;
    stub_sens.current = 0;
    stub_sens.gyro_rate = 0;
    stub_sens.valid = HD_HAL_VALID_ALL;
    stub_sens.motor_enc_raw = (uint32_t)in[0];
    stub_sens.output_enc_raw = (uint32_t)in[1];
    hd_app_init(&gv_app);
    (void)hd_app_param_set(&gv_app, HD_P_FAULT_ENABLE, 0);     /* the vectors are not a real axis */
    hd_app_step(&gv_app);
    (void)hd_app_move_to(&gv_app, gv_app.pos_out + ((hd_angle_t)1 << 24));
    (void)hd_app_set_mode(&gv_app, HD_MODE_PTP);
    for (k = 0; k < count; k++) {
        stub_sens.motor_enc_raw = (uint32_t)in[2u * k];
        stub_sens.output_enc_raw = (uint32_t)in[2u * k + 1u];
        hd_app_step(&gv_app);
        out[4u * k] = stub_cmd.torque;
        out[4u * k + 1u] = stub_cmd.current;
        out[4u * k + 2u] = gv_app.tel.vel_out;
        out[4u * k + 3u] = gv_app.tel.pos_err;
    }
}

static void cost_step(void)
{
    int32_t in[2 * 8];
    int32_t out[4 * 8];
    hd_gv_rng_t r;
    uint32_t i;
    r.s = 12345u;
    for (i = 0; i < 8u; i++) {
        gen_step(i, &r, &in[2u * i]);
    }
    run_step(in, out, 8u);           /* app in PTP, moving, loops primed */
    stub_sens.motor_enc_raw = (uint32_t)in[0] + 5u;
    hd_gv_cost_mark();
    hd_app_step(&gv_app);
    hd_gv_cost_mark();
}

/* control_step_hold inputs: the output encoder at rest (count 5000, +-1 noise) except
 * for excursions of 6..13 counts (beyond hold_hunt_win = 3 counts) in periods 100..119
 * of every 256; the motor encoder N = 100 times the output with 3 bits of noise. */
static void gen_hold(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    uint32_t out_cnt = 5000u + (hd_gv_rand32(r) & 1u);
    if ((idx & 255u) >= 100u && (idx & 255u) < 120u) {
        out_cnt += 6u + (hd_gv_rand32(r) & 7u);
    }
    in[0] = (int32_t)((out_cnt * 100u / 128u + (hd_gv_rand32(r) & 7u)) & 0x1FFFFu);   /* 2^24 / 2^17 = 128 */
    in[1] = (int32_t)(out_cnt & 0xFFFFFFu);
}

static void hold_setup(const int32_t *in)
{
    stub_tick = 0;
    stub_sens.current = 0;
    stub_sens.gyro_rate = 0;
    stub_sens.valid = HD_HAL_VALID_ALL;
    stub_sens.motor_enc_raw = (uint32_t)in[0];
    stub_sens.output_enc_raw = (uint32_t)in[1];
    hd_app_init(&gv_app);
    (void)hd_app_param_set(&gv_app, HD_P_FAULT_ENABLE, 0);
    (void)hd_app_param_set(&gv_app, HD_P_STR_W_REF, 0);            /* relay on the measured velocity */
    (void)hd_app_param_set(&gv_app, HD_P_CB_RAMP_TICKS, 4);
    (void)hd_app_param_set(&gv_app, HD_P_CB_ENABLE, (int32_t)HD_CB_STRIBECK);
    (void)hd_app_param_set(&gv_app, HD_P_HOLD_TICKS, 16);
    (void)hd_app_param_set(&gv_app, HD_P_HOLD_FADE_TICKS, 7);      /* 2^30 / 7: a rounded step */
    (void)hd_app_param_set(&gv_app, HD_P_HOLD_HUNT_WIN, 3 * 256);  /* 3 output counts */
    hd_app_step(&gv_app);
    (void)hd_app_set_mode(&gv_app, HD_MODE_POSITION);
}

static void run_hold(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    hold_setup(in);
    for (k = 0; k < count; k++) {
        stub_sens.motor_enc_raw = (uint32_t)in[2u * k];
        stub_sens.output_enc_raw = (uint32_t)in[2u * k + 1u];
        hd_app_step(&gv_app);
        out[4u * k] = stub_cmd.torque;
        out[4u * k + 1u] = gv_app.inpos_w;
        out[4u * k + 2u] = (int32_t)gv_app.inpos_n;
        out[4u * k + 3u] = hdf_sat32(hdf_asr64_rnd(gv_app.inpos_tau, 16u));
    }
}

static void cost_hold(void)
{
    int32_t in[2 * 128];
    int32_t out[4 * 128];
    hd_gv_rng_t r;
    uint32_t i;
    r.s = 12345u;
    for (i = 0; i < 128u; i++) {
        gen_hold(i + 64u, &r, &in[2u * i]);     /* periods 64..191: at rest, then the excursion */
    }
    run_hold(in, out, 40u);                     /* armed (16 periods at rest) */
    stub_sens.output_enc_raw = 5012u;           /* beyond the window: the breaker fades */
    hd_app_step(&gv_app);
    hd_app_step(&gv_app);
    hd_gv_cost_mark();
    hd_app_step(&gv_app);                       /* a fading period (the most work) */
    hd_gv_cost_mark();
}

const hd_gv_kernel_t hd_gv_app_kernels[] = {
    {"control_step_baseline", 2u, 4u, 512u, gen_step, run_step, cost_step},
    {"control_step_hold", 2u, 4u, 1024u, gen_hold, run_hold, cost_hold},
};
const uint32_t hd_gv_app_count = sizeof hd_gv_app_kernels / sizeof hd_gv_app_kernels[0];
