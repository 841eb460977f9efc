/*
 * g474_drivers.c - peripheral drivers of the STM32G474 drive: GPIO pin
 * assignment, FDCAN1 (classic CAN 1 Mbit/s), TIM1 three-phase PWM with dead
 * time, ADC1/ADC2 dual injected current sampling, TIM3 quadrature encoder,
 * SPI1 for the output encoder, IWDG, flash programming.  Register-level,
 * polling with bounded waits; the hardware-independent logic (bit timing,
 * encoder unwrapping, SSI frame decoding, flash store) lives in firmware/core
 * and is host-tested.
 *
 * Pins (docs/stm32g474.md):
 *   PA8/PA9/PA10  TIM1_CH1/2/3  AF6  high-side gates     PB13/PB14 TIM1_CH1N/CH2N AF6,
 *                                                           PB15 TIM1_CH3N AF4  low-side gates
 *   PA11/PA12     FDCAN1_RX/TX  AF9
 *   PB4/PB5       TIM3_CH1/CH2  AF2  motor encoder A/B
 *   PA5/PA6       SPI1_SCK/MISO AF5  output encoder clock / data (RS-422 transceiver)
 *   PA0  ADC1_IN1 phase A current   PA1  ADC2_IN2 phase B current
 *   PA2  ADC1_IN3 DC-link voltage   PC0  ADC2_IN6 phase C current (check)
 */
#include <stdint.h>
#include <stdbool.h>
#include "g474_regs.h"
#include "g474_config.h"
#include "g474_port.h"
#include "hd_bittiming.h"
#include "hd_le32.h"

#define WAIT_LIMIT 1000000u

/* ---- GPIO ---------------------------------------------------------------------- */

static void pin_af(uint32_t port, uint32_t pin, uint32_t af)
{
    const uint32_t sh2 = 2u * pin;
    HD_REG(GPIO_MODER(port)) = (HD_REG(GPIO_MODER(port)) & ~(3u << sh2)) | (2u << sh2);
    HD_REG(GPIO_OSPEEDR(port)) |= (3u << sh2);
    if (pin < 8u) {
        HD_REG(GPIO_AFRL(port)) = (HD_REG(GPIO_AFRL(port)) & ~(0xFu << (4u * pin))) | (af << (4u * pin));
    } else {
        const uint32_t p = pin - 8u;
        HD_REG(GPIO_AFRH(port)) = (HD_REG(GPIO_AFRH(port)) & ~(0xFu << (4u * p))) | (af << (4u * p));
    }
}

static void pin_analog(uint32_t port, uint32_t pin)
{
    HD_REG(GPIO_MODER(port)) |= (3u << (2u * pin));
}

void hd_g474_gpio_init(void)
{
    HD_REG(RCC_AHB2ENR) |= 7u;                     /* GPIOA, B, C */
    (void)HD_REG(RCC_AHB2ENR);
    pin_af(GPIOA_BASE, 8u, 6u);
    pin_af(GPIOA_BASE, 9u, 6u);
    pin_af(GPIOA_BASE, 10u, 6u);
    pin_af(GPIOB_BASE, 13u, 6u);
    pin_af(GPIOB_BASE, 14u, 6u);
    pin_af(GPIOB_BASE, 15u, 4u);
    pin_af(GPIOA_BASE, 11u, 9u);
    pin_af(GPIOA_BASE, 12u, 9u);
    pin_af(GPIOB_BASE, 4u, 2u);
    pin_af(GPIOB_BASE, 5u, 2u);
    pin_af(GPIOA_BASE, 5u, 5u);
    pin_af(GPIOA_BASE, 6u, 5u);
    /* encoder and SSI data inputs: pull-ups (a broken wire reads idle high) */
    HD_REG(GPIO_PUPDR(GPIOB_BASE)) |= (1u << 8) | (1u << 10);
    HD_REG(GPIO_PUPDR(GPIOA_BASE)) |= (1u << 12);
    pin_analog(GPIOA_BASE, 0u);
    pin_analog(GPIOA_BASE, 1u);
    pin_analog(GPIOA_BASE, 2u);
    pin_analog(GPIOC_BASE, 0u);
}

