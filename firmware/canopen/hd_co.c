/*
 * hd_co.c - CiA 301 services of the drive (see hd_co.h).
 */
#include "hd_crc32.h"
#include <stddef.h>
#include "hd_co_util.h"
#include "hd_co.h"

/* SDO server states. */
enum {
    SDO_IDLE = 0,
    SDO_DL_SEG,
    SDO_UL_SEG,
    SDO_BLK_DL,
    SDO_BLK_DL_END,
    SDO_BLK_UL_INIT,
    SDO_BLK_UL_SEND,
    SDO_BLK_UL_ACK,
    SDO_BLK_UL_END
};

/* ---- small helpers ------------------------------------------------------ */

static uint32_t rd_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void wr_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)((v >> 24) & 0xFFu);
}

static uint32_t type_size(uint8_t t)
{
    switch (t) {
    case HD_CO_T_BOOL: case HD_CO_T_I8: case HD_CO_T_U8: return 1u;
    case HD_CO_T_I16: case HD_CO_T_U16: return 2u;
    case HD_CO_T_I32: case HD_CO_T_U32: return 4u;
    case HD_CO_T_I64: case HD_CO_T_U64: return 8u;
    default: return 0u;
    }
}

static bool type_signed(uint8_t t)
{
    return t == HD_CO_T_I8 || t == HD_CO_T_I16 || t == HD_CO_T_I32 || t == HD_CO_T_I64;
}

/* Little-endian bytes -> int64 (sign-extended for signed types). */
static int64_t decode_le(const uint8_t *p, uint32_t n, bool sgn)
{
    uint64_t u = 0u;
    for (uint32_t i = 0u; i < n; i++) {
        u |= (uint64_t)p[i] << (8u * i);
    }
    if (sgn && n > 0u && n < 8u && (u & ((uint64_t)1u << (8u * n - 1u))) != 0u) {
        u |= ~(uint64_t)0u << (8u * n);
    }
    /* two's complement reinterpretation without implementation-defined conversion */
    if (u > (uint64_t)INT64_MAX) {
        return -(int64_t)(~u) - 1;
    }
    return (int64_t)u;
}

static void encode_le(uint8_t *p, uint32_t n, int64_t v)
{
    uint64_t u = (uint64_t)v;
    for (uint32_t i = 0u; i < n; i++) {
        p[i] = (uint8_t)((u >> (8u * i)) & 0xFFu);
    }
}

static uint8_t *var_ptr(hd_co_t *co, const hd_co_entry_t *e)
{
    return (uint8_t *)&co->od + e->arg;
}

/* Store / load a VAR through memcpy of the native object (the data struct has
 * the C type of each entry; host and MCU are little endian either way). */
static void var_store(hd_co_t *co, const hd_co_entry_t *e, int64_t v)
{
    uint8_t *p = var_ptr(co, e);
    switch (type_size(e->type)) {
    case 1u: { uint8_t x = (uint8_t)((uint64_t)v & 0xFFu); hd_co_copy(p, &x, 1u); break; }
    case 2u: { uint16_t x = (uint16_t)((uint64_t)v & 0xFFFFu); hd_co_copy(p, &x, 2u); break; }
    case 4u: { uint32_t x = (uint32_t)((uint64_t)v & 0xFFFFFFFFu); hd_co_copy(p, &x, 4u); break; }
    case 8u: { uint64_t x = (uint64_t)v; hd_co_copy(p, &x, 8u); break; }
    default: break;
    }
}

static int64_t var_load(const hd_co_t *co, const hd_co_entry_t *e)
{
    const uint8_t *p = (const uint8_t *)&co->od + e->arg;
    uint8_t b[8];
    uint32_t n = type_size(e->type);
    switch (n) {
    case 1u: { uint8_t x; hd_co_copy(&x, p, 1u); b[0] = x; break; }
    case 2u: { uint16_t x; hd_co_copy(&x, p, 2u); encode_le(b, 2u, (int64_t)x); break; }
    case 4u: { uint32_t x; hd_co_copy(&x, p, 4u); encode_le(b, 4u, (int64_t)x); break; }
    case 8u: { uint64_t x; hd_co_copy(&x, p, 8u); return decode_le((const uint8_t *)&x, 8u, true); }
    default: return 0;
    }
    return decode_le(b, n, type_signed(e->type));
}

uint16_t hd_co_crc16(uint16_t crc, const uint8_t *p, uint32_t len)
{
    uint32_t c = crc;
    for (uint32_t i = 0u; i < len; i++) {
        c ^= (uint32_t)p[i] << 8;
        for (uint32_t k = 0u; k < 8u; k++) {
            c = (c & 0x8000u) != 0u ? ((c << 1) ^ 0x1021u) : (c << 1);
            c &= 0xFFFFu;
        }
    }
    return (uint16_t)c;
}

static void co_send(hd_co_t *co, uint32_t id, uint8_t dlc, const uint8_t *data)
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

static bool co_try_send(hd_co_t *co, uint32_t id, uint8_t dlc, const uint8_t *data)
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

/* ---- object dictionary access ------------------------------------------ */

int32_t hd_co_find(const hd_co_t *co, uint16_t index, uint8_t sub)
{
    uint32_t lo = 0u, hi = co->count;
    uint32_t key = ((uint32_t)index << 8) | sub;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2u;
        const hd_co_entry_t *e = &co->table[mid];
        uint32_t k = ((uint32_t)e->index << 8) | e->sub;
        if (k == key) {
            return (int32_t)mid;
        }
        if (k < key) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return -1;
}

/* 0 and the entry number, or the abort code for a missing object/sub. */
static uint32_t lookup(const hd_co_t *co, uint16_t index, uint8_t sub, uint32_t *ent)
{
    int32_t i = hd_co_find(co, index, sub);
    if (i >= 0) {
        *ent = (uint32_t)i;
        return 0u;
    }
    /* does the index exist at all? */
    uint32_t lo = 0u, hi = co->count;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2u;
        if (co->table[mid].index < index) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    if (lo < co->count && co->table[lo].index == index) {
        return HD_CO_AB_NO_SUB;
    }
    return HD_CO_AB_NO_OBJECT;
}

/* lookup for a master (SDO): the device profile's filter first (hd_co_app_if_t.object_filter) */
static uint32_t sdo_lookup(const hd_co_t *co, uint16_t index, uint8_t sub, uint32_t *ent)
{
    if (co->app.object_filter != NULL) {
        const uint32_t ab = co->app.object_filter(co->app.ctx, index, sub);
        if (ab != 0u) {
            return ab;
        }
    }
    return lookup(co, index, sub, ent);
}

static uint32_t special_read(hd_co_t *co, const hd_co_entry_t *e, int64_t *v)
{
    if (e->sub == 0u && e->index != 0x1003u && e->index != 0x5000u) {
        *v = e->def;            /* highest sub-index supported */
        return 0u;
    }
    switch (e->index) {
    case 0x1003u:
        if (e->sub == 0u) {
            *v = co->n_err;
        } else {
            *v = (e->sub <= co->n_err) ? (int64_t)co->err_hist[e->sub - 1u] : 0;
        }
        return 0u;
    case 0x1010u:
    case 0x1011u:
        *v = 1;                 /* saves / restores on command */
        return 0u;
    default:
        if (co->app.special_read != NULL) {
            return co->app.special_read(co->app.ctx, e->index, e->sub, v);
        }
        *v = 0;
        return 0u;
    }
}

uint32_t hd_co_read(hd_co_t *co, uint32_t ent, uint8_t *buf, uint32_t cap, uint32_t *len)
{
    const hd_co_entry_t *e = &co->table[ent];
    int64_t v = 0;
    uint32_t n = type_size(e->type);
    switch (e->kind) {
    case HD_CO_K_STR: {
        uint32_t l = (uint32_t)hd_co_strlen(e->str);
        if (l > cap) {
            l = cap;
        }
        hd_co_copy(buf, e->str, l);
        *len = l;
        return 0u;
    }
    case HD_CO_K_DOMAIN:
        return HD_CO_AB_GENERAL;
    case HD_CO_K_PARAM:
        if (co->app.param_get == NULL) {
            return HD_CO_AB_GENERAL;
        }
        v = co->app.param_get(co->app.ctx, e->arg);
        break;
    case HD_CO_K_SPECIAL: {
        uint32_t ab = special_read(co, e, &v);
        if (ab != 0u) {
            return ab;
        }
        break;
    }
    default:
        v = var_load(co, e);
        break;
    }
    if (n > cap) {
        return HD_CO_AB_GENERAL;
    }
    encode_le(buf, n, v);
    *len = n;
    return 0u;
}

