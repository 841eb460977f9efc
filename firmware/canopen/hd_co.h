/*
 * hd_co.h - the drive's CANopen device, CiA 301: NMT slave, heartbeat
 * producer/consumer, SDO server with expedited / segmented / block transfer,
 * EMCY, SYNC, TPDO/RPDO with configurable mapping, identity, store/restore.
 * A device profile plugs in on top through hd_co_profile_if_t; the drive's is
 * CiA 402 (hd_co_402.h).
 *
 * One service per file (docs/firmware.md, "The CANopen device"):
 *   hd_co.c          entry points: init, frame dispatch, the tick's order, frames out
 *   hd_co_od_access.c object dictionary access: lookup, read, write, object rules, defaults
 *   hd_co_cobid.c    COB-ID rules (SYNC, EMCY, PDO)
 *   hd_co_sdo.c      SDO server (expedited, segmented, block; CRC-16)
 *   hd_co_pdo.c      PDO mapping checks, TPDO/RPDO runtime, SYNC consumer
 *   hd_co_emcy.c     EMCY producer, error register, 0x1003 history
 *   hd_co_errors.c   communication errors: CAN controller state, bus-off, 0x1029
 *   hd_co_nmt.c      NMT slave, boot-up, heartbeat producer and consumer
 *   hd_co_store.c    stored objects (0x1010 image, NMT resets return to it)
 *
 * One device = one hd_co_t (no globals, no malloc).  The object dictionary
 * is the generated const table hd_co_od[] (hd_co_od.h); its data lives in
 * co->od.  The application is reached only through hd_co_app_if_t
 * (callbacks + context pointer), so the stack is tested without the app and
 * the same code serves the real drive and the virtual drive.
 *
 * Use:
 *   hd_co402_use(&p402, &app_if);            the CiA 402 profile on top (optional)
 *   hd_co_init(&co, node_id, &app_if);       boot-up message goes out at once
 *   per received frame:  hd_co_process(&co, &frame);
 *   per control period:  hd_co_tick(&co, HD_CO_TICK_US);   (timers, PDOs, the profile)
 * Frames go out through app_if.send (false = TX queue full: the stack retries
 * what it can, e.g. block-upload segments, and counts the rest in tx_dropped).
 *
 * Never trusts the bus: a frame with an unexpected DLC, an unknown COB-ID or
 * a malformed SDO sequence is ignored or answered with an SDO abort; no
 * state outside the addressed service changes.  Every value written through
 * SDO or RPDO is range-checked against the table before it is stored.
 */
#ifndef HD_CO_H
#define HD_CO_H

#include <stdint.h>
#include <stdbool.h>
#include "hal.h"
#include "hd_co_types.h"
#include "hd_co_od.h"
#include "hd_crc32.h"          /* the table container's CRC */

#define HD_CO_TICK_US          100u     /* one control period */
#define HD_CO_SDO_TIMEOUT_MS   1000u    /* server-side SDO transfer time-out */
#define HD_CO_SDO_BUF          64u      /* largest non-domain value */
#define HD_CO_BLKSIZE          127u     /* block size the server asks for */
#define HD_CO_ERR_HIST         8u       /* 0x1003 depth */
#define HD_CO_BUSOFF_RESTART_MS 100u    /* bus-off: time before the recovery is started (and repeated) */

/* NMT states (heartbeat encoding). */
#define HD_CO_NMT_INIT      0x00u
#define HD_CO_NMT_STOPPED   0x04u
#define HD_CO_NMT_OP        0x05u
#define HD_CO_NMT_PREOP     0x7Fu

/* SDO abort codes. */
#define HD_CO_AB_TOGGLE       0x05030000u
#define HD_CO_AB_TIMEOUT      0x05040000u
#define HD_CO_AB_CMD          0x05040001u
#define HD_CO_AB_BLKSIZE      0x05040002u
#define HD_CO_AB_SEQNO        0x05040003u
#define HD_CO_AB_CRC          0x05040004u
#define HD_CO_AB_WRITEONLY    0x06010001u
#define HD_CO_AB_READONLY     0x06010002u
#define HD_CO_AB_NO_OBJECT    0x06020000u
#define HD_CO_AB_NO_MAP       0x06040041u
#define HD_CO_AB_MAP_LEN      0x06040042u
#define HD_CO_AB_TYPE_LEN     0x06070010u
#define HD_CO_AB_LEN_HIGH     0x06070012u
#define HD_CO_AB_LEN_LOW      0x06070013u
#define HD_CO_AB_NO_SUB       0x06090011u
#define HD_CO_AB_VALUE        0x06090030u
#define HD_CO_AB_VALUE_HIGH   0x06090031u
#define HD_CO_AB_VALUE_LOW    0x06090032u
#define HD_CO_AB_GENERAL      0x08000000u
#define HD_CO_AB_STORE        0x08000020u
#define HD_CO_AB_STATE        0x08000022u

