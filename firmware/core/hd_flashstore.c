/*
 * hd_flashstore.c - wear-levelled atomic record store and virtual NVM
 * (see hd_flashstore.h).
 */
#include <stddef.h>
#include "hd_flashstore.h"
#include "hd_le32.h"

static uint32_t slot_addr(const hd_fstore_t *s, uint32_t slot)
{
    return (slot / s->per_page) * s->fl->page_size + (slot % s->per_page) * s->rec;
}

/* CRC over the payload read from flash in chunks; -1 on read error */
static int32_t payload_crc(const hd_fstore_t *s, uint32_t addr, uint32_t crc, uint32_t *out)
{
    uint8_t buf[64];
    uint32_t done = 0u;
    while (done < s->len) {
        const uint32_t n = (s->len - done < 64u) ? (s->len - done) : 64u;
        if (s->fl->read(s->fl->ctx, addr + done, buf, n) != 0) {
            return -1;
        }
        crc = hd_crc32(crc, buf, n);
        done += n;
    }
    *out = crc;
    return 0;
}

/* 1 if the slot holds a valid record (its sequence number in *seq) */
static int slot_valid(const hd_fstore_t *s, uint32_t slot, uint32_t *seq)
{
    uint8_t h[HD_FS_HDR];
    uint8_t t[HD_FS_TRL];
    uint32_t crc;
    const uint32_t a = slot_addr(s, slot);
    if (s->fl->read(s->fl->ctx, a, h, HD_FS_HDR) != 0 ||
        s->fl->read(s->fl->ctx, a + HD_FS_HDR + s->len, t, HD_FS_TRL) != 0) {
        return 0;
    }
    const uint32_t sq = hd_get_le32(&h[4]);
    if (hd_get_le32(&h[0]) != HD_FS_MAGIC || hd_get_le32(&h[8]) != s->len || hd_get_le32(&t[0]) != HD_FS_COMMIT ||
        hd_get_le32(&t[4]) != ~sq) {
        return 0;
    }
    if (payload_crc(s, a + HD_FS_HDR, hd_crc32(0u, h, 12u), &crc) != 0 || crc != hd_get_le32(&h[12])) {
        return 0;
    }
    *seq = sq;
    return 1;
}

static int slot_blank(const hd_fstore_t *s, uint32_t slot)
{
    uint8_t buf[64];
    uint32_t done = 0u;
    uint32_t i;
    const uint32_t a = slot_addr(s, slot);
    while (done < s->rec) {
        const uint32_t n = (s->rec - done < 64u) ? (s->rec - done) : 64u;
        if (s->fl->read(s->fl->ctx, a + done, buf, n) != 0) {
            return 0;
        }
        for (i = 0u; i < n; i++) {
            if (buf[i] != 0xFFu) {
                return 0;
            }
        }
        done += n;
    }
    return 1;
}

int32_t hd_fstore_open(hd_fstore_t *s, const hd_flash_if_t *fl, uint32_t len)
{
    uint32_t k, sq;
    if (fl == NULL || fl->n_pages < 2u || (fl->page_size % 8u) != 0u || (len % 8u) != 0u || len == 0u ||
        len > fl->page_size || HD_FS_HDR + HD_FS_TRL + len > fl->page_size) {
        return -1;
    }
    s->fl = fl;
    s->len = len;
    s->rec = HD_FS_HDR + len + HD_FS_TRL;
    s->per_page = fl->page_size / s->rec;
    s->n_slots = s->per_page * fl->n_pages;
    s->cur = 0u;
    s->seq = 0u;
    s->have = 0u;
    s->erases = 0u;
    for (k = 0u; k < s->n_slots; k++) {
        if (slot_valid(s, k, &sq) && (s->have == 0u || hd_seq_newer(sq, s->seq))) {
            s->have = 1u;
            s->cur = k;
            s->seq = sq;
        }
    }
    return 0;
}

