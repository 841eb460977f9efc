/*
 * hd_co_402.c - CiA 402 drive profile on top of the CiA 301 services (hd_co.h).
 *
 * State machine (controlword 0x6040 -> statusword 0x6041):
 *   NOT READY -> SWITCH ON DISABLED (automatic at init)
 *   SOD  --shutdown 0x06-->  READY  --switch on 0x07-->  SWITCHED ON  --enable 0x0F-->  OPERATION ENABLED
 *   READY --0x0F--> OPERATION ENABLED (transitions 3+4 at once)
 *   OP --0x07--> SWITCHED ON, --0x06--> READY, --disable voltage--> SOD,
 *      --quick stop 0x02--> QUICK STOP ACTIVE --(standstill)--> SOD
 *   any state --fault--> FAULT REACTION ACTIVE --(power off)--> FAULT
 *   FAULT --rising edge of bit 7, cause gone--> SOD
 *   communication error (host heartbeat lost, bus-off) or an NMT command that ends
 *   the master's connection with the power stage on (stop, pre-operational from
 *   OPERATIONAL, reset communication, reset node), 0x6007 abort connection
 *   option code: 0 nothing, 1 (default) fault (as an app fault, EMCY 0x8130 /
 *   0x8140 / 0x8100), 2 disable voltage (-> SOD), 3 quick stop (-> QUICK STOP ACTIVE,
 *   then SOD at standstill); 2 and 3 need a new enable sequence, 1 a fault reset.
 *   NMT reset node also restarts the state machine with the power stage off.
 * Power is on only in OPERATION ENABLED and QUICK STOP ACTIVE.  In OPERATION
 * ENABLED the targets (0x607A, 0x60FF, 0x6071, offsets, profile) go to the app
 * every period; the actual values come back every period into the OD.
 *
 * Units: position 2^-24 turn at the output (i32), velocity 2^-32 turn/s,
 * torque 1/1000 of 0x6076 (mN.m, output side).
 *
 * The layer sits on top of the CiA 301 services: they call it only through the
 * hd_co_profile_if_t hooks at the end of this file, and it uses only hd_co.h (the
 * device's object data co->od, the app callbacks, hd_co_emcy / hd_co_emcy_clear).  Its
 * state is a hd_co402_t of the caller's (hd_co402_use).
 */
#include "hd_co_util.h"
#include "hd_co_402.h"
#include "hd_fixed.h"

#define CW_SO      0x0001u
#define CW_EV      0x0002u
#define CW_QS      0x0004u
#define CW_EO      0x0008u
#define CW_NEW_SP  0x0010u
#define CW_FR      0x0080u
#define CW_HALT    0x0100u

#define SW_RTSO    0x0001u
#define SW_SO      0x0002u
#define SW_OE      0x0004u
#define SW_FAULT   0x0008u
#define SW_VE      0x0010u
#define SW_QS      0x0020u
#define SW_SOD     0x0040u
#define SW_REMOTE  0x0200u
#define SW_TR      0x0400u
#define SW_ILA     0x0800u
#define SW_OMS1    0x1000u
#define SW_OMS2    0x2000u

static uint32_t check_mode(int64_t mode)
{
    switch (mode) {
    case HD_CO402_MODE_NONE:
    case HD_CO402_MODE_PP:
    case HD_CO402_MODE_CSP:
    case HD_CO402_MODE_CSV:
    case HD_CO402_MODE_CST:
    case HD_CO402_MODE_STAB:
        return 0u;
    default:
        return HD_CO_AB_VALUE;
    }
}

static int8_t mode_req(const hd_co_t *co) { return co->od.modes_of_operation; }

static bool power_on(hd_co_t *co, int8_t mode)
{
    if (co->app.drive_enable == NULL) {
        return true;
    }
    return co->app.drive_enable(co->app.ctx, mode, true) == 0u;
}