void hd_g474_nvic_enable(uint32_t irq, uint32_t prio)
{
    volatile uint8_t *ipr = (volatile uint8_t *)(uintptr_t)(NVIC_IPR_BASE + irq);
    *ipr = (uint8_t)((prio & 0xFu) << 4);          /* 4 priority bits */
    HD_REG(NVIC_ISER(irq >> 5)) = 1u << (irq & 31u);
}

/* ---- FDCAN1: classic CAN, 1 Mbit/s --------------------------------------------- */

int32_t hd_g474_can_init(void)
{
    hd_bt_t bt;
    uint32_t n;
    /* bit timing from the kernel clock, checked before use */
    if (hd_bittiming_calc(HD_G474_PCLK1_HZ, HD_G474_CAN_BITRATE, 875u, 800u, 875u,
                          &hd_bt_fdcan_nominal, &bt) != 0 ||
        hd_bittiming_check(&bt, HD_G474_PCLK1_HZ, HD_G474_CAN_BITRATE, 800u, 875u, &hd_bt_fdcan_nominal) != 0) {
        return -1;
    }
    HD_REG(RCC_CCIPR) = (HD_REG(RCC_CCIPR) & ~(3u << 24)) | (2u << 24);    /* FDCANSEL = PCLK1 */
    HD_REG(RCC_APB1ENR1) |= (1u << 25);
    (void)HD_REG(RCC_APB1ENR1);
    HD_REG(FDCAN_CCCR) |= 1u;                                /* INIT */
    for (n = 0u; (HD_REG(FDCAN_CCCR) & 1u) == 0u; n++) {
        if (n > WAIT_LIMIT) {
            return -1;
        }
    }
    HD_REG(FDCAN_CCCR) |= 2u;                                /* CCE */
    HD_REG(FDCAN_CCCR) &= ~((1u << 8) | (1u << 9) | (1u << 6));   /* classic CAN, auto-retransmit */
    HD_REG(FDCAN_NBTP) = hd_bittiming_fdcan_nbtp(&bt);
    for (n = 0u; n < SRAMCAN_SIZE; n += 4u) {                /* message RAM has no reset value */
        HD_REG(SRAMCAN_BASE + n) = 0u;
    }
    HD_REG(FDCAN_RXGFC) = 0u;          /* no filters: accept every std/ext frame into FIFO 0 */
    HD_REG(FDCAN_TXBC) = 0u;           /* TX FIFO mode */
    HD_REG(FDCAN_IE) = FDCAN_IR_RF0N | FDCAN_IR_RF0L | FDCAN_IR_TFE;
    HD_REG(FDCAN_ILS) = 0u;            /* all on interrupt line 0 */
    HD_REG(FDCAN_ILE) = 1u;
    HD_REG(FDCAN_CCCR) &= ~1u;                               /* leave INIT: join the bus */
    return 0;
}

bool hd_g474_can_tx_hw(const hd_can_frame_t *f)
{
    const uint32_t fqs = HD_REG(FDCAN_TXFQS);
    uint32_t w0, i;
    if ((fqs & (1u << 21)) != 0u) {
        return false;                                        /* TX FIFO full */
    }
    const uint32_t idx = (fqs >> 16) & 3u;
    const uint32_t a = SRAMCAN_TXB + idx * SRAMCAN_ELEM;
    const uint32_t dlc = (f->dlc > 8u) ? 8u : f->dlc;
    w0 = (f->ext != 0u) ? ((1u << 30) | (f->id & 0x1FFFFFFFu)) : ((f->id & 0x7FFu) << 18);
    if (f->rtr != 0u) {
        w0 |= (1u << 29);
    }
    HD_REG(a) = w0;
    HD_REG(a + 4u) = dlc << 16;                              /* classic, no BRS, no event */
    uint32_t d[2] = {0u, 0u};
    for (i = 0u; i < dlc; i++) {
        d[i >> 2] |= (uint32_t)f->data[i] << (8u * (i & 3u));
    }
    HD_REG(a + 8u) = d[0];
    HD_REG(a + 12u) = d[1];
    HD_REG(FDCAN_TXBAR) = 1u << idx;
    return true;
}

