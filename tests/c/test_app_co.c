/*
 * test_app_co.c - the CANopen <-> app adapter (firmware/canopen/hd_app_co.c) through
 * the hd_co_app_if_t it registers: table domains (staging, checks, refusal with
 * the old table kept, read-back), power-stage interlock, heartbeat loss as a
 * latched app fault.  Stub hal: axis at rest, encoders valid, no NVM.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "hd_app.h"
#include "hd_app_co.h"
#include "support/test_tables.h"

uint32_t hd_hal_tick(void) { return 0u; }
/* track = 1: the encoders read trk_pos (Q32.32 output turns; the test sets it to the
 * position reference after every period: an axis that follows its reference one period
 * late, so a stopped reference is an axis at rest); 0: at rest at 0 */
static int32_t track;
static int64_t trk_pos;
void hd_hal_read_sensors(hd_hal_sensors_t *s)
{
    memset(s, 0, sizeof *s);
    s->valid = HD_HAL_VALID_MOTOR_ENC | HD_HAL_VALID_OUTPUT_ENC | HD_HAL_VALID_CURRENT;
    if (track != 0) {
        /* default encoders: output 24 bit per output turn, motor 17 bit per motor turn, N = 100 */
        s->output_enc_raw = (uint32_t)((uint64_t)(trk_pos + 128) >> 8) & 0xFFFFFFu;
        s->motor_enc_raw = (uint32_t)((uint64_t)(trk_pos * 100 + 16384) >> 15) & 0x1FFFFu;
    }
}
void hd_hal_write_command(const hd_hal_command_t *c) { (void)c; }
bool hd_hal_can_send(const hd_can_frame_t *f) { (void)f; return true; }
bool hd_hal_can_recv(hd_can_frame_t *f) { (void)f; return false; }
static hd_hal_can_status_t can_st;   /* controller state the tests set */
static uint32_t n_recover;
void hd_hal_can_status(hd_hal_can_status_t *st) { *st = can_st; }
void hd_hal_can_recover(void) { n_recover++; }
/* NVM with flash semantics in RAM, the STM32G474 layout (1 KiB pages, 22 KiB used) */
#define NVM_SIZE 24576u
#define NVM_PAGE 1024u
static uint8_t nvm[NVM_SIZE];
static int nvm_off;                   /* 1: the hal reports no NVM (every call fails) */
uint32_t hd_hal_nvm_size(void) { return nvm_off ? 0u : NVM_SIZE; }
uint32_t hd_hal_nvm_page_size(void) { return NVM_PAGE; }
int32_t hd_hal_nvm_read(uint32_t o, void *b, uint32_t l)
{
    if (nvm_off || o > NVM_SIZE || l > NVM_SIZE - o) return -1;
    memcpy(b, &nvm[o], l);
    return 0;
}
int32_t hd_hal_nvm_write(uint32_t o, const void *b, uint32_t l)
{
    if (nvm_off || o > NVM_SIZE || l > NVM_SIZE - o || o % 8u || l % 8u) return -1;
    for (uint32_t i = 0; i < l; i++) {
        if (nvm[o + i] != 0xFFu) return -2;
        nvm[o + i] = ((const uint8_t *)b)[i];
    }
    return 0;
}
static uint32_t nvm_erases[NVM_SIZE / NVM_PAGE];   /* page erases (flash wear) */
int32_t hd_hal_nvm_erase(uint32_t o, uint32_t l)
{
    if (nvm_off || o > NVM_SIZE || l > NVM_SIZE - o || o % NVM_PAGE || l % NVM_PAGE) return -1;
    memset(&nvm[o], 0xFF, l);
    for (uint32_t k = o / NVM_PAGE; k < (o + l) / NVM_PAGE; k++) nvm_erases[k]++;
    return 0;
}
static uint32_t erases_total(void)
{
    uint32_t t = 0u;
    for (uint32_t k = 0u; k < NVM_SIZE / NVM_PAGE; k++) t += nvm_erases[k];
    return t;
}
/* the port's wear counter (hd_app_co_port_t.nvm_wear) */
static int32_t p_wear(void *c, uint32_t *total, uint32_t *max_page)
{
    (void)c;
    *total = erases_total();
    *max_page = 0u;
    for (uint32_t k = 0u; k < NVM_SIZE / NVM_PAGE; k++) {
        if (nvm_erases[k] > *max_page) *max_page = nvm_erases[k];
    }
    return 0;
}

static hd_app_t app;
static hd_co_t co;
static hd_app_co_t ac;
static uint32_t n_sent;
static uint8_t img[4u * HD_APP_CO_STAGE_WORDS + 16u];

static hd_can_frame_t last_sdo;      /* the last SDO response (0x581) */
static hd_can_frame_t last_emcy;     /* the last EMCY frame the drive sent */
static uint32_t n_emcy;
static bool p_send(void *c, const hd_can_frame_t *f)
{
    (void)c;
    n_sent++;
    if (f->id == 0x581u) {
        last_sdo = *f;
    }
    if (f->id >= 0x81u && f->id <= 0xFFu) {
        last_emcy = *f;
        n_emcy++;
    }
    return true;
}

/* power-on of the drive on the NVM as it is */
static void boot(uint8_t node)
{
    hd_app_co_port_t port;
    memset(&port, 0, sizeof port);
    port.send = p_send;
    port.nvm_wear = p_wear;
    n_emcy = 0u;
    memset(&last_emcy, 0, sizeof last_emcy);
    hd_app_init(&app);
    hd_app_co_init(&ac, &co, &app, node, &port);
    hd_app_step(&app);
}

