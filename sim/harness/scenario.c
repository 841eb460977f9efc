/*
 * scenario.c - parse scenario files (see scenario.h, docs/sim.md) and evaluate
 * the setpoint profile.
 */
#include "scenario.h"
#include "sim_err.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "hd_plant.h"
#include "hd_units.h"
#include "toml_lite.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif


const char *hd_scenario_mode_name(hd_sc_mode_t m)
{
    switch (m) {
    case HD_SC_MODE_OFF: return "off";
    case HD_SC_MODE_TORQUE: return "torque";
    case HD_SC_MODE_VELOCITY: return "velocity";
    case HD_SC_MODE_POSITION: return "position";
    case HD_SC_MODE_STABILISE: return "stabilise";
    }
    return "?";
}

const char *hd_scenario_fault_name(hd_fault_type_t f)
{
    switch (f) {
    case HD_FAULT_ENC_GLITCH: return "encoder_glitch";
    case HD_FAULT_ENC_DROPOUT: return "encoder_dropout";
    case HD_FAULT_CURRENT_LIMIT: return "current_limit";
    case HD_FAULT_LOAD_STEP: return "load_step";
    }
    return "?";
}

/* ---- small helpers over the TOML document ------------------------------------- */

typedef struct {
    hd_toml_doc_t *doc;
    char *err;
    size_t errlen;
} ctx_t;

/* number with range check; returns 1 found, 0 absent, -1 error */
static int num(ctx_t *c, const char *key, double lo, double hi, double *out)
{
    hd_toml_entry_t *e = hd_toml_find(c->doc, key);
    if (!e) return 0;
    if (e->type != HD_TOML_NUMBER) {
        hd_toml_entry_error(c->doc, e, c->err, c->errlen, "expected a number");
        return -1;
    }
    if (!(e->num >= lo && e->num <= hi)) {
        char msg[160];
        snprintf(msg, sizeof msg, "expected a number in [%g, %g], found %.17g", lo, hi, e->num);
        hd_toml_entry_error(c->doc, e, c->err, c->errlen, msg);
        return -1;
    }
    *out = e->num;
    return 1;
}

static int integer(ctx_t *c, const char *key, double lo, double hi, int64_t *out)
{
    double v;
    int rc = num(c, key, lo, hi, &v);
    if (rc != 1) return rc;
    if (v != floor(v)) {
        hd_toml_entry_error(c->doc, hd_toml_find(c->doc, key), c->err, c->errlen,
                            "expected an integer");
        return -1;
    }
    *out = (int64_t)v;
    return 1;
}

static int need(ctx_t *c, int rc, const char *key, const char *what)
{
    if (rc == 0) {
        sim_set_err(c->err, c->errlen, "%s: missing key '%s' (%s)", c->doc->file, key, what);
        return -1;
    }
    return rc < 0 ? -1 : 0;
}

static int str(ctx_t *c, const char *key, const char **out)
{
    return hd_toml_get_string(c->doc, key, out, c->err, c->errlen);
}

/* choose one of names[]; returns index or -1 */
static int choice(ctx_t *c, const char *key, const char *const *names, int n, int dflt, int *out)
{
    const char *s = NULL;
    int rc = str(c, key, &s);
    if (rc < 0) return -1;
    if (rc == 0) {
        if (dflt < 0) {
            sim_set_err(c->err, c->errlen, "%s: missing key '%s'", c->doc->file, key);
            return -1;
        }
        *out = dflt;
        return 0;
    }
    for (int i = 0; i < n; i++)
        if (strcmp(s, names[i]) == 0) { *out = i; return 0; }
    char msg[400];
    size_t k = (size_t)snprintf(msg, sizeof msg, "expected one of");
    for (int i = 0; i < n && k < sizeof msg; i++)
        k += (size_t)snprintf(msg + k, sizeof msg - k, " \"%s\"", names[i]);
    if (k < sizeof msg) snprintf(msg + k, sizeof msg - k, ", found \"%s\"", s);
    hd_toml_entry_error(c->doc, hd_toml_find(c->doc, key), c->err, c->errlen, msg);
    return -1;
}

static int copy_str(char *dst, size_t cap, const char *s)
{
    size_t n = strlen(s);
    if (n >= cap) return -1;
    memcpy(dst, s, n + 1);
    return 0;
}

/* ---- sections -------------------------------------------------------------------- */

static const char *const MODES[] = {"off", "torque", "velocity", "position", "stabilise"};
static const char *const SPTYPES[] = {"constant", "step", "ramp", "move", "sine",
                                      "chirp", "multisine", "prbs", "ptp"};
static const char *const FAULTS[] = {"encoder_glitch", "encoder_dropout", "current_limit",
                                     "load_step"};