bool hd_g474_can_rx_hw(hd_can_frame_t *f)
{
    const uint32_t s = HD_REG(FDCAN_RXF0S);
    uint32_t i;
    if ((s & 0xFu) == 0u) {
        return false;
    }
    const uint32_t idx = (s >> 8) & 3u;
    const uint32_t a = SRAMCAN_RXF0 + idx * SRAMCAN_ELEM;
    const uint32_t r0 = HD_REG(a);
    const uint32_t r1 = HD_REG(a + 4u);
    const uint32_t d[2] = {HD_REG(a + 8u), HD_REG(a + 12u)};
    f->ext = (uint8_t)((r0 >> 30) & 1u);
    f->rtr = (uint8_t)((r0 >> 29) & 1u);
    f->id = (f->ext != 0u) ? (r0 & 0x1FFFFFFFu) : ((r0 >> 18) & 0x7FFu);
    const uint32_t dlc = (r1 >> 16) & 0xFu;
    f->dlc = (uint8_t)((dlc > 8u) ? 8u : dlc);
    for (i = 0u; i < 8u; i++) {
        f->data[i] = (uint8_t)((d[i >> 2] >> (8u * (i & 3u))) & 0xFFu);
    }
    HD_REG(FDCAN_RXF0A) = idx;
    return true;
}

/* ---- TIM1: center-aligned three-phase PWM with dead time ------------------------- */

void hd_g474_pwm_init(void)
{
    const uint32_t b = TIM1_BASE;
    HD_REG(RCC_APB2ENR) |= (1u << 11);
    (void)HD_REG(RCC_APB2ENR);
    HD_REG(TIM_CR1(b)) = (1u << 5) | (1u << 7);              /* CMS = 01 center-aligned 1, ARPE */
    HD_REG(TIM_PSC(b)) = 0u;
    HD_REG(TIM_ARR(b)) = HD_G474_PWM_ARR;
    HD_REG(TIM_RCR(b)) = 1u;                                  /* one update per PWM period (at the valley) */
    /* CH1..CH3 PWM mode 1 with preload; CH4 PWM mode 2 at ARR - 1: ADC trigger at the peak,
     * where every low-side switch conducts (low-side shunt sampling) */
    HD_REG(TIM_CCMR1(b)) = (6u << 4) | (1u << 3) | (6u << 12) | (1u << 11);
    HD_REG(TIM_CCMR2(b)) = (6u << 4) | (1u << 3) | (7u << 12) | (1u << 11);
    HD_REG(TIM_CCR1(b)) = HD_G474_PWM_ARR / 2u;
    HD_REG(TIM_CCR2(b)) = HD_G474_PWM_ARR / 2u;
    HD_REG(TIM_CCR3(b)) = HD_G474_PWM_ARR / 2u;
    HD_REG(TIM_CCR4(b)) = HD_G474_PWM_ARR - 1u;
    /* CC1E, CC1NE, CC2E, CC2NE, CC3E, CC3NE, CC4E (internal trigger only) */
    HD_REG(TIM_CCER(b)) = (1u << 0) | (1u << 2) | (1u << 4) | (1u << 6) | (1u << 8) | (1u << 10) | (1u << 12);
    HD_REG(TIM_CR2(b)) = (7u << 20);                          /* MMS2 = OC4REF -> TRGO2 */
    /* dead time 500 ns, OSSI/OSSR: outputs held inactive (off) while MOE = 0; MOE stays 0 */
    HD_REG(TIM_BDTR(b)) = HD_G474_DEADTIME_DTG | (1u << 10) | (1u << 11);
    HD_REG(TIM_EGR(b)) = 1u;                                  /* load the preloads */
    HD_REG(TIM_CR1(b)) |= 1u;                                 /* CEN */
}

