/*
 * hd_app_co.h - the adapter between the CANopen device (firmware/canopen,
 * hd_co_app_if_t) and the drive application (hd_app_t).  The STM32 image and
 * the virtual drive (`hdservo-sim serve`) use this same code.
 *
 * Use (port):
 *   hd_app_co_init(&ac, &co, &app, node_id, &port);   hd_co_init + boot-up
 *   per received frame:   hd_co_process(&co, &frame);
 *   per control period:   hd_app_step(&app); hd_co_tick(&co, HD_CO_TICK_US);
 * all from the same context as hd_app_step() (never from an interrupt that can
 * pre-empt a step): the adapter calls the app's command API directly.
 *
 * What it maps:
 *   drive parameters 0x2000.. <-> hd_app_param_get/set (refused value: 0x06090030)
 *   CiA 402 enable / setpoints / actual values / fault reset <-> app modes and
 *     references (bumpless: targets start at the actual values)
 *   host heartbeat lost or bus-off with 0x6007 = 1 -> hd_app_fault_raise(HD_FAULT_COMM):
 *     a latched app fault (power stage off), cleared only by the 402 fault reset
 *   CAN controller state <- hd_hal_can_status() every period; bus-off recovery
 *     -> hd_hal_can_recover() (hd_co.h hd_co_can_state)
 *   0x1010 save -> hd_app_store_all: parameters + the Preisach table in force
 *     (0x08000022 unless the power stage is off), then the stored CANopen objects
 *     (hd_co_store_*: communication and CiA 402 settings) in their own record after
 *     the table store (0x08000020 if that write fails)
 *   0x1011 restore -> defaults (parameters, stored objects) and no Preisach table,
 *     now (power stage off, else 0x08000022); 0x1010 then stores them
 *   0x5101 store status: parameter and table store status of the boot load, table
 *     saved (1 = the NVM holds the table in force), stored-object status; a stored
 *     image goes in through the SDO write checks (hd_co_store_apply): refused ->
 *     defaults, status 5, the object in :6, EMCY 0x6300
 *   0x1010 saves write only what changed (an unchanged record is not rewritten) and are
 *     rate-limited in flash page erases (HD_APP_CO_SAVE_*): over the limit a save that
 *     would change the NVM is refused with 0x08000021 and EMCY 0xFF10; 0x5102 reports
 *     the wear (port callback nvm_wear), the refusals and the credit left
 *   0x5000 capture: arm (1) with the signals / length / decimation /
 *     pre-trigger of 0x5000:3..6, command trigger (2), state, data (domain 0:
 *     int32 LE, frame-major, frame 0 = oldest)
 *   0x5100 tables (domains 1..3), each "payload + CRC-32 trailer" (CRC-32 IEEE
 *     of the payload, LE).  Written only with the power stage off (else
 *     0x08000022, checked at the start and at the commit); enabling the drive
 *     while one is being written aborts that transfer (0x08000022 to the client,
 *     staging discarded: hd_co_sdo_abort).  A payload that fails any check is refused with 0x08000020
 *     and the table in force stays; read-back returns the table in force
 *     (payload + trailer), empty before the first one.
 *       1 Preisach/Everett table: the hd_preisach_table_t image of
 *         hd_preisach.h (magic, format, levels, its own CRC-32, E[i][i] = 0)
 *         -> hd_app_comp_table() (compensator bank); kept over a power cycle
 *         once saved with 0x1010 (hd_table_store.h).
 *       2 friction (Stribeck + LuGre parameters) and 3 transmission-error
 *         harmonics: parameter groups, payload = magic ("HDFR" / "HDTE"),
 *         format 1, version (1..2^31-1), count, then `count` raw int32 in the
 *         order of hd_app_co_group_ids(); every value range-checked, all
 *         applied or none (old values restored); the version goes to the
 *         parameter tbl_fr_version / tbl_te_version (saved with the others).
 *   other domains (>= HD_APP_CO_DOM_PORT) and SYNC go to the port's callbacks.
 *   the port's object filter (optional, hd_app_co_port_t.object_filter): the objects a
 *     master may reach (the virtual drive's generic CiA 402 profile); none on the STM32.
 *   the motor encoder in output units (motor angle / gear ratio) -> 0x60E4:1.
 */
