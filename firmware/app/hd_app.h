/*
 * hd_app.h - the drive application: one control period per hd_app_step().
 *
 * Contract
 * --------
 * The application is ONE statically sized struct (hd_app_t, no malloc, no
 * globals): the port owns it (static storage on the MCU, a field of the
 * harness on the PC) and calls
 *     hd_app_init(&app)   once at power-up (loads the parameter store from
 *                         NVM through hal.h; falls back to defaults, status in
 *                         app.pstore_status);
 *     hd_app_step(&app)   once per control period (100 us): reads the sensor
 *                         sample through hd_hal_read_sensors(), unwraps the
 *                         encoders, runs the velocity observers, the mode
 *                         logic (trajectory / excitation), the cascade
 *                         position -> velocity -> torque, the torque filters,
 *                         limits and faults, and writes the torque command
 *                         through hd_hal_write_command(); records capture and
 *                         refreshes app.tel.
 * Between steps the harness or the CANopen layer (same thread / same core, not
 * from an interrupt during a step) uses the command API below; commands take
 * effect at the next step.
 *
 * Signals: output angle Q32.32 turns (from the 24-bit absolute encoder minus
 * output_enc_zero, in [-0.5, 0.5) turn at power-up, then unwrapped); motor
 * angle Q32.32 motor turns (17-bit encoder, unwrapped, initialised to
 * N * output angle + its own fraction); velocities 2^-32 turn/s at the output
 * (motor: 2^-24 turn/s); the cascade's torque is OUTPUT-side torque Q15.16 N.m,
 * divided by N for the motor command (hal) and by Kt for the current.
 *
 * Modes (hd_app_set_mode; entering a closed-loop mode is bumpless: references
 * start at the measured position / zero velocity):
 *   OFF         power stage off, torque 0
 *   TORQUE      output torque = torque reference (+ excitation if injected)
 *   VELOCITY    velocity loop on the velocity reference
 *   POSITION    position + velocity loops on the position reference (direct,
 *               no trajectory; velocity/torque feed-forward references optional)
 *   PTP         jerk-limited point-to-point move to the target (hd_app_move_to)
 *   RATE        constant-rate move (hd_app_set_rate), down to 0.0001 deg/s
 *   SINE        sinusoid about the position at entry (hd_app_set_sine)
 *   EXCITATION  the excitation generator injected at torque (open loop), at
 *               the velocity reference (velocity loop), added to the held
 *               position reference (position loop) or added to the torque
 *               feed-forward of the position loop holding the position
 *   STAB        inertial stabilisation (hd_stab.h): hold the payload's inertial
 *               angle from the payload rate gyro.  The position loop (gains
 *               stab_kp/stab_ki) runs on the inertial-angle error (reference -
 *               integrated gyro), its velocity feed-forward is the commanded
 *               inertial rate minus the base-rate estimate, so the velocity
 *               loop (motor encoder) moves the payload relative to the base
 *               against the base motion.  vel_cmd (hd_app_set_velocity) is the
 *               commanded inertial rate; needs a valid gyro (else SENSOR fault)
 * A latched fault forces OFF behaviour until hd_app_fault_reset() and a new
 * set_mode(); set_mode() other than OFF is refused (-1) while faulted.
 */
#ifndef HD_APP_H
#define HD_APP_H

#include <stdint.h>
#include "hd_units.h"
#include "hal.h"
#include "hd_param_table.h"
#include "hd_param_store.h"
#include "hd_table_store.h"
#include "hd_pid.h"
#include "hd_vel_observer.h"
#include "hd_biquad.h"
#include "hd_trajectory.h"
#include "hd_excitation.h"
#include "hd_capture.h"
#include "hd_comp_bank.h"
#include "hd_stab.h"
#include "hd_feedback.h"

typedef enum {
    HD_MODE_OFF = 0,
    HD_MODE_TORQUE = 1,
    HD_MODE_VELOCITY = 2,
    HD_MODE_POSITION = 3,
    HD_MODE_PTP = 4,
    HD_MODE_RATE = 5,
    HD_MODE_SINE = 6,
    HD_MODE_EXCITATION = 7,
    HD_MODE_STAB = 8
} hd_mode_t;

