/*
 * hal.h - the only door between the drive application and hardware.
 *
 * Contract
 * --------
 * Plain C prototypes `hd_hal_*`, implemented once per port:
 *   firmware/port/stm32g474/  the real drive (timers, ADC, encoders, FDCAN, flash)
 *   firmware/port/host/       the simulator harness (plant in lock-step, NVM in a file)
 *   tests/golden/             a stub for the golden-vector / instruction-count image
 * Nothing in firmware/core includes this file; firmware/app and firmware/canopen do.
 *
 * Timing.  The port calls hd_app_step() once per control period (100 us,
 * HD_LOOP_HZ in hd_units.h).  Inside one step the application calls, in order:
 *   1. hd_hal_read_sensors()   exactly once, first: the sample latched by the port
 *                              at the START of this period (same instant for all
 *                              channels);
 *   2. hd_hal_write_command()  exactly once: the command applied by the port for
 *                              the rest of the period (zero-order hold);
 *   3. CAN and NVM calls       any number, never blocking the loop for long
 *                              (NVM erase/write are only issued from the
 *                              parameter-save command, with the power stage off).
 * hd_hal_tick() counts periods since power-up (wraps after 4.97 days, meant).
 *
 * Sensors are delivered RAW; the application owns every conversion:
 *   - motor encoder: single-turn count in [0, 2^bits), bits from the parameter
 *     table (17 on the reference axis); the app unwraps it to multi-turn.
 *   - output encoder: absolute single-turn count in [0, 2^24) (bits from the
 *     parameter table, 24 on the reference axis); the app unwraps it too.
 *   - measured motor current: Q15.16 A (q-axis, torque-producing).
 *   - payload rate gyro: output-velocity format (2^-32 turn/s), inertial rate.
 *   - validity flags HD_HAL_VALID_*: a channel whose flag is clear holds
 *     garbage and must not be used (the app faults if it needs it).
 *
 * Command out: the motor torque the current loop must produce, Q15.16 N.m at
 * the MOTOR shaft, and the same command as a q-axis current (Q15.16 A,
 * = torque / Kt with Kt from the parameter table), so that a port with a real
 * current loop uses `current` and a plant model may use either.  `enable` = 0
 * means power stage off (both values are then 0).
 *
 * CAN: classic CAN frames (no FD).  send() queues one frame and returns false
 * if the TX queue is full (the frame is dropped, the caller may retry).
 * recv() pops one frame and returns false if none is waiting.
 * can_status() reports the controller's fault-confinement state (ISO 11898-1)
 * as the STM32 FDCAN gives it (FDCAN_PSR BO/EP/EW, FDCAN_ECR TEC/REC): error
 * active (both counters <= 127), error passive (TEC or REC > 127: the node
 * still sends, with passive error flags), bus-off (TEC > 255: the controller
 * has left the bus, nothing is sent or received).  A controller leaves bus-off
 * only after can_recover() and 128 occurrences of 11 recessive bits on the
 * bus (FDCAN: clearing CCCR.INIT); it is then error active with TEC = REC = 0.
 *
 * NVM: a byte-addressed region of hd_hal_nvm_size() bytes reserved for the
 * parameter store, erased in pages of hd_hal_nvm_page_size() bytes (erased
 * bytes read 0xFF).  Writes go to erased memory only, at offsets and lengths
 * that are multiples of 8 (STM32G4 flash programs 64-bit words).  All three
 * return 0 on success and a negative value on error (bad range, hardware).
 * A write interrupted by power loss may leave that region in any state: the
 * parameter store (firmware/app/hd_param_store.c) makes saving atomic on top.
 */
#ifndef HD_HAL_H
#define HD_HAL_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"

/* ---- sensors ----------------------------------------------------------- */

#define HD_HAL_VALID_MOTOR_ENC   ((uint32_t)1u << 0)
#define HD_HAL_VALID_OUTPUT_ENC  ((uint32_t)1u << 1)
#define HD_HAL_VALID_CURRENT     ((uint32_t)1u << 2)
#define HD_HAL_VALID_GYRO        ((uint32_t)1u << 3)
#define HD_HAL_VALID_ALL         ((uint32_t)0xFu)

