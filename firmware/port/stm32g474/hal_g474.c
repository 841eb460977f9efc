/*
 * hal_g474.c - hal.h on the STM32G474, the interrupt structure and main().
 *
 * Interrupts (4 priority bits; lower number = more urgent):
 *   ADC1_2 (prio 0, 20 kHz)  injected conversion done at the PWM peak: phase
 *       currents, DC link; motor encoder; FOC current loop step; new duties
 *       (applied at the next PWM update).  Every 2nd period (10 kHz) it also
 *       latches the motor-encoder and current part of the control period's
 *       sensor sample and starts the output-encoder read (SPI1 by DMA, 48
 *       clocks, ~4.6 us; no CPU wait).
 *   DMA1_CH1 (prio 1, 10 kHz) output-encoder frame received: decode (CRC),
 *       complete the sensor sample, overrun check, pend PendSV.  The control
 *       period therefore starts on DMA completion, ~5 us after the sample.
 *   FDCAN1_IT0 (prio 1)      RX FIFO 0 -> software RX queue; TX FIFO empty ->
 *       refill from the software TX queue.
 *   PendSV (prio 15, 10 kHz) the control period: received CAN frames into
 *       the CANopen device (hd_co_process: SDO, NMT, RPDO, SYNC, ... reach the
 *       app through firmware/canopen/hd_app_co.c), hd_app_step(), hd_co_tick()
 *       (heartbeat, TPDOs, CiA 402, time-outs); then the watchdog is
 *       refreshed (only here: a stuck control step resets the MCU).
 * main() initialises everything, then runs the background below every interrupt
 * (hd_app_background: the online friction identification's queued steps, one short
 * part per call) and sleeps (WFI) when it has none.
 *
 * Static state: this file holds the port's driver state (the application
 * struct, FOC state, encoder state, CAN queues, the NVM image, the latched
 * sensor sample and the command).  Interrupt handlers take no arguments, so
 * their state must be static; firmware/core stays free of globals.
 * Sharing rules: the ADC ISR fills the next sample (sens_next) and starts the
 * DMA; the DMA ISR completes it, copies it to the sensor latch and pends
 * PendSV, which reads the latch first thing (100 us apart); the command goes from
 * PendSV to the ADC ISR through a two-entry buffer with an index flip (one
 * aligned word store, atomic); each CAN queue has a single producer and a
 * single consumer with the index updates as the last store.
 */
#include <stdint.h>
#include <stdbool.h>
#include "g474_regs.h"
#include "g474_config.h"
#include "g474_port.h"
#include "hal.h"
#include "hd_app.h"
#include "hd_app_co.h"
#include "hd_co.h"
#include "hd_foc.h"
#include "hd_fixed.h"
#include "hd_encoder.h"
#include "hd_ssi.h"
#include "hd_flashstore.h"

/* ---- port state ------------------------------------------------------------------ */

static hd_app_t app;                          /* the drive application (~RAM budget, see docs) */
static hd_co_t co;                            /* the CANopen device */
static hd_app_co_t app_co;                    /* CANopen <-> app adapter (+ table staging) */

static hd_foc_t foc;
static hd_foc_cfg_t foc_cfg;
static hd_enc_t menc;
static int32_t i_off[3];
static int32_t cal_acc[3];
static uint32_t cal_n;
static uint32_t foc_phase;                    /* 0 .. HD_G474_FOC_PER_CTRL-1 */
static volatile uint32_t tick;
static volatile uint32_t app_ran;             /* set by PendSV, cleared when the ISR pends */

static hd_hal_sensors_t sens_latch;
static hd_hal_sensors_t sens_next;            /* being assembled: ADC ISR, then the DMA ISR */
static uint8_t ssi_frame[HD_G474_SSI_BYTES];  /* DMA target (.bss in SRAM1, reachable by DMA1) */
static volatile uint32_t ssi_busy;            /* a frame transfer is running */
static hd_hal_command_t cmd_buf[2];
static volatile uint32_t cmd_idx;

/* CAN queues */
static hd_can_frame_t rxq[HD_G474_CAN_RXQ], txq[HD_G474_CAN_TXQ];
static volatile uint32_t rx_head, rx_tail, tx_head, tx_tail;   /* head: producer, tail: consumer */
static volatile uint32_t rx_dropped;

/* NVM */
static hd_vnvm_t vnvm;
static int32_t fl_read(void *ctx, uint32_t a, void *b, uint32_t l) { (void)ctx; return hd_g474_flash_read(a, b, l); }
static int32_t fl_prog(void *ctx, uint32_t a, const void *b, uint32_t l) { (void)ctx; return hd_g474_flash_prog(a, b, l); }
static int32_t fl_erase(void *ctx, uint32_t p) { (void)ctx; return hd_g474_flash_erase_page(p); }
static const hd_flash_if_t flash_if = {0, fl_read, fl_prog, fl_erase, HD_G474_NVM_PAGE, HD_G474_NVM_PAGES};
static int32_t nvm_ok;