typedef enum {
    HD_INJ_TORQUE = 0,    /* excitation = output torque (open loop) */
    HD_INJ_VEL_REF = 1,   /* excitation = velocity reference, 2^-32 turn/s */
    HD_INJ_POS_REF = 2,   /* excitation added to the held position, 2^-32 turn */
    HD_INJ_TORQUE_FF = 3  /* excitation added to the torque feed-forward, Q15.16 N.m,
                           * while the position loop holds the position at entry */
} hd_inj_t;

/* Fault codes (latched; the first one is kept). */
typedef enum {
    HD_FAULT_NONE = 0,
    HD_FAULT_TORQUE_SAT = 1,    /* torque command saturated longer than torque_sat_time */
    HD_FAULT_OVERSPEED = 2,     /* |output velocity| > vel_trip */
    HD_FAULT_TRAVEL = 3,        /* output angle outside [travel_min, travel_max] */
    HD_FAULT_FOLLOWING = 4,     /* |position error| > follow_err_max (position modes) */
    HD_FAULT_ENC_JUMP = 5,      /* output encoder step > enc_jump_max in one period */
    HD_FAULT_SENSOR = 6,        /* a needed sensor flagged invalid */
    HD_FAULT_PARAM = 7,         /* parameters inconsistent at apply (should not happen) */
    HD_FAULT_COMM = 8           /* communication: host heartbeat lost (raised by the CANopen adapter) */
} hd_fault_t;

/* Fault-check enable bits (parameter fault_enable). */
#define HD_FCHK_TORQUE_SAT  (1u << 0)
#define HD_FCHK_OVERSPEED   (1u << 1)
#define HD_FCHK_TRAVEL      (1u << 2)
#define HD_FCHK_FOLLOWING   (1u << 3)
#define HD_FCHK_ENC_JUMP    (1u << 4)
#define HD_FCHK_SENSOR      (1u << 5)

/* Capture signal ids (each one int32 word per frame). */
typedef enum {
    HD_SIG_TICK = 0,          /* loop tick */
    HD_SIG_POS_OUT_LO = 1,    /* output angle, low word of Q32.32 (2^-32 turn, wraps) */
    HD_SIG_POS_OUT_HI = 2,    /* output angle, whole turns */
    HD_SIG_POS_MOT_LO = 3,    /* motor angle, low word (2^-32 motor turn, wraps) */
    HD_SIG_POS_MOT_HI = 4,    /* motor angle, whole motor turns */
    HD_SIG_VEL_OUT = 5,       /* output velocity estimate, 2^-32 turn/s */
    HD_SIG_VEL_MOT = 6,       /* motor velocity estimate, 2^-24 turn/s */
    HD_SIG_POS_REF_LO = 7,    /* position reference, low word */
    HD_SIG_POS_REF_HI = 8,
    HD_SIG_VEL_REF = 9,       /* velocity reference, 2^-32 turn/s */
    HD_SIG_ACC_REF = 10,      /* acceleration reference, 2^-24 turn/s^2 */
    HD_SIG_TORQUE_CMD = 11,   /* output torque command, Q15.16 N.m */
    HD_SIG_CURRENT = 12,      /* measured current, Q15.16 A */
    HD_SIG_GYRO = 13,         /* payload gyro, 2^-32 turn/s */
    HD_SIG_EXC = 14,          /* excitation value, injection format */
    HD_SIG_POS_ERR = 15,      /* position error, 2^-32 turn (saturated) */
    HD_SIG_FAULT = 16,        /* fault code */
    HD_SIG_COUNT = 17
} hd_sig_t;

/* Standstill hunt breaker: running mean of the Stribeck FF, a one-pole low-pass of
 * 2^-HD_INPOS_TAU_SHIFT per period (2^-9: 51 ms at 10 kHz). */
#define HD_INPOS_TAU_SHIFT 9u

