/*
 * can_socketcand.h - a socketcand-protocol TCP server on loopback: the CAN
 * transport of the virtual drive that python-can reaches with
 * interface="socketcand" on any OS without kernel CAN.
 *
 * Protocol (what python-can's client needs, research/toolchain.md section 6):
 *   server -> "< hi >"                    bare, no newline, nothing behind it
 *   client -> "< open can0 >"             server -> "< ok >"   (bare)
 *   client -> "< rawmode >"               server -> "< ok >"   (bare)
 *   client -> "< send ID LEN B0 B1 ... >"   hex, not zero-padded
 *   server -> "< frame ID SEC.USEC HEXDATA >"  3 hex digits = standard id,
 *                                            8 = extended; contiguous data
 * One client at a time; a new client may connect after the old one left.
 * Outgoing frames are buffered (HD_SCD_OUT_CAP bytes); hd_scd_flush(block)
 * waits for the socket when asked (back-pressure for fast pacing), otherwise
 * frames that do not fit are dropped and counted.  sndbuf bounds what the
 * kernel buffers for the client (see hd_scd_t).
 */
#ifndef HD_CAN_SOCKETCAND_H
#define HD_CAN_SOCKETCAND_H

#include <signal.h>
#include <stdint.h>
#include <stdbool.h>
#include "hal.h"

#define HD_SCD_IN_CAP   8192u
#define HD_SCD_QUIET_MS 50      /* after the last "< ok >" before the first frame */
#define HD_SCD_OUT_CAP  (1u << 20)   /* the struct is large: give it static storage */
#define HD_SCD_STALL_MS 5000u   /* default: a client whose socket accepts nothing this long is dropped */

typedef struct {
    int      listen_fd;
    int      fd;                 /* client, -1 = none */
    uint16_t port;
    uint8_t  stage;              /* 0 hi sent, 1 open ok, 2 rawmode ok (streaming) */
    char     in[HD_SCD_IN_CAP];
    uint32_t in_len;
    char     out[HD_SCD_OUT_CAP];
    uint32_t out_len;
    uint32_t rx_frames, tx_frames, tx_dropped, bad_lines, clients;
    /* Blocking writes (handshake replies, hd_scd_flush with block) wait in slices
     * of at most 100 ms and give up when *stop becomes non-zero (the server's
     * signal flag; NULL = never) or when the socket has accepted no byte for
     * stall_ms (the client stopped reading: it is dropped and counted in
     * stalled).  hd_scd_open sets stop = NULL and stall_ms = HD_SCD_STALL_MS. */
    const volatile sig_atomic_t *stop;
    uint32_t stall_ms;
    uint32_t stalled;
    uint32_t quiet_ms;           /* pause after "rawmode" (HD_SCD_QUIET_MS; tests may shorten it) */
    /* SO_SNDBUF of each accepted client socket in bytes (0: the system's, autotuned up to
     * megabytes).  A server that waits for its client (fast pacing) sets it small: whatever
     * the kernel holds unsent is a backlog every later frame, an SDO answer too, waits behind. */
    uint32_t sndbuf;
} hd_scd_t;

/** Listen on 127.0.0.1:port (0 = ephemeral).  0 ok, -1 with a message in err. */
int32_t hd_scd_open(hd_scd_t *s, uint16_t port, char *err, uint32_t errlen);
void hd_scd_close(hd_scd_t *s);

/**
 * Accept / read / parse.  Waits at most timeout_ms for input (0 = poll).
 * Up to max frames received go to rx; *n gets the count.  Returns 0, or -1
 * on a fatal socket error.
 */
int32_t hd_scd_poll(hd_scd_t *s, int32_t timeout_ms, hd_can_frame_t *rx, uint32_t max, uint32_t *n);

/** Queue one frame for the client with timestamp t_us (dropped if no client / full). */
void hd_scd_send(hd_scd_t *s, const hd_can_frame_t *f, uint64_t t_us);

/** Write buffered output; with block, wait until at most keep bytes remain (or
 *  *stop is set, or the client stalls past stall_ms and is dropped). */
void hd_scd_flush(hd_scd_t *s, bool block, uint32_t keep);

/** True when a client finished the handshake. */
bool hd_scd_streaming(const hd_scd_t *s);

/* Parse one "< send ... >" body (between "< " and " >"); true if valid. */
bool hd_scd_parse_send(const char *line, uint32_t len, hd_can_frame_t *f);

#endif /* HD_CAN_SOCKETCAND_H */
