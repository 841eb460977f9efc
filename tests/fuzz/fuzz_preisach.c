/*
 * fuzz_preisach.c - the Preisach table loader (firmware/core/hd_preisach):
 * hd_preisach_check / hd_preisach_install on arbitrary table images, and the
 * online model, its inverse and the brute-force relay plane on every table
 * that the loader accepts.
 *
 * Input: byte 0 = mode flags
 *   bit 0  structured header (levels/sub_bits/in_shift from small bytes) instead
 *          of raw header words
 *   bit 1  force the diagonal E[i][i] = 0
 *   bit 2  seal (magic, format, n_entries, CRC made right) so that the table
 *          reaches the model code; otherwise the CRC must be guessed
 * then the header, the entries (int32, or int16 when bit 3 is set), then
 * (deadband byte, a sequence of int32 inputs) for the model.
 *
 * Invariants:
 *   - install() copies exactly when check() says OK; a refused table leaves
 *     the installed one bit-for-bit unchanged;
 *   - peek_p(p) == step_p(p) (peek does not change state);
 *   - online model == brute-force relay sum, exactly, while no stack merge
 *     happened (the header promises this for ANY table);
 *   - the inverse returns a lattice index in [0, P].
 */
#include <string.h>
#include "fuzz_common.h"
#include "hd_preisach.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static hd_preisach_table_t t_in, t_dst, t_ref;
static hd_preisach_t fwd;
static hd_preisach_bf_t bf;
static hd_preisach_inv_t inv;

static uint32_t tri(uint32_t l) { return l * (l + 1u) / 2u; }

static void make_reference(hd_preisach_table_t *t)
{
    memset(t, 0, sizeof *t);
    t->version = 7u;
    t->levels = 4u;
    t->sub_bits = 1u;
    t->in_shift = 10u;
    t->u0 = -4096;
    t->unit = HD_PREISACH_UNIT_GENERIC;
    for (uint32_t i = 0; i < 4u; i++) {
        for (uint32_t j = 0; j < i; j++) {
            t->e[tri(i) + j] = (int32_t)((i - j) * (i - j) * 100u);
        }
    }
    hd_preisach_seal(t);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_stream_t s;
    fz_init(&s, data, size);
    const uint8_t flags = fz_u8(&s);

    memset(&t_in, 0, sizeof t_in);
    if (flags & 1u) {
        t_in.levels = fz_u8(&s) % 70u;          /* a few out of range on purpose */
        t_in.sub_bits = fz_u8(&s) % 10u;
        t_in.in_shift = fz_u8(&s) % 33u;
        t_in.u0 = fz_i32(&s);
        t_in.version = fz_u8(&s);
        t_in.unit = fz_u8(&s) % 4u;
        t_in.magic = HD_PREISACH_MAGIC;
        t_in.format = HD_PREISACH_FORMAT;
        t_in.n_entries = (t_in.levels <= HD_PREISACH_L_MAX) ? tri(t_in.levels) : 0u;
        t_in.crc = fz_u32(&s);
    } else {
        t_in.magic = fz_u32(&s);
        t_in.format = fz_u32(&s);
        t_in.version = fz_u32(&s);
        t_in.levels = fz_u32(&s);
        t_in.sub_bits = fz_u32(&s);
        t_in.in_shift = fz_u32(&s);
        t_in.u0 = fz_i32(&s);
        t_in.unit = fz_u32(&s);
        t_in.n_entries = fz_u32(&s);
        t_in.crc = fz_u32(&s);
    }
    uint32_t n = t_in.n_entries < HD_PREISACH_N_MAX ? t_in.n_entries : HD_PREISACH_N_MAX;
    for (uint32_t i = 0; i < n; i++) {
        t_in.e[i] = (flags & 8u) ? (int32_t)(int16_t)fz_u16(&s) : fz_i32(&s);
    }
    if ((flags & 2u) && t_in.levels <= HD_PREISACH_L_MAX) {
        for (uint32_t i = 0; i < t_in.levels && tri(i) + i < HD_PREISACH_N_MAX; i++) {
            t_in.e[tri(i) + i] = 0;
        }
    }
    if (flags & 4u) {
        hd_preisach_seal(&t_in);
    }

    make_reference(&t_ref);
    t_dst = t_ref;
    const int32_t rc = hd_preisach_check(&t_in);
    FUZZ_ASSERT(rc <= 0 && rc >= HD_PREISACH_E_CRC);
    const int32_t rc2 = hd_preisach_install(&t_dst, &t_in);
    FUZZ_ASSERT(rc2 == rc);
    if (rc != HD_PREISACH_OK) {
        FUZZ_ASSERT(memcmp(&t_dst, &t_ref, sizeof t_dst) == 0);
        return 0;
    }
    FUZZ_ASSERT(t_dst.crc == t_in.crc && t_dst.levels == t_in.levels);
    FUZZ_ASSERT(memcmp(t_dst.e, t_in.e, t_in.n_entries * sizeof(int32_t)) == 0);
    FUZZ_ASSERT(hd_preisach_check(&t_dst) == HD_PREISACH_OK);

    const hd_preisach_table_t *t = &t_dst;
    const int32_t P = hd_preisach_p_top(t);
    FUZZ_ASSERT(P >= 1);
    const uint32_t deadband = fz_u8(&s) % 4u;
    hd_preisach_init(&fwd, t, deadband, 0u, true);
    /* brute force is O(P^2) per sample: small lattices only, to keep the rate up */
    const int use_bf = P <= 40;
    if (use_bf) {
        hd_preisach_bf_init(&bf, t, deadband);
    }
    hd_preisach_inv_init(&inv, t, deadband, 0u, true);
    for (uint32_t k = 0; k < 512u && fz_left(&s) >= 2u; k++) {
        const uint8_t op = fz_u8(&s);
        int32_t p;
        if (op & 1u) {
            p = hd_preisach_quantise(t, fz_i32(&s));
        } else {
            p = (int32_t)(fz_u16(&s) % (uint32_t)(P + 1));
        }
        FUZZ_ASSERT(p >= 0 && p <= P);
        (void)hd_preisach_dequantise(t, p);
        const int64_t yp = hd_preisach_peek_p(&fwd, t, p);
        const int64_t y = hd_preisach_step_p(&fwd, t, p);
        FUZZ_ASSERT(yp == y);
        if (use_bf) {
            const int64_t yb = hd_preisach_bf_step_p(&bf, t, p);
            if (fwd.merges == 0u) {
                FUZZ_ASSERT(yb == y);
            }
        }
        if (op & 2u) {
            const int32_t u = fz_i32(&s);
            (void)hd_preisach_step(&fwd, t, u);
            if (use_bf) {
                const int64_t yb = hd_preisach_bf_step_p(&bf, t, hd_preisach_quantise(t, u));
                if (fwd.merges == 0u) {
                    FUZZ_ASSERT(yb == fwd.y);
                }
            }
        }
        if (op & 4u) {
            const int32_t pi = hd_preisach_inv_step_p(&inv, t, (int64_t)fz_i32(&s) * (int64_t)(op >> 3));
            FUZZ_ASSERT(pi >= 0 && pi <= P);
        }
        if (op & 8u) {
            (void)hd_preisach_inv_step(&inv, t, fz_i32(&s));
        }
    }
    return 0;
}
