/*
 * can_socketcand.c - socketcand-protocol server (see can_socketcand.h).
 */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <arpa/inet.h>
#include <sys/socket.h>

#include "can_socketcand.h"

#define WAIT_SLICE_MS 100

/* One wait for the socket to take more output: a poll of at most WAIT_SLICE_MS, so a
 * stop request is seen promptly.  *idle_ms counts the slices that ended with the
 * socket still full (a slice cut short by a signal or by room is not counted; the
 * caller resets it whenever bytes go out), which keeps the port free of clocks and
 * floating point.  false: stop requested, or idle past the stall time-out (the
 * client is then dropped and counted). */
static void drop_client(hd_scd_t *s);
static bool wait_writable(hd_scd_t *s, uint32_t *idle_ms)
{
    if (s->stop != NULL && *s->stop != 0) {
        return false;
    }
    if (*idle_ms >= s->stall_ms) {
        s->stalled++;
        drop_client(s);
        return false;
    }
    struct pollfd p = {s->fd, POLLOUT, 0};
    if (poll(&p, 1, WAIT_SLICE_MS) == 0) {
        *idle_ms += (uint32_t)WAIT_SLICE_MS;
    }
    return !(s->stop != NULL && *s->stop != 0);
}

static void set_nonblock(int fd)
{
    int fl = fcntl(fd, F_GETFL, 0);
    if (fl >= 0) {
        (void)fcntl(fd, F_SETFL, fl | O_NONBLOCK);
    }
}

