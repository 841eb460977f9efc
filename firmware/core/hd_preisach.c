/* hd_preisach.c - discrete Preisach model (contract: hd_preisach.h). */
#include "hd_preisach.h"
#include <stddef.h>
#include "hd_fixed.h"
#include "hd_crc32.h"
#include "hd_le32.h"

/* ---- table ------------------------------------------------------------------ */

/* the table's CRC-32 (hd_crc32.h) continued over one word, little endian like the image */
static uint32_t hd__crc_word(uint32_t crc, uint32_t w)
{
    uint8_t b[4];
    hd_put_le32(b, w);
    return hd_crc32(crc, b, 4u);
}

uint32_t hd_preisach_crc(const hd_preisach_table_t *t)
{
    const uint32_t n = (t->n_entries < HD_PREISACH_N_MAX) ? t->n_entries : HD_PREISACH_N_MAX;
    uint32_t crc = 0u;
    uint32_t i;
    crc = hd__crc_word(crc, t->magic);
    crc = hd__crc_word(crc, t->format);
    crc = hd__crc_word(crc, t->version);
    crc = hd__crc_word(crc, t->levels);
    crc = hd__crc_word(crc, t->sub_bits);
    crc = hd__crc_word(crc, t->in_shift);
    crc = hd__crc_word(crc, (uint32_t)t->u0);
    crc = hd__crc_word(crc, t->unit);
    crc = hd__crc_word(crc, t->n_entries);
    for (i = 0; i < n; i++) {
        crc = hd__crc_word(crc, (uint32_t)t->e[i]);
    }
    return crc;
}

uint32_t *hd_preisach_word(hd_preisach_table_t *t, uint32_t w)
{
    switch (w) {
    case 0u: return &t->magic;
    case 1u: return &t->format;
    case 2u: return &t->version;
    case 3u: return &t->levels;
    case 4u: return &t->sub_bits;
    case 5u: return &t->in_shift;
    case 6u: return (uint32_t *)(void *)&t->u0;        /* same-size signed/unsigned alias */
    case 7u: return &t->unit;
    case 8u: return &t->n_entries;
    case 9u: return &t->crc;
    default: break;
    }
    return (w - HD_PREISACH_IMG_HDR < HD_PREISACH_N_MAX) ? (uint32_t *)(void *)&t->e[w - HD_PREISACH_IMG_HDR] : NULL;
}

uint32_t hd_preisach_word_get(const hd_preisach_table_t *t, uint32_t w)
{
    /* the header in the order of hd_preisach_word() */
    const uint32_t hdr[HD_PREISACH_IMG_HDR] = {t->magic, t->format, t->version, t->levels, t->sub_bits,
                                               t->in_shift, (uint32_t)t->u0, t->unit, t->n_entries, t->crc};
    if (w < HD_PREISACH_IMG_HDR) {
        return hdr[w];
    }
    return (w - HD_PREISACH_IMG_HDR < HD_PREISACH_N_MAX) ? (uint32_t)t->e[w - HD_PREISACH_IMG_HDR] : 0u;
}

static uint32_t hd__tri(uint32_t i)
{
    return i * (i + 1u) / 2u;
}

void hd_preisach_seal(hd_preisach_table_t *t)
{
    t->magic = HD_PREISACH_MAGIC;
    t->format = HD_PREISACH_FORMAT;
    t->n_entries = (t->levels <= HD_PREISACH_L_MAX) ? hd__tri(t->levels) : 0u;
    t->crc = hd_preisach_crc(t);
}

int32_t hd_preisach_check(const hd_preisach_table_t *t)
{
    uint32_t i;
    if (t->magic != HD_PREISACH_MAGIC) {
        return HD_PREISACH_E_MAGIC;
    }
    if (t->format != HD_PREISACH_FORMAT) {
        return HD_PREISACH_E_FORMAT;
    }
    if (t->levels < HD_PREISACH_L_MIN || t->levels > HD_PREISACH_L_MAX ||
        t->sub_bits > HD_PREISACH_SUB_MAX || t->in_shift > HD_PREISACH_SHIFT_MAX ||
        t->n_entries != hd__tri(t->levels)) {
        return HD_PREISACH_E_SIZE;
    }
    if (hd_preisach_crc(t) != t->crc) {
        return HD_PREISACH_E_CRC;
    }
    for (i = 0; i < t->levels; i++) {
        if (t->e[hd__tri(i) + i] != 0) {
            return HD_PREISACH_E_DIAG;
        }
    }
    return HD_PREISACH_OK;
}

