/*
 * test_canopen.c - CiA 301/402 device stack (firmware/canopen) against a
 * scripted master: exact frames in, exact frames out.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "hd_co.h"
#include "hd_co_402.h"
#include "hd_param_table.h"


#define NODE 5u
#define TXQ 512u
#define DOM_CAP 70000u

typedef struct {
    hd_can_frame_t tx[TXQ];
    uint32_t ntx, rd;
    bool tx_full;
    int32_t param[HD_PARAM_COUNT];
    uint8_t dom[DOM_CAP];        /* committed table (payload + CRC-32) */
    uint32_t dom_len;
    uint8_t stage[DOM_CAP];
    uint32_t stage_len;
    uint32_t stores, restores, comm_faults, fault_resets;
    int8_t mode;
    bool on;
    hd_co_setpoint_t sp;
    uint32_t pp_news;            /* set-points handed over with pp_new */
    uint16_t app_fault;
    uint32_t tick;
    uint32_t filtered;           /* accesses refused by t_filter */
    bool chatter;                /* internal limit on and off at loop rate (a hunting axis) */
} ctx_t;

static bool t_send(void *c, const hd_can_frame_t *f)
{
    ctx_t *x = c;
    if (x->tx_full || x->ntx >= TXQ) {
        return false;
    }
    x->tx[x->ntx++] = *f;
    return true;
}
static int32_t t_pget(void *c, uint16_t id) { return ((ctx_t *)c)->param[id]; }
static uint32_t t_pset(void *c, uint16_t id, int32_t raw)
{
    ((ctx_t *)c)->param[id] = raw;
    return 0u;
}
static uint32_t t_dsize(void *c, uint16_t dom, uint32_t *size)
{
    (void)dom;
    *size = ((ctx_t *)c)->dom_len;
    return 0u;
}
static uint32_t t_dread(void *c, uint16_t dom, uint32_t off, uint8_t *buf, uint32_t len)
{
    ctx_t *x = c;
    (void)dom;
    if (off + len > x->dom_len) {
        return HD_CO_AB_GENERAL;
    }
    memcpy(buf, &x->dom[off], len);
    return 0u;
}
static uint32_t t_dbegin(void *c, uint16_t dom, uint32_t size)
{
    (void)dom;
    if (size > DOM_CAP) {
        return HD_CO_AB_LEN_HIGH;
    }
    ((ctx_t *)c)->stage_len = 0u;
    return 0u;
}
static uint32_t t_dwrite(void *c, uint16_t dom, uint32_t off, const uint8_t *buf, uint32_t len)
{
    ctx_t *x = c;
    (void)dom;
    if (off + len > DOM_CAP) {
        return HD_CO_AB_LEN_HIGH;
    }
    memcpy(&x->stage[off], buf, len);
    x->stage_len = off + len;
    return 0u;
}
static uint32_t t_dend(void *c, uint16_t dom, uint32_t total, bool complete)
{
    ctx_t *x = c;
    (void)dom;
    if (!complete) {
        return 0u;
    }
    if (total < 4u) {
        return HD_CO_AB_STORE;
    }
    uint32_t crc = hd_crc32(0u, x->stage, total - 4u);
    uint32_t got = (uint32_t)x->stage[total - 4u] | ((uint32_t)x->stage[total - 3u] << 8) |
                   ((uint32_t)x->stage[total - 2u] << 16) | ((uint32_t)x->stage[total - 1u] << 24);
    if (crc != got) {
        return HD_CO_AB_STORE;
    }
    memcpy(x->dom, x->stage, total);
    x->dom_len = total;
    return 0u;
}
static uint32_t t_store(void *c) { ((ctx_t *)c)->stores++; return 0u; }
static uint32_t t_restore(void *c) { ((ctx_t *)c)->restores++; return 0u; }
static uint32_t t_enable(void *c, int8_t mode, bool on)
{
    ctx_t *x = c;
    if (on && x->app_fault != 0u) {
        return 1u;
    }
    x->mode = mode;
    x->on = on;
    return 0u;
}
static void t_setpoint(void *c, const hd_co_setpoint_t *sp)
{
    ctx_t *x = c;
    x->sp = *sp;
    x->pp_news += sp->pp_new;
}
static void t_actual(void *c, hd_co_actual_t *a)
{
    ctx_t *x = c;
    memset(a, 0, sizeof *a);
    a->tick = x->tick;
    a->load_angle = (int64_t)x->tick << 16;
    a->power_enabled = x->on ? 1u : 0u;
    a->standstill = 1u;
    a->fault_code = x->app_fault;
    a->fault_emcy = x->app_fault != 0u ? 0x8611u : 0u;
    /* irregular on/off (a multiplicative hash of the tick), so no inhibit time samples one phase only */
    a->internal_limit = (x->chatter && ((x->tick * 2654435761u) >> 31) != 0u) ? 1u : 0u;
}
static void t_fault_reset(void *c) { ((ctx_t *)c)->fault_resets++; ((ctx_t *)c)->app_fault = 0u; }
static void t_comm_fault(void *c, uint16_t code) { (void)code; ((ctx_t *)c)->comm_faults++; }

static ctx_t X;
static hd_co_t CO;
static hd_co402_t P402;     /* the CiA 402 profile on top of CO */
static bool no_profile;     /* setup_dev: a plain CiA 301 device (no profile plugged in) */

/* a device profile without the manufacturer range (the virtual drive's generic profile) */
static uint32_t t_filter(void *c, uint16_t index, uint8_t sub)
{
    (void)sub;
    if (index >= 0x2000u && index <= 0x5FFFu) {
        ((ctx_t *)c)->filtered++;
        return HD_CO_AB_NO_OBJECT;
    }
    return 0u;
}

static void setup_dev(void)
{
    memset(&X, 0, sizeof X);
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) {
        X.param[i] = hd_param_table[i].def;
    }
    hd_co_app_if_t ifc;
    memset(&ifc, 0, sizeof ifc);
    ifc.ctx = &X;
    ifc.send = t_send;
    ifc.param_get = t_pget;
    ifc.param_set = t_pset;
    ifc.domain_size = t_dsize;
    ifc.domain_read = t_dread;
    ifc.domain_write_begin = t_dbegin;
    ifc.domain_write = t_dwrite;
    ifc.domain_write_end = t_dend;
    ifc.store = t_store;
    ifc.restore = t_restore;
    ifc.drive_enable = t_enable;
    ifc.drive_setpoint = t_setpoint;
    ifc.drive_actual = t_actual;
    ifc.drive_fault_reset = t_fault_reset;
    ifc.drive_comm_fault = t_comm_fault;
    if (!no_profile) {
        hd_co402_use(&P402, &ifc);
    }
    hd_co_init(&CO, NODE, &ifc);
}

static void rx(uint32_t id, uint8_t dlc, const uint8_t *d)
{
    hd_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    if (dlc > 0u) {
        memcpy(f.data, d, dlc);
    }
    hd_co_process(&CO, &f);
}

static void tick(uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        X.tick++;
        hd_co_tick(&CO, HD_CO_TICK_US);
    }
}

/* next frame sent by the device, or NULL */
static const hd_can_frame_t *next_tx(void)
{
    return X.rd < X.ntx ? &X.tx[X.rd++] : NULL;
}

static void flush(void) { X.rd = X.ntx = 0u; }

