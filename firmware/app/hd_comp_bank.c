/*
 * hd_comp_bank.c - the compensators composed for the drive (contract: hd_comp_bank.h).
 */
#include "hd_comp_bank.h"
#include "hd_fixed.h"

#define CB_TWO_PI_Q28   1686629713      /* round(2 pi 2^28) */
#define CB_4PI2_Q24     662337939       /* round(4 pi^2 2^24) */

static int32_t prm(const int32_t *p, hd_param_id_t id)
{
    return p[id];
}

/* 1 - exp(-2 pi fc T) in Q30 from fc in Q16 Hz, T = 1 / rate_hz (at least 1 LSB) */
static int32_t lpf_alpha_at(int32_t fc_q16, int32_t rate_hz)
{
    const int32_t x = hdf_sat32(hd_div64_rnd(hdf_mul64x32_q((int64_t)fc_q16, CB_TWO_PI_Q28, 28u), rate_hz));
    const int32_t a = HD_Q30_ONE - hd_exp_neg_q16(x);
    return (a < 1) ? 1 : a;
}

/* the same at the control rate */
static int32_t lpf_alpha(int32_t fc_q16)
{
    return lpf_alpha_at(fc_q16, HD_LOOP_HZ);
}

int32_t hd_comp_bank_config(hd_comp_bank_cfg_t *c, const int32_t param[HD_PARAM_COUNT])
{
    const int32_t *p = param;
    uint32_t i;
    c->enable = (uint32_t)prm(p, HD_P_CB_ENABLE) & (HD_CB_ALL | HD_CB_COMPLIANCE);
    c->ramp_ticks = (uint32_t)prm(p, HD_P_CB_RAMP_TICKS);
    /* full closed: the corrections lead the motor (dvel); else the feedback estimate uses them */
    c->pos_mode = (prm(p, HD_P_FB_CONFIG) != 0) ? 1u : 0u;
    c->dpos_alpha = lpf_alpha(prm(p, HD_P_CB_DPOS_FC));

    /* Stribeck feed-forward */
    c->str.pos.fc = prm(p, HD_P_STR_FC_POS);
    c->str.pos.fs = prm(p, HD_P_STR_FS_POS);
    c->str.pos.vs = prm(p, HD_P_STR_VS_POS);
    c->str.pos.fv = prm(p, HD_P_STR_FV_POS);
    c->str.neg.fc = prm(p, HD_P_STR_FC_NEG);
    c->str.neg.fs = prm(p, HD_P_STR_FS_NEG);
    c->str.neg.vs = prm(p, HD_P_STR_VS_NEG);
    c->str.neg.fv = prm(p, HD_P_STR_FV_NEG);
    c->str.delta = (uint32_t)prm(p, HD_P_STR_DELTA);
    c->str.eps_v = prm(p, HD_P_STR_EPS_V);
    c->str.w_ref = prm(p, HD_P_STR_W_REF);
    c->str.tau_max = prm(p, HD_P_STR_TAU_MAX);
    c->str.cruise_ticks = (uint32_t)prm(p, HD_P_STR_CRUISE_TICKS);
    c->str.steady_vs = prm(p, HD_P_STR_STEADY_VS);

    /* LuGre */
    c->lug.g.fc = prm(p, HD_P_LUG_FC);
    c->lug.g.fs = prm(p, HD_P_LUG_FS);
    c->lug.g.vs = prm(p, HD_P_LUG_VS);
    c->lug.g.fv = 0;
    c->lug.delta = (uint32_t)prm(p, HD_P_LUG_DELTA);
    c->lug.sigma0 = prm(p, HD_P_LUG_SIGMA0);
    c->lug.sigma1 = prm(p, HD_P_LUG_SIGMA1);
    c->lug.sigma2 = prm(p, HD_P_LUG_SIGMA2);
    c->lug.k_obs = prm(p, HD_P_LUG_K_OBS);
    c->lug.tau_max = prm(p, HD_P_LUG_TAU_MAX);
    c->lug_v_src = (uint32_t)prm(p, HD_P_LUG_V_SRC);

    /* Maxwell-slip: compliance 2^-44 turn/N.m = 2^52 / K[Q23.8 N.m/turn] (K >= 2^13 N.m/turn) */
    {
        static const hd_param_id_t K[8] = {HD_P_MX_K1, HD_P_MX_K2, HD_P_MX_K3, HD_P_MX_K4,
                                           HD_P_MX_K5, HD_P_MX_K6, HD_P_MX_K7, HD_P_MX_K8};
        static const hd_param_id_t D[8] = {HD_P_MX_D1, HD_P_MX_D2, HD_P_MX_D3, HD_P_MX_D4,
                                           HD_P_MX_D5, HD_P_MX_D6, HD_P_MX_D7, HD_P_MX_D8};
        const int32_t kst = prm(p, HD_P_MX_STIFFNESS);
        const int64_t comp = hd_div64_rnd((int64_t)1 << 52, (kst > 0) ? kst : 1);
        if (comp > INT32_MAX) {
            return -1;
        }
        c->mx.n = (uint32_t)prm(p, HD_P_MX_N);
        c->mx.compliance = (int32_t)comp;
        c->mx.tau_max = prm(p, HD_P_MX_TAU_MAX);
        for (i = 0; i < HD_MAXWELL_N_MAX; i++) {
            c->mx.k[i] = (i < 8u) ? prm(p, K[i]) : 0;
            c->mx.d[i] = (i < 8u) ? prm(p, D[i]) : 0;
        }
    }

    /* Preisach inverse */
    c->pr_deadband = (uint32_t)prm(p, HD_P_PR_DEADBAND);
    /* the estimate from the model runs once per cycle (slow rate), the one from the command every
     * period: it closes a loop through the torque command, where the delay of a held estimate
     * would cost the phase margin */
    c->pr_alpha = lpf_alpha_at(prm(p, HD_P_PR_FC), (prm(p, HD_P_PR_T_SRC) != 0) ? (int32_t)HD_SCHED_SLOW_HZ : HD_LOOP_HZ);
    c->pr_share = prm(p, HD_P_PR_MOTOR_SHARE);
    c->pr_t_src = (uint32_t)prm(p, HD_P_PR_T_SRC);
    c->pr_jl = prm(p, HD_P_PR_JL);
    c->pr_mgl = prm(p, HD_P_PR_MGL);
    c->pr_g_off = (uint32_t)prm(p, HD_P_PR_G_OFF);
    /* pr_t_src 2: the motor-side estimate at the slow rate, handed over below 2 vs of the Stribeck FF */
    c->gt.jm = prm(p, HD_P_PR_JM);
    c->gt.vs = c->str.pos.vs;
    c->gt.step_hz = (int32_t)HD_SCHED_SLOW_HZ;

    /* scheduled position integral: leak T in Q30 from the leak rate in Q16 1/s */
    c->pki = prm(p, HD_P_CB_PKI);
    c->pki_vlo = prm(p, HD_P_CB_PKI_VLO);
    c->pki_vhi = prm(p, HD_P_CB_PKI_VHI);
    c->pki_leak_dt = hdf_sat32(hd_div64_rnd(hdf_shl64_sat((int64_t)prm(p, HD_P_CB_PKI_LEAK), 14u), HD_LOOP_HZ));
    c->pki_max = prm(p, HD_P_CB_PKI_MAX);
    if (c->pki_vlo > c->pki_vhi) {
        return -1;
    }

    /* compliance: three-slope twist (1/K computed here, not in the period) */
    if (hd_compliance_design(&c->cp, prm(p, HD_P_CP_K1), prm(p, HD_P_CP_K2), prm(p, HD_P_CP_K3),
                             prm(p, HD_P_CP_T1), prm(p, HD_P_CP_T2)) != 0) {
        return -1;
    }

    /* transmission error */
    {
        static const hd_param_id_t O[4] = {HD_P_TE_ORDER1, HD_P_TE_ORDER2, HD_P_TE_ORDER3, HD_P_TE_ORDER4};
        static const hd_param_id_t A[4] = {HD_P_TE_AMP1, HD_P_TE_AMP2, HD_P_TE_AMP3, HD_P_TE_AMP4};
        static const hd_param_id_t F[4] = {HD_P_TE_PHASE1, HD_P_TE_PHASE2, HD_P_TE_PHASE3, HD_P_TE_PHASE4};
        c->te.n = (uint32_t)prm(p, HD_P_TE_N);
        c->te.k1 = prm(p, HD_P_TE_K1);
        c->te.tau_max = prm(p, HD_P_TE_TAU_MAX);
        for (i = 0; i < HD_TE_N_MAX; i++) {
            c->te.order[i] = (i < 4u) ? (uint32_t)prm(p, O[i]) : 0u;
            c->te.amp[i] = (i < 4u) ? prm(p, A[i]) : 0;
            c->te.phase[i] = (i < 4u) ? (uint32_t)prm(p, F[i]) : 0u;   /* modulo 2^32: a turn fraction */
        }
        /* output-side lines: the same harmonic model on the output angle (orders per output turn) */
        static const hd_param_id_t OO[2] = {HD_P_TE_OUT_ORDER1, HD_P_TE_OUT_ORDER2};
        static const hd_param_id_t OA[2] = {HD_P_TE_OUT_AMP1, HD_P_TE_OUT_AMP2};
        static const hd_param_id_t OF[2] = {HD_P_TE_OUT_PHASE1, HD_P_TE_OUT_PHASE2};
        c->te_out.n = 0u;
        c->te_out.k1 = 0;
        c->te_out.tau_max = 1;
        for (i = 0; i < HD_TE_N_MAX; i++) {
            c->te_out.order[i] = 0u;
            c->te_out.amp[i] = 0;
            c->te_out.phase[i] = 0u;
        }
        for (i = 0; i < 2u; i++) {
            if (prm(p, OO[i]) > 0 && prm(p, OA[i]) != 0) {
                c->te_out.order[c->te_out.n] = (uint32_t)prm(p, OO[i]);
                c->te_out.amp[c->te_out.n] = prm(p, OA[i]);
                c->te_out.phase[c->te_out.n] = (uint32_t)prm(p, OF[i]);
                c->te_out.n++;
            }
        }
        hd_te_cfg_ranges(&c->te);
        hd_te_cfg_ranges(&c->te_out);
    }

    /* backstepping */
    {
        static const hd_param_id_t G[4] = {HD_P_BS_GAMMA1, HD_P_BS_GAMMA2, HD_P_BS_GAMMA3, HD_P_BS_GAMMA4};
        static const hd_param_id_t LO[4] = {HD_P_BS_MIN1, HD_P_BS_MIN2, HD_P_BS_MIN3, HD_P_BS_MIN4};
        static const hd_param_id_t HI[4] = {HD_P_BS_MAX1, HD_P_BS_MAX2, HD_P_BS_MAX3, HD_P_BS_MAX4};
        static const hd_param_id_t T0[4] = {HD_P_BS_TH0_1, HD_P_BS_TH0_2, HD_P_BS_TH0_3, HD_P_BS_TH0_4};
        c->bs.c1 = prm(p, HD_P_BS_C1);
        c->bs.c2 = prm(p, HD_P_BS_C2);
        c->bs.j = prm(p, HD_P_BS_J);
        c->bs.ke = prm(p, HD_P_BS_KE);
        c->bs.eps_w = prm(p, HD_P_BS_EPS_W);
        c->bs.w_s = prm(p, HD_P_BS_W_S);
        c->bs.e1_max = prm(p, HD_P_BS_E1_MAX);
        c->bs.u_max = prm(p, HD_P_BS_U_MAX);
        for (i = 0; i < HD_BS_NP; i++) {
            c->bs.gamma_dt[i] = prm(p, G[i]);
            c->bs.th_min[i] = prm(p, LO[i]);
            c->bs.th_max[i] = prm(p, HI[i]);
            c->bs_th0[i] = prm(p, T0[i]);
            if (c->bs.th_min[i] > c->bs.th_max[i]) {
                return -1;
            }
        }
    }

    /* online Stribeck identification */
    c->fe_on = (prm(p, HD_P_FE_ENABLE) != 0) ? 1u : 0u;
    c->fe_feed = (prm(p, HD_P_FE_FEED) != 0) ? 1u : 0u;
    c->fe_share = prm(p, HD_P_FE_SHARE);
    c->fe_decim = (prm(p, HD_P_FE_DECIM) > 0) ? (uint32_t)prm(p, HD_P_FE_DECIM) : 1u;
    c->fe_ramp = (uint32_t)prm(p, HD_P_FE_RAMP);
    if (hd_fric_est_config(&c->fe, prm(p, HD_P_FE_V_MIN), prm(p, HD_P_FE_VS_LO), prm(p, HD_P_FE_DV_MAX),
                           (uint32_t)prm(p, HD_P_FE_SETTLE), (uint32_t)prm(p, HD_P_FE_FORGET),
                           (uint32_t)prm(p, HD_P_FE_N_MIN), (uint32_t)prm(p, HD_P_FE_N_KEEP),
                           (uint32_t)prm(p, HD_P_FE_MAX_AGE), prm(p, HD_P_FE_TAU_MAX), prm(p, HD_P_FE_FV_MAX)) != 0) {
        return -1;
    }

    /* disturbance observer: its Q filter's step at the slow rate, 1 - exp(-g T_slow) (Q30; exact,
     * so stable for every corner up to its 500 Hz maximum), and g J (Q15.16 N.m/(turn/s)) = 4 pi^2 fc J */
    {
        const int32_t fc = prm(p, HD_P_DOB_FC);
        c->dob_g_t = lpf_alpha_at(fc, (int32_t)HD_SCHED_SLOW_HZ);
        c->dob_gj = hdf_sat32(hdf_mul64x32_q(hdf_mul64x32_q((int64_t)prm(p, HD_P_DOB_J), fc, 16u),
                                           CB_4PI2_Q24, 24u));
    }
    return 0;
}

