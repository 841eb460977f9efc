/*
 * hd_preisach.h - discrete Preisach hysteresis: Everett table (versioned, CRC32),
 * online recursive evaluation (stack of alternating dominant extrema with
 * wiping-out), brute-force relay-plane reference and exact inverse.
 *
 * Lattice.  The input u (int32, any format, e.g. Q15.16 N.m or 2^-32 turn) is
 * quantised to a lattice index
 *     p = clamp(round((u - u0) / 2^in_shift), 0, P),   P = (L - 1) * 2^sub_bits
 * (round half away from zero).  p = 0 is negative, p = P positive saturation.
 * The Everett table holds E at the L grid points (lattice multiples of
 * 2^sub_bits); between grid points E is interpolated on the lattice:
 *   - off-diagonal cells: bilinear in (alpha, beta);
 *   - diagonal cells (alpha, beta in the same cell): linear on the triangle
 *     alpha >= beta, E = (f_a - f_b) * E[i+1][i], so that E(p, p) = 0 exactly
 *     (continuity at every reversal);
 * rounded to nearest once (hd_preisach_everett).  sub_bits = 0 means the input
 * is quantised to the grid itself.
 *
 * Relay plane (the brute-force reference, same integers): one relay for each
 * lattice pair 0 <= b < a <= P, up when p >= a, down when p <= b, weight
 *     mu(a, b) = E(a, b) - E(a-1, b) - E(a, b+1) + E(a-1, b+1)   (E(x, y) = 0 for x <= y)
 * so that sum of mu over {b <= b' < a' <= a} = E(a, b) exactly (telescoping),
 * and y = -E(P, 0) + 2 * sum_{up} mu.  The online algorithm
 *   ascending from the memory min (m, y_m):  y = y_m + 2 E(p, m)
 *   descending from the memory max (M, y_M): y = y_M - 2 E(M, p)
 * with the wiping-out rule (ascending past a stored max removes it and the min
 * after it; descending past a stored min likewise) therefore reproduces the
 * relay sum EXACTLY in int64, for any table (tests/c/test_comp_preisach.c).
 *
 * Stacks: maxs[0] is an unpoppable sentinel above P, mins[0] = (0, -E(P,0))
 * (negative saturation).  Dominant extrema are strictly nested, so the depth
 * is <= P/2 + 1; HD_PREISACH_DEPTH (66) covers L = 64 at sub_bits = 0.  On
 * overflow (finer lattices, pathological inputs) the oldest max/min pair is
 * merged away (safety net, counted in `merges`; the output then deviates from
 * the exact model).  Reversal dead-band: a reversal of <= deadband lattice
 * steps is ignored (the previous extreme is kept), so encoder noise cannot fill
 * the stacks; the brute-force reference applies the same input filter.
 * Cost: one Everett evaluation per changed sample + amortised O(1) pops.
 *
 * Inverse (hysteresis compensation): for a desired output y_d, the lattice
 * input p that makes the forward model (same stacks) closest to y_d, found by
 * bisection over p on the current monotone branch (y(p) from the present
 * memory is non-decreasing in p when mu >= 0, wiping-out included), then
 * committed to the forward model.  O(log P) evaluations per sample.
 *
 * Formats: table entries int32 in the OUTPUT format (the same units as y;
 * `unit` documents them: HD_PREISACH_UNIT_*); y int64 internally, int32
 * saturated at the interface; u, u0 int32 input format.
 *
 * Table image (host/hdservo/preisach_table.py writes the same):
 *   words 0..8: magic "HDPT" (0x54504448), format (1), version, levels L,
 *   sub_bits, in_shift, u0, unit, n_entries = L(L+1)/2; word 9: crc; then
 *   n_entries int32 E[i][j] (0 <= j <= i < L) at index i(i+1)/2 + j.
 *   crc = CRC-32 (IEEE 802.3 / zlib) over the little-endian bytes of words
 *   0..8 followed by the entries.  E[i][i] must be 0.
 */