int32_t hd_preisach_install(hd_preisach_table_t *dst, const hd_preisach_table_t *src)
{
    const int32_t rc = hd_preisach_check(src);
    uint32_t i;
    if (rc != HD_PREISACH_OK) {
        return rc;
    }
    dst->magic = src->magic;
    dst->format = src->format;
    dst->version = src->version;
    dst->levels = src->levels;
    dst->sub_bits = src->sub_bits;
    dst->in_shift = src->in_shift;
    dst->u0 = src->u0;
    dst->unit = src->unit;
    dst->n_entries = src->n_entries;
    dst->crc = src->crc;
    for (i = 0; i < HD_PREISACH_N_MAX; i++) {
        dst->e[i] = (i < src->n_entries) ? src->e[i] : 0;
    }
    return HD_PREISACH_OK;
}

int32_t hd_preisach_p_top(const hd_preisach_table_t *t)
{
    const uint32_t l = (t->levels > HD_PREISACH_L_MAX) ? HD_PREISACH_L_MAX
                       : ((t->levels < 1u) ? 1u : t->levels);
    const uint32_t sb = (t->sub_bits > HD_PREISACH_SUB_MAX) ? HD_PREISACH_SUB_MAX : t->sub_bits;
    return (int32_t)((l - 1u) << sb);
}

int32_t hd_preisach_quantise(const hd_preisach_table_t *t, int32_t u)
{
    const uint32_t sh = (t->in_shift > HD_PREISACH_SHIFT_MAX) ? HD_PREISACH_SHIFT_MAX : t->in_shift;
    const int64_t d = (int64_t)u - (int64_t)t->u0;
    const int64_t p = hdf_asr64_rnd(d, sh);
    return (int32_t)hdf_clamp64(p, 0, (int64_t)hd_preisach_p_top(t));
}

int32_t hd_preisach_dequantise(const hd_preisach_table_t *t, int32_t p)
{
    const uint32_t sh = (t->in_shift > HD_PREISACH_SHIFT_MAX) ? HD_PREISACH_SHIFT_MAX : t->in_shift;
    return hdf_sat32(hdf_add64_sat((int64_t)t->u0, hdf_shl64_sat((int64_t)p, sh)));
}

/* Table entry E[i][j], 0 <= j <= i < L (callers guarantee the range). */
static int64_t hd__e(const hd_preisach_table_t *t, uint32_t i, uint32_t j)
{
    return (int64_t)t->e[hd__tri(i) + j];
}

static uint32_t hd__sub_bits(const hd_preisach_table_t *t)
{
    return (t->sub_bits > HD_PREISACH_SUB_MAX) ? HD_PREISACH_SUB_MAX : t->sub_bits;
}

/* hd_preisach_everett with ptop = hd_preisach_p_top(t) and sb = hd__sub_bits(t)
 * given (the inverse computes them once per period instead of per evaluation). */
static int32_t hd__everett_k(const hd_preisach_table_t *t, int32_t a, int32_t b, int32_t ptop, uint32_t sb)
{
    uint32_t ua;
    uint32_t ub;
    uint32_t ia;
    uint32_t ib;
    uint32_t fa;
    uint32_t fb;
    uint32_t n;
    int64_t acc;

    a = hdf_clamp32(a, 0, ptop);
    b = hdf_clamp32(b, 0, ptop);
    if (a <= b) {
        return 0;
    }
    ua = (uint32_t)a;
    ub = (uint32_t)b;
    if (sb == 0u) {
        return t->e[hd__tri(ua) + ub];
    }
    n = (uint32_t)1 << sb;
    ia = ua >> sb;
    ib = ub >> sb;
    fa = ua & (n - 1u);
    fb = ub & (n - 1u);
    if (ia == ib) {
        /* diagonal cell: fa > fb, linear on the triangle, zero on the diagonal */
        acc = (int64_t)(int32_t)(fa - fb) * hd__e(t, ia + 1u, ia);      /* < 2^8: a 32 x 32 product */
        return hdf_asr32_rnd(acc, sb);
    }
    /* off-diagonal cell (ia > ib): bilinear; a corner with weight 0 is not read.
     * The weights are <= 2^(2 sb) <= 2^16 (sb <= HD_PREISACH_SUB_MAX): int32, so each
     * term is a 32 x 32 -> 64 product (SMULL / SMLAL on the M4) */
    acc = (int64_t)(int32_t)((n - fa) * (n - fb)) * hd__e(t, ia, ib);
    if (fa != 0u) {
        acc += (int64_t)(int32_t)(fa * (n - fb)) * hd__e(t, ia + 1u, ib);
        if (fb != 0u) {
            acc += (int64_t)(int32_t)(fa * fb) * hd__e(t, ia + 1u, ib + 1u);
        }
    }
    if (fb != 0u) {
        acc += (int64_t)(int32_t)((n - fa) * fb) * hd__e(t, ia, ib + 1u);
    }
    return hdf_asr32_rnd(acc, 2u * sb);
}