/* Ramps in steps of each compensator: the decimated ones (hd_sched.h) step once per
 * cycle, so the same time is ramp / HD_SCHED_CYCLE of their steps (rounded up). */
static void set_blend_ramps(hd_comp_bank_t *b, uint32_t ramp)
{
    const uint32_t slow = (ramp + HD_SCHED_CYCLE - 1u) >> HD_SCHED_LOG2;
    b->str.blend.ramp_ticks = ramp;
    b->lug.blend.ramp_ticks = slow;
    b->mx.blend.ramp_ticks = slow;
    b->pr.blend.ramp_ticks = slow;
    b->te.blend.ramp_ticks = slow;
    b->bs.blend.ramp_ticks = ramp;
    b->dob_blend.ramp_ticks = slow;
    b->cp_blend.ramp_ticks = slow;
}

static void ex_reset(hd_cb_extrap_t *x)
{
    x->v = 0;
    x->last = 0;
    x->inc = 0;
    x->primed = 0u;
}

/* A new sample: the value now, and the increment of each tick until the next one */
static int64_t ex_sample(hd_cb_extrap_t *x, int64_t smp)
{
    x->inc = (x->primed != 0u) ? hdf_asr64_rnd(hdf_sub64_sat(smp, x->last), HD_SCHED_LOG2) : 0;
    x->last = smp;
    x->v = smp;
    x->primed = 1u;
    return smp;
}

