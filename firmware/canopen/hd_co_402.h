/*
 * hd_co_402.h - the CiA 402 drive profile (hd_co_402.c) on top of the CiA 301 device
 * (hd_co.h): its states and modes of operation, and how the app plugs it in.
 *
 * Use:
 *   hd_co402_t p402;                      the profile's state (the caller's, no globals)
 *   hd_co402_use(&p402, &app_if);         before hd_co_init(&co, node_id, &app_if)
 *   hd_co402_state(&p402)                 HD_CO402_* (also in the statusword 0x6041)
 * The app's side of the profile is in hd_co_app_if_t (drive_enable, drive_setpoint,
 * drive_actual, drive_fault_reset, drive_comm_fault).
 */
#ifndef HD_CO_402_H
#define HD_CO_402_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_co.h"

/* States of the drive's state machine. */
#define HD_CO402_NOT_READY      0u
#define HD_CO402_SO_DISABLED    1u
#define HD_CO402_READY          2u
#define HD_CO402_SWITCHED_ON    3u
#define HD_CO402_OP_ENABLED     4u
#define HD_CO402_QUICK_STOP     5u
#define HD_CO402_FAULT_REACTION 6u
#define HD_CO402_FAULT          7u

/* Modes of operation (0x6060 / 0x6061). */
#define HD_CO402_MODE_NONE  0
#define HD_CO402_MODE_PP    1
#define HD_CO402_MODE_CSP   8
#define HD_CO402_MODE_CSV   9
#define HD_CO402_MODE_CST   10
#define HD_CO402_MODE_STAB  (-1)   /* manufacturer-specific: inertial stabilisation (app mode STAB) */

/** The profile's state.  Its fields belong to hd_co_402.c; read the state with
 *  hd_co402_state. */
typedef struct {
    uint8_t  state;          /* HD_CO402_* */
    uint8_t  comm_fault;     /* latched stack-side fault */
    uint8_t  fault_pending_reset;
    uint16_t cw_prev;        /* last controlword written (edges of bits 4 and 7) */
    uint8_t  sp_pending;     /* a new-set-point edge written in OPERATION ENABLED, not yet handed
                              * to the app (latched at the write: several controlword writes
                              * can arrive within one control period) */
    uint16_t fault_code;     /* EMCY code of the active fault */
    uint32_t standstill_ticks;
    /* windows of 0x6065/0x6066 and 0x6067/0x6068: since when (hd_co_t.now_us) the
     * following error has been outside / inside, 0 = not */
    uint64_t fe_out_since_us;
    uint64_t win_in_since_us;
    uint8_t  fe_out;            /* the error is outside 0x6065 (since fe_out_since_us) */
    uint8_t  win_in;            /* the error is inside 0x6067 at rest (since win_in_since_us) */
    uint8_t  following_error;   /* statusword bit 13 (PP, CSP) */
    uint8_t  target_reached;    /* statusword bit 10 */
} hd_co402_t;

/** Plug the profile into the device: app->profile / profile_ctx point to it and p. */
void hd_co402_use(hd_co402_t *p, hd_co_app_if_t *app);
/** The state machine's state (HD_CO402_*). */
uint8_t hd_co402_state(const hd_co402_t *p);

#endif /* HD_CO_402_H */
