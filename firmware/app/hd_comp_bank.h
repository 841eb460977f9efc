/*
 * hd_comp_bank.h - every compensator of firmware/core composed for the drive
 * application: configs from the parameter table, enable bits with bumpless
 * ramps, and the two calls that hd_app_step() makes inside the cascade.
 *
 * Where each compensator acts (full-closed loop: position on the output
 * encoder, velocity on the motor encoder / N; docs/compensators.md section 8):
 *
 *   pos_ref --> position PI (feedback: fb_config, hd_feedback.h) --> vel_ref
 *                 (+ dvel: d/dt of the position corrections in full closed)
 *   vel_ref --> velocity PI --(+ tff: Stribeck / LuGre / DOB / TE torque)--> backstepping blend --> filters
 *
 *   Stribeck   torque FF, velocity = w_ref v_ref + (1 - w_ref) v_fb              -> tff
 *   LuGre      torque FF/observer, v = v_ref or v_fb, e = pos_out - pos_ref      -> tff
 *   Maxwell    x = pos_ref; lost-motion twist F / K                             -> position correction
 *   Preisach   the gear twist at the transmitted-torque estimate from the table:
 *              a torque -> twist image (HD_PREISACH_UNIT_TORQUE_TWIST) runs
 *              forward, a twist -> torque image (other units: the gear's own
 *              direction, what hdservo identify and compsetup write) through
 *              its inverse; the estimate is
 *              low-passed at pr_fc:
 *                pr_t_src 1 (model): (1 - share) Stribeck(v_ref) + J_L a_ref
 *                           + mgl cos(2 pi (pos_out + g_off)) (load-side friction, load
 *                           inertia and the unbalance it holds: what the gear must transmit)
 *                pr_t_src 2 (motor side while it slides, hd_gear_torque.h): t_prev
 *                           - share Stribeck - N^2 J_m a_fb, handed over to the model of
 *                           pr_t_src 1 between 2 vs and vs of the reference speed (the
 *                           swings of a move set the gear's hysteresis branch)
 *                pr_t_src 0 (command): t_prev - share Stribeck(v_ref) (contains the
 *                           loop's own reaction; kept for comparison)       -> position correction
 *   TE         -TE(motor angle) - TE_out(pos_out: the loop's output position, in
 *              semi-closed the motor-side estimate)                             -> position correction
 *              (+ optional torque FF -K1 TE -> tff)
 *   compliance twist of the three-slope stiffness (hd_compliance.h) at the
 *              transmitted-torque estimate of the Preisach inverse (same
 *              pr_t_src / pr_fc; the estimate runs when either is on)   -> position correction
 *   online Stribeck identification (fe_enable; hd_fric_est.h) from the slow slot
 *              hd_comp_bank_fric_est(): with fe_feed its estimate replaces the
 *              Stribeck FF parameters (ramped, bumpless)
 *   backstep   replaces the PID's torque: u = u_pid + w (u_bs - u_pid); preloaded at engage
 *   DOB        d = Q(t_prev - J s v_fb), Q = g/(s+g) first order; torque FF + d
 *   pos. I     scheduled position integral (cb_pki > 0): a second integrator of the
 *              position error whose gain is weighted by a smooth (C1 cubic) schedule
 *              w(|v_ref|), 0 below cb_pki_vlo, 1 above cb_pki_vhi:
 *                I += w Ki T e - (1 - w) leak T I,  |I| <= cb_pki_max        -> dvel
 *              It raises the loop's low-frequency gain during sliding motion and
 *              hands back to the plain cascade near standstill and at very slow
 *              rates, where the drive sits in presliding friction: there the
 *              bristle stiffness closes a loop through three integrators (position I,
 *              velocity I) with little phase margin and it hunts (stick-slip limit
 *              cycle; docs/compensators.md section 8).  Reset with the loops (the app
 *              clears dpos_primed).
 *
 * The position corrections sum to dpos (Q32.32 turns, output-referred
 * motor-side lead = predicted motor angle / N - output angle).  In full closed
 * (fb_config 0, the default) dpos is low-passed at cb_dpos_fc and its
 * per-period difference is the velocity feed-forward dvel: the motor travels
 * the lost motion / TE ahead of the output while the position loop keeps the
 * OUTPUT on the reference.  In semi-closed and dual-loop (fb_config 1, 2) dpos
 * is returned as it is (out.dpos) and the app subtracts it from the motor
 * angle / N: the predicted output position the loop closes on (hd_feedback.h).
 *
 * Rates (hd_sched.h): the scheduled position integral, the Stribeck feed-forward, the
 * DOB and the corrections' filter run every period; LuGre, TE, Maxwell-slip, the
 * torque estimate, the compliance twist and the Preisach twist once per cycle of
 * HD_SCHED_CYCLE periods, each in its own slot (the Preisach inverse's bisection
 * spread over three slots), outputs held or linearly extrapolated between updates.
 *
 * Switching: cb_enable bits (HD_CB_*).  A change of a bit calls the
 * compensator's set_enabled(): its output weight ramps over cb_ramp_ticks
 * periods (hd_blend).  A compensator is evaluated while enabled or ramping
 * out; fully off it costs nothing and keeps its last state (LuGre bristles,
 * Maxwell elements, Preisach memory re-converge within the presliding
 * distance after an enable; the ramp covers it; the DOB restarts from 0).
 * Backstepping is preloaded (hd_backstep_preload) with the PID output of the
 * period it is switched on.  The bank acts in the position modes only.
 *
 * Formats: those of hd_units.h and of each core header; parameters are the
 * raw words of hd_param_table.h (docs/parameters.md, index 0x2800-0x2870).
 * The Preisach table (hd_preisach_table_t image, 8.3 KiB) is installed with
 * hd_comp_bank_install_table(), which checks it and keeps the old one on error.
 */
