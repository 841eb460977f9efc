/*
 * hd_co_store.c - CiA 301 stored objects: the image of every VAR entry flagged
 * HD_CO_F_STORE that 0x1010 saves (layout word, one word per entry), put back in force
 * through the SDO write checks in the CiA 301 order; the NMT resets return to it
 * (hd_co.h, hd_co_store_*).
 */
#include "hd_co_internal.h"
#include "hd_crc32.h"

/* in the stored image only: the COB-ID is its default base + the node id, so the image
 * follows a change of the node id like the defaults do */
#define STORE_NODEREL 0x08000000u

static bool is_stored(const hd_co_entry_t *e)
{
    return e->kind == HD_CO_K_VAR && (e->flags & HD_CO_F_STORE) != 0u && hd_co__type_size(e->type) <= 4u;
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
    const uint32_t u = (uint32_t)((uint64_t)hd_co__var_load(co, e) & 0xFFFFFFFFu);
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
    hd_co__encode_le(b, 4u, (int64_t)w);
    return hd_co__decode_le(b, hd_co__type_size(e->type), hd_co__type_signed(e->type));
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


/* one value through the SDO download path: access, length, range, object rules */
static uint32_t store_write(hd_co_t *co, uint32_t ent, int64_t v)
{
    uint8_t b[8];
    const uint32_t n = hd_co__type_size(co->table[ent].type);
    uint32_t ab = hd_co__check_access(co, ent, true);
    if (ab != 0u) {
        return ab;
    }
    hd_co__encode_le(b, n, v);
    return hd_co_write(co, ent, b, n);
}

/* the stored entries in [lo, hi] to their defaults (the PDOs are rebuilt by the caller) */
static void store_defaults_range(hd_co_t *co, uint16_t lo, uint16_t hi)
{
    for (uint32_t i = 0u; i < co->count; i++) {
        const hd_co_entry_t *e = &co->table[i];
        if (is_stored(e) && e->index >= lo && e->index <= hi) {
            hd_co__var_store(co, e, e->def + (((e->flags & HD_CO_F_NODEID) != 0u) ? (int64_t)co->node_id : 0));
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
                hd_co__after_write(co, e);
            }
        }
    }
    hd_co__pdo_rebuild_all(co);
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
    hd_co__pdo_rebuild_all(co);
}
