/*
 * hal_host.c - hal.h implemented against the simulator harness (see hal_host.h).
 */
#include "hal_host.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

/* The one piece of static state: which port the application's hal calls reach.
 * PC-side only (firmware/core has no globals). */
static hd_host_port_t *g_port = NULL;

void hd_host_port_init(hd_host_port_t *p)
{
    memset(p, 0, sizeof *p);
    memset(p->nvm, 0xFF, sizeof p->nvm);
}

void hd_host_port_bind(hd_host_port_t *p) { g_port = p; }
hd_host_port_t *hd_host_port_bound(void) { return g_port; }

void hd_host_port_latch(hd_host_port_t *p, const hd_hal_sensors_t *s)
{
    p->sensors = *s;
    p->reads = 0u;
    p->writes = 0u;
}

const hd_hal_command_t *hd_host_port_command(const hd_host_port_t *p) { return &p->command; }

static void can_ctrl_update(hd_host_can_ctrl_t *c)
{
    if (c->state == HD_HAL_CAN_BUS_OFF) return;          /* only the recovery leaves it */
    if (c->tec > 255u) {
        c->tec = 256u;
        c->state = HD_HAL_CAN_BUS_OFF;
        c->recovering = 0u;
        if (c->bus_off_count < UINT32_MAX) c->bus_off_count++;
    } else if (c->tec > 127u || c->rec > 127u) {
        c->state = HD_HAL_CAN_ERROR_PASSIVE;
    } else {
        c->state = HD_HAL_CAN_ERROR_ACTIVE;
    }
}

void hd_host_can_errors(hd_host_port_t *p, uint32_t tx_errors, uint32_t rx_errors)
{
    hd_host_can_ctrl_t *c = &p->can_ctrl;
    if (c->state == HD_HAL_CAN_BUS_OFF) return;
    uint32_t t = (uint32_t)c->tec + (tx_errors > 64u ? 512u : 8u * tx_errors);
    uint32_t r = (uint32_t)c->rec + (rx_errors > 255u ? 255u : rx_errors);
    c->tec = (uint16_t)(t > 256u ? 256u : t);
    c->rec = (uint16_t)(r > 255u ? 255u : r);
    can_ctrl_update(c);
}

void hd_host_can_bus_off(hd_host_port_t *p)
{
    if (p->can_ctrl.state == HD_HAL_CAN_BUS_OFF) return;
    p->can_ctrl.tec = 256u;
    can_ctrl_update(&p->can_ctrl);
}

bool hd_host_can_tx_done(hd_host_port_t *p)
{
    hd_host_can_ctrl_t *c = &p->can_ctrl;
    if (c->state == HD_HAL_CAN_BUS_OFF) return false;
    if (c->tec > 0u) c->tec--;
    can_ctrl_update(c);
    return true;
}

bool hd_host_can_rx_done(hd_host_port_t *p)
{
    hd_host_can_ctrl_t *c = &p->can_ctrl;
    if (c->state == HD_HAL_CAN_BUS_OFF) return false;
    if (c->rec > 127u) c->rec = 127u;
    else if (c->rec > 0u) c->rec--;
    can_ctrl_update(c);
    return true;
}

void hd_host_port_end_period(hd_host_port_t *p)
{
    hd_host_can_ctrl_t *c = &p->can_ctrl;
    if (c->state == HD_HAL_CAN_BUS_OFF && c->recovering) {
        if (c->recover_left > 0u) c->recover_left--;
        if (c->recover_left == 0u) {
            c->tec = 0u;
            c->rec = 0u;
            c->recovering = 0u;
            c->state = HD_HAL_CAN_ERROR_ACTIVE;
            if (c->recoveries < UINT32_MAX) c->recoveries++;
        }
    }
    if (p->reads == 0u) p->violations |= HD_HOST_VIOL_NO_READ;
    if (p->reads > 1u) p->violations |= HD_HOST_VIOL_MULTI_READ;
    if (p->writes == 0u) p->violations |= HD_HOST_VIOL_NO_WRITE;
    if (p->writes > 1u) p->violations |= HD_HOST_VIOL_MULTI_WRITE;
    p->tick++; /* wraps after 2^32 periods, meant */
}

/* ---- hal.h ------------------------------------------------------------------- */

uint32_t hd_hal_tick(void) { return g_port ? g_port->tick : 0u; }

void hd_hal_read_sensors(hd_hal_sensors_t *s)
{
    if (!g_port) {
        memset(s, 0, sizeof *s);
        return;
    }
    if (g_port->reads < UINT32_MAX) g_port->reads++;
    *s = g_port->sensors;
}