#ifndef HD_COMP_BANK_H
#define HD_COMP_BANK_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_units.h"
#include "hd_param_table.h"
#include "hd_stribeck.h"
#include "hd_lugre.h"
#include "hd_maxwell.h"
#include "hd_preisach.h"
#include "hd_te_comp.h"
#include "hd_backstep.h"
#include "hd_blend.h"
#include "hd_compliance.h"
#include "hd_gear_torque.h"
#include "hd_fric_est.h"
#include "hd_sched.h"

#define HD_CB_STRIBECK  (1u << 0)
#define HD_CB_LUGRE     (1u << 1)
#define HD_CB_MAXWELL   (1u << 2)
#define HD_CB_PREISACH  (1u << 3)
#define HD_CB_TE        (1u << 4)
#define HD_CB_BACKSTEP  (1u << 5)
#define HD_CB_DOB       (1u << 6)
#define HD_CB_ALL       0x7Fu
/* cb_enable bit 7 is not a bank compensator: the one-direction final approach of
 * PTP moves (hd_trajectory.h, parameters appr_*), read by hd_app; the bank ignores it. */
#define HD_CB_APPROACH  (1u << 7)
/* cb_enable bit 8: the compliance twist (parameters cp_*), a position correction. */
#define HD_CB_COMPLIANCE 0x100u