static int setup(void **st)
{
    (void)st;
    track = 0;
    trk_pos = 0;
    nvm_off = 0;
    memset(nvm, 0xFF, sizeof nvm);
    memset(nvm_erases, 0, sizeof nvm_erases);
    boot(1u);
    return 0;
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

/* Everett table L levels, serialised + CRC-32 trailer into img; returns the length */
static uint32_t make_table(uint32_t levels, uint32_t version, int32_t scale)
{
    static hd_preisach_table_t t;
    uint32_t i, n = 0u;
    test_everett_table(&t, levels, version, scale);
    put32(img + 0, t.magic); put32(img + 4, t.format); put32(img + 8, t.version);
    put32(img + 12, t.levels); put32(img + 16, t.sub_bits); put32(img + 20, t.in_shift);
    put32(img + 24, (uint32_t)t.u0); put32(img + 28, t.unit); put32(img + 32, t.n_entries);
    put32(img + 36, t.crc);
    for (i = 0u; i < t.n_entries; i++) {
        put32(img + 40u + 4u * i, (uint32_t)t.e[i]);
    }
    n = 40u + 4u * t.n_entries;
    put32(img + n, hd_crc32(0u, img, n));
    return n + 4u;
}

static void reseal_trailer(uint32_t len)
{
    put32(img + len - 4u, hd_crc32(0u, img, len - 4u));
}

/* download through the registered callbacks in 7-byte segments */
static uint32_t download(uint16_t dom, const uint8_t *b, uint32_t len)
{
    const hd_co_app_if_t *a = &co.app;
    uint32_t off = 0u, r = a->domain_write_begin(a->ctx, dom, len);
    if (r != 0u) {
        return r;
    }
    while (off < len) {
        const uint32_t n = (len - off < 7u) ? len - off : 7u;
        r = a->domain_write(a->ctx, dom, off, b + off, n);
        if (r != 0u) {
            (void)a->domain_write_end(a->ctx, dom, off, false);
            return r;
        }
        off += n;
    }
    return a->domain_write_end(a->ctx, dom, len, true);
}

static uint32_t upload(uint16_t dom, uint8_t *b, uint32_t cap)
{
    const hd_co_app_if_t *a = &co.app;
    uint32_t size = 0u, off = 0u;
    assert_int_equal(a->domain_size(a->ctx, dom, &size), 0);
    assert_true(size <= cap);
    while (off < size) {
        const uint32_t n = (size - off < 889u) ? size - off : 889u;
        assert_int_equal(a->domain_read(a->ctx, dom, off, b + off, n), 0);
        off += n;
    }
    return size;
}

static void test_preisach_table(void **st)
{
    static uint8_t back[sizeof img], good[sizeof img];
    static hd_preisach_table_t before;
    (void)st;
    assert_int_equal(upload(HD_APP_CO_DOM_PREISACH, back, sizeof back), 0);   /* none in force */
    const uint32_t len = make_table(12u, 5u, 300);
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len), 0);
    assert_int_equal(app.cb.table_ok, 1);
    assert_int_equal(app.cb.table.version, 5);
    assert_int_equal(upload(HD_APP_CO_DOM_PREISACH, back, sizeof back), len);
    assert_memory_equal(back, img, len);
    memcpy(good, img, len);
    before = app.cb.table;

    /* inner CRC broken (trailer right) */
    img[40u + 4u * 7u] ^= 1u;
    reseal_trailer(len);
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len), HD_CO_AB_STORE);
    /* trailer broken */
    memcpy(img, good, len);
    img[len - 2u] ^= 0x10u;
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len), HD_CO_AB_STORE);
    /* length does not match n_entries */
    memcpy(img, good, len);
    reseal_trailer(len - 4u);
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len - 4u), HD_CO_AB_STORE);
    /* too short, too long */
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, 4u), HD_CO_AB_STORE);
    assert_int_equal(co.app.domain_write_begin(co.app.ctx, 1u, 4u * HD_APP_CO_STAGE_WORDS + 1u),
                     HD_CO_AB_LEN_HIGH);
    /* out-of-order segment */
    assert_int_equal(co.app.domain_write_begin(co.app.ctx, 1u, 0u), 0);
    assert_int_equal(co.app.domain_write(co.app.ctx, 1u, 7u, good, 7u), HD_CO_AB_GENERAL);
    assert_int_equal(co.app.domain_write_end(co.app.ctx, 1u, 14u, true), HD_CO_AB_STORE);
    /* aborted transfer of a good table: nothing changes */
    assert_int_equal(co.app.domain_write_begin(co.app.ctx, 1u, len), 0);
    assert_int_equal(co.app.domain_write(co.app.ctx, 1u, 0u, good, 100u), 0);
    assert_int_equal(co.app.domain_write_end(co.app.ctx, 1u, 100u, false), 0);

    assert_memory_equal(&app.cb.table, &before, sizeof before);
    assert_int_equal(upload(HD_APP_CO_DOM_PREISACH, back, sizeof back), len);
    assert_memory_equal(back, good, len);

    /* full-size table */
    const uint32_t len64 = make_table(HD_PREISACH_L_MAX, 6u, 3);
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len64), 0);
    assert_int_equal(app.cb.table.levels, HD_PREISACH_L_MAX);
    assert_int_equal(upload(HD_APP_CO_DOM_PREISACH, back, sizeof back), len64);
    assert_memory_equal(back, img, len64);
}

static void test_group_and_interlock(void **st)
{
    const uint16_t *ids;
    const uint32_t n = hd_app_co_group_ids(HD_APP_CO_DOM_TE, &ids);
    static uint8_t back[256];
    uint8_t p[4u * (HD_APP_CO_GROUP_HDR + HD_APP_CO_GROUP_MAX) + 4u];
    uint32_t i, len = 4u * (HD_APP_CO_GROUP_HDR + n) + 4u;
    int32_t old_amp;
    (void)st;
    assert_int_equal(n, 15);
    put32(p, HD_APP_CO_MAGIC_TE); put32(p + 4, 1u); put32(p + 8, 9u); put32(p + 12, n);
    for (i = 0u; i < n; i++) {
        put32(p + 16u + 4u * i, (uint32_t)hd_app_param_get(&app, ids[i]));
    }
    put32(p + 16u + 4u * 4u, 12345u);                     /* te_amp1 */
    put32(p + len - 4u, hd_crc32(0u, p, len - 4u));
    assert_int_equal(download(HD_APP_CO_DOM_TE, p, len), 0);
    assert_int_equal(hd_app_param_get(&app, HD_P_TE_AMP1), 12345);
    assert_int_equal(upload(HD_APP_CO_DOM_TE, back, sizeof back), len);
    assert_memory_equal(back, p, len);
    /* one value out of range: nothing applied */
    old_amp = hd_app_param_get(&app, HD_P_TE_AMP1);
    put32(p + 16u + 4u * 4u, 777u);
    put32(p + 16u + 4u * 1u, 0xFFFFFFFFu);                /* te_k1 = -1: below its minimum */
    put32(p + len - 4u, hd_crc32(0u, p, len - 4u));
    assert_int_equal(download(HD_APP_CO_DOM_TE, p, len), HD_CO_AB_STORE);
    assert_int_equal(hd_app_param_get(&app, HD_P_TE_AMP1), old_amp);
    /* the version is a parameter (saved with the others): 1..2^31-1 */
    assert_int_equal(hd_app_param_get(&app, HD_P_TBL_TE_VERSION), 9);
    assert_int_equal(hd_app_param_get(&app, HD_P_TBL_FR_VERSION), 0);
    put32(p + 16u + 4u * 1u, (uint32_t)hd_app_param_get(&app, ids[1]));
    put32(p + 8, 0x80000000u);
    put32(p + len - 4u, hd_crc32(0u, p, len - 4u));
    assert_int_equal(download(HD_APP_CO_DOM_TE, p, len), HD_CO_AB_STORE);
    assert_int_equal(hd_app_param_get(&app, HD_P_TE_AMP1), old_amp);
    assert_int_equal(hd_app_param_get(&app, HD_P_TBL_TE_VERSION), 9);
    put32(p + 8, 0x7FFFFFFFu);
    put32(p + len - 4u, hd_crc32(0u, p, len - 4u));
    assert_int_equal(download(HD_APP_CO_DOM_TE, p, len), 0);
    assert_int_equal(hd_app_param_get(&app, HD_P_TBL_TE_VERSION), 0x7FFFFFFF);
    assert_int_equal(upload(HD_APP_CO_DOM_TE, back, sizeof back), len);
    assert_memory_equal(back, p, len);
    /* a restore of the defaults: no group version, the group reads back empty */
    assert_int_equal(co.app.restore(co.app.ctx), 0u);
    assert_int_equal(upload(HD_APP_CO_DOM_TE, back, sizeof back), 0u);
    old_amp = hd_app_param_get(&app, HD_P_TE_AMP1);

    /* power stage on: every table domain refused */
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_VELOCITY), 0);
    hd_app_step(&app);
    assert_int_equal(co.app.domain_write_begin(co.app.ctx, HD_APP_CO_DOM_PREISACH, 0u), HD_CO_AB_STATE);
    assert_int_equal(co.app.domain_write_begin(co.app.ctx, HD_APP_CO_DOM_TE, 0u), HD_CO_AB_STATE);
    assert_int_equal(co.app.domain_write_begin(co.app.ctx, HD_APP_CO_DOM_CAPTURE, 0u), HD_CO_AB_READONLY);
    assert_int_equal(co.app.domain_write_begin(co.app.ctx, HD_APP_CO_DOM_PORT, 0u), HD_CO_AB_NO_OBJECT);

    /* heartbeat lost: a latched app fault, only the fault reset clears it */
    co.app.drive_comm_fault(co.app.ctx, HD_CO_EMCY_HB);
    hd_app_step(&app);
    assert_int_equal(app.fault, HD_FAULT_COMM);
    assert_int_equal(app.tel.mode, HD_MODE_OFF);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_VELOCITY), -1);
    {
        hd_co_actual_t a;
        co.app.drive_actual(co.app.ctx, &a);
        assert_int_equal(a.fault_code, HD_FAULT_COMM);
        assert_int_equal(a.fault_emcy, 0x8130);
        assert_int_equal(a.power_enabled, 0);
    }
    co.app.drive_fault_reset(co.app.ctx);
    assert_int_equal(app.fault, HD_FAULT_NONE);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_VELOCITY), 0);
    assert_int_equal(hd_app_fault_raise(&app, 0), -1);
    assert_int_equal(hd_app_fault_raise(&app, 99), -1);
    assert_true(n_sent >= 1u);                            /* boot-up */
}

