/*
 * serve.c - `hdservo-sim serve`: the simulated axis (plant + firmware app in
 * lock-step, harness.h) served as a CANopen node (firmware/canopen) over a
 * CAN transport of the host port (socketcand TCP server or SocketCAN).
 *
 *   hdservo-sim serve [--axis AXIS.toml|reference|minimal] [--node-id N]
 *       [--transport socketcand|socketcan] [--port P] [--channel can0]
 *       [--pacing realtime|fast|sync] [--sync-periods K] [--bitrate B]
 *       [--duration S] [--seed N] [--set KEY=VALUE]... [--rig] [--profile hdservo|generic] [-q]
 *
 * --profile generic: the same drive and plant seen as a generic CiA 402 servo drive.  A
 * master reaches only the CiA 301 / 402 standard objects (0x1000-0x1FFF, 0x6000-0x9FFF);
 * every SDO access to, or PDO mapping of, a manufacturer object (0x2000-0x5FFF: drive
 * parameters, capture, excitation, tables, process data) is refused as absent (abort
 * 0x06020000, a mapping 0x06040041), written as one stderr line "vendor-object access
 * 0xIIII:S refused" (the first 100) and counted ("vendor_refused" in the exit statistics),
 * so a test proves a host never relied on one.  It identifies as another product
 * (0x1018:2 = 0x0047454E, "GEN").  The default TPDOs carry standard objects
 * only (generic_pdos below).  --rig works with either profile: the test rig is the simulated
 * bench around the drive (brake, load), not an object of the drive.  The filter
 * is the port's (hd_app_co_port_t.object_filter): the flashed firmware has none.
 *
 * Test-rig features (not drive features; used by `hdservo test`, see
 * docs/procedures.md): --set KEY=VALUE overrides a plant key of the axis at
 * start-up (e.g. base.enabled=false, gravity.enabled=false); --rig reads rig
 * commands from stdin, one per line, and answers each with one line
 * "ok tick=N ..." (or "error ...") on stdout:
 *   brake 0|1                  output lock (plant brake)
 *   torque T_Nm [RATE_Nm_s]    external torque on the output, ramped at RATE (0 = step);
 *                              clears the queue below
 *   then T_Nm RATE_Nm_s        queue a ramp that starts when the applied torque has reached
 *                              the current target (up to 64): a whole torque profile runs in
 *                              DRIVE time, whatever the host's latency (fast pacing)
 *   record PATH DECIM | record stop
 *                              reference instruments (true gear torque, twist,
 *                              true/inertial angles) as CSV every DECIM periods
 *   status                     tick, applied torque, brake
 *   can drop P [SEED]          CAN fault injection: lose each frame (both directions)
 *                              with probability P in [0, 1] (xorshift64 from SEED)
 *   can errors TX RX           error burst: TX transmit errors (TEC + 8 each) and
 *                              RX receive errors (REC + 1 each) in the drive's controller
 *   can busoff                 force the controller bus-off (TEC 256)
 *   can status                 controller state, TEC, REC, bus-off and recovery counts,
 *                              frames lost by injection and while bus-off
 * The same injection from the start: --can-drop P [--can-seed N].  The drive's CAN
 * controller is the host port's model (hal_host.h hd_host_can_ctrl_t): bus-off means no
 * frame in or out until the stack's recovery request (hd_co_errors.c, every 100 ms) and
 * 128 x 11 bit times at --bitrate (1 Mbit/s without a bus model) have passed.
 * --nvm PATH backs the drive's NVM with a file (flash semantics, hal_host.h): a drive
 * restarted on the same file boots with the parameters saved there (0x1010), like a
 * drive after a power cycle; a blank file keeps the axis commissioning of the harness.
 *
 * The CANopen <-> app adapter is the firmware's (firmware/canopen/hd_app_co.c, the
 * same on the STM32); this file supplies the transport, SYNC pacing and the
 * 64 KiB conformance-test domain.
 * One loop iteration = one control period (100 us of simulated time):
 *   frames from the transport -> hd_co_process (commands reach the app API
 *   and take effect at the next step), hd_sim_step (sensors, app, plant),
 *   hd_co_tick (telemetry into the OD, heartbeat, PDOs), frames to the
 *   transport (through the optional bus model).
 * Pacing: realtime = one period per 100 us of wall-clock; fast = as fast as
 * the client reads (the TCP output blocks when its buffer is full, so no
 * frame is lost; a client whose socket accepts nothing for --client-timeout S,
 * default 5 s, is dropped, and SIGINT/SIGTERM end the wait at once).  In fast
 * pacing the drive runs ahead of its client by at most FAST_KEEP bytes of its
 * own output buffer and the socket's FAST_SNDBUF (the kernel doubles it): about
 * 500 frames, as a CAN interface's bounded receive FIFO, so a master streaming
 * TPDOs every period gets its SDO answers behind at most those frames, not behind
 * the megabytes an autotuned socket buffer holds; sync = K periods per SYNC received (lock-step with the host); frames
 * and rig commands are then read only between SYNC credits, so a run repeats exactly.
 * Bus model (--bitrate B > 0): every frame costs its bit-stuffed length at B;
 * frames wait in a 64-frame controller queue and are dropped (counted) when
 * it is full.  On exit (SIGINT/SIGTERM or --duration) one JSON line of
 * statistics goes to stderr.  Startup prints "listening on 127.0.0.1:PORT".
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <poll.h>
#include <unistd.h>

#include "harness.h"
#include "hd_app.h"
#include "hd_co.h"
#include "hd_app_co.h"
#include "can_socketcand.h"
#include "can_socketcan.h"
#include "hal_host.h"
#include "hd_param_store.h"
#include "rig.h"
#include "serve.h"

#define BUSQ 64u
#define TXQ 4096u
/* fast pacing: output the drive may hold for a client that reads slower than it runs (bytes;
 * a frame is about 40), and the send buffer of the client's socket (SO_SNDBUF; Linux doubles it) */