typedef struct {
    hd_stribeck_cfg_t str;
    hd_lugre_cfg_t    lug;
    hd_maxwell_cfg_t  mx;
    hd_te_cfg_t       te;
    hd_te_cfg_t       te_out;    /* output-side TE lines (per output revolution; k1 0) */
    hd_backstep_cfg_t bs;
    int32_t  bs_th0[HD_BS_NP];   /* Q15.16 initial estimates */
    hd_compliance_cfg_t cp;
    uint32_t enable;             /* HD_CB_* */
    uint32_t ramp_ticks;
    uint32_t pos_mode;           /* 0 velocity FF (full closed), 1 raw dpos for the feedback estimate (fb_config 1, 2) */
    int32_t  dpos_alpha;         /* Q30, 1 - exp(-2 pi fc T) */
    uint32_t pr_deadband;
    int32_t  pr_alpha;           /* Q30, at the slow rate HD_SCHED_SLOW_HZ */
    int32_t  pr_share;           /* Q30 */
    uint32_t lug_v_src;          /* 0 reference, 1 estimate */
    int32_t  dob_g_t;            /* Q30, 1 - exp(-g T) at the slow rate HD_SCHED_SLOW_HZ (first-order Q filter) */
    int32_t  dob_gj;             /* g J: N.m per (turn/s), Q15.16 */
    uint32_t pr_t_src;           /* Preisach torque estimate: 0 command - share F, 1 model (1 - share) F + J_L a */
    int32_t  pr_jl;              /* load inertia for pr_t_src 1, Q15.16 kg m^2 */
    int32_t  pr_mgl;             /* unbalance for pr_t_src 1, Q15.16 N.m (0 = none) */
    uint32_t pr_g_off;           /* its angle offset, 2^-32 turn (wraps) */
    hd_gear_torque_cfg_t gt;     /* pr_t_src 2: motor-side estimate (pr_jm, the Stribeck FF's vs) */
    int32_t  pki;                /* scheduled position integral gain, Q15.16 1/s^2 (0 = off) */
    int32_t  pki_vlo;            /* schedule: weight 0 at |v_ref| <= vlo, 2^-32 turn/s */
    int32_t  pki_vhi;            /* schedule: weight 1 at |v_ref| >= vhi, 2^-32 turn/s */
    int32_t  pki_leak_dt;        /* leak rate x T, Q30 (applied with weight 1 - w) */
    int32_t  pki_max;            /* integral clamp, 2^-32 turn/s */
    hd_fric_est_cfg_t fe;        /* online Stribeck identification (parameters fe_*) */
    uint32_t fe_on;              /* 1: the estimator runs (fe_enable) */
    uint32_t fe_feed;            /* 1: the Stribeck FF uses the estimate (fe_feed, with fe_on) */
    int32_t  fe_share;           /* share of the estimated levels fed, Q16 (fe_share) */
    uint32_t fe_decim;           /* control periods per estimator step */
    uint32_t fe_ramp;            /* estimator steps of the feed ramp */
} hd_comp_bank_cfg_t;

/* Signals of one period (inputs filled by the app). */
typedef struct {
    hd_angle_t   pos_ref;        /* output position reference, Q32.32 turns */
    hd_angle_t   pos_out;        /* output position (output encoder) */
    hd_angle_t   pos_mot;        /* motor angle, Q32.32 motor turns */
    hd_vel_out_t vel_ref;        /* velocity feed-forward of the reference, 2^-32 turn/s */
    hd_vel_out_t vel_fb;         /* velocity-loop feedback, 2^-32 turn/s */
    hd_acc_t     acc_ref;        /* 2^-24 turn/s^2 */
} hd_comp_bank_in_t;

typedef struct {
    hd_angle_t   dpos;           /* predicted motor / N - output (fb_config 1, 2), else 0 */
    hd_vel_out_t dvel;           /* added to the velocity feed-forward (position corrections in full closed; scheduled position I) */
    hd_torque_t  tff;            /* torque feed-forward, Q15.16 N.m */
} hd_comp_bank_out_t;

/* A slow position correction between its updates (hd_sched.h): the last sample,
 * extrapolated linearly by the change of the last cycle. */
typedef struct {
    int64_t  v;                  /* value of this tick, 2^-32 turn */
    int64_t  last;               /* last sample */
    int64_t  inc;                /* per-tick increment: last change / HD_SCHED_CYCLE */
    uint32_t primed;             /* 0: no sample yet (the first one gives no increment) */
} hd_cb_extrap_t;