static void power_off(hd_co_t *co)
{
    if (co->app.drive_enable != NULL) {
        (void)co->app.drive_enable(co->app.ctx, co->od.modes_of_operation_display, false);
    }
}

static void enter(hd_co402_t *p, hd_co_t *co, uint8_t st)
{
    uint8_t old = p->state;
    bool was_on = old == HD_CO402_OP_ENABLED || old == HD_CO402_QUICK_STOP;
    bool on = st == HD_CO402_OP_ENABLED || st == HD_CO402_QUICK_STOP;
    if (on && !was_on) {
        int8_t m = mode_req(co);
        if (!power_on(co, m)) {
            return;                     /* refused by the app: stay */
        }
        co->od.modes_of_operation_display = m;
    } else if (!on && was_on) {
        power_off(co);
    }
    p->state = st;
    p->standstill_ticks = 0u;
}

static void fault(hd_co402_t *p, hd_co_t *co, uint16_t code)
{
    if (p->state == HD_CO402_FAULT || p->state == HD_CO402_FAULT_REACTION) {
        return;
    }
    p->fault_code = code;
    co->od.error_code = code;
    enter(p, co, HD_CO402_FAULT_REACTION);
}

static void comm_fault(hd_co402_t *p, hd_co_t *co, uint16_t emcy_code)
{
    p->comm_fault = 1u;
    fault(p, co, emcy_code);
}

static void abort_connection(hd_co402_t *p, hd_co_t *co, uint16_t emcy_code)
{
    switch (co->od.abort_connection_option_code) {
    case 1:                                   /* fault signal: fault reaction, app fault COMM */
        comm_fault(p, co, emcy_code);
        if (co->app.drive_comm_fault != NULL) {
            co->app.drive_comm_fault(co->app.ctx, emcy_code);
        }
        break;
    case 2:                                   /* disable voltage command */
        if (p->state == HD_CO402_READY || p->state == HD_CO402_SWITCHED_ON ||
            p->state == HD_CO402_OP_ENABLED || p->state == HD_CO402_QUICK_STOP) {
            enter(p, co, HD_CO402_SO_DISABLED);
        }
        break;
    case 3:                                   /* quick stop command */
        if (p->state == HD_CO402_OP_ENABLED) {
            enter(p, co, co->od.quick_stop_option_code == 0 ? HD_CO402_SO_DISABLED : HD_CO402_QUICK_STOP);
        } else if (p->state == HD_CO402_READY || p->state == HD_CO402_SWITCHED_ON) {
            enter(p, co, HD_CO402_SO_DISABLED);
        } else {
            /* already stopping, disabled or in fault */
        }
        break;
    default:                                  /* 0: no action */
        break;
    }
}

static bool powered(const hd_co402_t *p)
{
    const uint8_t st = p->state;
    return st == HD_CO402_OP_ENABLED || st == HD_CO402_QUICK_STOP || st == HD_CO402_FAULT_REACTION;
}

static void init(hd_co402_t *p, hd_co_t *co)
{
    hd_co_fill(p, 0u, sizeof *p);
    p->state = HD_CO402_NOT_READY;
    co->od.modes_of_operation_display = HD_CO402_MODE_NONE;
    co->od.statusword = 0u;
}

