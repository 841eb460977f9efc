/*
 * g474_regs.h - the STM32G474 registers this port uses, written from RM0440
 * (rev 7) and PM0214; no vendor header is copied.  Only what is used.
 * Access through HD_REG(addr): a volatile 32-bit word.
 */
#ifndef HD_G474_REGS_H
#define HD_G474_REGS_H

#include <stdint.h>

#define HD_REG(a) (*(volatile uint32_t *)(uintptr_t)(a))

/* ---- Cortex-M4 system (PM0214) -------------------------------------------- */
#define SYST_CSR        0xE000E010u
#define SYST_RVR        0xE000E014u
#define SYST_CVR        0xE000E018u
#define NVIC_ISER(n)    (0xE000E100u + 4u * (n))
#define NVIC_ICER(n)    (0xE000E180u + 4u * (n))
#define NVIC_IPR_BASE   0xE000E400u          /* one byte per IRQ */
#define SCB_ICSR        0xE000ED04u
#define SCB_ICSR_PENDSVSET (1u << 28)
#define SCB_VTOR        0xE000ED08u
#define SCB_AIRCR       0xE000ED0Cu
#define SCB_AIRCR_RESET 0x05FA0004u           /* VECTKEY | SYSRESETREQ */
#define SCB_SHPR3       0xE000ED20u           /* PendSV [23:16], SysTick [31:24] */
#define SCB_CPACR       0xE000ED88u           /* CP10/CP11 full access: 0xF << 20 */

/* ---- IRQ numbers used (RM0440 table 97) ------------------------------------ */
#define IRQ_DMA1_CH1    11u
#define IRQ_ADC1_2      18u
#define IRQ_FDCAN1_IT0  21u
#define IRQ_COUNT       102u

/* ---- RCC (0x40021000) ------------------------------------------------------- */
#define RCC_BASE        0x40021000u
#define RCC_CR          (RCC_BASE + 0x00u)
#define   RCC_CR_HSEON    (1u << 16)
#define   RCC_CR_HSERDY   (1u << 17)
#define   RCC_CR_PLLON    (1u << 24)
#define   RCC_CR_PLLRDY   (1u << 25)
#define RCC_CFGR        (RCC_BASE + 0x08u)    /* SW [1:0], SWS [3:2], HPRE [7:4], PPRE1 [10:8], PPRE2 [13:11] */
#define RCC_PLLCFGR     (RCC_BASE + 0x0Cu)    /* PLLSRC [1:0], PLLM [7:4], PLLN [14:8], PLLREN 24, PLLR [26:25] */
#define RCC_AHB1ENR     (RCC_BASE + 0x48u)    /* DMA1 0, DMAMUX1 2 */
#define RCC_AHB2ENR     (RCC_BASE + 0x4Cu)    /* GPIOA 0, GPIOB 1, GPIOC 2, ADC12 13 */
#define RCC_APB1ENR1    (RCC_BASE + 0x58u)    /* TIM3 1, FDCAN 25, PWR 28 */
#define RCC_APB2ENR     (RCC_BASE + 0x60u)    /* SYSCFG 0, TIM1 11, SPI1 12 */
#define RCC_CCIPR       (RCC_BASE + 0x88u)    /* FDCANSEL [25:24]: 10 = PCLK1; ADC12SEL [29:28] */
#define RCC_CSR         (RCC_BASE + 0x94u)    /* RMVF 23, reset flags [31:25] (IWDGRSTF 29) */

/* ---- PWR (0x40007000) ------------------------------------------------------- */
#define PWR_BASE        0x40007000u
#define PWR_CR1         (PWR_BASE + 0x00u)    /* VOS [10:9]: 01 = range 1 */
#define PWR_SR2         (PWR_BASE + 0x14u)    /* VOSF 10 */
#define PWR_CR5         (PWR_BASE + 0x80u)    /* R1MODE 8: 0 = range 1 boost */

/* ---- FLASH (0x40022000) ----------------------------------------------------- */
#define FLASH_BASE_R    0x40022000u
#define FLASH_ACR       (FLASH_BASE_R + 0x00u) /* LATENCY [3:0], PRFTEN 8, ICEN 9, DCEN 10 */
#define FLASH_KEYR      (FLASH_BASE_R + 0x08u)
#define FLASH_SR        (FLASH_BASE_R + 0x10u) /* EOP 0, errors 1..9,14,15, BSY 16 */
#define   FLASH_SR_BSY    (1u << 16)
#define   FLASH_SR_ERRS   0x0000C3FAu
#define FLASH_CR        (FLASH_BASE_R + 0x14u) /* PG 0, PER 1, PNB [9:3], BKER 11, STRT 16, LOCK 31 */
#define FLASH_ECCR      (FLASH_BASE_R + 0x18u) /* ECCD 31 (write 1 to clear) */
#define FLASH_KEY1      0x45670123u
#define FLASH_KEY2      0xCDEF89ABu

