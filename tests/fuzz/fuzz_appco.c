/*
 * fuzz_appco.c - the CANopen device with the real drive application behind it:
 * the stack (hd_co, CiA 402), the adapter hd_app_co and hd_app (compensator bank,
 * capture, excitation, parameter / table / object stores) on the host port's hal
 * (sensors, power-stage command, CAN controller model, NVM with flash semantics).
 * The input is what a host, the bus and the power supply can do to a drive.
 *
 * Input: records, the first byte the operation (op % 16), then its arguments
 * (a stream that runs out reads as zeros):
 *   0  SDO download of any dictionary entry (u16 entry, u32 value, u8 variant:
 *      the value raw / min / max / default / min - 1 / max + 1, right or wrong size)
 *   1  SDO upload of any entry (u16 entry)
 *   2  start a segmented table download 0x5100:1..3 (u8 kind, u32 argument, u8
 *      corruption): Preisach table, friction or TE group, each with its CRC-32 trailer
 *   3  the next (u8 % 16 + 1) segments of that download; other operations in between
 *   4  a table download in one go by SDO block transfer (kind, argument, corruption)
 *   5  upload of a domain (0x5000:7 capture data, 0x5100:1..3), segmented or block
 *   6  RPDO 1..4 at its COB-ID (u8 pdo, u8 dlc, 8 data bytes)
 *   7  SYNC (with or without counter)
 *   8  NMT command (start, stop, pre-operational, reset node, reset communication)
 *      to this node, to all, or to another node
 *   9  (u8 % 32 + 1) control periods (hd_app_step + hd_co_tick) with a sensor model:
 *      the axis follows its reference, at rest, noise, or channels flagged invalid
 *   10 CiA 402 walk to OPERATION ENABLED in a mode (fault reset, 0x06, 0x07, 0x0F)
 *      by SDO or by RPDO 1, with control periods in between
 *   11 power-up reboot from the NVM written so far
 *   12 crafted stored image: the real save format (parameters or the CANopen object
 *      record), 1..4 payload or header words changed, CRC re-sealed; then reboot
 *   13 0x1010 save, 0x1011 restore, capture arm / trigger, excitation start / stop,
 *      store status reads, 0x6007 / 0x605A options
 *   14 CAN controller model: error burst, bus-off, good frames, TX queue full on/off
 *   15 any frame (11-bit id, dlc 0..15, data)
 *
 * Invariants (abort, so libFuzzer keeps the input):
 *   - no crash, no UB, no ASan error;
 *   - every frame sent has dlc <= 8 and an 11-bit id; SDO replies are 8 bytes; nothing
 *     is sent while the stack knows the controller is bus-off; no frame on a restricted
 *     COB-ID of CiA 301 but the drive's own SDO reply and heartbeat
 *     (FUZZ_CHECK_RESTRICTED_COBID);
 *   - the power stage (the hal command's enable) is off unless the 402 state is
 *     OPERATION ENABLED or QUICK STOP ACTIVE, and off while the app is faulted;
 *   - after an NMT stop / pre-operational / reset received in OPERATIONAL with 0x6007
 *     != 0, the power stage is off from the next control period on (QUICK STOP ACTIVE
 *     allowed: option 3 ramps), until the 402 state machine has left OPERATION ENABLED
 *     (FUZZ_CHECK_NMT_REACTION);
 *   - no table becomes live (Preisach table in force, group version) while the power
 *     stage is on (FUZZ_CHECK_COMMIT_INTERLOCK);
 *   - parameters stay in range (hd_params_check); a refused SDO write leaves the
 *     entry's value;
 *   - after a reboot the parameters are exactly the defaults or exactly one stored
 *     slot's set, the stored CANopen objects exactly the defaults or exactly one
 *     stored record, a loaded Preisach table passes its check; no RPDO maps an
 *     object that is not writable and RPDO-mappable (FUZZ_CHECK_LOAD_VALIDATION);
 *   - a 0x1010 save with the power stage off succeeds.
 * Each FUZZ_CHECK_* (default 1) guards one invariant so that a build can leave it out
 * (mk/fuzz.mk FUZZ_APPCO_DEFS) and still fuzz the rest; -DFUZZ_TRACE prints one state
 * line per operation.
 */
#include <string.h>
#include "fuzz_common.h"
#include "hd_app.h"
#include "hd_app_co.h"
#include "hd_co.h"
#include "hd_le32.h"
#include "hal_host.h"

#ifndef FUZZ_CHECK_NMT_REACTION
#define FUZZ_CHECK_NMT_REACTION 1
#endif
#ifndef FUZZ_CHECK_COMMIT_INTERLOCK
#define FUZZ_CHECK_COMMIT_INTERLOCK 1
#endif
#ifndef FUZZ_CHECK_LOAD_VALIDATION
#define FUZZ_CHECK_LOAD_VALIDATION 1
#endif
#ifndef FUZZ_CHECK_RESTRICTED_COBID
#define FUZZ_CHECK_RESTRICTED_COBID 1
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define NODE        5u
#define MAX_OPS     192u
#define MAX_PERIODS 1500u
#define DBUF        (4u * HD_APP_CO_STAGE_WORDS + 16u)
#define PS_REC      ((6u + HD_PARAM_COUNT + 1u) * 4u)   /* parameter record bytes (hd_param_store.h) */
#define PS_SEQ      8u                                  /* its sequence number's byte offset */

