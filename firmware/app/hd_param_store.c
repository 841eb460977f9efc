/*
 * hd_param_store.c - parameter defaults, range checks, atomic two-slot NVM store.
 * Layout and rules: hd_param_store.h.
 */
#include "hd_param_store.h"
#include <stddef.h>
#include "hal.h"
#include "hd_le32.h"

#define HDR_WORDS 6u
#define REC_BYTES ((HDR_WORDS + HD_PARAM_COUNT + 1u) * 4u)
#define REC_PADDED ((REC_BYTES + 7u) & ~7u)

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

static uint32_t slot_size(void)
{
    const uint32_t pg = hd_hal_nvm_page_size();
    if (pg == 0u) {
        return 0u;
    }
    return ((REC_PADDED + pg - 1u) / pg) * pg;
}

typedef enum { SLOT_EMPTY, SLOT_BAD, SLOT_OTHER, SLOT_OK, SLOT_IOERR } slot_res_t;

static slot_res_t read_slot(uint32_t s, int32_t values[HD_PARAM_COUNT], uint32_t *seq)
{
    uint8_t rec[REC_PADDED];
    uint32_t i;
    if (hd_hal_nvm_read(s * slot_size(), rec, REC_PADDED) != 0) {
        return SLOT_IOERR;
    }
    int32_t blank = 1;
    for (i = 0; i < REC_PADDED; i++) {
        if (rec[i] != 0xFFu) {
            blank = 0;
            break;
        }
    }
    if (blank) {
        return SLOT_EMPTY;
    }
    const uint32_t crc = hd_get_le32(&rec[REC_BYTES - 4u]);
    if (hd_get_le32(&rec[0]) != HD_PSTORE_MAGIC || hd_crc32(0, rec, REC_BYTES - 4u) != crc) {
        return SLOT_BAD;
    }
    if (hd_get_le32(&rec[4]) != HD_PSTORE_FORMAT || hd_get_le32(&rec[8]) != HD_PARAM_VERSION ||
        hd_get_le32(&rec[12]) != HD_PARAM_TABLE_HASH || hd_get_le32(&rec[20]) != HD_PARAM_COUNT) {
        return SLOT_OTHER;
    }
    for (i = 0; i < HD_PARAM_COUNT; i++) {
        const int32_t v = u2i(hd_get_le32(&rec[(HDR_WORDS + i) * 4u]));
        if (hd_params_check(i, v) != 0) {
            return SLOT_BAD;
        }
        values[i] = v;
    }
    *seq = hd_get_le32(&rec[16]);
    return SLOT_OK;
}

static int same_values(const int32_t a[HD_PARAM_COUNT], const int32_t b[HD_PARAM_COUNT])
{
    uint32_t i;
    for (i = 0; i < HD_PARAM_COUNT; i++) {
        if (a[i] != b[i]) {
            return 0;
        }
    }
    return 1;
}

int32_t hd_pstore_same(const int32_t values[HD_PARAM_COUNT])
{
    int32_t v0[HD_PARAM_COUNT];
    uint32_t s0 = 0u, s1 = 0u;
    const uint32_t ss = slot_size();
    if (ss == 0u || 2u * ss > hd_hal_nvm_size()) {
        return 0;
    }
    const slot_res_t r0 = read_slot(0, v0, &s0);
    const slot_res_t r1 = read_slot(1, v0, &s1);
    uint32_t k;
    if (r0 == SLOT_OK && r1 == SLOT_OK) {
        k = hd_seq_newer(s1, s0) ? 1u : 0u;
    } else if (r0 == SLOT_OK) {
        k = 0u;
    } else if (r1 == SLOT_OK) {
        k = 1u;
    } else {
        return 0;
    }
    return (read_slot(k, v0, &s0) == SLOT_OK && same_values(v0, values)) ? 1 : 0;
}

uint32_t hd_pstore_region(void)
{
    return 2u * slot_size();
}

