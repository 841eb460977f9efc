/*
 * hd_app_co.c - CANopen <-> application adapter (contract: hd_app_co.h).
 */
#include <stddef.h>
#include "hd_app_co.h"
#include "hd_fixed.h"

/* ---- parameter groups (0x5100:2 friction, 0x5100:3 TE) ------------------------------ */

static const uint16_t k_fr_ids[] = {
    HD_P_STR_FC_POS, HD_P_STR_FS_POS, HD_P_STR_VS_POS, HD_P_STR_FV_POS,
    HD_P_STR_FC_NEG, HD_P_STR_FS_NEG, HD_P_STR_VS_NEG, HD_P_STR_FV_NEG,
    HD_P_STR_DELTA, HD_P_STR_EPS_V, HD_P_STR_W_REF, HD_P_STR_TAU_MAX,
    HD_P_LUG_FC, HD_P_LUG_FS, HD_P_LUG_VS, HD_P_LUG_DELTA, HD_P_LUG_SIGMA0,
    HD_P_LUG_SIGMA1, HD_P_LUG_SIGMA2, HD_P_LUG_K_OBS, HD_P_LUG_TAU_MAX, HD_P_LUG_V_SRC
};
static const uint16_t k_te_ids[] = {
    HD_P_TE_N, HD_P_TE_K1, HD_P_TE_TAU_MAX,
    HD_P_TE_ORDER1, HD_P_TE_AMP1, HD_P_TE_PHASE1, HD_P_TE_ORDER2, HD_P_TE_AMP2, HD_P_TE_PHASE2,
    HD_P_TE_ORDER3, HD_P_TE_AMP3, HD_P_TE_PHASE3, HD_P_TE_ORDER4, HD_P_TE_AMP4, HD_P_TE_PHASE4
};

uint32_t hd_app_co_group_ids(uint32_t dom, const uint16_t **ids)
{
    if (dom == HD_APP_CO_DOM_FRICTION) {
        *ids = k_fr_ids;
        return (uint32_t)(sizeof k_fr_ids / sizeof k_fr_ids[0]);
    }
    if (dom == HD_APP_CO_DOM_TE) {
        *ids = k_te_ids;
        return (uint32_t)(sizeof k_te_ids / sizeof k_te_ids[0]);
    }
    *ids = NULL;
    return 0u;
}

static uint32_t group_magic(uint32_t dom)
{
    return (dom == HD_APP_CO_DOM_FRICTION) ? HD_APP_CO_MAGIC_FR : HD_APP_CO_MAGIC_TE;
}

/* ---- words of a Preisach table image ----------------------------------------------- */

/* word w of the staged domain (NULL beyond the staging area) */
static uint32_t *stage_word(hd_app_co_t *ac, uint32_t w)
{
    uint32_t *p = hd_preisach_word(&ac->stage, w);
    if (p != NULL) {
        return p;
    }
    return (w == HD_APP_CO_STAGE_WORDS - 1u) ? &ac->stage_tail : NULL;
}

static uint32_t crc_word(uint32_t crc, uint32_t w)
{
    uint8_t b[4];
    b[0] = (uint8_t)w;
    b[1] = (uint8_t)(w >> 8);
    b[2] = (uint8_t)(w >> 16);
    b[3] = (uint8_t)(w >> 24);
    return hd_crc32(crc, b, 4u);
}

/* ---- table domains: payload words in force ------------------------------------------ */

/* the parameter holding a group's version (saved with the parameters, so a group read
 * back after a power cycle is the saved one with its version) */
static uint32_t group_version_id(uint32_t dom)
{
    return (dom == HD_APP_CO_DOM_FRICTION) ? (uint32_t)HD_P_TBL_FR_VERSION : (uint32_t)HD_P_TBL_TE_VERSION;
}

static uint32_t group_version(const hd_app_co_t *ac, uint32_t dom)
{
    const int32_t v = hd_app_param_get(ac->app, group_version_id(dom));
    return (v > 0) ? (uint32_t)v : 0u;
}

/* number of payload words in force (0: none) */
static uint32_t dom_words(const hd_app_co_t *ac, uint32_t dom)
{
    if (dom == HD_APP_CO_DOM_PREISACH) {
        const hd_preisach_table_t *t = &ac->app->cb.table;
        return (ac->app->cb.table_ok != 0u) ? 10u + t->n_entries : 0u;
    }
    {
        const uint16_t *ids;
        const uint32_t n = hd_app_co_group_ids(dom, &ids);
        return (group_version(ac, dom) != 0u) ? HD_APP_CO_GROUP_HDR + n : 0u;
    }
}

static uint32_t dom_word(const hd_app_co_t *ac, uint32_t dom, uint32_t w)
{
    const uint16_t *ids;
    uint32_t n;
    if (dom == HD_APP_CO_DOM_PREISACH) {
        return hd_preisach_word_get(&ac->app->cb.table, w);
    }
    n = hd_app_co_group_ids(dom, &ids);
    switch (w) {
    case 0u: return group_magic(dom);
    case 1u: return HD_APP_CO_GROUP_FORMAT;
    case 2u: return group_version(ac, dom);
    case 3u: return n;
    default: break;
    }
    return (w - HD_APP_CO_GROUP_HDR < n) ? (uint32_t)hd_app_param_get(ac->app, ids[w - HD_APP_CO_GROUP_HDR]) : 0u;
}