static hd_host_port_t port;
static hd_app_t app;
static hd_app_co_t ac;
static hd_co_t CO;
static hd_co_t scratch;                   /* applies a stored image for the "never a mix" check */
static hd_co402_t scratch402;              /* its CiA 402 profile */
static uint8_t nvm_keep[HD_HOST_NVM_SIZE];

typedef struct {
    int tx_full;
    uint8_t rsp[8];                       /* last SDO reply */
    uint32_t n_rsp;
    uint32_t periods;
    uint32_t last_enable;                 /* hal command of the last period */
    uint16_t last_init_index;             /* index of the last SDO download initiated */
    int nmt_req;                          /* an NMT command that must stop the power stage */
    /* segmented table download in progress */
    int dl_active;
    uint8_t dl_sub, dl_tog;
    uint32_t dl_len, dl_off;
    uint8_t dbuf[DBUF];
    /* default image of the stored CANopen objects */
    uint32_t def_img[HD_CO_STORE_MAX];
    uint32_t def_words;
    int32_t def_param[HD_PARAM_COUNT];
    uint32_t sensor_pos_lo;
} harness_t;

static harness_t H;

/* ---- frames out ------------------------------------------------------------------- */

#if FUZZ_CHECK_RESTRICTED_COBID
/* CiA 301 restricted COB-IDs (7.3.5): not to be used by configurable objects */
static int restricted_cob(uint32_t id)
{
    return id == 0u || (id >= 0x001u && id <= 0x07Fu) || (id >= 0x101u && id <= 0x180u) ||
           (id >= 0x581u && id <= 0x5FFu) || (id >= 0x601u && id <= 0x67Fu) ||
           (id >= 0x6E0u && id <= 0x6FFu) || (id >= 0x701u && id <= 0x77Fu) || id >= 0x780u;
}
#endif

static bool p_send(void *c, const hd_can_frame_t *f)
{
    (void)c;
    FUZZ_ASSERT(CO.can_state != HD_HAL_CAN_BUS_OFF);
    FUZZ_ASSERT(f->dlc <= 8u);
    FUZZ_ASSERT(f->ext == 0u && f->rtr == 0u && f->id <= 0x7FFu);
    if (f->id == 0x580u + NODE) {
        FUZZ_ASSERT(f->dlc == 8u);
    }
#if FUZZ_CHECK_RESTRICTED_COBID
    if (f->id != 0x580u + NODE && f->id != 0x700u + NODE) {
        FUZZ_ASSERT(!restricted_cob(f->id));
    }
#endif
    if (H.tx_full) {
        return false;
    }
    if (f->id == 0x580u + NODE) {
        memcpy(H.rsp, f->data, 8u);
        H.n_rsp++;
    }
    return true;
}

static bool scratch_send(void *c, const hd_can_frame_t *f) { (void)c; (void)f; return true; }

/* ---- checks ------------------------------------------------------------------------ */

static int powered(void) { return app.mode != HD_MODE_OFF && app.fault == HD_FAULT_NONE; }

/* what a commit changes: the Preisach table in force and the group versions */
static uint32_t table_sig(void)
{
    uint32_t crc = hd_crc32(0u, (const uint8_t *)&app.cb.table_ok, sizeof app.cb.table_ok);
    for (uint32_t w = 0u; w < 10u; w++) {
        const uint32_t v = hd_preisach_word_get(&app.cb.table, w);
        crc = hd_crc32(crc, (const uint8_t *)&v, 4u);
    }
    return crc;
}
static uint32_t group_sig(void)
{
    const int32_t v[2] = {app.param[HD_P_TBL_FR_VERSION], app.param[HD_P_TBL_TE_VERSION]};
    return hd_crc32(0u, (const uint8_t *)v, sizeof v);
}

static void check_rpdo_maps(void)
{
#if FUZZ_CHECK_LOAD_VALIDATION
    for (uint32_t i = 0u; i < HD_CO_N_PDO; i++) {
        const hd_co_pdo_rt_t *p = &CO.rpdo[i];
        for (uint32_t k = 0u; p->valid && k < p->nmap; k++) {
            FUZZ_ASSERT(p->ent[k] < CO.count);
            const hd_co_entry_t *e = &CO.table[p->ent[k]];
            FUZZ_ASSERT((e->access & HD_CO_A_W) != 0u && (e->flags & HD_CO_F_RPDO) != 0u);
        }
    }
#endif
}

static void check_always(void)
{
    for (uint32_t i = 0u; i < HD_PARAM_COUNT; i++) {
        FUZZ_ASSERT(hd_params_check(i, app.param[i]) == 0);
    }
    if (H.nmt_req && hd_co402_state(&ac.p402) != HD_CO402_OP_ENABLED && hd_co402_state(&ac.p402) != HD_CO402_QUICK_STOP) {
        H.nmt_req = 0;                      /* the reaction happened */
    }
    check_rpdo_maps();
}

