/*
 * comp_ffi.c - batch-call shim over the compensators for the ctypes tests
 * (tests/python/test_comp_*.py).  Host-only test code, not firmware: every
 * function takes flat int32/int64 arrays (parameters in the field order of
 * the C structs, documented per function) and runs a whole sequence.
 */
#include <stdint.h>
#include <stdbool.h>
#include <string.h>
#include "hd_stribeck.h"
#include "hd_lugre.h"
#include "hd_maxwell.h"
#include "hd_preisach.h"
#include "hd_te_comp.h"
#include "hd_backstep.h"

int32_t comp_ffi_version(void);
void comp_stribeck_run(const int32_t *cfg, const int32_t *v_ref, const int32_t *v_est,
                       int32_t *tau, uint32_t n);
void comp_lugre_run(const int32_t *cfg, const int32_t *v, const int64_t *e, int32_t *tau,
                    int64_t *z, uint32_t n);
void comp_maxwell_run(uint32_t nel, const int32_t *k, const int32_t *d, int32_t compliance,
                      int32_t tau_max, const int64_t *x, int32_t *tau, int64_t *dth, uint32_t n);
void comp_te_run(uint32_t nh, const uint32_t *order, const int32_t *amp, const uint32_t *phase,
                 int32_t k1, int32_t tau_max, const int64_t *theta_m, int64_t *dth, int32_t *tau,
                 uint32_t n);
void comp_backstep_run(const int32_t *cfg, const int32_t *th0, const int64_t *theta,
                       const int64_t *theta_d, const int32_t *omega, const int32_t *omega_d,
                       const int32_t *acc_d, int32_t *u, int64_t *th, uint32_t n);
int32_t comp_preisach_load(const uint32_t *words, uint32_t n_words);
int32_t comp_preisach_everett(const uint32_t *words, uint32_t n_words, int32_t a, int32_t b);
int32_t comp_preisach_run(const uint32_t *words, uint32_t n_words, uint32_t deadband,
                          uint32_t brute, const int32_t *p, int64_t *y, uint32_t n);
int32_t comp_preisach_quantise(const uint32_t *words, uint32_t n_words, int32_t u);
int32_t comp_preisach_inv_run(const uint32_t *words, uint32_t n_words, uint32_t deadband,
                              const int64_t *yd, int32_t *p, int64_t *y, uint32_t n);

int32_t comp_ffi_version(void)
{
    return 1;
}

/* cfg: pos.fc pos.fs pos.vs pos.fv neg.fc neg.fs neg.vs neg.fv delta eps_v w_ref tau_max cruise_ticks */
void comp_stribeck_run(const int32_t *cfg, const int32_t *v_ref, const int32_t *v_est,
                       int32_t *tau, uint32_t n)
{
    hd_stribeck_cfg_t c;
    hd_stribeck_t s;
    uint32_t i;
    c.pos.fc = cfg[0]; c.pos.fs = cfg[1]; c.pos.vs = cfg[2]; c.pos.fv = cfg[3];
    c.neg.fc = cfg[4]; c.neg.fs = cfg[5]; c.neg.vs = cfg[6]; c.neg.fv = cfg[7];
    c.delta = (uint32_t)cfg[8]; c.eps_v = cfg[9]; c.w_ref = cfg[10]; c.tau_max = cfg[11];
    c.cruise_ticks = (uint32_t)cfg[12];
    c.steady_vs = 0;                    /* steady-motion rule off: the Python reference has none */
    hd_stribeck_init(&s, 0u, true);
    for (i = 0; i < n; i++) {
        tau[i] = hd_stribeck_step(&s, &c, v_ref[i], v_est[i]);
    }
}

/* cfg: fc fs vs delta sigma0 sigma1 sigma2 k_obs tau_max */
void comp_lugre_run(const int32_t *cfg, const int32_t *v, const int64_t *e, int32_t *tau,
                    int64_t *z, uint32_t n)
{
    hd_lugre_cfg_t c;
    hd_lugre_t s;
    uint32_t i;
    c.g.fc = cfg[0]; c.g.fs = cfg[1]; c.g.vs = cfg[2]; c.g.fv = 0;
    c.delta = (uint32_t)cfg[3]; c.sigma0 = cfg[4]; c.sigma1 = cfg[5]; c.sigma2 = cfg[6];
    c.k_obs = cfg[7]; c.tau_max = cfg[8];
    hd_lugre_init(&s, 0u, true);
    for (i = 0; i < n; i++) {
        tau[i] = hd_lugre_step(&s, &c, v[i], e[i]);
        z[i] = s.z;
    }
}

void comp_maxwell_run(uint32_t nel, const int32_t *k, const int32_t *d, int32_t compliance,
                      int32_t tau_max, const int64_t *x, int32_t *tau, int64_t *dth, uint32_t n)
{
    hd_maxwell_cfg_t c;
    hd_maxwell_t s;
    uint32_t i;
    memset(&c, 0, sizeof c);
    c.n = nel;
    for (i = 0; i < nel && i < HD_MAXWELL_N_MAX; i++) {
        c.k[i] = k[i];
        c.d[i] = d[i];
    }
    c.compliance = compliance;
    c.tau_max = tau_max;
    hd_maxwell_init(&s, 0u, true);
    for (i = 0; i < n; i++) {
        dth[i] = hd_maxwell_step(&s, &c, x[i]);
        tau[i] = s.tau;
    }
}

