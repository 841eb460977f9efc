/*
 * hd_rec_store.c - atomic two-slot record store in the hal NVM region.
 * Layout and rules: hd_rec_store.h.
 */
#include "hd_rec_store.h"
#include <stddef.h>
#include "hal.h"
#include "hd_crc32.h"
#include "hd_le32.h"

#define HDR_BYTES 16u
#define CHUNK     64u                  /* bytes per hal read (a multiple of 8) */
/* Bytes per hal write: one STM32G474 virtual page (hd_flashstore.h), because there every
 * hal write costs one flash page erase per virtual page it touches: a record written in
 * 1 KiB pieces from its page-aligned slot costs one erase per KiB, not one per 64 bytes.
 * A multiple of 8; the buffer lives only during a save, after the parameter store's
 * deeper save has returned (stack: docs/stm32g474.md). */
#define WCHUNK    1024u
#define FORMAT    1u

uint32_t hd_rstore_slot_bytes(uint32_t words_max)
{
    const uint32_t pg = hd_hal_nvm_page_size();
    const uint32_t rec = (HDR_BYTES + 4u * words_max + 4u + 7u) & ~7u;
    return (pg == 0u) ? 0u : ((rec + pg - 1u) / pg) * pg;
}

/* the store lies inside the hal's NVM and its slots can hold words_max words */
static int region_ok(const hd_rstore_t *s)
{
    const uint32_t size = hd_hal_nvm_size();
    return s->slot != 0u && s->slot >= hd_rstore_slot_bytes(s->words_max) && s->offset <= size &&
           s->slot <= (size - s->offset) / 2u;
}

typedef enum { RSLOT_EMPTY, RSLOT_BAD, RSLOT_OK, RSLOT_IOERR, RSLOT_OTHER } rslot_t;

/* the owner's verdict so far, with the one on word w of v added (OTHER outweighs BAD) */
static int32_t verdict(const hd_rstore_t *s, int32_t so_far, uint32_t words, uint32_t w, uint32_t v)
{
    const int32_t r = (s->check != NULL) ? s->check(words, w, v) : (int32_t)HD_RSTORE_WORD_OK;
    if (so_far == (int32_t)HD_RSTORE_WORD_OTHER || r == (int32_t)HD_RSTORE_WORD_OTHER) {
        return (int32_t)HD_RSTORE_WORD_OTHER;
    }
    return (so_far != (int32_t)HD_RSTORE_WORD_OK) ? so_far : r;
}

/* Read slot k: header, payload and CRC, streamed; put (if not NULL) gets the payload
 * words, the owner's check sees them.  *seq and *words are set when the slot is OK. */
static rslot_t scan_slot(const hd_rstore_t *s, uint32_t k, void *ctx, hd_rstore_put_fn put,
                         uint32_t *seq, uint32_t *words)
{
    uint8_t b[CHUNK];
    uint32_t i, w, n, crc;
    const uint32_t base = s->offset + k * s->slot;
    int blank = 1;
    int32_t vd;
    if (hd_hal_nvm_read(base, b, HDR_BYTES) != 0) {
        return RSLOT_IOERR;
    }
    for (i = 0u; i < HDR_BYTES; i++) {
        if (b[i] != 0xFFu) {
            blank = 0;
        }
    }
    if (blank) {
        return RSLOT_EMPTY;
    }
    n = hd_get_le32(&b[12]);
    if (hd_get_le32(&b[0]) != s->magic || hd_get_le32(&b[4]) != FORMAT || n > s->words_max) {
        return RSLOT_BAD;
    }
    *seq = hd_get_le32(&b[8]);
    crc = hd_crc32(0u, b, HDR_BYTES);
    vd = verdict(s, (int32_t)HD_RSTORE_WORD_OK, n, n, 0u);
    for (w = 0u; w < n; w += CHUNK / 4u) {
        const uint32_t m = (n - w < CHUNK / 4u) ? n - w : CHUNK / 4u;
        if (hd_hal_nvm_read(base + HDR_BYTES + 4u * w, b, 4u * m) != 0) {
            return RSLOT_IOERR;
        }
        crc = hd_crc32(crc, b, 4u * m);
        for (i = 0u; i < m; i++) {
            const uint32_t v = hd_get_le32(&b[4u * i]);
            vd = verdict(s, vd, n, w + i, v);
            if (put != NULL) {
                put(ctx, w + i, v);
            }
        }
    }
    if (hd_hal_nvm_read(base + HDR_BYTES + 4u * n, b, 4u) != 0) {
        return RSLOT_IOERR;
    }
    if (hd_get_le32(b) != crc || vd == (int32_t)HD_RSTORE_WORD_BAD) {
        return RSLOT_BAD;
    }
    if (vd == (int32_t)HD_RSTORE_WORD_OTHER) {
        return RSLOT_OTHER;
    }
    *words = n;
    return RSLOT_OK;
}

