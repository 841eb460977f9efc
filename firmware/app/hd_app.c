/*
 * hd_app.c - the drive application (contract: hd_app.h).
 *
 * Cascade per period (closed-loop modes):
 *   pos_err = sat32(pos_ref - pos_out)                        2^-32 turn
 *   vel_ref = PID_pos(pos_err) + vff_gain * v_ff              2^-32 turn/s, |.| <= pos_vlim
 *             (position loop run in error form: ref = error, meas = 0, no D)
 *   t_ff    = aff_gain * j_total * 2 pi * acc_ref + torque_cmd  Q15.16 N.m (output side)
 *   t       = PID_vel(vel_ref, vel_fb) + t_ff                 Q15.16 N.m, |.| <= torque_limit
 *   t_f     = biquad chain (notch, low-pass)(t), clamped to torque_limit
 *   motor torque = t_f / N ; current = motor torque / Kt
 * vel_fb = motor-encoder observer / N (vel_fb_src 0) or output-encoder observer (1);
 * always the motor encoder in semi-closed and dual-loop (fb_config 1, 2).
 * Position feedback (fb_config, hd_feedback.h): pos_out in full closed; in
 * semi-closed / dual-loop the motor angle / N minus the bank's predicted offset
 * dpos (alone, or blended with pos_out below fb_dual_fc), and the bank's inputs
 * pos_out (LuGre, backstepping, position I) see the last period's feedback.
 * STAB keeps the output encoder (its outer loop is the gyro).
 *
 * Standstill hunt breaker (hold_ticks > 0; position modes except STAB):
 * the reference is "at rest" when pos_ref (before the bank's corrections) equals last
 * period's and v_ff is 0; inpos_n counts such periods (a CSP stream moves pos_ref at
 * every SYNC, so a CSP multisine is never at rest).  The Stribeck feed-forward on the
 * measured velocity is a relay at rest: it dithers the axis onto its target (a ~107 Hz
 * cycle of +-1-3") but can also fall into a ~13 Hz cycle of +-10-20" (the load on the
 * friction's pre-sliding compliance, driven by the relay).  When |pos_err| > hold_hunt_win
 * after hold_ticks periods at rest, the Stribeck FF fades linearly to its running mean
 * (one-pole low-pass, 2^-HD_INPOS_TAU_SHIFT per period, updated only at full weight) over
 * hold_fade_ticks periods and then back to full at the same rate; the axis stops in
 * between and the relay restarts from rest, normally into the small cycle.  Re-armed
 * hold_ticks periods after the mean was reached; a moving reference restores the full
 * FF at once.
 */
#include "hd_app.h"
#include <stddef.h>
#include "hd_fixed.h"
#include "hd_sched.h"

#define TWO_PI_Q28 1686629713   /* round(2 pi 2^28) */

/* Per-period fixed-point helpers: the inline hdf_* forms of hd_fixed.h
 * (bit-identical to hd_fixed.c, shifts folded at the call sites). */
static inline uint64_t mag64(int64_t x)   /* |x| without overflow */
{
    return (x < 0) ? ((uint64_t)0 - (uint64_t)x) : (uint64_t)x;
}

static int32_t param_raw(const hd_app_t *a, hd_param_id_t id)
{
    return a->param[id];
}

/* 2 pi x for x in Q16 (Hz or per-rad gains) -> Q16, saturated */
static int32_t two_pi(int32_t x)
{
    return hd_mul_q(x, TWO_PI_Q28, 28u);
}

int32_t hd_app_apply_params(hd_app_t *a)
{
    const int32_t n = param_raw(a, HD_P_GEAR_RATIO);
    if (n < 1 || param_raw(a, HD_P_KT) <= 0) {
        return -1;
    }
    /* position loop: in 2^-32 turn, out 2^-32 turn/s, gains Q16 */
    a->pos_cfg.shift = 16u;
    a->pos_cfg.kp = param_raw(a, HD_P_POS_KP);
    a->pos_cfg.ki_dt = hd_sat32(hd_div64_rnd(param_raw(a, HD_P_POS_KI), HD_LOOP_HZ));
    a->pos_cfg.kd_fs = 0;
    a->pos_cfg.d_alpha = HD_Q30_ONE;
    a->pos_cfg.out_max = param_raw(a, HD_P_POS_VLIM);
    a->pos_cfg.out_min = hd_neg_sat(a->pos_cfg.out_max);

    /* hunt breaker: per-period step of the Stribeck FF weight (Q30), fade over hold_fade_ticks */
    a->inpos_dw = (param_raw(a, HD_P_HOLD_FADE_TICKS) > 0) ?
        hd_sat32(hd_div64_rnd((int64_t)HD_Q30_ONE, param_raw(a, HD_P_HOLD_FADE_TICKS))) : HD_Q30_ONE;

    /* velocity loop: in 2^-32 turn/s, out Q15.16 N.m, gains Q16 N.m/(turn/s) with shift 32 */
    a->vel_cfg.shift = 32u;
    a->vel_cfg.kp = two_pi(param_raw(a, HD_P_VEL_KP));
    a->vel_cfg.ki_dt = hd_sat32(hd_div64_rnd(hd_mul64x32_q(param_raw(a, HD_P_VEL_KI), TWO_PI_Q28, 28u), HD_LOOP_HZ));
    a->vel_cfg.kd_fs = hd_sat32(hd_mul64x32_q(hd_mul64x32_q(param_raw(a, HD_P_VEL_KD), TWO_PI_Q28, 28u), HD_LOOP_HZ, 0u));
    {
        const int32_t x = hd_sat32(hd_div64_rnd(two_pi(param_raw(a, HD_P_VEL_D_FC)), HD_LOOP_HZ)); /* 2 pi fc T, Q16 */
        a->vel_cfg.d_alpha = HD_Q30_ONE - hd_exp_neg_q16(x);
        if (a->vel_cfg.d_alpha <= 0) {
            a->vel_cfg.d_alpha = 1;
        }
    }
    a->vel_cfg.out_max = param_raw(a, HD_P_TORQUE_LIMIT);
    a->vel_cfg.out_min = hd_neg_sat(a->vel_cfg.out_max);

    hd_velobs_design(&a->obs_mot_cfg, two_pi(param_raw(a, HD_P_OBS_MOT_BW)), param_raw(a, HD_P_OBS_ZETA));
    hd_velobs_design(&a->obs_out_cfg, two_pi(param_raw(a, HD_P_OBS_OUT_BW)), param_raw(a, HD_P_OBS_ZETA));

    {
        const uint32_t en = (uint32_t)param_raw(a, HD_P_FILT_ENABLE);
        uint32_t k = 0;
        if (en & 1u) {
            hd_biquad_coef_t *c = &a->filt_cfg.c[k++];
            c->b0 = param_raw(a, HD_P_F1_B0); c->b1 = param_raw(a, HD_P_F1_B1); c->b2 = param_raw(a, HD_P_F1_B2);
            c->a1 = param_raw(a, HD_P_F1_A1); c->a2 = param_raw(a, HD_P_F1_A2);
        }
        if (en & 2u) {
            hd_biquad_coef_t *c = &a->filt_cfg.c[k++];
            c->b0 = param_raw(a, HD_P_F2_B0); c->b1 = param_raw(a, HD_P_F2_B1); c->b2 = param_raw(a, HD_P_F2_B2);
            c->a1 = param_raw(a, HD_P_F2_A1); c->a2 = param_raw(a, HD_P_F2_A2);
        }
        a->filt_cfg.n = k;
    }

    /* STAB: the position loop on the inertial-angle error, own gains */
    a->stab_pos_cfg = a->pos_cfg;
    a->stab_pos_cfg.kp = param_raw(a, HD_P_STAB_KP);
    a->stab_pos_cfg.ki_dt = hd_sat32(hd_div64_rnd(param_raw(a, HD_P_STAB_KI), HD_LOOP_HZ));
    hd_stab_design(&a->stab_cfg, param_raw(a, HD_P_STAB_GYRO_BIAS), param_raw(a, HD_P_STAB_BLEND_FC), param_raw(a, HD_P_STAB_BLEND_FR),
                   param_raw(a, HD_P_STAB_BIAS_MAX), param_raw(a, HD_P_STAB_BASE_BW), param_raw(a, HD_P_OBS_ZETA), param_raw(a, HD_P_STAB_FF_DB));

    /* travel limits in the unit of pos_out, compared every period */
    a->travel_min_q = hdf_shl64_sat(param_raw(a, HD_P_TRAVEL_MIN), 8u);
    a->travel_max_q = hdf_shl64_sat(param_raw(a, HD_P_TRAVEL_MAX), 8u);

    /* acceleration feed-forward as one gain: aff_gain [Q30] x j_total [Q16 kg m^2] x 2 pi,
     * N.m per turn/s^2 in Q32.32 (j_total 2 pi 2^44 < 2^62; the result < 2^51) */
    a->aff_k = hd_mul64x32_q(hd_mul64x32_q((int64_t)param_raw(a, HD_P_J_TOTAL), TWO_PI_Q28, 0u),
                             param_raw(a, HD_P_AFF_GAIN), 42u);

    a->traj_cfg.vmax = param_raw(a, HD_P_TRAJ_VMAX);
    a->traj_cfg.amax = param_raw(a, HD_P_TRAJ_AMAX);
    a->traj_cfg.jmax = param_raw(a, HD_P_TRAJ_JMAX);
    /* one-direction final approach of PTP moves: cb_enable bit HD_CB_APPROACH */
    if (((uint32_t)param_raw(a, HD_P_CB_ENABLE) & HD_CB_APPROACH) != 0u) {
        a->traj_cfg.appr_dir = param_raw(a, HD_P_APPR_DIR);
        a->traj_cfg.appr_dist = param_raw(a, HD_P_APPR_DIST);
        a->traj_cfg.appr_vmax = param_raw(a, HD_P_APPR_VMAX);
        a->traj_cfg.appr_dwell = (uint32_t)hd_div64_rnd((int64_t)param_raw(a, HD_P_APPR_DWELL) * HD_LOOP_HZ, 65536);
    } else {
        a->traj_cfg.appr_dir = 0;
        a->traj_cfg.appr_dist = 0;
        a->traj_cfg.appr_vmax = 0;
        a->traj_cfg.appr_dwell = 0u;
    }
    if (hd_comp_bank_config(&a->cb_cfg, a->param) != 0) {
        return -1;
    }
    if (hd_fb_design(&a->fb_cfg, param_raw(a, HD_P_FB_CONFIG), n, param_raw(a, HD_P_FB_DUAL_FC)) != 0) {
        return -1;
    }
    a->obs_out_fb = (param_raw(a, HD_P_VEL_FB_SRC) != 0 && a->fb_cfg.kind == (uint32_t)HD_FB_FULL_CLOSED) ? 1u : 0u;
    return 0;
}

