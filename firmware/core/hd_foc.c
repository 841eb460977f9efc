/*
 * hd_foc.c - field-oriented current loop (see hd_foc.h).
 *
 * hd_foc_step computes in 32-bit words (Cortex-M4: SMMULR, SMMLAR, SMLAL, SSAT
 * behind the hdf_ helpers of hd_fixed.h).  Range analysis of one step, Q-formats
 * (Qm.n: value x 2^-n), every bound including its rounding:
 *
 *   ia, ib        Q15.16 A, saturated to [-2^27, 2^27) (SSAT 28: +-2,048 A, far
 *                 beyond any current the ADC scaling produces)
 *   sin, cos      Q31, |.| <= 2^31 - 1 (table entries <= 2^31 - 1; the linear
 *                 interpolation lies between two entries)
 *   al2 = 2 ia    Q15.17 A (the alpha current doubled), |.| <= 2^28
 *   be2           Q15.17 A, 2 (ia + 2 ib) / sqrt(3) = SMMULR(4 (ia + 2 ib), 2^31 / sqrt(3)):
 *                 |4 (ia + 2 ib)| <= 3 2^29 < 2^31, |be2| <= sqrt(3) 2^28 + 1 < 2^29
 *   id, iq        Q15.16 A = (al2 cos + be2 sin) / 2^32, one rounding (two SMLAL on
 *                 the offset 2^31): each product < 2^60, the sum < 2^61 (no wrap);
 *                 |id|, |iq| <= |(ia, i_beta)| <= 2^28 + 1
 *   e             Q15.16 A, the saturated difference (QSUB) of the reference and id / iq
 *   integrator    2^-24 V (Q8.24), |.| <= min(vmax, 128 V) 2^8 < 2^31 - 2^8 (the clamp)
 *   ki_ts e + integ 2^8 + 2^7, kp e + integ 2^8 + 2^15
 *                 int64 (SMULL + SMLAL), |.| <= 2^62 + 2^40 (no wrap), shifted to Q8.24 V and
 *                 Q15.16 V and saturated
 *   vbus          Q15.16 V, saturated to < 2^29 (8,192 V; SSAT 30), > 0 here
 *   vmax          Q15.16 V = round(vbus vmax_k / 2^30) = SMMULR(4 vbus, vmax_k): 4 vbus < 2^31;
 *                 vmax_k <= 2^30 / sqrt(3), so vmax <= vbus / sqrt(3) < 2^28.2
 *   vd, vq        Q15.16 V, |.| <= vmax (the PI limits and the circle)
 *   vd^2 + vq^2   int64, < 2^57.4 (the circle test)
 *   vb1           vbus for the modulation, at least 1 V (below it the duties are those of
 *                 1 V: no operating point), in [2^16, 2^29); n = clz(vb1) = 3 .. 15
 *   inv_n         2^61 / (vb1 2^n) = 2^(30+z) / vbus with z = 31 - n, <= 2^30, from below
 *                 within 2^-28 relative (foc_recip61: one UDIV and a Newton step, the same
 *                 cost for every bus voltage)
 *   md, mq        Q4.27 modulation ratio v / vbus = SMMULR(v 2^(n-2), inv_n) = v 2^27 / vbus:
 *                 |v| <= vmax <= vbus / sqrt(3) + 1 < 2^(z+1) / sqrt(3) + 1, so
 *                 |v 2^(n-2)| < 2^30 / sqrt(3) + 2^13 < 2^29.3 and |md|, |mq| < 2^26.3
 *   ma, mb        Q5.26 ratios after the inverse Park = (md cos - mq sin) / 2^32: products
 *                 < 2^57.3, |ma|, |mb| < 2^26.3
 *   sb            Q5.26, sqrt(3) mb = SMMULR(4 mb, 2^31 sqrt(3) / 2): |4 mb| < 2^28.3, |sb| < 2^27.1
 *   2 p - (max + min) and the duty: as in foc_svm_inv below, two bits lower (|.| < 2^28;
 *                 the duty (2^27 + 2 p - (max + min) + 2^11) / 2^12)
 * The rounding of the 32-bit forms (half an LSB of Q15.17 current, of a Q31 sine,
 * of a Q27 ratio) is far below the 12-bit current ADC's LSB and the Q16 duty's.
 */
#include "hd_foc.h"
#include "hd_fixed.h"
#include "hd_foc_tables.h"

#define HD_INV_SQRT3_Q31  1239850262    /* 2^31 / sqrt(3), rounded */
#define HD_SQRT3_2_Q31    1859775393    /* 2^31 sqrt(3) / 2, rounded */