static const char *const ENCODERS[] = {"motor", "load"};

static double move_time(double d, double vmax, double amax);

/* Optional run-in of a position setpoint: moves through run_in_targets_rad (relative to
 * initial) at run_in_speeds_rad_s, one after another from run_in_t0_s; the last one ends
 * at initial (the setpoint's start) no later than t0_s, so the setpoint is continuous. */
static int parse_run_in(ctx_t *c, hd_scenario_t *sc)
{
    hd_sc_setpoint_t *sp = &sc->sp;
    const double *tg = NULL, *vv = NULL;
    size_t nt = 0, nv = 0;
    int rt = hd_toml_get_num_array(c->doc, "setpoint.run_in_targets_rad", &tg, &nt, c->err, c->errlen);
    int rv = hd_toml_get_num_array(c->doc, "setpoint.run_in_speeds_rad_s", &vv, &nv, c->err, c->errlen);
    double acc = 0.0, t0r = 0.0;
    int ra = num(c, "setpoint.run_in_accel_rad_s2", 1e-12, 1e9, &acc);
    int r0 = num(c, "setpoint.run_in_t0_s", 0.0, HD_SC_MAX_DURATION_S, &t0r);
    if (rt < 0 || rv < 0 || ra < 0 || r0 < 0) return -1;
    if (rt == 0 && rv == 0 && ra == 0 && r0 == 0) return 0;
    const hd_toml_entry_t *e = hd_toml_find(c->doc, rt ? "setpoint.run_in_targets_rad"
                                                       : rv ? "setpoint.run_in_speeds_rad_s"
                                                       : ra ? "setpoint.run_in_accel_rad_s2" : "setpoint.run_in_t0_s");
    if (sc->mode != HD_SC_MODE_POSITION || sp->type == HD_SP_PTP) {
        hd_toml_entry_error(c->doc, e, c->err, c->errlen,
                            "expected a run-in only with controller mode \"position\" and a setpoint other than \"ptp\"");
        return -1;
    }
    if (rt == 0 || rv == 0 || ra == 0) {
        hd_toml_entry_error(c->doc, e, c->err, c->errlen,
                            "expected run_in_targets_rad, run_in_speeds_rad_s and run_in_accel_rad_s2 together");
        return -1;
    }
    if (nt == 0 || nt != nv || nt > HD_SC_MAX_RUN_IN) {
        char msg[160];
        snprintf(msg, sizeof msg, "expected 1..%d run-in targets and as many speeds, found %zu targets and %zu speeds",
                 HD_SC_MAX_RUN_IN, nt, nv);
        hd_toml_entry_error(c->doc, hd_toml_find(c->doc, "setpoint.run_in_targets_rad"), c->err, c->errlen, msg);
        return -1;
    }
    double t = t0r, prev = 0.0;
    for (size_t i = 0; i < nt; i++) {
        if (!(vv[i] > 0.0 && vv[i] < 1e9) || !(fabs(tg[i]) < 1e9)) {
            char msg[160];
            snprintf(msg, sizeof msg, "expected finite targets and speeds > 0, found target %.17g speed %.17g (move %zu)",
                     tg[i], vv[i], i + 1);
            hd_toml_entry_error(c->doc, hd_toml_find(c->doc, "setpoint.run_in_speeds_rad_s"), c->err, c->errlen, msg);
            return -1;
        }
        sp->run_in_target[i] = tg[i];
        sp->run_in_speed[i] = vv[i];
        sp->run_in_start[i] = t;
        t += move_time(tg[i] - prev, vv[i], acc);
        prev = tg[i];
    }
    sp->run_in_start[nt] = t;
    if (tg[nt - 1] != 0.0 || t > sp->t0_s) {
        char msg[200];
        snprintf(msg, sizeof msg, "expected the run-in to end at the setpoint's initial value (last target 0) "
                 "by t0_s = %.6g s, found last target %.6g rad, end %.6g s", sp->t0_s, tg[nt - 1], t);
        hd_toml_entry_error(c->doc, hd_toml_find(c->doc, "setpoint.run_in_targets_rad"), c->err, c->errlen, msg);
        return -1;
    }
    sp->n_run_in = (int32_t)nt;
    sp->run_in_accel = acc;
    sp->run_in_t0_s = t0r;
    return 0;
}

