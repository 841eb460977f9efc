/*
 * hd_trajectory.c - exact integer reference generator (formats: hd_trajectory.h).
 *
 * PTP plan (per-period units of 2^-48 turn, all exact integers):
 *   accel (na periods) | cruise (tv) | decel (na periods, the accel levels negated)
 *   a = level(k); v += a; p += v (+ cruise fraction carry, + residual share) each period.
 * The accel levels are the jerk-limited ramp  j, 2j, .. tj j | tj j (ta) | (tj-1) j .. 0
 * (peak V0 = j tj (tj + ta)) with ONE extra period of level D = vmax - V0 inserted
 * between the levels m j and (m + 1) j, m = floor(D / j) (0 <= D < j tj): the jerk
 * next to it is D - m j and (m + 1) j - D, both in [0, j], its level D < tj j <= amax,
 * and the cruise velocity is V = V0 + D = vmax EXACTLY (whole periods alone quantise
 * V0 below vmax: 19 % at 0.001 deg/s with the default limits).  The fraction of the
 * commanded rate below one unit per period (vlim 2^16 mod HD_LOOP_HZ) is added in the
 * cruise with a remainder carry, so the cruise advances exactly vlim 2^16 t / HD_LOOP_HZ.
 * Because the decel levels are the accel levels negated in the same order, the decel
 * velocities are V - v_i and the two ramps together cover exactly na V.
 * tv = the largest with tv V + floor(tv frac / HD_LOOP_HZ) <= D_move - na V; the
 * residual R (< V + 1) is spread over all K periods of the move with a Bresenham
 * carry, so the move ends exactly on the target.  A move too short for na V takes the
 * largest whole-period ramp that fits (no inserted level, peak below vmax).
 */
#include "hd_trajectory.h"
#include "hd_fixed.h"

#define TJ_CAP 65536u           /* jerk phase cap, periods (6.5 s) */
#define TA_CAP 2097152u         /* constant-accel phase cap, periods (210 s) */
#define TWO_PI_Q28 1686629713   /* round(2 pi 2^28) */

/* Per-period fixed-point helpers: the inline hdf_* forms of hd_fixed.h
 * (bit-identical to hd_fixed.c, shifts folded at the call sites). */

/* floor division by a positive int64 with non-negative remainder */
static int64_t floordiv(int64_t num, int64_t den, int64_t *rem)
{
    int64_t q = num / den;
    int64_t r = num % den;
    if (r < 0) {
        q -= 1;
        r += den;
    }
    *rem = r;
    return q;
}

/* Advance (a, v, p) through n periods of constant jerk j (exact, saturating). */
static void phase(uint32_t n, int64_t j, int64_t *a, int64_t *v, int64_t *p)
{
    const int64_t nn = (int64_t)n;
    const int64_t t1 = nn * (nn + 1) / 2;
    const int64_t t2 = hd_mul64x32_q(t1, (int32_t)(nn + 2 <= INT32_MAX ? nn + 2 : INT32_MAX), 0) / 3;
    int64_t dp = hd_mul64x32_q(*v, (int32_t)n, 0);
    dp = hd_add64_sat(dp, hd_mul64x32_q(t1, hd_sat32(*a), 0));
    dp = hd_add64_sat(dp, hd_mul64x32_q(t2, hd_sat32(j), 0));
    *p = hd_add64_sat(*p, dp);
    *v = hd_add64_sat(*v, hd_add64_sat(hd_mul64x32_q(*a, (int32_t)n, 0), hd_mul64x32_q(t1, hd_sat32(j), 0)));
    *a = hd_add64_sat(*a, hd_mul64x32_q(j, (int32_t)n, 0));
}

/* distance of the accel + decel phases with unit jerk */
static int64_t dist1(uint32_t tj, uint32_t ta)
{
    int64_t a = 0, v = 0, p = 0;
    phase(tj, 1, &a, &v, &p);
    phase(ta, 0, &a, &v, &p);
    phase(tj, -1, &a, &v, &p);
    phase(tj, -1, &a, &v, &p);
    phase(ta, 0, &a, &v, &p);
    phase(tj, 1, &a, &v, &p);
    return p;
}

static int32_t fits(uint32_t tj, uint32_t ta, int64_t j, int64_t d)
{
    return hd_mul64x32_q(dist1(tj, ta), hd_sat32(j), 0) <= d;
}

