/* hd_fric_est.c - online Stribeck identification (contract: hd_fric_est.h). */
#include "hd_fric_est.h"
#include "hd_fixed.h"

/* round(2^30 / n), n = 1..HD_FE_NBIN: bin means without a division */
static const int32_t fe_inv_n[HD_FE_NBIN] = {
    1073741824, 536870912, 357913941, 268435456, 214748365, 178956971, 153391689, 134217728,
    119304647, 107374182, 97612893, 89478485, 82595525, 76695845, 71582788, 67108864,
    63161284, 59652324, 56512728, 53687091, 51130563, 48806447, 46684427, 44739243};

/* round(2^(k/4) 2^30), k = 0..3: the quarter-octave grid of candidate vs */
static const int32_t fe_qoct[4] = {1073741824, 1276901417, 1518500250, 1805811301};

#define FE_INV_SQRT2_Q30 759250125      /* round(2^30 / sqrt 2) */
#define FE_NO_FIT INT64_MAX
#define HD_FE_SNAP_BINS 1u   /* bins per snapshot part (a part: one exp) */
#define HD_FE_SUM_BINS 2u    /* bins per part of the solution's sums */
#define FE_SUM_PARTS (HD_FE_NBIN / HD_FE_SUM_BINS)
#define HD_FE_SSE_BINS 3u    /* bins per part of the residual */
#define FE_SSE_PARTS (HD_FE_NBIN / HD_FE_SSE_BINS)
#define HD_FE_SCAN_BINS 6u   /* bins per part of the close's scan of the bins */
#define FE_SCAN_PARTS (HD_FE_NBIN / HD_FE_SCAN_BINS)

/* bit i of a bin mask (i < HD_FE_NBIN <= 32) */
static uint32_t bin_bit(uint32_t i)
{
    return (i >= 32u) ? 0u : (1u << i);
}

static uint32_t half_octave(uint32_t a)   /* 2 floor(log2 a) + the next bit, a > 0 */
{
    const uint32_t m = 31u - (uint32_t)__builtin_clz(a);
    return 2u * m + ((m > 0u) ? ((a >> (m - 1u)) & 1u) : 0u);
}

int32_t hd_fric_est_bin_of(const hd_fric_est_cfg_t *c, int32_t v)
{
    const int32_t a = hdf_abs_sat(v);
    int32_t k;
    if (a < c->v_min || c->v_min <= 0) {
        return -1;
    }
    k = (int32_t)half_octave((uint32_t)a) - (int32_t)half_octave((uint32_t)c->v_min);
    return (k < (int32_t)HD_FE_NBIN) ? k : -1;
}

/* |v| / vs_lo in Q16 through the reciprocal (saturated) */
static int32_t r16_of(const hd_fric_est_cfg_t *c, int32_t v)
{
    const uint32_t s = c->rvs.sh - 16u;                 /* 15..45 */
    uint64_t prod = (uint64_t)(uint32_t)hdf_abs_sat(v) * (uint64_t)c->rvs.m;   /* < 2^62 */
    prod = (prod + ((uint64_t)1 << (s - 1u))) >> s;
    return (prod > (uint64_t)INT32_MAX) ? INT32_MAX : (int32_t)prod;
}

/* vs_lo 2^(j/4), saturated */
static int32_t vs_of(const hd_fric_est_cfg_t *c, uint32_t j)
{
    const int64_t v = hdf_mul64x32_q((int64_t)c->vs_lo << (j >> 2), fe_qoct[j & 3u], 30u);
    return hdf_sat32(v);
}

/* 2^62 / d for d in [2^31, 2^32): Newton iteration from the linear estimate
 * 48/17 - 32/17 d (relative error <= 1/17, squared at every iteration: three
 * iterations reach the Q30 resolution); result in (2^30, 2^31], a few LSB. */
static uint64_t recip30(uint32_t d)
{
    uint64_t r = 3031741621u - (((uint64_t)d * 2021161081u) >> 32);
    uint32_t i;
    for (i = 0; i < 3u; i++) {
        const uint64_t dr = ((uint64_t)d * r) >> 32;    /* d r, Q30 (about 2^30) */
        r = (r * ((uint64_t)1 << 31) - r * dr) >> 30;   /* r (2 - d r) */
    }
    return r;
}

/* round(num 2^q / den) for den > 0, to ~2^-29 relative, without a 64-bit division */
static int64_t div_approx(int64_t num, uint64_t den, uint32_t q)
{
    const uint32_t lz = (uint32_t)__builtin_clzll(den);
    const uint32_t d32 = (uint32_t)((den << lz) >> 32);           /* den ~ d32 2^(32 - lz) */
    const int32_t r29 = (int32_t)(recip30(d32) >> 1);            /* 2^61 / d32, <= 2^30 */
    const int64_t t = hdf_mul64x32_q(num, r29, 29u);             /* num 2^32 / d32 */
    const int32_t s = 64 - (int32_t)lz - (int32_t)q;
    return (s >= 0) ? hdf_asr64_rnd(t, (uint32_t)s) : hdf_shl64_sat(t, (uint32_t)(-s));
}

static uint32_t bitlen64(uint64_t x)
{
    return (x == 0u) ? 0u : 64u - (uint32_t)__builtin_clzll(x);
}

int32_t hd_fric_est_config(hd_fric_est_cfg_t *c, int32_t v_min, int32_t vs_lo, int32_t dv_max,
                           uint32_t settle, uint32_t n_forget, uint32_t n_min, uint32_t n_keep,
                           uint32_t max_age, int32_t tau_max, int32_t fv_max)
{
    if (v_min <= 0 || vs_lo <= 0 || dv_max < 0 || n_forget < 1u || n_min < 1u || tau_max <= 0 || fv_max < 0) {
        return -1;
    }
    c->v_min = v_min;
    c->vs_lo = vs_lo;
    c->dv_max = dv_max;
    c->settle = settle;
    c->n_forget = n_forget;
    c->n_min = n_min;
    c->n_keep = n_keep;
    c->max_age = max_age;
    /* |f| <= 2^30: the centred torque of the fit fits an int32 */
    c->tau_max = (tau_max > (1 << 30)) ? (1 << 30) : tau_max;
    c->fv_max = fv_max;
    hd_stribeck_recip(&c->rvs, vs_lo);
    return 0;
}

