/*
 * hd_co_pdo.c - CiA 301 PDOs: the mapping and communication rules of 0x1400-0x1BFF,
 * the runtime of each TPDO / RPDO built from those objects, event-driven and streamed
 * TPDOs, synchronous TPDOs / RPDOs on SYNC (the SYNC consumer), RPDO reception.
 */
#include "hd_co_util.h"
#include "hd_co_internal.h"

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
    if ((e->flags & need) == 0u || e->kind != HD_CO_K_VAR || nb != 8u * hd_co__type_size(e->type)) {
        return HD_CO_AB_NO_MAP;
    }
    *bits = nb;
    return 0u;
}

/* The PDO communication / mapping rules (index 0x1400-0x1BFF). */
uint32_t hd_co__pdo_check_write(hd_co_t *co, const hd_co_entry_t *e, int64_t v)
{
    uint16_t ix = e->index;
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
        if ((cob & HD_CO_COB_INVALID) == 0u && (nv & HD_CO_COB_INVALID) == 0u &&
        (nv & HD_CO_COB_ID_MASK) != (cob & HD_CO_COB_ID_MASK)) {
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

void hd_co__pdo_rebuild(hd_co_t *co, bool tx, uint32_t i)
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
        uint32_t sz = hd_co__type_size(co->table[ent].type);
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
        hd_co__encode_le(out + pos, p->esize[k], hd_co__var_load(co, e));
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
    hd_co__send(co, p->cob, p->len, d);
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

uint16_t hd_co__tpdo_stream_period(const hd_co_t *co, uint32_t i)
{
    switch (i) {
    case 0u: return co->od.tpdo_stream_period_1;
    case 1u: return co->od.tpdo_stream_period_2;
    case 2u: return co->od.tpdo_stream_period_3;
    default: return co->od.tpdo_stream_period_4;
    }
}

void hd_co__pdo_rebuild_all(hd_co_t *co)
{
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        hd_co__pdo_rebuild(co, true, i);
        hd_co__pdo_rebuild(co, false, i);
    }
}

/* event-driven TPDOs go out once on entering OPERATIONAL */
void hd_co__tpdo_arm_events(hd_co_t *co)
{
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        if (co->tpdo[i].type == 255u || (co->tpdo[i].type == 254u && hd_co__tpdo_stream_period(co, i) == 0u)) {
            co->tpdo[i].cos_armed = 1u;
        }
    }
}

void hd_co__tpdo_tick(hd_co_t *co)
{
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
        uint16_t per = hd_co__tpdo_stream_period(co, i);
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
        int64_t v = hd_co__decode_le(d + pos, p->esize[k], hd_co__type_signed(e->type));
        pos += p->esize[k];
        bool ok = v >= e->min && v <= e->max && !(e->type == HD_CO_T_BOOL && v > 1);
        if (e->type == HD_CO_T_U64 && v < 0) {
            ok = false;
        }
        if (ok && hd_co__check_write(co, e, v) == 0u) {
            hd_co__var_store(co, e, v);
            hd_co__after_write(co, e);
        }
    }
}

void hd_co__on_sync(hd_co_t *co, uint8_t counter)
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

bool hd_co__rpdo_receive(hd_co_t *co, const hd_can_frame_t *f, uint32_t id)
{
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        hd_co_pdo_rt_t *r = &co->rpdo[i];
        if (!r->valid || r->cob != id) {
            continue;
        }
        if (f->dlc < r->len) {
            co->stats.pdo_len_errors++;
            hd_co_emcy(co, HD_CO_EMCY_PDO_LEN, HD_CO_ER_COMM, NULL);
            return true;
        }
        if (r->type <= 240u) {
            hd_co_copy(r->rx_data, f->data, 8u);
            r->rx_pending = 1u;
        } else {
            rpdo_apply(co, r, f->data);
        }
        return true;
    }
    return false;
}
