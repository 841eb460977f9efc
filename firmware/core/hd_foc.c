/*
 * hd_foc.c - field-oriented current loop (see hd_foc.h).
 */
#include "hd_foc.h"
#include "hd_fixed.h"

#define HD_INV_SQRT3_Q30  619925131     /* 1/sqrt(3) in Q30 */
#define HD_SQRT3_2_Q30    929887697     /* sqrt(3)/2 in Q30 */
#define HD_TWO_PI_Q16     411775        /* 2 pi in Q16 */

void hd_foc_clarke(int32_t ia, int32_t ib, int32_t *i_alpha, int32_t *i_beta)
{
    const int64_t s = (int64_t)ia + 2 * (int64_t)ib;     /* |s| < 2^33 */
    *i_alpha = ia;
    *i_beta = hdf_sat32(hdf_mul64x32_q(s, HD_INV_SQRT3_Q30, 30u));
}

void hd_foc_park(int32_t a, int32_t b, int32_t sin_q30, int32_t cos_q30, int32_t *d, int32_t *q)
{
    /* each product < 2^61 in magnitude, the sums < 2^62: no overflow */
    const int64_t dd = (int64_t)a * cos_q30 + (int64_t)b * sin_q30;
    const int64_t qq = (int64_t)b * cos_q30 - (int64_t)a * sin_q30;
    *d = hdf_asr32_rnd(dd, 30u);
    *q = hdf_asr32_rnd(qq, 30u);
}

void hd_foc_ipark(int32_t d, int32_t q, int32_t sin_q30, int32_t cos_q30, int32_t *a, int32_t *b)
{
    const int64_t aa = (int64_t)d * cos_q30 - (int64_t)q * sin_q30;
    const int64_t bb = (int64_t)d * sin_q30 + (int64_t)q * cos_q30;
    *a = hdf_asr32_rnd(aa, 30u);
    *b = hdf_asr32_rnd(bb, 30u);
}

static int32_t duty_of(int64_t v_q46, int32_t inv_vbus_q30)
{
    /* v in Q46 V (Q16 V x Q30) -> Q16 V, then times 1/vbus (Q30 1/V) -> Q16 ratio */
    const int32_t v = hdf_asr32_rnd(v_q46, 30u);
    const int32_t r = hdf_mul_q(v, inv_vbus_q30, 30u);
    return hdf_clamp32(hdf_add_sat(HD_FOC_DUTY_ONE / 2, r), 0, HD_FOC_DUTY_ONE);
}

