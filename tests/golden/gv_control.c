/*
 * gv_control.c - golden-vector kernels of the baseline controllers:
 * PID, velocity observer, biquad chain, trajectory generator, excitation
 * generator, capture buffer.  Stateful kernels initialise their state in
 * run() and step once per vector.  Each has a cost() of one step.
 */
#include "gv.h"
#include "hd_fixed.h"
#include "hd_pid.h"
#include "hd_vel_observer.h"
#include "hd_biquad.h"
#include "hd_trajectory.h"
#include "hd_excitation.h"
#include "hd_capture.h"

#define GV_N 512u

static volatile int32_t cv_a = 123456789;
static volatile int32_t cv_b = -98765;
static volatile int32_t sink32;

/* ---- PID (velocity-loop formats: in 2^-32 turn/s, out Q15.16 N.m) ------ */

static const hd_pid_cfg_t pid_cfg = {
    100904141,       /* kp: 245 N.m s/rad * 2 pi, Q16 per turn/s */
    475648,          /* ki_dt */
    2000000,         /* kd_fs */
    289000000,       /* d_alpha Q30 */
    32u,
    -(60 << 16), 60 << 16
};

static void gen_pid(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_edge32(r);                 /* ref */
    in[1] = hd_gv_rand_range(r, -100000000, 100000000); /* meas */
    in[2] = hd_gv_rand_range(r, -(1 << 20), 1 << 20);  /* ff */
    if ((idx & 7u) == 0u) {
        in[1] = hd_gv_rand_edge32(r);
    }
}

static void run_pid(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_pid_t s;
    uint32_t k;
    hd_pid_reset(&s);
    for (k = 0; k < count; k++) {
        const int32_t *x = &in[3u * k];
        out[2u * k] = hd_pid_step(&s, &pid_cfg, x[0], x[1], x[2]);
        out[2u * k + 1u] = s.i;
    }
}

static void cost_pid(void)
{
    hd_pid_t s;
    hd_pid_reset(&s);
    (void)hd_pid_step(&s, &pid_cfg, cv_a, cv_b, 0);
    hd_gv_cost_mark();
    sink32 = hd_pid_step(&s, &pid_cfg, cv_a, cv_b, cv_b);
    hd_gv_cost_mark();
}

/* ---- velocity observer --------------------------------------------------- */

static const hd_velobs_cfg_t obs_cfg = {36480, 2583};  /* ~30 Hz, zeta 1 */

static void gen_obs(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    /* angle increments: slow ramp + encoder-like noise, occasional edge values */
    in[0] = 1193 * (int32_t)(idx & 63u) + hd_gv_rand_range(r, -512, 512);
    in[1] = ((idx % 97u) == 0u) ? hd_gv_rand_edge32(r) : 0;
}

static void run_obs(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_velobs_t s;
    hd_angle_t th = 0;
    uint32_t k;
    hd_velobs_reset(&s, 0);
    for (k = 0; k < count; k++) {
        th = hd_add64_sat(th, (int64_t)in[2u * k] + (int64_t)in[2u * k + 1u]);
        hd_velobs_step(&s, &obs_cfg, th);
        out[3u * k] = hd_velobs_vel_out(&s);
        out[3u * k + 1u] = s.err;
        out[3u * k + 2u] = s.frac;
    }
}

static void cost_obs(void)
{
    hd_velobs_t s;
    hd_velobs_reset(&s, 0);
    hd_gv_cost_mark();
    hd_velobs_step(&s, &obs_cfg, (hd_angle_t)cv_a);
    hd_gv_cost_mark();
    sink32 = hd_velobs_vel_out(&s);
}

/* ---- biquad chain (notch 50 Hz + low-pass 1 kHz, reference-axis defaults) -- */

static const hd_biquad_chain_cfg_t bq_cfg = {
    2u,
    {{1061750748, -2119790300, 1059086064, -2119790300, 1047094988},
     {72429545, 144859100, 72429545, -1227264858, 443239925},
     {0, 0, 0, 0, 0}, {0, 0, 0, 0, 0}}
};

static void gen_bq(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = ((idx & 15u) == 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -(1 << 24), 1 << 24);
}

static void run_bq(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_biquad_chain_t s;
    uint32_t k;
    hd_biquad_chain_reset(&s);
    for (k = 0; k < count; k++) {
        out[k] = hd_biquad_chain_step(&s, &bq_cfg, in[k]);
    }
}

static void cost_bq(void)
{
    hd_biquad_chain_t s;
    hd_biquad_chain_reset(&s);
    hd_gv_cost_mark();
    sink32 = hd_biquad_chain_step(&s, &bq_cfg, cv_a);
    hd_gv_cost_mark();
}

/* ---- trajectory: commands every 128 periods (fast limits so moves finish) -- */