/* commit a staged parameter group: all values or none */
static uint32_t group_commit(hd_app_co_t *ac, uint32_t dom, uint32_t words)
{
    const uint16_t *ids;
    const uint32_t n = hd_app_co_group_ids(dom, &ids);
    int32_t old[HD_APP_CO_GROUP_MAX];
    uint32_t i;
    if (words != HD_APP_CO_GROUP_HDR + n || n > HD_APP_CO_GROUP_MAX ||
        *stage_word(ac, 0u) != group_magic(dom) || *stage_word(ac, 1u) != HD_APP_CO_GROUP_FORMAT ||
        *stage_word(ac, 2u) == 0u || *stage_word(ac, 2u) > 0x7FFFFFFFu || *stage_word(ac, 3u) != n) {
        return HD_CO_AB_STORE;
    }
    for (i = 0u; i < n; i++) {
        const int32_t raw = (int32_t)*stage_word(ac, HD_APP_CO_GROUP_HDR + i);
        if (hd_params_check(ids[i], raw) != 0) {
            return HD_CO_AB_STORE;
        }
        old[i] = hd_app_param_get(ac->app, ids[i]);
    }
    for (i = 0u; i < n; i++) {
        if (hd_app_param_set(ac->app, ids[i], (int32_t)*stage_word(ac, HD_APP_CO_GROUP_HDR + i)) != 0) {
            /* inconsistent combination: put the old set back */
            uint32_t k;
            for (k = n; k-- > 0u;) {
                (void)hd_app_param_set(ac->app, ids[k], old[k]);
            }
            return HD_CO_AB_STORE;
        }
    }
    (void)hd_app_param_set(ac->app, group_version_id(dom), (int32_t)*stage_word(ac, 2u));   /* range checked above */
    return 0u;
}

/* ---- hd_co_app_if_t callbacks --------------------------------------------------------- */

static bool a_send(void *c, const hd_can_frame_t *f)
{
    hd_app_co_t *ac = c;
    return ac->port.send(ac->port.ctx, f);
}

static int32_t a_pget(void *c, uint16_t id)
{
    return hd_app_param_get(((hd_app_co_t *)c)->app, id);
}

static bool power_stage_on(const hd_app_co_t *ac);

static uint32_t a_pset(void *c, uint16_t id, int32_t raw)
{
    hd_app_co_t *ac = c;
    /* the feedback configuration changes only with the power stage off (0x08000022) */
    if (id == (uint16_t)HD_P_FB_CONFIG && raw != hd_app_param_get(ac->app, id) && power_stage_on(ac)) {
        return HD_CO_AB_STATE;
    }
    return hd_app_param_set(ac->app, id, raw) == 0 ? 0u : HD_CO_AB_VALUE;
}

static uint32_t a_dsize(void *c, uint16_t dom, uint32_t *size)
{
    hd_app_co_t *ac = c;
    if (dom == HD_APP_CO_DOM_CAPTURE) {
        const hd_capture_t *cap = &ac->app->cap;
        *size = hd_capture_frames(cap) * cap->cfg.n_ch * 4u;
        return 0u;
    }
    if (dom < HD_APP_CO_DOM_PORT) {
        const uint32_t n = dom_words(ac, dom);
        uint32_t crc = 0u, w;
        for (w = 0u; w < n; w++) {
            crc = crc_word(crc, dom_word(ac, dom, w));
        }
        ac->rd_trailer = crc;
        *size = (n != 0u) ? 4u * n + 4u : 0u;
        return 0u;
    }
    return ac->port.domain_size != NULL ? ac->port.domain_size(ac->port.ctx, dom, size) : HD_CO_AB_NO_OBJECT;
}

static uint32_t a_dread(void *c, uint16_t dom, uint32_t off, uint8_t *buf, uint32_t len)
{
    hd_app_co_t *ac = c;
    uint32_t i;
    if (dom == HD_APP_CO_DOM_CAPTURE) {
        const hd_capture_t *cap = &ac->app->cap;
        const uint32_t nch = (cap->cfg.n_ch != 0u) ? cap->cfg.n_ch : 1u;
        for (i = 0u; i < len; i++) {
            const uint32_t byte = off + i, word = byte / 4u;
            const uint32_t v = (uint32_t)hd_capture_read(cap, word / nch, word % nch);
            buf[i] = (uint8_t)(v >> (8u * (byte % 4u)));
        }
        return 0u;
    }
    if (dom < HD_APP_CO_DOM_PORT) {
        const uint32_t n = dom_words(ac, dom);
        if (off + len > 4u * n + 4u || off + len < off) {
            return HD_CO_AB_GENERAL;
        }
        for (i = 0u; i < len; i++) {
            const uint32_t byte = off + i, word = byte / 4u;
            const uint32_t v = (word < n) ? dom_word(ac, dom, word) : ac->rd_trailer;
            buf[i] = (uint8_t)(v >> (8u * (byte % 4u)));
        }
        return 0u;
    }
    return ac->port.domain_read != NULL ? ac->port.domain_read(ac->port.ctx, dom, off, buf, len)
                                     : HD_CO_AB_NO_OBJECT;
}

/* the power stage is on (or commanded on): no table changes now */
static bool power_stage_on(const hd_app_co_t *ac)
{
    return ac->app->tel.mode != HD_MODE_OFF || ac->app->mode != HD_MODE_OFF;
}

