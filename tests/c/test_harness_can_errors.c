/*
 * test_harness_can_errors.c - CAN controller error states end to end on the PC port:
 * the host port's fault-confinement model (firmware/port/host/hal_host.c) -> hal.h
 * hd_hal_can_status / hd_hal_can_recover -> the CANopen adapter (hd_app_co.c) ->
 * the stack's reactions (hd_co.c: EMCY 0x8120 / 0x8140, 0x1029 error behaviour,
 * bus-off recovery; hd_co_402.c: 0x6007 abort connection option code) and the app
 * (HD_FAULT_COMM, power stage).  Each test: setUp (fresh port, app, device),
 * the test, tearDown (unbind the port).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "hal_host.h"
#include "hd_app.h"
#include "hd_app_co.h"

#define NODE 3u
#define TXQ 4096u

typedef struct {
    hd_host_port_t port;
    hd_app_t app;
    hd_co_t co;
    hd_app_co_t ac;
    hd_can_frame_t tx[TXQ];
    uint32_t ntx;
} fx_t;

static fx_t *F;

static bool p_send(void *c, const hd_can_frame_t *f)
{
    fx_t *x = c;
    if (x->ntx >= TXQ) return false;
    x->tx[x->ntx++] = *f;
    return true;
}

/* one control period as the virtual drive runs it: sensors, app, port, stack */
static void period(uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        hd_hal_sensors_t s;
        memset(&s, 0, sizeof s);
        s.valid = HD_HAL_VALID_MOTOR_ENC | HD_HAL_VALID_OUTPUT_ENC | HD_HAL_VALID_CURRENT;
        hd_host_port_latch(&F->port, &s);
        hd_app_step(&F->app);
        hd_host_port_end_period(&F->port);
        hd_co_tick(&F->co, HD_CO_TICK_US);
    }
}

static void rx(uint32_t id, uint8_t dlc, const uint8_t *d)
{
    hd_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    memcpy(f.data, d, dlc);
    hd_co_process(&F->co, &f);
}

/* expedited SDO write of n bytes; returns 0 or the abort code */
static uint32_t sdo_w(uint16_t idx, uint8_t sub, uint32_t v, uint32_t n)
{
    uint8_t d[8] = {(uint8_t)(0x23u | ((4u - n) << 2)), (uint8_t)idx, (uint8_t)(idx >> 8), sub,
                    (uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    uint32_t before = F->ntx;
    rx(0x600u + NODE, 8u, d);
    for (uint32_t i = before; i < F->ntx; i++) {
        const hd_can_frame_t *f = &F->tx[i];
        if (f->id == 0x580u + NODE) {
            if (f->data[0] == 0x80u)
                return (uint32_t)f->data[4] | ((uint32_t)f->data[5] << 8) | ((uint32_t)f->data[6] << 16) |
                       ((uint32_t)f->data[7] << 24);
            return 0u;
        }
    }
    fail_msg("no SDO response");
    return 1u;
}

static void cw(uint16_t v)
{
    assert_int_equal(sdo_w(0x6040u, 0u, v, 2u), 0);
    period(1);
}

static uint16_t sw(void) { return F->co.od.statusword; }

/* EMCY frames with this code sent at index >= from */
static uint32_t emcy_count(uint32_t from, uint16_t code, uint8_t *reg)
{
    uint32_t n = 0;
    for (uint32_t i = from; i < F->ntx; i++) {
        const hd_can_frame_t *f = &F->tx[i];
        if (f->id == 0x80u + NODE && f->dlc == 8u && (uint16_t)(f->data[0] | (f->data[1] << 8)) == code) {
            n++;
            if (reg) *reg = f->data[2];
        }
    }
    return n;
}

static void enable_csv(void)
{
    assert_int_equal(sdo_w(0x6060u, 0u, 9u, 1u), 0);
    cw(0x06);
    cw(0x07);
    cw(0x0F);
    assert_int_equal(sw() & 0x6F, 0x27);              /* operation enabled */
    assert_int_not_equal(F->app.mode, HD_MODE_OFF);
}

static int setUp(void **st)
{
    (void)st;
    F = test_calloc(1, sizeof *F);
    hd_host_port_init(&F->port);
    hd_host_port_bind(&F->port);
    hd_app_init(&F->app);
    hd_app_co_port_t pif;
    memset(&pif, 0, sizeof pif);
    pif.ctx = F;
    pif.send = p_send;
    hd_app_co_init(&F->ac, &F->co, &F->app, (uint8_t)NODE, &pif);
    period(2);
    uint8_t start[2] = {0x01, NODE};
    rx(0, 2, start);
    assert_int_equal(F->co.nmt, HD_CO_NMT_OP);
    return 0;
}

static int tearDown(void **st)
{
    (void)st;
    hd_host_port_bind(NULL);
    test_free(F);
    F = NULL;
    return 0;
}

/* the port's counters follow ISO 11898-1 and the recovery takes 128 x 11 bit times */
static void test_port_fault_confinement(void **st)
{
    (void)st;
    hd_hal_can_status_t s;
    hd_host_can_errors(&F->port, 12u, 0u);              /* TEC 96: warning, still active */
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_ERROR_ACTIVE);
    assert_int_equal(s.tec, 96);
    assert_int_equal(s.warning, 1);
    hd_host_can_errors(&F->port, 4u, 0u);               /* TEC 128 */
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_ERROR_PASSIVE);
    assert_true(hd_host_can_tx_done(&F->port));         /* TEC 127: active again */
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_ERROR_ACTIVE);
    assert_int_equal(s.tec, 127);
    hd_host_can_errors(&F->port, 0u, 200u);             /* REC 200 */
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_ERROR_PASSIVE);
    assert_int_equal(s.rec, 128);
    assert_true(hd_host_can_rx_done(&F->port));         /* REC back to 127 */
    hd_hal_can_status(&s);
    assert_int_equal(s.rec, 127);
    hd_host_can_errors(&F->port, 17u, 0u);              /* TEC 127 + 136 > 255 */
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_BUS_OFF);
    assert_false(hd_host_can_tx_done(&F->port));
    assert_false(hd_host_can_rx_done(&F->port));
    hd_host_port_end_period(&F->port);                  /* no recovery before it is asked for */
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_BUS_OFF);
    F->port.can_ctrl.bitrate = 125000u;                 /* 1408 bits = 11.264 ms -> 113 periods */
    hd_hal_can_recover();
    for (int i = 0; i < 112; i++) hd_host_port_end_period(&F->port);
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_BUS_OFF);
    hd_host_port_end_period(&F->port);
    hd_hal_can_status(&s);
    assert_int_equal(s.state, HD_HAL_CAN_ERROR_ACTIVE);
    assert_int_equal(s.tec, 0);
    assert_int_equal(s.rec, 0);
    assert_int_equal(F->port.can_ctrl.bus_off_count, 1);
    assert_int_equal(F->port.can_ctrl.recoveries, 1);
}