static void controlword(hd_co402_t *p, hd_co_t *co)
{
    uint16_t cw = co->od.controlword;
    bool fr_edge = (cw & CW_FR) != 0u && (p->cw_prev & CW_FR) == 0u;
    bool sp_edge = (cw & CW_NEW_SP) != 0u && (p->cw_prev & CW_NEW_SP) == 0u;
    p->cw_prev = cw;
    uint16_t c = (uint16_t)(cw & 0x008Fu);
    bool disable_voltage = (cw & CW_EV) == 0u;
    bool quick_stop = (cw & (CW_EV | CW_QS)) == CW_EV;
    bool shutdown = (c & 0x87u) == 0x06u;
    bool switch_on = (c & 0x8Fu) == 0x07u;
    bool enable_op = (c & 0x8Fu) == 0x0Fu;
    switch (p->state) {
    case HD_CO402_FAULT:
        if (fr_edge) {
            if (co->app.drive_fault_reset != NULL) {
                co->app.drive_fault_reset(co->app.ctx);
            }
            p->comm_fault = 0u;
            p->fault_pending_reset = 1u;   /* completes in tick when the cause is gone */
        }
        break;
    case HD_CO402_SO_DISABLED:
        if (shutdown) {
            enter(p, co, HD_CO402_READY);
        }
        break;
    case HD_CO402_READY:
        if (disable_voltage || quick_stop) {
            enter(p, co, HD_CO402_SO_DISABLED);
        } else if (switch_on) {
            enter(p, co, HD_CO402_SWITCHED_ON);
        } else if (enable_op) {
            enter(p, co, HD_CO402_SWITCHED_ON);
            enter(p, co, HD_CO402_OP_ENABLED);
        }
        break;
    case HD_CO402_SWITCHED_ON:
        if (disable_voltage || quick_stop) {
            enter(p, co, HD_CO402_SO_DISABLED);
        } else if (shutdown) {
            enter(p, co, HD_CO402_READY);
        } else if (enable_op) {
            enter(p, co, HD_CO402_OP_ENABLED);
        }
        break;
    case HD_CO402_OP_ENABLED:
        if (disable_voltage) {
            enter(p, co, HD_CO402_SO_DISABLED);
        } else if (quick_stop) {
            if (co->od.quick_stop_option_code == 0) {
                enter(p, co, HD_CO402_SO_DISABLED);
            } else {
                enter(p, co, HD_CO402_QUICK_STOP);
            }
        } else if (shutdown) {
            enter(p, co, HD_CO402_READY);
        } else if (switch_on) {
            enter(p, co, HD_CO402_SWITCHED_ON);
        }
        break;
    case HD_CO402_QUICK_STOP:
        if (disable_voltage) {
            enter(p, co, HD_CO402_SO_DISABLED);
        }
        break;
    default:
        break;
    }
    /* The new-set-point edge is latched here, at the write, not sampled by the tick: a host
     * (or two RPDOs) can set and clear bit 4 within one control period, and a sampled edge
     * would then be lost.  Only in OPERATION ENABLED (also when this write enabled it), so
     * an edge written while disabled never starts a move later. */
    if (sp_edge && p->state == HD_CO402_OP_ENABLED) {
        p->sp_pending = 1u;
    } else if (p->state != HD_CO402_OP_ENABLED) {
        p->sp_pending = 0u;
    }
}

static int32_t torque_permille_to_q16(int32_t permille, uint32_t rated_mNm)
{
    /* permille/1000 * rated/1000 N.m * 2^16 */
    int64_t num = (int64_t)permille * (int64_t)rated_mNm * 65536;
    return hd_sat32(hd_div64_rnd(num, 1000000));
}

static int16_t torque_q16_to_permille(int32_t q16, uint32_t rated_mNm)
{
    if (rated_mNm == 0u) {
        return 0;
    }
    int64_t v = hd_div64_rnd((int64_t)q16 * 1000000, (int64_t)rated_mNm * 65536);
    return (int16_t)hd_clamp64(v, -32768, 32767);
}

/* |following error| in 0x6065/0x6067 units (2^-24 turn), as unsigned */
static uint32_t fe_abs(const hd_co_t *co)
{
    const int32_t e = co->od.following_error_actual_value;
    return (e < 0) ? (uint32_t)(-(e + 1)) + 1u : (uint32_t)e;
}

/* true once cond has held for at least ms milliseconds (since_us = when it began) */
static bool held(const hd_co_t *co, bool cond, uint8_t *on, uint64_t *since_us, uint32_t ms)
{
    if (!cond) {
        *on = 0u;
        return false;
    }
    if (*on == 0u) {
        *on = 1u;
        *since_us = co->now_us;
    }
    return co->now_us - *since_us >= (uint64_t)ms * 1000u;
}

