/*
 * hd_param_store.h - parameter values, range checks, and the NVM store.
 *
 * Values live in an int32 array indexed by hd_param_id_t (raw = round(SI *
 * 2^frac), see the generated hd_param_table.h and docs/parameters.md).
 *
 * NVM layout (through hal.h): one record of the two-slot record store
 * (hd_rec_store.h) from offset 0, magic 'HDPS'.  A slot is
 *     header { magic 'HDPS', format 1, sequence number, words = 2 + count }
 *     payload { table version, table hash, values[count] (int32) }
 *     crc32   (IEEE 802.3 CRC-32 over header + payload)
 * all little-endian 32-bit words, padded to a multiple of 8 bytes.  Load picks
 * the valid slot with the newer sequence number (serial-number arithmetic); save
 * erases and writes the OTHER slot with a newer sequence and reads it back, so a
 * power loss during save leaves the old set or the new set, never a mix.  A slot
 * whose magic, CRC, format, table version, hash or count disagrees is ignored,
 * and so is one with a value out of its range; if no slot is usable the defaults
 * are loaded and the status says why.  A save of the values the newest valid
 * slot already holds writes nothing (no erase, no flash wear).
 */
#ifndef HD_PARAM_STORE_H
#define HD_PARAM_STORE_H

#include <stdint.h>
#include "hd_param_table.h"
#include "hd_crc32.h"          /* the records' CRC */

typedef enum {
    HD_PSTORE_OK = 0,             /* loaded from NVM */
    HD_PSTORE_BLANK = 1,          /* no slot written yet: defaults */
    HD_PSTORE_CORRUPT = 2,        /* slot(s) present but bad CRC/magic/range: defaults */
    HD_PSTORE_INCOMPATIBLE = 3,   /* valid slot of another table version/layout: defaults */
    HD_PSTORE_NVM_ERROR = 4       /* hal NVM call failed: defaults */
} hd_pstore_status_t;

#define HD_PSTORE_MAGIC 0x53504448u  /* "HDPS" */
#define HD_PSTORE_FORMAT 1u

/** Fill values with the table defaults. */
void hd_params_defaults(int32_t values[HD_PARAM_COUNT]);
/** Range check one raw value. 0 ok, -1 unknown id or out of range. */
int32_t hd_params_check(uint32_t id, int32_t raw);

/** Bytes of the hal NVM region the store's two slots take from offset 0 (0: no page size). */
uint32_t hd_pstore_region(void);
/** Load from NVM into values (defaults on any failure); *seq gets the slot sequence (0 if none). */
int32_t hd_pstore_load(int32_t values[HD_PARAM_COUNT], uint32_t *seq);
/** 1 if the newest valid slot holds exactly these values (a save would write nothing), else 0. */
int32_t hd_pstore_same(const int32_t values[HD_PARAM_COUNT]);
/** Save values to the other slot with a newer sequence; updates *seq.  Values equal to the
 *  newest valid slot: nothing is written, *seq becomes that slot's.  0 ok, -1 error. */
int32_t hd_pstore_save(const int32_t values[HD_PARAM_COUNT], uint32_t *seq);

#endif