/* Error register bits (0x1001). */
#define HD_CO_ER_GENERIC   0x01u
#define HD_CO_ER_CURRENT   0x02u
#define HD_CO_ER_COMM      0x10u
#define HD_CO_ER_PROFILE   0x20u
#define HD_CO_ER_MFR       0x80u

/* EMCY codes used by the stack. */
#define HD_CO_EMCY_RESET        0x0000u
#define HD_CO_EMCY_HB           0x8130u  /* life guard / heartbeat error */
#define HD_CO_EMCY_CAN_PASSIVE  0x8120u  /* CAN in error passive mode */
#define HD_CO_EMCY_BUS_OFF      0x8140u  /* recovered from bus off */
#define HD_CO_EMCY_PDO_LEN      0x8210u
#define HD_CO_EMCY_CAN_OVERRUN  0x8110u
#define HD_CO_EMCY_COMM         0x8100u  /* communication, generic: an NMT command ended the
                                          * master's connection with the power stage on */

/** Words of the stored-object image at most (hd_co_store_*, below). */
#define HD_CO_STORE_MAX 192u

/** Setpoints a profile hands to the app every period (CiA 402: in OPERATION ENABLED /
 *  QUICK STOP). */
typedef struct {
    int8_t   mode;            /* HD_CO402_MODE_* (hd_co_402.h) */
    uint8_t  quick_stop;      /* 1: decelerate to standstill with quick_stop_decel */
    uint8_t  pp_new;          /* PP: a new set-point was latched this period */
    uint8_t  halt;            /* controlword bit 8 */
    int32_t  target_position; /* 2^-24 turn (output) */
    int32_t  target_velocity; /* 2^-32 turn/s */
    int32_t  velocity_offset; /* 2^-32 turn/s */
    int32_t  target_torque;   /* Q15.16 N.m, output (from 1/1000 rated, + offset) */
    /* the PP profile (0x6081/0x6083) is not here: those objects are the drive
     * parameters traj_vmax/traj_amax themselves (OD kind param) */
    uint32_t quick_stop_decel;     /* 2^-24 turn/s^2 (0x6085) */
    int16_t  quick_stop_option;    /* 0x605A: 1 stop at the profile deceleration, 2 at quick_stop_decel */
    int16_t  halt_option;          /* 0x605D: 1 stop at the profile deceleration, 2 at quick_stop_decel */
} hd_co_setpoint_t;

/** What the app reports every period. */
typedef struct {
    uint32_t tick;            /* loop tick */
    int64_t  load_angle;      /* Q32.32 turns */
    int64_t  motor_angle;     /* Q32.32 motor turns */
    int64_t  motor_angle_out; /* Q32.32 output turns: motor angle / gear ratio (0x60E4:1) */
    int64_t  setpoint_angle;  /* Q32.32 turns */
    int32_t  load_velocity;   /* 2^-32 turn/s */
    int32_t  motor_velocity;  /* 2^-24 turn/s */
    int32_t  output_torque;   /* Q15.16 N.m (output side command) */
    int32_t  motor_torque;    /* Q15.16 N.m (motor side command) */
    int32_t  motor_current;   /* Q15.16 A */
    uint16_t fault_code;      /* app fault (0 = none) */
    uint16_t fault_emcy;      /* EMCY error code of that fault */
    uint8_t  power_enabled;
    uint8_t  standstill;      /* |velocity| small (quick stop done) */
    uint8_t  at_rest;         /* the set-point generator at rest (PP: move finished or halted;
                               * other modes 1): bit 10 also needs the 0x6067/0x6068 window */
    uint8_t  internal_limit;
} hd_co_actual_t;

typedef struct hd_co_s hd_co_t;

/*
 * A device profile on top of the 301 services (CiA 402: hd_co_402.h).  The services call
 * it at these points only; it reaches the device through the public functions of this
 * header and the device's object data (co->od), never through the services' internals.
 * Every member is required; ctx is hd_co_app_if_t.profile_ctx.
 */
