/*
 * hd_co_emcy.c - CiA 301 EMCY producer: the error register (0x1001), the
 * pre-defined error field (0x1003), the EMCY frame with its inhibit time (0x1015), held
 * back while off the bus.
 */
#include "hd_co_util.h"
#include "hd_co_internal.h"

void hd_co__emcy_send(hd_co_t *co, const uint8_t d[8])
{
    uint32_t cob = co->od.cob_id_emcy;
    if ((cob & 0x80000000u) != 0u || co->nmt == HD_CO_NMT_STOPPED || co->nmt == HD_CO_NMT_INIT) {
        return;
    }
    if (co->now_us < co->emcy_inhibit_until_us || co->can_state == HD_HAL_CAN_BUS_OFF) {
        /* inhibit time running, or off the bus: the newest one goes out when possible */
        hd_co_copy(co->emcy_pending_data, d, 8u);
        co->emcy_pending = 1u;
        return;
    }
    hd_co__send(co, cob & 0x7FFu, 8u, d);
    co->stats.emcy_sent++;
    co->emcy_inhibit_until_us = co->now_us + (uint64_t)co->od.inhibit_time_emcy * 100u;
}

void hd_co_emcy(hd_co_t *co, uint16_t code, uint8_t reg_bits, const uint8_t mfr[5])
{
    co->od.error_register = (uint8_t)(co->od.error_register | reg_bits | HD_CO_ER_GENERIC);
    if (code != 0u) {
        hd_co_copy(&co->err_hist[1], &co->err_hist[0], (HD_CO_ERR_HIST - 1u) * sizeof co->err_hist[0]);
        co->err_hist[0] = code;
        if (co->n_err < HD_CO_ERR_HIST) {
            co->n_err++;
        }
    }
    uint8_t d[8] = {0};
    d[0] = (uint8_t)(code & 0xFFu);
    d[1] = (uint8_t)(code >> 8);
    d[2] = co->od.error_register;
    if (mfr != NULL) {
        hd_co_copy(&d[3], mfr, 5u);
    }
    hd_co__emcy_send(co, d);
}

void hd_co_emcy_clear(hd_co_t *co, uint8_t reg_bits)
{
    uint8_t before = co->od.error_register;
    uint8_t r = (uint8_t)(before & (uint8_t)~reg_bits);
    if ((r & (uint8_t)~HD_CO_ER_GENERIC) == 0u) {
        r = 0u;
    }
    co->od.error_register = r;
    if (before != 0u && r == 0u) {
        uint8_t d[8] = {0};
        hd_co__emcy_send(co, d);
    }
}

void hd_co__emcy_tick(hd_co_t *co)
{
    if (co->emcy_pending && co->now_us >= co->emcy_inhibit_until_us && co->can_state != HD_HAL_CAN_BUS_OFF) {
        co->emcy_pending = 0u;
        hd_co__emcy_send(co, co->emcy_pending_data);
    }
}
