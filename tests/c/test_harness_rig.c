/*
 * test_harness_rig.c - the test rig's command channel (sim/harness/rig.c): each
 * command parsed with its values, bad values and extra words refused with one
 * line, lines assembled from arbitrary chunks, overlong lines discarded.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <string.h>

#include "rig.h"

static hd_rig_cmd_t parse(const char *text)
{
    static char line[HD_RIG_LINE_MAX];
    hd_rig_cmd_t c;
    snprintf(line, sizeof line, "%s", text);
    hd_rig_parse(line, &c);
    return c;
}

static void test_commands_and_values(void **state)
{
    (void)state;
    hd_rig_cmd_t c = parse("brake 1");
    assert_int_equal(c.kind, HD_RIG_BRAKE);
    assert_int_equal(c.on, 1);
    c = parse("torque -1.5\t20\r");
    assert_int_equal(c.kind, HD_RIG_TORQUE);
    assert_true(c.torque_Nm == -1.5 && c.rate_Nm_s == 20.0);
    c = parse("then 2 0.5");
    assert_int_equal(c.kind, HD_RIG_THEN);
    assert_true(c.torque_Nm == 2.0 && c.rate_Nm_s == 0.5);
    c = parse("record out.csv 10");
    assert_int_equal(c.kind, HD_RIG_RECORD);
    assert_string_equal(c.path, "out.csv");
    assert_int_equal(c.decimation, 10);
    assert_int_equal(parse("record stop").kind, HD_RIG_RECORD_STOP);
    c = parse("can drop 0.25 7");
    assert_int_equal(c.kind, HD_RIG_CAN_DROP);
    assert_true(c.probability == 0.25 && c.has_seed && c.seed == 7u);
    c = parse("can errors 16 3");
    assert_int_equal(c.kind, HD_RIG_CAN_ERRORS);
    assert_true(c.tx_errors == 16u && c.rx_errors == 3u);
    assert_int_equal(parse("can busoff").kind, HD_RIG_CAN_BUSOFF);
    assert_int_equal(parse("can status").kind, HD_RIG_CAN_STATUS);
    assert_int_equal(parse("status").kind, HD_RIG_STATUS);
    assert_int_equal(parse("  \t ").kind, HD_RIG_NONE);
}

static void test_bad_input_is_one_error_line(void **state)
{
    (void)state;
    static const char *const bad[] = {
        "torque nan", "torque 1 -1", "torque inf", "then 1 0", "then x 1", "record f 0", "record f 2000000",
        "can drop 1.5", "can drop 0.5 -1", "can errors 1001 0", "brake 2", "bogus",
        /* extra words are refused, not ignored */
        "can errors 1 2 3", "can drop 0.5 7 9", "brake 1 0", "status now", "record stop now",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        hd_rig_cmd_t c = parse(bad[i]);
        if (c.kind != HD_RIG_ERROR) fail_msg("accepted: %s", bad[i]);
        assert_non_null(c.error);
        assert_true(c.error[0] != '\0' && strchr(c.error, '\n') == NULL);
    }
}

static char got[8][HD_RIG_LINE_MAX];
static int n_got, n_long;
static void on_line(void *ctx, char *line) { (void)ctx; if (n_got < 8) snprintf(got[n_got], sizeof got[0], "%s", line); n_got++; }
static void on_long(void *ctx) { (void)ctx; n_long++; }

static void test_line_assembly(void **state)
{
    (void)state;
    hd_rig_lines_t lb;
    memset(&lb, 0, sizeof lb);
    n_got = n_long = 0;
    const char *text = "brake 1\nsta";
    hd_rig_lines_add(&lb, text, strlen(text), on_line, on_long, NULL);
    hd_rig_lines_add(&lb, "tus\n\n", 5, on_line, on_long, NULL);
    assert_int_equal(n_got, 3);
    assert_string_equal(got[0], "brake 1");
    assert_string_equal(got[1], "status");
    assert_string_equal(got[2], "");
    /* an overlong line is discarded (reported once per full buffer), the next one works */
    static char big[3000];
    memset(big, 'x', sizeof big);
    hd_rig_lines_add(&lb, big, sizeof big, on_line, on_long, NULL);
    assert_int_equal(n_long, 2);
    assert_true(lb.len < HD_RIG_LINE_MAX);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_commands_and_values),
        cmocka_unit_test(test_bad_input_is_one_error_line),
        cmocka_unit_test(test_line_assembly),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
