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

#endif
