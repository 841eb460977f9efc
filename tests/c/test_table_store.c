/*
 * test_table_store.c - the Preisach table's two-slot NVM store (hd_table_store.h),
 * and the parameter store as a record of the same two-slot store (hd_rec_store.h),
 * against a stub hal NVM with flash semantics (erase to 0xFF, program only erased
 * bytes, 8-byte granularity) and injected faults: a power cut after any number of
 * programmed bytes, an interrupted erase that leaves garbage, read errors.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "hal.h"
#include "hd_crc32.h"
#include "hd_le32.h"
#include "hd_param_store.h"
#include "hd_rec_store.h"
#include "hd_table_store.h"
#include "support/test_tables.h"

/* ---- stub hal NVM ------------------------------------------------------------ */

#define NVM_SIZE 20480u      /* the STM32G474 layout: 1 KiB pages, 2 + 18 KiB */
#define NVM_PAGE 1024u

static struct {
    uint8_t nvm[NVM_SIZE];
    uint32_t size;           /* what hd_hal_nvm_size() reports */
    int64_t cut_after;       /* bytes still programmed before the "power cut" (-1: none) */
    int erase_garbage;       /* an erase leaves pseudo-random bytes and fails */
    int read_fail;
    uint32_t writes, erases; /* hal calls that changed the NVM */
} N;

uint32_t hd_hal_nvm_size(void) { return N.size; }
uint32_t hd_hal_nvm_page_size(void) { return NVM_PAGE; }

int32_t hd_hal_nvm_read(uint32_t off, void *buf, uint32_t len)
{
    if (N.read_fail || off > N.size || len > N.size - off) return -1;
    memcpy(buf, &N.nvm[off], len);
    return 0;
}

int32_t hd_hal_nvm_write(uint32_t off, const void *buf, uint32_t len)
{
    uint32_t i;
    if (off > N.size || len > N.size - off || off % 8u || len % 8u) return -1;
    for (i = 0; i < len; i++) {
        if (N.cut_after == 0) return -1;                 /* power gone: nothing more */
        if (N.nvm[off + i] != 0xFFu) return -2;          /* not erased */
        N.nvm[off + i] = ((const uint8_t *)buf)[i];
        if (N.cut_after > 0) N.cut_after--;
    }
    N.writes++;
    return 0;
}

int32_t hd_hal_nvm_erase(uint32_t off, uint32_t len)
{
    uint32_t i;
    if (off > N.size || len > N.size - off || off % NVM_PAGE || len % NVM_PAGE) return -1;
    if (N.erase_garbage) {
        for (i = 0; i < len; i++) N.nvm[off + i] = (uint8_t)(i * 37u + 11u);
        return -1;
    }
    memset(&N.nvm[off], 0xFF, len);
    N.erases++;
    return 0;
}

/* ---- fixture --------------------------------------------------------------------- */

typedef struct {
    hd_preisach_table_t a, b, got;
} fx_t;

static int same_image(const hd_preisach_table_t *x, const hd_preisach_table_t *y)
{
    uint32_t w;
    if (x->n_entries != y->n_entries) return 0;
    for (w = 0; w < HD_PREISACH_IMG_HDR + x->n_entries; w++) {
        if (hd_preisach_word_get(x, w) != hd_preisach_word_get(y, w)) return 0;
    }
    return 1;
}

static int setUp(void **state)
{
    fx_t *f = calloc(1, sizeof(fx_t));
    if (f == NULL) return -1;
    memset(&N, 0, sizeof N);
    memset(N.nvm, 0xFF, sizeof N.nvm);
    N.size = NVM_SIZE;
    N.cut_after = -1;
    test_everett_table(&f->a, 16u, 3u, 1000);
    test_everett_table(&f->b, 32u, 4u, 7);
    *state = f;
    return 0;
}

static int tearDown(void **state)
{
    free(*state);
    return 0;
}