/* next SDO response */
static const hd_can_frame_t *sdo_rsp(void)
{
    const hd_can_frame_t *f;
    while ((f = next_tx()) != NULL) {
        if (f->id == 0x580u + NODE) {
            return f;
        }
    }
    return NULL;
}

static uint32_t u32le(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void sdo_req(uint8_t cmd, uint16_t idx, uint8_t sub, uint32_t v)
{
    uint8_t d[8] = {cmd, (uint8_t)idx, (uint8_t)(idx >> 8), sub, (uint8_t)v, (uint8_t)(v >> 8),
                    (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    rx(0x600u + NODE, 8u, d);
}

/* expedited write of n bytes; returns 0 or the abort code */
static uint32_t sdo_write(uint16_t idx, uint8_t sub, uint32_t v, uint32_t n)
{
    flush();
    sdo_req((uint8_t)(0x23u | ((4u - n) << 2)), idx, sub, v);
    const hd_can_frame_t *f = sdo_rsp();
    assert_non_null(f);
    if (f->data[0] == 0x80u) {
        return u32le(&f->data[4]);
    }
    assert_int_equal(f->data[0], 0x60);
    return 0u;
}

/* expedited read; returns 0 or the abort code */
static uint32_t sdo_read(uint16_t idx, uint8_t sub, uint32_t *v)
{
    flush();
    sdo_req(0x40u, idx, sub, 0u);
    const hd_can_frame_t *f = sdo_rsp();
    assert_non_null(f);
    if (f->data[0] == 0x80u) {
        return u32le(&f->data[4]);
    }
    *v = u32le(&f->data[4]);
    return 0u;
}

/* ---- tests ------------------------------------------------------------------ */

static void test_bootup_nmt_heartbeat(void **st)
{
    (void)st;
    setup_dev();
    const hd_can_frame_t *f = next_tx();
    assert_non_null(f);
    assert_int_equal(f->id, 0x700u + NODE);
    assert_int_equal(f->dlc, 1);
    assert_int_equal(f->data[0], 0);
    assert_int_equal(CO.nmt, HD_CO_NMT_PREOP);
    flush();
    tick(1000);                                   /* 100 ms = one heartbeat period */
    uint32_t hb = 0;
    for (uint32_t i = 0; i < X.ntx; i++) {
        if (X.tx[i].id == 0x700u + NODE) {
            hb++;
            assert_int_equal(X.tx[i].data[0], 0x7F);
        }
    }
    assert_int_equal(hb, 1);
    uint8_t start[2] = {0x01, NODE};
    rx(0, 2, start);
    assert_int_equal(CO.nmt, HD_CO_NMT_OP);
    uint8_t bad[3] = {0x02, 0, 0};               /* wrong DLC: ignored */
    rx(0, 3, bad);
    assert_int_equal(CO.nmt, HD_CO_NMT_OP);
    uint8_t other[2] = {0x02, NODE + 1u};        /* other node */
    rx(0, 2, other);
    assert_int_equal(CO.nmt, HD_CO_NMT_OP);
    uint8_t stop[2] = {0x02, 0};                 /* broadcast */
    rx(0, 2, stop);
    assert_int_equal(CO.nmt, HD_CO_NMT_STOPPED);
    flush();
    sdo_req(0x40u, 0x1000u, 0u, 0u);             /* no SDO while stopped */
    assert_null(sdo_rsp());
    uint8_t rc[2] = {0x82, NODE};
    rx(0, 2, rc);
    assert_int_equal(CO.nmt, HD_CO_NMT_PREOP);
}

static void test_sdo_expedited_and_aborts(void **st)
{
    (void)st;
    setup_dev();
    uint32_t v = 0;
    assert_int_equal(sdo_read(0x1000u, 0u, &v), 0);
    assert_int_equal(v, 0x00020192u);
    assert_int_equal(sdo_read(0x1018u, 1u, &v), 0);
    assert_int_equal(v, HD_CO_VENDOR_ID);
    assert_int_equal(sdo_read(0x1200u, 1u, &v), 0);
    assert_int_equal(v, 0x600u + NODE);
    assert_int_equal(sdo_read(0x1234u, 0u, &v), HD_CO_AB_NO_OBJECT);
    assert_int_equal(sdo_read(0x1018u, 9u, &v), HD_CO_AB_NO_SUB);
    assert_int_equal(sdo_write(0x1000u, 0u, 1u, 4u), HD_CO_AB_READONLY);
    assert_int_equal(sdo_read(0x5F20u, 10u, &v), HD_CO_AB_WRITEONLY);
    assert_int_equal(sdo_write(0x5F20u, 8u, 5u, 4u), HD_CO_AB_VALUE_LOW);
    assert_int_equal(sdo_write(0x5F20u, 8u, 2000000u, 4u), HD_CO_AB_VALUE_HIGH);
    assert_int_equal(sdo_write(0x5F20u, 8u, 1234u, 4u), 0);
    assert_int_equal(sdo_read(0x5F20u, 8u, &v), 0);
    assert_int_equal(v, 1234u);
    assert_int_equal(sdo_write(0x5F20u, 8u, 12u, 2u), HD_CO_AB_LEN_LOW);
    assert_int_equal(sdo_write(0x5F20u, 7u, 12u, 4u), HD_CO_AB_LEN_HIGH);
    assert_int_equal(sdo_write(0x5F20u, 1u, 2u, 1u), HD_CO_AB_VALUE);     /* bool */
    assert_int_equal(sdo_write(0x6060u, 0u, 7u, 1u), HD_CO_AB_VALUE);     /* unsupported mode */
    assert_int_equal(sdo_write(0x5F20u, 2u, (uint32_t)(uint8_t)-50, 1u), 0);
    assert_int_equal(sdo_read(0x5F20u, 2u, &v), 0);
    assert_int_equal((int8_t)v, -50);
    /* drive parameter through the app, range from the generated table */
    assert_int_equal(sdo_write(0x2000u, 1u, 50u, 4u), 0);
    assert_int_equal(X.param[HD_P_GEAR_RATIO], 50);
    assert_int_equal(sdo_write(0x2000u, 1u, 5000u, 4u), HD_CO_AB_VALUE_HIGH);
    assert_int_equal(X.param[HD_P_GEAR_RATIO], 50);
    /* store / restore signatures */
    assert_int_equal(sdo_write(0x1010u, 1u, 0x12345678u, 4u), HD_CO_AB_STORE);
    assert_int_equal(sdo_write(0x1010u, 1u, 0x65766173u, 4u), 0);
    assert_int_equal(X.stores, 1);
    assert_int_equal(sdo_write(0x1011u, 1u, 0x64616F6Cu, 4u), 0);
    assert_int_equal(X.restores, 1);
    /* unknown command specifier, segment outside a transfer */
    flush();
    sdo_req(0xE0u, 0x1000u, 0u, 0u);
    const hd_can_frame_t *f = sdo_rsp();
    assert_non_null(f);
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_CMD);
    /* a short SDO frame is ignored */
    flush();
    uint8_t d[4] = {0x40, 0x00, 0x10, 0x00};
    rx(0x600u + NODE, 4u, d);
    assert_null(sdo_rsp());
}

static void test_sdo_segmented(void **st)
{
    (void)st;
    setup_dev();
    /* upload the device name */
    flush();
    sdo_req(0x40u, 0x1008u, 0u, 0u);
    const hd_can_frame_t *f = sdo_rsp();
    assert_int_equal(f->data[0], 0x41);
    uint32_t size = u32le(&f->data[4]);
    char name[64] = {0};
    uint32_t got = 0;
    uint8_t t = 0;
    while (got < size) {
        sdo_req((uint8_t)(0x60u | (t << 4)), 0, 0, 0);
        f = sdo_rsp();
        assert_non_null(f);
        assert_int_equal(f->data[0] & 0x10, t << 4);
        uint32_t n = 7u - ((f->data[0] >> 1) & 7u);
        memcpy(&name[got], &f->data[1], n);
        got += n;
        t ^= 1u;
        if (f->data[0] & 1u) {
            break;
        }
    }
    assert_string_equal(name, "hdservo harmonic-drive servo");
    /* segmented download of an int64 */
    flush();
    sdo_req(0x21u, 0x5F20u, 5u, 8u);
    f = sdo_rsp();
    assert_int_equal(f->data[0], 0x60);
    uint8_t s1[8] = {0x00, 1, 2, 3, 4, 5, 6, 7};
    rx(0x600u + NODE, 8, s1);
    f = sdo_rsp();
    assert_int_equal(f->data[0], 0x20);
    uint8_t s2[8] = {0x10 | (6u << 1) | 1u, 0x88, 0, 0, 0, 0, 0, 0};
    rx(0x600u + NODE, 8, s2);
    f = sdo_rsp();
    assert_int_equal(f->data[0], 0x30);
    assert_int_equal((uint64_t)CO.od.sdo_test_test_i64, 0x8807060504030201ull);
    /* toggle error */
    flush();
    sdo_req(0x21u, 0x5F20u, 5u, 8u);
    (void)sdo_rsp();
    uint8_t bad[8] = {0x10, 1, 2, 3, 4, 5, 6, 7};
    rx(0x600u + NODE, 8, bad);
    f = sdo_rsp();
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_TOGGLE);
    /* time-out */
    flush();
    sdo_req(0x21u, 0x5F20u, 5u, 8u);
    (void)sdo_rsp();
    tick(HD_CO_SDO_TIMEOUT_MS * 10u + 20u);
    f = sdo_rsp();
    assert_non_null(f);
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_TIMEOUT);
    /* indicated size mismatch */
    flush();
    sdo_req(0x21u, 0x5F20u, 5u, 9u);
    f = sdo_rsp();
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_LEN_HIGH);
}

