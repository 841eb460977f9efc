/*
 * hd_table_store.h - the Preisach table in NVM: an atomic two-slot store
 * (hd_rec_store.h) after the parameter store's slots, so an identified hysteresis
 * table survives a power cycle.
 *
 * NVM layout (through hal.h): the parameter store owns [0, hd_pstore_region());
 * this store owns two slots of hd_tstore_slot_size() bytes (a page multiple) from
 * there.  A slot is
 *     header { magic 'HDTS', format 1, sequence number, words }  4 x uint32 LE
 *     image  words x uint32 LE: the hd_preisach_table_t image in its wire order
 *            (hd_preisach_word(): 10 header words + n_entries entries), or no
 *            words at all: "no table" (saved after a restore of the defaults)
 *     crc32  IEEE 802.3 over header + image
 * padded with 0xFF to a multiple of 8 bytes.  Load takes the valid slot with the
 * newer sequence number (serial-number arithmetic) whose image also passes
 * hd_preisach_check() (the image carries its own CRC), else the other valid one;
 * save erases and writes the slot that does not hold the newest valid record and
 * reads it back, so a power loss during save leaves the old table or the new one,
 * never a mix.  Streamed through hd_rec_store's 1 KiB write buffer: no second table
 * image in RAM.
 */
#ifndef HD_TABLE_STORE_H
#define HD_TABLE_STORE_H

#include <stdint.h>
#include "hd_preisach.h"

typedef enum {
    HD_TSTORE_OK = 0,          /* a table was loaded */
    HD_TSTORE_BLANK = 1,       /* nothing saved yet: no table */
    HD_TSTORE_CORRUPT = 2,     /* slot(s) present but bad (CRC, magic, size, table check): no table */
    HD_TSTORE_NONE = 3,        /* a valid "no table" record: no table */
    HD_TSTORE_NVM_ERROR = 4    /* NVM too small or a hal call failed: no table */
} hd_tstore_status_t;

#define HD_TSTORE_MAGIC  0x53544448u  /* "HDTS" */
#define HD_TSTORE_FORMAT 1u

/** First byte of the store in the hal NVM region. */
uint32_t hd_tstore_offset(void);
/** Bytes of one slot (0 if the hal has no page size). */
uint32_t hd_tstore_slot_size(void);
/** Load the newest valid table into *t (whose content is undefined unless OK); *seq
 *  gets the record's sequence number (0 if none).  Returns hd_tstore_status_t. */
int32_t hd_tstore_load(hd_preisach_table_t *t, uint32_t *seq);
/** 1 if the newest valid record holds exactly *t (NULL: "no table"): a save would write nothing. */
int32_t hd_tstore_same(const hd_preisach_table_t *t);
/** Save *t (checked first; NULL: "no table"; equal to the newest record: nothing written) with a sequence newer than the slot that
 *  survives; updates *seq.  0 ok, -1 bad table, -2 NVM error (the old record stays). */
int32_t hd_tstore_save(const hd_preisach_table_t *t, uint32_t *seq);

#endif
