/*
 * test_harness_loop.c - firmware app + plant in lock-step (sanitized build):
 * hal contract kept every period, bit-identical reruns, the setpoint reaches
 * the app and the command reaches the plant, an injected fault reaches the app.
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
#include "hd_app.h"

static const char *STEP =
    "[scenario]\nduration_s = 0.05\nseed = 5\n"
    "[controller]\nmode = \"position\"\n"
    "[setpoint]\ntype = \"step\"\namplitude_rad = 1e-3\nt0_s = 0.005\n";

static double *run(const char *text, hd_sim_t **keep, int64_t *n_out)
{
    hd_scenario_t *sc = malloc(sizeof *sc);
    hd_plant_params prm;
    char err[512];
    assert_int_equal(hd_scenario_parse(text, strlen(text), "loop.toml", sc, err, sizeof err), 0);
    assert_int_equal(hd_sim_scenario_params(sc, &prm, err, sizeof err), 0);
    hd_sim_t *s = hd_sim_new(sc, &prm, err, sizeof err);
    assert_non_null(s);
    int64_t n = hd_sim_n_rows(s);
    double *rows = calloc((size_t)n * HD_SIM_NCOL, sizeof *rows);
    assert_int_equal(hd_sim_run(s, rows, err, sizeof err), 0);
    free(sc);
    *n_out = n;
    if (keep) *keep = s;
    else hd_sim_free(s);
    return rows;
}

static void test_lockstep_contract_and_response(void **state)
{
    (void)state;
    hd_sim_t *s;
    int64_t n;
    double *r = run(STEP, &s, &n);
    assert_int_equal(n, 500);
    assert_int_equal(hd_sim_port_violations(s), 0);   /* one read, one write per period */
    const hd_app_t *app = hd_sim_app(s);
    assert_int_equal(app->tel.tick, 499u);   /* tick of the last period, from 0 */
    assert_int_equal(app->tel.fault, 0);
    /* setpoint reached the app: its position reference is the last setpoint */
    assert_true(app->tel.pos_ref == hd_bridge_rad_to_q32_turns(1e-3));
    /* command reached the plant: it moved towards the setpoint */
    double y = r[(n - 1) * HD_SIM_NCOL + HD_COL_LOAD_TRUE];
    assert_true(y > 0.3e-3);
    /* rows: t = k * 100 us, setpoint column switches at t0 */
    assert_true(r[10 * HD_SIM_NCOL + HD_COL_T] == 10 * 1e-4);
    assert_true(r[49 * HD_SIM_NCOL + HD_COL_SETPOINT] == 0.0);
    assert_true(r[50 * HD_SIM_NCOL + HD_COL_SETPOINT] == 1e-3);
    assert_string_equal(hd_sim_column_name(HD_COL_SETPOINT, HD_SC_MODE_POSITION), "setpoint_rad");
    hd_sim_free(s);
    free(r);
}

static void test_rerun_is_bit_identical(void **state)
{
    (void)state;
    int64_t n1, n2;
    double *a = run(STEP, NULL, &n1);
    double *b = run(STEP, NULL, &n2);
    assert_int_equal(n1, n2);
    assert_memory_equal(a, b, (size_t)n1 * HD_SIM_NCOL * sizeof *a);
    free(a);
    free(b);
}

/* hd_sim_run_columns: the same log as hd_sim_run, column-major (every value equal, bits
 * included), with log decimation and noise on. */
static void test_run_columns_is_transposed_run(void **state)
{
    static const char *NOISY =
        "[scenario]\nduration_s = 0.05\nseed = 9\nlog_decimation = 3\n"
        "[controller]\nmode = \"position\"\n"
        "[setpoint]\ntype = \"step\"\namplitude_rad = 1e-3\nt0_s = 0.005\n";
    (void)state;
    int64_t n;
    double *r = run(NOISY, NULL, &n);
    hd_scenario_t *sc = malloc(sizeof *sc);
    hd_plant_params prm;
    char err[512];
    assert_int_equal(hd_scenario_parse(NOISY, strlen(NOISY), "loop.toml", sc, err, sizeof err), 0);
    assert_int_equal(hd_sim_scenario_params(sc, &prm, err, sizeof err), 0);
    hd_sim_t *s = hd_sim_new(sc, &prm, err, sizeof err);
    assert_non_null(s);
    assert_int_equal(hd_sim_n_rows(s), n);
    assert_true(n > 100);
    double *c = calloc((size_t)n * HD_SIM_NCOL, sizeof *c);
    assert_int_equal(hd_sim_run_columns(s, c, err, sizeof err), 0);
    for (int64_t j = 0; j < n; j++)
        for (int32_t k = 0; k < HD_SIM_NCOL; k++)
            assert_memory_equal(&c[k * n + j], &r[j * HD_SIM_NCOL + k], sizeof(double));
    assert_true(c[HD_COL_T * n + 2] == 2 * 3 * 1e-4);   /* decimated: t = j * D * dt */
    hd_sim_free(s);
    free(sc);
    free(c);
    free(r);
}

