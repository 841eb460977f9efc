/*
 * serve.c - `hdservo-sim serve`: the simulated axis (plant + firmware app in
 * lock-step, harness.h) served as a CANopen node (firmware/canopen) over a
 * CAN transport of the host port (socketcand TCP server or SocketCAN).
 *
 *   hdservo-sim serve [--axis AXIS.toml|reference|minimal] [--node-id N]
 *       [--transport socketcand|socketcan] [--port P] [--channel can0]
 *       [--pacing realtime|fast|sync] [--sync-periods K] [--bitrate B]
 *       [--duration S] [--seed N] [-q]
 *
 * One loop iteration = one control period (100 us of simulated time):
 *   frames from the transport -> hd_co_process (commands reach the app API
 *   and take effect at the next step), hd_sim_step (sensors, app, plant),
 *   hd_co_tick (telemetry into the OD, heartbeat, PDOs), frames to the
 *   transport (through the optional bus model).
 * Pacing: realtime = one period per 100 us of wall-clock; fast = as fast as
 * the client reads (the TCP output blocks when its buffer is full, so no
 * frame is lost); sync = K periods per SYNC received (lock-step with the host).
 * Bus model (--bitrate B > 0): every frame costs its bit-stuffed length at B;
 * frames wait in a 64-frame controller queue and are dropped (counted) when
 * it is full.  On exit (SIGINT/SIGTERM or --duration) one JSON line of
 * statistics goes to stderr.  Startup prints "listening on 127.0.0.1:PORT".
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "harness.h"
#include "hd_app.h"
#include "hd_co.h"
#include "can_socketcand.h"
#include "can_socketcan.h"
#include "serve.h"

#define BUSQ 64u
#define TXQ 4096u
#define DOM_N 5u
#define DOM_CAP (HD_CAPTURE_WORDS * 4u + 65536u + 64u)

typedef struct {
    uint8_t *data;
    uint32_t len;
    uint8_t *stage;
    uint32_t stage_len;
} dom_t;

typedef struct {
    hd_sim_t *sim;
    hd_app_t *app;
    hd_co_t co;
    /* transport */
    int use_scan;
    hd_scd_t *scd;
    hd_scan_t scan;
    /* drive -> bus queue */
    hd_can_frame_t txq[TXQ];
    uint32_t txq_head, txq_n;
    uint64_t t_us;
    /* bus model */
    uint32_t bitrate;
    double bus_credit_bits;
    uint64_t bus_bits_total, bus_frames, bus_dropped;
    /* drive state */
    int8_t mode;
    int32_t cap_sig[4];
    uint32_t cap_n;
    dom_t dom[DOM_N];
    uint32_t sync_credit;
    uint32_t sync_periods;
} srv_t;

static volatile sig_atomic_t g_stop = 0;
static void on_signal(int sig) { (void)sig; g_stop = 1; }

/* ---- bus model: exact bit-stuffed length of a classic CAN frame ---------- */

int32_t hd_serve_frame_bits(const hd_can_frame_t *f)
{
    uint8_t bits[160];
    int n = 0;
    bits[n++] = 0;                                   /* SOF */
    if (!f->ext) {
        for (int i = 10; i >= 0; i--) bits[n++] = (uint8_t)((f->id >> i) & 1u);
        bits[n++] = f->rtr ? 1 : 0;                  /* RTR */
        bits[n++] = 0;                               /* IDE */
        bits[n++] = 0;                               /* r0 */
    } else {
        for (int i = 28; i >= 18; i--) bits[n++] = (uint8_t)((f->id >> i) & 1u);
        bits[n++] = 1;                               /* SRR */
        bits[n++] = 1;                               /* IDE */
        for (int i = 17; i >= 0; i--) bits[n++] = (uint8_t)((f->id >> i) & 1u);
        bits[n++] = f->rtr ? 1 : 0;
        bits[n++] = 0;                               /* r1 */
        bits[n++] = 0;                               /* r0 */
    }
    uint8_t dlc = f->dlc > 8 ? 8 : f->dlc;
    for (int i = 3; i >= 0; i--) bits[n++] = (uint8_t)((dlc >> i) & 1u);
    if (!f->rtr)
        for (int b = 0; b < dlc; b++)
            for (int i = 7; i >= 0; i--) bits[n++] = (uint8_t)((f->data[b] >> i) & 1u);
    uint32_t crc = 0;
    for (int i = 0; i < n; i++) {
        uint32_t nxt = bits[i] ^ ((crc >> 14) & 1u);
        crc = (crc << 1) & 0x7FFFu;
        if (nxt) crc ^= 0x4599u;
    }
    for (int i = 14; i >= 0; i--) bits[n++] = (uint8_t)((crc >> i) & 1u);
    int stuffed = 0, run = 1;
    for (int i = 1; i < n; i++) {
        if (bits[i] == bits[i - 1]) {
            run++;
            if (run == 5) { stuffed++; run = 1; /* stuff bit has opposite value */
                if (i + 1 < n && bits[i + 1] != bits[i]) run = 0; }
        } else {
            run = 1;
        }
    }
    return n + stuffed + 1 /* CRC delimiter */ + 2 /* ACK */ + 7 /* EOF */ + 3 /* IFS */;
}