/* ---- PDO configuration -------------------------------------------------- */

static void pdo_rebuild(hd_co_t *co, bool tx, uint32_t i);

/* Check one mapping value for PDO i: 0 or an abort code. */
static uint32_t map_check(const hd_co_t *co, bool tx, uint32_t v, uint32_t *bits)
{
    uint16_t idx = (uint16_t)(v >> 16);
    uint8_t sub = (uint8_t)((v >> 8) & 0xFFu);
    uint32_t nb = v & 0xFFu;
    *bits = 0u;
    if (v == 0u) {
        return 0u;
    }
    /* an object outside the device profile cannot be mapped (it is absent for the master) */
    if (co->app.object_filter != NULL && co->app.object_filter(co->app.ctx, idx, sub) != 0u) {
        return HD_CO_AB_NO_MAP;
    }
    int32_t i = hd_co_find(co, idx, sub);
    if (i < 0) {
        return HD_CO_AB_NO_MAP;
    }
    const hd_co_entry_t *e = &co->table[i];
    uint8_t need = tx ? HD_CO_F_TPDO : HD_CO_F_RPDO;
    if ((e->flags & need) == 0u || e->kind != HD_CO_K_VAR || nb != 8u * type_size(e->type)) {
        return HD_CO_AB_NO_MAP;
    }
    *bits = nb;
    return 0u;
}

/* ---- COB-IDs (CiA 301) ---------------------------------------------------- */

#define COB_INVALID   0x80000000u      /* EMCY / PDO: the object is not used */
#define COB_ID_MASK   0x7FFu