/* Following error (0x6065 window, 0x6066 time-out; window 0xFFFFFFFF = off): bit 13
 * once the error has been above the window for the time-out, in OPERATION ENABLED.
 * Target reached (0x6067 window, 0x6068 time): bit 10 once the generator is at rest
 * and the error has stayed within the window for the time. */
static void windows(hd_co402_t *p, hd_co_t *co)
{
    const uint32_t e = fe_abs(co);
    const bool fe_on = co->od.following_error_window != 0xFFFFFFFFu && p->state == HD_CO402_OP_ENABLED &&
                       e > co->od.following_error_window;
    p->following_error = held(co, fe_on, &p->fe_out, &p->fe_out_since_us, co->od.following_error_time_out) ? 1u : 0u;
    p->target_reached = held(co, co->act.at_rest != 0u && e <= co->od.position_window, &p->win_in,
                             &p->win_in_since_us, co->od.position_window_time) ? 1u : 0u;
}

static uint16_t statusword(const hd_co402_t *p, const hd_co_t *co)
{
    uint16_t sw;
    switch (p->state) {
    case HD_CO402_SO_DISABLED:   sw = SW_SOD; break;
    case HD_CO402_READY:         sw = SW_RTSO | SW_QS; break;
    case HD_CO402_SWITCHED_ON:   sw = SW_RTSO | SW_SO | SW_QS; break;
    case HD_CO402_OP_ENABLED:    sw = SW_RTSO | SW_SO | SW_OE | SW_QS; break;
    case HD_CO402_QUICK_STOP:    sw = SW_RTSO | SW_SO | SW_OE; break;
    case HD_CO402_FAULT_REACTION: sw = SW_RTSO | SW_SO | SW_OE | SW_FAULT; break;
    case HD_CO402_FAULT:         sw = SW_FAULT; break;
    default:                     sw = 0u; break;
    }
    if (co->act.power_enabled) {
        sw |= SW_VE;
    }
    sw |= SW_REMOTE;
    if (p->target_reached) {
        sw |= SW_TR;
    }
    if (co->act.internal_limit) {
        sw |= SW_ILA;
    }
    if (p->state == HD_CO402_OP_ENABLED) {
        int8_t m = co->od.modes_of_operation_display;
        if (m == HD_CO402_MODE_CSP || m == HD_CO402_MODE_CSV || m == HD_CO402_MODE_CST) {
            sw |= SW_OMS1;               /* drive follows the command value */
        } else if (m == HD_CO402_MODE_PP && (co->od.controlword & CW_NEW_SP) != 0u && p->sp_pending == 0u) {
            sw |= SW_OMS1;               /* set-point acknowledge: handed over, bit 4 still set */
        }
        if ((m == HD_CO402_MODE_PP || m == HD_CO402_MODE_CSP) && p->following_error != 0u) {
            sw |= SW_OMS2;               /* following error (0x6065 / 0x6066) */
        }
    }
    return sw;
}

