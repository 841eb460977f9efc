/*
 * fuzz_plant.c - the simulated axis (sim/plant) and the closed-loop harness
 * (sim/harness) with in-range extreme parameter values.  The input is not TOML:
 * it is decoded into values for every documented plant parameter (its range's
 * ends, 0, tiny, huge, a log-spread value in range, every effect on or off), a
 * controller mode, a setpoint and input torques; then a short closed-loop run
 * and a short open-loop run of the plant alone.
 * Invariants: no crash and no undefined behaviour (ASan/UBSan); a parameter
 * set is accepted or refused with one message line; an accepted run ends
 * cleanly with finite rows or with the one "the simulation diverged" error;
 * a diverged plant stays diverged and holds its output.
 */
#include <math.h>
#include <string.h>

#include "fuzz_common.h"
#include "harness.h"
#include "hd_plant.h"
#include "scenario.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* a value in [lo, hi] from one selector byte (+ 4 more bytes for the spread) */
static double pick(fz_stream_t *z, double lo, double hi, double def)
{
    const uint8_t sel = fz_u8(z);
    double v;
    switch (sel % 16u) {
    case 0: v = lo; break;
    case 1: v = hi; break;
    case 2: v = 0.0; break;
    case 3: v = 1e-300; break;                 /* tiny */
    case 4: v = 1e-12; break;
    case 5: v = 1e9; break;                    /* huge for a gear */
    case 6: v = 1e15; break;
    case 7: v = -1e9; break;
    case 8: v = def * 10.0; break;
    case 9: v = def * 0.1; break;
    case 10: v = -def; break;
    case 11: {                                 /* log-spread magnitude 1e-15..1e15, either sign */
        const uint32_t u = fz_u32(z);
        v = pow(10.0, -15.0 + 30.0 * (double)(u >> 1) / 2147483647.0) * ((u & 1u) ? -1.0 : 1.0);
        break;
    }
    default: v = def; break;                   /* most parameters keep their value */
    }
    if (v < lo) v = lo;
    if (v > hi) v = hi;
    return v;
}

static void set_params(fz_stream_t *z, hd_plant_params *prm)
{
    for (size_t i = 0; i < hd_plant_param_count(); i++) {
        const hd_plant_param_desc *d = hd_plant_param_at(i);
        double def = 0.0, v;
        FUZZ_ASSERT(d != NULL && hd_plant_param_get(prm, d->name, &def) == HD_PLANT_OK);
        if (d->type == HD_PARAM_BOOL) {
            const uint8_t b = fz_u8(z);
            v = b < 96u ? def : (double)(b & 1u);
        } else if (d->type == HD_PARAM_INT) {
            const uint8_t b = fz_u8(z);
            v = b < 160u ? def : floor(d->min + fmod((double)b, d->max - d->min + 1.0));
        } else {
            v = pick(z, d->min, d->max, def);
        }
        const int rc = hd_plant_param_set(prm, d->name, v);
        FUZZ_ASSERT(rc == HD_PLANT_OK);          /* in range by construction */
    }
}

static void open_loop(fz_stream_t *z, const hd_plant_params *prm)
{
    static hd_plant p;
    char msg[256];
    msg[0] = '\0';
    if (hd_plant_init(&p, prm, fz_u32(z), msg, sizeof msg) != HD_PLANT_OK) {
        FUZZ_ASSERT(msg[0] != '\0' && strchr(msg, '\n') == NULL);
        return;
    }
    hd_plant_input in;
    memset(&in, 0, sizeof in);
    const int n = 1 + fz_u8(z) % 64;
    for (int k = 0; k < n; k++) {
        in.current_cmd_A = (double)fz_i32(z) * 1e-3;
        in.load_torque_Nm = (double)(int8_t)fz_u8(z) * (fz_u8(z) > 200u ? 1e6 : 1.0);
        in.base_rate_rad_s = (double)(int8_t)fz_u8(z) * 0.01;
        const int was = hd_plant_diverged(&p);
        const hd_plant_output before = p.out;
        const hd_plant_output *o = hd_plant_step(&p, &in, k % 7 == 6 ? 1e-3 : 1e-4);
        if (was) {
            FUZZ_ASSERT(hd_plant_diverged(&p));
            FUZZ_ASSERT(memcmp(&before, o, sizeof before) == 0);
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const modes[] = {"position", "velocity", "torque", "off", "stabilise"};
    fz_stream_t z;
    hd_plant_params prm;
    char err[512], text[1024];
    fz_init(&z, data, size);
    if (fz_u8(&z) & 1u) hd_plant_defaults_minimal(&prm);
    else hd_plant_defaults_reference(&prm);
    /* the run's shape first, so that short inputs still choose it */
    const char *mode = modes[fz_u8(&z) % 5u];
    const int periods = 20 + fz_u8(&z) % 120;
    const double amp = ldexp((double)(int8_t)fz_u8(&z), -(int)(fz_u8(&z) % 40u));
    set_params(&z, &prm);

    /* refused sets: one message line, and init refuses them the same way */
    err[0] = '\0';
    if (hd_plant_check(&prm, err, sizeof err) != HD_PLANT_OK) {
        FUZZ_ASSERT(err[0] != '\0' && strchr(err, '\n') == NULL);
        return 0;
    }

    snprintf(text, sizeof text,
             "[scenario]\nduration_s = %.17g\nseed = %u\n[controller]\nmode = \"%s\"\n"
             "[setpoint]\ntype = \"step\"\namplitude_%s = %.17g\nt0_s = 0.001\n",
             periods * 1e-4, (unsigned)fz_u8(&z), mode,
             strcmp(mode, "position") == 0 ? "rad" : strcmp(mode, "torque") == 0 ? "Nm" : "rad_s", amp);
    static hd_scenario_t sc;
    memset(&sc, 0, sizeof sc);
    if (hd_scenario_parse(text, strlen(text), "fuzz.toml", &sc, err, sizeof err) != 0) {
        FUZZ_ASSERT(strchr(err, '\n') == NULL);
        return 0;
    }
    err[0] = '\0';
    hd_sim_t *s = hd_sim_new(&sc, &prm, err, sizeof err);
    if (s == NULL) {
        FUZZ_ASSERT(err[0] != '\0' && strchr(err, '\n') == NULL);
    } else {
        const int64_t n = hd_sim_n_rows(s);
        double *rows = calloc((size_t)n * HD_SIM_NCOL, sizeof *rows);
        FUZZ_ASSERT(rows != NULL);
        err[0] = '\0';
        const int rc = hd_sim_run(s, rows, err, sizeof err);
        if (rc != 0) {
            FUZZ_ASSERT(strstr(err, "fuzz.toml: the simulation diverged at t = ") == err);
            FUZZ_ASSERT(strchr(err, '\n') == NULL);
        } else {
            for (int64_t i = 0; i < n * HD_SIM_NCOL; i++) FUZZ_ASSERT(isfinite(rows[i]));
        }
        free(rows);
        hd_sim_free(s);
    }
    open_loop(&z, &prm);
    return 0;
}