/* one received frame, with the checks that watch a single frame */
static void rx(const hd_can_frame_t *f)
{
    const uint32_t ts = table_sig(), gs = group_sig();
    const int pw = powered();
    const uint8_t nmt0 = CO.nmt;
    const int16_t opt = CO.od.abort_connection_option_code;
    if (f->id == 0x600u + NODE && f->dlc == 8u && !f->rtr) {
        const uint8_t ccs = f->data[0] >> 5;
        if (ccs == 1u || (ccs == 6u && (f->data[0] & 1u) == 0u)) {
            H.last_init_index = (uint16_t)(f->data[1] | (f->data[2] << 8));
        }
    }
    hd_co_process(&CO, f);
#if FUZZ_CHECK_COMMIT_INTERLOCK
    if (pw) {
        FUZZ_ASSERT(table_sig() == ts);                     /* Preisach table installed while on */
        if (H.last_init_index != 0x2880u) {                 /* (0x2880 direct writes are allowed) */
            FUZZ_ASSERT(group_sig() == gs);                 /* group committed while on */
        }
    }
#else
    (void)ts; (void)gs; (void)pw;
#endif
    if (f->id == 0u && f->dlc == 2u && !f->rtr && (f->data[1] == 0u || f->data[1] == NODE)) {
        const uint8_t cmd = f->data[0];
        if ((cmd == 0x02u || cmd == 0x80u || cmd == 0x81u || cmd == 0x82u) && nmt0 == HD_CO_NMT_OP && opt != 0) {
            H.nmt_req = 1;
        }
    }
    check_always();
}

static void rx_frame(uint32_t id, uint8_t dlc, const uint8_t *d)
{
    hd_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    if (d != NULL) {
        memcpy(f.data, d, 8u);
    }
    rx(&f);
}

/* one SDO request; 1 if a reply came */
static int sdo(const uint8_t d[8])
{
    const uint32_t n = H.n_rsp;
    rx_frame(0x600u + NODE, 8u, d);
    return H.n_rsp != n;
}

static uint32_t type_bytes(uint8_t t)
{
    switch (t) {
    case HD_CO_T_BOOL: case HD_CO_T_I8: case HD_CO_T_U8: return 1u;
    case HD_CO_T_I16: case HD_CO_T_U16: return 2u;
    case HD_CO_T_I32: case HD_CO_T_U32: return 4u;
    case HD_CO_T_I64: case HD_CO_T_U64: return 8u;
    default: return 0u;
    }
}

/* ---- control periods ------------------------------------------------------------------ */

static void period(uint32_t how, uint32_t rnd)
{
    hd_hal_sensors_t se;
    memset(&se, 0, sizeof se);
    se.valid = HD_HAL_VALID_ALL;
    const uint64_t p = (how == 0u) ? (uint64_t)app.tel.pos_ref : (uint64_t)H.sensor_pos_lo << 8;
    /* default encoders: output 24 bit per turn, motor 17 bit per motor turn, N = 100 */
    se.output_enc_raw = (uint32_t)((p + 128u) >> 8) & 0xFFFFFFu;
    se.motor_enc_raw = (uint32_t)((p * 100u + 16384u) >> 15) & 0x1FFFFu;
    if (how == 2u) {
        se.output_enc_raw ^= rnd & 0xFFu;
        se.motor_enc_raw ^= (rnd >> 8) & 0xFFu;
        se.current = (int32_t)(rnd >> 12) - (1 << 19);
        se.gyro_rate = (int32_t)rnd;
    } else if (how == 3u) {
        se.valid = rnd & 0xFu;
    }
    hd_host_port_latch(&port, &se);
    const uint8_t st = hd_co402_state(&ac.p402);
    hd_app_step(&app);
    while (hd_app_background(&app)) {          /* the background between the periods, as on the drive */
    }
    const hd_hal_command_t *c = hd_host_port_command(&port);
    if (c->enable != 0u) {
        FUZZ_ASSERT(st == HD_CO402_OP_ENABLED || st == HD_CO402_QUICK_STOP);
        FUZZ_ASSERT(app.fault == HD_FAULT_NONE);
#if FUZZ_CHECK_NMT_REACTION
        /* an NMT stop / pre-op / reset in OPERATIONAL stops the power stage within a period */
        FUZZ_ASSERT(!(H.nmt_req > 1 && CO.nmt != HD_CO_NMT_OP && st != HD_CO402_QUICK_STOP));
#endif
    }
    H.last_enable = c->enable;
    hd_host_port_end_period(&port);
    hd_co_tick(&CO, HD_CO_TICK_US);
    if (H.nmt_req) {
        H.nmt_req = (CO.nmt == HD_CO_NMT_OP) ? 0 : 2;   /* back in OPERATIONAL before it was due */
    }
    H.periods++;
    check_always();
}

static void periods(uint32_t n, uint32_t how, uint32_t rnd)
{
    for (uint32_t i = 0u; i < n && H.periods < MAX_PERIODS; i++) {
        period(how, rnd);
    }
}

/* ---- stores: boot, crafted images ------------------------------------------------------ */

static hd_rstore_t co_store(void)
{
    hd_rstore_t s;
    s.offset = hd_tstore_offset() + 2u * hd_tstore_slot_size();
    s.slot = hd_rstore_slot_bytes(HD_CO_STORE_MAX);
    s.magic = HD_APP_CO_CSTORE_MAGIC;
    s.words_max = HD_CO_STORE_MAX;
    s.check = NULL;
    return s;
}

static uint32_t co_get(const void *ctx, uint32_t w) { return hd_co_store_word((const hd_co_t *)ctx, w); }

/* slot k of the CANopen object record: 1 and its payload words if it is a valid record */
static int co_slot(uint32_t k, uint32_t img[HD_CO_STORE_MAX], uint32_t *n)
{
    const hd_rstore_t s = co_store();
    const uint8_t *b = &port.nvm[s.offset + k * s.slot];
    *n = hd_get_le32(&b[12]);
    if (hd_get_le32(&b[0]) != s.magic || hd_get_le32(&b[4]) != 1u || *n > HD_CO_STORE_MAX) {
        return 0;
    }
    if (hd_crc32(0u, b, 16u + 4u * *n) != hd_get_le32(&b[16u + 4u * *n])) {
        return 0;
    }
    for (uint32_t w = 0u; w < *n; w++) {
        img[w] = hd_get_le32(&b[16u + 4u * w]);
    }
    return 1;
}