/* The compensators evaluated by hd_comp_bank_pre (backstepping runs in _post). */
#define HD_CB_PRE_MASK (HD_CB_STRIBECK | HD_CB_LUGRE | HD_CB_MAXWELL | HD_CB_PREISACH | HD_CB_TE | \
                        HD_CB_DOB | HD_CB_COMPLIANCE)

/* 1 when hd_comp_bank_pre would return zero corrections and change nothing but its
 * bookkeeping (bank_idle_step): no compensator of the pre part enabled or ramping,
 * no scheduled position integral, and every held, extrapolated and filtered
 * correction exactly 0 (or, for the low-passed one, no longer moving), no torque estimate
 * waiting for its low-pass (pr_lp_due).  Evaluated in the parameter-set path and, while a
 * compensator ramps out, after each period's bank step, never in an idle period. */
static uint32_t bank_idle(const hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    const bool quiet = (b->enabled & HD_CB_PRE_MASK) == 0u && c->pki == 0 && b->pki_i == 0 &&
        !hd_blend_active(&b->str.blend) && !hd_blend_active(&b->lug.blend) &&
        !hd_blend_active(&b->mx.blend) && !hd_blend_active(&b->pr.blend) &&
        !hd_blend_active(&b->te.blend) && !hd_blend_active(&b->dob_blend) &&
        !hd_blend_active(&b->cp_blend) && b->pr_lp_due == 0u;    /* a low-pass due: the next step runs it */
    const bool zero = b->lug.tau == 0 && b->dob_d == 0 && b->te.tau == 0 && b->pr_dth == 0 &&
        b->cp_dth == 0 && b->te_dth == 0 && b->te_out_dth == 0 && b->mx_x.v == 0 &&
        b->mx_x.inc == 0 && b->te_slope == 0;
    /* the corrections' low-pass (full closed): settled when its step toward 0 is 0 (its
     * rounding can leave a few 2^-48 turn); semi-closed / dual-loop set it to 0 */
    const bool settled = c->pos_mode != 0u || b->dpos_f == 0 ||
        hdf_mul64x32_q(hdf_neg64_sat(b->dpos_f), c->dpos_alpha, 30u) == 0;
    return (quiet && zero && settled) ? 1u : 0u;
}

/* What hd_comp_bank_pre does to the bank's state when idle (bank_idle): the schedule's
 * tick goes on, the loops' start is recorded, the outputs are 0.  Keeps an idle
 * period bit-identical to a call, so that a compensator switched on later starts in
 * the same tick of the schedule and with the same state. */
static void bank_idle_step(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, hd_comp_bank_out_t *out)
{
    b->tick = (b->tick & (HD_SCHED_CYCLE - 1u)) + 1u;
    if (c->pos_mode != 0u || b->dpos_primed == 0u) {
        b->dpos_f = 0;                  /* the correction's sum (0), as the bank's own step sets it */
    }
    b->dpos_primed = 1u;
    b->pki_w = 0;
    out->dpos = 0;
    out->dvel = 0;
    out->tff = 0;
    b->out = *out;
}

/* 1 when backstepping is off and its weight 0 (hd_comp_bank_post returns the PID's torque) */
static uint32_t bs_idle(const hd_comp_bank_t *b)
{
    return ((b->enabled & HD_CB_BACKSTEP) == 0u && !hd_blend_active(&b->bs.blend)) ? 1u : 0u;
}

/* 1 when the online identification is off and its feed ramped out (hd_comp_bank_fric_est
 * returns at once) */
static uint32_t fe_idle(const hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    return (c->fe_on == 0u && !hd_fric_est_feeding(&b->fe)) ? 1u : 0u;
}

/* The bank's skip flags, after a parameter set or a reset of the bank. */
static void bank_flags(hd_app_t *a)
{
    a->cb_idle = bank_idle(&a->cb, &a->cb_cfg);
    a->bs_idle = bs_idle(&a->cb);
    a->fe_idle = fe_idle(&a->cb, &a->cb_cfg);
}