/* A tick without a sample: one increment further */
static void ex_tick(hd_cb_extrap_t *x)
{
    x->v = hdf_add64_sat(x->v, x->inc);
}

/* the estimator from the Stribeck FF parameters, empty bins */
static void fe_reset(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    hd_stribeck_dir_t init[HD_FE_NDIR];
    init[HD_FE_DIR_POS] = c->str.pos;
    init[HD_FE_DIR_NEG] = c->str.neg;
    hd_fric_est_init(&b->fe, init, c->fe_ramp, (c->fe_on & c->fe_feed) != 0u);
    b->fe_str = c->str;
    b->fe_tick = 0u;
    b->fe_v_min = c->fe.v_min;
    b->fe_vs_lo = c->fe.vs_lo;
}

/* The estimator's side of a parameter change (new binning: empty bins; new str_* map: the
 * estimate without a fit follows it; the config the background works with).  The background
 * (hd_comp_bank_fric_est_work) may be inside a part, preempted by the control period: then
 * its state is left alone and the change is applied in the first period in which no part is
 * in progress (hd_comp_bank_fric_est). */
#define FE_PEND_RESET 1u
#define FE_PEND_SEED 2u
#define FE_PEND_CFG 4u
/* 1 when the control period's part is the inline one (hd_comp_bank_fric_est): the estimator
 * on, nothing pending, fe_decim >= 2 (the observation and the fed config in periods of their
 * own) */
static void fe_fast_set(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    b->fe_fast = (c->fe_on != 0u && b->fe_pend == 0u && c->fe_decim >= 2u) ? 1u : 0u;
}

