/*
 * test_port_flashstore.c - the wear-levelled atomic flash store and the
 * virtual NVM of hal.h (hd_flashstore.h) against a simulated NOR flash with
 * STM32G4 rules (erase whole pages to 0xFF, program erased 8-byte
 * double-words only).
 *
 * Power loss: the simulated flash counts operations (one per programmed
 * double-word, one per page erase); when the budget runs out the operation in
 * progress is TORN (a double-word gets a random subset of its bits programmed
 * and may become unreadable, as with the G4's ECC; an erase leaves random
 * bits set and unreadable double-words) and every later operation fails until
 * the "reboot".  Each test cuts the power at EVERY operation position of a
 * save, reboots, and requires that exactly the old or the new data is read
 * back (the new data if the save had reported success), and that the next
 * save works.  The parameter store of the app (two-slot A/B on top of the
 * hal NVM) is run through the same torture via hd_hal_nvm_* implemented here
 * on hd_vnvm.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "hd_flashstore.h"
#include "hal.h"
#include "hd_param_store.h"
#include "hd_rec_store.h"
#include "hd_table_store.h"
#include "support/test_tables.h"

#define MAXMEM (24u * 2048u)     /* the STM32G474 NVM area: 24 pages of 2 KiB */

typedef struct {
    uint8_t mem[MAXMEM];
    uint8_t bad[MAXMEM / 8u];      /* 1 = double-word unreadable (ECC) */
    uint32_t erase_count[64];
    uint32_t page_size, n_pages;
    int64_t budget;                /* ops left before power loss; < 0 = unlimited */
    int dead;                      /* power lost: every op fails until reboot */
    uint64_t rng;
    uint32_t ops;                  /* operations done (for dry runs) */
    hd_flash_if_t fi;
} simflash_t;

static uint32_t srand32(simflash_t *f)
{
    f->rng ^= f->rng << 13; f->rng ^= f->rng >> 7; f->rng ^= f->rng << 17;
    return (uint32_t)(f->rng >> 11);
}

/* returns 1 if this op may proceed, 0 if power is lost now (op torn) */
static int take(simflash_t *f)
{
    if (f->dead) return -1;
    f->ops++;
    if (f->budget < 0) return 1;
    if (f->budget == 0) { f->dead = 1; return 0; }
    f->budget--;
    return 1;
}

static int32_t sf_read(void *ctx, uint32_t addr, void *buf, uint32_t len)
{
    simflash_t *f = (simflash_t *)ctx;
    uint32_t i;
    if (f->dead || addr > f->page_size * f->n_pages || len > f->page_size * f->n_pages - addr) return -1;
    for (i = addr / 8u; len > 0u && i <= (addr + len - 1u) / 8u; i++) {
        if (f->bad[i]) return -1;
    }
    memcpy(buf, &f->mem[addr], len);
    return 0;
}

static int32_t sf_prog(void *ctx, uint32_t addr, const void *buf, uint32_t len)
{
    simflash_t *f = (simflash_t *)ctx;
    const uint8_t *p = (const uint8_t *)buf;
    uint32_t dw, k;
    assert_int_equal(addr % 8u, 0u);
    assert_int_equal(len % 8u, 0u);
    assert_true(addr + len <= f->page_size * f->n_pages);
    for (dw = 0; dw < len; dw += 8u) {
        for (k = 0; k < 8u; k++) {
            assert_int_equal(f->mem[addr + dw + k], 0xFFu);   /* programming erased memory only */
        }
        const int t = take(f);
        if (t < 0) return -1;
        if (t == 0) {       /* torn: a random subset of the zero bits gets programmed */
            for (k = 0; k < 8u; k++) {
                f->mem[addr + dw + k] = (uint8_t)(p[dw + k] | (uint8_t)srand32(f));
            }
            f->bad[(addr + dw) / 8u] = (uint8_t)(srand32(f) & 1u);
            return -1;
        }
        memcpy(&f->mem[addr + dw], &p[dw], 8u);
    }
    return 0;
}