/* ---- adapter: hd_co_app_if_t over hd_app_t ---------------------------------- */

static bool a_send(void *c, const hd_can_frame_t *f)
{
    srv_t *s = c;
    if (s->txq_n >= TXQ) return false;
    s->txq[(s->txq_head + s->txq_n) % TXQ] = *f;
    s->txq_n++;
    return true;
}

static int32_t a_pget(void *c, uint16_t id) { return hd_app_param_get(((srv_t *)c)->app, id); }
static uint32_t a_pset(void *c, uint16_t id, int32_t raw)
{
    return hd_app_param_set(((srv_t *)c)->app, id, raw) == 0 ? 0u : HD_CO_AB_VALUE;
}

/* domain 0: capture data (int32 LE, frame-major); 1..3 tables; 4 test domain */
static uint32_t a_dsize(void *c, uint16_t dom, uint32_t *size)
{
    srv_t *s = c;
    if (dom >= DOM_N) return HD_CO_AB_NO_OBJECT;
    if (dom == 0) {
        const hd_capture_t *cap = &s->app->cap;
        *size = hd_capture_frames(cap) * cap->cfg.n_ch * 4u;
        return 0;
    }
    *size = s->dom[dom].len;
    return 0;
}

static uint32_t a_dread(void *c, uint16_t dom, uint32_t off, uint8_t *buf, uint32_t len)
{
    srv_t *s = c;
    if (dom >= DOM_N) return HD_CO_AB_NO_OBJECT;
    if (dom == 0) {
        const hd_capture_t *cap = &s->app->cap;
        uint32_t nch = cap->cfg.n_ch ? cap->cfg.n_ch : 1u;
        for (uint32_t i = 0; i < len; i++) {
            uint32_t byte = off + i, word = byte / 4u;
            uint32_t v = (uint32_t)hd_capture_read(cap, word / nch, word % nch);
            buf[i] = (uint8_t)(v >> (8u * (byte % 4u)));
        }
        return 0;
    }
    if (off + len > s->dom[dom].len) return HD_CO_AB_GENERAL;
    memcpy(buf, s->dom[dom].data + off, len);
    return 0;
}

static uint32_t a_dbegin(void *c, uint16_t dom, uint32_t size)
{
    srv_t *s = c;
    if (dom == 0 || dom >= DOM_N) return HD_CO_AB_READONLY;
    if (size > DOM_CAP) return HD_CO_AB_LEN_HIGH;
    s->dom[dom].stage_len = 0;
    return 0;
}

static uint32_t a_dwrite(void *c, uint16_t dom, uint32_t off, const uint8_t *buf, uint32_t len)
{
    srv_t *s = c;
    if (dom == 0 || dom >= DOM_N) return HD_CO_AB_READONLY;
    if (off + len > DOM_CAP) return HD_CO_AB_LEN_HIGH;
    memcpy(s->dom[dom].stage + off, buf, len);
    s->dom[dom].stage_len = off + len;
    return 0;
}