static void fe_sync(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    if (b->fe_pend == 0u || hd_fric_est_busy(&b->fe)) {
        fe_fast_set(b, c);
        return;
    }
    if ((b->fe_pend & FE_PEND_RESET) != 0u) {
        const hd_blend_t feed = b->fe.feed;
        fe_reset(b, c);
        b->fe.feed = feed;
    } else if ((b->fe_pend & FE_PEND_SEED) != 0u) {
        /* new str_* parameters (written after the estimator started, e.g. one SDO at a
         * time): an estimate without a fit is the model in force, else the feed would put
         * the start-up map (the defaults) into the FF */
        hd_stribeck_dir_t init[HD_FE_NDIR];
        init[HD_FE_DIR_POS] = c->str.pos;
        init[HD_FE_DIR_NEG] = c->str.neg;
        hd_fric_est_seed(&b->fe, init);
    }
    b->fe_cfg = c->fe;
    b->fe_base = c->str;
    b->fe_base_share = c->fe_share;
    b->fe.feed.ramp_ticks = c->fe_ramp;
    if (b->fe.feed.w == 0) {
        b->fe_str = c->str;     /* a feed switched on starts from the parameters in force */
        b->fe_next = c->str;
    }
    hd_fric_est_set_feed(&b->fe, (c->fe_on & c->fe_feed) != 0u);
    b->fe_pend = 0u;
    fe_fast_set(b, c);
}

void hd_comp_bank_init(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    const uint32_t en = c->enable;
    const uint32_t r = c->ramp_ticks;
    uint32_t i;
    /* placeholder table: L = 2, all zero (valid), until one is installed */
    b->table.version = 0u;
    b->table.levels = 2u;
    b->table.sub_bits = 0u;
    b->table.in_shift = 0u;
    b->table.u0 = 0;
    b->table.unit = HD_PREISACH_UNIT_GENERIC;
    for (i = 0; i < HD_PREISACH_N_MAX; i++) {
        b->table.e[i] = 0;
    }
    hd_preisach_seal(&b->table);
    b->table_ok = 0u;
    hd_stribeck_init(&b->str, r, (en & HD_CB_STRIBECK) != 0u);
    hd_lugre_init(&b->lug, r, (en & HD_CB_LUGRE) != 0u);
    hd_maxwell_init(&b->mx, r, (en & HD_CB_MAXWELL) != 0u);
    hd_preisach_inv_init(&b->pr, &b->table, c->pr_deadband, r, (en & HD_CB_PREISACH) != 0u);
    hd_te_comp_init(&b->te, r, (en & HD_CB_TE) != 0u);
    hd_backstep_init(&b->bs, &c->bs, c->bs_th0, r, (en & HD_CB_BACKSTEP) != 0u);
    hd_blend_init(&b->dob_blend, r, (en & HD_CB_DOB) != 0u);
    hd_blend_init(&b->cp_blend, r, (en & HD_CB_COMPLIANCE) != 0u);
    b->enabled = en;
    b->bs_preload = ((en & HD_CB_BACKSTEP) != 0u) ? 1u : 0u;
    b->dpos_f = 0;
    b->dpos_primed = 0u;
    b->pr_t = 0;
    b->te_out = 0;
    b->pr_dth = 0;
    b->dob_x = 0;
    b->dob_d = 0;
    b->t_prev = 0;
    b->out.dpos = 0;
    b->out.dvel = 0;
    b->out.tff = 0;
    b->u_bs = 0;
    b->pki_i = 0;
    b->pki_w = 0;
    b->pr_test = 0;
    b->cp_dth = 0;
    b->tick = 0u;
    b->pr_yd = 0;
    b->pr_lp_due = 0u;
    hd_gear_torque_reset(&b->gt);
    ex_reset(&b->mx_x);
    b->te_dth = 0;
    b->te_out_dth = 0;
    b->te_mot = 0;
    b->te_slope = 0;
    set_blend_ramps(b, r);
    fe_reset(b, c);
    b->fe_cfg = c->fe;
    b->fe_base = c->str;
    b->fe_base_share = c->fe_share;
    b->fe_next = c->str;
    b->fe_pend = 0u;
    fe_fast_set(b, c);
}

void hd_comp_bank_apply(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    const uint32_t en = c->enable;
    const uint32_t ch = en ^ b->enabled;
    set_blend_ramps(b, c->ramp_ticks);
    b->pr.fwd.deadband = c->pr_deadband;
    if (ch & HD_CB_STRIBECK) hd_stribeck_set_enabled(&b->str, (en & HD_CB_STRIBECK) != 0u);
    if (ch & HD_CB_LUGRE) hd_lugre_set_enabled(&b->lug, (en & HD_CB_LUGRE) != 0u);
    if (ch & HD_CB_MAXWELL) hd_maxwell_set_enabled(&b->mx, (en & HD_CB_MAXWELL) != 0u);
    if (ch & HD_CB_PREISACH) hd_preisach_inv_set_enabled(&b->pr, (en & HD_CB_PREISACH) != 0u);
    if (ch & HD_CB_TE) hd_te_comp_set_enabled(&b->te, (en & HD_CB_TE) != 0u);
    if (ch & HD_CB_DOB) hd_blend_set_enabled(&b->dob_blend, (en & HD_CB_DOB) != 0u);
    if (ch & HD_CB_COMPLIANCE) hd_blend_set_enabled(&b->cp_blend, (en & HD_CB_COMPLIANCE) != 0u);
    if (ch & HD_CB_BACKSTEP) {
        const bool on = (en & HD_CB_BACKSTEP) != 0u;
        if (on && !hd_blend_active(&b->bs.blend)) {
            b->bs_preload = 1u;       /* engage from the present effort */
        }
        hd_backstep_set_enabled(&b->bs, on);
    }
    b->enabled = en;
    /* the estimator: new binning empties the bins, new str_* parameters seed an estimate
     * without a fit (fe_sync: at once, or after the background's part in progress); the
     * feed switch ramps */
    b->fe_pend |= FE_PEND_CFG | ((c->fe.v_min != b->fe_v_min || c->fe.vs_lo != b->fe_vs_lo) ? FE_PEND_RESET
                                                                                              : FE_PEND_SEED);
    fe_sync(b, c);
}