typedef struct {
    uint32_t     tick;        /* periods since hd_app_init */
    int32_t      mode;        /* hd_mode_t */
    int32_t      fault;       /* hd_fault_t */
    hd_angle_t   pos_out;     /* output angle, Q32.32 turns */
    hd_angle_t   pos_mot;     /* motor angle, Q32.32 motor turns */
    hd_vel_out_t vel_out;     /* velocity estimate used by the loop, 2^-32 turn/s (output) */
    hd_vel_out_t vel_out_enc; /* output-encoder observer, 2^-32 turn/s (0 while it is off:
                               * it runs for vel_fb_src 1 in full closed and in STAB) */
    hd_vel_mot_t vel_mot;     /* motor-encoder observer, 2^-24 turn/s */
    hd_angle_t   pos_ref;     /* position reference, Q32.32 turns */
    hd_vel_out_t vel_ref;     /* velocity reference into the velocity loop, 2^-32 turn/s */
    hd_acc_t     acc_ref;     /* acceleration reference (feed-forward), 2^-24 turn/s^2 */
    hd_torque_t  torque_cmd;  /* output torque command after filters and limit, Q15.16 N.m */
    hd_torque_t  motor_torque;/* motor torque command sent to hal, Q15.16 N.m */
    hd_current_t current;     /* measured current, Q15.16 A */
    hd_vel_out_t gyro;        /* payload gyro, 2^-32 turn/s */
    int32_t      exc;         /* excitation value */
    int32_t      pos_err;     /* pos_ref - loop position feedback, 2^-32 turn (saturated) */
    hd_angle_t   pos_fb;      /* loop position feedback (fb_config: output encoder, motor-side
                               * estimate or their blend), Q32.32 turns */
} hd_telemetry_t;