void hd_foc_svm(int32_t v_alpha, int32_t v_beta, int32_t vbus, int32_t duty[3])
{
    if (vbus <= 0) {
        duty[0] = HD_FOC_DUTY_ONE / 2;
        duty[1] = HD_FOC_DUTY_ONE / 2;
        duty[2] = HD_FOC_DUTY_ONE / 2;
        return;
    }
    /* phase voltages in Q46 V: |terms| < 2^61, sums < 2^62 */
    const int64_t va = (int64_t)v_alpha * HD_Q30_ONE;
    const int64_t half_a = (int64_t)v_alpha * (HD_Q30_ONE / 2);
    const int64_t sb = (int64_t)v_beta * HD_SQRT3_2_Q30;
    const int64_t vb = sb - half_a;
    const int64_t vc = -sb - half_a;
    int64_t mx = va, mn = va;
    if (vb > mx) { mx = vb; }
    if (vc > mx) { mx = vc; }
    if (vb < mn) { mn = vb; }
    if (vc < mn) { mn = vc; }
    /* zero sequence v0 = -(max + min) / 2, rounded (|max + min| < 2^63) */
    const int64_t v0 = -hdf_asr64_rnd(mx + mn, 1u);
    const int32_t inv = hd_div_q(HD_Q16_ONE, vbus, 30u);    /* 1/vbus, Q30 per V */
    duty[0] = duty_of(va + v0, inv);
    duty[1] = duty_of(vb + v0, inv);
    duty[2] = duty_of(vc + v0, inv);
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

/* PI with the integrator clamped to +-lim (anti-windup: the integrator never
 * holds more than the usable voltage, so it keeps tracking what the
 * saturated axis needs, e.g. the back-EMF, and recovery takes a few periods);
 * returns the output limited to +-lim (lim >= 0); *lim_hit = 1 if clamped. */
static int32_t pi_axis(int64_t *integ, const hd_foc_cfg_t *c, int32_t e, int32_t lim, uint32_t *lim_hit)
{
    const int64_t ilim = (int64_t)lim * HD_Q16_ONE;          /* Q32 V */
    const int32_t p = hdf_mul_q(c->kp, e, 16u);
    const int64_t in = hdf_clamp64(hdf_mac64(*integ, c->ki_ts, e), -ilim, ilim);
    *integ = in;
    const int32_t v = hdf_add_sat(p, hdf_asr32_rnd(in, 16u));
    if (v > lim || v < -lim) {
        *lim_hit = 1u;
    }
    return hdf_clamp32(v, -lim, lim);
}

void hd_foc_step(hd_foc_t *s, const hd_foc_cfg_t *c, const hd_foc_in_t *in, hd_foc_out_t *out)
{
    int32_t sn, cs, ial, ibe, id, iq, val, vbe;
    uint32_t hit = 0u;
    hd_sincos_turn(in->theta_e, &sn, &cs);
    hd_foc_clarke(in->ia, in->ib, &ial, &ibe);
    hd_foc_park(ial, ibe, sn, cs, &id, &iq);
    s->id = id;
    s->iq = iq;
    if (in->vbus <= 0) {
        s->vd = 0;
        s->vq = 0;
        s->limited = 1u;
        hd_foc_svm(0, 0, 0, out->duty);
        return;
    }
    /* usable phase-voltage amplitude of linear SVM */
    const int32_t vmax = hdf_mul_q(hdf_mul_q(in->vbus, c->m_max, 30u), HD_INV_SQRT3_Q30, 30u);
    const int32_t vd = pi_axis(&s->integ_d, c, hdf_sub_sat(in->id_ref, id), vmax, &hit);
    /* q axis: output and integrator clamped to the rest of the circle,
     * sqrt(vmax^2 - vd^2) - computed only when the vector would leave the circle */
    uint32_t hit_q = 0u;
    int32_t vq = pi_axis(&s->integ_q, c, hdf_sub_sat(in->iq_ref, iq), vmax, &hit_q);
    const int64_t r2 = (int64_t)vmax * vmax;                                  /* < 2^62 */
    const int64_t vd2 = (int64_t)vd * vd;                                     /* <= r2 */
    if ((int64_t)vq * vq > r2 - vd2) {
        const int32_t vq_lim = (int32_t)hd_isqrt64((uint64_t)(r2 - vd2));
        vq = hdf_clamp32(vq, -vq_lim, vq_lim);
        s->integ_q = hdf_clamp64(s->integ_q, -(int64_t)vq_lim * HD_Q16_ONE, (int64_t)vq_lim * HD_Q16_ONE);
        hit = 1u;
    }
    hit |= hit_q;
    s->vd = vd;
    s->vq = vq;
    s->limited = hit;
    hd_foc_ipark(vd, vq, sn, cs, &val, &vbe);
    hd_foc_svm(val, vbe, in->vbus, out->duty);
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
    c->m_max = (int32_t)((HD_Q30_ONE / 100) * 95);    /* 95 % of the linear range */
    return 0;
}

int32_t hd_foc_adc_current(int32_t raw, int32_t offset, int32_t gain_q30)
{
    return hdf_mul_q(hdf_sub_sat(raw, offset), gain_q30, 14u);
}

uint32_t hd_foc_elec_angle(uint32_t count, uint32_t bits, uint32_t pole_pairs, uint32_t offset)
{
    const uint32_t b = (bits < 1u) ? 1u : ((bits > 32u) ? 32u : bits);
    const uint32_t mech = (b == 32u) ? count : (count << (32u - b));
    return mech * pole_pairs + offset;     /* modulo 2^32: the angle wraps, meant */
}