static int live_co_equals(const hd_co_t *co, const uint32_t *img, uint32_t n)
{
    if (n != hd_co_store_words(&CO)) {
        return 0;
    }
    for (uint32_t w = 1u; w < n; w++) {
        if (hd_co_store_word(co, w) != img[w]) {
            return 0;
        }
    }
    return 1;
}

static void check_boot(void)
{
    static uint32_t img[HD_CO_STORE_MAX], norm[HD_CO_STORE_MAX];
    const uint32_t ss = hd_pstore_region() / 2u;
    int ok;
    /* parameters: the defaults or one slot's set, never a mix */
    ok = memcmp(app.param, H.def_param, sizeof app.param) == 0;
    for (uint32_t k = 0u; k < 2u && !ok; k++) {
        int same = 1;
        for (uint32_t i = 0u; i < HD_PARAM_COUNT && same; i++) {
            same = hd_get_le32(&port.nvm[k * ss + (6u + i) * 4u]) == (uint32_t)app.param[i];
        }
        ok = same;
    }
    FUZZ_ASSERT(ok);
    FUZZ_ASSERT(app.pstore_status >= HD_PSTORE_OK && app.pstore_status <= HD_PSTORE_NVM_ERROR);
    /* stored CANopen objects: the defaults or one stored record (as applied), never a mix */
    FUZZ_ASSERT(ac.cstore_status <= HD_APP_CO_CSTORE_REFUSED);
    ok = live_co_equals(&CO, H.def_img, H.def_words);
    /* a record the SDO write checks refuse leaves exactly the defaults */
    FUZZ_ASSERT(ac.cstore_status != HD_APP_CO_CSTORE_REFUSED || ok);
    for (uint32_t k = 0u; k < 2u && !ok; k++) {
        uint32_t n = 0u;
        if (co_slot(k, img, &n) && n == hd_co_store_words(&CO)) {
            hd_co_app_if_t ifc;
            memset(&ifc, 0, sizeof ifc);
            ifc.send = scratch_send;
            hd_co402_use(&scratch402, &ifc);
            hd_co_init(&scratch, NODE, &ifc);
            if (hd_co_store_apply(&scratch, img, n, 0x1000u, 0xFFFFu) == 0) {
                for (uint32_t w = 0u; w < n; w++) {
                    norm[w] = hd_co_store_word(&scratch, w);
                }
                ok = live_co_equals(&CO, norm, n);
            }
        }
    }
    FUZZ_ASSERT(ok);
    if (app.cb.table_ok != 0u) {
        FUZZ_ASSERT(hd_preisach_check(&app.cb.table) == HD_PREISACH_OK);
    }
    check_always();
}

static void boot(int first)
{
    static const hd_app_co_port_t pif = {NULL, p_send, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL};
    memcpy(nvm_keep, port.nvm, sizeof nvm_keep);
    hd_host_port_init(&port);
    if (!first) {
        memcpy(port.nvm, nvm_keep, sizeof port.nvm);
    }
    hd_host_port_bind(&port);
    memset(&app, 0, sizeof app);
    memset(&ac, 0, sizeof ac);
    H.tx_full = 0;
    H.dl_active = 0;
    H.nmt_req = 0;
    H.last_enable = 0u;
    hd_app_init(&app);
    hd_app_co_init(&ac, &CO, &app, NODE, &pif);
    if (first) {
        hd_params_defaults(H.def_param);
        H.def_words = hd_co_store_words(&CO);
        FUZZ_ASSERT(H.def_words <= HD_CO_STORE_MAX);
        for (uint32_t w = 0u; w < H.def_words; w++) {
            H.def_img[w] = hd_co_store_word(&CO, w);
        }
    }
    check_boot();
    period(1u, 0u);
}