int32_t hd_pstore_load(int32_t values[HD_PARAM_COUNT], uint32_t *seq)
{
    int32_t v0[HD_PARAM_COUNT], v1[HD_PARAM_COUNT];
    uint32_t s0 = 0, s1 = 0, i;
    *seq = 0;
    if (slot_size() == 0u || 2u * slot_size() > hd_hal_nvm_size()) {
        hd_params_defaults(values);
        return HD_PSTORE_NVM_ERROR;
    }
    const slot_res_t r0 = read_slot(0, v0, &s0);
    const slot_res_t r1 = read_slot(1, v1, &s1);
    const int32_t *pick = NULL;
    if (r0 == SLOT_OK && r1 == SLOT_OK) {
        if (hd_seq_newer(s1, s0)) {
            pick = v1;
            *seq = s1;
        } else {
            pick = v0;
            *seq = s0;
        }
    } else if (r0 == SLOT_OK) {
        pick = v0;
        *seq = s0;
    } else if (r1 == SLOT_OK) {
        pick = v1;
        *seq = s1;
    }
    if (pick != NULL) {
        for (i = 0; i < HD_PARAM_COUNT; i++) {
            values[i] = pick[i];
        }
        return HD_PSTORE_OK;
    }
    hd_params_defaults(values);
    if (r0 == SLOT_IOERR || r1 == SLOT_IOERR) {
        return HD_PSTORE_NVM_ERROR;
    }
    if (r0 == SLOT_OTHER || r1 == SLOT_OTHER) {
        return HD_PSTORE_INCOMPATIBLE;
    }
    if (r0 == SLOT_BAD || r1 == SLOT_BAD) {
        return HD_PSTORE_CORRUPT;
    }
    return HD_PSTORE_BLANK;
}

int32_t hd_pstore_save(const int32_t values[HD_PARAM_COUNT], uint32_t *seq)
{
    uint8_t rec[REC_PADDED];
    uint32_t i, cur = 0, target;
    int32_t tmp[HD_PARAM_COUNT];
    const uint32_t ss = slot_size();
    if (ss == 0u || 2u * ss > hd_hal_nvm_size()) {
        return -1;
    }
    for (i = 0; i < HD_PARAM_COUNT; i++) {
        if (hd_params_check(i, values[i]) != 0) {
            return -1;
        }
    }
    /* write the slot that does NOT hold the current newest valid set */
    const slot_res_t r0 = read_slot(0, tmp, &cur);
    uint32_t s1 = 0;
    const slot_res_t r1 = read_slot(1, tmp, &s1);
    if (r0 == SLOT_OK && r1 == SLOT_OK) {
        target = hd_seq_newer(s1, cur) ? 0u : 1u;
    } else if (r0 == SLOT_OK) {
        target = 1u;
    } else {
        target = 0u;
    }
    /* The new sequence must be newer, in the serial arithmetic hd_pstore_load
     * uses, than the slot that survives this save (the target is overwritten),
     * not only than the caller's *seq: after a boot that fell back to defaults
     * (read error, seq 0) the surviving slot may hold any sequence, and a save
     * with *seq + 1 would lose to it at the next boot (both cases found by
     * tests/fuzz/fuzz_pstore; the second with the two slots 2^31 apart). */
    /* the newest valid set already holds these values: nothing to write (no flash wear) */
    if (r0 == SLOT_OK || r1 == SLOT_OK) {
        const uint32_t newest = (target == 0u) ? 1u : 0u;
        uint32_t sn = 0u;
        if (read_slot(newest, tmp, &sn) == SLOT_OK && same_values(tmp, values)) {
            *seq = sn;
            return 0;
        }
    }
    const slot_res_t rk = (target == 0u) ? r1 : r0;
    const uint32_t sk = (target == 0u) ? s1 : cur;
    const uint32_t nseq = hd_seq_next(*seq, rk == SLOT_OK, sk);
    for (i = 0; i < REC_PADDED; i++) {
        rec[i] = 0xFFu;
    }
    hd_put_le32(&rec[0], HD_PSTORE_MAGIC);
    hd_put_le32(&rec[4], HD_PSTORE_FORMAT);
    hd_put_le32(&rec[8], HD_PARAM_VERSION);
    hd_put_le32(&rec[12], HD_PARAM_TABLE_HASH);
    hd_put_le32(&rec[16], nseq);
    hd_put_le32(&rec[20], HD_PARAM_COUNT);
    for (i = 0; i < HD_PARAM_COUNT; i++) {
        hd_put_le32(&rec[(HDR_WORDS + i) * 4u], i2u(values[i]));
    }
    hd_put_le32(&rec[REC_BYTES - 4u], hd_crc32(0, rec, REC_BYTES - 4u));
    if (hd_hal_nvm_erase(target * ss, ss) != 0 ||
        hd_hal_nvm_write(target * ss, rec, REC_PADDED) != 0) {
        return -1;
    }
    *seq = nseq;
    return 0;
}
