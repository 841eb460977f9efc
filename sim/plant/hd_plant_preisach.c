/*
 * hd_plant_preisach.c - Preisach operator (see hd_plant_preisach.h).
 */
#include "hd_plant_preisach.h"

#include <math.h>
#include <string.h>

#define L HD_PLANT_PREISACH_L
#define W (HD_PLANT_PREISACH_L + 1)

static double density(double alpha, double beta, double r0, double s)
{
    double r = 0.5 * (alpha - beta), m = 0.5 * (alpha + beta);
    return exp(-r / r0) * exp(-m * m / (2.0 * s * s));
}

void hd_plant_preisach_everett(double *E, double u_max, double t_sat, double r0, double s)
{
    double du = 2.0 * u_max / (double)L, scale;
    int i, j, a, b;
    memset(E, 0, sizeof(double) * W * W);
    for (j = 0; j < L; j++) {
        double acc = 0.0;
        for (a = j; a < L; a++) {
            double ua = -u_max + (double)a * du, row = 0.0;
            for (b = j; b < a; b++) {
                double ub = -u_max + (double)b * du;
                row += density(ua + 0.5 * du, ub + 0.5 * du, r0, s) * du * du;
            }
            row += density(ua + 2.0 * du / 3.0, ua + du / 3.0, r0, s) * 0.5 * du * du;
            acc += row;
            E[(a + 1) * W + j] = acc;
        }
    }
    scale = E[L * W + 0] > 0.0 ? t_sat / E[L * W + 0] : 0.0;
    for (i = 0; i < W * W; i++) E[i] *= scale;
}

/* E(alpha, beta) with the grid's cells per rad inv_du = L / (2 u_max) given (the operator
 * keeps it in its state: no division per evaluation). */
static double everett(const double *E, double u_max, double inv_du, double alpha, double beta)
{
    double xa = (alpha + u_max) * inv_du, xb = (beta + u_max) * inv_du, fa, fb;
    int ia, ib;
    /* a diverged plant hands in NaN: no table cell belongs to it, and converting
     * NaN to int is undefined, so it propagates as NaN for the harness to report */
    if (isnan(xa) || isnan(xb)) return NAN;
    if (alpha <= beta) return 0.0;
    /* clamp in double before the cast: an out-of-range double -> int is undefined */
    if (xa < 0.0) xa = 0.0;
    if (xa > (double)L) xa = (double)L;
    if (xb < 0.0) xb = 0.0;
    if (xb > (double)L) xb = (double)L;
    ia = (int)xa; if (ia > L - 1) ia = L - 1;
    ib = (int)xb; if (ib > L - 1) ib = L - 1;
    fa = xa - (double)ia;
    fb = xb - (double)ib;
    if (ia < ib) return 0.0;
    if (ia == ib) return fa > fb ? E[(ia + 1) * W + ia] * (fa - fb) : 0.0;
    return (1.0 - fa) * (1.0 - fb) * E[ia * W + ib] + fa * (1.0 - fb) * E[(ia + 1) * W + ib]
           + (1.0 - fa) * fb * E[ia * W + ib + 1] + fa * fb * E[(ia + 1) * W + ib + 1];
}

double hd_preisach_E(const double *E, double u_max, double alpha, double beta)
{
    return everett(E, u_max, (double)L / (2.0 * u_max), alpha, beta);
}

/* Drop the oldest (max, min) pair above the sentinels when a stack is full. */
static void make_room(hd_plant_preisach_state *s)
{
    if (s->n_max >= HD_PLANT_PREISACH_STACK - 1 || s->n_min >= HD_PLANT_PREISACH_STACK - 1) {
        if (s->n_max > 1 && s->n_min > 1) {
            memmove(&s->max_u[1], &s->max_u[2], sizeof(double) * (size_t)(s->n_max - 2));
            memmove(&s->max_y[1], &s->max_y[2], sizeof(double) * (size_t)(s->n_max - 2));
            memmove(&s->min_u[1], &s->min_u[2], sizeof(double) * (size_t)(s->n_min - 2));
            memmove(&s->min_y[1], &s->min_y[2], sizeof(double) * (size_t)(s->n_min - 2));
            s->n_max--;
            s->n_min--;
        }
    }
}

