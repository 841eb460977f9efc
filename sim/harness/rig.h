/*
 * rig.h - the command channel of the virtual drive's test rig (`hdservo-sim serve
 * --rig`, serve.c): splitting stdin into lines and parsing one line into a
 * command.  Pure functions (no I/O, no drive state), so the channel can be tested
 * and fuzzed without a process or a socket; serve.c executes the commands.
 *
 * Commands (one per line, tokens separated by blanks/tabs, at most 4 tokens):
 *   brake 0|1 | torque T [RATE] | then T RATE | record PATH DECIM | record stop |
 *   status | can drop P [SEED] | can errors TX RX | can busoff | can status
 */
#ifndef HD_RIG_H
#define HD_RIG_H

#include <stddef.h>
#include <stdint.h>

#define HD_RIG_LINE_MAX 1024    /* longest line (with its newline) the channel accepts */

typedef enum {
    HD_RIG_NONE = 0,            /* blank line: no answer */
    HD_RIG_ERROR,               /* cmd.error says what was expected */
    HD_RIG_BRAKE,               /* on */
    HD_RIG_TORQUE,              /* torque_Nm, rate_Nm_s (0 = step) */
    HD_RIG_THEN,                /* torque_Nm, rate_Nm_s (> 0) */
    HD_RIG_RECORD,              /* path, decimation */
    HD_RIG_RECORD_STOP,
    HD_RIG_STATUS,
    HD_RIG_CAN_DROP,            /* probability, has_seed, seed */
    HD_RIG_CAN_ERRORS,          /* tx_errors, rx_errors */
    HD_RIG_CAN_BUSOFF,
    HD_RIG_CAN_STATUS
} hd_rig_kind;

typedef struct {
    hd_rig_kind kind;
    int         on;             /* brake */
    double      torque_Nm;      /* torque/then: finite */
    double      rate_Nm_s;      /* torque: finite >= 0; then: finite > 0 */
    const char *path;           /* record: points into the parsed line */
    uint32_t    decimation;     /* record: 1..1000000 */
    double      probability;    /* can drop: 0..1 */
    int         has_seed;
    uint32_t    seed;           /* can drop */
    uint32_t    tx_errors, rx_errors;   /* can errors: 0..1000 each */
    const char *error;          /* HD_RIG_ERROR: one line, no newline */
} hd_rig_cmd_t;

/* Parse one line (without its newline; tokenised in place).  Always fills cmd. */
void hd_rig_parse(char *line, hd_rig_cmd_t *cmd);

/* Line assembly of the channel's byte stream. */
typedef struct {
    char   buf[HD_RIG_LINE_MAX];
    size_t len;
} hd_rig_lines_t;

/* Append n bytes; call on_line(ctx, line) for each complete line (newline removed,
 * NUL-terminated, no '\n' inside) and on_too_long(ctx) when HD_RIG_LINE_MAX - 1
 * bytes gather without a newline (they are discarded). */
void hd_rig_lines_add(hd_rig_lines_t *lb, const char *data, size_t n, void (*on_line)(void *ctx, char *line),
                      void (*on_too_long)(void *ctx), void *ctx);

/* Unsigned integer in [lo, hi] (decimal, 0x hex or 0 octal, no sign). 0 ok, -1 otherwise. */
int hd_rig_parse_u(const char *s, unsigned long lo, unsigned long hi, unsigned long *out);

#endif /* HD_RIG_H */
