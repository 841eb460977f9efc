/*
 * hd_param_store.c - parameter defaults, range checks, and their atomic two-slot NVM
 * store: one record of the two-slot record store (hd_rec_store.h) with the parameter
 * table's rules as its check.  Layout and rules: hd_param_store.h.
 */
#include "hd_param_store.h"
#include <stddef.h>
#include "hd_rec_store.h"

/* payload: table version, table hash, the values */
#define PAYLOAD_WORDS (2u + HD_PARAM_COUNT)

void hd_params_defaults(int32_t values[HD_PARAM_COUNT])
{
    uint32_t i;
    for (i = 0; i < HD_PARAM_COUNT; i++) {
        values[i] = hd_param_table[i].def;
    }
}

int32_t hd_params_check(uint32_t id, int32_t raw)
{
    if (id >= HD_PARAM_COUNT) {
        return -1;
    }
    return (raw < hd_param_table[id].min || raw > hd_param_table[id].max) ? -1 : 0;
}

/* int32 <-> uint32 bit pattern without implementation-defined conversions */
static uint32_t i2u(int32_t v)
{
    return (v < 0) ? (uint32_t)(-(v + 1)) ^ 0xFFFFFFFFu : (uint32_t)v;
}

static int32_t u2i(uint32_t u)
{
    return (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u;
}

/* the record's rules: this table's version and hash, then every value in its range */
static int32_t check(uint32_t words, uint32_t w, uint32_t v)
{
    if (w == words) {
        return (words == PAYLOAD_WORDS) ? (int32_t)HD_RSTORE_WORD_OK : (int32_t)HD_RSTORE_WORD_OTHER;
    }
    if (w == 0u) {
        return (v == HD_PARAM_VERSION) ? (int32_t)HD_RSTORE_WORD_OK : (int32_t)HD_RSTORE_WORD_OTHER;
    }
    if (w == 1u) {
        return (v == HD_PARAM_TABLE_HASH) ? (int32_t)HD_RSTORE_WORD_OK : (int32_t)HD_RSTORE_WORD_OTHER;
    }
    return (hd_params_check(w - 2u, u2i(v)) == 0) ? (int32_t)HD_RSTORE_WORD_OK : (int32_t)HD_RSTORE_WORD_BAD;
}

static hd_rstore_t store(void)
{
    hd_rstore_t s;
    s.offset = 0u;
    s.slot = hd_rstore_slot_bytes(PAYLOAD_WORDS);
    s.magic = HD_PSTORE_MAGIC;
    s.words_max = PAYLOAD_WORDS;
    s.check = check;
    return s;
}

static void put(void *ctx, uint32_t w, uint32_t v)
{
    if (w >= 2u && w < PAYLOAD_WORDS) {
        ((int32_t *)ctx)[w - 2u] = u2i(v);
    }
}

static uint32_t get(const void *ctx, uint32_t w)
{
    if (w == 0u) {
        return HD_PARAM_VERSION;
    }
    if (w == 1u) {
        return HD_PARAM_TABLE_HASH;
    }
    return i2u(((const int32_t *)ctx)[w - 2u]);
}

uint32_t hd_pstore_region(void)
{
    return 2u * hd_rstore_slot_bytes(PAYLOAD_WORDS);
}

int32_t hd_pstore_load(int32_t values[HD_PARAM_COUNT], uint32_t *seq)
{
    const hd_rstore_t s = store();
    uint32_t words = 0u;
    const int32_t rc = hd_rstore_load(&s, values, put, seq, &words);
    if (rc == HD_RSTORE_OK) {
        return HD_PSTORE_OK;
    }
    *seq = 0u;
    hd_params_defaults(values);
    switch (rc) {
    case HD_RSTORE_BLANK: return HD_PSTORE_BLANK;
    case HD_RSTORE_OTHER: return HD_PSTORE_INCOMPATIBLE;
    case HD_RSTORE_NVM_ERROR: return HD_PSTORE_NVM_ERROR;
    default: return HD_PSTORE_CORRUPT;           /* CORRUPT, or an empty record (never saved here) */
    }
}

int32_t hd_pstore_same(const int32_t values[HD_PARAM_COUNT])
{
    const hd_rstore_t s = store();
    return hd_rstore_same(&s, values, get, PAYLOAD_WORDS);
}

int32_t hd_pstore_save(const int32_t values[HD_PARAM_COUNT], uint32_t *seq)
{
    const hd_rstore_t s = store();
    uint32_t i;
    for (i = 0; i < HD_PARAM_COUNT; i++) {
        if (hd_params_check(i, values[i]) != 0) {
            return -1;
        }
    }
    return (hd_rstore_save(&s, values, get, PAYLOAD_WORDS, seq) == 0) ? 0 : -1;
}
