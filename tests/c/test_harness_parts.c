/*
 * test_harness_parts.c - the harness pieces that do not need the firmware
 * app: TOML reader, scenario parser and setpoint profiles, host port (CAN
 * rings, NVM flash semantics, contract checks), log writer and bridge.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "hal_host.h"
#include "logwrite.h"
#include "scenario.h"
#include "toml_lite.h"

static int parse(const char *text, hd_toml_doc_t *doc, char *err, size_t n)
{
    return hd_toml_parse(text, strlen(text), "t.toml", doc, err, n);
}

static void test_toml_values(void **state)
{
    (void)state;
    const char *t =
        "# comment\n"
        "top = 1_000\n"
        "[a]\n"
        "x = -2.5e-3  # trailing\n"
        "s = \"q\\\"uote\\n\"\n"
        "lit = 'c:\\path'\n"
        "b = true\n"
        "arr = [1, 2.5,\n  -3, ]\n"
        "names = [\"p\", 'q']\n"
        "sub.key = +inf\n"
        "\"quoted-key\" = false\n"
        "[[fault]]\n"
        "t_s = 0.1\n"
        "[[fault]]\n"
        "t_s = 0.2\r\n";
    hd_toml_doc_t d;
    char err[256];
    assert_int_equal(parse(t, &d, err, sizeof err), 0);
    double v;
    const char *s;
    int b;
    const double *arr;
    size_t n;
    assert_int_equal(hd_toml_get_number(&d, "top", &v, err, sizeof err), 1);
    assert_true(v == 1000.0);
    assert_int_equal(hd_toml_get_number(&d, "a.x", &v, err, sizeof err), 1);
    assert_true(v == -2.5e-3);
    assert_int_equal(hd_toml_get_string(&d, "a.s", &s, err, sizeof err), 1);
    assert_string_equal(s, "q\"uote\n");
    assert_int_equal(hd_toml_get_string(&d, "a.lit", &s, err, sizeof err), 1);
    assert_string_equal(s, "c:\\path");
    assert_int_equal(hd_toml_get_bool(&d, "a.b", &b, err, sizeof err), 1);
    assert_int_equal(b, 1);
    assert_int_equal(hd_toml_get_num_array(&d, "a.arr", &arr, &n, err, sizeof err), 1);
    assert_int_equal(n, 3);
    assert_true(arr[0] == 1.0 && arr[1] == 2.5 && arr[2] == -3.0);
    hd_toml_entry_t *e = hd_toml_find(&d, "a.names");
    assert_non_null(e);
    assert_int_equal(e->type, HD_TOML_STR_ARRAY);
    assert_string_equal(e->sarr[1], "q");
    assert_int_equal(hd_toml_get_number(&d, "a.sub.key", &v, err, sizeof err), 1);
    assert_true(isinf(v) && v > 0);
    assert_int_equal(hd_toml_get_bool(&d, "a.quoted-key", &b, err, sizeof err), 1);
    assert_int_equal(b, 0);
    assert_int_equal(hd_toml_table_count(&d, "fault"), 2);
    assert_int_equal(hd_toml_get_number(&d, "fault.1.t_s", &v, err, sizeof err), 1);
    assert_true(v == 0.2);
    /* wrong type names the place */
    assert_int_equal(hd_toml_get_number(&d, "a.s", &v, err, sizeof err), -1);
    assert_string_equal(err, "t.toml:5:5: a.s: expected a number, found a string");
    /* absent */
    assert_int_equal(hd_toml_get_number(&d, "nope", &v, err, sizeof err), 0);
    /* unused: everything was read except a.names? it was found -> used */
    assert_null(hd_toml_first_unused(&d, "a."));
    hd_toml_free(&d);
}

typedef struct {
    const char *text;
    const char *err;
} bad_case_t;

