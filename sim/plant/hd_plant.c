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

static double rng_gauss(uint64_t s[4])
{
    double u1 = rng_uniform(s), u2 = rng_uniform(s);
    return sqrt(-2.0 * log(u1)) * cos(TWO_PI * u2);
}

/* ---- model pieces -------------------------------------------------------------- */
static double sat(double x, double d) { return x > d ? d : (x < -d ? -d : x); }

static double sat_pot(double x, double d)   /* integral of sat_d from 0 to x */
{
    double ax = fabs(x);
    return ax <= d ? 0.5 * x * x : d * ax - 0.5 * d * d;
}

static double spring_torque(const hd_plant *p, double phi)
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

/* cos/sin(n*x) from c = cos x, s = sin x by binary powers of exp(i x). */
static void cis_pow(double c, double s, uint32_t n, double *cn, double *sn)
{
    double rc = 1.0, rs = 0.0, bc = c, bs = s, t;
    while (n != 0u) {
        if (n & 1u) { t = rc * bc - rs * bs; rs = rc * bs + rs * bc; rc = t; }
        n >>= 1;
        if (n != 0u) { t = bc * bc - bs * bs; bs = 2.0 * bc * bs; bc = t; }
    }
    *cn = rc;
    *sn = rs;
}

/* sum_k a_k*sin(n_k*th + p_k) and its derivative d/dth, for harmonic list `list`
 * (0 cogging, 1 TE wave generator, 2 TE output); c1/s1 = cos/sin(th). */
static double harm_sum(const hd_plant *p, int list, double th, double c1, double s1, double *dsum)
{
    const hd_plant_params *q = &p->prm;
    const double *ord = list == 0 ? q->cog_order : (list == 1 ? q->te_wg_order : q->te_out_order);
    const double *amp = list == 0 ? q->cog_amp_Nm : (list == 1 ? q->te_wg_amp_rad : q->te_out_amp_rad);
    const double *ph = list == 0 ? q->cog_phase_rad : (list == 1 ? q->te_wg_phase_rad : q->te_out_phase_rad);
    double sum = 0.0, d = 0.0;
    int k;
    for (k = 0; k < HD_PLANT_MAX_HARM; k++) {
        double n = ord[k], a = amp[k], sn, cn;
        if (n == 0.0 || a == 0.0) continue;
        if (p->harm_int[list][k]) {
            double cb, sb;
            cis_pow(c1, s1, (uint32_t)n, &cb, &sb);
            sn = sb * p->harm_cp[list][k] + cb * p->harm_sp[list][k];
            cn = cb * p->harm_cp[list][k] - sb * p->harm_sp[list][k];
        } else {
            sn = sin(n * th + ph[k]);
            cn = cos(n * th + ph[k]);
        }
        sum += a * sn;
        d += a * n * cn;
    }
    *dsum = d;
    return sum;
}

/* Kinematic TE and its partial derivatives w.r.t. theta_m and theta_l (cm, sm = cos, sin theta_m). */
static double te_eval(const hd_plant *p, double th_m, double cm, double sm, double th_l, double cl, double sl,
                      double *de_m, double *de_l)
{
    double e = 0.0;
    *de_m = 0.0;
    *de_l = 0.0;
    if (p->prm.te_enabled) {
        e = harm_sum(p, 1, th_m, cm, sm, de_m);
        if (p->has_te_out) e += harm_sum(p, 2, th_l, cl, sl, de_l);
    }
    return e;
}

static double te_eval1(const hd_plant *p, double th_m, double th_l, double *de_m, double *de_l)
{
    return te_eval(p, th_m, cos(th_m), sin(th_m), th_l, cos(th_l), sin(th_l), de_m, de_l);
}

