/*
 * fuzz_pstore.c - the parameter-store loader (firmware/app/hd_param_store)
 * on corrupt NVM images, through a fake hal NVM (this file implements the
 * hd_hal_nvm_* calls; no other hal function is linked).
 *
 * Input: byte 0 = flags
 *   bit 0  raw image: the rest of the input IS the NVM (padded with 0xFF)
 *   otherwise the NVM starts as two valid slots (defaults and a variant, saved
 *   by hd_pstore_save), then records (offset u16, xor byte) flip bits;
 *   bit 1/2 re-seal slot 0/1 (fix the CRC after the flips) so that the range
 *   checks and the sequence-number logic are reached;
 *   bit 3  NVM reads fail
 *   bit 4  the sequence numbers come from the input (wrap-around cases)
 *
 * Invariants:
 *   - load returns one of the documented statuses; on anything but OK the
 *     values are exactly the defaults;
 *   - on OK every value passes hd_params_check, and the set is one of the
 *     sets present in a slot (never a mix of two slots);
 *   - save after load, then load again, gives the same values (seq + 1, or
 *     newer than every slot when the boot could not read the NVM).
 */
#include <string.h>
#include "fuzz_common.h"
#include "hal.h"
#include "hd_param_store.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define NVM_SIZE 8192u
#define NVM_PAGE 1024u

static uint8_t nvm[NVM_SIZE];
static int nvm_fail_read;

uint32_t hd_hal_nvm_size(void) { return NVM_SIZE; }
uint32_t hd_hal_nvm_page_size(void) { return NVM_PAGE; }
int32_t hd_hal_nvm_read(uint32_t off, void *buf, uint32_t len)
{
    if (nvm_fail_read || off > NVM_SIZE || len > NVM_SIZE - off) {
        return -1;
    }
    memcpy(buf, &nvm[off], len);
    return 0;
}
int32_t hd_hal_nvm_write(uint32_t off, const void *buf, uint32_t len)
{
    FUZZ_ASSERT(off % 8u == 0u && len % 8u == 0u);
    if (off > NVM_SIZE || len > NVM_SIZE - off) {
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
    FUZZ_ASSERT(off % NVM_PAGE == 0u && len % NVM_PAGE == 0u);
    if (off > NVM_SIZE || len > NVM_SIZE - off) {
        return -1;
    }
    memset(&nvm[off], 0xFF, len);
    return 0;
}

#define REC_BYTES ((6u + HD_PARAM_COUNT + 1u) * 4u)

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}
static void reseal(uint32_t slot)
{
    uint8_t *r = &nvm[slot * NVM_PAGE];
    put32(&r[REC_BYTES - 4u], hd_crc32(0, r, REC_BYTES - 4u));
}
/* values stored in a slot (raw words), for the "never a mix" check */
static int slot_holds(uint32_t slot, const int32_t v[HD_PARAM_COUNT])
{
    const uint8_t *r = &nvm[slot * NVM_PAGE];
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) {
        if (get32(&r[(6u + i) * 4u]) != (uint32_t)v[i]) {
            return 0;
        }
    }
    return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int32_t def[HD_PARAM_COUNT], alt[HD_PARAM_COUNT], v[HD_PARAM_COUNT], w[HD_PARAM_COUNT];
    fz_stream_t s;
    fz_init(&s, data, size);
    const uint8_t flags = fz_u8(&s);
    uint32_t seq = 0;

    nvm_fail_read = 0;
    memset(nvm, 0xFF, sizeof nvm);
    hd_params_defaults(def);
    if (flags & 1u) {
        const size_t n = fz_left(&s) < NVM_SIZE ? fz_left(&s) : NVM_SIZE;
        memcpy(nvm, data + 1, n);
    } else {
        /* two valid slots: defaults (seq a), then a variant (seq a + 1) */
        memcpy(alt, def, sizeof alt);
        const uint32_t id = fz_u8(&s) % HD_PARAM_COUNT;
        alt[id] = hd_param_table[id].min;
        seq = (flags & 16u) ? fz_u32(&s) : 0u;
        FUZZ_ASSERT(hd_pstore_save(def, &seq) == 0);
        FUZZ_ASSERT(hd_pstore_save(alt, &seq) == 0);
        while (fz_left(&s) >= 3u) {
            const uint32_t off = fz_u16(&s) % (2u * NVM_PAGE);
            nvm[off] ^= fz_u8(&s);
        }
        if (flags & 2u) {
            reseal(0);
        }
        if (flags & 4u) {
            reseal(1);
        }
    }
    nvm_fail_read = (flags & 8u) != 0u;

    const int32_t st = hd_pstore_load(v, &seq);
    FUZZ_ASSERT(st >= HD_PSTORE_OK && st <= HD_PSTORE_NVM_ERROR);
    if (st != HD_PSTORE_OK) {
        FUZZ_ASSERT(memcmp(v, def, sizeof v) == 0);
        FUZZ_ASSERT(seq == 0u);
    } else {
        for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) {
            FUZZ_ASSERT(hd_params_check(i, v[i]) == 0);
        }
        FUZZ_ASSERT(slot_holds(0, v) || slot_holds(1, v));
    }
    nvm_fail_read = 0;
    /* a save after any boot must give back exactly what was saved */
    const uint32_t seq0 = seq;
    if (hd_pstore_save(v, &seq) == 0) {
        /* newer than the boot's seq, when the boot read the NVM (after a read error the boot's
         * seq 0 carries no order; what matters then is that the next load returns this save) */
        FUZZ_ASSERT((flags & 8u) != 0u || seq - seq0 - 1u < 0x7FFFFFFFu);
        FUZZ_ASSERT((flags & 8u) != 0u || seq == seq0 + 1u);
        uint32_t seq2 = 0;
        FUZZ_ASSERT(hd_pstore_load(w, &seq2) == HD_PSTORE_OK);
        FUZZ_ASSERT(memcmp(v, w, sizeof v) == 0);
        FUZZ_ASSERT(seq2 == seq);
    }
    return 0;
}