/* ---- CiA 402 halt (controlword bit 8) ------------------------------------------ */

#define CW_ENABLE 0x000Fu
#define CW_NEWSP  0x0010u
#define CW_HALT   0x0100u
#define SW_TR     0x0400u

/* one control period: app step, CANopen tick, the tracking axis follows the reference */
static void period(void)
{
    hd_app_step(&app);
    hd_co_tick(&co, HD_CO_TICK_US);
    trk_pos = hd_app_telemetry(&app)->pos_ref;
}

static void cw_write(uint16_t v)
{
    assert_int_equal(hd_co_set_i64(&co, 0x6040u, 0u, v), 0);
}

/* tracking axis, fault checks off (the stub power stage moves nothing), OPERATION ENABLED in mode */
static void enable_402(int8_t mode)
{
    track = 1;
    trk_pos = 0;
    assert_int_equal(hd_app_param_set(&app, HD_P_FAULT_ENABLE, 0), 0);
    co.od.modes_of_operation = mode;
    period();
    cw_write(0x06u);
    cw_write(CW_ENABLE);
    period();
    assert_int_equal(hd_co402_state(&ac.p402), HD_CO402_OP_ENABLED);
    assert_int_equal(ac.mode, mode);
}

/* PP new set-point (bit 4 edge) to target (2^-24 turn), other bits as in extra */
static void pp_setpoint(int32_t target, uint16_t extra)
{
    co.od.target_position = target;
    cw_write((uint16_t)(CW_ENABLE | extra));
    cw_write((uint16_t)(CW_ENABLE | CW_NEWSP | extra));
    period();
    cw_write((uint16_t)(CW_ENABLE | extra));
}

/* velocity step per period of a ramp at acc (2^-24 turn/s^2), 2^-32 turn/s, rounded */
static int32_t dv_of(int64_t acc)
{
    return (int32_t)((acc * 256 + HD_LOOP_HZ / 2) / HD_LOOP_HZ);
}

/* CSV at v, then halt for n periods: the command never goes negative and never drops by
 * more than dmax per period, and is 0 at the end; returns the periods it dropped by more
 * than dsteep */
static uint32_t csv_halt_ramp(int32_t v, int32_t dmax, int32_t dsteep, uint32_t n)
{
    int32_t prev = v;
    uint32_t i, n_steep = 0u;
    enable_402(HD_CO402_MODE_CSV);
    co.od.target_velocity = v;
    period();
    assert_int_equal(app.vel_cmd, v);
    cw_write(CW_ENABLE | CW_HALT);
    for (i = 0u; i < n; i++) {
        period();
        assert_true(app.vel_cmd >= 0);
        assert_true(prev - app.vel_cmd <= dmax);
        if (prev - app.vel_cmd > dsteep) {
            n_steep++;
        }
        prev = app.vel_cmd;
    }
    assert_int_equal(app.vel_cmd, 0);
    return n_steep;
}

static int64_t special(uint16_t index, uint8_t sub)
{
    int64_t v = -1;
    assert_int_equal(co.app.special_read(co.app.ctx, index, sub, &v), 0u);
    return v;
}

static int64_t od_get(uint16_t index, uint8_t sub)
{
    int64_t v = 0;
    assert_int_equal(hd_co_get_i64(&co, index, sub, &v), 0u);
    return v;
}

static void nmt(uint8_t cmd)
{
    hd_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0u;
    f.dlc = 2u;
    f.data[0] = cmd;
    f.data[1] = 0u;                                       /* all nodes */
    hd_co_process(&co, &f);
}

/* 0x1010 saves parameters, the Preisach table and the communication / CiA 402 settings;
 * a power cycle, an NMT reset and 0x1011 restore (0x5101 reports what boot found) */
/* fb_config (0x2100:17) over SDO: accepted with the power stage off, refused with
 * 0x08000022 while it is on (the value in force kept); rewriting the same value is fine */
/* 0x5200: the estimator's common-mode scale (:15) and bias (:16) read through the OD as
 * signed 32-bit words, the confidence (:9, :10) beside them; the record ends at :16 */
static void test_fric_est_common_mode_objects(void **st)
{
    int64_t v = 0;
    (void)st;
    app.cb.fe.scale = 3 * HD_FE_SCALE_ONE / 2;       /* x1.5 */
    app.cb.fe.bias = -(5 << 14);                    /* -1.25 N.m */
    app.cb.fe.conf[HD_FE_DIR_POS] = 1000u;
    app.cb.fe.conf[HD_FE_DIR_NEG] = 250u;
    assert_int_equal(od_get(0x5200u, 15u), 98304);
    assert_int_equal(od_get(0x5200u, 16u), -81920);
    assert_int_equal(od_get(0x5200u, 9u), 1000);
    assert_int_equal(od_get(0x5200u, 10u), 250);
    assert_int_equal(special(0x5200u, 15u), 98304);
    assert_int_equal(special(0x5200u, 16u), -81920);
    /* read-only: a write is refused and the value stays */
    assert_int_not_equal(hd_co_set_i64(&co, 0x5200u, 15u, 65536), 0u);
    assert_int_equal(od_get(0x5200u, 15u), 98304);
    /* no sub-index beyond :16 */
    assert_int_equal(hd_co_get_i64(&co, 0x5200u, 17u, &v), HD_CO_AB_NO_SUB);
}

