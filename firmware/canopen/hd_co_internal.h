/*
 * hd_co_internal.h - what the CiA 301 service files of the device share (hd_co.c,
 * hd_co_od_access.c, hd_co_cobid.c, hd_co_sdo.c, hd_co_pdo.c, hd_co_emcy.c,
 * hd_co_errors.c, hd_co_nmt.c, hd_co_store.c).  Not for the app, nor for a device
 * profile: those use hd_co.h only.  Each function is defined in the file named above
 * its group.
 */
#ifndef HD_CO_INTERNAL_H
#define HD_CO_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include "hd_co.h"

/* EMCY / PDO COB-IDs: bit 31 marks the object not used; bits 0-10 the identifier */
#define HD_CO_COB_INVALID   0x80000000u
#define HD_CO_COB_ID_MASK   0x7FFu

/* ---- hd_co.c: frames out -------------------------------------------------------- */

/** Send one frame (counted in tx_frames, or tx_dropped when the queue is full or the
 *  controller is off the bus). */
void hd_co__send(hd_co_t *co, uint32_t id, uint8_t dlc, const uint8_t *data);
/** Send one frame if the queue takes it (true); nothing is counted when it does not. */
bool hd_co__try_send(hd_co_t *co, uint32_t id, uint8_t dlc, const uint8_t *data);

/* ---- hd_co_od_access.c: values of the object dictionary ------------------------- */

/** Bytes of a CANopen basic type (0: not a fixed-size type). */
uint32_t hd_co__type_size(uint8_t t);
bool hd_co__type_signed(uint8_t t);
/** Little-endian bytes -> int64 (sign-extended for signed types). */
int64_t hd_co__decode_le(const uint8_t *p, uint32_t n, bool sgn);
void hd_co__encode_le(uint8_t *p, uint32_t n, int64_t v);
/** A VAR entry's value in co->od. */
void hd_co__var_store(hd_co_t *co, const hd_co_entry_t *e, int64_t v);
int64_t hd_co__var_load(const hd_co_t *co, const hd_co_entry_t *e);
/** 0 and the entry number, or the abort code for a missing object / sub-index. */
uint32_t hd_co__lookup(const hd_co_t *co, uint16_t index, uint8_t sub, uint32_t *ent);
/** Access rights of an entry for a master: 0 or the abort code. */
uint32_t hd_co__check_access(const hd_co_t *co, uint32_t ent, bool write);
/** The object rules of a value about to be stored in a VAR entry: 0 or an abort code. */
uint32_t hd_co__check_write(hd_co_t *co, const hd_co_entry_t *e, int64_t v);
/** The side effects of a VAR entry written (PDO rebuilt, heartbeat timers, the profile). */
void hd_co__after_write(hd_co_t *co, const hd_co_entry_t *e);
/** The VAR entries with index in [lo, hi] to their defaults (node-relative ones + node id). */
void hd_co__load_defaults(hd_co_t *co, uint16_t lo, uint16_t hi);

/* ---- hd_co_pdo.c ------------------------------------------------------------------ */

/** The PDO communication / mapping rules (index 0x1400-0x1BFF): 0 or an abort code. */
uint32_t hd_co__pdo_check_write(hd_co_t *co, const hd_co_entry_t *e, int64_t v);
/** The runtime of TPDO (tx) or RPDO i from its objects. */
void hd_co__pdo_rebuild(hd_co_t *co, bool tx, uint32_t i);
/** Every TPDO and RPDO rebuilt. */
void hd_co__pdo_rebuild_all(hd_co_t *co);
/** TPDO i's event-stream period (0x2F00+ objects), loop ticks; 0 = off. */
uint16_t hd_co__tpdo_stream_period(const hd_co_t *co, uint32_t i);
/** Event-driven TPDOs go out once on entering OPERATIONAL. */
void hd_co__tpdo_arm_events(hd_co_t *co);
/** One period of the event-driven TPDOs (OPERATIONAL). */
void hd_co__tpdo_tick(hd_co_t *co);
/** A SYNC received: synchronous RPDOs applied, synchronous TPDOs sent, the app told. */
void hd_co__on_sync(hd_co_t *co, uint8_t counter);
/** A frame on a valid RPDO's COB-ID id (OPERATIONAL): false when no RPDO has that id. */
bool hd_co__rpdo_receive(hd_co_t *co, const hd_can_frame_t *f, uint32_t id);

/* ---- hd_co_sdo.c -------------------------------------------------------------------- */

/** One frame to the SDO server (0x600 + node id). */
void hd_co__sdo_process(hd_co_t *co, const hd_can_frame_t *f);
/** Forget the running transfer; domain_discard: a domain download is discarded. */
void hd_co__sdo_reset(hd_co_t *co, bool domain_discard);
/** One period: time-out, block-upload segments the TX queue refused. */
void hd_co__sdo_tick(hd_co_t *co);

/* ---- hd_co_emcy.c -------------------------------------------------------------------- */

/** Send an EMCY frame now, or hold the newest back (inhibit time, bus-off). */
void hd_co__emcy_send(hd_co_t *co, const uint8_t d[8]);
/** One period: the EMCY held back goes out when allowed. */
void hd_co__emcy_tick(hd_co_t *co);

/* ---- hd_co_errors.c ------------------------------------------------------------------ */

/** Heartbeat lost or bus-off: EMCY, the 0x1029 NMT reaction, the profile's reaction. */
void hd_co__comm_error(hd_co_t *co, uint16_t code, const uint8_t mfr[5]);
/** One period: the controller's state polled, the bus-off recovery requested. */
void hd_co__can_tick(hd_co_t *co);

/* ---- hd_co_nmt.c ---------------------------------------------------------------------- */

/** One NMT command frame (COB-ID 0). */
void hd_co__nmt_process(hd_co_t *co, const hd_can_frame_t *f);
/** Reset communication: the communication objects to their defaults / the stored image,
 *  the boot-up message. */
void hd_co__reset_comm(hd_co_t *co);
/** A heartbeat frame from node id - 0x700 (the consumer of 0x1016:1). */
void hd_co__hb_receive(hd_co_t *co, const hd_can_frame_t *f, uint32_t id);
/** 0x1016 / 0x1017 written: the consumer restarts / the producer's next beat. */
void hd_co__hb_config_changed(hd_co_t *co, uint16_t index);
/** One period of the heartbeat producer. */
void hd_co__hb_produce(hd_co_t *co);
/** One period of the heartbeat consumer (suspended while off the bus). */
void hd_co__hb_consume(hd_co_t *co);

#endif /* HD_CO_INTERNAL_H */