/* The COB-ID objects, in one order: 0 SYNC, 1 EMCY, 2.. RPDOs, then TPDOs; -1 for none. */
enum { COB_SYNC = 0, COB_EMCY = 1, COB_RPDO = 2, COB_TPDO = 2 + (int)HD_CO_N_PDO, COB_COUNT = 2 + 2 * (int)HD_CO_N_PDO };

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
    const uint32_t reserved = (slot == COB_SYNC) ? ~COB_ID_MASK : (~COB_ID_MASK & ~COB_INVALID);
    if ((v & reserved) != 0u) {
        return false;
    }
    if ((v & COB_INVALID) != 0u) {
        return true;                         /* not in use: any identifier until it is valid */
    }
    const uint32_t id = v & COB_ID_MASK;
    if (cob_restricted(id)) {
        return false;
    }
    for (int32_t k = 0; k < COB_COUNT; k++) {
        const uint32_t other = cob_value(co, k);
        if (k != slot && (other & COB_INVALID) == 0u && (other & COB_ID_MASK) == id) {
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

/* Object-specific rules before a write is accepted. */
static uint32_t check_write(hd_co_t *co, const hd_co_entry_t *e, int64_t v)
{
    uint16_t ix = e->index;
    if (ix >= 0x1400u && ix < 0x1C00u) {
        bool tx = ix >= 0x1800u;
        bool map = (ix & 0x0200u) != 0u;
        uint32_t i = (uint32_t)(ix & 0x1FFu);
        if (i >= HD_CO_N_PDO) {
            return HD_CO_AB_NO_OBJECT;
        }
        if (map) {
            uint8_t nmap = tx ? co->od.tpdo_nmap[i] : co->od.rpdo_nmap[i];
            const uint32_t *m = tx ? co->od.tpdo_map[i] : co->od.rpdo_map[i];
            if (e->sub == 0u) {
                if (v > (int64_t)HD_CO_N_MAP) {
                    return HD_CO_AB_VALUE_HIGH;
                }
                uint32_t total = 0u;
                for (uint32_t k = 0u; k < (uint32_t)v; k++) {
                    uint32_t bits;
                    uint32_t ab = map_check(co, tx, m[k], &bits);
                    if (ab != 0u) {
                        return ab;
                    }
                    if (bits == 0u) {
                        return HD_CO_AB_NO_MAP;
                    }
                    total += bits;
                }
                if (total > 64u) {
                    return HD_CO_AB_MAP_LEN;
                }
                return 0u;
            }
            if (nmap != 0u) {
                return HD_CO_AB_STATE;   /* mapping is changed only with sub 0 = 0 */
            }
            uint32_t bits;
            return map_check(co, tx, (uint32_t)v, &bits);
        }
        uint32_t cob = tx ? co->od.tpdo_cob[i] : co->od.rpdo_cob[i];
        if (e->sub == 1u) {
            uint32_t nv = (uint32_t)v;
            if ((cob & COB_INVALID) == 0u && (nv & COB_INVALID) == 0u && (nv & COB_ID_MASK) != (cob & COB_ID_MASK)) {
                return HD_CO_AB_VALUE;   /* valid PDO: disable before changing the id */
            }
            return hd_co_cobid_allowed(co, ix, e->sub, nv) ? 0u : HD_CO_AB_VALUE;
        }
        if (e->sub == 2u) {
            if (!(v <= 240 || v == 254 || v == 255)) {
                return HD_CO_AB_VALUE;
            }
            return 0u;
        }
        if (e->sub == 3u && (cob & 0x80000000u) == 0u && tx) {
            return HD_CO_AB_STATE;   /* inhibit time only while not valid */
        }
        return 0u;
    }
    switch (ix) {
    case 0x1005u:
    case 0x1014u:
        return hd_co_cobid_allowed(co, ix, e->sub, (uint32_t)v) ? 0u : HD_CO_AB_VALUE;
    case 0x1016u: {
        uint32_t node = ((uint32_t)v >> 16) & 0xFFu;
        if (node > 127u || (node == co->node_id && ((uint32_t)v & 0xFFFFu) != 0u)) {
            return HD_CO_AB_VALUE;
        }
        return 0u;
    }
    case 0x6060u:
        return hd_co402_check_mode(v);
    default:
        return 0u;
    }
}

static void after_write(hd_co_t *co, const hd_co_entry_t *e)
{
    uint16_t ix = e->index;
    if (ix >= 0x1400u && ix < 0x1C00u) {
        pdo_rebuild(co, ix >= 0x1800u, (uint32_t)(ix & 0x1FFu));
        return;
    }
    switch (ix) {
    case 0x1017u:
        co->hb_next_us = co->now_us + (uint64_t)co->od.producer_heartbeat_time * 1000u;
        break;
    case 0x1016u:
        co->hbc_active = 0u;
        co->hbc_lost = 0u;
        break;
    case 0x6040u:
        hd_co402_controlword(co);
        break;
    default:
        break;
    }
}

static uint32_t special_write(hd_co_t *co, const hd_co_entry_t *e, int64_t v)
{
    switch (e->index) {
    case 0x1003u:
        if (e->sub != 0u) {
            return HD_CO_AB_READONLY;
        }
        if (v != 0) {
            return HD_CO_AB_VALUE;
        }
        co->n_err = 0u;
        hd_co_fill(co->err_hist, 0u, sizeof co->err_hist);
        return 0u;
    case 0x1010u:
        if (v != 0x65766173) {            /* "save" */
            return HD_CO_AB_STORE;
        }
        return co->app.store != NULL ? co->app.store(co->app.ctx) : HD_CO_AB_STORE;
    case 0x1011u:
        if (v != 0x64616F6C) {            /* "load" */
            return HD_CO_AB_STORE;
        }
        return co->app.restore != NULL ? co->app.restore(co->app.ctx) : HD_CO_AB_STORE;
    default:
        if (co->app.special_write != NULL) {
            return co->app.special_write(co->app.ctx, e->index, e->sub, v);
        }
        return HD_CO_AB_READONLY;
    }
}

uint32_t hd_co_write(hd_co_t *co, uint32_t ent, const uint8_t *buf, uint32_t len)
{
    const hd_co_entry_t *e = &co->table[ent];
    uint32_t n = type_size(e->type);
    if (e->kind == HD_CO_K_DOMAIN || e->kind == HD_CO_K_STR || n == 0u) {
        return HD_CO_AB_TYPE_LEN;
    }
    if (len > n) {
        return HD_CO_AB_LEN_HIGH;
    }
    if (len < n) {
        return HD_CO_AB_LEN_LOW;
    }
    int64_t v = decode_le(buf, n, type_signed(e->type));
    if (e->type == HD_CO_T_BOOL && v > 1) {
        return HD_CO_AB_VALUE;
    }
    if (e->type == HD_CO_T_U64) {
        if (v < 0) {
            return HD_CO_AB_VALUE_HIGH;   /* above INT64_MAX */
        }
    }
    if (v < e->min) {
        return HD_CO_AB_VALUE_LOW;
    }
    if (v > e->max) {
        return HD_CO_AB_VALUE_HIGH;
    }
    if (e->kind == HD_CO_K_SPECIAL) {
        return special_write(co, e, v);
    }
    if (e->kind == HD_CO_K_PARAM) {
        if (co->app.param_set == NULL) {
            return HD_CO_AB_GENERAL;
        }
        return co->app.param_set(co->app.ctx, e->arg, (int32_t)v);
    }
    uint32_t ab = check_write(co, e, v);
    if (ab != 0u) {
        return ab;
    }
    var_store(co, e, v);
    after_write(co, e);
    return 0u;
}

uint32_t hd_co_get_i64(hd_co_t *co, uint16_t index, uint8_t sub, int64_t *v)
{
    uint32_t ent;
    uint32_t ab = lookup(co, index, sub, &ent);
    if (ab != 0u) {
        return ab;
    }
    uint8_t b[HD_CO_SDO_BUF];
    uint32_t n = 0u;
    ab = hd_co_read(co, ent, b, sizeof b, &n);
    if (ab != 0u) {
        return ab;
    }
    if (n > 8u) {
        return HD_CO_AB_TYPE_LEN;
    }
    *v = decode_le(b, n, type_signed(co->table[ent].type));
    return 0u;
}

uint32_t hd_co_set_i64(hd_co_t *co, uint16_t index, uint8_t sub, int64_t v)
{
    uint32_t ent;
    uint32_t ab = lookup(co, index, sub, &ent);
    if (ab != 0u) {
        return ab;
    }
    uint8_t b[8];
    uint32_t n = type_size(co->table[ent].type);
    encode_le(b, n, v);
    return hd_co_write(co, ent, b, n);
}

/* ---- defaults ------------------------------------------------------------ */

static void load_defaults(hd_co_t *co, uint16_t lo, uint16_t hi)
{
    for (uint32_t i = 0u; i < co->count; i++) {
        const hd_co_entry_t *e = &co->table[i];
        if (e->kind != HD_CO_K_VAR || e->index < lo || e->index > hi) {
            continue;
        }
        int64_t v = e->def;
        if ((e->flags & HD_CO_F_NODEID) != 0u) {
            v += co->node_id;
        }
        var_store(co, e, v);
    }
}

/* ---- stored objects (0x1010 save; hd_co.h hd_co_store_*) --------------------------- */

/* in the stored image only: the COB-ID is its default base + the node id, so the image
 * follows a change of the node id like the defaults do */
#define STORE_NODEREL 0x08000000u

static bool is_stored(const hd_co_entry_t *e)
{
    return e->kind == HD_CO_K_VAR && (e->flags & HD_CO_F_STORE) != 0u && type_size(e->type) <= 4u;
}

uint32_t hd_co_store_words(const hd_co_t *co)
{
    uint32_t n = 1u;
    for (uint32_t i = 0u; i < co->count; i++) {
        n += is_stored(&co->table[i]) ? 1u : 0u;
    }
    return n;
}

uint32_t hd_co_store_layout(const hd_co_t *co)
{
    uint32_t crc = 0u;
    for (uint32_t i = 0u; i < co->count; i++) {
        const hd_co_entry_t *e = &co->table[i];
        if (is_stored(e)) {
            const uint8_t b[5] = {(uint8_t)(e->index & 0xFFu), (uint8_t)(e->index >> 8), e->sub, e->type, e->flags};
            crc = hd_crc32(crc, b, 5u);
        }
    }
    return crc;
}

/* live value of a stored entry -> its image word */
static uint32_t store_encode(const hd_co_t *co, const hd_co_entry_t *e)
{
    const uint32_t u = (uint32_t)((uint64_t)var_load(co, e) & 0xFFFFFFFFu);
    if ((e->flags & HD_CO_F_NODEID) != 0u && (u & 0x7FFu) == (((uint32_t)e->def + co->node_id) & 0x7FFu)) {
        return (u - co->node_id) | STORE_NODEREL;
    }
    return u;
}

/* image word -> value of a stored entry (the inverse of store_encode) */
static int64_t store_decode(const hd_co_t *co, const hd_co_entry_t *e, uint32_t w)
{
    uint8_t b[4];
    if ((e->flags & HD_CO_F_NODEID) != 0u && (w & STORE_NODEREL) != 0u) {
        w = (w & ~STORE_NODEREL) + co->node_id;
    }
    encode_le(b, 4u, (int64_t)w);
    return decode_le(b, type_size(e->type), type_signed(e->type));
}

uint32_t hd_co_store_word(const hd_co_t *co, uint32_t w)
{
    uint32_t k = 1u;
    if (w == 0u) {
        return hd_co_store_layout(co);
    }
    for (uint32_t i = 0u; i < co->count; i++) {
        const hd_co_entry_t *e = &co->table[i];
        if (is_stored(e)) {
            if (k == w) {
                return store_encode(co, e);
            }
            k++;
        }
    }
    return 0u;
}

/* Where an entry's image word is written when an image is applied: in the order a
 * master follows over SDO (CiA 301 PDO reconfiguration), so that every write passes the
 * same object rules as an SDO download does. */
typedef enum {
    STORE_STEP_DISABLE = 0,   /* PDO and EMCY COB-IDs with bit 31 set: the objects off */
    STORE_STEP_UNMAP = 1,     /* PDO mapping counts to 0: entries may change */
    STORE_STEP_VALUES = 2,    /* every other entry: mapping entries, types, timers, ... */
    STORE_STEP_MAP = 3,       /* PDO mapping counts: the mapping is checked whole */
    STORE_STEP_COBID = 4,     /* PDO and EMCY COB-IDs as stored: restricted ids are refused here */
    STORE_STEP_N = 5
} store_step_t;

/* a COB-ID whose bit 31 means "not valid" (PDO, EMCY): written invalid first, as stored last */
static bool is_pdo_cobid(const hd_co_entry_t *e)
{
    return (e->sub == 1u && ((e->index >= 0x1400u && e->index < 0x1600u) || (e->index >= 0x1800u && e->index < 0x1A00u))) ||
           (e->index == 0x1014u && e->sub == 0u);
}

static bool is_pdo_nmap(const hd_co_entry_t *e)
{
    return e->sub == 0u && ((e->index >= 0x1600u && e->index < 0x1800u) || (e->index >= 0x1A00u && e->index < 0x1C00u));
}

/* the value an entry gets in a step (false: the entry is not written in that step) */
static bool store_step_value(const hd_co_entry_t *e, store_step_t step, int64_t stored, int64_t *v)
{
    if (is_pdo_cobid(e)) {
        if (step == STORE_STEP_DISABLE) {
            *v = (int64_t)((uint32_t)stored | 0x80000000u);
            return true;
        }
        *v = stored;
        return step == STORE_STEP_COBID;
    }
    if (is_pdo_nmap(e)) {
        *v = (step == STORE_STEP_UNMAP) ? 0 : stored;
        return step == STORE_STEP_UNMAP || step == STORE_STEP_MAP;
    }
    *v = stored;
    return step == STORE_STEP_VALUES;
}

static uint32_t check_access(const hd_co_t *co, uint32_t ent, bool write);

/* one value through the SDO download path: access, length, range, object rules */
static uint32_t store_write(hd_co_t *co, uint32_t ent, int64_t v)
{
    uint8_t b[8];
    const uint32_t n = type_size(co->table[ent].type);
    uint32_t ab = check_access(co, ent, true);
    if (ab != 0u) {
        return ab;
    }
    encode_le(b, n, v);
    return hd_co_write(co, ent, b, n);
}

/* the stored entries in [lo, hi] to their defaults (the PDOs are rebuilt by the caller) */
static void store_defaults_range(hd_co_t *co, uint16_t lo, uint16_t hi)
{
    for (uint32_t i = 0u; i < co->count; i++) {
        const hd_co_entry_t *e = &co->table[i];
        if (is_stored(e) && e->index >= lo && e->index <= hi) {
            var_store(co, e, e->def + (((e->flags & HD_CO_F_NODEID) != 0u) ? (int64_t)co->node_id : 0));
        }
    }
}

int32_t hd_co_store_apply(hd_co_t *co, const uint32_t *img, uint32_t words, uint16_t lo, uint16_t hi)
{
    uint32_t k;
    uint32_t ab = 0u;
    co->store_refused_index = 0u;
    co->store_refused_sub = 0u;
    co->store_refused_abort = 0u;
    if (words != hd_co_store_words(co) || img[0] != hd_co_store_layout(co)) {
        return -1;
    }
    /* every value inside its entry's limits before anything is written */
    k = 1u;
    for (uint32_t i = 0u; i < co->count; i++) {
        const hd_co_entry_t *e = &co->table[i];
        if (is_stored(e)) {
            const int64_t v = store_decode(co, e, img[k]);
            if (v < e->min || v > e->max) {
                return -1;
            }
            k++;
        }
    }
    /* Then the image goes in through the SDO write checks (mapping rules, COB-ID rules,
     * whatever an SDO download is refused for), in the CiA 301 order; a CRC-valid image
     * is not trusted more than a master.  The first refusal puts the defaults of the
     * stored entries back, so nothing of a refused image stays in force.  (Rolling back
     * to defaults, not to a scratch copy of the dictionary: the drive's stack has no room
     * for a second hd_co_t, and defaults are what a refused image means anyway.) */
    for (uint32_t step = 0u; step < (uint32_t)STORE_STEP_N && ab == 0u; step++) {
        k = 1u;
        for (uint32_t i = 0u; i < co->count && ab == 0u; i++) {
            const hd_co_entry_t *e = &co->table[i];
            int64_t v;
            if (!is_stored(e)) {
                continue;
            }
            if (e->index >= lo && e->index <= hi &&
                store_step_value(e, (store_step_t)step, store_decode(co, e, img[k]), &v)) {
                ab = store_write(co, i, v);
                if (ab != 0u) {
                    co->store_refused_index = e->index;
                    co->store_refused_sub = e->sub;
                    co->store_refused_abort = ab;
                }
            }
            k++;
        }
    }
    if (ab != 0u) {
        store_defaults_range(co, lo, hi);
        /* the side effects of the values written before the refusal follow the defaults
         * too (heartbeat timers, consumer state), as if the defaults had been written */
        for (uint32_t i = 0u; i < co->count; i++) {
            const hd_co_entry_t *e = &co->table[i];
            if (is_stored(e) && e->index >= lo && e->index <= hi) {
                after_write(co, e);
            }
        }
    }
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        pdo_rebuild(co, true, i);
        pdo_rebuild(co, false, i);
    }
    return (ab == 0u) ? 0 : -2;
}

void hd_co_store_capture(hd_co_t *co)
{
    const uint32_t n = hd_co_store_words(co);
    co->stored_ok = 0u;
    if (n <= HD_CO_STORE_MAX) {
        for (uint32_t w = 0u; w < n; w++) {
            co->stored[w] = hd_co_store_word(co, w);
        }
        co->stored_ok = 1u;
    }
}

void hd_co_store_defaults(hd_co_t *co)
{
    store_defaults_range(co, 0x0000u, 0xFFFFu);
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        pdo_rebuild(co, true, i);
        pdo_rebuild(co, false, i);
    }
}