static int parse_setpoint(ctx_t *c, hd_scenario_t *sc)
{
    static const char *const VU[] = {"", "_Nm", "_rad_s", "_rad", "_rad_s"};
    static const char *const RU[] = {"", "_Nm_per_s", "_rad_s2", "_rad_s", "_rad_s2"};
    hd_sc_setpoint_t *sp = &sc->sp;
    const char *vu = VU[sc->mode], *ru = RU[sc->mode];
    char k[96];
    int t = 0;
    const double BIG = 1e9;
    memset(sp, 0, sizeof *sp);
    if (choice(c, "setpoint.type", SPTYPES, 9, 0, &t)) return -1;
    sp->type = (hd_sp_type_t)t;
    if (sc->mode == HD_SC_MODE_OFF) {
        if (sp->type != HD_SP_CONSTANT) {
            hd_toml_entry_error(c->doc, hd_toml_find(c->doc, "setpoint.type"), c->err, c->errlen,
                                "expected no setpoint (or \"constant\") with controller mode \"off\"");
            return -1;
        }
        return 0;
    }
    snprintf(k, sizeof k, "setpoint.initial%s", vu);
    if (num(c, k, -BIG, BIG, &sp->initial) < 0) return -1;
    if (num(c, "setpoint.t0_s", 0.0, HD_SC_MAX_DURATION_S, &sp->t0_s) < 0) return -1;
    switch (sp->type) {
    case HD_SP_CONSTANT:
        break;
    case HD_SP_STEP:
        snprintf(k, sizeof k, "setpoint.amplitude%s", vu);
        if (need(c, num(c, k, -BIG, BIG, &sp->amplitude), k, "step height")) return -1;
        break;
    case HD_SP_RAMP:
        snprintf(k, sizeof k, "setpoint.rate%s", ru);
        if (need(c, num(c, k, -BIG, BIG, &sp->rate), k, "ramp slope")) return -1;
        if (num(c, "setpoint.t1_s", 0.0, HD_SC_MAX_DURATION_S, &sp->t1_s) < 0) return -1;
        break;
    case HD_SP_MOVE:
        if (sc->mode != HD_SC_MODE_POSITION) {
            hd_toml_entry_error(c->doc, hd_toml_find(c->doc, "setpoint.type"), c->err, c->errlen,
                                "expected controller mode \"position\" for a \"move\"");
            return -1;
        }
        if (need(c, num(c, "setpoint.target_rad", -BIG, BIG, &sp->target), "setpoint.target_rad",
                 "end position") ||
            need(c, num(c, "setpoint.max_velocity_rad_s", 1e-12, BIG, &sp->max_velocity),
                 "setpoint.max_velocity_rad_s", "> 0") ||
            need(c, num(c, "setpoint.max_accel_rad_s2", 1e-12, BIG, &sp->max_accel),
                 "setpoint.max_accel_rad_s2", "> 0"))
            return -1;
        break;
    case HD_SP_PTP:
        if (sc->mode != HD_SC_MODE_POSITION) {
            hd_toml_entry_error(c->doc, hd_toml_find(c->doc, "setpoint.type"), c->err, c->errlen,
                                "expected controller mode \"position\" for a \"ptp\"");
            return -1;
        }
        if (need(c, num(c, "setpoint.target_rad", -BIG, BIG, &sp->target), "setpoint.target_rad",
                 "end position"))
            return -1;
        break;
    case HD_SP_SINE:
        snprintf(k, sizeof k, "setpoint.amplitude%s", vu);
        if (need(c, num(c, k, -BIG, BIG, &sp->amplitude), k, "sine amplitude")) return -1;
        if (need(c, num(c, "setpoint.frequency_Hz", 0.0, 1e5, &sp->frequency_Hz),
                 "setpoint.frequency_Hz", "sine frequency")) return -1;
        if (num(c, "setpoint.phase_rad", -BIG, BIG, &sp->phase_rad) < 0) return -1;
        break;
    case HD_SP_CHIRP:
    case HD_SP_MULTISINE: {
        snprintf(k, sizeof k, "setpoint.amplitude%s", vu);
        if (need(c, num(c, k, -BIG, BIG, &sp->amplitude), k, "excitation amplitude")) return -1;
        if (need(c, num(c, "setpoint.f0_Hz", 0.0, 1e5, &sp->f0_Hz), "setpoint.f0_Hz", "start frequency") ||
            need(c, num(c, "setpoint.f1_Hz", 0.0, 1e5, &sp->f1_Hz), "setpoint.f1_Hz", "end frequency"))
            return -1;
        if (num(c, "setpoint.t1_s", 0.0, HD_SC_MAX_DURATION_S, &sp->t1_s) < 0) return -1;
        if (sp->type == HD_SP_MULTISINE) {
            int64_t n = 0;
            if (need(c, integer(c, "setpoint.lines", 1, 4096, &n), "setpoint.lines", "number of lines"))
                return -1;
            sp->n_lines = (int32_t)n;
        }
        break;
    }
    case HD_SP_PRBS:
        snprintf(k, sizeof k, "setpoint.amplitude%s", vu);
        if (need(c, num(c, k, -BIG, BIG, &sp->amplitude), k, "prbs amplitude")) return -1;
        if (need(c, num(c, "setpoint.bit_period_s", 1e-4, 1e4, &sp->bit_period_s),
                 "setpoint.bit_period_s", "bit period")) return -1;
        if (num(c, "setpoint.t1_s", 0.0, HD_SC_MAX_DURATION_S, &sp->t1_s) < 0) return -1;
        break;
    }
    if (parse_run_in(c, sc)) return -1;
    /* excitation ends at the end of the run unless told */
    if ((sp->type == HD_SP_CHIRP || sp->type == HD_SP_MULTISINE || sp->type == HD_SP_PRBS) &&
        sp->t1_s <= 0.0)
        sp->t1_s = sc->duration_s;
    if ((sp->type == HD_SP_CHIRP || sp->type == HD_SP_MULTISINE) && sp->t1_s <= sp->t0_s) {
        sim_set_err(c->err, c->errlen, "%s: setpoint: expected t1_s > t0_s", c->doc->file);
        return -1;
    }
    return 0;
}