void hd_g474_pwm_set(const int32_t duty_q16[3])
{
    uint32_t c[3];
    uint32_t i;
    for (i = 0u; i < 3u; i++) {
        const uint32_t d = (duty_q16[i] < 0) ? 0u : ((duty_q16[i] > 65536) ? 65536u : (uint32_t)duty_q16[i]);
        c[i] = (d * HD_G474_PWM_ARR + 32768u) >> 16;          /* rounded; < 2^32 */
    }
    HD_REG(TIM_CCR1(TIM1_BASE)) = c[0];
    HD_REG(TIM_CCR2(TIM1_BASE)) = c[1];
    HD_REG(TIM_CCR3(TIM1_BASE)) = c[2];
}

void hd_g474_pwm_enable(bool on)
{
    if (on) {
        HD_REG(TIM_BDTR(TIM1_BASE)) |= TIM_BDTR_MOE;
    } else {
        HD_REG(TIM_BDTR(TIM1_BASE)) &= ~TIM_BDTR_MOE;
    }
}

/* ---- ADC1/ADC2: dual injected simultaneous, triggered by TIM1 TRGO2 ---------- */

static void adc_power_up(uint32_t b)
{
    uint32_t n;
    HD_REG(ADC_CR(b)) = 0u;                                   /* DEEPPWD off */
    HD_REG(ADC_CR(b)) = ADC_CR_ADVREGEN;
    hd_g474_delay_us(25u);                                    /* regulator start-up 20 us */
    HD_REG(ADC_CR(b)) = ADC_CR_ADVREGEN | ADC_CR_ADCAL;       /* single-ended calibration */
    for (n = 0u; (HD_REG(ADC_CR(b)) & ADC_CR_ADCAL) != 0u && n < WAIT_LIMIT; n++) {
    }
    hd_g474_delay_us(1u);
    HD_REG(ADC_ISR(b)) = ADC_ISR_ADRDY;
    HD_REG(ADC_CR(b)) = ADC_CR_ADVREGEN | ADC_CR_ADEN;
    for (n = 0u; (HD_REG(ADC_ISR(b)) & ADC_ISR_ADRDY) == 0u && n < WAIT_LIMIT; n++) {
    }
    /* 12.5 ADC cycles sampling on channels 1, 2, 3, 6 */
    HD_REG(ADC_SMPR1(b)) = (2u << 3) | (2u << 6) | (2u << 9) | (2u << 18);
}

void hd_g474_adc_init(void)
{
    HD_REG(RCC_AHB2ENR) |= (1u << 13);
    (void)HD_REG(RCC_AHB2ENR);
    HD_REG(ADC_CCR_C) = (3u << 16) | 5u;      /* CKMODE = HCLK/4 (42.5 MHz), DUAL = injected simultaneous */
    adc_power_up(ADC1_BASE);
    adc_power_up(ADC2_BASE);
    /* master ADC1: [IN1 phase A, IN3 DC link], trigger TIM1_TRGO2 rising; slave ADC2: [IN2 phase B, IN6 phase C] */
    HD_REG(ADC_JSQR(ADC1_BASE)) = 1u | (ADC_JEXTSEL_TIM1_TRGO2 << 2) | (1u << 7) | (1u << 9) | (3u << 15);
    HD_REG(ADC_JSQR(ADC2_BASE)) = 1u | (2u << 9) | (6u << 15);
    HD_REG(ADC_IER(ADC1_BASE)) = ADC_ISR_JEOS;
    HD_REG(ADC_CR(ADC1_BASE)) |= ADC_CR_JADSTART;
}