/* ---- PDO runtime ---------------------------------------------------------- */

static void pdo_rebuild(hd_co_t *co, bool tx, uint32_t i)
{
    if (i >= HD_CO_N_PDO) {
        return;
    }
    hd_co_pdo_rt_t *p = tx ? &co->tpdo[i] : &co->rpdo[i];
    uint32_t cob = tx ? co->od.tpdo_cob[i] : co->od.rpdo_cob[i];
    uint8_t nmap = tx ? co->od.tpdo_nmap[i] : co->od.rpdo_nmap[i];
    const uint32_t *m = tx ? co->od.tpdo_map[i] : co->od.rpdo_map[i];
    hd_co_fill(p, 0u, sizeof *p);
    p->type = tx ? co->od.tpdo_type[i] : co->od.rpdo_type[i];
    p->cob = (uint16_t)(cob & 0x7FFu);
    uint32_t len = 0u;
    uint32_t n = 0u;
    bool ok = (cob & 0x80000000u) == 0u && nmap <= HD_CO_N_MAP;
    for (uint32_t k = 0u; ok && k < nmap; k++) {
        int32_t ent = hd_co_find(co, (uint16_t)(m[k] >> 16), (uint8_t)((m[k] >> 8) & 0xFFu));
        if (ent < 0) {
            ok = false;
            break;
        }
        uint32_t sz = type_size(co->table[ent].type);
        if (sz == 0u || len + sz > 8u) {
            ok = false;
            break;
        }
        p->ent[n] = (uint16_t)ent;
        p->esize[n] = (uint8_t)sz;
        n++;
        len += sz;
    }
    p->nmap = (uint8_t)n;
    p->len = (uint8_t)len;
    p->valid = (uint8_t)((ok && n > 0u) ? 1u : 0u);
    p->next_event_us = co->now_us;
}

static void pdo_pack(hd_co_t *co, const hd_co_pdo_rt_t *p, uint8_t *out, bool cos_only, uint8_t *n_out)
{
    uint32_t pos = 0u;
    for (uint32_t k = 0u; k < p->nmap; k++) {
        const hd_co_entry_t *e = &co->table[p->ent[k]];
        if (cos_only && (e->flags & HD_CO_F_COS) == 0u) {
            continue;
        }
        encode_le(out + pos, p->esize[k], var_load(co, e));
        pos += p->esize[k];
    }
    *n_out = (uint8_t)pos;
}

static void tpdo_send(hd_co_t *co, uint32_t i)
{
    hd_co_pdo_rt_t *p = &co->tpdo[i];
    uint8_t d[8] = {0};
    uint8_t n;
    pdo_pack(co, p, d, false, &n);
    co_send(co, p->cob, p->len, d);
    p->inhibit_until_us = co->now_us + (uint64_t)co->od.tpdo_inhibit[i] * 100u;
    if (co->od.tpdo_event[i] != 0u) {
        p->next_event_us = co->now_us + (uint64_t)co->od.tpdo_event[i] * 1000u;
    }
}

/* change of state of the COS-flagged mapped objects since the last look */
static bool tpdo_cos(hd_co_t *co, hd_co_pdo_rt_t *p)
{
    uint8_t d[8] = {0};
    uint8_t n;
    pdo_pack(co, p, d, true, &n);
    bool changed = (n != p->cos_len) || hd_co_diff(d, p->cos_prev, n) != 0;
    hd_co_copy(p->cos_prev, d, sizeof p->cos_prev);
    p->cos_len = n;
    return changed && n > 0u;
}

static uint16_t stream_period(const hd_co_t *co, uint32_t i)
{
    switch (i) {
    case 0u: return co->od.tpdo_stream_period_1;
    case 1u: return co->od.tpdo_stream_period_2;
    case 2u: return co->od.tpdo_stream_period_3;
    default: return co->od.tpdo_stream_period_4;
    }
}

static void tpdo_tick(hd_co_t *co, uint32_t dt_us)
{
    (void)dt_us;
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        hd_co_pdo_rt_t *p = &co->tpdo[i];
        if (!p->valid) {
            continue;
        }
        bool cos = tpdo_cos(co, p);
        if (p->type == 0u && cos) {
            p->cos_armed = 1u;
        }
        if (p->type < 254u) {
            continue;
        }
        bool due = cos;
        uint16_t per = stream_period(co, i);
        if (p->type == 254u && per != 0u && (co->act.tick % per) == 0u) {
            due = true;     /* on loop ticks divisible by the period: all streams in phase */
        }
        if (co->od.tpdo_event[i] != 0u && co->now_us >= p->next_event_us) {
            due = true;
        }
        if (due && co->now_us >= p->inhibit_until_us) {
            tpdo_send(co, i);
        } else if (due) {
            p->cos_armed = 1u;          /* send when the inhibit time has passed */
        } else if (p->cos_armed && co->now_us >= p->inhibit_until_us) {
            p->cos_armed = 0u;
            tpdo_send(co, i);
        }
    }
}