/* the real save of the parameters or of the object record, words changed, CRC re-sealed */
static void crafted(fz_stream_t *s)
{
    const uint8_t b = fz_u8(s);
    const uint32_t nmut = (uint32_t)(b >> 1) % 4u + 1u;
    if ((b & 1u) == 0u) {
        const uint32_t ss = hd_pstore_region() / 2u;
        uint32_t seq = app.pstore_seq;
        if (hd_pstore_save(app.param, &seq) != 0) {
            return;
        }
        uint32_t k = (hd_get_le32(&port.nvm[PS_SEQ]) == seq) ? 0u : 1u;
        uint8_t *r = &port.nvm[k * ss];
        FUZZ_ASSERT(hd_get_le32(&r[PS_SEQ]) == seq);
        for (uint32_t m = 0u; m < nmut; m++) {
            const uint8_t how = fz_u8(s);
            const uint32_t id = fz_u8(s) % HD_PARAM_COUNT;
            const uint32_t raw = fz_u32(s);
            uint32_t w = 6u + id, v = raw;
            switch (how % 6u) {
            case 0: v = (uint32_t)hd_param_table[id].min - 1u; break;
            case 1: v = (uint32_t)hd_param_table[id].max + 1u; break;
            case 2: v = (uint32_t)hd_param_table[id].min; break;
            case 3: v = (uint32_t)hd_param_table[id].max; break;
            case 4: w = raw % (6u + HD_PARAM_COUNT); v = raw >> 8; break;   /* header words too */
            default: break;
            }
            hd_put_le32(&r[4u * w], v);
        }
        hd_put_le32(&r[PS_REC - 4u], hd_crc32(0u, r, PS_REC - 4u));
    } else {
        const hd_rstore_t st = co_store();
        const uint32_t n = hd_co_store_words(&CO);
        uint32_t seq = ac.cstore_seq;
        static uint32_t maps[HD_CO_N_PDO * HD_CO_N_MAP + HD_CO_N_PDO];
        uint32_t nmaps = 0u, k = 1u;
        if (n < 2u || hd_rstore_save(&st, &CO, co_get, n, &seq) != 0) {
            return;
        }
        /* image words of the RPDO mapping entries */
        for (uint32_t i = 0u; i < CO.count; i++) {
            const hd_co_entry_t *e = &CO.table[i];
            if (e->kind == HD_CO_K_VAR && (e->flags & HD_CO_F_STORE) != 0u && type_bytes(e->type) <= 4u) {
                if (e->index >= 0x1600u && e->index < 0x1600u + HD_CO_N_PDO && e->sub >= 1u && nmaps < sizeof maps / sizeof maps[0]) {
                    maps[nmaps++] = k;
                }
                k++;
            }
        }
        const uint32_t slot = (hd_get_le32(&port.nvm[st.offset + 8u]) == seq &&
                               hd_get_le32(&port.nvm[st.offset]) == st.magic) ? 0u : 1u;
        uint8_t *r = &port.nvm[st.offset + slot * st.slot];
        FUZZ_ASSERT(hd_get_le32(&r[8]) == seq && hd_get_le32(&r[12]) == n);
        for (uint32_t m = 0u; m < nmut; m++) {
            const uint8_t how = fz_u8(s);
            const uint16_t a = fz_u16(s);
            const uint32_t raw = fz_u32(s);
            uint32_t w = 1u + a % (n - 1u), v = raw;
            switch (how % 4u) {
            case 0: {                  /* an RPDO mapping entry -> any object of the dictionary */
                /* raw = index << 8 | sub of an object, else any entry */
                const int32_t f = hd_co_find(&CO, (uint16_t)(raw >> 8), (uint8_t)raw);
                const hd_co_entry_t *e = &CO.table[f >= 0 ? (uint32_t)f : raw % CO.count];
                w = nmaps ? maps[a % nmaps] : w;
                v = ((uint32_t)e->index << 16) | ((uint32_t)e->sub << 8) | (8u * type_bytes(e->type));
                break;
            }
            case 1: v = raw & 0x7FFu; break;                  /* a bare 11-bit COB-ID */
            case 2: v = hd_get_le32(&r[16u + 4u * w]) ^ (1u << (raw % 32u)); break;
            default: break;
            }
            hd_put_le32(&r[16u + 4u * w], v);
        }
        hd_put_le32(&r[16u + 4u * n], hd_crc32(0u, r, 16u + 4u * n));
    }
    boot(0);
}

/* ---- SDO transfers --------------------------------------------------------------------- */

static void sdo_download(uint16_t index, uint8_t sub, const uint8_t *v, uint32_t len)
{
    uint8_t d[8] = {0};
    d[1] = (uint8_t)index;
    d[2] = (uint8_t)(index >> 8);
    d[3] = sub;
    if (len <= 4u) {
        d[0] = (uint8_t)(0x23u | ((4u - len) << 2));
        memcpy(&d[4], v, len);
        (void)sdo(d);
        return;
    }
    d[0] = 0x21u;
    hd_put_le32(&d[4], len);
    if (!sdo(d) || H.rsp[0] != 0x60u) {
        return;
    }
    uint8_t t = 0u;
    for (uint32_t off = 0u; off < len; off += 7u) {
        const uint32_t n = (len - off < 7u) ? len - off : 7u;
        uint8_t g[8] = {0};
        g[0] = (uint8_t)((t << 4) | ((7u - n) << 1) | (off + n >= len ? 1u : 0u));
        memcpy(&g[1], v + off, n);
        if (!sdo(g) || (H.rsp[0] & 0xE0u) != 0x20u) {
            return;
        }
        t ^= 1u;
    }
}

static void write_u32(uint16_t index, uint8_t sub, uint32_t v, uint32_t len)
{
    uint8_t b[4];
    hd_put_le32(b, v);
    sdo_download(index, sub, b, len);
}

/* upload: segmented (block = 0) or block; at most max_seg segments */
static void sdo_upload(uint16_t index, uint8_t sub, int block, uint32_t max_seg)
{
    uint8_t d[8] = {0};
    d[1] = (uint8_t)index;
    d[2] = (uint8_t)(index >> 8);
    d[3] = sub;
    if (!block) {
        d[0] = 0x40u;
        if (!sdo(d) || (H.rsp[0] & 0xE2u) != 0x40u) {
            return;                           /* abort or expedited */
        }
        uint8_t t = 0u;
        for (uint32_t k = 0u; k < max_seg; k++) {
            uint8_t g[8] = {0};
            g[0] = (uint8_t)(0x60u | (t << 4));
            if (!sdo(g) || (H.rsp[0] & 0xE0u) != 0x00u || ((H.rsp[0] >> 4) & 1u) != t) {
                return;
            }
            if (H.rsp[0] & 1u) {
                return;                       /* last segment */
            }
            t ^= 1u;
        }
        uint8_t ab[8] = {0x80u, d[1], d[2], d[3], 0, 0, 0, 0x08};
        (void)sdo(ab);
        return;
    }
    d[0] = 0xA4u;
    d[4] = (uint8_t)(max_seg % 127u + 1u);    /* block size */
    if (!sdo(d) || (H.rsp[0] & 0xF9u) != 0xC0u) {
        return;
    }
    uint8_t g[8] = {0xA3u};
    int seen_last = 0;
    for (uint32_t k = 0u; k < 64u; k++) {
        if (!sdo(g)) {
            return;
        }
        if (seen_last) {                      /* all acknowledged: the end comes */
            if ((H.rsp[0] & 0xE3u) == 0xC1u) {
                uint8_t e[8] = {0xA1u};
                (void)sdo(e);
            }
            return;
        }
        if (H.rsp[0] == 0x80u) {
            return;                           /* abort */
        }
        seen_last = (H.rsp[0] & 0x80u) != 0u;
        memset(g, 0, sizeof g);
        g[0] = 0xA2u;
        g[1] = H.rsp[0] & 0x7Fu;              /* every segment up to the last one seen */
        g[2] = 127u;
    }
}