/* ---- tests ----------------------------------------------------------------------- */

static void test_layout_after_the_parameter_store(void **state)
{
    (void)state;
    assert_int_equal(hd_tstore_offset(), hd_pstore_region());
    assert_int_equal(hd_tstore_offset(), 2u * NVM_PAGE);
    /* a 64-level image (8 360 bytes) + header + CRC in 9 pages of 1 KiB */
    assert_int_equal(hd_tstore_slot_size(), 9u * NVM_PAGE);
    assert_true(hd_tstore_offset() + 2u * hd_tstore_slot_size() <= NVM_SIZE);
}

static void test_blank_loads_no_table(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 99u;
    assert_int_equal(hd_tstore_load(&f->got, &seq), HD_TSTORE_BLANK);
    assert_int_equal(seq, 0u);
}

static void test_save_load_round_trip_bit_for_bit(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, seq2 = 0u;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    assert_int_equal(seq, 1u);
    assert_int_equal(hd_tstore_load(&f->got, &seq2), HD_TSTORE_OK);
    assert_int_equal(seq2, 1u);
    assert_true(same_image(&f->got, &f->a));
    assert_int_equal(hd_preisach_check(&f->got), HD_PREISACH_OK);
    /* the record is little-endian words: magic, format, sequence, words, then the image */
    assert_int_equal(hd_get_le32(&N.nvm[hd_tstore_offset()]), HD_TSTORE_MAGIC);
    assert_int_equal(hd_get_le32(&N.nvm[hd_tstore_offset() + 12u]), HD_PREISACH_IMG_HDR + f->a.n_entries);
    assert_int_equal(hd_get_le32(&N.nvm[hd_tstore_offset() + 16u]), HD_PREISACH_MAGIC);
    /* the parameter store's slots are untouched */
    for (uint32_t i = 0; i < hd_tstore_offset(); i++) assert_int_equal(N.nvm[i], 0xFF);
}

static void test_largest_table_fits(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u;
    test_everett_table(&f->b, HD_PREISACH_L_MAX, 9u, 3);
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);     /* both slots */
    assert_int_equal(hd_tstore_load(&f->got, &seq), HD_TSTORE_OK);
    assert_true(same_image(&f->got, &f->b));
}

static void test_saves_alternate_and_newest_wins(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, s = 0u;
    const uint32_t s0 = hd_tstore_offset(), s1 = s0 + hd_tstore_slot_size();
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);     /* slot 0, seq 1 */
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);     /* slot 1, seq 2 */
    assert_int_equal(hd_get_le32(&N.nvm[s0 + 8u]), 1u);
    assert_int_equal(hd_get_le32(&N.nvm[s1 + 8u]), 2u);
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_OK);
    assert_true(same_image(&f->got, &f->b));
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);     /* slot 0 again, seq 3 */
    assert_int_equal(hd_get_le32(&N.nvm[s0 + 8u]), 3u);
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_OK);
    assert_int_equal(s, 3u);
    assert_true(same_image(&f->got, &f->a));
}

static void test_power_cut_during_save_keeps_the_old_table(void **state)
{
    fx_t *f = *state;
    /* table b: 16 + 4 (10 + 528) + 4 = 2 172 bytes; cuts in the header, image and CRC */
    const int64_t cuts[] = {0, 8, 16, 17, 64, 100, 1000, 2000, 4 * (10 + 528) + 16, 4 * (10 + 528) + 19};
    uint32_t seq = 0u, s = 0u, k;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    for (k = 0; k < sizeof cuts / sizeof cuts[0]; k++) {
        uint32_t sq = seq;
        N.cut_after = cuts[k];
        assert_int_equal(hd_tstore_save(&f->b, &sq), -2);
        assert_int_equal(sq, seq);                        /* not counted */
        N.cut_after = -1;
        assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_OK);
        assert_int_equal(s, seq);
        assert_true(same_image(&f->got, &f->a));
    }
    /* and the next complete save wins */
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_OK);
    assert_true(same_image(&f->got, &f->b));
}