static void outputs(hd_traj_t *s, int64_t step48)
{
    s->pos = hdf_asr64_rnd(s->p48, 16u);
    s->vel = hdf_sat32(hdf_mul64x32_q(step48, HD_LOOP_HZ, 16u));
    s->acc = hdf_sat32(hdf_mul64x32_q(s->a48, 100000000, 24u));
}

void hd_traj_reset(hd_traj_t *s, hd_angle_t pos)
{
    s->mode = HD_TRAJ_HOLD;
    s->p48 = hd_shl64_sat(pos, 16u);
    s->v48 = 0;
    s->a48 = 0;
    s->j48 = 0;
    s->target48 = s->p48;
    s->dir = 1;
    s->k = 0;
    s->tj = 0;
    s->ta = 0;
    s->tv = 0;
    s->tn = 0;
    s->ins_k = 0;
    s->ins_a = 0;
    s->vfrac = 0;
    s->vfrac_acc = 0;
    s->cruise_r = 0;
    s->cruise_acc = 0;
    s->goal48 = s->p48;
    s->appr_leg = 0;
    s->appr_wait = 0;
    s->rate_target = 0;
    s->rate_cur = 0;
    s->rate_dv = 1;
    s->rate_rem = 0;
    s->center = pos;
    s->amp = 0;
    s->w_q16 = 0;
    s->phase = 0;
    s->inc_q = 0;
    s->inc_r = 0;
    s->inc_acc = 0;
    outputs(s, 0);
}

/* accel-phase periods: ramp up, plateau, ramp down, inserted level */
static uint32_t ptp_ramp(const hd_traj_t *s)
{
    return 2u * s->tj + s->ta + s->tn;
}

static uint32_t ptp_total(const hd_traj_t *s)
{
    return 2u * ptp_ramp(s) + s->tv;
}

/* accel-phase level i (0 <= i < na): the ramp, with the inserted level at ins_k */
static inline int64_t ramp_level(const hd_traj_t *s, uint32_t i)
{
    const uint32_t tj = s->tj, ta = s->ta;
    if (s->tn != 0u) {
        if (i == s->ins_k) {
            return s->ins_a;
        }
        if (i > s->ins_k) {
            i--;
        }
    }
    if (i < tj) {
        return (int64_t)(i + 1u) * s->j48;
    }
    if (i < tj + ta) {
        return (int64_t)tj * s->j48;
    }
    return (int64_t)(2u * tj + ta - 1u - i) * s->j48;
}

/* cruise distance of t periods at V + frac / HD_LOOP_HZ */
static int64_t cruise_dist(int64_t t, int64_t v, uint32_t frac)
{
    return hd_add64_sat(hd_mul64x32_q(v, hd_sat32(t), 0), t * (int64_t)frac / HD_LOOP_HZ);
}

/* Plan one jerk-limited leg from rest at p48 to target48 with velocity limit
 * vlim (2^-32 turn/s, > 0) and the acceleration / jerk limits of c. */
