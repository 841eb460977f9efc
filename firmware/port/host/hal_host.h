/*
 * hal_host.h - hal.h on a PC: the port the simulator harness (sim/harness)
 * and the virtual drive use.
 *
 * The port state lives in one hd_host_port_t owned by the caller (the
 * simulation context).  hd_host_port_bind() makes it the target of the
 * hd_hal_* calls of the application; this pointer is the only static state
 * and it exists only in this PC-side port, never in firmware/core.
 *
 * Per control period the harness:
 *   1. hd_host_port_latch(p, &sensors)    sensors sampled at the period start
 *   2. hd_app_step(...)                   app reads sensors, writes command
 *   3. hd_host_port_command(p)            the command to apply to the plant
 *   4. hd_host_port_end_period(p)         tick++, per-period contract checks, CAN
 *                                         bus-off recovery time
 *
 * CAN: two rings of HD_HOST_CAN_RING frames.  A transport (socketcand server,
 * SocketCAN, a Python test) pushes received frames with hd_host_can_push_rx()
 * and drains what the drive sent with hd_host_can_pop_tx().  Frames pushed
 * into a full RX ring are dropped and counted (like a CAN controller overrun).
 *
 * NVM: HD_HOST_NVM_SIZE bytes in memory with flash semantics (erased = 0xFF,
 * program only erased 8-byte words, erase whole pages).  Optionally backed by
 * a file: loaded at attach, written back (temp file + rename) after every
 * successful write or erase.  Page erases are counted per page (flash wear, CANopen
 * 0x5102); with a file the counts persist in PATH.wear (one decimal count per page
 * and line, written like the image), so they survive a restart of the drive.
 *
 * Integer-only like the rest of firmware/ (unit conversion to SI is done on
 * the sim side).
 */
#ifndef HD_HAL_HOST_H
#define HD_HAL_HOST_H

#include <stdint.h>
#include <stdbool.h>
#include "hal.h"

#define HD_HOST_CAN_RING      256u    /* frames per ring (power of two) */
#define HD_HOST_NVM_SIZE      32768u  /* bytes: 16 pages of 2 KiB (STM32G4 page): parameter
                                        * store 2 x 2 KiB, table store 2 x 10 KiB, stored
                                        * CANopen objects 2 x 2 KiB, spare */
#define HD_HOST_NVM_PAGE      2048u
#define HD_HOST_PATH_MAX      1024u

/* Contract violations seen by the port (bits of hd_host_port_t.violations). */
#define HD_HOST_VIOL_NO_READ      ((uint32_t)1u << 0)  /* a period without read_sensors */
#define HD_HOST_VIOL_MULTI_READ   ((uint32_t)1u << 1)  /* read_sensors twice in one period */
#define HD_HOST_VIOL_NO_WRITE     ((uint32_t)1u << 2)  /* a period without write_command */
#define HD_HOST_VIOL_MULTI_WRITE  ((uint32_t)1u << 3)  /* write_command twice */
#define HD_HOST_VIOL_ORDER        ((uint32_t)1u << 4)  /* write before read */

typedef struct {
    hd_can_frame_t f[HD_HOST_CAN_RING];
    uint32_t head;      /* next to pop */
    uint32_t count;     /* frames held */
    uint32_t dropped;   /* frames refused because the ring was full */
} hd_host_can_ring_t;

/* CAN controller fault confinement (ISO 11898-1), what hd_hal_can_status() reports:
 * a transmit error adds 8 to TEC, a receive error 1 to REC, every frame sent or
 * received without error takes 1 off (REC above 127 goes back to 127).  TEC or REC
 * > 127: error passive; TEC > 255: bus-off (nothing sent or received).  Recovery:
 * hd_hal_can_recover() starts the wait for 128 x 11 recessive bits at `bitrate`
 * (1 Mbit/s if 0), counted in whole periods at the end of each period; then error
 * active with TEC = REC = 0.  The transport calls hd_host_can_tx_done / _rx_done
 * per frame and the injection helpers below (virtual drive fault tests). */
