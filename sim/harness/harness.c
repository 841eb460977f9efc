/*
 * harness.c - firmware app + plant in lock-step (see harness.h).
 *
 * This file is simulator side (double precision); it reaches the firmware
 * only through hd_app.h and the host port (hal_host.h).
 */
#include "harness.h"
#include "sim_err.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "hal_host.h"
#include "hd_app.h"
#include "hd_param_table.h"
#include "logwrite.h"
#include "toml_lite.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#define TWO_PI (2.0 * M_PI)

struct hd_sim {
    hd_scenario_t sc;
    hd_plant_params prm;
    hd_plant plant;
    hd_app_t app;
    hd_host_port_t port;
    int64_t k;                  /* next period */
    int64_t n_periods;
    int32_t next_fault;
    double motor_count_to_rad, load_count_to_rad;
    double load_dist_Nm;        /* external load torque applied in the last period */
    int timing;
    double t_app_s, t_plant_s;
    int64_t timed;              /* periods actually timed (every 32nd) */
    int64_t periods_run;        /* periods run with timing on */
    int ptp_started;            /* setpoint "ptp": drive mode PTP entered */
    int fe_snap_taken;          /* 1: fe_snap holds the online friction estimator at the end of the run-in */
    hd_fric_est_t fe_snap;      /* (the setpoint's t0 of a scenario with a run-in; meta "fric_est") */
};


/* ---- bridge ---------------------------------------------------------------------- */

static int64_t sat_i64(double x)
{
    if (!(x == x)) return 0;
    if (x >= 9.2233720368547748e18) return INT64_MAX;
    if (x <= -9.2233720368547758e18) return INT64_MIN;
    return (int64_t)llround(x);
}

static int32_t sat_i32(double x)
{
    if (!(x == x)) return 0;
    double r = nearbyint(x);
    if (r >= 2147483647.0) return INT32_MAX;
    if (r <= -2147483648.0) return INT32_MIN;
    return (int32_t)r;
}

int64_t hd_bridge_rad_to_q32_turns(double rad) { return sat_i64(rad / TWO_PI * 4294967296.0); }
double hd_bridge_q32_turns_to_rad(int64_t q) { return (double)q / 4294967296.0 * TWO_PI; }
int32_t hd_bridge_rad_s_to_vel_out(double rad_s) { return sat_i32(rad_s / TWO_PI * 4294967296.0); }
double hd_bridge_vel_out_to_rad_s(int32_t v) { return (double)v / 4294967296.0 * TWO_PI; }
int32_t hd_bridge_to_q16(double x) { return sat_i32(x * 65536.0); }
double hd_bridge_from_q16(int32_t q) { return (double)q / 65536.0; }

static void bridge_sensors(const hd_plant_output *o, hd_hal_sensors_t *s)
{
    s->motor_enc_raw = o->enc_motor_raw;
    s->output_enc_raw = o->enc_load_raw;
    s->current = hd_bridge_to_q16(o->current_meas_A);
    s->gyro_rate = hd_bridge_rad_s_to_vel_out(o->gyro_rad_s);
    s->valid = HD_HAL_VALID_CURRENT | HD_HAL_VALID_GYRO;
    if (o->enc_motor_valid) s->valid |= HD_HAL_VALID_MOTOR_ENC;
    if (o->enc_load_valid) s->valid |= HD_HAL_VALID_OUTPUT_ENC;
}

/* ---- parameters ---------------------------------------------------------------------- */

static int plant_err(const hd_toml_doc_t *doc, const hd_toml_entry_t *e, int rc, const char *key,
                     char *err, size_t errlen)
{
    char msg[200];
    const hd_plant_param_desc *d = hd_plant_param_find(key);
    if (rc == HD_PLANT_EUNKNOWN || !d)
        snprintf(msg, sizeof msg, "unknown plant parameter (see docs/plant.md)");
    else
        snprintf(msg, sizeof msg, "%s: expected %s in [%g, %g] %s", hd_plant_strerror(rc),
                 d->type == HD_PARAM_BOOL ? "true/false" : d->type == HD_PARAM_INT ? "an integer" : "a number",
                 d->min, d->max, d->unit);
    hd_toml_entry_error(doc, e, err, errlen, msg);
    return -1;
}

