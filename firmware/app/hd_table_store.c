/*
 * hd_table_store.c - the Preisach table's atomic two-slot NVM store.
 * Layout and rules: hd_table_store.h.
 */
#include "hd_table_store.h"
#include <stddef.h>
#include "hal.h"
#include "hd_crc32.h"
#include "hd_le32.h"
#include "hd_param_store.h"

#define HDR_BYTES  16u
#define WORDS_MAX  (HD_PREISACH_IMG_HDR + HD_PREISACH_N_MAX)
#define REC_MAX    (HDR_BYTES + 4u * WORDS_MAX + 4u)
#define REC_PADDED ((REC_MAX + 7u) & ~7u)
#define CHUNK      64u                 /* bytes per hal call (a multiple of 8) */

uint32_t hd_tstore_offset(void)
{
    return hd_pstore_region();
}

uint32_t hd_tstore_slot_size(void)
{
    const uint32_t pg = hd_hal_nvm_page_size();
    return (pg == 0u) ? 0u : ((REC_PADDED + pg - 1u) / pg) * pg;
}

/* the region exists: page size known, both slots inside the hal's NVM */
static int region_ok(void)
{
    const uint32_t ss = hd_tstore_slot_size();
    const uint32_t off = hd_tstore_offset();
    const uint32_t size = hd_hal_nvm_size();
    return ss != 0u && off != 0u && off <= size && ss <= (size - off) / 2u;
}

typedef enum { TSLOT_EMPTY, TSLOT_BAD, TSLOT_OK, TSLOT_IOERR } tslot_t;

/* Read slot s: header, image and CRC, streamed; if t is not NULL the image words are
 * decoded into *t.  *seq and *words are set when the slot is OK. */
static tslot_t scan_slot(uint32_t s, hd_preisach_table_t *t, uint32_t *seq, uint32_t *words)
{
    uint8_t b[CHUNK];
    uint32_t i, w, n, crc;
    const uint32_t base = hd_tstore_offset() + s * hd_tstore_slot_size();
    int blank = 1;
    if (hd_hal_nvm_read(base, b, HDR_BYTES) != 0) {
        return TSLOT_IOERR;
    }
    for (i = 0u; i < HDR_BYTES; i++) {
        if (b[i] != 0xFFu) {
            blank = 0;
        }
    }
    if (blank) {
        return TSLOT_EMPTY;
    }
    n = hd_get_le32(&b[12]);
    if (hd_get_le32(&b[0]) != HD_TSTORE_MAGIC || hd_get_le32(&b[4]) != HD_TSTORE_FORMAT ||
        (n != 0u && (n < HD_PREISACH_IMG_HDR || n > WORDS_MAX))) {
        return TSLOT_BAD;
    }
    *seq = hd_get_le32(&b[8]);
    crc = hd_crc32(0u, b, HDR_BYTES);
    for (w = 0u; w < n; w += CHUNK / 4u) {
        const uint32_t k = (n - w < CHUNK / 4u) ? n - w : CHUNK / 4u;
        if (hd_hal_nvm_read(base + HDR_BYTES + 4u * w, b, 4u * k) != 0) {
            return TSLOT_IOERR;
        }
        crc = hd_crc32(crc, b, 4u * k);
        if (t != NULL) {
            for (i = 0u; i < k; i++) {
                *hd_preisach_word(t, w + i) = hd_get_le32(&b[4u * i]);
            }
        }
    }
    if (hd_hal_nvm_read(base + HDR_BYTES + 4u * n, b, 4u) != 0) {
        return TSLOT_IOERR;
    }
    if (hd_get_le32(b) != crc) {
        return TSLOT_BAD;
    }
    *words = n;
    return TSLOT_OK;
}

/* the slot (0/1) of the newest valid record, -1 if none */
static int32_t newest(tslot_t r0, uint32_t s0, tslot_t r1, uint32_t s1)
{
    if (r0 == TSLOT_OK && r1 == TSLOT_OK) {
        return hd_seq_newer(s1, s0) ? 1 : 0;
    }
    return (r0 == TSLOT_OK) ? 0 : ((r1 == TSLOT_OK) ? 1 : -1);
}