typedef struct {
    /* derived controller configs (from param by hd_app_apply_params) */
    hd_pid_cfg_t pos_cfg, vel_cfg;
    hd_velobs_cfg_t obs_mot_cfg, obs_out_cfg;
    hd_biquad_chain_cfg_t filt_cfg;
    hd_traj_cfg_t traj_cfg;
    hd_angle_t travel_min_q;      /* travel limits as Q32.32 turns (travel_min/max x 2^8, saturated) */
    hd_angle_t travel_max_q;
    int64_t      aff_k;           /* acceleration FF gain aff_gain j_total 2 pi, N.m per turn/s^2 in Q32.32 */

    /* controller state */
    hd_pid_t pos_pid, vel_pid;
    hd_velobs_t obs_mot, obs_out;    /* obs_mot.err is not kept (hd_velobs_step_vel_inline): nothing reads it */
    uint32_t obs_out_fb;          /* 1: the velocity loop's feedback is the output-encoder observer
                                   * (vel_fb_src 1 in full closed; set in the parameter-set path) */
    uint32_t obs_out_run;         /* 1: the output-encoder observer ran last period */
    hd_biquad_chain_t filt;
    hd_traj_t traj;
    hd_exc_t exc;
    hd_exc_cfg_t exc_cfg;
    int32_t  exc_inj;             /* hd_inj_t */

    /* sensor unwrapping */
    uint32_t   started;           /* 0 until the first sensor sample */
    uint32_t   mot_raw_prev, out_raw_prev;
    hd_angle_t pos_mot, pos_out;

    /* mode, references */
    int32_t      mode, mode_req;
    uint32_t     mode_changed;
    hd_angle_t   pos_cmd;         /* POSITION mode reference, Q32.32 turns */
    hd_vel_out_t vel_cmd;         /* VELOCITY mode reference / POSITION feed-forward */
    hd_torque_t  torque_cmd;      /* TORQUE mode reference / feed-forward, output Q15.16 N.m */
    hd_angle_t   ptp_target;
    hd_vel_out_t rate_cmd;
    int32_t      sine_amp, sine_f_q16;
    hd_angle_t   hold_pos;        /* excitation: held position */

    /* standstill hunt breaker (params hold_*; hd_app.c header comment) */
    hd_angle_t   inpos_ref_prev;  /* position reference (before the bank) of the last period */
    uint32_t     inpos_n;         /* periods at rest (saturates at hold_ticks) */
    uint32_t     inpos_on;        /* 1 = breaking a hunt: the Stribeck FF fading to its mean */
    int64_t      inpos_tau;       /* running mean of the Stribeck FF, Q15.16 N.m x 2^16 */
    int32_t      inpos_w;         /* weight of the Stribeck FF about its mean, Q30 (1 = full FF) */
    int32_t      inpos_dw;        /* its step per period, Q30 (= 2^30 / hold_fade_ticks) */

    /* faults */
    int32_t  fault;
    uint32_t sat_count;

    hd_telemetry_t tel;

    /* inertial stabilisation (mode STAB; parameters stab_*) */
    hd_pid_cfg_t stab_pos_cfg;
    hd_stab_cfg_t stab_cfg;
    hd_stab_t stab;
    uint32_t stab_primed;         /* 0: hd_stab_start() at the next STAB period */

    /* feedback configuration of the position loop (parameters fb_*; hd_feedback.h) */
    hd_fb_cfg_t fb_cfg;
    hd_fb_t fb;

    /* compensator bank (hd_comp_bank.h; parameters cb_*, str_*, lug_*, mx_*, pr_*, te_*, bs_*, dob_*) */
    uint32_t cb_idle;             /* 1: no compensator of hd_comp_bank_pre enabled or ramping and every
                                   * held correction 0, so the period skips it (set in the
                                   * parameter-set path, cleared there, re-checked while ramping out) */
    uint32_t bs_idle;             /* 1: backstepping off and not ramping: hd_comp_bank_post is skipped */
    uint32_t fe_idle;             /* 1: online Stribeck identification off and not feeding: its slow
                                   * slot is skipped (both set like cb_idle) */
    hd_comp_bank_cfg_t cb_cfg;
    /* parameters (raw, see hd_param_table.h) and their store: behind the period's fields (the
     * period reads the derived configs, not these), so a parameter added to the table moves
     * none of them toward the end of the short load / store offsets */
    int32_t  param[HD_PARAM_COUNT];
    uint32_t pstore_seq;
    int32_t  pstore_status;       /* hd_pstore_status_t of the last load */
    /* the Preisach table's store (hd_table_store.h) */
    uint32_t tstore_seq;
    int32_t  tstore_status;       /* hd_tstore_status_t of the boot load */
    uint32_t tstore_sync;         /* 1 if the NVM holds the table in force (or "none" and none) */
    hd_comp_bank_t cb;

    /* capture, last: its sample buffer (32 KiB) and the bank's Preisach table (at the end
     * of hd_comp_bank_t) would push the period's fields above out of the Cortex-M4's
     * short load / store offsets (12 bits): each access past them needs an extra add */
    hd_capture_t cap;
    uint32_t cap_sig[HD_CAPTURE_MAX_CH];
} hd_app_t;

/** Power-up: load parameters (NVM or defaults), reset everything, mode OFF. */
void hd_app_init(hd_app_t *a);
/** One control period (see the contract above). */
void hd_app_step(hd_app_t *a);
/** Background work below the control period: one part of the online Stribeck
 *  identification's queued steps (hd_comp_bank_fric_est_work, at most a few hundred
 *  instructions); true while work is left.  The port calls it from its main loop, the
 *  simulator after every period until it returns false. */
bool hd_app_background(hd_app_t *a);

/* ---- command API (harness, CANopen) ------------------------------------ */
/** Request a mode; 0 ok, -1 refused (faulted and mode != OFF, or bad mode). */
int32_t hd_app_set_mode(hd_app_t *a, int32_t mode);
/** TORQUE reference / feed-forward in closed-loop modes, output Q15.16 N.m. */
void hd_app_set_torque(hd_app_t *a, hd_torque_t t);
/** VELOCITY reference (and velocity feed-forward in POSITION), 2^-32 turn/s. */
void hd_app_set_velocity(hd_app_t *a, hd_vel_out_t v);
/** POSITION reference, Q32.32 turns. */
void hd_app_set_position(hd_app_t *a, hd_angle_t p);
/** PTP target (used on entry to PTP, or immediately if already in PTP and at rest). 0 ok, -1 moving. */
int32_t hd_app_move_to(hd_app_t *a, hd_angle_t target);
/** Halt (CiA 402 controlword bit 8 in profile position): in PTP / RATE the running
 *  trajectory ramps its velocity to 0 at amax (2^-24 turn/s^2, > 0: the caller's
 *  choice, traj amax or a quick-stop deceleration; hd_traj_stop) and ends in HOLD at
 *  the position where it came to rest; a pending final-approach leg is dropped.  The
 *  axis stays there until the next hd_app_move_to().  No effect in the other modes or
 *  when the trajectory is already at rest. */