#define HD_INV_SQRT3_Q30  619925131     /* 1/sqrt(3) in Q30 */
#define HD_SQRT3_Q30      1859775393    /* sqrt(3) in Q30 */
#define HD_TWO_PI_Q16     411775        /* 2 pi in Q16 */

/* The 64-bit reference transforms of the public functions (Q30 sin / cos, one
 * rounding half up each); hd_foc_step has its own 32-bit forms (below). */

/* round(x / 2^q) (half up), saturated to int32, for |x| < 2^62 and 1 <= q <= 30:
 * floor((x + 2^(q-1)) / 2^q), the sum cannot overflow in that range. */
static inline int32_t foc_rnd_sat(int64_t x, uint32_t q)
{
    return hdf_sat32(hdf_asr64_floor(x + ((int64_t)1 << (q - 1u)), q));
}

static inline int32_t foc_clarke_beta(int32_t ia, int32_t ib)
{
    /* |ia + 2 ib| <= 3 2^31 < 2^32.6, times 1/sqrt(3) (< 2^29.3): < 2^62 */
    return foc_rnd_sat(((int64_t)ia + 2 * (int64_t)ib) * HD_INV_SQRT3_Q30, 30u);
}

static inline void foc_rot(int32_t a, int32_t b, int32_t sn, int32_t cs, int32_t *x, int32_t *y)
{
    /* (x, y) = (a cos - b sin, a sin + b cos): |sin|, |cos| <= 2^30 (hd_sincos_turn*),
     * so each product <= 2^61 and the sums < 2^62 */
    *x = foc_rnd_sat((int64_t)a * cs - (int64_t)b * sn, 30u);
    *y = foc_rnd_sat((int64_t)a * sn + (int64_t)b * cs, 30u);
}

void hd_foc_clarke(int32_t ia, int32_t ib, int32_t *i_alpha, int32_t *i_beta)
{
    *i_alpha = ia;
    *i_beta = foc_clarke_beta(ia, ib);
}

void hd_foc_park(int32_t a, int32_t b, int32_t sin_q30, int32_t cos_q30, int32_t *d, int32_t *q)
{
    /* d = a cos + b sin, q = b cos - a sin: the rotation by -theta */
    foc_rot(a, b, hdf_neg_sat(sin_q30), cos_q30, d, q);
}

void hd_foc_ipark(int32_t d, int32_t q, int32_t sin_q30, int32_t cos_q30, int32_t *a, int32_t *b)
{
    foc_rot(d, q, sin_q30, cos_q30, a, b);
}

/* round(p / 2^18) for p in Q46, saturated to +-2^28 (+-1.0 in Q28); the bias
 * makes the shift act on a non-negative number (round half up). */
static inline int32_t foc_ratio_q28(int64_t p)
{
    const int64_t lim = (int64_t)1 << 46;
    const int64_t c = (p > lim) ? lim : ((p < -lim) ? -lim : p);
    return (int32_t)((uint32_t)((uint64_t)(c + lim + ((int64_t)1 << 17)) >> 18) - ((uint32_t)1 << 28));
}