/* block download of n bytes (with CRC unless bad_crc) to 0x5F20:11; returns abort or 0 */
static uint32_t block_download(const uint8_t *data, uint32_t n, bool bad_crc)
{
    flush();
    sdo_req(0xC6u, 0x5F20u, 11u, n);
    const hd_can_frame_t *f = sdo_rsp();
    if (f->data[0] == 0x80u) {
        return u32le(&f->data[4]);
    }
    assert_int_equal(f->data[0] & 0xE3, 0xA0);
    uint32_t blk = f->data[4];
    uint32_t off = 0, seq = 0;
    uint16_t crc = hd_co_crc16(0, data, n);
    uint32_t last_n = 0;
    while (off < n) {
        uint8_t d[8] = {0};
        uint32_t k = n - off < 7u ? n - off : 7u;
        memcpy(&d[1], &data[off], k);
        off += k;
        seq++;
        d[0] = (uint8_t)(seq | (off >= n ? 0x80u : 0u));
        rx(0x600u + NODE, 8, d);
        last_n = k;
        if (seq == blk || off >= n) {
            f = sdo_rsp();
            assert_non_null(f);
            if (f->data[0] == 0x80u) {
                return u32le(&f->data[4]);
            }
            assert_int_equal(f->data[0], 0xA2);
            assert_int_equal(f->data[1], seq);
            blk = f->data[2];
            seq = 0;
            flush();
        }
    }
    if (bad_crc) {
        crc ^= 1u;
    }
    uint8_t e[8] = {(uint8_t)(0xC1u | ((7u - last_n) << 2)), (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0};
    rx(0x600u + NODE, 8, e);
    f = sdo_rsp();
    assert_non_null(f);
    if (f->data[0] == 0x80u) {
        return u32le(&f->data[4]);
    }
    assert_int_equal(f->data[0], 0xA1);
    return 0u;
}

/* block upload of 0x5F20:11 into out; returns byte count */
static uint32_t block_upload(uint8_t *out, uint32_t cap)
{
    flush();
    uint8_t d[8] = {0xA4, 0x20, 0x5F, 11, 127, 0, 0, 0};
    rx(0x600u + NODE, 8, d);
    const hd_can_frame_t *f = sdo_rsp();
    assert_int_equal(f->data[0], 0xC6);
    uint32_t size = u32le(&f->data[4]);
    assert_true(size <= cap);
    flush();
    uint8_t s[8] = {0xA3, 0, 0, 0, 0, 0, 0, 0};
    rx(0x600u + NODE, 8, s);
    uint32_t got = 0;
    uint16_t crc = 0;
    for (;;) {
        tick(1);   /* lets the pump refill */
        uint32_t seq = 0;
        bool last = false;
        while ((f = sdo_rsp()) != NULL) {
            seq = f->data[0] & 0x7Fu;
            last = (f->data[0] & 0x80u) != 0u;
            uint32_t k = size - got < 7u ? size - got : 7u;
            memcpy(&out[got], &f->data[1], k);
            crc = hd_co_crc16(crc, &f->data[1], k);
            got += k;
            if (last || seq == 127u) {
                break;
            }
        }
        if (seq == 0u) {
            continue;
        }
        flush();
        uint8_t a[8] = {0xA2, (uint8_t)seq, 127, 0, 0, 0, 0, 0};
        rx(0x600u + NODE, 8, a);
        if (last) {
            break;
        }
    }
    f = sdo_rsp();
    assert_non_null(f);
    assert_int_equal(f->data[0] & 0xE3, 0xC1);
    uint32_t n = (f->data[0] >> 2) & 7u;
    assert_int_equal(n, (7u - size % 7u) % 7u);
    assert_int_equal(f->data[1] | (f->data[2] << 8), crc);
    uint8_t e[8] = {0xA1, 0, 0, 0, 0, 0, 0, 0};
    rx(0x600u + NODE, 8, e);
    return got;
}

static uint8_t BUF[DOM_CAP], BUF2[DOM_CAP];

static void make_table(uint8_t *b, uint32_t n, uint32_t seed)
{
    for (uint32_t i = 0; i < n - 4u; i++) {
        seed = seed * 1103515245u + 12345u;
        b[i] = (uint8_t)(seed >> 16);
    }
    uint32_t c = hd_crc32(0u, b, n - 4u);
    b[n - 4u] = (uint8_t)c;
    b[n - 3u] = (uint8_t)(c >> 8);
    b[n - 2u] = (uint8_t)(c >> 16);
    b[n - 1u] = (uint8_t)(c >> 24);
}

static void test_sdo_block_domain(void **st)
{
    (void)st;
    setup_dev();
    const uint32_t n = 65536u;
    make_table(BUF, n, 1u);
    assert_int_equal(block_download(BUF, n, false), 0);
    assert_int_equal(X.dom_len, n);
    assert_memory_equal(X.dom, BUF, n);
    memset(BUF2, 0, n);
    assert_int_equal(block_upload(BUF2, sizeof BUF2), n);
    assert_memory_equal(BUF2, BUF, n);
    /* transfer CRC wrong: abort, old table stays */
    uint8_t other[1003];
    make_table(other, sizeof other, 7u);
    assert_int_equal(block_download(other, sizeof other, true), HD_CO_AB_CRC);
    assert_int_equal(X.dom_len, n);
    /* table's own CRC-32 wrong: refused, old table stays */
    other[10] ^= 0x55u;
    assert_int_equal(block_download(other, sizeof other, false), HD_CO_AB_STORE);
    assert_int_equal(X.dom_len, n);
    assert_memory_equal(X.dom, BUF, n);
    /* invalid sequence number 0 and invalid block size */
    flush();
    sdo_req(0xC6u, 0x5F20u, 11u, 100u);
    (void)sdo_rsp();
    uint8_t z[8] = {0x00, 1, 2, 3, 4, 5, 6, 7};
    rx(0x600u + NODE, 8, z);
    const hd_can_frame_t *f = sdo_rsp();
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_SEQNO);
    flush();
    uint8_t d[8] = {0xA4, 0x20, 0x5F, 11, 0, 0, 0, 0};
    rx(0x600u + NODE, 8, d);
    f = sdo_rsp();
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_BLKSIZE);
    /* a small table (odd length) through segmented upload */
    make_table(other, 20u, 3u);
    assert_int_equal(block_download(other, 20u, false), 0);
    assert_int_equal(block_upload(BUF2, sizeof BUF2), 20u);
    assert_memory_equal(BUF2, other, 20u);
}

