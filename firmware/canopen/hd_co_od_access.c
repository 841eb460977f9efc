/*
 * hd_co_od_access.c - CiA 301 object dictionary access: entry hd_co__lookup, reads and writes of
 * values (type length, limits, the objects' rules, side effects), local access by index,
 * defaults.  The table is the generated hd_co_od[] (hd_co_od.c); the values of VAR
 * entries live in co->od, PARAM / DOMAIN / SPECIAL entries go through the app.  A
 * device profile adds its objects' rules and side effects (hd_co_profile_if_t).
 */
#include "hd_co_util.h"
#include "hd_co_internal.h"

uint32_t hd_co__type_size(uint8_t t)
{
    switch (t) {
    case HD_CO_T_BOOL: case HD_CO_T_I8: case HD_CO_T_U8: return 1u;
    case HD_CO_T_I16: case HD_CO_T_U16: return 2u;
    case HD_CO_T_I32: case HD_CO_T_U32: return 4u;
    case HD_CO_T_I64: case HD_CO_T_U64: return 8u;
    default: return 0u;
    }
}

bool hd_co__type_signed(uint8_t t)
{
    return t == HD_CO_T_I8 || t == HD_CO_T_I16 || t == HD_CO_T_I32 || t == HD_CO_T_I64;
}

/* Little-endian bytes -> int64 (sign-extended for signed types). */
int64_t hd_co__decode_le(const uint8_t *p, uint32_t n, bool sgn)
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

void hd_co__encode_le(uint8_t *p, uint32_t n, int64_t v)
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
void hd_co__var_store(hd_co_t *co, const hd_co_entry_t *e, int64_t v)
{
    uint8_t *p = var_ptr(co, e);
    switch (hd_co__type_size(e->type)) {
    case 1u: { uint8_t x = (uint8_t)((uint64_t)v & 0xFFu); hd_co_copy(p, &x, 1u); break; }
    case 2u: { uint16_t x = (uint16_t)((uint64_t)v & 0xFFFFu); hd_co_copy(p, &x, 2u); break; }
    case 4u: { uint32_t x = (uint32_t)((uint64_t)v & 0xFFFFFFFFu); hd_co_copy(p, &x, 4u); break; }
    case 8u: { uint64_t x = (uint64_t)v; hd_co_copy(p, &x, 8u); break; }
    default: break;
    }
}

int64_t hd_co__var_load(const hd_co_t *co, const hd_co_entry_t *e)
{
    const uint8_t *p = (const uint8_t *)&co->od + e->arg;
    uint8_t b[8];
    uint32_t n = hd_co__type_size(e->type);
    switch (n) {
    case 1u: { uint8_t x; hd_co_copy(&x, p, 1u); b[0] = x; break; }
    case 2u: { uint16_t x; hd_co_copy(&x, p, 2u); hd_co__encode_le(b, 2u, (int64_t)x); break; }
    case 4u: { uint32_t x; hd_co_copy(&x, p, 4u); hd_co__encode_le(b, 4u, (int64_t)x); break; }
    case 8u: { uint64_t x; hd_co_copy(&x, p, 8u); return hd_co__decode_le((const uint8_t *)&x, 8u, true); }
    default: return 0;
    }
    return hd_co__decode_le(b, n, hd_co__type_signed(e->type));
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
uint32_t hd_co__lookup(const hd_co_t *co, uint16_t index, uint8_t sub, uint32_t *ent)
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

/* hd_co__lookup for a master (SDO): the device profile's filter first (hd_co_app_if_t.object_filter) */

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
    uint32_t n = hd_co__type_size(e->type);
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
        v = hd_co__var_load(co, e);
        break;
    }
    if (n > cap) {
        return HD_CO_AB_GENERAL;
    }
    hd_co__encode_le(buf, n, v);
    *len = n;
    return 0u;
}

/* Object-specific rules before a write is accepted. */
uint32_t hd_co__check_write(hd_co_t *co, const hd_co_entry_t *e, int64_t v)
{
    uint16_t ix = e->index;
    if (ix >= 0x1400u && ix < 0x1C00u) {
        return hd_co__pdo_check_write(co, e, v);
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
    default:
        if (co->app.profile != NULL) {
            return co->app.profile->check_write(co->app.profile_ctx, co, ix, e->sub, v);
        }
        return 0u;
    }
}

void hd_co__after_write(hd_co_t *co, const hd_co_entry_t *e)
{
    uint16_t ix = e->index;
    if (ix >= 0x1400u && ix < 0x1C00u) {
        hd_co__pdo_rebuild(co, ix >= 0x1800u, (uint32_t)(ix & 0x1FFu));
        return;
    }
    switch (ix) {
    case 0x1016u:
    case 0x1017u:
        hd_co__hb_config_changed(co, ix);
        break;
    default:
        if (co->app.profile != NULL) {
            co->app.profile->after_write(co->app.profile_ctx, co, ix, e->sub);
        }
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
    uint32_t n = hd_co__type_size(e->type);
    if (e->kind == HD_CO_K_DOMAIN || e->kind == HD_CO_K_STR || n == 0u) {
        return HD_CO_AB_TYPE_LEN;
    }
    if (len > n) {
        return HD_CO_AB_LEN_HIGH;
    }
    if (len < n) {
        return HD_CO_AB_LEN_LOW;
    }
    int64_t v = hd_co__decode_le(buf, n, hd_co__type_signed(e->type));
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
    uint32_t ab = hd_co__check_write(co, e, v);
    if (ab != 0u) {
        return ab;
    }
    hd_co__var_store(co, e, v);
    hd_co__after_write(co, e);
    return 0u;
}

uint32_t hd_co_get_i64(hd_co_t *co, uint16_t index, uint8_t sub, int64_t *v)
{
    uint32_t ent;
    uint32_t ab = hd_co__lookup(co, index, sub, &ent);
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
    *v = hd_co__decode_le(b, n, hd_co__type_signed(co->table[ent].type));
    return 0u;
}

uint32_t hd_co_set_i64(hd_co_t *co, uint16_t index, uint8_t sub, int64_t v)
{
    uint32_t ent;
    uint32_t ab = hd_co__lookup(co, index, sub, &ent);
    if (ab != 0u) {
        return ab;
    }
    uint8_t b[8];
    uint32_t n = hd_co__type_size(co->table[ent].type);
    hd_co__encode_le(b, n, v);
    return hd_co_write(co, ent, b, n);
}

void hd_co__load_defaults(hd_co_t *co, uint16_t lo, uint16_t hi)
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
        hd_co__var_store(co, e, v);
    }
}

uint32_t hd_co__check_access(const hd_co_t *co, uint32_t ent, bool write)
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
