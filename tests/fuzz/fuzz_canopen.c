/*
 * fuzz_canopen.c - the CAN frame dispatcher and the SDO server
 * (firmware/canopen/hd_co.c, hd_co_402.c) against a fake application.
 *
 * Input: records of 12 bytes (kind, id lo, id hi, dlc, data[8]):
 *   kind % 4 = 0  frame to this node's SDO server (0x600 + node), dlc from the record
 *              1  frame with any 11-bit identifier (NMT, SYNC, RPDO, heartbeat, ...)
 *              2  frame with any identifier, ext / rtr flags from kind bits 2, 3
 *              3  advance time by (id lo + 1) control periods (time-outs, heartbeat,
 *                 PDOs, CiA 402)
 *   kind bit 4: the TX queue is full for this record (send() returns false)
 *   kind bits 6-7 of a time record: CAN controller state reported to the stack from
 *              now on (0 unchanged, 1 error passive, 2 bus-off, 3 error active); a
 *              recovery request of the stack brings a bus-off controller back
 * The fake application range-checks PARAM writes with the firmware's own
 * hd_params_check and commits DOMAIN downloads only through the Preisach
 * table loader (hd_preisach_check), like the drive.
 *
 * Invariants: every frame sent is well formed (dlc <= 8, 11-bit id); every
 * SDO response is 8 bytes from 0x580 + node; parameters never leave their
 * range; the committed table is always one that passed hd_preisach_check;
 * nothing is sent while the stack knows the controller is bus-off; a 0x1010
 * save keeps the stored objects' image, which the stack accepts back without a
 * change (the NMT resets then return to it).
 */
#include <string.h>
#include "fuzz_common.h"
#include "hd_co.h"
#include "hd_co_402.h"
#include "hd_param_store.h"
#include "hd_preisach.h"
#include "hal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define NODE 5u
#define DOM_CAP (sizeof(hd_preisach_table_t) + 64u)

typedef struct {
    int tx_full;
    uint32_t ntx;
    int32_t param[HD_PARAM_COUNT];
    uint8_t stage[DOM_CAP];
    uint32_t stage_len;
    hd_preisach_table_t table;      /* committed */
    hd_preisach_table_t cand;
    int on;
    uint16_t fault;
    uint8_t can;                    /* HD_HAL_CAN_* reported to the stack */
} ctx_t;

static ctx_t X;
static hd_co_t CO;
static hd_co402_t P402;     /* the CiA 402 profile on top of CO */

/* hd_param_store.o (range checks) also holds the NVM code: no NVM here. */
uint32_t hd_hal_nvm_size(void) { return 0u; }
uint32_t hd_hal_nvm_page_size(void) { return 0u; }
int32_t hd_hal_nvm_read(uint32_t off, void *buf, uint32_t len) { (void)off; (void)buf; (void)len; return -1; }
int32_t hd_hal_nvm_write(uint32_t off, const void *buf, uint32_t len) { (void)off; (void)buf; (void)len; return -1; }
int32_t hd_hal_nvm_erase(uint32_t off, uint32_t len) { (void)off; (void)len; return -1; }

