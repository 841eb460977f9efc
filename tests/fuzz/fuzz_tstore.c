/*
 * fuzz_tstore.c - the Preisach table store's loader (firmware/app/hd_table_store on
 * hd_rec_store) on corrupt NVM images, through a fake hal NVM (this file implements
 * the hd_hal_nvm_* calls; no other hal function is linked).  The layout is the
 * STM32G474's: 1 KiB pages, the parameter store's two slots, then the table slots.
 *
 * Input: byte 0 = flags
 *   bit 0  raw image: the rest of the input IS the table region (padded with 0xFF)
 *   otherwise: byte 1 = levels of table A, byte 2 = levels of table B; the region
 *   starts as two valid records (A, then B or "no table" with bit 4), then records
 *   (offset u16, xor byte) flip bits in the table region;
 *   bit 1/2 re-seal slot 0/1 (fix the record CRC after the flips) so that the
 *   size and table checks are reached;
 *   bit 3  NVM reads fail
 *
 * Invariants:
 *   - load returns one of the documented statuses, its sequence 0 unless OK / NONE;
 *   - on OK the table passes hd_preisach_check and is, word for word, the image of
 *     one slot (never a mix of two records);
 *   - a save after any boot (the loaded table, or "no table") loads back as saved.
 */
#include <string.h>
#include "hd_crc32.h"
#include "hd_le32.h"
#include "hd_table_store.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define FUZZ_NVM_SIZE 24576u
#define FUZZ_NVM_PAGE 1024u
#define FUZZ_NVM_ERASE_MIN hd_tstore_offset()    /* never the parameter store's slots */
#include "fuzz_nvm.h"

/* a valid L-level table, entries from the level count and version */
static void build(hd_preisach_table_t *t, uint32_t levels, uint32_t version)
{
    memset(t, 0, sizeof *t);
    t->levels = levels;
    t->sub_bits = 1u;
    t->in_shift = 8u;
    t->u0 = -(1 << 14);
    t->unit = HD_PREISACH_UNIT_GENERIC;
    t->version = version;
    for (uint32_t i = 0; i < levels; i++) {
        for (uint32_t j = 0; j <= i; j++) {
            t->e[i * (i + 1u) / 2u + j] = (int32_t)((i - j) * (i - j + version));
        }
    }
    hd_preisach_seal(t);
}

static uint8_t *slot(uint32_t k)
{
    return &nvm[hd_tstore_offset() + k * hd_tstore_slot_size()];
}

/* fix the record CRC of slot k after flips (when its word count still fits) */
static void reseal(uint32_t k)
{
    uint8_t *r = slot(k);
    const uint32_t n = hd_get_le32(&r[12]);
    if (16u + 4u * n + 4u <= hd_tstore_slot_size()) {
        hd_put_le32(&r[16u + 4u * n], hd_crc32(0, r, 16u + 4u * n));
    }
}

/* the image in slot k equals t word for word */
static int slot_holds(uint32_t k, const hd_preisach_table_t *t)
{
    const uint8_t *r = slot(k);
    const uint32_t n = hd_get_le32(&r[12]);
    if (n != HD_PREISACH_IMG_HDR + t->n_entries) {
        return 0;
    }
    for (uint32_t w = 0; w < n; w++) {
        if (hd_get_le32(&r[16u + 4u * w]) != hd_preisach_word_get(t, w)) {
            return 0;
        }
    }
    return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static hd_preisach_table_t a, b, t, u;
    fz_stream_t s;
    fz_init(&s, data, size);
    const uint8_t flags = fz_u8(&s);
    const uint32_t base = hd_tstore_offset(), region = 2u * hd_tstore_slot_size();
    uint32_t seq = 0;

    FUZZ_ASSERT(base + region <= FUZZ_NVM_SIZE);
    nvm_fail_read = 0;
    memset(nvm, 0xFF, sizeof nvm);
    if (flags & 1u) {
        const size_t n = fz_left(&s) < region ? fz_left(&s) : region;
        memcpy(&nvm[base], data + 1, n);
    } else {
        build(&a, HD_PREISACH_L_MIN + fz_u8(&s) % (HD_PREISACH_L_MAX - HD_PREISACH_L_MIN + 1u), 3u);
        build(&b, HD_PREISACH_L_MIN + fz_u8(&s) % (HD_PREISACH_L_MAX - HD_PREISACH_L_MIN + 1u), 4u);
        FUZZ_ASSERT(hd_tstore_save(&a, &seq) == 0);
        FUZZ_ASSERT(hd_tstore_save((flags & 16u) ? NULL : &b, &seq) == 0);
        while (fz_left(&s) >= 3u) {
            const uint32_t off = fz_u16(&s) % region;
            nvm[base + off] ^= fz_u8(&s);
        }
        if (flags & 2u) {
            reseal(0);
        }
        if (flags & 4u) {
            reseal(1);
        }
    }
    nvm_fail_read = (flags & 8u) != 0u;

    const int32_t st = hd_tstore_load(&t, &seq);
    FUZZ_ASSERT(st >= HD_TSTORE_OK && st <= HD_TSTORE_NVM_ERROR);
    if (st != HD_TSTORE_OK && st != HD_TSTORE_NONE) {
        FUZZ_ASSERT(seq == 0u || st == HD_TSTORE_CORRUPT);
    }
    if (st == HD_TSTORE_OK) {
        FUZZ_ASSERT(hd_preisach_check(&t) == HD_PREISACH_OK);
        FUZZ_ASSERT(slot_holds(0, &t) || slot_holds(1, &t));
    }
    nvm_fail_read = 0;
    /* a save after any boot loads back as saved */
    const hd_preisach_table_t *keep = (st == HD_TSTORE_OK) ? &t : NULL;
    if (hd_tstore_save(keep, &seq) == 0) {
        uint32_t seq2 = 0;
        const int32_t st2 = hd_tstore_load(&u, &seq2);
        FUZZ_ASSERT(seq2 == seq);
        if (keep != NULL) {
            FUZZ_ASSERT(st2 == HD_TSTORE_OK);
            FUZZ_ASSERT(memcmp(u.e, t.e, sizeof(int32_t) * t.n_entries) == 0 && u.crc == t.crc);
        } else {
            FUZZ_ASSERT(st2 == HD_TSTORE_NONE);
        }
    }
    return 0;
}
