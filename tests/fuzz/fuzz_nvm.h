/*
 * fuzz_nvm.h - a fake hal NVM with flash semantics for the store fuzz targets: define
 * FUZZ_NVM_SIZE and FUZZ_NVM_PAGE (bytes), optionally FUZZ_NVM_ERASE_MIN (the lowest
 * offset an erase may touch), then include this once.  Gives nvm[], nvm_fail_read
 * (reads fail while set) and the four hd_hal_nvm_* calls; writes assert the G4 rules
 * (8-byte alignment, program erased memory only), erases the page alignment.
 */
#ifndef FUZZ_NVM_H
#define FUZZ_NVM_H

#include <string.h>
#include "fuzz_common.h"
#include "hal.h"

#ifndef FUZZ_NVM_ERASE_MIN
#define FUZZ_NVM_ERASE_MIN 0u
#endif

static uint8_t nvm[FUZZ_NVM_SIZE];
static int nvm_fail_read;

uint32_t hd_hal_nvm_size(void) { return FUZZ_NVM_SIZE; }
uint32_t hd_hal_nvm_page_size(void) { return FUZZ_NVM_PAGE; }
int32_t hd_hal_nvm_read(uint32_t off, void *buf, uint32_t len)
{
    if (nvm_fail_read || off > FUZZ_NVM_SIZE || len > FUZZ_NVM_SIZE - off) {
        return -1;
    }
    memcpy(buf, &nvm[off], len);
    return 0;
}
int32_t hd_hal_nvm_write(uint32_t off, const void *buf, uint32_t len)
{
    FUZZ_ASSERT(off % 8u == 0u && len % 8u == 0u);
    if (off > FUZZ_NVM_SIZE || len > FUZZ_NVM_SIZE - off) {
        return -1;
    }
    const uint8_t *b = buf;
    for (uint32_t i = 0; i < len; i++) {
        FUZZ_ASSERT(nvm[off + i] == 0xFFu); /* flash: program erased memory only */
        nvm[off + i] = b[i];
    }
    return 0;
}
int32_t hd_hal_nvm_erase(uint32_t off, uint32_t len)
{
    FUZZ_ASSERT(off % FUZZ_NVM_PAGE == 0u && len % FUZZ_NVM_PAGE == 0u);
    FUZZ_ASSERT(off >= FUZZ_NVM_ERASE_MIN);
    if (off > FUZZ_NVM_SIZE || len > FUZZ_NVM_SIZE - off) {
        return -1;
    }
    memset(&nvm[off], 0xFF, len);
    return 0;
}

#endif