/* ---- TIM3: quadrature encoder (x4, 16-bit counter) ---------------------------- */

void hd_g474_enc_init(void)
{
    const uint32_t b = TIM3_BASE;
    HD_REG(RCC_APB1ENR1) |= (1u << 1);
    (void)HD_REG(RCC_APB1ENR1);
    HD_REG(TIM_CCMR1(b)) = 1u | (3u << 4) | (1u << 8) | (3u << 12);  /* TI1, TI2 inputs, filter 8 samples */
    HD_REG(TIM_SMCR(b)) = 3u;                                  /* encoder mode 3: both edges of both */
    HD_REG(TIM_ARR(b)) = 0xFFFFu;
    HD_REG(TIM_CR1(b)) = 1u;
}

uint32_t hd_g474_enc_raw(void)
{
    return HD_REG(TIM_CNT(TIM3_BASE)) & 0xFFFFu;
}

/* ---- SPI1: output encoder (receive only, 8-bit frames, 10.6 MHz) --------------- */

void hd_g474_spi_init(void)
{
    const uint32_t b = SPI1_BASE;
    HD_REG(RCC_APB2ENR) |= (1u << 12);
    (void)HD_REG(RCC_APB2ENR);
    /* master, CPOL = 1 (clock idles high, as SSI/BiSS), CPHA = 1 (sample on the rising edge),
     * BR = /16 -> 10.6 MHz, software NSS */
    HD_REG(SPI_CR1(b)) = (1u << 0) | (1u << 1) | (1u << 2) | (3u << 3) | (1u << 8) | (1u << 9);
    HD_REG(SPI_CR2(b)) = (7u << 8) | (1u << 12);               /* 8-bit frames, RXNE at 8 bits */
    HD_REG(SPI_CR1(b)) |= (1u << 6);                            /* SPE */
}

/* Clock n bytes in (one byte in flight at a time: the FIFO never overruns).
 * 48 bits at 10.6 MHz take ~4.6 us.  0 ok, -1 time-out. */
int32_t hd_g474_ssi_read(uint8_t *buf, uint32_t n)
{
    const uint32_t b = SPI1_BASE;
    volatile uint8_t *dr8 = (volatile uint8_t *)(uintptr_t)SPI_DR(b);
    uint32_t i, k;
    for (i = 0u; i < n; i++) {
        *dr8 = 0xFFu;
        for (k = 0u; (HD_REG(SPI_SR(b)) & 1u) == 0u; k++) {
            if (k > 2000u) {
                return -1;
            }
        }
        buf[i] = *dr8;
    }
    return 0;
}

/* ---- SPI1 + DMA1: the output-encoder frame without a CPU busy-wait ------------------
 * DMA1 channel 1 (DMAMUX 0) takes SPI1_RX into the frame buffer, channel 2
 * (DMAMUX 1) feeds SPI1_TX with 0xFF bytes (the master only clocks while it
 * transmits; MOSI has no pin).  Full duplex, 8-bit frames (FRXTH = 1), both
 * channels byte-wide; RX has the higher channel priority so the RX FIFO never
 * overruns.  The RX transfer-complete interrupt (DMA1_CH1) ends the read; the
 * last byte received means the 48 clocks are done.  (RM0440 SPI "communication
 * using DMA": RXDMAEN first, then the channels, then TXDMAEN.) */

#define SSI_DMA_RX 1u
#define SSI_DMA_TX 2u
#define SSI_DMA_MAX 16u

static const uint8_t ssi_dummy_tx[SSI_DMA_MAX] = {
    0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu, 0xFFu};