static bool f_send(void *c, const hd_can_frame_t *f)
{
    ctx_t *x = c;
    FUZZ_ASSERT(CO.can_state != HD_HAL_CAN_BUS_OFF);
    FUZZ_ASSERT(f->dlc <= 8u);
    FUZZ_ASSERT(f->ext || f->id <= 0x7FFu);
    if ((f->id & 0x780u) == 0x580u && f->id == 0x580u + NODE) {
        FUZZ_ASSERT(f->dlc == 8u);
    }
    if (x->tx_full) {
        return false;
    }
    x->ntx++;
    return true;
}
static int32_t f_pget(void *c, uint16_t id)
{
    FUZZ_ASSERT(id < HD_PARAM_COUNT);
    return ((ctx_t *)c)->param[id];
}
static uint32_t f_pset(void *c, uint16_t id, int32_t raw)
{
    FUZZ_ASSERT(id < HD_PARAM_COUNT);
    if (hd_params_check(id, raw) != 0) {
        return HD_CO_AB_VALUE;
    }
    ((ctx_t *)c)->param[id] = raw;
    return 0u;
}
static uint32_t f_dsize(void *c, uint16_t dom, uint32_t *size)
{
    (void)c;
    *size = (dom == 1u) ? 40u + 4u * ((ctx_t *)c)->table.n_entries : 0u;
    return 0u;
}
static uint32_t f_dread(void *c, uint16_t dom, uint32_t off, uint8_t *buf, uint32_t len)
{
    ctx_t *x = c;
    uint32_t sz = 0;
    (void)f_dsize(c, dom, &sz);
    if (off > sz || len > sz - off) {
        return HD_CO_AB_GENERAL;
    }
    memcpy(buf, (const uint8_t *)&x->table + off, len);
    return 0u;
}
static uint32_t f_dbegin(void *c, uint16_t dom, uint32_t size)
{
    (void)dom;
    if (size > DOM_CAP) {
        return HD_CO_AB_LEN_HIGH;
    }
    ((ctx_t *)c)->stage_len = 0u;
    return 0u;
}
static uint32_t f_dwrite(void *c, uint16_t dom, uint32_t off, const uint8_t *buf, uint32_t len)
{
    ctx_t *x = c;
    (void)dom;
    if (off > DOM_CAP || len > DOM_CAP - off) {
        return HD_CO_AB_LEN_HIGH;
    }
    memcpy(&x->stage[off], buf, len);
    if (off + len > x->stage_len) {
        x->stage_len = off + len;
    }
    return 0u;
}
static uint32_t f_dend(void *c, uint16_t dom, uint32_t total, bool complete)
{
    ctx_t *x = c;
    (void)dom;
    if (!complete) {
        return 0u;
    }
    FUZZ_ASSERT(total <= DOM_CAP);
    memset(&x->cand, 0, sizeof x->cand);
    memcpy(&x->cand, x->stage, total < sizeof x->cand ? total : sizeof x->cand);
    const int32_t rc = hd_preisach_install(&x->table, &x->cand);
    return rc == HD_PREISACH_OK ? 0u : HD_CO_AB_VALUE;
}
static uint32_t f_special_read(void *c, uint16_t index, uint8_t sub, int64_t *v)
{
    (void)c;
    *v = (int64_t)index + sub;
    return 0u;
}
static uint32_t f_special_write(void *c, uint16_t index, uint8_t sub, int64_t v)
{
    (void)c; (void)index; (void)sub;
    return v < 0 ? HD_CO_AB_VALUE : 0u;
}
/* 0x1010: keep the stored objects' image (as the adapter does after its NVM write); the
 * image of live values must always be one the stack accepts back unchanged */
