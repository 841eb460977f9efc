/*
 * hd_ssi.h - the output absolute encoder's serial frame (BiSS-C style,
 * read with an SPI master in receive mode; hardware-independent decoding).
 *
 * Frame on the data line (MSB first, one bit per clock; the line idles high):
 *
 *   [idle 1...] Ack 0 [0...]  Start 1  CDS 0  | POS[23..0]  nE  nW  CRC[5..0] |
 *                 (latency, >= 1 bit)         |  24 bits     1   1   6 bits   |
 *                                             '---- single-cycle data, 32 bits'
 *
 *   POS  absolute single-turn position, 24 bits, MSB first
 *   nE   error bit, active LOW  (0 = the encoder reports an error: position invalid)
 *   nW   warning bit, active LOW (0 = warning, e.g. dirty scale; position still valid)
 *   CRC  6 bits, polynomial x^6 + x + 1 (0x43), initial value 0, computed over
 *        the 26 bits POS, nE, nW, transmitted INVERTED (BiSS convention).
 *
 * The master clocks a fixed number of bits (the port reads 48 = 6 SPI bytes);
 * the decoder finds the Ack (first 0), then the Start bit (the first 1 after
 * it), checks CDS = 0, and takes the 32 data bits that follow; so any
 * encoder processing latency up to nbits - 35 bits is accepted.
 *
 * The CRC detects every single-bit error and every odd number of bit errors
 * in the 32-bit data section, and every burst up to 6 bits
 * (tests/c/test_port_ssi.c checks all single- and two-bit errors).
 */
#ifndef HD_SSI_H
#define HD_SSI_H

#include <stdint.h>

#define HD_SSI_POS_BITS   24u
#define HD_SSI_DATA_BITS  32u       /* POS + nE + nW + CRC6 */
#define HD_SSI_CRC_POLY   0x43u     /* x^6 + x + 1 */

/* decode results */
#define HD_SSI_OK          0
#define HD_SSI_ERR_NO_ACK  (-1)     /* the line never went low */
#define HD_SSI_ERR_NO_START (-2)    /* no start bit / frame does not fit */
#define HD_SSI_ERR_CDS     (-3)     /* CDS bit not 0 */
#define HD_SSI_ERR_CRC     (-4)     /* CRC mismatch */
#define HD_SSI_ERR_ARG     (-5)     /* bad arguments */

typedef struct {
    uint32_t position;   /* [0, 2^24) */
    uint32_t error;      /* 1 = encoder error (nE was 0): do not use the position */
    uint32_t warning;    /* 1 = encoder warning (nW was 0) */
} hd_ssi_reading_t;

/** CRC-6 (poly 0x43, init 0, not inverted) of the low nbits of data, MSB first (nbits <= 32). */
uint32_t hd_ssi_crc6(uint32_t data, uint32_t nbits);
/** The 32-bit data section for a position and error / warning flags (CRC inverted). */
uint32_t hd_ssi_encode(uint32_t position, uint32_t error, uint32_t warning);
/** Decode the 32-bit data section: HD_SSI_OK or HD_SSI_ERR_CRC (reading filled only when OK). */
int32_t hd_ssi_decode_data(uint32_t data, hd_ssi_reading_t *r);
/** Decode a raw bit stream of nbits bits (MSB of buf[0] first, nbits <= 8 * nbytes).
 *  Returns HD_SSI_OK (reading filled) or a negative HD_SSI_ERR_*.  A frame with
 *  error = 1 still returns HD_SSI_OK: the flag is the encoder's own verdict. */
int32_t hd_ssi_decode(const uint8_t *buf, uint32_t nbytes, uint32_t nbits, hd_ssi_reading_t *r);

#endif