static uint32_t a_dbegin(void *c, uint16_t dom, uint32_t size)
{
    hd_app_co_t *ac = c;
    if (dom == HD_APP_CO_DOM_CAPTURE) {
        return HD_CO_AB_READONLY;
    }
    if (dom < HD_APP_CO_DOM_PORT) {
        if (power_stage_on(ac)) {
            return HD_CO_AB_STATE;             /* tables change with the power stage off */
        }
        if (size > 4u * HD_APP_CO_STAGE_WORDS) {
            return HD_CO_AB_LEN_HIGH;
        }
        ac->stage_dom = (uint8_t)dom;
        ac->stage_bad = 0u;
        ac->stage_len = 0u;
        ac->stage_crc = 0u;
        return 0u;
    }
    return ac->port.domain_write_begin != NULL ? ac->port.domain_write_begin(ac->port.ctx, dom, size)
                                            : HD_CO_AB_NO_OBJECT;
}

static uint32_t a_dwrite(void *c, uint16_t dom, uint32_t off, const uint8_t *buf, uint32_t len)
{
    hd_app_co_t *ac = c;
    uint32_t i;
    if (dom == HD_APP_CO_DOM_CAPTURE) {
        return HD_CO_AB_READONLY;
    }
    if (dom < HD_APP_CO_DOM_PORT) {
        if (dom != ac->stage_dom || off != ac->stage_len) {
            ac->stage_bad = 1u;
            return HD_CO_AB_GENERAL;
        }
        if (len > 4u * HD_APP_CO_STAGE_WORDS - off) {
            ac->stage_bad = 1u;
            return HD_CO_AB_LEN_HIGH;
        }
        for (i = 0u; i < len; i++) {
            const uint32_t byte = off + i;
            uint32_t *w = stage_word(ac, byte / 4u);
            const uint32_t sh = 8u * (byte % 4u);
            if (w == NULL) {
                ac->stage_bad = 1u;
                return HD_CO_AB_LEN_HIGH;
            }
            *w = (*w & ~(0xFFu << sh)) | ((uint32_t)buf[i] << sh);
            /* CRC lags 4 bytes: at the end it covers everything but the trailer */
            if (byte >= 4u) {
                ac->stage_crc = hd_crc32(ac->stage_crc, &ac->stage_win[byte % 4u], 1u);
            }
            ac->stage_win[byte % 4u] = buf[i];
        }
        ac->stage_len = off + len;
        return 0u;
    }
    return ac->port.domain_write != NULL ? ac->port.domain_write(ac->port.ctx, dom, off, buf, len)
                                      : HD_CO_AB_NO_OBJECT;
}

static uint32_t a_dend(void *c, uint16_t dom, uint32_t total, bool complete)
{
    hd_app_co_t *ac = c;
    if (dom == HD_APP_CO_DOM_CAPTURE) {
        return HD_CO_AB_READONLY;
    }
    if (dom < HD_APP_CO_DOM_PORT) {
        uint32_t words, trailer;
        const uint8_t *t = ac->stage_win;
        const uint32_t k = ac->stage_len;      /* the trailer is bytes k-4 .. k-1 */
        const bool ours = (dom == ac->stage_dom) && ac->stage_bad == 0u;
        ac->stage_dom = 0u;
        if (!complete) {
            return 0u;                          /* aborted: the table in force stays */
        }
        if (power_stage_on(ac)) {
            /* enabled after the transfer began (by a path that did not abort it): the
             * table in force stays, the staged one is dropped */
            return HD_CO_AB_STATE;
        }
        if (!ours || total != k || k < 8u || (k % 4u) != 0u) {
            return HD_CO_AB_STORE;
        }
        trailer = (uint32_t)t[(k - 4u) % 4u] | ((uint32_t)t[(k - 3u) % 4u] << 8) |
                  ((uint32_t)t[(k - 2u) % 4u] << 16) | ((uint32_t)t[(k - 1u) % 4u] << 24);
        if (trailer != ac->stage_crc) {
            return HD_CO_AB_STORE;
        }
        words = k / 4u - 1u;
        if (dom == HD_APP_CO_DOM_PREISACH) {
            if (words < 10u || ac->stage.n_entries != words - 10u) {
                return HD_CO_AB_STORE;
            }
            return hd_app_comp_table(ac->app, &ac->stage) == HD_PREISACH_OK ? 0u : HD_CO_AB_STORE;
        }
        return group_commit(ac, dom, words);
    }
    return ac->port.domain_write_end != NULL ? ac->port.domain_write_end(ac->port.ctx, dom, total, complete)
                                          : HD_CO_AB_NO_OBJECT;
}