typedef struct {
    /* the profile's state from the start (hd_co_init, after the defaults, before the boot-up) */
    void     (*init)(void *ctx, hd_co_t *co);
    /* the profile's rules for a value about to be written to index:sub: 0 or an abort code */
    uint32_t (*check_write)(void *ctx, const hd_co_t *co, uint16_t index, uint8_t sub, int64_t v);
    /* index:sub was written (SDO, RPDO, local write) */
    void     (*after_write)(void *ctx, hd_co_t *co, uint16_t index, uint8_t sub);
    /* one control period (hd_co_tick, after the SDO server, before the TPDOs) */
    void     (*tick)(void *ctx, hd_co_t *co);
    /* a communication error (host heartbeat lost, bus-off): the profile's reaction */
    void     (*comm_error)(void *ctx, hd_co_t *co, uint16_t emcy_code);
    /* an NMT command ends the master's connection (stop, pre-operational from OPERATIONAL,
     * either reset): the profile's reaction; true when it is a fault whose EMCY the NMT
     * service sends after the transition */
    bool     (*nmt_leave)(void *ctx, hd_co_t *co);
    /* NMT reset node: the application restarts */
    void     (*restart)(void *ctx, hd_co_t *co);
    /* a profile fault is active (the communication error bit stays set while it is) */
    bool     (*faulted)(void *ctx, const hd_co_t *co);
} hd_co_profile_if_t;

typedef struct {
    void *ctx;
    /* required */
    bool     (*send)(void *ctx, const hd_can_frame_t *f);
    /* PARAM entries (drive parameters); param_set returns 0 or an abort code */
    int32_t  (*param_get)(void *ctx, uint16_t id);
    uint32_t (*param_set)(void *ctx, uint16_t id, int32_t raw);
    /* DOMAIN entries; every function returns 0 or an abort code.
     * write_end(complete = true) commits (checks the table CRC, swaps it in);
     * complete = false discards (abort, time-out): the old data stays. */
    uint32_t (*domain_size)(void *ctx, uint16_t dom, uint32_t *size);
    uint32_t (*domain_read)(void *ctx, uint16_t dom, uint32_t off, uint8_t *buf, uint32_t len);
    uint32_t (*domain_write_begin)(void *ctx, uint16_t dom, uint32_t size_or_0);
    uint32_t (*domain_write)(void *ctx, uint16_t dom, uint32_t off, const uint8_t *buf, uint32_t len);
    uint32_t (*domain_write_end)(void *ctx, uint16_t dom, uint32_t total, bool complete);
    /* SPECIAL manufacturer entries (capture control/state) */
    uint32_t (*special_read)(void *ctx, uint16_t index, uint8_t sub, int64_t *v);
    uint32_t (*special_write)(void *ctx, uint16_t index, uint8_t sub, int64_t v);
    /* 0x1010 / 0x1011 */
    uint32_t (*store)(void *ctx);
    uint32_t (*restore)(void *ctx);
    /* NMT reset node (application reset); the stack then resets communication */
    void     (*reset_node)(void *ctx);
    /* SYNC received (counter or 0) */
    void     (*on_sync)(void *ctx, uint8_t counter);
    /* 402 drive */
    uint32_t (*drive_enable)(void *ctx, int8_t mode, bool on);  /* 0 ok, else refused */
    void     (*drive_setpoint)(void *ctx, const hd_co_setpoint_t *sp);
    void     (*drive_actual)(void *ctx, hd_co_actual_t *a);
    void     (*drive_fault_reset)(void *ctx);
    /* stack-detected fault (host heartbeat lost, bus-off) with 0x6007 = 1: the app's fault reaction */
    void     (*drive_comm_fault)(void *ctx, uint16_t emcy_code);
    /* optional: CAN controller state (hal.h hd_hal_can_status), polled every tick;
     * NULL = always error active */
    void     (*can_status)(void *ctx, hd_hal_can_status_t *st);
    /* optional: start the controller's bus-off recovery (hal.h hd_hal_can_recover) */
    void     (*can_recover)(void *ctx);
    /* optional: the objects a master may reach (a device profile narrower than the table,
     * e.g. the virtual drive's generic CiA 402 profile).  Asked before every SDO access
     * (upload, download, block) and every PDO mapping entry written; non-zero = the abort
     * code (the object is absent for the master: 0x06020000, a mapping 0x06040041).
     * NULL = every object of the table.  Local accesses (hd_co_get/set_i64) are not asked. */
    uint32_t (*object_filter)(void *ctx, uint16_t index, uint8_t sub);
    /* optional: the device profile on top (CiA 402: hd_co402_use); NULL = CiA 301 only */
    const hd_co_profile_if_t *profile;
    void *profile_ctx;
} hd_co_app_if_t;