static double cogging(const hd_plant *p, double th_m, double cm, double sm)
{
    double d;
    return p->prm.cogging_enabled ? harm_sum(p, 0, th_m, cm, sm, &d) : 0.0;
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

/* Stribeck level g(v) > 0 for the direction of v (v == 0: positive side). */
static double stribeck_g(const hd_plant_friction_params *f, double v)
{
    double fc = v < 0.0 ? f->fc_neg_Nm : f->fc_pos_Nm;
    double fs = v < 0.0 ? f->fs_neg_Nm : f->fs_pos_Nm;
    double r = fabs(v) / f->vs_rad_s, e;
    if (f->delta == 2.0) e = r * r > 700.0 ? 0.0 : exp(-r * r);   /* avoid the slow underflow path */
    else if (f->delta == 1.0) e = r > 700.0 ? 0.0 : exp(-r);
    else { double rp = pow(r, f->delta); e = rp > 700.0 ? 0.0 : exp(-rp); }
    return fc + (fs - fc) * e;
}

/* LuGre: bristle state after time s at constant velocity v, from z0 (g = g(v)). */
static double lugre_z(const hd_plant_friction_params *f, double z0, double v, double s, double g)
{
    double x = -f->sigma0_Nm_per_rad * fabs(v) * s / g, em1;
    if (s == 0.0) return z0;
    if (fabs(x) < 1e-8) return z0 * (1.0 + x) + v * s * (1.0 + 0.5 * x);
    em1 = x < -40.0 ? -1.0 : expm1(x);
    return z0 * (1.0 + em1) + v * s * (em1 / x);
}

static double lugre_force(const hd_plant_friction_params *f, double z0, double v, double s)
{
    double g = stribeck_g(f, v);
    double z = lugre_z(f, z0, v, s, g);
    double zd = v - f->sigma0_Nm_per_rad * fabs(v) * z / g;
    return f->sigma0_Nm_per_rad * z + f->sigma1_Nms_per_rad * zd + f->viscous_Nms_per_rad * v;
}

/* Friction of a moving (not stuck) side without LuGre. */
static double static_friction(const hd_plant_friction_params *f, double v, double applied)
{
    if (v > 0.0) return stribeck_g(f, v) + f->viscous_Nms_per_rad * v;
    if (v < 0.0) return -stribeck_g(f, v) + f->viscous_Nms_per_rad * v;
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
    double t0, h;
    double tq_m;           /* Kt * mean current */
    double t_ext;          /* external load torque */
    double base_ext_angle0, base_ext_rate, base_ext_accel;
    double bth[3], bw[3], ba[3];   /* base angle, rate, accel at s = 0, h/2, h */
    double gc[3], gs[3];           /* cos/sin(base angle + gravity offset) */
} substep_ctx;

typedef struct {           /* diagnostics of one evaluation */
    double phi, te, T, Th, Fm, Fl, Tcog, Tg, appl_m, appl_l, th_b, w_b;
} eval_diag;

static void base_motion(const hd_plant *p, const substep_ctx *c, double s, double *th, double *w, double *acc)
{
    const hd_plant_params *q = &p->prm;
    double a = c->base_ext_accel, v = c->base_ext_rate, x = c->base_ext_angle0 + c->base_ext_rate * s;
    if (q->base_enabled && q->base_amp_rad != 0.0) {
        double om = TWO_PI * q->base_freq_Hz, arg = om * (c->t0 + s) + q->base_phase_rad;
        double sn = sin(arg), cs = cos(arg);
        x += q->base_amp_rad * sn;
        v += q->base_amp_rad * om * cs;
        a -= q->base_amp_rad * om * om * sn;
    }
    *th = x; *w = v; *acc = a;
}

/* base motion at s = 0, h/2, h of the sub-step */
static void base_cache(const hd_plant *p, substep_ctx *c)
{
    int k;
    for (k = 0; k < 3; k++) {
        base_motion(p, c, 0.5 * c->h * (double)k, &c->bth[k], &c->bw[k], &c->ba[k]);
        if (p->prm.gravity_enabled) {
            c->gc[k] = cos(c->bth[k] + p->prm.gravity_offset_rad);
            c->gs[k] = sin(c->bth[k] + p->prm.gravity_offset_rad);
        } else {
            c->gc[k] = 1.0;
            c->gs[k] = 0.0;
        }
    }
}

static void deriv(const hd_plant *p, const substep_ctx *c, double s, const xstate *x, xstate *dx, eval_diag *dg)
{
    const hd_plant_params *q = &p->prm;
    double de_m, de_l, th_b, w_b, a_b, T, Th = 0.0, Fm = 0.0, Fl = 0.0, Tg = 0.0, Tcog, appl_m, appl_l, dphi;
    double N = q->ratio;
    double cm = 1.0, sm = 0.0, cl = 1.0, sl = 0.0, e;
    if (q->te_enabled || q->cogging_enabled) { cm = cos(x->th_m); sm = sin(x->th_m); }
    if ((q->te_enabled && p->has_te_out) || q->gravity_enabled) { cl = cos(x->th_l); sl = sin(x->th_l); }
    e = te_eval(p, x->th_m, cm, sm, x->th_l, cl, sl, &de_m, &de_l);
    double phi;
    int bi = s <= 0.0 ? 0 : (s < c->h ? 1 : 2);
    th_b = c->bth[bi]; w_b = c->bw[bi]; a_b = c->ba[bi];
    phi = x->th_m / N + e - x->th_l;

    dphi = x->w_m * (1.0 / N + de_m) + x->w_l * (de_l - 1.0);
    T = spring_torque(p, phi);
    if (q->maxwell_enabled) {
        int k;
        for (k = 0; k < q->maxwell_n; k++)
            Th += sat(q->maxwell_k_Nm_per_rad[k] * (phi - p->xi[k]), q->maxwell_w_Nm[k]);
    }
    if (q->preisach_enabled) /* k_P*sat(phi) - P[phi]: dissipative orientation, zero net torque at saturation */
        Th += p->preisach_kp * sat(phi, q->preisach_u_max_rad)
              - hd_preisach_eval(&p->pz, p->everett, q->preisach_u_max_rad, phi, NULL);
    T += Th;
    if (q->stiffness_enabled || q->cubic_enabled) T += q->damping_Nms_per_rad * dphi;

    Tcog = cogging(p, x->th_m, cm, sm);
    /* cos(theta_l + theta_b + offset) by angle addition with the cached cos/sin of theta_b + offset */
    if (q->gravity_enabled) Tg = -q->mgl_Nm * (cl * c->gc[bi] - sl * c->gs[bi]);

    appl_m = c->tq_m + Tcog - T * (1.0 / N + de_m) - q->jm_kgm2 * a_b;
    appl_l = T * (1.0 - de_l) + Tg + c->t_ext - q->jl_kgm2 * a_b;

    /* motor side */
    if (q->fric_m.enabled) {
        if (q->fric_m.lugre_enabled) Fm = lugre_force(&q->fric_m, p->z_m, x->w_m, s);
        else if (p->stuck_m) Fm = appl_m;
        else Fm = static_friction(&q->fric_m, x->w_m, appl_m);
    }
    if (q->fric_m.enabled && !q->fric_m.lugre_enabled && p->stuck_m) {
        dx->th_m = 0.0; dx->w_m = 0.0;
    } else {
        dx->th_m = x->w_m;
        dx->w_m = (appl_m - Fm) / q->jm_kgm2;
    }
    /* load side */
    if (p->brake) {
        dx->th_l = 0.0; dx->w_l = 0.0;
    } else {
        if (q->fric_l.enabled) {
            if (q->fric_l.lugre_enabled) Fl = lugre_force(&q->fric_l, p->z_l, x->w_l, s);
            else if (p->stuck_l) Fl = appl_l;
            else Fl = static_friction(&q->fric_l, x->w_l, appl_l);
        }
        if (q->fric_l.enabled && !q->fric_l.lugre_enabled && p->stuck_l) {
            dx->th_l = 0.0; dx->w_l = 0.0;
        } else {
            dx->th_l = x->w_l;
            dx->w_l = (appl_l - Fl) / q->jl_kgm2;
        }
    }
    if (dg != NULL) {
        dg->phi = phi; dg->te = e; dg->T = T; dg->Th = Th; dg->Fm = Fm; dg->Fl = Fl;
        dg->Tcog = Tcog; dg->Tg = Tg; dg->appl_m = appl_m; dg->appl_l = appl_l; dg->th_b = th_b; dg->w_b = w_b;
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
    double h = c->h, phi_end, de_m, de_l;
    int k;

    deriv(p, c, 0.0, &x0, &k1, NULL);
    axpy(&xt, &x0, 0.5 * h, &k1);
    deriv(p, c, 0.5 * h, &xt, &k2, NULL);
    axpy(&xt, &x0, 0.5 * h, &k2);
    deriv(p, c, 0.5 * h, &xt, &k3, NULL);
    axpy(&xt, &x0, h, &k3);
    deriv(p, c, h, &xt, &k4, &dg);
    p->th_m = x0.th_m + h / 6.0 * (k1.th_m + 2.0 * k2.th_m + 2.0 * k3.th_m + k4.th_m);
    p->w_m = x0.w_m + h / 6.0 * (k1.w_m + 2.0 * k2.w_m + 2.0 * k3.w_m + k4.w_m);
    p->th_l = x0.th_l + h / 6.0 * (k1.th_l + 2.0 * k2.th_l + 2.0 * k3.th_l + k4.th_l);
    p->w_l = x0.w_l + h / 6.0 * (k1.w_l + 2.0 * k2.w_l + 2.0 * k3.w_l + k4.w_l);

    /* LuGre bristles: exponential update with the mean velocity of the sub-step */
    if (q->fric_m.enabled && q->fric_m.lugre_enabled)
        { double v = (p->th_m - x0.th_m) / h; p->z_m = lugre_z(&q->fric_m, p->z_m, v, h, stribeck_g(&q->fric_m, v)); }
    if (q->fric_l.enabled && q->fric_l.lugre_enabled && !p->brake)
        { double v = (p->th_l - x0.th_l) / h; p->z_l = lugre_z(&q->fric_l, p->z_l, v, h, stribeck_g(&q->fric_l, v)); }

    /* stick/slip of the static friction model (applied torque at the end of the step) */
    stick_update(&q->fric_m, &p->stuck_m, x0.w_m, &p->w_m, dg.appl_m);
    if (!p->brake) stick_update(&q->fric_l, &p->stuck_l, x0.w_l, &p->w_l, dg.appl_l);

    /* commit the hysteresis memory */
    phi_end = p->th_m / q->ratio + te_eval1(p, p->th_m, p->th_l, &de_m, &de_l) - p->th_l;
    if (q->maxwell_enabled) {
        for (k = 0; k < q->maxwell_n; k++) {
            double kk = q->maxwell_k_Nm_per_rad[k], w = q->maxwell_w_Nm[k];
            if (kk <= 0.0) continue;
            if (kk * (phi_end - p->xi[k]) > w) p->xi[k] = phi_end - w / kk;
            else if (kk * (phi_end - p->xi[k]) < -w) p->xi[k] = phi_end + w / kk;
        }
    }
    if (q->preisach_enabled)
        (void)hd_preisach_eval(&p->pz, p->everett, q->preisach_u_max_rad, phi_end, &p->pz);
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
    if (prm->preisach_enabled) {
        hd_preisach_everett(p->everett, prm->preisach_u_max_rad, prm->preisach_t_sat_Nm,
                            prm->preisach_r0_rad, prm->preisach_s_rad);
        hd_preisach_reset(&p->pz, p->everett, prm->preisach_u_max_rad);
        p->preisach_kp = prm->preisach_t_sat_Nm / prm->preisach_u_max_rad;
    }
    for (k = 0; k < 4; k++) p->rng[k] = splitmix64(&sm);
    p->faults.current_limit_A = -1.0;
    p->enc_last[0] = p->enc_last[1] = 0;
    return HD_PLANT_OK;
}

void hd_plant_set_state(hd_plant *p, double th_m, double w_m, double th_l, double w_l)
{
    double de_m, de_l, phi;
    int k;
    p->th_m = th_m; p->w_m = w_m; p->th_l = th_l; p->w_l = w_l;
    p->stuck_m = p->stuck_l = 0;
    /* hysteresis memory: elements relaxed at the new twist */
    phi = th_m / p->prm.ratio + te_eval1(p, th_m, th_l, &de_m, &de_l) - th_l;
    for (k = 0; k < HD_PLANT_MAX_MAXWELL; k++) p->xi[k] = phi;
}

double hd_plant_energy(const hd_plant *p)
{
    const hd_plant_params *q = &p->prm;
    double de_m, de_l;
    double phi = p->th_m / q->ratio + te_eval1(p, p->th_m, p->th_l, &de_m, &de_l) - p->th_l;
    double e = 0.5 * q->jm_kgm2 * p->w_m * p->w_m + 0.5 * q->jl_kgm2 * p->w_l * p->w_l;
    e += spring_energy(p, phi);
    e += cogging_energy(q, p->th_m);   /* T_cog = -dV/dtheta, V = sum a/n cos(...) */
    if (q->gravity_enabled) e += q->mgl_Nm * sin(p->th_l + q->gravity_offset_rad);
    return e;
}

static int64_t floor_i64(double x)
{
    double f = floor(x);
    if (f > 9.0e18) return INT64_MAX;
    if (f < -9.0e18) return INT64_MIN;
    return (int64_t)f;
}

static void encoder(hd_plant *p, int id, double angle_rad, int enabled, int bits, double noise, double offset,
                    uint32_t *raw, int64_t *count, int *valid)
{
    double x = (angle_rad / TWO_PI + offset) * ldexp(1.0, bits);
    int64_t c, m = (int64_t)1 << bits;
    if (enabled && noise > 0.0) x += noise * rng_gauss(p->rng);
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
    *raw = (uint32_t)(((c % m) + m) % m);
}

const hd_plant_output *hd_plant_step(hd_plant *p, const hd_plant_input *in, double dt_s)
{
    const hd_plant_params *q = &p->prm;
    hd_plant_output *o = &p->out;
    substep_ctx c;
    xstate x, dx;
    eval_diag dg;
    double icmd, lim, h, E = 0.0, base_th, base_w, base_a;
    int n = q->substeps, k;

    if (!(dt_s > 0.0)) return o;
    h = dt_s / (double)n;
    icmd = in->current_cmd_A + in->torque_cmd_Nm / q->kt_Nm_per_A;
    lim = q->current_peak_A;
    if (p->faults.current_limit_A >= 0.0 && p->faults.current_limit_A < lim) lim = p->faults.current_limit_A;
    o->current_saturated = fabs(icmd) > lim;
    icmd = sat(icmd, lim);
    if (q->current_loop_enabled) E = exp(-h / p->tau_i);

    c.h = h;
    c.t_ext = in->load_torque_Nm + p->faults.load_step_Nm;
    c.base_ext_rate = in->base_rate_rad_s;
    c.base_ext_accel = in->base_accel_rad_s2;
    for (k = 0; k < n; k++) {
        double iavg;
        if (q->current_loop_enabled) {
            double d = p->i - icmd;
            iavg = icmd + d * (p->tau_i / h) * (1.0 - E);
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

    /* diagnostics at the end of the period */
    x.th_m = p->th_m; x.w_m = p->w_m; x.th_l = p->th_l; x.w_l = p->w_l;
    c.t0 = p->t;
    c.tq_m = q->kt_Nm_per_A * p->i;
    c.base_ext_angle0 = p->base_ext_angle;
    base_cache(p, &c);
    deriv(p, &c, 0.0, &x, &dx, &dg);
    base_motion(p, &c, 0.0, &base_th, &base_w, &base_a);

    o->t_s = p->t;
    o->motor_angle_rad = p->th_m;
    o->motor_velocity_rad_s = p->w_m;
    o->load_angle_rad = p->th_l;
    o->load_velocity_rad_s = p->w_l;
    o->base_angle_rad = base_th;
    o->base_rate_rad_s = base_w;
    o->load_inertial_rate_rad_s = p->w_l + base_w;
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
    if (q->isense_enabled) o->current_meas_A += q->isense_offset_A + q->isense_noise_A * rng_gauss(p->rng);
    if (q->gyro_enabled) {
        double meas = o->load_inertial_rate_rad_s + q->gyro_bias_rad_s
                      + q->gyro_noise_rad_s_per_rtHz / sqrt(dt_s) * rng_gauss(p->rng);
        double a = -expm1(-dt_s * TWO_PI * q->gyro_bandwidth_Hz);
        p->gyro_f += a * (meas - p->gyro_f);
        o->gyro_rad_s = p->gyro_f;
    } else {
        p->gyro_f = o->load_inertial_rate_rad_s;
        o->gyro_rad_s = p->gyro_f;
    }
    return o;
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