static int add_override(ctx_t *c, hd_sc_override_t *list, int32_t *n, const char *key,
                        const hd_toml_entry_t *e, double v)
{
    if (*n >= HD_SC_MAX_OVERRIDES) {
        hd_toml_entry_error(c->doc, e, c->err, c->errlen, "too many overrides");
        return -1;
    }
    if (copy_str(list[*n].key, sizeof list[*n].key, key)) {
        hd_toml_entry_error(c->doc, e, c->err, c->errlen, "key too long");
        return -1;
    }
    list[*n].value = v;
    list[*n].line = e->line;
    (*n)++;
    return 0;
}

static int parse_plant(ctx_t *c, hd_scenario_t *sc)
{
    hd_plant_params scratch;
    hd_plant_defaults_reference(&scratch);
    for (size_t i = 0; i < c->doc->n; i++) {
        hd_toml_entry_t *e = &c->doc->e[i];
        if (strncmp(e->key, "plant.", 6) != 0) continue;
        e->used = 1;
        const char *key = e->key + 6;
        double v;
        if (e->type == HD_TOML_NUMBER) v = e->num;
        else if (e->type == HD_TOML_BOOL) v = e->boolean ? 1.0 : 0.0;
        else {
            hd_toml_entry_error(c->doc, e, c->err, c->errlen, "expected a number or true/false");
            return -1;
        }
        int rc = hd_plant_param_set(&scratch, key, v);
        if (rc != HD_PLANT_OK) {
            char msg[200];
            const hd_plant_param_desc *d = hd_plant_param_find(key);
            if (rc == HD_PLANT_EUNKNOWN)
                snprintf(msg, sizeof msg, "unknown plant parameter (see docs/plant.md)");
            else if (d)
                snprintf(msg, sizeof msg, "%s: expected %s in [%g, %g] %s", hd_plant_strerror(rc),
                         d->type == HD_PARAM_BOOL ? "true/false" :
                         d->type == HD_PARAM_INT ? "an integer" : "a number",
                         d->min, d->max, d->unit);
            else
                snprintf(msg, sizeof msg, "%s", hd_plant_strerror(rc));
            hd_toml_entry_error(c->doc, e, c->err, c->errlen, msg);
            return -1;
        }
        if (add_override(c, sc->over, &sc->n_over, key, e, v)) return -1;
    }
    return 0;
}

static int parse_disturbance(ctx_t *c, hd_scenario_t *sc)
{
    const double BIG = 1e6;
    if (num(c, "disturbance.load_torque_Nm", -BIG, BIG, &sc->load_torque_Nm) < 0) return -1;
    int a = num(c, "disturbance.load_step_Nm", -BIG, BIG, &sc->load_step_Nm);
    int b = num(c, "disturbance.load_step_t_s", 0.0, HD_SC_MAX_DURATION_S, &sc->load_step_t_s);
    if (a < 0 || b < 0) return -1;
    if (a != b) {
        sim_set_err(c->err, c->errlen, "%s: disturbance: expected load_step_Nm and load_step_t_s together",
                c->doc->file);
        return -1;
    }
    double amp = 0.0, f = 0.0, ph = 0.0;
    a = num(c, "disturbance.base_amp_rad", -10.0, 10.0, &amp);
    b = num(c, "disturbance.base_freq_Hz", 0.0, 1000.0, &f);
    int p = num(c, "disturbance.base_phase_rad", -BIG, BIG, &ph);
    if (a < 0 || b < 0 || p < 0) return -1;
    if (a != b) {
        sim_set_err(c->err, c->errlen, "%s: disturbance: expected base_amp_rad and base_freq_Hz together",
                c->doc->file);
        return -1;
    }
    if (a == 1) {
        /* base rocking through the plant's own generator (exact inside sub-steps) */
        hd_toml_entry_t *e = hd_toml_find(c->doc, "disturbance.base_amp_rad");
        if (add_override(c, sc->over, &sc->n_over, "base.enabled", e, 1.0) ||
            add_override(c, sc->over, &sc->n_over, "base.amplitude_rad", e, amp) ||
            add_override(c, sc->over, &sc->n_over, "base.frequency_Hz", e, f) ||
            add_override(c, sc->over, &sc->n_over, "base.phase_rad", e, ph))
            return -1;
    }
    return 0;
}