int32_t hd_fstore_read(const hd_fstore_t *s, void *buf)
{
    if (s->have == 0u) {
        return -1;
    }
    return (s->fl->read(s->fl->ctx, slot_addr(s, s->cur) + HD_FS_HDR, buf, s->len) == 0) ? 0 : -1;
}

int32_t hd_fstore_save(hd_fstore_t *s, const void *payload)
{
    uint8_t h[HD_FS_HDR];
    uint8_t t[HD_FS_TRL];
    uint32_t tries, sq;
    const uint32_t seq = (s->have != 0u) ? s->seq + 1u : 1u;
    const uint32_t cur_page = s->cur / s->per_page;
    uint32_t target = (s->have != 0u) ? (s->cur + 1u) % s->n_slots : 0u;
    hd_put_le32(&h[0], HD_FS_MAGIC);
    hd_put_le32(&h[4], seq);
    hd_put_le32(&h[8], s->len);
    hd_put_le32(&h[12], hd_crc32(hd_crc32(0u, h, 12u), (const uint8_t *)payload, s->len));
    hd_put_le32(&t[0], HD_FS_COMMIT);
    hd_put_le32(&t[4], ~seq);
    for (tries = 0u; tries < s->n_slots; tries++, target = (target + 1u) % s->n_slots) {
        const uint32_t page = target / s->per_page;
        if (s->have != 0u && page == cur_page && target <= s->cur) {
            return -1;           /* wrapped round to the newest record's page: give up */
        }
        if ((target % s->per_page) == 0u) {
            if (s->fl->erase(s->fl->ctx, page) != 0) {
                continue;
            }
            s->erases++;
        }
        if (!slot_blank(s, target)) {
            continue;
        }
        const uint32_t a = slot_addr(s, target);
        if (s->fl->prog(s->fl->ctx, a, h, HD_FS_HDR) != 0 ||
            s->fl->prog(s->fl->ctx, a + HD_FS_HDR, payload, s->len) != 0 ||
            s->fl->prog(s->fl->ctx, a + HD_FS_HDR + s->len, t, HD_FS_TRL) != 0) {
            continue;
        }
        if (slot_valid(s, target, &sq) && sq == seq) {
            s->cur = target;
            s->seq = seq;
            s->have = 1u;
            return 0;
        }
    }
    return -1;
}

/* ---- virtual NVM ------------------------------------------------------------ */

#define VN_REC(v) (HD_FS_HDR + (v)->vpage + HD_FS_TRL)

/* 1 if physical page p holds a valid record; index and seq out */
static int vn_valid(const hd_vnvm_t *v, uint32_t p, uint32_t *idx, uint32_t *seq)
{
    uint8_t h[HD_FS_HDR];
    uint8_t t[HD_FS_TRL];
    uint8_t buf[64];
    uint32_t done = 0u;
    const uint32_t a = p * v->fl->page_size;
    if (v->fl->read(v->fl->ctx, a, h, HD_FS_HDR) != 0 ||
        v->fl->read(v->fl->ctx, a + HD_FS_HDR + v->vpage, t, HD_FS_TRL) != 0) {
        return 0;
    }
    if (hd_get_le32(&h[0]) != HD_VN_MAGIC || hd_get_le32(&h[4]) >= v->n_vpages || hd_get_le32(&h[12]) != v->vpage ||
        hd_get_le32(&t[4]) != HD_FS_COMMIT) {
        return 0;
    }
    uint32_t crc = hd_crc32(0u, h, HD_FS_HDR);
    while (done < v->vpage) {
        const uint32_t n = (v->vpage - done < 64u) ? (v->vpage - done) : 64u;
        if (v->fl->read(v->fl->ctx, a + HD_FS_HDR + done, buf, n) != 0) {
            return 0;
        }
        crc = hd_crc32(crc, buf, n);
        done += n;
    }
    if (crc != hd_get_le32(&t[0])) {
        return 0;
    }
    *idx = hd_get_le32(&h[4]);
    *seq = hd_get_le32(&h[8]);
    return 1;
}