typedef struct {
    uint32_t     motor_enc_raw;   /* single-turn count, [0, 2^motor_enc_bits) */
    uint32_t     output_enc_raw;  /* absolute single-turn count, [0, 2^output_enc_bits) */
    hd_current_t current;         /* measured q-axis current, Q15.16 A */
    hd_vel_out_t gyro_rate;       /* payload inertial rate, 2^-32 turn/s */
    uint32_t     valid;           /* HD_HAL_VALID_* bits */
} hd_hal_sensors_t;

/* ---- command ------------------------------------------------------------ */

typedef struct {
    hd_torque_t  torque;   /* motor-shaft torque command, Q15.16 N.m */
    hd_current_t current;  /* the same as q-axis current, Q15.16 A (torque / Kt) */
    uint32_t     enable;   /* 1 = power stage on, 0 = off (torque and current 0) */
} hd_hal_command_t;

/* ---- CAN -------------------------------------------------------------- */

typedef struct {
    uint32_t id;       /* 11-bit (ext = 0) or 29-bit (ext = 1) identifier */
    uint8_t  ext;      /* 1 = extended 29-bit identifier */
    uint8_t  rtr;      /* 1 = remote transmission request */
    uint8_t  dlc;      /* data length 0..8 */
    uint8_t  data[8];  /* payload; bytes >= dlc are don't-care */
} hd_can_frame_t;

#define HD_HAL_CAN_ERROR_ACTIVE   0u   /* TEC <= 127 and REC <= 127 */
#define HD_HAL_CAN_ERROR_PASSIVE  1u   /* TEC > 127 or REC > 127 */
#define HD_HAL_CAN_BUS_OFF        2u   /* TEC > 255: off the bus until recovered */

typedef struct {
    uint8_t  state;    /* HD_HAL_CAN_* */
    uint8_t  warning;  /* 1: a counter >= 96 (FDCAN_PSR.EW) */
    uint8_t  tec;      /* transmit error counter (saturated at 255) */
    uint8_t  rec;      /* receive error counter (127 + 1 when above 127: FDCAN_ECR.RP) */
} hd_hal_can_status_t;

/* ---- prototypes (one implementation per port) --------------------------- */

/** Control periods elapsed since power-up (wraps, meant). */
uint32_t hd_hal_tick(void);

/** The sensor sample latched at the start of the current period. */
void hd_hal_read_sensors(hd_hal_sensors_t *s);

/** Apply the command for the rest of the current period. */
void hd_hal_write_command(const hd_hal_command_t *c);

/** Queue one CAN frame; false if the TX queue is full. */
bool hd_hal_can_send(const hd_can_frame_t *f);
/** Pop one received CAN frame into *f; false if none is waiting. */
bool hd_hal_can_recv(hd_can_frame_t *f);
/** The CAN controller's error state and counters. */
void hd_hal_can_status(hd_hal_can_status_t *st);
/** Start the bus-off recovery sequence (no effect unless bus-off). */
void hd_hal_can_recover(void);

/** Size of the NVM region for the parameter store, bytes. */
uint32_t hd_hal_nvm_size(void);
/** Erase granularity, bytes (a power of two dividing hd_hal_nvm_size()). */
uint32_t hd_hal_nvm_page_size(void);
/** Copy len bytes at offset into buf. 0 = ok, < 0 = error. */
int32_t hd_hal_nvm_read(uint32_t offset, void *buf, uint32_t len);
/** Program len bytes from buf at offset (erased memory; offset, len multiples of 8). */
int32_t hd_hal_nvm_write(uint32_t offset, const void *buf, uint32_t len);
/** Erase len bytes at offset (whole pages: offset, len multiples of the page size). */
int32_t hd_hal_nvm_erase(uint32_t offset, uint32_t len);

#endif /* HD_HAL_H */