void hd_fric_est_init(hd_fric_est_t *e, const hd_stribeck_dir_t init[HD_FE_NDIR], uint32_t ramp_steps,
                      bool feed)
{
    uint32_t d;
    uint32_t i;
    for (d = 0; d < HD_FE_NDIR; d++) {
        for (i = 0; i < HD_FE_NBIN; i++) {
            e->bin[d][i].v = 0;
            e->bin[d][i].f = 0;
            e->bin[d][i].r16 = 0;
            e->bin[d][i].n = 0u;
            e->bin[d][i].stamp = 0u;
        }
        e->est[d] = init[d];
        e->shape[d] = init[d];
        e->oth_m[d] = 0;
        e->oth_g[d] = 0;
        e->oth_t[d] = 0u;
        e->conf[d] = 0u;
        e->fits[d] = 0u;
    }
    for (i = 0; i < HD_FE_NGRID; i++) {
        e->sse[i] = FE_NO_FIT;
        e->th[i][0] = 0;
        e->th[i][1] = 0;
        e->th[i][2] = 0;
    }
    e->fit_dir = 0u;
    e->fit_j = 0u;
    e->fit_pass = 0u;
    e->fit_part = 0u;
    e->fit_due = 0u;
    e->fit_nb = 0u;
    for (i = 0; i < 5u; i++) {
        e->fit_q[i] = 0;
    }
    e->fit_m[0] = 0;
    e->fit_m[1] = 0;
    e->fit_m[2] = 0;
    e->fin_ok = 0u;
    e->fin_best = 0u;
    e->fit_best = 0u;
    for (i = 0; i < 4u; i++) {
        e->fin[i] = 0;
        e->fin_n[i] = 0u;
    }
    e->fin_v[0] = 0;
    e->fin_v[1] = 0;
    for (i = 0; i < 3u; i++) {
        e->fit_a[i] = 0;
        e->fit_sh[i] = 0u;
    }
    e->fit_dfs = 0;
    e->fin_x = 0;
    e->fin_par = 0u;
    e->fin_acc = 0u;
    e->fit_mask = 0u;
    e->fit_ok = 0u;
    e->fit_s[0] = 0;
    e->fit_s[1] = 0;
    e->fit_s[2] = 0;
    for (i = 0; i < HD_FE_NBIN; i++) {
        e->fit_e[i] = 0;
        e->fit_u[i] = 0;
        e->fit_f[i] = 0;
    }
    e->scale = HD_FE_SCALE_ONE;
    e->bias = 0;
    e->vis_g = 0;
    e->vis_bin = 0u;
    e->vis_n = 0u;
    e->vis_m = 0;
    e->vis_s0 = HD_FE_SCALE_ONE;
    e->vis_b0 = 0;
    e->vis_k = 0u;
    e->vis_a = 0;
    e->vis_n0 = 0u;
    for (i = 0; i < HD_FE_QLEN; i++) {
        e->q[i].v = 0;
        e->q[i].v_meas = 0;
        e->q[i].tau = 0;
        e->q[i].flags = 0u;
    }
    e->q_head = 0u;
    e->q_tail = 0u;
    e->q_drop = 0u;
    e->q_gap = 0u;
    e->in_step = 0u;
    e->busy = 0u;
    e->smp_stage = 0u;
    e->smp_v = 0;
    e->smp_tau = 0;
    e->smp_first = 0u;
    e->smp_k = -1;
    e->smp_tc = 0;
    e->smp_st = 0;
    e->smp_bt = 0;
    e->smp_f = 0;
    e->smp_cap = 0u;
    e->v_prev = 0;
    e->v_lp = 0;
    e->visit = 0u;
    e->steady_n = 0u;
    e->samples = 0u;
    e->steps = 0u;
    hd_blend_init(&e->feed, ramp_steps, feed);
}

/* x + (y - x) / n rounded half away (|y - x| < 2^31: both in [-2^30, 2^31)) */
static int32_t mean_step(int32_t x, int32_t y, uint32_t n)
{
    const int32_t d = y - x;
    const int32_t h = (int32_t)(n / 2u);
    const int32_t q = (d >= 0) ? (d + h) / (int32_t)n : -((-d + h) / (int32_t)n);
    return x + q;
}

/* the published estimate of direction d: the shape fit's levels and viscous term times the
 * common-mode scale (vs is a shape parameter: a friction drift does not move it) */
static void publish(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, uint32_t d)
{
    const hd_stribeck_dir_t *sh = &e->shape[d];
    const int32_t fc = hdf_clamp32(hdf_sat32(hdf_mul64x32_q((int64_t)sh->fc, e->scale, 16u)), 0, c->tau_max);
    e->est[d].fc = fc;
    e->est[d].fs = hdf_clamp32(hdf_sat32(hdf_mul64x32_q((int64_t)sh->fs, e->scale, 16u)), fc, c->tau_max);
    e->est[d].vs = sh->vs;
    e->est[d].fv = hdf_clamp32(hdf_sat32(hdf_mul64x32_q((int64_t)sh->fv, e->scale, 16u)), 0, c->fv_max);
}

/* a + (t - a) n / (n + 2^HD_FE_SCALE_SHIFT): the visit's evidence (n samples) against the value
 * at the visit's start (weight 2^HD_FE_SCALE_SHIFT samples) */
static int64_t visit_blend(int64_t a, int64_t t, uint32_t n)
{
    return a + div_approx((t - a) * (int64_t)n, (uint64_t)n + (1u << HD_FE_SCALE_SHIFT), 0u);
}

/* The sample in parts (bin_update of a step, one part per call of sample_part, each with
 * at most one approximate division; hd_fric_est.h "Cost"):
 *   1 the bin and the visit (a new one: its mean when it began, the scale and bias of its
 *     start, the old mean's weight), the visit's mean signed torque; the common mode's
 *     scale from the visit (established bins only, as every part of the common mode),
 *   2 its bias (with a recent visit of the other direction),
 *   3 the scale blended with its value at the visit's start,
 *   4 the bias likewise, and this direction's visit for the other's pairing,
 *   5 the sample normalised by the scale (established: the visit's mean torque),
 *   6 the bin's means, count, Q16 velocity and stamp,
 *   7 the published estimates (the new scale).
 * The model of the common mode is m = sg scale g0 + bias (direction d, sign sg, the visited
 * bin's mean g0 when the visit began, the visit's mean signed torque m over n samples).
 * With a recent visit of the other direction (mean mo of a bin of mean go) the two
 * equations give both unknowns; without one, the bias stays and the visit gives the scale.
 * The result is blended with the values at the visit's start. */
#define FE_SMP_PARTS 7u

/* the other direction's last established visit pairs with this one (recent enough) */
static bool smp_paired(const hd_fric_est_t *e, const hd_fric_est_cfg_t *c, uint32_t o)
{
    const uint32_t age = (c->max_age < HD_FE_PAIR_AGE) ? c->max_age : HD_FE_PAIR_AGE;
    return e->oth_g[o] > 0 && (uint32_t)(e->steps - e->oth_t[o]) <= age;
}