typedef struct {
    hd_stribeck_t     str;
    hd_lugre_t        lug;
    hd_maxwell_t      mx;
    hd_preisach_inv_t pr;
    hd_te_comp_t      te;
    hd_backstep_t     bs;
    hd_blend_t        dob_blend;
    hd_blend_t        cp_blend;
    uint32_t enabled;            /* last applied enable bits */
    uint32_t bs_preload;         /* 1: preload backstepping at the next post() */
    int64_t  dpos_f;             /* low-passed position correction, 2^-48 turn (int64) */
    uint32_t dpos_primed;
    int64_t  pr_t;               /* torque estimate state, Q15.16 x 2^16 */
    int64_t  te_out;             /* last output-side TE model value, 2^-32 turn (unweighted) */
    int32_t  pr_dth;             /* weighted Preisach twist, 2^-32 turn */
    int64_t  dob_x;              /* DOB state, Q15.16 x 2^16 */
    int32_t  dob_d;              /* weighted DOB torque, Q15.16 */
    int32_t  t_prev;             /* torque applied in the previous period, Q15.16 N.m */
    hd_comp_bank_out_t out;      /* last outputs (telemetry) */
    int32_t  u_bs;               /* last torque after the backstepping blend */
    int64_t  pki_i;              /* scheduled position integral, 2^-48 turn/s */
    int32_t  pki_w;              /* its last schedule weight, Q30 (telemetry) */
    int32_t  pr_test;            /* last Preisach torque estimate, Q15.16 N.m (telemetry) */
    int32_t  cp_dth;             /* weighted compliance twist, 2^-32 turn */
    hd_fric_est_t fe;            /* online Stribeck identification */
    hd_stribeck_cfg_t fe_str;    /* the Stribeck FF config with the estimate fed in (while feeding) */
    hd_fric_est_cfg_t fe_cfg;    /* the estimator's config as the background uses it (fe_sync) */
    hd_stribeck_cfg_t fe_base;   /* ... the Stribeck FF parameters it feeds from */
    int32_t  fe_base_share;      /* ... and the share of the estimated levels it feeds, Q16 */
    hd_stribeck_cfg_t fe_next;   /* the background's fed FF config (copied to fe_str between its parts) */
    uint32_t fe_pend;            /* estimator changes waiting for the background's part to end */
    uint32_t fe_tick;            /* periods since the last estimator step */
    uint32_t fe_fast;            /* 1: the estimator's period is the inline one (fe on, nothing
                                  * pending, fe_decim >= 2; hd_comp_bank_fric_est) */
    int32_t  fe_v_min;           /* binning of the bins in fe (a change empties them) */
    int32_t  fe_vs_lo;
    uint32_t tick;               /* schedule tick (hd_sched.h), counts the pre() calls */
    hd_cb_extrap_t mx_x;         /* Maxwell-slip correction between its updates */
    hd_angle_t te_dth;           /* TE correction at its last step (motor-side harmonics), 2^-32 turn */
    hd_angle_t te_out_dth;       /* TE correction of the output-side lines, held */
    hd_angle_t te_mot;           /* motor angle of the last TE step, Q32.32 motor turns */
    int32_t  te_slope;           /* d(te_dth)/d(motor angle) there, 2^-32 turn per motor turn */
    int32_t  pr_yd;              /* held transmitted-torque estimate (low-passed), Q15.16 N.m */
    hd_gear_torque_t gt;         /* its motor-side part (pr_t_src 2) */
    uint32_t table_ok;           /* 1 once a table passed the check */
    uint32_t pr_lp_due;          /* 1: pr_test of slot 4 (pr_t_src 2) not yet low-passed (done in the next period) */
    /* last: 8.3 KiB that would put the fields above out of the short load / store offsets */
    hd_preisach_table_t table;   /* installed Preisach table (checked) */
} hd_comp_bank_t;

