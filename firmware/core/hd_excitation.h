/*
 * hd_excitation.h - deterministic excitation signals for identification.
 *
 * The generator produces one int32 per control period in the format of the
 * injection point chosen by the application (Q15.16 N.m for torque,
 * 2^-32 turn/s for the velocity reference, 2^-32 turn for the position
 * reference); `amp` and `offset` are in that same format.  Same cfg -> same
 * sequence on every target (integer only, no hidden state).
 *
 * Kinds:
 *   VSTEPS     constant-velocity (or any constant-level) steps in both
 *              directions: levels amp * 10^(i/m), i = 0 .. n*m (n decades,
 *              m = 1, 2, 5 or 10 steps per decade), each held `hold` periods
 *              at +level then `hold` periods at -level.  n >= 4 covers the
 *              four decades asked for friction maps (e.g. 0.001 .. 10 deg/s).
 *   TRAMP      triangle: 0 -> +amp -> -amp -> ... at `rate` per period, n cycles.
 *   FORC       first-order reversal curves (hysteresis / Preisach): go to
 *              -amp; for i = 1..n ramp up to -amp + 2 amp i / n, then back to
 *              -amp, all at `rate` per period.
 *   CHIRP      amp * sin(phase), linear sweep f0 -> f1 (Q16.16 Hz) over `length` periods.
 *   MULTISINE  sum over harmonics k = 1..n of amp * sin(2 pi k t / (period T)
 *              + Schroeder phase -pi k (k-1) / n); amp is per component; the
 *              signal repeats exactly every `period` periods.
 *   PRBS       +-amp from a maximal-length Galois LFSR of order n (7, 9, 10,
 *              11, 15 or 16; period 2^n - 1 bits), each bit held `hold` periods.
 * All kinds add `offset`.  `length` (periods, 0 = natural length / endless
 * for CHIRP-free kinds) ends the signal; afterwards the output is `offset`
 * and done = 1.  Levels saturate to int32.
 */
#ifndef HD_EXCITATION_H
#define HD_EXCITATION_H

#include <stdint.h>

typedef enum {
    HD_EXC_NONE = 0,
    HD_EXC_VSTEPS = 1,
    HD_EXC_TRAMP = 2,
    HD_EXC_FORC = 3,
    HD_EXC_CHIRP = 4,
    HD_EXC_MULTISINE = 5,
    HD_EXC_PRBS = 6
} hd_exc_kind_t;

typedef struct {
    int32_t  kind;     /* hd_exc_kind_t */
    int32_t  amp;      /* signal format, >= 0 */
    int32_t  offset;   /* signal format */
    uint32_t length;   /* periods; 0 = natural length (endless for PRBS/MULTISINE/TRAMP n=0) */
    uint32_t hold;     /* periods per level (VSTEPS) or per bit (PRBS) */
    uint32_t n;        /* decades / cycles / reversals / harmonics / LFSR order */
    uint32_t m;        /* VSTEPS steps per decade (1, 2, 5, 10) */
    int32_t  rate;     /* TRAMP/FORC slope, signal LSB per period, > 0 */
    int32_t  f0_q16;   /* CHIRP start, Q16.16 Hz */
    int32_t  f1_q16;   /* CHIRP end, Q16.16 Hz */
    uint32_t period;   /* MULTISINE period, periods (>= 2) */
    uint32_t seed;     /* PRBS initial state (0 -> 1) */
} hd_exc_cfg_t;

typedef struct {
    uint32_t k;        /* periods since start */
    uint32_t idx;      /* level / reversal / bit index */
    uint32_t sub;      /* periods into the current level / bit; FORC phase */
    int32_t  cur;      /* TRAMP/FORC current value (without offset) */
    int32_t  dir;      /* TRAMP/FORC direction */
    uint32_t lfsr;     /* PRBS state */
    uint64_t phase;    /* CHIRP phase, 2^64 = one cycle (wraps, meant) */
    int64_t  inc;      /* CHIRP phase increment per period */
    int64_t  dinc;     /* CHIRP increment change per period */
    uint32_t done;     /* 1 after the end */
    int32_t  out;      /* last output */
} hd_exc_t;

/** Validate cfg and reset the generator. 0 ok, -1 bad cfg (kind NONE is ok). */
int32_t hd_exc_start(hd_exc_t *s, const hd_exc_cfg_t *c);
/** One period: returns the excitation value (offset when done or NONE). */
int32_t hd_exc_step(hd_exc_t *s, const hd_exc_cfg_t *c);
/** Natural length in periods of a cfg (0 = endless). */
uint32_t hd_exc_length(const hd_exc_cfg_t *c);

#endif