static uint16_t statusword(void) { return CO.od.statusword; }

static void cw(uint16_t v)
{
    assert_int_equal(sdo_write(0x6040u, 0u, v, 2u), 0);
    tick(1);
}

static void test_402_state_machine(void **st)
{
    (void)st;
    setup_dev();
    tick(1);
    assert_int_equal(statusword() & 0x4F, 0x40);            /* switch on disabled */
    assert_int_equal(sdo_write(0x6060u, 0u, 8u, 1u), 0);
    cw(0x06);
    assert_int_equal(statusword() & 0x6F, 0x21);
    cw(0x07);
    assert_int_equal(statusword() & 0x6F, 0x23);
    assert_false(X.on);
    cw(0x0F);
    assert_int_equal(statusword() & 0x6F, 0x27);
    assert_true(X.on);
    assert_int_equal(X.mode, 8);
    assert_int_equal(CO.od.modes_of_operation_display, 8);
    assert_int_equal(sdo_write(0x607Au, 0u, 123456u, 4u), 0);
    tick(1);
    assert_int_equal(X.sp.target_position, 123456);
    assert_int_equal(X.sp.mode, 8);
    /* quick stop -> quick stop active -> (standstill) switch on disabled */
    cw(0x02);
    assert_int_equal(statusword() & 0x6F, 0x07);
    tick(20);
    assert_int_equal(statusword() & 0x4F, 0x40);
    assert_false(X.on);
    /* back to operation enabled, then an app fault */
    cw(0x06);
    cw(0x0F);
    assert_int_equal(statusword() & 0x6F, 0x27);
    flush();
    X.app_fault = 4u;
    tick(2);
    assert_int_equal(statusword() & 0x4F, 0x08);
    assert_false(X.on);
    const hd_can_frame_t *f;
    bool emcy = false;
    for (uint32_t i = 0; i < X.ntx; i++) {
        f = &X.tx[i];
        if (f->id == 0x80u + NODE && f->data[0] == 0x11 && f->data[1] == 0x86) {
            emcy = true;
        }
    }
    assert_true(emcy);
    uint32_t v = 0;
    assert_int_equal(sdo_read(0x603Fu, 0u, &v), 0);
    assert_int_equal(v, 0x8611u);
    assert_int_equal(sdo_read(0x1003u, 0u, &v), 0);
    assert_int_equal(v, 1u);
    assert_int_equal(sdo_read(0x1003u, 1u, &v), 0);
    assert_int_equal(v, 0x8611u);
    /* fault reset (rising edge of bit 7) */
    cw(0x00);
    cw(0x80);
    tick(1);
    assert_int_equal(X.fault_resets, 1);
    assert_int_equal(statusword() & 0x4F, 0x40);
    assert_int_equal(CO.od.error_register, 0);
    /* clear the history */
    assert_int_equal(sdo_write(0x1003u, 0u, 0u, 1u), 0);
    assert_int_equal(sdo_read(0x1003u, 0u, &v), 0);
    assert_int_equal(v, 0u);
}

/* CiA 402 profile position: the new-set-point edge (controlword bit 4) is taken once per
 * rising edge, even when the host sets and clears the bit within one control period
 * (the virtual drive's fast pacing, or two RPDOs in a row); an edge written while the
 * drive is not in OPERATION ENABLED never starts a move later. */
static void test_402_new_setpoint_edge_latched_at_write(void **st)
{
    (void)st;
    setup_dev();
    tick(1);
    assert_int_equal(sdo_write(0x6060u, 0u, 1u, 1u), 0);       /* profile position */
    cw(0x06);
    cw(0x0F);
    assert_int_equal(statusword() & 0x6F, 0x27);
    assert_int_equal(X.pp_news, 0u);
    /* set and clear within one period: one set-point, no acknowledge left standing */
    assert_int_equal(sdo_write(0x6040u, 0u, 0x1Fu, 2u), 0);
    assert_int_equal(sdo_write(0x6040u, 0u, 0x0Fu, 2u), 0);
    tick(1);
    assert_int_equal(X.pp_news, 1u);
    assert_int_equal(statusword() & 0x1000u, 0u);
    tick(5);
    assert_int_equal(X.pp_news, 1u);
    /* the usual handshake: acknowledge while bit 4 stays set, one set-point only */
    cw(0x1F);
    assert_int_equal(X.pp_news, 2u);
    assert_int_equal(statusword() & 0x1000u, 0x1000u);
    cw(0x1F);                                                  /* no edge: no new set-point */
    tick(3);
    assert_int_equal(X.pp_news, 2u);
    cw(0x0F);
    assert_int_equal(statusword() & 0x1000u, 0u);
    /* an edge written while only READY TO SWITCH ON is void */
    cw(0x06);
    cw(0x16);
    cw(0x0F);
    assert_int_equal(statusword() & 0x6F, 0x27);
    tick(3);
    assert_int_equal(X.pp_news, 2u);
    /* an edge pending when the drive faults does not start a move after the reset */
    assert_int_equal(sdo_write(0x6040u, 0u, 0x1Fu, 2u), 0);
    X.app_fault = 4u;
    tick(2);
    assert_int_equal(statusword() & 0x4F, 0x08);
    uint32_t after_fault = X.pp_news;
    cw(0x00);
    cw(0x80);
    tick(1);
    cw(0x06);
    cw(0x0F);
    assert_int_equal(statusword() & 0x6F, 0x27);
    tick(3);
    assert_int_equal(X.pp_news, after_fault);
}