static int parse_faults(ctx_t *c, hd_scenario_t *sc)
{
    size_t n = hd_toml_table_count(c->doc, "fault");
    if (n > HD_SC_MAX_FAULTS) {
        sim_set_err(c->err, c->errlen, "%s: too many [[fault]] tables (at most %d)", c->doc->file,
                HD_SC_MAX_FAULTS);
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        hd_sc_fault_t *f = &sc->faults[i];
        char k[64], kt[64];
        int t = 0;
        memset(f, 0, sizeof *f);
        snprintf(kt, sizeof kt, "fault.%zu.type", i);
        if (choice(c, kt, FAULTS, 4, -1, &t)) return -1;
        f->type = (hd_fault_type_t)t;
        f->line = hd_toml_find(c->doc, kt)->line;
        snprintf(k, sizeof k, "fault.%zu.t_s", i);
        if (need(c, num(c, k, 0.0, HD_SC_MAX_DURATION_S, &f->t_s), k, "time of the fault")) return -1;
        f->limit_A = -1.0;
        switch (f->type) {
        case HD_FAULT_ENC_GLITCH:
        case HD_FAULT_ENC_DROPOUT: {
            int enc = 0;
            snprintf(k, sizeof k, "fault.%zu.encoder", i);
            if (choice(c, k, ENCODERS, 2, -1, &enc)) return -1;
            f->encoder = enc;
            if (f->type == HD_FAULT_ENC_GLITCH) {
                snprintf(k, sizeof k, "fault.%zu.counts", i);
                if (need(c, integer(c, k, -2147483648.0, 2147483647.0, &f->counts), k, "glitch size"))
                    return -1;
            } else {
                snprintf(k, sizeof k, "fault.%zu.duration_s", i);
                if (need(c, num(c, k, 1e-4, HD_SC_MAX_DURATION_S, &f->duration_s), k, "dropout length"))
                    return -1;
            }
            break;
        }
        case HD_FAULT_CURRENT_LIMIT:
            snprintf(k, sizeof k, "fault.%zu.limit_A", i);
            if (need(c, num(c, k, -1.0, 1e4, &f->limit_A), k, "current limit, A (< 0 removes)")) return -1;
            break;
        case HD_FAULT_LOAD_STEP:
            snprintf(k, sizeof k, "fault.%zu.torque_Nm", i);
            if (need(c, num(c, k, -1e6, 1e6, &f->torque_Nm), k, "load torque step, N.m")) return -1;
            break;
        }
    }
    sc->n_faults = (int32_t)n;
    /* stable insertion sort by time */
    for (int32_t i = 1; i < sc->n_faults; i++) {
        hd_sc_fault_t x = sc->faults[i];
        int32_t j = i - 1;
        while (j >= 0 && sc->faults[j].t_s > x.t_s) {
            sc->faults[j + 1] = sc->faults[j];
            j--;
        }
        sc->faults[j + 1] = x;
    }
    return 0;
}

static int file_exists(const char *p);

/* A file given relative to the scenario's directory or one of its ancestors (or absolute). 0 found. */
static int find_rel_file(const char *scenario_path, const char *given, char *out, size_t outlen)
{
    char dir[HD_SC_PATH_MAX];
    char cand[2 * HD_SC_PATH_MAX + 2];
    if (given[0] == '/') return (file_exists(given) && !copy_str(out, outlen, given)) ? 0 : -1;
    if (copy_str(dir, sizeof dir, scenario_path)) return -1;
    char *slash = strrchr(dir, '/');
    if (slash) *slash = '\0';
    else copy_str(dir, sizeof dir, ".");
    for (int depth = 0; depth < 16; depth++) {
        snprintf(cand, sizeof cand, "%s/%s", dir, given);
        if (file_exists(cand)) return copy_str(out, outlen, cand) ? -1 : 0;
        if (strlen(dir) + 4 >= sizeof dir) break;
        strcat(dir, "/..");
    }
    return (file_exists(given) && !copy_str(out, outlen, given)) ? 0 : -1;
}