int hd_sim_axis_params(const char *axis, hd_plant_params *prm, char *err, size_t errlen)
{
    if (strcmp(axis, "reference") == 0) { hd_plant_defaults_reference(prm); return 0; }
    if (strcmp(axis, "minimal") == 0) { hd_plant_defaults_minimal(prm); return 0; }
    hd_toml_doc_t doc;
    if (hd_toml_load(axis, &doc, err, errlen)) return -1;
    int rc = 0;
    hd_toml_entry_t *d = hd_toml_find(&doc, "axis.defaults");
    if (d && d->type == HD_TOML_STRING && strcmp(d->str, "minimal") == 0) hd_plant_defaults_minimal(prm);
    else if (!d || (d->type == HD_TOML_STRING && strcmp(d->str, "reference") == 0)) hd_plant_defaults_reference(prm);
    else {
        hd_toml_entry_error(&doc, d, err, errlen, "expected \"reference\" or \"minimal\"");
        hd_toml_free(&doc);
        return -1;
    }
    for (size_t i = 0; i < doc.n && rc == 0; i++) {
        hd_toml_entry_t *e = &doc.e[i];
        if (strncmp(e->key, "axis.", 5) == 0) {
            /* metadata: name, description, defaults */
            if (e->type != HD_TOML_STRING) {
                hd_toml_entry_error(&doc, e, err, errlen, "expected a string (axis metadata)");
                rc = -1;
            }
            continue;
        }
        double v;
        if (e->type == HD_TOML_NUMBER) v = e->num;
        else if (e->type == HD_TOML_BOOL) v = e->boolean ? 1.0 : 0.0;
        else {
            hd_toml_entry_error(&doc, e, err, errlen, "expected a number or true/false");
            rc = -1;
            break;
        }
        int prc = hd_plant_param_set(prm, e->key, v);
        if (prc != HD_PLANT_OK) rc = plant_err(&doc, e, prc, e->key, err, errlen);
    }
    hd_toml_free(&doc);
    return rc;
}

int hd_sim_scenario_params(const hd_scenario_t *sc, hd_plant_params *prm, char *err, size_t errlen)
{
    if (hd_sim_axis_params(sc->axis, prm, err, errlen)) return -1;
    for (int32_t i = 0; i < sc->n_over; i++) {
        int rc = hd_plant_param_set(prm, sc->over[i].key, sc->over[i].value);
        if (rc != HD_PLANT_OK) {
            sim_set_err(err, errlen, "%s:%ld: plant.%s: %s", sc->path, (long)sc->over[i].line, sc->over[i].key,
                    hd_plant_strerror(rc));
            return -1;
        }
    }
    return 0;
}

/* ---- app set-up -------------------------------------------------------------------- */

static int32_t param_id(const char *name)
{
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++)
        if (strcmp(hd_param_table[i].name, name) == 0) return (int32_t)i;
    return -1;
}

static int set_param_si(hd_sim_t *s, const char *name, double v, const char *why, char *err, size_t errlen)
{
    int32_t id = param_id(name);
    if (id < 0) {
        sim_set_err(err, errlen, "%s: %s: unknown drive parameter '%s'", s->sc.path, why, name);
        return -1;
    }
    double raw = v * ldexp(1.0, hd_param_table[id].frac);
    int32_t r = sat_i32(raw);
    if (hd_app_param_set(&s->app, (uint32_t)id, r) != 0) {
        const hd_param_desc_t *d = &hd_param_table[id];
        sim_set_err(err, errlen, "%s: %s: drive parameter %s = %.17g refused: expected [%.9g, %.9g] %s", s->sc.path,
                why, name, v, ldexp((double)d->min, -d->frac), ldexp((double)d->max, -d->frac), d->unit);
        return -1;
    }
    return 0;
}

/* Compensators: [controller] compensators = [...] -> cb_enable bits (hd_comp_bank.h),
 * [compensators.preisach] table = file -> hd_app_comp_table(). */