static void test_toml_errors(void **state)
{
    (void)state;
    static const bad_case_t cases[] = {
        {"x = \n", "t.toml:1:5: expected a value (number, \"string\", true/false or [array]), found end of line"},
        {"x = 1\nx = 2\n", "t.toml:2:1: key 'x' is already defined (line 1)"},
        {"[a\n", "t.toml:1:3: expected ']', found end of line"},
        {"x = \"abc\n", "t.toml:1:9: expected closing '\"' of the string, found end of line"},
        {"x = nan\n", "t.toml:1:5: expected a finite number, found nan"},
        {"x = 1e999\n", "t.toml:1:5: expected a number within the double range"},
        {"x = 012\n", "t.toml:1:5: expected a number without leading zeros"},
        {"x = 1 2\n", "t.toml:1:7: expected end of line, found '2'"},
        {"x = [1, \"a\"]\n", "t.toml:1:9: expected a number (arrays hold one type), found '\"'"},
        {"x = {a = 1}\n", "t.toml:1:5: expected a value (inline tables are not supported), found '{'"},
        {"x = 1__0\n", "t.toml:1:7: expected a digit after '_', found '_'"},
        {"= 3\n", "t.toml:1:1: expected a key (letters, digits, '_', '-' or a quoted name), found '='"},
        {"a = 1\na.b = 2\n", "t.toml:2:1: key 'a.b' is already defined (line 1)"},
        {"x = [1, 2\n", "t.toml:2:1: expected ',' or ']' in the array, found end of file"},
        {"x = truex\n", "t.toml:1:9: expected end of the value, found 'x'"},
        {"x = 1\x01\n", "t.toml:1:6: expected end of the number, found byte 0x01"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        hd_toml_doc_t d;
        char err[256];
        int rc = parse(cases[i].text, &d, err, sizeof err);
        if (rc != -1 || strcmp(err, cases[i].err) != 0)
            fail_msg("case %zu: rc %d err '%s', expected '%s'", i, rc, err, cases[i].err);
        assert_null(strchr(err, '\n'));
        hd_toml_free(&d);
    }
}

/* Robustness: every prefix and a sweep of single-byte mutations of a valid file
 * parse or fail cleanly (ASan/UBSan watch). */
static void test_toml_mutations(void **state)
{
    (void)state;
    const char *base =
        "[scenario]\nname = \"x\" # c\nduration_s = 1.5e-1\n[[fault]]\nt_s = 0.1\narr = [1, 2, 3]\n"
        "\"k\" = 'lit'\nb = false\n";
    size_t n = strlen(base);
    char buf[512];
    char err[256];
    static const char subs[] = "[]\"'#=.,\n\r\\ \t0e+-_x{}\x01\xff";
    for (size_t cut = 0; cut <= n; cut++) {
        hd_toml_doc_t d;
        hd_toml_parse(base, cut, "m.toml", &d, err, sizeof err);
        hd_toml_free(&d);
    }
    for (size_t i = 0; i < n; i++) {
        for (size_t j = 0; j < sizeof subs - 1; j++) {
            memcpy(buf, base, n);
            buf[i] = subs[j];
            hd_toml_doc_t d;
            int rc = hd_toml_parse(buf, n, "m.toml", &d, err, sizeof err);
            if (rc != 0) assert_int_equal(strncmp(err, "m.toml:", 7), 0);
            hd_toml_free(&d);
        }
    }
}

static int scen(const char *text, hd_scenario_t *sc, char *err, size_t n)
{
    return hd_scenario_parse(text, strlen(text), "tests/c/s.toml", sc, err, n);
}

static void test_scenario_parse(void **state)
{
    (void)state;
    hd_scenario_t *sc = malloc(sizeof *sc);
    char err[512];
    const char *t =
        "[scenario]\nduration_s = 0.25\nseed = 9\nlog_decimation = 5\n"
        "[controller]\nmode = \"velocity\"\n[controller.gains]\nvel_kp = 300.0\n"
        "[setpoint]\ntype = \"ramp\"\nrate_rad_s2 = 2.0\nt0_s = 0.1\nt1_s = 0.2\n"
        "[disturbance]\nload_step_Nm = 3\nload_step_t_s = 0.1\nbase_amp_rad = 0.0087\nbase_freq_Hz = 1\n"
        "[plant]\nfriction_motor.enabled = false\nstiffness.k1_Nm_per_rad = 2.9e4\n"
        "[[fault]]\nt_s = 0.2\ntype = \"encoder_dropout\"\nencoder = \"motor\"\nduration_s = 0.01\n"
        "[[fault]]\nt_s = 0.1\ntype = \"load_step\"\ntorque_Nm = 1.5\n";
    assert_int_equal(scen(t, sc, err, sizeof err), 0);
    assert_string_equal(sc->name, "s");
    assert_string_equal(sc->axis, "reference");
    assert_true(sc->duration_s == 0.25);
    assert_int_equal(sc->seed, 9);
    assert_int_equal(sc->log_decimation, 5);
    assert_int_equal(sc->mode, HD_SC_MODE_VELOCITY);
    assert_int_equal(sc->n_gains, 1);
    assert_string_equal(sc->gains[0].key, "vel_kp");
    assert_int_equal(sc->sp.type, HD_SP_RAMP);
    assert_true(sc->sp.rate == 2.0);
    /* ramp: flat before t0, slope, held after t1 */
    assert_true(hd_scenario_setpoint(&sc->sp, 0.05, 1) == 0.0);
    assert_true(fabs(hd_scenario_setpoint(&sc->sp, 0.15, 1) - 0.1) < 1e-12);
    assert_true(fabs(hd_scenario_setpoint(&sc->sp, 0.3, 1) - 0.2) < 1e-12);
    /* plant overrides + base rocking from the disturbance section */
    assert_int_equal(sc->n_over, 6);
    assert_string_equal(sc->over[0].key, "base.enabled");
    assert_string_equal(sc->over[4].key, "friction_motor.enabled");
    assert_true(sc->over[4].value == 0.0);
    /* faults sorted by time */
    assert_int_equal(sc->n_faults, 2);
    assert_int_equal(sc->faults[0].type, HD_FAULT_LOAD_STEP);
    assert_int_equal(sc->faults[1].type, HD_FAULT_ENC_DROPOUT);
    assert_true(sc->load_step_Nm == 3.0);
    free(sc);
}

static void test_scenario_errors(void **state)
{
    (void)state;
    static const bad_case_t cases[] = {
        {"[scenario]\nduration_s = 1\n", "tests/c/s.toml: missing key 'controller.mode'"},
        {"[controller]\nmode = \"position\"\n", "tests/c/s.toml: missing key 'scenario.duration_s' (run length in s)"},
        {"[scenario]\nduration_s = 1\n[controller]\nmode = \"speed\"\n",
         "tests/c/s.toml:4:8: controller.mode: expected one of \"off\" \"torque\" \"velocity\" \"position\" \"stabilise\", found \"speed\""},
        {"[scenario]\nduration_s = 1\nduraton_s = 2\n[controller]\nmode = \"off\"\n",
         "tests/c/s.toml:3:13: scenario.duraton_s: unknown key for this scenario (mode \"off\", setpoint \"constant\"); see docs/sim.md"},
        {"[scenario]\nduration_s = 1\n[controller]\nmode = \"velocity\"\n[setpoint]\ntype = \"step\"\namplitude_rad = 1\n",
         "tests/c/s.toml: missing key 'setpoint.amplitude_rad_s' (step height)"},
        {"[scenario]\nduration_s = -1\n[controller]\nmode = \"off\"\n",
         "tests/c/s.toml:2:14: scenario.duration_s: expected a number in [0.0001, 3600], found -1"},
        {"[scenario]\nduration_s = 1\n[controller]\nmode = \"off\"\n[plant]\nstiffness.k9 = 1\n",
         "tests/c/s.toml:6:16: plant.stiffness.k9: unknown plant parameter (see docs/plant.md)"},
        {"[scenario]\nduration_s = 1\naxis = \"no/such/axis.toml\"\n[controller]\nmode = \"off\"\n",
         "tests/c/s.toml:3:8: scenario.axis: expected an axis file (relative to the scenario or the repository) or \"reference\"/\"minimal\": not found"},
        {"[scenario]\nduration_s = 1\n[controller]\nmode = \"off\"\n[[fault]]\nt_s = 0.1\ntype = \"encoder_glitch\"\nencoder = \"motor\"\n",
         "tests/c/s.toml: missing key 'fault.0.counts' (glitch size)"},
    };
    hd_scenario_t *sc = malloc(sizeof *sc);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char err[512];
        int rc = scen(cases[i].text, sc, err, sizeof err);
        if (rc != -1 || strcmp(err, cases[i].err) != 0)
            fail_msg("case %zu: rc %d err '%s', expected '%s'", i, rc, err, cases[i].err);
    }
    free(sc);
}