int32_t hd_scd_open(hd_scd_t *s, uint16_t port, char *err, uint32_t errlen)
{
    s->fd = -1;
    s->stage = 0u;
    s->in_len = s->out_len = 0u;
    s->rx_frames = s->tx_frames = s->tx_dropped = s->bad_lines = s->clients = 0u;
    s->stop = NULL;
    s->stall_ms = HD_SCD_STALL_MS;
    s->stalled = 0u;
    s->quiet_ms = HD_SCD_QUIET_MS;
    s->sndbuf = 0u;
    s->listen_fd = socket(AF_INET, SOCK_STREAM, 0);
    if (s->listen_fd < 0) {
        snprintf(err, errlen, "socketcand: socket: %s", strerror(errno));
        return -1;
    }
    int one = 1;
    (void)setsockopt(s->listen_fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(s->listen_fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(s->listen_fd, 4) != 0) {
        snprintf(err, errlen, "socketcand: cannot listen on 127.0.0.1:%u: %s", (unsigned)port, strerror(errno));
        close(s->listen_fd);
        s->listen_fd = -1;
        return -1;
    }
    socklen_t l = sizeof a;
    if (getsockname(s->listen_fd, (struct sockaddr *)&a, &l) == 0) {
        s->port = ntohs(a.sin_port);
    }
    set_nonblock(s->listen_fd);
    return 0;
}

static void drop_client(hd_scd_t *s)
{
    if (s->fd >= 0) {
        close(s->fd);
    }
    s->fd = -1;
    s->stage = 0u;
    s->in_len = 0u;
    s->out_len = 0u;
}

void hd_scd_close(hd_scd_t *s)
{
    drop_client(s);
    if (s->listen_fd >= 0) {
        close(s->listen_fd);
        s->listen_fd = -1;
    }
}

bool hd_scd_streaming(const hd_scd_t *s) { return s->fd >= 0 && s->stage >= 2u; }
/* bare handshake strings: written at once, nothing queued behind them */
static void send_bare(hd_scd_t *s, const char *msg)
{
    size_t n = strlen(msg);
    size_t off = 0u;
    uint32_t idle = 0u;
    while (off < n && s->fd >= 0) {
        ssize_t w = send(s->fd, msg + off, n - off, MSG_NOSIGNAL);
        if (w < 0) {
            if (errno == EAGAIN || errno == EINTR) {
                if (!wait_writable(s, &idle)) {
                    return;
                }
                continue;
            }
            drop_client(s);
            return;
        }
        off += (size_t)w;
        idle = 0u;
    }
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* parse a hex token at *p (advances); false if none or too long */
static bool hex_token(const char **p, const char *end, uint32_t *v, uint32_t *ndig)
{
    const char *q = *p;
    while (q < end && *q == ' ') q++;
    uint32_t x = 0u, n = 0u;
    while (q < end && *q != ' ') {
        int h = hexval(*q);
        if (h < 0 || n >= 8u) {
            return false;
        }
        x = (x << 4) | (uint32_t)h;
        n++;
        q++;
    }
    *p = q;
    *v = x;
    *ndig = n;
    return n > 0u;
}

bool hd_scd_parse_send(const char *line, uint32_t len, hd_can_frame_t *f)
{
    const char *p = line, *end = line + len;
    if (len < 5u || strncmp(p, "send ", 5u) != 0) {
        return false;
    }
    p += 5;
    uint32_t id, nd, dlc, nd2;
    if (!hex_token(&p, end, &id, &nd) || !hex_token(&p, end, &dlc, &nd2) || dlc > 8u) {
        return false;
    }
    memset(f, 0, sizeof *f);
    f->ext = (uint8_t)((nd > 3u || id > 0x7FFu) ? 1u : 0u);
    if ((f->ext && id > 0x1FFFFFFFu)) {
        return false;
    }
    f->id = id;
    f->dlc = (uint8_t)dlc;
    for (uint32_t i = 0u; i < dlc; i++) {
        uint32_t b, nb;
        if (!hex_token(&p, end, &b, &nb) || b > 0xFFu) {
            return false;
        }
        f->data[i] = (uint8_t)b;
    }
    while (p < end && *p == ' ') p++;
    return p == end;
}

static void handle_line(hd_scd_t *s, const char *body, uint32_t len, hd_can_frame_t *rx, uint32_t max, uint32_t *n)
{
    if (s->stage == 0u) {
        if (len >= 5u && strncmp(body, "open ", 5u) == 0) {
            s->stage = 1u;
            send_bare(s, "< ok >");
            return;
        }
    } else if (s->stage == 1u) {
        if (len == 7u && strncmp(body, "rawmode", 7u) == 0) {
            s->stage = 2u;
            send_bare(s, "< ok >");
            /* the client compares this reply with ONE recv(): stay quiet for a
             * moment so that no frame lands in the same read */
            (void)poll(NULL, 0, (int)s->quiet_ms);
            return;
        }
    } else {
        hd_can_frame_t f;
        if (hd_scd_parse_send(body, len, &f)) {
            if (*n < max) {
                rx[(*n)++] = f;
                s->rx_frames++;
            }
            return;
        }
        if (len == 4u && strncmp(body, "echo", 4u) == 0) {
            return;
        }
    }
    s->bad_lines++;
}

int32_t hd_scd_poll(hd_scd_t *s, int32_t timeout_ms, hd_can_frame_t *rx, uint32_t max, uint32_t *n)
{
    *n = 0u;
    if (s->fd < 0) {
        struct pollfd p = {s->listen_fd, POLLIN, 0};
        if (poll(&p, 1, timeout_ms) <= 0) {
            return 0;
        }
        int c = accept(s->listen_fd, NULL, NULL);
        if (c < 0) {
            return 0;
        }
        s->fd = c;
        int one = 1;
        (void)setsockopt(c, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        if (s->sndbuf > 0u) {
            /* before any byte is queued: a fixed buffer also turns the kernel's autotuning off */
            int sb = (int)s->sndbuf;
            (void)setsockopt(c, SOL_SOCKET, SO_SNDBUF, &sb, sizeof sb);
        }
        set_nonblock(c);
        s->clients++;
        s->stage = 0u;
        s->in_len = 0u;
        s->out_len = 0u;
        send_bare(s, "< hi >");
        timeout_ms = 0;
    }
    if (s->fd < 0) {
        return 0;
    }
    /* room for at most max frames: read only what can be parsed */
    struct pollfd p = {s->fd, POLLIN, 0};
    if (s->in_len > 0u && memchr(s->in, '>', s->in_len) != NULL) {
        timeout_ms = 0;                       /* complete messages already buffered */
    }
    int ready = poll(&p, 1, timeout_ms);
    uint32_t room = HD_SCD_IN_CAP - s->in_len;
    if (ready > 0 && room > 0u) {
        ssize_t r = recv(s->fd, s->in + s->in_len, room, 0);
        if (r == 0 || (r < 0 && errno != EAGAIN && errno != EINTR)) {
            drop_client(s);
            return 0;
        }
        if (r > 0) {
            s->in_len += (uint32_t)r;
#ifdef TCP_QUICKACK
            /* ACK at once: python-can writes one small segment per frame with
             * Nagle on, and a delayed ACK here would stall it ~40 ms */
            int one = 1;
            (void)setsockopt(s->fd, IPPROTO_TCP, TCP_QUICKACK, &one, sizeof one);
#endif
        }
    }
    /* parse complete "< ... >" messages */
    uint32_t pos = 0u;
    while (pos < s->in_len && *n < max) {
        char *lt = memchr(s->in + pos, '<', s->in_len - pos);
        if (lt == NULL) {
            pos = s->in_len;
            break;
        }
        uint32_t st = (uint32_t)(lt - s->in);
        char *gt = memchr(s->in + st, '>', s->in_len - st);
        if (gt == NULL) {
            pos = st;
            if (s->in_len - st > 256u) {   /* garbage without an end */
                s->bad_lines++;
                pos = s->in_len;
            }
            break;
        }
        uint32_t en = (uint32_t)(gt - s->in);
        const char *b = s->in + st + 1u;
        uint32_t bl = en - st - 1u;
        while (bl > 0u && *b == ' ') { b++; bl--; }
        while (bl > 0u && b[bl - 1u] == ' ') { bl--; }
        handle_line(s, b, bl, rx, max, n);
        pos = en + 1u;
        if (s->fd < 0) {
            return 0;
        }
    }
    memmove(s->in, s->in + pos, s->in_len - pos);
    s->in_len -= pos;
    return 0;
}

void hd_scd_send(hd_scd_t *s, const hd_can_frame_t *f, uint64_t t_us)
{
    if (!hd_scd_streaming(s)) {
        s->tx_dropped++;
        return;
    }
    char line[80];
    int k;
    uint32_t sec = (uint32_t)(t_us / 1000000u);
    uint32_t usec = (uint32_t)(t_us % 1000000u);
    if (f->ext) {
        k = snprintf(line, sizeof line, "< frame %08X %u.%06u ", (unsigned)(f->id & 0x1FFFFFFFu), sec, usec);
    } else {
        k = snprintf(line, sizeof line, "< frame %03X %u.%06u ", (unsigned)(f->id & 0x7FFu), sec, usec);
    }
    static const char hx[] = "0123456789ABCDEF";
    uint32_t len = (uint32_t)k;
    uint8_t dlc = f->dlc > 8u ? 8u : f->dlc;
    for (uint32_t i = 0u; i < dlc; i++) {
        line[len++] = hx[f->data[i] >> 4];
        line[len++] = hx[f->data[i] & 15u];
    }
    line[len++] = ' ';
    line[len++] = '>';
    if (s->out_len + len > HD_SCD_OUT_CAP) {
        s->tx_dropped++;
        return;
    }
    memcpy(s->out + s->out_len, line, len);
    s->out_len += len;
    s->tx_frames++;
}

void hd_scd_flush(hd_scd_t *s, bool block, uint32_t keep)
{
    uint32_t idle = 0u;              /* ms waited since the socket last took a byte */
    while (s->fd >= 0 && s->out_len > 0u) {
        ssize_t w = send(s->fd, s->out, s->out_len, MSG_NOSIGNAL);
        if (w > 0) {
            memmove(s->out, s->out + w, s->out_len - (uint32_t)w);
            s->out_len -= (uint32_t)w;
            idle = 0u;
            continue;
        }
        if (w < 0 && (errno == EAGAIN || errno == EINTR)) {
            if (!block || s->out_len <= keep) {
                return;
            }
            if (!wait_writable(s, &idle)) {
                return;
            }
            continue;
        }
        drop_client(s);
        return;
    }
}