static void tick(hd_co402_t *p, hd_co_t *co)
{
    hd_co_actual_t *a = &co->act;
    if (co->app.drive_actual != NULL) {
        co->app.drive_actual(co->app.ctx, a);
    }
    /* actual values into the OD */
    co->od.drive_status_loop_tick = a->tick;
    co->od.drive_status_load_phase = (uint32_t)((uint64_t)a->load_angle & 0xFFFFFFFFu);
    co->od.drive_status_motor_phase = (uint32_t)((uint64_t)a->motor_angle & 0xFFFFFFFFu);
    co->od.drive_status_load_velocity = a->load_velocity;
    co->od.drive_status_motor_velocity = a->motor_velocity;
    co->od.drive_status_motor_torque = a->motor_torque;
    co->od.drive_status_motor_current = a->motor_current;
    co->od.drive_status_setpoint_phase = (uint32_t)((uint64_t)a->setpoint_angle & 0xFFFFFFFFu);
    co->od.drive_status_load_angle = a->load_angle;
    co->od.drive_status_fault_code = a->fault_code;
    co->od.drive_status_uptime_ticks++;
    co->od.drive_status_power_enabled = a->power_enabled ? 1u : 0u;
    co->od.position_actual_value = hd_sat32(hd_asr64_rnd(a->load_angle, 8u));
    co->od.velocity_actual_value = a->load_velocity;
    co->od.torque_actual_value = torque_q16_to_permille(a->output_torque, co->od.motor_rated_torque);
    /* the same conversion: Q15.16 A -> 1/1000 of 0x6075 (mA) */
    co->od.current_actual_value = torque_q16_to_permille(a->motor_current, co->od.motor_rated_current);
    co->od.additional_position_actual_value_motor_encoder = hd_sat32(hd_asr64_rnd(a->motor_angle_out, 8u));
    co->od.following_error_actual_value = hd_sat32(hd_asr64_rnd(hd_sub64_sat(a->setpoint_angle, a->load_angle), 8u));
    windows(p, co);

    if (p->state == HD_CO402_NOT_READY) {
        enter(p, co, HD_CO402_SO_DISABLED);
    }
    /* app fault -> fault reaction */
    if (a->fault_code != 0u && p->state != HD_CO402_FAULT && p->state != HD_CO402_FAULT_REACTION) {
        uint8_t mfr[5] = {(uint8_t)(a->fault_code & 0xFFu), 0u, 0u, 0u, 0u};
        uint16_t code = a->fault_emcy != 0u ? a->fault_emcy : 0x1000u;
        fault(p, co, code);
        hd_co_emcy(co, code, HD_CO_ER_MFR, mfr);
    }
    if (p->state == HD_CO402_FAULT_REACTION) {
        power_off(co);
        p->state = HD_CO402_FAULT;
        p->fault_pending_reset = 0u;
    }
    if (p->state == HD_CO402_FAULT && p->fault_pending_reset) {
        if (a->fault_code == 0u && !p->comm_fault) {
            p->fault_pending_reset = 0u;
            p->fault_code = 0u;
            co->od.error_code = 0u;
            enter(p, co, HD_CO402_SO_DISABLED);
            hd_co_emcy_clear(co, (uint8_t)(HD_CO_ER_MFR | HD_CO_ER_COMM | HD_CO_ER_PROFILE));
        }
    }
    /* mode change while enabled */
    if (p->state == HD_CO402_OP_ENABLED && co->od.modes_of_operation != co->od.modes_of_operation_display) {
        int8_t m = mode_req(co);
        if (co->app.drive_enable == NULL || co->app.drive_enable(co->app.ctx, m, true) == 0u) {
            co->od.modes_of_operation_display = m;
        }
    } else if (p->state != HD_CO402_OP_ENABLED && p->state != HD_CO402_QUICK_STOP) {
        co->od.modes_of_operation_display = co->od.modes_of_operation;
    }
    /* setpoints */
    if (p->state == HD_CO402_OP_ENABLED || p->state == HD_CO402_QUICK_STOP) {
        hd_co_setpoint_t sp;
        hd_co_fill(&sp, 0u, sizeof sp);
        sp.mode = co->od.modes_of_operation_display;
        sp.quick_stop = p->state == HD_CO402_QUICK_STOP ? 1u : 0u;
        sp.halt = (co->od.controlword & CW_HALT) != 0u ? 1u : 0u;
        sp.pp_new = p->sp_pending;
        p->sp_pending = 0u;
        sp.target_position = co->od.target_position;
        sp.target_velocity = co->od.target_velocity;
        sp.velocity_offset = co->od.velocity_offset;
        sp.target_torque = hd_add_sat(torque_permille_to_q16(co->od.target_torque, co->od.motor_rated_torque),
                                      torque_permille_to_q16(co->od.torque_offset, co->od.motor_rated_torque));
        sp.quick_stop_decel = co->od.quick_stop_deceleration;
        sp.quick_stop_option = co->od.quick_stop_option_code;
        sp.halt_option = co->od.halt_option_code;
        if (co->app.drive_setpoint != NULL) {
            co->app.drive_setpoint(co->app.ctx, &sp);
        }
        if (p->state == HD_CO402_QUICK_STOP) {
            p->standstill_ticks = a->standstill ? p->standstill_ticks + 1u : 0u;
            if (p->standstill_ticks >= 10u) {
                enter(p, co, HD_CO402_SO_DISABLED);
            }
        }
    } else {
        p->sp_pending = 0u;              /* left OPERATION ENABLED (fault): the edge is void */
    }
    co->od.statusword = statusword(p, co);
}