/* A new table's memory: the gear demagnetised at rest (input 0: no torque, no twist), not
 * negative saturation, which the torques of normal motion never reach again, so its
 * remanence would offset every predicted twist. */
static void table_memory(hd_comp_bank_t *b)
{
    hd_preisach_inv_search_reset(&b->pr);       /* a search of the old table means nothing */
    hd_preisach_demagnetise(&b->pr.fwd, &b->table, hd_preisach_quantise(&b->table, 0));
}

int32_t hd_comp_bank_install_table(hd_comp_bank_t *b, const hd_preisach_table_t *t)
{
    const int32_t rc = hd_preisach_install(&b->table, t);
    if (rc == HD_PREISACH_OK) {
        b->table_ok = 1u;
        table_memory(b);
    }
    return rc;
}

int32_t hd_comp_bank_adopt_table(hd_comp_bank_t *b)
{
    const int32_t rc = hd_preisach_check(&b->table);
    b->table_ok = (rc == HD_PREISACH_OK) ? 1u : 0u;
    if (rc == HD_PREISACH_OK) {
        table_memory(b);
    }
    return rc;
}

void hd_comp_bank_clear_table(hd_comp_bank_t *b)
{
    b->table_ok = 0u;
    hd_preisach_inv_search_reset(&b->pr);
}

/* A compensator is evaluated while enabled or while its weight is not 0 (ramping
 * out); fully off it costs nothing and keeps its last state. */
static bool running(const hd_comp_bank_t *b, uint32_t bit, const hd_blend_t *bl)
{
    return ((b->enabled & bit) != 0u) || hd_blend_active(bl);
}

/* Schedule weight w(|v|) in Q30: 0 at |v| <= lo, 1 at |v| >= hi, C1 cubic between
 * (hd_sign_smooth_q30 of |v| - mid over the half width; a step at lo if hi == lo). */
static int32_t pki_weight(const hd_comp_bank_cfg_t *c, hd_vel_out_t v)
{
    const int64_t av = hdf_abs64_sat((int64_t)v);
    const int64_t mid = ((int64_t)c->pki_vlo + (int64_t)c->pki_vhi) / 2;
    const int32_t hw = hdf_sat32(((int64_t)c->pki_vhi - (int64_t)c->pki_vlo) / 2);
    int32_t s;
    if (av <= (int64_t)c->pki_vlo) {
        return 0;
    }
    if (av >= (int64_t)c->pki_vhi) {
        return HD_Q30_ONE;
    }
    s = hd_sign_smooth_q30(hdf_sat32(av - mid), hw);
    return (int32_t)(((int64_t)HD_Q30_ONE + (int64_t)s + 1) / 2);
}

/* Scheduled position integral (hd_comp_bank.h): returns its velocity term, 2^-32 turn/s. */
static int32_t pki_step(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in)
{
    const int32_t w = (c->pki > 0) ? pki_weight(c, in->vel_ref) : 0;
    int64_t i = b->pki_i;
    b->pki_w = w;
    if (w == 0 && i == 0) {
        return 0;
    }
    /* an int32 x 2^16 cannot saturate: the product is the saturating shift */
    const int64_t imax = (int64_t)((c->pki_max > 0) ? c->pki_max : 0) * 65536;
    if (w > 0) {
        /* w Ki T e: e [2^-32 turn] * Ki [Q16 1/s^2] = 2^-48 turn/s^2; x w (Q30); x T */
        const int32_t e = hdf_sat32(hdf_sub64_sat(in->pos_ref, in->pos_out));
        const int64_t ke = hdf_mul64x32_q((int64_t)e * (int64_t)c->pki, w, 30u);
        i = hdf_add64_sat(i, hdf_div64_rnd_u16(ke, (uint32_t)HD_LOOP_HZ));
    }
    if (w < HD_Q30_ONE && i != 0) {
        /* leak (1 - w) leak T I; at least 1 LSB toward 0 so that it reaches 0 */
        int64_t d = hdf_mul64x32_q(hdf_mul64x32_q(i, c->pki_leak_dt, 30u), HD_Q30_ONE - w, 30u);
        if (d == 0 && c->pki_leak_dt > 0) {
            d = (i > 0) ? 1 : -1;
        }
        i = hdf_sub64_sat(i, d);
    }
    b->pki_i = hdf_clamp64(i, hdf_neg64_sat(imax), imax);
    return hdf_sat32(hdf_asr64_rnd(b->pki_i, 16u));
}

/* The estimate's low-pass at pr_fc: pr_test into pr_t, the filtered value held in b->pr_yd */
static void torque_lowpass(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    const int64_t tg = hdf_shl64_sat((int64_t)b->pr_test, 16u);
    b->pr_t = hdf_add64_sat(b->pr_t, hdf_mul64x32_q(hdf_sub64_sat(tg, b->pr_t), c->pr_alpha, 30u));
    b->pr_yd = hdf_sat32(hdf_asr64_rnd(b->pr_t, 16u));
    b->pr_lp_due = 0u;
}

/* The low-pass of a slot-4 motor-side estimate (pr_t_src 2), in the next period: before a
 * reader of pr_yd (Preisach, compliance) and before the next estimate, so each estimate is
 * filtered once and read as if filtered in its own tick (slot 4 then carries the estimate
 * alone; the app does not skip the bank while it is due, hd_app.c bank_idle) */
static void torque_lowpass_due(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    if (b->pr_lp_due != 0u) {
        torque_lowpass(b, c);
    }
}

