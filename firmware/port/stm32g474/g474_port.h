/*
 * g474_port.h - internal interfaces of the STM32G474 port (startup, clock,
 * drivers, hal).  Not used outside firmware/port/stm32g474.
 */
#ifndef HD_G474_PORT_H
#define HD_G474_PORT_H

#include <stdint.h>
#include <stdbool.h>
#include "hal.h"

/* startup / clock */
void hd_g474_clock_init(void);
void hd_g474_delay_us(uint32_t us);
void hd_g474_pwm_kill(void);               /* outputs off at once (faults) */
uint32_t hd_g474_flash_ecc_take(void);      /* 1 if an ECC two-bit error hit since the last call */
int main(void);

/* drivers */
void hd_g474_gpio_init(void);
int32_t hd_g474_can_init(void);
bool hd_g474_can_tx_hw(const hd_can_frame_t *f);   /* into the TX FIFO; false if full */
bool hd_g474_can_rx_hw(hd_can_frame_t *f);         /* from RX FIFO 0; false if empty */
void hd_g474_pwm_init(void);
void hd_g474_pwm_set(const int32_t duty_q16[3]);
void hd_g474_pwm_enable(bool on);
void hd_g474_adc_init(void);
void hd_g474_enc_init(void);
uint32_t hd_g474_enc_raw(void);
void hd_g474_spi_init(void);
int32_t hd_g474_ssi_read(uint8_t *buf, uint32_t n);          /* polled (start-up only) */
void hd_g474_ssi_dma_init(void);
void hd_g474_ssi_dma_start(uint8_t *buf, uint32_t n);        /* buf in SRAM1/2, n <= 16 */
int32_t hd_g474_ssi_dma_finish(void);                         /* in the DMA ISR: 0 ok, -1 error */
void hd_g474_ssi_dma_abort(void);
void hd_g474_iwdg_init(void);
void hd_g474_iwdg_kick(void);
int32_t hd_g474_flash_read(uint32_t off, void *buf, uint32_t len);
int32_t hd_g474_flash_prog(uint32_t off, const void *buf, uint32_t len);
int32_t hd_g474_flash_erase_page(uint32_t page);
void hd_g474_nvic_enable(uint32_t irq, uint32_t prio);

/* interrupt handlers (vector table) */
void hd_g474_adc_irq(void);
void hd_g474_fdcan_irq(void);
void hd_g474_pendsv(void);
void hd_g474_ssi_dma_irq(void);

#endif
