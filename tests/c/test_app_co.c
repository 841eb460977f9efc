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

uint32_t hd_hal_tick(void) { return 0u; }
void hd_hal_read_sensors(hd_hal_sensors_t *s)
{
    memset(s, 0, sizeof *s);
    s->valid = HD_HAL_VALID_MOTOR_ENC | HD_HAL_VALID_OUTPUT_ENC | HD_HAL_VALID_CURRENT;
}
void hd_hal_write_command(const hd_hal_command_t *c) { (void)c; }
bool hd_hal_can_send(const hd_can_frame_t *f) { (void)f; return true; }
bool hd_hal_can_recv(hd_can_frame_t *f) { (void)f; return false; }
static hd_hal_can_status_t can_st;   /* controller state the tests set */
static uint32_t n_recover;
void hd_hal_can_status(hd_hal_can_status_t *st) { *st = can_st; }
void hd_hal_can_recover(void) { n_recover++; }
uint32_t hd_hal_nvm_size(void) { return 0u; }
uint32_t hd_hal_nvm_page_size(void) { return 1024u; }
int32_t hd_hal_nvm_read(uint32_t o, void *b, uint32_t l) { (void)o; (void)b; (void)l; return -1; }
int32_t hd_hal_nvm_write(uint32_t o, const void *b, uint32_t l) { (void)o; (void)b; (void)l; return -1; }
int32_t hd_hal_nvm_erase(uint32_t o, uint32_t l) { (void)o; (void)l; return -1; }

static hd_app_t app;
static hd_co_t co;
static hd_app_co_t ac;
static uint32_t n_sent;
static uint8_t img[4u * HD_APP_CO_STAGE_WORDS + 16u];

static bool p_send(void *c, const hd_can_frame_t *f) { (void)c; (void)f; n_sent++; return true; }

static int setup(void **st)
{
    (void)st;
    hd_app_co_port_t port;
    memset(&port, 0, sizeof port);
    port.send = p_send;
    hd_app_init(&app);
    hd_app_co_init(&ac, &co, &app, 1u, &port);
    hd_app_step(&app);
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
    uint32_t i, j, n = 0u;
    memset(&t, 0, sizeof t);
    t.version = version;
    t.levels = levels;
    t.sub_bits = 1u;
    t.in_shift = 10u;
    t.u0 = -4096;
    t.unit = HD_PREISACH_UNIT_TORQUE_TWIST;
    for (i = 0u; i < levels; i++) {
        for (j = 0u; j <= i; j++) {
            t.e[i * (i + 1u) / 2u + j] = scale * (int32_t)((i - j) * (i - j + 1u));
        }
    }
    hd_preisach_seal(&t);
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_preisach_table, setup),
        cmocka_unit_test_setup(test_group_and_interlock, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