static void rpdo_apply(hd_co_t *co, hd_co_pdo_rt_t *p, const uint8_t *d)
{
    uint32_t pos = 0u;
    for (uint32_t k = 0u; k < p->nmap; k++) {
        const hd_co_entry_t *e = &co->table[p->ent[k]];
        int64_t v = decode_le(d + pos, p->esize[k], type_signed(e->type));
        pos += p->esize[k];
        bool ok = v >= e->min && v <= e->max && !(e->type == HD_CO_T_BOOL && v > 1);
        if (e->type == HD_CO_T_U64 && v < 0) {
            ok = false;
        }
        if (ok && check_write(co, e, v) == 0u) {
            var_store(co, e, v);
            after_write(co, e);
        }
    }
}

static void on_sync(hd_co_t *co, uint8_t counter)
{
    if (co->nmt == HD_CO_NMT_OP) {
        for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
            hd_co_pdo_rt_t *r = &co->rpdo[i];
            if (r->valid && r->rx_pending) {
                r->rx_pending = 0u;
                rpdo_apply(co, r, r->rx_data);
            }
        }
        for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
            hd_co_pdo_rt_t *p = &co->tpdo[i];
            if (!p->valid || p->type > 240u) {
                continue;
            }
            if (p->type == 0u) {
                if (p->cos_armed) {
                    p->cos_armed = 0u;
                    tpdo_send(co, i);
                }
                continue;
            }
            p->sync_cnt++;
            if (p->sync_cnt >= p->type) {
                p->sync_cnt = 0u;
                tpdo_send(co, i);
            }
        }
    }
    if (co->app.on_sync != NULL) {
        co->app.on_sync(co->app.ctx, counter);
    }
}

/* ---- EMCY ----------------------------------------------------------------- */

static void emcy_send(hd_co_t *co, const uint8_t d[8])
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
    co_send(co, cob & 0x7FFu, 8u, d);
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
    emcy_send(co, d);
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
        emcy_send(co, d);
    }
}

/* ---- communication errors (CiA 301 0x1029, CiA 402 0x6007) ------------------ */

static void sdo_reset(hd_co_t *co, bool domain_discard);

/* heartbeat lost or bus-off: EMCY (held back while off the bus), NMT and drive reactions */
static void comm_error(hd_co_t *co, uint16_t code, const uint8_t mfr[5])
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
        sdo_reset(co, true);
        break;
    default:
        break;                            /* 1: no NMT state change */
    }
    hd_co402_abort_connection(co, code);
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
        comm_error(co, HD_CO_EMCY_BUS_OFF, NULL);      /* the EMCY waits for the bus */
        return;
    }
    if (old == HD_HAL_CAN_BUS_OFF) {
        co->stats.can_recovered++;
        co->hbc_last_us = co->now_us;                  /* the consumer's time restarts on the bus */
        if (co->emcy_pending && co->now_us >= co->emcy_inhibit_until_us) {
            co->emcy_pending = 0u;
            emcy_send(co, co->emcy_pending_data);      /* the 0x8140 held back at bus-off */
        }
    }
    if (state == HD_HAL_CAN_ERROR_PASSIVE) {
        co->stats.can_passive++;
        hd_co_emcy(co, HD_CO_EMCY_CAN_PASSIVE, HD_CO_ER_COMM, NULL);
    } else if (co->p402.state != HD_CO402_FAULT && co->p402.state != HD_CO402_FAULT_REACTION &&
               !co->hbc_lost && !co->emcy_pending) {
        hd_co_emcy_clear(co, HD_CO_ER_COMM);            /* error active, nothing else pending */
    }
}

/* ---- SDO server ----------------------------------------------------------- */

static uint32_t sdo_tx_id(const hd_co_t *co) { return 0x580u + co->node_id; }

static void sdo_abort(hd_co_t *co, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t d[8];
    d[0] = 0x80u;
    d[1] = (uint8_t)(index & 0xFFu);
    d[2] = (uint8_t)(index >> 8);
    d[3] = sub;
    wr_u32(&d[4], code);
    co_send(co, sdo_tx_id(co), 8u, d);
    co->last_abort = code;
    co->stats.sdo_aborts_sent++;
}

static void sdo_reset(hd_co_t *co, bool domain_discard)
{
    hd_co_sdo_t *s = &co->sdo;
    if (domain_discard && s->state != SDO_IDLE && co->table[s->ent].kind == HD_CO_K_DOMAIN &&
        (s->state == SDO_DL_SEG || s->state == SDO_BLK_DL || s->state == SDO_BLK_DL_END) &&
        co->app.domain_write_end != NULL) {
        (void)co->app.domain_write_end(co->app.ctx, co->table[s->ent].arg, s->off, false);
    }
    hd_co_fill(s, 0u, sizeof *s);
}

/* abort the running transfer (if any) with code */
static void sdo_fail(hd_co_t *co, uint32_t code)
{
    const hd_co_entry_t *e = &co->table[co->sdo.ent];
    uint16_t ix = co->sdo.state != SDO_IDLE ? e->index : 0u;
    uint8_t sb = co->sdo.state != SDO_IDLE ? e->sub : 0u;
    sdo_reset(co, true);
    sdo_abort(co, ix, sb, code);
}

void hd_co_sdo_abort(hd_co_t *co, uint32_t code)
{
    if (co->sdo.state != SDO_IDLE) {
        sdo_fail(co, code);
    }
}

static void sdo_reply(hd_co_t *co, uint8_t cmd, uint16_t index, uint8_t sub, uint32_t v)
{
    uint8_t d[8];
    d[0] = cmd;
    d[1] = (uint8_t)(index & 0xFFu);
    d[2] = (uint8_t)(index >> 8);
    d[3] = sub;
    wr_u32(&d[4], v);
    co_send(co, sdo_tx_id(co), 8u, d);
}

static bool is_domain(const hd_co_t *co, uint32_t ent) { return co->table[ent].kind == HD_CO_K_DOMAIN; }

/* sink for download data: buffer (values) or domain callback */
static uint32_t dl_sink(hd_co_t *co, const uint8_t *p, uint32_t n)
{
    hd_co_sdo_t *s = &co->sdo;
    if (n == 0u) {
        return 0u;
    }
    if (s->crc_on) {
        s->crc = hd_co_crc16(s->crc, p, n);
    }
    if (is_domain(co, s->ent)) {
        uint32_t ab = co->app.domain_write != NULL
                          ? co->app.domain_write(co->app.ctx, co->table[s->ent].arg, s->off, p, n)
                          : HD_CO_AB_GENERAL;
        if (ab != 0u) {
            return ab;
        }
    } else {
        if (s->off + n > HD_CO_SDO_BUF) {
            return HD_CO_AB_LEN_HIGH;
        }
        hd_co_copy(&s->buf[s->off], p, n);
    }
    s->off += n;
    return 0u;
}

/* download complete: commit (value write or domain commit) */
static uint32_t dl_commit(hd_co_t *co)
{
    hd_co_sdo_t *s = &co->sdo;
    if (s->size != 0u && s->off != s->size) {
        return s->off > s->size ? HD_CO_AB_LEN_HIGH : HD_CO_AB_LEN_LOW;
    }
    if (is_domain(co, s->ent)) {
        uint32_t ab = co->app.domain_write_end != NULL
                          ? co->app.domain_write_end(co->app.ctx, co->table[s->ent].arg, s->off, true)
                          : HD_CO_AB_GENERAL;
        s->state = SDO_IDLE;   /* committed or refused: nothing to discard */
        return ab;
    }
    return hd_co_write(co, s->ent, s->buf, s->off);
}

static uint32_t check_access(const hd_co_t *co, uint32_t ent, bool write)
{
    const hd_co_entry_t *e = &co->table[ent];
    if (write) {
        if ((e->access & HD_CO_A_W) == 0u) {
            return HD_CO_AB_READONLY;
        }
    } else if ((e->access & HD_CO_A_R) == 0u) {
        return HD_CO_AB_WRITEONLY;
    }
    return 0u;
}

static uint32_t ul_size(hd_co_t *co, uint32_t ent, uint32_t *size)
{
    if (is_domain(co, ent)) {
        if (co->app.domain_size == NULL) {
            return HD_CO_AB_GENERAL;
        }
        return co->app.domain_size(co->app.ctx, co->table[ent].arg, size);
    }
    return hd_co_read(co, ent, co->sdo.buf, HD_CO_SDO_BUF, size);
}

