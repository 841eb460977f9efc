/*
 * simlib.c - the ctypes-facing API of libhdsim.so (see simlib.h).
 */
#include "simlib.h"
#include "sim_err.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "hd_plant.h"
#include "scenario.h"

struct hd_simlib {
    hd_scenario_t sc;
    int32_t n_set;
    hd_sc_override_t set[HD_SC_MAX_OVERRIDES];
    hd_sim_t *sim;
    char meta[65536];
};


hd_simlib_t *hd_simlib_open(const char *scenario_path, char *err, size_t errlen)
{
    hd_simlib_t *h = calloc(1, sizeof *h);
    if (!h) { sim_set_err(err, errlen, "out of memory"); return NULL; }
    if (hd_scenario_load(scenario_path, &h->sc, err, errlen)) {
        free(h);
        return NULL;
    }
    return h;
}

int32_t hd_simlib_set_param(hd_simlib_t *h, const char *key, double value, char *err, size_t errlen)
{
    hd_plant_params scratch;
    hd_plant_defaults_reference(&scratch);
    int rc = hd_plant_param_set(&scratch, key, value);
    if (rc != HD_PLANT_OK) {
        sim_set_err(err, errlen, "plant parameter '%s' = %.17g: %s", key, value, hd_plant_strerror(rc));
        return -1;
    }
    if (h->n_set >= HD_SC_MAX_OVERRIDES || strlen(key) >= HD_SC_KEY_MAX) {
        sim_set_err(err, errlen, "too many overrides or key too long: %s", key);
        return -1;
    }
    memcpy(h->set[h->n_set].key, key, strlen(key) + 1);
    h->set[h->n_set].value = value;
    h->n_set++;
    return 0;
}

void hd_simlib_set_seed(hd_simlib_t *h, uint64_t seed) { h->sc.seed = seed; }

int32_t hd_simlib_set_duration(hd_simlib_t *h, double duration_s, char *err, size_t errlen)
{
    if (!(duration_s >= h->sc.dt_s && duration_s <= HD_SC_MAX_DURATION_S)) {
        sim_set_err(err, errlen, "duration %.17g s: expected [%g, %g] s", duration_s, h->sc.dt_s, HD_SC_MAX_DURATION_S);
        return -1;
    }
    h->sc.duration_s = duration_s;
    return 0;
}

int64_t hd_simlib_prepare(hd_simlib_t *h, char *err, size_t errlen)
{
    hd_plant_params prm;
    if (h->sim) { hd_sim_free(h->sim); h->sim = NULL; }
    if (hd_sim_scenario_params(&h->sc, &prm, err, errlen)) return -1;
    for (int32_t i = 0; i < h->n_set; i++) {
        int rc = hd_plant_param_set(&prm, h->set[i].key, h->set[i].value);
        if (rc != HD_PLANT_OK) {
            sim_set_err(err, errlen, "plant parameter '%s': %s", h->set[i].key, hd_plant_strerror(rc));
            return -1;
        }
    }
    h->sim = hd_sim_new(&h->sc, &prm, err, errlen);
    if (!h->sim) return -1;
    hd_sim_enable_timing(h->sim, 1);
    hd_sim_meta_json(h->sim, h->meta, sizeof h->meta);
    return hd_sim_n_rows(h->sim);
}

int32_t hd_simlib_ncol(void) { return HD_SIM_NCOL; }

const char *hd_simlib_column(const hd_simlib_t *h, int32_t col)
{
    return hd_sim_column_name(col, (int32_t)h->sc.mode);
}

int32_t hd_simlib_run(hd_simlib_t *h, double *rows, char *err, size_t errlen)
{
    if (!h->sim) { sim_set_err(err, errlen, "hd_simlib_run before hd_simlib_prepare"); return -1; }
    return hd_sim_run(h->sim, rows, err, errlen) ? -1 : 0;
}

int32_t hd_simlib_run_columns(hd_simlib_t *h, double *cols, char *err, size_t errlen)
{
    if (!h->sim) { sim_set_err(err, errlen, "hd_simlib_run_columns before hd_simlib_prepare"); return -1; }
    return hd_sim_run_columns(h->sim, cols, err, errlen) ? -1 : 0;
}

