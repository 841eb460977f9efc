/*
 * hd_plant.c - two-mass harmonic-drive axis: dynamics, integrator, sensors.
 *
 * Integrator (one control period dt = substeps * h):
 *   - current loop: exact first-order update over h; the mechanical step uses the
 *     exact average current of the sub-step;
 *   - mechanics (theta_m, w_m, theta_l, w_l): classical RK4;
 *   - LuGre bristles: exponential update for constant velocity
 *       z(t+s) = z*exp(-a*s) + v*s*phi1(-a*s),  a = sigma0*|v|/g(v),  phi1(x) = expm1(x)/x,
 *     used inside the RK4 stages (with the stage velocity) and to commit z at the
 *     end of the sub-step (with the mean velocity dtheta/h), so stiff bristles
 *     never limit h;
 *   - rate-independent hysteresis (Maxwell-slip, Preisach): stages evaluate the
 *     operator from the committed memory (exact while the twist is monotone inside
 *     a sub-step); the memory is committed with the end-of-step twist;
 *   - static (non-LuGre) friction: a sticking state; a stuck side has zero
 *     velocity and its friction balances the applied torque up to the breakaway
 *     level, so below breakaway nothing creeps.
 */
#include "hd_plant.h"
#include "hd_plant_preisach.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define TWO_PI 6.283185307179586

/* ---- PRNG: xoshiro256** seeded by splitmix64 -------------------------------- */
static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static uint64_t rng_next(uint64_t s[4])
{
    uint64_t r = rotl(s[1] * 5u, 7) * 9u;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0]; s[3] ^= s[1]; s[1] ^= s[2]; s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return r;
}

