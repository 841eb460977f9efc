/*
 * hd_feedback.c - feedback configuration of the position loop (contract: hd_feedback.h).
 */
#include "hd_feedback.h"
#include "hd_fixed.h"

#define FB_TWO_PI_Q28 1686629713      /* round(2 pi 2^28) */

/* x / n and x % n for n < 2^16 in four 32-bit UDIVs of 16 bits each (no
 * __aeabi_uldivmod anywhere in the feedback, not even on a rare path) */
static uint64_t udiv64_small(uint64_t x, uint32_t n, uint32_t *rem)
{
    uint64_t q = 0;
    uint32_t r = 0;
    int32_t sh;
    for (sh = 48; sh >= 0; sh -= 16) {
        const uint32_t cur = (r << 16) | (uint32_t)((x >> (uint32_t)sh) & 0xFFFFu);   /* < n 2^16 <= 2^32 */
        const uint32_t d = cur / n;
        r = cur - d * n;
        q = (q << 16) | d;
    }
    *rem = r;
    return q;
}

/* floor(x / n) and the remainder in [0, n) for 1 <= n < 2^16 */
static int64_t floor_div_small(int64_t x, uint32_t n, uint32_t *rem)
{
    if (x >= 0) {
        return (int64_t)udiv64_small((uint64_t)x, n, rem);
    }
    uint32_t r;
    const uint64_t q = udiv64_small((uint64_t)0 - (uint64_t)x, n, &r);
    /* -(q n + r) = -(q + 1) n + (n - r) for r > 0 */
    *rem = (r == 0u) ? 0u : n - r;
    return (r == 0u) ? -(int64_t)q : -(int64_t)q - 1;
}

int32_t hd_fb_design(hd_fb_cfg_t *c, int32_t kind, int32_t n, int32_t dual_fc_q16)
{
    if (kind < (int32_t)HD_FB_FULL_CLOSED || kind > (int32_t)HD_FB_DUAL_LOOP || n < 1 || n > 65535 ||
        dual_fc_q16 <= 0) {
        return -1;
    }
    /* 1 - exp(-2 pi fc T) in Q30 (at least 1 LSB so that the blend moves) */
    const int32_t x = hd_sat32(hd_div64_rnd(hd_mul64x32_q((int64_t)dual_fc_q16, FB_TWO_PI_Q28, 28u), HD_LOOP_HZ));
    const int32_t a = HD_Q30_ONE - hd_exp_neg_q16(x);
    c->kind = (uint32_t)kind;
    c->n = n;
    c->dual_alpha = (a < 1) ? 1 : a;
    return 0;
}

void hd_fb_reset(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_mot, hd_angle_t pos_out)
{
    /* floor division, remainder in [0, N): why the tracking is exact afterwards */
    uint32_t r;
    const int64_t q = floor_div_small(pos_mot, (uint32_t)c->n, &r);
    s->mot_prev = pos_mot;
    s->mo = q;
    s->mo_rem = (int32_t)r;
    s->offset = 0;
    s->est = q;
    s->corr = 0;
    s->pos_fb = pos_out;
    s->bias = 0;
    s->primed = 1u;
}

void hd_fb_motor(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_mot)
{
    const int64_t d = hdf_sub64_sat(pos_mot, s->mot_prev);
    const int64_t t = (int64_t)s->mo_rem + d;         /* pos_mot - N mo */
    const uint32_t un = (uint32_t)c->n;
    s->mot_prev = pos_mot;
    if (t > (int64_t)UINT32_MAX || t < -(int64_t)UINT32_MAX) {
        /* not a per-period step (never after the start): the long form */
        uint32_t r;
        s->mo = hdf_add64_sat(s->mo, floor_div_small(t, un, &r));
        s->mo_rem = (int32_t)r;
    } else if (t >= 0) {
        const uint32_t ut = (uint32_t)t;
        const uint32_t q = ut / un;
        s->mo = hdf_add64_sat(s->mo, (int64_t)q);
        s->mo_rem = (int32_t)(ut - q * un);
    } else {
        /* -(q N + r) = -(q + 1) N + (N - r) for r > 0 */
        const uint32_t ut = (uint32_t)(-t);
        const uint32_t q = ut / un;
        const uint32_t r = ut - q * un;
        if (r == 0u) {
            s->mo = hdf_sub64_sat(s->mo, (int64_t)q);
            s->mo_rem = 0;
        } else {
            s->mo = hdf_sub64_sat(s->mo, (int64_t)q + 1);
            s->mo_rem = (int32_t)(un - r);
        }
    }
}

hd_angle_t hd_fb_entry_position(const hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_out)
{
    if (c->kind != (uint32_t)HD_FB_SEMI_CLOSED) {
        return pos_out;
    }
    return hdf_sub64_sat(s->mo, hdf_sub64_sat(s->offset, hdf_asr64_rnd(s->bias, 16u)));
}

hd_angle_t hd_fb_enter(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_out)
{
    /* the offset the estimate holds now: the last prediction minus what of it still fades */
    s->offset = hdf_sub64_sat(s->offset, hdf_asr64_rnd(s->bias, 16u));
    s->est = hdf_sub64_sat(s->mo, s->offset);
    s->bias = 0;
    s->primed = 0u;
    if (c->kind == (uint32_t)HD_FB_SEMI_CLOSED) {
        s->pos_fb = s->est;
    } else {
        /* full closed, dual loop: the output encoder; the blend starts at it */
        s->corr = hdf_shl64_sat(hdf_sub64_sat(pos_out, s->est), 16u);
        s->pos_fb = pos_out;
    }
    return s->pos_fb;
}

hd_angle_t hd_fb_step(hd_fb_t *s, const hd_fb_cfg_t *c, hd_angle_t pos_out, hd_angle_t offset)
{
    if (s->primed == 0u) {
        /* first period after an entry: keep the estimate where the entry put it */
        s->bias = hdf_shl64_sat(hdf_sub64_sat(offset, s->offset), 16u);
        s->primed = 1u;
    }
    s->offset = offset;
    s->est = hdf_add64_sat(hdf_sub64_sat(s->mo, offset), hdf_asr64_rnd(s->bias, 16u));
    s->bias = hdf_sub64_sat(s->bias, hdf_asr64_rnd(s->bias, HD_FB_BIAS_SHIFT));
    if (c->kind == (uint32_t)HD_FB_SEMI_CLOSED) {
        s->pos_fb = s->est;
    } else if (c->kind == (uint32_t)HD_FB_DUAL_LOOP) {
        /* corr += alpha (pos_out - est - corr): the output encoder at low frequency */
        const int64_t inn = hdf_sub64_sat(hdf_shl64_sat(hdf_sub64_sat(pos_out, s->est), 16u), s->corr);
        s->corr = hdf_add64_sat(s->corr, hdf_mul64x32_q(inn, c->dual_alpha, 30u));
        s->pos_fb = hdf_add64_sat(s->est, hdf_asr64_rnd(s->corr, 16u));
    } else {
        s->pos_fb = pos_out;
    }
    return s->pos_fb;
}