#ifndef HD_APP_CO_H
#define HD_APP_CO_H

#include <stdint.h>
#include <stdbool.h>
#include "hal.h"
#include "hd_app.h"
#include "hd_co.h"
#include "hd_co_402.h"
#include "hd_rec_store.h"

#define HD_APP_CO_DOM_CAPTURE   0u
#define HD_APP_CO_DOM_PREISACH  1u
#define HD_APP_CO_DOM_FRICTION  2u
#define HD_APP_CO_DOM_TE        3u
#define HD_APP_CO_DOM_PORT      4u      /* first domain handled by the port */

#define HD_APP_CO_MAGIC_FR      0x52464448u   /* "HDFR" little-endian */
#define HD_APP_CO_MAGIC_TE      0x45544448u   /* "HDTE" little-endian */
#define HD_APP_CO_GROUP_FORMAT  1u
#define HD_APP_CO_GROUP_MAX     24u           /* parameters per group */
#define HD_APP_CO_GROUP_HDR     4u            /* words before the values */

/* words of a table domain: Preisach header + crc + entries + trailer */
#define HD_APP_CO_STAGE_WORDS   (HD_PREISACH_HDR_WORDS + 1u + HD_PREISACH_N_MAX + 1u)

/** What the port provides. */
/* ac->mode while the quick stop runs (not a CiA 402 mode value; -1 is the vendor mode STAB) */
#define HD_APP_CO_MODE_QSTOP ((int8_t)-128)

typedef struct {
    void *ctx;
    /* required: one frame to the bus; false = TX queue full */
    bool (*send)(void *ctx, const hd_can_frame_t *f);
    /* optional: SYNC received (pacing of the virtual drive) */
    void (*on_sync)(void *ctx, uint8_t counter);
    /* optional: domains >= HD_APP_CO_DOM_PORT (same contract as hd_co_app_if_t) */
    uint32_t (*domain_size)(void *ctx, uint16_t dom, uint32_t *size);
    uint32_t (*domain_read)(void *ctx, uint16_t dom, uint32_t off, uint8_t *buf, uint32_t len);
    uint32_t (*domain_write_begin)(void *ctx, uint16_t dom, uint32_t size_or_0);
    uint32_t (*domain_write)(void *ctx, uint16_t dom, uint32_t off, const uint8_t *buf, uint32_t len);
    uint32_t (*domain_write_end)(void *ctx, uint16_t dom, uint32_t total, bool complete);
    /* optional: flash wear of the NVM area, page erases in all (*total) and of the most
     * erased page (*max_page); 0 ok.  Without it 0x5102:1/2 read 0 and a save that
     * changes the NVM costs HD_APP_CO_SAVE_COST_UNKNOWN of the rate limit's credit. */
    int32_t (*nvm_wear)(void *ctx, uint32_t *total, uint32_t *max_page);
    /* optional: the objects a master may reach (hd_co_app_if_t.object_filter): 0 or the
     * abort code.  NULL (the STM32 image) = the whole object dictionary; the virtual
     * drive's generic CiA 402 profile refuses the manufacturer objects with it. */
    uint32_t (*object_filter)(void *ctx, uint16_t index, uint8_t sub);
} hd_app_co_port_t;

/* 0x1010 save rate limit: a token bucket of flash page erases in the drive's own time
 * (hd_co now_us, advanced by hd_co_tick: lock-step reproducible, no wall clock).  The
 * STM32G474 flash endures 10 000 erases per page.  Of the 24 pages of the NVM area at
 * least 4 rotate (wear levelling: the two slots of the store being saved and the 2 free
 * pages, when everything else is saved and still), so one erase per 3 h for 10 years
 * (29 200) plus the burst is <= 7 340 erases per page, 1 230 when all 24 rotate.  The
 * burst of 160 is commissioning: about 14 saves with a new 64-level table (11 erases
 * each) or 160 saves of parameters or objects (1 erase each).
 * Saves that change nothing cost nothing and are never refused.  docs/can.md. */