static int setup_comp(hd_sim_t *s, char *err, size_t errlen)
{
    static const char *const NAMES[] = {"stribeck", "lugre", "maxwell", "preisach", "te", "backstep", "dob",
                                        "approach", "compliance"};
    const uint32_t n_names = (uint32_t)(sizeof NAMES / sizeof NAMES[0]);
    uint32_t bits = 0;
    for (int32_t i = 0; i < s->sc.n_comp; i++) {
        uint32_t k = 0;
        while (k < n_names && strcmp(s->sc.comp[i], NAMES[k]) != 0) k++;
        if (k == n_names) {
            sim_set_err(err, errlen, "%s: controller.compensators: unknown '%s'; expected stribeck, lugre, maxwell, "
                    "preisach, te, backstep, dob, approach or compliance", s->sc.path, s->sc.comp[i]);
            return -1;
        }
        bits |= 1u << k;
    }
    if (s->sc.comp_table[0]) {
        hd_preisach_table_t *t = calloc(1, sizeof *t);
        FILE *f = fopen(s->sc.comp_table, "rb");
        size_t n = 0;
        uint8_t *buf = malloc(sizeof *t);
        if (t && buf && f) n = fread(buf, 1, sizeof *t, f);
        if (f) fclose(f);
        int rc = -1;
        if (t && buf && n >= 40u && n % 4u == 0u) {
            uint32_t w[10];
            for (size_t j = 0; j < 10u; j++)
                w[j] = (uint32_t)buf[4 * j] | (uint32_t)buf[4 * j + 1] << 8 | (uint32_t)buf[4 * j + 2] << 16 |
                       (uint32_t)buf[4 * j + 3] << 24;
            t->magic = w[0]; t->format = w[1]; t->version = w[2]; t->levels = w[3]; t->sub_bits = w[4];
            t->in_shift = w[5]; t->u0 = (int32_t)w[6]; t->unit = w[7]; t->n_entries = w[8]; t->crc = w[9];
            size_t ne = (n - 40u) / 4u;
            if (ne == t->n_entries && ne <= HD_PREISACH_N_MAX) {
                for (size_t j = 0; j < ne; j++) {
                    const uint8_t *b = buf + 40u + 4u * j;
                    t->e[j] = (int32_t)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 |
                                        (uint32_t)b[3] << 24);
                }
                rc = hd_app_comp_table(&s->app, t);
            }
        }
        free(t);
        free(buf);
        if (rc != 0) {
            sim_set_err(err, errlen, "%s: compensators.preisach.table: %s: expected a valid Preisach table image "
                    "(hdservo.compsetup / preisach_table.py), refused (%d)", s->sc.path, s->sc.comp_table, rc);
            return -1;
        }
    }
    if (s->sc.n_comp > 0 && set_param_si(s, "cb_enable", (double)bits, "controller.compensators", err, errlen))
        return -1;
    return 0;
}

/* Commission the drive for the simulated axis, then apply the scenario's gains. */
static int setup_app(hd_sim_t *s, char *err, size_t errlen)
{
    const hd_plant_params *q = &s->prm;
    if (q->ratio != floor(q->ratio)) {
        sim_set_err(err, errlen, "%s: gear ratio %.17g: the drive needs an integer ratio", s->sc.axis, q->ratio);
        return -1;
    }
    if (set_param_si(s, "gear_ratio", q->ratio, "axis", err, errlen) ||
        set_param_si(s, "motor_enc_bits", (double)q->enc_m_bits, "axis", err, errlen) ||
        set_param_si(s, "output_enc_bits", (double)q->enc_l_bits, "axis", err, errlen) ||
        set_param_si(s, "kt", q->kt_Nm_per_A, "axis", err, errlen) ||
        set_param_si(s, "j_total", q->jl_kgm2 + q->ratio * q->ratio * q->jm_kgm2, "axis", err, errlen))
        return -1;
    for (int32_t i = 0; i < s->sc.n_gains; i++) {
        char why[64];
        snprintf(why, sizeof why, "line %ld [controller.gains]", (long)s->sc.gains[i].line);
        if (set_param_si(s, s->sc.gains[i].key, s->sc.gains[i].value, why, err, errlen)) return -1;
    }
    if (setup_comp(s, err, errlen)) return -1;
    static const int32_t MODE_MAP[] = {HD_MODE_OFF, HD_MODE_TORQUE, HD_MODE_VELOCITY, HD_MODE_POSITION, HD_MODE_STAB};
    if (hd_app_set_mode(&s->app, MODE_MAP[s->sc.mode]) != 0) {
        sim_set_err(err, errlen, "%s: the drive refused mode %s", s->sc.path, hd_scenario_mode_name(s->sc.mode));
        return -1;
    }
    return 0;
}