typedef struct {
    uint16_t tec, rec;              /* error counters (tec 256 = bus-off) */
    uint8_t  state;                 /* HD_HAL_CAN_* */
    uint8_t  recovering;            /* 1: recovery requested, waiting */
    uint16_t pad;
    uint32_t recover_left;          /* periods of the recovery sequence still to wait */
    uint32_t bitrate;               /* bit/s for the recovery time (0 = 1 Mbit/s) */
    uint32_t bus_off_count, recoveries;
} hd_host_can_ctrl_t;

typedef struct {
    uint32_t tick;                  /* periods since power-up */
    hd_hal_sensors_t sensors;       /* latched for the current period */
    hd_hal_command_t command;       /* last command written by the app */
    uint32_t reads, writes;         /* calls in the current period */
    uint32_t violations;            /* HD_HOST_VIOL_* bits seen so far */
    hd_host_can_ring_t can_rx;      /* bus -> drive */
    hd_host_can_ring_t can_tx;      /* drive -> bus */
    hd_host_can_ctrl_t can_ctrl;    /* controller error state */
    uint8_t  nvm[HD_HOST_NVM_SIZE];
    char     nvm_path[HD_HOST_PATH_MAX];  /* "" = memory only */
    int32_t  nvm_file_error;        /* last file write-back error (0 = none) */
    uint32_t nvm_erases[HD_HOST_NVM_SIZE / HD_HOST_NVM_PAGE];  /* erases of each page */
} hd_host_port_t;

/* Reset: tick 0, zero sensors (all invalid), command off, empty rings,
 * NVM erased (0xFF), no backing file. */
void hd_host_port_init(hd_host_port_t *p);

/* Route the hd_hal_* calls to p (NULL unbinds; calls then act on nothing and
 * return errors / empty values). */
void hd_host_port_bind(hd_host_port_t *p);
hd_host_port_t *hd_host_port_bound(void);

/* Harness side of one period. */
void hd_host_port_latch(hd_host_port_t *p, const hd_hal_sensors_t *s);
const hd_hal_command_t *hd_host_port_command(const hd_host_port_t *p);
void hd_host_port_end_period(hd_host_port_t *p);

/* Back the NVM with a file: read it if it exists (must be exactly
 * HD_HOST_NVM_SIZE bytes), else start erased.  0 ok, -1 bad path/size, -2 read error. */
int32_t hd_host_nvm_attach_file(hd_host_port_t *p, const char *path);

/* Flash wear: page erases in all and of the most erased page. */
void hd_host_nvm_wear(const hd_host_port_t *p, uint32_t *total, uint32_t *max_page);

/* CAN for transports (act on the bound port).  push_rx: false if the ring is
 * full or nothing is bound; pop_tx: false if nothing is waiting. */
bool hd_host_can_push_rx(const hd_can_frame_t *f);
bool hd_host_can_pop_tx(hd_can_frame_t *f);

/* CAN controller model (see hd_host_can_ctrl_t).  errors: tx_errors transmit and
 * rx_errors receive errors (an error burst); bus_off: TEC to 256 at once.
 * tx_done / rx_done: one frame sent / received without error; false (and no
 * change) while bus-off, when the frame cannot be sent or received. */
void hd_host_can_errors(hd_host_port_t *p, uint32_t tx_errors, uint32_t rx_errors);
void hd_host_can_bus_off(hd_host_port_t *p);
bool hd_host_can_tx_done(hd_host_port_t *p);
bool hd_host_can_rx_done(hd_host_port_t *p);

/* Ring helpers on an explicit port (used by the two above and by tests). */
bool hd_host_ring_push(hd_host_can_ring_t *r, const hd_can_frame_t *f);
bool hd_host_ring_pop(hd_host_can_ring_t *r, hd_can_frame_t *f);

#endif /* HD_HAL_HOST_H */