/* the rate limit's credit grows by one page erase per HD_APP_CO_SAVE_REFILL_US of drive time */
static void save_refill(hd_app_co_t *ac)
{
    const uint64_t now = ac->co->now_us;
    const uint64_t n = (now - ac->save_credit_us) / HD_APP_CO_SAVE_REFILL_US;
    if (ac->save_credit >= HD_APP_CO_SAVE_CREDIT_MAX || n >= (uint64_t)HD_APP_CO_SAVE_CREDIT_MAX * 2u) {
        ac->save_credit_us = now;      /* full (or empty for ages): the next erase starts a new period */
        if (n >= (uint64_t)HD_APP_CO_SAVE_CREDIT_MAX * 2u) {
            ac->save_credit = HD_APP_CO_SAVE_CREDIT_MAX;
        }
        return;
    }
    ac->save_credit += (int32_t)n;
    ac->save_credit_us += n * HD_APP_CO_SAVE_REFILL_US;
    if (ac->save_credit > HD_APP_CO_SAVE_CREDIT_MAX) {
        ac->save_credit = HD_APP_CO_SAVE_CREDIT_MAX;
    }
}

/* page erases counted by the port so far (0 if it counts none) */
static uint32_t wear_total(const hd_app_co_t *ac)
{
    uint32_t total = 0u, max_page = 0u;
    if (ac->port.nvm_wear == NULL || ac->port.nvm_wear(ac->port.ctx, &total, &max_page) != 0) {
        return 0u;
    }
    return total;
}

/* 0x5200: the online Stribeck estimate (hd_fric_est.h), sub-index 1..16 */
static int64_t fric_est_read(const hd_fric_est_t *e, uint8_t sub)
{
    if (sub <= 8u) {
        /* :1..:4 positive direction, :5..:8 negative: fc, fs, vs, fv */
        const hd_stribeck_dir_t *d = &e->est[(sub <= 4u) ? HD_FE_DIR_POS : HD_FE_DIR_NEG];
        const uint32_t k = ((uint32_t)sub - 1u) & 3u;
        return (k == 0u) ? d->fc : (k == 1u) ? d->fs : (k == 2u) ? d->vs : d->fv;
    }
    switch (sub) {
    case 9u: return (int64_t)e->conf[HD_FE_DIR_POS];
    case 10u: return (int64_t)e->conf[HD_FE_DIR_NEG];
    case 11u: return (int64_t)e->fits[HD_FE_DIR_POS];
    case 12u: return (int64_t)e->fits[HD_FE_DIR_NEG];
    case 13u: return (int64_t)e->samples;
    case 14u: return (int64_t)e->feed.w;
    case 15u: return (int64_t)e->scale;
    default: return (int64_t)e->bias;
    }
}

static uint32_t a_special_read(void *c, uint16_t index, uint8_t sub, int64_t *v)
{
    hd_app_co_t *ac = c;
    if (index == 0x5000u && sub == 0u) { *v = 7; return 0u; }
    if (index == 0x5000u && sub == 1u) { *v = 0; return 0u; }
    if (index == 0x5000u && sub == 2u) { *v = (int64_t)ac->app->cap.state; return 0u; }
    if (index == 0x5010u && sub == 1u) { *v = 0; return 0u; }
    if (index == 0x5101u && sub == 1u) { *v = (int64_t)ac->app->pstore_status; return 0u; }
    if (index == 0x5101u && sub == 2u) { *v = (int64_t)ac->app->tstore_status; return 0u; }
    if (index == 0x5101u && sub == 3u) { *v = (int64_t)ac->app->tstore_sync; return 0u; }
    if (index == 0x5101u && sub == 4u) { *v = (int64_t)ac->cstore_status; return 0u; }
    if (index == 0x5101u && sub == 5u) { *v = (int64_t)HD_PARAM_TABLE_HASH; return 0u; }
    if (index == 0x5101u && sub == 6u) { *v = (int64_t)ac->cstore_refused; return 0u; }
    if (index == 0x5102u && sub >= 1u && sub <= 2u) {
        uint32_t total = 0u, max_page = 0u;
        if (ac->port.nvm_wear == NULL || ac->port.nvm_wear(ac->port.ctx, &total, &max_page) != 0) {
            total = 0u;
            max_page = 0u;
        }
        *v = (int64_t)((sub == 1u) ? total : max_page);
        return 0u;
    }
    if (index == 0x5200u && sub >= 1u && sub <= 16u) {
        *v = fric_est_read(&ac->app->cb.fe, sub);
        return 0u;
    }
    if (index == 0x5102u && sub == 3u) { *v = (int64_t)ac->saves_refused; return 0u; }
    if (index == 0x5102u && sub == 4u) { save_refill(ac); *v = (int64_t)ac->save_credit; return 0u; }
    if (index == 0x5010u && sub == 2u) {
        *v = (ac->app->mode != HD_MODE_EXCITATION) ? 0 : (ac->app->exc.done != 0u ? 2 : 1);
        return 0u;
    }
    return HD_CO_AB_NO_OBJECT;
}

static uint32_t a_enable(void *c, int8_t mode, bool on);

/* 0x5010:1: 1 = start the excitation from the 0x5010 configuration (OPERATION ENABLED,
 * no fault, not in quick stop; an armed capture is triggered in the same period),
 * 0 = stop: back to the 402 mode, bumpless (targets = actual values) */