const char *hd_simlib_meta(hd_simlib_t *h)
{
    /* again after a run: the sidecar also reports state the run leaves (the online friction estimator) */
    if (h->sim) hd_sim_meta_json(h->sim, h->meta, sizeof h->meta);
    return h->meta;
}

int32_t hd_simlib_write_log(hd_simlib_t *h, const double *rows, int64_t n_rows, const char *csv_path,
                            char *err, size_t errlen)
{
    if (!h->sim) { sim_set_err(err, errlen, "hd_simlib_write_log before hd_simlib_prepare"); return -1; }
    return hd_sim_write_log(h->sim, rows, n_rows, csv_path, err, errlen) ? -1 : 0;
}

void hd_simlib_timing(const hd_simlib_t *h, double *app_s, double *plant_s)
{
    *app_s = *plant_s = 0.0;
    if (h->sim) hd_sim_timing(h->sim, app_s, plant_s, NULL);
}

void hd_simlib_close(hd_simlib_t *h)
{
    if (!h) return;
    hd_sim_free(h->sim);
    free(h);
}

/* ---- open loop ------------------------------------------------------------------- */

static const char *const OL_COLS[] = {
    "t_s", "motor_angle_rad", "load_angle_rad", "motor_velocity_rad_s", "load_velocity_rad_s",
    "motor_torque_Nm", "motor_current_A", "torsion_rad", "gyro_rate_rad_s", "motor_angle_true_rad",
    "load_angle_true_rad", "transmitted_torque_Nm", "hysteresis_torque_Nm", "friction_motor_Nm",
    "friction_load_Nm", "te_rad"};
#define OL_NCOL ((int32_t)(sizeof OL_COLS / sizeof OL_COLS[0]))

int32_t hd_simlib_ol_ncol(void) { return OL_NCOL; }
const char *hd_simlib_ol_column(int32_t col) { return (col >= 0 && col < OL_NCOL) ? OL_COLS[col] : NULL; }

/* One output row of the open-loop column list (hd_simlib_ol_column). */
static void ol_row(const hd_plant_output *o, double t, double mc, double lc, double *r)
{
    r[0] = t;
    r[1] = (double)o->enc_motor_count * mc;
    r[2] = (double)o->enc_load_count * lc;
    r[3] = o->motor_velocity_rad_s;
    r[4] = o->load_velocity_rad_s;
    r[5] = o->motor_torque_Nm;
    r[6] = o->current_meas_A;
    r[7] = o->twist_rad;
    r[8] = o->gyro_rad_s;
    r[9] = o->motor_angle_rad;
    r[10] = o->load_angle_rad;
    r[11] = o->transmitted_torque_Nm;
    r[12] = o->hysteresis_torque_Nm;
    r[13] = o->friction_motor_Nm;
    r[14] = o->friction_load_Nm;
    r[15] = o->te_rad;
}

/* The plant parameters of an axis file (the reference axis when NULL) with n_over overrides
 * keys[i] = values[i] applied in order; 0, or -1 with the first refusal in err. */
static int axis_with_overrides(const char *axis, const char *const *keys, const double *values, int32_t n_over,
                               hd_plant_params *prm, char *err, size_t errlen)
{
    if (hd_sim_axis_params(axis ? axis : "reference", prm, err, errlen)) return -1;
    for (int32_t i = 0; i < n_over; i++) {
        int rc = hd_plant_param_set(prm, keys[i], values[i]);
        if (rc != HD_PLANT_OK) {
            sim_set_err(err, errlen, "plant parameter '%s' = %.17g: %s", keys[i], values[i], hd_plant_strerror(rc));
            return -1;
        }
    }
    return 0;
}

