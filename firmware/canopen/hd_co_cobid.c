/*
 * hd_co_cobid.c - CiA 301 COB-ID rules of the node's SYNC, EMCY and PDO objects:
 * 11-bit identifiers only, none of the restricted CAN-IDs, no identifier used twice
 * (docs/can.md, COB-IDs).
 */
#include "hd_co_internal.h"

/* The COB-ID objects, in one order: 0 SYNC, 1 EMCY, 2.. RPDOs, then TPDOs; -1 for none. */
typedef enum {
    COB_SYNC = 0,
    COB_EMCY = 1,
    COB_RPDO = 2,
    COB_TPDO = 2 + (int)HD_CO_N_PDO,
    COB_COUNT = 2 + 2 * (int)HD_CO_N_PDO
} hd_co_cob_slot_t;

static int32_t cob_slot(uint16_t index, uint8_t sub)
{
    if (index == 0x1005u && sub == 0u) {
        return COB_SYNC;
    }
    if (index == 0x1014u && sub == 0u) {
        return COB_EMCY;
    }
    if (sub == 1u && index >= 0x1400u && index < 0x1400u + HD_CO_N_PDO) {
        return COB_RPDO + (int32_t)(index - 0x1400u);
    }
    if (sub == 1u && index >= 0x1800u && index < 0x1800u + HD_CO_N_PDO) {
        return COB_TPDO + (int32_t)(index - 0x1800u);
    }
    return -1;
}

/* the value in force of COB-ID object `slot` */
static uint32_t cob_value(const hd_co_t *co, int32_t slot)
{
    if (slot == COB_SYNC) {
        return co->od.cob_id_sync;
    }
    if (slot == COB_EMCY) {
        return co->od.cob_id_emcy;
    }
    if (slot < COB_TPDO) {
        return co->od.rpdo_cob[slot - COB_RPDO];
    }
    return co->od.tpdo_cob[slot - COB_TPDO];
}

/* CiA 301 restricted CAN-IDs: NMT, the reserved block below SYNC, 0x101-0x180 (reserved, and
 * no node 0 for 0x180), every node's SDO, 0x6E0-0x6FF, every node's heartbeat, LSS and the rest */
static bool cob_restricted(uint32_t id)
{
    return id <= 0x07Fu || (id >= 0x101u && id <= 0x180u) || (id >= 0x581u && id <= 0x5FFu) ||
           (id >= 0x601u && id <= 0x67Fu) || (id >= 0x6E0u && id <= 0x6FFu) || id >= 0x701u;
}

bool hd_co_cobid_allowed(const hd_co_t *co, uint16_t index, uint8_t sub, uint32_t v)
{
    const int32_t slot = cob_slot(index, sub);
    if (slot < 0) {
        return false;
    }
    /* SYNC: this device consumes it, so no "generate" bit 30, and there is no invalid bit;
     * EMCY / PDO: bit 31 invalid; bit 30 (PDO: RTR) and bit 29 (29-bit frame) never */
    const uint32_t reserved = (slot == COB_SYNC) ? ~HD_CO_COB_ID_MASK : (~HD_CO_COB_ID_MASK & ~HD_CO_COB_INVALID);
    if ((v & reserved) != 0u) {
        return false;
    }
    if ((v & HD_CO_COB_INVALID) != 0u) {
        return true;                         /* not in use: any identifier until it is valid */
    }
    const uint32_t id = v & HD_CO_COB_ID_MASK;
    if (cob_restricted(id)) {
        return false;
    }
    for (int32_t k = 0; k < COB_COUNT; k++) {
        const uint32_t other = cob_value(co, k);
        if (k != slot && (other & HD_CO_COB_INVALID) == 0u && (other & HD_CO_COB_ID_MASK) == id) {
            return false;                    /* another of the node's services uses it */
        }
    }
    return true;
}

bool hd_co_cobids_ok(const hd_co_t *co)
{
    static const uint16_t base[4] = {0x1005u, 0x1014u, 0x1400u, 0x1800u};
    for (int32_t k = 0; k < COB_COUNT; k++) {
        uint16_t index;
        uint8_t sub;
        if (k < COB_RPDO) {
            index = base[k];
            sub = 0u;
        } else if (k < COB_TPDO) {
            index = (uint16_t)(base[2] + (uint32_t)(k - COB_RPDO));
            sub = 1u;
        } else {
            index = (uint16_t)(base[3] + (uint32_t)(k - COB_TPDO));
            sub = 1u;
        }
        if (!hd_co_cobid_allowed(co, index, sub, cob_value(co, k))) {
            return false;
        }
    }
    return true;
}