static void test_interrupted_erase_keeps_the_old_table(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, s = 0u;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    N.erase_garbage = 1;
    assert_int_equal(hd_tstore_save(&f->b, &seq), -2);
    N.erase_garbage = 0;
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_OK);
    assert_true(same_image(&f->got, &f->a));
}

static void test_flipped_bit_in_the_newest_falls_back(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, s = 0u;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);
    N.nvm[hd_tstore_offset() + hd_tstore_slot_size() + 16u + 4u * 40u] ^= 0x10u;   /* an entry of b */
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_OK);
    assert_int_equal(s, 1u);
    assert_true(same_image(&f->got, &f->a));
    /* both bad: corrupt, no table */
    N.nvm[hd_tstore_offset() + 16u + 4u * 12u] ^= 0x01u;
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_CORRUPT);
    assert_int_equal(s, 0u);
}

static void test_record_valid_but_table_bad_is_corrupt(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, s = 0u, crc;
    const uint32_t o = hd_tstore_offset();
    const uint32_t n = HD_PREISACH_IMG_HDR + f->a.n_entries;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    /* a nonzero diagonal entry E[1][1] with the record CRC made to match again: the
     * record is whole, the table's own check refuses it */
    hd_put_le32(&N.nvm[o + 16u + 4u * (HD_PREISACH_IMG_HDR + 2u)], 5u);
    crc = hd_crc32(0u, &N.nvm[o], 16u + 4u * n);
    hd_put_le32(&N.nvm[o + 16u + 4u * n], crc);
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_CORRUPT);
}

static void test_no_table_record(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, s = 0u;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    assert_int_equal(hd_tstore_save(NULL, &seq), 0);      /* after a restore of the defaults */
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_NONE);
    assert_int_equal(s, 2u);
}

static void test_bad_table_refused_nvm_unchanged(void **state)
{
    fx_t *f = *state;
    static uint8_t before[NVM_SIZE];
    uint32_t seq = 0u;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    memcpy(before, N.nvm, NVM_SIZE);
    f->b.crc ^= 1u;
    assert_int_equal(hd_tstore_save(&f->b, &seq), -1);
    assert_int_equal(seq, 1u);
    assert_memory_equal(before, N.nvm, NVM_SIZE);
}

static void test_sequence_newer_than_the_survivor_after_a_default_boot(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, s = 0u;
    /* a, b, a: a save equal to the newest record writes nothing, so the contents alternate */
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);     /* seq 3 in slot 0, 2 in slot 1 */
    assert_int_equal(seq, 3u);
    seq = 0u;                                             /* e.g. a boot with a read error */
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);
    assert_int_equal(seq, 4u);
    assert_int_equal(hd_tstore_load(&f->got, &s), HD_TSTORE_OK);
    assert_true(same_image(&f->got, &f->b));
}

/* flash wear: a save equal to the newest record erases and programs nothing, for the
 * table, "no table" and the parameter set; a changed one is written */