static const hd_traj_cfg_t tr_cfg = {.vmax = 1 << 28, .amax = 1 << 26, .jmax = 1 << 28};

static void gen_traj(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = ((idx & 127u) == 0u) ? (int32_t)((idx / 128u) % 4u) : -1;
    in[1] = hd_gv_rand_range(r, -(1 << 26), 1 << 26);
}

static void run_traj(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_traj_t s;
    uint32_t k;
    hd_traj_reset(&s, 0);
    for (k = 0; k < count; k++) {
        const int32_t cmd = in[2u * k], v = in[2u * k + 1u];
        if (cmd == 0) {
            (void)hd_traj_ptp(&s, &tr_cfg, s.pos + v);
        } else if (cmd == 1) {
            hd_traj_rate(&s, &tr_cfg, v);
        } else if (cmd == 2) {
            hd_traj_stop(&s, &tr_cfg);
        } else if (cmd == 3) {
            hd_traj_reset(&s, s.pos);
            (void)hd_traj_sine(&s, s.pos, v < 0 ? -v : v, 7 << 16);
        }
        hd_traj_step(&s, &tr_cfg);
        hd_gv_put64(&out[5u * k], s.pos);
        out[5u * k + 2u] = s.vel;
        out[5u * k + 3u] = s.acc;
        out[5u * k + 4u] = s.mode;
    }
}

static void cost_traj(void)
{
    hd_traj_t s;
    hd_traj_reset(&s, 0);
    (void)hd_traj_ptp(&s, &tr_cfg, (hd_angle_t)cv_a);
    hd_traj_step(&s, &tr_cfg);
    hd_gv_cost_mark();
    hd_traj_step(&s, &tr_cfg);
    hd_gv_cost_mark();
    sink32 = s.vel;
}

/* ---- trajectory with the one-direction final approach: a PTP every 160 periods
 * (refused while a move is under way), approach + or - by the command, so both
 * the split (wrong side: first leg, dwell, slow final leg) and the one-leg case
 * and the final-leg planning inside hd_traj_step() run on both targets. */

static const hd_traj_cfg_t tra_cfg_p = {.vmax = 1 << 28, .amax = 1 << 26, .jmax = 1 << 28,
                                        .appr_dir = 1, .appr_dist = 1 << 18, .appr_vmax = 1 << 26,
                                        .appr_dwell = 5u};
static const hd_traj_cfg_t tra_cfg_m = {.vmax = 1 << 28, .amax = 1 << 26, .jmax = 1 << 28,
                                        .appr_dir = -1, .appr_dist = 3 << 17, .appr_vmax = 0,
                                        .appr_dwell = 0u};

static void gen_traj_appr(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = ((idx % 160u) == 0u) ? (int32_t)((idx / 160u) % 2u) : -1;
    in[1] = hd_gv_rand_range(r, -(1 << 20), 1 << 20);
}

static void run_traj_appr(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_traj_t s;
    uint32_t k;
    const hd_traj_cfg_t *c = &tra_cfg_p;
    hd_traj_reset(&s, 0);
    for (k = 0; k < count; k++) {
        const int32_t cmd = in[2u * k], v = in[2u * k + 1u];
        if (cmd == 0 || cmd == 1) {
            const hd_traj_cfg_t *nc = (cmd == 0) ? &tra_cfg_p : &tra_cfg_m;
            if (hd_traj_ptp(&s, nc, s.pos + v) == 0) {
                c = nc;
            }
        }
        hd_traj_step(&s, c);
        hd_gv_put64(&out[5u * k], s.pos);
        out[5u * k + 2u] = s.vel;
        out[5u * k + 3u] = s.acc;
        out[5u * k + 4u] = s.mode | (s.appr_leg << 4) | (hd_traj_done(&s) << 8);
    }
}

/* ---- trajectory at slow velocity limits (reference-axis acceleration and jerk, the
 * min-rate ladder's rates and below): a PTP every 128 periods with its own vmax, so
 * the inserted-level ramps (cruise exactly at vmax), the one-period ramp (jerk above
 * vmax) and the cruise fraction carry run on both targets; v48 and a48 are output. */

static void gen_traj_slow(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    /* vmax 40 .. 81920 (2^-32 turn/s, log-spread: 3.4e-6 .. 6.9e-3 deg/s); travel 0 .. 8 ms of it */
    in[0] = ((idx & 127u) == 0u) ? (hd_gv_rand_range(r, 40, 80) << hd_gv_rand_range(r, 0, 10)) : -1;
    in[1] = hd_gv_rand_range(r, -8, 8);
}

