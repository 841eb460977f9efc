/*
 * hd_crc32.h - CRC-32 (IEEE 802.3: reflected polynomial 0xEDB88320, init and xorout
 * 0xFFFFFFFF; "123456789" -> 0xCBF43926), the one CRC of every stored or downloaded
 * image: parameter records, the flash record store, CANopen domain tables.  Python's
 * zlib.crc32 computes the same value, so host tools check the images with it.
 */
#ifndef HD_CRC32_H
#define HD_CRC32_H

#include <stdint.h>

/** CRC-32 of p[0..len) continued from crc (start with 0; chain calls for split data). */
uint32_t hd_crc32(uint32_t crc, const uint8_t *p, uint32_t len);

#endif