#ifndef HD_PREISACH_H
#define HD_PREISACH_H

#include <stdint.h>
#include <stdbool.h>
#include "hd_blend.h"

#define HD_PREISACH_MAGIC     0x54504448u  /* "HDPT" little-endian */
#define HD_PREISACH_FORMAT    1u
#define HD_PREISACH_L_MIN     2u
#define HD_PREISACH_L_MAX     64u
#define HD_PREISACH_N_MAX     (HD_PREISACH_L_MAX * (HD_PREISACH_L_MAX + 1u) / 2u)
#define HD_PREISACH_SUB_MAX   8u
#define HD_PREISACH_SHIFT_MAX 30u
#define HD_PREISACH_DEPTH     66u          /* entries per stack, sentinel included */
#define HD_PREISACH_HDR_WORDS 9u           /* words covered by the CRC before the entries */
#define HD_PREISACH_IMG_HDR   10u          /* image words before the entries (crc included) */

/* Brute-force reference: lattice size limit (P <= this). */
#define HD_PREISACH_BF_PMAX   255u
#define HD_PREISACH_BF_WORDS  ((HD_PREISACH_BF_PMAX * (HD_PREISACH_BF_PMAX + 1u) / 2u + 31u) / 32u)

/* Units documentation codes (input -> output). */
/* reversals of hd_preisach_demagnetise (fewer than the stack depth) */
#define HD_PREISACH_DEMAG_CYCLES 24u
#define HD_PREISACH_UNIT_GENERIC      0u
#define HD_PREISACH_UNIT_TORQUE_TWIST 1u   /* Q15.16 N.m -> 2^-32 turn */
#define HD_PREISACH_UNIT_POS_POS      2u   /* 2^-32 turn -> 2^-32 turn */

/* Install / check results */
#define HD_PREISACH_OK          0
#define HD_PREISACH_E_MAGIC    (-1)
#define HD_PREISACH_E_FORMAT   (-2)
#define HD_PREISACH_E_SIZE     (-3)
#define HD_PREISACH_E_DIAG     (-4)
#define HD_PREISACH_E_CRC      (-5)

typedef struct {
    uint32_t magic;
    uint32_t format;
    uint32_t version;     /* table version (identification run), host-assigned */
    uint32_t levels;      /* L, 2..64 */
    uint32_t sub_bits;    /* lattice steps per grid cell = 2^sub_bits, 0..8 */
    uint32_t in_shift;    /* input LSB per lattice step = 2^in_shift, 0..30 */
    int32_t  u0;          /* input at lattice 0 */
    uint32_t unit;        /* HD_PREISACH_UNIT_* */
    uint32_t n_entries;   /* L(L+1)/2 */
    uint32_t crc;         /* CRC-32, see above */
    int32_t  e[HD_PREISACH_N_MAX];
} hd_preisach_table_t;

typedef struct {
    int32_t p;            /* lattice index of the extremum */
    int64_t y;            /* output there */
} hd_preisach_ext_t;

typedef struct {
    hd_blend_t blend;
    uint32_t deadband;                          /* parameter: reversal dead-band, lattice steps */
    hd_preisach_ext_t maxs[HD_PREISACH_DEPTH];  /* [0] sentinel */
    hd_preisach_ext_t mins[HD_PREISACH_DEPTH];  /* [0] negative saturation */
    uint32_t n_max;                             /* entries in use, >= 1 */
    uint32_t n_min;                             /* entries in use, >= 1 */
    int32_t  p_prev;                            /* last effective lattice input */
    int32_t  dir;                               /* +1 ascending, -1 descending */
    int64_t  y;                                 /* current output, table units */
    int32_t  p_top;                             /* P of the table the memory belongs to */
    uint32_t table_crc;                         /* CRC of that table (change -> reset) */
    uint32_t merges;                            /* stack overflows merged (diagnostic) */
    int32_t  out;                               /* last weighted output, int32 */
} hd_preisach_t;