static void test_glitch_reaches_app(void **state)
{
    (void)state;
    const char *t =
        "[scenario]\nduration_s = 0.02\n[controller]\nmode = \"position\"\n"
        "[[fault]]\nt_s = 0.01\ntype = \"encoder_glitch\"\nencoder = \"load\"\ncounts = 200000\n";
    hd_sim_t *s;
    int64_t n;
    double *r = run(t, &s, &n);
    assert_int_equal(((const hd_app_t *)hd_sim_app(s))->tel.fault, HD_FAULT_ENC_JUMP);
    /* no fault before the glitch is seen (one period after injection) */
    assert_true(r[100 * HD_SIM_NCOL + HD_COL_FAULT] == 0.0);
    assert_true(r[102 * HD_SIM_NCOL + HD_COL_FAULT] == (double)HD_FAULT_ENC_JUMP);
    hd_sim_free(s);
    free(r);
}

static void test_bridge_rounds_and_saturates(void **state)
{
    (void)state;
    const double turn = 6.283185307179586;
    assert_true(hd_bridge_rad_to_q32_turns(turn) == ((int64_t)1 << 32));
    assert_true(hd_bridge_rad_to_q32_turns(-turn / 4.0) == -((int64_t)1 << 30));
    assert_true(hd_bridge_rad_to_q32_turns(1e30) == INT64_MAX);
    assert_true(hd_bridge_rad_s_to_vel_out(1e9) == INT32_MAX);
    assert_true(hd_bridge_rad_s_to_vel_out(-1e9) == INT32_MIN);
    assert_true(hd_bridge_to_q16(1.5) == 98304);
    assert_true(hd_bridge_to_q16(-0.5 / 65536.0) == 0);   /* round half to even */
    assert_true(hd_bridge_to_q16(NAN) == 0);
    assert_true(hd_bridge_from_q16(65536) == 1.0);
}

/* hd_sim_run: logged rows every log_decimation periods (t = j * D * dt), and a run whose
 * state stops being finite ends with one error naming the time and the column. */
static void test_run_decimation_and_divergence(void **state)
{
    (void)state;
    static const char *DEC =
        "[scenario]\nduration_s = 0.01\nseed = 5\nlog_decimation = 3\n"
        "[controller]\nmode = \"position\"\n"
        "[setpoint]\ntype = \"step\"\namplitude_rad = 1e-3\nt0_s = 0.002\n";
    /* a load inertia far below what one 100 us RK4 step can integrate: unstable, so the
     * states overflow to inf/NaN within a few ms (Preisach off: its table index needs a
     * finite twist) */
    static const char *DIVERGE =
        "[scenario]\nduration_s = 0.05\nseed = 5\nlog_decimation = 2\n"
        "[controller]\nmode = \"position\"\n"
        "[setpoint]\ntype = \"step\"\namplitude_rad = 1e-3\nt0_s = 0.0\n"
        "[plant]\nload.jl_kgm2 = 1e-9\nhysteresis_preisach.enabled = false\n";
    int64_t n;
    double *r = run(DEC, NULL, &n);
    assert_int_equal(n, 34);                          /* periods 0, 3, ..., 99 */
    for (int64_t j = 0; j < n; j++) assert_true(fabs(r[j * HD_SIM_NCOL + HD_COL_T] - (double)(3 * j) * 1e-4) < 1e-12);
    free(r);

    hd_scenario_t *sc = malloc(sizeof *sc);
    hd_plant_params prm;
    char err[512];
    assert_non_null(sc);
    assert_int_equal(hd_scenario_parse(DIVERGE, strlen(DIVERGE), "diverge.toml", sc, err, sizeof err), 0);
    assert_int_equal(hd_sim_scenario_params(sc, &prm, err, sizeof err), 0);
    hd_sim_t *s = hd_sim_new(sc, &prm, err, sizeof err);
    assert_non_null(s);
    n = hd_sim_n_rows(s);
    r = calloc((size_t)n * HD_SIM_NCOL, sizeof *r);
    assert_non_null(r);
    err[0] = '\0';
    assert_int_equal(hd_sim_run(s, r, err, sizeof err), -1);
    assert_non_null(strstr(err, "diverge.toml: the simulation diverged at t = "));
    assert_non_null(strstr(err, " is not finite)"));
    free(r);
    free(sc);
    hd_sim_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lockstep_contract_and_response),
        cmocka_unit_test(test_rerun_is_bit_identical),
        cmocka_unit_test(test_run_columns_is_transposed_run),
        cmocka_unit_test(test_glitch_reaches_app),
        cmocka_unit_test(test_bridge_rounds_and_saturates),
        cmocka_unit_test(test_run_decimation_and_divergence),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