static void test_fb_config_interlock(void **st)
{
    (void)st;
    assert_int_equal(co.app.param_set(co.app.ctx, HD_P_FB_CONFIG, 1), 0u);
    assert_int_equal(hd_app_param_get(&app, HD_P_FB_CONFIG), 1);
    assert_int_equal(co.app.param_set(co.app.ctx, HD_P_FB_CONFIG, 3), HD_CO_AB_VALUE);   /* out of range */
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_VELOCITY), 0);
    hd_app_step(&app);
    assert_int_equal(co.app.param_set(co.app.ctx, HD_P_FB_CONFIG, 2), HD_CO_AB_STATE);
    assert_int_equal(co.app.param_set(co.app.ctx, HD_P_FB_CONFIG, 0), HD_CO_AB_STATE);
    assert_int_equal(hd_app_param_get(&app, HD_P_FB_CONFIG), 1);
    assert_int_equal(app.fb_cfg.kind, 1u);
    assert_int_equal(co.app.param_set(co.app.ctx, HD_P_FB_CONFIG, 1), 0u);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_OFF), 0);
    hd_app_step(&app);
    assert_int_equal(co.app.param_set(co.app.ctx, HD_P_FB_CONFIG, 2), 0u);
    assert_int_equal(app.fb_cfg.kind, 2u);
}

static void test_store_objects(void **st)
{
    static uint8_t back[sizeof img];
    (void)st;
    /* the generator's count (the host's od_gen.STORED) is the runtime predicate's */
    assert_int_equal(hd_co_store_words(&co), 1u + HD_CO_OD_STORED);   /* word 0: layout CRC */
    assert_int_equal(special(0x5101u, 1u), HD_PSTORE_BLANK);
    assert_int_equal(special(0x5101u, 2u), HD_TSTORE_BLANK);
    assert_int_equal(special(0x5101u, 3u), 1);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_BLANK);
    const uint32_t len = make_table(12u, 5u, 300);
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len), 0);
    assert_int_equal(special(0x5101u, 3u), 0);
    /* settings a master makes: heartbeat, following error window, a TPDO event timer,
     * a custom RPDO2 COB-ID (disabled first, as CiA 301 asks), a drive parameter */
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, 250), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x6065u, 0u, 1234), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x1800u, 5u, 77), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x1401u, 1u, 0x80000000 | 0x3A1), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x1401u, 1u, 0x3A1), 0u);
    assert_int_equal(hd_app_param_set(&app, HD_P_POS_KP, 33 << 16), 0);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    assert_int_equal(special(0x5101u, 3u), 1);

    /* power cycle: all of it back */
    boot(1u);
    assert_int_equal(special(0x5101u, 1u), HD_PSTORE_OK);
    assert_int_equal(special(0x5101u, 2u), HD_TSTORE_OK);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_OK);
    assert_int_equal(od_get(0x1017u, 0u), 250);
    assert_int_equal(od_get(0x6065u, 0u), 1234);
    assert_int_equal(od_get(0x1800u, 5u), 77);
    assert_int_equal(od_get(0x1401u, 1u), 0x3A1);
    assert_int_equal(od_get(0x1400u, 1u), 0x201);            /* default: 0x200 + node */
    assert_int_equal(app.param[HD_P_POS_KP], 33 << 16);
    assert_int_equal(upload(HD_APP_CO_DOM_PREISACH, back, sizeof back), len);
    assert_memory_equal(back, img, len);
    /* NMT reset communication goes back to the saved values, not the defaults */
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, 500), 0u);
    nmt(0x82u);
    assert_int_equal(od_get(0x1017u, 0u), 250);
    /* another node id on the same NVM: node-relative COB-IDs follow it, a custom one stays */
    boot(5u);
    assert_int_equal(od_get(0x1400u, 1u), 0x205);
    assert_int_equal(od_get(0x1401u, 1u), 0x3A1);
    assert_int_equal(od_get(0x1017u, 0u), 250);
    boot(1u);

    /* restore with the power stage on: refused, everything stays */
    enable_402(8);
    assert_int_equal(co.app.restore(co.app.ctx), HD_CO_AB_STATE);
    assert_int_equal(app.cb.table_ok, 1u);
    assert_int_equal(app.param[HD_P_POS_KP], 33 << 16);
    assert_int_equal(od_get(0x6065u, 0u), 1234);
    /* power stage off: defaults and no table, now; saved, the next boot has them */
    cw_write(0x06u);
    period();
    assert_int_equal(app.mode, HD_MODE_OFF);
    assert_int_equal(co.app.restore(co.app.ctx), 0u);
    assert_int_equal(app.cb.table_ok, 0u);
    assert_int_equal(app.param[HD_P_POS_KP], hd_param_table[HD_P_POS_KP].def);
    assert_int_equal(od_get(0x6065u, 0u), 0xFFFFFFFF);
    assert_int_equal(od_get(0x1017u, 0u), 100);
    assert_int_equal(od_get(0x1401u, 1u), 0x301);              /* default 0x300 + node 1 */
    assert_int_equal(upload(HD_APP_CO_DOM_PREISACH, back, sizeof back), 0u);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    boot(1u);
    assert_int_equal(special(0x5101u, 2u), HD_TSTORE_NONE);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_OK);
    assert_int_equal(od_get(0x1017u, 0u), 100);
    assert_int_equal(od_get(0x6065u, 0u), 0xFFFFFFFF);

    /* a damaged object record: defaults, the parameters still load */
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, 300), 0u);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    {
        const uint32_t o = 2u * NVM_PAGE + 18u * NVM_PAGE;   /* after the parameter and table slots */
        nvm[o + 20u] ^= 0x01u;
        nvm[o + NVM_PAGE + 20u] ^= 0x01u;
    }
    boot(1u);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_CORRUPT);
    assert_int_equal(special(0x5101u, 1u), HD_PSTORE_OK);
    assert_int_equal(od_get(0x1017u, 0u), 100);
    /* no NVM at all: every store reports it, a save is refused */
    nvm_off = 1;
    boot(1u);
    assert_int_equal(special(0x5101u, 1u), HD_PSTORE_NVM_ERROR);
    assert_int_equal(special(0x5101u, 2u), HD_TSTORE_NVM_ERROR);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_NVM_ERROR);
    assert_int_equal(co.app.store(co.app.ctx), HD_CO_AB_STATE);
}

static uint16_t emcy_code(void)
{
    return (uint16_t)(last_emcy.data[0] | (last_emcy.data[1] << 8));
}

/* A CRC-valid stored image (written by the drive's own 0x1010 from values set behind
 * the SDO checks) that maps a read-only object into an RPDO: refused at boot like the
 * SDO write would be; every stored object at its default (nothing of the image, not the
 * valid heartbeat either), 0x5101:4 = 5 with the object in :6, EMCY 0x6300; an NMT reset
 * communication keeps the defaults. */
