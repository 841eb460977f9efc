/*
 * rig.c - the test rig's command channel: line assembly and parsing (see rig.h).
 */
#include "rig.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int hd_rig_parse_u(const char *s, unsigned long lo, unsigned long hi, unsigned long *out)
{
    char *end;
    errno = 0;
    unsigned long v = strtoul(s, &end, 0);
    if (errno || *end || s[0] == '-' || s[0] == '\0' || v < lo || v > hi) return -1;
    *out = v;
    return 0;
}

/* a whole token as a finite number */
static int parse_num(const char *s, double *out)
{
    char *end = NULL;
    double v = strtod(s, &end);
    if (!end || end == s || *end || !isfinite(v)) return -1;
    *out = v;
    return 0;
}

static void fail(hd_rig_cmd_t *c, const char *msg)
{
    c->kind = HD_RIG_ERROR;
    c->error = msg;
}

void hd_rig_parse(char *line, hd_rig_cmd_t *c)
{
    char *argv[5] = { 0 };
    int argc = 0;
    char *save = NULL;
    unsigned long u, v;
    memset(c, 0, sizeof *c);
    /* one token more than any command takes, so that extra words are refused */
    for (char *tok = strtok_r(line, " \t\r", &save); tok && argc < 5; tok = strtok_r(NULL, " \t\r", &save))
        argv[argc++] = tok;
    if (argc == 0) { c->kind = HD_RIG_NONE; return; }
    if (strcmp(argv[0], "brake") == 0 && argc == 2 && (strcmp(argv[1], "0") == 0 || strcmp(argv[1], "1") == 0)) {
        c->kind = HD_RIG_BRAKE;
        c->on = argv[1][0] == '1';
    } else if (strcmp(argv[0], "torque") == 0 && (argc == 2 || argc == 3)) {
        if (parse_num(argv[1], &c->torque_Nm)) { fail(c, "torque: expected a number of N.m"); return; }
        if (argc == 3 && (parse_num(argv[2], &c->rate_Nm_s) || c->rate_Nm_s < 0.0)) {
            fail(c, "torque: expected a rate >= 0 N.m/s");
            return;
        }
        c->kind = HD_RIG_TORQUE;
    } else if (strcmp(argv[0], "then") == 0 && argc == 3) {
        if (parse_num(argv[1], &c->torque_Nm)) { fail(c, "then: expected a number of N.m"); return; }
        if (parse_num(argv[2], &c->rate_Nm_s) || !(c->rate_Nm_s > 0.0)) {
            fail(c, "then: expected a rate > 0 N.m/s");
            return;
        }
        c->kind = HD_RIG_THEN;
    } else if (strcmp(argv[0], "record") == 0 && argc == 2 && strcmp(argv[1], "stop") == 0) {
        c->kind = HD_RIG_RECORD_STOP;
    } else if (strcmp(argv[0], "record") == 0 && argc == 3) {
        if (hd_rig_parse_u(argv[2], 1, 1000000, &u) != 0) { fail(c, "record: expected a decimation 1..1000000"); return; }
        c->kind = HD_RIG_RECORD;
        c->path = argv[1];
        c->decimation = (uint32_t)u;
    } else if (strcmp(argv[0], "can") == 0 && argc >= 2) {
        if (strcmp(argv[1], "drop") == 0 && (argc == 3 || argc == 4)) {
            if (parse_num(argv[2], &c->probability) || !(c->probability >= 0.0 && c->probability <= 1.0)) {
                fail(c, "can drop: expected a probability 0..1");
                return;
            }
            if (argc == 4) {
                if (hd_rig_parse_u(argv[3], 0, 0xFFFFFFFFul, &u) != 0) { fail(c, "can drop: expected a seed 0..2^32-1"); return; }
                c->has_seed = 1;
                c->seed = (uint32_t)u;
            }
            c->kind = HD_RIG_CAN_DROP;
        } else if (strcmp(argv[1], "errors") == 0 && argc == 4) {
            if (hd_rig_parse_u(argv[2], 0, 1000, &u) || hd_rig_parse_u(argv[3], 0, 1000, &v)) {
                fail(c, "can errors: expected TX RX error counts 0..1000");
                return;
            }
            c->kind = HD_RIG_CAN_ERRORS;
            c->tx_errors = (uint32_t)u;
            c->rx_errors = (uint32_t)v;
        } else if (strcmp(argv[1], "busoff") == 0 && argc == 2) {
            c->kind = HD_RIG_CAN_BUSOFF;
        } else if (strcmp(argv[1], "status") == 0 && argc == 2) {
            c->kind = HD_RIG_CAN_STATUS;
        } else {
            fail(c, "can: expected drop P [SEED], errors TX RX, busoff or status");
        }
    } else if (strcmp(argv[0], "status") == 0 && argc == 1) {
        c->kind = HD_RIG_STATUS;
    } else {
        fail(c, "unknown rig command (expected: brake 0|1, torque T [RATE], then T RATE, record PATH DECIM, "
                "record stop, status, can drop P [SEED], can errors TX RX, can busoff, can status)");
    }
}

void hd_rig_lines_add(hd_rig_lines_t *lb, const char *data, size_t n, void (*on_line)(void *ctx, char *line),
                      void (*on_too_long)(void *ctx), void *ctx)
{
    while (n > 0) {
        size_t room = sizeof lb->buf - 1 - lb->len, take = n < room ? n : room;
        memcpy(lb->buf + lb->len, data, take);
        lb->len += take;
        lb->buf[lb->len] = '\0';
        data += take;
        n -= take;
        char *nl;
        while ((nl = memchr(lb->buf, '\n', lb->len)) != NULL) {
            size_t used = (size_t)(nl - lb->buf) + 1;
            *nl = '\0';
            on_line(ctx, lb->buf);
            memmove(lb->buf, lb->buf + used, lb->len - used);
            lb->len -= used;
            lb->buf[lb->len] = '\0';
        }
        if (lb->len >= sizeof lb->buf - 1) {
            on_too_long(ctx);
            lb->len = 0;
            lb->buf[0] = '\0';
        }
    }
}