static void test_setpoint_profiles(void **state)
{
    (void)state;
    hd_sc_setpoint_t sp;
    memset(&sp, 0, sizeof sp);
    /* move 1 rad, vmax 2, amax 4: triangular? ta = 0.5, da = 0.5 -> 2*da = 1 = D: trapezoid with tc = 0 */
    sp.type = HD_SP_MOVE;
    sp.target = 1.0;
    sp.max_velocity = 2.0;
    sp.max_accel = 4.0;
    assert_true(hd_scenario_setpoint(&sp, 0.0, 0) == 0.0);
    assert_true(fabs(hd_scenario_setpoint(&sp, 0.5, 0) - 0.5) < 1e-12);
    assert_true(hd_scenario_setpoint(&sp, 1.0, 0) == 1.0);
    assert_true(hd_scenario_setpoint(&sp, 5.0, 0) == 1.0);
    /* longer move: cruise at vmax */
    sp.target = -3.0;
    assert_true(fabs(hd_scenario_setpoint(&sp, 1.0, 0) - (-1.5)) < 1e-12);
    assert_true(hd_scenario_setpoint(&sp, 2.0, 0) == -3.0);
    /* prbs: +-amplitude, deterministic, changes only at bit boundaries */
    sp.type = HD_SP_PRBS;
    sp.amplitude = 0.5;
    sp.bit_period_s = 0.01;
    sp.t1_s = 10.0;
    int flips = 0;
    double prev = hd_scenario_setpoint(&sp, 0.0, 42);
    for (int k = 1; k < 1000; k++) {
        double v = hd_scenario_setpoint(&sp, k * 1e-3 + 5e-4, 42);
        assert_true(v == 0.5 || v == -0.5);
        if (k % 10 != 0) assert_true(v == hd_scenario_setpoint(&sp, (k - k % 10) * 1e-3 + 5e-4, 42));
        if (v != prev) flips++;
        prev = v;
    }
    assert_true(flips > 20 && flips < 80);
    /* multisine: rms = amplitude / sqrt(2) over a whole period */
    sp.type = HD_SP_MULTISINE;
    sp.amplitude = 1.0;
    sp.f0_Hz = 1.0;
    sp.f1_Hz = 10.0;
    sp.n_lines = 10;
    double ss = 0.0;
    for (int k = 0; k < 10000; k++) {
        double v = hd_scenario_setpoint(&sp, k * 1e-4, 0);
        ss += v * v;
    }
    assert_true(fabs(sqrt(ss / 10000.0) - sqrt(0.5)) < 1e-3);
}

