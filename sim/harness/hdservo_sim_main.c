/*
 * hdservo_sim_main.c - the `hdservo-sim` program.
 *
 *   hdservo-sim run SCENARIO.toml -o LOG.csv [--seed N] [--duration S] [--set KEY=VALUE]... [-q]
 *
 * Runs the firmware application against the simulated axis in lock-step and
 * writes LOG.csv plus its sidecar LOG.json (DESIGN.md section 7).  Errors:
 * one line on stderr, exit status 2, no output file left behind.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "harness.h"
#include "scenario.h"
#include "serve.h"   /* `serve`: the virtual drive over CAN (sim/harness/serve.c) */

static const char *USAGE =
    "usage: hdservo-sim run SCENARIO.toml -o LOG.csv [--seed N] [--duration S] [--set SECTION.KEY=VALUE]... [-q]\n"
    "  Run the drive firmware against the simulated harmonic-drive axis in lock-step\n"
    "  and write the log (CSV, SI units) and its sidecar LOG.json.  See docs/sim.md.\n";

static int fail(const char *msg)
{
    fprintf(stderr, "hdservo-sim: error: %s\n", msg);
    return 2;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmd_run(int argc, char **argv)
{
    const char *scen = NULL, *out = NULL;
    int quiet = 0, have_seed = 0;
    unsigned long long seed = 0;
    double duration = -1.0;
    const char *sets[HD_SC_MAX_OVERRIDES];
    int n_sets = 0;
    char err[2048];
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) {
            if (++i >= argc) return fail("-o needs a file name (LOG.csv)");
            out = argv[i];
        } else if (strcmp(a, "--seed") == 0) {
            char *end;
            if (++i >= argc) return fail("--seed needs a non-negative integer");
            errno = 0;
            seed = strtoull(argv[i], &end, 10);
            if (errno || *end || argv[i][0] == '-' || argv[i][0] == '\0')
                return fail("--seed: expected a non-negative integer");
            have_seed = 1;
        } else if (strcmp(a, "--duration") == 0) {
            char *end;
            if (++i >= argc) return fail("--duration needs seconds");
            duration = strtod(argv[i], &end);
            if (*end || !(duration > 0.0)) return fail("--duration: expected a positive number of seconds");
        } else if (strcmp(a, "--set") == 0) {
            if (++i >= argc) return fail("--set needs SECTION.KEY=VALUE");
            if (n_sets >= HD_SC_MAX_OVERRIDES) return fail("too many --set options");
            sets[n_sets++] = argv[i];
        } else if (strcmp(a, "-q") == 0 || strcmp(a, "--quiet") == 0) {
            quiet = 1;
        } else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            fputs(USAGE, stdout);
            return 0;
        } else if (a[0] == '-' && a[1] != '\0') {
            snprintf(err, sizeof err, "unknown option '%s' (see hdservo-sim --help)", a);
            return fail(err);
        } else if (!scen) {
            scen = a;
        } else {
            snprintf(err, sizeof err, "unexpected argument '%s'", a);
            return fail(err);
        }
    }
    if (!scen) return fail("missing SCENARIO.toml (usage: hdservo-sim run SCENARIO.toml -o LOG.csv)");
    if (!out) return fail("missing -o LOG.csv");

    hd_scenario_t *sc = malloc(sizeof *sc);
    if (!sc) return fail("out of memory");
    if (hd_scenario_load(scen, sc, err, sizeof err)) { free(sc); return fail(err); }
    if (have_seed) sc->seed = seed;
    if (duration > 0.0) {
        if (duration > HD_SC_MAX_DURATION_S) { free(sc); return fail("--duration: too long"); }
        sc->duration_s = duration;
    }
    hd_plant_params prm;
    if (hd_sim_scenario_params(sc, &prm, err, sizeof err)) { free(sc); return fail(err); }
    for (int i = 0; i < n_sets; i++) {
        char key[256];
        const char *eq = strchr(sets[i], '=');
        char *end;
        size_t kl = eq ? (size_t)(eq - sets[i]) : 0;
        double v = eq ? strtod(eq + 1, &end) : 0.0;
        if (eq && (strcmp(eq + 1, "true") == 0 || strcmp(eq + 1, "false") == 0)) {
            v = (eq[1] == 't') ? 1.0 : 0.0;
            end = (char *)eq + strlen(eq);
        }
        if (!eq || kl == 0 || kl >= sizeof key || eq[1] == '\0' || *end != '\0') {
            snprintf(err, sizeof err, "--set %s: expected SECTION.KEY=VALUE (a number or true/false)", sets[i]);
            free(sc);
            return fail(err);
        }
        memcpy(key, sets[i], kl);
        key[kl] = '\0';
        int rc = hd_plant_param_set(&prm, key, v);
        if (rc != HD_PLANT_OK) {
            snprintf(err, sizeof err, "--set %s: %s", sets[i], hd_plant_strerror(rc));
            free(sc);
            return fail(err);
        }
    }
    hd_sim_t *s = hd_sim_new(sc, &prm, err, sizeof err);
    if (!s) { free(sc); return fail(err); }
    int64_t n = hd_sim_n_rows(s);
    double *rows = malloc((size_t)n * HD_SIM_NCOL * sizeof *rows);
    if (!rows) { hd_sim_free(s); free(sc); return fail("out of memory for the log"); }
    double t0 = now_s();
    int rc = hd_sim_run(s, rows, err, sizeof err);
    double wall = now_s() - t0;
    if (rc == 0) rc = hd_sim_write_log(s, rows, n, out, err, sizeof err);
    if (rc == 0 && !quiet) {
        double simt = (double)hd_sim_n_periods(s) * sc->dt_s;
        printf("hdservo-sim: %s: %lld periods (%.6g s simulated) in %.3g s wall (%.0fx real time), %lld rows -> %s\n",
               sc->name, (long long)hd_sim_n_periods(s), simt, wall, wall > 0 ? simt / wall : 0.0,
               (long long)n, out);
    }
    free(rows);
    hd_sim_free(s);
    free(sc);
    return rc == 0 ? 0 : fail(err);
}

int main(int argc, char **argv)
{
    if (argc < 2 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "--help") == 0) {
        fputs(USAGE, argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (strcmp(argv[1], "run") == 0) return cmd_run(argc - 2, argv + 2);
    if (strcmp(argv[1], "serve") == 0) return hd_sim_serve_main(argc - 2, argv + 2);
    char msg[256];
    snprintf(msg, sizeof msg, "unknown command '%.100s' (expected: run)", argv[1]);
    return fail(msg);
}