/** Configs from raw parameters. 0 ok, -1 inconsistent (bounds, sizes). */
int32_t hd_comp_bank_config(hd_comp_bank_cfg_t *c, const int32_t param[HD_PARAM_COUNT]);
/** Power-up: states reset, enables as in c (no ramp at start), no table. */
void hd_comp_bank_init(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c);
/** Apply new configs: enable-bit changes start the ramps (bumpless). */
void hd_comp_bank_apply(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c);
/** Check and install a Preisach table image; the old one stays on error. HD_PREISACH_* code. */
int32_t hd_comp_bank_install_table(hd_comp_bank_t *b, const hd_preisach_table_t *t);
/** Check the image already written into b->table (loaded from NVM) and put it in force
 *  if it passes. HD_PREISACH_* code. */
int32_t hd_comp_bank_adopt_table(hd_comp_bank_t *b);
/** No table in force (the Preisach compensator then outputs 0). */
void hd_comp_bank_clear_table(hd_comp_bank_t *b);
/** Before the position loop: position/velocity corrections and torque feed-forward. */
void hd_comp_bank_pre(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in,
                      hd_comp_bank_out_t *out);
/** After the velocity PID (u_pid, Q15.16 N.m): the backstepping blend; returns the torque. */
int32_t hd_comp_bank_post(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in,
                          int32_t u_pid);
/** End of the period: the torque command actually applied (for the DOB / torque estimate). */
void hd_comp_bank_end(hd_comp_bank_t *b, int32_t t_applied);
/** The slow slot of the online Stribeck identification (hd_fric_est.h): call once per
 *  control period with the reference velocity before the bank's corrections and the
 *  velocity-loop feedback (2^-32 turn/s), the output torque applied (Q15.16 N.m) and
 *  whether the position loops ran; every fe_decim-th call queues one observation for the
 *  background and refreshes the fed Stribeck FF config (not while a background part is in
 *  progress: the estimate is whole between parts). */
bool hd_comp_bank_fric_est_rare(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c);
/** The period's part of hd_comp_bank_fric_est without the observation: true when the
 *  observation is due in this period (then hd_fric_est_observe on b->fe with c->fe).  Split
 *  so that the caller computes the observation's inputs only in its period: inline, the
 *  periods of a running estimator without a pending change (fe_fast) cost a counter and, in
 *  the step's last period, the fed config's copy; the rest (fe off, its feed ramping out, a
 *  parameter change, fe_decim 1) is hd_comp_bank_fric_est_rare. */
static inline bool hd_comp_bank_fric_est_tick(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    const uint32_t t = b->fe_tick + 1u;
    if (b->fe_fast == 0u) {
        return hd_comp_bank_fric_est_rare(b, c);
    }
    if (t == 1u) {
        b->fe_tick = t;
        return true;
    }
    if (t < c->fe_decim) {
        b->fe_tick = t;
        return false;
    }
    b->fe_tick = 0u;
    if (!hd_fric_est_busy(&b->fe)) {
        /* the background's fed config of its last entry (whole between its parts) */
        b->fe_str = b->fe_next;
    }
    return false;
}
static inline void hd_comp_bank_fric_est(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, hd_vel_out_t v_ref,
                                         hd_vel_out_t v_fb, int32_t tau, bool active)
{
    if (hd_comp_bank_fric_est_tick(b, c)) {
        hd_fric_est_observe(&b->fe, &c->fe, v_ref, v_fb, tau, active);
    }
}
/** The background of the online identification: one part of the oldest queued step
 *  (hd_fric_est_work); true while work is left.  Call it below the control period (the
 *  port's main loop; the simulator after every period until false). */
bool hd_comp_bank_fric_est_work(hd_comp_bank_t *b);
/** True while any compensator output may be non-zero. */
bool hd_comp_bank_active(const hd_comp_bank_t *b);

#endif