static void test_identical_save_costs_no_erase(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u, pseq = 0u, before;
    int32_t values[HD_PARAM_COUNT];
    assert_int_equal(hd_tstore_same(&f->a), 0);            /* blank: a save writes */
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    assert_int_equal(seq, 1u);
    assert_true(N.erases > 0u);
    before = N.erases + N.writes;
    assert_int_equal(hd_tstore_same(&f->a), 1);
    assert_int_equal(hd_tstore_same(&f->b), 0);
    assert_int_equal(hd_tstore_same(NULL), 0);
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    assert_int_equal(N.erases + N.writes, before);         /* nothing erased, nothing written */
    assert_int_equal(seq, 1u);
    assert_int_equal(hd_tstore_save(&f->b, &seq), 0);      /* changed: written */
    assert_true(N.erases + N.writes > before);
    assert_int_equal(seq, 2u);
    assert_int_equal(hd_tstore_save(NULL, &seq), 0);       /* "no table" once, then free */
    before = N.erases + N.writes;
    assert_int_equal(hd_tstore_same(NULL), 1);
    assert_int_equal(hd_tstore_save(NULL, &seq), 0);
    assert_int_equal(N.erases + N.writes, before);
    assert_int_equal(hd_tstore_load(&f->got, &seq), HD_TSTORE_NONE);

    hd_params_defaults(values);
    assert_int_equal(hd_pstore_same(values), 0);
    assert_int_equal(hd_pstore_save(values, &pseq), 0);
    assert_int_equal(pseq, 1u);
    before = N.erases + N.writes;
    assert_int_equal(hd_pstore_same(values), 1);
    assert_int_equal(hd_pstore_save(values, &pseq), 0);
    assert_int_equal(N.erases + N.writes, before);
    assert_int_equal(pseq, 1u);
    values[0] = (values[0] == hd_param_table[0].max) ? hd_param_table[0].min : hd_param_table[0].max;
    assert_int_equal(hd_pstore_same(values), 0);
    assert_int_equal(hd_pstore_save(values, &pseq), 0);
    assert_true(N.erases + N.writes > before);
    assert_int_equal(pseq, 2u);
}

static void test_nvm_too_small_or_unreadable(void **state)
{
    fx_t *f = *state;
    uint32_t seq = 0u;
    N.size = hd_tstore_offset() + hd_tstore_slot_size();  /* room for one slot only */
    assert_int_equal(hd_tstore_load(&f->got, &seq), HD_TSTORE_NVM_ERROR);
    assert_int_equal(hd_tstore_save(&f->a, &seq), -2);
    assert_int_equal(N.erases + N.writes, 0u);
    N.size = NVM_SIZE;
    assert_int_equal(hd_tstore_save(&f->a, &seq), 0);
    N.read_fail = 1;
    assert_int_equal(hd_tstore_load(&f->got, &seq), HD_TSTORE_NVM_ERROR);
}

/* ---- the parameter store: one record of the two-slot record store ---------------- */

/* a parameter record written by the record store itself: {version, hash, values} */
typedef struct {
    uint32_t version, hash;
    const int32_t *v;
    uint32_t bad_at;            /* value index written out of its range (HD_PARAM_COUNT: none) */
} prec_t;

static uint32_t prec_get(const void *ctx, uint32_t w)
{
    const prec_t *r = ctx;
    if (w == 0u) return r->version;
    if (w == 1u) return r->hash;
    if (w - 2u == r->bad_at) return (uint32_t)hd_param_table[w - 2u].max + 1u;
    return (uint32_t)r->v[w - 2u];
}

/* the parameter store's two slots as a record store that accepts every valid record */
static hd_rstore_t raw_pstore(void)
{
    hd_rstore_t s;
    s.offset = 0u;
    s.slot = hd_pstore_region() / 2u;
    s.magic = HD_PSTORE_MAGIC;
    s.words_max = 2u + HD_PARAM_COUNT;
    s.check = NULL;
    return s;
}

static void test_param_record_is_a_record_store_record(void **state)
{
    static int32_t a[HD_PARAM_COUNT], got[HD_PARAM_COUNT];
    const hd_rstore_t raw = raw_pstore();
    prec_t r;
    uint32_t seq = 0u, n = 0u;
    (void)state;
    hd_params_defaults(a);
    a[HD_P_POS_KP] = hd_param_table[HD_P_POS_KP].min;
    r.version = HD_PARAM_VERSION;
    r.hash = HD_PARAM_TABLE_HASH;
    r.v = a;
    r.bad_at = HD_PARAM_COUNT;
    assert_int_equal(hd_pstore_region(), 2u * hd_rstore_slot_bytes(2u + HD_PARAM_COUNT));
    assert_int_equal(hd_rstore_save(&raw, &r, prec_get, 2u + HD_PARAM_COUNT, &seq), 0);
    assert_int_equal(hd_pstore_load(got, &n), HD_PSTORE_OK);
    assert_int_equal(n, seq);
    assert_memory_equal(got, a, sizeof a);
    assert_int_equal(hd_pstore_same(a), 1);
    /* and the other way round: a parameter save is a record the record store reads */
    a[HD_P_POS_KP] = hd_param_table[HD_P_POS_KP].max;
    assert_int_equal(hd_pstore_save(a, &n), 0);
    assert_int_equal(hd_rstore_same(&raw, &r, prec_get, 2u + HD_PARAM_COUNT), 1);
}