static void test_stored_image_with_read_only_rpdo_mapping_refused(void **st)
{
    (void)st;
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, 250), 0u);      /* a valid setting */
    /* an SDO master cannot do this: */
    assert_int_equal(hd_co_set_i64(&co, 0x1600u, 0u, 0), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x1600u, 1u, 0x60410010), HD_CO_AB_NO_MAP);
    co.od.rpdo_map[0][0] = 0x60410010u;                                 /* statusword: ro, TPDO only */
    co.od.rpdo_nmap[0] = 1u;
    assert_int_equal(co.app.store(co.app.ctx), 0u);                     /* CRC-valid record */
    boot(1u);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_REFUSED);
    assert_int_equal(special(0x5101u, 6u), (0x1600 << 8) | 1);
    assert_int_equal(special(0x5101u, 1u), HD_PSTORE_OK);               /* the parameters still load */
    assert_int_equal(od_get(0x1600u, 1u), co.table[hd_co_find(&co, 0x1600u, 1u)].def);
    assert_int_equal(od_get(0x1600u, 0u), co.table[hd_co_find(&co, 0x1600u, 0u)].def);
    assert_int_equal(od_get(0x1017u, 0u), 100);                         /* default, not 250 */
    assert_int_equal(co.hb_next_us, co.now_us + 100000u);               /* its timer too */
    assert_true(n_emcy >= 1u);
    assert_int_equal(emcy_code(), HD_APP_CO_EMCY_STORE_REFUSED);
    assert_int_equal(last_emcy.data[3] | (last_emcy.data[4] << 8), 0x1600);
    assert_int_equal(last_emcy.data[5], 1);
    assert_true((od_get(0x1001u, 0u) & HD_CO_ER_GENERIC) != 0);
    nmt(0x82u);
    assert_int_equal(od_get(0x1017u, 0u), 100);
    assert_int_equal(od_get(0x1600u, 0u), co.table[hd_co_find(&co, 0x1600u, 0u)].def);
}

/* the same for an RPDO COB-ID in a restricted range (LSS, 0x7E5) */
static void test_stored_image_with_restricted_cob_id_refused(void **st)
{
    (void)st;
    assert_int_equal(hd_co_set_i64(&co, 0x6065u, 0u, 1234), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x1401u, 1u, 0x80000000 | 0x7E5), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x1401u, 1u, 0x7E5), HD_CO_AB_VALUE);
    co.od.rpdo_cob[1] = 0x7E5u;
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    boot(1u);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_REFUSED);
    assert_int_equal(special(0x5101u, 6u), (0x1401 << 8) | 1);
    assert_int_equal(od_get(0x1401u, 1u), 0x301);                       /* default 0x300 + node */
    assert_int_equal(od_get(0x6065u, 0u), 0xFFFFFFFF);                  /* nothing half-applied */
    assert_int_equal(emcy_code(), HD_APP_CO_EMCY_STORE_REFUSED);
    /* a good image loads again once saved: the status goes back to 0 */
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    boot(1u);
    assert_int_equal(special(0x5101u, 4u), HD_APP_CO_CSTORE_OK);
    assert_int_equal(special(0x5101u, 6u), 0);
}

/* 0x1010 writes only what changed: a save of unchanged settings erases nothing */
static void test_identical_save_erases_nothing(void **st)
{
    uint32_t e0;
    (void)st;
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, 250), 0u);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    e0 = erases_total();
    assert_true(e0 > 0u);
    assert_int_equal(special(0x5102u, 1u), (int64_t)e0);
    for (uint32_t i = 0u; i < 5u; i++) {
        assert_int_equal(co.app.store(co.app.ctx), 0u);
    }
    assert_int_equal(erases_total(), e0);
    assert_int_equal(special(0x5102u, 1u), (int64_t)e0);
    /* a changed object: one record rewritten (its own slot page), not the parameters */
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, 300), 0u);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    assert_int_equal(erases_total(), e0 + 1u);
    assert_int_equal(special(0x5102u, 2u), 1);                          /* no page twice yet */
    /* a table saved once, then downloaded again unchanged: the save erases nothing and
     * the table counts as saved */
    const uint32_t len = make_table(12u, 5u, 300);
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len), 0);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    e0 = erases_total();
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len), 0);
    assert_int_equal(special(0x5101u, 3u), 0);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    assert_int_equal(erases_total(), e0);
    assert_int_equal(special(0x5101u, 3u), 1);
}

/* 0x1010 rate limit: page erases in drive time; over it a save that changes the NVM
 * is refused (0x08000021, EMCY 0xFF10, 0x5102:3), one that changes nothing is not;
 * credit comes back with drive time (hd_co_tick) and the next save clears the EMCY */
static void test_save_rate_limit(void **st)
{
    uint32_t i, ab = 0u, saves = 0u, e0;
    (void)st;
    assert_int_equal(special(0x5102u, 4u), HD_APP_CO_SAVE_CREDIT_MAX);
    for (i = 0u; i < 1000u && ab == 0u; i++) {
        assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, (int64_t)(200u + (i % 2u))), 0u);
        ab = co.app.store(co.app.ctx);
        saves += (ab == 0u) ? 1u : 0u;
    }
    assert_int_equal(ab, HD_APP_CO_AB_SAVE_RATE);
    assert_true(erases_total() >= (uint32_t)HD_APP_CO_SAVE_CREDIT_MAX);
    assert_true(erases_total() <= (uint32_t)HD_APP_CO_SAVE_CREDIT_MAX + 2u);
    assert_true(saves >= 100u);                          /* one page per changed object save */
    assert_int_equal(special(0x5102u, 3u), 1);
    assert_true(special(0x5102u, 4u) <= 0);
    assert_int_equal(emcy_code(), HD_APP_CO_EMCY_SAVE_RATE);
    e0 = erases_total();
    assert_int_equal(co.app.store(co.app.ctx), HD_APP_CO_AB_SAVE_RATE);   /* again: refused, */
    assert_int_equal(special(0x5102u, 3u), 2);
    assert_int_equal(erases_total(), e0);                                 /* nothing erased */
    /* back to the saved value: nothing to write, so not refused */
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, (int64_t)(200u + ((i - 2u) % 2u))), 0u);
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    assert_int_equal(erases_total(), e0);
    /* drive time refills the credit: one erase per 3 h */
    assert_int_equal(hd_co_set_i64(&co, 0x1017u, 0u, 999), 0u);
    while (special(0x5102u, 4u) <= 0) {
        hd_co_tick(&co, (uint32_t)(HD_APP_CO_SAVE_REFILL_US / 4u));
    }
    assert_int_equal(co.app.store(co.app.ctx), 0u);
    assert_int_equal(erases_total(), e0 + 1u);
    assert_int_equal(emcy_code(), 0x0000u);                               /* error reset */
    assert_int_equal(special(0x5102u, 3u), 2);
}

