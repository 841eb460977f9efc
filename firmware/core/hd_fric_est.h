/*
 * hd_fric_est.h - online Stribeck identification from normal motion.
 *
 * The drive keeps the static friction map of each direction,
 *     g_d(v) = fc_d + (fs_d - fc_d) exp(-(v / vs_d)^2) + fv_d |v|,   d = pos, neg
 * (the map of hd_stribeck.h with delta = 2) up to date while it moves, from
 * the torque it applies at constant velocity.  No dedicated experiment: at
 * a constant reference velocity and after the loops have settled, the torque
 * command is the friction at that velocity (inertia torque 0, no feed-forward
 * can change that: whatever the loop applies to keep the rate is friction).
 *
 * Data (excitation check 1: only steady sliding informs the static map).
 *   hd_fric_est_step() runs at a decimated rate (the caller's, e.g. 1 kHz).  The
 *   reference velocity v_ref is "steady" when it is non-zero, keeps its sign
 *   and changes by at most dv_max per step, and the axis slides with it: the
 *   measured velocity, low-passed over 2^HD_FE_VLP_SHIFT steps, is within
 *   |v_ref| / 2 of v_ref (after a reversal the axis sticks while the loops wind
 *   the torque through twice the breakaway level: at slow rates that takes
 *   longer than any fixed time; the torque of that phase is not friction).
 *   After settle steady steps each step adds (|v_ref|, torque) to the bin of
 *   |v_ref| of its direction.  Bins are half octaves of |v_ref| (bin edges 2^k and 1.5 2^k LSB), HD_FE_NBIN per
 *   direction from v_min up; outside [v_min, top edge] nothing is updated.
 *   Each bin holds the mean velocity and mean torque magnitude of its samples
 *   and their count n: a running mean while n < n_forget, then an exponential
 *   mean over the last ~n_forget samples.  Forgetting across visits: a slow
 *   bin gets few samples per visit and is visited once per motion cycle, so
 *   at the first sample of each visit (steady segment) its count is cut to
 *   n_keep (at least HD_FE_KEEP_MIN once the bin is established, below): the old
 *   mean then weighs as n_keep samples against the new visit.  An established bin
 *   (below) takes the visit as one mean: its value is the old mean g0 (weight n0)
 *   and the visit's mean torque over its k samples normalised by the present scale
 *   and bias, g0 + (m_k / scale - g0) k / (n0 + k).  The torque within a move is
 *   not constant (the loops settling, transmission error and cogging along the
 *   stroke) and the scale moves towards the visit's running mean during the visit:
 *   each sample normalised by the scale of its own moment would compare the sample
 *   with the running mean, and a torque that falls along every fast move would lower
 *   the fast bins at every visit (the viscous term drifting off with more data).
 *   A bin whose last sample is older than max_age steps is left out of the
 *   fit (a stale bin would hold the friction of another time; without it the
 *   excitation checks may keep the last estimate until the speed comes again).
 *   Updating a bin costs one 32-bit division (by n + 1).
 *
 * Common mode (fast): level drift and unbalance.
 *   A friction drift (temperature, lubricant) scales the Coulomb, static and viscous
 *   terms of both directions together; an unbalance adds the same signed torque to both
 *   directions.  The steady torque is modelled as
 *       tau = sign(v) scale g_d(|v|) + bias
 *   with the bins holding g, the shape (each sample enters its bin as
 *   sign(v) (tau - bias) / scale), and scale (Q16, bounded to x1/8..x8) and bias (Q15.16
 *   N.m, bounded by tau_max) shared by every bin.  Excitation check 3: only a visit to a
 *   bin that held n_min samples when the visit began informs the common mode (a new bin
 *   cannot tell a level change from its own level); the visit is compared with that
 *   mean g0, held for the whole visit (not with the running mean: a visit's own settling
 *   would look like a drift).  With the visit's mean signed torque m (n samples) and the
 *   last established visit of the other direction (m', g0', its last sample not older
 *   than HD_FE_PAIR_AGE steps, 4 s at 1 kHz, nor max_age: an older one may hold the
 *   friction of another time and would put part of a drift into the bias) the two equations m = sign scale g0 + bias give scale and bias; without
 *   a recent visit of the other direction the bias stays and the visit gives the scale
 *   (from one direction alone a level change and an unbalance look the same: the
 *   friction hypothesis).  Each sample moves scale and bias from their values at the
 *   visit's start towards that solution by n / (n + 2^HD_FE_SCALE_SHIFT): a drift seen in
 *   any established bin moves the published levels of every bin within one visit.  An
 *   established bin forgets over at least HD_FE_KEEP_MIN samples whatever n_forget and
 *   n_keep (the shape, vs and the ratio of the levels, moves slowly; the scale, not the
 *   visited bin, takes a level change).  The published estimate is the last accepted fit
 *   of the bins with its levels and viscous term times the scale (vs unchanged),
 *   refreshed at every sample once a fit of the direction was accepted.  A steady
 *   unbalance present from the start is in the bins (it looks like asymmetric friction);
 *   one that appears or changes goes to the bias, not to the friction levels.
 *   Stale levels (the feed only, hd_fric_est_fed_scale): a scale above 1 is the friction of
 *   the last established visit (a warm axis); while the axis only reverses or rests no visit
 *   tells whether it stays there or cools back.  Past HD_FE_LEVEL_AGE steps without an
 *   established visit of either direction the feed takes the scale linearly back to 1 (the
 *   bins' level) over 2^HD_FE_LEVEL_FADE_SHIFT steps: a fed level above the axis' gives a
 *   reversal peak worse than no compensation, one below it costs little (the peak is flat
 *   there), so an unconfirmed raise is not kept.  The estimate stays; the next established
 *   visit feeds it again.  A scale at or below 1 is fed as it is.
 *   Cost per sample of an established visit: three approximate divisions (div_approx,
 *   no 64-bit division), the normalisation of the visit's mean and its weight in the
 *   bin (two more).

 * Fit (excitation check 2: a parameter changes only when the bins inform it).
 *   Per direction, for each candidate Stribeck velocity vs_j = vs_lo 2^(j/4),
 *   j = 0..HD_FE_NGRID-1 (8 octaves), the map is linear in (fc, fs - fc, fv):
 *   least squares over the valid bins (n >= n_min, not older than max_age;
 *   centred 2x2 normal equations, solved through a reciprocal found by Newton
 *   iteration: no 64-bit division), and its residual sum of squares S_j.  A
 *   candidate takes four steps (two halves of the bins into a snapshot, the
 *   solution, the residual: a step costs a quarter of a candidate); both
 *   directions in turn, a full fit every 8 HD_FE_NGRID steps (256 ms at 1 kHz).
 *   After the last candidate: the best j, refined by a parabola through S_j-1,
 *   S_j, S_j+1 (vs interpolated linearly between the grid values, the linear
 *   parameters likewise), then the estimate of the
 *   direction is replaced only if
 *     - at least 5 bins are valid and they reach two octaves below and above
 *       the fitted vs (slowest valid bin <= vs / 4, fastest >= 4 vs: fs needs
 *       the plateau under the Stribeck drop, vs the drop, fc and fv the sliding
 *       above it; a fit to bins on one side only would place vs outside them),
 *     - the best j is not at either end of the grid (vs is inside the range),
 *     - the fit shows a Stribeck drop (fs >= fc) and no viscous term that lowers
 *       the fastest bin by more than fc / 8 (a line through the bins is not a
 *       Stribeck curve),
 *   and it is bounded: 0 <= fc <= fs <= tau_max, 0 <= fv <= fv_max, vs in the grid
 *   range.  Otherwise the old estimate stays.
 *
 * Confidence (per direction, permille): 1000 x min(n_lo, 2) min(n_mid, 2)
 *   min(n_hi, 2) / 8 with the valid bins below vs / 2 (lo: static level),
 *   within [vs / 2, 2 vs] (mid: Stribeck velocity) and above 2 vs (hi: Coulomb
 *   level and viscous term) of the last fit: 1000 when each region has two
 *   bins, 0 while one of them has none.
 *
 * Formats:
 *   v_ref, v_min, vs_lo, dv_max, est vs : output velocity, 2^-32 turn/s
 *   tau (input), fc, fs, tau_max        : Q15.16 N.m, output-referred
 *   fv, fv_max                          : Q15.16 N.m per (turn/s) (as hd_stribeck.h)
 *   bin velocity                        : 2^-32 turn/s; r16 = |v| / vs_lo in Q16
 *   e (shape)                           : Q16 inside the fit (exp(-x) by hd_exp_neg_q16)
 *   fit velocity column                 : |v| / 2^HD_FE_U_SHIFT (2^-21 turn/s)
 * Cost: a step is its observation (a queue entry: hd_fric_est_observe, inline, the
 *   control period's only share, a few stores), its steadiness test and sample (the bin update and the common mode: five approximate
 *   divisions) and a quarter of a fit candidate: 12 exp, or the 2x2 solution (two
 *   reciprocals), or the residual over 24 bins (+ the closing of a fit after the last
 *   one).  The sample and the pass run in the background (hd_fric_est_work) in parts of
 *   at most one division, one exp or a few bins each: the sample in 7 parts, a pass in at
 *   most 16 (HD_FE_STEP_PARTS in all); a step's background work is at most about 6,800
 *   instructions with the app's calls (tests/bench/10_cm4_cost.sh fe_background_step,
 *   docs/firmware.md).
 * Memory: hd_fric_est_t, about 2.4 KiB (the queue of HD_FE_QLEN observations included).
 */