/* upload source: bytes [off, off+n) */
static uint32_t ul_source(hd_co_t *co, uint32_t off, uint8_t *out, uint32_t n)
{
    hd_co_sdo_t *s = &co->sdo;
    if (is_domain(co, s->ent)) {
        return co->app.domain_read != NULL ? co->app.domain_read(co->app.ctx, co->table[s->ent].arg, off, out, n)
                                           : HD_CO_AB_GENERAL;
    }
    if (off + n > HD_CO_SDO_BUF) {
        return HD_CO_AB_GENERAL;
    }
    hd_co_copy(out, &s->buf[off], n);
    return 0u;
}

static uint32_t domain_begin(hd_co_t *co, uint32_t ent, uint32_t size)
{
    if (co->app.domain_write_begin == NULL) {
        return HD_CO_AB_GENERAL;
    }
    return co->app.domain_write_begin(co->app.ctx, co->table[ent].arg, size);
}

static void sdo_initiate_download(hd_co_t *co, const uint8_t *d, uint16_t index, uint8_t sub)
{
    hd_co_sdo_t *s = &co->sdo;
    uint32_t ent;
    uint32_t ab = sdo_lookup(co, index, sub, &ent);
    if (ab == 0u) {
        ab = check_access(co, ent, true);
    }
    if (ab != 0u) {
        sdo_abort(co, index, sub, ab);
        return;
    }
    bool e = (d[0] & 0x02u) != 0u;
    bool sz = (d[0] & 0x01u) != 0u;
    uint32_t tsize = type_size(co->table[ent].type);
    if (e) {
        uint32_t n = sz ? 4u - ((uint32_t)(d[0] >> 2) & 3u) : (tsize != 0u && tsize < 4u ? tsize : 4u);
        if (is_domain(co, ent)) {
            ab = domain_begin(co, ent, n);
            if (ab == 0u) {
                s->ent = (uint16_t)ent;
                s->state = SDO_DL_SEG;   /* so that a failure discards */
                ab = dl_sink(co, &d[4], n);
                if (ab == 0u) {
                    ab = dl_commit(co);
                }
                if (ab != 0u) {
                    sdo_fail(co, ab);
                    return;
                }
                sdo_reset(co, false);
            }
        } else if (tsize > 4u) {
            ab = HD_CO_AB_LEN_LOW;
        } else {
            ab = hd_co_write(co, ent, &d[4], n);
        }
        if (ab != 0u) {
            sdo_abort(co, index, sub, ab);
            return;
        }
        sdo_reply(co, 0x60u, index, sub, 0u);
        return;
    }
    uint32_t size = sz ? rd_u32(&d[4]) : 0u;
    if (!is_domain(co, ent)) {
        if (tsize == 0u) {
            sdo_abort(co, index, sub, HD_CO_AB_TYPE_LEN);
            return;
        }
        if (sz && size != tsize) {
            sdo_abort(co, index, sub, size > tsize ? HD_CO_AB_LEN_HIGH : HD_CO_AB_LEN_LOW);
            return;
        }
    } else {
        ab = domain_begin(co, ent, size);
        if (ab != 0u) {
            sdo_abort(co, index, sub, ab);
            return;
        }
    }
    sdo_reset(co, false);
    s->state = SDO_DL_SEG;
    s->ent = (uint16_t)ent;
    s->size = size;
    s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    sdo_reply(co, 0x60u, index, sub, 0u);
}

static void sdo_download_segment(hd_co_t *co, const uint8_t *d)
{
    hd_co_sdo_t *s = &co->sdo;
    uint8_t t = (uint8_t)((d[0] >> 4) & 1u);
    if (t != s->toggle) {
        sdo_fail(co, HD_CO_AB_TOGGLE);
        return;
    }
    uint32_t n = 7u - ((uint32_t)(d[0] >> 1) & 7u);
    uint32_t ab = dl_sink(co, &d[1], n);
    if (ab == 0u && s->size != 0u && s->off > s->size) {
        ab = HD_CO_AB_LEN_HIGH;
    }
    if (ab != 0u) {
        sdo_fail(co, ab);
        return;
    }
    uint8_t reply[8] = {0};
    reply[0] = (uint8_t)(0x20u | ((uint32_t)t << 4));
    if ((d[0] & 0x01u) != 0u) {
        ab = dl_commit(co);
        if (ab != 0u) {
            sdo_fail(co, ab);
            return;
        }
        sdo_reset(co, false);
    } else {
        s->toggle ^= 1u;
        s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    }
    co_send(co, sdo_tx_id(co), 8u, reply);
}

/* Start an upload of index:sub (expedited/segmented or block): look the object up,
 * check read access, reset the SDO state and get the size.  On any refusal the
 * transfer is aborted with the code and false is returned. */
static bool upload_open(hd_co_t *co, uint16_t index, uint8_t sub, uint32_t *size)
{
    hd_co_sdo_t *s = &co->sdo;
    uint32_t ent;
    uint32_t ab = sdo_lookup(co, index, sub, &ent);
    if (ab == 0u) {
        ab = check_access(co, ent, false);
    }
    sdo_reset(co, false);
    *size = 0u;
    if (ab == 0u) {
        s->ent = (uint16_t)ent;
        ab = ul_size(co, ent, size);
    }
    if (ab != 0u) {
        sdo_reset(co, false);
        sdo_abort(co, index, sub, ab);
        return false;
    }
    return true;
}

static void sdo_initiate_upload(hd_co_t *co, uint16_t index, uint8_t sub)
{
    hd_co_sdo_t *s = &co->sdo;
    uint32_t size;
    if (!upload_open(co, index, sub, &size)) {
        return;
    }
    if (size <= 4u && size > 0u) {
        uint8_t v[4] = {0};
        const uint32_t ab = ul_source(co, 0u, v, size);
        if (ab != 0u) {
            sdo_reset(co, false);
            sdo_abort(co, index, sub, ab);
            return;
        }
        sdo_reply(co, (uint8_t)(0x43u | ((4u - size) << 2)), index, sub, rd_u32(v));
        sdo_reset(co, false);
        return;
    }
    s->state = SDO_UL_SEG;
    s->size = size;
    s->off = 0u;
    s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    sdo_reply(co, 0x41u, index, sub, size);
}

static void sdo_upload_segment(hd_co_t *co, const uint8_t *d)
{
    hd_co_sdo_t *s = &co->sdo;
    uint8_t t = (uint8_t)((d[0] >> 4) & 1u);
    if (t != s->toggle) {
        sdo_fail(co, HD_CO_AB_TOGGLE);
        return;
    }
    uint32_t n = s->size - s->off;
    if (n > 7u) {
        n = 7u;
    }
    uint8_t reply[8] = {0};
    uint32_t ab = ul_source(co, s->off, &reply[1], n);
    if (ab != 0u) {
        sdo_fail(co, ab);
        return;
    }
    s->off += n;
    bool last = s->off >= s->size;
    reply[0] = (uint8_t)(((uint32_t)t << 4) | ((7u - n) << 1) | (last ? 1u : 0u));
    co_send(co, sdo_tx_id(co), 8u, reply);
    if (last) {
        sdo_reset(co, false);
    } else {
        s->toggle ^= 1u;
        s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    }
}

static void sdo_block_download_init(hd_co_t *co, const uint8_t *d, uint16_t index, uint8_t sub)
{
    hd_co_sdo_t *s = &co->sdo;
    if ((d[0] & 0x01u) != 0u) {          /* cs must be 0 (initiate) */
        sdo_abort(co, index, sub, HD_CO_AB_CMD);
        return;
    }
    uint32_t ent;
    uint32_t ab = sdo_lookup(co, index, sub, &ent);
    if (ab == 0u) {
        ab = check_access(co, ent, true);
    }
    uint32_t size = (d[0] & 0x02u) != 0u ? rd_u32(&d[4]) : 0u;
    if (ab == 0u) {
        if (is_domain(co, ent)) {
            ab = domain_begin(co, ent, size);
        } else {
            uint32_t tsize = type_size(co->table[ent].type);
            if (tsize == 0u) {
                ab = HD_CO_AB_TYPE_LEN;
            } else if (size != 0u && size != tsize) {
                ab = size > tsize ? HD_CO_AB_LEN_HIGH : HD_CO_AB_LEN_LOW;
            }
        }
    }
    if (ab != 0u) {
        sdo_abort(co, index, sub, ab);
        return;
    }
    sdo_reset(co, false);
    s->state = SDO_BLK_DL;
    s->ent = (uint16_t)ent;
    s->size = size;
    s->crc_on = (uint8_t)((d[0] & 0x04u) != 0u ? 1u : 0u);
    s->crc = 0u;
    s->blksize = HD_CO_BLKSIZE;
    s->seq = 0u;
    s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    uint8_t r[8] = {0};
    r[0] = 0xA4u;                        /* scs 5, crc supported, ss 0 */
    r[1] = (uint8_t)(index & 0xFFu);
    r[2] = (uint8_t)(index >> 8);
    r[3] = sub;
    r[4] = s->blksize;
    co_send(co, sdo_tx_id(co), 8u, r);
}

