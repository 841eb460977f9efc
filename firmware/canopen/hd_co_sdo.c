/*
 * hd_co_sdo.c - CiA 301 SDO server: expedited, segmented and block transfers
 * (upload and download, CRC-16 of the block transfer), aborts and the server-side
 * time-out.  Values go through the object dictionary access (hd_co_od_access.c);
 * domains stream through the app's domain callbacks.
 */
#include "hd_co_util.h"
#include "hd_co_internal.h"
#include "hd_le32.h"

/* SDO server states (hd_co_sdo_t.state). */
typedef enum {
    SDO_IDLE = 0,
    SDO_DL_SEG,
    SDO_UL_SEG,
    SDO_BLK_DL,
    SDO_BLK_DL_END,
    SDO_BLK_UL_INIT,
    SDO_BLK_UL_SEND,
    SDO_BLK_UL_ACK,
    SDO_BLK_UL_END
} hd_co_sdo_state_t;

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

/* The entry of index:sub for a master (SDO): the device profile's filter first
 * (hd_co_app_if_t.object_filter), then the table, then the access right (write or read).
 * 0 and *ent, or the abort code. */
static uint32_t sdo_entry(const hd_co_t *co, uint16_t index, uint8_t sub, bool write, uint32_t *ent)
{
    uint32_t ab = 0u;
    if (co->app.object_filter != NULL) {
        ab = co->app.object_filter(co->app.ctx, index, sub);
    }
    if (ab == 0u) {
        ab = hd_co__lookup(co, index, sub, ent);
    }
    if (ab == 0u) {
        ab = hd_co__check_access(co, *ent, write);
    }
    return ab;
}

static uint32_t sdo_tx_id(const hd_co_t *co) { return 0x580u + co->node_id; }

static void sdo_abort(hd_co_t *co, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t d[8];
    d[0] = 0x80u;
    d[1] = (uint8_t)(index & 0xFFu);
    d[2] = (uint8_t)(index >> 8);
    d[3] = sub;
    hd_put_le32(&d[4], code);
    hd_co__send(co, sdo_tx_id(co), 8u, d);
    co->last_abort = code;
    co->stats.sdo_aborts_sent++;
}

void hd_co__sdo_reset(hd_co_t *co, bool domain_discard)
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
    hd_co__sdo_reset(co, true);
    sdo_abort(co, ix, sb, code);
}

/* a download whose commit was refused: dl_commit has already ended a domain transfer (the
 * domain refused or kept its old content, nothing to discard), yet the abort still names the
 * object (CiA 301: the abort carries the transfer's multiplexer; a master matches on it) */
