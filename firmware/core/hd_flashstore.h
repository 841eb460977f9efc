/*
 * hd_flashstore.h - a wear-levelled, CRC-protected, power-loss-atomic record
 * store on NOR flash, and the byte-addressed "virtual NVM" of hal.h on top.
 *
 * Flash model (hd_flash_if_t, implemented by the port or a test):
 * n_pages pages of page_size bytes; erase sets a whole page to 0xFF; program
 * writes 8-byte aligned dwords (64 bit) of erased memory (STM32G4 rule); an
 * interrupted erase or program may leave the page / dword (64 bit) in ANY state,
 * and a read of a torn dword (64 bit) may fail (the G4's ECC two-bit error:
 * read() returns < 0).
 *
 * Store: fixed-size records in slots; each page holds floor(page_size / rec)
 * slots, slots never cross a page.  A record is
 *     header  { 'HDFS', seq, len, crc32 }     16 bytes (uint32 LE)
 *     payload len bytes (len a multiple of 8)
 *     trailer { 'CMIT', ~seq }                 8 bytes, programmed LAST
 * crc32 (IEEE 802.3) covers magic, seq, len and the payload.  A slot is valid
 * only if magic, len, trailer and CRC all match.  Open scans every slot and
 * takes the valid record with the newest sequence number (serial-number
 * arithmetic, RFC 1982).  Save writes the NEXT slot after the newest record
 * (ring order over all pages: wear levelling, every page is erased equally
 * often); entering a new page erases it first (it holds only older records,
 * never the newest: at least 2 pages); a slot that is not blank (left by an
 * interrupted save) is skipped.  The record is read back and checked before
 * it counts.  Power loss at any point therefore leaves the newest valid record
 * either the old one or the new one, never a mix.
 *
 * Virtual NVM (hd_vnvm_t): hal.h's NVM region (n_vpages virtual pages of
 * vpage bytes; program 8-byte multiples of erased memory) without a RAM
 * image.  Each virtual page lives in one physical page as a record
 *     header  { 'HDVN', vpage index, seq, vpage size }   16 bytes
 *     data    vpage bytes
 *     trailer { crc32 of header + data, 'CMIT' }        8 bytes, programmed LAST
 * and the newest valid record (global sequence number) of each index wins.
 * A write merges the old content of the virtual page (read from flash) with
 * the new bytes while streaming a new record into a FREE physical page (one
 * that holds no live record), taken in ring order from the last one used:
 * wear levelling, and the old record stays valid until the new one is
 * committed, so every hal write is atomic (old or new page content).  An
 * erase is recorded in RAM only (the page then reads 0xFF) and takes effect
 * with the next write of that page; lost by a power cut it simply did not
 * happen - the page keeps its older valid content, which hal.h allows and the
 * parameter store's sequence numbers handle.  Needs n_pages >= n_vpages + 1.
 * Every hal write costs one page erase per virtual page it touches (hd_vnvm_wear
 * counts them); the stores on top write only records that changed.
 */
#ifndef HD_FLASHSTORE_H
#define HD_FLASHSTORE_H

#include <stdint.h>
#include "hd_crc32.h"

#define HD_FS_MAGIC   0x53464448u   /* "HDFS" */
#define HD_FS_COMMIT  0x54494D43u   /* "CMIT" */
#define HD_FS_HDR     16u
#define HD_FS_TRL     8u

typedef struct {
    void *ctx;
    /** Copy len bytes at addr (byte offset in the store's area). 0 ok, < 0 error (e.g. ECC). */
    int32_t (*read)(void *ctx, uint32_t addr, void *buf, uint32_t len);
    /** Program len bytes (addr, len multiples of 8) into erased memory. 0 ok, < 0 error. */
    int32_t (*prog)(void *ctx, uint32_t addr, const void *buf, uint32_t len);
    /** Erase one page. 0 ok, < 0 error. */
    int32_t (*erase)(void *ctx, uint32_t page);
    uint32_t page_size;   /* bytes, a multiple of 8 */
    uint32_t n_pages;     /* >= 2 */
} hd_flash_if_t;

typedef struct {
    const hd_flash_if_t *fl;
    uint32_t len;        /* payload bytes */
    uint32_t rec;        /* record bytes = HD_FS_HDR + len + HD_FS_TRL */
    uint32_t per_page;   /* slots per page */
    uint32_t n_slots;
    uint32_t cur;        /* slot of the newest valid record (if have) */
    uint32_t seq;        /* its sequence number */
    uint32_t have;       /* 1 if a valid record exists */
    uint32_t erases;     /* pages erased by this instance (statistics) */
} hd_fstore_t;


/** Scan the flash for the newest valid record of len payload bytes.
 *  0 ok (s->have says whether one was found), -1 bad geometry. */
int32_t hd_fstore_open(hd_fstore_t *s, const hd_flash_if_t *fl, uint32_t len);
/** Copy the newest payload (len bytes) into buf. 0 ok, -1 none / read error. */
int32_t hd_fstore_read(const hd_fstore_t *s, void *buf);
/** Save a new payload (len bytes). 0 ok (it is now the newest), -1 error (old one kept). */
int32_t hd_fstore_save(hd_fstore_t *s, const void *payload);

#define HD_VNVM_MAX_VPAGES 24u
#define HD_VN_MAGIC   0x4E564448u   /* "HDVN" */

typedef struct {
    const hd_flash_if_t *fl;
    uint32_t n_vpages;                     /* virtual pages, 1..HD_VNVM_MAX_VPAGES */
    uint32_t vpage;                        /* virtual page bytes, power of two, >= 8 */
    uint32_t seq;                          /* newest sequence number in the store */
    uint32_t last;                         /* physical page used last */
    uint32_t phys[HD_VNVM_MAX_VPAGES];     /* physical page of the live record */
    uint32_t live[HD_VNVM_MAX_VPAGES];     /* 1 if the virtual page has a record */
    uint32_t pend_erase[HD_VNVM_MAX_VPAGES]; /* 1 if erased since (reads 0xFF) */
    uint32_t erases;                       /* physical erases by this instance */
    uint32_t seq_open;                     /* newest sequence number found by open */
} hd_vnvm_t;

/** Open the virtual NVM of size bytes in erase pages of page bytes (scans the flash).
 *  0 ok, -1 bad geometry (page not a power of two, size not a multiple, too many
 *  virtual pages, a record does not fit a physical page, or too few physical pages). */
int32_t hd_vnvm_open(hd_vnvm_t *v, const hd_flash_if_t *fl, uint32_t size, uint32_t page);
/** hal.h semantics: 0 ok, < 0 bad range / not erased / flash error (image unchanged). */
int32_t hd_vnvm_read(const hd_vnvm_t *v, uint32_t off, void *buf, uint32_t len);
int32_t hd_vnvm_write(hd_vnvm_t *v, uint32_t off, const void *buf, uint32_t len);
int32_t hd_vnvm_erase(hd_vnvm_t *v, uint32_t off, uint32_t len);
/** Flash wear, persisted without a counter of its own: every committed record took one
 *  page erase and carries the next sequence number, so the sequence number found at open
 *  (+ the erases since) is the erases since the area was blank (*total; a failed try
 *  before a boot is not counted).  Free pages are taken in ring order and each live
 *  virtual page is skipped at most once per round, so no page is erased more than
 *  ceil(total / (n_pages - live)) + 1 times (*max_page, an upper bound). */
void hd_vnvm_wear(const hd_vnvm_t *v, uint32_t *total, uint32_t *max_page);

#endif