/* a table payload (+ CRC-32 trailer) into H.dbuf; returns its length */
static uint32_t build_table(uint32_t kind, uint32_t arg, uint32_t bad)
{
    uint32_t len;
    static hd_preisach_table_t t;
    if (kind == 1u) {
        memset(&t, 0, sizeof t);
        t.version = arg >> 8;
        t.levels = 2u + arg % 7u;
        t.sub_bits = (arg >> 3) % 3u;
        t.in_shift = 8u + (arg >> 5) % 8u;
        t.u0 = -(int32_t)(1u << 15);
        t.unit = (arg >> 4) % 3u;
        for (uint32_t i = 0u; i < t.levels; i++) {
            for (uint32_t j = 0u; j < i; j++) {
                t.e[i * (i + 1u) / 2u + j] = (int32_t)((i - j) * (i - j) * ((arg >> 16) % 64u + 1u));
            }
        }
        hd_preisach_seal(&t);
        len = 0u;
        for (uint32_t w = 0u; w < 10u + t.n_entries; w++, len += 4u) {
            hd_put_le32(&H.dbuf[len], hd_preisach_word_get(&t, w));
        }
    } else {
        const uint16_t *ids;
        const uint32_t n = hd_app_co_group_ids(kind, &ids);
        hd_put_le32(&H.dbuf[0], kind == HD_APP_CO_DOM_FRICTION ? HD_APP_CO_MAGIC_FR : HD_APP_CO_MAGIC_TE);
        hd_put_le32(&H.dbuf[4], HD_APP_CO_GROUP_FORMAT);
        hd_put_le32(&H.dbuf[8], (arg & 0x7FFFFFu) + 1u);
        hd_put_le32(&H.dbuf[12], n);
        for (uint32_t i = 0u; i < n; i++) {
            int32_t v = app.param[ids[i]];
            if (i == (arg >> 24) % n) {       /* one value at an end of its range */
                v = ((arg >> 23) & 1u) ? hd_param_table[ids[i]].max : hd_param_table[ids[i]].min;
            }
            hd_put_le32(&H.dbuf[16u + 4u * i], (uint32_t)v);
        }
        len = 16u + 4u * n;
    }
    switch (bad % 8u) {
    case 1: H.dbuf[(bad >> 3) % len] ^= 0x10u; break;            /* damaged, trailer made to match */
    case 2: len -= 4u * ((bad >> 3) % 3u + 1u); break;            /* truncated */
    case 3: hd_put_le32(&H.dbuf[len], 0u); len += 4u; break;      /* one word too many */
    default: break;
    }
    hd_put_le32(&H.dbuf[len], hd_crc32(0u, H.dbuf, len));
    if (bad % 8u == 4u) {
        H.dbuf[len] ^= 1u;                                        /* wrong trailer */
    }
    return len + 4u;
}

static void dl_start(fz_stream_t *s)
{
    const uint32_t kind = fz_u8(s) % 3u + 1u;
    const uint32_t arg = fz_u32(s);
    const uint32_t bad = fz_u8(s);
    uint8_t d[8] = {0x21u, 0x00u, 0x51u, (uint8_t)kind};
    H.dl_len = build_table(kind, arg, bad);
    hd_put_le32(&d[4], (bad % 8u == 5u) ? H.dl_len + 7u : H.dl_len);   /* wrong size indicated */
    H.dl_active = sdo(d) && H.rsp[0] == 0x60u;
    H.dl_sub = (uint8_t)kind;
    H.dl_off = 0u;
    H.dl_tog = 0u;
}

static void dl_next(uint32_t count)
{
    for (uint32_t k = 0u; k < count && H.dl_active; k++) {
        const uint32_t n = (H.dl_len - H.dl_off < 7u) ? H.dl_len - H.dl_off : 7u;
        const int last = H.dl_off + n >= H.dl_len;
        uint8_t g[8] = {0};
        g[0] = (uint8_t)((H.dl_tog << 4) | ((7u - n) << 1) | (last ? 1u : 0u));
        memcpy(&g[1], &H.dbuf[H.dl_off], n);
        if (!sdo(g) || (H.rsp[0] & 0xE0u) != 0x20u) {
            H.dl_active = 0;
            return;
        }
        H.dl_off += n;
        H.dl_tog ^= 1u;
        if (last) {
            H.dl_active = 0;
        }
    }
}