#ifndef HD_FRIC_EST_H
#define HD_FRIC_EST_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_stribeck.h"
#include "hd_blend.h"

#define HD_FE_NBIN   24u     /* half-octave bins per direction (12 octaves) */
#define HD_FE_NGRID  32u     /* candidate Stribeck velocities, quarter octaves (8 octaves) */
#define HD_FE_U_SHIFT 11u    /* fit velocity column: |v| >> 11 (2^-21 turn/s) */
#define HD_FE_VLP_SHIFT 5u   /* low-pass of the measured velocity: 2^-5 per step (32 ms at 1 kHz) */
#define HD_FE_SCALE_ONE 65536          /* common-mode scale 1.0, Q16 */
#define HD_FE_SCALE_MIN (HD_FE_SCALE_ONE / 8)   /* bounds of the scale: x1/8 .. x8 */
#define HD_FE_SCALE_MAX (HD_FE_SCALE_ONE * 8)
#define HD_FE_SCALE_SHIFT 5u /* weight of scale and bias at a visit's start: 2^5 samples (32 ms at 1 kHz) */

#define HD_FE_STEP_PARTS 23u  /* most parts of one step's work: its sample (7) and a pass (16) */

#define HD_FE_PAIR_AGE 4096u  /* the other direction's visit pairs with this one if not older, steps */
#define HD_FE_KEEP_MIN 1024u  /* least memory of an established bin, samples (the shape moves slowly) */
#define HD_FE_LEVEL_AGE HD_FE_PAIR_AGE /* a raised scale is fed in full this long after the last
                                        * established visit, steps (the pairing's horizon) */
#define HD_FE_LEVEL_FADE_SHIFT 12u    /* ... then falls to 1 over 2^12 steps (4.1 s at 1 kHz) */

typedef enum {
    HD_FE_DIR_POS = 0,
    HD_FE_DIR_NEG = 1,
    HD_FE_NDIR = 2
} hd_fe_dir_t;

typedef struct {
    int32_t  v_min;          /* lowest velocity binned, 2^-32 turn/s, > 0 */
    int32_t  vs_lo;          /* smallest candidate vs, 2^-32 turn/s, > 0 (vs_hi = 2^7.75 vs_lo) */
    int32_t  dv_max;         /* largest change of v_ref per step that is still steady, 2^-32 turn/s */
    uint32_t settle;         /* steady steps before a sample is taken */
    uint32_t n_forget;       /* bin memory, samples (>= 1) */
    uint32_t n_min;          /* samples for a bin to count in the fit (>= 1) */
    uint32_t n_keep;         /* weight of a bin's old mean at the start of a visit, samples */
    uint32_t max_age;        /* a bin not updated for longer than this (steps) is left out of the fit */
    int32_t  tau_max;        /* bound of fc and fs, Q15.16 N.m, > 0 */
    int32_t  fv_max;         /* bound of fv, Q15.16 N.m/(turn/s), >= 0 */
    hd_stribeck_recip_t rvs; /* reciprocal of vs_lo (hd_fric_est_config) */
} hd_fric_est_cfg_t;

typedef struct {
    int32_t  v;              /* mean |v_ref|, 2^-32 turn/s */
    int32_t  f;              /* mean torque magnitude, Q15.16 N.m */
    int32_t  r16;            /* v / vs_lo, Q16 (saturated) */
    uint32_t n;              /* samples (saturates at n_forget) */
    uint32_t stamp;          /* step count of its last sample */
} hd_fe_bin_t;

/* One observation for the background (hd_fric_est_observe -> hd_fric_est_work). */
#define HD_FE_QLEN 8u                  /* observations queued (8 ms at 1 kHz) */
#define HD_FE_OBS_SAMPLE 1u            /* flags: a steady sample ... */
#define HD_FE_OBS_FIRST 2u             /* ... the first of its visit */
#define HD_FE_OBS_FEED 4u              /* no step: the feed's step only (estimator off, feed ramping out) */
#define HD_FE_OBS_ACTIVE 8u            /* the loops ran the step (the steadiness test applies) */
#define HD_FE_OBS_GAP 16u              /* steps before it were not queued (lost or not observed) */
typedef struct {
    int32_t  v;              /* v_ref, 2^-32 turn/s */
    int32_t  v_meas;         /* measured velocity, 2^-32 turn/s */
    int32_t  tau;            /* torque applied, Q15.16 N.m */
    uint32_t flags;          /* HD_FE_OBS_* */
} hd_fe_obs_t;

typedef struct {
    hd_fe_bin_t bin[HD_FE_NDIR][HD_FE_NBIN];
    hd_stribeck_dir_t est[HD_FE_NDIR];  /* published estimate (magnitudes): shape x scale */
    hd_stribeck_dir_t shape[HD_FE_NDIR];/* last accepted fit of the bins (normalised levels) */
    int32_t  scale;                     /* common-mode friction level, Q16 (1.0 = HD_FE_SCALE_ONE) */
    int32_t  bias;                      /* direction-independent torque (unbalance), Q15.16 N.m */
    int32_t  vis_g;                     /* mean of the visited bin when the visit began, Q15.16 N.m (0: none) */
    uint32_t vis_bin;                   /* the visited bin, direction x HD_FE_NBIN + bin */
    uint32_t vis_n;                     /* samples of the visit (saturates at n_forget) */
    int32_t  vis_m;                     /* the visit's mean signed torque, Q15.16 N.m */
    int32_t  vis_s0;                    /* scale when the visit began, Q16 */
    int32_t  vis_b0;                    /* bias when the visit began, Q15.16 N.m */
    uint32_t vis_k;                     /* samples of the visit for its bin (saturates at the bin's memory) */
    int32_t  vis_a;                     /* the visit's plain mean signed torque, Q15.16 N.m */
    uint32_t vis_n0;                    /* the bin's weight when the visit began, samples */
    int32_t  oth_m[HD_FE_NDIR];         /* per direction: mean signed torque of its last established visit */
    int32_t  oth_g[HD_FE_NDIR];         /* ... the mean of its bin when that visit began (0: none) */
    uint32_t oth_t[HD_FE_NDIR];         /* ... and the step of its last sample */
    uint32_t conf[HD_FE_NDIR];          /* confidence, permille */
    uint32_t fits[HD_FE_NDIR];          /* accepted fits (wraps) */
    int64_t  sse[HD_FE_NGRID];          /* residual sums of the fit in progress */
    int32_t  th[HD_FE_NGRID][3];        /* its (fc, fs - fc, fv) per candidate */
    uint32_t fit_dir;                   /* direction of the fit in progress */
    uint32_t fit_j;                     /* its candidate in progress */
    uint32_t fit_pass;                  /* the candidate's step, 0..3 */
    uint32_t fit_part;                  /* the pass's next part (hd_fric_est_fit_part) */
    uint32_t fit_due;                   /* 1 while the pass of the last step has parts left */
    uint32_t fit_nb;                    /* valid bins of the snapshot (pass 2) */
    int64_t  fit_q[5];                  /* pass 2: centred sums (see, suu, seu, sef, suf), then det and Cramer's
                                         * numerators in [0..2]; pass 3: residual */
    int32_t  fit_m[3];                  /* pass 2: means of shape, velocity column, torque */
    uint32_t fin_ok;                    /* close of a fit: 1 when a candidate was picked */
    uint32_t fin_best;                  /* its best candidate */
    uint32_t fit_best;                  /* least residual so far in the sweep (first of equals) */
    uint32_t fin_n[4];                  /* close: valid bins below vs / 2, within [vs / 2, 2 vs], above, all */
    int32_t  fin_v[2];                  /* close: slowest and fastest valid bin, 2^-32 turn/s */
    int32_t  fin[4];                    /* its refined (vs, fc, fs - fc, fv) */
    int32_t  fit_a[3];                  /* pass 2: the scaled normal matrix (a, b, c), < 2^30 + 1 */
    uint32_t fit_sh[3];                 /* ... its shifts (shape, velocity, cross term) */
    int32_t  fit_dfs;                   /* pass 2: fs - fc of the candidate, Q15.16 N.m */
    int32_t  fin_x;                     /* close: the parabola's vertex, Q16 grid steps */
    uint32_t fin_par;                   /* close: 1 when the vertex refines the best candidate */
    uint32_t fin_acc;                   /* close: 1 when the check accepts the fit */
    uint32_t fit_mask;                  /* valid bins of the candidate's snapshot (bit per bin) */
    uint32_t fit_ok;                    /* 1: pass 2 solved the candidate */
    int64_t  fit_s[3];                  /* snapshot sums of shape, velocity column, torque */
    int32_t  fit_e[HD_FE_NBIN];         /* snapshot: shape, Q16 */
    int32_t  fit_u[HD_FE_NBIN];         /* snapshot: velocity column, 2^-21 turn/s */
    int32_t  fit_f[HD_FE_NBIN];         /* snapshot: mean torque, Q15.16 N.m */
    hd_fe_obs_t q[HD_FE_QLEN];          /* observations not yet worked (ring) */
    volatile uint32_t q_head;           /* observations queued (wraps; written by the observation) */
    volatile uint32_t q_tail;           /* steps worked (wraps; written by the background) */
    uint32_t q_drop;                    /* observations lost to a full queue (wraps) */
    uint32_t q_gap;                     /* HD_FE_OBS_GAP: a step not queued since the last entry
                                         * (0: none; the control period's, the next entry carries it) */
    uint32_t in_step;                   /* 1 while the background works a step */
    volatile uint32_t busy;             /* 1 inside hd_fric_est_work (the control period then
                                         * leaves the background's state alone) */
    uint32_t smp_stage;                 /* the step's sample: its next part, 1..7 (0: none due) */
    int32_t  smp_v;                     /* its reference velocity, 2^-32 turn/s */
    int32_t  smp_tau;                   /* its torque, Q15.16 N.m */
    uint32_t smp_first;                 /* 1: the first sample of a visit */
    int32_t  smp_k;                     /* its bin (-1: outside the bins) */
    int32_t  smp_tc;                    /* its torque bounded by tau_max, Q15.16 N.m */
    int64_t  smp_st;                    /* the common mode's scale from the visit, Q16 (unbounded) */
    int64_t  smp_bt;                    /* ... and its bias, Q15.16 N.m (unbounded) */
    int32_t  smp_f;                     /* the sample normalised by scale and bias, Q15.16 N.m */
    uint32_t smp_cap;                   /* the bin's memory for this sample, samples */
    int32_t  v_prev;                    /* v_ref of the last step */
    int32_t  v_lp;                      /* low-passed measured velocity, 2^-32 turn/s */
    uint32_t steady_n;                  /* steady steps (saturates at settle) */
    uint32_t visit;                     /* 1 while a steady segment is being binned */
    uint32_t samples;                   /* samples taken (wraps) */
    uint32_t steps;                     /* steps since init (wraps; bin ages) */
    hd_blend_t feed;                    /* weight of the estimate in the Stribeck feed-forward */
} hd_fric_est_t;

/** Config from raw values; 0 ok, -1 inconsistent (non-positive velocities, n 0). Contains a
 *  64-bit division (the reciprocal of vs_lo): call it when the parameters change. */
int32_t hd_fric_est_config(hd_fric_est_cfg_t *c, int32_t v_min, int32_t vs_lo, int32_t dv_max,
                           uint32_t settle, uint32_t n_forget, uint32_t n_min, uint32_t n_keep,
                           uint32_t max_age, int32_t tau_max, int32_t fv_max);
/** Empty bins; the estimate starts from init (magnitudes of both directions, e.g. the
 *  Stribeck FF parameters) with confidence 0; feed weight ramp over ramp_steps steps. */
void hd_fric_est_init(hd_fric_est_t *e, const hd_stribeck_dir_t init[HD_FE_NDIR], uint32_t ramp_steps,
                      bool feed);
/** One step (decimated rate): v_ref the reference velocity, v_meas the measured velocity,
 *  tau the torque applied (all of the step's period), active = 0 while the loops do not run
 *  (forgets the steadiness). */
void hd_fric_est_step(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, int32_t v_ref, int32_t v_meas, int32_t tau,
                      bool active);
/** hd_fric_est_step split between the control period and the background.
 *  hd_fric_est_observe (the control period, every step): the step's reference, measured
 *  velocity, torque and activity go into a queue of HD_FE_QLEN observations (a full queue
 *  loses it: q_drop); it touches only the queue's head and q_gap.  The background takes the
 *  low-passed velocity and the steadiness test (v_lp, v_prev, steady_n, visit) with the
 *  entry, in order; an entry after steps that were not queued (a full queue,
 *  hd_fric_est_skip) starts with the steadiness forgotten, as after a step without the loops.
 *  hd_fric_est_work (the background, below the control period): one part of the oldest
 *  queued step per call (the step's count, its sample in 7 parts, then its pass of the fit:
 *  12 snapshot parts of one bin, 12 parts of the solution's sums of 2 bins + 4 of the
 *  solution, or 8 residual parts of 3 bins + 8 for the close of a fit); true while work is
 *  left.  Every step is worked whole and in order: observe + work until false =
 *  hd_fric_est_step, bit for bit.  busy is 1 inside a call: the control period changes the
 *  background's state (hd_fric_est_init, hd_fric_est_seed, the config the background uses)
 *  only while it is 0 (hd_comp_bank_fric_est). */
static inline void hd_fric_est_observe(hd_fric_est_t *e, const hd_fric_est_cfg_t *c, int32_t v_ref,
                                       int32_t v_meas, int32_t tau, bool active)
{
    /* inline: a few stores in the control period's worst tick (the steadiness test, config c,
     * is the background's) */
    const uint32_t head = e->q_head;
    hd_fe_obs_t *o;
    (void)c;
    if ((uint32_t)(head - e->q_tail) >= HD_FE_QLEN) {
        e->q_drop++;
        e->q_gap = HD_FE_OBS_GAP;
        return;
    }
    o = &e->q[head % HD_FE_QLEN];
    o->v = v_ref;
    o->v_meas = v_meas;
    o->tau = tau;
    o->flags = (active ? HD_FE_OBS_ACTIVE : 0u) | e->q_gap;
    e->q_gap = 0u;
    e->q_head = head + 1u;                  /* after the entry: the background reads it whole */
}
bool hd_fric_est_work(hd_fric_est_t *e, const hd_fric_est_cfg_t *c);
/** A step not observed (an identification experiment, not normal motion): nothing queued,
 *  the next observation's steadiness starts afresh (HD_FE_OBS_GAP). */
static inline void hd_fric_est_skip(hd_fric_est_t *e)
{
    e->q_gap = HD_FE_OBS_GAP;
}
/** A feed-only entry for the background (the estimator off, its feed ramping out: the
 *  weight's step without an estimator step); a full queue loses it (q_drop). */
void hd_fric_est_queue_feed(hd_fric_est_t *e);
/** The background's feed after a worked entry: hd_fric_est_feed_share inside the busy mark
 *  (the weight and out are the background's; the control period copies out between parts). */
void hd_fric_est_work_feed(hd_fric_est_t *e, const hd_stribeck_cfg_t *base, int32_t share,
                           hd_stribeck_cfg_t *out);
/** True inside hd_fric_est_work (a part in progress). */
static inline bool hd_fric_est_busy(const hd_fric_est_t *e)
{
    return e->busy != 0u;
}
/** The bin of |v| (0..HD_FE_NBIN-1), or -1 outside the binned range. */
int32_t hd_fric_est_bin_of(const hd_fric_est_cfg_t *c, int32_t v);
/** The initial estimate follows new parameters (init, e.g. the Stribeck FF parameters just
 *  written) in each direction without an accepted fit: until the bins have given a fit the
 *  estimate is the model in force, not the one at the estimator's start.  A direction with
 *  a fit keeps it (the bins, not the parameters, inform it). */
void hd_fric_est_seed(hd_fric_est_t *e, const hd_stribeck_dir_t init[HD_FE_NDIR]);
/** Switch the feed of the estimate into the Stribeck FF (weight ramps, bumpless). */
void hd_fric_est_set_feed(hd_fric_est_t *e, bool on);
/** The Stribeck FF config the drive uses: base with its four parameters per direction
 *  moved to the estimate by the feed weight, out = base + w (est - base); the weight
 *  advances one ramp step per call (call once per estimator step). */
void hd_fric_est_feed(hd_fric_est_t *e, const hd_stribeck_cfg_t *base, hd_stribeck_cfg_t *out);
/** hd_fric_est_feed with the estimate's levels (fc, fs) times share (Q16, 0..1: the share of the
 *  total friction the FF relays, as the written levels carry it).  The estimate is fed once both
 *  directions have an accepted fit; until then the fed map is base. */
void hd_fric_est_feed_share(hd_fric_est_t *e, const hd_stribeck_cfg_t *base, int32_t share,
                            hd_stribeck_cfg_t *out);
/** The scale the feed uses (Q16): the common-mode scale while an established visit of either
 *  direction is at most HD_FE_LEVEL_AGE steps old or the scale is at most 1; past that a scale
 *  above 1 falls linearly to 1 over 2^HD_FE_LEVEL_FADE_SHIFT steps (the stale-level rule,
 *  above).  The estimate itself (est, scale) is kept: the next established visit feeds it again. */
int32_t hd_fric_est_fed_scale(const hd_fric_est_t *e);
/** True while the feed weight is not 0. */
static inline bool hd_fric_est_feeding(const hd_fric_est_t *e)
{
    return hd_blend_active(&e->feed);     /* inline: the bank asks every period */
}

#endif