static void test_pp_halt(void **st)
{
    const int32_t target = 1 << 22;                       /* 0.25 turn (90 deg), 2^-24 turn */
    const int64_t amax = app.traj_cfg.amax;               /* 2^-24 turn/s^2 */
    const int64_t dv = dv_of(amax);                       /* 2^-32 turn/s per period */
    int64_t p0, prev, v0, stop, lim;
    int32_t vprev;
    uint32_t i;
    (void)st;
    enable_402(HD_CO402_MODE_PP);
    for (i = 0u; i < 8u; i++) {
        period();                                         /* the entry move (length 0) ends */
    }
    assert_true((co.od.statusword & SW_TR) != 0u);        /* at rest, no move: reached */
    pp_setpoint(target, 0u);
    /* 1 s into the move (accelerated to the 60 deg/s limit, cruising): bit 10 stays 0 */
    prev = app.tel.pos_ref;
    for (i = 0u; i < 10000u; i++) {
        period();
        assert_true(app.tel.pos_ref >= prev);
        assert_true((co.od.statusword & SW_TR) == 0u);
        prev = app.tel.pos_ref;
    }
    v0 = app.traj.vel;
    p0 = app.tel.pos_ref;
    assert_true(v0 > app.traj_cfg.vmax / 2);
    assert_true(p0 < (int64_t)target * 256 / 2);          /* mid-way */

    /* halt: decelerates at amax to standstill, never reverses, bit 10 once at rest */
    cw_write(CW_ENABLE | CW_HALT);
    vprev = (int32_t)v0;
    for (i = 0u; i < 20000u; i++) {
        period();
        assert_true(app.tel.pos_ref >= prev);             /* never reverses */
        assert_true(app.traj.vel >= 0);
        assert_true((int64_t)vprev - app.traj.vel <= dv); /* decelerates within amax */
        vprev = app.traj.vel;
        prev = app.tel.pos_ref;
    }
    stop = app.tel.pos_ref - p0;                          /* Q32.32 turn */
    /* v0^2 / (2 amax): (2^-32 turn/s)^2 / (2^-24 turn/s^2) = 2^-40 turn = 2^-8 Q32.32 units;
     * allowance 2 periods at v0 (the ramp's first step and the rounding of dv) */
    lim = v0 * v0 / (2 * amax) / 256;
    assert_true(stop <= lim + 2 * v0 / HD_LOOP_HZ);
    assert_true(stop >= lim - 2 * v0 / HD_LOOP_HZ);       /* a ramp at amax, not a jump to 0 */
    assert_int_equal(app.traj.vel, 0);
    assert_int_equal(hd_traj_done(&app.traj), 1);
    assert_true((co.od.statusword & SW_TR) != 0u);

    /* a set-point while halt is set: acknowledged, not executed */
    p0 = app.tel.pos_ref;
    pp_setpoint(target, CW_HALT);
    for (i = 0u; i < 1000u; i++) {
        period();
    }
    assert_true(app.tel.pos_ref == p0);
    /* halt released: the axis stays at rest until a new set-point */
    cw_write(CW_ENABLE);
    for (i = 0u; i < 1000u; i++) {
        period();
    }
    assert_true(app.tel.pos_ref == p0);
    assert_true((co.od.statusword & SW_TR) != 0u);
    /* the next set-point is accepted and ends exactly on its target (back to 0.1 turn) */
    pp_setpoint(target * 2 / 5, 0u);
    for (i = 0u; i < 100u; i++) {
        period();
    }
    assert_true(app.tel.pos_ref < p0);
    assert_true((co.od.statusword & SW_TR) == 0u);
    for (i = 0u; i < 50000u && hd_traj_done(&app.traj) == 0; i++) {
        period();
    }
    period();
    period();
    assert_true(app.tel.pos_ref == (int64_t)(target * 2 / 5) * 256);
    assert_true((co.od.statusword & SW_TR) != 0u);
}

/* one period; the encoders read the reference minus lag (Q32.32 turns) from the next
 * period on (like period(): the stub axis follows one period late) */
static void period_lag(int64_t lag)
{
    hd_app_step(&app);
    hd_co_tick(&co, HD_CO_TICK_US);
    trk_pos = hd_app_telemetry(&app)->pos_ref - lag;
}

/* 0x6065/0x6066 following error window and time-out -> statusword bit 13 (CSP, PP);
 * 0x6067/0x6068 position window and time -> bit 10 */
static void test_following_error_and_position_window(void **st)
{
    const uint32_t per_ms = 1000u / HD_CO_TICK_US;
    uint32_t i;
    (void)st;
    assert_int_equal(co.od.following_error_window, 0xFFFFFFFFu);     /* off by default */
    assert_int_equal(co.od.position_window, 256u);                    /* 2^-16 turn */
    enable_402(8);
    period_lag(0);
    period_lag(0);
    assert_true((co.od.statusword & SW_TR) != 0u);
    assert_true((co.od.statusword & 0x2000u) == 0u);
    /* 1000 units behind, window off: no bit 13; bit 10 off (outside 256) */
    for (i = 0u; i < 3u; i++) {
        period_lag((int64_t)1000 << 8);
    }
    assert_int_equal(co.od.following_error_actual_value, 1000);
    assert_true((co.od.statusword & 0x2000u) == 0u);
    assert_true((co.od.statusword & SW_TR) == 0u);
    /* window 500, time-out 2 ms: bit 13 after 2 ms outside, not before */
    co.od.following_error_window = 500u;
    co.od.following_error_time_out = 2u;
    period_lag((int64_t)1000 << 8);                                   /* outside from here */
    for (i = 1u; i < 2u * per_ms; i++) {
        period_lag((int64_t)1000 << 8);
        assert_true((co.od.statusword & 0x2000u) == 0u);
    }
    period_lag((int64_t)1000 << 8);
    assert_true((co.od.statusword & 0x2000u) != 0u);
    /* back inside: bit 13 clears at once; bit 10 after 0x6068 = 3 ms within 256 */
    co.od.position_window_time = 3u;
    period_lag((int64_t)100 << 8);                                    /* the encoders read it next period */
    assert_true((co.od.statusword & 0x2000u) != 0u);
    period_lag((int64_t)100 << 8);                                    /* inside from here */
    assert_int_equal(co.od.following_error_actual_value, 100);
    assert_true((co.od.statusword & 0x2000u) == 0u);
    for (i = 1u; i < 3u * per_ms; i++) {
        period_lag((int64_t)100 << 8);
        assert_true((co.od.statusword & SW_TR) == 0u);
    }
    period_lag((int64_t)100 << 8);
    assert_true((co.od.statusword & SW_TR) != 0u);
    /* a wider position window takes the 1000-unit lag as reached (after its time) */
    co.od.position_window = 2000u;
    co.od.position_window_time = 0u;
    period_lag((int64_t)1000 << 8);
    period_lag((int64_t)1000 << 8);
    assert_int_equal(co.od.following_error_actual_value, 1000);
    assert_true((co.od.statusword & SW_TR) != 0u);
    /* CSV: no bit 13 (CiA 402: reserved there) */
    co.od.modes_of_operation = 9;
    for (i = 0u; i < 3u * per_ms; i++) {
        period_lag((int64_t)1000 << 8);
    }
    assert_int_equal(co.od.modes_of_operation_display, 9);
    assert_true((co.od.statusword & 0x2000u) == 0u);
}

static void test_csv_halt(void **st)
{
    const int32_t v = 429496730;                          /* 0.1 turn/s, 2^-32 turn/s */
    const int32_t dv = dv_of(app.traj_cfg.amax);
    (void)st;
    /* ramps at the profile acceleration to rest, the target velocity still set */
    (void)csv_halt_ramp(v, dv, dv, 10000u);
    cw_write(CW_ENABLE);
    period();
    assert_int_equal(app.vel_cmd, v);                     /* CSV: the host's set-point again */
}

/* 0x6081 / 0x6083 are traj_vmax / traj_amax: one value under two indexes, the parameter's
 * limits (a bad write is refused and the old value stays), and a PP move runs at them */