static int32_t sf_erase(void *ctx, uint32_t page)
{
    simflash_t *f = (simflash_t *)ctx;
    uint32_t i;
    assert_true(page < f->n_pages);
    const int t = take(f);
    if (t < 0) return -1;
    uint8_t *m = &f->mem[page * f->page_size];
    if (t == 0) {           /* torn erase: random bits set, some double-words unreadable */
        for (i = 0; i < f->page_size; i++) m[i] = (uint8_t)(m[i] | (uint8_t)srand32(f));
        for (i = 0; i < f->page_size / 8u; i++) f->bad[page * f->page_size / 8u + i] = (uint8_t)((srand32(f) & 7u) == 0u);
        return -1;
    }
    memset(m, 0xFF, f->page_size);
    memset(&f->bad[page * f->page_size / 8u], 0, f->page_size / 8u);
    f->erase_count[page]++;
    return 0;
}

static void sf_init(simflash_t *f, uint32_t page_size, uint32_t n_pages, uint64_t seed)
{
    memset(f, 0, sizeof *f);
    f->page_size = page_size;
    f->n_pages = n_pages;
    f->budget = -1;
    f->rng = seed | 1u;
    memset(f->mem, 0x5A, sizeof f->mem);     /* factory state: garbage, not erased */
    f->fi.ctx = f;
    f->fi.read = sf_read;
    f->fi.prog = sf_prog;
    f->fi.erase = sf_erase;
    f->fi.page_size = page_size;
    f->fi.n_pages = n_pages;
}

static void reboot(simflash_t *f)
{
    f->dead = 0;
    f->budget = -1;
}

static void fill(uint8_t *p, uint32_t n, uint32_t tag)
{
    uint32_t i;
    for (i = 0; i < n; i++) p[i] = (uint8_t)(tag * 31u + i * 7u + (i >> 3));
}

static simflash_t F;   /* big: static */

static void test_crc32_check_value(void **st)
{
    (void)st;
    assert_int_equal(hd_crc32(0u, (const uint8_t *)"123456789", 9u), 0xCBF43926u);
    /* continuation */
    const uint32_t a = hd_crc32(0u, (const uint8_t *)"1234", 4u);
    assert_int_equal(hd_crc32(a, (const uint8_t *)"56789", 5u), 0xCBF43926u);
}

static void test_basic_and_geometry(void **st)
{
    hd_fstore_t s;
    uint8_t a[64], b[64];
    (void)st;
    sf_init(&F, 256u, 4u, 1u);
    assert_int_equal(hd_fstore_open(&s, &F.fi, 64u), 0);
    assert_int_equal(s.have, 0u);
    assert_int_equal(s.per_page, 2u);          /* 16 + 64 + 8 = 88 bytes */
    assert_int_equal(hd_fstore_read(&s, b), -1);
    fill(a, 64u, 1u);
    assert_int_equal(hd_fstore_save(&s, a), 0);
    assert_int_equal(hd_fstore_read(&s, b), 0);
    assert_memory_equal(a, b, 64u);
    /* reopen finds it */
    assert_int_equal(hd_fstore_open(&s, &F.fi, 64u), 0);
    assert_int_equal(s.have, 1u);
    assert_int_equal(hd_fstore_read(&s, b), 0);
    assert_memory_equal(a, b, 64u);
    /* bad geometry */
    assert_int_equal(hd_fstore_open(&s, &F.fi, 60u), -1);
    assert_int_equal(hd_fstore_open(&s, &F.fi, 256u), -1);
    F.fi.n_pages = 1u;
    assert_int_equal(hd_fstore_open(&s, &F.fi, 64u), -1);
}

static void test_wear_levelling(void **st)
{
    hd_fstore_t s;
    uint8_t a[1024], b[1024];
    uint32_t k, mn = 0xFFFFFFFFu, mx = 0u;
    (void)st;
    sf_init(&F, 2048u, 8u, 2u);               /* the drive's geometry */
    assert_int_equal(hd_fstore_open(&s, &F.fi, 1024u), 0);
    for (k = 0; k < 1000u; k++) {
        fill(a, 1024u, k);
        assert_int_equal(hd_fstore_save(&s, a), 0);
        if (k % 97u == 0u) {                  /* reboots in between do not disturb the rotation */
            assert_int_equal(hd_fstore_open(&s, &F.fi, 1024u), 0);
        }
    }
    assert_int_equal(hd_fstore_open(&s, &F.fi, 1024u), 0);
    assert_int_equal(hd_fstore_read(&s, b), 0);
    assert_memory_equal(a, b, 1024u);
    for (k = 0; k < 8u; k++) {
        if (F.erase_count[k] < mn) mn = F.erase_count[k];
        if (F.erase_count[k] > mx) mx = F.erase_count[k];
    }
    printf("# 1000 saves on 8 pages: erases per page min %u max %u\n", mn, mx);
    assert_true(mx - mn <= 1u);
    assert_int_equal(mx, 125u);
}