#define HD_APP_CO_SAVE_CREDIT_MAX    160          /* page erases */
#define HD_APP_CO_SAVE_REFILL_US     10800000000ull  /* one page erase of credit per 3 h */
#define HD_APP_CO_SAVE_COST_UNKNOWN  16           /* credit of a save when the port counts no erases */
#define HD_APP_CO_AB_SAVE_RATE       0x08000021u  /* save refused: rate limit (local control) */
#define HD_APP_CO_EMCY_SAVE_RATE     0xFF10u      /* manufacturer: 0x1010 save refused by the rate limit */
#define HD_APP_CO_EMCY_STORE_REFUSED 0x6300u      /* data set: the stored objects were refused at boot */

typedef struct {
    hd_co_t *co;
    hd_co402_t p402;               /* the CiA 402 profile on top of co (hd_co402_use) */
    hd_app_t *app;
    hd_app_co_port_t port;
    int8_t   mode;                 /* 402 mode the app was enabled in (HD_APP_CO_MODE_QSTOP: quick stop) */
    uint8_t  stage_dom;            /* domain being written (0 = none) */
    uint8_t  stage_bad;            /* out-of-order or oversized data seen */
    uint8_t  halt;                 /* controlword bit 8 (halt) seen last period: its rising edge stops a PP move */
    uint32_t stage_len;            /* bytes received */
    uint32_t stage_crc;            /* running CRC-32 of the received bytes but the last 4 */
    uint8_t  stage_win[4];         /* the last 4 bytes received (the trailer at the end) */
    uint32_t rd_trailer;           /* trailer of the domain being uploaded */
    hd_preisach_table_t stage;     /* table being received: word w of the domain is field /
                                    * entry w of the image (any domain is staged here) */
    uint32_t stage_tail;           /* word HD_APP_CO_STAGE_WORDS - 1 (a full table's trailer) */
    uint32_t cstore_seq;           /* stored-object record (hd_rec_store.h) sequence */
    uint8_t  cstore_status;        /* HD_APP_CO_CSTORE_* of the boot load (0x5101:4) */
    uint32_t cstore_refused;       /* index << 8 | sub the boot load refused (0x5101:6) */
    int32_t  save_credit;          /* rate limit: page erases still allowed (0x5102:4) */
    uint64_t save_credit_us;       /* drive time the credit was last refilled to */
    uint32_t saves_refused;        /* saves refused by the rate limit (0x5102:3) */
    uint8_t  save_emcy;            /* 1: the rate-limit EMCY is active (cleared by a save) */
} hd_app_co_t;

/* the stored CANopen objects at boot (0x5101:4) */
#define HD_APP_CO_CSTORE_OK        0u   /* loaded */
#define HD_APP_CO_CSTORE_BLANK     1u   /* nothing saved: defaults */
#define HD_APP_CO_CSTORE_CORRUPT   2u   /* no valid record: defaults */
#define HD_APP_CO_CSTORE_OTHER     3u   /* another object dictionary's record, or a value out of range: defaults */
#define HD_APP_CO_CSTORE_NVM_ERROR 4u   /* defaults */
#define HD_APP_CO_CSTORE_REFUSED   5u   /* refused by the SDO write checks (EMCY 0x6300): defaults */
#define HD_APP_CO_CSTORE_MAGIC     0x53434448u  /* "HDCS" */

/** Wire the device to the app and start it (hd_co_init: boot-up goes out), then put
 *  the saved communication and CiA 402 objects in force (hd_co_store_apply). */
void hd_app_co_init(hd_app_co_t *ac, hd_co_t *co, hd_app_t *app, uint8_t node_id,
                    const hd_app_co_port_t *port);

/** Parameter ids of a group domain (HD_APP_CO_DOM_FRICTION / _TE); returns the count (0: none). */
uint32_t hd_app_co_group_ids(uint32_t dom, const uint16_t **ids);

/** EMCY error code of an app fault code. */
uint16_t hd_app_co_emcy_for_fault(int32_t fault);

#endif
