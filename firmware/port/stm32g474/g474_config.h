/*
 * g474_config.h - board and motor constants of the STM32G474 drive image
 * (docs/stm32g474.md has the wiring).  Everything integer.
 */
#ifndef HD_G474_CONFIG_H
#define HD_G474_CONFIG_H

/* Clocks: HSE crystal 8 or 24 MHz -> PLL -> SYSCLK 170 MHz (range 1 boost). */
#ifndef HD_G474_HSE_HZ
#define HD_G474_HSE_HZ      24000000u
#endif
#define HD_G474_SYSCLK_HZ   170000000u
#define HD_G474_PCLK1_HZ    170000000u     /* FDCAN kernel clock (FDCANSEL = PCLK1) */
#define HD_G474_CAN_BITRATE 1000000u

/* PWM: TIM1 center-aligned, 20 kHz, ARR = 170 MHz / (2 * 20 kHz). */
#define HD_G474_PWM_HZ      20000u
#define HD_G474_PWM_ARR     (HD_G474_SYSCLK_HZ / (2u * HD_G474_PWM_HZ))   /* 4250 */
#define HD_G474_FOC_PER_CTRL (HD_G474_PWM_HZ / 10000u)                   /* 2 FOC steps per 100 us */
#define HD_G474_DEADTIME_DTG 85u            /* 85 x 5.88 ns = 500 ns */

/* Current sensing: 12-bit ADC, +-25 A full scale (shunt amplifier biased at mid-scale). */
#define HD_G474_I_GAIN_Q30  13107200        /* 50 A / 4096 LSB in Q30 */
#define HD_G474_I_CAL_N     256u            /* offset calibration samples (power stage off) */
/* DC link: divider to 66 V full scale: Q15.16 V per LSB = 66 * 65536 / 4096. */
#define HD_G474_VBUS_Q16_PER_LSB 1056

/* Motor (frameless PMSM, Kt ~ 0.1 N m/A): 8 pole pairs, R = 0.3 Ohm, L = 0.3 mH. */
#define HD_G474_POLE_PAIRS  8u
#define HD_G474_R_MOHM      300
#define HD_G474_L_NH        300000
#define HD_G474_FOC_FC_HZ   900             /* -> ~2 kHz closed-loop bandwidth (test_foc.c) */
#define HD_G474_ELEC_OFFSET 0u              /* encoder-to-rotor-flux angle, from commissioning */
#define HD_G474_GEAR_N      100u

/* Encoders */
#define HD_G474_MOTOR_ENC_BITS 17u          /* 32768 lines x 4 on TIM3 (16-bit counter) */
#define HD_G474_MOTOR_ENC_MAX_STEP 2500u    /* counts per 50 us FOC period (8000 rpm + margin) */
#define HD_G474_SSI_BYTES   6u              /* 48 clocks per output-encoder read */

/* NVM: the last 48 KiB of the 512 KiB flash (bank 2 pages 104..127, dual-bank
 * mode, 2 KiB pages), exposed to hal.h as a 22 KiB virtual region of 1 KiB pages:
 * the parameter store's two slots (1 KiB each: up to 249 parameters; 155 today),
 * the Preisach table store's two (9 KiB each: a 64-level table) and the stored
 * CANopen objects' two (1 KiB each).  hd_vnvm needs one physical page per virtual
 * page plus a free one (24 >= 22 + 1; the spare spreads the wear).  No RAM image: hd_vnvm streams records
 * (hd_flashstore.h). */
#define HD_G474_NVM_ADDR    0x08074000u
#define HD_G474_NVM_PAGES   24u
#define HD_G474_NVM_PAGE    2048u
#define HD_G474_NVM_BANK2_FIRST_PAGE 104u
#define HD_G474_VNVM_SIZE   22528u
#define HD_G474_VNVM_PAGE   1024u

/* CAN software queues (frames, powers of two) */
#define HD_G474_CAN_RXQ     16u
#define HD_G474_CAN_TXQ     16u

/* CANopen node id (1..127): -DHD_G474_NODE_ID=n */
#ifndef HD_G474_NODE_ID
#define HD_G474_NODE_ID     1u
#endif

#endif