/* One power-loss sweep: history of `pre` saves, then a save interrupted at
 * every op position; after reboot the data is old or new, and recovery works. */
static void sweep(uint32_t page, uint32_t npages, uint32_t len, uint32_t pre)
{
    static uint8_t old[1024], nw[1024], got[1024], nxt[1024];
    hd_fstore_t s;
    uint32_t cut, total, n_old = 0, n_new = 0;
    /* dry run to count the ops of the save */
    sf_init(&F, page, npages, 7u);
    assert_int_equal(hd_fstore_open(&s, &F.fi, len), 0);
    for (uint32_t k = 0; k < pre; k++) { fill(old, len, k); assert_int_equal(hd_fstore_save(&s, old), 0); }
    fill(nw, len, 1000u);
    F.ops = 0;
    assert_int_equal(hd_fstore_save(&s, nw), 0);
    total = F.ops;
    for (cut = 0; cut <= total; cut++) {
        sf_init(&F, page, npages, 100u + cut);
        assert_int_equal(hd_fstore_open(&s, &F.fi, len), 0);
        for (uint32_t k = 0; k < pre; k++) { fill(old, len, k); assert_int_equal(hd_fstore_save(&s, old), 0); }
        F.budget = (int64_t)cut;
        const int32_t rc = hd_fstore_save(&s, nw);
        reboot(&F);
        assert_int_equal(hd_fstore_open(&s, &F.fi, len), 0);
        if (pre == 0u && rc != 0) {
            if (s.have == 0u) { n_old++; goto recover; }
        }
        assert_int_equal(s.have, 1u);
        assert_int_equal(hd_fstore_read(&s, got), 0);
        if (memcmp(got, nw, len) == 0) {
            n_new++;
        } else {
            assert_memory_equal(got, old, len);     /* exactly the old set, never a mix */
            assert_int_not_equal(rc, 0);
            n_old++;
        }
recover:
        /* the next save after the torn one works, also when it is torn again half-way */
        fill(nxt, len, 2000u + cut);
        F.budget = (int64_t)(cut / 2u);
        (void)hd_fstore_save(&s, nxt);
        reboot(&F);
        assert_int_equal(hd_fstore_open(&s, &F.fi, len), 0);
        if (s.have) {
            assert_int_equal(hd_fstore_read(&s, got), 0);
            assert_true(memcmp(got, nxt, len) == 0 || memcmp(got, nw, len) == 0 || memcmp(got, old, len) == 0);
        }
        assert_int_equal(hd_fstore_save(&s, nxt), 0);
        assert_int_equal(hd_fstore_open(&s, &F.fi, len), 0);
        assert_int_equal(hd_fstore_read(&s, got), 0);
        assert_memory_equal(got, nxt, len);
    }
    printf("# page %u x %u, payload %u, %u saves before: %u cut points, old %u, new %u\n",
           page, npages, len, pre, total + 1u, n_old, n_new);
    assert_true(n_old > 0u && n_new > 0u);
}

static void test_power_loss_every_position(void **st)
{
    uint32_t pre;
    (void)st;
    /* small geometry, 2 slots per page: covers mid-page slots, page changes and wrap-around */
    for (pre = 0; pre <= 9u; pre++) {
        sweep(256u, 4u, 64u, pre);
    }
    /* the drive's geometry (one slot per page, every save erases) */
    sweep(2048u, 8u, 1024u, 3u);
    sweep(2048u, 8u, 1024u, 8u);
}

/* ---- the hal NVM on hd_vnvm, and the app's parameter store on top -------- */