int32_t hd_tstore_load(hd_preisach_table_t *t, uint32_t *seq)
{
    uint32_t s0 = 0u, s1 = 0u, n0 = 0u, n1 = 0u, sq = 0u, nw = 0u;
    tslot_t r0, r1;
    int32_t k;
    *seq = 0u;
    if (!region_ok()) {
        return HD_TSTORE_NVM_ERROR;
    }
    r0 = scan_slot(0u, NULL, &s0, &n0);
    r1 = scan_slot(1u, NULL, &s1, &n1);
    k = newest(r0, s0, r1, s1);
    if (k < 0) {
        if (r0 == TSLOT_IOERR || r1 == TSLOT_IOERR) {
            return HD_TSTORE_NVM_ERROR;
        }
        return (r0 == TSLOT_BAD || r1 == TSLOT_BAD) ? HD_TSTORE_CORRUPT : HD_TSTORE_BLANK;
    }
    /* the newest valid record is the last save's intent: its table or "no table"; a
     * torn (CRC-invalid) newer slot was skipped above, so power loss falls back */
    *seq = (k == 0) ? s0 : s1;
    if (((k == 0) ? n0 : n1) == 0u) {
        return HD_TSTORE_NONE;
    }
    if (scan_slot((uint32_t)k, t, &sq, &nw) != TSLOT_OK) {
        return HD_TSTORE_NVM_ERROR;         /* it read fine a moment ago */
    }
    if (nw != HD_PREISACH_IMG_HDR + t->n_entries || hd_preisach_check(t) != HD_PREISACH_OK) {
        return HD_TSTORE_CORRUPT;
    }
    return HD_TSTORE_OK;
}

/* streamed record writer: CHUNK bytes per hal write, at 8-aligned offsets */
typedef struct {
    uint8_t b[CHUNK];
    uint32_t fill;
    uint32_t at;       /* NVM offset of b[0] */
    int32_t err;
} writer_t;

static void flush(writer_t *wr)
{
    uint32_t len = (wr->fill + 7u) & ~7u;
    uint32_t i;
    for (i = wr->fill; i < len; i++) {
        wr->b[i] = 0xFFu;
    }
    if (len != 0u && wr->err == 0 && hd_hal_nvm_write(wr->at, wr->b, len) != 0) {
        wr->err = -1;
    }
    wr->at += len;
    wr->fill = 0u;
}

static void put_word(writer_t *wr, uint32_t v)
{
    hd_put_le32(&wr->b[wr->fill], v);
    wr->fill += 4u;
    if (wr->fill == CHUNK) {
        flush(wr);
    }
}

int32_t hd_tstore_save(const hd_preisach_table_t *t, uint32_t *seq)
{
    uint32_t s0 = 0u, s1 = 0u, n0 = 0u, n1 = 0u, sq = 0u, nw = 0u, w, crc;
    uint8_t hdr[HDR_BYTES];
    writer_t wr;
    tslot_t r0, r1;
    int32_t k;
    uint32_t target, nseq, n;
    if (t != NULL && hd_preisach_check(t) != HD_PREISACH_OK) {
        return -1;
    }
    if (!region_ok()) {
        return -2;
    }
    /* write the slot that does NOT hold the newest valid record */
    r0 = scan_slot(0u, NULL, &s0, &n0);
    r1 = scan_slot(1u, NULL, &s1, &n1);
    k = newest(r0, s0, r1, s1);
    target = (k == 0) ? 1u : 0u;
    nseq = hd_seq_next(*seq, k >= 0, (k == 1) ? s1 : s0);
    n = (t != NULL) ? HD_PREISACH_IMG_HDR + t->n_entries : 0u;
    hd_put_le32(&hdr[0], HD_TSTORE_MAGIC);
    hd_put_le32(&hdr[4], HD_TSTORE_FORMAT);
    hd_put_le32(&hdr[8], nseq);
    hd_put_le32(&hdr[12], n);
    wr.fill = 0u;
    wr.at = hd_tstore_offset() + target * hd_tstore_slot_size();
    wr.err = 0;
    if (hd_hal_nvm_erase(wr.at, hd_tstore_slot_size()) != 0) {
        return -2;
    }
    crc = hd_crc32(0u, hdr, HDR_BYTES);
    for (w = 0u; w < HDR_BYTES / 4u; w++) {
        put_word(&wr, hd_get_le32(&hdr[4u * w]));
    }
    for (w = 0u; w < n; w++) {
        uint8_t le[4];
        const uint32_t v = hd_preisach_word_get(t, w);
        hd_put_le32(le, v);
        crc = hd_crc32(crc, le, 4u);
        put_word(&wr, v);
    }
    put_word(&wr, crc);
    flush(&wr);
    /* it counts only once it reads back whole */
    if (wr.err != 0 || scan_slot(target, NULL, &sq, &nw) != TSLOT_OK || sq != nseq || nw != n) {
        return -2;
    }
    *seq = nseq;
    return 0;
}