void hd_hal_write_command(const hd_hal_command_t *c)
{
    if (!g_port) return;
    if (g_port->reads == 0u) g_port->violations |= HD_HOST_VIOL_ORDER;
    if (g_port->writes < UINT32_MAX) g_port->writes++;
    g_port->command = *c;
    if (c->enable == 0u) {
        g_port->command.torque = 0;
        g_port->command.current = 0;
    }
}

bool hd_host_ring_push(hd_host_can_ring_t *r, const hd_can_frame_t *f)
{
    if (r->count >= HD_HOST_CAN_RING) {
        if (r->dropped < UINT32_MAX) r->dropped++;
        return false;
    }
    uint32_t idx = (r->head + r->count) & (HD_HOST_CAN_RING - 1u);
    r->f[idx] = *f;
    if (r->f[idx].dlc > 8u) r->f[idx].dlc = 8u;
    r->count++;
    return true;
}

bool hd_host_ring_pop(hd_host_can_ring_t *r, hd_can_frame_t *f)
{
    if (r->count == 0u) return false;
    *f = r->f[r->head];
    r->head = (r->head + 1u) & (HD_HOST_CAN_RING - 1u);
    r->count--;
    return true;
}

bool hd_hal_can_send(const hd_can_frame_t *f)
{
    return g_port ? hd_host_ring_push(&g_port->can_tx, f) : false;
}

bool hd_hal_can_recv(hd_can_frame_t *f)
{
    return g_port ? hd_host_ring_pop(&g_port->can_rx, f) : false;
}

bool hd_host_can_push_rx(const hd_can_frame_t *f)
{
    return g_port ? hd_host_ring_push(&g_port->can_rx, f) : false;
}

bool hd_host_can_pop_tx(hd_can_frame_t *f)
{
    return g_port ? hd_host_ring_pop(&g_port->can_tx, f) : false;
}

void hd_hal_can_status(hd_hal_can_status_t *st)
{
    memset(st, 0, sizeof *st);
    if (!g_port) return;
    const hd_host_can_ctrl_t *c = &g_port->can_ctrl;
    st->state = c->state;
    st->tec = (uint8_t)(c->tec > 255u ? 255u : c->tec);
    st->rec = (uint8_t)(c->rec > 127u ? 128u : c->rec);
    st->warning = (c->tec >= 96u || c->rec >= 96u) ? 1u : 0u;
}

void hd_hal_can_recover(void)
{
    if (!g_port) return;
    hd_host_can_ctrl_t *c = &g_port->can_ctrl;
    if (c->state != HD_HAL_CAN_BUS_OFF || c->recovering) return;
    /* 128 x 11 recessive bits, whole periods (100 us) rounded up */
    const uint32_t br = c->bitrate ? c->bitrate : 1000000u;
    c->recover_left = (uint32_t)(((uint64_t)128u * 11u * HD_LOOP_HZ + br - 1u) / br);
    if (c->recover_left == 0u) c->recover_left = 1u;
    c->recovering = 1u;
}

/* ---- NVM ----------------------------------------------------------------------- */

uint32_t hd_hal_nvm_size(void) { return HD_HOST_NVM_SIZE; }
uint32_t hd_hal_nvm_page_size(void) { return HD_HOST_NVM_PAGE; }

static bool nvm_range_ok(uint32_t offset, uint32_t len)
{
    return offset <= HD_HOST_NVM_SIZE && len <= HD_HOST_NVM_SIZE - offset;
}

/* Write the whole image to the backing file through a temp file + rename. */
static int32_t nvm_flush(hd_host_port_t *p)
{
    if (p->nvm_path[0] == '\0') return 0;
    char tmp[HD_HOST_PATH_MAX + 8];
    int n = snprintf(tmp, sizeof tmp, "%s.tmp", p->nvm_path);
    if (n < 0 || (size_t)n >= sizeof tmp) return -1;
    FILE *f = fopen(tmp, "wb");
    if (!f) { p->nvm_file_error = -2; return -2; }
    size_t w = fwrite(p->nvm, 1u, sizeof p->nvm, f);
    int bad = (w != sizeof p->nvm);
    if (fclose(f) != 0) bad = 1;
    if (bad || rename(tmp, p->nvm_path) != 0) {
        remove(tmp);
        p->nvm_file_error = -2;
        return -2;
    }
    return 0;
}

#define NVM_PAGES (HD_HOST_NVM_SIZE / HD_HOST_NVM_PAGE)