/* The transmitted-torque estimate (Preisach and compliance) into b->pr_test, unfiltered */
static void torque_estimate(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in)
{
    int32_t test;
    if (c->pr_t_src != 0u) {
        /* model: load-side friction (1 - share) F(v_ref) + J_L a_ref (2 pi J [Q16] acc [2^-24 turn/s^2])
         * + the unbalance */
        const int32_t fl = hdf_mul_q(b->str.tau_raw, hdf_sub_sat(HD_Q30_ONE, c->pr_share), 30u);
        const int64_t ja = hdf_mul64x32_q(hdf_mul64x32_q((int64_t)c->pr_jl, in->acc_ref, 24u), CB_TWO_PI_Q28, 28u);
        test = hdf_add_sat(fl, hdf_sat32(ja));
        if (c->pr_mgl != 0) {
            /* the unbalance the gear holds, mgl cos(output angle + offset): at rest it is the
             * whole transmitted torque, so without it a position hold predicts no twist */
            int32_t sn, cs;
            hd_sincos_turn_fast((uint32_t)((uint64_t)in->pos_out & 0xFFFFFFFFu) + c->pr_g_off, &sn, &cs);
            test = hdf_add_sat(test, hdf_mul_q(c->pr_mgl, cs, 30u));
        }
        if (c->pr_t_src == 2u) {
            /* while the motor slides, the torque the motor side passes to the gear (its swings
             * set the hysteresis branch a stop keeps); the model near standstill */
            test = hd_gear_torque_step(&b->gt, &c->gt, b->t_prev, hdf_mul_q(b->str.tau_raw, c->pr_share, 30u),
                                       in->vel_ref, in->vel_fb, test);
        }
    } else {
        /* command: t_prev - share F(v_ref) (includes the loop's reaction) */
        test = hdf_sub_sat(b->t_prev, hdf_mul_q(b->str.tau_raw, c->pr_share, 30u));
    }
    b->pr_test = test;
}

/* One Preisach tick (slots 5 .. 7 of hd_sched.h, k the tick in the cycle): the twist at
 * the held torque estimate.  The blend steps once per cycle (its first Preisach tick). */
static void preisach_tick(hd_comp_bank_t *b, uint32_t k, uint32_t budget)
{
    int32_t u = b->pr.u;
    if (k == (uint32_t)HD_SLOT_PREISACH) {
        (void)hd_blend_update(&b->pr.blend);
    }
    if (b->table_ok == 0u) {
        u = 0;
    } else if (b->table.unit == HD_PREISACH_UNIT_TORQUE_TWIST) {
        /* a torque -> twist image is the twist operator itself: its forward
         * output at the torque is the twist (once per cycle) */
        if (k == (uint32_t)HD_SLOT_PREISACH) {
            u = hdf_sat32(hd_preisach_step_p(&b->pr.fwd, &b->table, hd_preisach_quantise(&b->table, b->pr_yd)));
        }
    } else if (hd_preisach_inv_search(&b->pr, &b->table, (int64_t)b->pr_yd, budget)) {
        /* a twist -> torque image (the gear's direction: hdservo identify, compsetup): the
         * twist is its inverse at the torque; the
         * bisection runs HD_SCHED_PR_TRIALS trials per tick, the twist changes when it ends */
        u = hd_preisach_dequantise(&b->table, b->pr.fwd.p_prev);
    }
    b->pr.u = u;
    b->pr_dth = hd_blend_apply(&b->pr.blend, u);
    b->pr.out = b->pr_dth;
}

/* ---- the slow work, one function per part of a slot (hd_sched.h) ---- */

/* LuGre, one step of HD_SCHED_CYCLE periods in three parts: g(v) and z_ss at the velocity
 * of its first tick, the step's exponential factor, the bristle update and torque */
static void lugre_g(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in)
{
    if (running(b, HD_CB_LUGRE, &b->lug.blend)) {
        hd_lugre_prep_g(&b->lug, &c->lug, (c->lug_v_src != 0u) ? in->vel_fb : in->vel_ref);
    }
}

static void lugre_exp(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    if (running(b, HD_CB_LUGRE, &b->lug.blend)) {
        hd_lugre_prep_exp_n(&b->lug, &c->lug, HD_SCHED_CYCLE);
    }
}

static void lugre_finish(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in)
{
    if (running(b, HD_CB_LUGRE, &b->lug.blend)) {
        (void)hd_lugre_finish_n(&b->lug, &c->lug, hdf_sub64_sat(in->pos_out, in->pos_ref), HD_SCHED_CYCLE);
    }
}

/* disturbance observer at the slow rate: x += a (T + g J w - x), d = x - g J w (states
 * Q15.16 x 2^16, a = 1 - exp(-g T_slow)) */
static void dob_step(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in)
{
    const int64_t gjw = hdf_mul64x32_q((int64_t)c->dob_gj, in->vel_fb, 16u);      /* Q15.16 x 2^16 */
    if (running(b, HD_CB_DOB, &b->dob_blend)) {
        const int64_t drive = hdf_add64_sat(hdf_shl64_sat((int64_t)b->t_prev, 16u), gjw);
        b->dob_x = hdf_add64_sat(b->dob_x, hdf_mul64x32_q(hdf_sub64_sat(drive, b->dob_x), c->dob_g_t, 30u));
        const int32_t d = hdf_sat32(hdf_asr64_rnd(hdf_sub64_sat(b->dob_x, gjw), 16u));
        (void)hd_blend_update(&b->dob_blend);
        b->dob_d = hd_blend_apply(&b->dob_blend, d);
    } else {
        /* cold: restart from d = 0 at the next enable */
        b->dob_x = gjw;
        b->dob_d = 0;
    }
}