/* a valid record the parameter table refuses (another version, a value out of range)
 * is passed over: the older set loads; none left: INCOMPATIBLE before CORRUPT */
static void test_param_record_refused_by_the_table_falls_back(void **state)
{
    static int32_t a[HD_PARAM_COUNT], b[HD_PARAM_COUNT], got[HD_PARAM_COUNT];
    const hd_rstore_t raw = raw_pstore();
    prec_t r;
    uint32_t seq = 0u, rseq = 0u, n = 0u;
    (void)state;
    hd_params_defaults(a);
    hd_params_defaults(b);
    b[HD_P_POS_KP] = hd_param_table[HD_P_POS_KP].max;
    assert_int_equal(hd_pstore_save(a, &seq), 0);          /* slot 0 */
    assert_int_equal(hd_pstore_save(b, &seq), 0);          /* slot 1, newest */
    r.version = HD_PARAM_VERSION ^ 0x40u;                   /* another table version */
    r.hash = HD_PARAM_TABLE_HASH;
    r.v = a;
    r.bad_at = HD_PARAM_COUNT;
    rseq = seq;
    assert_int_equal(hd_rstore_save(&raw, &r, prec_get, 2u + HD_PARAM_COUNT, &rseq), 0);   /* over a: newest */
    assert_true(rseq - seq - 1u < 0x7FFFFFFFu);
    assert_int_equal(hd_pstore_load(got, &n), HD_PSTORE_OK);
    assert_int_equal(n, seq);
    assert_memory_equal(got, b, sizeof b);
    assert_int_equal(hd_pstore_same(b), 1);
    /* the newest value out of its range, the other slot of another version */
    r.version = HD_PARAM_VERSION;
    r.bad_at = HD_P_POS_KP;
    assert_int_equal(hd_rstore_save(&raw, &r, prec_get, 2u + HD_PARAM_COUNT, &rseq), 0);   /* over b */
    assert_int_equal(hd_pstore_load(got, &n), HD_PSTORE_INCOMPATIBLE);
    assert_int_equal(n, 0u);
    hd_params_defaults(a);
    assert_memory_equal(got, a, sizeof a);
    assert_int_equal(hd_pstore_same(a), 0);
    /* a save then numbers after the records it passed over, and loads back */
    assert_int_equal(hd_pstore_save(b, &n), 0);
    assert_int_equal(hd_pstore_load(got, &seq), HD_PSTORE_OK);
    assert_int_equal(seq, n);
    assert_memory_equal(got, b, sizeof b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_layout_after_the_parameter_store, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_blank_loads_no_table, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_save_load_round_trip_bit_for_bit, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_largest_table_fits, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_saves_alternate_and_newest_wins, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_power_cut_during_save_keeps_the_old_table, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_interrupted_erase_keeps_the_old_table, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_flipped_bit_in_the_newest_falls_back, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_record_valid_but_table_bad_is_corrupt, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_no_table_record, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_bad_table_refused_nvm_unchanged, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_sequence_newer_than_the_survivor_after_a_default_boot, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_identical_save_costs_no_erase, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_nvm_too_small_or_unreadable, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_param_record_is_a_record_store_record, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_param_record_refused_by_the_table_falls_back, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