/* commit: the last 4 bytes are the CRC-32 of the rest; refused -> old data stays */
static uint32_t a_dend(void *c, uint16_t dom, uint32_t total, bool complete)
{
    srv_t *s = c;
    if (dom == 0 || dom >= DOM_N) return HD_CO_AB_READONLY;
    if (!complete) return 0;
    dom_t *d = &s->dom[dom];
    if (total < 4u || total != d->stage_len) return HD_CO_AB_STORE;
    uint32_t crc = hd_co_crc32(0, d->stage, total - 4u);
    const uint8_t *t = d->stage + total - 4u;
    uint32_t got = (uint32_t)t[0] | ((uint32_t)t[1] << 8) | ((uint32_t)t[2] << 16) | ((uint32_t)t[3] << 24);
    if (crc != got) return HD_CO_AB_STORE;
    memcpy(d->data, d->stage, total);
    d->len = total;
    return 0;
}

static uint32_t a_special_read(void *c, uint16_t index, uint8_t sub, int64_t *v)
{
    srv_t *s = c;
    if (index == 0x5000 && sub == 0) { *v = 7; return 0; }
    if (index == 0x5000 && sub == 1) { *v = 0; return 0; }
    if (index == 0x5000 && sub == 2) { *v = (int64_t)s->app->cap.state; return 0; }
    return HD_CO_AB_NO_OBJECT;
}

static uint32_t a_special_write(void *c, uint16_t index, uint8_t sub, int64_t v)
{
    srv_t *s = c;
    if (index == 0x5000 && sub == 1) {
        if (v == 1) {
            hd_capture_cfg_t cfg;
            memset(&cfg, 0, sizeof cfg);
            uint32_t sig[HD_CAPTURE_MAX_CH];
            uint32_t n = 0, packed = s->co.od.capture_signals;
            for (uint32_t k = 0; k < 4 && k < HD_CAPTURE_MAX_CH; k++) {
                uint32_t id = (packed >> (8 * k)) & 0xFFu;
                if (id == 0xFFu) continue;
                if (id >= HD_SIG_COUNT) return HD_CO_AB_VALUE;
                sig[n++] = id;
            }
            if (n == 0) return HD_CO_AB_VALUE;
            cfg.n_ch = n;
            cfg.decim = s->co.od.capture_decimation;
            cfg.frames = s->co.od.capture_length;
            cfg.pretrig = s->co.od.capture_pretrigger;
            cfg.trig_mode = 0;   /* command trigger */
            return hd_app_capture_arm(s->app, &cfg, sig) == 0 ? 0u : HD_CO_AB_VALUE;
        }
        if (v == 2) {
            hd_app_capture_trigger(s->app);
            return 0;
        }
        return 0;
    }
    return HD_CO_AB_READONLY;
}

static uint32_t a_store(void *c)
{
    return hd_app_param_save(((srv_t *)c)->app) == 0 ? 0u : HD_CO_AB_STATE;
}

static uint32_t a_restore(void *c)
{
    srv_t *s = c;
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) (void)hd_app_param_set(s->app, i, hd_param_table[i].def);
    return 0;
}

static void a_sync(void *c, uint8_t counter)
{
    srv_t *s = c;
    (void)counter;
    s->sync_credit += s->sync_periods;
}

static int32_t app_mode_for(int8_t m)
{
    switch (m) {
    case HD_CO402_MODE_PP: return HD_MODE_PTP;
    case HD_CO402_MODE_CSV: return HD_MODE_VELOCITY;
    case HD_CO402_MODE_CST: return HD_MODE_TORQUE;
    default: return HD_MODE_POSITION;   /* CSP, and "no mode" = hold position */
    }
}

static uint32_t a_enable(void *c, int8_t mode, bool on)
{
    srv_t *s = c;
    if (!on) {
        (void)hd_app_set_mode(s->app, HD_MODE_OFF);
        s->mode = 0;
        return 0;
    }
    /* bumpless: the targets start at the actual values */
    s->co.od.target_position = s->co.od.position_actual_value;
    s->co.od.target_velocity = 0;
    s->co.od.target_torque = 0;
    hd_app_set_position(s->app, s->app->tel.pos_out);
    hd_app_set_velocity(s->app, 0);
    hd_app_set_torque(s->app, 0);
    if (hd_app_set_mode(s->app, app_mode_for(mode)) != 0) return 1;
    s->mode = mode;
    return 0;
}