int32_t hd_simlib_open_loop(const char *axis, const char *const *keys, const double *values, int32_t n_over,
                            uint64_t seed, double dt_s, int64_t n, const double *torque_Nm,
                            const double *load_Nm, double *out, char *err, size_t errlen)
{
    hd_plant_params prm;
    if (!(dt_s > 0.0 && dt_s <= 1.0) || n < 0) {
        sim_set_err(err, errlen, "open loop: expected 0 < dt_s <= 1 and n >= 0 (got dt_s = %g, n = %lld)", dt_s,
                (long long)n);
        return -1;
    }
    if (axis_with_overrides(axis, keys, values, n_over, &prm, err, errlen)) return -1;
    hd_plant *p = malloc(sizeof *p);
    if (!p) { sim_set_err(err, errlen, "out of memory"); return -1; }
    char msg[256];
    if (hd_plant_init(p, &prm, seed, msg, sizeof msg) != HD_PLANT_OK) {
        sim_set_err(err, errlen, "%s", msg);
        free(p);
        return -1;
    }
    const double mc = 2.0 * 3.14159265358979323846 / ldexp(1.0, prm.enc_m_bits);
    const double lc = 2.0 * 3.14159265358979323846 / ldexp(1.0, prm.enc_l_bits);
    hd_plant_input in;
    memset(&in, 0, sizeof in);
    for (int64_t i = 0; i < n; i++) {
        in.torque_cmd_Nm = torque_Nm[i];
        in.load_torque_Nm = load_Nm ? load_Nm[i] : 0.0;
        const hd_plant_output *o = hd_plant_step(p, &in, dt_s);
        ol_row(o, (double)(i + 1) * dt_s, mc, lc, out + i * OL_NCOL);
    }
    free(p);
    return 0;
}

/* ---- plant stepped by the caller (simlib.h) ------------------------------------------- */

struct hd_simlib_plant {
    hd_plant p;
    double mc, lc;          /* rad per encoder count */
    int64_t steps;          /* periods run so far */
    double t;               /* s */
};

hd_simlib_plant_t *hd_simlib_plant_open(const char *axis, const char *const *keys, const double *values,
                                        int32_t n_over, uint64_t seed, char *err, size_t errlen)
{
    hd_plant_params prm;
    if (axis_with_overrides(axis, keys, values, n_over, &prm, err, errlen)) return NULL;
    hd_simlib_plant_t *h = calloc(1, sizeof *h);
    if (!h) { sim_set_err(err, errlen, "out of memory"); return NULL; }
    char msg[256];
    if (hd_plant_init(&h->p, &prm, seed, msg, sizeof msg) != HD_PLANT_OK) {
        sim_set_err(err, errlen, "%s", msg);
        free(h);
        return NULL;
    }
    h->mc = 2.0 * 3.14159265358979323846 / ldexp(1.0, prm.enc_m_bits);
    h->lc = 2.0 * 3.14159265358979323846 / ldexp(1.0, prm.enc_l_bits);
    return h;
}

int32_t hd_simlib_plant_run(hd_simlib_plant_t *h, double dt_s, int64_t n, const double *torque_Nm, double *out,
                            char *err, size_t errlen)
{
    if (!(dt_s > 0.0 && dt_s <= 1.0) || n < 0) {
        sim_set_err(err, errlen, "plant run: expected 0 < dt_s <= 1 and n >= 0 (got dt_s = %g, n = %lld)", dt_s,
                    (long long)n);
        return -1;
    }
    hd_plant_input in;
    memset(&in, 0, sizeof in);
    for (int64_t i = 0; i < n; i++) {
        in.torque_cmd_Nm = torque_Nm[i];
        const hd_plant_output *o = hd_plant_step(&h->p, &in, dt_s);
        h->steps++;
        h->t += dt_s;
        ol_row(o, h->t, h->mc, h->lc, out + i * OL_NCOL);
    }
    return 0;
}

void hd_simlib_plant_close(hd_simlib_plant_t *h) { free(h); }

/* ---- windowed replay (simlib.h) ------------------------------------------------------ */

int32_t hd_simlib_max_maxwell(void) { return HD_PLANT_MAX_MAXWELL; }

