/*
 * hd_table_store.c - the Preisach table's atomic two-slot NVM store (an hd_rec_store
 * of the image words).  Layout and rules: hd_table_store.h.
 */
#include "hd_table_store.h"
#include <stddef.h>
#include "hd_param_store.h"
#include "hd_rec_store.h"

#define WORDS_MAX (HD_PREISACH_IMG_HDR + HD_PREISACH_N_MAX)

uint32_t hd_tstore_offset(void)
{
    return hd_pstore_region();
}

uint32_t hd_tstore_slot_size(void)
{
    return hd_rstore_slot_bytes(WORDS_MAX);
}

static hd_rstore_t store(void)
{
    hd_rstore_t s;
    s.offset = hd_tstore_offset();
    s.slot = hd_tstore_slot_size();
    s.magic = HD_TSTORE_MAGIC;
    s.words_max = WORDS_MAX;
    s.check = NULL;             /* the table's own check runs on the loaded image */
    return s;
}

static void put(void *ctx, uint32_t w, uint32_t v)
{
    uint32_t *p = hd_preisach_word((hd_preisach_table_t *)ctx, w);
    if (p != NULL) {
        *p = v;
    }
}

static uint32_t get(const void *ctx, uint32_t w)
{
    return hd_preisach_word_get((const hd_preisach_table_t *)ctx, w);
}

int32_t hd_tstore_load(hd_preisach_table_t *t, uint32_t *seq)
{
    const hd_rstore_t s = store();
    uint32_t n = 0u;
    int32_t rc;
    *seq = 0u;
    if (hd_tstore_offset() == 0u) {
        return HD_TSTORE_NVM_ERROR;
    }
    rc = hd_rstore_load(&s, t, put, seq, &n);
    switch (rc) {
    case HD_RSTORE_OK: break;
    case HD_RSTORE_BLANK: return HD_TSTORE_BLANK;
    case HD_RSTORE_EMPTY: return HD_TSTORE_NONE;         /* the newest save's intent: no table */
    case HD_RSTORE_CORRUPT: return HD_TSTORE_CORRUPT;
    default: return HD_TSTORE_NVM_ERROR;
    }
    /* a whole record whose image fails its own check (another firmware's format) */
    if (n < HD_PREISACH_IMG_HDR || n != HD_PREISACH_IMG_HDR + t->n_entries || hd_preisach_check(t) != HD_PREISACH_OK) {
        return HD_TSTORE_CORRUPT;
    }
    return HD_TSTORE_OK;
}

int32_t hd_tstore_save(const hd_preisach_table_t *t, uint32_t *seq)
{
    const hd_rstore_t s = store();
    if (t != NULL && hd_preisach_check(t) != HD_PREISACH_OK) {
        return -1;
    }
    if (hd_tstore_offset() == 0u) {
        return -2;
    }
    return (hd_rstore_save(&s, t, get, (t != NULL) ? HD_PREISACH_IMG_HDR + t->n_entries : 0u, seq) == 0) ? 0 : -2;
}

int32_t hd_tstore_same(const hd_preisach_table_t *t)
{
    const hd_rstore_t s = store();
    if (hd_tstore_offset() == 0u) {
        return 0;
    }
    return hd_rstore_same(&s, t, get, (t != NULL) ? HD_PREISACH_IMG_HDR + t->n_entries : 0u);
}