static int parse_controller(ctx_t *c, hd_scenario_t *sc)
{
    int m = 0;
    if (choice(c, "controller.mode", MODES, 5, -1, &m)) return -1;
    sc->mode = (hd_sc_mode_t)m;
    hd_toml_entry_t *g = hd_toml_find(c->doc, "controller.gains");
    if (g && !(g->type == HD_TOML_STRING && strcmp(g->str, "defaults") == 0)) {
        hd_toml_entry_error(c->doc, g, c->err, c->errlen,
                            "expected \"defaults\" (or a [controller.gains] table of overrides)");
        return -1;
    }
    for (size_t i = 0; i < c->doc->n; i++) {
        hd_toml_entry_t *e = &c->doc->e[i];
        if (strncmp(e->key, "controller.gains.", 17) != 0) continue;
        e->used = 1;
        if (e->type != HD_TOML_NUMBER) {
            hd_toml_entry_error(c->doc, e, c->err, c->errlen, "expected a number");
            return -1;
        }
        if (add_override(c, sc->gains, &sc->n_gains, e->key + 17, e, e->num)) return -1;
    }
    hd_toml_entry_t *cp = hd_toml_find(c->doc, "controller.compensators");
    if (cp) {
        if (cp->type != HD_TOML_STR_ARRAY && !(cp->type == HD_TOML_NUM_ARRAY && cp->n == 0)) {
            hd_toml_entry_error(c->doc, cp, c->err, c->errlen, "expected an array of names");
            return -1;
        }
        if (cp->n > HD_SC_MAX_COMP) {
            hd_toml_entry_error(c->doc, cp, c->err, c->errlen, "too many compensators");
            return -1;
        }
        for (size_t i = 0; i < cp->n && cp->type == HD_TOML_STR_ARRAY; i++) {
            if (copy_str(sc->comp[i], sizeof sc->comp[i], cp->sarr[i])) {
                hd_toml_entry_error(c->doc, cp, c->err, c->errlen, "compensator name too long");
                return -1;
            }
        }
        sc->n_comp = (cp->type == HD_TOML_STR_ARRAY) ? (int32_t)cp->n : 0;
    }
    /* controller.preisach_table = file (same as [compensators.preisach] table) */
    hd_toml_entry_t *pt = hd_toml_find(c->doc, "controller.preisach_table");
    if (pt) {
        pt->used = 1;
        if (pt->type != HD_TOML_STRING || find_rel_file(sc->path, pt->str, sc->comp_table, sizeof sc->comp_table)) {
            hd_toml_entry_error(c->doc, pt, c->err, c->errlen,
                                "expected a Preisach table file (relative to the scenario or the repository)");
            return -1;
        }
    }
    /* [compensators.<name>]: drive parameters (appended to the gains), preisach.table = file */
    for (size_t i = 0; i < c->doc->n; i++) {
        hd_toml_entry_t *e = &c->doc->e[i];
        if (strncmp(e->key, "compensators.", 13) != 0) continue;
        const char *dot = strchr(e->key + 13, '.');
        e->used = 1;
        if (!dot || dot == e->key + 13 || dot[1] == '\0') {
            hd_toml_entry_error(c->doc, e, c->err, c->errlen, "expected [compensators.<name>] key = value");
            return -1;
        }
        if (strcmp(e->key, "compensators.preisach.table") == 0) {
            if (e->type != HD_TOML_STRING || find_rel_file(sc->path, e->str, sc->comp_table, sizeof sc->comp_table)) {
                hd_toml_entry_error(c->doc, e, c->err, c->errlen,
                                    "expected a Preisach table file (relative to the scenario or the repository)");
                return -1;
            }
            continue;
        }
        if (e->type != HD_TOML_NUMBER) {
            hd_toml_entry_error(c->doc, e, c->err, c->errlen, "expected a number (drive parameter, table unit)");
            return -1;
        }
        if (add_override(c, sc->gains, &sc->n_gains, dot + 1, e, e->num)) return -1;
    }
    return 0;
}

static int file_exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

/* Axis file: "reference"/"minimal" (built in), absolute, relative to the
 * scenario file's directory, or relative to one of its ancestors (repo root). */
