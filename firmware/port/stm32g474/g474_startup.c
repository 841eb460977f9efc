/*
 * g474_startup.c - vector table, reset handler, fault handlers and the clock
 * tree of the STM32G474 drive image.
 *
 * Reset: enable the FPU (the image is built for the hard-FP ABI (FPv4-SP) although
 * the code is integer-only), copy .data, zero .bss (also the CCM-SRAM
 * section .ccmbss), then main().  Faults switch the PWM outputs off first
 * (MOE = 0, so the power stage is safe) and reset the MCU.
 *
 * Clock: HSE (8 or 24 MHz, HD_G474_HSE_HZ) -> PLL (M so that the VCO input
 * is 4 MHz, N = 85 -> VCO 340 MHz, R = 2) -> SYSCLK 170 MHz, voltage range 1
 * boost mode (PWR_CR5.R1MODE = 0), 4 flash wait states with prefetch and the
 * instruction/data caches (ART), AHB = APB1 = APB2 = 170 MHz.  The switch to
 * 170 MHz goes through AHB/2 for 1 us as RM0440 6.1.5 requires.
 */
#include <stdint.h>
#include "g474_regs.h"
#include "g474_config.h"
#include "g474_port.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _sccmbss, _eccmbss, _estack;
void hd_g474_reset(void);

static volatile uint32_t ecc_hits;

void hd_g474_reset(void)
{
    uint32_t *d;
    const uint32_t *s = &_sidata;
    HD_REG(SCB_CPACR) |= (0xFu << 20);            /* CP10, CP11 full access */
    for (d = &_sdata; d < &_edata; d++) {
        *d = *s++;
    }
    for (d = &_sbss; d < &_ebss; d++) {
        *d = 0u;
    }
    for (d = &_sccmbss; d < &_eccmbss; d++) {
        *d = 0u;
    }
    (void)main();
    for (;;) {
        HD_REG(SCB_AIRCR) = SCB_AIRCR_RESET;
    }
}

void hd_g474_pwm_kill(void)
{
    HD_REG(TIM_BDTR(TIM1_BASE)) &= ~TIM_BDTR_MOE;
}

static void fault_reset(void)
{
    hd_g474_pwm_kill();
    for (;;) {
        HD_REG(SCB_AIRCR) = SCB_AIRCR_RESET;
    }
}

/* NMI: a flash ECC two-bit error (a torn dword (64 bit) in the parameter area)
 * is recorded and execution continues (the NVM read then reports an error);
 * any other NMI is fatal. */
static void nmi_handler(void)
{
    if ((HD_REG(FLASH_ECCR) & (1u << 31)) != 0u) {
        HD_REG(FLASH_ECCR) = (1u << 31);
        ecc_hits++;
        return;
    }
    fault_reset();
}

uint32_t hd_g474_flash_ecc_take(void)
{
    const uint32_t h = ecc_hits;
    ecc_hits = 0u;
    return (h != 0u) ? 1u : 0u;
}

static void default_handler(void) { fault_reset(); }

typedef void (*hd_vector_t)(void);

/* 16 system vectors + 102 IRQs (RM0440 table 97); unused IRQs reset the MCU. */
__attribute__((section(".isr_vector"), used))
static const hd_vector_t hd_g474_vectors[16u + IRQ_COUNT] = {
    [0] = (hd_vector_t)(uintptr_t)&_estack,
    [1] = hd_g474_reset,
    [2] = nmi_handler,
    [3] = default_handler,          /* HardFault */
    [4] = default_handler,          /* MemManage */
    [5] = default_handler,          /* BusFault */
    [6] = default_handler,          /* UsageFault */
    [11] = default_handler,         /* SVCall */
    [12] = default_handler,         /* DebugMonitor */
    [14] = hd_g474_pendsv,          /* PendSV: the 10 kHz control step */
    [15] = default_handler,         /* SysTick (not enabled: used as a delay counter) */
    [16u + IRQ_DMA1_CH1] = hd_g474_ssi_dma_irq,  /* output-encoder frame received */
    [16u + IRQ_ADC1_2] = hd_g474_adc_irq,        /* 20 kHz FOC */
    [16u + IRQ_FDCAN1_IT0] = hd_g474_fdcan_irq,  /* CAN RX / TX-empty */
    [16u + 0u] = default_handler,   /* WWDG (and, below, every other IRQ) */
    [16u + 1u ... 16u + IRQ_DMA1_CH1 - 1u] = default_handler,
    [16u + IRQ_DMA1_CH1 + 1u ... 16u + IRQ_ADC1_2 - 1u] = default_handler,
    [16u + IRQ_ADC1_2 + 1u ... 16u + IRQ_FDCAN1_IT0 - 1u] = default_handler,
    [16u + IRQ_FDCAN1_IT0 + 1u ... 16u + IRQ_COUNT - 1u] = default_handler,
};