static uint32_t f_store(void *c)
{
    static uint32_t img[HD_CO_STORE_MAX];
    const uint32_t n = hd_co_store_words(&CO);
    (void)c;
    FUZZ_ASSERT(n <= HD_CO_STORE_MAX);
    hd_co_store_capture(&CO);
    FUZZ_ASSERT(CO.stored_ok != 0u);
    memcpy(img, CO.stored, 4u * n);
    FUZZ_ASSERT(hd_co_store_apply(&CO, img, n, 0x1000u, 0xFFFFu) == 0);
    for (uint32_t w = 0u; w < n; w++) {
        FUZZ_ASSERT(hd_co_store_word(&CO, w) == img[w]);   /* applying it changed nothing */
    }
    return 0u;
}
static uint32_t f_restore(void *c) { (void)c; hd_co_store_defaults(&CO); return 0u; }
static void f_reset_node(void *c) { (void)c; }
static void f_sync(void *c, uint8_t n) { (void)c; (void)n; }
static uint32_t f_enable(void *c, int8_t mode, bool on)
{
    ctx_t *x = c;
    (void)mode;
    if (on && x->fault != 0u) {
        return 1u;
    }
    x->on = on;
    return 0u;
}
static void f_setpoint(void *c, const hd_co_setpoint_t *sp) { (void)c; (void)sp; }
static void f_actual(void *c, hd_co_actual_t *a)
{
    ctx_t *x = c;
    memset(a, 0, sizeof *a);
    a->power_enabled = x->on ? 1u : 0u;
    a->standstill = 1u;
    a->fault_code = x->fault;
    a->fault_emcy = x->fault ? 0x8611u : 0u;
}
static void f_fault_reset(void *c) { ((ctx_t *)c)->fault = 0u; }
static void f_comm_fault(void *c, uint16_t code) { (void)code; ((ctx_t *)c)->on = 0; }
static void f_can_status(void *c, hd_hal_can_status_t *st)
{
    memset(st, 0, sizeof *st);
    st->state = ((ctx_t *)c)->can;
}
static void f_can_recover(void *c) { ((ctx_t *)c)->can = HD_HAL_CAN_ERROR_ACTIVE; }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_stream_t s;
    fz_init(&s, data, size);
    memset(&X, 0, sizeof X);
    hd_params_defaults(X.param);
    hd_co_app_if_t ifc;
    memset(&ifc, 0, sizeof ifc);
    ifc.ctx = &X;
    ifc.send = f_send;
    ifc.param_get = f_pget;
    ifc.param_set = f_pset;
    ifc.domain_size = f_dsize;
    ifc.domain_read = f_dread;
    ifc.domain_write_begin = f_dbegin;
    ifc.domain_write = f_dwrite;
    ifc.domain_write_end = f_dend;
    ifc.special_read = f_special_read;
    ifc.special_write = f_special_write;
    ifc.store = f_store;
    ifc.restore = f_restore;
    ifc.reset_node = f_reset_node;
    ifc.on_sync = f_sync;
    ifc.drive_enable = f_enable;
    ifc.drive_setpoint = f_setpoint;
    ifc.drive_actual = f_actual;
    ifc.drive_fault_reset = f_fault_reset;
    ifc.drive_comm_fault = f_comm_fault;
    ifc.can_status = f_can_status;
    ifc.can_recover = f_can_recover;
    hd_co402_use(&P402, &ifc);
    hd_co_init(&CO, NODE, &ifc);

    for (uint32_t k = 0; k < 1024u && fz_left(&s) >= 4u; k++) {
        const uint8_t kind = fz_u8(&s);
        const uint16_t id = fz_u16(&s);
        hd_can_frame_t f;
        memset(&f, 0, sizeof f);
        f.dlc = (uint8_t)(fz_u8(&s) % 16u);   /* DLC 9..15 on purpose */
        for (uint32_t i = 0; i < 8u; i++) {
            f.data[i] = fz_u8(&s);
        }
        X.tx_full = (kind & 16u) != 0u;
        X.fault = (kind & 32u) ? 1u : X.fault;
        switch (kind % 4u) {
        case 0:
            f.id = 0x600u + NODE;
            hd_co_process(&CO, &f);
            break;
        case 1:
            f.id = id & 0x7FFu;
            hd_co_process(&CO, &f);
            break;
        case 2:
            f.ext = (uint8_t)((kind >> 2) & 1u);
            f.rtr = (uint8_t)((kind >> 3) & 1u);
            f.id = f.ext ? ((uint32_t)id | ((uint32_t)f.data[7] << 16)) : (id & 0x7FFu);
            hd_co_process(&CO, &f);
            break;
        default:
            if ((kind >> 6) != 0u) {
                static const uint8_t st[4] = {0u, HD_HAL_CAN_ERROR_PASSIVE, HD_HAL_CAN_BUS_OFF,
                                              HD_HAL_CAN_ERROR_ACTIVE};
                X.can = st[kind >> 6];
            }
            for (uint32_t i = 0; i <= (id & 0xFFu); i++) {
                hd_co_tick(&CO, HD_CO_TICK_US);
            }
            break;
        }
        for (uint32_t i = 0; i < HD_PARAM_COUNT; i++) {
            FUZZ_ASSERT(hd_params_check(i, X.param[i]) == 0);
        }
        if (X.table.magic != 0u) {
            FUZZ_ASSERT(hd_preisach_check(&X.table) == HD_PREISACH_OK);
        }
    }
    return 0;
}
