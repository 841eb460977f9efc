/*
 * hd_rec_store.h - an atomic two-slot store of one record of 32-bit words in the hal
 * NVM region: the one implementation under the parameter store (hd_param_store.h), the
 * Preisach table store (hd_table_store.h) and the CANopen object store (hd_app_co.h).
 *
 * A store owns two slots of `slot` bytes (a page multiple) from `offset`.  A slot is
 *     header  { magic, format 1, sequence number, words }  4 x uint32 LE
 *     payload words x uint32 LE (0 words: an empty record, e.g. "no table")
 *     crc32   IEEE 802.3 over header + payload
 * padded with 0xFF to a multiple of 8 bytes.  Load delivers the payload of the valid
 * slot (magic, format, size, CRC) with the newer sequence number (serial-number
 * arithmetic), word by word to a callback; save erases and writes the slot that does
 * not hold the newest valid record, streamed through a 1 KiB buffer (one hal write
 * per KiB: one flash page erase per KiB on the STM32G474), and reads it back: a power loss during a save leaves the old record or the new one, never a mix.
 * A save of the words the newest valid record already holds writes nothing (no erase):
 * repeated saves of unchanged settings cost no flash wear.
 * An owner with rules of its own for the payload (the parameter store: its table
 * version, and every value in range) gives a check: a record it does not accept counts
 * as not valid, so load, same and save see the newest ACCEPTED record, and a load that
 * finds only records it refuses says whether one was of another kind (OTHER).
 */
#ifndef HD_REC_STORE_H
#define HD_REC_STORE_H

#include <stdint.h>

/** The owner's verdict on a record (hd_rstore_t.check). */
typedef enum {
    HD_RSTORE_WORD_OK = 0,     /* nothing against it */
    HD_RSTORE_WORD_OTHER = 1,  /* a record of another kind (e.g. another table version) */
    HD_RSTORE_WORD_BAD = 2     /* a value the owner never writes (e.g. out of range) */
} hd_rstore_verdict_t;

/** The owner's check of a record of `words` payload words: called with w = words
 *  (the length alone, v = 0), then with each payload word v at w = 0 .. words - 1;
 *  returns hd_rstore_verdict_t.  OTHER outweighs BAD. */
typedef int32_t (*hd_rstore_check_fn)(uint32_t words, uint32_t w, uint32_t v);

typedef struct {
    uint32_t offset;      /* hal NVM offset of slot 0 (slot 1 follows) */
    uint32_t slot;        /* bytes per slot, a page multiple (hd_rstore_slot_bytes) */
    uint32_t magic;       /* record magic */
    uint32_t words_max;   /* payload words at most */
    hd_rstore_check_fn check;   /* NULL: every valid record is accepted */
} hd_rstore_t;

typedef enum {
    HD_RSTORE_OK = 0,          /* a record was delivered */
    HD_RSTORE_BLANK = 1,       /* nothing saved yet */
    HD_RSTORE_CORRUPT = 2,     /* slot(s) present but none valid */
    HD_RSTORE_EMPTY = 3,       /* the newest valid record has no words */
    HD_RSTORE_NVM_ERROR = 4,   /* region outside the NVM, or a hal call failed */
    HD_RSTORE_OTHER = 5        /* no record accepted, one (at least) of another kind (check) */
} hd_rstore_status_t;

/** Payload word w of the record being saved. */
typedef uint32_t (*hd_rstore_get_fn)(const void *ctx, uint32_t w);
/** Payload word w of the record being loaded. */
typedef void (*hd_rstore_put_fn)(void *ctx, uint32_t w, uint32_t v);

/** Slot bytes for up to words_max payload words at the hal's page size (0: no pages). */
uint32_t hd_rstore_slot_bytes(uint32_t words_max);
/** Deliver the newest valid record to put(); *words gets its length.  A CORRUPT or
 *  NVM_ERROR result may follow calls of put() (a record that failed its CRC while
 *  being delivered). Returns hd_rstore_status_t; *seq is 0 unless OK or EMPTY. */
int32_t hd_rstore_load(const hd_rstore_t *s, void *ctx, hd_rstore_put_fn put, uint32_t *seq, uint32_t *words);
/** 1 if the newest valid record holds exactly these words (a save would write nothing), else 0. */
int32_t hd_rstore_same(const hd_rstore_t *s, const void *ctx, hd_rstore_get_fn get, uint32_t words);
/** Save words payload words from get() with a sequence number newer than *seq and than
 *  the record that survives; updates *seq.  Equal to the newest valid record: nothing is
 *  written, *seq becomes that record's.  0 ok, -1 too many words, -2 NVM error. */
int32_t hd_rstore_save(const hd_rstore_t *s, const void *ctx, hd_rstore_get_fn get, uint32_t words, uint32_t *seq);

#endif