static void test_heartbeat_consumer(void **st)
{
    (void)st;
    setup_dev();
    tick(1);
    assert_int_equal(sdo_write(0x1016u, 1u, (127u << 16) | 50u, 4u), 0);
    assert_int_equal(sdo_write(0x6060u, 0u, 9u, 1u), 0);
    cw(0x06);
    cw(0x0F);
    uint8_t hb[1] = {0x05};
    for (int i = 0; i < 10; i++) {
        rx(0x77Fu, 1, hb);
        tick(300);                                  /* 30 ms < 50 ms */
    }
    assert_int_equal(statusword() & 0x6F, 0x27);
    flush();
    tick(600);                                      /* 60 ms of silence */
    assert_int_equal(X.comm_faults, 1);
    assert_int_equal(statusword() & 0x4F, 0x08);
    bool emcy = false;
    for (uint32_t i = 0; i < X.ntx; i++) {
        if (X.tx[i].id == 0x80u + NODE && X.tx[i].data[0] == 0x30 && X.tx[i].data[1] == 0x81) {
            emcy = true;
            assert_true(X.tx[i].data[2] & HD_CO_ER_COMM);
        }
    }
    assert_true(emcy);
    cw(0x00);
    cw(0x80);
    tick(1);
    assert_int_equal(statusword() & 0x4F, 0x40);
}

/* hd_co_app_if_t.object_filter: what a master may reach.  Every SDO path and every PDO
 * mapping entry asks it; refused = absent (0x06020000, mapping 0x06040041); local
 * accesses of the app do not ask it. */
static void test_object_filter(void **st)
{
    (void)st;
    uint32_t v = 0u;
    int64_t w = 0;
    setup_dev();
    assert_int_equal(sdo_read(0x5F00u, 1u, &v), 0);              /* no filter: every object */
    CO.app.object_filter = t_filter;
    assert_int_equal(sdo_read(0x5F00u, 1u, &v), HD_CO_AB_NO_OBJECT);
    assert_int_equal(sdo_write(0x2000u, 1u, 100u, 4u), HD_CO_AB_NO_OBJECT);
    assert_int_equal(sdo_read(0x5000u, 99u, &v), HD_CO_AB_NO_OBJECT);   /* not "no sub-index" */
    assert_int_equal(X.param[0], hd_param_table[0].def);                /* nothing written */
    /* segmented and block transfers ask it too */
    flush();
    uint8_t seg[8] = {0x21u, 0x20u, 0x5Fu, 11u, 8u, 0u, 0u, 0u};       /* segmented download 0x5F20:11 */
    rx(0x600u + NODE, 8u, seg);
    const hd_can_frame_t *f = sdo_rsp();
    assert_non_null(f);
    assert_int_equal(f->data[0], 0x80u);
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_NO_OBJECT);
    flush();
    uint8_t blk[8] = {0xA0u, 0x20u, 0x5Fu, 11u, 64u, 0u, 0u, 0u};      /* block upload 0x5F20:11 */
    rx(0x600u + NODE, 8u, blk);
    f = sdo_rsp();
    assert_non_null(f);
    assert_int_equal(f->data[0], 0x80u);
    assert_int_equal(u32le(&f->data[4]), HD_CO_AB_NO_OBJECT);
    assert_int_equal(X.filtered, 5u);
    /* standard objects answer */
    assert_int_equal(sdo_read(0x6041u, 0u, &v), 0);
    assert_int_equal(sdo_read(0x1000u, 0u, &v), 0);
    assert_int_equal(v, 0x00020192u);
    /* a vendor object cannot be mapped; a standard one can */
    assert_int_equal(sdo_write(0x1801u, 1u, 0x80000280u + NODE, 4u), 0);
    assert_int_equal(sdo_write(0x1A01u, 0u, 0u, 1u), 0);
    assert_int_equal(sdo_write(0x1A01u, 1u, 0x5F000120u, 4u), HD_CO_AB_NO_MAP);
    assert_int_equal(sdo_write(0x1A01u, 1u, 0x60640020u, 4u), 0);
    assert_int_equal(X.filtered, 6u);
    /* the app's own access is not the master's */
    assert_int_equal(hd_co_get_i64(&CO, 0x5F00u, 1u, &w), 0);
    assert_int_equal(X.filtered, 6u);
}

static void test_pdo_mapping_and_stream(void **st)
{
    (void)st;
    setup_dev();
    /* remap TPDO2: tick + load velocity, stream every 5 periods (2 kHz) */
    assert_int_equal(sdo_write(0x1A01u, 1u, 0x5F000120u, 4u), HD_CO_AB_STATE);   /* sub0 != 0 */
    assert_int_equal(sdo_write(0x1801u, 1u, 0x80000281u + NODE - 1u, 4u), 0);
    assert_int_equal(sdo_write(0x1A01u, 0u, 0u, 1u), 0);
    assert_int_equal(sdo_write(0x1A01u, 1u, 0x5F000420u, 4u), 0);
    assert_int_equal(sdo_write(0x1A01u, 2u, 0x60400010u, 4u), HD_CO_AB_NO_MAP);   /* RPDO object */
    assert_int_equal(sdo_write(0x1A01u, 2u, 0x5F000120u, 4u), 0);
    assert_int_equal(sdo_write(0x1A01u, 3u, 0x5F000920u, 4u), HD_CO_AB_NO_MAP);   /* wrong length */
    assert_int_equal(sdo_write(0x1A01u, 3u, 0x5F000940u, 4u), 0);
    assert_int_equal(sdo_write(0x1A01u, 0u, 3u, 1u), HD_CO_AB_MAP_LEN);           /* 128 bits */
    assert_int_equal(sdo_write(0x1A01u, 0u, 2u, 1u), 0);
    assert_int_equal(sdo_write(0x1801u, 2u, 254u, 1u), 0);
    assert_int_equal(sdo_write(0x1801u, 2u, 250u, 1u), HD_CO_AB_VALUE);
    assert_int_equal(sdo_write(0x1801u, 1u, 0x281u + NODE - 1u, 4u), 0);
    assert_int_equal(sdo_write(0x5F10u, 2u, 5u, 2u), 0);
    uint8_t start[2] = {0x01, 0};
    rx(0, 2, start);
    flush();
    tick(10000);                                    /* 1 s */
    uint32_t n = 0, prev = 0;
    for (uint32_t i = 0; i < X.ntx; i++) {
        const hd_can_frame_t *f = &X.tx[i];
        if (f->id != 0x280u + NODE) {
            continue;
        }
        assert_int_equal(f->dlc, 8);
        uint32_t t = u32le(&f->data[4]);
        if (n > 0) {
            assert_int_equal(t - prev, 5u);
        }
        prev = t;
        n++;
    }
    assert_true(n >= 400u);
    /* RPDO: controlword + mode through RPDO1 (type 255: immediate) */
    uint8_t r1[3] = {0x06, 0x00, 10};
    rx(0x200u + NODE, 3, r1);
    tick(1);
    assert_int_equal(CO.od.controlword, 6);
    assert_int_equal(CO.od.modes_of_operation, 10);
    assert_int_equal(statusword() & 0x6F, 0x21);
    /* short RPDO: EMCY 0x8210, nothing applied */
    flush();
    uint8_t r2[1] = {0x0F};
    rx(0x200u + NODE, 1, r2);
    assert_int_equal(CO.od.controlword, 6);
    const hd_can_frame_t *f = next_tx();
    assert_non_null(f);
    assert_int_equal(f->id, 0x80u + NODE);
    assert_int_equal(f->data[0] | (f->data[1] << 8), 0x8210);
    /* SYNC-triggered TPDO1 (type 2: every second SYNC) */
    assert_int_equal(sdo_write(0x1800u, 2u, 2u, 1u), 0);
    flush();
    for (int i = 0; i < 6; i++) {
        rx(0x80u, 0, NULL);
    }
    uint32_t s = 0;
    for (uint32_t i = 0; i < X.ntx; i++) {
        if (X.tx[i].id == 0x180u + NODE) {
            s++;
        }
    }
    assert_int_equal(s, 3);
}