int32_t hd_vnvm_open(hd_vnvm_t *v, const hd_flash_if_t *fl, uint32_t size, uint32_t page)
{
    uint32_t p, k, idx, sq;
    uint32_t have_seq = 0u;
    uint32_t best[HD_VNVM_MAX_VPAGES];
    if (fl == NULL || page < 8u || (page & (page - 1u)) != 0u || size == 0u || (size % page) != 0u ||
        size / page > HD_VNVM_MAX_VPAGES || HD_FS_HDR + page + HD_FS_TRL > fl->page_size ||
        (fl->page_size % 8u) != 0u || fl->n_pages < size / page + 1u) {
        return -1;
    }
    v->fl = fl;
    v->vpage = page;
    v->n_vpages = size / page;
    v->seq = 0u;
    v->last = fl->n_pages - 1u;
    v->erases = 0u;
    for (k = 0u; k < HD_VNVM_MAX_VPAGES; k++) {
        v->phys[k] = 0u;
        v->live[k] = 0u;
        v->pend_erase[k] = 0u;
        best[k] = 0u;
    }
    for (p = 0u; p < fl->n_pages; p++) {
        if (!vn_valid(v, p, &idx, &sq)) {
            continue;
        }
        if (v->live[idx] == 0u || hd_seq_newer(sq, best[idx])) {
            v->live[idx] = 1u;
            v->phys[idx] = p;
            best[idx] = sq;
        }
        if (have_seq == 0u || hd_seq_newer(sq, v->seq)) {
            have_seq = 1u;
            v->seq = sq;
            v->last = p;
        }
    }
    v->seq_open = v->seq;
    return 0;
}

void hd_vnvm_wear(const hd_vnvm_t *v, uint32_t *total, uint32_t *max_page)
{
    uint32_t k, live = 0u;
    for (k = 0u; k < v->n_vpages; k++) {
        live += (v->live[k] != 0u) ? 1u : 0u;
    }
    /* open ensures n_pages >= n_vpages + 1, so at least one page rotates */
    const uint32_t rot = v->fl->n_pages - live;
    *total = v->seq_open + v->erases;
    *max_page = (*total == 0u) ? 0u : (*total + rot - 1u) / rot + 1u;
}

static int range_ok(const hd_vnvm_t *v, uint32_t off, uint32_t len)
{
    const uint32_t size = v->n_vpages * v->vpage;
    return off <= size && len <= size - off;
}

int32_t hd_vnvm_read(const hd_vnvm_t *v, uint32_t off, void *buf, uint32_t len)
{
    uint8_t *p = (uint8_t *)buf;
    if (!range_ok(v, off, len)) {
        return -1;
    }
    while (len > 0u) {
        const uint32_t vp = off / v->vpage;
        const uint32_t in = off % v->vpage;
        const uint32_t n = (v->vpage - in < len) ? (v->vpage - in) : len;
        if (v->live[vp] == 0u || v->pend_erase[vp] != 0u) {
            uint32_t i;
            for (i = 0u; i < n; i++) {
                p[i] = 0xFFu;
            }
        } else if (v->fl->read(v->fl->ctx, v->phys[vp] * v->fl->page_size + HD_FS_HDR + in, p, n) != 0) {
            return -2;
        }
        p += n;
        off += n;
        len -= n;
    }
    return 0;
}

static int is_live_phys(const hd_vnvm_t *v, uint32_t p)
{
    uint32_t k;
    for (k = 0u; k < v->n_vpages; k++) {
        if (v->live[k] != 0u && v->phys[k] == p) {
            return 1;
        }
    }
    return 0;
}