void hd_app_halt(hd_app_t *a, hd_acc_t amax);
/** RATE: constant output rate, 2^-32 turn/s (takes effect at once in RATE mode). */
void hd_app_set_rate(hd_app_t *a, hd_vel_out_t v);
/** SINE: amplitude 2^-32 turn, frequency Q16.16 Hz (used on entry to SINE). */
void hd_app_set_sine(hd_app_t *a, int32_t amp, int32_t f_q16);
/** EXCITATION: generator config and injection point (used on entry to EXCITATION). 0 ok, -1 bad cfg. */
int32_t hd_app_set_excitation(hd_app_t *a, const hd_exc_cfg_t *c, int32_t inj);
/** Clear a latched fault (mode becomes OFF). */
void hd_app_fault_reset(hd_app_t *a);
/** Raise (latch) a fault from outside the control step, e.g. HD_FAULT_COMM: the
 *  power stage goes off at the next step; only hd_app_fault_reset() clears it.
 *  The first fault is kept.  -1 for code <= HD_FAULT_NONE or unknown. */
int32_t hd_app_fault_raise(hd_app_t *a, int32_t code);

/** Set one parameter (raw); applied at once. 0 ok, -1 unknown id / out of range, or a
 *  change of fb_config while the mode is not OFF (old value kept). */
int32_t hd_app_param_set(hd_app_t *a, uint32_t id, int32_t raw);
/** Get one raw parameter (0 for an unknown id). */
int32_t hd_app_param_get(const hd_app_t *a, uint32_t id);
/** Save all parameters to NVM (refused with -1 unless mode OFF). */
int32_t hd_app_param_save(hd_app_t *a);
/** Recompute the controller configs from a->param. 0 ok, -1 inconsistent.  The bank's
 *  enable switches and the skip flags (cb_idle, bs_idle, fe_idle) follow in
 *  hd_app_param_set: change parameters through it. */
int32_t hd_app_apply_params(hd_app_t *a);

/** Arm the capture of n_ch signals (hd_sig_t ids in sig[]) with cfg. 0 ok, -1 bad. */
int32_t hd_app_capture_arm(hd_app_t *a, const hd_capture_cfg_t *c, const uint32_t *sig);
/** Command trigger for the capture. */
void hd_app_capture_trigger(hd_app_t *a);

/** Install a Preisach table image for the compensator bank (checked; the old one
 *  stays on error). HD_PREISACH_OK (0) or an HD_PREISACH_E_* code.  The table is in
 *  RAM until hd_app_store_all(). */
int32_t hd_app_comp_table(hd_app_t *a, const hd_preisach_table_t *t);
/** Drop the Preisach table in force (restore of the defaults: no table). */
void hd_app_comp_table_clear(hd_app_t *a);
/** Save the parameters and, if it changed since the last load or save, the Preisach
 *  table in force (or "no table") to NVM; only with the power stage off.  0 ok, -1
 *  refused or failed (what was not written keeps its old NVM content). */
int32_t hd_app_store_all(hd_app_t *a);
/** 1 if hd_app_store_all() would write anything (parameters other than the newest saved
 *  set, or a table in force other than the saved one), 0 if it would write nothing. */
int32_t hd_app_store_pending(const hd_app_t *a);

/** The position at which entering a closed-loop position mode now starts the references
 *  (the loop's position feedback: the output encoder in full closed and dual-loop, the
 *  motor-side estimate in semi-closed), Q32.32 turns; for bumpless targets of a master. */
hd_angle_t hd_app_entry_position(const hd_app_t *a);

/** Latest telemetry (also available as a->tel). */
const hd_telemetry_t *hd_app_telemetry(const hd_app_t *a);

#endif