/* SysTick as a free-running 24-bit down-counter at 170 MHz for short delays. */
void hd_g474_delay_us(uint32_t us)
{
    uint32_t left = us * (HD_G474_SYSCLK_HZ / 1000000u);
    uint32_t prev = HD_REG(SYST_CVR);
    while (left > 0u) {
        const uint32_t now = HD_REG(SYST_CVR);
        const uint32_t el = (prev - now) & 0x00FFFFFFu;    /* down-counter, wraps at 2^24 */
        prev = now;
        left = (el >= left) ? 0u : left - el;
    }
}

void hd_g474_clock_init(void)
{
    const uint32_t pllm = HD_G474_HSE_HZ / 4000000u;        /* VCO input 4 MHz */
    HD_REG(RCC_APB1ENR1) |= (1u << 28);                      /* PWR */
    (void)HD_REG(RCC_APB1ENR1);
    /* range 1 boost: R1MODE = 0 while still at 16 MHz */
    HD_REG(PWR_CR1) = (HD_REG(PWR_CR1) & ~(3u << 9)) | (1u << 9);
    while ((HD_REG(PWR_SR2) & (1u << 10)) != 0u) {
    }
    HD_REG(PWR_CR5) &= ~(1u << 8);
    /* HSE */
    HD_REG(RCC_CR) |= RCC_CR_HSEON;
    while ((HD_REG(RCC_CR) & RCC_CR_HSERDY) == 0u) {
    }
    /* PLL: src HSE (3), M, N = 85, R = 2 (00), R output enabled */
    HD_REG(RCC_CR) &= ~RCC_CR_PLLON;
    while ((HD_REG(RCC_CR) & RCC_CR_PLLRDY) != 0u) {
    }
    HD_REG(RCC_PLLCFGR) = 3u | ((pllm - 1u) << 4) | (85u << 8) | (1u << 24);
    HD_REG(RCC_CR) |= RCC_CR_PLLON;
    while ((HD_REG(RCC_CR) & RCC_CR_PLLRDY) == 0u) {
    }
    /* flash: 4 wait states, prefetch, I- and D-cache */
    HD_REG(FLASH_ACR) = 4u | (1u << 8) | (1u << 9) | (1u << 10);
    while ((HD_REG(FLASH_ACR) & 0xFu) != 4u) {
    }
    /* AHB /2 during the switch, then /1 after >= 1 us */
    HD_REG(RCC_CFGR) = (8u << 4) | 3u;                       /* HPRE = /2, SW = PLL */
    while (((HD_REG(RCC_CFGR) >> 2) & 3u) != 3u) {
    }
    HD_REG(SYST_RVR) = 0x00FFFFFFu;
    HD_REG(SYST_CVR) = 0u;
    HD_REG(SYST_CSR) = 5u;                                   /* processor clock, enabled, no IRQ */
    hd_g474_delay_us(2u);                                    /* counts at 85 MHz: >= 1 us */
    HD_REG(RCC_CFGR) = 3u;                                   /* HPRE = PPRE1 = PPRE2 = /1 */
}