static void run_traj_slow(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_traj_t s;
    hd_traj_cfg_t c = {.vmax = 11930, .amax = 4660338, .jmax = 182044};
    uint32_t k;
    hd_traj_reset(&s, 0);
    for (k = 0; k < count; k++) {
        if (in[2u * k] > 0 && hd_traj_done(&s)) {
            c.vmax = in[2u * k];
            (void)hd_traj_ptp(&s, &c, s.pos + (hd_angle_t)c.vmax * in[2u * k + 1u] / 1000);
        }
        hd_traj_step(&s, &c);
        hd_gv_put64(&out[6u * k], s.pos);
        out[6u * k + 2u] = s.vel;
        out[6u * k + 3u] = hd_sat32(s.v48);
        out[6u * k + 4u] = hd_sat32(s.a48);
        out[6u * k + 5u] = s.mode | (int32_t)(s.tn << 4);
    }
}

/* ---- excitation: each kind for 96 periods -------------------------------------- */

static void exc_cfg_for(uint32_t kind, int32_t amp, hd_exc_cfg_t *c)
{
    c->kind = (int32_t)kind;
    c->amp = amp;
    c->offset = 17;
    c->length = 0;
    c->hold = 3;
    c->n = (kind == HD_EXC_PRBS) ? 7u : 4u;
    c->m = 2;
    c->rate = amp / 20 + 1;
    c->f0_q16 = 10 << 16;
    c->f1_q16 = 900 << 16;
    c->period = 50;
    c->seed = 0x5Au;
    if (kind == HD_EXC_CHIRP) {
        c->length = 96;
    }
}

static void gen_exc(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    in[0] = hd_gv_rand_range(r, 0, 1 << 24);
}

static void run_exc(const int32_t *in, int32_t *out, uint32_t count)
{
    hd_exc_t s;
    hd_exc_cfg_t c;
    uint32_t k;
    exc_cfg_for(HD_EXC_VSTEPS, in[0], &c);
    (void)hd_exc_start(&s, &c);
    for (k = 0; k < count; k++) {
        if (k % 96u == 0u) {
            exc_cfg_for(1u + (k / 96u) % 6u, in[k], &c);
            out[2u * k + 1u] = hd_exc_start(&s, &c);
        } else {
            out[2u * k + 1u] = (int32_t)s.done;
        }
        out[2u * k] = hd_exc_step(&s, &c);
    }
}

static void cost_exc(void)
{
    hd_exc_t s;
    hd_exc_cfg_t c;
    exc_cfg_for(HD_EXC_MULTISINE, cv_a, &c);
    (void)hd_exc_start(&s, &c);
    hd_gv_cost_mark();
    sink32 = hd_exc_step(&s, &c);
    hd_gv_cost_mark();
}

/* ---- capture ---------------------------------------------------------------------- */

static hd_capture_t cap;

static void gen_cap(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    in[0] = (int32_t)idx * 3 - 600 + hd_gv_rand_range(r, -2, 2);
    in[1] = hd_gv_rand_edge32(r);
}

static void run_cap(const int32_t *in, int32_t *out, uint32_t count)
{
    const hd_capture_cfg_t c = {2u, 2u, 64u, 16u, HD_CAP_TRIG_RISING, 0u, 0};
    uint32_t k;
    hd_capture_reset(&cap);
    (void)hd_capture_arm(&cap, &c);
    for (k = 0; k < count; k++) {
        hd_capture_step(&cap, &in[2u * k]);
        out[2u * k] = (int32_t)cap.state;
        out[2u * k + 1u] = hd_capture_read(&cap, k % 64u, k & 1u);
    }
}

static void cost_cap(void)
{
    const hd_capture_cfg_t c = {4u, 1u, 0u, 100u, HD_CAP_TRIG_COMMAND, 0u, 0};
    int32_t smp[4];
    smp[0] = cv_a;
    smp[1] = cv_b;
    smp[2] = cv_a;
    smp[3] = cv_b;
    hd_capture_reset(&cap);
    (void)hd_capture_arm(&cap, &c);
    hd_gv_cost_mark();
    hd_capture_step(&cap, smp);
    hd_gv_cost_mark();
}

const hd_gv_kernel_t hd_gv_control_kernels[] = {
    {"pid_step", 3u, 2u, GV_N, gen_pid, run_pid, cost_pid},
    {"velobs_step", 2u, 3u, GV_N, gen_obs, run_obs, cost_obs},
    {"biquad_chain_step", 1u, 1u, GV_N, gen_bq, run_bq, cost_bq},
    {"traj_step", 2u, 5u, GV_N, gen_traj, run_traj, cost_traj},
    {"traj_approach", 2u, 5u, 1280u, gen_traj_appr, run_traj_appr, NULL},
    {"traj_slow", 2u, 6u, 1024u, gen_traj_slow, run_traj_slow, NULL},
    {"exc_step", 1u, 2u, 576u, gen_exc, run_exc, cost_exc},
    {"capture_step", 2u, 2u, 256u, gen_cap, run_cap, cost_cap},
};
const uint32_t hd_gv_control_count = sizeof hd_gv_control_kernels / sizeof hd_gv_control_kernels[0];