static void plan(hd_traj_t *s, const hd_traj_cfg_t *c, hd_vel_out_t vlim, int64_t target48)
{
    /* limits in per-period units of 2^-48 turn; vmax + frac / HD_LOOP_HZ = vlim 2^16 / HD_LOOP_HZ */
    int64_t rem;
    const int64_t vmax = floordiv((int64_t)vlim * 65536, HD_LOOP_HZ, &rem);
    const int64_t amax = hd_div64_rnd((int64_t)c->amax * 16777216, 100000000);
    int64_t j = hd_div64_rnd(hd_shl64_sat((int64_t)c->jmax, 32u), 1000000000000LL);
    if (j < 1) {
        j = 1;
    }
    int64_t d = hd_sub64_sat(target48, s->p48);
    s->dir = (d < 0) ? -1 : 1;
    d = hd_abs64_sat(d);

    uint32_t tj, ta, tn = 0u;
    int64_t ins = 0;
    uint32_t frac = 0u;
    if (j >= amax) {                 /* acceleration limit reached within one period */
        j = (amax > 0) ? amax : 1;
        tj = 1;
    } else {
        int64_t q = amax / j;
        tj = (q > (int64_t)TJ_CAP) ? TJ_CAP : (uint32_t)q;
    }
    if (j > vmax && vmax > 0) {      /* one period of jerk would pass vmax: ramp in one period */
        j = vmax;
        tj = 1;
    }
    /* velocity limit: V0 = j tj (tj + ta) <= vmax, tj as large as the limits allow */
    if (hd_mul64x32_q((int64_t)tj * (int64_t)tj, hd_sat32(j), 0) > vmax) {
        int64_t q = vmax / j;
        uint32_t r = hd_isqrt64((uint64_t)(q > 0 ? q : 0));
        tj = (r < 1u) ? 1u : r;
    }
    {
        int64_t q = vmax / hd_mul64x32_q(j, (int32_t)tj, 0) - (int64_t)tj;
        ta = (q <= 0) ? 0u : (q > (int64_t)TA_CAP ? TA_CAP : (uint32_t)q);
    }
    int64_t vpk = hd_mul64x32_q((int64_t)tj * (int64_t)(tj + ta), hd_sat32(j), 0);
    {
        /* the inserted level lands the cruise exactly on vmax (0 <= D < j tj unless ta was capped) */
        const int64_t dv = vmax - vpk;
        if (dv >= 0 && dv < hd_mul64x32_q(j, (int32_t)tj, 0)) {
            tn = (dv > 0) ? 1u : 0u;
            ins = dv;
            vpk = vmax;
            frac = (uint32_t)rem;
        }
    }
    int64_t covered = hd_mul64x32_q(vpk, (int32_t)(2u * tj + ta + tn), 0);
    if (covered > d) {
        /* distance: no inserted level; shrink ta, then tj, to the largest that fits */
        tn = 0u;
        ins = 0;
        frac = 0u;
        if (!fits(tj, ta, j, d)) {
            if (!fits(tj, 0, j, d)) {
                uint32_t lo = 1, hi = tj;
                ta = 0;
                if (!fits(1, 0, j, d)) {
                    tj = 1;
                    j = d / dist1(1, 0);  /* tiny move: reduce jerk (may be 0) */
                } else {
                    while (lo < hi) {   /* largest tj in [1, hi] that fits */
                        uint32_t mid = lo + (hi - lo + 1u) / 2u;
                        if (fits(mid, 0, j, d)) {
                            lo = mid;
                        } else {
                            hi = mid - 1u;
                        }
                    }
                    tj = lo;
                }
            } else {
                uint32_t lo = 0, hi = ta;
                while (lo < hi) {
                    uint32_t mid = lo + (hi - lo + 1u) / 2u;
                    if (fits(tj, mid, j, d)) {
                        lo = mid;
                    } else {
                        hi = mid - 1u;
                    }
                }
                ta = lo;
            }
        }
        vpk = hd_mul64x32_q((int64_t)tj * (int64_t)(tj + ta), hd_sat32(j), 0);
        covered = hd_mul64x32_q(dist1(tj, ta), hd_sat32(j), 0);
    }
    int64_t left = d - covered;
    int64_t tv = (vpk > 0) ? left / vpk : 0;
    if (tv > (int64_t)INT32_MAX / 2) {
        tv = INT32_MAX / 2;
    }
    while (tv > 0 && cruise_dist(tv, vpk, frac) > left) {
        /* the cruise fraction adds < 1 unit per period: step back by the excess */
        const int64_t over = cruise_dist(tv, vpk, frac) - left;
        tv -= (over + vpk - 1) / vpk;
        if (tv < 0) {
            tv = 0;
        }
    }
    left -= cruise_dist(tv, vpk, frac);   /* residual, spread over the whole move */
    s->j48 = j;
    s->tj = tj;
    s->ta = ta;
    s->tn = tn;
    s->ins_a = ins;
    s->ins_k = (tn != 0u) ? (uint32_t)(ins / j) : 0u;
    s->vfrac = frac;
    s->vfrac_acc = 0u;
    s->tv = (uint32_t)tv;
    if (ptp_total(s) == 0u) {
        s->tv = 1u;                   /* zero-jerk tiny move: one period */
    }
    s->cruise_r = left;
    s->cruise_acc = 0;
    s->target48 = target48;
    s->k = 0;
    s->v48 = 0;
    s->a48 = 0;
    s->mode = HD_TRAJ_PTP;
}

/* final-leg velocity limit: min(appr_vmax, vmax), appr_vmax <= 0 = vmax */
static hd_vel_out_t appr_vlim(const hd_traj_cfg_t *c)
{
    return (c->appr_vmax > 0 && c->appr_vmax < c->vmax) ? c->appr_vmax : c->vmax;
}

