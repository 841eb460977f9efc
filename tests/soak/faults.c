/*
 * faults.c - fault-injection runner for host/hdservo/faults.py (the fault
 * table of `make results`).  Optimised build, like hdservo-sim.
 *
 *   hdservo-faults run SCENARIO.toml RESET_AT_S
 *       Runs the scenario (its [[fault]] entries inject encoder glitches and
 *       dropouts, current clamps, load steps); at RESET_AT_S the runner does
 *       what an operator does: hd_app_fault_reset() and set_mode(scenario mode).
 *       Prints one JSON object: first fault code and time, largest output
 *       motion while faulted (true load angle relative to the angle at the
 *       fault), whether the torque command was zero whenever a fault was
 *       latched, the fault state after the reset and at the end, the largest
 *       |position error| in the last 0.1 s.
 *   hdservo-faults nvm
 *       Parameter-store cases on the host port's flash-semantics NVM: blank,
 *       valid, one slot corrupt, both corrupt, out-of-range value with a good
 *       CRC, other table version, and power loss at every 8-byte step of a
 *       save (plus an interrupted erase).  Prints a JSON array.
 */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "hal_host.h"
#include "hd_app.h"

static const double TWO_PI = 6.283185307179586;

static int run(const char *path, double t_reset)
{
    char err[512];
    static hd_scenario_t sc;
    if (hd_scenario_load(path, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    hd_plant_params prm;
    if (hd_sim_scenario_params(&sc, &prm, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    hd_sim_t *s = hd_sim_new(&sc, &prm, err, sizeof err);
    if (s == NULL) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    hd_app_t *a = (hd_app_t *)(void *)(uintptr_t)hd_sim_app(s);   /* the runner acts as the operator */
    const int32_t mode = a->mode_req;   /* requested by the harness, applied at the first step */
    const int64_t n = hd_sim_n_periods(s);
    double row[HD_SIM_NCOL];
    int32_t first_fault = 0, fault_after_reset = 0, reset_done = 0, set_mode_rc = 0;
    double t_fault = -1.0, load_at_fault = 0.0, max_motion = 0.0, max_err_end = 0.0;
    int torque_off = 1;
    for (int64_t k = 0; k < n; k++) {
        const double t = (double)k * sc.dt_s;
        if (!reset_done && t >= t_reset) {
            hd_app_fault_reset(a);
            set_mode_rc = hd_app_set_mode(a, mode);
            reset_done = 1;
        }
        hd_sim_step(s, row);
        if (a->fault != 0 && first_fault == 0) {
            first_fault = a->fault;
            t_fault = t;
            load_at_fault = row[HD_COL_LOAD_TRUE];
        }
        if (a->fault != 0 && !reset_done) {
            const double m = fabs(row[HD_COL_LOAD_TRUE] - load_at_fault);
            if (m > max_motion) max_motion = m;
            if (a->tel.motor_torque != 0 || row[HD_COL_TORQUE_CMD] != 0.0) torque_off = 0;
        }
        if (getenv("HD_FAULTS_TRACE") != NULL && k % 500 == 0) {
            fprintf(stderr, "t %.3f mode %d fault %d load %.4f rad\n", t, (int)a->mode, (int)a->fault, row[HD_COL_LOAD_TRUE]);
        }
        if (reset_done && a->fault != 0 && fault_after_reset == 0) {
            fault_after_reset = a->fault;
        }
        if (t >= sc.duration_s - 0.1) {
            const double e = fabs((double)a->tel.pos_err) / 4294967296.0 * TWO_PI;
            if (e > max_err_end) max_err_end = e;
        }
    }
    printf("{\"first_fault\": %d, \"t_fault_s\": %.4f, \"max_motion_while_faulted_rad\": %.6g, "
           "\"torque_off_while_faulted\": %s, \"reset_at_s\": %.3f, \"set_mode_after_reset\": %d, "
           "\"fault_after_reset\": %d, \"fault_at_end\": %d, \"mode_at_end\": %d, "
           "\"max_pos_err_last_0.1s_rad\": %.6g}\n",
           (int)first_fault, t_fault, max_motion, torque_off ? "true" : "false", t_reset, (int)set_mode_rc,
           (int)fault_after_reset, (int)a->fault, (int)a->mode, max_err_end);
    hd_sim_free(s);
    return 0;
}

/* ---- NVM ------------------------------------------------------------------- */
static hd_host_port_t port;
static hd_app_t app;

static int32_t boot(void)
{
    memset(&app, 0, sizeof app);
    hd_host_port_bind(&port);
    hd_app_init(&app);
    return app.pstore_status;
}

static int same(const int32_t *x, const int32_t *y) { return memcmp(x, y, sizeof(int32_t) * HD_PARAM_COUNT) == 0; }

static const char *which(const int32_t *v, const int32_t *s0, const int32_t *s1, const int32_t *def)
{
    if (same(v, s1)) return "new";
    if (same(v, s0)) return "old";
    if (same(v, def)) return "defaults";
    return "MIXED";
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

static int nvm(void)
{
    static int32_t def[HD_PARAM_COUNT], s0[HD_PARAM_COUNT], s1[HD_PARAM_COUNT];
    static uint8_t img_old[HD_HOST_NVM_SIZE], img_new[HD_HOST_NVM_SIZE];
    const uint32_t slot = HD_HOST_NVM_PAGE;   /* slot size: one page on this port */
    const uint32_t rec = (6u + HD_PARAM_COUNT + 1u) * 4u;
    hd_params_defaults(def);
    memcpy(s0, def, sizeof s0);
    s0[HD_P_POS_KP] = hd_param_table[HD_P_POS_KP].def / 2;
    s0[HD_P_TORQUE_LIMIT] = hd_param_table[HD_P_TORQUE_LIMIT].def / 2;
    memcpy(s1, s0, sizeof s1);
    s1[HD_P_VEL_KP] = hd_param_table[HD_P_VEL_KP].def / 2;
    s1[HD_P_ENC_JUMP_MAX] = hd_param_table[HD_P_ENC_JUMP_MAX].def * 2;
    s1[HD_P_TRAVEL_MAX] = hd_param_table[HD_P_TRAVEL_MAX].def / 4;
    printf("[\n");

    hd_host_port_init(&port);
    int32_t st = boot();
    printf(" {\"case\": \"blank NVM at boot\", \"status\": %d, \"values\": \"%s\"},\n", (int)st, which(app.param, s0, s1, def));

    /* save s0 then s1 through the app (mode OFF) */
    memcpy(app.param, s0, sizeof s0);
    (void)hd_app_apply_params(&app);
    const int32_t r0 = hd_app_param_save(&app);
    memcpy(img_old, port.nvm, sizeof img_old);
    memcpy(app.param, s1, sizeof s1);
    (void)hd_app_apply_params(&app);
    const int32_t r1 = hd_app_param_save(&app);
    memcpy(img_new, port.nvm, sizeof img_new);
    st = boot();
    printf(" {\"case\": \"two saves, boot\", \"save_rc\": [%d, %d], \"status\": %d, \"values\": \"%s\", \"seq\": %u},\n",
           (int)r0, (int)r1, (int)st, which(app.param, s0, s1, def), (unsigned)app.pstore_seq);

    /* which slot did the second save write? */
    uint32_t tgt = 0;
    for (uint32_t i = 0; i < slot; i++) {
        if (img_old[slot + i] != img_new[slot + i]) tgt = 1;
    }
    /* newest slot corrupt (one bit) -> older set */
    memcpy(port.nvm, img_new, sizeof img_new);
    port.nvm[tgt * slot + 40u] ^= 0x10u;
    st = boot();
    printf(" {\"case\": \"newest slot one bit flipped\", \"status\": %d, \"values\": \"%s\"},\n", (int)st, which(app.param, s0, s1, def));
    /* both corrupt -> defaults, CORRUPT */
    port.nvm[(1u - tgt) * slot + 44u] ^= 0x01u;
    st = boot();
    printf(" {\"case\": \"both slots corrupt\", \"status\": %d, \"values\": \"%s\"},\n", (int)st, which(app.param, s0, s1, def));
    /* out-of-range value with a correct CRC in the newest slot -> older set */
    memcpy(port.nvm, img_new, sizeof img_new);
    {
        uint8_t *r = &port.nvm[tgt * slot];
        put32(&r[(6u + HD_P_GEAR_RATIO) * 4u], 0u);   /* gear ratio 0: below its range */
        put32(&r[rec - 4u], hd_crc32(0, r, rec - 4u));
    }
    st = boot();
    printf(" {\"case\": \"newest slot out-of-range value, CRC good\", \"status\": %d, \"values\": \"%s\"},\n", (int)st, which(app.param, s0, s1, def));
    /* other table version in both slots -> INCOMPATIBLE, defaults */
    memcpy(port.nvm, img_new, sizeof img_new);
    for (uint32_t sl = 0; sl < 2u; sl++) {
        uint8_t *r = &port.nvm[sl * slot];
        put32(&r[8], HD_PARAM_VERSION + 1u);
        put32(&r[rec - 4u], hd_crc32(0, r, rec - 4u));
    }
    st = boot();
    printf(" {\"case\": \"other parameter-table version\", \"status\": %d, \"values\": \"%s\"},\n", (int)st, which(app.param, s0, s1, def));

    /* power loss during the second save: erase interrupted (garbage), erase done, every 8-byte prefix */
    uint32_t n_cut = 0, n_old = 0, n_new = 0, n_other = 0;
    for (int32_t cut = -2; cut <= (int32_t)((rec + 7u) & ~7u); cut += (cut < 0 ? 1 : 8)) {
        memcpy(port.nvm, img_old, sizeof img_old);
        uint8_t *r = &port.nvm[tgt * slot];
        if (cut == -2) {
            for (uint32_t i = 0; i < slot; i += 2u) r[i] = (uint8_t)(i * 37u);   /* half-erased page */
        } else {
            memset(r, 0xFF, slot);
            if (cut > 0) memcpy(r, &img_new[tgt * slot], (size_t)cut);
        }
        st = boot();
        n_cut++;
        const char *w = which(app.param, s0, s1, def);
        if (strcmp(w, "old") == 0) n_old++;
        else if (strcmp(w, "new") == 0) n_new++;
        else n_other++;
    }
    printf(" {\"case\": \"power loss during save\", \"cut_points\": %u, \"boots_with_old_set\": %u, "
           "\"boots_with_new_set\": %u, \"boots_with_other\": %u},\n", n_cut, n_old, n_new, n_other);
    /* after a power-loss boot (old set), a new save must win at the next boot */
    memcpy(port.nvm, img_old, sizeof img_old);
    memset(&port.nvm[tgt * slot], 0xFF, 64);
    (void)boot();
    memcpy(app.param, s1, sizeof s1);
    (void)hd_app_apply_params(&app);
    const int32_t r2 = hd_app_param_save(&app);
    st = boot();
    printf(" {\"case\": \"save again after the interrupted save\", \"save_rc\": %d, \"status\": %d, \"values\": \"%s\"}\n",
           (int)r2, (int)st, which(app.param, s0, s1, def));
    printf("]\n");
    hd_host_port_bind(NULL);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 4 && strcmp(argv[1], "run") == 0) {
        return run(argv[2], atof(argv[3]));
    }
    if (argc == 2 && strcmp(argv[1], "nvm") == 0) {
        return nvm();
    }
    fprintf(stderr, "usage: hdservo-faults run SCENARIO RESET_AT_S | hdservo-faults nvm\n");
    return 2;
}
