/*
 * test_harness_diverge.c - a plant that diverges (every stiffness at 1e9 N.m/rad with
 * Preisach hysteresis on) ends the run with the one-line "diverged" error instead
 * of a crash (sanitized build: a NaN twist used as a Preisach table index is caught
 * here as UB or a segfault), and the Preisach table look-up refuses a NaN input.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "hd_plant.h"
#include "hd_plant_preisach.h"

/* the reference axis (Preisach on) with every stiffness at 1e9 N.m/rad: the 100 us
 * control period cannot hold the spring, and the state goes to inf/NaN within 0.1 s */
static const char *DIVERGE =
    "[scenario]\nduration_s = 0.2\nseed = 1\nlog_decimation = 7\n"
    "[controller]\nmode = \"position\"\n"
    "[setpoint]\ntype = \"step\"\namplitude_rad = 4.84813681109536e-4\nt0_s = 0.01\n"
    "[plant]\nstiffness.k1_Nm_per_rad = 1e9\nstiffness.k2_Nm_per_rad = 1e9\nstiffness.k3_Nm_per_rad = 1e9\n"
    "stiffness_cubic.k1_Nm_per_rad = 1e9\nstiffness_cubic.k3_Nm_per_rad3 = 1e9\n";

static void test_diverging_run_ends_with_the_diverged_error(void **state)
{
    (void)state;
    hd_scenario_t *sc = malloc(sizeof *sc);
    hd_plant_params prm;
    char err[512];
    assert_non_null(sc);
    assert_int_equal(hd_scenario_parse(DIVERGE, strlen(DIVERGE), "diverge.toml", sc, err, sizeof err), 0);
    assert_int_equal(hd_sim_scenario_params(sc, &prm, err, sizeof err), 0);
    assert_int_equal(prm.preisach_enabled, 1);
    hd_sim_t *s = hd_sim_new(sc, &prm, err, sizeof err);
    assert_non_null(s);
    int64_t n = hd_sim_n_rows(s);
    double *rows = calloc((size_t)n * HD_SIM_NCOL, sizeof *rows);
    assert_non_null(rows);
    err[0] = '\0';
    assert_int_equal(hd_sim_run(s, rows, err, sizeof err), -1);
    assert_non_null(strstr(err, "diverge.toml: the simulation diverged at t = "));
    assert_null(strchr(err, '\n'));
    /* it stopped early, well before the end of the scenario */
    assert_true(hd_sim_n_periods(s) == 2000);
    free(rows);
    hd_sim_free(s);
    free(sc);
}

static void test_plant_flags_divergence_and_holds(void **state)
{
    (void)state;
    hd_plant_params prm;
    hd_plant *p = malloc(sizeof *p);
    char msg[256];
    assert_non_null(p);
    hd_plant_defaults_reference(&prm);
    prm.k1_Nm_per_rad = prm.k2_Nm_per_rad = prm.k3_Nm_per_rad = 1e9;
    prm.cubic_k1_Nm_per_rad = prm.cubic_k3_Nm_per_rad3 = 1e9;
    assert_int_equal(hd_plant_init(p, &prm, 1, msg, sizeof msg), HD_PLANT_OK);
    hd_plant_input in;
    memset(&in, 0, sizeof in);
    in.current_cmd_A = 1.0;
    int k;
    for (k = 0; k < 5000 && !hd_plant_diverged(p); k++) hd_plant_step(p, &in, 1e-4);
    assert_true(hd_plant_diverged(p));
    assert_true(k < 5000);
    /* further steps are harmless and keep the flag */
    for (int j = 0; j < 10; j++) hd_plant_step(p, &in, 1e-4);
    assert_true(hd_plant_diverged(p));
    assert_false(isfinite(p->th_m) && isfinite(p->w_m) && isfinite(p->th_l) && isfinite(p->w_l) &&
                 isfinite(p->i));
    free(p);
}

static void test_preisach_table_refuses_nan(void **state)
{
    (void)state;
    static double E[(HD_PLANT_PREISACH_L + 1) * (HD_PLANT_PREISACH_L + 1)];
    hd_plant_preisach_everett(E, 1e-4, 0.5, 2e-5, 5e-5);
    assert_true(isnan(hd_preisach_E(E, 1e-4, NAN, -1e-4)));
    assert_true(isnan(hd_preisach_E(E, 1e-4, 1e-4, NAN)));
    /* out of range clamps to the table's edge (huge doubles never reach the cast) */
    assert_true(hd_preisach_E(E, 1e-4, 1e300, -1e300) == hd_preisach_E(E, 1e-4, 1e-4, -1e-4));
    assert_true(hd_preisach_E(E, 1e-4, INFINITY, -INFINITY) == hd_preisach_E(E, 1e-4, 1e-4, -1e-4));
    assert_true(fabs(hd_preisach_E(E, 1e-4, 1e-4, -1e-4) - 0.5) < 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_diverging_run_ends_with_the_diverged_error),
        cmocka_unit_test(test_plant_flags_divergence_and_holds),
        cmocka_unit_test(test_preisach_table_refuses_nan),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