/* Maxwell-slip at the position reference; extrapolated in the other ticks */
static void maxwell(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in, bool all)
{
    if (running(b, HD_CB_MAXWELL, &b->mx.blend)) {
        if (all) {
            ex_reset(&b->mx_x);     /* no increment from a sample of an earlier run */
        }
        (void)ex_sample(&b->mx_x, hd_maxwell_step(&b->mx, &c->mx, in->pos_ref));
        if (!hd_blend_active(&b->mx.blend)) {
            ex_reset(&b->mx_x);     /* ramped out: 0 from now on */
        }
    } else {
        ex_reset(&b->mx_x);
    }
}

/* the compliance twist at the held torque estimate: the output lags motor / N by it */
static void compliance(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    if (running(b, HD_CB_COMPLIANCE, &b->cp_blend)) {
        (void)hd_blend_update(&b->cp_blend);
        b->cp_dth = hd_blend_apply(&b->cp_blend, hd_compliance_twist(&c->cp, b->pr_yd));
    }
}

/* TE at the motor angle, with its slope for the ticks until the next step */
static void te_step(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in)
{
    if (running(b, HD_CB_TE, &b->te.blend)) {
        b->te_dth = hd_te_comp_step_slope(&b->te, &c->te, in->pos_mot, &b->te_slope);
        b->te_mot = in->pos_mot;
        b->te_out_dth = 0;
        if (c->te_out.n > 0u) {
            /* output-side lines at the output position the loop knows (semi-closed: the estimate;
             * a line of one per output turn moves by far less than an LSB between the two),
             * held: the output moves N times less than the motor */
            b->te_out = hd_te_model(&c->te_out, in->pos_out);
            b->te_out_dth = hd_blend_mix64(&b->te.blend, 0, hdf_neg64_sat(b->te_out));
        }
    }
}

/* The torque estimate and the Preisach twist, when either of its users runs */
static bool estimate_needed(const hd_comp_bank_t *b)
{
    return running(b, HD_CB_PREISACH, &b->pr.blend) || running(b, HD_CB_COMPLIANCE, &b->cp_blend);
}

static void preisach(hd_comp_bank_t *b, uint32_t k, uint32_t budget)
{
    if (running(b, HD_CB_PREISACH, &b->pr.blend)) {
        preisach_tick(b, k, budget);
    }
}

void hd_comp_bank_pre(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in,
                      hd_comp_bank_out_t *out)
{
    int32_t tff = 0;
    int64_t dpos;
    int32_t dv_i;
    const uint32_t k = b->tick & (HD_SCHED_CYCLE - 1u);
    /* the first period after the loops start (app reset, mode entry) evaluates every
     * compensator, so that the entry sees the whole correction (bumpless, hd_feedback.h);
     * the schedule then goes on from there */
    const bool all = (b->dpos_primed == 0u);
    b->tick = k + 1u;

    if (all) {
        b->pki_i = 0;           /* the loops were reset (app) or first period */
        hd_gear_torque_reset(&b->gt);
    }
    dv_i = pki_step(b, c, in);

    /* friction: the Stribeck map every period (also the torque estimate's model) */
    if (running(b, HD_CB_STRIBECK, &b->str.blend) || estimate_needed(b)) {
        /* while the estimate is fed in (or ramping out): its config, else the parameters */
        const hd_stribeck_cfg_t *sc = hd_fric_est_feeding(&b->fe) ? &b->fe_str : &c->str;
        tff = hd_stribeck_step(&b->str, sc, in->vel_ref, in->vel_fb);
    }

    /* the slow work of this tick (every part in the first period); the torque estimate from
     * the command (pr_t_src 0) every period: it closes a loop through the torque command */
    if (all) {
        lugre_g(b, c, in);
        lugre_exp(b, c);
        lugre_finish(b, c, in);
        dob_step(b, c, in);
        maxwell(b, c, in, true);
        torque_lowpass_due(b, c);
        if (estimate_needed(b)) {
            torque_estimate(b, c, in);
            torque_lowpass(b, c);
            preisach(b, (uint32_t)HD_SLOT_PREISACH, UINT32_MAX);           /* the whole search */
            compliance(b, c);
        }
        te_step(b, c, in);
    } else {
        if (c->pr_t_src == 0u && estimate_needed(b)) {
            torque_lowpass_due(b, c);       /* a slot-4 estimate of pr_t_src 2 before a change to 0 */
            torque_estimate(b, c, in);
            torque_lowpass(b, c);
        }
        ex_tick(&b->mx_x);          /* Maxwell-slip one increment on (its slot samples anew) */
        switch (hd_sched_slot(k)) {
        case HD_SLOT_LUGRE_G:
            lugre_g(b, c, in);
            break;
        case HD_SLOT_LUGRE_EXP:
            lugre_exp(b, c);
            dob_step(b, c, in);
            break;
        case HD_SLOT_LUGRE_FINISH:
            lugre_finish(b, c, in);
            torque_lowpass_due(b, c);
            compliance(b, c);
            break;
        case HD_SLOT_TE:
            te_step(b, c, in);
            break;
        case HD_SLOT_MAXWELL_EST:
            maxwell(b, c, in, false);
            if (c->pr_t_src != 0u && estimate_needed(b)) {
                /* the motor-side estimate (pr_t_src 2) fills slot 4: its low-pass in the next
                 * period (tick 5 is lighter); the model's (pr_t_src 1) here, tick 5 carries the
                 * first Preisach trial of the full-closed and excitation periods' worst tick */
                torque_estimate(b, c, in);
                if (c->pr_t_src == 2u) {
                    b->pr_lp_due = 1u;
                } else {
                    torque_lowpass(b, c);
                }
            }
            break;
        default:
            torque_lowpass_due(b, c);
            preisach(b, k, HD_SCHED_PR_TRIALS);
            break;
        }
    }

    /* the held torques (0 for a compensator that is off: its last step had weight 0) */
    tff = hdf_add_sat(tff, hdf_add_sat(hdf_add_sat(b->lug.tau, b->dob_d), b->te.tau));
    /* position corrections (output-referred motor lead): held (Preisach, compliance, the TE
     * step's value), extrapolated (Maxwell-slip) and, between the TE steps, first order in the
     * motor angle's change since (its slope at the step), not in time: the motor angle is fed
     * back, a prediction in time is a delay */
    dpos = hdf_add64_sat(hdf_add64_sat(hdf_add64_sat((int64_t)b->pr_dth, (int64_t)b->cp_dth),
                                       hdf_add64_sat(b->te_dth, b->te_out_dth)), b->mx_x.v);
    if (b->te_slope != 0) {
        dpos = hdf_add64_sat(dpos, hdf_mul64x32_q(hdf_sub64_sat(in->pos_mot, b->te_mot), b->te_slope, 32u));
    }

    out->tff = tff;
    if (c->pos_mode != 0u) {
        out->dpos = dpos;
        out->dvel = dv_i;
        b->dpos_f = hdf_shl64_sat(dpos, 16u);
        b->dpos_primed = 1u;
    } else {
        const int64_t target = hdf_shl64_sat(dpos, 16u);       /* 2^-48 turn */
        if (b->dpos_primed == 0u) {
            b->dpos_f = target;
            b->dpos_primed = 1u;
        }
        out->dpos = 0;
        if (target == b->dpos_f) {
            out->dvel = dv_i;           /* settled (or every correction off): the step is exactly 0 */
        } else {
            const int64_t step = hdf_mul64x32_q(hdf_sub64_sat(target, b->dpos_f), c->dpos_alpha, 30u);
            b->dpos_f = hdf_add64_sat(b->dpos_f, step);
            out->dvel = hdf_add_sat(hdf_sat32(hdf_asr64_rnd(hdf_mul64x32_q(step, HD_LOOP_HZ, 0u), 16u)), dv_i);
        }
    }
    b->out = *out;
}