static hd_vnvm_t V;
uint32_t hd_hal_tick(void) { return 0u; }
void hd_hal_read_sensors(hd_hal_sensors_t *s) { memset(s, 0, sizeof *s); }
void hd_hal_write_command(const hd_hal_command_t *c) { (void)c; }
bool hd_hal_can_send(const hd_can_frame_t *f) { (void)f; return false; }
bool hd_hal_can_recv(hd_can_frame_t *f) { (void)f; return false; }
uint32_t hd_hal_nvm_size(void) { return V.n_vpages * V.vpage; }
uint32_t hd_hal_nvm_page_size(void) { return V.vpage; }
int32_t hd_hal_nvm_read(uint32_t o, void *b, uint32_t l) { return hd_vnvm_read(&V, o, b, l); }
int32_t hd_hal_nvm_write(uint32_t o, const void *b, uint32_t l) { return hd_vnvm_write(&V, o, b, l); }
int32_t hd_hal_nvm_erase(uint32_t o, uint32_t l) { return hd_vnvm_erase(&V, o, l); }

static void test_vnvm_semantics(void **st)
{
    uint8_t b[64], r[64];
    (void)st;
    sf_init(&F, 2048u, 8u, 3u);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
    assert_int_equal(hd_vnvm_read(&V, 0u, r, 64u), 0);
    for (int i = 0; i < 64; i++) assert_int_equal(r[i], 0xFFu);      /* blank */
    fill(b, 64u, 5u);
    assert_int_equal(hd_vnvm_write(&V, 1024u + 64u, b, 64u), 0);
    assert_int_equal(hd_vnvm_write(&V, 1024u + 64u, b, 64u), -1);    /* not erased */
    assert_int_equal(hd_vnvm_write(&V, 4u, b, 8u), -1);              /* misaligned */
    assert_int_equal(hd_vnvm_write(&V, 2044u, b, 8u), -1);           /* out of range */
    assert_int_equal(hd_vnvm_erase(&V, 512u, 1024u), -1);            /* not page aligned */
    assert_int_equal(hd_vnvm_read(&V, 2040u, r, 64u), -1);
    /* a second write into the same page keeps the first (merge) */
    assert_int_equal(hd_vnvm_write(&V, 1024u, b, 64u), 0);
    /* persistent */
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
    assert_int_equal(hd_vnvm_read(&V, 1024u + 64u, r, 64u), 0);
    assert_memory_equal(b, r, 64u);
    assert_int_equal(hd_vnvm_read(&V, 1024u, r, 64u), 0);
    assert_memory_equal(b, r, 64u);
    assert_int_equal(hd_vnvm_read(&V, 0u, r, 8u), 0);
    assert_int_equal(r[0], 0xFFu);                                   /* the other page untouched */
    /* erase reads 0xFF at once; a write after it starts from a blank page */
    assert_int_equal(hd_vnvm_erase(&V, 1024u, 1024u), 0);
    assert_int_equal(hd_vnvm_read(&V, 1024u, r, 8u), 0);
    assert_int_equal(r[0], 0xFFu);
    assert_int_equal(hd_vnvm_write(&V, 1024u + 512u, b, 8u), 0);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
    assert_int_equal(hd_vnvm_read(&V, 1024u, r, 8u), 0);
    assert_int_equal(r[0], 0xFFu);
    assert_int_equal(hd_vnvm_read(&V, 1024u + 512u, r, 8u), 0);
    assert_memory_equal(b, r, 8u);
    /* a failing flash: error, old content stays */
    F.dead = 1;
    assert_true(hd_vnvm_write(&V, 0u, b, 8u) < 0);
    F.dead = 0;
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
    assert_int_equal(hd_vnvm_read(&V, 0u, r, 8u), 0);
    assert_int_equal(r[0], 0xFFu);
    /* geometry */
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 2048u), -1);     /* record does not fit a page */
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 3000u, 1000u), -1);     /* not a power of two */
}