/* a new record for virtual page vp: old content merged with data at [in, in + n) */
static int32_t vn_commit(hd_vnvm_t *v, uint32_t vp, uint32_t in, const uint8_t *data, uint32_t n)
{
    uint8_t h[HD_FS_HDR];
    uint8_t t[HD_FS_TRL];
    uint8_t buf[64];
    uint32_t tries, idx, sq;
    const uint32_t seq = v->seq + 1u;
    uint32_t p = v->last;
    hd_put_le32(&h[0], HD_VN_MAGIC);
    hd_put_le32(&h[4], vp);
    hd_put_le32(&h[8], seq);
    hd_put_le32(&h[12], v->vpage);
    for (tries = 0u; tries < v->fl->n_pages; tries++) {
        uint32_t done = 0u;
        uint32_t crc;
        int ok = 1;
        p = (p + 1u) % v->fl->n_pages;
        if (is_live_phys(v, p)) {
            continue;
        }
        v->last = p;
        if (v->fl->erase(v->fl->ctx, p) != 0) {
            continue;
        }
        v->erases++;
        const uint32_t a = p * v->fl->page_size;
        if (v->fl->prog(v->fl->ctx, a, h, HD_FS_HDR) != 0) {
            continue;
        }
        crc = hd_crc32(0u, h, HD_FS_HDR);
        while (done < v->vpage && ok) {
            const uint32_t m = (v->vpage - done < 64u) ? (v->vpage - done) : 64u;
            uint32_t i;
            if (hd_vnvm_read(v, vp * v->vpage + done, buf, m) != 0) {
                return -2;              /* the old content is unreadable: give up */
            }
            for (i = 0u; i < m; i++) {
                if (done + i >= in && done + i < in + n) {
                    buf[i] = data[done + i - in];
                }
            }
            crc = hd_crc32(crc, buf, m);
            ok = (v->fl->prog(v->fl->ctx, a + HD_FS_HDR + done, buf, m) == 0);
            done += m;
        }
        hd_put_le32(&t[0], crc);
        hd_put_le32(&t[4], HD_FS_COMMIT);
        if (!ok || v->fl->prog(v->fl->ctx, a + HD_FS_HDR + v->vpage, t, HD_FS_TRL) != 0) {
            continue;
        }
        if (vn_valid(v, p, &idx, &sq) && idx == vp && sq == seq) {
            v->seq = seq;
            v->phys[vp] = p;
            v->live[vp] = 1u;
            v->pend_erase[vp] = 0u;
            return 0;
        }
    }
    return -2;
}

int32_t hd_vnvm_write(hd_vnvm_t *v, uint32_t off, const void *buf, uint32_t len)
{
    uint8_t chk[64];
    const uint8_t *p = (const uint8_t *)buf;
    uint32_t i, k;
    if (!range_ok(v, off, len) || (off % 8u) != 0u || (len % 8u) != 0u) {
        return -1;
    }
    for (k = 0u; k < len; k += 64u) {           /* erased memory only: check first */
        const uint32_t n = (len - k < 64u) ? (len - k) : 64u;
        if (hd_vnvm_read(v, off + k, chk, n) != 0) {
            return -2;
        }
        for (i = 0u; i < n; i++) {
            if (chk[i] != 0xFFu) {
                return -1;
            }
        }
    }
    while (len > 0u) {                          /* one atomic record per virtual page */
        const uint32_t vp = off / v->vpage;
        const uint32_t in = off % v->vpage;
        const uint32_t n = (v->vpage - in < len) ? (v->vpage - in) : len;
        if (vn_commit(v, vp, in, p, n) != 0) {
            return -2;
        }
        p += n;
        off += n;
        len -= n;
    }
    return 0;
}

int32_t hd_vnvm_erase(hd_vnvm_t *v, uint32_t off, uint32_t len)
{
    uint32_t k;
    if (!range_ok(v, off, len) || (off % v->vpage) != 0u || (len % v->vpage) != 0u) {
        return -1;
    }
    for (k = off / v->vpage; k < (off + len) / v->vpage; k++) {
        v->pend_erase[k] = 1u;
    }
    return 0;
}