static void a_setpoint(void *c, const hd_co_setpoint_t *sp)
{
    srv_t *s = c;
    if (sp->quick_stop) {
        if (s->mode != -1) {
            (void)hd_app_set_mode(s->app, HD_MODE_VELOCITY);
            s->mode = -1;
        }
        hd_app_set_velocity(s->app, 0);
        return;
    }
    hd_angle_t pos = (hd_angle_t)sp->target_position * 256;
    switch (sp->mode) {
    case HD_CO402_MODE_PP:
        if (sp->pp_new) (void)hd_app_move_to(s->app, pos);
        break;
    case HD_CO402_MODE_CSV:
        hd_app_set_velocity(s->app, sp->target_velocity);
        hd_app_set_torque(s->app, sp->target_torque);
        break;
    case HD_CO402_MODE_CST:
        hd_app_set_torque(s->app, sp->target_torque);
        break;
    case HD_CO402_MODE_CSP:
        hd_app_set_position(s->app, pos);
        hd_app_set_velocity(s->app, sp->velocity_offset);
        hd_app_set_torque(s->app, sp->target_torque);
        break;
    default:
        break;
    }
}

static uint16_t emcy_for_fault(int32_t f)
{
    switch (f) {
    case HD_FAULT_TORQUE_SAT: return 0x2310;   /* continuous over-current */
    case HD_FAULT_OVERSPEED: return 0x8400;    /* velocity speed controller */
    case HD_FAULT_TRAVEL: return 0x8612;       /* reference limit */
    case HD_FAULT_FOLLOWING: return 0x8611;    /* following error */
    case HD_FAULT_ENC_JUMP: return 0x7305;     /* incremental sensor 1 fault */
    case HD_FAULT_SENSOR: return 0x7300;       /* sensor */
    case HD_FAULT_PARAM: return 0x6320;        /* parameter error */
    default: return 0x1000;
    }
}

static void a_actual(void *c, hd_co_actual_t *a)
{
    srv_t *s = c;
    const hd_telemetry_t *t = hd_app_telemetry(s->app);
    a->tick = t->tick;
    a->load_angle = t->pos_out;
    a->motor_angle = t->pos_mot;
    a->setpoint_angle = t->pos_ref;
    a->load_velocity = t->vel_out;
    a->motor_velocity = t->vel_mot;
    a->output_torque = t->torque_cmd;
    a->motor_torque = t->motor_torque;
    a->motor_current = t->current;
    a->fault_code = (uint16_t)t->fault;
    a->fault_emcy = t->fault ? emcy_for_fault(t->fault) : 0;
    a->power_enabled = t->mode != HD_MODE_OFF;
    int32_t v = t->vel_out < 0 ? -t->vel_out : t->vel_out;
    a->standstill = v < 4295 * 100;            /* 0.1 mturn/s ~ 0.036 deg/s */
    int64_t e = t->pos_ref - t->pos_out;
    if (e < 0) e = -e;
    a->target_reached = e < ((int64_t)1 << 16);
    a->internal_limit = 0;
}

static void a_fault_reset(void *c) { hd_app_fault_reset(((srv_t *)c)->app); }

static void a_comm_fault(void *c, uint16_t code)
{
    srv_t *s = c;
    (void)code;
    /* the app's fault reaction for a lost host: power stage off at once */
    (void)hd_app_set_mode(s->app, HD_MODE_OFF);
}

static void a_reset_node(void *c)
{
    srv_t *s = c;
    (void)hd_app_set_mode(s->app, HD_MODE_OFF);
}

/* ---- transport ------------------------------------------------------------------ */

static void deliver(srv_t *s, const hd_can_frame_t *f)
{
    if (s->use_scan) hd_scan_send(&s->scan, f);
    else hd_scd_send(s->scd, f, s->t_us);
}

