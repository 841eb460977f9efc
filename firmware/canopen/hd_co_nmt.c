/*
 * hd_co_nmt.c - CiA 301 NMT slave and heartbeat: the NMT commands (start, stop,
 * pre-operational, reset node, reset communication), the boot-up message, the heartbeat
 * producer (0x1017) and consumer (0x1016:1).
 */
#include "hd_co_internal.h"

static void boot_up(hd_co_t *co)
{
    uint8_t d[1] = {0u};
    hd_co__send(co, 0x700u + co->node_id, 1u, d);
    co->nmt = HD_CO_NMT_PREOP;
    co->hb_next_us = co->now_us + (uint64_t)co->od.producer_heartbeat_time * 1000u;
}

void hd_co__reset_comm(hd_co_t *co)
{
    hd_co__sdo_reset(co, true);
    hd_co__load_defaults(co, 0x1000u, 0x1FFFu);
    if (co->stored_ok != 0u) {            /* CiA 301: reset communication = the stored values */
        (void)hd_co_store_apply(co, co->stored, hd_co_store_words(co), 0x1000u, 0x1FFFu);
    }
    hd_co__pdo_rebuild_all(co);
    co->hbc_active = 0u;
    co->hbc_lost = 0u;
    co->emcy_pending = 0u;
    boot_up(co);
}

/* The profile's reaction when an NMT command ends the master's connection (`leaving`:
 * stop from OPERATIONAL or PRE-OPERATIONAL, pre-operational from OPERATIONAL, either
 * reset; CiA 402: 0x6007 with the power stage on); true when the reaction was a fault
 * (its EMCY follows the transition) */
static bool nmt_abort_connection(hd_co_t *co, bool leaving)
{
    if (!leaving || co->app.profile == NULL) {
        return false;
    }
    return co->app.profile->nmt_leave(co->app.profile_ctx, co);
}

void hd_co__nmt_process(hd_co_t *co, const hd_can_frame_t *f)
{
    bool faulted = false;
    if (f->dlc != 2u || f->rtr) {
        co->stats.rx_ignored++;
        return;
    }
    uint8_t cmd = f->data[0];
    uint8_t node = f->data[1];
    if (node != 0u && node != co->node_id) {
        return;
    }
    switch (cmd) {
    case 0x01u:
        if (co->nmt != HD_CO_NMT_OP) {
            hd_co__tpdo_arm_events(co);
        }
        co->nmt = HD_CO_NMT_OP;
        break;
    case 0x02u:
        faulted = nmt_abort_connection(co, co->nmt != HD_CO_NMT_STOPPED);
        co->nmt = HD_CO_NMT_STOPPED;
        hd_co__sdo_reset(co, true);
        break;
    case 0x80u:
        faulted = nmt_abort_connection(co, co->nmt == HD_CO_NMT_OP);
        co->nmt = HD_CO_NMT_PREOP;
        break;
    case 0x81u:
        faulted = nmt_abort_connection(co, true);
        if (co->app.reset_node != NULL) {
            co->app.reset_node(co->app.ctx);
        }
        hd_co__load_defaults(co, 0x2000u, 0xFFFFu);
        if (co->stored_ok != 0u) {
            (void)hd_co_store_apply(co, co->stored, hd_co_store_words(co), 0x2000u, 0xFFFFu);
        }
        if (co->app.profile != NULL) {
            co->app.profile->restart(co->app.profile_ctx, co);
        }
        hd_co__reset_comm(co);
        break;
    case 0x82u:
        faulted = nmt_abort_connection(co, true);
        hd_co__reset_comm(co);
        break;
    default: co->stats.rx_ignored++; break;
    }
    if (faulted) {
        /* after the transition: a reset's boot-up goes first and its cleared error register
         * gets the bit back; in STOPPED the EMCY is only recorded (0x1003, 0x1001) */
        hd_co_emcy(co, HD_CO_EMCY_COMM, HD_CO_ER_COMM, NULL);
    }
}

void hd_co__hb_receive(hd_co_t *co, const hd_can_frame_t *f, uint32_t id)
{
    uint32_t c = co->od.consumer_heartbeat_time_1;
    if (f->dlc == 1u && !f->rtr && (c & 0xFFFFu) != 0u && (id - 0x700u) == ((c >> 16) & 0x7Fu)) {
        co->hbc_last_us = co->now_us;
        co->hbc_active = 1u;
        co->hbc_lost = 0u;
    }
}

void hd_co__hb_config_changed(hd_co_t *co, uint16_t index)
{
    if (index == 0x1017u) {
        co->hb_next_us = co->now_us + (uint64_t)co->od.producer_heartbeat_time * 1000u;
    } else {
        co->hbc_active = 0u;
        co->hbc_lost = 0u;
    }
}

void hd_co__hb_produce(hd_co_t *co)
{
    if (co->od.producer_heartbeat_time != 0u && co->now_us >= co->hb_next_us) {
        uint8_t st = co->nmt;
        hd_co__send(co, 0x700u + co->node_id, 1u, &st);
        co->hb_next_us = co->now_us + (uint64_t)co->od.producer_heartbeat_time * 1000u;
    }
}

void hd_co__hb_consume(hd_co_t *co)
{
    uint32_t c = co->od.consumer_heartbeat_time_1;
    if (co->hbc_active && (c & 0xFFFFu) != 0u && co->can_state != HD_HAL_CAN_BUS_OFF &&
        co->now_us - co->hbc_last_us > (uint64_t)(c & 0xFFFFu) * 1000u) {
        co->hbc_active = 0u;
        co->hbc_lost = 1u;
        uint8_t mfr[5] = {(uint8_t)((c >> 16) & 0x7Fu), 0u, 0u, 0u, 0u};
        hd_co__comm_error(co, HD_CO_EMCY_HB, mfr);
    }
}