/* ---- hal.h ------------------------------------------------------------------------ */

uint32_t hd_hal_tick(void)
{
    return tick;
}

void hd_hal_read_sensors(hd_hal_sensors_t *s)
{
    *s = sens_latch;
}

void hd_hal_write_command(const hd_hal_command_t *c)
{
    const uint32_t next = cmd_idx ^ 1u;
    cmd_buf[next] = *c;
    __asm__ volatile("dmb" ::: "memory");
    cmd_idx = next;                          /* the ADC ISR picks it up from here */
}

static void can_pump_tx(void)
{
    while (tx_tail != tx_head) {
        if (!hd_g474_can_tx_hw(&txq[tx_tail % HD_G474_CAN_TXQ])) {
            break;
        }
        tx_tail = tx_tail + 1u;
    }
}

bool hd_hal_can_send(const hd_can_frame_t *f)
{
    if (tx_head - tx_tail >= HD_G474_CAN_TXQ) {
        return false;
    }
    txq[tx_head % HD_G474_CAN_TXQ] = *f;
    __asm__ volatile("dmb" ::: "memory");
    tx_head = tx_head + 1u;
    /* the pump runs in the FDCAN ISR; mask it while this context pumps too */
    HD_REG(NVIC_ICER(IRQ_FDCAN1_IT0 >> 5)) = 1u << (IRQ_FDCAN1_IT0 & 31u);
    can_pump_tx();
    HD_REG(NVIC_ISER(IRQ_FDCAN1_IT0 >> 5)) = 1u << (IRQ_FDCAN1_IT0 & 31u);
    return true;
}

bool hd_hal_can_recv(hd_can_frame_t *f)
{
    if (rx_tail == rx_head) {
        return false;
    }
    *f = rxq[rx_tail % HD_G474_CAN_RXQ];
    __asm__ volatile("dmb" ::: "memory");
    rx_tail = rx_tail + 1u;
    return true;
}

/* FDCAN fault confinement: PSR.BO / PSR.EP / PSR.EW and the counters of ECR */
void hd_hal_can_status(hd_hal_can_status_t *st)
{
    const uint32_t psr = HD_REG(FDCAN_PSR);
    const uint32_t ecr = HD_REG(FDCAN_ECR);
    if ((psr & (1u << 7)) != 0u) {
        st->state = HD_HAL_CAN_BUS_OFF;
    } else if ((psr & (1u << 5)) != 0u) {
        st->state = HD_HAL_CAN_ERROR_PASSIVE;
    } else {
        st->state = HD_HAL_CAN_ERROR_ACTIVE;
    }
    st->warning = (uint8_t)((psr >> 6) & 1u);
    st->tec = (uint8_t)(ecr & 0xFFu);
    st->rec = (uint8_t)(((ecr & (1u << 15)) != 0u) ? 128u : ((ecr >> 8) & 0x7Fu));
}

/* Bus-off sets CCCR.INIT; clearing it starts the recovery (128 x 11 recessive bits, RM0440 44.3.2) */
void hd_hal_can_recover(void)
{
    if ((HD_REG(FDCAN_PSR) & (1u << 7)) != 0u && (HD_REG(FDCAN_CCCR) & 1u) != 0u) {
        HD_REG(FDCAN_CCCR) &= ~1u;
    }
}

uint32_t hd_hal_nvm_size(void) { return (nvm_ok == 0) ? HD_G474_VNVM_SIZE : 0u; }
uint32_t hd_hal_nvm_page_size(void) { return HD_G474_VNVM_PAGE; }
int32_t hd_hal_nvm_read(uint32_t o, void *b, uint32_t l) { return (nvm_ok == 0) ? hd_vnvm_read(&vnvm, o, b, l) : -1; }
int32_t hd_hal_nvm_write(uint32_t o, const void *b, uint32_t l) { return (nvm_ok == 0) ? hd_vnvm_write(&vnvm, o, b, l) : -1; }
int32_t hd_hal_nvm_erase(uint32_t o, uint32_t l) { return (nvm_ok == 0) ? hd_vnvm_erase(&vnvm, o, l) : -1; }

/* ---- interrupts --------------------------------------------------------------------- */