static void test_vnvm_wear_and_power_loss(void **st)
{
    static uint8_t a[1024], b[1024], got[1024];
    uint32_t k, cut, total, n_old = 0, n_new = 0, mn = 0xFFFFFFFFu, mx = 0;
    (void)st;
    /* wear: the app's pattern (erase + write of alternate slots), 1000 saves */
    sf_init(&F, 2048u, 8u, 21u);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
    for (k = 0; k < 1000u; k++) {
        fill(a, 1024u, k);
        assert_int_equal(hd_vnvm_erase(&V, (k & 1u) * 1024u, 1024u), 0);
        assert_int_equal(hd_vnvm_write(&V, (k & 1u) * 1024u, a, 1024u), 0);
    }
    for (k = 0; k < 8u; k++) {
        if (F.erase_count[k] < mn) mn = F.erase_count[k];
        if (F.erase_count[k] > mx) mx = F.erase_count[k];
    }
    printf("# virtual NVM, 1000 slot saves on 8 pages: erases per page min %u max %u\n", mn, mx);
    assert_true(mx - mn <= 1u);
    /* power loss at every operation of a slot write */
    fill(a, 1024u, 1u);
    fill(b, 1024u, 2u);
    sf_init(&F, 2048u, 8u, 22u);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
    assert_int_equal(hd_vnvm_write(&V, 0u, a, 1024u), 0);
    assert_int_equal(hd_vnvm_erase(&V, 0u, 1024u), 0);
    F.ops = 0;
    assert_int_equal(hd_vnvm_write(&V, 0u, b, 1024u), 0);
    total = F.ops;
    for (cut = 0; cut <= total; cut++) {
        sf_init(&F, 2048u, 8u, 900u + cut);
        assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
        for (k = 0; k < cut % 5u; k++) {        /* vary the ring position */
            assert_int_equal(hd_vnvm_erase(&V, 1024u, 1024u), 0);
            assert_int_equal(hd_vnvm_write(&V, 1024u, a, 1024u), 0);
        }
        assert_int_equal(hd_vnvm_write(&V, 0u, a, 1024u), 0);
        assert_int_equal(hd_vnvm_erase(&V, 0u, 1024u), 0);
        F.budget = (int64_t)cut;
        (void)hd_vnvm_write(&V, 0u, b, 1024u);
        reboot(&F);
        assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
        assert_int_equal(hd_vnvm_read(&V, 0u, got, 1024u), 0);
        if (memcmp(got, b, 1024u) == 0) n_new++;
        else { assert_memory_equal(got, a, 1024u); n_old++; }
        if (cut % 5u) {
            assert_int_equal(hd_vnvm_read(&V, 1024u, got, 1024u), 0);
            assert_memory_equal(got, a, 1024u);   /* the other page never disturbed */
        }
    }
    printf("# virtual NVM slot write: %u cut points, old %u, new %u\n", total + 1u, n_old, n_new);
    assert_true(n_old > 0u && n_new > 0u);
}

/* hd_vnvm_wear: the erase count survives a reboot (from the sequence numbers) and the
 * per-page figure bounds the most erased page */
static void test_vnvm_wear_count(void **st)
{
    static uint8_t a[1024];
    uint32_t k, total, max_page, real_total = 0u, real_max = 0u;
    (void)st;
    sf_init(&F, 2048u, 8u, 31u);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 4096u, 1024u), 0);
    hd_vnvm_wear(&V, &total, &max_page);
    assert_int_equal(total, 0u);
    assert_int_equal(max_page, 0u);
    for (k = 0; k < 300u; k++) {
        fill(a, 1024u, k);
        assert_int_equal(hd_vnvm_erase(&V, (k % 3u) * 1024u, 1024u), 0);
        assert_int_equal(hd_vnvm_write(&V, (k % 3u) * 1024u, a, 1024u), 0);
    }
    for (k = 0; k < 8u; k++) {
        real_total += F.erase_count[k];
        if (F.erase_count[k] > real_max) real_max = F.erase_count[k];
    }
    hd_vnvm_wear(&V, &total, &max_page);
    assert_int_equal(total, real_total);
    assert_true(max_page >= real_max);
    assert_true(max_page <= real_total / (8u - 3u) + 2u);
    /* power cycle: the count is read back from the flash, not lost */
    reboot(&F);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 4096u, 1024u), 0);
    hd_vnvm_wear(&V, &total, &max_page);
    assert_int_equal(total, real_total);
    assert_true(max_page >= real_max);
}