static void sample_part(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, uint32_t stage)
{
    const int32_t v_ref = e->smp_v;
    const uint32_t d = (v_ref > 0) ? (uint32_t)HD_FE_DIR_POS : (uint32_t)HD_FE_DIR_NEG;
    const uint32_t o = (d == (uint32_t)HD_FE_DIR_POS) ? (uint32_t)HD_FE_DIR_NEG : (uint32_t)HD_FE_DIR_POS;
    const int32_t sg = (v_ref > 0) ? 1 : -1;
    const int64_t m = e->vis_m;
    const int64_t g0 = e->vis_g;
    switch (stage) {
    case 1u: {
        const int32_t k = hd_fric_est_bin_of(c, v_ref);
        hd_fe_bin_t *b;
        e->smp_k = k;
        if (k < 0) {
            return;
        }
        b = &e->bin[d][k];
        /* excitation check of the common mode: the bin held n_min samples of earlier visits
         * when this visit began; the visit is compared with that mean, held for the whole
         * visit (a comparison with the running mean would take the visit's own settling for
         * a drift).  A visit of the common mode is one bin: a reference that creeps (within
         * dv_max) into the next bin starts a new one there. */
        if (e->smp_first != 0u || e->vis_bin != d * HD_FE_NBIN + (uint32_t)k) {
            e->vis_bin = d * HD_FE_NBIN + (uint32_t)k;
            e->vis_g = (b->n >= c->n_min && b->f > 0) ? b->f : 0;
            e->vis_n = 0u;
            e->vis_m = 0;
            e->vis_s0 = e->scale;
            e->vis_b0 = e->bias;
            e->vis_k = 0u;
            e->vis_a = 0;
            e->vis_n0 = b->n;
        }
        if (e->smp_first != 0u) {
            /* a new visit: the old mean weighs as n_keep samples, but at least HD_FE_KEEP_MIN:
             * a common-mode change is the scale's to follow; a bin that forgot faster would
             * take it into the shape before the scale sees it */
            const uint32_t keep = (c->n_keep > HD_FE_KEEP_MIN) ? c->n_keep : HD_FE_KEEP_MIN;
            b->n = (b->n > keep) ? keep : b->n;
            e->vis_n0 = b->n;
        }
        e->smp_tc = hdf_clamp32(e->smp_tau, hdf_neg_sat(c->tau_max), c->tau_max);
        if (e->vis_g > 0) {
            /* samples of the visit, 1..n_forget (n_forget >= 1 by hd_fric_est_config) */
            e->vis_n = (e->vis_n < c->n_forget) ? e->vis_n + 1u : ((c->n_forget > 0u) ? c->n_forget : 1u);
            e->vis_m = mean_step(e->vis_m, e->smp_tc, e->vis_n);
            if (smp_paired(e, c, o)) {
                /* pos: mp = s gp + b, neg: mn = -s gn + b  ->  s = (mp - mn) / (gp + gn) */
                const int64_t mo = e->oth_m[o];
                const int64_t mv = e->vis_m;
                e->smp_st = div_approx((sg > 0) ? mv - mo : mo - mv, (uint64_t)((int64_t)e->vis_g + e->oth_g[o]), 16u);
            } else {
                const int64_t f = (sg > 0) ? (int64_t)e->vis_m - (int64_t)e->vis_b0
                                           : (int64_t)e->vis_b0 - (int64_t)e->vis_m;
                e->smp_st = div_approx(f, (uint64_t)(int64_t)e->vis_g, 16u);
            }
        }
        return;
    }
    case 2u:
        e->smp_bt = e->vis_b0;
        if (e->smp_k >= 0 && g0 > 0 && smp_paired(e, c, o)) {
            /* b = (mp gn + mn gp) / (gp + gn) */
            const int64_t mo = e->oth_m[o];
            const int64_t go = e->oth_g[o];
            const int64_t mp = (sg > 0) ? m : mo;
            const int64_t mn = (sg > 0) ? mo : m;
            const int64_t gp = (sg > 0) ? g0 : go;
            const int64_t gn = (sg > 0) ? go : g0;
            e->smp_bt = div_approx(mp * gn + mn * gp, (uint64_t)(g0 + go), 0u);                 /* Q16 N.m */
        }
        return;
    case 3u:
        if (e->smp_k >= 0 && g0 > 0) {
            const int64_t s_t = hdf_clamp64(e->smp_st, HD_FE_SCALE_MIN, HD_FE_SCALE_MAX);
            e->scale = hdf_sat32(visit_blend(e->vis_s0, s_t, e->vis_n));
        }
        return;
    case 4u:
        if (e->smp_k >= 0 && g0 > 0) {
            const int64_t b_t = hdf_clamp64(e->smp_bt, -(int64_t)c->tau_max, (int64_t)c->tau_max);
            e->bias = hdf_sat32(visit_blend(e->vis_b0, b_t, e->vis_n));
            e->oth_m[d] = e->vis_m;
            e->oth_g[d] = e->vis_g;
            e->oth_t[d] = e->steps;
        }
        return;
    case 5u:
        if (e->smp_k >= 0) {
            /* an established bin (the common mode follows its visits) forgets over at least
             * HD_FE_KEEP_MIN samples: its shape changes slowly, the scale takes the level */
            const uint32_t cap = (e->vis_g > 0 && c->n_forget < HD_FE_KEEP_MIN) ? HD_FE_KEEP_MIN : c->n_forget;
            int64_t fn;
            if (e->vis_g > 0) {
                /* established: the bin is its old mean and the visit's mean torque normalised
                 * by the present scale and bias, weighed k : n0 (hd_fric_est.h: a sample
                 * normalised by the scale of its moment would be compared with the visit's
                 * running mean) */
                e->vis_k = (e->vis_k < cap) ? e->vis_k + 1u : cap;
                e->vis_a = mean_step(e->vis_a, e->smp_tc, e->vis_k);
                fn = (int64_t)e->vis_a - (int64_t)e->bias;
            } else {
                /* friction magnitude of the direction, the unbalance taken off and normalised
                 * by the scale: the bins hold the shape of the map, the scale its level */
                fn = (int64_t)e->smp_tc - (int64_t)e->bias;
            }
            fn = (v_ref > 0) ? fn : -fn;
            fn = hdf_clamp64(fn, -(int64_t)c->tau_max, (int64_t)c->tau_max);
            e->smp_f = hdf_clamp32(hdf_sat32(div_approx(fn, (uint64_t)(uint32_t)e->scale, 16u)),
                                   hdf_neg_sat(c->tau_max), c->tau_max);
            e->smp_cap = cap;
        }
        return;
    case 6u:
        if (e->smp_k >= 0) {
            hd_fe_bin_t *b = &e->bin[d][e->smp_k];
            const uint32_t cap = e->smp_cap;
            const int32_t f = e->smp_f;
            uint32_t n1;
            if (e->vis_g > 0) {
                n1 = (e->vis_n0 < UINT32_MAX - e->vis_k) ? e->vis_n0 + e->vis_k : UINT32_MAX;
                {
                    /* k / (n0 + k) in Q16 by a 32-bit division: both shifted to below 2^15 */
                    const uint32_t sh = (n1 >= 32768u) ? 32u - (uint32_t)__builtin_clz(n1) - 15u : 0u;
                    const uint32_t den = n1 >> sh;
                    const uint32_t w16 = (((e->vis_k >> sh) << 16) + den / 2u) / den;
                    b->f = hdf_clamp32(hdf_sat32((int64_t)e->vis_g +
                                                 hdf_mul64x32_q((int64_t)f - (int64_t)e->vis_g, (int32_t)w16, 16u)),
                                       hdf_neg_sat(c->tau_max), c->tau_max);
                }
                n1 = (n1 < cap) ? n1 : cap;
                b->v = mean_step(b->v, hdf_abs_sat(v_ref), n1);
            } else {
                n1 = (b->n < cap) ? b->n + 1u : cap;
                b->v = mean_step(b->v, hdf_abs_sat(v_ref), n1);
                b->f = mean_step(b->f, f, n1);
            }
            b->n = n1;
            b->r16 = r16_of(c, b->v);
            b->stamp = e->steps;
            e->samples++;
        }
        return;
    default:
        /* the levels follow the scale once the bins have given a fit (before it, the
         * initial estimate stays: excitation check 2) */
        if (e->smp_k >= 0) {
            if (e->fits[HD_FE_DIR_POS] != 0u) {
                publish(e, c, HD_FE_DIR_POS);
            }
            if (e->fits[HD_FE_DIR_NEG] != 0u) {
                publish(e, c, HD_FE_DIR_NEG);
            }
        }
        return;
    }
}