/* checksum of everything a bus frame must not change by accident */
static uint32_t param_checksum(void)
{
    uint32_t c = hd_crc32(0u, (const uint8_t *)X.param, sizeof X.param);
    for (uint32_t i = 0; i < CO.count; i++) {
        const hd_co_entry_t *e = &CO.table[i];
        if (e->kind == HD_CO_K_VAR && ((e->flags & HD_CO_F_STORE) != 0u || e->access == HD_CO_A_CONST ||
                                        e->index == 0x1018u)) {
            uint8_t b[8];
            uint32_t n = 0;
            assert_int_equal(hd_co_read(&CO, i, b, sizeof b, &n), 0);
            c = hd_crc32(c, b, n);
        }
    }
    return c;
}

static void test_fuzz_random_frames(void **st)
{
    (void)st;
    setup_dev();
    uint32_t before = param_checksum();
    uint32_t seed = 0x1234567u;
    static const uint32_t ids[] = {0x000, 0x080, 0x600 + NODE, 0x200 + NODE, 0x300 + NODE, 0x400 + NODE,
                                   0x77F, 0x700 + NODE, 0x580 + NODE};
    for (uint32_t i = 0; i < 100000u; i++) {
        hd_can_frame_t f;
        memset(&f, 0, sizeof f);
        seed = seed * 1664525u + 1013904223u;
        uint32_t r = seed >> 8;
        f.id = (r & 1u) ? ids[(r >> 1) % (sizeof ids / sizeof ids[0])] : (r >> 4) & 0x1FFFFFFFu;
        seed = seed * 1664525u + 1013904223u;
        f.dlc = (uint8_t)((seed >> 24) % 16u);     /* includes illegal DLC > 8 */
        f.ext = (uint8_t)(((seed >> 20) & 7u) == 0u);
        f.rtr = (uint8_t)(((seed >> 17) & 15u) == 0u);
        for (uint32_t k = 0; k < 8u; k++) {
            seed = seed * 1664525u + 1013904223u;
            f.data[k] = (uint8_t)(seed >> 24);
        }
        /* never a genuine NMT reset-node from the fuzzer (that legitimately reloads defaults) */
        if (f.id == 0u && f.dlc == 2u && f.data[0] == 0x81u) {
            f.data[0] = 0x7Eu;
        }
        hd_co_process(&CO, &f);
        if ((i & 15u) == 0u) {
            X.tick++;
            hd_co_tick(&CO, HD_CO_TICK_US);
        }
        if (X.ntx > TXQ - 64u) {
            flush();
        }
    }
    assert_int_equal(param_checksum(), before);
    /* still answers SDO: pre-operational, let any half transfer time out */
    uint8_t preop[2] = {0x80, 0};
    rx(0, 2, preop);
    tick(HD_CO_SDO_TIMEOUT_MS * 10u + 20u);
    uint32_t v = 0;
    assert_int_equal(sdo_read(0x1000u, 0u, &v), 0);
    assert_int_equal(v, 0x00020192u);
    assert_int_equal(sdo_write(0x5F20u, 8u, 777u, 4u), 0);
    assert_int_equal(sdo_read(0x5F20u, 8u, &v), 0);
    assert_int_equal(v, 777u);
    assert_true(CO.stats.rx_ignored > 1000u);
}


/* ---- NMT transitions and CiA 402 0x6007 ------------------------------------------- */

static void nmt_cmd(uint8_t cmd)
{
    uint8_t d[2] = {cmd, NODE};
    rx(0, 2, d);
}

/* OPERATION ENABLED in CSV at a target velocity, with 0x6007 = opt; NMT `op`: OPERATIONAL */
static void enable_csv(int16_t opt, bool op)
{
    setup_dev();
    tick(1);
    assert_int_equal(sdo_write(0x6007u, 0u, (uint32_t)(uint16_t)opt, 2u), 0);
    assert_int_equal(sdo_write(0x6060u, 0u, 9u, 1u), 0);
    cw(0x06);
    cw(0x0F);
    assert_int_equal(sdo_write(0x60FFu, 0u, 100000u, 4u), 0);
    if (op) {
        nmt_cmd(0x01);
        assert_int_equal(CO.nmt, HD_CO_NMT_OP);
    }
    tick(1);
    assert_int_equal(statusword() & 0x6F, 0x27);
    assert_true(X.on);
    assert_int_equal(X.sp.target_velocity, 100000);
}

static bool emcy_sent(uint16_t code)
{
    for (uint32_t i = 0; i < X.ntx; i++) {
        const hd_can_frame_t *f = &X.tx[i];
        if (f->id == 0x80u + NODE && (uint16_t)(f->data[0] | (f->data[1] << 8)) == code) {
            return true;
        }
    }
    return false;
}

/* Every NMT command that ends the master's connection (stop, pre-operational from
 * OPERATIONAL, reset communication, reset node) with the power stage on applies 0x6007
 * (docs/can.md): 0 nothing (reset node: power stage off all the same), 1 FAULT with 0x603F
 * 0x8100, 2 SWITCH ON DISABLED, 3 QUICK STOP ACTIVE then SWITCH ON DISABLED. */
static void test_nmt_leaving_operational_applies_0x6007(void **st)
{
    static const uint8_t cmds[4] = {0x02, 0x80, 0x82, 0x81};
    (void)st;
    for (int16_t opt = 0; opt <= 3; opt++) {
        for (uint32_t c = 0; c < 4u; c++) {
            const uint8_t cmd = cmds[c];
            enable_csv(opt, true);
            flush();
            nmt_cmd(cmd);
            if (opt == 3 && cmd != 0x81) {
                assert_int_equal(statusword() & 0x6F, 0x27);     /* updated by the tick */
                tick(1);
                assert_int_equal(statusword() & 0x6F, 0x07);     /* quick stop active */
                assert_true(X.on);
                assert_int_equal(X.sp.quick_stop, 1);
            }
            tick(20);
            const bool emcy = emcy_sent(HD_CO_EMCY_COMM);
            uint32_t v = 0;
            if (cmd != 0x02) {
                assert_int_equal(sdo_read(0x603Fu, 0u, &v), 0);
            } else {
                v = CO.od.error_code;                            /* STOPPED: no SDO */
            }
            if (opt == 0 && cmd != 0x81) {
                assert_int_equal(statusword() & 0x6F, 0x27);     /* "no action": keeps running */
                assert_true(X.on);
            } else if (opt == 1) {
                assert_int_equal(statusword() & 0x4F, 0x08);     /* fault */
                assert_false(X.on);
                assert_int_equal(v, HD_CO_EMCY_COMM);
                assert_int_equal(X.comm_faults, 1);
                assert_true((CO.od.error_register & HD_CO_ER_COMM) != 0u);
                assert_int_equal(CO.err_hist[0], HD_CO_EMCY_COMM);
                /* the EMCY goes out unless the node is STOPPED */
                assert_int_equal(emcy, cmd != 0x02);
            } else {
                assert_int_equal(statusword() & 0x4F, 0x40);     /* switch on disabled */
                assert_false(X.on);
                assert_int_equal(X.comm_faults, 0);
                assert_false(emcy);
            }
        }
    }
    /* recovery from the fault: start, fault reset, enable again */
    enable_csv(1, true);
    nmt_cmd(0x02);
    tick(2);
    nmt_cmd(0x01);
    cw(0x00);
    cw(0x80);
    tick(1);
    assert_int_equal(statusword() & 0x4F, 0x40);
    assert_int_equal(CO.od.error_register, 0);
    cw(0x06);
    cw(0x0F);
    assert_int_equal(statusword() & 0x6F, 0x27);
    assert_true(X.on);
}

