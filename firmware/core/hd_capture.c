/*
 * hd_capture.c - ring-buffer capture with pre-trigger (see hd_capture.h).
 */
#include "hd_capture.h"

void hd_capture_reset(hd_capture_t *s)
{
    s->state = HD_CAP_IDLE;
    s->cap_frames = 0;
    s->head = 0;
    s->filled = 0;
    s->post = 0;
    s->start = 0;
    s->decim_cnt = 0;
    s->cmd_trig = 0;
    s->prev = 0;
    s->have_prev = 0;
    s->cfg.n_ch = 0;
}

int32_t hd_capture_arm(hd_capture_t *s, const hd_capture_cfg_t *c)
{
    if (c->n_ch == 0u || c->n_ch > HD_CAPTURE_MAX_CH || c->decim == 0u ||
        c->trig_mode > (uint32_t)HD_CAP_TRIG_EDGE || c->trig_ch >= c->n_ch) {
        return -1;
    }
    const uint32_t ring = HD_CAPTURE_WORDS / c->n_ch;
    const uint32_t frames = (c->frames == 0u) ? ring : c->frames;
    if (frames > ring || c->pretrig >= frames) {
        return -1;
    }
    hd_capture_reset(s);
    s->cfg = *c;
    s->cfg.frames = frames;
    s->cap_frames = ring;
    s->state = HD_CAP_ARMED;
    return 0;
}

void hd_capture_trigger(hd_capture_t *s)
{
    s->cmd_trig = 1;
}

static uint32_t triggered(hd_capture_t *s, int32_t v)
{
    const hd_capture_cfg_t *c = &s->cfg;
    const int32_t l = c->trig_level;
    const uint32_t hp = s->have_prev;
    const int32_t p = s->prev;
    switch (c->trig_mode) {
    case HD_CAP_TRIG_IMMEDIATE: return 1;
    case HD_CAP_TRIG_COMMAND: return s->cmd_trig;
    case HD_CAP_TRIG_ABOVE: return v >= l;
    case HD_CAP_TRIG_BELOW: return v <= l;
    case HD_CAP_TRIG_RISING: return hp && p < l && v >= l;
    case HD_CAP_TRIG_FALLING: return hp && p > l && v <= l;
    case HD_CAP_TRIG_EDGE: return hp && ((p < l && v >= l) || (p > l && v <= l));
    default: return 0;
    }
}

void hd_capture_step(hd_capture_t *s, const int32_t *sample)
{
    if (s->state != HD_CAP_ARMED && s->state != HD_CAP_TRIGGERED) {
        return;
    }
    if (s->decim_cnt != 0u) {
        s->decim_cnt = (s->decim_cnt + 1u >= s->cfg.decim) ? 0u : s->decim_cnt + 1u;
        return;
    }
    s->decim_cnt = (s->cfg.decim > 1u) ? 1u : 0u;

    const uint32_t n = s->cfg.n_ch;
    uint32_t ch;
    for (ch = 0; ch < n; ch++) {
        s->buf[s->head * n + ch] = sample[ch];
    }
    const uint32_t slot = s->head;
    s->head = (s->head + 1u >= s->cap_frames) ? 0u : s->head + 1u;
    if (s->filled < s->cap_frames) {
        s->filled++;
    }
    const int32_t v = sample[s->cfg.trig_ch];
    if (s->state == HD_CAP_ARMED) {
        if (s->filled > s->cfg.pretrig && triggered(s, v)) {
            s->state = HD_CAP_TRIGGERED;
            s->post = 0;
            /* frame 0 = pretrig frames before the trigger frame */
            s->start = (slot + s->cap_frames - s->cfg.pretrig) % s->cap_frames;
        }
    }
    s->prev = v;
    s->have_prev = 1;
    if (s->state == HD_CAP_TRIGGERED) {
        s->post++;
        if (s->post >= s->cfg.frames - s->cfg.pretrig) {
            s->state = HD_CAP_DONE;
        }
    }
}

uint32_t hd_capture_frames(const hd_capture_t *s)
{
    return (s->state == HD_CAP_DONE) ? s->cfg.frames : 0u;
}

int32_t hd_capture_read(const hd_capture_t *s, uint32_t frame, uint32_t ch)
{
    if (s->state != HD_CAP_DONE || frame >= s->cfg.frames || ch >= s->cfg.n_ch) {
        return 0;
    }
    const uint32_t slot = (s->start + frame) % s->cap_frames;
    return s->buf[slot * s->cfg.n_ch + ch];
}