static void reset_loops(hd_app_t *a)
{
    hd_pid_reset(&a->pos_pid);
    hd_pid_reset(&a->vel_pid);
    hd_biquad_chain_reset(&a->filt);
    a->sat_count = 0;
    a->cb.bs_preload = 1u;       /* backstepping re-engages from the PID effort */
    a->cb.dpos_primed = 0u;
    a->inpos_n = 0u;
    a->inpos_on = 0u;
    a->inpos_tau = 0;
    a->inpos_w = HD_Q30_ONE;
    a->inpos_ref_prev = a->pos_out;
}

void hd_app_init(hd_app_t *a)
{
    uint32_t i;
    a->pstore_status = hd_pstore_load(a->param, &a->pstore_seq);
    if (hd_app_apply_params(a) != 0) {
        hd_params_defaults(a->param);
        a->pstore_status = HD_PSTORE_CORRUPT;
        (void)hd_app_apply_params(a);
    }
    reset_loops(a);
    hd_velobs_reset(&a->obs_mot, 0);
    hd_velobs_reset(&a->obs_out, 0);
    a->obs_out_run = 0u;
    hd_comp_bank_init(&a->cb, &a->cb_cfg);
    bank_flags(a);
    hd_fb_reset(&a->fb, &a->fb_cfg, 0, 0);
    /* the saved Preisach table, read straight into the bank (no second image in RAM) */
    a->tstore_status = hd_tstore_load(&a->cb.table, &a->tstore_seq);
    if (a->tstore_status == HD_TSTORE_OK && hd_comp_bank_adopt_table(&a->cb) != HD_PREISACH_OK) {
        a->tstore_status = HD_TSTORE_CORRUPT;
    }
    a->tstore_sync = (a->tstore_status == HD_TSTORE_OK || a->tstore_status == HD_TSTORE_NONE ||
                      a->tstore_status == HD_TSTORE_BLANK) ? 1u : 0u;
    hd_stab_init(&a->stab);
    a->stab_primed = 0;
    hd_traj_reset(&a->traj, 0);
    a->exc_cfg.kind = HD_EXC_NONE;
    a->exc_cfg.amp = 0;
    a->exc_cfg.offset = 0;
    a->exc_cfg.length = 0;
    a->exc_cfg.hold = 0;
    a->exc_cfg.n = 0;
    a->exc_cfg.m = 0;
    a->exc_cfg.rate = 0;
    a->exc_cfg.f0_q16 = 0;
    a->exc_cfg.f1_q16 = 0;
    a->exc_cfg.period = 0;
    a->exc_cfg.seed = 0;
    (void)hd_exc_start(&a->exc, &a->exc_cfg);
    a->exc_inj = HD_INJ_TORQUE;
    a->started = 0;
    a->mot_raw_prev = 0;
    a->out_raw_prev = 0;
    a->pos_mot = 0;
    a->pos_out = 0;
    a->mode = HD_MODE_OFF;
    a->mode_req = HD_MODE_OFF;
    a->mode_changed = 0;
    a->pos_cmd = 0;
    a->vel_cmd = 0;
    a->torque_cmd = 0;
    a->ptp_target = 0;
    a->rate_cmd = 0;
    a->sine_amp = 0;
    a->sine_f_q16 = 0;
    a->hold_pos = 0;
    a->fault = HD_FAULT_NONE;
    hd_capture_reset(&a->cap);
    for (i = 0; i < HD_CAPTURE_MAX_CH; i++) {
        a->cap_sig[i] = 0;
    }
    {
        hd_telemetry_t z = {0};
        a->tel = z;
    }
}

/* ---- sensors ------------------------------------------------------------ */

/* The step now - prev of a bits-bit counter (wrapped into [-2^(bits-1), 2^(bits-1)))
 * times 2^(32 - bits), i.e. in 2^-32 turn: shifted to the top of a 32-bit word the
 * wrapped difference IS that signed value (two's complement), so no 64-bit shift and
 * no saturation (|result| <= 2^31).  8 <= bits <= 32 (parameter ranges). */
