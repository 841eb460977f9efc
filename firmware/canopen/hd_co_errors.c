/*
 * hd_co_errors.c - CiA 301 communication errors: the CAN controller's state (error
 * passive, bus-off and its recovery), the 0x1029 NMT reaction to a communication error
 * and the hand-over to the device profile's reaction (CiA 402 0x6007).
 */
#include "hd_co_util.h"
#include "hd_co_internal.h"

/* heartbeat lost or bus-off: EMCY (held back while off the bus), NMT and drive reactions */
void hd_co__comm_error(hd_co_t *co, uint16_t code, const uint8_t mfr[5])
{
    hd_co_emcy(co, code, HD_CO_ER_COMM, mfr);
    switch (co->od.error_behavior_communication_error) {
    case 0u:
        if (co->nmt == HD_CO_NMT_OP) {
            co->nmt = HD_CO_NMT_PREOP;
        }
        break;
    case 2u:
        co->nmt = HD_CO_NMT_STOPPED;
        hd_co__sdo_reset(co, true);
        break;
    default:
        break;                            /* 1: no NMT state change */
    }
    if (co->app.profile != NULL) {
        co->app.profile->comm_error(co->app.profile_ctx, co, code);
    }
}

void hd_co_can_state(hd_co_t *co, uint8_t state)
{
    const uint8_t old = co->can_state;
    if (state > HD_HAL_CAN_BUS_OFF || state == old) {
        return;
    }
    co->can_state = state;
    if (state == HD_HAL_CAN_BUS_OFF) {
        co->stats.can_bus_off++;
        co->can_recover_us = co->now_us + (uint64_t)HD_CO_BUSOFF_RESTART_MS * 1000u;
        hd_co__comm_error(co, HD_CO_EMCY_BUS_OFF, NULL);      /* the EMCY waits for the bus */
        return;
    }
    if (old == HD_HAL_CAN_BUS_OFF) {
        co->stats.can_recovered++;
        co->hbc_last_us = co->now_us;                  /* the consumer's time restarts on the bus */
        if (co->emcy_pending && co->now_us >= co->emcy_inhibit_until_us) {
            co->emcy_pending = 0u;
            hd_co__emcy_send(co, co->emcy_pending_data);      /* the 0x8140 held back at bus-off */
        }
    }
    if (state == HD_HAL_CAN_ERROR_PASSIVE) {
        co->stats.can_passive++;
        hd_co_emcy(co, HD_CO_EMCY_CAN_PASSIVE, HD_CO_ER_COMM, NULL);
    } else if ((co->app.profile == NULL || !co->app.profile->faulted(co->app.profile_ctx, co)) &&
               !co->hbc_lost && !co->emcy_pending) {
        hd_co_emcy_clear(co, HD_CO_ER_COMM);            /* error active, nothing else pending */
    }
}

void hd_co__can_tick(hd_co_t *co)
{
    /* CAN controller state; bus-off: request the recovery every HD_CO_BUSOFF_RESTART_MS */
    if (co->app.can_status != NULL) {
        hd_hal_can_status_t cs;
        hd_co_fill(&cs, 0u, sizeof cs);
        co->app.can_status(co->app.ctx, &cs);
        hd_co_can_state(co, cs.state);
    }
    if (co->can_state == HD_HAL_CAN_BUS_OFF && co->now_us >= co->can_recover_us) {
        co->can_recover_us = co->now_us + (uint64_t)HD_CO_BUSOFF_RESTART_MS * 1000u;
        if (co->app.can_recover != NULL) {
            co->app.can_recover(co->app.ctx);
        }
    }
}