static uint32_t excitation_control(hd_app_co_t *ac, int64_t v)
{
    const hd_co_od_data_t *od = &ac->co->od;
    if (v == 0) {
        if (ac->app->mode == HD_MODE_EXCITATION && hd_co402_state(&ac->p402) == HD_CO402_OP_ENABLED) {
            return a_enable(ac, ac->mode, true) == 0u ? 0u : HD_CO_AB_STATE;
        }
        return 0u;
    }
    if (hd_co402_state(&ac->p402) != HD_CO402_OP_ENABLED || ac->mode == HD_APP_CO_MODE_QSTOP ||
        ac->app->fault != HD_FAULT_NONE || ac->app->mode == HD_MODE_OFF) {
        return HD_CO_AB_STATE;
    }
    hd_exc_cfg_t cfg;
    cfg.kind = (int32_t)od->excitation_type;
    cfg.amp = od->excitation_amplitude;
    cfg.offset = od->excitation_offset;
    cfg.length = od->excitation_duration;
    cfg.hold = od->excitation_hold;
    cfg.n = od->excitation_count;
    cfg.m = od->excitation_steps_per_decade;
    cfg.rate = od->excitation_rate;
    cfg.f0_q16 = od->excitation_f0;
    cfg.f1_q16 = od->excitation_f1;
    cfg.period = od->excitation_period;
    cfg.seed = od->excitation_seed;
    if (hd_app_set_excitation(ac->app, &cfg, (int32_t)od->excitation_injection) != 0) {
        return HD_CO_AB_VALUE;
    }
    if (hd_app_set_mode(ac->app, HD_MODE_EXCITATION) != 0) {
        return HD_CO_AB_STATE;
    }
    if (ac->app->cap.state == HD_CAP_ARMED) {
        hd_app_capture_trigger(ac->app);
    }
    return 0u;
}

static uint32_t a_special_write(void *c, uint16_t index, uint8_t sub, int64_t v)
{
    hd_app_co_t *ac = c;
    if (index == 0x5000u && sub == 1u) {
        if (v == 1) {
            hd_capture_cfg_t cfg;
            uint32_t sig[HD_CAPTURE_MAX_CH];
            uint32_t n = 0u, k;
            const uint32_t packed = ac->co->od.capture_signals;
            for (k = 0u; k < 4u && k < HD_CAPTURE_MAX_CH; k++) {
                const uint32_t id = (packed >> (8u * k)) & 0xFFu;
                if (id == 0xFFu) {
                    continue;
                }
                if (id >= (uint32_t)HD_SIG_COUNT) {
                    return HD_CO_AB_VALUE;
                }
                sig[n++] = id;
            }
            if (n == 0u) {
                return HD_CO_AB_VALUE;
            }
            cfg.n_ch = n;
            cfg.decim = ac->co->od.capture_decimation;
            cfg.frames = ac->co->od.capture_length;
            cfg.pretrig = ac->co->od.capture_pretrigger;
            cfg.trig_mode = HD_CAP_TRIG_COMMAND;   /* 0x5000:1 = 2 triggers */
            cfg.trig_ch = 0u;
            cfg.trig_level = 0;
            return hd_app_capture_arm(ac->app, &cfg, sig) == 0 ? 0u : HD_CO_AB_VALUE;
        }
        if (v == 2) {
            if (ac->app->cap.state != HD_CAP_ARMED) {
                return HD_CO_AB_STATE;
            }
            hd_app_capture_trigger(ac->app);
            return 0u;
        }
        return 0u;
    }
    if (index == 0x5010u && sub == 1u) {
        return excitation_control(ac, v);
    }
    return HD_CO_AB_READONLY;
}

/* the communication-object store: after the Preisach table store's two slots */
static hd_rstore_t co_store(void)
{
    hd_rstore_t s;
    s.offset = hd_tstore_offset() + 2u * hd_tstore_slot_size();
    s.slot = hd_rstore_slot_bytes(HD_CO_STORE_MAX);
    s.magic = HD_APP_CO_CSTORE_MAGIC;
    s.words_max = HD_CO_STORE_MAX;
    s.check = NULL;             /* hd_co_store_apply checks the image */
    return s;
}

static void co_img_put(void *ctx, uint32_t w, uint32_t v)
{
    hd_co_t *co = ctx;
    if (w < HD_CO_STORE_MAX) {
        co->stored[w] = v;
    }
}

static uint32_t co_img_get(const void *ctx, uint32_t w)
{
    return hd_co_store_word((const hd_co_t *)ctx, w);
}

/* 0x1010: drive parameters and the Preisach table (app), then the stored objects */
static uint32_t a_store(void *c)
{
    hd_app_co_t *ac = c;
    const hd_rstore_t st = co_store();
    const uint32_t words = hd_co_store_words(ac->co);
    uint32_t before, cost;
    bool changed;
    if (ac->app->mode != HD_MODE_OFF) {
        return HD_CO_AB_STATE;
    }
    /* only a save that changes the NVM wears the flash, so only such a save is limited;
     * one that changes nothing still runs (it writes nothing, and marks a re-downloaded
     * table that equals the saved one as saved) */
    save_refill(ac);
    changed = hd_app_store_pending(ac->app) != 0 || hd_rstore_same(&st, ac->co, co_img_get, words) == 0;
    if (changed && ac->save_credit <= 0) {
        ac->saves_refused++;
        if (ac->save_emcy == 0u) {
            hd_co_emcy(ac->co, HD_APP_CO_EMCY_SAVE_RATE, 0u, NULL);
            ac->save_emcy = 1u;
        }
        return HD_APP_CO_AB_SAVE_RATE;
    }
    before = wear_total(ac);
    if (hd_app_store_all(ac->app) != 0) {
        return HD_CO_AB_STATE;
    }
    if (hd_rstore_save(&st, ac->co, co_img_get, words, &ac->cstore_seq) != 0) {
        return HD_CO_AB_STORE;
    }
    if (ac->port.nvm_wear != NULL) {
        cost = wear_total(ac) - before;
    } else {
        cost = changed ? (uint32_t)HD_APP_CO_SAVE_COST_UNKNOWN : 0u;
    }
    ac->save_credit -= (cost > (uint32_t)HD_APP_CO_SAVE_CREDIT_MAX) ? HD_APP_CO_SAVE_CREDIT_MAX : (int32_t)cost;
    if (ac->save_emcy != 0u) {
        ac->save_emcy = 0u;
        hd_co_emcy_clear(ac->co, 0u);    /* EMCY 0x0000 unless another error is active */
    }
    hd_co_store_capture(ac->co);         /* NMT resets now return to these */
    return 0u;
}

