/*
 * serve.h - `hdservo-sim serve`: the virtual drive (see serve.c).
 */
#ifndef HD_SERVE_H
#define HD_SERVE_H

#include <stdint.h>
#include "hal.h"

/** Entry of the serve subcommand (argv after "serve"); process exit status. */
int hd_sim_serve_main(int argc, char **argv);
/** Bit-stuffed length of a classic CAN frame including ACK, EOF and IFS (bus model). */
int32_t hd_serve_frame_bits(const hd_can_frame_t *f);

#endif /* HD_SERVE_H */