typedef struct {
    uint8_t  valid;
    uint8_t  type;
    uint8_t  nmap;
    uint8_t  len;                          /* bytes */
    uint16_t cob;
    uint16_t ent[HD_CO_N_MAP];             /* entry numbers in the table */
    uint8_t  esize[HD_CO_N_MAP];           /* bytes per mapped entry */
    /* TPDO */
    uint8_t  sync_cnt;
    uint8_t  cos_armed;                    /* a change was seen (type 0) */
    uint8_t  cos_len;
    uint8_t  cos_prev[8];
    uint64_t next_event_us;
    uint64_t inhibit_until_us;
    uint32_t stream_cnt;
    /* RPDO */
    uint8_t  rx_pending;
    uint8_t  rx_data[8];
} hd_co_pdo_rt_t;

typedef struct {
    uint8_t  state;          /* SDO server state (hd_co_sdo.c) */
    uint8_t  toggle;
    uint8_t  crc_on;
    uint8_t  blksize;
    uint8_t  seq;            /* block: last accepted (download) / last sent (upload) */
    uint8_t  pend_len;       /* block download: bytes held back (last segment) */
    uint8_t  last_seen;      /* block download: segment with c bit accepted */
    uint8_t  pad;
    uint16_t ent;            /* table entry of the transfer */
    uint16_t crc;
    uint32_t size;           /* indicated size (0 = not indicated) */
    uint32_t off;            /* bytes transferred so far (upload: acked base in block mode) */
    uint64_t deadline_us;
    uint8_t  pend[7];
    uint8_t  buf[HD_CO_SDO_BUF];
} hd_co_sdo_t;

typedef struct {
    uint32_t rx_frames, rx_ignored, tx_frames, tx_dropped;
    uint32_t sdo_aborts_sent, emcy_sent, pdo_len_errors;
    uint32_t can_passive, can_bus_off, can_recovered;   /* controller state changes seen */
} hd_co_stats_t;

struct hd_co_s {
    const hd_co_entry_t *table;
    uint32_t count;
    hd_co_od_data_t od;
    hd_co_app_if_t app;
    uint8_t  node_id;
    uint8_t  nmt;
    uint8_t  sync_counter;
    uint8_t  hbc_active, hbc_lost;
    uint8_t  n_err;
    uint8_t  emcy_pending;
    uint8_t  can_state;       /* HD_HAL_CAN_* as last polled */
    uint64_t can_recover_us;  /* bus-off: when the (next) recovery request is due */
    uint64_t now_us;
    uint64_t hb_next_us;
    uint64_t hbc_last_us;
    uint64_t emcy_inhibit_until_us;
    uint8_t  emcy_pending_data[8];
    uint32_t err_hist[HD_CO_ERR_HIST];
    uint32_t last_abort;      /* last SDO abort code sent (diagnostics) */
    uint32_t sdo_timeout_ms;
    hd_co_sdo_t sdo;
    hd_co_pdo_rt_t tpdo[HD_CO_N_PDO];
    hd_co_pdo_rt_t rpdo[HD_CO_N_PDO];
    hd_co_actual_t act;       /* the app's actual values (a profile fills them every tick) */
    hd_co_stats_t stats;
    /* the stored objects' saved image (hd_co_store_*, HD_CO_STORE_MAX words): NMT
     * resets go back to it */
    uint32_t stored[HD_CO_STORE_MAX];
    uint8_t  stored_ok;
    /* the entry and abort code that made the last hd_co_store_apply refuse an image (0: none) */
    uint16_t store_refused_index;
    uint8_t  store_refused_sub;
    uint32_t store_refused_abort;
};

/*
 * Stored objects: every VAR entry flagged HD_CO_F_STORE (communication and CiA 402
 * settings; the drive parameters have their own store) as one image of 32-bit words:
 * word 0 the layout (CRC-32 of index, sub, type and flags of those entries, so an image
 * of another object dictionary is refused), then one word per entry in table order (a
 * COB-ID that is its default base + node id is kept node-relative).  The app adapter
 * saves it with 0x1010 and hands it back at boot (hd_app_co.c); the NMT resets return
 * to it (CiA 301: reset communication / application load the stored values).
 */
/** Words of the image (1 + stored entries). */
uint32_t hd_co_store_words(const hd_co_t *co);
/** The layout word (image word 0). */
uint32_t hd_co_store_layout(const hd_co_t *co);
/** Image word w of the live values. */
uint32_t hd_co_store_word(const hd_co_t *co, uint32_t w);
/** Apply an image to the entries with index in [lo, hi].  Layout, length and every
 *  value's limits are checked first: -1 and nothing changes.  Then each value goes
 *  through the SDO download checks (access, object rules such as PDO mapping and COB-ID
 *  rules) in the CiA 301 order (PDOs disabled, mapping counts 0, values, mapping counts,
 *  COB-IDs); the first refusal puts the stored entries in [lo, hi] back to their
 *  defaults and returns -2 (co->store_refused_* name the entry and the abort code).
 *  0: the whole image is in force. */
