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
#include "hd_le32.h"
#include "hd_param_store.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define FUZZ_NVM_SIZE 8192u
#define FUZZ_NVM_PAGE 1024u
#include "fuzz_nvm.h"
#define NVM_SIZE FUZZ_NVM_SIZE
#define NVM_PAGE FUZZ_NVM_PAGE

#define REC_BYTES ((6u + HD_PARAM_COUNT + 1u) * 4u)

static void reseal(uint32_t slot)
{
    uint8_t *r = &nvm[slot * NVM_PAGE];
    hd_put_le32(&r[REC_BYTES - 4u], hd_crc32(0, r, REC_BYTES - 4u));
}
/* values stored in a slot (raw words), for the "never a mix" check */
static int slot_holds(uint32_t slot, const int32_t v[HD_PARAM_COUNT])
{
    const uint8_t *r = &nvm[slot * NVM_PAGE];
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) {
        if (hd_get_le32(&r[(6u + i) * 4u]) != (uint32_t)v[i]) {
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
    static uint8_t before[NVM_SIZE];
    memcpy(before, nvm, sizeof before);
    if (hd_pstore_save(v, &seq) == 0) {
        if (st == HD_PSTORE_OK) {
            /* the newest valid set already holds v: a save writes nothing (flash wear) */
            FUZZ_ASSERT(seq == seq0);
            FUZZ_ASSERT(memcmp(before, nvm, sizeof before) == 0);
        } else {
            /* newer than the boot's seq, when the boot read the NVM (after a read error the
             * boot's seq 0 carries no order; what matters then is that the next load returns
             * this save) */
            FUZZ_ASSERT((flags & 8u) != 0u || seq - seq0 - 1u < 0x7FFFFFFFu);
            FUZZ_ASSERT((flags & 8u) != 0u || seq == seq0 + 1u);
        }
        uint32_t seq2 = 0;
        FUZZ_ASSERT(hd_pstore_load(w, &seq2) == HD_PSTORE_OK);
        FUZZ_ASSERT(memcmp(v, w, sizeof v) == 0);
        FUZZ_ASSERT(seq2 == seq);
    }
    return 0;
}