/* ---- GPIO ------------------------------------------------------------------- */
#define GPIOA_BASE      0x48000000u
#define GPIOB_BASE      0x48000400u
#define GPIOC_BASE      0x48000800u
#define GPIO_MODER(b)   ((b) + 0x00u)
#define GPIO_OSPEEDR(b) ((b) + 0x08u)
#define GPIO_PUPDR(b)   ((b) + 0x0Cu)
#define GPIO_AFRL(b)    ((b) + 0x20u)
#define GPIO_AFRH(b)    ((b) + 0x24u)

/* ---- TIM1 (advanced, 0x40012C00) and TIM3 (general, 0x40000400) -------------- */
#define TIM1_BASE       0x40012C00u
#define TIM3_BASE       0x40000400u
#define TIM_CR1(b)      ((b) + 0x00u)         /* CEN 0, CMS [6:5], ARPE 7 */
#define TIM_CR2(b)      ((b) + 0x04u)         /* MMS2 [23:20] */
#define TIM_SMCR(b)     ((b) + 0x08u)         /* SMS [2:0] */
#define TIM_SR(b)       ((b) + 0x10u)
#define TIM_EGR(b)      ((b) + 0x14u)         /* UG 0 */
#define TIM_CCMR1(b)    ((b) + 0x18u)
#define TIM_CCMR2(b)    ((b) + 0x1Cu)
#define TIM_CCER(b)     ((b) + 0x20u)
#define TIM_CNT(b)      ((b) + 0x24u)
#define TIM_PSC(b)      ((b) + 0x28u)
#define TIM_ARR(b)      ((b) + 0x2Cu)
#define TIM_RCR(b)      ((b) + 0x30u)
#define TIM_CCR1(b)     ((b) + 0x34u)
#define TIM_CCR2(b)     ((b) + 0x38u)
#define TIM_CCR3(b)     ((b) + 0x3Cu)
#define TIM_CCR4(b)     ((b) + 0x40u)
#define TIM_BDTR(b)     ((b) + 0x44u)         /* DTG [7:0], OSSI 10, OSSR 11, MOE 15 */
#define   TIM_BDTR_MOE    (1u << 15)

/* ---- SPI1 (0x40013000) ------------------------------------------------------ */
#define SPI1_BASE       0x40013000u
#define SPI_CR1(b)      ((b) + 0x00u)         /* CPHA 0, CPOL 1, MSTR 2, BR [5:3], SPE 6, SSI 8, SSM 9 */
#define SPI_CR2(b)      ((b) + 0x04u)         /* RXDMAEN 0, TXDMAEN 1, DS [11:8], FRXTH 12 */
#define   SPI_CR2_RXDMAEN (1u << 0)
#define   SPI_CR2_TXDMAEN (1u << 1)
#define SPI_SR(b)       ((b) + 0x08u)         /* RXNE 0, TXE 1, OVR 6, BSY 7 */
#define SPI_DR(b)       ((b) + 0x0Cu)

/* ---- DMA1 (0x40020000) and DMAMUX1 (0x40020800) ---------------------------- */
#define DMA1_BASE       0x40020000u
#define DMA_ISR         (DMA1_BASE + 0x00u)   /* channel x (1..8): GIF 4(x-1), TCIF +1, HTIF +2, TEIF +3 */
#define DMA_IFCR        (DMA1_BASE + 0x04u)   /* same bit positions, write 1 to clear */
#define DMA_CCR(x)      (DMA1_BASE + 0x08u + 0x14u * ((x) - 1u))  /* EN 0, TCIE 1, TEIE 3, DIR 4, MINC 7, PL [13:12] */
#define DMA_CNDTR(x)    (DMA1_BASE + 0x0Cu + 0x14u * ((x) - 1u))
#define DMA_CPAR(x)     (DMA1_BASE + 0x10u + 0x14u * ((x) - 1u))
#define DMA_CMAR(x)     (DMA1_BASE + 0x14u + 0x14u * ((x) - 1u))
#define   DMA_CCR_EN      (1u << 0)
#define   DMA_CCR_TCIE    (1u << 1)
#define   DMA_CCR_TEIE    (1u << 3)
#define   DMA_CCR_DIR     (1u << 4)           /* 1: memory -> peripheral */
#define   DMA_CCR_MINC    (1u << 7)
#define   DMA_CCR_PL_HIGH (2u << 12)
#define DMAMUX1_BASE    0x40020800u
#define DMAMUX_CCR(c)   (DMAMUX1_BASE + 4u * (c))   /* DMAMUX channel c = DMA1 channel c+1; DMAREQ_ID [6:0] */
#define DMAREQ_SPI1_RX  10u                   /* RM0440 table 91 */
#define DMAREQ_SPI1_TX  11u