/* move drive frames to the transport, through the bus model if on */
static void drain_tx(srv_t *s)
{
    if (s->bitrate == 0) {
        while (s->txq_n) {
            deliver(s, &s->txq[s->txq_head]);
            s->txq_head = (s->txq_head + 1) % TXQ;
            s->txq_n--;
            s->bus_frames++;
        }
        return;
    }
    /* controller queue of BUSQ frames: the rest is dropped */
    while (s->txq_n > BUSQ) {
        s->txq_head = (s->txq_head + 1) % TXQ;
        s->txq_n--;
        s->bus_dropped++;
    }
    while (s->txq_n) {
        int32_t b = hd_serve_frame_bits(&s->txq[s->txq_head]);
        if (s->bus_credit_bits < b) break;
        s->bus_credit_bits -= b;
        s->bus_bits_total += (uint64_t)b;
        deliver(s, &s->txq[s->txq_head]);
        s->txq_head = (s->txq_head + 1) % TXQ;
        s->txq_n--;
        s->bus_frames++;
    }
}

static int receive(srv_t *s, int32_t timeout_ms)
{
    hd_can_frame_t rx[64];
    uint32_t n = 0;
    int32_t r = s->use_scan ? hd_scan_poll(&s->scan, timeout_ms, rx, 64, &n)
                            : hd_scd_poll(s->scd, timeout_ms, rx, 64, &n);
    for (uint32_t i = 0; i < n; i++) {
        if (s->bitrate) {
            int32_t b = hd_serve_frame_bits(&rx[i]);
            s->bus_credit_bits -= b;              /* host frames share the bus */
            s->bus_bits_total += (uint64_t)b;
        }
        hd_co_process(&s->co, &rx[i]);
    }
    return r;
}

static double wall_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int usage_fail(const char *msg)
{
    fprintf(stderr, "hdservo-sim serve: error: %s\n", msg);
    return 2;
}

static int parse_u(const char *s, unsigned long lo, unsigned long hi, unsigned long *out)
{
    char *end;
    errno = 0;
    unsigned long v = strtoul(s, &end, 0);
    if (errno || *end || s[0] == '-' || s[0] == '\0' || v < lo || v > hi) return -1;
    *out = v;
    return 0;
}

static hd_scd_t g_scd_storage;   /* 1 MiB output buffer: static storage, PC-side process only */

int hd_sim_serve_main(int argc, char **argv)
{
    const char *axis = "reference", *transport = "socketcand", *pacing = "realtime", *channel = "can0";
    unsigned long node = 1, port = 0, sync_periods = 10, bitrate = 0, seed = 1;
    double duration = 0.0;
    int quiet = 0;
    char msg[512];
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
#define NEEDV() do { if (!v) { snprintf(msg, sizeof msg, "%s needs a value", a); return usage_fail(msg); } i++; } while (0)
        if (strcmp(a, "--axis") == 0) { NEEDV(); axis = v; }
        else if (strcmp(a, "--node-id") == 0) { NEEDV(); if (parse_u(v, 1, 127, &node)) return usage_fail("--node-id must be 1..127"); }
        else if (strcmp(a, "--transport") == 0) { NEEDV(); transport = v; }
        else if (strcmp(a, "--port") == 0) { NEEDV(); if (parse_u(v, 0, 65535, &port)) return usage_fail("--port must be 0..65535"); }
        else if (strcmp(a, "--channel") == 0) { NEEDV(); channel = v; }
        else if (strcmp(a, "--pacing") == 0) { NEEDV(); pacing = v; }
        else if (strcmp(a, "--sync-periods") == 0) { NEEDV(); if (parse_u(v, 1, 100000, &sync_periods)) return usage_fail("--sync-periods must be 1..100000"); }
        else if (strcmp(a, "--bitrate") == 0) { NEEDV(); if (parse_u(v, 0, 1000000, &bitrate) || (bitrate && bitrate < 10000)) return usage_fail("--bitrate must be 0 (no bus model) or 10000..1000000"); }
        else if (strcmp(a, "--seed") == 0) { NEEDV(); if (parse_u(v, 0, 0xFFFFFFFFul, &seed)) return usage_fail("--seed must be an integer"); }
        else if (strcmp(a, "--duration") == 0) {
            NEEDV();
            char *end;
            duration = strtod(v, &end);
            if (*end || !(duration > 0.0) || duration > 1e7) return usage_fail("--duration must be a positive number of seconds");
        }
        else if (strcmp(a, "-q") == 0 || strcmp(a, "--quiet") == 0) quiet = 1;
        else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            printf("usage: hdservo-sim serve [--axis AXIS.toml|reference|minimal] [--node-id N] "
                   "[--transport socketcand|socketcan] [--port P] [--channel can0] "
                   "[--pacing realtime|fast|sync] [--sync-periods K] [--bitrate B] [--duration S] [--seed N] [-q]\n");
            return 0;
        } else {
            snprintf(msg, sizeof msg, "unknown option '%.100s'", a);
            return usage_fail(msg);
        }
