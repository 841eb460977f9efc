/*
 * hd_pid.h - one PID loop: anti-windup, filtered derivative on measurement,
 * feed-forward, output limits.  Struct + step(), no hidden state.
 *
 * Formats.  The loop is unit-agnostic: ref, meas and ff are int32 in the
 * INPUT format (e.g. 2^-32 turn for the position loop, 2^-32 turn/s for the
 * velocity loop) and the output is int32 in the OUTPUT format (2^-32 turn/s
 * or Q15.16 N.m).  Gains are fixed-point with `shift` fractional bits so that
 *     out = kp * e / 2^shift                 (kp   in out-LSB per in-LSB, Q(shift))
 *     I  += ki_dt * e / 2^shift              (ki_dt = Ki * T, T = 1/HD_LOOP_HZ)
 *     D   = -kd_fs * dmeas_f / 2^shift       (kd_fs = Kd / T)
 * Position loop:  in 2^-32 turn, out 2^-32 turn/s, shift 16 -> kp is Q15.16 1/s.
 * Velocity loop:  in 2^-32 turn/s, out Q15.16 N.m, shift 32 -> kp is
 *                 Q15.16 N.m/(turn/s)  (out = kp_raw * e / 2^32).
 *
 * State.  integ: int64, units out-LSB * 2^shift (i.e. `shift` more fractional
 * bits than the output).  dfilt: int64, the first-order-filtered measurement
 * increment per period in in-LSB * 2^16:  dfilt += alpha * (dmeas*2^16 - dfilt),
 * alpha = 1 - exp(-2 pi f_d T) in Q30.  With kd_fs = 0 (no D term) the filter is
 * not run and rests at 0: a D gain switched on later starts from the filter at rest.
 *
 * Anti-windup: conditional integration (the integrator does not move in the
 * direction that deepens saturation) plus clamping of the integral term to the
 * output limits.  Output = sat(P + I + D + ff, out_min, out_max), rounded to
 * nearest on every narrowing (hd_fixed helpers).
 */
#ifndef HD_PID_H
#define HD_PID_H

#include <stdint.h>
#include "hd_fixed.h"

typedef struct {
    int32_t  kp;        /* Q(shift), out-LSB per in-LSB */
    int32_t  ki_dt;     /* Q(shift), Ki*T */
    int32_t  kd_fs;     /* Q(shift), Kd/T */
    int32_t  d_alpha;   /* Q30, derivative filter coefficient, (0, 1] */
    uint32_t shift;     /* fractional bits of the gains, <= 40 */
    int32_t  out_min;   /* output limits, out format, out_min <= out_max */
    int32_t  out_max;
} hd_pid_cfg_t;

typedef struct {
    int64_t integ;      /* out-LSB * 2^shift */
    int64_t dfilt;      /* in-LSB * 2^16 per period */
    int32_t meas_prev;  /* previous measurement, in format */
    int32_t p, i, d;    /* last terms, out format (telemetry) */
    int32_t out;        /* last output, out format */
    uint32_t saturated; /* 1 if the last output was clamped */
    uint32_t primed;    /* 0 until the first step (no derivative kick) */
} hd_pid_t;

/** Reset the state (integrator 0, derivative history cleared). */
void hd_pid_reset(hd_pid_t *s);
/** Preload the integrator so that the I term equals `out_i` (bumpless transfer). */
void hd_pid_preload(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t out_i);
/** One period; returns the limited output. */
int32_t hd_pid_step(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff);

/* The step (hd_pid_step_q, hd_pid_step_pi_q); no_d (a constant) 1: the caller's kd_fs is 0,
 * so the derivative's history and filter are set as the general path sets them without
 * its tests. */