void hd_g474_fdcan_irq(void)
{
    hd_can_frame_t f;
    const uint32_t ir = HD_REG(FDCAN_IR);
    HD_REG(FDCAN_IR) = ir;
    while (hd_g474_can_rx_hw(&f)) {
        if (rx_head - rx_tail < HD_G474_CAN_RXQ) {
            rxq[rx_head % HD_G474_CAN_RXQ] = f;
            __asm__ volatile("dmb" ::: "memory");
            rx_head = rx_head + 1u;
        } else {
            rx_dropped = rx_dropped + 1u;
        }
    }
    if ((ir & FDCAN_IR_RF0L) != 0u) {
        rx_dropped = rx_dropped + 1u;
    }
    can_pump_tx();
}

/* Start of a control period's sample, in the ADC ISR: motor encoder and
 * current now; the output encoder follows by DMA (hd_g474_ssi_dma_irq). */
static void latch_fast(void)
{
    uint32_t valid = 0u;
    sens_next.motor_enc_raw = hd_enc_single_turn(&menc, HD_G474_MOTOR_ENC_BITS);
    if (menc.ok != 0u) {
        valid |= HD_HAL_VALID_MOTOR_ENC;
    }
    sens_next.output_enc_raw = sens_latch.output_enc_raw;   /* kept if this frame is bad */
    sens_next.current = foc.iq;
    if (cal_n >= HD_G474_I_CAL_N) {
        valid |= HD_HAL_VALID_CURRENT;
    }
    sens_next.gyro_rate = 0;                  /* no gyro interface on this board yet */
    sens_next.valid = valid;
}

/* The sample is complete: publish it and start the control step (PendSV). */
static void control_period_start(void)
{
    sens_latch = sens_next;
    tick = tick + 1u;
    if (app_ran == 0u && tick > 2u) {
        /* the previous control step has not finished: overrun -> safe state */
        hd_g474_pwm_kill();
    }
    app_ran = 0u;
    HD_REG(SCB_ICSR) = SCB_ICSR_PENDSVSET;
}

void hd_g474_ssi_dma_irq(void)
{
    hd_ssi_reading_t r;
    if (hd_g474_ssi_dma_finish() == 0 &&
        hd_ssi_decode(ssi_frame, HD_G474_SSI_BYTES, 8u * HD_G474_SSI_BYTES, &r) == HD_SSI_OK && r.error == 0u) {
        sens_next.output_enc_raw = r.position;
        sens_next.valid |= HD_HAL_VALID_OUTPUT_ENC;
    }
    if (ssi_busy != 0u) {
        ssi_busy = 0u;
        control_period_start();
    }
}

void hd_g474_adc_irq(void)
{
    hd_foc_in_t in;
    hd_foc_out_t out;
    const int32_t ra = (int32_t)(HD_REG(ADC_JDR1(ADC1_BASE)) & 0xFFFu);
    const int32_t rv = (int32_t)(HD_REG(ADC_JDR2(ADC1_BASE)) & 0xFFFu);
    const int32_t rb = (int32_t)(HD_REG(ADC_JDR1(ADC2_BASE)) & 0xFFFu);
    const int32_t rc = (int32_t)(HD_REG(ADC_JDR2(ADC2_BASE)) & 0xFFFu);
    HD_REG(ADC_ISR(ADC1_BASE)) = ADC_ISR_JEOS;
    (void)hd_enc_update(&menc, hd_g474_enc_raw());
    if (cal_n < HD_G474_I_CAL_N) {            /* current offsets, power stage off */
        cal_acc[0] += ra;
        cal_acc[1] += rb;
        cal_acc[2] += rc;
        cal_n++;
        if (cal_n == HD_G474_I_CAL_N) {
            i_off[0] = hd_asr32_rnd(cal_acc[0], 8u);
            i_off[1] = hd_asr32_rnd(cal_acc[1], 8u);
            i_off[2] = hd_asr32_rnd(cal_acc[2], 8u);
        }
    }
    const hd_hal_command_t *c = &cmd_buf[cmd_idx];
    in.ia = hd_foc_adc_current(ra, i_off[0], HD_G474_I_GAIN_Q30);
    in.ib = hd_foc_adc_current(rb, i_off[1], HD_G474_I_GAIN_Q30);
    in.theta_e = hd_foc_elec_angle(hd_enc_single_turn(&menc, HD_G474_MOTOR_ENC_BITS), HD_G474_MOTOR_ENC_BITS,
                                   HD_G474_POLE_PAIRS, HD_G474_ELEC_OFFSET);
    in.id_ref = 0;
    in.iq_ref = c->current;
    in.vbus = rv * HD_G474_VBUS_Q16_PER_LSB;
    if (c->enable != 0u && cal_n >= HD_G474_I_CAL_N) {
        hd_foc_step(&foc, &foc_cfg, &in, &out);
        hd_g474_pwm_set(out.duty);
        hd_g474_pwm_enable(true);
    } else {
        static const int32_t half[3] = {32768, 32768, 32768};
        hd_g474_pwm_enable(false);
        hd_foc_reset(&foc);
        hd_g474_pwm_set(half);
    }
    foc_phase++;
    if (foc_phase >= HD_G474_FOC_PER_CTRL) {
        foc_phase = 0u;
        if (ssi_busy != 0u) {
            /* the last frame never completed (100 us for a 4.6 us transfer): run
             * that control period without the output encoder, read again next time */
            hd_g474_ssi_dma_abort();
            ssi_busy = 0u;
            latch_fast();
            control_period_start();
        } else {
            latch_fast();
            ssi_busy = 1u;
            hd_g474_ssi_dma_start(ssi_frame, HD_G474_SSI_BYTES);
        }
    }
}