int32_t hd_traj_ptp(hd_traj_t *s, const hd_traj_cfg_t *c, hd_angle_t target)
{
    if (c->vmax <= 0 || c->amax <= 0 || c->jmax <= 0) {
        return -1;
    }
    if (s->mode != HD_TRAJ_HOLD && !hd_traj_done(s)) {
        return -1;
    }
    const int64_t target48 = hd_shl64_sat(target, 16u);
    const int64_t d = hd_sub64_sat(target48, s->p48);
    s->goal48 = target48;
    s->appr_leg = 0;
    s->appr_wait = 0;
    if ((c->appr_dir == 1 || c->appr_dir == -1) && c->appr_dist > 0 && d != 0 &&
        ((d < 0) != (c->appr_dir < 0))) {
        /* wrong side: first leg to target - dir * dist, the final leg follows */
        const int64_t dist48 = hd_shl64_sat((int64_t)c->appr_dist, 16u);
        s->appr_leg = 1;
        plan(s, c, c->vmax,
             (c->appr_dir > 0) ? hd_sub64_sat(target48, dist48) : hd_add64_sat(target48, dist48));
        return 0;
    }
    plan(s, c, c->vmax, target48);
    return 0;
}

void hd_traj_rate(hd_traj_t *s, const hd_traj_cfg_t *c, hd_vel_out_t v)
{
    int32_t dv = hd_sat32(hd_div64_rnd((int64_t)c->amax * 256, HD_LOOP_HZ));
    if (s->mode != HD_TRAJ_RATE) {
        s->rate_cur = s->vel;
        s->rate_rem = 0;
    }
    s->rate_dv = (dv < 1) ? 1 : dv;
    s->appr_leg = 0;
    s->rate_target = hd_clamp32(v, hd_neg_sat(c->vmax), c->vmax);
    s->mode = HD_TRAJ_RATE;
}

void hd_traj_stop(hd_traj_t *s, const hd_traj_cfg_t *c)
{
    hd_traj_rate(s, c, 0);
}

int32_t hd_traj_sine(hd_traj_t *s, hd_angle_t center, int32_t amp, int32_t f_q16)
{
    if (f_q16 <= 0 || amp < 0) {
        return -1;
    }
    if (s->mode != HD_TRAJ_HOLD && !hd_traj_done(s)) {
        return -1;
    }
    /* phase increment per period = f * 2^64 / HD_LOOP_HZ = f_q16 * 2^48 / HD_LOOP_HZ,
     * as quotient + remainder (den HD_LOOP_HZ) so the phase is exact. */
    const uint64_t x = (uint64_t)(uint32_t)f_q16 << 20;
    const uint64_t q1 = x / HD_LOOP_HZ;
    const uint64_t r1 = x % HD_LOOP_HZ;
    const uint64_t y = r1 << 28;
    s->inc_q = (q1 << 28) + y / HD_LOOP_HZ;
    s->inc_r = (uint32_t)(y % HD_LOOP_HZ);
    s->inc_acc = 0;
    s->phase = 0;
    s->center = center;
    s->amp = amp;
    s->w_q16 = hd_mul_q(f_q16, TWO_PI_Q28, 28u);
    s->appr_leg = 0;
    s->mode = HD_TRAJ_SINE;
    return 0;
}

int32_t hd_traj_done(const hd_traj_t *s)
{
    if (s->mode == HD_TRAJ_HOLD) {
        return 1;
    }
    if (s->mode == HD_TRAJ_PTP) {
        return (s->appr_leg != 1 && s->appr_wait == 0u && s->k >= ptp_total(s)) ? 1 : 0;
    }
    return 0;
}

static void step_ptp(hd_traj_t *s, const hd_traj_cfg_t *c)
{
    if (s->appr_wait > 0u) {          /* at rest between the legs */
        s->appr_wait--;
        outputs(s, 0);
        return;
    }
    const uint32_t na = ptp_ramp(s), tv = s->tv;
    const uint32_t k = s->k;
    const uint32_t total = ptp_total(s);
    int64_t cruise_carry = 0;
    if (k >= total) {
        s->v48 = 0;
        s->a48 = 0;
        s->mode = HD_TRAJ_HOLD;
        outputs(s, 0);
        return;
    }
    if (k < na) {
        s->a48 = ramp_level(s, k);
    } else if (k < na + tv) {
        s->a48 = 0;
        s->vfrac_acc += s->vfrac;    /* cruise fraction, den HD_LOOP_HZ */
        if (s->vfrac_acc >= (uint32_t)HD_LOOP_HZ) {
            s->vfrac_acc -= (uint32_t)HD_LOOP_HZ;
            cruise_carry = 1;
        }
    } else {
        s->a48 = -ramp_level(s, k - na - tv);
    }
    s->v48 += s->a48;
    /* residual share: floor(R (k+1) / K) - floor(R k / K) */
    s->cruise_acc += s->cruise_r;
    int64_t extra;
    if (s->cruise_acc >= 0 && s->cruise_acc <= (int64_t)UINT32_MAX) {
        /* 0 <= cruise_acc < 2^32 (the usual case): 32-bit division, same quotient */
        extra = (int64_t)((uint32_t)s->cruise_acc / total);
    } else {
        extra = s->cruise_acc / (int64_t)total;
    }
    s->cruise_acc -= extra * (int64_t)total;
    const int64_t step = s->v48 + extra + cruise_carry;
    s->p48 = hdf_add64_sat(s->p48, (s->dir < 0) ? -step : step);
    s->k = k + 1u;
    {
        const int64_t a_keep = s->a48;
        if (s->dir < 0) {
            s->a48 = -a_keep;
        }
        outputs(s, (s->dir < 0) ? -step : step);
        s->a48 = a_keep;
    }
    if (s->k >= total) {
        s->v48 = 0;
        s->a48 = 0;
        if (s->appr_leg == 1) {
            /* first leg done (exactly at goal - dir * dist): plan the final leg */
            s->appr_leg = 2;
            plan(s, c, appr_vlim(c), s->goal48);
            s->appr_wait = c->appr_dwell;
        } else {
            s->mode = HD_TRAJ_HOLD;
        }
    }
}

