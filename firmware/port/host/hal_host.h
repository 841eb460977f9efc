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
 *   4. hd_host_port_end_period(p)         tick++ and per-period contract checks
 *
 * CAN: two rings of HD_HOST_CAN_RING frames.  A transport (socketcand server,
 * SocketCAN, a Python test) pushes received frames with hd_host_can_push_rx()
 * and drains what the drive sent with hd_host_can_pop_tx().  Frames pushed
 * into a full RX ring are dropped and counted (like a CAN controller overrun).
 *
 * NVM: HD_HOST_NVM_SIZE bytes in memory with flash semantics (erased = 0xFF,
 * program only erased 8-byte words, erase whole pages).  Optionally backed by
 * a file: loaded at attach, written back (temp file + rename) after every
 * successful write or erase.
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
#define HD_HOST_NVM_SIZE      16384u  /* bytes: 8 pages of 2 KiB (STM32G4 page) */
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

typedef struct {
    uint32_t tick;                  /* periods since power-up */
    hd_hal_sensors_t sensors;       /* latched for the current period */
    hd_hal_command_t command;       /* last command written by the app */
    uint32_t reads, writes;         /* calls in the current period */
    uint32_t violations;            /* HD_HOST_VIOL_* bits seen so far */
    hd_host_can_ring_t can_rx;      /* bus -> drive */
    hd_host_can_ring_t can_tx;      /* drive -> bus */
    uint8_t  nvm[HD_HOST_NVM_SIZE];
    char     nvm_path[HD_HOST_PATH_MAX];  /* "" = memory only */
    int32_t  nvm_file_error;        /* last file write-back error (0 = none) */
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

/* CAN for transports (act on the bound port).  push_rx: false if the ring is
 * full or nothing is bound; pop_tx: false if nothing is waiting. */
bool hd_host_can_push_rx(const hd_can_frame_t *f);
bool hd_host_can_pop_tx(hd_can_frame_t *f);

/* Ring helpers on an explicit port (used by the two above and by tests). */
bool hd_host_ring_push(hd_host_can_ring_t *r, const hd_can_frame_t *f);
bool hd_host_ring_pop(hd_host_can_ring_t *r, hd_can_frame_t *f);

#endif /* HD_HAL_HOST_H */