/* No reaction when the connection does not end or the power stage is off: NMT start, pre-
 * operational from PRE-OPERATIONAL (the SDO channel stays), any command with the power stage
 * off; stop from PRE-OPERATIONAL with the power stage on does react. */
static void test_nmt_without_reaction(void **st)
{
    (void)st;
    enable_csv(1, false);                          /* enabled over SDO in PRE-OPERATIONAL */
    nmt_cmd(0x80);
    nmt_cmd(0x01);
    nmt_cmd(0x01);
    tick(5);
    assert_int_equal(statusword() & 0x6F, 0x27);
    assert_true(X.on);
    nmt_cmd(0x80);                                 /* OPERATIONAL -> PRE-OPERATIONAL */
    tick(2);
    assert_int_equal(statusword() & 0x4F, 0x08);
    enable_csv(2, false);
    nmt_cmd(0x02);                                 /* PRE-OPERATIONAL -> STOPPED */
    tick(2);
    assert_int_equal(statusword() & 0x4F, 0x40);
    assert_false(X.on);
    /* power stage off: every command leaves the state alone (0x6007 = 1 would fault) */
    static const uint8_t cmds[5] = {0x01, 0x02, 0x80, 0x82, 0x01};
    setup_dev();
    tick(1);
    cw(0x06);
    cw(0x07);
    for (uint32_t c = 0; c < 5u; c++) {
        nmt_cmd(cmds[c]);
        tick(2);
        assert_int_equal(statusword() & 0x6F, 0x23);  /* switched on */
        assert_int_equal(X.comm_faults, 0);
    }
    nmt_cmd(0x81);                                 /* the application restarts */
    tick(2);
    assert_int_equal(statusword() & 0x4F, 0x40);
    assert_int_equal(X.comm_faults, 0);
}

/* ---- COB-IDs ------------------------------------------------------------------------ */

/* CiA 301 restricted CAN-IDs and the node's own service IDs are refused with 0x06090030,
 * the old value kept; the disable / change / enable sequence works. */
/* The CiA 402 layer is a profile plugged in on top: with it the mode rule, the state
 * machine and the statusword; without it the same device is plain CiA 301 (the 402
 * objects are plain values, the 301 services unchanged). */
static void test_profile_plugged_in_or_plain_301(void **st)
{
    uint32_t v = 0u;
    (void)st;
    setup_dev();
    tick(1);
    assert_int_equal(hd_co402_state(&P402), HD_CO402_SO_DISABLED);
    assert_int_equal(sdo_write(0x6060u, 0u, 3u, 1u), HD_CO_AB_VALUE);     /* no mode 3 in this drive */
    cw(0x06);
    assert_int_equal(hd_co402_state(&P402), HD_CO402_READY);
    assert_int_equal(statusword() & 0x6F, 0x21);

    no_profile = true;
    setup_dev();
    no_profile = false;
    assert_null(CO.app.profile);
    tick(3);
    assert_int_equal(sdo_write(0x6060u, 0u, 3u, 1u), 0u);                 /* a plain value */
    cw(0x06);
    tick(3);
    assert_int_equal(statusword(), 0u);                                  /* nobody drives it */
    assert_false(X.on);
    assert_int_equal(sdo_read(0x1017u, 0u, &v), 0u);                      /* 301 as before */
    assert_int_equal(sdo_write(0x1017u, 0u, 100u, 2u), 0u);
    flush();
    const uint8_t reset_comm[2] = {0x82u, (uint8_t)NODE};
    rx(0u, 2u, reset_comm);
    const hd_can_frame_t *f = next_tx();
    assert_non_null(f);
    assert_int_equal(f->id, 0x700u + NODE);                               /* boot-up */
    assert_int_equal(f->data[0], 0u);
}

/* A statusword that changes every period (an axis hunting about its target toggles
 * target reached / internal limit at loop rate) must not put a TPDO1 on the bus every
 * period: at 10 kHz the change-of-state TPDO would fill the bus ahead of the SDO
 * answers (0x180+n outranks 0x580+n) and the master would lose the drive.  The default
 * inhibit time (0x1800:3) spaces them; the last state still goes out. */
static void test_tpdo1_chatter_is_spaced_by_the_inhibit_time(void **st)
{
    (void)st;
    setup_dev();
    uint32_t inhibit = 0u;
    assert_int_equal(sdo_read(0x1800u, 3u, &inhibit), 0);
    uint8_t start[2] = {0x01, 0};
    rx(0, 2, start);
    tick(10);
    flush();
    X.chatter = true;
    const uint32_t periods = 10000u;                 /* 1 s of drive time */
    uint32_t n = 0u;
    uint32_t last_tick = 0u;
    uint32_t min_gap = UINT32_MAX;
    uint16_t sw = 0u;                                /* the last statusword the master has seen */
    uint32_t with_limit = 0u;
    for (uint32_t k = 0u; k < periods; k += 100u) {
        tick(100u);
        for (uint32_t i = 0u; i < X.ntx; i++) {
            const hd_can_frame_t *f = &X.tx[i];
            if (f->id != 0x180u + NODE) {
                continue;
            }
            const uint32_t t = u32le(&f->data[4]);
            if (n > 0u && t - last_tick < min_gap) {
                min_gap = t - last_tick;
            }
            last_tick = t;
            sw = (uint16_t)(f->data[0] | (f->data[1] << 8));
            with_limit += (sw & 0x0800u) != 0u ? 1u : 0u;
            n++;
        }
        assert_false(X.tx_full);
        flush();
    }
    /* at most one TPDO1 per millisecond whatever the statusword does; the changes are still
     * reported, one per inhibit time (0x1800:3, 100 us units) */
    assert_true(n <= periods / 10u + 1u);
    assert_true(min_gap >= 10u);
    assert_true(inhibit >= 10u && min_gap >= inhibit);
    assert_true(n >= periods / inhibit / 2u);
    assert_true(with_limit > 0u && with_limit < n);  /* both states were reported */
    /* the chatter ends in the limit-free state: it reaches the master within one inhibit time */
    X.chatter = false;
    tick(inhibit + 1u);
    const hd_can_frame_t *f;
    while ((f = next_tx()) != NULL) {
        if (f->id == 0x180u + NODE) {
            sw = (uint16_t)(f->data[0] | (f->data[1] << 8));
        }
    }
    assert_int_equal(sw & 0x0800u, 0u);
}