/* ---- ADC1/ADC2 (0x50000000 / 0x50000100, common 0x50000300) ------------------ */
#define ADC1_BASE       0x50000000u
#define ADC2_BASE       0x50000100u
#define ADC12_COMMON    0x50000300u
#define ADC_ISR(b)      ((b) + 0x00u)         /* ADRDY 0, JEOC 5, JEOS 6 */
#define   ADC_ISR_ADRDY   (1u << 0)
#define   ADC_ISR_JEOS    (1u << 6)
#define ADC_IER(b)      ((b) + 0x04u)         /* JEOSIE 6 */
#define ADC_CR(b)       ((b) + 0x08u)         /* ADEN 0, JADSTART 3, ADVREGEN 28, DEEPPWD 29, ADCAL 31 */
#define   ADC_CR_ADEN     (1u << 0)
#define   ADC_CR_JADSTART (1u << 3)
#define   ADC_CR_ADVREGEN (1u << 28)
#define   ADC_CR_ADCAL    (1u << 31)
#define ADC_SMPR1(b)    ((b) + 0x14u)         /* SMPx [3x+2:3x] for channels 0..9 */
#define ADC_JSQR(b)     ((b) + 0x4Cu)         /* JL [1:0], JEXTSEL [6:2], JEXTEN [8:7], JSQ1 [13:9], JSQ2 [19:15] */
#define ADC_JDR1(b)     ((b) + 0x80u)
#define ADC_JDR2(b)     ((b) + 0x84u)
#define ADC_CCR_C       (ADC12_COMMON + 0x08u) /* DUAL [4:0], CKMODE [17:16] */
#define ADC_JEXTSEL_TIM1_TRGO2 8u             /* RM0440 table 163 (ADC1/2 injected triggers) */

/* ---- FDCAN1 (0x40006400) and its message RAM (0x4000A400) ----------------- */
#define FDCAN1_BASE     0x40006400u
#define FDCAN_CCCR      (FDCAN1_BASE + 0x18u) /* INIT 0, CCE 1, DAR 6, FDOE 8, BRSE 9 */
#define FDCAN_NBTP      (FDCAN1_BASE + 0x1Cu)
#define FDCAN_ECR       (FDCAN1_BASE + 0x40u) /* TEC [7:0], REC [14:8], RP 15 */
#define FDCAN_PSR       (FDCAN1_BASE + 0x44u) /* EP 5, EW 6, BO 7 */
#define FDCAN_IR        (FDCAN1_BASE + 0x50u) /* RF0N 0, RF0L 2, TFE 9, BO 19 */
#define FDCAN_IE        (FDCAN1_BASE + 0x54u)
#define FDCAN_ILS       (FDCAN1_BASE + 0x58u)
#define FDCAN_ILE       (FDCAN1_BASE + 0x5Cu) /* EINT0 0 */
#define FDCAN_RXGFC     (FDCAN1_BASE + 0x80u) /* ANFS [5:4], ANFE [3:2]: 00 = accept into FIFO 0 */
#define FDCAN_RXF0S     (FDCAN1_BASE + 0x90u) /* F0FL [3:0], F0GI [9:8] */
#define FDCAN_RXF0A     (FDCAN1_BASE + 0x94u)
#define FDCAN_TXBC      (FDCAN1_BASE + 0xC0u) /* TFQM 24: 0 = FIFO */
#define FDCAN_TXFQS     (FDCAN1_BASE + 0xC4u) /* TFFL [2:0], TFQPI [17:16], TFQF 21 */
#define FDCAN_TXBAR     (FDCAN1_BASE + 0xCCu)
#define FDCAN_IR_RF0N   (1u << 0)
#define FDCAN_IR_RF0L   (1u << 2)
#define FDCAN_IR_TFE    (1u << 9)
#define SRAMCAN_BASE    0x4000A400u
#define SRAMCAN_RXF0    (SRAMCAN_BASE + 0x0B0u) /* 3 elements of 18 words */
#define SRAMCAN_TXB     (SRAMCAN_BASE + 0x278u) /* 3 elements of 18 words */
#define SRAMCAN_SIZE    0x350u
#define SRAMCAN_ELEM    72u                     /* bytes per RX/TX element */

/* ---- IWDG (0x40003000) ------------------------------------------------------ */
#define IWDG_KR         0x40003000u
#define IWDG_PR         0x40003004u
#define IWDG_RLR        0x40003008u
#define IWDG_SR         0x4000300Cu

#endif