HD_FX_INLINE int32_t hd__pid_step(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff,
                                  const uint32_t shift, const uint32_t no_d)
{
    const int32_t e = hdf_sub_sat(ref, meas);

    if (no_d != 0u) {
        /* no D (the caller's kd_fs is 0): the history and the filter as the path below
         * leaves them with kd_fs 0 */
        s->meas_prev = meas;
        s->primed = 1;
        s->dfilt = 0;
    } else {
        /* derivative on measurement, first-order filtered, in in-LSB * 2^16 per period */
        int64_t dmeas = 0;
        if (s->primed) {
            dmeas = (int64_t)meas - (int64_t)s->meas_prev;
        }
        s->meas_prev = meas;
        s->primed = 1;
        if (c->kd_fs == 0) {
            /* no D term: the filter is not needed, so it rests at 0 (a D gain switched on
             * later starts from a filter at rest, like a reset; the measurement history
             * above stays current, so there is no derivative kick either) */
            s->dfilt = 0;
        } else if (dmeas != 0 || s->dfilt != 0) {     /* else the update leaves dfilt at 0 exactly */
            /* |dmeas| < 2^32, so dmeas * 2^16 < 2^48: the saturating shift is the product */
            const int64_t target = dmeas * 65536;
            const int64_t diff = hdf_sub64_sat(target, s->dfilt);
            /* |diff| < 2^49 so the 64x32 product fits the helper's 96-bit intermediate */
            /* d_alpha == 1.0 (no filter): the product is diff itself, exactly */
            const int64_t step = (c->d_alpha == HD_Q30_ONE) ? diff : hdf_mul64x32_q(diff, c->d_alpha, 30);
            s->dfilt = hdf_add64_sat(s->dfilt, step);
        }
    }

    /* shift 32: |kp e| <= 2^62, so the rounded term is at most 2^30 and needs no
     * saturation (the high word after the rounding offset) */
    const int32_t p = (shift == 32u) ? hdf_asr32_rnd_fit((int64_t)c->kp * (int64_t)e, 32u)
                                     : hdf_mul_q(c->kp, e, shift);
    /* kd_fs == 0 (no D term): the term is 0 */
    const int32_t d = (no_d != 0u || c->kd_fs == 0) ? 0
                      : hdf_neg_sat((int32_t)hdf_sat32(hdf_mul64x32_q(s->dfilt, c->kd_fs, shift + 16u)));

    /* the terms other than I, summed once for both tries (four int32s: exact in int64) */
    const int64_t pdf = (int64_t)p + (int64_t)d + (int64_t)ff;
    int64_t u;
    int32_t i_new;
    if (c->ki_dt == 0 && s->integ == 0 && c->out_min <= 0 && c->out_max >= 0) {
        /* no I gain and the integrator at 0 (the position loop's default): the tentative
         * update is 0, inside the limits and equal to the old value, so it is kept and
         * reads out 0; the same words as the general path below, without its 64-bit work */
        i_new = 0;
        u = pdf;
    } else {
        /* conditional integration: tentative update, kept unless it deepens saturation */
        /* an int32 times 2^shift, shift <= 32, stays within int64 (-2^63 at the least):
         * the saturating shift is the product (the drive's shifts 16 and 32 fold it) */
        const int64_t lim_hi = (shift <= 32u) ? (int64_t)c->out_max * ((int64_t)1 << shift)
                                              : hdf_shl64_sat((int64_t)c->out_max, shift);
        const int64_t lim_lo = (shift <= 32u) ? (int64_t)c->out_min * ((int64_t)1 << shift)
                                              : hdf_shl64_sat((int64_t)c->out_min, shift);
        int64_t integ_new = hdf_mac64(s->integ, c->ki_dt, e);
        integ_new = hdf_clamp64(integ_new, lim_lo, lim_hi);
        /* the integrator is clamped to [out_min, out_max] 2^shift (shift <= 32: exact
         * limits), so its rounded read-out lies in [out_min, out_max]: no saturation */
        i_new = (shift <= 32u) ? hdf_asr32_rnd_fit(integ_new, shift) : hdf_asr32_rnd(integ_new, shift);
        u = pdf + (int64_t)i_new;
        if ((u > (int64_t)c->out_max && integ_new > s->integ) ||
            (u < (int64_t)c->out_min && integ_new < s->integ)) {
            integ_new = s->integ;                       /* freeze */
            i_new = (shift <= 32u) ? hdf_asr32_rnd_fit(integ_new, shift) : hdf_asr32_rnd(integ_new, shift);
            u = pdf + (int64_t)i_new;
        }
        s->integ = integ_new;
    }

    /* the output limits are int32s: a sum outside the int32 range is clamped to the limit
     * of its sign, one inside is clamped in 32-bit words (the same value and flag as the
     * 64-bit clamp, without its 64-bit compares) */
    int32_t uc;
    const uint32_t ul = hdf__lo(u);
    const int32_t u32 = hdf__s32(ul);
    if (hdf__hi(u) != (uint32_t)(0u - (ul >> 31))) {
        uc = (u < 0) ? c->out_min : c->out_max;
        s->saturated = 1u;
    } else {
        uc = (u32 < c->out_min) ? c->out_min : ((u32 > c->out_max) ? c->out_max : u32);
        s->saturated = (uc != u32) ? 1u : 0u;
    }
    s->p = p;
    s->i = i_new;
    s->d = d;
    s->out = uc;
    return s->out;
}

/** hd_pid_step with the gain shift given as a constant (shift == c->shift): inlined
 *  into the caller with the shift folded (the drive's loops use 16 and 32). */
HD_FX_INLINE int32_t hd_pid_step_q(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t ref, int32_t meas, int32_t ff,
                                   const uint32_t shift)
{
    return hd__pid_step(s, c, ref, meas, ff, shift, 0u);
}

/** hd_pid_step_q for a loop without D (c->kd_fs == 0, the caller's guarantee) in error
 *  form (ref = e, meas = 0): the same words, without the derivative's tests (the
 *  drive's position loop). */
HD_FX_INLINE int32_t hd_pid_step_pi_q(hd_pid_t *s, const hd_pid_cfg_t *c, int32_t e, int32_t ff,
                                      const uint32_t shift)
{
    return hd__pid_step(s, c, e, 0, ff, shift, 1u);
}

#endif
