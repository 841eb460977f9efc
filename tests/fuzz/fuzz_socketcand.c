/*
 * fuzz_socketcand.c - the two text channels of the virtual drive:
 *   - the socketcand server of the host port (firmware/port/host/can_socketcand.c),
 *     fed the bytes a TCP client would send (< open >, < rawmode >, < send ... >,
 *     garbage, partial frames, overlong tokens) in random chunks through a
 *     socketpair, at any handshake stage, with outgoing frames interleaved;
 *   - the --rig command channel of `hdservo-sim serve` (sim/harness/rig.c):
 *     line assembly and command parsing.
 * Invariants: no crash and no undefined behaviour (ASan/UBSan); every frame
 * handed to the stack has dlc <= 8, a standard id <= 0x7FF or an extended id
 * <= 0x1FFFFFFF and no RTR; every reply is a well-formed "< ok >" or
 * "< frame ID SEC.USEC HEX >"; every rig line is newline-free and shorter than
 * the line limit, and every parsed command is in range or one error line.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "fuzz_common.h"
#include "can_socketcand.h"
#include "rig.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_frame(const hd_can_frame_t *f)
{
    FUZZ_ASSERT(f->dlc <= 8u);
    FUZZ_ASSERT(f->rtr == 0u);
    FUZZ_ASSERT(f->ext ? f->id <= 0x1FFFFFFFu : f->id <= 0x7FFu);
}

static int is_hex(char c) { return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'F'); }

/* one reply message "< ... >" of len bytes */
static void check_reply(const char *m, size_t len)
{
    if (len == 6 && memcmp(m, "< ok >", 6) == 0) return;
    FUZZ_ASSERT(len > 9 && memcmp(m, "< frame ", 8) == 0 && memcmp(m + len - 2, " >", 2) == 0);
    size_t i = 8, nid = 0, nsec = 0, nus = 0, nd = 0;
    while (i < len && is_hex(m[i])) { i++; nid++; }
    FUZZ_ASSERT(nid == 3 || nid == 8);
    FUZZ_ASSERT(m[i++] == ' ');
    while (i < len && m[i] >= '0' && m[i] <= '9') { i++; nsec++; }
    FUZZ_ASSERT(nsec >= 1 && m[i++] == '.');
    while (i < len && m[i] >= '0' && m[i] <= '9') { i++; nus++; }
    FUZZ_ASSERT(nus == 6 && m[i++] == ' ');
    while (i < len && is_hex(m[i])) { i++; nd++; }
    FUZZ_ASSERT(nd % 2 == 0 && nd <= 16);
    FUZZ_ASSERT(i == len - 2 && m[i] == ' ' && m[i + 1] == '>');
}

static char g_reply[1 << 16];
static size_t g_reply_len;

/* read what the server wrote; check every complete message */
static void drain_replies(int fd)
{
    for (;;) {
        ssize_t r = read(fd, g_reply + g_reply_len, sizeof g_reply - g_reply_len);
        if (r <= 0) break;
        g_reply_len += (size_t)r;
        size_t pos = 0;
        for (;;) {
            char *gt = memchr(g_reply + pos, '>', g_reply_len - pos);
            if (!gt) break;
            FUZZ_ASSERT(g_reply[pos] == '<');
            size_t end = (size_t)(gt - g_reply) + 1;
            check_reply(g_reply + pos, end - pos);
            pos = end;
        }
        memmove(g_reply, g_reply + pos, g_reply_len - pos);
        g_reply_len -= pos;
        FUZZ_ASSERT(g_reply_len < 200);        /* no message is that long */
    }
}