/* a bin counts in the fit: enough samples, and the last one not older than max_age */
static bool bin_valid(const hd_fric_est_t *e, const hd_fric_est_cfg_t *c, const hd_fe_bin_t *b)
{
    return (b->n >= c->n_min) && ((uint32_t)(e->steps - b->stamp) <= c->max_age);
}

/* shape exp(-(v / vs_j)^2) in Q16 from r16 = v / vs_lo: (v / vs_j)^2 = r^2 2^(-j/2) */
static int32_t shape16(int32_t r16, uint32_t j)
{
    const int64_t x32 = (int64_t)r16 * (int64_t)r16;                     /* Q32 */
    int32_t x16 = hdf_sat32(hdf_asr64_rnd(x32, 16u + (j >> 1)));
    if ((j & 1u) != 0u) {
        x16 = hdf_mul_q(x16, FE_INV_SQRT2_Q30, 30u);
    }
    return hdf_asr32_rnd((int64_t)hd_exp_neg_q16(x16), 14u);
}

/* Least squares of candidate j over the valid bins of direction d -> e->sse[j], e->th[j], in
 * four steps (the cost of one estimator step stays a quarter of a candidate):
 *   pass 0, 1: bins 0..11, 12..23: snapshot of the valid bins (shape, velocity column,
 *              torque; the bins may change before the candidate is done) and their sums;
 *   pass 2:    means, centred normal equations, (fc, fs - fc, fv);
 *   pass 3:    residual sum of squares. */
static void fit_snapshot(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, uint32_t d, uint32_t j, uint32_t lo,
                         uint32_t n)
{
    const hd_fe_bin_t *bn = e->bin[d];
    uint32_t i;
    if (lo == 0u) {
        e->fit_mask = 0u;
        e->fit_s[0] = 0;
        e->fit_s[1] = 0;
        e->fit_s[2] = 0;
        e->sse[j] = FE_NO_FIT;
    }
    for (i = lo; i < lo + n; i++) {
        if (bin_valid(e, c, &bn[i])) {
            e->fit_e[i] = shape16(bn[i].r16, j);
            e->fit_u[i] = (int32_t)((uint32_t)bn[i].v >> HD_FE_U_SHIFT);
            e->fit_f[i] = bn[i].f;
            e->fit_mask |= bin_bit(i);
            e->fit_s[0] += e->fit_e[i];
            e->fit_s[1] += e->fit_u[i];
            e->fit_s[2] += e->fit_f[i];
        }
    }
}

static uint32_t popcount24(uint32_t m)
{
    uint32_t n = 0u;
    while (m != 0u) {
        m &= m - 1u;
        n++;
    }
    return n;
}

/* The solution in four parts: the means (fit_solve_begin), the centred sums over a range
 * of bins (fit_solve_sums, in bin order), the scaled normal equations' determinant and
 * numerators (fit_solve_cramer), their quotients (fit_solve_end). */
static void fit_solve_begin(hd_fric_est_t *e)
{
    const uint32_t nb = popcount24(e->fit_mask);
    uint32_t k;
    e->fit_ok = 0u;
    e->fit_nb = nb;
    for (k = 0; k < 5u; k++) {
        e->fit_q[k] = 0;
    }
    if (nb < 4u) {
        return;                             /* fewer bins than parameters + 1 */
    }
    {
        const int32_t inv = fe_inv_n[nb - 1u];
        e->fit_m[0] = hdf_sat32(hdf_mul64x32_q(e->fit_s[0], inv, 30u));
        e->fit_m[1] = hdf_sat32(hdf_mul64x32_q(e->fit_s[1], inv, 30u));
        e->fit_m[2] = hdf_sat32(hdf_mul64x32_q(e->fit_s[2], inv, 30u));
    }
}

static void fit_solve_sums(hd_fric_est_t *e, uint32_t lo, uint32_t n)
{
    /* the sums in locals (registers, not five 64-bit read-modify-writes per bin); the shape
     * and velocity columns' centred values fit 32 bits: their products are 32 x 32 -> 64 */
    const int32_t me = e->fit_m[0], mu = e->fit_m[1], mf = e->fit_m[2];
    int64_t see = e->fit_q[0], suu = e->fit_q[1], seu = e->fit_q[2], sef = e->fit_q[3], suf = e->fit_q[4];
    uint32_t i;
    if (e->fit_nb < 4u) {
        return;
    }
    for (i = lo; i < lo + n; i++) {
        if ((e->fit_mask & bin_bit(i)) != 0u) {
            const int32_t ec = e->fit_e[i] - me;                    /* |.| <= 2^16 */
            const int32_t uc = e->fit_u[i] - mu;                    /* |.| <= 2^20 */
            const int64_t fcn = (int64_t)e->fit_f[i] - mf;          /* |.| <= 2^31 */
            see += (int64_t)ec * ec;                                /* see <= 2^37 */
            suu += (int64_t)uc * uc;                                /* suu <= 2^45 */
            seu += (int64_t)ec * uc;                                /* seu */
            sef += ec * fcn;                                        /* sef <= 2^52 */
            suf += uc * fcn;                                        /* suf <= 2^56 */
        }
    }
    e->fit_q[0] = see;
    e->fit_q[1] = suu;
    e->fit_q[2] = seu;
    e->fit_q[3] = sef;
    e->fit_q[4] = suf;
}