/* error passive: EMCY 0x8120 (communication bit); back to active: error reset 0x0000 */
static void test_error_passive_emcy(void **st)
{
    (void)st;
    uint32_t t0 = F->ntx;
    uint8_t reg = 0;
    hd_host_can_errors(&F->port, 0u, 128u);
    period(1);
    assert_int_equal(emcy_count(t0, HD_CO_EMCY_CAN_PASSIVE, &reg), 1);
    assert_true(reg & HD_CO_ER_COMM);
    assert_int_equal(F->co.err_hist[0], HD_CO_EMCY_CAN_PASSIVE);
    period(100);                                        /* stays passive: no second EMCY */
    assert_int_equal(emcy_count(t0, HD_CO_EMCY_CAN_PASSIVE, NULL), 1);
    assert_true(hd_host_can_rx_done(&F->port));
    period(1);
    assert_int_equal(emcy_count(t0, 0x0000u, NULL), 1);
    assert_int_equal(F->co.od.error_register, 0);
    assert_int_equal(F->co.stats.can_passive, 1);
}

/* bus-off with 0x6007 = 1 (default): fault, nothing sent while off, recovery after
 * 100 ms + 128 x 11 bits, EMCY 0x8140, then the host's fault reset and a new enable */
static void test_bus_off_fault_and_recovery(void **st)
{
    (void)st;
    assert_int_equal(F->co.od.abort_connection_option_code, 1);
    assert_int_equal(F->co.od.error_behavior_communication_error, 1);
    enable_csv();
    uint32_t t0 = F->ntx;
    hd_host_can_bus_off(&F->port);
    period(2);
    assert_int_equal(sw() & 0x4F, 0x08);                /* FAULT */
    assert_int_equal(F->app.fault, HD_FAULT_COMM);
    assert_int_equal(F->app.mode, HD_MODE_OFF);
    assert_int_equal(F->co.od.error_code, HD_CO_EMCY_BUS_OFF);
    assert_int_equal(F->co.err_hist[0], HD_CO_EMCY_BUS_OFF);
    assert_true(F->co.od.error_register & HD_CO_ER_COMM);
    assert_int_equal(F->co.nmt, HD_CO_NMT_OP);          /* 0x1029:1 = 1: no NMT change */
    period(900);                                        /* 90 ms: no recovery asked yet */
    assert_int_equal(F->ntx, t0);                       /* nothing on the bus, not even heartbeats */
    assert_int_equal(F->port.can_ctrl.recovering, 0);
    period(100);                                        /* 100 ms: recovery requested ... */
    assert_int_equal(F->port.can_ctrl.recovering + F->port.can_ctrl.recoveries, 1);
    period(20);                                         /* ... 15 periods at 1 Mbit/s later: back */
    assert_int_equal(F->port.can_ctrl.state, HD_HAL_CAN_ERROR_ACTIVE);
    uint8_t reg = 0;
    assert_int_equal(emcy_count(t0, HD_CO_EMCY_BUS_OFF, &reg), 1);
    assert_true(reg & HD_CO_ER_COMM);
    assert_int_equal(F->co.stats.can_recovered, 1);
    assert_int_equal(sw() & 0x4F, 0x08);                /* still FAULT until the host resets */
    uint32_t t1 = F->ntx;
    cw(0x00);
    cw(0x80);
    period(1);
    assert_int_equal(sw() & 0x4F, 0x40);                /* switch on disabled */
    assert_int_equal(F->app.fault, HD_FAULT_NONE);
    assert_int_equal(emcy_count(t1, 0x0000u, NULL), 1);
    assert_int_equal(F->co.od.error_register, 0);
    enable_csv();
}

