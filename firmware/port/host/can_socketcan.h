/*
 * can_socketcan.h - Linux SocketCAN transport of the virtual drive (can0,
 * vcan0).  With HD_HAVE_LIBSOCKETCAN defined (link -lsocketcan) the
 * interface is configured first: bitrate, restart-ms, then started, and its
 * state can be read.  Without kernel CAN (this development machine) open
 * fails with one line that names the socketcand transport instead.
 */
#ifndef HD_CAN_SOCKETCAN_H
#define HD_CAN_SOCKETCAN_H

#include <stdint.h>
#include <stdbool.h>
#include "hal.h"

typedef struct {
    int  fd;
    char ifname[32];
    uint32_t rx_frames, tx_frames, tx_dropped;
} hd_scan_t;

/** Open channel; bitrate/restart_ms 0 = leave the interface as it is.  0 ok, -1 with err. */
int32_t hd_scan_open(hd_scan_t *s, const char *channel, uint32_t bitrate, uint32_t restart_ms,
                     char *err, uint32_t errlen);
void hd_scan_close(hd_scan_t *s);
/** Receive up to max frames, waiting at most timeout_ms.  0 ok, -1 fatal. */
int32_t hd_scan_poll(hd_scan_t *s, int32_t timeout_ms, hd_can_frame_t *rx, uint32_t max, uint32_t *n);
/** Send one frame (dropped and counted when the socket is full). */
void hd_scan_send(hd_scan_t *s, const hd_can_frame_t *f);
/** Controller state as text ("ERROR-ACTIVE", ..., "unknown"). */
const char *hd_scan_state(const hd_scan_t *s);

#endif /* HD_CAN_SOCKETCAN_H */
