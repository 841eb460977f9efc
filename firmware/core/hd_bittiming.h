/*
 * hd_bittiming.h - classic CAN bit timing from a controller kernel clock.
 *
 * A bit is 1 + tseg1 + tseg2 time quanta (tq = prescaler / f_clk), sampled
 * after 1 + tseg1 tq.  hd_bittiming_calc() searches every prescaler in the
 * controller's range for an EXACT division (f_clk = bitrate * prescaler *
 * n_tq, no bit-rate error), places the sample point as close as possible to
 * the target without leaving [sp_min, sp_max], and breaks ties with the
 * largest number of time quanta (finest phase resolution, largest SJW).
 * SJW = min(tseg2, sjw_max).  Sample points are given in per mille (875 =
 * 87.5 %, the CiA 301 recommendation up to 800 kbit/s; 80 - 87.5 % is fine
 * at 1 Mbit/s).
 *
 * Limits of the STM32G4 FDCAN nominal bit timing (NBTP, values as counts,
 * not "minus one"): prescaler 1..512, tseg1 1..256, tseg2 1..128 (but at
 * least 2 for a real controller), sjw 1..128; a bit has 8..385 tq here (CAN
 * needs >= 8 tq for a sensible sample point).
 */
#ifndef HD_BITTIMING_H
#define HD_BITTIMING_H

#include <stdint.h>

typedef struct {
    uint32_t brp_max;     /* largest prescaler */
    uint32_t tseg1_max;   /* largest tseg1 (prop + phase1), tq */
    uint32_t tseg2_max;   /* largest tseg2 (phase2), tq */
    uint32_t sjw_max;     /* largest SJW, tq */
    uint32_t tq_min;      /* fewest tq per bit accepted */
} hd_bt_limits_t;

typedef struct {
    uint32_t brp;         /* prescaler (count) */
    uint32_t tseg1;       /* tq */
    uint32_t tseg2;       /* tq */
    uint32_t sjw;         /* tq */
    uint32_t n_tq;        /* 1 + tseg1 + tseg2 */
    uint32_t sp_permille; /* sample point, per mille, rounded */
} hd_bt_t;

/** The FDCAN nominal limits of the STM32G4 (RM0440, FDCAN_NBTP). */
extern const hd_bt_limits_t hd_bt_fdcan_nominal;

/** Compute a bit timing: 0 ok, -1 impossible (no exact division with >= tq_min
 *  tq and the sample point inside [sp_min, sp_max] per mille, or bad arguments). */
int32_t hd_bittiming_calc(uint32_t f_clk_hz, uint32_t bitrate, uint32_t sp_target,
                          uint32_t sp_min, uint32_t sp_max, const hd_bt_limits_t *lim, hd_bt_t *out);

/** Check a timing against a clock and bitrate: 0 if it gives exactly the bitrate,
 *  fits the limits and its sample point lies in [sp_min, sp_max]; else -1. */
int32_t hd_bittiming_check(const hd_bt_t *t, uint32_t f_clk_hz, uint32_t bitrate,
                           uint32_t sp_min, uint32_t sp_max, const hd_bt_limits_t *lim);

/** FDCAN_NBTP register image: NSJW-1 [31:25], NBRP-1 [24:16], NTSEG1-1 [15:8], NTSEG2-1 [6:0]. */
uint32_t hd_bittiming_fdcan_nbtp(const hd_bt_t *t);

#endif