/* the scaled normal equations in four parts: the scaling and the determinant
 * (fit_solve_det, into fit_q[0]: the sums of shape and velocity are not needed after it),
 * Cramer's numerators (fit_solve_num, into fit_q[1..2]), then the two quotients and fc
 * (fit_solve_dfs, fit_solve_end) */
static void fit_solve_det(hd_fric_est_t *e)
{
    const int64_t see = e->fit_q[0], suu = e->fit_q[1], seu = e->fit_q[2];
    uint32_t s_e, s_u, h;
    int64_t a, b, cc;
    if (e->fit_nb < 4u) {
        return;
    }
    /* scale the normal matrix into 30 bits (the same h on the cross term) */
    s_e = (bitlen64((uint64_t)see) > 30u) ? bitlen64((uint64_t)see) - 30u : 0u;
    s_u = (bitlen64((uint64_t)suu) > 30u) ? bitlen64((uint64_t)suu) - 30u : 0u;
    if (((s_e + s_u) & 1u) != 0u) {
        s_e++;
    }
    h = (s_e + s_u) / 2u;
    a = hdf_asr64_rnd(see, s_e);
    cc = hdf_asr64_rnd(suu, s_u);
    b = hdf_asr64_rnd(seu, h);
    b = hdf_clamp64(b, -((int64_t)1 << 30), (int64_t)1 << 30);
    e->fit_q[0] = a * cc - b * b;           /* <= 2^60; a == 0 gives det <= 0 */
    e->fit_a[0] = (int32_t)a;               /* a, cc < 2^30 + 1, |b| <= 2^30 */
    e->fit_a[1] = (int32_t)b;
    e->fit_a[2] = (int32_t)cc;
    e->fit_sh[0] = s_e;
    e->fit_sh[1] = s_u;
    e->fit_sh[2] = h;
}

static void fit_solve_num(hd_fric_est_t *e)
{
    const int64_t sef = e->fit_q[3], suf = e->fit_q[4];
    const int32_t a = e->fit_a[0], b = e->fit_a[1], cc = e->fit_a[2];
    const uint32_t s_e = e->fit_sh[0], s_u = e->fit_sh[1], h = e->fit_sh[2];
    if (e->fit_nb < 4u || e->fit_q[0] <= 0) {
        return;                             /* the shape column carries no information */
    }
    /* (dF, fv) det / 2^30 by Cramer's rule on the scaled sums */
    e->fit_q[1] = hdf_sub64_sat(hdf_mul64x32_q(hdf_asr64_rnd(sef, s_e), cc, 30u),
                                hdf_mul64x32_q(hdf_asr64_rnd(suf, h), b, 30u));
    e->fit_q[2] = hdf_sub64_sat(hdf_mul64x32_q(hdf_asr64_rnd(suf, s_u), a, 30u),
                                hdf_mul64x32_q(hdf_asr64_rnd(sef, h), b, 30u));
}

static void fit_solve_dfs(hd_fric_est_t *e)
{
    if (e->fit_nb < 4u || e->fit_q[0] <= 0) {
        return;
    }
    e->fit_dfs = hdf_sat32(div_approx(e->fit_q[1], (uint64_t)e->fit_q[0], 46u));   /* Q16 N.m (e in Q16) */
}

static void fit_solve_end(hd_fric_est_t *e, uint32_t j)
{
    const int64_t det = e->fit_q[0], ngam = e->fit_q[2];
    const int32_t me = e->fit_m[0], mu = e->fit_m[1], mf = e->fit_m[2];
    const int32_t dfs = e->fit_dfs;
    int32_t fv, fc;
    if (e->fit_nb < 4u || det <= 0) {
        return;
    }
    fv = hdf_sat32(div_approx(ngam, (uint64_t)det, 30u + HD_FE_U_SHIFT + 10u)); /* per 2^-21 -> per turn/s */
    fc = hdf_sat32((int64_t)mf - hdf_mul64x32_q((int64_t)dfs, me, 16u) -
                   hdf_mul64x32_q((int64_t)fv, mu, 21u));
    e->th[j][0] = fc;
    e->th[j][1] = dfs;
    e->th[j][2] = fv;
    e->fit_ok = 1u;
}

/* residual sum of squares over a range of bins (in bin order), into fit_q[0] */
static void fit_sse(hd_fric_est_t *e, uint32_t j, uint32_t lo, uint32_t n)
{
    int64_t sse = (lo == 0u) ? 0 : e->fit_q[0];
    uint32_t i;
    if (e->fit_ok == 0u) {
        return;
    }
    for (i = lo; i < lo + n; i++) {
        if ((e->fit_mask & bin_bit(i)) != 0u) {
            const int64_t m = (int64_t)e->th[j][0] + hdf_mul64x32_q((int64_t)e->th[j][1], e->fit_e[i], 16u) +
                              hdf_mul64x32_q((int64_t)e->th[j][2], e->fit_u[i], 21u);
            const int64_t r = hdf_asr64_rnd((int64_t)e->fit_f[i] - m, 4u);
            const int64_t rc = hdf_clamp64(r, -((int64_t)1 << 31), (int64_t)1 << 31);
            sse = hdf_add64_sat(sse, rc * rc);
        }
    }
    e->fit_q[0] = sse;
    if (lo + n >= HD_FE_NBIN) {
        e->sse[j] = (sse < FE_NO_FIT) ? sse : FE_NO_FIT - 1;
    }
}

/* a + w (b - a), w in Q16 [0, 2^16] */
static int32_t lerp16(int32_t a, int32_t b, int32_t w)
{
    return hdf_sat32((int64_t)a + hdf_mul64x32_q((int64_t)b - (int64_t)a, w, 16u));
}

/* After the last candidate of direction d: best vs, excitation check, bounds, publish, in
 * parts of bounded cost: the best candidate (kept by the residual parts) and the parabola's
 * vertex (fit_finish_vertex), the refined parameters (fit_finish_pick), where the valid
 * bins lie relative to its vs (fit_finish_bins, in parts), the check (fit_finish_check),
 * the publication (fit_finish_publish) */