int32_t hd_co_store_apply(hd_co_t *co, const uint32_t *img, uint32_t words, uint16_t lo, uint16_t hi);
/** Keep the live values as the stored image (after a successful save). */
void hd_co_store_capture(hd_co_t *co);
/** The stored entries to their defaults, now (0x1011 restore). */
void hd_co_store_defaults(hd_co_t *co);

/** Set everything to defaults, enter PRE-OPERATIONAL, send the boot-up message. */
void hd_co_init(hd_co_t *co, uint8_t node_id, const hd_co_app_if_t *app);
/** One received frame. */
void hd_co_process(hd_co_t *co, const hd_can_frame_t *f);
/** Advance time by dt_us: timers, heartbeat, PDOs, SDO time-out, CiA 402. */
void hd_co_tick(hd_co_t *co, uint32_t dt_us);

/** The CAN controller's state (HD_HAL_CAN_*), polled by hd_co_tick through app.can_status
 *  or given by the port.  Entering error passive: EMCY 0x8120.  Entering bus-off: nothing
 *  is sent until the controller is back; the communication-error reactions run at once
 *  (0x1029:1 NMT, 0x6007 drive), 0x8140 goes into 0x1003 and the error register, and the
 *  recovery is requested every HD_CO_BUSOFF_RESTART_MS.  Back on the bus: EMCY 0x8140
 *  (error passive again: also 0x8120); back to error active with no other communication
 *  error and no 402 fault: the communication bit is cleared (EMCY 0x0000 if none is left). */
void hd_co_can_state(hd_co_t *co, uint8_t state);

/** Raise an error: error register bits, 0x1003 history, EMCY frame. */
void hd_co_emcy(hd_co_t *co, uint16_t code, uint8_t reg_bits, const uint8_t mfr[5]);
/** Clear error register bits; when none is left an EMCY 0x0000 (error reset) goes out. */
void hd_co_emcy_clear(hd_co_t *co, uint8_t reg_bits);

/** CiA 301 COB-ID rules (docs/can.md, COB-IDs): may v be the COB-ID of index:sub (SYNC 0x1005:0,
 *  EMCY 0x1014:0, RPDO 0x1400+i:1, TPDO 0x1800+i:1) on this node?  11-bit identifiers only
 *  (bit 29 and the other reserved bits clear); bit 31 (EMCY, PDO) marks the object invalid and
 *  is always allowed; a valid identifier is none of the CiA 301 restricted CAN-IDs and none
 *  of the identifiers the node's other COB-ID objects use now (SYNC, a valid EMCY, every valid
 *  RPDO/TPDO; the object itself excluded).  false for any other object.  The SDO write
 *  refuses a value it rejects with 0x06090030; a stored image checked after it is put in
 *  force calls it for each of those objects (hd_co_cobids_ok). */
bool hd_co_cobid_allowed(const hd_co_t *co, uint16_t index, uint8_t sub, uint32_t v);
/** Every COB-ID object in force passes hd_co_cobid_allowed. */
bool hd_co_cobids_ok(const hd_co_t *co);
/** Abort the running SDO transfer (if any) with code: the client gets the abort, a domain
 *  download is discarded (domain_write_end complete = false: the old data stays). */
void hd_co_sdo_abort(hd_co_t *co, uint32_t code);

/** Entry number of (index, sub) or -1. */
int32_t hd_co_find(const hd_co_t *co, uint16_t index, uint8_t sub);
/** Read one non-domain entry into buf (little endian); returns 0 or an abort code. */
uint32_t hd_co_read(hd_co_t *co, uint32_t ent, uint8_t *buf, uint32_t cap, uint32_t *len);
/** Write one non-domain entry (checks type length, range, object rules, not access). */
uint32_t hd_co_write(hd_co_t *co, uint32_t ent, const uint8_t *buf, uint32_t len);
/** Local read/write by index (for the app and tests). */
uint32_t hd_co_get_i64(hd_co_t *co, uint16_t index, uint8_t sub, int64_t *v);
uint32_t hd_co_set_i64(hd_co_t *co, uint16_t index, uint8_t sub, int64_t v);

/** CRC-16/XMODEM (SDO block transfer): poly 0x1021, init as given (0). */
uint16_t hd_co_crc16(uint16_t crc, const uint8_t *p, uint32_t len);

#endif /* HD_CO_H */
