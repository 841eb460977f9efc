/*
 * hd_capture.h - capture buffer: chosen signals at loop rate or decimated,
 * pre-trigger, trigger on level / edge / command, upload afterwards.
 *
 * Size: HD_CAPTURE_WORDS int32 words; 8192 (32 KiB) by default (simulator,
 * host tests), i.e. 8192 samples of one channel, 1024 samples of 8 channels
 * (0.1 s at 10 kHz, or longer with decimation).  The STM32G474 image (48 KiB
 * RAM budget shared with the control state, the Preisach table, the CANopen
 * stack and its table staging) builds with a smaller value, see
 * docs/stm32g474.md.
 *
 * The caller chooses WHAT is captured (it passes n_ch int32 values per
 * period); this module only stores them.  Samples are frames of n_ch words
 * in a ring of floor(HD_CAPTURE_WORDS / n_ch) frames.
 *
 * States: IDLE -> arm() -> ARMED (recording pre-trigger history) -> trigger
 * condition -> TRIGGERED (recording post-trigger frames) -> DONE.  The
 * trigger is only accepted once `pretrig` frames have been recorded.  After
 * DONE, hd_capture_read(frame, ch) returns frame 0 = oldest (pretrig frames
 * before the trigger frame, which is frame `pretrig`).
 * Trigger modes: IMMEDIATE (at arm), COMMAND (hd_capture_trigger()),
 * ABOVE / BELOW (channel trig_ch >= / <= level), RISING / FALLING / EDGE
 * (crossing of level between two recorded frames).
 */
#ifndef HD_CAPTURE_H
#define HD_CAPTURE_H

#include <stdint.h>

/* Capture size in int32 words; a port may build with a smaller buffer
 * (-DHD_CAPTURE_WORDS=...; the STM32G474 image uses 4096 = 16 KiB, see
 * docs/stm32g474.md).  Must be >= HD_CAPTURE_MAX_CH. */
#ifndef HD_CAPTURE_WORDS
#define HD_CAPTURE_WORDS 8192u
#endif
#define HD_CAPTURE_MAX_CH 8u

typedef enum {
    HD_CAP_IDLE = 0, HD_CAP_ARMED = 1, HD_CAP_TRIGGERED = 2, HD_CAP_DONE = 3
} hd_cap_state_t;

typedef enum {
    HD_CAP_TRIG_IMMEDIATE = 0, HD_CAP_TRIG_COMMAND = 1, HD_CAP_TRIG_ABOVE = 2,
    HD_CAP_TRIG_BELOW = 3, HD_CAP_TRIG_RISING = 4, HD_CAP_TRIG_FALLING = 5,
    HD_CAP_TRIG_EDGE = 6
} hd_cap_trig_t;

typedef struct {
    uint32_t n_ch;       /* channels per frame, 1..HD_CAPTURE_MAX_CH */
    uint32_t decim;      /* record every decim-th period, >= 1 */
    uint32_t frames;     /* total frames wanted (0 = as many as fit) */
    uint32_t pretrig;    /* frames before the trigger, < frames */
    uint32_t trig_mode;  /* hd_cap_trig_t */
    uint32_t trig_ch;    /* channel tested by level/edge modes */
    int32_t  trig_level; /* level in that channel's format */
} hd_capture_cfg_t;

typedef struct {
    int32_t  buf[HD_CAPTURE_WORDS];
    hd_capture_cfg_t cfg;
    uint32_t state;      /* hd_cap_state_t */
    uint32_t cap_frames; /* ring size in frames for this cfg */
    uint32_t head;       /* next frame slot to write */
    uint32_t filled;     /* frames recorded so far (saturates at cap_frames) */
    uint32_t post;       /* frames recorded since the trigger (incl. trigger frame) */
    uint32_t start;      /* slot of frame 0 once DONE */
    uint32_t decim_cnt;
    uint32_t cmd_trig;   /* pending command trigger */
    int32_t  prev;       /* previous value of trig_ch */
    uint32_t have_prev;
} hd_capture_t;

/** Stop and clear. */
void hd_capture_reset(hd_capture_t *s);
/** Arm with cfg. 0 ok, -1 bad cfg (state unchanged). */
int32_t hd_capture_arm(hd_capture_t *s, const hd_capture_cfg_t *c);
/** Command trigger (COMMAND mode; ignored in other modes). */
void hd_capture_trigger(hd_capture_t *s);
/** One control period with n_ch values. */
void hd_capture_step(hd_capture_t *s, const int32_t *sample);
/** Frames available for upload (0 unless DONE). */
uint32_t hd_capture_frames(const hd_capture_t *s);
/** Value of frame f (0 = oldest), channel ch, after DONE; 0 if out of range. */
int32_t hd_capture_read(const hd_capture_t *s, uint32_t frame, uint32_t ch);

#endif
