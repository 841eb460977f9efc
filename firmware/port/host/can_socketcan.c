/*
 * can_socketcan.c - SocketCAN transport (see can_socketcan.h).
 */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include <fcntl.h>
#include <net/if.h>
#include <sys/socket.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#ifdef HD_HAVE_LIBSOCKETCAN
#include <libsocketcan.h>
#endif

#include "can_socketcan.h"

static int32_t fail(char *err, uint32_t errlen, const char *ch, const char *what, int e)
{
    if (e == EAFNOSUPPORT || e == ENODEV || e == ENOENT) {
        snprintf(err, errlen,
                 "SocketCAN %s: %s: %s (this kernel has no CAN support or no such interface); "
                 "use --transport socketcand", ch, what, strerror(e));
    } else {
        snprintf(err, errlen, "SocketCAN %s: %s: %s", ch, what, strerror(e));
    }
    return -1;
}

int32_t hd_scan_open(hd_scan_t *s, const char *channel, uint32_t bitrate, uint32_t restart_ms,
                     char *err, uint32_t errlen)
{
    memset(s, 0, sizeof *s);
    s->fd = -1;
    snprintf(s->ifname, sizeof s->ifname, "%s", channel);
#ifdef HD_HAVE_LIBSOCKETCAN
    if (bitrate != 0u) {
        /* libsocketcan's netlink errors do not say "no such interface": check first */
        if (if_nametoindex(s->ifname) == 0u) {
            return fail(err, errlen, channel, "interface", errno);
        }
        (void)can_do_stop(s->ifname);
        if (can_set_bitrate(s->ifname, bitrate) != 0) {
            return fail(err, errlen, channel, "set bitrate", errno);
        }
        if (can_set_restart_ms(s->ifname, restart_ms) != 0) {
            return fail(err, errlen, channel, "set restart-ms", errno);
        }
        if (can_do_start(s->ifname) != 0) {
            return fail(err, errlen, channel, "start", errno);
        }
    }
#else
    (void)bitrate;
    (void)restart_ms;
#endif
    int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd < 0) {
        return fail(err, errlen, channel, "socket(PF_CAN)", errno);
    }
    unsigned int ifindex = if_nametoindex(s->ifname);
    if (ifindex == 0u) {
        int e = errno;
        close(fd);
        return fail(err, errlen, channel, "interface", e);
    }
    struct sockaddr_can a;
    memset(&a, 0, sizeof a);
    a.can_family = AF_CAN;
    a.can_ifindex = (int)ifindex;
    if (bind(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        int e = errno;
        close(fd);
        return fail(err, errlen, channel, "bind", e);
    }
    int fl = fcntl(fd, F_GETFL, 0);
    (void)fcntl(fd, F_SETFL, fl | O_NONBLOCK);
    s->fd = fd;
    return 0;
}

void hd_scan_close(hd_scan_t *s)
{
    if (s->fd >= 0) {
        close(s->fd);
    }
    s->fd = -1;
}

int32_t hd_scan_poll(hd_scan_t *s, int32_t timeout_ms, hd_can_frame_t *rx, uint32_t max, uint32_t *n)
{
    *n = 0u;
    struct pollfd p = {s->fd, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0) {
        return 0;
    }
    while (*n < max) {
        struct can_frame cf;
        ssize_t r = read(s->fd, &cf, sizeof cf);
        if (r < 0) {
            return (errno == EAGAIN || errno == EINTR) ? 0 : -1;
        }
        if ((size_t)r != sizeof cf || (cf.can_id & CAN_ERR_FLAG) != 0u || cf.can_dlc > 8u) {
            continue;
        }
        hd_can_frame_t *f = &rx[(*n)++];
        memset(f, 0, sizeof *f);
        f->ext = (uint8_t)((cf.can_id & CAN_EFF_FLAG) != 0u ? 1u : 0u);
        f->rtr = (uint8_t)((cf.can_id & CAN_RTR_FLAG) != 0u ? 1u : 0u);
        f->id = cf.can_id & (f->ext ? CAN_EFF_MASK : CAN_SFF_MASK);
        f->dlc = cf.can_dlc;
        memcpy(f->data, cf.data, 8u);
        s->rx_frames++;
    }
    return 0;
}

void hd_scan_send(hd_scan_t *s, const hd_can_frame_t *f)
{
    struct can_frame cf;
    memset(&cf, 0, sizeof cf);
    cf.can_id = f->id | (f->ext ? CAN_EFF_FLAG : 0u) | (f->rtr ? CAN_RTR_FLAG : 0u);
    cf.can_dlc = f->dlc > 8u ? 8u : f->dlc;
    memcpy(cf.data, f->data, 8u);
    if (write(s->fd, &cf, sizeof cf) != (ssize_t)sizeof cf) {
        s->tx_dropped++;
        return;
    }
    s->tx_frames++;
}

const char *hd_scan_state(const hd_scan_t *s)
{
#ifdef HD_HAVE_LIBSOCKETCAN
    int st = -1;
    /* libsocketcan prints "no link data found" on stderr for interfaces without a
       CAN controller (vcan): keep stderr for the program's own messages */
    int saved = dup(2), null = open("/dev/null", O_WRONLY);
    if (saved >= 0 && null >= 0) {
        (void)dup2(null, 2);
    }
    int r = can_get_state(s->ifname, &st);
    if (saved >= 0 && null >= 0) {
        (void)dup2(saved, 2);
    }
    if (saved >= 0) {
        close(saved);
    }
    if (null >= 0) {
        close(null);
    }
    if (r == 0) {
        switch (st) {
        case CAN_STATE_ERROR_ACTIVE: return "ERROR-ACTIVE";
        case CAN_STATE_ERROR_WARNING: return "ERROR-WARNING";
        case CAN_STATE_ERROR_PASSIVE: return "ERROR-PASSIVE";
        case CAN_STATE_BUS_OFF: return "BUS-OFF";
        case CAN_STATE_STOPPED: return "STOPPED";
        default: return "unknown";
        }
    }
#else
    (void)s;
#endif
    return "unknown";
}