static double rng_uniform(uint64_t s[4])   /* (0, 1) */
{
    return ((double)(rng_next(s) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

/* Standard Gaussian by the ziggurat method (Marsaglia & Tsang 2000, 128 layers of
 * equal area, in Doornik's floating-point form): exact in distribution, usually one
 * uniform draw, a table look-up and a compare; exp/log only in the rare wedges and
 * the tail (beyond R = 3.4426).  Tables are built once at init. */
#define ZIG_C 128
#define ZIG_R 3.442619855899
#define ZIG_V 9.91256303526217e-3

static void zig_init(double *x, double *r)
{
    double f = exp(-0.5 * ZIG_R * ZIG_R);
    int i;
    x[0] = ZIG_V / f;
    x[1] = ZIG_R;
    x[ZIG_C] = 0.0;
    for (i = 2; i < ZIG_C; i++) {
        x[i] = sqrt(-2.0 * log(ZIG_V / x[i - 1] + f));
        f = exp(-0.5 * x[i] * x[i]);
    }
    for (i = 0; i < ZIG_C; i++) r[i] = x[i + 1] / x[i];
}

/* The rare part of a draw (wedge, tail; about 1 % of the calls), out of line so that the
 * common path needs no registers saved around libm calls. */
__attribute__((noinline)) static double rng_gauss_slow(hd_plant *p, int i, double u)
{
    for (;;) {
        double xx, f0, f1;
        uint64_t b;
        if (fabs(u) < p->zig_r[i]) return u * p->zig_x[i];
        if (i == 0) {                                                    /* tail beyond R */
            double t, y;
            do {
                t = -log(rng_uniform(p->rng)) / ZIG_R;
                y = -log(rng_uniform(p->rng));
            } while (y + y < t * t);
            return u < 0.0 ? -(ZIG_R + t) : ZIG_R + t;
        }
        xx = u * p->zig_x[i];                                            /* wedge */
        f0 = exp(-0.5 * (p->zig_x[i] * p->zig_x[i] - xx * xx));
        f1 = exp(-0.5 * (p->zig_x[i + 1] * p->zig_x[i + 1] - xx * xx));
        if (f1 + rng_uniform(p->rng) * (f0 - f1) < 1.0) return xx;
        b = rng_next(p->rng);
        i = (int)(b & 0x7Fu);
        u = 2.0 * (((double)(b >> 11) + 0.5) * (1.0 / 9007199254740992.0)) - 1.0;
    }
}

static double rng_gauss(hd_plant *p)
{
    const uint64_t b = rng_next(p->rng);
    const int i = (int)(b & 0x7Fu);                                      /* layer: low 7 bits */
    const double u = 2.0 * (((double)(b >> 11) + 0.5) * (1.0 / 9007199254740992.0)) - 1.0; /* top 53 bits */
    if (fabs(u) < p->zig_r[i]) return u * p->zig_x[i];
    return rng_gauss_slow(p, i, u);
}

/* cos/sin(x0 + d) from c0 = cos x0, s0 = sin x0: angle addition with a Taylor
 * polynomial of cos/sin d for small |d| (truncation < 1e-22), libm otherwise. */
static inline void rot_poly(double c0, double s0, double d, double *c, double *s)
{
    double ad = fabs(d);
    if (ad < 2e-3) {
        /* sin d = d - d^3/6 (error < d^5/120 < 3e-16), cos d - 1 = -d^2/2 + d^4/24 (< 1e-22) */
        double d2 = d * d;
        double sd = d * (1.0 - d2 * (1.0 / 6.0));
        double cm1 = -0.5 * d2 * (1.0 - d2 * (1.0 / 12.0));
        *c = c0 + (c0 * cm1 - s0 * sd);
        *s = s0 + (s0 * cm1 + c0 * sd);
    } else {                               /* 2e-3 <= |d| < ROT_MAX (callers check) */
        double d2 = d * d;
        /* Taylor terms to d^11 / d^12 in Estrin's form (powers d^2, d^4, d^8; the
         * coefficients are 1/(2k+1)! and 1/(2k+2)!): a short dependency chain */
        const double d4 = d2 * d2, d8 = d4 * d4;
        double sd = d * (((1.0 - d2 * (1.0 / 6.0)) + d4 * (1.0 / 120.0 - d2 * (1.0 / 5040.0)))
                         + d8 * (1.0 / 362880.0 - d2 * (1.0 / 39916800.0)));
        double cm1 = d2 * (((-1.0 / 2.0 + d2 * (1.0 / 24.0)) + d4 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0)))
                           + d8 * (-1.0 / 3628800.0 + d2 * (1.0 / 479001600.0)));
        *c = c0 + (c0 * cm1 - s0 * sd);
        *s = s0 + (s0 * cm1 + c0 * sd);
    }
}

#define ROT_MAX 0.1   /* rot_poly's range: |d| < ROT_MAX */
#define TRIG_SYNC 64  /* rotations between refreshes of cos/sin from libm */
#define HT_XMAX 0.125 /* range of the harmonics' series in n_max |d| (degree <= HD_PLANT_HT_JMAX) */
#define HT_EMIN 60    /* n_max |d| < 2^-60: degree 0 (the first term is below 2^-60 relative) */

static inline void rot_small(double c0, double s0, double x, double d, double *c, double *s)
{
    if (fabs(d) < ROT_MAX) {
        rot_poly(c0, s0, d, c, s);
    } else {
        *c = cos(x);
        *s = sin(x);
    }
}

/* ---- model pieces -------------------------------------------------------------- */
static double sat(double x, double d) { return x > d ? d : (x < -d ? -d : x); }

/* Centre line of the Preisach operator's major loop, the mean of the ascending
 * branch -E(M,-M) + 2E(u,-M) and the descending branch E(M,-M) - 2E(M,u):
 * P_mean(u) = E(u,-M) - E(M,u), M = u_max.  The gear's hysteresis torque is
 * P_mean(phi) - P[phi]: it has no single-valued (spring-like) part, so the
 * stiffness seen by a torque-twist test is the stiffness model's alone, and it
 * is dissipative (above the centre line on loading, below on unloading).
 * With one argument on the grid's edge the interpolated Everett function is linear
 * in the other inside each cell, so P_mean is piecewise linear on the grid: it is
 * tabulated at the L+1 nodes at init (pmean_table) and interpolated here. */
static void pmean_table(hd_plant *p)
{
    const double M = p->prm.preisach_u_max_rad, du = 2.0 * M / (double)HD_PLANT_PREISACH_L;
    int i;
    for (i = 0; i <= HD_PLANT_PREISACH_L; i++) {
        const double u = i == HD_PLANT_PREISACH_L ? M : -M + (double)i * du;
        p->preisach_pm[i] = hd_preisach_E(p->everett, M, u, -M) - hd_preisach_E(p->everett, M, M, u);
    }
    p->preisach_inv_du = (double)HD_PLANT_PREISACH_L / (2.0 * M);
}

static double preisach_mean(const hd_plant *p, const hd_plant_params *q, double phi)
{
    const double M = q->preisach_u_max_rad, x = (sat(phi, M) + M) * p->preisach_inv_du;
    int i;
    double f;
    /* a diverging state (NaN, or a range no table holds) must never reach the int cast:
     * the table's end is used and the divergence check stops the run */
    if (!(x >= 0.0)) {
        i = 0;
    } else if (x >= (double)(HD_PLANT_PREISACH_L - 1)) {
        i = HD_PLANT_PREISACH_L - 1;
    } else {
        i = (int)x;
    }
    f = x - (double)i;
    return p->preisach_pm[i] + f * (p->preisach_pm[i + 1] - p->preisach_pm[i]);
}

static double sat_pot(double x, double d)   /* integral of sat_d from 0 to x */
{
    double ax = fabs(x);
    return ax <= d ? 0.5 * x * x : d * ax - 0.5 * d * d;
}

static inline __attribute__((always_inline)) double spring_torque(const hd_plant *p, double phi)
{
    const hd_plant_params *q = &p->prm;
    double t = 0.0;
    if (q->stiffness_enabled)
        t += q->k3_Nm_per_rad * phi + (q->k1_Nm_per_rad - q->k2_Nm_per_rad) * sat(phi, p->phi1)
             + (q->k2_Nm_per_rad - q->k3_Nm_per_rad) * sat(phi, p->phi2);
    if (q->cubic_enabled)
        t += q->cubic_k1_Nm_per_rad * phi + q->cubic_k3_Nm_per_rad3 * phi * phi * phi;
    return t;
}

static double spring_energy(const hd_plant *p, double phi)
{
    const hd_plant_params *q = &p->prm;
    double e = 0.0;
    if (q->stiffness_enabled)
        e += 0.5 * q->k3_Nm_per_rad * phi * phi + (q->k1_Nm_per_rad - q->k2_Nm_per_rad) * sat_pot(phi, p->phi1)
             + (q->k2_Nm_per_rad - q->k3_Nm_per_rad) * sat_pot(phi, p->phi2);
    if (q->cubic_enabled)
        e += 0.5 * q->cubic_k1_Nm_per_rad * phi * phi + 0.25 * q->cubic_k3_Nm_per_rad3 * phi * phi * phi * phi;
    return e;
}

/* Harmonic lists (0 cogging, 1 TE wave generator, 2 TE output), compacted at init to
 * the active entries.  Integer orders are evaluated from one cos/sin of the angle by a
 * power chain shared by every list on that angle (chain 0: theta_m for cogging and
 * the wave-generator TE, chain 1: theta_l for the output TE): entry 0 is e^{i theta},
 * each later entry the product of two earlier ones (a square when both are the same),
 * so e.g. orders 1, 2, 4, 36, 72 cost 7 complex products per evaluation instead of a
 * binary power per harmonic.  Non-integer orders (hidx < 0) use libm sin/cos. */
static int32_t pw_find(const hd_plant *p, int ch, uint32_t o)
{
    int32_t j;
    for (j = 0; j < p->pw_n[ch]; j++)
        if (p->pw_ord[ch][j] == o) return j;
    return -1;
}

static int32_t pw_push(hd_plant *p, int ch, int32_t a, int32_t b)
{
    int32_t n = p->pw_n[ch];
    p->pw_a[ch][n] = a;
    p->pw_b[ch][n] = b;
    p->pw_ord[ch][n] = p->pw_ord[ch][a] + p->pw_ord[ch][b];
    p->pw_n[ch] = n + 1;
    return n;
}

/* Entry of order o (1 <= o <= 4096), added with what it needs: a sum of two entries
 * already there, else the binary method (o = 2*(o/2) or (o-1) + 1); at most 24 new
 * entries per order, so HD_PLANT_POW_MAX always suffices. */
static int32_t pw_add(hd_plant *p, int ch, uint32_t o)
{
    int32_t j, i2, e = pw_find(p, ch, o);
    if (e >= 0) return e;
    for (j = 0; j < p->pw_n[ch]; j++)
        if (p->pw_ord[ch][j] < o && (i2 = pw_find(p, ch, o - p->pw_ord[ch][j])) >= 0) return pw_push(p, ch, j, i2);
    if ((o & 1u) == 0u) { e = pw_add(p, ch, o / 2u); return pw_push(p, ch, e, e); }
    e = pw_add(p, ch, o - 1u);
    return pw_push(p, ch, e, 0);
}

static void harm_plan(hd_plant *p)
{
    const hd_plant_params *q = &p->prm;
    int l, k, ch;
    for (ch = 0; ch < 2; ch++) {
        p->pw_n[ch] = 1;
        p->pw_ord[ch][0] = 1u;
        p->pw_a[ch][0] = p->pw_b[ch][0] = 0;
        p->hmax[ch] = 0.0;
    }
    for (l = 0; l <= HD_PLANT_HT_JMAX; l++)      /* radius of degree J: x^(J+1)/(J+1)! = 2^-53 */
        p->ht_xb[l] = exp((lgamma((double)l + 2.0) - 53.0 * log(2.0)) / ((double)l + 1.0));
    for (l = 0; l < HD_PLANT_HT_NTAB; l++) {   /* degree by octave: x < 2^(l + 1 - HT_EMIN) */
        const double top = ldexp(1.0, l + 1 - HT_EMIN);
        int32_t J = 0;
        while (J < HD_PLANT_HT_JMAX && top > p->ht_xb[J]) J++;
        p->ht_jtab[l] = J;
    }
    for (l = 0; l < 3; l++) {
        const double *ord = l == 0 ? q->cog_order : (l == 1 ? q->te_wg_order : q->te_out_order);
        const double *amp = l == 0 ? q->cog_amp_Nm : (l == 1 ? q->te_wg_amp_rad : q->te_out_amp_rad);
        const double *ph = l == 0 ? q->cog_phase_rad : (l == 1 ? q->te_wg_phase_rad : q->te_out_phase_rad);
        int n = 0, pass;
        ch = l == 2 ? 1 : 0;
        for (pass = 0; pass < 2; pass++) {         /* integer orders first, then the rest */
            for (k = 0; k < HD_PLANT_MAX_HARM; k++) {
                if (ord[k] == 0.0 || amp[k] == 0.0 || (p->harm_int[l][k] != 0) != (pass == 0)) continue;
                p->hfo[l][n] = ord[k];
                p->hamp[l][n] = amp[k];
                p->hampn[l][n] = amp[k] * ord[k];
                p->hcp[l][n] = p->harm_cp[l][k];
                p->hsp[l][n] = p->harm_sp[l][k];
                p->hph[l][n] = ph[k];
                p->hidx[l][n] = pass == 0 ? pw_add(p, ch, (uint32_t)ord[k]) : -1;
                n++;
            }
            if (pass == 0) p->hn_int[l] = n;
        }
        p->hn[l] = n;
        if (p->hn_int[l] < n) p->h_libm = 1;
        for (k = 0; k < p->hn_int[l]; k++) {      /* Taylor weights a n^j / j!, sign of the j-th derivative of sin */
            double w = p->hamp[l][k];
            int32_t j;
            for (j = 0; j <= HD_PLANT_HT_JMAX + 1; j++) {
                p->ht_w[l][k][j] = (j & 2) ? -w : w;
                w = w * p->hfo[l][k] / (double)(j + 1);
            }
        }
        for (k = 0; k < p->hn_int[l]; k++)
            if (p->hfo[l][k] > p->hmax[ch]) p->hmax[ch] = p->hfo[l][k];
    }
}

/* Non-integer orders of list l (entries hn_int..hn-1) by libm, kept out of the
 * arithmetic loops of harm_eval (no call there). */
static double harm_sum_libm(const hd_plant *p, int l, double th, double *dsum)
{
    double sum = 0.0, d = 0.0;
    int32_t k;
    for (k = p->hn_int[l]; k < p->hn[l]; k++) {
        const double arg = p->hfo[l][k] * th + p->hph[l][k];
        sum += p->hamp[l][k] * sin(arg);
        d += p->hampn[l][k] * cos(arg);
    }
    *dsum += d;
    return sum;
}

/* cos/sin of every entry of chain ch from c1 = cos, s1 = sin of the angle. */
#define HARM_POWERS(ch, c1, s1)                                                    \
    do {                                                                           \
        const int32_t n_ = p->pw_n[ch], *ia_ = p->pw_a[ch], *ib_ = p->pw_b[ch];    \
        int32_t j_;                                                                \
        pc[0] = (c1);                                                              \
        ps[0] = (s1);                                                              \
        for (j_ = 1; j_ < n_; j_++) {                                              \
            const double a_ = pc[ia_[j_]], b_ = ps[ia_[j_]];                       \
            const double e_ = pc[ib_[j_]], f_ = ps[ib_[j_]];                       \
            pc[j_] = a_ * e_ - b_ * f_;                                            \
            ps[j_] = a_ * f_ + b_ * e_;                                            \
        }                                                                          \
    } while (0)

/* Kinematic TE (both TE lists), its partial derivatives w.r.t. theta_m and theta_l,
 * and the cogging torque (cm, sm = cos, sin theta_m; cl, sl = cos, sin theta_l).
 * One power chain per angle serves every list on it; written out in one function
 * (no calls on the integer-order path) because it runs at every RK stage. */
static double harm_eval(const hd_plant *p, double th_m, double cm, double sm, double th_l, double cl, double sl,
                        double *de_m, double *de_l, double *tcog, double (*hc)[HD_PLANT_MAX_HARM],
                        double (*hs)[HD_PLANT_MAX_HARM])
{
    double pc[HD_PLANT_POW_MAX], ps[HD_PLANT_POW_MAX], e = 0.0, d = 0.0, dl = 0.0, cg = 0.0;
    const int te = p->prm.te_enabled != 0, cog = p->prm.cogging_enabled != 0;
    int32_t k, n;
    if (te || cog) {
        HARM_POWERS(0, cm, sm);
        if (te) {
            const int32_t *idx = p->hidx[1];
            const double *cp = p->hcp[1], *sp = p->hsp[1], *amp = p->hamp[1], *ampn = p->hampn[1];
            n = p->hn_int[1];
            for (k = 0; k < n; k++) {
                const double c = pc[idx[k]], s = ps[idx[k]];
                e += amp[k] * (s * cp[k] + c * sp[k]);
                d += ampn[k] * (c * cp[k] - s * sp[k]);
            }
        }
        if (cog) {
            const int32_t *idx = p->hidx[0];
            const double *cp = p->hcp[0], *sp = p->hsp[0], *amp = p->hamp[0];
            n = p->hn_int[0];
            for (k = 0; k < n; k++)
                cg += amp[k] * (ps[idx[k]] * cp[k] + pc[idx[k]] * sp[k]);
        }
        if (hc != NULL) {
            int l;
            for (l = 0; l < 2; l++)
                for (k = 0; k < p->hn_int[l]; k++) {          /* cos/sin(n theta + phase) */
                    const double c = pc[p->hidx[l][k]], s = ps[p->hidx[l][k]];
                    hc[l][k] = c * p->hcp[l][k] - s * p->hsp[l][k];
                    hs[l][k] = s * p->hcp[l][k] + c * p->hsp[l][k];
                }
        }
    }
    if (te && p->has_te_out) {
        const int32_t *idx = p->hidx[2];
        const double *cp = p->hcp[2], *sp = p->hsp[2], *amp = p->hamp[2], *ampn = p->hampn[2];
        HARM_POWERS(1, cl, sl);
        n = p->hn_int[2];
        for (k = 0; k < n; k++) {
            const double c = pc[idx[k]], s = ps[idx[k]];
            e += amp[k] * (s * cp[k] + c * sp[k]);
            dl += ampn[k] * (c * cp[k] - s * sp[k]);
            if (hc != NULL) { hc[2][k] = c * cp[k] - s * sp[k]; hs[2][k] = s * cp[k] + c * sp[k]; }
        }
    }
    if (p->h_libm) {                     /* some order is not an integer */
        double dd = 0.0;
        if (te) e += harm_sum_libm(p, 1, th_m, &d) + harm_sum_libm(p, 2, th_l, &dl);
        if (cog) cg += harm_sum_libm(p, 0, th_m, &dd);
    }
    *de_m = d;
    *de_l = dl;
    *tcog = cg;
    return e;
}

static double te_eval1(const hd_plant *p, double th_m, double th_l, double *de_m, double *de_l)
{
    double tcog;
    return harm_eval(p, th_m, cos(th_m), sin(th_m), th_l, cos(th_l), sin(th_l), de_m, de_l, &tcog, NULL, NULL);
}

/* ---- harmonics by Taylor series about an anchor ------------------------------------------
 * The RK stages and the end evaluations take TE and cogging from Taylor series of the sums
 * about an anchor angle (theta_a: theta_m for chain 0, theta_l for chain 1), where
 * cos/sin(n theta_a + phase) of every integer-order harmonic are stored (hc0, hs0):
 *   S(theta_a + d) = sum_k a_k sin(n_k (theta_a + d) + p_k) = sum_j E_j d^j,
 *   E_j = sum_k a_k n_k^j / j! * sin^(j)(n_k theta_a + p_k)   (sin, cos, -sin, -cos, ...),
 * and the derivative sum sum_k a_k n_k cos(...) = sum_j (j + 1) E_{j+1} d^j.  The degree J
 * of an evaluation is the smallest with x^(J+1)/(J+1)! <= 2^-53, x = n_max |d| (ht_xb): the
 * truncation is below 2^-53 of sum |a_k| (of sum |a_k n_k| for the derivative), i.e. the
 * series equals the libm formula to rounding.  Coefficients are formed lazily up to the
 * degree asked for (ht_deg), so an axis at rest pays for a degree 0-2 polynomial per sum
 * and no trigonometry.  The end evaluation moves the anchor to its angles when they are
 * beyond the degree-HT_JANCHOR radius: each stored harmonic is rotated by n d (rot_poly,
 * about one ulp), re-seeded from libm cos/sin and the power chain every TRIG_SYNC
 * re-anchorings, so rounding cannot accumulate.  Beyond the degree-HD_PLANT_HT_JMAX radius
 * (fast motion) the caller evaluates the power chain instead (harm_eval). */
#define HT_JANCHOR 5

/* E_j, and D_{j-1} = j E_j, of the lists on chain ch for j up to J + 1. */
static void ht_build(hd_plant *p, int ch, int32_t J)
{
    const int l0 = ch == 0 ? 0 : 2, l1 = ch == 0 ? 1 : 2;
    int32_t j, k, l;
    for (j = p->ht_deg[ch] + 1; j <= J; j++) {
        int32_t m;
        for (m = j == 0 ? 0 : j + 1; m <= j + 1; m++) {   /* E_0 with the first degree */
            for (l = l0; l <= l1; l++) {
                const double *t = (m & 1) ? p->hc0[l] : p->hs0[l];  /* sin, cos, -sin, -cos: sign in ht_w */
                double e = 0.0;
                for (k = 0; k < p->hn_int[l]; k++) e += p->ht_w[l][k][m] * t[k];
                p->ht_e[l][m] = e;
                if (m > 0) p->ht_d[l][m - 1] = (double)m * e;
            }
        }
    }
    if (J > p->ht_deg[ch]) p->ht_deg[ch] = J;
}

/* Degree for 0 <= x < HT_XMAX: a table by the binary exponent of x, the degree of the
 * upper end of x's octave (at most one more than the smallest degree for x itself). */
static int32_t ht_degree(const hd_plant *p, double x)
{
    uint64_t b;
    int32_t e;
    memcpy(&b, &x, sizeof b);
    e = (int32_t)(b >> 52) - 1023 + HT_EMIN;        /* x in [2^(e - HT_EMIN), 2^(e - HT_EMIN + 1)) */
    return e < 0 ? 0 : p->ht_jtab[e];
}

/* Horner's scheme for degree J (0..HD_PLANT_HT_JMAX) as straight-line code, three series
 * (a, b, c; c may repeat b) of the same offset d side by side: one jump per evaluation. */
static inline __attribute__((always_inline)) void ht_horner3(const double *a, const double *b, const double *c, int32_t J, double d, double *out)
{
    double ra = a[J], rb = b[J], rc = c[J];
    switch (J) {
    case 10:
        ra = ra * d + a[9]; rb = rb * d + b[9]; rc = rc * d + c[9];
        /* fall through */
    case 9:
        ra = ra * d + a[8]; rb = rb * d + b[8]; rc = rc * d + c[8];
        /* fall through */
    case 8:
        ra = ra * d + a[7]; rb = rb * d + b[7]; rc = rc * d + c[7];
        /* fall through */
    case 7:
        ra = ra * d + a[6]; rb = rb * d + b[6]; rc = rc * d + c[6];
        /* fall through */
    case 6:
        ra = ra * d + a[5]; rb = rb * d + b[5]; rc = rc * d + c[5];
        /* fall through */
    case 5:
        ra = ra * d + a[4]; rb = rb * d + b[4]; rc = rc * d + c[4];
        /* fall through */
    case 4:
        ra = ra * d + a[3]; rb = rb * d + b[3]; rc = rc * d + c[3];
        /* fall through */
    case 3:
        ra = ra * d + a[2]; rb = rb * d + b[2]; rc = rc * d + c[2];
        /* fall through */
    case 2:
        ra = ra * d + a[1]; rb = rb * d + b[1]; rc = rc * d + c[1];
        /* fall through */
    case 1:
        ra = ra * d + a[0]; rb = rb * d + b[0]; rc = rc * d + c[0];
        /* fall through */
    default:
        break;
    }
    out[0] = ra; out[1] = rb; out[2] = rc;
}

/* The sums at theta_m = ha_th[0] + dm, theta_l = ha_th[1] + dl by the series; 0 (nothing
 * written) when an offset is beyond the series' range. */
static int harm_eval_taylor(hd_plant *p, double dm, double dl, double *te, double *de_m, double *de_l,
                            double *tcog)
{
    const double xm = fabs(dm) * p->hmax[0], xl = fabs(dl) * p->hmax[1];
    int32_t Jm, Jl;
    double r0[3], r1[3];
    if (!p->ha_valid || !(xm < HT_XMAX) || !(xl < HT_XMAX)) return 0;
    Jm = ht_degree(p, xm);
    Jl = ht_degree(p, xl);
    if (Jm > p->ht_deg[0]) ht_build(p, 0, Jm);
    if (Jl > p->ht_deg[1]) ht_build(p, 1, Jl);
    ht_horner3(p->ht_e[1], p->ht_d[1], p->ht_e[0], Jm, dm, r0);    /* TE wg, its derivative, cogging */
    ht_horner3(p->ht_e[2], p->ht_d[2], p->ht_d[2], Jl, dl, r1);    /* TE output, its derivative */
    if (p->prm.te_enabled) { *te = r0[0] + r1[0]; *de_m = r0[1]; *de_l = r1[1]; }
    else { *te = 0.0; *de_m = 0.0; *de_l = 0.0; }
    *tcog = p->prm.cogging_enabled ? r0[2] : 0.0;
    return 1;
}

/* Move the anchor to (th_m, th_l): rotate the stored harmonics by n * (new - old), or seed
 * them from libm cos/sin and the power chain (first time, every TRIG_SYNC re-anchorings, or
 * a move beyond the rotation's range).  The coefficients are formed again on demand. */
static void harm_anchor(hd_plant *p, double th_m, double th_l)
{
    const double dm = th_m - p->ha_th[0], dl = th_l - p->ha_th[1];
    int32_t k, l;
    if (p->ha_valid && p->ha_n < TRIG_SYNC && fabs(dm) * p->hmax[0] < ROT_MAX && fabs(dl) * p->hmax[1] < ROT_MAX) {
        for (l = 0; l < 3; l++) {
            const double d = l == 2 ? dl : dm;
            for (k = 0; k < p->hn_int[l]; k++)
                rot_poly(p->hc0[l][k], p->hs0[l][k], p->hfo[l][k] * d, &p->hc0[l][k], &p->hs0[l][k]);
        }
        p->ha_n++;
    } else {
        double de_m, de_l, tcog, cm = cos(th_m), sm = sin(th_m), cl = cos(th_l), sl = sin(th_l);
        (void)harm_eval(p, th_m, cm, sm, th_l, cl, sl, &de_m, &de_l, &tcog, p->hc0, p->hs0);
        p->ha_n = 0;
    }
    p->ha_th[0] = th_m;
    p->ha_th[1] = th_l;
    p->ha_valid = 1;
    p->ht_deg[0] = p->ht_deg[1] = -1;
}

static double cogging_energy(const hd_plant_params *q, double th_m)
{
    double e = 0.0;
    int k;
    if (!q->cogging_enabled) return 0.0;
    for (k = 0; k < HD_PLANT_MAX_HARM; k++)
        if (q->cog_order[k] != 0.0 && q->cog_amp_Nm[k] != 0.0)
            e += q->cog_amp_Nm[k] / q->cog_order[k] * cos(q->cog_order[k] * th_m + q->cog_phase_rad[k]);
    return e;
}

/* exp(-y), y >= 0, for side 0 (motor) / 1 (load): within STRIBECK_DY of the side's
 * anchor ya, exp(-ya) * exp(-(y - ya)) with a Taylor polynomial of the small factor
 * (terms to d^6, truncation < d^7/7! < 5e-17 relative for |d| <= 1/64); else libm,
 * which re-anchors.  The anchor value always comes from libm, so the error stays
 * at about one ulp and does not accumulate; successive RK stages move y by far less
 * than 1/64 while the side turns slowly, which is where the Stribeck curve matters. */
#define STRIBECK_DY 0.015625
static double stribeck_exp(hd_plant *p, int side, double y)
{
    const double d = y - p->fr_ya[side];
    if (d <= STRIBECK_DY && d >= -STRIBECK_DY) {
        /* the same polynomial in Estrin's form (pairs of terms, then d^2 and d^4): shorter
         * dependency chain than Horner's, same truncation */
        const double d2 = d * d, d4 = d2 * d2;
        return p->fr_ea[side] * (((1.0 - d) + d2 * (1.0 / 2.0 - d * (1.0 / 6.0)))
                                 + d4 * ((1.0 / 24.0 - d * (1.0 / 120.0)) + d2 * (1.0 / 720.0)));
    }
    if (y > 700.0) return 0.0;                                   /* avoid the slow underflow path */
    p->fr_ya[side] = y;
    p->fr_ea[side] = exp(-y);
    return p->fr_ea[side];
}

/* Per-side look-up tables of the friction levels in force (p->prm.fric_m / fric_l). */
static void friction_tables(hd_plant *p)
{
    int k;
    for (k = 0; k < 2; k++) {
        const hd_plant_friction_params *f = k == 0 ? &p->prm.fric_m : &p->prm.fric_l;
        p->fr_inv_vs[k] = 1.0 / f->vs_rad_s;
        p->fr_fc[k][0] = f->fc_pos_Nm;
        p->fr_fc[k][1] = f->fc_neg_Nm;
        p->fr_dfs[k][0] = f->fs_pos_Nm - f->fc_pos_Nm;
        p->fr_dfs[k][1] = f->fs_neg_Nm - f->fc_neg_Nm;
    }
    p->fr_v[0] = p->fr_v[1] = NAN;        /* the memoised levels are stale */
}

/* [friction_drift]: scale both sides' levels and viscous term from their initial values
 * to s(t); the cached evaluations of the last period are dropped when s changes. */
static void friction_drift(hd_plant *p)
{
    const hd_plant_params *q = &p->prm;
    const double x = (p->t - q->drift_t_start_s) / q->drift_ramp_s;
    double w = x <= 0.0 ? 0.0 : (x >= 1.0 ? 1.0 : x), s;
    int k;
    if (q->drift_return_s > 0.0) {           /* cold -> warm -> cold: back to 1 after the hold */
        const double y = (p->t - q->drift_t_start_s - q->drift_ramp_s - q->drift_hold_s) / q->drift_return_s;
        if (y > 0.0) w = y >= 1.0 ? 0.0 : 1.0 - y;
    }
    s = 1.0 + (q->drift_scale - 1.0) * w;
    if (s == p->fr_scale) return;
    p->fr_scale = s;
    for (k = 0; k < 2; k++) {
        const hd_plant_friction_params *b = &p->fr_base[k];
        hd_plant_friction_params *f = k == 0 ? &p->prm.fric_m : &p->prm.fric_l;
        f->fc_pos_Nm = b->fc_pos_Nm * s;
        f->fc_neg_Nm = b->fc_neg_Nm * s;
        f->fs_pos_Nm = b->fs_pos_Nm * s;
        f->fs_neg_Nm = b->fs_neg_Nm * s;
        f->viscous_Nms_per_rad = b->viscous_Nms_per_rad * s;
    }
    friction_tables(p);
    p->k1_valid = 0;       /* the end evaluation holds no friction: only the first-stage cache is stale */
}

static double ramp_weight(double t, double t_start_s, double ramp_s)
{
    const double x = (t - t_start_s) / ramp_s;
    return x <= 0.0 ? 0.0 : (x >= 1.0 ? 1.0 : x);
}

/* [inertia_drift], [stiffness_drift], [gravity_drift]: set the drifting parameters from
 * their initial values.  The caches of the last period are kept where they stay right, so
 * that a drift costs no extra evaluation per period: the end evaluation's position part
 * (twist, TE, hysteresis) depends on none of them; the spring torque in it is recomputed
 * when the stiffness changes (and the first-stage cache dropped); the first-stage cache
 * holds no inertia and applies the unbalance in force (k1_from_cache). */
static void param_drift(hd_plant *p)
{
    hd_plant_params *q = &p->prm;
    if (q->jdrift_enabled) {
        const double w = ramp_weight(p->t, q->jdrift_t_start_s, q->jdrift_ramp_s);
        if (w != p->pd_w[0]) {
            p->pd_w[0] = w;
            q->jl_kgm2 = p->pd_jl * (1.0 + (q->jdrift_scale - 1.0) * w);
            p->inv_jl = 1.0 / q->jl_kgm2;
        }
    }
    if (q->kdrift_enabled) {
        const double w = ramp_weight(p->t, q->kdrift_t_start_s, q->kdrift_ramp_s);
        const double s = 1.0 + (q->kdrift_scale - 1.0) * w;
        if (s != p->pd_ks) {
            p->pd_w[1] = w;
            p->pd_ks = s;
            q->k1_Nm_per_rad = p->pd_k[0] * s;   /* slopes and breakpoint torques together: */
            q->k2_Nm_per_rad = p->pd_k[1] * s;   /* phi1, phi2 (twists) are unchanged */
            q->k3_Nm_per_rad = p->pd_k[2] * s;
            q->t1_Nm = p->pd_k[3] * s;
            q->t2_Nm = p->pd_k[4] * s;
            q->cubic_k1_Nm_per_rad = p->pd_cubic[0] * s;
            q->cubic_k3_Nm_per_rad3 = p->pd_cubic[1] * s;
            if (p->end_valid) p->end_Tsh = spring_torque(p, p->end_phi) + p->end_Th;
            p->k1_valid = 0;
        }
    }
    if (q->gdrift_enabled) {
        const double w = ramp_weight(p->t, q->gdrift_t_start_s, q->gdrift_ramp_s);
        if (w != p->pd_w[2]) {
            p->pd_w[2] = w;
            q->mgl_Nm = p->pd_mgl + (q->gdrift_mgl_Nm - p->pd_mgl) * w;
        }
    }
}

/* Stribeck level g(v) > 0 for the direction of v (v == 0: positive side). */
static inline __attribute__((always_inline)) double stribeck_g(hd_plant *p, int side, const hd_plant_friction_params *f, double v)
{
    const int neg = v < 0.0;                 /* table look-up, no branch on the sign */
    const double fc = p->fr_fc[side][neg], dfs = p->fr_dfs[side][neg];
    double r = fabs(v) * p->fr_inv_vs[side], e;
    if (f->delta == 2.0) e = stribeck_exp(p, side, r * r);
    else if (f->delta == 1.0) e = stribeck_exp(p, side, r);
    else { double rp = pow(r, f->delta); e = rp > 700.0 ? 0.0 : exp(-rp); }
    return fc + dfs * e;
}

/* g(v) of side 0 (motor) / 1 (load) and its reciprocal, memoised on the last velocity
 * (the end-of-step evaluation and the next step's first stage share the velocity). */
static inline __attribute__((always_inline)) double stribeck_m(hd_plant *p, int side, const hd_plant_friction_params *f, double v)
{
    if (v != p->fr_v[side]) {
        p->fr_v[side] = v;
        p->fr_g[side] = stribeck_g(p, side, f, v);
        p->fr_ig[side] = 1.0 / p->fr_g[side];
    }
    return p->fr_g[side];
}

/* LuGre: bristle state after time s at constant velocity v, from z0 (ig = 1/g(v)):
 * z0*e^x + v*s*phi1(x), x = -sigma0*|v|*s/g, phi1(x) = expm1(x)/x.  For |x| <= 1/64
 * phi1 by its Taylor series (terms to x^7/8!, truncation < 1e-20; no cancellation and
 * no division), else expm1 (exp when e^x < 0.5, where it is as accurate). */
#define LUGRE_XPOLY 0.015625
static double lugre_z(const hd_plant_friction_params *f, double z0, double v, double s, double ig)
{
    double x, em1;
    if (s == 0.0) return z0;
    x = -f->sigma0_Nm_per_rad * fabs(v) * s * ig;
    if (x >= -LUGRE_XPOLY) {
        /* Estrin's form of the series (pairs of terms, then x^2 and x^4): same terms as
         * Horner's, half the dependency chain */
        const double x2 = x * x, x4 = x2 * x2;
        const double ph = ((1.0 + x * (1.0 / 2.0)) + x2 * (1.0 / 6.0 + x * (1.0 / 24.0)))
                          + x4 * ((1.0 / 120.0 + x * (1.0 / 720.0)) + x2 * (1.0 / 5040.0 + x * (1.0 / 40320.0)));
        return z0 + ph * (x * z0 + v * s);    /* z0 (1 + x ph) + v s ph: ph last on the chain */
    }
    em1 = x < -40.0 ? -1.0 : (x < -0.7 ? exp(x) - 1.0 : expm1(x));
    return z0 * (1.0 + em1) + v * s * (em1 / x);
}

static inline __attribute__((always_inline)) double lugre_force(hd_plant *p, int side, const hd_plant_friction_params *f, double z0, double v, double s)
{
    double z, zf;
    (void)stribeck_m(p, side, f, v);
    /* sigma0 z + sigma1 zd + viscous v with zd = v - sigma0 |v| z / g, as
     * z (sigma0 - sigma1 sigma0 |v| / g) + (sigma1 + viscous) v: the factor of z is formed
     * beside z, so z is one multiply-add from the force (the stages are a chain) */
    zf = f->sigma0_Nm_per_rad - f->sigma1_Nms_per_rad * f->sigma0_Nm_per_rad * fabs(v) * p->fr_ig[side];
    z = lugre_z(f, z0, v, s, p->fr_ig[side]);
    return z * zf + (f->sigma1_Nms_per_rad + f->viscous_Nms_per_rad) * v;
}

/* Friction of a moving (not stuck) side without LuGre. */
static double static_friction(hd_plant *p, int side, const hd_plant_friction_params *f, double v, double applied)
{
    if (v > 0.0) return stribeck_m(p, side, f, v) + f->viscous_Nms_per_rad * v;
    if (v < 0.0) return -stribeck_m(p, side, f, v) + f->viscous_Nms_per_rad * v;
    /* exactly at rest: static friction holds up to the breakaway level */
    if (applied > f->fs_pos_Nm) return f->fs_pos_Nm;
    if (applied < -f->fs_neg_Nm) return -f->fs_neg_Nm;
    return applied;
}

static double breakaway(const hd_plant_friction_params *f, double applied)
{
    return applied >= 0.0 ? f->fs_pos_Nm : f->fs_neg_Nm;
}

/* ---- derivative evaluation ---------------------------------------------------------- */
typedef struct { double th_m, w_m, th_l, w_l; } xstate;

typedef struct {           /* constants of one sub-step */
    double t0, h, inv_h;
    double tq_m;           /* Kt * mean current */
    double t_ext;          /* external load torque */
    double base_ext_angle0, base_ext_rate, base_ext_accel;
    double bth[3], bw[3], ba[3];   /* base angle, rate, accel at s = 0, h/2, h */
    double gc[3], gs[3];           /* cos/sin(base angle + gravity offset) */
} substep_ctx;

typedef struct {           /* diagnostics of one evaluation */
    double phi, te, T, Th, Fm, Fl, Tcog, Tg, appl_m, appl_l, th_b, w_b;
    double rest_m, rest_l;         /* applied torques without the motor torque, external load, base inertia
                                      (and, on the load side, gravity) */
    double gf;                     /* gravity torque per unit unbalance: T_grav = -mgl * gf */
} eval_diag;

typedef struct {           /* the velocity-independent part of one evaluation */
    double phi, te, de_m, de_l, Tsh, Th, Tcog, cl, sl;
} pos_part;

/* base motion at s = 0, h/2, h of the sub-step: one sin/cos of the generator phase at
 * s = 0, the later points by rotation with cos/sin(om h/2) (cached per h); gravity's
 * cos/sin(base angle + offset) at s = 0 by libm, later points by a small rotation. */
static void base_cache(hd_plant *p, substep_ctx *c)
{
    const hd_plant_params *q = &p->prm;
    int k;
    for (k = 0; k < 3; k++) {
        c->bth[k] = c->base_ext_angle0 + c->base_ext_rate * (0.5 * c->h * (double)k);
        c->bw[k] = c->base_ext_rate;
        c->ba[k] = c->base_ext_accel;
    }
    if (q->base_enabled && q->base_amp_rad != 0.0) {
        double om = TWO_PI * q->base_freq_Hz, arg = om * c->t0 + q->base_phase_rad;
        double sn, cs, A = q->base_amp_rad;
        if (p->trig_n != 0 && c->t0 == p->base_t && c->h == p->base_h) {
            /* continues the last sub-step: rotate its phase by om h (one ulp per step,
             * refreshed from libm with the angles every TRIG_SYNC sub-steps) */
            sn = p->base_s * p->k_rot2_c + p->base_c * p->k_rot2_s;
            cs = p->base_c * p->k_rot2_c - p->base_s * p->k_rot2_s;
        } else {
            sn = sin(arg);
            cs = cos(arg);
        }
        p->base_t = c->t0 + c->h;         /* the next sub-step's start (p->t += h) */
        p->base_h = c->h; p->base_c = cs; p->base_s = sn;
        for (k = 0; k < 3; k++) {
            double t;
            c->bth[k] += A * sn;
            c->bw[k] += A * om * cs;
            c->ba[k] -= A * om * om * sn;
            t = cs * p->k_rot_c - sn * p->k_rot_s;
            sn = sn * p->k_rot_c + cs * p->k_rot_s;
            cs = t;
        }
    }
    if (q->gravity_enabled) {
        double a0 = c->bth[0] + q->gravity_offset_rad;
        if (p->trig_n != 0 && fabs(a0 - p->grav_a) < 0.1) {
            rot_small(p->grav_c, p->grav_s, a0, a0 - p->grav_a, &c->gc[0], &c->gs[0]);
        } else {
            c->gc[0] = cos(a0);
            c->gs[0] = sin(a0);
        }
        p->grav_a = a0; p->grav_c = c->gc[0]; p->grav_s = c->gs[0];
        for (k = 1; k < 3; k++)
            rot_small(c->gc[0], c->gs[0], c->bth[k] + q->gravity_offset_rad, c->bth[k] - c->bth[0], &c->gc[k], &c->gs[k]);
    } else {
        for (k = 0; k < 3; k++) { c->gc[k] = 1.0; c->gs[k] = 0.0; }
    }
}

static int need_trig_m(const hd_plant_params *q) { return q->te_enabled || q->cogging_enabled; }
static int need_trig_l(const hd_plant *p) { return (p->prm.te_enabled && p->has_te_out) || p->prm.gravity_enabled; }

/* The hysteresis torque of the committed memory (Maxwell-slip elements at xi, Preisach
 * memory pz) is, as a function of the twist, continuous and piecewise linear: each element
 * is linear or saturated, P_mean is linear in a grid cell, and the Preisach output is linear
 * while its moving argument stays in one Everett cell and wipes out no extremum.  From the
 * end evaluation's twist phi (torque end_Th) this finds, per direction (0 up, 1 down), the
 * slope and the twist up to which it holds, so that a stage inside that piece needs one
 * multiply-add instead of the operators (the same function; rounding differs by an ulp or so). */
static void hyst_piece(hd_plant *p, int dir)
{
    const hd_plant_params *q = &p->prm;
    const double phi = p->end_phi;
    double sl = 0.0, bd = dir == 0 ? INFINITY : -INFINITY, b;
    int k;
    if (!isfinite(phi)) {                          /* no piece: every stage takes the operators */
        p->hy_s[dir] = 0.0;
        p->hy_b[dir] = dir == 0 ? -INFINITY : INFINITY;
        p->hy_ok[dir] = 1;
        return;
    }
    if (q->maxwell_enabled) {
        for (k = 0; k < q->maxwell_n; k++) {
            const double kk = q->maxwell_k_Nm_per_rad[k], w = q->maxwell_w_Nm[k], xi = p->xi[k];
            double v;
            if (kk <= 0.0) continue;
            v = kk * (phi - xi);
            if (dir == 0 && v < w) {               /* up: linear until +w, or saturated at -w until -w */
                if (v >= -w) sl += kk;
                b = v >= -w ? xi + p->mx_slip[k] : xi - p->mx_slip[k];
                if (b < bd) bd = b;
            } else if (dir == 1 && v > -w) {       /* down: linear until -w, or saturated at +w until +w */
                if (v <= w) sl += kk;
                b = v <= w ? xi - p->mx_slip[k] : xi + p->mx_slip[k];
                if (b > bd) bd = b;
            }
        }
    }
    if (q->preisach_enabled) {
        const double M = q->preisach_u_max_rad, inv = p->preisach_inv_du;
        if (phi >= M || phi <= -M) {                /* saturated: P_mean and P constant beyond +-M */
            if (dir == 0 && phi < 0.0 && -M < bd) bd = -M;
            if (dir == 1 && phi > 0.0 && M > bd) bd = M;
        } else {
            const double x = (phi + M) * inv;
            double sp;
            int32_t i = dir == 0 ? (int32_t)floor(x) : (int32_t)ceil(x) - 1;   /* P_mean's cell */
            if (i > HD_PLANT_PREISACH_L - 1) i = HD_PLANT_PREISACH_L - 1;
            if (i < 0) i = 0;
            sl += (p->preisach_pm[i + 1] - p->preisach_pm[i]) * inv;
            b = -M + (double)(dir == 0 ? i + 1 : i) / inv;
            if (dir == 0 ? b < bd : b > bd) bd = b;
            hd_plant_preisach_piece(&p->pz, p->everett, M, dir == 0 ? 1 : -1, &sp, &b);
            sl -= sp;
            if (dir == 0 ? b < bd : b > bd) bd = b;
        }
    }
    p->hy_s[dir] = sl;
    p->hy_b[dir] = bd;
    p->hy_ok[dir] = 1;
}

/* Spring + hysteresis (from the committed memory) at angles x, with TE and cogging
 * already in pp (te, de_m, de_l, Tcog) and cos/sin of theta_l (cl, sl).  p is written only
 * to form the hysteresis piece of the committed memory on its first use (hyst_piece). */
static void pos_eval(hd_plant *p, const xstate *x, double cl, double sl, pos_part *pp)
{
    const hd_plant_params *q = &p->prm;
    double Th = 0.0, phi;
    int dir;
    phi = x->th_m * p->inv_ratio + pp->te - x->th_l;
    pp->phi = phi;
    dir = phi >= p->end_phi ? 0 : 1;
    if (p->hy_lin_ok && !p->hy_ok[dir]) hyst_piece(p, dir);
    if (p->hy_lin_ok && (dir == 0 ? phi <= p->hy_b[0] : phi >= p->hy_b[1])) {
        /* within the linear piece of the committed memory (hyst_piece) */
        Th = p->end_Th + p->hy_s[dir] * (phi - p->end_phi);
        p->n_hy_lin++;
    } else {
        if (q->maxwell_enabled) {
            int k;
            for (k = 0; k < q->maxwell_n; k++)
                Th += sat(q->maxwell_k_Nm_per_rad[k] * (phi - p->xi[k]), q->maxwell_w_Nm[k]);
        }
        if (q->preisach_enabled) /* P_mean(phi) - P[phi]: purely hysteretic, dissipative, zero net torque at saturation */
            Th += preisach_mean(p, q, phi)
                  - hd_plant_preisach_eval(&p->pz, p->everett, q->preisach_u_max_rad, phi, NULL);
    }
    pp->Th = Th;
    pp->Tsh = spring_torque(p, phi) + Th;
    pp->cl = cl;
    pp->sl = sl;
}

/* Accelerations from the position part, the velocities and the sub-step constants. */
/* s: time into the sub-step (bristles), bi: base-motion point (0, h/2, h). */
static void accel_eval(hd_plant *p, const substep_ctx *c, double s, int bi, const xstate *x, const pos_part *pp,
                       xstate *dx, eval_diag *dg)
{
    const hd_plant_params *q = &p->prm;
    double T = pp->Tsh, Fm = 0.0, Fl = 0.0, Tg = 0.0, gf = 0.0, appl_m, appl_l, rest_m, rest_l, rest_l0, a_b;
    const double invN = p->inv_ratio;
    a_b = c->ba[bi];
    if (q->stiffness_enabled || q->cubic_enabled)
        T += q->damping_Nms_per_rad * (x->w_m * (invN + pp->de_m) + x->w_l * (pp->de_l - 1.0));
    /* cos(theta_l + theta_b + offset) by angle addition with the cached cos/sin of theta_b + offset */
    if (q->gravity_enabled) { gf = pp->cl * c->gc[bi] - pp->sl * c->gs[bi]; Tg = -q->mgl_Nm * gf; }

    rest_m = pp->Tcog - T * (invN + pp->de_m);
    rest_l0 = T * (1.0 - pp->de_l);
    rest_l = rest_l0 + Tg;
    appl_m = c->tq_m + rest_m - q->jm_kgm2 * a_b;
    appl_l = rest_l + c->t_ext - q->jl_kgm2 * a_b;

    /* motor side */
    if (q->fric_m.enabled) {
        if (q->fric_m.lugre_enabled) Fm = lugre_force(p, 0, &q->fric_m, p->z_m, x->w_m, s);
        else if (p->stuck_m) Fm = appl_m;
        else Fm = static_friction(p, 0, &q->fric_m, x->w_m, appl_m);
    }
    if (q->fric_m.enabled && !q->fric_m.lugre_enabled && p->stuck_m) {
        dx->th_m = 0.0; dx->w_m = 0.0;
    } else {
        dx->th_m = x->w_m;
        dx->w_m = (appl_m - Fm) * p->inv_jm;
    }
    /* load side */
    if (p->brake) {
        dx->th_l = 0.0; dx->w_l = 0.0;
    } else {
        if (q->fric_l.enabled) {
            if (q->fric_l.lugre_enabled) Fl = lugre_force(p, 1, &q->fric_l, p->z_l, x->w_l, s);
            else if (p->stuck_l) Fl = appl_l;
            else Fl = static_friction(p, 1, &q->fric_l, x->w_l, appl_l);
        }
        if (q->fric_l.enabled && !q->fric_l.lugre_enabled && p->stuck_l) {
            dx->th_l = 0.0; dx->w_l = 0.0;
        } else {
            dx->th_l = x->w_l;
            dx->w_l = (appl_l - Fl) * p->inv_jl;
        }
    }
    if (dg != NULL) {
        dg->phi = pp->phi; dg->te = pp->te; dg->T = T; dg->Th = pp->Th; dg->Fm = Fm; dg->Fl = Fl;
        dg->Tcog = pp->Tcog; dg->Tg = Tg; dg->appl_m = appl_m; dg->appl_l = appl_l;
        dg->th_b = c->bth[bi]; dg->w_b = c->bw[bi];
        dg->rest_m = rest_m; dg->rest_l = rest_l0; dg->gf = gf;
    }
}

/* One stage at xt, trig by a small rotation from the sub-step start x0 (cos/sin c0m.. there). */
static void stage(hd_plant *p, const substep_ctx *c, double s, const xstate *x0, const xstate *xt,
                  const double *t0, xstate *dx, eval_diag *dg)
{
    double cm = 1.0, sm = 0.0, cl = 1.0, sl = 0.0;
    const double dm = xt->th_m - x0->th_m, dl = xt->th_l - x0->th_l;
    pos_part pp;
    if (need_trig_l(p)) rot_small(t0[2], t0[3], xt->th_l, dl, &cl, &sl);
    if (!p->h_rot_ok || p->h_libm
        || !harm_eval_taylor(p, xt->th_m - p->ha_th[0], xt->th_l - p->ha_th[1], &pp.te, &pp.de_m, &pp.de_l, &pp.Tcog)) {
        if (need_trig_m(&p->prm)) rot_small(t0[0], t0[1], xt->th_m, dm, &cm, &sm);
        pp.te = harm_eval(p, xt->th_m, cm, sm, xt->th_l, cl, sl, &pp.de_m, &pp.de_l, &pp.Tcog, NULL, NULL);
    }
    pos_eval(p, xt, cl, sl, &pp);
    accel_eval(p, c, s, s < c->h ? 1 : 2, xt, &pp, dx, dg);
}

/* Evaluate the end-of-sub-step state (libm trig), commit the hysteresis memory with
 * its twist, and cache the position part for diagnostics and the next first stage. */
static void end_eval(hd_plant *p)
{
    const hd_plant_params *q = &p->prm;
    xstate x = { p->th_m, p->w_m, p->th_l, p->w_l };
    double cm = 1.0, sm = 0.0, cl = 1.0, sl = 0.0, de_m, de_l, te, phi, Th = 0.0;
    int k, rotated = 0;
    p->n_end_eval++;
    /* cos/sin at the end of the sub-step: a small rotation from the start (the last end
     * evaluation), refreshed from libm every TRIG_SYNC evaluations so that rounding
     * cannot accumulate (each rotation is good to about one ulp); the harmonics by their
     * series about the anchor (harm_eval_taylor) */
    if (p->end_valid && p->trig_n < TRIG_SYNC) {
        const double dm = x.th_m - p->end_th_m, dl = x.th_l - p->end_th_l;
        if (need_trig_m(q)) rot_small(p->end_cm, p->end_sm, x.th_m, dm, &cm, &sm);
        if (need_trig_l(p)) rot_small(p->end_cl, p->end_sl, x.th_l, dl, &cl, &sl);
        p->trig_n++;
    } else {
        if (need_trig_m(q)) { cm = cos(x.th_m); sm = sin(x.th_m); }
        if (need_trig_l(p)) { cl = cos(x.th_l); sl = sin(x.th_l); }
        p->trig_n = 0;
    }
    if (p->h_rot_ok && !p->h_libm) {
        /* TE and cogging by the series about the anchor, moved here when beyond its radius */
        const double ra = p->ht_xb[HT_JANCHOR];
        if (!p->ha_valid || fabs(x.th_m - p->ha_th[0]) * p->hmax[0] > ra || fabs(x.th_l - p->ha_th[1]) * p->hmax[1] > ra)
            harm_anchor(p, x.th_m, x.th_l);
        rotated = harm_eval_taylor(p, x.th_m - p->ha_th[0], x.th_l - p->ha_th[1], &te, &de_m, &de_l, &p->end_Tcog);
    }
    if (!rotated) te = harm_eval(p, x.th_m, cm, sm, x.th_l, cl, sl, &de_m, &de_l, &p->end_Tcog, NULL, NULL);
    phi = x.th_m * p->inv_ratio + te - x.th_l;
    if (q->maxwell_enabled) {
        for (k = 0; k < q->maxwell_n; k++) {
            double kk = q->maxwell_k_Nm_per_rad[k], w = q->maxwell_w_Nm[k];
            if (kk <= 0.0) continue;
            if (kk * (phi - p->xi[k]) > w) p->xi[k] = phi - p->mx_slip[k];
            else if (kk * (phi - p->xi[k]) < -w) p->xi[k] = phi + p->mx_slip[k];
        }
        for (k = 0; k < q->maxwell_n; k++)
            Th += sat(q->maxwell_k_Nm_per_rad[k] * (phi - p->xi[k]), q->maxwell_w_Nm[k]);
    }
    if (q->preisach_enabled)
        Th += preisach_mean(p, q, phi)
              - hd_plant_preisach_eval(&p->pz, p->everett, q->preisach_u_max_rad, phi, &p->pz);
    p->end_th_m = x.th_m; p->end_th_l = x.th_l;
    p->end_phi = phi; p->end_te = te; p->end_de_m = de_m; p->end_de_l = de_l;
    p->end_Th = Th;
    p->end_Tsh = spring_torque(p, phi) + Th;
    p->hy_ok[0] = p->hy_ok[1] = 0;             /* pieces formed when a stage first needs one */
    p->end_cm = cm; p->end_sm = sm; p->end_cl = cl; p->end_sl = sl;
    p->end_valid = 1;
}

static int end_current(const hd_plant *p)
{
    return p->end_valid && p->end_th_m == p->th_m && p->end_th_l == p->th_l;
}

static void end_part(const hd_plant *p, pos_part *pp)
{
    pp->phi = p->end_phi; pp->te = p->end_te; pp->de_m = p->end_de_m; pp->de_l = p->end_de_l;
    pp->Tsh = p->end_Tsh; pp->Th = p->end_Th; pp->Tcog = p->end_Tcog; pp->cl = p->end_cl; pp->sl = p->end_sl;
}

/* First stage of a period's first sub-step from the end-of-period evaluation that
 * hd_plant_step made for its outputs at the same state (same angles, velocities,
 * bristles and committed hysteresis memory): only the motor torque, the external load
 * and the base acceleration of the new period are applied again.  Not used with the
 * static friction map, whose force depends on the applied torque (sticking). */
static int k1_cached(const hd_plant *p, const xstate *x)
{
    return p->k1_valid && p->k1_ok && end_current(p) && p->k1_w_m == x->w_m && p->k1_w_l == x->w_l
           && p->k1_brake == p->brake;
}

static void k1_from_cache(const hd_plant *p, const substep_ctx *c, const xstate *x, xstate *dx)
{
    const hd_plant_params *q = &p->prm;
    const double a_b = c->ba[0];
    const double appl_m = c->tq_m + p->k1_rest_m - q->jm_kgm2 * a_b;
    const double Tg = q->gravity_enabled ? -q->mgl_Nm * p->k1_gf : 0.0;   /* the unbalance in force */
    const double appl_l = (p->k1_rest_l + Tg) + c->t_ext - q->jl_kgm2 * a_b;
    dx->th_m = x->w_m;
    dx->w_m = (appl_m - p->k1_Fm) * p->inv_jm;
    if (p->brake) {
        dx->th_l = 0.0; dx->w_l = 0.0;
    } else {
        dx->th_l = x->w_l;
        dx->w_l = (appl_l - p->k1_Fl) * p->inv_jl;
    }
}

static void axpy(xstate *o, const xstate *x, double a, const xstate *d)
{
    o->th_m = x->th_m + a * d->th_m;
    o->w_m = x->w_m + a * d->w_m;
    o->th_l = x->th_l + a * d->th_l;
    o->w_l = x->w_l + a * d->w_l;
}

static void stick_update(const hd_plant_friction_params *f, int32_t *stuck, double v0, double *v1, double applied)
{
    if (!f->enabled || f->lugre_enabled) { *stuck = 0; return; }
    if (*stuck) {
        if (fabs(applied) > breakaway(f, applied)) *stuck = 0;
        return;
    }
    if ((v0 * *v1 <= 0.0 || fabs(*v1) < f->stick_velocity_rad_s) && fabs(applied) <= breakaway(f, applied)) {
        *stuck = 1;
        *v1 = 0.0;
    }
}

static void substep(hd_plant *p, const substep_ctx *c)
{
    const hd_plant_params *q = &p->prm;
    xstate x0 = { p->th_m, p->w_m, p->th_l, p->w_l }, k1, k2, k3, k4, xt;
    eval_diag dg;
    pos_part pp;
    double h = c->h, t0[4];

    if (!end_current(p)) end_eval(p);      /* first call, or the state was placed from outside */
    end_part(p, &pp);
    t0[0] = p->end_cm; t0[1] = p->end_sm; t0[2] = p->end_cl; t0[3] = p->end_sl;
    if (k1_cached(p, &x0)) k1_from_cache(p, c, &x0, &k1);
    else accel_eval(p, c, 0.0, 0, &x0, &pp, &k1, NULL);
    p->k1_valid = 0;
    axpy(&xt, &x0, 0.5 * h, &k1);
    stage(p, c, 0.5 * h, &x0, &xt, t0, &k2, NULL);
    axpy(&xt, &x0, 0.5 * h, &k2);
    stage(p, c, 0.5 * h, &x0, &xt, t0, &k3, NULL);
    axpy(&xt, &x0, h, &k3);
    stage(p, c, h, &x0, &xt, t0, &k4, &dg);
    p->th_m = x0.th_m + h / 6.0 * (k1.th_m + 2.0 * k2.th_m + 2.0 * k3.th_m + k4.th_m);
    p->w_m = x0.w_m + h / 6.0 * (k1.w_m + 2.0 * k2.w_m + 2.0 * k3.w_m + k4.w_m);
    p->th_l = x0.th_l + h / 6.0 * (k1.th_l + 2.0 * k2.th_l + 2.0 * k3.th_l + k4.th_l);
    p->w_l = x0.w_l + h / 6.0 * (k1.w_l + 2.0 * k2.w_l + 2.0 * k3.w_l + k4.w_l);

    /* LuGre bristles: exponential update with the mean velocity of the sub-step */
    if (q->fric_m.enabled && q->fric_m.lugre_enabled)
        { double v = (p->th_m - x0.th_m) * c->inv_h; (void)stribeck_m(p, 0, &q->fric_m, v);
          p->z_m = lugre_z(&q->fric_m, p->z_m, v, h, p->fr_ig[0]); }
    if (q->fric_l.enabled && q->fric_l.lugre_enabled && !p->brake)
        { double v = (p->th_l - x0.th_l) * c->inv_h; (void)stribeck_m(p, 1, &q->fric_l, v);
          p->z_l = lugre_z(&q->fric_l, p->z_l, v, h, p->fr_ig[1]); }

    /* stick/slip of the static friction model (applied torque at the end of the step) */
    stick_update(&q->fric_m, &p->stuck_m, x0.w_m, &p->w_m, dg.appl_m);
    if (!p->brake) stick_update(&q->fric_l, &p->stuck_l, x0.w_l, &p->w_l, dg.appl_l);

    /* commit the hysteresis memory with the end-of-step twist, cache the end evaluation */
    end_eval(p);
}

/* ---- public API ---------------------------------------------------------------------- */
int hd_plant_init(hd_plant *p, const hd_plant_params *prm, uint64_t seed, char *msg, size_t msg_len)
{
    int rc = hd_plant_check(prm, msg, msg_len);
    uint64_t sm = seed;
    int k;
    if (rc != HD_PLANT_OK) return rc;
    memset(p, 0, sizeof *p);
    p->prm = *prm;
    if (prm->stiffness_enabled) {
        p->phi1 = prm->t1_Nm / prm->k1_Nm_per_rad;
        p->phi2 = p->phi1 + (prm->t2_Nm - prm->t1_Nm) / prm->k2_Nm_per_rad;
    }
    p->tau_i = 1.0 / (TWO_PI * prm->current_bandwidth_Hz);
    p->inv_ratio = 1.0 / prm->ratio;      /* the RK stages multiply, they do not divide */
    p->inv_jm = 1.0 / prm->jm_kgm2;
    for (k = 0; k < HD_PLANT_MAX_MAXWELL; k++)      /* slip deflection w/k of each element */
        p->mx_slip[k] = prm->maxwell_k_Nm_per_rad[k] > 0.0 ? prm->maxwell_w_Nm[k] / prm->maxwell_k_Nm_per_rad[k] : 0.0;
    p->inv_jl = 1.0 / prm->jl_kgm2;
    for (k = 0; k < HD_PLANT_MAX_HARM; k++) {
        int l;
        const double *ord[3], *ph[3];
        ord[0] = prm->cog_order; ord[1] = prm->te_wg_order; ord[2] = prm->te_out_order;
        ph[0] = prm->cog_phase_rad; ph[1] = prm->te_wg_phase_rad; ph[2] = prm->te_out_phase_rad;
        for (l = 0; l < 3; l++) {
            p->harm_int[l][k] = ord[l][k] == floor(ord[l][k]) && ord[l][k] <= 4096.0;
            p->harm_cp[l][k] = cos(ph[l][k]);
            p->harm_sp[l][k] = sin(ph[l][k]);
        }
        if (prm->te_out_order[k] != 0.0 && prm->te_out_amp_rad[k] != 0.0) p->has_te_out = 1;
    }
    harm_plan(p);
    p->h_rot_ok = 1;
    p->hy_lin_ok = 1;
    if (prm->preisach_enabled) {
        hd_plant_preisach_everett(p->everett, prm->preisach_u_max_rad, prm->preisach_t_sat_Nm,
                            prm->preisach_r0_rad, prm->preisach_s_rad);
        hd_plant_preisach_reset(&p->pz, p->everett, prm->preisach_u_max_rad);
        p->preisach_kp = prm->preisach_t_sat_Nm / prm->preisach_u_max_rad;
        pmean_table(p);
    }
    for (k = 0; k < 4; k++) p->rng[k] = splitmix64(&sm);
    zig_init(p->zig_x, p->zig_r);
    p->faults.current_limit_A = -1.0;
    p->enc_last[0] = p->enc_last[1] = 0;
    p->enc_scale[0] = ldexp(1.0, prm->enc_m_bits);
    p->enc_scale[1] = ldexp(1.0, prm->enc_l_bits);
    p->fr_v[0] = p->fr_v[1] = NAN;        /* no memoised friction level yet */
    p->fr_ya[0] = p->fr_ya[1] = 0.0;      /* Stribeck exponential anchors: exp(-0) = 1 */
    p->fr_ea[0] = p->fr_ea[1] = 1.0;
    p->fr_base[0] = prm->fric_m;
    p->fr_base[1] = prm->fric_l;
    p->fr_scale = 1.0;
    p->pd_ks = 1.0;
    friction_tables(p);
    p->pd_jl = prm->jl_kgm2;
    p->pd_k[0] = prm->k1_Nm_per_rad; p->pd_k[1] = prm->k2_Nm_per_rad; p->pd_k[2] = prm->k3_Nm_per_rad;
    p->pd_k[3] = prm->t1_Nm; p->pd_k[4] = prm->t2_Nm;
    p->pd_cubic[0] = prm->cubic_k1_Nm_per_rad; p->pd_cubic[1] = prm->cubic_k3_Nm_per_rad3;
    p->pd_mgl = prm->gravity_enabled ? prm->mgl_Nm : 0.0;
    if (prm->gdrift_enabled && !prm->gravity_enabled) {   /* the unbalance appears from zero */
        p->prm.gravity_enabled = 1;
        p->prm.mgl_Nm = 0.0;
    }
    p->k_dt = 0.0;
    p->end_valid = 0;
    p->k1_valid = 0;
    p->k1_ok = !(prm->fric_m.enabled && !prm->fric_m.lugre_enabled) && !(prm->fric_l.enabled && !prm->fric_l.lugre_enabled);
    return HD_PLANT_OK;
}

void hd_plant_set_state(hd_plant *p, double th_m, double w_m, double th_l, double w_l)
{
    double de_m, de_l, phi;
    int k;
    p->th_m = th_m; p->w_m = w_m; p->th_l = th_l; p->w_l = w_l;
    p->stuck_m = p->stuck_l = 0;
    /* hysteresis memory: elements relaxed at the new twist */
    phi = th_m * p->inv_ratio + te_eval1(p, th_m, th_l, &de_m, &de_l) - th_l;
    for (k = 0; k < HD_PLANT_MAX_MAXWELL; k++) p->xi[k] = phi;
    p->end_valid = 0;
}

double hd_plant_energy(const hd_plant *p)
{
    const hd_plant_params *q = &p->prm;
    double de_m, de_l;
    double phi = p->th_m * p->inv_ratio + te_eval1(p, p->th_m, p->th_l, &de_m, &de_l) - p->th_l;
    double e = 0.5 * q->jm_kgm2 * p->w_m * p->w_m + 0.5 * q->jl_kgm2 * p->w_l * p->w_l;
    e += spring_energy(p, phi);
    e += cogging_energy(q, p->th_m);   /* T_cog = -dV/dtheta, V = sum a/n cos(...) */
    if (q->gravity_enabled) e += q->mgl_Nm * sin(p->th_l + q->gravity_offset_rad);
    return e;
}

static int64_t floor_i64(double x)
{
    double f = floor(x);
    if (isnan(f)) return 0;           /* diverged plant: no count (NaN -> integer is undefined) */
    if (f > 9.0e18) return INT64_MAX;
    if (f < -9.0e18) return INT64_MIN;
    return (int64_t)f;
}

static void encoder(hd_plant *p, int id, double angle_rad, int enabled, int bits, double noise, double offset,
                    uint32_t *raw, int64_t *count, int *valid)
{
    double x = (angle_rad / TWO_PI + offset) * p->enc_scale[id];
    int64_t c;
    if (enabled && noise > 0.0) x += noise * rng_gauss(p);
    c = floor_i64(x);
    if (p->faults.glitch_counts[id] != 0) {
        c += p->faults.glitch_counts[id];
        p->faults.glitch_counts[id] = 0;
    }
    if (p->faults.dropout_steps[id] > 0) {
        p->faults.dropout_steps[id]--;
        c = p->enc_last[id];
        *valid = 0;
    } else {
        *valid = 1;
        p->enc_last[id] = c;
    }
    *count = c;
    *raw = (uint32_t)((uint64_t)c & (((uint64_t)1 << bits) - 1u));   /* c mod 2^bits */
}

/* constants that depend on the period only (recomputed when dt changes) */
static void period_constants(hd_plant *p, double dt_s)
{
    const hd_plant_params *q = &p->prm;
    double h = dt_s / (double)q->substeps;
    p->k_dt = dt_s;
    p->k_h = h;
    p->k_inv_h = 1.0 / h;
    p->k_E = q->current_loop_enabled ? exp(-h / p->tau_i) : 0.0;
    p->k_Efac = (p->tau_i / h) * (1.0 - p->k_E);
    p->k_gyro_a = -expm1(-dt_s * TWO_PI * q->gyro_bandwidth_Hz);
    p->k_gyro_sd = q->gyro_noise_rad_s_per_rtHz / sqrt(dt_s);
    p->k_rot_c = cos(TWO_PI * q->base_freq_Hz * 0.5 * h);
    p->k_rot_s = sin(TWO_PI * q->base_freq_Hz * 0.5 * h);
    p->k_rot2_c = cos(TWO_PI * q->base_freq_Hz * h);
    p->k_rot2_s = sin(TWO_PI * q->base_freq_Hz * h);
}

const hd_plant_output *hd_plant_step(hd_plant *p, const hd_plant_input *in, double dt_s)
{
    const hd_plant_params *q = &p->prm;
    hd_plant_output *o = &p->out;
    substep_ctx c;
    xstate x, dx;
    eval_diag dg;
    pos_part pp;
    double icmd, lim, h, E;
    int n = q->substeps, k;

    if (!(dt_s > 0.0)) return o;
    /* once the state is not finite nothing meaningful can follow: hold the diverged
     * output (the harness reports the divergence) instead of integrating NaN */
    if (p->diverged) return o;
    if (dt_s != p->k_dt) period_constants(p, dt_s);
    if (q->drift_enabled) friction_drift(p);
    if (q->jdrift_enabled || q->kdrift_enabled || q->gdrift_enabled) param_drift(p);
    h = p->k_h;
    E = p->k_E;
    icmd = in->current_cmd_A + in->torque_cmd_Nm / q->kt_Nm_per_A;
    lim = q->current_peak_A;
    if (p->faults.current_limit_A >= 0.0 && p->faults.current_limit_A < lim) lim = p->faults.current_limit_A;
    o->current_saturated = fabs(icmd) > lim;
    icmd = sat(icmd, lim);

    c.h = h;
    c.inv_h = p->k_inv_h;
    c.t_ext = in->load_torque_Nm + p->faults.load_step_Nm;
    c.base_ext_rate = in->base_rate_rad_s;
    c.base_ext_accel = in->base_accel_rad_s2;
    for (k = 0; k < n; k++) {
        double iavg;
        if (q->current_loop_enabled) {
            double d = p->i - icmd;
            iavg = icmd + d * p->k_Efac;
            p->i = icmd + d * E;
        } else {
            iavg = icmd;
            p->i = icmd;
        }
        c.t0 = p->t;
        c.tq_m = q->kt_Nm_per_A * iavg;
        c.base_ext_angle0 = p->base_ext_angle;
        base_cache(p, &c);
        substep(p, &c);
        p->base_ext_angle += in->base_rate_rad_s * h;
        p->t += h;
    }

    if (!(isfinite(p->th_m) && isfinite(p->w_m) && isfinite(p->th_l) && isfinite(p->w_l) && isfinite(p->i)
          && isfinite(p->z_m) && isfinite(p->z_l)))
        p->diverged = 1;

    /* diagnostics at the end of the period: the cached end evaluation (base motion at
     * the end of the last sub-step), motor torque from the end current */
    x.th_m = p->th_m; x.w_m = p->w_m; x.th_l = p->th_l; x.w_l = p->w_l;
    c.tq_m = q->kt_Nm_per_A * p->i;
    if (!end_current(p)) end_eval(p);
    end_part(p, &pp);
    accel_eval(p, &c, 0.0, 2, &x, &pp, &dx, &dg);   /* bristles as committed; base at the end (point 2) */
    p->k1_valid = 1;                                  /* the next period's first stage starts from here */
    p->k1_rest_m = dg.rest_m; p->k1_rest_l = dg.rest_l; p->k1_gf = dg.gf; p->k1_Fm = dg.Fm; p->k1_Fl = dg.Fl;
    p->k1_w_m = x.w_m; p->k1_w_l = x.w_l; p->k1_brake = p->brake;

    o->t_s = p->t;
    o->motor_angle_rad = p->th_m;
    o->motor_velocity_rad_s = p->w_m;
    o->load_angle_rad = p->th_l;
    o->load_velocity_rad_s = p->w_l;
    o->base_angle_rad = dg.th_b;
    o->base_rate_rad_s = dg.w_b;
    o->load_inertial_rate_rad_s = p->w_l + dg.w_b;
    o->current_A = p->i;
    o->motor_torque_Nm = q->kt_Nm_per_A * p->i;
    o->twist_rad = dg.phi;
    o->te_rad = dg.te;
    o->transmitted_torque_Nm = dg.T;
    o->hysteresis_torque_Nm = dg.Th;
    o->friction_motor_Nm = dg.Fm;
    o->friction_load_Nm = dg.Fl;
    o->cogging_torque_Nm = dg.Tcog;
    o->gravity_torque_Nm = dg.Tg;
    o->brake_engaged = p->brake != 0;

    /* sensors */
    encoder(p, 0, p->th_m, q->enc_m_enabled, q->enc_m_bits, q->enc_m_noise_counts, q->enc_m_offset_turn,
            &o->enc_motor_raw, &o->enc_motor_count, &o->enc_motor_valid);
    encoder(p, 1, p->th_l, q->enc_l_enabled, q->enc_l_bits, q->enc_l_noise_counts, q->enc_l_offset_turn,
            &o->enc_load_raw, &o->enc_load_count, &o->enc_load_valid);
    o->current_meas_A = p->i;
    if (q->isense_enabled) o->current_meas_A += q->isense_offset_A + q->isense_noise_A * rng_gauss(p);
    if (q->gyro_enabled) {
        double meas = o->load_inertial_rate_rad_s + q->gyro_bias_rad_s + p->k_gyro_sd * rng_gauss(p);
        p->gyro_f += p->k_gyro_a * (meas - p->gyro_f);
        o->gyro_rad_s = p->gyro_f;
    } else {
        p->gyro_f = o->load_inertial_rate_rad_s;
        o->gyro_rad_s = p->gyro_f;
    }
    return o;
}

int hd_plant_diverged(const hd_plant *p)
{
    return p->diverged != 0;
}

void hd_plant_set_brake(hd_plant *p, int engaged)
{
    p->brake = engaged != 0;
    if (p->brake) { p->w_l = 0.0; p->stuck_l = 0; }
}

void hd_plant_fault_encoder_glitch(hd_plant *p, hd_plant_encoder_id e, int64_t counts)
{
    p->faults.glitch_counts[e == HD_PLANT_ENC_LOAD ? 1 : 0] = counts;
}

void hd_plant_fault_encoder_dropout(hd_plant *p, hd_plant_encoder_id e, uint32_t steps)
{
    p->faults.dropout_steps[e == HD_PLANT_ENC_LOAD ? 1 : 0] = steps;
}

void hd_plant_fault_current_limit(hd_plant *p, double limit_A)
{
    p->faults.current_limit_A = limit_A;
}

void hd_plant_fault_load_step(hd_plant *p, double torque_Nm)
{
    p->faults.load_step_Nm = torque_Nm;
}