/* floor(x / 2^s) of an int32 (arithmetic shift, written without >> on a signed value) */
static inline int32_t foc_floor32(int32_t x, uint32_t s)
{
    const uint32_t m = (x < 0) ? 0xFFFFFFFFu : 0u;
    const uint32_t u = (((uint32_t)x ^ m) >> s) ^ m;
    return (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u;
}

/* twice the phase ratios p0, p1, p2 (Q28, summing to 0) -> three Q16 duties: phase ratio +
 * v0 in Q30 = 2 p - (max + min); duty Q16 = (2^29 + that) / 2^14, rounded, within [0, 1] */
static inline void foc_duties(int32_t p0, int32_t p1, int32_t p2, uint32_t sh, int32_t duty[3])
{
    const int32_t mx = (p1 > p0) ? ((p2 > p1) ? p2 : p1) : ((p2 > p0) ? p2 : p0);
    const int32_t mn = (p1 < p0) ? ((p2 < p1) ? p2 : p1) : ((p2 < p0) ? p2 : p0);
    const int32_t o = ((int32_t)1 << (sh + 15u)) + ((int32_t)1 << (sh - 1u)) - (mx + mn);
    const int32_t q0 = 2 * p0 + o;
    const int32_t q1 = 2 * p1 + o;
    const int32_t q2 = 2 * p2 + o;
    const int32_t d0 = (q0 <= 0) ? 0 : (int32_t)((uint32_t)q0 >> sh);
    const int32_t d1 = (q1 <= 0) ? 0 : (int32_t)((uint32_t)q1 >> sh);
    const int32_t d2 = (q2 <= 0) ? 0 : (int32_t)((uint32_t)q2 >> sh);
    duty[0] = (d0 > HD_FOC_DUTY_ONE) ? HD_FOC_DUTY_ONE : d0;
    duty[1] = (d1 > HD_FOC_DUTY_ONE) ? HD_FOC_DUTY_ONE : d1;
    duty[2] = (d2 > HD_FOC_DUTY_ONE) ? HD_FOC_DUTY_ONE : d2;
}

/*
 * SVM with 1/vbus given (Q30 per V), in 32-bit: the voltage components as
 * modulation ratios m = v / vbus in Q28, each saturated to +-1 (the duties
 * saturate long before: the linear range is |m| <= 1/sqrt(3)); twice the phase
 * ratios (Q28, so that m_alpha / 2 is exact) pa = 2 m_alpha, pb, pc = -m_alpha
 * +- sqrt(3) m_beta (|.| < 2^30; they sum to 0, so |max + min| < 2^30);
 * zero sequence v0 = -(max + min) / 2; duty = 1/2 + phase ratio + v0 in Q16,
 * rounded, within [0, 1].  2 p - (max + min) is a phase-to-phase difference,
 * |.| <= 2 sqrt(3) sqrt(2) 2^28 < 2^31 - 2^29: all in 32 bits.
 */
static void foc_svm_inv(int32_t v_alpha, int32_t v_beta, int32_t inv_q30, int32_t duty[3])
{
    const int32_t ma = foc_ratio_q28((int64_t)v_alpha * inv_q30);
    const int32_t mb = foc_ratio_q28((int64_t)v_beta * inv_q30);
    /* sqrt(3) m_beta in Q28, rounded (biased to a non-negative shift: |product| < 2^59) */
    const int32_t sb = (int32_t)((uint32_t)((uint64_t)((int64_t)mb * HD_SQRT3_Q30 + ((int64_t)1 << 59) +
                                                       ((int64_t)1 << 29)) >> 30) - ((uint32_t)1 << 29));
    foc_duties(2 * ma, sb - ma, -sb - ma, 14u, duty);
}

static inline int32_t foc_inv_vbus(int32_t vbus)
{
    /* 2^46 / d for 2^16 <= d < 2^23 by long division in 32-bit words: the first digit from
     * 2^28, then two 9-bit digits (a remainder r < d < 2^23 shifted by 9 stays below 2^32);
     * the quotient is <= 2^30.  Rounded half away from zero like hd_div_q (d > 0). */
    if (vbus >= HD_Q16_ONE && vbus < 0x800000) {                     /* 1 V .. 2^23 (128 V) */
        const uint32_t d = (uint32_t)vbus;
        const uint32_t n28 = 0x10000000u;                               /* 2^28 */
        uint32_t q = n28 / d;
        uint32_t r = n28 - q * d;
        uint32_t t = r << 9;
        uint32_t qd = t / d;
        r = t - qd * d;
        q = (q << 9) + qd;
        t = r << 9;
        qd = t / d;
        r = t - qd * d;
        q = (q << 9) + qd;
        if (r >= d - r) {
            q += 1u;
        }
        return (int32_t)q;
    }
    return hd_div_q(HD_Q16_ONE, vbus, 30u);
}

int32_t hd_foc_inv_vbus(int32_t vbus)
{
    return foc_inv_vbus(vbus);
}

void hd_foc_svm(int32_t v_alpha, int32_t v_beta, int32_t vbus, int32_t duty[3])
{
    if (vbus <= 0) {
        duty[0] = HD_FOC_DUTY_ONE / 2;
        duty[1] = HD_FOC_DUTY_ONE / 2;
        duty[2] = HD_FOC_DUTY_ONE / 2;
        return;
    }
    foc_svm_inv(v_alpha, v_beta, hd_foc_inv_vbus(vbus), duty);
}

void hd_foc_reset(hd_foc_t *s)
{
    s->integ_d = 0;
    s->integ_q = 0;
    s->id = 0;
    s->iq = 0;
    s->vd = 0;
    s->vq = 0;
    s->limited = 0u;
}

/* The integrators are int32 in 2^-24 V (Q8.24: 8 more fractional bits than the
 * output, +-128 V): the axis limit is at most HD_FOC_I_LIM (128 V - 2^-16 V) there,
 * so |integrator| < 2^31 - 2^8 and the rounding offset 2^7 cannot overflow. */
#define HD_FOC_I_SHIFT 8u
#define HD_FOC_I_LIM   (((int32_t)1 << 23) - 1)    /* Q15.16 V */


/* an axis limit lim (Q15.16 V, >= 0) as the integrator's bound in 2^-24 V */
static inline int32_t foc_ilim(int32_t lim)
{
    return (int32_t)((uint32_t)((lim < HD_FOC_I_LIM) ? lim : HD_FOC_I_LIM) << HD_FOC_I_SHIFT);
}

/* sin and cos of an electrical angle (2^32 == one turn) in Q31 from the 512-entry table by
 * linear interpolation: value + slope x fraction in one SMMLAR each (the fraction, the
 * angle's low 23 bits, as a Q31 word: below 2^31).  Error <= (2 pi / 512)^2 / 8 = 1.9e-5
 * of the amplitude + 1.5 LSB (tests/c/test_foc_fast.c): 0.08 LSB of a 12-bit current ADC's
 * full scale. */
static inline void foc_sincos(uint32_t theta, int32_t *sn, int32_t *cs)
{
    const int32_t f = (int32_t)((theta << 9) >> 1);
    const int32_t *ps = &hd_foc_sin_tab[2u * (theta >> 23)];
    const int32_t *pc = &hd_foc_sin_tab[2u * ((theta + 0x40000000u) >> 23)];
    *sn = hdf_smmlar(ps[0], ps[1], f);
    *cs = hdf_smmlar(pc[0], pc[1], f);
}

void hd_foc_sincos(uint32_t theta_e, int32_t *sin_q31, int32_t *cos_q31)
{
    foc_sincos(theta_e, sin_q31, cos_q31);
}

/* floor(2^61 / vn) or a little less (relative error < 2^-28) for a normalised bus voltage
 * vn in [2^31, 2^32): a 16-bit estimate from below by one 32-bit division,
 * x0 = floor((2^32 - 1) / (floor(vn / 2^16) + 1)) 2^13 < 2^61 / vn (relative error
 * < 2^-14), then one Newton step x0 + x0 (2^61 - vn x0) / 2^61 (from below it stays below,
 * error squared): vn x0 < 2^61, (2^61 - vn x0) / 2^16 < 2^31, x0 times that < 2^61: two
 * UMULL, no wrap.  The result is <= 2^30. */
static inline int32_t foc_recip61(uint32_t vn)
{
    const uint32_t x0 = (0xFFFFFFFFu / ((vn >> 16) + 1u)) << 13;
    const uint64_t t = (uint64_t)vn * x0;
    const uint32_t e16 = (uint32_t)((((uint64_t)1 << 61) - t) >> 16);
    return (int32_t)(x0 + (uint32_t)(((uint64_t)x0 * e16) >> 45));
}

/* PI of one axis: the integrator (2^-24 V) advances by ki_ts e rounded half up, as one
 * 64-bit sum integ 2^8 + ki_ts e + 2^7 (|.| < 2^62 + 2^40: SMLAL, no wrap) shifted by 8 and
 * saturated, then clamped to +-ilim (anti-windup: the integrator never holds more than the
 * usable voltage, so it keeps tracking what the saturated axis needs, e.g. the back-EMF,
 * and recovery takes a few periods); the output is P and I rounded once, (kp e + in 2^8 +
 * 2^15) / 2^16 (Q32 V -> Q15.16 V, the same bound), saturated, then clamped to +-lim;
 * *lim_hit = 1 if clamped. */
static inline int32_t foc_pi(int32_t *integ, int32_t kp, int32_t ki_ts, int32_t e, int32_t lim, int32_t ilim,
                             uint32_t *lim_hit)
{
    const int64_t ai = (int64_t)*integ * 256 + (int64_t)ki_ts * e + 128;
    const int32_t in = hdf_clamp32(hdf_sat32(hdf_asr64_floor(ai, 8u)), -ilim, ilim);
    const int64_t av = hdf_dot2_64(kp, e, in + 128, 256);           /* + 2^15 as (in + 2^7) 2^8 */
    const int32_t v = hdf_sat32(hdf_asr64_floor(av, 16u));
    *integ = in;
    if (v > lim || v < -lim) {
        *lim_hit = 1u;
        return (v > lim) ? lim : -lim;
    }
    return v;
}

void hd_foc_step(hd_foc_t *s, const hd_foc_cfg_t *c, const hd_foc_in_t *in, hd_foc_out_t *out)
{
    int32_t sn, cs;
    uint32_t hit = 0u;
    foc_sincos(in->theta_e, &sn, &cs);
    const int32_t ia = hdf_ssat(in->ia, 28u);
    const int32_t ib = hdf_ssat(in->ib, 28u);
    const int32_t al2 = 2 * ia;                                            /* Clarke, doubled */
    const int32_t be2 = hdf_smmulr(4 * (ia + 2 * ib), HD_INV_SQRT3_Q31);
    const int32_t id = hdf_dot2_rnd32(al2, cs, be2, sn);                   /* Park */
    const int32_t iq = hdf_dot2_rnd32(be2, cs, -al2, sn);
    s->id = id;
    s->iq = iq;
    if (in->vbus <= 0) {
        s->vd = 0;
        s->vq = 0;
        s->limited = 1u;
        out->duty[0] = HD_FOC_DUTY_ONE / 2;
        out->duty[1] = HD_FOC_DUTY_ONE / 2;
        out->duty[2] = HD_FOC_DUTY_ONE / 2;
        return;
    }
    const int32_t vbus = hdf_ssat(in->vbus, 30u);
    /* usable phase-voltage amplitude of linear SVM */
    const int32_t vmax = hdf_smmulr(4 * vbus, hdf_clamp32(c->vmax_k, 0, HD_INV_SQRT3_Q30));
    const int32_t ilim = foc_ilim(vmax);
    const int32_t vd = foc_pi(&s->integ_d, c->kp, c->ki_ts, hdf_sub_sat(in->id_ref, id), vmax, ilim, &hit);
    int32_t vq = foc_pi(&s->integ_q, c->kp, c->ki_ts, hdf_sub_sat(in->iq_ref, iq), vmax, ilim, &hit);
    /* q axis: output and integrator clamped to the rest of the circle,
     * sqrt(vmax^2 - vd^2) - computed only when the vector would leave the circle */
    const int64_t r2 = (int64_t)vmax * vmax - (int64_t)vd * vd;               /* >= 0 */
    const uint32_t l1 = (uint32_t)((vd < 0) ? -vd : vd) + (uint32_t)((vq < 0) ? -vq : vq);
    /* |vd| + |vq| <= vmax is inside the circle: the squares only near its edge */
    if (l1 > (uint32_t)vmax && (int64_t)vq * vq > r2) {
        const int32_t vq_lim = (int32_t)hd_isqrt64((uint64_t)r2);
        vq = hdf_clamp32(vq, -vq_lim, vq_lim);
        s->integ_q = hdf_clamp32(s->integ_q, -foc_ilim(vq_lim), foc_ilim(vq_lim));
        hit = 1u;
    }
    s->vd = vd;
    s->vq = vq;
    s->limited = hit;
    {
        /* modulation ratios (Q27), inverse Park to Q26, then the SVM of foc_svm_inv */
        const uint32_t vb1 = (uint32_t)((vbus < HD_Q16_ONE) ? HD_Q16_ONE : vbus);   /* [2^16, 2^29) */
        const uint32_t n = (uint32_t)__builtin_clz(vb1);                           /* 3 .. 15 */
        const int32_t inv_n = foc_recip61(vb1 << n);
        const int32_t md = hdf_smmulr(hdf__s32((uint32_t)vd << (n - 2u)), inv_n);
        const int32_t mq = hdf_smmulr(hdf__s32((uint32_t)vq << (n - 2u)), inv_n);
        const int32_t ma = hdf_dot2_rnd32(md, cs, -mq, sn);
        const int32_t mb = hdf_dot2_rnd32(md, sn, mq, cs);
        const int32_t sb = hdf_smmulr(4 * mb, HD_SQRT3_2_Q31);
        foc_duties(2 * ma, sb - ma, -sb - ma, 12u, out->duty);
    }
}

int32_t hd_foc_design(hd_foc_cfg_t *c, int32_t r_mohm, int32_t l_nh, int32_t fc_hz, int32_t fs_hz)
{
    if (r_mohm <= 0 || l_nh <= 0 || fc_hz <= 0 || fs_hz <= 0 || fc_hz > 100000 || l_nh > 100000000 ||
        r_mohm > 100000000) {
        return -1;
    }
    const int64_t kp = hd_div64_rnd((int64_t)HD_TWO_PI_Q16 * fc_hz * l_nh, 1000000000);
    const int64_t ki = hd_div64_rnd((int64_t)HD_TWO_PI_Q16 * fc_hz * r_mohm, (int64_t)1000 * fs_hz);
    c->kp = hdf_sat32(kp);
    c->ki_ts = hdf_sat32(ki);
    /* 95 % of the linear range: m_max / sqrt(3) with m_max = 0.95, formed once here */
    c->vmax_k = foc_rnd_sat((int64_t)((HD_Q30_ONE / 100) * 95) * HD_INV_SQRT3_Q30, 30u);
    return 0;
}