hd_sim_t *hd_sim_new(const hd_scenario_t *sc, const hd_plant_params *prm, char *err, size_t errlen)
{
    hd_sim_t *s = calloc(1, sizeof *s);
    if (!s) { sim_set_err(err, errlen, "out of memory"); return NULL; }
    s->sc = *sc;
    s->prm = *prm;
    char msg[256];
    if (hd_plant_init(&s->plant, &s->prm, sc->seed, msg, sizeof msg) != HD_PLANT_OK) {
        sim_set_err(err, errlen, "%s: %s", sc->axis, msg);
        free(s);
        return NULL;
    }
    s->motor_count_to_rad = TWO_PI / ldexp(1.0, s->prm.enc_m_bits);
    s->load_count_to_rad = TWO_PI / ldexp(1.0, s->prm.enc_l_bits);
    s->n_periods = (int64_t)llround(sc->duration_s / sc->dt_s);
    if (s->n_periods < 1) s->n_periods = 1;
    /* power-up period: the plant runs one period unpowered so a sample exists */
    hd_plant_input in;
    memset(&in, 0, sizeof in);
    in.load_torque_Nm = sc->load_torque_Nm;
    hd_plant_step(&s->plant, &in, sc->dt_s);
    hd_host_port_init(&s->port);
    hd_host_port_bind(&s->port);
    hd_app_init(&s->app);
    if (setup_app(s, err, errlen)) {
        hd_host_port_bind(NULL);
        free(s);
        return NULL;
    }
    return s;
}

void hd_sim_free(hd_sim_t *s)
{
    if (!s) return;
    if (hd_host_port_bound() == &s->port) hd_host_port_bind(NULL);
    free(s);
}

int64_t hd_sim_n_periods(const hd_sim_t *s) { return s->n_periods; }
int64_t hd_sim_n_rows(const hd_sim_t *s)
{
    return (s->n_periods + s->sc.log_decimation - 1) / s->sc.log_decimation;
}
int32_t hd_sim_mode(const hd_sim_t *s) { return (int32_t)s->sc.mode; }
void hd_sim_enable_timing(hd_sim_t *s, int on) { s->timing = on; }
void hd_sim_timing(const hd_sim_t *s, double *app_s, double *plant_s, int64_t *periods)
{
    /* sampled sums scaled to every period run with timing on */
    const double f = s->timed > 0 ? (double)s->periods_run / (double)s->timed : 0.0;
    if (app_s) *app_s = s->t_app_s * f;
    if (plant_s) *plant_s = s->t_plant_s * f;
    if (periods) *periods = s->periods_run;
}
const void *hd_sim_app(const hd_sim_t *s) { return &s->app; }
const hd_plant *hd_sim_plant(const hd_sim_t *s) { return &s->plant; }
uint32_t hd_sim_port_violations(const hd_sim_t *s) { return s->port.violations; }

static const char *const COLS[HD_SIM_NCOL] = {
    "t_s", "motor_angle_rad", "load_angle_rad", "motor_velocity_rad_s", "load_velocity_rad_s",
    "motor_torque_Nm", "motor_current_A", "setpoint_rad", "torque_cmd_Nm", "torsion_rad",
    "gyro_rate_rad_s", "motor_angle_true_rad", "load_angle_true_rad", "load_velocity_est_rad_s",
    "load_disturbance_Nm", "sensor_valid_code", "fault_code", "base_angle_true_rad"};