static void test_param_store_power_loss(void **st)
{
    int32_t a[HD_PARAM_COUNT], b[HD_PARAM_COUNT], got[HD_PARAM_COUNT];
    uint32_t seq = 0, cut, total, n_old = 0, n_new = 0;
    (void)st;
    hd_params_defaults(a);
    memcpy(b, a, sizeof b);
    /* a second valid set: change values that are in range (re-use another default within range) */
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) {
        if (hd_params_check(i, a[i] + 1) == 0) { b[i] = a[i] + 1; }
    }
    assert_true(memcmp(a, b, sizeof a) != 0);
    /* dry run */
    sf_init(&F, 2048u, 8u, 11u);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
    assert_int_equal(hd_pstore_save(a, &seq), 0);
    F.ops = 0;
    assert_int_equal(hd_pstore_save(b, &seq), 0);
    total = F.ops;
    for (cut = 0; cut <= total; cut++) {
        sf_init(&F, 2048u, 8u, 500u + cut);
        assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
        seq = 0;
        assert_int_equal(hd_pstore_save(a, &seq), 0);
        F.budget = (int64_t)cut;
        (void)hd_pstore_save(b, &seq);
        reboot(&F);
        assert_int_equal(hd_vnvm_open(&V, &F.fi, 2048u, 1024u), 0);
        assert_int_equal(hd_pstore_load(got, &seq), HD_PSTORE_OK);
        if (memcmp(got, b, sizeof b) == 0) n_new++;
        else { assert_memory_equal(got, a, sizeof a); n_old++; }
    }
    printf("# parameter store on the virtual NVM: %u cut points, old %u, new %u\n", total + 1u, n_old, n_new);
    assert_true(n_old > 0u && n_new > 0u);
}

static uint32_t w_get(const void *ctx, uint32_t w) { return *(const uint32_t *)ctx + w; }

/* Flash erases per save on the drive's geometry (24 pages of 2 KiB, 22 KiB of 1 KiB virtual
 * pages): a changed parameter set 1, a 125-word CANopen object record 1, a 64-level
 * Preisach table 9 (one erase per KiB written); an unchanged save 0. */
static void test_erases_per_save_on_the_drive_geometry(void **st)
{
    static hd_preisach_table_t t;
    int32_t a[HD_PARAM_COUNT];
    uint32_t seq = 0u, tseq = 0u, cseq = 0u, e;
    const uint32_t base = 7u;
    hd_rstore_t co;
    (void)st;
    sf_init(&F, 2048u, 24u, 41u);
    assert_int_equal(hd_vnvm_open(&V, &F.fi, 22528u, 1024u), 0);
    hd_params_defaults(a);
    assert_int_equal(hd_pstore_save(a, &seq), 0);
    for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) {
        if (hd_params_check(i, a[i] + 1) == 0) { a[i] = a[i] + 1; break; }
    }
    e = V.erases;
    assert_int_equal(hd_pstore_save(a, &seq), 0);
    assert_int_equal(V.erases - e, 1u);
    e = V.erases;
    assert_int_equal(hd_pstore_save(a, &seq), 0);
    assert_int_equal(V.erases - e, 0u);

    test_everett_table(&t, 64u, 1u, 1000);
    e = V.erases;
    assert_int_equal(hd_tstore_save(&t, &tseq), 0);
    printf("# 64-level table save: %u page erases\n", V.erases - e);
    assert_int_equal(V.erases - e, 9u);
    e = V.erases;
    assert_int_equal(hd_tstore_save(&t, &tseq), 0);
    assert_int_equal(V.erases - e, 0u);

    co.offset = hd_tstore_offset() + 2u * hd_tstore_slot_size();   /* as hd_app_co.c */
    co.slot = hd_rstore_slot_bytes(192u);
    co.magic = 0x53434448u;
    co.words_max = 192u;
    co.check = NULL;
    e = V.erases;
    assert_int_equal(hd_rstore_save(&co, &base, w_get, 125u, &cseq), 0);
    assert_int_equal(V.erases - e, 1u);
    hd_vnvm_wear(&V, &e, &seq);
    assert_int_equal(e, V.erases);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc32_check_value),
        cmocka_unit_test(test_basic_and_geometry),
        cmocka_unit_test(test_wear_levelling),
        cmocka_unit_test(test_power_loss_every_position),
        cmocka_unit_test(test_vnvm_semantics),
        cmocka_unit_test(test_vnvm_wear_and_power_loss),
        cmocka_unit_test(test_vnvm_wear_count),
        cmocka_unit_test(test_param_store_power_loss),
        cmocka_unit_test(test_erases_per_save_on_the_drive_geometry),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