static int32_t enc_step_q32(uint32_t now, uint32_t prev, uint32_t bits)
{
    const uint32_t u = (now - prev) << (32u - bits);
    return (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u;
}

/* hd_sat32(hd_div64_rnd(num, den)) for int32 num and den >= 1, in 32-bit
 * arithmetic (one UDIV on the M4 instead of __aeabi_ldivmod); same result.
 * Range: |num| <= 2^31, so quo <= 2^31, and quo == 2^31 only for num = -2^31 and
 * den = 1 (den >= 2 gives quo <= 2^30 + 1; den = 1 leaves num itself): a positive
 * quotient fits an int32 and a negative one is -quo without saturation. */
static int32_t div32_rnd(int32_t num, int32_t den)
{
    const uint32_t un = (num < 0) ? 0u - (uint32_t)num : (uint32_t)num;   /* <= 2^31 */
    const uint32_t ud = (uint32_t)den;
    uint32_t quo = un / ud;
    const uint32_t rem = un - quo * ud;
    if (rem >= ud - rem) {
        quo += 1u;
    }
    return hdf__s32((num < 0) ? 0u - quo : quo);
}

/* hd_div_q(num, den, 16u) for den >= 1: with den < 2^16 the 48-bit dividend
 * |num| 2^16 is divided in two 32-bit steps (q1 = |num| / den, then the
 * remainder r1 < 2^16 shifted by 16 bits: < 2^32), two UDIVs instead of the
 * 64-bit long division; same quotient, rounding and saturation.  Larger den: hd_div_q.
 * Range: q2 < 2^16, so with q1 < 2^15 the rounded quotient is at most 2^31 (a
 * uint32): 2^31 saturates to INT32_MAX when positive and is INT32_MIN itself when
 * negative; q1 >= 2^15 means |quotient| >= 2^31: the limit of the sign of num. */
static int32_t div_q16_rnd(int32_t num, int32_t den)
{
    if (den < 1 || den > 65535) {
        return hd_div_q(num, den, 16u);
    }
    const uint32_t un = (num < 0) ? 0u - (uint32_t)num : (uint32_t)num;   /* <= 2^31 */
    const uint32_t ud = (uint32_t)den;
    const uint32_t q1 = un / ud;
    if (q1 >= 32768u) {
        return (num < 0) ? INT32_MIN : INT32_MAX;
    }
    const uint32_t t = (un - q1 * ud) << 16;
    const uint32_t q2 = t / ud;
    const uint32_t r2 = t - q2 * ud;
    uint32_t quo = (q1 << 16) + q2;
    if (r2 >= ud - r2) {
        quo += 1u;
    }
    if (num < 0) {
        return hdf__s32(0u - quo);
    }
    return (quo > (uint32_t)INT32_MAX) ? INT32_MAX : (int32_t)quo;
}

/* hd_sat32(hd_div64_rnd(x, n * 65536)) for 1 <= n < 65536: floor(|x| / (n 2^16)) =
 * floor((|x| >> 16) / n), and (|x| >> 16) < 2^48 is divided by n in two 32-bit
 * steps of 16 bits each (two UDIVs); same result as the 64-bit division.
 * Range, so that the rest is 32-bit words too: the remainder r2 < n <= 65535, so
 * (r2 2^16 + |x| mod 2^16) < n 2^16 < 2^32; q1 >= 2^15 means |quotient| >= 2^31 (the
 * limit of the sign of x), else the rounded quotient q1 2^16 + q2 + 1 <= 2^31 fits a
 * uint32 (2^31 saturates to INT32_MAX when positive, is INT32_MIN when negative). */
static int32_t div_n_q16_rnd(int64_t x, int32_t n)
{
    if (n < 1 || n > 65535) {
        return hdf_sat32(hd_div64_rnd(x, (int64_t)n * 65536));
    }
    const uint64_t m = mag64(x);
    const uint32_t un = (uint32_t)n;
    const uint32_t xh = (uint32_t)(m >> 32);           /* (|x| >> 16) >> 16 */
    const uint32_t q1 = xh / un;
    if (q1 >= 32768u) {
        return (x < 0) ? INT32_MIN : INT32_MAX;
    }
    const uint32_t ml = (uint32_t)m;
    const uint32_t t = ((xh - q1 * un) << 16) | (ml >> 16);    /* < n 2^16 <= 2^32 */
    const uint32_t q2 = t / un;
    const uint32_t rem = ((t - q2 * un) << 16) | (ml & 0xFFFFu);  /* < n 2^16 */
    uint32_t quo = (q1 << 16) + q2;
    if (rem >= (un << 16) - rem) {
        quo += 1u;
    }
    if (x < 0) {
        return hdf__s32(0u - quo);
    }
    return (quo > (uint32_t)INT32_MAX) ? INT32_MAX : (int32_t)quo;
}

/* returns 0 or a fault code */
static int32_t read_sensors(hd_app_t *a, hd_hal_sensors_t *sn)
{
    const uint32_t mb = (uint32_t)param_raw(a, HD_P_MOTOR_ENC_BITS);
    const uint32_t ob = (uint32_t)param_raw(a, HD_P_OUTPUT_ENC_BITS);
    const uint32_t need = HD_HAL_VALID_MOTOR_ENC | HD_HAL_VALID_OUTPUT_ENC;
    const uint32_t omask = (1u << ob) - 1u;
    hd_hal_read_sensors(sn);
    if ((sn->valid & need) != need) {
        return HD_FAULT_SENSOR;
    }
    const uint32_t mraw = sn->motor_enc_raw & ((1u << mb) - 1u);
    const uint32_t oraw = (sn->output_enc_raw - (uint32_t)param_raw(a, HD_P_OUTPUT_ENC_ZERO)) & omask;
    int32_t fault = 0;
    if (!a->started) {
        /* output: signed single turn in [-0.5, 0.5) */
        const int64_t half = (int64_t)1 << (ob - 1u);
        const int64_t so = ((int64_t)oraw >= half) ? (int64_t)oraw - 2 * half : (int64_t)oraw;
        a->pos_out = hdf_shl64_sat(so, 32u - ob);
        /* motor: N * output angle, adjusted to the encoder's own fraction */
        const int64_t base = hdf_mul64x32_q(a->pos_out, param_raw(a, HD_P_GEAR_RATIO), 0u);
        const uint32_t mfrac = mraw << (32u - mb);
        const uint32_t d = mfrac - (uint32_t)(uint64_t)base;
        a->pos_mot = base + ((d >= 0x80000000u) ? (int64_t)d - 4294967296LL : (int64_t)d);
        a->started = 1;
        hd_velobs_reset(&a->obs_mot, a->pos_mot);
        hd_velobs_reset(&a->obs_out, a->pos_out);
        a->obs_out_run = 0u;
        hd_traj_reset(&a->traj, a->pos_out);
        hd_fb_reset(&a->fb, &a->fb_cfg, a->pos_mot, a->pos_out);
    } else {
        const int32_t dm = enc_step_q32(mraw, a->mot_raw_prev, mb);
        const int32_t dq = enc_step_q32(oraw, a->out_raw_prev, ob);
        a->pos_mot = hdf_add64_sat(a->pos_mot, (int64_t)dm);
        a->pos_out = hdf_add64_sat(a->pos_out, (int64_t)dq);
        if (hdf_abs64_sat((int64_t)dq) > (int64_t)param_raw(a, HD_P_ENC_JUMP_MAX)) {
            fault = HD_FAULT_ENC_JUMP;
        }
    }
    a->mot_raw_prev = mraw;
    a->out_raw_prev = oraw;
    return fault;
}

/* ---- modes ---------------------------------------------------------------- */

static void enter_mode(hd_app_t *a, int32_t mode)
{
    /* the references start at the loop's position feedback (bumpless in every
     * feedback configuration; the output encoder in full closed and in STAB) */
    const hd_angle_t p0 = (a->fb_cfg.kind == (uint32_t)HD_FB_FULL_CLOSED || mode == HD_MODE_STAB) ?
        a->pos_out : hd_fb_enter(&a->fb, &a->fb_cfg, a->pos_out);
    reset_loops(a);
    a->inpos_ref_prev = p0;
    a->pos_cmd = p0;
    a->vel_cmd = 0;
    hd_traj_reset(&a->traj, p0);
    a->hold_pos = p0;
    switch (mode) {
    case HD_MODE_TORQUE:
        break;
    case HD_MODE_PTP:
        (void)hd_traj_ptp(&a->traj, &a->traj_cfg, a->ptp_target);
        break;
    case HD_MODE_RATE:
        hd_traj_rate(&a->traj, &a->traj_cfg, a->rate_cmd);
        break;
    case HD_MODE_SINE:
        (void)hd_traj_sine(&a->traj, p0, a->sine_amp, a->sine_f_q16);
        break;
    case HD_MODE_EXCITATION:
        (void)hd_exc_start(&a->exc, &a->exc_cfg);
        break;
    case HD_MODE_STAB:
        a->stab_primed = 0;      /* estimator started with the next sample */
        break;
    default:
        a->torque_cmd = 0;
        break;
    }
    a->mode = mode;
}

int32_t hd_app_set_mode(hd_app_t *a, int32_t mode)
{
    if (mode < HD_MODE_OFF || mode > HD_MODE_STAB) {
        return -1;
    }
    if (a->fault != HD_FAULT_NONE && mode != HD_MODE_OFF) {
        return -1;
    }
    a->mode_req = mode;
    if (a->started) {
        enter_mode(a, mode);
        a->mode_changed = 0;
    } else {
        a->mode_changed = 1;     /* entered at the first sensor sample */
    }
    return 0;
}

void hd_app_set_torque(hd_app_t *a, hd_torque_t t) { a->torque_cmd = t; }
void hd_app_set_velocity(hd_app_t *a, hd_vel_out_t v) { a->vel_cmd = v; }
void hd_app_set_position(hd_app_t *a, hd_angle_t p) { a->pos_cmd = p; }

int32_t hd_app_move_to(hd_app_t *a, hd_angle_t target)
{
    a->ptp_target = target;
    if (a->mode == HD_MODE_PTP && a->started) {
        return hd_traj_ptp(&a->traj, &a->traj_cfg, target);
    }
    return 0;
}

void hd_app_halt(hd_app_t *a, hd_acc_t amax)
{
    if ((a->mode == HD_MODE_PTP || a->mode == HD_MODE_RATE) && a->started &&
        a->traj.mode != HD_TRAJ_HOLD) {
        /* the ramp's step is taken from the cfg once, at the stop (hd_traj_rate) */
        hd_traj_cfg_t c = a->traj_cfg;
        c.amax = (amax > 0) ? amax : a->traj_cfg.amax;
        hd_traj_stop(&a->traj, &c);
    }
}

void hd_app_set_rate(hd_app_t *a, hd_vel_out_t v)
{
    a->rate_cmd = v;
    if (a->mode == HD_MODE_RATE) {
        hd_traj_rate(&a->traj, &a->traj_cfg, v);
    }
}

void hd_app_set_sine(hd_app_t *a, int32_t amp, int32_t f_q16)
{
    a->sine_amp = amp;
    a->sine_f_q16 = f_q16;
}

int32_t hd_app_set_excitation(hd_app_t *a, const hd_exc_cfg_t *c, int32_t inj)
{
    hd_exc_t probe;
    if (inj < HD_INJ_TORQUE || inj > HD_INJ_TORQUE_FF || hd_exc_start(&probe, c) != 0) {
        return -1;
    }
    a->exc_cfg = *c;
    a->exc_inj = inj;
    return 0;
}

void hd_app_fault_reset(hd_app_t *a)
{
    a->fault = HD_FAULT_NONE;
    a->sat_count = 0;
    a->mode = HD_MODE_OFF;
    a->mode_req = HD_MODE_OFF;
    a->mode_changed = 0;
    reset_loops(a);
}

int32_t hd_app_fault_raise(hd_app_t *a, int32_t code)
{
    if (code <= HD_FAULT_NONE || code > HD_FAULT_COMM) {
        return -1;
    }
    if (a->fault == HD_FAULT_NONE) {
        a->fault = code;
    }
    return 0;
}

int32_t hd_app_param_set(hd_app_t *a, uint32_t id, int32_t raw)
{
    if (hd_params_check(id, raw) != 0) {
        return -1;
    }
    const int32_t old = a->param[id];
    /* the loop's feedback source changes only with the power stage off */
    if (id == (uint32_t)HD_P_FB_CONFIG && raw != old && (a->mode != HD_MODE_OFF || a->mode_req != HD_MODE_OFF)) {
        return -1;
    }
    a->param[id] = raw;
    if (hd_app_apply_params(a) != 0) {
        a->param[id] = old;
        (void)hd_app_apply_params(a);
        return -1;
    }
    hd_comp_bank_apply(&a->cb, &a->cb_cfg);   /* enable changes ramp (bumpless) */
    bank_flags(a);
    if ((id == (uint32_t)HD_P_FB_CONFIG || id == (uint32_t)HD_P_GEAR_RATIO) && raw != old) {
        /* motor / N restarts from the present angles (the next mode entry starts there) */
        hd_fb_reset(&a->fb, &a->fb_cfg, a->pos_mot, a->pos_out);
    }
    return 0;
}

int32_t hd_app_comp_table(hd_app_t *a, const hd_preisach_table_t *t)
{
    const int32_t rc = hd_comp_bank_install_table(&a->cb, t);
    if (rc == HD_PREISACH_OK) {
        a->tstore_sync = 0u;
    }
    return rc;
}

void hd_app_comp_table_clear(hd_app_t *a)
{
    if (a->cb.table_ok != 0u) {
        a->tstore_sync = 0u;
    }
    hd_comp_bank_clear_table(&a->cb);
}

int32_t hd_app_param_get(const hd_app_t *a, uint32_t id)
{
    return (id < HD_PARAM_COUNT) ? a->param[id] : 0;
}

int32_t hd_app_param_save(hd_app_t *a)
{
    if (a->mode != HD_MODE_OFF) {
        return -1;
    }
    return hd_pstore_save(a->param, &a->pstore_seq);
}

int32_t hd_app_store_all(hd_app_t *a)
{
    if (hd_app_param_save(a) != 0) {
        return -1;
    }
    /* an unchanged table is not written again (8 KiB of flash wear per save) */
    if (a->tstore_sync == 0u) {
        if (hd_tstore_save((a->cb.table_ok != 0u) ? &a->cb.table : NULL, &a->tstore_seq) != 0) {
            return -1;
        }
        a->tstore_sync = 1u;
    }
    return 0;
}

int32_t hd_app_store_pending(const hd_app_t *a)
{
    if (hd_pstore_same(a->param) == 0) {
        return 1;
    }
    if (a->tstore_sync == 0u && hd_tstore_same((a->cb.table_ok != 0u) ? &a->cb.table : NULL) == 0) {
        return 1;
    }
    return 0;
}

int32_t hd_app_capture_arm(hd_app_t *a, const hd_capture_cfg_t *c, const uint32_t *sig)
{
    uint32_t i;
    if (c->n_ch == 0u || c->n_ch > HD_CAPTURE_MAX_CH) {
        return -1;
    }
    for (i = 0; i < c->n_ch; i++) {
        if (sig[i] >= (uint32_t)HD_SIG_COUNT) {
            return -1;
        }
    }
    if (hd_capture_arm(&a->cap, c) != 0) {
        return -1;
    }
    for (i = 0; i < c->n_ch; i++) {
        a->cap_sig[i] = sig[i];
    }
    return 0;
}

void hd_app_capture_trigger(hd_app_t *a)
{
    hd_capture_trigger(&a->cap);
}

hd_angle_t hd_app_entry_position(const hd_app_t *a)
{
    return hd_fb_entry_position(&a->fb, &a->fb_cfg, a->pos_out);
}

const hd_telemetry_t *hd_app_telemetry(const hd_app_t *a)
{
    return &a->tel;
}

/* ---- one period ------------------------------------------------------------ */

static int32_t lo32(int64_t x)
{
    const uint32_t u = (uint32_t)(uint64_t)x;
    return (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u;
}

static int32_t hi32(int64_t x)
{
    return hd_sat32(hd_asr64_floor(x, 32u));
}

static int32_t signal(const hd_app_t *a, uint32_t id)
{
    const hd_telemetry_t *t = &a->tel;
    switch (id) {
    case HD_SIG_TICK: return lo32((int64_t)t->tick);
    case HD_SIG_POS_OUT_LO: return lo32(t->pos_out);
    case HD_SIG_POS_OUT_HI: return hi32(t->pos_out);
    case HD_SIG_POS_MOT_LO: return lo32(t->pos_mot);
    case HD_SIG_POS_MOT_HI: return hi32(t->pos_mot);
    case HD_SIG_VEL_OUT: return t->vel_out;
    case HD_SIG_VEL_MOT: return t->vel_mot;
    case HD_SIG_POS_REF_LO: return lo32(t->pos_ref);
    case HD_SIG_POS_REF_HI: return hi32(t->pos_ref);
    case HD_SIG_VEL_REF: return t->vel_ref;
    case HD_SIG_ACC_REF: return t->acc_ref;
    case HD_SIG_TORQUE_CMD: return t->torque_cmd;
    case HD_SIG_CURRENT: return t->current;
    case HD_SIG_GYRO: return t->gyro;
    case HD_SIG_EXC: return t->exc;
    case HD_SIG_POS_ERR: return t->pos_err;
    case HD_SIG_FAULT: return t->fault;
    default: return 0;
    }
}

static void trip(hd_app_t *a, int32_t code)
{
    if (a->fault == HD_FAULT_NONE) {
        a->fault = code;
    }
}

/* Which loops of the cascade run this period. */
typedef enum {
    HD_LOOPS_NONE = 0,      /* open loop: torque reference, excitation at torque, or off */
    HD_LOOPS_VEL = 1,       /* velocity loop only */
    HD_LOOPS_POS_VEL = 2    /* position + velocity loops (and the compensator bank) */
} hd_loops_t;

/* The signals of one period, handed from phase to phase (stack, no state kept); the
 * ones the telemetry reports (velocity feedback and output-encoder observer, position
 * reference, feedback and error, velocity and acceleration references, excitation)
 * the phases write into a->tel directly, which the later phases read. */
typedef struct {
    hd_hal_sensors_t   sn;        /* the sensor sample */
    uint32_t           fen;       /* fault_enable bits */
    int32_t            n;         /* gear ratio */
    int32_t            mode;      /* hd_mode_t in effect (OFF while faulted) */
    hd_loops_t         loops;
    hd_angle_t         ref_plain; /* pos_ref before the bank's corrections */
    hd_vel_out_t       v_ff;      /* velocity feed-forward, 2^-32 turn/s */
    hd_vel_out_t       vff_plain; /* v_ff before the bank's corrections */
    hd_torque_t        t_ff;      /* torque feed-forward, Q15.16 N.m */
    int32_t            t_out;     /* torque before the limit, Q15.16 N.m (an int32 from every source) */
    int32_t            t_cmd;     /* limited output torque command, Q15.16 N.m */
    hd_comp_bank_in_t  cbi;       /* the bank's inputs (pre and post) */
    hd_hal_command_t   cmd;
} hd_period_t;

/* Sensors: sample, unwrap, sensor / encoder-jump faults, pending mode entry,
 * velocity observers and the loop's velocity feedback -> p->sn, tel.vel_out, vel_out_enc. */
static void phase_sensors(hd_app_t *a, hd_period_t *p)
{
    p->fen = (uint32_t)param_raw(a, HD_P_FAULT_ENABLE);
    const int32_t sf = read_sensors(a, &p->sn);
    if (sf == HD_FAULT_SENSOR && (p->fen & HD_FCHK_SENSOR) && a->mode != HD_MODE_OFF) {
        trip(a, sf);
    }
    if (sf == HD_FAULT_ENC_JUMP && (p->fen & HD_FCHK_ENC_JUMP)) {
        trip(a, sf);
    }
    if (a->fb_cfg.kind != (uint32_t)HD_FB_FULL_CLOSED && a->started) {
        hd_fb_motor(&a->fb, &a->fb_cfg, a->pos_mot);     /* motor / N of this sample */
    }
    if (a->started && a->mode_changed) {
        a->mode_changed = 0;
        enter_mode(a, a->mode_req);
    }
    hd_velobs_step_vel_inline(&a->obs_mot, &a->obs_mot_cfg, a->pos_mot);   /* its err is never read */
    p->n = param_raw(a, HD_P_GEAR_RATIO);
    const hd_vel_out_t v_mot_out = div_n_q16_rnd(hd_velobs_vel48(&a->obs_mot), p->n);
    /* the output-encoder observer only while its velocity is used: the loop's feedback
     * (vel_fb_src 1, full closed) or STAB; switched on, it starts at the output angle
     * with the motor side's velocity (motor observer / N) */
    a->tel.vel_out_enc = 0;
    if (a->obs_out_fb != 0u || a->mode == HD_MODE_STAB) {
        if (a->obs_out_run == 0u) {
            hd_velobs_start(&a->obs_out, a->pos_out, hd_div64_rnd(hd_velobs_vel48(&a->obs_mot), p->n));
            a->obs_out_run = 1u;
        }
        hd_velobs_step(&a->obs_out, &a->obs_out_cfg, a->pos_out);
        a->tel.vel_out_enc = hd_velobs_vel_out(&a->obs_out);
    } else {
        a->obs_out_run = 0u;
    }
    a->tel.vel_out = (a->obs_out_fb != 0u) ? a->tel.vel_out_enc : v_mot_out;
}

/* References of the mode in effect (trajectory, excitation, stabilisation)
 * -> p->mode, loops, v_ff, t_ff, t_out; tel.pos_ref, acc_ref, exc, vel_ref. */
static void phase_references(hd_app_t *a, hd_period_t *p)
{
    p->mode = (a->fault != HD_FAULT_NONE) ? HD_MODE_OFF : a->mode;
    a->tel.pos_ref = a->pos_out;
    p->v_ff = 0;
    a->tel.acc_ref = 0;
    p->t_ff = a->torque_cmd;
    a->tel.exc = 0;
    p->loops = HD_LOOPS_NONE;
    a->tel.vel_ref = 0;
    p->t_out = 0;

    switch (p->mode) {
    case HD_MODE_TORQUE:
        p->t_out = a->torque_cmd;
        break;
    case HD_MODE_VELOCITY:
        a->tel.vel_ref = a->vel_cmd;
        p->loops = HD_LOOPS_VEL;
        break;
    case HD_MODE_POSITION:
        a->tel.pos_ref = a->pos_cmd;
        p->v_ff = a->vel_cmd;
        p->loops = HD_LOOPS_POS_VEL;
        break;
    case HD_MODE_PTP:
    case HD_MODE_RATE:
    case HD_MODE_SINE:
        hd_traj_step(&a->traj, &a->traj_cfg);
        a->tel.pos_ref = a->traj.pos;
        p->v_ff = a->traj.vel;
        a->tel.acc_ref = a->traj.acc;
        p->loops = HD_LOOPS_POS_VEL;
        break;
    case HD_MODE_EXCITATION:
        a->tel.exc = hd_exc_step(&a->exc, &a->exc_cfg);
        if (a->exc_inj == HD_INJ_TORQUE) {
            p->t_out = a->tel.exc;
        } else if (a->exc_inj == HD_INJ_VEL_REF) {
            a->tel.vel_ref = a->tel.exc;
            p->loops = HD_LOOPS_VEL;
        } else if (a->exc_inj == HD_INJ_TORQUE_FF) {
            a->tel.pos_ref = a->hold_pos;
            p->t_ff = hdf_add_sat(p->t_ff, a->tel.exc);
            p->loops = HD_LOOPS_POS_VEL;
        } else {
            a->tel.pos_ref = hdf_add64_sat(a->hold_pos, a->tel.exc);
            p->loops = HD_LOOPS_POS_VEL;
        }
        break;
    case HD_MODE_STAB:
        if ((p->sn.valid & HD_HAL_VALID_GYRO) == 0u && (p->fen & HD_FCHK_SENSOR)) {
            trip(a, HD_FAULT_SENSOR);
        }
        if (a->stab_primed == 0u) {
            hd_stab_start(&a->stab, &a->stab_cfg, a->pos_out, p->sn.gyro_rate, a->tel.vel_out_enc);
            a->stab_primed = 1u;
        }
        hd_stab_step(&a->stab, &a->stab_cfg, p->sn.gyro_rate, a->pos_out, a->vel_cmd);
        a->tel.pos_ref = hdf_add64_sat(a->pos_out, a->stab.err);   /* pos_err = inertial-angle error */
        p->v_ff = a->stab.vff;
        p->loops = HD_LOOPS_POS_VEL;
        break;
    default:
        break;
    }
    /* the reference before the bank's corrections ("at rest" of the hunt breaker) */
    p->ref_plain = a->tel.pos_ref;
    p->vff_plain = p->v_ff;
}

/* The bank's inputs of this period (pre and post). */
static inline void bank_inputs(hd_app_t *a, hd_period_t *p, bool est)
{
    p->cbi.pos_ref = a->tel.pos_ref;
    p->cbi.pos_out = est ? a->fb.pos_fb : a->pos_out;   /* last period's loop feedback */
    p->cbi.pos_mot = a->pos_mot;
    p->cbi.vel_ref = (p->mode == HD_MODE_STAB) ? a->stab.vff_db : p->v_ff;   /* friction FF without gyro-noise chatter */
    p->cbi.vel_fb = a->tel.vel_out;
    p->cbi.acc_ref = a->tel.acc_ref;
}

/* Compensator bank (position loops only): corrections of pos_ref / v_ff, its torque
 * feed-forward into t_ff, the velocity-integrator hand-over of a weight ramp;
 * then tel.pos_fb and tel.pos_err of the corrected reference. */
static void phase_comp_bank(hd_app_t *a, hd_period_t *p)
{
    /* semi-closed / dual-loop outside STAB: the loop closes on the motor-side estimate */
    const bool est = (a->fb_cfg.kind != (uint32_t)HD_FB_FULL_CLOSED) && p->mode != HD_MODE_STAB;
    hd_angle_t pos_fb = a->pos_out;
    if (p->loops == HD_LOOPS_POS_VEL) {
        hd_comp_bank_out_t cbo;
        if (a->cb_idle != 0u) {
            bank_idle_step(&a->cb, &a->cb_cfg, &cbo);       /* every correction 0, no weight moves */
            if (a->bs_idle == 0u) {
                bank_inputs(a, p, est);                     /* for backstepping alone */
            }
            if (est) {
                pos_fb = hd_fb_step(&a->fb, &a->fb_cfg, a->pos_out, 0);   /* motor / N (blend) */
            }
        } else {
            bank_inputs(a, p, est);
            /* velocity-integrator hand-over: the part of the friction FF that a weight ramp adds
             * this period, (w_k - w_k-1) x raw torque, is taken off the integrator (bumpless) */
            const int32_t w_str = a->cb.str.blend.w, w_lug = a->cb.lug.blend.w;
            hd_comp_bank_pre(&a->cb, &a->cb_cfg, &p->cbi, &cbo);
            if (a->cb.str.blend.w != w_str || a->cb.lug.blend.w != w_lug) {    /* else the part is exactly 0 */
                a->vel_pid.integ = hdf_sub64_sat(a->vel_pid.integ, hdf_shl64_sat(
                    (int64_t)hdf_mul_q(a->cb.str.tau_raw, a->cb.str.blend.w - w_str, 30u) +
                    (int64_t)hdf_mul_q(a->cb.lug.tau_raw, a->cb.lug.blend.w - w_lug, 30u), a->vel_cfg.shift));
            }
            if ((a->cb.enabled & HD_CB_PRE_MASK) == 0u) {
                a->cb_idle = bank_idle(&a->cb, &a->cb_cfg);     /* ramped out and settled? */
            }
            if (est) {
                pos_fb = hd_fb_step(&a->fb, &a->fb_cfg, a->pos_out, cbo.dpos);   /* motor / N - dpos (blend) */
            } else if (a->fb_cfg.kind == (uint32_t)HD_FB_FULL_CLOSED) {
                a->tel.pos_ref = hdf_add64_sat(a->tel.pos_ref, cbo.dpos);        /* 0 in full closed (dvel instead) */
            }
            p->v_ff = hdf_add_sat(p->v_ff, cbo.dvel);
            p->t_ff = hdf_add_sat(p->t_ff, cbo.tff);
        }
    }
    a->tel.pos_fb = pos_fb;
    a->tel.pos_err = hdf_sat32(hdf_sub64_sat(a->tel.pos_ref, pos_fb));
}

/* Standstill hunt breaker (file header comment): at rest and hunting, the Stribeck
 * FF in p->t_ff fades to its running mean and back; otherwise disarmed. */
static void phase_hunt_breaker(hd_app_t *a, hd_period_t *p)
{
    const uint32_t hold_ticks = (uint32_t)param_raw(a, HD_P_HOLD_TICKS);
    if (p->loops == HD_LOOPS_POS_VEL && hold_ticks > 0u && p->mode != HD_MODE_STAB) {
        if (p->ref_plain != a->inpos_ref_prev || p->vff_plain != 0) {
            a->inpos_n = 0u;                    /* the reference moves: full FF at once */
            a->inpos_on = 0u;
            a->inpos_w = HD_Q30_ONE;
        } else if (a->inpos_n < hold_ticks) {
            a->inpos_n++;
        }
        a->inpos_ref_prev = p->ref_plain;
        if (a->inpos_on != 0u) {
            /* breaking a hunt: fade to the mean, then back */
            if (a->inpos_w > a->inpos_dw) {
                a->inpos_w -= a->inpos_dw;
            } else {
                a->inpos_w = 0;
                a->inpos_on = 0u;
                a->inpos_n = 0u;                /* re-armed hold_ticks after the fade back */
            }
        } else if (a->inpos_w < HD_Q30_ONE) {
            a->inpos_w = (a->inpos_w < HD_Q30_ONE - a->inpos_dw) ? a->inpos_w + a->inpos_dw : HD_Q30_ONE;
        } else if (a->inpos_n >= hold_ticks && hdf_abs_sat(a->tel.pos_err) > param_raw(a, HD_P_HOLD_HUNT_WIN)) {
            a->inpos_on = 1u;                   /* hunting at rest */
        }
        if (a->inpos_w < HD_Q30_ONE) {
            /* the Stribeck FF (already in t_ff) -> mean + w (FF - mean) */
            const int32_t mean = hdf_sat32(hdf_asr64_rnd(a->inpos_tau, 16u));
            p->t_ff = hdf_sub_sat(p->t_ff, hdf_mul_q(hdf_sub_sat(a->cb.str.tau, mean), HD_Q30_ONE - a->inpos_w, 30u));
        } else {
            const int64_t d = hdf_sub64_sat(hdf_shl64_sat((int64_t)a->cb.str.tau, 16u), a->inpos_tau);
            a->inpos_tau = hdf_add64_sat(a->inpos_tau, hdf_asr64_rnd(d, HD_INPOS_TAU_SHIFT));
        }
    } else {
        a->inpos_n = 0u;
        a->inpos_on = 0u;
        a->inpos_w = HD_Q30_ONE;
        a->inpos_ref_prev = p->ref_plain;
    }
}

/* The cascade: position PID -> velocity PID (+ acceleration FF) -> backstepping
 * blend -> torque filters, then the torque limit -> tel.vel_ref, p->t_out, t_cmd. */
static void phase_loops(hd_app_t *a, hd_period_t *p)
{
    if (p->loops == HD_LOOPS_POS_VEL) {
        /* gain 1.0 (the default): the Q30 product is v_ff itself, exactly */
        const int32_t gain = param_raw(a, HD_P_VFF_GAIN);
        const hd_vel_out_t vff = (gain == HD_Q30_ONE) ? p->v_ff : hdf_mul_q(p->v_ff, gain, 30u);
        /* the loops' gain shifts are set in hd_app_apply_params: 16 (position), 32 (velocity) */
        /* no D in the position loops (kd_fs 0, hd_app_apply_params) */
        a->tel.vel_ref = hd_pid_step_pi_q(&a->pos_pid, (p->mode == HD_MODE_STAB) ? &a->stab_pos_cfg : &a->pos_cfg,
                                          a->tel.pos_err, vff, 16u);
    }
    if (p->loops != HD_LOOPS_NONE) {
        /* acceleration feed-forward: aff_k [Q32.32 N.m per turn/s^2] * acc [2^-24 turn/s^2] -> Q16 N.m */
        if (a->tel.acc_ref != 0 && a->aff_k != 0) {    /* else the product is exactly 0 */
            p->t_ff = hdf_add_sat(p->t_ff, hdf_sat32(hdf_mul64x32_q(a->aff_k, a->tel.acc_ref, 40u)));
        }
        int32_t t = hd_pid_step_q(&a->vel_pid, &a->vel_cfg, a->tel.vel_ref, a->tel.vel_out, p->t_ff, 32u);
        if (p->loops == HD_LOOPS_POS_VEL) {
            if (a->bs_idle != 0u) {
                a->cb.u_bs = t;                 /* what the bank's post step records when off */
            } else {
                t = hd_comp_bank_post(&a->cb, &a->cb_cfg, &p->cbi, t);
                if ((a->cb.enabled & HD_CB_BACKSTEP) == 0u) {
                    a->bs_idle = bs_idle(&a->cb);           /* ramped out? */
                }
            }
        }
        p->t_out = hd_biquad_chain_step(&a->filt, &a->filt_cfg, t);
    }
    const int32_t tlim = param_raw(a, HD_P_TORQUE_LIMIT);
    p->t_cmd = hdf_clamp32(p->t_out, hdf_neg_sat(tlim), tlim);
}

/* Limits and faults (latched; each check enabled by its fault_enable bit). */
static void phase_limits_faults(hd_app_t *a, const hd_period_t *p)
{
    if (p->mode == HD_MODE_OFF) {
        return;
    }
    const uint32_t fen = p->fen;
    const int32_t tlim = param_raw(a, HD_P_TORQUE_LIMIT);
    /* The velocity PI's clamp counts only while its output is the torque the drive applies:
     * while the backstepping law drives the position loops (blending in, at full weight or
     * blending out) the PI runs alongside unapplied, and its integrator winds on a position
     * error the law holds (a heavy axis' friction lag) into its clamp with the applied torque
     * far below the limit; the applied torque's own clamp (t_cmd) still counts */
    const bool pi_applied = (p->loops != HD_LOOPS_NONE) &&
                            !((p->loops == HD_LOOPS_POS_VEL) && (a->bs_idle == 0u));
    if (hdf_abs_sat(p->t_cmd) >= tlim || (pi_applied && a->vel_pid.saturated)) {
        a->sat_count++;
    } else {
        a->sat_count = 0;
    }
    if ((fen & HD_FCHK_TORQUE_SAT) && a->sat_count > (uint32_t)param_raw(a, HD_P_TORQUE_SAT_TIME)) {
        trip(a, HD_FAULT_TORQUE_SAT);
    }
    if ((fen & HD_FCHK_OVERSPEED) && hdf_abs_sat(a->tel.vel_out) > param_raw(a, HD_P_VEL_TRIP)) {
        trip(a, HD_FAULT_OVERSPEED);
    }
    if ((fen & HD_FCHK_TRAVEL) &&
        (a->pos_out < a->travel_min_q || a->pos_out > a->travel_max_q)) {
        trip(a, HD_FAULT_TRAVEL);
    }
    if ((fen & HD_FCHK_FOLLOWING) && p->loops == HD_LOOPS_POS_VEL &&
        hdf_abs_sat(a->tel.pos_err) > param_raw(a, HD_P_FOLLOW_ERR_MAX)) {
        trip(a, HD_FAULT_FOLLOWING);
    }
}

/* Command: power stage off on a fault or in OFF (loops reset), else motor torque
 * t_cmd / N and current / Kt to the hal; the bank learns the torque applied. */
static void phase_command(hd_app_t *a, hd_period_t *p)
{
    if (a->fault != HD_FAULT_NONE || p->mode == HD_MODE_OFF) {
        if (a->fault != HD_FAULT_NONE && a->mode != HD_MODE_OFF) {
            a->mode = HD_MODE_OFF;
            reset_loops(a);
        }
        p->cmd.torque = 0;
        p->cmd.current = 0;
        p->cmd.enable = 0;
    } else {
        p->cmd.torque = div32_rnd(p->t_cmd, p->n);
        p->cmd.current = div_q16_rnd(p->cmd.torque, param_raw(a, HD_P_KT));
        p->cmd.enable = 1;
    }
    hd_hal_write_command(&p->cmd);
    hd_comp_bank_end(&a->cb, p->cmd.enable ? p->t_cmd : 0);
}

/* The rest of the period's telemetry (a->tel) and the capture of the armed signals. */
static void phase_telemetry(hd_app_t *a, const hd_period_t *p)
{
    hd_telemetry_t *t = &a->tel;
    t->tick = (a->started > 1u) ? t->tick + 1u : 0u;
    a->started = 2u;
    t->mode = a->mode;
    t->fault = a->fault;
    t->pos_out = a->pos_out;
    t->pos_mot = a->pos_mot;
    t->vel_mot = hdf_asr32_rnd(hd_velobs_vel48(&a->obs_mot), 24u);
    t->torque_cmd = p->cmd.enable ? p->t_cmd : 0;
    t->motor_torque = p->cmd.torque;
    t->current = p->sn.current;
    t->gyro = p->sn.gyro_rate;

    if (a->cap.state == HD_CAP_ARMED || a->cap.state == HD_CAP_TRIGGERED) {
        int32_t smp[HD_CAPTURE_MAX_CH];
        uint32_t i;
        for (i = 0; i < a->cap.cfg.n_ch; i++) {
            smp[i] = signal(a, a->cap_sig[i]);
        }
        hd_capture_step(&a->cap, smp);
    }
}

/* Instruction-count probe between the phases (tests/bench/15_phase_cost.sh builds
 * the cost image with HD_APP_PHASE_PROBE defined); nothing in the firmware. */
#ifdef HD_APP_PHASE_PROBE
void hd_app_phase_mark(void);
#define PHASE_MARK() hd_app_phase_mark()
#else
#define PHASE_MARK() ((void)0)
#endif

bool hd_app_background(hd_app_t *a)
{
    return hd_comp_bank_fric_est_work(&a->cb);
}

void hd_app_step(hd_app_t *a)
{
    hd_period_t p;
    PHASE_MARK();
    phase_sensors(a, &p);
    PHASE_MARK();
    phase_references(a, &p);
    PHASE_MARK();
    phase_comp_bank(a, &p);
    PHASE_MARK();
    phase_hunt_breaker(a, &p);
    PHASE_MARK();
    phase_loops(a, &p);
    PHASE_MARK();
    phase_limits_faults(a, &p);
    PHASE_MARK();
    phase_command(a, &p);
    PHASE_MARK();
    /* slow slot: online Stribeck identification (steady reference velocity, torque applied);
     * an excitation is an identification experiment, not the normal motion the estimator
     * learns from: its steps are not observed, and its fed config and pending parameter
     * changes wait for the end of the experiment */
    if (a->fe_idle == 0u && a->mode == HD_MODE_EXCITATION) {
        hd_fric_est_skip(&a->cb.fe);
    } else if (a->fe_idle == 0u) {
        if (hd_comp_bank_fric_est_tick(&a->cb, &a->cb_cfg)) {
            /* the step's observation (its inputs computed only in its period) */
            hd_fric_est_observe(&a->cb.fe, &a->cb_cfg.fe, p.vff_plain, a->tel.vel_out, p.cmd.enable ? p.t_cmd : 0,
                                p.loops == HD_LOOPS_POS_VEL && p.cmd.enable != 0);
        }
        if (a->cb_cfg.fe_on == 0u) {
            a->fe_idle = fe_idle(&a->cb, &a->cb_cfg);      /* the feed ramped out? */
        }
    }
    phase_telemetry(a, &p);
    PHASE_MARK();
}