double hd_plant_preisach_eval(const hd_plant_preisach_state *s, const double *E, double u_max, double u,
                        hd_plant_preisach_state *commit)
{
    int32_t nmin = s->n_min, nmax = s->n_max, d, virt = 0; /* virt: +1 pending min, -1 pending max */
    double vu = s->u_prev, vy = s->y, y;
    if (u > u_max) u = u_max;
    if (u < -u_max) u = -u_max;
    if (u == s->u_prev) return s->y;
    d = u > s->u_prev ? 1 : -1;
    if (d != s->dir) virt = d > 0 ? 1 : -1;
    if (d > 0) {
        double m, ym;
        /* wipe out maxima passed (the bottom max is a sentinel above u_max) */
        while (u >= s->max_u[nmax - 1]) {
            nmax--;
            if (virt == 1) virt = 0; else nmin--;
        }
        if (virt == 1) { m = vu; ym = vy; } else { m = s->min_u[nmin - 1]; ym = s->min_y[nmin - 1]; }
        y = ym + 2.0 * everett(E, u_max, s->inv_du, u, m);
    } else {
        double M, yM;
        while (u <= (virt == 1 ? vu : s->min_u[nmin - 1]) && (virt == 1 || nmin > 1)) {
            /* never reached with virt == 1 (a pending min implies d > 0) */
            nmin--;
            if (virt == -1) virt = 0; else nmax--;
        }
        if (virt == -1) { M = vu; yM = vy; } else { M = s->max_u[nmax - 1]; yM = s->max_y[nmax - 1]; }
        y = yM - 2.0 * everett(E, u_max, s->inv_du, M, u);
    }
    if (commit != NULL) {
        if (commit != s) *commit = *s;
        commit->n_min = nmin;
        commit->n_max = nmax;
        if (virt != 0) {
            make_room(commit);
            if (virt == 1) {
                commit->min_u[commit->n_min] = vu; commit->min_y[commit->n_min] = vy; commit->n_min++;
            } else {
                commit->max_u[commit->n_max] = vu; commit->max_y[commit->n_max] = vy; commit->n_max++;
            }
        }
        commit->dir = d;
        commit->u_prev = u;
        commit->y = y;
    }
    return y;
}

/* Slope (output per rad of input) of the operator from memory s for inputs moving from
 * s->u_prev in direction dir, and the input up to which it holds.  y(u) is continuous and,
 * for fixed memory, piecewise linear: one Everett cell of the moving argument (the bilinear
 * interpolation is linear in one argument when the other is fixed), until the next stored
 * extremum is wiped out or the input saturates. */
void hd_plant_preisach_piece(const hd_plant_preisach_state *s, const double *E, double u_max, int32_t dir,
                             double *slope, double *bound)
{
    const double u = s->u_prev, inv = s->inv_du;
    double x, f;
    int32_t i, j;
    if (dir > 0) {
        const double m = s->dir != 1 ? u : s->min_u[s->n_min - 1];   /* the last minimum (or u itself) */
        double b;
        if (u >= u_max) { *slope = 0.0; *bound = INFINITY; return; }  /* saturated: constant */
        x = (u + u_max) * inv;
        i = (int32_t)floor(x);                                      /* alpha cell [i, i + 1) */
        if (i > L - 1) i = L - 1;
        if (i < 0) i = 0;
        x = (m + u_max) * inv;
        if (x < 0.0) x = 0.0;
        j = (int32_t)x; if (j > L - 1) j = L - 1;
        f = x - (double)j;
        if (i == j) *slope = 2.0 * inv * E[(i + 1) * W + i];
        else *slope = 2.0 * inv * ((1.0 - f) * (E[(i + 1) * W + j] - E[i * W + j])
                                   + f * (E[(i + 1) * W + j + 1] - E[i * W + j + 1]));
        b = -u_max + (double)(i + 1) / inv;
        if (s->max_u[s->n_max - 1] < b) b = s->max_u[s->n_max - 1];  /* wiping out the last maximum */
        *bound = b < u_max ? b : u_max;
    } else {
        const double M = s->dir != -1 ? u : s->max_u[s->n_max - 1];  /* the last maximum (or u itself) */
        double b;
        if (u <= -u_max) { *slope = 0.0; *bound = -INFINITY; return; }
        x = (u + u_max) * inv;
        j = (int32_t)ceil(x) - 1;                                   /* beta cell [j, j + 1) */
        if (j > L - 1) j = L - 1;
        if (j < 0) j = 0;
        x = (M + u_max) * inv;
        if (x > (double)L) x = (double)L;
        i = (int32_t)x; if (i > L - 1) i = L - 1;
        f = x - (double)i;
        if (i == j) *slope = 2.0 * inv * E[(i + 1) * W + i];
        else *slope = -2.0 * inv * ((1.0 - f) * (E[i * W + j + 1] - E[i * W + j])
                                    + f * (E[(i + 1) * W + j + 1] - E[(i + 1) * W + j]));
        b = -u_max + (double)j / inv;
        if (s->n_min > 1 && s->min_u[s->n_min - 1] > b) b = s->min_u[s->n_min - 1]; /* the last minimum */
        *bound = b > -u_max ? b : -u_max;
    }
}

void hd_plant_preisach_reset(hd_plant_preisach_state *s, const double *E, double u_max)
{
    int k;
    const int cycles = 24;
    memset(s, 0, sizeof *s);
    s->inv_du = (double)L / (2.0 * u_max);
    s->min_u[0] = -u_max;
    s->min_y[0] = -E[L * W + 0];
    s->n_min = 1;
    s->max_u[0] = 2.0 * u_max + 1.0;   /* sentinel, never wiped out */
    s->max_y[0] = E[L * W + 0];
    s->n_max = 1;
    s->dir = 1;
    s->u_prev = -u_max;
    s->y = -E[L * W + 0];
    for (k = 0; k < cycles; k++) {
        double a = u_max * (double)(cycles - k) / (double)cycles;
        (void)hd_plant_preisach_eval(s, E, u_max, a, s);
        (void)hd_plant_preisach_eval(s, E, u_max, -a * (1.0 - 0.5 / (double)cycles), s);
    }
    (void)hd_plant_preisach_eval(s, E, u_max, 0.0, s);
}