int32_t hd_simlib_replay_windows(const char *axis, const char *const *keys, const double *values, int32_t n_over,
                                 double dt_s, int64_t n, const double *torque_Nm, int64_t n_win,
                                 const int64_t *start, const double *x0, const double *xi0, double *out,
                                 char *err, size_t errlen)
{
    hd_plant_params prm;
    if (!(dt_s > 0.0 && dt_s <= 1.0) || n < 0 || n_win < 0) {
        sim_set_err(err, errlen, "replay: expected 0 < dt_s <= 1, n >= 0 and n_win >= 0 (got dt_s = %g, n = %lld, "
                    "n_win = %lld)", dt_s, (long long)n, (long long)n_win);
        return -1;
    }
    for (int64_t w = 0; w < n_win; w++) {
        if (start[w] < 0 || start[w] >= n || (w > 0 && start[w] <= start[w - 1])) {
            sim_set_err(err, errlen, "replay: window %lld starts at row %lld, expected increasing rows in [0, %lld)",
                        (long long)w, (long long)start[w], (long long)n);
            return -1;
        }
    }
    if (axis_with_overrides(axis, keys, values, n_over, &prm, err, errlen)) return -1;
    /* one initialised plant (tables, caches) copied into every window: hd_plant holds no pointers */
    hd_plant *p0 = malloc(sizeof *p0);
    hd_plant *p = malloc(sizeof *p);
    if (!p0 || !p) { free(p0); free(p); sim_set_err(err, errlen, "out of memory"); return -1; }
    char msg[256];
    if (hd_plant_init(p0, &prm, 0, msg, sizeof msg) != HD_PLANT_OK) {
        sim_set_err(err, errlen, "%s", msg);
        free(p0); free(p);
        return -1;
    }
    const double nan_v = nan("");
    for (int64_t i = 0; i < (n_win > 0 ? start[0] : n); i++) { out[2 * i] = nan_v; out[2 * i + 1] = nan_v; }
    hd_plant_input in;
    memset(&in, 0, sizeof in);
    for (int64_t w = 0; w < n_win; w++) {
        const int64_t a = start[w], b = w + 1 < n_win ? start[w + 1] : n;
        const double *x = x0 + 4 * w;
        memcpy(p, p0, sizeof *p);
        hd_plant_set_state(p, x[0], x[1], x[2], x[3]);
        if (xi0)
            for (int k = 0; k < HD_PLANT_MAX_MAXWELL; k++) p->xi[k] = xi0[w * HD_PLANT_MAX_MAXWELL + k];
        if (prm.kt_Nm_per_A > 0.0) p->i = torque_Nm[a] / prm.kt_Nm_per_A;
        out[2 * a] = x[0];
        out[2 * a + 1] = x[2];
        int dead = 0;
        for (int64_t i = a; i + 1 < b; i++) {
            if (!dead) {
                in.torque_cmd_Nm = torque_Nm[i];
                hd_plant_step(p, &in, dt_s);
                dead = hd_plant_diverged(p);
            }
            out[2 * (i + 1)] = dead ? nan_v : p->th_m;
            out[2 * (i + 1) + 1] = dead ? nan_v : p->th_l;
        }
    }
    free(p0);
    free(p);
    return 0;
}

/* ---- parameter table --------------------------------------------------------------- */

int32_t hd_simlib_param_count(void) { return (int32_t)hd_plant_param_count(); }

const char *hd_simlib_param_name(int32_t i)
{
    const hd_plant_param_desc *d = (i >= 0) ? hd_plant_param_at((size_t)i) : NULL;
    return d ? d->name : NULL;
}

const char *hd_simlib_param_unit(int32_t i)
{
    const hd_plant_param_desc *d = (i >= 0) ? hd_plant_param_at((size_t)i) : NULL;
    return d ? d->unit : NULL;
}

int32_t hd_simlib_param_type(int32_t i)
{
    const hd_plant_param_desc *d = (i >= 0) ? hd_plant_param_at((size_t)i) : NULL;
    return d ? (int32_t)d->type : -1;
}

int32_t hd_simlib_axis_param(const char *axis, const char *name, double *value, char *err, size_t errlen)
{
    hd_plant_params prm;
    if (hd_sim_axis_params(axis ? axis : "reference", &prm, err, errlen)) return -1;
    if (hd_plant_param_get(&prm, name, value) != HD_PLANT_OK) {
        sim_set_err(err, errlen, "unknown plant parameter '%s'", name);
        return -1;
    }
    return 0;
}