void comp_te_run(uint32_t nh, const uint32_t *order, const int32_t *amp, const uint32_t *phase,
                 int32_t k1, int32_t tau_max, const int64_t *theta_m, int64_t *dth, int32_t *tau,
                 uint32_t n)
{
    hd_te_cfg_t c;
    hd_te_comp_t s;
    uint32_t i;
    memset(&c, 0, sizeof c);
    c.n = nh;
    for (i = 0; i < nh && i < HD_TE_N_MAX; i++) {
        c.order[i] = order[i];
        c.amp[i] = amp[i];
        c.phase[i] = phase[i];
    }
    c.k1 = k1;
    c.tau_max = tau_max;
    hd_te_comp_init(&s, 0u, true);
    for (i = 0; i < n; i++) {
        dth[i] = hd_te_comp_step(&s, &c, theta_m[i]);
        tau[i] = s.tau;
    }
}

/* cfg: c1 c2 j ke eps_w w_s e1_max u_max gamma_dt[4] th_min[4] th_max[4] (20 words) */
void comp_backstep_run(const int32_t *cfg, const int32_t *th0, const int64_t *theta,
                       const int64_t *theta_d, const int32_t *omega, const int32_t *omega_d,
                       const int32_t *acc_d, int32_t *u, int64_t *th, uint32_t n)
{
    hd_backstep_cfg_t c;
    hd_backstep_t s;
    uint32_t i;
    uint32_t k;
    c.c1 = cfg[0]; c.c2 = cfg[1]; c.j = cfg[2]; c.ke = cfg[3]; c.eps_w = cfg[4];
    c.w_s = cfg[5]; c.e1_max = cfg[6]; c.u_max = cfg[7];
    for (k = 0; k < HD_BS_NP; k++) {
        c.gamma_dt[k] = cfg[8 + k];
        c.th_min[k] = cfg[12 + k];
        c.th_max[k] = cfg[16 + k];
    }
    hd_backstep_init(&s, &c, th0, 0u, true);
    for (i = 0; i < n; i++) {
        hd_backstep_in_t in;
        in.theta = theta[i]; in.theta_d = theta_d[i]; in.omega = omega[i];
        in.omega_d = omega_d[i]; in.acc_d = acc_d[i];
        u[i] = hd_backstep_step(&s, &c, &in, 0);
        for (k = 0; k < HD_BS_NP; k++) {
            th[i * HD_BS_NP + k] = s.th[k];
        }
    }
}

/* ---- Preisach: the table comes as the host image (little-endian words) ---- */

static hd_preisach_table_t g_tab;      /* test shim only */
static hd_preisach_t g_pz;
static hd_preisach_bf_t g_bf;
static hd_preisach_inv_t g_inv;

static void ffi_image(hd_preisach_table_t *t, const uint32_t *w, uint32_t nw)
{
    uint32_t i;
    memset(t, 0, sizeof *t);
    if (nw < 10u) {
        return;
    }
    t->magic = w[0]; t->format = w[1]; t->version = w[2]; t->levels = w[3];
    t->sub_bits = w[4]; t->in_shift = w[5]; t->u0 = (int32_t)w[6]; t->unit = w[7];
    t->n_entries = w[8]; t->crc = w[9];
    for (i = 0; i < HD_PREISACH_N_MAX && 10u + i < nw; i++) {
        t->e[i] = (int32_t)w[10u + i];
    }
}

/* Returns hd_preisach_check of the image (0 = accepted). */
int32_t comp_preisach_load(const uint32_t *words, uint32_t n_words)
{
    hd_preisach_table_t tmp;
    ffi_image(&tmp, words, n_words);
    return hd_preisach_install(&g_tab, &tmp);
}

int32_t comp_preisach_everett(const uint32_t *words, uint32_t n_words, int32_t a, int32_t b)
{
    ffi_image(&g_tab, words, n_words);
    return hd_preisach_everett(&g_tab, a, b);
}

int32_t comp_preisach_quantise(const uint32_t *words, uint32_t n_words, int32_t u)
{
    ffi_image(&g_tab, words, n_words);
    return hd_preisach_quantise(&g_tab, u);
}

int32_t comp_preisach_run(const uint32_t *words, uint32_t n_words, uint32_t deadband,
                          uint32_t brute, const int32_t *p, int64_t *y, uint32_t n)
{
    uint32_t i;
    const int32_t rc = comp_preisach_load(words, n_words);
    if (rc != 0) {
        return rc;
    }
    if (brute) {
        hd_preisach_bf_init(&g_bf, &g_tab, deadband);
        for (i = 0; i < n; i++) {
            y[i] = hd_preisach_bf_step_p(&g_bf, &g_tab, p[i]);
        }
    } else {
        hd_preisach_init(&g_pz, &g_tab, deadband, 0u, true);
        for (i = 0; i < n; i++) {
            y[i] = hd_preisach_step_p(&g_pz, &g_tab, p[i]);
        }
    }
    return 0;
}

int32_t comp_preisach_inv_run(const uint32_t *words, uint32_t n_words, uint32_t deadband,
                              const int64_t *yd, int32_t *p, int64_t *y, uint32_t n)
{
    uint32_t i;
    const int32_t rc = comp_preisach_load(words, n_words);
    if (rc != 0) {
        return rc;
    }
    hd_preisach_inv_init(&g_inv, &g_tab, deadband, 0u, true);
    for (i = 0; i < n; i++) {
        p[i] = hd_preisach_inv_step_p(&g_inv, &g_tab, yd[i]);
        y[i] = g_inv.fwd.y;
    }
    return 0;
}