static void test_pp_profile_objects(void **st)
{
    const int32_t target = 1 << 22;                       /* 0.25 turn, 2^-24 turn */
    const int64_t vprof = 107374182;                      /* 0.025 turn/s (9 deg/s), 2^-32 turn/s */
    const int64_t aprof = 838861;                         /* 0.05 turn/s^2, 2^-24 turn/s^2 */
    int64_t v, old;
    int64_t vpk = 0;
    uint32_t i;
    (void)st;
    /* defaults: the parameters' */
    assert_int_equal(hd_co_get_i64(&co, 0x6081u, 0u, &v), 0u);
    assert_int_equal(v, hd_app_param_get(&app, HD_P_TRAJ_VMAX));
    assert_int_equal(hd_co_get_i64(&co, 0x6083u, 0u, &v), 0u);
    assert_int_equal(v, hd_app_param_get(&app, HD_P_TRAJ_AMAX));
    /* written under the CiA 402 index, read back under the parameter's (0x2400) */
    assert_int_equal(hd_co_set_i64(&co, 0x6081u, 0u, vprof), 0u);
    assert_int_equal(hd_co_set_i64(&co, 0x6083u, 0u, aprof), 0u);
    assert_int_equal(hd_co_get_i64(&co, 0x2400u, 1u, &v), 0u);
    assert_int_equal(v, vprof);
    assert_int_equal(hd_co_get_i64(&co, 0x2400u, 2u, &v), 0u);
    assert_int_equal(v, aprof);
    assert_int_equal(app.traj_cfg.vmax, vprof);
    assert_int_equal(app.traj_cfg.amax, aprof);
    /* out of the parameter's range: refused, old value kept */
    old = vprof;
    assert_int_equal(hd_co_set_i64(&co, 0x6081u, 0u, 0), HD_CO_AB_VALUE_LOW);
    assert_int_equal(hd_co_set_i64(&co, 0x6081u, 0u, 0x7FFFFFFF), HD_CO_AB_VALUE_HIGH);
    assert_int_equal(hd_co_get_i64(&co, 0x6081u, 0u, &v), 0u);
    assert_int_equal(v, old);
    /* a PP move cruises at the profile velocity, reached after vprof / aprof s */
    enable_402(HD_CO402_MODE_PP);
    for (i = 0u; i < 8u; i++) {
        period();
    }
    pp_setpoint(target, 0u);
    for (i = 0u; i < 20000u; i++) {                       /* 2 s: 0.5 s ramp, then cruise */
        period();
        /* vel is the generator's 2^-48 state rounded to 2^-32 turn/s: 1 LSB of rounding */
        assert_true(app.traj.vel <= vprof + 1);
        if (app.traj.vel > vpk) {
            vpk = app.traj.vel;
        }
        if (i == 2000u) {                                 /* 0.2 s: still ramping at aprof */
            assert_true(app.traj.vel < vprof / 2);
        }
    }
    assert_true(vpk >= vprof - 1 && vpk <= vprof + 1);
    assert_true((co.od.statusword & SW_TR) == 0u);        /* 0.05 turn of 0.25: still moving */
}

/* 0x605D halt option 2 and 0x605A quick stop: the stops ramp at the quick-stop deceleration
 * 0x6085 (option 1: the profile deceleration traj_amax); 0x605D 3/4 are refused */
static void test_stop_options(void **st)
{
    const int32_t v = 429496730;                          /* 0.1 turn/s, 2^-32 turn/s */
    int64_t qs = 0, opt = 0;
    int32_t dq, da, prev;
    uint32_t i, n_ramp = 0u;
    (void)st;
    assert_int_equal(hd_co_get_i64(&co, 0x605Du, 0u, &opt), 0u);
    assert_int_equal(opt, 1);                             /* default: profile deceleration */
    assert_int_equal(hd_co_set_i64(&co, 0x605Du, 0u, 3), HD_CO_AB_VALUE_HIGH);
    assert_int_equal(hd_co_set_i64(&co, 0x605Du, 0u, 0), HD_CO_AB_VALUE_LOW);
    assert_int_equal(hd_co_get_i64(&co, 0x605Du, 0u, &opt), 0u);
    assert_int_equal(opt, 1);                             /* kept */
    assert_int_equal(hd_co_get_i64(&co, 0x6085u, 0u, &qs), 0u);
    dq = dv_of(qs);
    da = dv_of(app.traj_cfg.amax);
    assert_true(dq > da);                                 /* the default 0x6085 is the steeper one */

    /* CSV halt with option 2: ramps at 0x6085, i.e. faster than the profile would */
    assert_int_equal(hd_co_set_i64(&co, 0x605Du, 0u, 2), 0u);
    n_ramp = csv_halt_ramp(v, dq, da, 5000u);             /* steps steeper than traj_amax allows */
    assert_true(n_ramp > 10u);
    assert_true((uint32_t)((v + dq - 1) / dq) <= 5000u);

    /* quick stop (controlword bit 2 = 0) from CSV at v: the command ramps from the measured
     * speed at 0x6085 (0x605A default 2), never reverses */
    cw_write(CW_ENABLE);
    for (i = 0u; i < 2000u; i++) {
        period();
    }
    assert_int_equal(app.vel_cmd, v);
    cw_write(0x000Bu);                                    /* enable operation, quick stop bit clear */
    period();
    assert_int_equal(hd_co402_state(&ac.p402), HD_CO402_QUICK_STOP);
    prev = app.vel_cmd;
    assert_true(prev > 0);                                /* a ramp, not a step to 0 */
    for (i = 0u; i < 5000u && app.vel_cmd > 0; i++) {
        period();
        assert_true(app.vel_cmd >= 0);
        assert_true(prev - app.vel_cmd <= dq);
        prev = app.vel_cmd;
    }
    assert_int_equal(app.vel_cmd, 0);
    assert_true(i + 1u >= (uint32_t)(v / dq));             /* as long as the ramp takes */
    for (i = 0u; i < 20u; i++) {
        period();
    }
    assert_int_equal(hd_co402_state(&ac.p402), HD_CO402_SO_DISABLED); /* then switch-on disabled */
}

/* PP halt with 0x605D = 2: the move ramps to rest at 0x6085, stopping in v0^2 / (2 qs) */
static void test_pp_halt_quick_stop_decel(void **st)
{
    const int32_t target = 1 << 22;                       /* 0.25 turn, 2^-24 turn */
    int64_t qs = 0, v0, p0, prev, stop, lim;
    int32_t dq, da, vprev;
    uint32_t i, n_steep = 0u;
    (void)st;
    assert_int_equal(hd_co_set_i64(&co, 0x605Du, 0u, 2), 0u);
    assert_int_equal(hd_co_get_i64(&co, 0x6085u, 0u, &qs), 0u);
    dq = dv_of(qs);
    da = dv_of(app.traj_cfg.amax);
    enable_402(HD_CO402_MODE_PP);
    for (i = 0u; i < 8u; i++) {
        period();
    }
    pp_setpoint(target, 0u);
    for (i = 0u; i < 10000u; i++) {                       /* 1 s: cruising at traj_vmax */
        period();
    }
    v0 = app.traj.vel;
    p0 = app.tel.pos_ref;
    prev = p0;
    assert_true(v0 > app.traj_cfg.vmax / 2);
    cw_write(CW_ENABLE | CW_HALT);
    vprev = (int32_t)v0;
    for (i = 0u; i < 20000u; i++) {
        period();
        assert_true(app.tel.pos_ref >= prev);
        assert_true((int64_t)vprev - app.traj.vel <= dq);
        if ((int64_t)vprev - app.traj.vel > da) {
            n_steep++;
        }
        vprev = app.traj.vel;
        prev = app.tel.pos_ref;
    }
    assert_int_equal(app.traj.vel, 0);
    assert_true(n_steep > 100u);                          /* at 0x6085, not at traj_amax */
    stop = app.tel.pos_ref - p0;
    lim = v0 * v0 / (2 * qs) / 256;
    assert_true(stop <= lim + 2 * v0 / HD_LOOP_HZ);
    assert_true(stop >= lim - 2 * v0 / HD_LOOP_HZ);
}