/* ---- the hooks the CiA 301 services call (hd_co_profile_if_t) --------------------- */

static void h_init(void *ctx, hd_co_t *co)
{
    init((hd_co402_t *)ctx, co);
}

static uint32_t h_check_write(void *ctx, const hd_co_t *co, uint16_t index, uint8_t sub, int64_t v)
{
    (void)ctx;
    (void)co;
    (void)sub;
    return (index == 0x6060u) ? check_mode(v) : 0u;
}

static void h_after_write(void *ctx, hd_co_t *co, uint16_t index, uint8_t sub)
{
    (void)sub;
    if (index == 0x6040u) {
        controlword((hd_co402_t *)ctx, co);
    }
}

static void h_tick(void *ctx, hd_co_t *co)
{
    tick((hd_co402_t *)ctx, co);
}

/* 0x6007 reaction to a communication error (heartbeat lost, bus-off) */
static void h_comm_error(void *ctx, hd_co_t *co, uint16_t emcy_code)
{
    abort_connection((hd_co402_t *)ctx, co, emcy_code);
}

/* 0x6007 reaction to an NMT command that ends the master's connection, with the power
 * stage on only; true when the reaction was the fault */
static bool h_nmt_leave(void *ctx, hd_co_t *co)
{
    hd_co402_t *p = ctx;
    if (p->state == HD_CO402_FAULT_REACTION || !powered(p)) {
        return false;
    }
    abort_connection(p, co, HD_CO_EMCY_COMM);
    return p->state == HD_CO402_FAULT_REACTION || p->state == HD_CO402_FAULT;
}

/* NMT reset node: the power stage off now, the state machine from NOT READY TO SWITCH ON */
static void h_restart(void *ctx, hd_co_t *co)
{
    hd_co402_t *p = ctx;
    /* the fault latched by 0x6007 = 1 (or a lost heartbeat) is the host's to reset: a
     * restart of the application does not clear it */
    const bool latched = p->comm_fault != 0u;
    const uint16_t code = p->fault_code;
    if (powered(p)) {
        power_off(co);                      /* no quick stop ramp survives a restart */
    }
    init(p, co);
    if (latched) {
        comm_fault(p, co, code);
    }
}

static bool h_faulted(void *ctx, const hd_co_t *co)
{
    const hd_co402_t *p = ctx;
    (void)co;
    return p->state == HD_CO402_FAULT || p->state == HD_CO402_FAULT_REACTION;
}

static const hd_co_profile_if_t profile_402 = {
    h_init, h_check_write, h_after_write, h_tick, h_comm_error, h_nmt_leave, h_restart, h_faulted
};

void hd_co402_use(hd_co402_t *p, hd_co_app_if_t *app)
{
    hd_co_fill(p, 0u, sizeof *p);
    app->profile = &profile_402;
    app->profile_ctx = p;
}

uint8_t hd_co402_state(const hd_co402_t *p)
{
    return p->state;
}