/* the slot (0/1) of the newest valid record, -1 if none */
static int32_t newest(rslot_t r0, uint32_t s0, rslot_t r1, uint32_t s1)
{
    if (r0 == RSLOT_OK && r1 == RSLOT_OK) {
        return hd_seq_newer(s1, s0) ? 1 : 0;
    }
    return (r0 == RSLOT_OK) ? 0 : ((r1 == RSLOT_OK) ? 1 : -1);
}

int32_t hd_rstore_load(const hd_rstore_t *s, void *ctx, hd_rstore_put_fn put, uint32_t *seq, uint32_t *words)
{
    uint32_t s0 = 0u, s1 = 0u, n0 = 0u, n1 = 0u, sq = 0u, nw = 0u;
    rslot_t r0, r1, r;
    int32_t k;
    *seq = 0u;
    *words = 0u;
    if (!region_ok(s)) {
        return HD_RSTORE_NVM_ERROR;
    }
    /* first pass: which slots are whole (nothing delivered from a torn record) */
    r0 = scan_slot(s, 0u, NULL, NULL, &s0, &n0);
    r1 = scan_slot(s, 1u, NULL, NULL, &s1, &n1);
    k = newest(r0, s0, r1, s1);
    if (k < 0) {
        if (r0 == RSLOT_IOERR || r1 == RSLOT_IOERR) {
            return HD_RSTORE_NVM_ERROR;
        }
        if (r0 == RSLOT_OTHER || r1 == RSLOT_OTHER) {
            return HD_RSTORE_OTHER;
        }
        return (r0 == RSLOT_BAD || r1 == RSLOT_BAD) ? HD_RSTORE_CORRUPT : HD_RSTORE_BLANK;
    }
    if (((k == 0) ? n0 : n1) == 0u) {
        *seq = (k == 0) ? s0 : s1;
        return HD_RSTORE_EMPTY;
    }
    r = scan_slot(s, (uint32_t)k, ctx, put, &sq, &nw);
    if (r != RSLOT_OK) {
        return (r == RSLOT_IOERR) ? HD_RSTORE_NVM_ERROR : HD_RSTORE_CORRUPT;   /* it read fine a moment ago */
    }
    *seq = sq;
    *words = nw;
    return HD_RSTORE_OK;
}

/* streamed record writer: WCHUNK bytes per hal write, at 8-aligned offsets */
typedef struct {
    uint8_t b[WCHUNK];
    uint32_t fill;
    uint32_t at;       /* NVM offset of b[0] */
    int32_t err;
} writer_t;