static void test_cobid_rules(void **st)
{
    static const uint32_t restricted[] = {0x001, 0x07F, 0x101, 0x17F, 0x180, 0x581, 0x580 + NODE, 0x5FF,
                                          0x601, 0x600 + NODE, 0x67F, 0x6E0, 0x6FF, 0x701, 0x700 + NODE,
                                          0x77F, 0x780, 0x7E5, 0x7FF};
    uint32_t v = 0;
    (void)st;
    setup_dev();
    assert_true(hd_co_cobids_ok(&CO));
    /* SYNC on the node's SDO request id would make every request a SYNC */
    assert_int_equal(sdo_write(0x1005u, 0u, 0x600u + NODE, 4u), HD_CO_AB_VALUE);
    assert_int_equal(sdo_read(0x1005u, 0u, &v), 0);               /* still answers */
    assert_int_equal(v, 0x80u);
    for (uint32_t i = 0; i < sizeof restricted / sizeof restricted[0]; i++) {
        const uint32_t id = restricted[i];
        assert_false(hd_co_cobid_allowed(&CO, 0x1005u, 0u, id));
        assert_int_equal(sdo_write(0x1005u, 0u, id, 4u), HD_CO_AB_VALUE);
        assert_int_equal(sdo_write(0x1800u, 1u, id, 4u), HD_CO_AB_VALUE);
        assert_int_equal(sdo_write(0x1400u, 1u, id, 4u), HD_CO_AB_VALUE);
        if (id > 0x80u) {                                          /* 0x1014 minimum 0x81 */
            assert_int_equal(sdo_write(0x1014u, 0u, id, 4u), HD_CO_AB_VALUE);
        }
        /* through the CiA 301 sequence too: invalid first, then the id */
        assert_int_equal(sdo_write(0x1801u, 1u, 0x80000000u | (0x280u + NODE), 4u), 0);
        assert_int_equal(sdo_write(0x1801u, 1u, id, 4u), HD_CO_AB_VALUE);
        assert_int_equal(sdo_write(0x1801u, 1u, 0x280u + NODE, 4u), 0);
    }
    assert_int_equal(sdo_write(0x1400u, 1u, 0x80000000u | (0x200u + NODE), 4u), 0);
    assert_int_equal(sdo_write(0x1400u, 1u, 0x000u, 4u), HD_CO_AB_VALUE);
    assert_int_equal(sdo_write(0x1400u, 1u, 0x200u + NODE, 4u), 0);
    /* the node's own services: SYNC, EMCY, every valid PDO */
    assert_int_equal(sdo_write(0x1005u, 0u, 0x80u + NODE, 4u), HD_CO_AB_VALUE);   /* = EMCY */
    assert_int_equal(sdo_write(0x1005u, 0u, 0x180u + NODE, 4u), HD_CO_AB_VALUE);  /* = TPDO1 */
    assert_int_equal(sdo_write(0x1005u, 0u, 0x200u + NODE, 4u), HD_CO_AB_VALUE);  /* = RPDO1 */
    assert_int_equal(sdo_write(0x1014u, 0u, 0x180u + NODE, 4u), HD_CO_AB_VALUE);
    assert_int_equal(sdo_write(0x1801u, 1u, 0x80000000u | (0x280u + NODE), 4u), 0);
    assert_int_equal(sdo_write(0x1801u, 1u, 0x180u + NODE, 4u), HD_CO_AB_VALUE);  /* = TPDO1 */
    assert_int_equal(sdo_write(0x1801u, 1u, 0x200u + NODE, 4u), HD_CO_AB_VALUE);  /* = RPDO1 */
    assert_int_equal(sdo_write(0x1801u, 1u, 0x080u, 4u), HD_CO_AB_VALUE);         /* = SYNC */
    assert_int_equal(sdo_write(0x1801u, 1u, 0x80u + NODE, 4u), HD_CO_AB_VALUE);   /* = EMCY */
    /* 29-bit (bit 29) and the reserved bits are refused */
    assert_int_equal(sdo_write(0x1801u, 1u, 0x20000000u | (0x2A0u + NODE), 4u), HD_CO_AB_VALUE);
    assert_int_equal(sdo_write(0x1801u, 1u, 0x00000800u | (0x2A0u + NODE), 4u), HD_CO_AB_VALUE);
    assert_int_equal(sdo_write(0x1014u, 0u, 0x20000000u | (0x80u + NODE), 4u), HD_CO_AB_VALUE);
    assert_false(hd_co_cobid_allowed(&CO, 0x1005u, 0u, 0x20000090u));
    assert_false(hd_co_cobid_allowed(&CO, 0x1005u, 0u, 0x40000090u));
    assert_false(hd_co_cobid_allowed(&CO, 0x1006u, 0u, 0x90u));                 /* not a COB-ID */
    /* none of it changed anything */
    assert_int_equal(CO.od.cob_id_sync, 0x80u);
    assert_int_equal(CO.od.cob_id_emcy, 0x80u + NODE);
    assert_int_equal(CO.od.tpdo_cob[0], 0x180u + NODE);
    assert_int_equal(CO.od.tpdo_cob[1], 0x80000000u | (0x280u + NODE));
    assert_int_equal(CO.od.rpdo_cob[0], 0x200u + NODE);
    /* legal changes: a valid PDO's id only through invalid; an id freed by another object */
    assert_int_equal(sdo_write(0x1800u, 1u, 0x1A0u + NODE, 4u), HD_CO_AB_VALUE);  /* valid: disable first */
    assert_int_equal(sdo_write(0x1800u, 1u, 0x80000000u | (0x180u + NODE), 4u), 0);
    assert_int_equal(sdo_write(0x1800u, 1u, 0x1A0u + NODE, 4u), 0);
    assert_int_equal(sdo_write(0x1801u, 1u, 0x180u + NODE, 4u), 0);              /* TPDO1's old id */
    assert_int_equal(sdo_write(0x1005u, 0u, 0x0FFu, 4u), 0);
    assert_int_equal(sdo_write(0x1014u, 0u, 0x80000000u | (0x80u + NODE), 4u), 0); /* EMCY off */
    assert_int_equal(sdo_write(0x1401u, 1u, 0x80000000u | (0x300u + NODE), 4u), 0);
    assert_int_equal(sdo_write(0x1401u, 1u, 0x80u + NODE, 4u), 0);               /* free now */
    assert_int_equal(sdo_write(0x1014u, 0u, 0x80u + NODE, 4u), HD_CO_AB_VALUE);   /* taken */
    assert_true(hd_co_cobids_ok(&CO));
    /* the new ids work: SYNC on 0x0FF, TPDO1 on 0x1A0+n */
    assert_int_equal(sdo_write(0x1800u, 2u, 1u, 1u), 0);
    nmt_cmd(0x01);
    flush();
    rx(0x0FFu, 0, NULL);
    bool seen = false;
    for (uint32_t i = 0; i < X.ntx; i++) {
        seen = seen || X.tx[i].id == 0x1A0u + NODE;
    }
    assert_true(seen);
    /* a dictionary with a colliding pair in force fails the shared check */
    CO.od.tpdo_cob[3] = 0x1A0u + NODE;
    assert_false(hd_co_cobids_ok(&CO));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bootup_nmt_heartbeat),
        cmocka_unit_test(test_sdo_expedited_and_aborts),
        cmocka_unit_test(test_sdo_segmented),
        cmocka_unit_test(test_sdo_block_domain),
        cmocka_unit_test(test_402_state_machine),
        cmocka_unit_test(test_402_new_setpoint_edge_latched_at_write),
        cmocka_unit_test(test_heartbeat_consumer),
        cmocka_unit_test(test_pdo_mapping_and_stream),
        cmocka_unit_test(test_tpdo1_chatter_is_spaced_by_the_inhibit_time),
        cmocka_unit_test(test_object_filter),
        cmocka_unit_test(test_nmt_leaving_operational_applies_0x6007),
        cmocka_unit_test(test_nmt_without_reaction),
        cmocka_unit_test(test_cobid_rules),
        cmocka_unit_test(test_profile_plugged_in_or_plain_301),
        cmocka_unit_test(test_fuzz_random_frames),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