int32_t hd_preisach_everett(const hd_preisach_table_t *t, int32_t a, int32_t b)
{
    return hd__everett_k(t, a, b, hd_preisach_p_top(t), hd__sub_bits(t));
}

/* ---- online recursive model ------------------------------------------------- */

static void hd__pz_reset(hd_preisach_t *s, const hd_preisach_table_t *t)
{
    const int32_t ptop = hd_preisach_p_top(t);
    const int64_t ysat = -(int64_t)hd_preisach_everett(t, ptop, 0);
    s->maxs[0].p = INT32_MAX;      /* sentinel: never reached (p <= P < INT32_MAX) */
    s->maxs[0].y = -ysat;
    s->mins[0].p = 0;              /* negative saturation */
    s->mins[0].y = ysat;
    s->n_max = 1u;
    s->n_min = 1u;
    s->p_prev = 0;
    s->dir = 1;
    s->y = ysat;
    s->p_top = ptop;
    s->table_crc = t->crc;
}

void hd_preisach_init(hd_preisach_t *s, const hd_preisach_table_t *t, uint32_t deadband,
                      uint32_t ramp_ticks, bool enabled)
{
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    s->deadband = deadband;
    s->merges = 0u;
    s->out = 0;
    hd__pz_reset(s, t);
}

void hd_preisach_demagnetise(hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p_c)
{
    /* from negative saturation, reversals of decaying amplitude about p_c, as an axis whose
     * hysteresis was cycled down to rest there: the memory sits in the middle of the loop,
     * where a gear at rest is, not on the branch of the last extreme (whose remanence would
     * stay in every later minor loop that does not reach that extreme again) */
    const int32_t n = (int32_t)HD_PREISACH_DEMAG_CYCLES;
    int32_t k;
    hd__pz_reset(s, t);
    p_c = hdf_clamp32(p_c, 0, s->p_top);
    const int32_t span = (p_c > s->p_top - p_c) ? p_c : s->p_top - p_c;
    for (k = 0; k < n; k++) {
        const int32_t a = (int32_t)(((int64_t)span * (int64_t)(n - k)) / (int64_t)n);
        const int32_t b = (int32_t)(((int64_t)a * (int64_t)(2 * n - 1)) / (int64_t)(2 * n));
        (void)hd_preisach_step_p(s, t, hdf_clamp32(p_c + a, 0, s->p_top));
        (void)hd_preisach_step_p(s, t, hdf_clamp32(p_c - b, 0, s->p_top));
    }
    (void)hd_preisach_step_p(s, t, p_c);
}