/* The erase counts to PATH.wear (temp file + rename): a torn write leaves the old counts. */
static void wear_flush(hd_host_port_t *p)
{
    char path[HD_HOST_PATH_MAX + 8];
    char tmp[HD_HOST_PATH_MAX + 16];
    int n = snprintf(path, sizeof path, "%s.wear", p->nvm_path);
    int m = snprintf(tmp, sizeof tmp, "%s.wear.tmp", p->nvm_path);
    if (p->nvm_path[0] == '\0' || n < 0 || (size_t)n >= sizeof path || m < 0 || (size_t)m >= sizeof tmp) return;
    FILE *f = fopen(tmp, "w");
    if (!f) return;
    int bad = 0;
    for (uint32_t k = 0u; k < NVM_PAGES; k++)
        if (fprintf(f, "%lu\n", (unsigned long)p->nvm_erases[k]) < 0) bad = 1;
    if (fclose(f) != 0) bad = 1;
    if (bad || rename(tmp, path) != 0) remove(tmp);
}

/* The erase counts from PATH.wear if it is there and whole; else they start at 0. */
static void wear_load(hd_host_port_t *p)
{
    char path[HD_HOST_PATH_MAX + 8];
    uint32_t c[NVM_PAGES];
    int n = snprintf(path, sizeof path, "%s.wear", p->nvm_path);
    memset(p->nvm_erases, 0, sizeof p->nvm_erases);
    if (n < 0 || (size_t)n >= sizeof path) return;
    FILE *f = fopen(path, "r");
    if (!f) return;
    for (uint32_t k = 0u; k < NVM_PAGES; k++) {
        unsigned long v;
        if (fscanf(f, "%lu", &v) != 1 || v > 0xFFFFFFFFul) { fclose(f); return; }
        c[k] = (uint32_t)v;
    }
    fclose(f);
    memcpy(p->nvm_erases, c, sizeof c);
}

void hd_host_nvm_wear(const hd_host_port_t *p, uint32_t *total, uint32_t *max_page)
{
    uint32_t t = 0u, m = 0u;
    for (uint32_t k = 0u; k < NVM_PAGES; k++) {
        t += p->nvm_erases[k];
        if (p->nvm_erases[k] > m) m = p->nvm_erases[k];
    }
    *total = t;
    *max_page = m;
}

int32_t hd_host_nvm_attach_file(hd_host_port_t *p, const char *path)
{
    size_t len = strlen(path);
    if (len == 0u || len >= sizeof p->nvm_path) return -1;
    memcpy(p->nvm_path, path, len + 1u);
    FILE *f = fopen(path, "rb");
    if (!f) {
        if (errno == ENOENT) {
            memset(p->nvm, 0xFF, sizeof p->nvm);
            wear_load(p);
            return 0;
        }
        p->nvm_path[0] = '\0';
        return -2;
    }
    uint8_t extra;
    size_t r = fread(p->nvm, 1u, sizeof p->nvm, f);
    size_t more = fread(&extra, 1u, 1u, f);
    fclose(f);
    if (r != sizeof p->nvm || more != 0u) {
        memset(p->nvm, 0xFF, sizeof p->nvm);
        p->nvm_path[0] = '\0';
        return -1;
    }
    wear_load(p);
    return 0;
}

int32_t hd_hal_nvm_read(uint32_t offset, void *buf, uint32_t len)
{
    if (!g_port || !nvm_range_ok(offset, len) || (len > 0u && !buf)) return -1;
    if (len > 0u) memcpy(buf, &g_port->nvm[offset], len);
    return 0;
}

int32_t hd_hal_nvm_write(uint32_t offset, const void *buf, uint32_t len)
{
    if (!g_port || !nvm_range_ok(offset, len) || (len > 0u && !buf)) return -1;
    if ((offset % 8u) != 0u || (len % 8u) != 0u) return -1;
    for (uint32_t i = 0u; i < len; i++)
        if (g_port->nvm[offset + i] != 0xFFu) return -3; /* not erased */
    if (len > 0u) memcpy(&g_port->nvm[offset], buf, len);
    return nvm_flush(g_port);
}

int32_t hd_hal_nvm_erase(uint32_t offset, uint32_t len)
{
    if (!g_port || !nvm_range_ok(offset, len)) return -1;
    if ((offset % HD_HOST_NVM_PAGE) != 0u || (len % HD_HOST_NVM_PAGE) != 0u) return -1;
    memset(&g_port->nvm[offset], 0xFF, len);
    for (uint32_t k = offset / HD_HOST_NVM_PAGE; k < (offset + len) / HD_HOST_NVM_PAGE; k++)
        g_port->nvm_erases[k]++;
    wear_flush(g_port);
    return nvm_flush(g_port);
}