static int resolve_axis(ctx_t *c, hd_scenario_t *sc, const char *given, const hd_toml_entry_t *e)
{
    if (strcmp(given, "reference") == 0 || strcmp(given, "minimal") == 0)
        return copy_str(sc->axis, sizeof sc->axis, given);
    if (given[0] == '/') {
        if (file_exists(given)) return copy_str(sc->axis, sizeof sc->axis, given);
    } else {
        char dir[HD_SC_PATH_MAX];
        char cand[2 * HD_SC_PATH_MAX + 2];
        if (copy_str(dir, sizeof dir, sc->path)) return -1;
        char *slash = strrchr(dir, '/');
        if (slash) *slash = '\0';
        else copy_str(dir, sizeof dir, ".");
        for (int depth = 0; depth < 16; depth++) {
            snprintf(cand, sizeof cand, "%s/%s", dir, given);
            if (file_exists(cand)) {
                if (copy_str(sc->axis, sizeof sc->axis, cand)) break;
                return 0;
            }
            size_t dl = strlen(dir);
            if (dl + 4 >= sizeof dir) break;
            strcat(dir, "/..");
        }
        if (file_exists(given)) return copy_str(sc->axis, sizeof sc->axis, given);
    }
    hd_toml_entry_error(c->doc, e, c->err, c->errlen,
                        "expected an axis file (relative to the scenario or the repository) "
                        "or \"reference\"/\"minimal\": not found");
    return -1;
}

static int parse_doc(hd_toml_doc_t *doc, hd_scenario_t *sc, char *err, size_t errlen)
{
    ctx_t c = {doc, err, errlen};
    const char *s = NULL;
    int rc;
    sc->dt_s = 1.0 / (double)HD_LOOP_HZ;
    sc->log_decimation = 1;
    sc->seed = 1;
    rc = str(&c, "scenario.name", &s);
    if (rc < 0) return -1;
    if (rc == 1 && copy_str(sc->name, sizeof sc->name, s)) {
        sim_set_err(err, errlen, "%s: scenario.name too long", doc->file);
        return -1;
    }
    if (rc == 0) {
        const char *base = strrchr(sc->path, '/');
        base = base ? base + 1 : sc->path;
        size_t bl = strlen(base);
        if (bl >= sizeof sc->name) bl = sizeof sc->name - 1;
        memcpy(sc->name, base, bl);
        sc->name[bl] = '\0';
        char *dot = strrchr(sc->name, '.');
        if (dot) *dot = '\0';
    }
    rc = str(&c, "scenario.axis", &s);
    if (rc < 0) return -1;
    if (rc == 0) s = "reference";
    if (resolve_axis(&c, sc, s, hd_toml_find(doc, "scenario.axis"))) return -1;
    if (need(&c, num(&c, "scenario.duration_s", sc->dt_s, HD_SC_MAX_DURATION_S, &sc->duration_s),
             "scenario.duration_s", "run length in s"))
        return -1;
    int64_t v = 1;
    if (integer(&c, "scenario.seed", 0.0, 9007199254740992.0, &v) < 0) return -1;
    sc->seed = (uint64_t)v;
    v = 1;
    if (integer(&c, "scenario.log_decimation", 1.0, 1e6, &v) < 0) return -1;
    sc->log_decimation = (int32_t)v;
    if (parse_controller(&c, sc)) return -1;
    if (parse_setpoint(&c, sc)) return -1;
    if (parse_disturbance(&c, sc)) return -1;
    if (parse_plant(&c, sc)) return -1;
    if (parse_faults(&c, sc)) return -1;
    const hd_toml_entry_t *u = hd_toml_first_unused(doc, NULL);
    if (u) {
        char msg[160];
        snprintf(msg, sizeof msg, "unknown key for this scenario (mode \"%s\", setpoint \"%s\"); see docs/sim.md",
                 hd_scenario_mode_name(sc->mode), SPTYPES[sc->sp.type]);
        hd_toml_entry_error(doc, u, err, errlen, msg);
        return -1;
    }
    return 0;
}

int hd_scenario_parse(const char *text, size_t len, const char *fname, hd_scenario_t *sc,
                      char *err, size_t errlen)
{
    hd_toml_doc_t doc;
    memset(sc, 0, sizeof *sc);
    if (!fname) fname = "<scenario>";
    if (copy_str(sc->path, sizeof sc->path, fname)) {
        sim_set_err(err, errlen, "%s: path too long", fname);
        return -1;
    }
    if (hd_toml_parse(text, len, fname, &doc, err, errlen)) return -1;
    int rc = parse_doc(&doc, sc, err, errlen);
    hd_toml_free(&doc);
    return rc;
}

int hd_scenario_load(const char *path, hd_scenario_t *sc, char *err, size_t errlen)
{
    hd_toml_doc_t doc;
    memset(sc, 0, sizeof *sc);
    if (copy_str(sc->path, sizeof sc->path, path)) {
        sim_set_err(err, errlen, "%s: path too long", path);
        return -1;
    }
    if (hd_toml_load(path, &doc, err, errlen)) return -1;
    int rc = parse_doc(&doc, sc, err, errlen);
    hd_toml_free(&doc);
    return rc;
}

/* ---- setpoint profile ------------------------------------------------------------ */