static uint32_t a_restore(void *c)
{
    hd_app_co_t *ac = c;
    uint32_t i;
    /* the defaults include "no Preisach table": dropping a table in use would step
     * the compensation, so like a save this needs the power stage off */
    if (ac->app->mode != HD_MODE_OFF) {
        return HD_CO_AB_STATE;
    }
    for (i = 0u; i < HD_PARAM_COUNT; i++) {
        (void)hd_app_param_set(ac->app, i, hd_param_table[i].def);
    }
    hd_app_comp_table_clear(ac->app);
    hd_co_store_defaults(ac->co);
    return 0u;
}

static void a_sync(void *c, uint8_t counter)
{
    hd_app_co_t *ac = c;
    if (ac->port.on_sync != NULL) {
        ac->port.on_sync(ac->port.ctx, counter);
    }
}

static int32_t app_mode_for(int8_t m)
{
    switch (m) {
    case HD_CO402_MODE_PP: return HD_MODE_PTP;
    case HD_CO402_MODE_CSV: return HD_MODE_VELOCITY;
    case HD_CO402_MODE_CST: return HD_MODE_TORQUE;
    case HD_CO402_MODE_STAB: return HD_MODE_STAB;   /* vendor mode -1 */
    default: return HD_MODE_POSITION;   /* CSP, and "no mode" = hold position */
    }
}

static uint32_t a_enable(void *c, int8_t mode, bool on)
{
    hd_app_co_t *ac = c;
    if (!on) {
        (void)hd_app_set_mode(ac->app, HD_MODE_OFF);
        ac->mode = 0;
        return 0u;
    }
    /* bumpless: the targets start at the actual values (the loop's position feedback:
     * the output encoder, or in semi-closed the motor-side estimate, hd_feedback.h) */
    const hd_angle_t p0 = hd_app_entry_position(ac->app);
    ac->co->od.target_position = hd_sat32(hd_asr64_rnd(p0, 8u));
    ac->co->od.target_velocity = 0;
    ac->co->od.target_torque = 0;
    hd_app_set_position(ac->app, p0);
    hd_app_set_velocity(ac->app, 0);
    hd_app_set_torque(ac->app, 0);
    /* PP: the entry move goes to where the axis is, not to the previous session's target
     * (a move nobody commanded; while it ran - 20 ms for 0.001 turn - set-points were refused) */
    (void)hd_app_move_to(ac->app, p0);
    if (hd_app_set_mode(ac->app, app_mode_for(mode)) != 0) {
        return 1u;
    }
    ac->mode = mode;
    if (ac->stage_dom != 0u) {
        /* a table download running: it would land with the power stage on, so the client
         * gets 0x08000022 now and the staging is discarded (a_dend, complete = false) */
        hd_co_sdo_abort(ac->co, HD_CO_AB_STATE);
    }
    return 0u;
}

/* One period of the CSV halt ramp: v (2^-32 turn/s) towards 0 by amax / HD_LOOP_HZ
 * (amax 2^-24 turn/s^2: dv = amax 2^8 / HD_LOOP_HZ, at least 1), never past 0. */
static hd_vel_out_t halt_ramp(hd_vel_out_t v, hd_acc_t amax)
{
    int32_t dv = hd_sat32(hd_div64_rnd((int64_t)amax * 256, HD_LOOP_HZ));
    if (dv < 1) {
        dv = 1;
    }
    if (v > 0) {
        return (v > dv) ? v - dv : 0;
    }
    if (v < 0) {
        return (v < -dv) ? v + dv : 0;
    }
    return 0;
}

/* The deceleration a stop option selects (0x605A quick stop, 0x605D halt): 2 the
 * quick-stop deceleration 0x6085, otherwise the profile deceleration traj_amax (= 0x6083). */
static hd_acc_t stop_decel(const hd_app_co_t *ac, int16_t option, uint32_t qs_decel)
{
    if (option == 2 && qs_decel > 0u) {
        return (hd_acc_t)hd_sat32((int64_t)qs_decel);
    }
    return ac->app->traj_cfg.amax;
}