static void dl_block(fz_stream_t *s)
{
    const uint32_t kind = fz_u8(s) % 3u + 1u;
    const uint32_t arg = fz_u32(s);
    const uint32_t bad = fz_u8(s);
    const uint32_t len = build_table(kind, arg, bad);
    uint8_t d[8] = {(uint8_t)((bad & 0x80u) ? 0xC2u : 0xC6u), 0x00u, 0x51u, (uint8_t)kind};
    hd_put_le32(&d[4], len);
    H.dl_active = 0;
    if (!sdo(d) || H.rsp[0] != 0xA4u) {
        return;
    }
    uint32_t blk = H.rsp[4], off = 0u;
    while (off < len) {
        uint32_t seq;
        if (blk == 0u || blk > 127u) {
            return;
        }
        const uint32_t n0 = H.n_rsp;
        for (seq = 1u; seq <= blk && off < len; seq++) {
            const uint32_t n = (len - off < 7u) ? len - off : 7u;
            uint8_t g[8] = {0};
            g[0] = (uint8_t)(seq | (off + n >= len ? 0x80u : 0u));
            memcpy(&g[1], &H.dbuf[off], n);
            rx_frame(0x600u + NODE, 8u, g);
            off += n;
        }
        if (H.n_rsp == n0 || H.rsp[0] != 0xA2u || H.rsp[1] != seq - 1u) {
            return;
        }
        blk = H.rsp[2];
    }
    const uint32_t pad = (7u - len % 7u) % 7u;
    const uint16_t crc = (uint16_t)(hd_co_crc16(0u, H.dbuf, len) ^ ((bad & 0x40u) ? 1u : 0u));
    uint8_t e[8] = {(uint8_t)(0xC1u | (pad << 2)), (uint8_t)crc, (uint8_t)(crc >> 8)};
    (void)sdo(e);
}

/* ---- operations ------------------------------------------------------------------------ */

static void op_sdo_write(fz_stream_t *s)
{
    const uint32_t ent = fz_u16(s) % CO.count;
    uint32_t raw = fz_u32(s);
    const uint8_t var = fz_u8(s);
    const hd_co_entry_t *e = &CO.table[ent];
    uint32_t len = type_bytes(e->type);
    uint8_t v[8] = {0};
    int64_t x = (int64_t)raw;
    switch (var % 8u) {
    case 1: x = e->min; break;
    case 2: x = e->max; break;
    case 3: x = e->def; break;
    case 4: x = (e->min > INT64_MIN) ? e->min - 1 : e->min; break;
    case 5: x = (e->max < INT64_MAX) ? e->max + 1 : e->max; break;
    default: break;
    }
    for (uint32_t i = 0u; i < 8u; i++) {
        v[i] = (uint8_t)((uint64_t)x >> (8u * i));
    }
    if (len == 0u || (var & 0x80u)) {
        len = (var >> 3) % 8u + 1u;      /* strings, domains, wrong sizes */
    }
    uint8_t before[8] = {0}, after[8] = {0};
    uint32_t lb = 0u, la = 0u;
    const int plain = (e->kind == HD_CO_K_VAR || e->kind == HD_CO_K_PARAM) && type_bytes(e->type) != 0u;
    const uint32_t rb = plain ? hd_co_read(&CO, ent, before, sizeof before, &lb) : 1u;
    const uint32_t n0 = H.n_rsp;
    sdo_download(e->index, e->sub, v, len);
    if (plain && rb == 0u && H.n_rsp != n0 && H.rsp[0] == 0x80u) {
        /* refused: the old value stays */
        FUZZ_ASSERT(hd_co_read(&CO, ent, after, sizeof after, &la) == 0u);
        FUZZ_ASSERT(la == lb && memcmp(before, after, lb) == 0);
    }
}

static void walk(fz_stream_t *s)
{
    static const int8_t modes[6] = {HD_CO402_MODE_PP, HD_CO402_MODE_CSP, HD_CO402_MODE_CSV,
                                    HD_CO402_MODE_CST, HD_CO402_MODE_STAB, HD_CO402_MODE_NONE};
    static const uint16_t cw[5] = {0x00u, 0x80u, 0x06u, 0x07u, 0x0Fu};
    const uint8_t b = fz_u8(s);
    const int8_t m = modes[b % 6u];
    for (uint32_t i = 0u; i < 5u; i++) {
        if (b & 0x80u) {                                  /* RPDO 1: controlword + mode */
            const uint8_t d[8] = {(uint8_t)cw[i], (uint8_t)(cw[i] >> 8), (uint8_t)m};
            rx_frame(CO.rpdo[0].cob, 3u, d);
        } else {
            if (i == 0u) {
                write_u32(0x6060u, 0u, (uint32_t)(uint8_t)m, 1u);
            }
            write_u32(0x6040u, 0u, cw[i], 2u);
        }
        periods((b >> 3) % 4u + 1u, 0u, 0u);
    }
}