int32_t hd_comp_bank_post(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c, const hd_comp_bank_in_t *in,
                          int32_t u_pid)
{
    hd_backstep_in_t bi;
    bi.theta = in->pos_out;
    bi.theta_d = in->pos_ref;
    bi.omega = in->vel_fb;
    bi.omega_d = in->vel_ref;
    bi.acc_d = in->acc_ref;
    if (!running(b, HD_CB_BACKSTEP, &b->bs.blend)) {
        b->u_bs = u_pid;
        return u_pid;
    }
    /* the law every period with the held estimates; the Stribeck regressor's shape and the
     * adaptation (HD_SCHED_CYCLE periods' worth at once) in its slot (hd_sched.h) */
    const bool slot = ((b->tick - 1u) & (HD_SCHED_CYCLE - 1u)) == (uint32_t)HD_SLOT_BACKSTEP;
    if (b->bs_preload != 0u) {
        hd_backstep_preload(&b->bs, &c->bs, &bi, u_pid);     /* also the regressor's shape */
        b->bs_preload = 0u;
    } else if (slot) {
        hd_backstep_regressor(&b->bs, &c->bs, &bi);
    }
    b->u_bs = hd_backstep_step_held(&b->bs, &c->bs, &bi, u_pid);
    if (slot) {
        hd_backstep_adapt(&b->bs, &c->bs, HD_SCHED_LOG2);
    }
    return b->u_bs;
}

void hd_comp_bank_end(hd_comp_bank_t *b, int32_t t_applied)
{
    b->t_prev = t_applied;
}

bool hd_comp_bank_fric_est_rare(hd_comp_bank_t *b, const hd_comp_bank_cfg_t *c)
{
    uint32_t t;
    bool obs = false;
    if (c->fe_on == 0u && !hd_fric_est_feeding(&b->fe)) {
        b->fe_fast = 0u;
        return false;           /* off and not ramping out: no cost, the bins keep their data */
    }
    fe_sync(b, c);              /* a parameter change the background's part delayed (fe_fast) */
    b->fe_tick++;
    t = b->fe_tick;
    /* the observation in the first period of the step, the fed FF config in its last
     * (fe_decim >= 2: each period carries one of them) */
    if (t == 1u || c->fe_decim == 1u) {
        if (c->fe_on != 0u) {
            /* the observation only (the caller's): the step's sample and fit are the
             * background's (hd_comp_bank_fric_est_work) */
            obs = true;
        } else {
            hd_fric_est_queue_feed(&b->fe);     /* off: the feed ramps out */
        }
    }
    if (t < c->fe_decim) {
        return obs;
    }
    b->fe_tick = 0u;
    if (!hd_fric_est_busy(&b->fe)) {
        /* the background's fed config of its last entry (whole between its parts) */
        b->fe_str = b->fe_next;
    }
    return obs;
}

bool hd_comp_bank_fric_est_work(hd_comp_bank_t *b)
{
    const uint32_t tail = b->fe.q_tail;
    const bool more = hd_fric_est_work(&b->fe, &b->fe_cfg);
    if (b->fe.q_tail != tail) {
        /* an entry done: the feed's step (weight, fed config) */
        hd_fric_est_work_feed(&b->fe, &b->fe_base, b->fe_base_share, &b->fe_next);
    }
    return more;
}

bool hd_comp_bank_active(const hd_comp_bank_t *b)
{
    return hd_blend_active(&b->str.blend) || hd_blend_active(&b->lug.blend) || hd_blend_active(&b->mx.blend) ||
           hd_blend_active(&b->pr.blend) || hd_blend_active(&b->te.blend) || hd_blend_active(&b->bs.blend) ||
           hd_blend_active(&b->dob_blend) || hd_blend_active(&b->cp_blend);
}