#define FAST_KEEP 4096u
#define FAST_SNDBUF 8192u
#define DOM_TEST 4u          /* 0x5F20:11, the 64 KiB conformance-test domain */
#define DOM_CAP (65536u + 64u)

typedef struct {
    uint8_t *data;
    uint32_t len;
    uint8_t *stage;
    uint32_t stage_len;
} dom_t;

#define RIG_QUEUE 64   /* queued rig torque ramps */

typedef struct {
    hd_sim_t *sim;
    hd_app_t *app;
    hd_co_t co;
    hd_app_co_t ac;      /* CANopen <-> app adapter (firmware/canopen/hd_app_co.h) */
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
    dom_t test;
    uint32_t sync_credit;
    uint32_t sync_periods;
    /* test rig (--rig): output lock, external output torque, reference instruments */
    int rig;
    hd_rig_lines_t rig_in;   /* stdin line assembly (rig.c) */
    double rig_torque, rig_torque_target, rig_torque_rate;
    double rig_q_target[RIG_QUEUE], rig_q_rate[RIG_QUEUE];   /* queued ramps ("then") */
    int rig_q_head, rig_q_n;
    FILE *rig_rec;
    uint32_t rig_rec_decim;
    int64_t rig_k;
    /* CAN fault injection (rig "can ...", --can-drop/--can-seed) */
    hd_host_port_t *port;
    double can_drop;
    uint64_t can_rng;
    uint64_t can_lost_rx, can_lost_tx, can_busoff_rx, can_busoff_tx;
    /* --profile generic: manufacturer objects refused; counted once a master can ask */
    int generic;
    int vendor_armed;
    uint64_t vendor_refused;
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

/* ---- port side of the adapter (firmware/canopen/hd_app_co.h) ------------------------ */

static bool a_send(void *c, const hd_can_frame_t *f)
{
    srv_t *s = c;
    if (s->txq_n >= TXQ) return false;
    s->txq[(s->txq_head + s->txq_n) % TXQ] = *f;
    s->txq_n++;
    return true;
}

static void a_sync(void *c, uint8_t counter)
{
    srv_t *s = c;
    (void)counter;
    s->sync_credit += s->sync_periods;
}

/* the virtual drive's own domain: 4 = 64 KiB test domain (payload + CRC-32 trailer) */
static uint32_t a_dsize(void *c, uint16_t dom, uint32_t *size)
{
    srv_t *s = c;
    if (dom != DOM_TEST) return HD_CO_AB_NO_OBJECT;
    *size = s->test.len;
    return 0;
}

static uint32_t a_dread(void *c, uint16_t dom, uint32_t off, uint8_t *buf, uint32_t len)
{
    srv_t *s = c;
    if (dom != DOM_TEST) return HD_CO_AB_NO_OBJECT;
    if (off + len > s->test.len) return HD_CO_AB_GENERAL;
    memcpy(buf, s->test.data + off, len);
    return 0;
}

static uint32_t a_dbegin(void *c, uint16_t dom, uint32_t size)
{
    srv_t *s = c;
    if (dom != DOM_TEST) return HD_CO_AB_NO_OBJECT;
    if (size > DOM_CAP) return HD_CO_AB_LEN_HIGH;
    s->test.stage_len = 0;
    return 0;
}

static uint32_t a_dwrite(void *c, uint16_t dom, uint32_t off, const uint8_t *buf, uint32_t len)
{
    srv_t *s = c;
    if (dom != DOM_TEST) return HD_CO_AB_NO_OBJECT;
    if (off + len > DOM_CAP) return HD_CO_AB_LEN_HIGH;
    memcpy(s->test.stage + off, buf, len);
    s->test.stage_len = off + len;
    return 0;
}

/* flash wear of the NVM (0x5102): the host port counts every page erase */
static int32_t a_nvm_wear(void *c, uint32_t *total, uint32_t *max_page)
{
    srv_t *s = c;
    hd_host_nvm_wear(s->port, total, max_page);
    return 0;
}

#define VENDOR_LOG_LINES 100u
/* 0x1018:2 of the generic profile, "GEN": another product than the hdservo firmware
 * (0x00484453, "HDS"), so a host that keys its vendor extensions on the identity (as
 * hdservo.drive_caps does) treats this drive as a third-party one and never probes them */
#define GENERIC_PRODUCT_CODE 0x0047454Eu   /* stderr lines of refused vendor accesses (the count goes on) */

/* --profile generic: only the CiA 301 / 402 standard ranges exist for a master */
static uint32_t a_object_filter(void *c, uint16_t index, uint8_t sub)
{
    srv_t *s = c;
    if (index < 0x2000u || index > 0x5FFFu) return 0;
    if (s->vendor_armed) {
        s->vendor_refused++;
        if (s->vendor_refused <= VENDOR_LOG_LINES)
            fprintf(stderr, "hdservo-sim serve: vendor-object access 0x%04X:%u refused (--profile generic)\n",
                    (unsigned)index, (unsigned)sub);
    }
    return HD_CO_AB_NO_OBJECT;
}

/* The generic profile's default PDOs (a CiA 402 drive's usual set): TPDO1 statusword,
 * mode display, error register (event, 100 ms); TPDO2 position and velocity actual
 * (every SYNC); TPDO3 additional position actual (the motor encoder, 0x60E4:1) and torque
 * actual (every SYNC); TPDO4 invalid.  The RPDO defaults are standard already.  Set
 * through the SDO write checks and kept as the stored image, so the NMT resets return to
 * them (and after a 0x1011 restore, generic_after_frame); 0 or the abort code of the
 * write that failed. */
static void generic_identity(srv_t *s)
{
    /* the NMT resets load the defaults of 0x1000-0x1FFF: put the product code back after
     * each frame the stack processed, before any SDO can read it */
    if (s->generic) s->co.od.identity_object_product_code = GENERIC_PRODUCT_CODE;
}

static uint32_t generic_pdos(srv_t *s, uint8_t node)
{
    static const uint32_t map[4][3] = {
        {0x60410010u, 0x60610008u, 0x10010008u},
        {0x60640020u, 0x606C0020u, 0u},
        {0x60E40120u, 0x60770010u, 0u},
        {0u, 0u, 0u},
    };
    static const uint8_t trans[4] = {255u, 1u, 1u, 255u};
    hd_co_t *co = &s->co;
    for (uint16_t i = 0; i < 4u; i++) {
        const uint32_t cob = (0x180u + 0x100u * i + node);
        uint32_t ab = hd_co_set_i64(co, (uint16_t)(0x1800u + i), 1u, (int64_t)(0x80000000u | cob));
        if (!ab) ab = hd_co_set_i64(co, (uint16_t)(0x1A00u + i), 0u, 0);
        uint8_t n = 0;
        for (uint8_t k = 0; k < 3u && map[i][k]; k++) n++;
        /* every entry, the unused ones 0: the stored image holds all of them, and an NMT
         * reset puts it back through the mapping checks (a default 0x5F00 entry would fail) */
        for (uint8_t k = 0; !ab && k < HD_CO_N_MAP; k++)
            ab = hd_co_set_i64(co, (uint16_t)(0x1A00u + i), (uint8_t)(k + 1u), k < 3u ? (int64_t)map[i][k] : 0);
        if (!ab) ab = hd_co_set_i64(co, (uint16_t)(0x1A00u + i), 0u, n);
        if (!ab) ab = hd_co_set_i64(co, (uint16_t)(0x1800u + i), 2u, trans[i]);
        if (!ab && n) ab = hd_co_set_i64(co, (uint16_t)(0x1800u + i), 1u, cob);
        if (ab) return ab;
    }
    hd_co_store_capture(co);
    return 0;
}

/* After each frame the stack processed: the generic identity (NMT resets), and the generic
 * default PDOs when the firmware's defaults came back (0x1011 restore puts them in force,
 * whose TPDOs map 0x5F00): the generic profile's defaults are its own. */
static void generic_after_frame(srv_t *s)
{
    if (!s->generic) return;
    generic_identity(s);
    for (uint32_t i = 0; i < HD_CO_N_PDO; i++)
        for (uint32_t k = 0; k < HD_CO_N_MAP; k++) {
            const uint16_t t = (uint16_t)(s->co.od.tpdo_map[i][k] >> 16), r = (uint16_t)(s->co.od.rpdo_map[i][k] >> 16);
            if ((t >= 0x2000u && t <= 0x5FFFu) || (r >= 0x2000u && r <= 0x5FFFu)) {
                (void)generic_pdos(s, s->co.node_id);
                return;
            }
        }
}

/* commit: the last 4 bytes are the CRC-32 of the rest; refused -> old data stays */
static uint32_t a_dend(void *c, uint16_t dom, uint32_t total, bool complete)
{
    srv_t *s = c;
    if (dom != DOM_TEST) return HD_CO_AB_NO_OBJECT;
    if (!complete) return 0;
    dom_t *d = &s->test;
    if (total < 4u || total != d->stage_len) return HD_CO_AB_STORE;
    uint32_t crc = hd_crc32(0, d->stage, total - 4u);
    const uint8_t *t = d->stage + total - 4u;
    uint32_t got = (uint32_t)t[0] | ((uint32_t)t[1] << 8) | ((uint32_t)t[2] << 16) | ((uint32_t)t[3] << 24);
    if (crc != got) return HD_CO_AB_STORE;
    memcpy(d->data, d->stage, total);
    d->len = total;
    return 0;
}

/* ---- CAN fault injection ---------------------------------------------------------- */

static void can_seed(srv_t *s, uint64_t seed)
{
    s->can_rng = seed * 0x9E3779B97F4A7C15ull + 0x2545F4914F6CDD1Dull;
    if (s->can_rng == 0) s->can_rng = 1;
}

/* true: this frame is lost (probability can_drop) */
static int can_lost(srv_t *s)
{
    if (s->can_drop <= 0.0) return 0;
    uint64_t x = s->can_rng;
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    s->can_rng = x;
    return (double)(x >> 11) * (1.0 / 9007199254740992.0) < s->can_drop;
}

/* ---- transport ------------------------------------------------------------------ */

static void deliver(srv_t *s, const hd_can_frame_t *f)
{
    if (!hd_host_can_tx_done(s->port)) { s->can_busoff_tx++; return; }   /* controller off the bus */
    if (can_lost(s)) { s->can_lost_tx++; return; }
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
        if (!hd_host_can_rx_done(s->port)) { s->can_busoff_rx++; continue; }
        if (can_lost(s)) { s->can_lost_rx++; continue; }
        hd_co_process(&s->co, &rx[i]);
        generic_after_frame(s);
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

/* s as a TOML basic string body (no quotes) in out: a path may hold quotes and
 * backslashes (C:\\axes\\x.toml), which the scenario text must carry unchanged.
 * Returns -1 when it does not fit or holds a control character the reader refuses. */
static int toml_escape(const char *s, char *out, size_t cap)
{
    size_t n = 0;
    for (; *s; s++) {
        const unsigned char c = (unsigned char)*s;
        char e = 0;
        if (c == '\\' || c == '"') e = (char)c;
        else if (c == '\n') e = 'n';
        else if (c == '\t') e = 't';
        else if (c == '\r') e = 'r';
        else if (c < 0x20u || c == 0x7fu) return -1;
        if (n + (e ? 2u : 1u) >= cap) return -1;
        if (e) { out[n++] = '\\'; out[n++] = e; }
        else out[n++] = (char)c;
    }
    out[n] = '\0';
    return 0;
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

/* ---- test rig (--rig): commands on stdin, one answer line each on stdout ----------- */

static hd_plant *rig_plant(srv_t *s)
{
    /* the harness owns the plant; the rig is the bench around it (PC-side only) */
    return (hd_plant *)(uintptr_t)hd_sim_plant(s->sim);
}

static uint32_t rig_tick(const srv_t *s)
{
    return hd_app_telemetry(s->app)->tick;
}

static void rig_answer(const srv_t *s, const char *fmt_extra)
{
    printf("ok tick=%lu%s%s\n", (unsigned long)rig_tick(s), fmt_extra[0] ? " " : "", fmt_extra);
    fflush(stdout);
}

static void rig_error(const char *what)
{
    printf("error %s\n", what);
    fflush(stdout);
}

static void rig_command_can_status(srv_t *s)
{
    static const char *const names[] = {"active", "passive", "bus-off"};
    const hd_host_can_ctrl_t *c = &s->port->can_ctrl;
    char extra[256];
    snprintf(extra, sizeof extra,
             "can=%s tec=%u rec=%u bus_off=%lu recoveries=%lu lost_rx=%llu lost_tx=%llu busoff_rx=%llu busoff_tx=%llu",
             names[c->state <= 2u ? c->state : 0u], (unsigned)c->tec, (unsigned)c->rec,
             (unsigned long)c->bus_off_count, (unsigned long)c->recoveries,
             (unsigned long long)s->can_lost_rx, (unsigned long long)s->can_lost_tx,
             (unsigned long long)s->can_busoff_rx, (unsigned long long)s->can_busoff_tx);
    rig_answer(s, extra);
}

/* Execute one parsed rig command (rig.c parses) and answer it with one line. */
static void rig_command(srv_t *s, char *line)
{
    hd_rig_cmd_t c;
    char extra[160];
    hd_rig_parse(line, &c);
    switch (c.kind) {
    case HD_RIG_NONE:
        return;
    case HD_RIG_ERROR:
        rig_error(c.error);
        return;
    case HD_RIG_BRAKE:
        hd_plant_set_brake(rig_plant(s), c.on);
        snprintf(extra, sizeof extra, "brake=%c", c.on ? '1' : '0');
        rig_answer(s, extra);
        return;
    case HD_RIG_TORQUE:
        s->rig_torque_target = c.torque_Nm;
        s->rig_torque_rate = c.rate_Nm_s;
        s->rig_q_n = 0;
        if (c.rate_Nm_s == 0.0) s->rig_torque = c.torque_Nm;
        hd_plant_fault_load_step(rig_plant(s), s->rig_torque);
        snprintf(extra, sizeof extra, "torque=%.9g target=%.9g", s->rig_torque, c.torque_Nm);
        rig_answer(s, extra);
        return;
    case HD_RIG_THEN: {
        if (s->rig_q_n >= RIG_QUEUE) { rig_error("then: queue full (64 ramps)"); return; }
        int q = (s->rig_q_head + s->rig_q_n) % RIG_QUEUE;
        s->rig_q_target[q] = c.torque_Nm;
        s->rig_q_rate[q] = c.rate_Nm_s;
        s->rig_q_n++;
        snprintf(extra, sizeof extra, "queued=%d", s->rig_q_n);
        rig_answer(s, extra);
        return;
    }
    case HD_RIG_RECORD_STOP:
        if (s->rig_rec) fclose(s->rig_rec);
        s->rig_rec = NULL;
        rig_answer(s, "record=stop");
        return;
    case HD_RIG_RECORD:
        if (s->rig_rec) fclose(s->rig_rec);
        s->rig_rec = fopen(c.path, "w");
        if (!s->rig_rec) { rig_error("record: cannot open the file for writing"); return; }
        fputs("tick,t_s,gear_torque_Nm,applied_torque_Nm,torsion_rad,load_angle_true_rad,"
              "inertial_angle_rad,motor_angle_true_rad,te_rad\n", s->rig_rec);
        s->rig_rec_decim = c.decimation;
        s->rig_k = 0;
        rig_answer(s, "record=start");
        return;
    case HD_RIG_CAN_DROP:
        s->can_drop = c.probability;
        if (c.has_seed) can_seed(s, (uint64_t)c.seed);
        snprintf(extra, sizeof extra, "can_drop=%.9g", c.probability);
        rig_answer(s, extra);
        return;
    case HD_RIG_CAN_ERRORS:
        hd_host_can_errors(s->port, c.tx_errors, c.rx_errors);
        rig_command_can_status(s);
        return;
    case HD_RIG_CAN_BUSOFF:
        hd_host_can_bus_off(s->port);
        rig_command_can_status(s);
        return;
    case HD_RIG_CAN_STATUS:
        rig_command_can_status(s);
        return;
    case HD_RIG_STATUS:
        snprintf(extra, sizeof extra, "torque=%.9g brake=%d queued=%d", s->rig_torque,
                 hd_sim_plant(s->sim)->out.brake_engaged, s->rig_q_n);
        rig_answer(s, extra);
        return;
    }
}

static void rig_line(void *ctx, char *line) { rig_command(ctx, line); }
static void rig_too_long(void *ctx) { (void)ctx; rig_error("rig command too long"); }

/* Read whatever is waiting on stdin (never blocks) and run each complete line. */
static void rig_poll(srv_t *s)
{
    for (;;) {
        struct pollfd pfd = { 0, POLLIN, 0 };
        char chunk[512];
        if (poll(&pfd, 1, 0) <= 0 || !(pfd.revents & (POLLIN | POLLHUP))) return;
        ssize_t n = read(0, chunk, sizeof chunk);
        if (n <= 0) { s->rig = 0; return; }           /* stdin closed: no more rig commands */
        hd_rig_lines_add(&s->rig_in, chunk, (size_t)n, rig_line, rig_too_long, s);
    }
}

/* After each period: ramp the applied torque (then the next queued ramp) and write the
 * reference instruments. */
static void rig_period(srv_t *s, double dt)
{
    if (s->rig_torque == s->rig_torque_target && s->rig_q_n > 0) {   /* next queued ramp */
        s->rig_torque_target = s->rig_q_target[s->rig_q_head];
        s->rig_torque_rate = s->rig_q_rate[s->rig_q_head];
        s->rig_q_head = (s->rig_q_head + 1) % RIG_QUEUE;
        s->rig_q_n--;
    }
    if (s->rig_torque != s->rig_torque_target) {
        double step = s->rig_torque_rate * dt, d = s->rig_torque_target - s->rig_torque;
        s->rig_torque = fabs(d) <= step ? s->rig_torque_target : s->rig_torque + (d > 0.0 ? step : -step);
        hd_plant_fault_load_step(rig_plant(s), s->rig_torque);
    }
    if (s->rig_rec && (s->rig_k++ % s->rig_rec_decim) == 0) {
        const hd_plant_output *o = &hd_sim_plant(s->sim)->out;
        fprintf(s->rig_rec, "%lu,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                (unsigned long)rig_tick(s), o->t_s, o->transmitted_torque_Nm, s->rig_torque, o->twist_rad,
                o->load_angle_rad, o->load_angle_rad + o->base_angle_rad, o->motor_angle_rad, o->te_rad);
    }
}

static hd_scd_t g_scd_storage;   /* 1 MiB output buffer: static storage, PC-side process only */

int hd_sim_serve_main(int argc, char **argv)
{
    const char *axis = "reference", *transport = "socketcand", *pacing = "realtime", *channel = "can0";
    unsigned long node = 1, port = 0, sync_periods = 10, bitrate = 0, seed = 1;
    double duration = 0.0, can_drop = 0.0, client_timeout = HD_SCD_STALL_MS / 1000.0;
    unsigned long can_seed_v = 1;
    const char *nvm_path = NULL;
    int quiet = 0, rig = 0, generic = 0;
    char msg[512];
    static char plant_set[4096];
    size_t plant_set_len = 0;
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
        else if (strcmp(a, "--set") == 0) {
            NEEDV();
            const char *eq = strchr(v, '=');
            size_t klen = eq ? (size_t)(eq - v) : 0u;
            int ok = eq && klen > 0 && eq[1] != '\0' && strlen(v) < 200;
            for (const char *c = v; ok && *c; c++)
                if (!((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
                      strchr("_.+-=", *c))) ok = 0;
            if (!ok) {
                snprintf(msg, sizeof msg, "--set '%.100s': expected SECTION.KEY=VALUE (a plant key of docs/plant.md)", v);
                return usage_fail(msg);
            }
            int w = snprintf(plant_set + plant_set_len, sizeof plant_set - plant_set_len, "%.*s = %s\n",
                             (int)klen, v, eq + 1);
            if (w < 0 || (size_t)w >= sizeof plant_set - plant_set_len) return usage_fail("too many --set options");
            plant_set_len += (size_t)w;
        }
        else if (strcmp(a, "--can-drop") == 0) {
            NEEDV();
            char *end;
            can_drop = strtod(v, &end);
            if (*end || !(can_drop >= 0.0 && can_drop <= 1.0)) return usage_fail("--can-drop must be a probability 0..1");
        }
        else if (strcmp(a, "--client-timeout") == 0) {
            NEEDV();
            char *end;
            client_timeout = strtod(v, &end);
            if (*end || !(client_timeout >= 0.1 && client_timeout <= 3600.0))
                return usage_fail("--client-timeout must be 0.1..3600 seconds");
        }
        else if (strcmp(a, "--can-seed") == 0) { NEEDV(); if (parse_u(v, 0, 0xFFFFFFFFul, &can_seed_v)) return usage_fail("--can-seed must be an integer 0..2^32-1"); }
        else if (strcmp(a, "--nvm") == 0) { NEEDV(); nvm_path = v; }
        else if (strcmp(a, "--rig") == 0) rig = 1;
        else if (strcmp(a, "--profile") == 0) {
            NEEDV();
            if (strcmp(v, "generic") == 0) generic = 1;
            else if (strcmp(v, "hdservo") == 0) generic = 0;
            else {
                snprintf(msg, sizeof msg, "--profile '%.100s': expected hdservo or generic", v);
                return usage_fail(msg);
            }
        }
        else if (strcmp(a, "-q") == 0 || strcmp(a, "--quiet") == 0) quiet = 1;
        else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            printf("usage: hdservo-sim serve [--axis AXIS.toml|reference|minimal] [--node-id N] "
                   "[--transport socketcand|socketcan] [--port P] [--channel can0] "
                   "[--pacing realtime|fast|sync] [--sync-periods K] [--bitrate B] [--duration S] [--seed N] "
                   "[--set KEY=VALUE]... [--rig] [--profile hdservo|generic] [--can-drop P] [--can-seed N] [--nvm PATH] [--client-timeout S] [-q]\n");
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
    static char text[8192];
    static char axis_q[2048];
    if (toml_escape(axis, axis_q, sizeof axis_q) != 0) {
        fprintf(stderr, "hdservo-sim serve: error: --axis %.200s: expected a path of printable characters, "
                "shorter than %zu bytes\n", axis, sizeof axis_q / 2);
        return 1;
    }
    snprintf(text, sizeof text,
             "[scenario]\nname = \"serve\"\naxis = \"%s\"\nduration_s = 3600\nseed = %lu\n"
             "[controller]\nmode = \"off\"\n%s%s", axis_q, seed, plant_set_len ? "[plant]\n" : "", plant_set);
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
    s->test.data = calloc(1, DOM_CAP);
    s->test.stage = calloc(1, DOM_CAP);
    if (!s->test.data || !s->test.stage) return usage_fail("out of memory");
    s->bitrate = (uint32_t)bitrate;
    s->sync_periods = (uint32_t)sync_periods;
    s->rig = rig;
    s->port = hd_host_port_bound();             /* the harness's host port (bound by hd_sim_new) */
    s->port->can_ctrl.bitrate = (uint32_t)bitrate;
    s->can_drop = can_drop;
    can_seed(s, (uint64_t)can_seed_v);
    if (nvm_path) {
        /* power-up on this NVM: a valid saved set replaces the harness's commissioning */
        int32_t rc = hd_host_nvm_attach_file(s->port, nvm_path);
        if (rc != 0) {
            fprintf(stderr, "hdservo-sim serve: error: --nvm %s: %s\n", nvm_path,
                    rc == -1 ? "expected a file of exactly 32768 bytes (or none yet)" : "cannot read the file");
            return 1;
        }
        static int32_t vals[HD_PARAM_COUNT];
        uint32_t seq = 0;
        if (hd_pstore_load(vals, &seq) == HD_PSTORE_OK) hd_app_init(s->app);
    }

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
        /* blocking writes to a client that stopped reading watch the signal flag and
         * give the client up after --client-timeout without progress */
        s->scd->stop = &g_stop;
        s->scd->stall_ms = (uint32_t)llround(client_timeout * 1000.0);
        if (pace == 1) s->scd->sndbuf = FAST_SNDBUF;
        printf("listening on 127.0.0.1:%u\n", (unsigned)s->scd->port);
    }
    fflush(stdout);

    hd_app_co_port_t pif;
    memset(&pif, 0, sizeof pif);
    pif.ctx = s;
    pif.send = a_send;
    pif.on_sync = a_sync;
    pif.domain_size = a_dsize;
    pif.domain_read = a_dread;
    pif.domain_write_begin = a_dbegin;
    pif.domain_write = a_dwrite;
    pif.domain_write_end = a_dend;
    pif.nvm_wear = a_nvm_wear;
    s->generic = generic;
    if (generic) pif.object_filter = a_object_filter;
    hd_app_co_init(&s->ac, &s->co, s->app, (uint8_t)node, &pif);
    /* a record saved by the generic profile is in force as it is; otherwise its default PDOs */
    if (generic && s->ac.cstore_status != HD_APP_CO_CSTORE_OK) {
        const uint32_t ab = generic_pdos(s, (uint8_t)node);
        if (ab) {
            fprintf(stderr, "hdservo-sim serve: error: --profile generic: default PDO set-up refused (abort 0x%08X)\n",
                    (unsigned)ab);
            return 1;
        }
    }
    generic_identity(s);
    s->vendor_armed = generic;

    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    signal(SIGPIPE, SIG_IGN);

    const double dt = 1.0 / HD_LOOP_HZ;
    const int64_t n_end = duration > 0.0 ? (int64_t)llround(duration / dt) : INT64_MAX;
    double t0 = wall_s();
    int64_t k = 0;
    int had_client = 0, diverged = 0;
    while (!g_stop && k < n_end) {
        /* wait for a client before time starts (the boot-up message must reach it) */
        if (!s->use_scan && !hd_scd_streaming(s->scd)) {
            if (s->rig) rig_poll(s);
            receive(s, had_client ? 5 : 50);
            if (!hd_scd_streaming(s->scd)) continue;
            had_client = 1;
            t0 = wall_s() - (double)k * dt;   /* realtime pacing starts (again) with the client */
            drain_tx(s);
            hd_scd_flush(s->scd, true, 0);
        }
        if (pace == 2) {
            while (!g_stop && s->sync_credit == 0) {
                if (s->rig) rig_poll(s);
                receive(s, s->rig ? 2 : 20);
                drain_tx(s);
                if (!s->use_scan) hd_scd_flush(s->scd, true, 0);
            }
            if (g_stop) break;
            s->sync_credit--;
        } else {
            receive(s, 0);
        }
        /* rig commands: in sync pacing only between SYNC credits (the wait above), so a command
         * takes effect at the same tick whatever the host's timing (lock-step is exact) */
        if (s->rig && pace != 2 && k % 10 == 0) rig_poll(s);
        hd_sim_step(s->sim, NULL);
        if (hd_sim_check_diverged(s->sim, msg, sizeof msg)) {
            /* the plant state is not finite: nothing the drive sends from here on is
             * meaningful, so the server stops with the harness's one-line error */
            snprintf(msg, sizeof msg, "--axis %s: the simulation diverged at t = %.6g s (the plant state is not finite)",
                     axis, (double)k * dt);
            diverged = 1;
            break;
        }
        hd_co_tick(&s->co, HD_CO_TICK_US);
        k++;
        s->t_us = (uint64_t)k * 100u;
        if (s->rig) rig_period(s, dt);
        if (s->bitrate) {
            s->bus_credit_bits += (double)s->bitrate * dt;
            if (s->bus_credit_bits > 2.0 * s->bitrate * dt + 200.0) s->bus_credit_bits = 2.0 * s->bitrate * dt + 200.0;
        }
        drain_tx(s);
        if (!s->use_scan) hd_scd_flush(s->scd, pace == 1, pace == 1 ? FAST_KEEP : HD_SCD_OUT_CAP);
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
    if (s->rig_rec) fclose(s->rig_rec);
    double wall = wall_s() - t0;
    fprintf(stderr,
            "{\"periods\": %lld, \"sim_s\": %.4f, \"wall_s\": %.4f, \"frames_to_bus\": %llu, "
            "\"bus_dropped\": %llu, \"bus_load\": %.4f, \"stack_tx_dropped\": %u, \"rx_frames\": %u, "
            "\"rx_ignored\": %u, \"transport_dropped\": %u, \"can_lost_rx\": %llu, \"can_lost_tx\": %llu, "
            "\"can_busoff_rx\": %llu, \"can_busoff_tx\": %llu, \"can_bus_off\": %lu, \"can_recoveries\": %lu, "
            "\"client_timeouts\": %u, \"profile\": \"%s\", \"vendor_refused\": %llu}\n",
            (long long)k, (double)k * dt, wall, (unsigned long long)s->bus_frames,
            (unsigned long long)s->bus_dropped,
            s->bitrate && k ? (double)s->bus_bits_total / ((double)s->bitrate * (double)k * dt) : 0.0,
            s->co.stats.tx_dropped, s->co.stats.rx_frames, s->co.stats.rx_ignored,
            s->use_scan ? s->scan.tx_dropped : s->scd->tx_dropped,
            (unsigned long long)s->can_lost_rx, (unsigned long long)s->can_lost_tx,
            (unsigned long long)s->can_busoff_rx, (unsigned long long)s->can_busoff_tx,
            (unsigned long)s->port->can_ctrl.bus_off_count, (unsigned long)s->port->can_ctrl.recoveries,
            s->use_scan ? 0u : s->scd->stalled, s->generic ? "generic" : "hdservo",
            (unsigned long long)s->vendor_refused);
    if (s->use_scan) hd_scan_close(&s->scan);
    else hd_scd_close(s->scd);
    hd_sim_free(s->sim);
    free(s->test.data);
    free(s->test.stage);
    free(s);
    free(sc);
    if (diverged) {
        fprintf(stderr, "hdservo-sim serve: error: %s\n", msg);
        return 2;
    }
    return 0;
}