static void a_setpoint(void *c, const hd_co_setpoint_t *sp)
{
    hd_app_co_t *ac = c;
    hd_angle_t pos;
    const hd_acc_t halt_decel = stop_decel(ac, sp->halt_option, sp->quick_stop_decel);
    if (sp->quick_stop != 0u) {
        /* QUICK STOP ACTIVE: velocity control, the command ramping to 0 at the 0x605A
         * deceleration from where the velocity loop was (its reference: bumpless), or from
         * the measured output speed after torque control; the state machine goes on to
         * SWITCH ON DISABLED at standstill */
        if (ac->mode != HD_APP_CO_MODE_QSTOP) {
            const hd_telemetry_t *t = hd_app_telemetry(ac->app);
            const hd_vel_out_t v0 = (ac->mode == HD_CO402_MODE_CST) ? t->vel_out : t->vel_ref;
            (void)hd_app_set_mode(ac->app, HD_MODE_VELOCITY);
            ac->mode = HD_APP_CO_MODE_QSTOP;
            hd_app_set_velocity(ac->app, v0);
        }
        hd_app_set_velocity(ac->app, halt_ramp(ac->app->vel_cmd,
                                               stop_decel(ac, sp->quick_stop_option, sp->quick_stop_decel)));
        ac->halt = sp->halt;
        return;
    }
    pos = (hd_angle_t)sp->target_position * 256;    /* 2^-24 turn -> Q32.32 */
    switch (sp->mode) {
    case HD_CO402_MODE_PP:
        /* halt (controlword bit 8): its rising edge ramps the running move to rest at the
         * 0x605D deceleration (hd_app_halt); while it is set, new set-points are
         * acknowledged but not executed; after it is cleared the axis stays at rest until
         * the next new set-point (docs/can.md, halt) */
        if (sp->halt != 0u) {
            if (ac->halt == 0u) {
                hd_app_halt(ac->app, halt_decel);
            }
        } else if (sp->pp_new != 0u) {
            (void)hd_app_move_to(ac->app, pos);
        }
        break;
    case HD_CO402_MODE_CSV:
        if (sp->halt != 0u) {
            /* halt: the velocity command ramps to 0 at the 0x605D deceleration */
            hd_app_set_velocity(ac->app, halt_ramp(ac->app->vel_cmd, halt_decel));
        } else {
            hd_app_set_velocity(ac->app, sp->target_velocity);
        }
        hd_app_set_torque(ac->app, sp->target_torque);
        break;
    case HD_CO402_MODE_CST:
        hd_app_set_torque(ac->app, sp->target_torque);
        break;
    case HD_CO402_MODE_STAB:
        /* target velocity (0x60FF) = commanded inertial rate; torque = feed-forward */
        hd_app_set_velocity(ac->app, sp->target_velocity);
        hd_app_set_torque(ac->app, sp->target_torque);
        break;
    case HD_CO402_MODE_CSP:
        /* CSP / CST / STAB: halt is ignored - the host owns the cyclic set-point (docs/can.md) */
        hd_app_set_position(ac->app, pos);
        hd_app_set_velocity(ac->app, sp->velocity_offset);
        hd_app_set_torque(ac->app, sp->target_torque);
        break;
    default:
        break;
    }
    ac->halt = sp->halt;
}

uint16_t hd_app_co_emcy_for_fault(int32_t fault)
{
    switch (fault) {
    case HD_FAULT_TORQUE_SAT: return 0x2310u;   /* continuous over-current */
    case HD_FAULT_OVERSPEED: return 0x8400u;    /* velocity speed controller */
    case HD_FAULT_TRAVEL: return 0x8612u;       /* reference limit */
    case HD_FAULT_FOLLOWING: return 0x8611u;    /* following error */
    case HD_FAULT_ENC_JUMP: return 0x7305u;     /* incremental sensor 1 fault */
    case HD_FAULT_SENSOR: return 0x7300u;       /* sensor */
    case HD_FAULT_PARAM: return 0x6320u;        /* parameter error */
    case HD_FAULT_COMM: return HD_CO_EMCY_HB;   /* heartbeat / life guard */
    default: return 0x1000u;
    }
}

static void a_actual(void *c, hd_co_actual_t *a)
{
    hd_app_co_t *ac = c;
    const hd_telemetry_t *t = hd_app_telemetry(ac->app);
    const int32_t v = hd_abs_sat(t->vel_out);
    a->tick = t->tick;
    a->load_angle = t->pos_out;
    a->motor_angle = t->pos_mot;
    /* the motor encoder in output units (0x60E4:1), for a master that knows only 0x6064's unit */
    a->motor_angle_out = hdf_div64_rnd_u16(t->pos_mot, (uint32_t)hd_app_param_get(ac->app, HD_P_GEAR_RATIO));
    a->setpoint_angle = t->pos_ref;
    a->load_velocity = t->vel_out;
    a->motor_velocity = t->vel_mot;
    a->output_torque = t->torque_cmd;
    a->motor_torque = t->motor_torque;
    a->motor_current = t->current;
    a->fault_code = (uint16_t)t->fault;
    a->fault_emcy = (t->fault != 0) ? hd_app_co_emcy_for_fault(t->fault) : 0u;
    a->power_enabled = (t->mode != HD_MODE_OFF) ? 1u : 0u;
    /* 0.1 mturn/s ~ 0.036 deg/s; during a quick stop also the ramp at its end (an axis
     * that lags its ramp, or a standstill before the ramp is down, does not end it) */
    a->standstill = (v < 4295 * 100 && (ac->mode != HD_APP_CO_MODE_QSTOP || ac->app->vel_cmd == 0)) ? 1u : 0u;
    /* PP: the profile generator at rest (move finished, or halted: CiA 402 bit 10 with
     * halt = 1); the position window 0x6067/0x6068 is applied by hd_co_402.c */
    a->at_rest = (ac->mode != HD_CO402_MODE_PP || hd_traj_done(&ac->app->traj) != 0) ? 1u : 0u;
    a->internal_limit = 0u;
}