#undef NEEDV
    }
    int pace;
    if (strcmp(pacing, "realtime") == 0) pace = 0;
    else if (strcmp(pacing, "fast") == 0) pace = 1;
    else if (strcmp(pacing, "sync") == 0) pace = 2;
    else return usage_fail("--pacing must be realtime, fast or sync");
    if (strcmp(transport, "socketcand") != 0 && strcmp(transport, "socketcan") != 0)
        return usage_fail("--transport must be socketcand or socketcan");

    /* the axis: a scenario with the controller off (references come from CAN) */
    hd_scenario_t *sc = calloc(1, sizeof *sc);
    srv_t *s = calloc(1, sizeof *s);
    if (!sc || !s) return usage_fail("out of memory");
    char text[2048];
    snprintf(text, sizeof text,
             "[scenario]\nname = \"serve\"\naxis = \"%s\"\nduration_s = 3600\nseed = %lu\n"
             "[controller]\nmode = \"off\"\n", axis, seed);
    if (hd_scenario_parse(text, strlen(text), "serve", sc, msg, sizeof msg) != 0) {
        fprintf(stderr, "hdservo-sim serve: error: --axis %s: %s\n", axis, msg);
        return 1;
    }
    hd_plant_params prm;
    if (hd_sim_scenario_params(sc, &prm, msg, sizeof msg) != 0) {
        fprintf(stderr, "hdservo-sim serve: error: %s\n", msg);
        return 1;
    }
    s->sim = hd_sim_new(sc, &prm, msg, sizeof msg);
    if (!s->sim) {
        fprintf(stderr, "hdservo-sim serve: error: %s\n", msg);
        return 1;
    }
    /* the harness owns the app; the CANopen layer drives it through its command API */
    s->app = (hd_app_t *)(uintptr_t)hd_sim_app(s->sim);
    for (uint32_t d = 1; d < DOM_N; d++) {
        s->dom[d].data = calloc(1, DOM_CAP);
        s->dom[d].stage = calloc(1, DOM_CAP);
        if (!s->dom[d].data || !s->dom[d].stage) return usage_fail("out of memory");
    }
    s->bitrate = (uint32_t)bitrate;
    s->sync_periods = (uint32_t)sync_periods;

    if (strcmp(transport, "socketcan") == 0) {
        if (hd_scan_open(&s->scan, channel, (uint32_t)bitrate, 100u, msg, sizeof msg) != 0) {
            fprintf(stderr, "hdservo-sim serve: error: %s\n", msg);
            return 1;
        }
        s->use_scan = 1;
        if (!quiet) printf("serving node %lu on SocketCAN %s (state %s)\n", node, channel, hd_scan_state(&s->scan));
    } else {
        s->scd = &g_scd_storage;
        if (hd_scd_open(s->scd, (uint16_t)port, msg, sizeof msg) != 0) {
            fprintf(stderr, "hdservo-sim serve: error: %s\n", msg);
            return 1;
        }
        printf("listening on 127.0.0.1:%u\n", (unsigned)s->scd->port);
    }
    fflush(stdout);

    hd_co_app_if_t ifc;
    memset(&ifc, 0, sizeof ifc);
    ifc.ctx = s;
    ifc.send = a_send;
    ifc.param_get = a_pget;
    ifc.param_set = a_pset;
    ifc.domain_size = a_dsize;
    ifc.domain_read = a_dread;
    ifc.domain_write_begin = a_dbegin;
    ifc.domain_write = a_dwrite;
    ifc.domain_write_end = a_dend;
    ifc.special_read = a_special_read;
    ifc.special_write = a_special_write;
    ifc.store = a_store;
    ifc.restore = a_restore;
    ifc.reset_node = a_reset_node;
    ifc.on_sync = a_sync;
    ifc.drive_enable = a_enable;
    ifc.drive_setpoint = a_setpoint;
    ifc.drive_actual = a_actual;
    ifc.drive_fault_reset = a_fault_reset;
    ifc.drive_comm_fault = a_comm_fault;
    hd_co_init(&s->co, (uint8_t)node, &ifc);

    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    signal(SIGPIPE, SIG_IGN);

    const double dt = 1.0 / HD_LOOP_HZ;
    const int64_t n_end = duration > 0.0 ? (int64_t)llround(duration / dt) : INT64_MAX;
    double t0 = wall_s();
    int64_t k = 0;
    int had_client = 0;
    while (!g_stop && k < n_end) {
        /* wait for a client before time starts (the boot-up message must reach it) */
        if (!s->use_scan && !hd_scd_streaming(s->scd)) {
            receive(s, had_client ? 5 : 50);
            if (!hd_scd_streaming(s->scd)) continue;
            had_client = 1;
            t0 = wall_s() - (double)k * dt;   /* realtime pacing starts (again) with the client */
            drain_tx(s);
            hd_scd_flush(s->scd, true, 0);
        }
        if (pace == 2) {
            while (!g_stop && s->sync_credit == 0) {
                receive(s, 20);
                drain_tx(s);
                if (!s->use_scan) hd_scd_flush(s->scd, true, 0);
            }
            if (g_stop) break;
            s->sync_credit--;
        } else {
            receive(s, 0);
        }
        hd_sim_step(s->sim, NULL);
        hd_co_tick(&s->co, HD_CO_TICK_US);
        k++;
        s->t_us = (uint64_t)k * 100u;
        if (s->bitrate) {
            s->bus_credit_bits += (double)s->bitrate * dt;
            if (s->bus_credit_bits > 2.0 * s->bitrate * dt + 200.0) s->bus_credit_bits = 2.0 * s->bitrate * dt + 200.0;
        }
        drain_tx(s);
        if (!s->use_scan) hd_scd_flush(s->scd, pace == 1, pace == 1 ? 65536u : HD_SCD_OUT_CAP);
        if (pace == 0) {
            double due = t0 + (double)k * dt;
            double now = wall_s();
            if (due - now > 0.0005) {
                int32_t ms = (int32_t)((due - now) * 1000.0);
                receive(s, ms);     /* sleep while listening */
            }
        }
    }
    if (!s->use_scan) hd_scd_flush(s->scd, true, 0);
    double wall = wall_s() - t0;
    fprintf(stderr,
            "{\"periods\": %lld, \"sim_s\": %.4f, \"wall_s\": %.4f, \"frames_to_bus\": %llu, "
            "\"bus_dropped\": %llu, \"bus_load\": %.4f, \"stack_tx_dropped\": %u, \"rx_frames\": %u, "
            "\"rx_ignored\": %u, \"transport_dropped\": %u}\n",
            (long long)k, (double)k * dt, wall, (unsigned long long)s->bus_frames,
            (unsigned long long)s->bus_dropped,
            s->bitrate && k ? (double)s->bus_bits_total / ((double)s->bitrate * (double)k * dt) : 0.0,
            s->co.stats.tx_dropped, s->co.stats.rx_frames, s->co.stats.rx_ignored,
            s->use_scan ? s->scan.tx_dropped : s->scd->tx_dropped);
    if (s->use_scan) hd_scan_close(&s->scan);
    else hd_scd_close(s->scd);
    hd_sim_free(s->sim);
    for (uint32_t d = 1; d < DOM_N; d++) {
        free(s->dom[d].data);
        free(s->dom[d].stage);
    }
    free(s);
    free(sc);
    return 0;
}