static void test_port_can_rings(void **state)
{
    (void)state;
    hd_host_port_t *p = malloc(sizeof *p);
    hd_host_port_init(p);
    hd_can_frame_t f, g;
    memset(&f, 0, sizeof f);
    assert_false(hd_host_can_push_rx(&f)); /* nothing bound */
    hd_host_port_bind(p);
    for (uint32_t i = 0; i < HD_HOST_CAN_RING; i++) {
        f.id = 0x600u + i;
        f.dlc = 9; /* clamped to 8 */
        assert_true(hd_host_can_push_rx(&f));
    }
    f.id = 0x7FF;
    assert_false(hd_host_can_push_rx(&f));
    assert_int_equal(p->can_rx.dropped, 1);
    for (uint32_t i = 0; i < HD_HOST_CAN_RING; i++) {
        assert_true(hd_hal_can_recv(&g));
        assert_int_equal(g.id, 0x600u + i);
        assert_int_equal(g.dlc, 8);
    }
    assert_false(hd_hal_can_recv(&g));
    /* drive -> bus */
    f.id = 0x181;
    f.dlc = 2;
    f.data[0] = 0xAB;
    assert_true(hd_hal_can_send(&f));
    assert_true(hd_host_can_pop_tx(&g));
    assert_int_equal(g.id, 0x181);
    assert_int_equal(g.data[0], 0xAB);
    assert_false(hd_host_can_pop_tx(&g));
    hd_host_port_bind(NULL);
    free(p);
}