/* flash wear of the NVM area (0x5102), persisted in the virtual NVM's sequence numbers */
static int32_t nvm_wear(void *ctx, uint32_t *total, uint32_t *max_page)
{
    (void)ctx;
    if (nvm_ok != 0) {
        return -1;
    }
    hd_vnvm_wear(&vnvm, total, max_page);
    return 0;
}

static bool co_send(void *ctx, const hd_can_frame_t *f)
{
    (void)ctx;
    return hd_hal_can_send(f);
}

void hd_g474_pendsv(void)
{
    hd_can_frame_t f;
    uint32_t n = 0u;
    /* at most one queue's worth per period: the control step stays bounded */
    while (n < HD_G474_CAN_RXQ && hd_hal_can_recv(&f)) {
        hd_co_process(&co, &f);
        n++;
    }
    hd_app_step(&app);
    hd_co_tick(&co, HD_CO_TICK_US);
    app_ran = 1u;
    hd_g474_iwdg_kick();
}

/* ---- main ---------------------------------------------------------------------------- */

int main(void)
{
    uint8_t raw[HD_G474_SSI_BYTES];
    hd_ssi_reading_t r;
    hd_g474_clock_init();
    hd_g474_gpio_init();
    hd_g474_pwm_init();                       /* outputs off (MOE = 0) */
    hd_g474_enc_init();
    hd_g474_spi_init();
    nvm_ok = hd_vnvm_open(&vnvm, &flash_if, HD_G474_VNVM_SIZE, HD_G474_VNVM_PAGE);
    (void)hd_foc_design(&foc_cfg, HD_G474_R_MOHM, HD_G474_L_NH, HD_G474_FOC_FC_HZ, (int32_t)HD_G474_PWM_HZ);
    hd_foc_reset(&foc);
    /* motor encoder start: the output encoder times N gives the motor's
     * single-turn angle at power-up (mod one motor turn) */
    {
        int64_t c0 = 0;
        if (hd_g474_ssi_read(raw, HD_G474_SSI_BYTES) == 0 &&
            hd_ssi_decode(raw, HD_G474_SSI_BYTES, 8u * HD_G474_SSI_BYTES, &r) == HD_SSI_OK) {
            /* motor turns = N * output turns: frac(N * pos / 2^24) in 2^17 counts */
            const uint64_t m = ((uint64_t)r.position * HD_G474_GEAR_N) & 0xFFFFFFu;
            c0 = (int64_t)(m >> (24u - HD_G474_MOTOR_ENC_BITS));
        }
        hd_enc_init(&menc, hd_g474_enc_raw(), c0, HD_G474_MOTOR_ENC_MAX_STEP);
    }
    cmd_buf[0].enable = 0u;
    cmd_idx = 0u;
    hd_app_init(&app);                        /* parameters from the flash store */
    (void)hd_g474_can_init();
    hd_g474_iwdg_init();
    HD_REG(SCB_SHPR3) = (HD_REG(SCB_SHPR3) & ~(0xFFu << 16)) | (0xF0u << 16);   /* PendSV lowest */
    hd_g474_nvic_enable(IRQ_FDCAN1_IT0, 1u);
    {
        /* CANopen: boot-up goes out now; the control period (PendSV) runs it */
        static const hd_app_co_port_t co_port = {0, co_send, 0, 0, 0, 0, 0, 0, nvm_wear, 0};   /* no object filter: every object */
        hd_app_co_init(&app_co, &co, &app, (uint8_t)HD_G474_NODE_ID, &co_port);
    }
    hd_g474_ssi_dma_init();                   /* from now on the output encoder is read by DMA */
    hd_g474_nvic_enable(IRQ_DMA1_CH1, 1u);
    hd_g474_nvic_enable(IRQ_ADC1_2, 0u);
    hd_g474_adc_init();                       /* conversions (and the 20 kHz interrupt) start */
    for (;;) {
        /* background below the control period (PendSV preempts it): the online friction
         * identification's queued steps, one part per call; sleep when none is left */
        if (!hd_app_background(&app)) {
            __asm__ volatile("wfi");
        }
    }
}