void hd_preisach_set_enabled(hd_preisach_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

/* Where p lands against the memory (no change to s).  *push: 0 none, -1 a
 * max (p_prev, y) is pushed (reversal downwards), +1 a min is pushed.
 * Returns false if the sample changes nothing (equal, or dead-band). */
typedef hd_preisach_loc_t hd__pz_loc_t;

static bool hd__pz_locate_k(const hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p,
                            hd__pz_loc_t *r, int32_t ptop, uint32_t sb)
{
    const hd_preisach_ext_t virt = { s->p_prev, s->y };
    int32_t d;
    uint32_t nmax = s->n_max;
    uint32_t nmin = s->n_min;
    int32_t push = 0;

    if (p == s->p_prev) {
        return false;
    }
    d = (p > s->p_prev) ? 1 : -1;
    if (d != s->dir) {
        const int64_t step = (int64_t)p - (int64_t)s->p_prev;
        if (hdf_abs64_sat(step) <= (int64_t)s->deadband) {
            return false;
        }
        push = d;                  /* going down pushes a max (-1), going up a min (+1) */
        if (push < 0) {
            nmax++;
        } else {
            nmin++;
        }
    }
    /* entries at index n_max (resp. n_min) are the virtual pushed one */
    if (d > 0) {
        for (;;) {
            const hd_preisach_ext_t *m = (push < 0 && nmax - 1u == s->n_max) ? &virt
                                         : &s->maxs[nmax - 1u];
            if (p < m->p) {
                break;
            }
            nmax--;                /* wiping-out: the max and the min after it */
            nmin--;
        }
        {
            const hd_preisach_ext_t *m = (push > 0 && nmin - 1u == s->n_min) ? &virt
                                         : &s->mins[nmin - 1u];
            r->y = m->y + 2 * (int64_t)hd__everett_k(t, p, m->p, ptop, sb);
        }
    } else {
        for (;;) {
            const hd_preisach_ext_t *m = (push > 0 && nmin - 1u == s->n_min) ? &virt
                                         : &s->mins[nmin - 1u];
            if (nmin <= 1u || p > m->p) {
                break;
            }
            nmin--;
            nmax--;
        }
        {
            const hd_preisach_ext_t *m = (push < 0 && nmax - 1u == s->n_max) ? &virt
                                         : &s->maxs[nmax - 1u];
            r->y = m->y - 2 * (int64_t)hd__everett_k(t, m->p, p, ptop, sb);
        }
    }
    r->n_max = nmax;
    r->n_min = nmin;
    r->push = push;
    r->dir = d;
    return true;
}

static bool hd__pz_locate(const hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p,
                          hd__pz_loc_t *r)
{
    return hd__pz_locate_k(s, t, p, r, hd_preisach_p_top(t), hd__sub_bits(t));
}

/* Safety net: drop the oldest max/min pair (indices 1) of both stacks. */
static void hd__pz_merge_oldest(hd_preisach_t *s)
{
    uint32_t i;
    for (i = 1u; i + 1u < s->n_max; i++) {
        s->maxs[i] = s->maxs[i + 1u];
    }
    for (i = 1u; i + 1u < s->n_min; i++) {
        s->mins[i] = s->mins[i + 1u];
    }
    s->n_max--;
    s->n_min--;
    s->merges++;
}

/* Apply a located sample (the result of hd__pz_locate for p) to the memory. */
static void hd__pz_commit(hd_preisach_t *s, int32_t p, const hd__pz_loc_t *r)
{
    if (r->push < 0) {
        s->maxs[s->n_max].p = s->p_prev;
        s->maxs[s->n_max].y = s->y;
    } else if (r->push > 0) {
        s->mins[s->n_min].p = s->p_prev;
        s->mins[s->n_min].y = s->y;
    }
    s->n_max = r->n_max;
    s->n_min = r->n_min;
    s->dir = r->dir;
    s->p_prev = p;
    s->y = r->y;
}

/* True if hd_preisach_step_p(s, t, p) (p already clamped) would first drop the
 * oldest max/min pair to make room for a pushed max. */
static bool hd__pz_needs_merge(const hd_preisach_t *s, int32_t p)
{
    return p < s->p_prev && s->dir > 0 && s->n_max >= HD_PREISACH_DEPTH &&
           (s->p_prev - p) > (int32_t)hdf_clamp64((int64_t)s->deadband, 0, INT32_MAX) &&
           s->n_min >= 2u;
}

int64_t hd_preisach_step_p(hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p)
{
    hd__pz_loc_t r;

    if (s->table_crc != t->crc || s->p_top != hd_preisach_p_top(t)) {
        hd__pz_reset(s, t);
    }
    p = hdf_clamp32(p, 0, s->p_top);
    /* a reversal downwards pushes a max; make room first if the stack is full */
    if (hd__pz_needs_merge(s, p)) {
        hd__pz_merge_oldest(s);
    }
    if (!hd__pz_locate(s, t, p, &r)) {
        return s->y;
    }
    hd__pz_commit(s, p, &r);
    return s->y;
}

int64_t hd_preisach_peek_p(const hd_preisach_t *s, const hd_preisach_table_t *t, int32_t p)
{
    hd__pz_loc_t r;
    p = hdf_clamp32(p, 0, s->p_top);
    if (!hd__pz_locate(s, t, p, &r)) {
        return s->y;
    }
    return r.y;
}

int32_t hd_preisach_step(hd_preisach_t *s, const hd_preisach_table_t *t, int32_t u)
{
    const int64_t y = hd_preisach_step_p(s, t, hd_preisach_quantise(t, u));
    (void)hd_blend_update(&s->blend);
    s->out = hd_blend_apply(&s->blend, hdf_sat32(y));
    return s->out;
}

/* ---- brute-force reference ---------------------------------------------------- */

void hd_preisach_bf_init(hd_preisach_bf_t *s, const hd_preisach_table_t *t, uint32_t deadband)
{
    uint32_t i;
    for (i = 0; i < HD_PREISACH_BF_WORDS; i++) {
        s->bits[i] = 0u;
    }
    s->deadband = deadband;
    s->p_prev = 0;
    s->dir = 1;
    s->p_top = hd_preisach_p_top(t);
    if (s->p_top > (int32_t)HD_PREISACH_BF_PMAX) {
        s->p_top = (int32_t)HD_PREISACH_BF_PMAX;
    }
    s->y = -(int64_t)hd_preisach_everett(t, s->p_top, 0);
}

int64_t hd_preisach_bf_step_p(hd_preisach_bf_t *s, const hd_preisach_table_t *t, int32_t p)
{
    int32_t d;
    int32_t a;
    int32_t b;
    uint32_t r = 0u;
    int64_t up = 0;

    p = hdf_clamp32(p, 0, s->p_top);
    if (p == s->p_prev) {
        return s->y;
    }
    d = (p > s->p_prev) ? 1 : -1;
    if (d != s->dir && hdf_abs64_sat((int64_t)p - (int64_t)s->p_prev) <= (int64_t)s->deadband) {
        return s->y;
    }
    s->dir = d;
    s->p_prev = p;
    for (a = 1; a <= s->p_top; a++) {
        for (b = 0; b < a; b++, r++) {
            const uint32_t w = r >> 5;
            const uint32_t m = (uint32_t)1 << (r & 31u);
            if (p >= a) {
                s->bits[w] |= m;
            } else if (p <= b) {
                s->bits[w] &= ~m;
            }
            if ((s->bits[w] & m) != 0u) {
                const int64_t mu = (int64_t)hd_preisach_everett(t, a, b)
                                   - (int64_t)hd_preisach_everett(t, a - 1, b)
                                   - (int64_t)hd_preisach_everett(t, a, b + 1)
                                   + (int64_t)hd_preisach_everett(t, a - 1, b + 1);
                up += mu;
            }
        }
    }
    s->y = 2 * up - (int64_t)hd_preisach_everett(t, s->p_top, 0);
    return s->y;
}

/* ---- inverse ------------------------------------------------------------------ */

void hd_preisach_inv_init(hd_preisach_inv_t *s, const hd_preisach_table_t *t, uint32_t deadband,
                          uint32_t ramp_ticks, bool enabled)
{
    hd_preisach_init(&s->fwd, t, deadband, 0u, true);
    hd_blend_init(&s->blend, ramp_ticks, enabled);
    s->srch.kind = HD_PREISACH_SEARCH_IDLE;
    s->srch.y_d = 0;
    s->srch.lo.p = 0;
    s->srch.hi.p = 0;
    s->u = hd_preisach_dequantise(t, 0);
    s->out = 0;
}

void hd_preisach_inv_set_enabled(hd_preisach_inv_t *s, bool enabled)
{
    hd_blend_set_enabled(&s->blend, enabled);
}

static int64_t hd__dist(int64_t a, int64_t b)
{
    return hdf_abs64_sat(hdf_sub64_sat(a, b));
}

/* A trial point of the inverse search: hd_preisach_peek_p(f, t, p) with the
 * located memory change kept (ok = 0: the sample changes nothing, y = f->y). */
typedef hd_preisach_try_t hd__pz_try_t;

/* the table's P and sub-bits, computed once per inverse step */
typedef struct {
    int32_t ptop;
    uint32_t sb;
} hd__pz_k_t;

static int64_t hd__try(const hd_preisach_t *f, const hd_preisach_table_t *t, const hd__pz_k_t *k, int32_t p,
                       hd__pz_try_t *x)
{
    x->p = p;
    x->ok = hd__pz_locate_k(f, t, p, &x->r, k->ptop, k->sb) ? 1u : 0u;
    if (x->ok == 0u) {
        x->r.y = f->y;
    }
    return x->r.y;
}

void hd_preisach_inv_search_reset(hd_preisach_inv_t *s)
{
    s->srch.kind = HD_PREISACH_SEARCH_IDLE;
}

/* The chosen point to the memory; the search ends. */
static void hd__inv_finish(hd_preisach_inv_t *s, const hd_preisach_table_t *t, const hd__pz_try_t *sel)
{
    hd_preisach_t *f = &s->fwd;
    if (hd__pz_needs_merge(f, sel->p)) {
        (void)hd_preisach_step_p(f, t, sel->p);     /* the memory changes first: locate again */
    } else if (sel->ok != 0u) {
        hd__pz_commit(f, sel->p, &sel->r);
    }
    s->srch.kind = HD_PREISACH_SEARCH_IDLE;
}

/*
 * Bisection for the lattice point whose output is closest to y_d on the
 * monotone branch from p_prev.  Every trial point is located once: its output
 * and memory change are kept, so the end comparison and the final step reuse
 * them instead of evaluating the Everett function again (same result as
 * peek at every point, then hd_preisach_step_p at the chosen one).  The
 * bracket lives in s->srch, so the trials may be spread over several calls;
 * the memory changes only when the search ends, and the trials depend only on
 * the memory and y_d, so the result does not depend on the budget.
 */
bool hd_preisach_inv_search(hd_preisach_inv_t *s, const hd_preisach_table_t *t, int64_t y_d, uint32_t budget)
{
    hd_preisach_t *f = &s->fwd;
    hd_preisach_search_t *q = &s->srch;
    hd__pz_try_t mid;
    hd__pz_k_t k;

    k.ptop = hd_preisach_p_top(t);
    k.sb = hd__sub_bits(t);
    if (f->table_crc != t->crc || f->p_top != k.ptop) {
        hd__pz_reset(f, t);
        q->kind = HD_PREISACH_SEARCH_IDLE;          /* a bracket of the old table means nothing */
    }
    if (q->kind == HD_PREISACH_SEARCH_IDLE) {
        if (y_d == f->y) {
            return true;
        }
        q->y_d = y_d;
        budget = (budget > 2u) ? budget - 2u : 0u;  /* the two ends */
        if (y_d > f->y) {
            /* y(p) non-decreasing on [p_prev, P]; y(lo) < y_d */
            (void)hd__try(f, t, &k, f->p_prev, &q->lo);
            if (f->p_top == f->p_prev) {
                hd__inv_finish(s, t, &q->lo);
                return true;
            }
            if (hd__try(f, t, &k, f->p_top, &q->hi) < y_d) {
                hd__inv_finish(s, t, &q->hi);
                return true;
            }
            q->kind = HD_PREISACH_SEARCH_UP;
        } else {
            /* y(p) non-decreasing on [0, p_prev]; y(hi) > y_d */
            (void)hd__try(f, t, &k, f->p_prev, &q->hi);
            if (f->p_prev == 0) {
                hd__inv_finish(s, t, &q->hi);
                return true;
            }
            if (hd__try(f, t, &k, 0, &q->lo) > y_d) {
                hd__inv_finish(s, t, &q->lo);
                return true;
            }
            q->kind = HD_PREISACH_SEARCH_DOWN;
        }
    }
    while (q->hi.p - q->lo.p > 1 && budget > 0u) {
        const int64_t ym = hd__try(f, t, &k, q->lo.p + (q->hi.p - q->lo.p) / 2, &mid);
        const bool to_hi = (q->kind == HD_PREISACH_SEARCH_UP) ? (ym >= q->y_d) : (ym > q->y_d);
        if (to_hi) {
            q->hi = mid;
        } else {
            q->lo = mid;
        }
        budget--;
    }
    if (q->hi.p - q->lo.p > 1) {
        return false;                               /* the budget ran out: go on next call */
    }
    if (q->kind == HD_PREISACH_SEARCH_UP) {
        hd__inv_finish(s, t, (hd__dist(q->hi.r.y, q->y_d) < hd__dist(q->lo.r.y, q->y_d)) ? &q->hi : &q->lo);
    } else {
        hd__inv_finish(s, t, (hd__dist(q->lo.r.y, q->y_d) < hd__dist(q->hi.r.y, q->y_d)) ? &q->lo : &q->hi);
    }
    return true;
}

int32_t hd_preisach_inv_step_p(hd_preisach_inv_t *s, const hd_preisach_table_t *t, int64_t y_d)
{
    s->srch.kind = HD_PREISACH_SEARCH_IDLE;
    (void)hd_preisach_inv_search(s, t, y_d, UINT32_MAX);
    return s->fwd.p_prev;
}

int32_t hd_preisach_inv_step(hd_preisach_inv_t *s, const hd_preisach_table_t *t, int32_t y_d)
{
    const int32_t p = hd_preisach_inv_step_p(s, t, (int64_t)y_d);
    s->u = hd_preisach_dequantise(t, p);
    (void)hd_blend_update(&s->blend);
    s->out = hd_blend_mix(&s->blend, y_d, s->u);
    return s->out;
}