static uint64_t splitmix64(uint64_t x)
{
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

/* trapezoidal (or triangular) move of signed distance d, from rest to rest */
static double move_pos(double d, double vmax, double amax, double tau)
{
    double s = d < 0 ? -1.0 : 1.0, D = fabs(d);
    double ta = vmax / amax;
    double da = 0.5 * amax * ta * ta;
    double tc, total;
    if (2.0 * da > D) { /* triangular */
        ta = sqrt(D / amax);
        vmax = amax * ta;
        da = 0.5 * D;
        tc = 0.0;
    } else {
        tc = (D - 2.0 * da) / vmax;
    }
    total = 2.0 * ta + tc;
    if (tau <= 0.0) return 0.0;
    if (tau >= total) return d;
    double x;
    if (tau < ta) x = 0.5 * amax * tau * tau;
    else if (tau < ta + tc) x = da + vmax * (tau - ta);
    else {
        double r = total - tau;
        x = D - 0.5 * amax * r * r;
    }
    return s * x;
}

/* duration of move_pos's move of signed distance d */
static double move_time(double d, double vmax, double amax)
{
    double D = fabs(d), ta = vmax / amax;
    if (amax * ta * ta > D) return 2.0 * sqrt(D / amax);   /* triangular */
    return 2.0 * ta + (D - amax * ta * ta) / vmax;
}

/* run-in position at t (before t0): the move under way (binary search), else where the last ended */
static double run_in_pos(const hd_sc_setpoint_t *sp, double t)
{
    const int32_t n = sp->n_run_in;
    if (t < sp->run_in_start[0]) return sp->initial;
    if (t >= sp->run_in_start[n]) return sp->initial + sp->run_in_target[n - 1];
    int32_t lo = 0, hi = n - 1;              /* start[lo] <= t < start[hi + 1] */
    while (lo < hi) {
        int32_t mid = (lo + hi + 1) / 2;
        if (sp->run_in_start[mid] <= t) lo = mid;
        else hi = mid - 1;
    }
    double from = lo > 0 ? sp->run_in_target[lo - 1] : 0.0;
    return sp->initial + from + move_pos(sp->run_in_target[lo] - from, sp->run_in_speed[lo], sp->run_in_accel,
                                         t - sp->run_in_start[lo]);
}

double hd_scenario_setpoint(const hd_sc_setpoint_t *sp, double t, uint64_t seed)
{
    double tau = t - sp->t0_s;
    if (tau < 0.0) return sp->n_run_in > 0 ? run_in_pos(sp, t) : sp->initial;
    switch (sp->type) {
    case HD_SP_CONSTANT:
        return sp->initial;
    case HD_SP_STEP:
        return sp->initial + sp->amplitude;
    case HD_SP_RAMP: {
        double te = (sp->t1_s > sp->t0_s && t > sp->t1_s) ? sp->t1_s - sp->t0_s : tau;
        return sp->initial + sp->rate * te;
    }
    case HD_SP_PTP:
        return sp->target;
    case HD_SP_MOVE:
        return sp->initial + move_pos(sp->target - sp->initial, sp->max_velocity, sp->max_accel, tau);
    case HD_SP_SINE:
        return sp->initial + sp->amplitude * (sin(2.0 * M_PI * sp->frequency_Hz * tau + sp->phase_rad) -
                                              sin(sp->phase_rad));
    case HD_SP_CHIRP: {
        if (t >= sp->t1_s) return sp->initial;
        double T = sp->t1_s - sp->t0_s;
        double ph = 2.0 * M_PI * (sp->f0_Hz * tau + 0.5 * (sp->f1_Hz - sp->f0_Hz) * tau * tau / T);
        return sp->initial + sp->amplitude * sin(ph);
    }
    case HD_SP_MULTISINE: {
        if (t >= sp->t1_s) return sp->initial;
        int32_t n = sp->n_lines;
        double y = 0.0;
        for (int32_t k = 0; k < n; k++) {
            double f = (n == 1) ? sp->f0_Hz : sp->f0_Hz + (sp->f1_Hz - sp->f0_Hz) * (double)k / (double)(n - 1);
            double ph = -M_PI * (double)k * (double)(k + 1) / (double)n; /* Schroeder */
            y += sin(2.0 * M_PI * f * tau + ph);
        }
        return sp->initial + sp->amplitude * y / sqrt((double)n);
    }
    case HD_SP_PRBS: {
        if (t >= sp->t1_s) return sp->initial;
        uint64_t bit = (uint64_t)(tau / sp->bit_period_s);
        uint64_t h = splitmix64(seed ^ splitmix64(bit + 0x5eedull));
        return sp->initial + ((h >> 63) ? sp->amplitude : -sp->amplitude);
    }
    }
    return sp->initial;
}