static void fuzz_scd(fz_stream_t *z)
{
    static hd_scd_t s;                         /* 1 MiB output buffer */
    int sv[2];
    hd_can_frame_t rx[8];
    if (socketpair(AF_UNIX, SOCK_STREAM, 0, sv) != 0) return;
    (void)fcntl(sv[0], F_SETFL, O_NONBLOCK);
    (void)fcntl(sv[1], F_SETFL, O_NONBLOCK);
    memset(&s, 0, sizeof s);
    s.listen_fd = -1;
    s.fd = sv[0];
    s.stage = (uint8_t)(fz_u8(z) % 3u);        /* after "< hi >", after open, streaming */
    s.stall_ms = 200u;
    s.quiet_ms = 0u;
    g_reply_len = 0;
    uint64_t t_us = 0;
    while (fz_left(z) > 0 && s.fd >= 0) {
        const uint8_t ctl = fz_u8(z);
        if (ctl >= 240u) {                     /* the drive sends a frame */
            hd_can_frame_t f;
            memset(&f, 0, sizeof f);
            f.ext = (uint8_t)(ctl & 1u);
            f.id = fz_u32(z);
            f.dlc = (uint8_t)(fz_u8(z) % 16u);
            for (int i = 0; i < 8; i++) f.data[i] = fz_u8(z);
            t_us += fz_u32(z);
            hd_scd_send(&s, &f, t_us);
            hd_scd_flush(&s, (ctl & 2u) != 0, 0u);
        } else {                               /* the client writes a chunk */
            size_t len = 1u + ctl % 96u;
            if (len > fz_left(z)) len = fz_left(z);
            if (len > 0 && write(sv[1], z->p + z->i, len) < 0 && errno != EAGAIN) break;
            z->i += len;
        }
        uint32_t n = 0, max = 1u + (ctl >> 4) % 8u;
        FUZZ_ASSERT(hd_scd_poll(&s, 0, rx, max, &n) == 0);
        FUZZ_ASSERT(n <= max);
        for (uint32_t i = 0; i < n; i++) check_frame(&rx[i]);
        FUZZ_ASSERT(s.in_len <= HD_SCD_IN_CAP && s.stage <= 2u);
        drain_replies(sv[1]);
    }
    /* whatever complete messages are still buffered get parsed */
    for (int k = 0; k < 64 && s.fd >= 0; k++) {
        uint32_t n = 0;
        (void)hd_scd_poll(&s, 0, rx, 8, &n);
        for (uint32_t i = 0; i < n; i++) check_frame(&rx[i]);
        if (n == 0) break;
    }
    drain_replies(sv[1]);
    if (s.fd >= 0) close(s.fd);
    close(sv[1]);
}

static int g_lines;

static void on_line(void *ctx, char *line)
{
    (void)ctx;
    FUZZ_ASSERT(strchr(line, '\n') == NULL && strlen(line) < HD_RIG_LINE_MAX);
    hd_rig_cmd_t c;
    hd_rig_parse(line, &c);
    g_lines++;
    switch (c.kind) {
    case HD_RIG_NONE: case HD_RIG_RECORD_STOP: case HD_RIG_STATUS: case HD_RIG_CAN_BUSOFF: case HD_RIG_CAN_STATUS:
        break;
    case HD_RIG_ERROR:
        FUZZ_ASSERT(c.error != NULL && c.error[0] != '\0' && strchr(c.error, '\n') == NULL);
        break;
    case HD_RIG_BRAKE: FUZZ_ASSERT(c.on == 0 || c.on == 1); break;
    case HD_RIG_TORQUE:
        FUZZ_ASSERT(isfinite(c.torque_Nm) && isfinite(c.rate_Nm_s) && c.rate_Nm_s >= 0.0);
        break;
    case HD_RIG_THEN:
        FUZZ_ASSERT(isfinite(c.torque_Nm) && isfinite(c.rate_Nm_s) && c.rate_Nm_s > 0.0);
        break;
    case HD_RIG_RECORD:
        FUZZ_ASSERT(c.path != NULL && c.path[0] != '\0' && strpbrk(c.path, " \t\r\n") == NULL);
        FUZZ_ASSERT(c.decimation >= 1u && c.decimation <= 1000000u);
        break;
    case HD_RIG_CAN_DROP: FUZZ_ASSERT(c.probability >= 0.0 && c.probability <= 1.0); break;
    case HD_RIG_CAN_ERRORS: FUZZ_ASSERT(c.tx_errors <= 1000u && c.rx_errors <= 1000u); break;
    default: FUZZ_ASSERT(0);
    }
}

static void on_too_long(void *ctx) { (void)ctx; }

static void fuzz_rig(fz_stream_t *z)
{
    static hd_rig_lines_t lb;
    memset(&lb, 0, sizeof lb);
    g_lines = 0;
    while (fz_left(z) > 0) {
        size_t len = 1u + fz_u8(z) % 128u;
        if (len > fz_left(z)) len = fz_left(z);
        hd_rig_lines_add(&lb, (const char *)z->p + z->i, len, on_line, on_too_long, NULL);
        z->i += len;
        FUZZ_ASSERT(lb.len < HD_RIG_LINE_MAX);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_stream_t z;
    fz_init(&z, data, size);
    if (fz_u8(&z) & 1u) fuzz_rig(&z);
    else fuzz_scd(&z);
    return 0;
}