static void step_rate(hd_traj_t *s)
{
    int32_t acc = 0;
    if (s->rate_cur < s->rate_target) {
        int32_t nv = hd_add_sat(s->rate_cur, s->rate_dv);
        s->rate_cur = (nv > s->rate_target) ? s->rate_target : nv;
        acc = 1;
    } else if (s->rate_cur > s->rate_target) {
        int32_t nv = hd_sub_sat(s->rate_cur, s->rate_dv);
        s->rate_cur = (nv < s->rate_target) ? s->rate_target : nv;
        acc = -1;
    }
    int64_t rem;
    const int64_t num = (int64_t)s->rate_cur * 65536 + (int64_t)s->rate_rem;
    const int64_t step = floordiv(num, HD_LOOP_HZ, &rem);
    s->rate_rem = (int32_t)rem;
    s->p48 = hdf_add64_sat(s->p48, step);
    s->v48 = step;
    s->a48 = 0;
    s->pos = hdf_asr64_rnd(s->p48, 16u);
    s->vel = s->rate_cur;
    /* acceleration feed-forward: the ramp slope, 2^-24 turn/s^2 */
    s->acc = (acc == 0) ? 0 : hdf_sat32(hd_div64_rnd((int64_t)acc * s->rate_dv * HD_LOOP_HZ, 256));
    if (s->rate_cur == 0 && s->rate_target == 0) {
        s->mode = HD_TRAJ_HOLD;
        s->v48 = 0;
        s->acc = 0;
    }
}

static void step_sine(hd_traj_t *s)
{
    s->inc_acc += s->inc_r;
    uint64_t carry = 0;
    if (s->inc_acc >= (uint32_t)HD_LOOP_HZ) {
        s->inc_acc -= (uint32_t)HD_LOOP_HZ;
        carry = 1;
    }
    s->phase += s->inc_q + carry;   /* uint64: wraps once per cycle, meant */
    int32_t sn, cs;
    hd_sincos_turn((uint32_t)(s->phase >> 32), &sn, &cs);
    s->pos = hdf_add64_sat(s->center, (int64_t)hdf_mul_q(s->amp, sn, 30u));
    s->p48 = hdf_shl64_sat(s->pos, 16u);
    const int64_t aw = hdf_mul64x32_q((int64_t)s->amp, s->w_q16, 16u);        /* 2^-32 turn/s */
    s->vel = hdf_mul_q(hdf_sat32(aw), cs, 30u);
    const int64_t aww = hdf_mul64x32_q(aw, s->w_q16, 24u);                      /* 2^-24 turn/s^2 */
    s->acc = hd_neg_sat(hdf_mul_q(hdf_sat32(aww), sn, 30u));
    s->v48 = 0;
    s->a48 = 0;
}

void hd_traj_step(hd_traj_t *s, const hd_traj_cfg_t *c)
{
    if (s->mode == HD_TRAJ_PTP) {       /* the usual profile: tested first */
        step_ptp(s, c);
        return;
    }
    switch (s->mode) {
    case HD_TRAJ_RATE:
        step_rate(s);
        break;
    case HD_TRAJ_SINE:
        step_sine(s);
        break;
    default:
        s->v48 = 0;
        s->a48 = 0;
        outputs(s, 0);
        break;
    }
}
