/*
 * hd_co.c - the CANopen device's entry points (hd_co.h): init, the dispatch of
 * a received frame to its service, the order of the services in one tick, frames out.
 * The services themselves are one file each (hd_co_internal.h).
 */
#include "hd_co_util.h"
#include "hd_co_internal.h"

void hd_co__send(hd_co_t *co, uint32_t id, uint8_t dlc, const uint8_t *data)
{
    hd_can_frame_t f;
    hd_co_fill(&f, 0u, sizeof f);
    f.id = id;
    f.dlc = dlc;
    if (dlc > 0u) {
        hd_co_copy(f.data, data, dlc);
    }
    if (co->can_state == HD_HAL_CAN_BUS_OFF) {
        co->stats.tx_dropped++;          /* the controller is off the bus */
        return;
    }
    if (co->app.send != NULL && co->app.send(co->app.ctx, &f)) {
        co->stats.tx_frames++;
    } else {
        co->stats.tx_dropped++;
    }
}

bool hd_co__try_send(hd_co_t *co, uint32_t id, uint8_t dlc, const uint8_t *data)
{
    hd_can_frame_t f;
    hd_co_fill(&f, 0u, sizeof f);
    f.id = id;
    f.dlc = dlc;
    hd_co_copy(f.data, data, dlc);
    if (co->can_state != HD_HAL_CAN_BUS_OFF && co->app.send != NULL && co->app.send(co->app.ctx, &f)) {
        co->stats.tx_frames++;
        return true;
    }
    return false;
}

void hd_co_init(hd_co_t *co, uint8_t node_id, const hd_co_app_if_t *app)
{
    hd_co_fill(co, 0u, sizeof *co);
    co->table = hd_co_od;
    co->count = HD_CO_OD_COUNT;
    co->node_id = (uint8_t)((node_id >= 1u && node_id <= 127u) ? node_id : 1u);
    co->sdo_timeout_ms = HD_CO_SDO_TIMEOUT_MS;
    if (app != NULL) {
        co->app = *app;
    }
    hd_co__load_defaults(co, 0x2000u, 0xFFFFu);
    if (co->app.profile != NULL) {
        co->app.profile->init(co->app.profile_ctx, co);
    }
    hd_co__reset_comm(co);
}

void hd_co_process(hd_co_t *co, const hd_can_frame_t *f)
{
    co->stats.rx_frames++;
    if (f->ext || f->dlc > 8u) {
        co->stats.rx_ignored++;
        return;
    }
    uint32_t id = f->id & 0x7FFu;
    if (f->id > 0x7FFu) {
        co->stats.rx_ignored++;
        return;
    }
    if (id == 0u) {
        hd_co__nmt_process(co, f);
        return;
    }
    if (co->nmt == HD_CO_NMT_INIT) {
        return;
    }
    if (id == (co->od.cob_id_sync & 0x7FFu)) {
        if (f->dlc > 1u || f->rtr || co->nmt == HD_CO_NMT_STOPPED) {
            co->stats.rx_ignored++;
            return;
        }
        co->sync_counter = f->dlc == 1u ? f->data[0] : 0u;
        hd_co__on_sync(co, co->sync_counter);
        return;
    }
    if (id == 0x600u + co->node_id) {
        hd_co__sdo_process(co, f);
        return;
    }
    if (id >= 0x701u && id <= 0x77Fu) {
        hd_co__hb_receive(co, f, id);
        return;
    }
    if (co->nmt == HD_CO_NMT_OP && !f->rtr && hd_co__rpdo_receive(co, f, id)) {
        return;
    }
    co->stats.rx_ignored++;
}

void hd_co_tick(hd_co_t *co, uint32_t dt_us)
{
    co->now_us += dt_us;
    hd_co__hb_produce(co);
    hd_co__can_tick(co);
    hd_co__hb_consume(co);
    hd_co__emcy_tick(co);
    hd_co__sdo_tick(co);
    if (co->app.profile != NULL) {
        co->app.profile->tick(co->app.profile_ctx, co);
    }
    if (co->nmt == HD_CO_NMT_OP) {
        hd_co__tpdo_tick(co);
    }
}