static void sdo_commit_refused(hd_co_t *co, uint32_t code)
{
    const hd_co_entry_t *e = &co->table[co->sdo.ent];
    const uint16_t ix = e->index;
    const uint8_t sb = e->sub;
    hd_co__sdo_reset(co, false);
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
    hd_put_le32(&d[4], v);
    hd_co__send(co, sdo_tx_id(co), 8u, d);
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
    uint32_t ab = sdo_entry(co, index, sub, true, &ent);
    if (ab != 0u) {
        sdo_abort(co, index, sub, ab);
        return;
    }
    bool e = (d[0] & 0x02u) != 0u;
    bool sz = (d[0] & 0x01u) != 0u;
    uint32_t tsize = hd_co__type_size(co->table[ent].type);
    if (e) {
        uint32_t n = sz ? 4u - ((uint32_t)(d[0] >> 2) & 3u) : (tsize != 0u && tsize < 4u ? tsize : 4u);
        if (is_domain(co, ent)) {
            ab = domain_begin(co, ent, n);
            if (ab == 0u) {
                s->ent = (uint16_t)ent;
                s->state = SDO_DL_SEG;   /* so that a failure discards */
                ab = dl_sink(co, &d[4], n);
                if (ab != 0u) {
                    sdo_fail(co, ab);
                    return;
                }
                ab = dl_commit(co);
                if (ab != 0u) {
                    sdo_commit_refused(co, ab);
                    return;
                }
                hd_co__sdo_reset(co, false);
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
    uint32_t size = sz ? hd_get_le32(&d[4]) : 0u;
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
    hd_co__sdo_reset(co, false);
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
            sdo_commit_refused(co, ab);
            return;
        }
        hd_co__sdo_reset(co, false);
    } else {
        s->toggle ^= 1u;
        s->deadline_us = co->now_us + (uint64_t)co->sdo_timeout_ms * 1000u;
    }
    hd_co__send(co, sdo_tx_id(co), 8u, reply);
}

/* Start an upload of index:sub (expedited/segmented or block): look the object up,
 * check read access, reset the SDO state and get the size.  On any refusal the
 * transfer is aborted with the code and false is returned. */
static bool upload_open(hd_co_t *co, uint16_t index, uint8_t sub, uint32_t *size)
{
    hd_co_sdo_t *s = &co->sdo;
    uint32_t ent;
    uint32_t ab = sdo_entry(co, index, sub, false, &ent);
    hd_co__sdo_reset(co, false);
    *size = 0u;
    if (ab == 0u) {
        s->ent = (uint16_t)ent;
        ab = ul_size(co, ent, size);
    }
    if (ab != 0u) {
        hd_co__sdo_reset(co, false);
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
            hd_co__sdo_reset(co, false);
            sdo_abort(co, index, sub, ab);
            return;
        }
        sdo_reply(co, (uint8_t)(0x43u | ((4u - size) << 2)), index, sub, hd_get_le32(v));
        hd_co__sdo_reset(co, false);
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
    hd_co__send(co, sdo_tx_id(co), 8u, reply);
    if (last) {
        hd_co__sdo_reset(co, false);
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
    uint32_t ab = sdo_entry(co, index, sub, true, &ent);
    uint32_t size = (d[0] & 0x02u) != 0u ? hd_get_le32(&d[4]) : 0u;
    if (ab == 0u) {
        if (is_domain(co, ent)) {
            ab = domain_begin(co, ent, size);
        } else {
            uint32_t tsize = hd_co__type_size(co->table[ent].type);
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
    hd_co__sdo_reset(co, false);
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
    hd_co__send(co, sdo_tx_id(co), 8u, r);
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
        hd_co__send(co, sdo_tx_id(co), 8u, r);
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
        sdo_commit_refused(co, ab);
        return;
    }
    hd_co__sdo_reset(co, false);
    uint8_t r[8] = {0};
    r[0] = 0xA1u;
    (void)ix;
    (void)sb;
    hd_co__send(co, sdo_tx_id(co), 8u, r);
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
        if (!hd_co__try_send(co, sdo_tx_id(co), 8u, f)) {
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
        hd_co__send(co, sdo_tx_id(co), 8u, r);
        s->state = SDO_BLK_UL_END;
        return;
    }
    s->state = SDO_BLK_UL_SEND;
    sdo_block_upload_pump(co);
}

void hd_co__sdo_process(hd_co_t *co, const hd_can_frame_t *f)
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
            hd_co__sdo_reset(co, true);            /* client abort */
            return;
        }
        sdo_block_download_segment(co, d);
        return;
    }
    uint8_t ccs = (uint8_t)(d[0] >> 5);
    uint16_t index = (uint16_t)(d[1] | ((uint32_t)d[2] << 8));
    uint8_t sub = d[3];
    if (ccs == 4u) {                        /* abort from the client */
        hd_co__sdo_reset(co, true);
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
            hd_co__sdo_reset(co, false);
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
        hd_co__sdo_reset(co, true);
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

void hd_co__sdo_tick(hd_co_t *co)
{
    if (co->sdo.state != SDO_IDLE && co->now_us > co->sdo.deadline_us) {
        sdo_fail(co, HD_CO_AB_TIMEOUT);
    }
    if (co->sdo.state == SDO_BLK_UL_SEND) {
        sdo_block_upload_pump(co);
    }
}