typedef struct {
    uint32_t bits[HD_PREISACH_BF_WORDS];        /* relay states, 1 = up */
    uint32_t deadband;
    int32_t  p_prev;
    int32_t  dir;
    int32_t  p_top;
    int64_t  y;
} hd_preisach_bf_t;

/* Where a trial input lands against the memory of a forward model (its output and
 * the memory change it would make; internal to the inverse search). */
typedef struct {
    int64_t  y;           /* output at the trial input */
    uint32_t n_max;       /* stack sizes after it */
    uint32_t n_min;
    int32_t  push;        /* 0 none, -1 a max is pushed, +1 a min */
    int32_t  dir;         /* direction of the move */
} hd_preisach_loc_t;

/* A trial point of the inverse search. */
typedef struct {
    int32_t  p;           /* lattice input */
    uint32_t ok;          /* 1: the input changes the memory (r holds the change) */
    hd_preisach_loc_t r;
} hd_preisach_try_t;

/* Kinds of the inverse search state. */
typedef enum {
    HD_PREISACH_SEARCH_IDLE = 0,    /* no search in progress */
    HD_PREISACH_SEARCH_UP = 1,      /* bisection on [p_prev, P] (output rises) */
    HD_PREISACH_SEARCH_DOWN = 2     /* bisection on [0, p_prev] (output falls) */
} hd_preisach_search_kind_t;

/* An inverse search that may be spread over several calls (hd_preisach_inv_search):
 * the bisection's bracket and its target, kept between the calls. */
typedef struct {
    hd_preisach_search_kind_t kind;
    int64_t  y_d;                   /* the target output of the search in progress */
    hd_preisach_try_t lo;
    hd_preisach_try_t hi;
} hd_preisach_search_t;

typedef struct {
    hd_preisach_t fwd;                          /* forward model driven by the inverse */
    hd_preisach_search_t srch;                  /* search in progress (hd_preisach_inv_search) */
    hd_blend_t blend;
    int32_t u;                                  /* last (unweighted) inverse input, input format */
    int32_t out;                                /* last weighted output */
} hd_preisach_inv_t;

/* ---- table ---------------------------------------------------------------- */

/** CRC-32 of a table image (words 0..8 and n_entries entries); n_entries is
 *  clamped to HD_PREISACH_N_MAX. */
uint32_t hd_preisach_crc(const hd_preisach_table_t *t);
/** Set magic, format, n_entries and crc of a table whose other fields are filled. */
void hd_preisach_seal(hd_preisach_table_t *t);
/** Validate a table image: HD_PREISACH_OK or HD_PREISACH_E_*. */
int32_t hd_preisach_check(const hd_preisach_table_t *t);
/** Copy src into dst only if src passes hd_preisach_check (else dst untouched:
 *  the previous table stays in force).  Returns the check result. */
int32_t hd_preisach_install(hd_preisach_table_t *dst, const hd_preisach_table_t *src);
/** Words of a table image (10 header words + n_entries entries, the wire and NVM
 *  order): a pointer to word w, or NULL for w >= 10 + HD_PREISACH_N_MAX. */
uint32_t *hd_preisach_word(hd_preisach_table_t *t, uint32_t w);
/** Word w of a table image (0 for w >= 10 + HD_PREISACH_N_MAX). */
uint32_t hd_preisach_word_get(const hd_preisach_table_t *t, uint32_t w);
/** Lattice size P = (L - 1) * 2^sub_bits. */
int32_t hd_preisach_p_top(const hd_preisach_table_t *t);
/** Input u -> lattice index p in [0, P]. */
int32_t hd_preisach_quantise(const hd_preisach_table_t *t, int32_t u);
/** Lattice index p -> input value u0 + p * 2^in_shift (saturated). */
int32_t hd_preisach_dequantise(const hd_preisach_table_t *t, int32_t p);
/** Everett function on the lattice, 0 <= b, a <= P (0 when a <= b). */
int32_t hd_preisach_everett(const hd_preisach_table_t *t, int32_t a, int32_t b);