void hd_g474_ssi_dma_init(void)
{
    HD_REG(RCC_AHB1ENR) |= (1u << 0) | (1u << 2);              /* DMA1, DMAMUX1 */
    (void)HD_REG(RCC_AHB1ENR);
    HD_REG(DMAMUX_CCR(SSI_DMA_RX - 1u)) = DMAREQ_SPI1_RX;
    HD_REG(DMAMUX_CCR(SSI_DMA_TX - 1u)) = DMAREQ_SPI1_TX;
    HD_REG(DMA_CCR(SSI_DMA_RX)) = 0u;
    HD_REG(DMA_CCR(SSI_DMA_TX)) = 0u;
    HD_REG(DMA_CPAR(SSI_DMA_RX)) = SPI_DR(SPI1_BASE);
    HD_REG(DMA_CPAR(SSI_DMA_TX)) = SPI_DR(SPI1_BASE);
    HD_REG(DMA_IFCR) = 0xFFu;                                   /* channels 1 and 2: every flag */
}

void hd_g474_ssi_dma_start(uint8_t *buf, uint32_t n)
{
    const uint32_t b = SPI1_BASE;
    const uint32_t cnt = (n > SSI_DMA_MAX) ? SSI_DMA_MAX : n;
    volatile uint8_t *dr8 = (volatile uint8_t *)(uintptr_t)SPI_DR(b);
    uint32_t k;
    for (k = 0u; (HD_REG(SPI_SR(b)) & 1u) != 0u && k < 4u; k++) {
        (void)*dr8;                                             /* stale bytes out of the RX FIFO */
    }
    HD_REG(DMA_IFCR) = 0xFFu;
    HD_REG(DMA_CMAR(SSI_DMA_RX)) = (uint32_t)(uintptr_t)buf;
    HD_REG(DMA_CNDTR(SSI_DMA_RX)) = cnt;
    HD_REG(DMA_CMAR(SSI_DMA_TX)) = (uint32_t)(uintptr_t)ssi_dummy_tx;
    HD_REG(DMA_CNDTR(SSI_DMA_TX)) = cnt;
    HD_REG(SPI_CR2(b)) |= SPI_CR2_RXDMAEN;
    HD_REG(DMA_CCR(SSI_DMA_RX)) = DMA_CCR_MINC | DMA_CCR_TCIE | DMA_CCR_TEIE | DMA_CCR_PL_HIGH | DMA_CCR_EN;
    HD_REG(DMA_CCR(SSI_DMA_TX)) = DMA_CCR_MINC | DMA_CCR_DIR | DMA_CCR_EN;
    HD_REG(SPI_CR2(b)) |= SPI_CR2_TXDMAEN;                      /* the clocks start */
}

void hd_g474_ssi_dma_abort(void)
{
    HD_REG(DMA_CCR(SSI_DMA_TX)) = 0u;
    HD_REG(DMA_CCR(SSI_DMA_RX)) = 0u;
    HD_REG(SPI_CR2(SPI1_BASE)) &= ~(SPI_CR2_RXDMAEN | SPI_CR2_TXDMAEN);
    HD_REG(DMA_IFCR) = 0xFFu;
}

int32_t hd_g474_ssi_dma_finish(void)
{
    const uint32_t isr = HD_REG(DMA_ISR);
    const bool ok = ((isr & (1u << 1)) != 0u) && ((isr & ((1u << 3) | (1u << 7))) == 0u);  /* TCIF1, no TEIF1/2 */
    hd_g474_ssi_dma_abort();                                    /* channels off, flags cleared */
    return ok ? 0 : -1;
}

/* ---- IWDG: 10 ms ------------------------------------------------------------------ */

void hd_g474_iwdg_init(void)
{
    uint32_t n;
    HD_REG(IWDG_KR) = 0xCCCCu;          /* start (also starts the LSI) */
    HD_REG(IWDG_KR) = 0x5555u;          /* unlock PR/RLR */
    HD_REG(IWDG_PR) = 0u;               /* /4: 8 kHz */
    HD_REG(IWDG_RLR) = 80u;             /* 10 ms */
    for (n = 0u; HD_REG(IWDG_SR) != 0u && n < WAIT_LIMIT; n++) {
    }
    HD_REG(IWDG_KR) = 0xAAAAu;
}