static void sdo_block_download_segment(hd_co_t *co, const uint8_t *d)
{
    hd_co_sdo_t *s = &co->sdo;
    uint8_t seq = (uint8_t)(d[0] & 0x7Fu);
    bool c = (d[0] & 0x80u) != 0u;
    if (seq == 0u || seq > s->blksize) {
        sdo_fail(co, HD_CO_AB_SEQNO);
        return;
    }
    bool accepted = false;
    if (seq == (uint8_t)(s->seq + 1u) && !s->last_seen) {
        if (s->pend_len != 0u) {
            uint32_t ab = dl_sink(co, s->pend, s->pend_len);
            if (ab != 0u) {
                sdo_fail(co, ab);
                return;
            }
        }
        hd_co_copy(s->pend, &d[1], 7u);
        s->pend_len = 7u;
        s->seq = seq;
        accepted = true;
        if (c) {
            s->last_seen = 1u;
        }
    }
    s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    if (seq >= s->blksize || (c && accepted)) {
        uint8_t r[8] = {0};
        r[0] = 0xA2u;
        r[1] = s->seq;
        r[2] = s->blksize;
        co_send(co, sdo_tx_id(co), 8u, r);
        s->seq = 0u;
        if (s->last_seen) {
            s->state = SDO_BLK_DL_END;
        }
    }
}

static void sdo_block_download_end(hd_co_t *co, const uint8_t *d)
{
    hd_co_sdo_t *s = &co->sdo;
    if ((d[0] & 0xE3u) != 0xC1u) {
        sdo_fail(co, HD_CO_AB_CMD);
        return;
    }
    uint32_t n = (uint32_t)(d[0] >> 2) & 7u;
    uint32_t ab = dl_sink(co, s->pend, 7u - n);
    s->pend_len = 0u;
    if (ab != 0u) {
        sdo_fail(co, ab);
        return;
    }
    if (s->crc_on) {
        uint16_t crc = (uint16_t)(d[1] | ((uint32_t)d[2] << 8));
        if (crc != s->crc) {
            sdo_fail(co, HD_CO_AB_CRC);
            return;
        }
    }
    const hd_co_entry_t *e = &co->table[s->ent];
    uint16_t ix = e->index;
    uint8_t sb = e->sub;
    ab = dl_commit(co);
    if (ab != 0u) {
        sdo_fail(co, ab);
        return;
    }
    sdo_reset(co, false);
    uint8_t r[8] = {0};
    r[0] = 0xA1u;
    (void)ix;
    (void)sb;
    co_send(co, sdo_tx_id(co), 8u, r);
}

static void sdo_block_upload_init(hd_co_t *co, const uint8_t *d, uint16_t index, uint8_t sub)
{
    hd_co_sdo_t *s = &co->sdo;
    if ((d[0] & 0x03u) != 0u) {
        sdo_abort(co, index, sub, HD_CO_AB_CMD);
        return;
    }
    uint8_t blk = d[4];
    if (blk == 0u || blk > 127u) {
        sdo_abort(co, index, sub, HD_CO_AB_BLKSIZE);
        return;
    }
    uint32_t size;
    if (!upload_open(co, index, sub, &size)) {
        return;
    }
    s->state = SDO_BLK_UL_INIT;
    s->size = size;
    s->off = 0u;
    s->blksize = blk;
    s->crc_on = (uint8_t)((d[0] & 0x04u) != 0u ? 1u : 0u);
    s->crc = 0u;
    s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    sdo_reply(co, 0xC6u, index, sub, size);   /* scs 6, crc, size indicated */
}

/* send as many segments of the current sub-block as the TX queue takes */
static void sdo_block_upload_pump(hd_co_t *co)
{
    hd_co_sdo_t *s = &co->sdo;
    while (s->state == SDO_BLK_UL_SEND) {
        uint32_t start = s->off + (uint32_t)s->seq * 7u;
        uint32_t n = s->size > start ? s->size - start : 0u;
        if (n > 7u) {
            n = 7u;
        }
        bool last = start + n >= s->size;
        uint8_t f[8] = {0};
        uint32_t ab = ul_source(co, start, &f[1], n);
        if (ab != 0u) {
            sdo_fail(co, ab);
            return;
        }
        f[0] = (uint8_t)((uint32_t)(s->seq + 1u) | (last ? 0x80u : 0u));
        if (!co_try_send(co, sdo_tx_id(co), 8u, f)) {
            return;                         /* retry next tick */
        }
        s->seq++;
        if (last || s->seq >= s->blksize) {
            s->state = SDO_BLK_UL_ACK;
            s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
        }
    }
}

static void sdo_block_upload_ack(hd_co_t *co, const uint8_t *d)
{
    hd_co_sdo_t *s = &co->sdo;
    if ((d[0] & 0xE3u) != 0xA2u) {
        sdo_fail(co, HD_CO_AB_CMD);
        return;
    }
    uint8_t ackseq = d[1];
    uint8_t blk = d[2];
    if (ackseq > s->seq) {
        sdo_fail(co, HD_CO_AB_SEQNO);
        return;
    }
    if (blk == 0u || blk > 127u) {
        sdo_fail(co, HD_CO_AB_BLKSIZE);
        return;
    }
    uint32_t acked = (uint32_t)ackseq * 7u;
    if (s->off + acked > s->size) {
        acked = s->size - s->off;
    }
    if (s->crc_on && acked > 0u) {
        uint8_t tmp[7];
        for (uint32_t p = 0u; p < acked; p += 7u) {
            uint32_t n = acked - p < 7u ? acked - p : 7u;
            if (ul_source(co, s->off + p, tmp, n) != 0u) {
                sdo_fail(co, HD_CO_AB_GENERAL);
                return;
            }
            s->crc = hd_co_crc16(s->crc, tmp, n);
        }
    }
    s->off += acked;
    s->blksize = blk;
    s->seq = 0u;
    s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    bool all_sent_acked = s->off >= s->size && (ackseq > 0u || s->size == 0u);
    if (all_sent_acked) {
        uint32_t rem = s->size % 7u;
        uint32_t n = (s->size == 0u) ? 7u : (rem == 0u ? 0u : 7u - rem);
        uint8_t r[8] = {0};
        r[0] = (uint8_t)(0xC1u | (n << 2));
        r[1] = (uint8_t)(s->crc & 0xFFu);
        r[2] = (uint8_t)(s->crc >> 8);
        co_send(co, sdo_tx_id(co), 8u, r);
        s->state = SDO_BLK_UL_END;
        return;
    }
    s->state = SDO_BLK_UL_SEND;
    sdo_block_upload_pump(co);
}