/* ---- online recursive model ------------------------------------------------- */

/** Negative saturation (y = -E(P, 0)), memory empty. */
void hd_preisach_init(hd_preisach_t *s, const hd_preisach_table_t *t, uint32_t deadband,
                      uint32_t ramp_ticks, bool enabled);
/** Memory of a demagnetised axis at rest at lattice index p_c: from negative saturation,
 *  HD_PREISACH_DEMAG_CYCLES reversals of decaying amplitude about p_c, then p_c (the stacks
 *  hold them; not for the control period: about 2 x HD_PREISACH_DEMAG_CYCLES forward steps). */
void hd_preisach_demagnetise(hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p_c);
void hd_preisach_set_enabled(hd_preisach_t *s, bool enabled);
/** One sample given as lattice index; returns y (table units, int64).  If the
 *  table changed since the memory was built (other CRC) the memory restarts
 *  from negative saturation. */
int64_t hd_preisach_step_p(hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p);
/** The y that hd_preisach_step_p(s, t, p) would return, without changing s. */
int64_t hd_preisach_peek_p(const hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p);
/** One period with input u; returns the weighted output, int32 saturated. */
int32_t hd_preisach_step(hd_preisach_t *s, const hd_preisach_table_t *t, int32_t u);

/* ---- brute-force reference ---------------------------------------------------- */

/** All relays down (negative saturation).  Requires P <= HD_PREISACH_BF_PMAX. */
void hd_preisach_bf_init(hd_preisach_bf_t *s, const hd_preisach_table_t *t, uint32_t deadband);
/** One sample (lattice index): update every relay, sum the weights; O(P^2). */
int64_t hd_preisach_bf_step_p(hd_preisach_bf_t *s, const hd_preisach_table_t *t, int32_t p);

/* ---- inverse ------------------------------------------------------------------ */

void hd_preisach_inv_init(hd_preisach_inv_t *s, const hd_preisach_table_t *t, uint32_t deadband,
                          uint32_t ramp_ticks, bool enabled);
void hd_preisach_inv_set_enabled(hd_preisach_inv_t *s, bool enabled);
/** Lattice index whose forward output is closest to y_d on the current branch;
 *  committed to s->fwd.  Ties go to the smaller move. */
int32_t hd_preisach_inv_step_p(hd_preisach_inv_t *s, const hd_preisach_table_t *t, int64_t y_d);
/** The same search spread over calls: starts a search for y_d when none is in progress
 *  (locating both ends of the branch: two trials), then runs bisection trials while the
 *  call's budget of trials lasts.  Returns true once the search is done: the lattice index
 *  is committed to s->fwd (s->fwd.p_prev), the same index and memory as
 *  hd_preisach_inv_step_p(s, t, y_d) gives.  y_d is read only when a search starts; a
 *  table change (its CRC) restarts the search.  budget >= 2 + ceil(log2(P)) finishes
 *  in one call. */
bool hd_preisach_inv_search(hd_preisach_inv_t *s, const hd_preisach_table_t *t, int64_t y_d, uint32_t budget);
/** Abandon a search in progress (the memory is unchanged). */
void hd_preisach_inv_search_reset(hd_preisach_inv_t *s);
/** One period: desired output y_d (output format) -> input command, weighted as
 *  y_d + w * (u - y_d) (for hysteresis whose input and output share a format,
 *  e.g. HD_PREISACH_UNIT_POS_POS; w = 0 passes y_d through). */
int32_t hd_preisach_inv_step(hd_preisach_inv_t *s, const hd_preisach_table_t *t, int32_t y_d);

#endif