void hd_g474_iwdg_kick(void)
{
    HD_REG(IWDG_KR) = 0xAAAAu;
}

/* ---- flash: the NVM area (bank 2, pages 104..127) ---------------------------- */

static int32_t flash_wait(void)
{
    uint32_t n;
    for (n = 0u; (HD_REG(FLASH_SR) & FLASH_SR_BSY) != 0u; n++) {
        if (n > 50000000u) {
            return -1;
        }
    }
    const uint32_t sr = HD_REG(FLASH_SR);
    HD_REG(FLASH_SR) = sr & (FLASH_SR_ERRS | 1u);            /* clear EOP and errors */
    return ((sr & FLASH_SR_ERRS) != 0u) ? -1 : 0;
}

static void flash_unlock(void)
{
    if ((HD_REG(FLASH_CR) & (1u << 31)) != 0u) {
        HD_REG(FLASH_KEYR) = FLASH_KEY1;
        HD_REG(FLASH_KEYR) = FLASH_KEY2;
    }
    HD_REG(FLASH_SR) = FLASH_SR_ERRS | 1u;
}

static void flash_lock(void)
{
    HD_REG(FLASH_CR) = (1u << 31);
}

int32_t hd_g474_flash_read(uint32_t off, void *buf, uint32_t len)
{
    const volatile uint8_t *src = (const volatile uint8_t *)(uintptr_t)(HD_G474_NVM_ADDR + off);
    uint8_t *d = (uint8_t *)buf;
    uint32_t i;
    if (off > HD_G474_NVM_PAGES * HD_G474_NVM_PAGE || len > HD_G474_NVM_PAGES * HD_G474_NVM_PAGE - off) {
        return -1;
    }
    (void)hd_g474_flash_ecc_take();
    for (i = 0u; i < len; i++) {
        d[i] = src[i];
    }
    return (hd_g474_flash_ecc_take() != 0u) ? -1 : 0;       /* torn dword (64 bit): ECC error */
}

int32_t hd_g474_flash_prog(uint32_t off, const void *buf, uint32_t len)
{
    const uint8_t *s = (const uint8_t *)buf;
    uint32_t i;
    int32_t rc = 0;
    if ((off % 8u) != 0u || (len % 8u) != 0u || off > HD_G474_NVM_PAGES * HD_G474_NVM_PAGE ||
        len > HD_G474_NVM_PAGES * HD_G474_NVM_PAGE - off) {
        return -1;
    }
    flash_unlock();
    if (flash_wait() != 0) {
        flash_lock();
        return -1;
    }
    HD_REG(FLASH_CR) = 1u;                                    /* PG */
    for (i = 0u; i < len && rc == 0; i += 8u) {
        const uint32_t lo = hd_get_le32(&s[i]);
        const uint32_t hi = hd_get_le32(&s[i + 4u]);
        HD_REG(HD_G474_NVM_ADDR + off + i) = lo;               /* a dword (64 bit): two word writes */
        HD_REG(HD_G474_NVM_ADDR + off + i + 4u) = hi;
        rc = flash_wait();
    }
    flash_lock();
    return rc;
}

int32_t hd_g474_flash_erase_page(uint32_t page)
{
    int32_t rc;
    if (page >= HD_G474_NVM_PAGES) {
        return -1;
    }
    flash_unlock();
    if (flash_wait() != 0) {
        flash_lock();
        return -1;
    }
    HD_REG(FLASH_CR) = (1u << 1) | ((HD_G474_NVM_BANK2_FIRST_PAGE + page) << 3) | (1u << 11);  /* PER, PNB, BKER */
    HD_REG(FLASH_CR) |= (1u << 16);                           /* STRT */
    rc = flash_wait();
    flash_lock();
    return rc;
}
