/*
 * hd_pid.c - PID loop (formats: see hd_pid.h).
 */
#include "hd_pid.h"
#include "hd_fixed.h"

void hd_pid_reset(hd_pid_t *s)
{
    s->integ = 0;
    s->dfilt = 0;
    s->meas_prev = 0;
    s->p = 0;
    s->i = 0;
    s->d = 0;
    s->out = 0;
    s->saturated = 0;
    s->primed = 0;
}

void hd_pid_preload(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t out_i)
{
    int32_t v = hdf_clamp32(out_i, c->out_min, c->out_max);
    s->integ = hdf_shl64_sat((int64_t)v, c->shift);
    s->i = v;
}

int32_t hd_pid_step(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff)
{
    switch (c->shift) {
    case 16u:
        return hd_pid_step_q(s, c, ref, meas, ff, 16u);
    case 32u:
        return hd_pid_step_q(s, c, ref, meas, ff, 32u);
    default:
        return hd_pid_step_q(s, c, ref, meas, ff, c->shift);
    }
}