static void sdo_process(hd_co_t *co, const hd_can_frame_t *f)
{
    hd_co_sdo_t *s = &co->sdo;
    const uint8_t *d = f->data;
    if (f->dlc != 8u || f->rtr) {
        co->stats.rx_ignored++;
        return;
    }
    if (co->nmt != HD_CO_NMT_PREOP && co->nmt != HD_CO_NMT_OP) {
        return;
    }
    /* block download sub-block: every frame is a segment, except an abort */
    if (s->state == SDO_BLK_DL) {
        if (d[0] == 0x80u) {
            sdo_reset(co, true);            /* client abort */
            return;
        }
        sdo_block_download_segment(co, d);
        return;
    }
    uint8_t ccs = (uint8_t)(d[0] >> 5);
    uint16_t index = (uint16_t)(d[1] | ((uint32_t)d[2] << 8));
    uint8_t sub = d[3];
    if (ccs == 4u) {                        /* abort from the client */
        sdo_reset(co, true);
        return;
    }
    switch (s->state) {
    case SDO_DL_SEG:
        if (ccs == 0u) {
            sdo_download_segment(co, d);
            return;
        }
        break;
    case SDO_UL_SEG:
        if (ccs == 3u) {
            sdo_upload_segment(co, d);
            return;
        }
        break;
    case SDO_BLK_DL_END:
        sdo_block_download_end(co, d);
        return;
    case SDO_BLK_UL_INIT:
        if (d[0] == 0xA3u) {
            s->state = SDO_BLK_UL_SEND;
            s->seq = 0u;
            sdo_block_upload_pump(co);
            return;
        }
        sdo_fail(co, HD_CO_AB_CMD);
        return;
    case SDO_BLK_UL_SEND:
    case SDO_BLK_UL_ACK:
        if ((d[0] & 0xE3u) == 0xA2u) {
            sdo_block_upload_ack(co, d);
            return;
        }
        sdo_fail(co, HD_CO_AB_CMD);
        return;
    case SDO_BLK_UL_END:
        if ((d[0] & 0xE3u) == 0xA1u) {
            sdo_reset(co, false);
            return;
        }
        sdo_fail(co, HD_CO_AB_CMD);
        return;
    default:
        break;
    }
    /* a new request (any running segmented transfer is superseded) */
    if (s->state != SDO_IDLE && ccs != 1u && ccs != 2u && ccs != 5u && ccs != 6u) {
        sdo_fail(co, HD_CO_AB_CMD);
        return;
    }
    if (s->state != SDO_IDLE) {
        sdo_reset(co, true);
    }
    switch (ccs) {
    case 1u: sdo_initiate_download(co, d, index, sub); break;
    case 2u: sdo_initiate_upload(co, index, sub); break;
    case 5u: sdo_block_upload_init(co, d, index, sub); break;
    case 6u: sdo_block_download_init(co, d, index, sub); break;
    default:
        sdo_abort(co, index, sub, HD_CO_AB_CMD);   /* segment outside a transfer, unknown ccs */
        break;
    }
}

/* ---- NMT ------------------------------------------------------------------ */

static void boot_up(hd_co_t *co)
{
    uint8_t d[1] = {0u};
    co_send(co, 0x700u + co->node_id, 1u, d);
    co->nmt = HD_CO_NMT_PREOP;
    co->hb_next_us = co->now_us + (uint64_t)co->od.producer_heartbeat_time * 1000u;
}

static void reset_comm(hd_co_t *co)
{
    sdo_reset(co, true);
    load_defaults(co, 0x1000u, 0x1FFFu);
    if (co->stored_ok != 0u) {            /* CiA 301: reset communication = the stored values */
        (void)hd_co_store_apply(co, co->stored, hd_co_store_words(co), 0x1000u, 0x1FFFu);
    }
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        pdo_rebuild(co, true, i);
        pdo_rebuild(co, false, i);
    }
    co->hbc_active = 0u;
    co->hbc_lost = 0u;
    co->emcy_pending = 0u;
    boot_up(co);
}

/* CiA 402 0x6007 when an NMT command ends the master's connection (`leaving`: stop from
 * OPERATIONAL or PRE-OPERATIONAL, pre-operational from OPERATIONAL, either reset) with the
 * power stage on; true when the reaction was the fault (its EMCY follows the transition) */
static bool nmt_abort_connection(hd_co_t *co, bool leaving)
{
    if (!leaving || co->p402.state == HD_CO402_FAULT_REACTION || !hd_co402_powered(co)) {
        return false;
    }
    hd_co402_abort_connection(co, HD_CO_EMCY_COMM);
    return co->p402.state == HD_CO402_FAULT_REACTION || co->p402.state == HD_CO402_FAULT;
}

static void nmt_process(hd_co_t *co, const hd_can_frame_t *f)
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
            /* event-driven TPDOs go out once on entering OPERATIONAL */
            for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
                if (co->tpdo[i].type == 255u || (co->tpdo[i].type == 254u && stream_period(co, i) == 0u)) {
                    co->tpdo[i].cos_armed = 1u;
                }
            }
        }
        co->nmt = HD_CO_NMT_OP;
        break;
    case 0x02u:
        faulted = nmt_abort_connection(co, co->nmt != HD_CO_NMT_STOPPED);
        co->nmt = HD_CO_NMT_STOPPED;
        sdo_reset(co, true);
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
        load_defaults(co, 0x2000u, 0xFFFFu);
        if (co->stored_ok != 0u) {
            (void)hd_co_store_apply(co, co->stored, hd_co_store_words(co), 0x2000u, 0xFFFFu);
        }
        hd_co402_restart(co);
        reset_comm(co);
        break;
    case 0x82u:
        faulted = nmt_abort_connection(co, true);
        reset_comm(co);
        break;
    default: co->stats.rx_ignored++; break;
    }
    if (faulted) {
        /* after the transition: a reset's boot-up goes first and its cleared error register
         * gets the bit back; in STOPPED the EMCY is only recorded (0x1003, 0x1001) */
        hd_co_emcy(co, HD_CO_EMCY_COMM, HD_CO_ER_COMM, NULL);
    }
}

/* ---- entry points ---------------------------------------------------------- */

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
    load_defaults(co, 0x2000u, 0xFFFFu);
    hd_co402_init(co);
    reset_comm(co);
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
        nmt_process(co, f);
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
        on_sync(co, co->sync_counter);
        return;
    }
    if (id == 0x600u + co->node_id) {
        sdo_process(co, f);
        return;
    }
    if (id >= 0x701u && id <= 0x77Fu) {
        uint32_t c = co->od.consumer_heartbeat_time_1;
        if (f->dlc == 1u && !f->rtr && (c & 0xFFFFu) != 0u && (id - 0x700u) == ((c >> 16) & 0x7Fu)) {
            co->hbc_last_us = co->now_us;
            co->hbc_active = 1u;
            co->hbc_lost = 0u;
        }
        return;
    }
    if (co->nmt == HD_CO_NMT_OP && !f->rtr) {
        for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
            hd_co_pdo_rt_t *r = &co->rpdo[i];
            if (!r->valid || r->cob != id) {
                continue;
            }
            if (f->dlc < r->len) {
                co->stats.pdo_len_errors++;
                hd_co_emcy(co, HD_CO_EMCY_PDO_LEN, HD_CO_ER_COMM, NULL);
                return;
            }
            if (r->type <= 240u) {
                hd_co_copy(r->rx_data, f->data, 8u);
                r->rx_pending = 1u;
            } else {
                rpdo_apply(co, r, f->data);
            }
            return;
        }
    }
    co->stats.rx_ignored++;
}

void hd_co_tick(hd_co_t *co, uint32_t dt_us)
{
    co->now_us += dt_us;
    /* heartbeat producer */
    if (co->od.producer_heartbeat_time != 0u && co->now_us >= co->hb_next_us) {
        uint8_t st = co->nmt;
        co_send(co, 0x700u + co->node_id, 1u, &st);
        co->hb_next_us = co->now_us + (uint64_t)co->od.producer_heartbeat_time * 1000u;
    }
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
    /* heartbeat consumer (suspended while off the bus: bus-off is its own error) */
    uint32_t c = co->od.consumer_heartbeat_time_1;
    if (co->hbc_active && (c & 0xFFFFu) != 0u && co->can_state != HD_HAL_CAN_BUS_OFF &&
        co->now_us - co->hbc_last_us > (uint64_t)(c & 0xFFFFu) * 1000u) {
        co->hbc_active = 0u;
        co->hbc_lost = 1u;
        uint8_t mfr[5] = {(uint8_t)((c >> 16) & 0x7Fu), 0u, 0u, 0u, 0u};
        comm_error(co, HD_CO_EMCY_HB, mfr);
    }
    /* pending EMCY (inhibit time, bus-off) */
    if (co->emcy_pending && co->now_us >= co->emcy_inhibit_until_us && co->can_state != HD_HAL_CAN_BUS_OFF) {
        co->emcy_pending = 0u;
        emcy_send(co, co->emcy_pending_data);
    }
    /* SDO: time-out, block-upload pump */
    if (co->sdo.state != SDO_IDLE && co->now_us > co->sdo.deadline_us) {
        sdo_fail(co, HD_CO_AB_TIMEOUT);
    }
    if (co->sdo.state == SDO_BLK_UL_SEND) {
        sdo_block_upload_pump(co);
    }
    hd_co402_tick(co);
    if (co->nmt == HD_CO_NMT_OP) {
        tpdo_tick(co, dt_us);
    }
}