static void op_misc(fz_stream_t *s)
{
    const uint8_t b = fz_u8(s);
    const uint32_t a = fz_u32(s);
    switch (b % 8u) {
    case 0: {
        const int off = app.mode == HD_MODE_OFF && CO.sdo.state == 0u;   /* power off, SDO server idle */
        const uint32_t n0 = H.n_rsp;
        write_u32(0x1010u, 1u, 0x65766173u, 4u);
        if (off && H.n_rsp != n0) {
            FUZZ_ASSERT(H.rsp[0] == 0x60u);         /* saved */
        }
        break;
    }
    case 1:
        write_u32(0x1011u, 1u, 0x64616F6Cu, 4u);
        break;
    case 2:
        write_u32(0x5000u, 3u, a, 4u);
        write_u32(0x5000u, 4u, (a >> 4) % 700u, 4u);
        write_u32(0x5000u, 5u, (a >> 12) % 5u + 1u, 2u);
        write_u32(0x5000u, 6u, (a >> 16) % 300u, 4u);
        write_u32(0x5000u, 1u, 1u, 1u);
        break;
    case 3:
        write_u32(0x5000u, 1u, 2u, 1u);
        break;
    case 4:
        write_u32(0x5010u, 3u, a % 8u, 1u);
        write_u32(0x5010u, 4u, (a >> 3) % 5u, 1u);
        write_u32(0x5010u, 5u, (a >> 8) & 0xFFFu, 4u);
        write_u32(0x5010u, 9u, (a >> 20) % 4000u, 4u);
        write_u32(0x5010u, 1u, 1u, 1u);
        break;
    case 5:
        write_u32(0x5010u, 1u, 0u, 1u);
        break;
    case 6:
        sdo_upload(0x5101u, (uint8_t)(a % 6u), 0, 4u);
        sdo_upload(0x5010u, 2u, 0, 4u);
        sdo_upload(0x5000u, 2u, 0, 4u);
        break;
    default:
        write_u32(0x6007u, 0u, (a & 0xFFu) % 5u, 2u);
        write_u32(0x605Au, 0u, (a >> 8) % 8u, 2u);
        break;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_stream_t s;
    fz_init(&s, data, size);
    memset(&H, 0, sizeof H);
    boot(1);
    for (uint32_t k = 0u; k < MAX_OPS && fz_left(&s) > 0u; k++) {
        const uint8_t op = fz_u8(&s);
#ifdef FUZZ_TRACE
        fprintf(stderr, "op %2u: nmt %02x 402 %u app mode %d fault %d enable %u table %u fr %d 6007 %d\n", op % 16u, CO.nmt,
                hd_co402_state(&ac.p402), (int)app.mode, (int)app.fault, (unsigned)H.last_enable, (unsigned)app.cb.table_ok,
                (int)app.param[HD_P_TBL_FR_VERSION],
                (int)CO.od.abort_connection_option_code);
#endif
        switch (op % 16u) {
        case 0: op_sdo_write(&s); break;
        case 1: {
            const hd_co_entry_t *e = &CO.table[fz_u16(&s) % CO.count];
            sdo_upload(e->index, e->sub, (op >> 4) & 1u, 16u);
            break;
        }
        case 2: dl_start(&s); break;
        case 3: dl_next(fz_u8(&s) % 16u + 1u); break;
        case 4: dl_block(&s); break;
        case 5: {
            const uint8_t b = fz_u8(&s);
            sdo_upload(0x5000u + ((b & 3u) ? 0x100u : 0u), (b & 3u) ? (uint8_t)(b & 3u) : 7u, (b >> 2) & 1u,
                       (uint32_t)(b >> 3) * 8u + 8u);
            break;
        }
        case 6: {
            const uint8_t b = fz_u8(&s);
            const uint8_t dlc = fz_u8(&s) % 9u;
            uint8_t d[8];
            for (uint32_t i = 0u; i < 8u; i++) {
                d[i] = fz_u8(&s);
            }
            const uint32_t i = b % HD_CO_N_PDO;
            rx_frame((b & 0x80u) ? 0x200u + 0x100u * i + NODE : CO.rpdo[i].cob, dlc, d);
            break;
        }
        case 7: {
            const uint8_t c = fz_u8(&s);
            const uint8_t d[8] = {c};
            rx_frame(0x080u, (c & 0x80u) ? 1u : 0u, d);
            break;
        }
        case 8: {
            static const uint8_t cmd[5] = {0x01u, 0x02u, 0x80u, 0x81u, 0x82u};
            const uint8_t b = fz_u8(&s);
            const uint8_t d[8] = {cmd[b % 5u], (uint8_t)((b & 0x40u) ? 0u : ((b & 0x20u) ? NODE + 1u : NODE))};
            rx_frame(0x000u, 2u, d);
            break;
        }
        case 9: {
            const uint8_t b = fz_u8(&s);
            const uint32_t rnd = (b & 0x40u) ? fz_u32(&s) : 0u;
            H.sensor_pos_lo += (uint32_t)(b >> 5) * 977u;
            periods(b % 32u + 1u, (op >> 4) % 4u, rnd);
            break;
        }
        case 10: walk(&s); break;
        case 11: boot(0); break;
        case 12: crafted(&s); break;
        case 13: op_misc(&s); break;
        case 14: {
            const uint8_t b = fz_u8(&s);
            const uint8_t c = fz_u8(&s);
            switch (b % 4u) {
            case 0: hd_host_can_errors(&port, c % 40u, (uint32_t)(c >> 4) * 20u); break;
            case 1: hd_host_can_bus_off(&port); break;
            case 2: for (uint32_t i = 0u; i < c; i++) { (void)hd_host_can_tx_done(&port); } break;
            default: H.tx_full = !H.tx_full; break;
            }
            break;
        }
        default: {
            const uint16_t id = fz_u16(&s);
            const uint8_t dlc = fz_u8(&s) % 16u;
            uint8_t d[8];
            for (uint32_t i = 0u; i < 8u; i++) {
                d[i] = fz_u8(&s);
            }
            hd_can_frame_t f;
            memset(&f, 0, sizeof f);
            f.id = id & 0x7FFu;
            f.dlc = dlc;
            f.rtr = (uint8_t)((id >> 15) & 1u);
            memcpy(f.data, d, 8u);
            rx(&f);
            break;
        }
        }
    }
    hd_host_port_bind(NULL);
    return 0;
}