const char *hd_sim_column_name(int32_t col, int32_t mode)
{
    if (col < 0 || col >= HD_SIM_NCOL) return NULL;
    if (col == HD_COL_SETPOINT) {
        if (mode == HD_SC_MODE_VELOCITY || mode == HD_SC_MODE_STABILISE) return "setpoint_velocity_rad_s";
        if (mode == HD_SC_MODE_TORQUE) return "setpoint_torque_Nm";
    }
    return COLS[col];
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int smooth_profile(hd_sp_type_t t)
{
    return t == HD_SP_RAMP || t == HD_SP_MOVE || t == HD_SP_SINE || t == HD_SP_CHIRP || t == HD_SP_MULTISINE;
}

static void apply_faults(hd_sim_t *s, double tau)
{
    while (s->next_fault < s->sc.n_faults && s->sc.faults[s->next_fault].t_s <= tau + 0.5 * s->sc.dt_s) {
        const hd_sc_fault_t *f = &s->sc.faults[s->next_fault++];
        hd_plant_encoder_id e = f->encoder ? HD_PLANT_ENC_LOAD : HD_PLANT_ENC_MOTOR;
        switch (f->type) {
        case HD_FAULT_ENC_GLITCH:
            hd_plant_fault_encoder_glitch(&s->plant, e, f->counts);
            break;
        case HD_FAULT_ENC_DROPOUT: {
            double n = ceil(f->duration_s / s->sc.dt_s - 1e-9);
            hd_plant_fault_encoder_dropout(&s->plant, e, n > 4e9 ? 4000000000u : (uint32_t)n);
            break;
        }
        case HD_FAULT_CURRENT_LIMIT:
            hd_plant_fault_current_limit(&s->plant, f->limit_A);
            break;
        case HD_FAULT_LOAD_STEP:
            hd_plant_fault_load_step(&s->plant, f->torque_Nm);
            break;
        }
    }
}

/* One period; row (if not NULL) receives column c at row[c * stride]. */
static void sim_step(hd_sim_t *s, double *row, int64_t stride)
{
    const hd_scenario_t *sc = &s->sc;
    const double dt = sc->dt_s;
    const double tau = (double)s->k * dt;
    const hd_plant_output *o = &s->plant.out;
    hd_hal_sensors_t sens;

    /* 1. sample of the start of this period */
    bridge_sensors(o, &sens);
    hd_host_port_bind(&s->port);
    hd_host_port_latch(&s->port, &sens);

    /* 2. reference */
    double r = hd_scenario_setpoint(&sc->sp, tau, sc->seed);
    switch (sc->mode) {
    case HD_SC_MODE_POSITION:
        if (sc->sp.type == HD_SP_PTP) {
            /* drive trajectory: hold the initial position, then one PTP move at t0 */
            if (tau < sc->sp.t0_s) {
                hd_app_set_position(&s->app, hd_bridge_rad_to_q32_turns(sc->sp.initial));
            } else if (!s->ptp_started) {
                s->ptp_started = 1;
                (void)hd_app_move_to(&s->app, hd_bridge_rad_to_q32_turns(sc->sp.target));
                (void)hd_app_set_mode(&s->app, HD_MODE_PTP);
            }
            break;
        }
        hd_app_set_position(&s->app, hd_bridge_rad_to_q32_turns(r));
        if (smooth_profile(sc->sp.type) || (sc->sp.n_run_in > 0 && tau < sc->sp.t0_s)) {
            double r1 = hd_scenario_setpoint(&sc->sp, tau + dt, sc->seed);
            hd_app_set_velocity(&s->app, hd_bridge_rad_s_to_vel_out((r1 - r) / dt));
        }
        break;
    case HD_SC_MODE_VELOCITY:
    case HD_SC_MODE_STABILISE:          /* commanded inertial rate */
        hd_app_set_velocity(&s->app, hd_bridge_rad_s_to_vel_out(r));
        break;
    case HD_SC_MODE_TORQUE:
        hd_app_set_torque(&s->app, hd_bridge_to_q16(r));
        break;
    case HD_SC_MODE_OFF:
        break;
    }

    /* the estimator as the run-in leaves it (what the measurement after t0 starts from) */
    if (sc->sp.n_run_in > 0 && !s->fe_snap_taken && tau >= sc->sp.t0_s) {
        s->fe_snap = s->app.cb.fe;
        s->fe_snap_taken = 1;
    }

    /* 3. firmware */
    /* timing: clock reads cost about as much as a tenth of a period, so only every
     * 32nd period is timed and the sums are scaled to all periods (hd_sim_timing) */
    const int timed = s->timing && (s->k & 31) == 0;
    double t0 = 0.0, t1 = 0.0, t2 = 0.0;
    if (timed) t0 = now_s();
    hd_app_step(&s->app);
    /* the drive's background below the control period (hd_app_background): on the drive
     * it works the queued steps between the periods, here to completion in every period */
    while (hd_app_background(&s->app)) {
    }
    hd_host_port_end_period(&s->port);
    const hd_hal_command_t *cmd = hd_host_port_command(&s->port);

    /* 6 (first half). log row: sample + truth at the start of the period */
    if (row) {
        row[HD_COL_T * stride] = tau;
        row[HD_COL_MOTOR_ANGLE * stride] = (double)o->enc_motor_count * s->motor_count_to_rad;
        row[HD_COL_LOAD_ANGLE * stride] = (double)o->enc_load_count * s->load_count_to_rad;
        row[HD_COL_MOTOR_VEL * stride] = o->motor_velocity_rad_s;
        row[HD_COL_LOAD_VEL * stride] = o->load_velocity_rad_s;
        row[HD_COL_MOTOR_TORQUE * stride] = o->motor_torque_Nm;
        row[HD_COL_MOTOR_CURRENT * stride] = o->current_meas_A;
        row[HD_COL_SETPOINT * stride] = (sc->mode == HD_SC_MODE_OFF) ? 0.0
                               : (sc->sp.type == HD_SP_PTP && s->ptp_started) ? hd_bridge_q32_turns_to_rad(s->app.tel.pos_ref)
                               : r;
        row[HD_COL_TORQUE_CMD * stride] = cmd->enable ? hd_bridge_from_q16(cmd->torque) : 0.0;
        row[HD_COL_TORSION * stride] = o->twist_rad;
        row[HD_COL_GYRO * stride] = o->gyro_rad_s;
        row[HD_COL_MOTOR_TRUE * stride] = o->motor_angle_rad;
        row[HD_COL_LOAD_TRUE * stride] = o->load_angle_rad;
        row[HD_COL_LOAD_VEL_EST * stride] = hd_bridge_vel_out_to_rad_s(s->app.tel.vel_out);
        row[HD_COL_VALID * stride] = (double)sens.valid;
        row[HD_COL_FAULT * stride] = (double)s->app.tel.fault;
        row[HD_COL_BASE_TRUE * stride] = o->base_angle_rad;
    }

    /* 4. faults due now, 5. plant period */
    apply_faults(s, tau);
    hd_plant_input in;
    memset(&in, 0, sizeof in);
    in.current_cmd_A = cmd->enable ? hd_bridge_from_q16(cmd->current) : 0.0;
    in.load_torque_Nm = sc->load_torque_Nm;
    if (sc->load_step_t_s > 0.0 || sc->load_step_Nm != 0.0)
        if (tau + 0.5 * dt >= sc->load_step_t_s) in.load_torque_Nm += sc->load_step_Nm;
    if (row) row[HD_COL_LOAD_DIST * stride] = in.load_torque_Nm + s->plant.faults.load_step_Nm;
    if (timed) t1 = now_s();
    hd_plant_step(&s->plant, &in, dt);
    if (timed) {
        t2 = now_s();
        s->t_app_s += t1 - t0;
        s->t_plant_s += t2 - t1;
        s->timed++;
    }
    if (s->timing) s->periods_run++;
    s->load_dist_Nm = in.load_torque_Nm;
    s->k++;
}

void hd_sim_step(hd_sim_t *s, double *row)
{
    sim_step(s, row, 1);
}

int hd_sim_check_diverged(const hd_sim_t *s, char *err, size_t errlen)
{
    if (!hd_plant_diverged(&s->plant)) return 0;
    sim_set_err(err, errlen, "%s: the simulation diverged at t = %.6g s (the plant state is not finite)",
                s->sc.path, (double)(s->k - 1) * s->sc.dt_s);
    return -1;
}

/* Every period; logged row j goes to out[j * row_stride + c * col_stride], c = column
 * (row-major: HD_SIM_NCOL, 1; column-major: 1, n_rows), written in place. */
static int sim_run(hd_sim_t *s, double *out, int64_t row_stride, int64_t col_stride, char *err, size_t errlen)
{
    int64_t D = s->sc.log_decimation, j = 0, m = s->k % D;   /* m = k mod D, counted (no division per period) */
    while (s->k < s->n_periods) {
        int log = m == 0;
        double *r = out + j * row_stride;
        if (++m == D) m = 0;
        sim_step(s, log ? r : NULL, col_stride);
        /* every period, not only logged rows: a diverged plant must stop the run at once */
        if (hd_sim_check_diverged(s, err, errlen)) return -1;
        if (log) {
            /* one check per row: the sum of the columns is finite unless a column is
             * (or the sum overflows, which the column scan below then tells apart) */
            double sum = 0.0;
            for (int32_t c = 0; c < HD_SIM_NCOL; c++) sum += r[c * col_stride];
            for (int32_t c = 0; c < HD_SIM_NCOL && !isfinite(sum); c++) {
                if (!isfinite(r[c * col_stride])) {
                    sim_set_err(err, errlen, "%s: the simulation diverged at t = %.6g s (%s is not finite)",
                            s->sc.path, r[HD_COL_T * col_stride], hd_sim_column_name(c, (int32_t)s->sc.mode));
                    return -1;
                }
            }
            j++;
        }
    }
    return 0;
}

int hd_sim_run(hd_sim_t *s, double *rows, char *err, size_t errlen)
{
    return sim_run(s, rows, HD_SIM_NCOL, 1, err, errlen);
}

int hd_sim_run_columns(hd_sim_t *s, double *cols, char *err, size_t errlen)
{
    return sim_run(s, cols, 1, hd_sim_n_rows(s), err, errlen);
}

/* Stribeck map of both directions (output side, SI) as a JSON object */
static void fe_dirs_json(char *buf, size_t cap, size_t *n, const hd_stribeck_dir_t *pos,
                         const hd_stribeck_dir_t *neg)
{
    const hd_stribeck_dir_t *d[2] = {pos, neg};
    for (int i = 0; i < 2; i++)
        hd_json_add(buf, cap, n, "%s\"%s\": {\"fc_Nm\": %.9g, \"fs_Nm\": %.9g, \"vs_rad_s\": %.9g, "
                    "\"viscous_Nms_per_rad\": %.9g}", i ? ", " : "{", i ? "neg" : "pos",
                    hd_bridge_from_q16(d[i]->fc), hd_bridge_from_q16(d[i]->fs),
                    hd_bridge_vel_out_to_rad_s(d[i]->vs), hd_bridge_from_q16(d[i]->fv) / (2.0 * M_PI));
    hd_json_add(buf, cap, n, "}");
}

/* accepted fits, confidence, common mode and published estimate of the online friction estimator */
static void fe_state_json(char *buf, size_t cap, size_t *n, const hd_fric_est_t *e)
{
    hd_json_add(buf, cap, n, "{\"fits\": [%u, %u], \"confidence\": [%g, %g], \"samples\": %u, \"scale\": %.9g, "
                "\"bias_Nm\": %.9g, \"estimate\": ", (unsigned)e->fits[0], (unsigned)e->fits[1],
                1e-3 * (double)e->conf[0], 1e-3 * (double)e->conf[1], (unsigned)e->samples,
                (double)e->scale / (double)HD_FE_SCALE_ONE, hd_bridge_from_q16(e->bias));
    fe_dirs_json(buf, cap, n, &e->est[HD_FE_DIR_POS], &e->est[HD_FE_DIR_NEG]);
    hd_json_add(buf, cap, n, "}");
}

size_t hd_sim_meta_json(const hd_sim_t *s, char *buf, size_t cap)
{
    size_t n = 0;
    const hd_plant_params *q = &s->prm;
    hd_json_add(buf, cap, &n, "{\n  \"format\": \"hdservo-log\",\n  \"version\": 1,\n  \"source\": \"hdservo-sim\",\n");
    hd_json_add(buf, cap, &n, "  \"scenario\": ");
    hd_json_str(buf, cap, &n, s->sc.path);
    hd_json_add(buf, cap, &n, ",\n  \"scenario_name\": ");
    hd_json_str(buf, cap, &n, s->sc.name);
    hd_json_add(buf, cap, &n, ",\n  \"axis\": ");
    hd_json_str(buf, cap, &n, s->sc.axis);
    hd_json_add(buf, cap, &n, ",\n  \"mode\": \"%s\",\n", hd_scenario_mode_name(s->sc.mode));
    hd_json_add(buf, cap, &n, "  \"gear_ratio\": %.17g,\n", q->ratio);
    hd_json_add(buf, cap, &n, "  \"sample_period_s\": %.17g,\n", s->sc.dt_s * (double)s->sc.log_decimation);
    hd_json_add(buf, cap, &n, "  \"loop_period_s\": %.17g,\n", s->sc.dt_s);
    hd_json_add(buf, cap, &n, "  \"log_decimation\": %ld,\n", (long)s->sc.log_decimation);
    hd_json_add(buf, cap, &n, "  \"duration_s\": %.17g,\n", s->sc.duration_s);
    hd_json_add(buf, cap, &n, "  \"motor_encoder_counts_per_rev\": %lld,\n", 1LL << q->enc_m_bits);
    hd_json_add(buf, cap, &n, "  \"load_encoder_counts_per_rev\": %lld,\n", 1LL << q->enc_l_bits);
    hd_json_add(buf, cap, &n, "  \"firmware_version\": \"hdservo-fw params v%u\",\n", (unsigned)HD_PARAM_VERSION);
    hd_json_add(buf, cap, &n, "  \"od_version\": \"0x%08X\",\n", (unsigned)HD_PARAM_TABLE_HASH);
    hd_json_add(buf, cap, &n, "  \"seed\": %llu,\n", (unsigned long long)s->sc.seed);
    hd_json_add(buf, cap, &n, "  \"effects\": {");
    int first = 1;
    for (size_t i = 0; i < hd_plant_param_count(); i++) {
        const hd_plant_param_desc *d = hd_plant_param_at(i);
        if (!d || d->type != HD_PARAM_BOOL) continue;
        double v = 0.0;
        hd_plant_param_get(q, d->name, &v);
        char name[128];
        size_t nl = strlen(d->name);
        if (nl >= sizeof name) continue;
        memcpy(name, d->name, nl + 1);
        /* "sec.enabled" -> "sec", "sec.x_enabled" -> "sec.x" */
        if (nl > 8 && strcmp(name + nl - 8, ".enabled") == 0) name[nl - 8] = '\0';
        else if (nl > 8 && strcmp(name + nl - 8, "_enabled") == 0) name[nl - 8] = '\0';
        hd_json_add(buf, cap, &n, "%s\n    ", first ? "" : ",");
        hd_json_str(buf, cap, &n, name);
        hd_json_add(buf, cap, &n, ": %s", v != 0.0 ? "true" : "false");
        first = 0;
    }
    hd_json_add(buf, cap, &n, "\n  },\n  \"faults\": [");
    for (int32_t i = 0; i < s->sc.n_faults; i++) {
        const hd_sc_fault_t *f = &s->sc.faults[i];
        hd_json_add(buf, cap, &n, "%s{\"t_s\": %.17g, \"type\": \"%s\"}", i ? ", " : "", f->t_s,
                    hd_scenario_fault_name(f->type));
    }
    hd_json_add(buf, cap, &n, "],\n");
    if (s->app.cb_cfg.fe_on != 0u) {
        hd_json_add(buf, cap, &n, "  \"fric_est\": {\"model\": ");
        fe_dirs_json(buf, cap, &n, &s->app.cb_cfg.str.pos, &s->app.cb_cfg.str.neg);
        if (s->fe_snap_taken) {
            hd_json_add(buf, cap, &n, ",\n    \"run_in_end\": ");
            fe_state_json(buf, cap, &n, &s->fe_snap);
        }
        hd_json_add(buf, cap, &n, ",\n    \"end\": ");
        fe_state_json(buf, cap, &n, &s->app.cb.fe);
        hd_json_add(buf, cap, &n, "},\n");
    }
    hd_json_add(buf, cap, &n, "  \"columns\": [");
    for (int32_t c = 0; c < HD_SIM_NCOL; c++)
        hd_json_add(buf, cap, &n, "%s\"%s\"", c ? ", " : "", hd_sim_column_name(c, (int32_t)s->sc.mode));
    hd_json_add(buf, cap, &n, "]\n}\n");
    return n;
}

int hd_sim_write_log(const hd_sim_t *s, const double *rows, int64_t n_rows, const char *csv_path,
                     char *err, size_t errlen)
{
    const char *names[HD_SIM_NCOL];
    for (int32_t c = 0; c < HD_SIM_NCOL; c++) names[c] = hd_sim_column_name(c, (int32_t)s->sc.mode);
    size_t cap = 64 * 1024;
    char *meta = malloc(cap);
    if (!meta) { sim_set_err(err, errlen, "out of memory"); return -1; }
    hd_sim_meta_json(s, meta, cap);
    int rc = hd_log_write(csv_path, names, HD_SIM_NCOL, rows, n_rows, meta, err, errlen);
    free(meta);
    return rc;
}