static void test_port_period_and_nvm(void **state)
{
    (void)state;
    hd_host_port_t *p = malloc(sizeof *p);
    hd_host_port_init(p);
    hd_host_port_bind(p);
    hd_hal_sensors_t s = {123u, 456u, 7, 8, HD_HAL_VALID_ALL}, r;
    hd_host_port_latch(p, &s);
    hd_hal_read_sensors(&r);
    assert_int_equal(r.motor_enc_raw, 123u);
    assert_int_equal(r.output_enc_raw, 456u);
    hd_hal_command_t c = {1000, 2000, 0u};
    hd_hal_write_command(&c);
    assert_int_equal(hd_host_port_command(p)->torque, 0); /* disabled -> zero */
    hd_host_port_end_period(p);
    assert_int_equal(p->violations, 0);
    assert_int_equal(hd_hal_tick(), 1u);
    /* a period without read and write is recorded */
    hd_host_port_latch(p, &s);
    hd_host_port_end_period(p);
    assert_int_equal(p->violations, HD_HOST_VIOL_NO_READ | HD_HOST_VIOL_NO_WRITE);

    /* NVM: erased 0xFF, program erased double-words only, erase pages */
    uint8_t buf[16], back[16];
    assert_int_equal(hd_hal_nvm_size(), HD_HOST_NVM_SIZE);
    assert_int_equal(hd_hal_nvm_read(0, back, 16), 0);
    assert_int_equal(back[5], 0xFF);
    for (int i = 0; i < 16; i++) buf[i] = (uint8_t)i;
    assert_int_equal(hd_hal_nvm_write(8, buf, 16), 0);
    assert_int_equal(hd_hal_nvm_write(8, buf, 8), -3);      /* not erased */
    assert_int_equal(hd_hal_nvm_write(3, buf, 8), -1);      /* misaligned */
    assert_int_equal(hd_hal_nvm_write(HD_HOST_NVM_SIZE - 8, buf, 16), -1); /* out of range */
    assert_int_equal(hd_hal_nvm_read(8, back, 16), 0);
    assert_memory_equal(buf, back, 16);
    assert_int_equal(hd_hal_nvm_erase(100, HD_HOST_NVM_PAGE), -1);
    assert_int_equal(hd_hal_nvm_erase(0, HD_HOST_NVM_PAGE), 0);
    assert_int_equal(hd_hal_nvm_read(8, back, 1), 0);
    assert_int_equal(back[0], 0xFF);

    /* file backing survives a "power cycle" */
    char path[64];
    snprintf(path, sizeof path, "/tmp/hd_nvm_test_%ld.bin", (long)getpid());
    remove(path);
    assert_int_equal(hd_host_nvm_attach_file(p, path), 0);
    assert_int_equal(hd_hal_nvm_write(0, buf, 16), 0);
    hd_host_port_init(p);
    assert_int_equal(hd_hal_nvm_read(0, back, 1), 0);
    assert_int_equal(back[0], 0xFF);
    assert_int_equal(hd_host_nvm_attach_file(p, path), 0);
    assert_int_equal(hd_hal_nvm_read(0, back, 16), 0);
    assert_memory_equal(buf, back, 16);
    remove(path);
    hd_host_port_bind(NULL);
    free(p);
}

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    char *b = calloc(1, 1 << 16);
    size_t n = fread(b, 1, (1 << 16) - 1, f);
    b[n] = '\0';
    fclose(f);
    return b;
}

static void test_log_writer(void **state)
{
    (void)state;
    char csv[96], side[96], err[256];
    snprintf(csv, sizeof csv, "/tmp/hd_log_test_%ld.csv", (long)getpid());
    assert_int_equal(hd_log_sidecar_path(csv, side, sizeof side), 0);
    assert_non_null(strstr(side, ".json"));
    const char *names[] = {"t_s", "x_rad"};
    double rows[] = {0.0, 0.1, 1e-4, 1.0 / 3.0};
    assert_int_equal(hd_log_write(csv, names, 2, rows, 2, "{\"a\": 1}\n", err, sizeof err), 0);
    char *text = slurp(csv);
    assert_non_null(text);
    assert_string_equal(text, "t_s,x_rad\n0,0.10000000000000001\n0.0001,0.33333333333333331\n");
    double back = strtod("0.33333333333333331", NULL);
    assert_true(back == 1.0 / 3.0);
    free(text);
    text = slurp(side);
    assert_string_equal(text, "{\"a\": 1}\n");
    free(text);
    remove(csv);
    remove(side);
    /* non-finite: refused, nothing written */
    rows[3] = NAN;
    assert_int_equal(hd_log_write(csv, names, 2, rows, 2, "{}", err, sizeof err), -1);
    assert_null(fopen(csv, "r"));
    assert_null(fopen(side, "r"));
    /* unwritable directory */
    assert_int_equal(hd_log_write("/nonexistent-dir/x.csv", names, 2, rows, 1, "{}", err, sizeof err), -1);
    assert_non_null(strstr(err, "/nonexistent-dir/x.csv: cannot write"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_toml_values),
        cmocka_unit_test(test_toml_errors),
        cmocka_unit_test(test_toml_mutations),
        cmocka_unit_test(test_scenario_parse),
        cmocka_unit_test(test_scenario_errors),
        cmocka_unit_test(test_setpoint_profiles),
        cmocka_unit_test(test_port_can_rings),
        cmocka_unit_test(test_port_period_and_nvm),
        cmocka_unit_test(test_log_writer),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