static void fit_finish_vertex(hd_fric_est_t *e)
{
    const uint32_t best = e->fit_best;      /* the residual parts kept the least (fit_part) */
    e->fin_ok = 0u;
    e->fin_x = 0;
    e->fin_par = 0u;
    if (e->sse[best] == FE_NO_FIT) {
        return;
    }
    e->fin_ok = 1u;
    e->fin_best = best;
    if (best > 0u && best < HD_FE_NGRID - 1u && e->sse[best - 1u] != FE_NO_FIT &&
        e->sse[best + 1u] != FE_NO_FIT) {
        /* parabola through the three sums: minimum at x = (a - c) / (2 (a - 2b + c)) grid steps */
        const int64_t sa = e->sse[best - 1u], sb = e->sse[best], sc = e->sse[best + 1u];
        const int64_t den = hdf_add64_sat(hdf_sub64_sat(sa, sb), hdf_sub64_sat(sc, sb));
        if (den > 0) {
            const int64_t x15 = div_approx(hdf_sub64_sat(sa, sc), (uint64_t)den, 15u);    /* x in Q16 */
            e->fin_x = hdf_sat32(hdf_clamp64(x15, -32768, 32768));
            e->fin_par = 1u;
        }
    }
}

static void fit_finish_pick(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, uint32_t d)
{
    const uint32_t best = e->fin_best;
    int32_t vs, fc, dfs, fv;
    if (e->fin_ok == 0u) {
        e->conf[d] = 0u;
        return;
    }
    vs = vs_of(c, best);
    fc = e->th[best][0];
    dfs = e->th[best][1];
    fv = e->th[best][2];
    if (e->fin_par != 0u) {
        const int32_t x = e->fin_x;
        const uint32_t nbj = (x > 0) ? best + 1u : best - 1u;
        const int32_t w = hdf_abs_sat(x);
        vs = lerp16(vs, vs_of(c, nbj), w);
        fc = lerp16(fc, e->th[nbj][0], w);
        dfs = lerp16(dfs, e->th[nbj][1], w);
        fv = lerp16(fv, e->th[nbj][2], w);
    }
    e->fin[0] = vs;
    e->fin[1] = fc;
    e->fin[2] = dfs;
    e->fin[3] = fv;
}

/* where the valid bins lo .. lo + n - 1 lie relative to the picked vs (the bins of this step,
 * in bin order) -> fin_n (counts), fin_v (slowest and fastest valid bin) */
static void fit_finish_bins(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, uint32_t d, uint32_t lo, uint32_t n)
{
    const int32_t vs = e->fin[0];
    uint32_t i;
    if (e->fin_ok == 0u) {
        return;
    }
    if (lo == 0u) {
        for (i = 0; i < 4u; i++) {
            e->fin_n[i] = 0u;
        }
        e->fin_v[0] = INT32_MAX;
        e->fin_v[1] = 0;
    }
    for (i = lo; i < lo + n; i++) {
        const hd_fe_bin_t *b = &e->bin[d][i];
        if (bin_valid(e, c, b)) {
            e->fin_n[3]++;
            e->fin_v[0] = (b->v < e->fin_v[0]) ? b->v : e->fin_v[0];
            e->fin_v[1] = (b->v > e->fin_v[1]) ? b->v : e->fin_v[1];
            if (b->v < vs / 2) {
                e->fin_n[0]++;
            } else if (b->v <= 2 * (int64_t)vs) {
                e->fin_n[1]++;
            } else {
                e->fin_n[2]++;
            }
        }
    }
}

static void fit_finish_check(hd_fric_est_t *e, uint32_t d)
{
    const uint32_t best = e->fin_best;
    const uint32_t nlo = e->fin_n[0], nmid = e->fin_n[1], nhi = e->fin_n[2], nvalid = e->fin_n[3];
    const int32_t vmin_valid = e->fin_v[0], vmax_valid = e->fin_v[1];
    const int32_t vs = e->fin[0], fc = e->fin[1], dfs = e->fin[2], fv = e->fin[3];
    e->fin_acc = 0u;
    if (e->fin_ok == 0u) {
        return;
    }
    e->conf[d] = 1000u * ((nlo < 2u) ? nlo : 2u) * ((nmid < 2u) ? nmid : 2u) * ((nhi < 2u) ? nhi : 2u) / 8u;
    /* vs two octaves inside the binned range (the drop and both plateaus seen), five bins */
    if (nvalid < 5u || (int64_t)vmin_valid * 4 > (int64_t)vs || (int64_t)vmax_valid < 4 * (int64_t)vs ||
        best == 0u || best == HD_FE_NGRID - 1u) {
        return;                             /* the bins do not inform every parameter: keep the old */
    }
    /* no Stribeck drop, or a viscous term that pulls the fastest bin down by more than fc / 8:
     * a straight line through the bins, not a Stribeck curve (the data do not show one) */
    if (dfs < 0 || hdf_mul64x32_q((int64_t)fv, vmax_valid, 32u) < -(int64_t)(fc / 8)) {
        return;
    }
    e->fin_acc = 1u;
}

static void fit_finish_publish(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, uint32_t d)
{
    const int32_t vs = e->fin[0], dfs = e->fin[2], fv = e->fin[3];
    int32_t fc = e->fin[1];
    if (e->fin_acc == 0u) {
        return;
    }
    fc = hdf_clamp32(fc, 0, c->tau_max);
    e->shape[d].fc = fc;
    e->shape[d].fs = hdf_clamp32(hdf_add_sat(fc, dfs), fc, c->tau_max);
    e->shape[d].vs = hdf_clamp32(vs, c->vs_lo, vs_of(c, HD_FE_NGRID - 1u));
    e->shape[d].fv = hdf_clamp32(fv, 0, c->fv_max);
    publish(e, c, d);
    e->fits[d]++;
}

/* One part of the fit's pass in progress (bounded cost: hd_fric_est.h "Cost"); true when
 * the pass is complete (then the next is set up). */