static void flush(writer_t *wr)
{
    const uint32_t len = (wr->fill + 7u) & ~7u;
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

/* append one word; returns the CRC continued over its 4 bytes */
static uint32_t put_word(writer_t *wr, uint32_t crc, uint32_t v)
{
    hd_put_le32(&wr->b[wr->fill], v);
    crc = hd_crc32(crc, &wr->b[wr->fill], 4u);
    wr->fill += 4u;
    if (wr->fill == WCHUNK) {
        flush(wr);
    }
    return crc;
}

/* 1 if slot k (valid, n words) holds exactly the words get() gives */
static int slot_equals(const hd_rstore_t *s, uint32_t k, uint32_t n, const void *ctx, hd_rstore_get_fn get,
                       uint32_t words)
{
    uint8_t b[CHUNK];
    uint32_t w, i;
    const uint32_t base = s->offset + k * s->slot + HDR_BYTES;
    if (n != words) {
        return 0;
    }
    for (w = 0u; w < n; w += CHUNK / 4u) {
        const uint32_t m = (n - w < CHUNK / 4u) ? n - w : CHUNK / 4u;
        if (hd_hal_nvm_read(base + 4u * w, b, 4u * m) != 0) {
            return 0;
        }
        for (i = 0u; i < m; i++) {
            if (hd_get_le32(&b[4u * i]) != get(ctx, w + i)) {
                return 0;
            }
        }
    }
    return 1;
}

int32_t hd_rstore_same(const hd_rstore_t *s, const void *ctx, hd_rstore_get_fn get, uint32_t words)
{
    uint32_t s0 = 0u, s1 = 0u, n0 = 0u, n1 = 0u;
    rslot_t r0, r1;
    int32_t k;
    if (words > s->words_max || !region_ok(s)) {
        return 0;
    }
    r0 = scan_slot(s, 0u, NULL, NULL, &s0, &n0);
    r1 = scan_slot(s, 1u, NULL, NULL, &s1, &n1);
    k = newest(r0, s0, r1, s1);
    if (k < 0) {
        return 0;
    }
    return slot_equals(s, (uint32_t)k, (k == 0) ? n0 : n1, ctx, get, words);
}

int32_t hd_rstore_save(const hd_rstore_t *s, const void *ctx, hd_rstore_get_fn get, uint32_t words, uint32_t *seq)
{
    uint32_t s0 = 0u, s1 = 0u, n0 = 0u, n1 = 0u, sq = 0u, nw = 0u, w, crc = 0u;
    writer_t wr;
    rslot_t r0, r1;
    int32_t k;
    uint32_t target, nseq;
    if (words > s->words_max) {
        return -1;
    }
    if (!region_ok(s)) {
        return -2;
    }
    /* write the slot that does NOT hold the newest valid record */
    r0 = scan_slot(s, 0u, NULL, NULL, &s0, &n0);
    r1 = scan_slot(s, 1u, NULL, NULL, &s1, &n1);
    k = newest(r0, s0, r1, s1);
    /* the newest record already holds these words: nothing to write (no flash wear) */
    if (k >= 0 && slot_equals(s, (uint32_t)k, (k == 0) ? n0 : n1, ctx, get, words)) {
        *seq = (k == 0) ? s0 : s1;
        return 0;
    }
    target = (k == 0) ? 1u : 0u;
    nseq = hd_seq_next(*seq, k >= 0, (k == 1) ? s1 : s0);
    wr.fill = 0u;
    wr.at = s->offset + target * s->slot;
    wr.err = 0;
    if (hd_hal_nvm_erase(wr.at, s->slot) != 0) {
        return -2;
    }
    crc = put_word(&wr, crc, s->magic);
    crc = put_word(&wr, crc, FORMAT);
    crc = put_word(&wr, crc, nseq);
    crc = put_word(&wr, crc, words);
    for (w = 0u; w < words; w++) {
        crc = put_word(&wr, crc, get(ctx, w));
    }
    (void)put_word(&wr, 0u, crc);
    flush(&wr);
    /* it counts only once it reads back whole */
    if (wr.err != 0 || scan_slot(s, target, NULL, NULL, &sq, &nw) != RSLOT_OK || sq != nseq || nw != words) {
        return -2;
    }
    *seq = nseq;
    return 0;
}
