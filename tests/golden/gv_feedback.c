/*
 * gv_feedback.c - golden vectors of the feedback-configuration kernels:
 *   compliance_twist  hd_compliance_design + hd_compliance_twist over random
 *                     slopes, breakpoints and torques (edge values included)
 *   fb_track          hd_fb_motor / hd_fb_enter / hd_fb_step in the dual loop
 *                     (N = 100, 20 Hz blend): exact motor / N tracking over
 *                     random motor steps, the blend and the entry bias (an
 *                     entry every 128 vectors)
 */
#include "gv.h"
#include "hd_compliance.h"
#include "hd_feedback.h"

/* in: k1, k2, k3 (Q23.8 N.m/turn), t1, t2 (Q15.16 N.m), t; out: rc, twist */
static void gen_twist(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    const int32_t t1 = hd_gv_rand_range(r, 0, 1 << 23);
    in[0] = hd_gv_rand_range(r, 1 << 21, INT32_MAX);
    in[1] = hd_gv_rand_range(r, 1 << 21, INT32_MAX);
    in[2] = hd_gv_rand_range(r, 1 << 21, INT32_MAX);
    in[3] = t1;
    in[4] = (idx % 17u == 3u) ? t1 - 1 : hd_gv_rand_range(r, t1, INT32_MAX);   /* some refused */
    in[5] = (idx % 5u == 0u) ? hd_gv_rand_edge32(r) : hd_gv_rand_range(r, -(1 << 24), 1 << 24);
}

static void run_twist(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    for (k = 0; k < count; k++) {
        const int32_t *v = &in[6u * k];
        hd_compliance_cfg_t c = {0, 0, 0, 0, 0};
        out[2u * k] = hd_compliance_design(&c, v[0], v[1], v[2], v[3], v[4]);
        out[2u * k + 1u] = hd_compliance_twist(&c, v[5]);
    }
}

static volatile int32_t cost_t = 40 << 16;

static void cost_twist(void)
{
    hd_compliance_cfg_t c;
    (void)hd_compliance_design(&c, 194779 * 256, 314159 * 256, 358142 * 256, 14 << 16, 48 << 16);
    const int32_t t = cost_t;
    hd_gv_cost_mark();
    cost_t = hd_compliance_twist(&c, t);
    hd_gv_cost_mark();
}

/* in: motor step (2^-32 motor turn), output minus motor / N (2^-32 turn), offset;
 * out: mo (2 words), mo_rem, pos_fb (2 words) */
static void gen_track(uint32_t idx, hd_gv_rng_t *r, int32_t *in)
{
    (void)idx;
    const uint32_t sh = hd_gv_rand32(r) & 31u;
    in[0] = (int32_t)(hd_gv_rand32(r) & 0x7FFFFFFFu) >> sh;
    if ((hd_gv_rand32(r) & 1u) != 0u) {
        in[0] = -in[0];
    }
    in[1] = hd_gv_rand_range(r, -(1 << 20), 1 << 20);
    in[2] = hd_gv_rand_range(r, -(1 << 22), 1 << 22);
}

static hd_fb_cfg_t trk_cfg;
static hd_fb_t trk;

static void run_track(const int32_t *in, int32_t *out, uint32_t count)
{
    uint32_t k;
    hd_angle_t pm = -((hd_angle_t)7 << 32) + 99;
    (void)hd_fb_design(&trk_cfg, HD_FB_DUAL_LOOP, 100, 20 << 16);
    hd_fb_reset(&trk, &trk_cfg, pm, 0);
    for (k = 0; k < count; k++) {
        const int32_t *v = &in[3u * k];
        pm += v[0];
        hd_fb_motor(&trk, &trk_cfg, pm);
        const hd_angle_t pos_out = trk.mo + v[1];
        if ((k & 127u) == 0u) {
            (void)hd_fb_enter(&trk, &trk_cfg, pos_out);
        }
        const hd_angle_t fb = hd_fb_step(&trk, &trk_cfg, pos_out, v[2]);
        hd_gv_put64(&out[5u * k], trk.mo);
        out[5u * k + 2u] = trk.mo_rem;
        hd_gv_put64(&out[5u * k + 3u], fb);
    }
}

static volatile int32_t cost_d = 781 << 15;

static void cost_track(void)
{
    hd_angle_t pm = (hd_angle_t)1 << 36;
    (void)hd_fb_design(&trk_cfg, HD_FB_DUAL_LOOP, 100, 2 << 16);
    hd_fb_reset(&trk, &trk_cfg, pm, 0);
    (void)hd_fb_enter(&trk, &trk_cfg, trk.mo);
    pm += cost_d;
    hd_gv_cost_mark();
    hd_fb_motor(&trk, &trk_cfg, pm);
    (void)hd_fb_step(&trk, &trk_cfg, trk.mo + 5000, 1234);
    hd_gv_cost_mark();
}

const hd_gv_kernel_t hd_gv_feedback_kernels[] = {
    {"compliance_twist", 6u, 2u, 512u, gen_twist, run_twist, cost_twist},
    {"fb_track", 3u, 5u, 1024u, gen_track, run_track, cost_track},
};
const uint32_t hd_gv_feedback_count = sizeof hd_gv_feedback_kernels / sizeof hd_gv_feedback_kernels[0];