static bool fit_part(hd_fric_est_t *e, const hd_fric_est_cfg_t *c)
{
    const uint32_t k = e->fit_part;
    const uint32_t j = e->fit_j;
    bool done = false;
    switch (e->fit_pass) {
    case 0u:
    case 1u:
        /* snapshot: HD_FE_NBIN / 2 bins per pass, HD_FE_SNAP_BINS per part */
        fit_snapshot(e, c, e->fit_dir, j, e->fit_pass * (HD_FE_NBIN / 2u) + k * HD_FE_SNAP_BINS, HD_FE_SNAP_BINS);
        done = (k + 1u) * HD_FE_SNAP_BINS >= HD_FE_NBIN / 2u;
        break;
    case 2u:
        /* the solution: the means and HD_FE_SUM_BINS bins of the sums per part, then the
         * normal equations in four parts */
        if (k == 0u) {
            fit_solve_begin(e);
        }
        if (k < FE_SUM_PARTS) {
            fit_solve_sums(e, k * HD_FE_SUM_BINS, HD_FE_SUM_BINS);
        } else if (k == FE_SUM_PARTS) {
            fit_solve_det(e);
        } else if (k == FE_SUM_PARTS + 1u) {
            fit_solve_num(e);
        } else if (k == FE_SUM_PARTS + 2u) {
            fit_solve_dfs(e);
        } else {
            fit_solve_end(e, j);
            done = true;
        }
        break;
    default:
        /* the residual, HD_FE_SSE_BINS bins per part; after the last candidate the close */
        if (k < FE_SSE_PARTS) {
            fit_sse(e, j, k * HD_FE_SSE_BINS, HD_FE_SSE_BINS);
            if (k + 1u == FE_SSE_PARTS && (j == 0u || e->sse[j] < e->sse[e->fit_best])) {
                e->fit_best = j;            /* the close's pick without its own scan of the sums */
            }
            done = (k + 1u == FE_SSE_PARTS) && (j + 1u < HD_FE_NGRID);
        } else if (k == FE_SSE_PARTS) {
            fit_finish_vertex(e);
        } else if (k == FE_SSE_PARTS + 1u) {
            fit_finish_pick(e, c, e->fit_dir);
        } else if (k < FE_SSE_PARTS + 2u + FE_SCAN_PARTS) {
            fit_finish_bins(e, c, e->fit_dir, (k - FE_SSE_PARTS - 2u) * HD_FE_SCAN_BINS, HD_FE_SCAN_BINS);
        } else if (k == FE_SSE_PARTS + 2u + FE_SCAN_PARTS) {
            fit_finish_check(e, e->fit_dir);
        } else {
            fit_finish_publish(e, c, e->fit_dir);
            done = true;
        }
        break;
    }
    if (!done) {
        e->fit_part = k + 1u;
        return false;
    }
    e->fit_part = 0u;
    e->fit_due = 0u;
    if (e->fit_pass < 3u) {
        e->fit_pass++;
    } else {
        e->fit_pass = 0u;
        if (j + 1u < HD_FE_NGRID) {
            e->fit_j++;
        } else {
            e->fit_j = 0u;
            e->fit_dir = (e->fit_dir + 1u) % HD_FE_NDIR;
        }
    }
    return true;
}

/* an entry for the background (hd_fric_est_work): a full queue loses it, counted */
/* the control period's part of a step: the entry whole, then the head (the background reads
 * only entries below the head) */
static void queue_push(hd_fric_est_t *e, int32_t v, int32_t v_meas, int32_t tau, uint32_t flags)
{
    const uint32_t head = e->q_head;
    hd_fe_obs_t *o;
    if ((uint32_t)(head - e->q_tail) >= HD_FE_QLEN) {
        e->q_drop++;
        e->q_gap = HD_FE_OBS_GAP;
        return;
    }
    o = &e->q[head % HD_FE_QLEN];
    o->v = v;
    o->v_meas = v_meas;
    o->tau = tau;
    o->flags = flags | e->q_gap;
    e->q_gap = 0u;
    e->q_head = head + 1u;                  /* after the entry: the background reads it whole */
}

void hd_fric_est_queue_feed(hd_fric_est_t *e)
{
    queue_push(e, 0, 0, 0, HD_FE_OBS_FEED);
}

/* the step's low-passed velocity and steadiness test, in the order of the steps: whether its
 * sample is taken (HD_FE_OBS_SAMPLE) and the first of its visit (HD_FE_OBS_FIRST) */
static uint32_t classify(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, const hd_fe_obs_t *o)
{
    const int32_t v_ref = o->v;
    uint32_t flags = 0u;
    if ((o->flags & HD_FE_OBS_GAP) != 0u) {
        /* steps missing before it: a steady segment across them is not known to be one */
        e->steady_n = 0u;
        e->v_prev = 0;
        e->visit = 0u;
    }
    /* the measured velocity, low-passed (the observer's noise at slow rates) */
    e->v_lp = hdf_sat32((int64_t)e->v_lp + hdf_asr64_rnd((int64_t)o->v_meas - (int64_t)e->v_lp, HD_FE_VLP_SHIFT));
    if ((o->flags & HD_FE_OBS_ACTIVE) == 0u) {
        e->steady_n = 0u;
        e->v_prev = 0;
        e->visit = 0u;
    } else {
        const bool same = ((v_ref > 0) && (e->v_prev > 0)) || ((v_ref < 0) && (e->v_prev < 0));
        const int64_t dv = (int64_t)v_ref - (int64_t)e->v_prev;
        const int64_t slip = (int64_t)e->v_lp - (int64_t)v_ref;
        const int64_t half = (int64_t)hdf_abs_sat(v_ref) / 2;
        if (same && dv <= (int64_t)c->dv_max && dv >= -(int64_t)c->dv_max && slip <= half && slip >= -half) {
            if (e->steady_n < c->settle) {
                e->steady_n++;
            }
        } else {
            e->steady_n = 0u;
        }
        e->v_prev = v_ref;
        if (same && e->steady_n >= c->settle) {
            flags = HD_FE_OBS_SAMPLE | ((e->visit == 0u) ? HD_FE_OBS_FIRST : 0u);
            e->visit = 1u;
        } else {
            e->visit = 0u;
        }
    }
    return flags;
}

/* the next step of the queue: its count, its sample (the first part of the step's work),
 * then a quarter of a fit candidate */
static void work_begin(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, const hd_fe_obs_t *o)
{
    uint32_t flags;
    if ((o->flags & HD_FE_OBS_FEED) != 0u) {
        return;                             /* no step: done at once (the caller's feed only) */
    }
    flags = classify(e, c, o);
    e->steps++;
    if ((flags & HD_FE_OBS_SAMPLE) != 0u) {
        e->smp_v = o->v;
        e->smp_tau = o->tau;
        e->smp_first = ((flags & HD_FE_OBS_FIRST) != 0u) ? 1u : 0u;
        e->smp_stage = 1u;
    }
    e->fit_due = 1u;
    e->in_step = 1u;
}

bool hd_fric_est_work(hd_fric_est_t *e, const hd_fric_est_cfg_t *c)
{
    const uint32_t tail = e->q_tail;
    e->busy = 1u;
    if (e->in_step == 0u) {
        if (tail == e->q_head) {
            e->busy = 0u;
            return false;
        }
        work_begin(e, c, &e->q[tail % HD_FE_QLEN]);
    }
    if (e->in_step == 0u) {
        e->q_tail = tail + 1u;              /* a feed-only entry */
    } else if (e->smp_stage != 0u) {
        /* the step's sample first (as bin_update before the pass) */
        const uint32_t st = e->smp_stage;
        e->smp_stage = (st < FE_SMP_PARTS) ? st + 1u : 0u;
        sample_part(e, c, st);
    } else if (e->fit_due != 0u) {
        (void)fit_part(e, c);
    }
    if (e->in_step != 0u && e->smp_stage == 0u && e->fit_due == 0u) {
        e->in_step = 0u;
        e->q_tail = tail + 1u;              /* the step done: its entry is free */
    }
    e->busy = 0u;
    return (e->in_step != 0u) || (e->q_tail != e->q_head);
}