static void a_fault_reset(void *c)
{
    hd_app_fault_reset(((hd_app_co_t *)c)->app);
}

static void a_comm_fault(void *c, uint16_t code)
{
    hd_app_co_t *ac = c;
    (void)code;
    /* a real app fault: latched, power stage off, cleared only by the fault reset */
    (void)hd_app_fault_raise(ac->app, HD_FAULT_COMM);
    (void)hd_app_set_mode(ac->app, HD_MODE_OFF);
    ac->mode = 0;
}

/* the CAN controller through hal.h (FDCAN on the drive, the host port's model in the simulator) */
static void a_can_status(void *c, hd_hal_can_status_t *st)
{
    (void)c;
    hd_hal_can_status(st);
}

static void a_can_recover(void *c)
{
    (void)c;
    hd_hal_can_recover();
}

static void a_reset_node(void *c)
{
    hd_app_co_t *ac = c;
    (void)hd_app_set_mode(ac->app, HD_MODE_OFF);
    ac->mode = 0;
}

/* the port's device profile (hd_app_co_port_t.object_filter) */
static uint32_t a_object_filter(void *c, uint16_t index, uint8_t sub)
{
    const hd_app_co_t *ac = c;
    return ac->port.object_filter(ac->port.ctx, index, sub);
}

void hd_app_co_init(hd_app_co_t *ac, hd_co_t *co, hd_app_t *app, uint8_t node_id,
                    const hd_app_co_port_t *port)
{
    hd_co_app_if_t ifc;
    ac->co = co;
    ac->app = app;
    ac->port = *port;
    ac->mode = 0;
    ac->stage_dom = 0u;
    ac->stage_bad = 0u;
    ac->halt = 0u;
    ac->stage_len = 0u;
    ac->stage_crc = 0u;
    ac->rd_trailer = 0u;
    ac->cstore_refused = 0u;
    ac->save_credit = HD_APP_CO_SAVE_CREDIT_MAX;
    ac->save_credit_us = 0u;
    ac->saves_refused = 0u;
    ac->save_emcy = 0u;
    ifc.ctx = ac;
    ifc.send = a_send;
    ifc.param_get = a_pget;
    ifc.param_set = a_pset;
    ifc.domain_size = a_dsize;
    ifc.domain_read = a_dread;
    ifc.domain_write_begin = a_dbegin;
    ifc.domain_write = a_dwrite;
    ifc.domain_write_end = a_dend;
    ifc.special_read = a_special_read;
    ifc.special_write = a_special_write;
    ifc.store = a_store;
    ifc.restore = a_restore;
    ifc.reset_node = a_reset_node;
    ifc.on_sync = a_sync;
    ifc.drive_enable = a_enable;
    ifc.drive_setpoint = a_setpoint;
    ifc.drive_actual = a_actual;
    ifc.drive_fault_reset = a_fault_reset;
    ifc.drive_comm_fault = a_comm_fault;
    ifc.can_status = a_can_status;
    ifc.can_recover = a_can_recover;
    ifc.object_filter = (port->object_filter != NULL) ? a_object_filter : NULL;
    hd_co402_use(&ac->p402, &ifc);
    hd_co_init(co, node_id, &ifc);
    /* the saved communication and CiA 402 settings (0x1010), over the defaults */
    {
        const hd_rstore_t st = co_store();
        uint32_t words = 0u;
        const int32_t rc = hd_rstore_load(&st, co, co_img_put, &ac->cstore_seq, &words);
        if (rc == HD_RSTORE_OK) {
            const int32_t ap = hd_co_store_apply(co, co->stored, words, 0x1000u, 0xFFFFu);
            if (ap == 0) {
                co->stored_ok = 1u;
                ac->cstore_status = HD_APP_CO_CSTORE_OK;
            } else if (ap == -2) {
                /* CRC-valid but a master could not have set it (a read-only object in an
                 * RPDO, a restricted COB-ID, ...): defaults in force, and the master told */
                uint8_t mfr[5] = {0u, 0u, 0u, 0u, 0u};
                ac->cstore_status = HD_APP_CO_CSTORE_REFUSED;
                ac->cstore_refused = ((uint32_t)co->store_refused_index << 8) | co->store_refused_sub;
                mfr[0] = (uint8_t)(co->store_refused_index & 0xFFu);
                mfr[1] = (uint8_t)(co->store_refused_index >> 8);
                mfr[2] = co->store_refused_sub;
                hd_co_emcy(co, HD_APP_CO_EMCY_STORE_REFUSED, HD_CO_ER_GENERIC, mfr);
            } else {
                ac->cstore_status = HD_APP_CO_CSTORE_OTHER;
            }
        } else {
            ac->cstore_status = (rc == HD_RSTORE_BLANK) ? HD_APP_CO_CSTORE_BLANK :
                                ((rc == HD_RSTORE_NVM_ERROR) ? HD_APP_CO_CSTORE_NVM_ERROR : HD_APP_CO_CSTORE_CORRUPT);
        }
    }
}