/* 0x6007: 0 no action, 2 disable voltage, 3 quick stop; 0x1029:1: 0 pre-op, 2 stopped */
static void test_abort_connection_options(void **st)
{
    (void)st;
    /* 0: the drive keeps running, only the EMCY and the NMT reaction */
    assert_int_equal(sdo_w(0x6007u, 0u, 0u, 2u), 0);
    assert_int_equal(sdo_w(0x1029u, 1u, 0u, 1u), 0);
    enable_csv();
    hd_host_can_bus_off(&F->port);
    period(2);
    assert_int_equal(sw() & 0x6F, 0x27);
    assert_int_equal(F->co.nmt, HD_CO_NMT_PREOP);
    period(1100);
    assert_int_equal(F->port.can_ctrl.state, HD_HAL_CAN_ERROR_ACTIVE);
    uint8_t start[2] = {0x01, NODE};
    rx(0, 2, start);
    /* 2: disable voltage -> switch on disabled, no fault */
    assert_int_equal(sdo_w(0x6007u, 0u, 2u, 2u), 0);
    assert_int_equal(sdo_w(0x1029u, 1u, 2u, 1u), 0);
    hd_host_can_bus_off(&F->port);
    period(2);
    assert_int_equal(sw() & 0x4F, 0x40);
    assert_int_equal(F->app.mode, HD_MODE_OFF);
    assert_int_equal(F->app.fault, HD_FAULT_NONE);
    assert_int_equal(F->co.nmt, HD_CO_NMT_STOPPED);
    period(1100);
    rx(0, 2, start);
    assert_int_equal(F->co.nmt, HD_CO_NMT_OP);
    /* 3: quick stop on a lost host heartbeat -> quick stop active -> (standstill) disabled */
    assert_int_equal(sdo_w(0x6007u, 0u, 3u, 2u), 0);
    assert_int_equal(sdo_w(0x1029u, 1u, 1u, 1u), 0);
    assert_int_equal(sdo_w(0x1016u, 1u, (127u << 16) | 20u, 4u), 0);
    uint8_t hb[1] = {0x05};
    rx(0x77Fu, 1, hb);
    enable_csv();
    uint32_t t0 = F->ntx;
    period(250);                                        /* 25 ms > 20 ms without a heartbeat */
    assert_int_equal(emcy_count(t0, HD_CO_EMCY_HB, NULL), 1);
    assert_int_equal(F->app.fault, HD_FAULT_NONE);
    assert_int_equal(sw() & 0x4F, 0x40);                /* standstill reached: switch on disabled */
    assert_int_equal(F->app.mode, HD_MODE_OFF);
    assert_int_equal(F->co.nmt, HD_CO_NMT_OP);
    /* values outside 0x6007 0..3 / 0x1029:1 0..2 are refused */
    assert_int_equal(sdo_w(0x6007u, 0u, 4u, 2u), HD_CO_AB_VALUE_HIGH);
    assert_int_equal(sdo_w(0x1029u, 1u, 3u, 1u), HD_CO_AB_VALUE_HIGH);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_port_fault_confinement, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_error_passive_emcy, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_bus_off_fault_and_recovery, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_abort_connection_options, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