void hd_fric_est_work_feed(hd_fric_est_t *e, const hd_stribeck_cfg_t *base, int32_t share,
                           hd_stribeck_cfg_t *out)
{
    e->busy = 1u;
    hd_fric_est_feed_share(e, base, share, out);
    e->busy = 0u;
}

void hd_fric_est_step(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, int32_t v_ref, int32_t v_meas, int32_t tau,
                      bool active)
{
    hd_fric_est_observe(e, c, v_ref, v_meas, tau, active);
    while (hd_fric_est_work(e, c)) {
    }
}

void hd_fric_est_seed(hd_fric_est_t *e, const hd_stribeck_dir_t init[HD_FE_NDIR])
{
    uint32_t d;
    for (d = 0; d < HD_FE_NDIR; d++) {
        if (e->fits[d] == 0u) {
            e->est[d] = init[d];
            e->shape[d] = init[d];
        }
    }
}

void hd_fric_est_set_feed(hd_fric_est_t *e, bool on)
{
    hd_blend_set_enabled(&e->feed, on);
}

static void mix_dir(const hd_blend_t *w, const hd_stribeck_dir_t *base, const hd_stribeck_dir_t *est,
                    hd_stribeck_dir_t *out)
{
    out->fc = hd_blend_mix(w, base->fc, est->fc);
    out->fs = hd_blend_mix(w, base->fs, est->fs);
    out->vs = hd_blend_mix(w, base->vs, est->vs);
    out->fv = hd_blend_mix(w, base->fv, est->fv);
}

int32_t hd_fric_est_fed_scale(const hd_fric_est_t *e)
{
    const uint32_t a_pos = e->steps - e->oth_t[HD_FE_DIR_POS];
    const uint32_t a_neg = e->steps - e->oth_t[HD_FE_DIR_NEG];
    const uint32_t age = (a_pos < a_neg) ? a_pos : a_neg;
    uint32_t over;
    /* a level below the bins' is fed as it is: under-compensation costs little at a reversal
     * (the peak is flat below the friction level and steep above it, docs/compensators.md
     * section 11); a raised level is the friction of its last established visit */
    if (e->scale <= HD_FE_SCALE_ONE || age <= HD_FE_LEVEL_AGE) {
        return e->scale;
    }
    over = age - HD_FE_LEVEL_AGE;
    if (over >= ((uint32_t)1u << HD_FE_LEVEL_FADE_SHIFT)) {
        return HD_FE_SCALE_ONE;
    }
    /* linear over 2^HD_FE_LEVEL_FADE_SHIFT steps: a shift, no division; scale - 1 < 2^19 and
     * over < 2^12, so the product fits 31 bits */
    return e->scale - (int32_t)(((uint32_t)(e->scale - HD_FE_SCALE_ONE) * over) >> HD_FE_LEVEL_FADE_SHIFT);
}

/* the published estimate of a direction at the fed scale (publish() with s for the scale; s <= the
 * scale, so the levels stay within the bounds publish() gave them and fs >= fc holds) */
static hd_stribeck_dir_t est_at_scale(const hd_fric_est_t *e, uint32_t d, int32_t s)
{
    hd_stribeck_dir_t r;
    const hd_stribeck_dir_t *sh = &e->shape[d];
    if (s == e->scale) {
        return e->est[d];
    }
    /* below the published level: the bounds publish() applied (tau_max, fv_max) hold through
     * the minimum with it */
    r.fc = hdf_sat32(hdf_mul64x32_q((int64_t)sh->fc, s, 16u));
    r.fc = (r.fc > e->est[d].fc) ? e->est[d].fc : r.fc;
    r.fs = hdf_sat32(hdf_mul64x32_q((int64_t)sh->fs, s, 16u));
    r.fs = (r.fs > e->est[d].fs) ? e->est[d].fs : r.fs;
    r.fs = (r.fs < r.fc) ? r.fc : r.fs;
    r.vs = sh->vs;
    r.fv = hdf_sat32(hdf_mul64x32_q((int64_t)sh->fv, s, 16u));
    r.fv = (r.fv > e->est[d].fv) ? e->est[d].fv : r.fv;
    return r;
}

void hd_fric_est_feed_share(hd_fric_est_t *e, const hd_stribeck_cfg_t *base, int32_t share,
                            hd_stribeck_cfg_t *out)
{
    hd_stribeck_dir_t fed[HD_FE_NDIR];
    int32_t s;
    uint32_t d;
    *out = *base;
    if (hd_blend_update(&e->feed) == 0) {
        return;
    }
    s = hd_fric_est_fed_scale(e);
    for (d = 0u; d < (uint32_t)HD_FE_NDIR; d++) {
        fed[d] = est_at_scale(e, d, s);
        /* the torque turns from -g_neg to +g_pos at a reversal; the bins of a direction hold
         * g_d plus any direction-independent torque present while they filled (an unbalance,
         * + in one direction, - in the other): a fit of one direction with the model in the
         * other would carry that torque into the jump, so the estimate is fed once both
         * directions have a fit (the pair's jump is g_pos + g_neg) */
        if (e->fits[HD_FE_DIR_POS] == 0u || e->fits[HD_FE_DIR_NEG] == 0u) {
            fed[d] = (d == (uint32_t)HD_FE_DIR_POS) ? base->pos : base->neg;
        } else {
            /* the estimate is the total steady friction; the FF relays the share the written
             * levels carry (on the measured velocity the output side's friction sits behind
             * the gear's spring, docs/compensators.md section 13): levels times share, shape kept */
            fed[d].fc = hdf_sat32(hdf_mul64x32_q((int64_t)fed[d].fc, share, 16u));
            fed[d].fs = hdf_sat32(hdf_mul64x32_q((int64_t)fed[d].fs, share, 16u));
        }
    }
    mix_dir(&e->feed, &base->pos, &fed[HD_FE_DIR_POS], &out->pos);
    mix_dir(&e->feed, &base->neg, &fed[HD_FE_DIR_NEG], &out->neg);
    out->delta = 2u;                        /* the estimate's shape */
}

void hd_fric_est_feed(hd_fric_est_t *e, const hd_stribeck_cfg_t *base, hd_stribeck_cfg_t *out)
{
    hd_fric_est_feed_share(e, base, HD_FE_SCALE_ONE, out);
}