/* ---- table commit interlock ------------------------------------------------------ */

static void sdo_frame(const uint8_t d[8])
{
    hd_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x601u;
    f.dlc = 8u;
    memcpy(f.data, d, 8u);
    memset(&last_sdo, 0, sizeof last_sdo);
    hd_co_process(&co, &f);
}

static uint32_t last_abort_code(void)
{
    assert_int_equal(last_sdo.data[0], 0x80);
    return (uint32_t)last_sdo.data[4] | ((uint32_t)last_sdo.data[5] << 8) |
           ((uint32_t)last_sdo.data[6] << 16) | ((uint32_t)last_sdo.data[7] << 24);
}

/* segmented download of img[0..len) to 0x5100:1, segments [from, to) of 7 bytes */
static void seg_initiate(uint32_t len)
{
    const uint8_t d[8] = {0x21, 0x00, 0x51, 0x01, (uint8_t)len, (uint8_t)(len >> 8), 0, 0};
    sdo_frame(d);
    assert_int_equal(last_sdo.data[0], 0x60);
}

static void seg_send(uint32_t len, uint32_t seg, uint8_t toggle)
{
    uint8_t d[8] = {0};
    const uint32_t off = 7u * seg;
    const uint32_t n = (len - off < 7u) ? len - off : 7u;
    d[0] = (uint8_t)((toggle << 4) | ((7u - n) << 1) | (off + n >= len ? 1u : 0u));
    memcpy(&d[1], img + off, n);
    sdo_frame(d);
}

/* A table download that is running when the power stage comes on never lands: enabling
 * aborts it (0x08000022 to the client, staging discarded), and a commit with the power
 * stage on (enabled by a path that did not abort the transfer) is refused with 0x08000022. */
static void test_table_commit_interlock(void **st)
{
    static uint8_t back[sizeof img], good[sizeof img];
    (void)st;
    uint32_t len = make_table(8u, 3u, 200);
    assert_int_equal(download(HD_APP_CO_DOM_PREISACH, img, len), 0);
    memcpy(good, img, len);
    assert_int_equal(app.cb.table.version, 3);

    /* commit with the power stage on: refused, the old table stays */
    len = make_table(8u, 4u, 100);
    const hd_co_app_if_t *a = &co.app;
    assert_int_equal(a->domain_write_begin(a->ctx, HD_APP_CO_DOM_PREISACH, len), 0);
    assert_int_equal(a->domain_write(a->ctx, HD_APP_CO_DOM_PREISACH, 0u, img, len), 0);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_VELOCITY), 0);
    hd_app_step(&app);
    assert_int_equal(a->domain_write_end(a->ctx, HD_APP_CO_DOM_PREISACH, len, true), HD_CO_AB_STATE);
    assert_int_equal(app.cb.table.version, 3);
    assert_int_equal(upload(HD_APP_CO_DOM_PREISACH, back, sizeof back), len);
    assert_memory_equal(back, good, len);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_OFF), 0);
    hd_app_step(&app);

    /* over SDO: a segmented download, the drive enabled half-way (CiA 402) */
    seg_initiate(len);
    seg_send(len, 0u, 0u);
    assert_int_equal(last_sdo.data[0], 0x20);
    seg_send(len, 1u, 1u);
    assert_int_equal(last_sdo.data[0], 0x30);
    memset(&last_sdo, 0, sizeof last_sdo);
    enable_402(HD_CO402_MODE_CSV);
    assert_int_equal(last_abort_code(), HD_CO_AB_STATE);   /* the client is told at once */
    assert_int_equal(ac.stage_dom, 0u);                     /* staging discarded */
    /* the rest of the segments belong to no transfer */
    for (uint32_t seg = 2u, t = 0u; 7u * seg < len; seg++, t ^= 1u) {
        seg_send(len, seg, (uint8_t)t);
        assert_int_equal(last_abort_code(), HD_CO_AB_CMD);
    }
    assert_int_equal(app.cb.table.version, 3);
    /* with the power stage off again the same table goes in */
    cw_write(0x06u);
    period();
    assert_int_equal(app.tel.mode, HD_MODE_OFF);
    seg_initiate(len);
    for (uint32_t seg = 0u, t = 0u; 7u * seg < len; seg++, t ^= 1u) {
        seg_send(len, seg, (uint8_t)t);
        assert_int_equal(last_sdo.data[0] & 0xE0, 0x20);
    }
    assert_int_equal(app.cb.table.version, 4);
}

/* A table whose CRC-32 trailer does not match is refused at the commit of the transfer, and
 * the abort names the transfer's object (CiA 301: the abort carries the multiplexer; a master
 * that matches aborts to its transfer would otherwise not see its answer). */
static void test_refused_table_commit_names_its_object(void **st)
{
    (void)st;
    uint32_t len = make_table(8u, 3u, 200);
    img[len - 1u] ^= 0x40u;                                   /* CRC-32 trailer broken */
    seg_initiate(len);
    for (uint32_t seg = 0u, t = 0u; 7u * seg < len; seg++, t ^= 1u) {
        seg_send(len, seg, (uint8_t)t);
    }
    assert_int_not_equal(last_abort_code(), 0u);
    assert_int_equal(last_sdo.data[1], 0x00);                 /* index 0x5100 */
    assert_int_equal(last_sdo.data[2], 0x51);
    assert_int_equal(last_sdo.data[3], 0x01);                 /* sub 1 */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_preisach_table, setup),
        cmocka_unit_test_setup(test_store_objects, setup),
        cmocka_unit_test_setup(test_stored_image_with_read_only_rpdo_mapping_refused, setup),
        cmocka_unit_test_setup(test_refused_table_commit_names_its_object, setup),
        cmocka_unit_test_setup(test_stored_image_with_restricted_cob_id_refused, setup),
        cmocka_unit_test_setup(test_identical_save_erases_nothing, setup),
        cmocka_unit_test_setup(test_save_rate_limit, setup),
        cmocka_unit_test_setup(test_group_and_interlock, setup),
        cmocka_unit_test_setup(test_fb_config_interlock, setup),
        cmocka_unit_test_setup(test_pp_halt, setup),
        cmocka_unit_test_setup(test_csv_halt, setup),
        cmocka_unit_test_setup(test_following_error_and_position_window, setup),
        cmocka_unit_test_setup(test_pp_profile_objects, setup),
        cmocka_unit_test_setup(test_stop_options, setup),
        cmocka_unit_test_setup(test_pp_halt_quick_stop_decel, setup),
        cmocka_unit_test_setup(test_table_commit_interlock, setup),
        cmocka_unit_test_setup(test_fric_est_common_mode_objects, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
