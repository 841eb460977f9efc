/*
 * fuzz_params.c - the parameter write path of the drive application
 * (hd_app_param_set -> range check -> hd_app_apply_params, save/load through
 * the host port's flash-semantics NVM) interleaved with control periods,
 * mode changes, references and fault resets, all from the input.
 *
 * Input: records of 6 bytes (op, arg, int32 value):
 *   op % 8 = 0 param_set(arg % (COUNT + 2), value)   (2 unknown ids on purpose)
 *            1 set_mode(arg % 10)                     (2 bad modes on purpose)
 *            2 run (arg % 16 + 1) periods with sensors derived from value
 *            3 fault reset
 *            4 save, then reload from NVM and compare
 *            5 set_position / set_velocity / set_torque (arg % 3) = value
 *            6 move_to(value), set_rate(value)
 *            7 param_set(arg % COUNT, min or max of its range)
 * Invariants:
 *   - a refused write leaves the value in force; an accepted one is stored
 *     exactly and is inside the table range;
 *   - a faulted app refuses every mode but OFF; OFF/faulted writes enable 0;
 *   - a saved set reloads bit-for-bit;
 *   - UBSan/ASan: no undefined behaviour for any accepted parameter set.
 */
#include <string.h>
#include "fuzz_common.h"
#include "hd_app.h"
#include "hal_host.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static hd_host_port_t port;
static hd_app_t app;

static void period(uint32_t mot, uint32_t out, int32_t cur, uint32_t valid)
{
    hd_hal_sensors_t se;
    const uint32_t mbits = (uint32_t)hd_app_param_get(&app, HD_P_MOTOR_ENC_BITS);
    const uint32_t obits = (uint32_t)hd_app_param_get(&app, HD_P_OUTPUT_ENC_BITS);
    se.motor_enc_raw = (mbits >= 32u) ? mot : (mot & ((1u << mbits) - 1u));
    se.output_enc_raw = (obits >= 32u) ? out : (out & ((1u << obits) - 1u));
    se.current = cur;
    se.gyro_rate = cur;
    se.valid = valid;
    hd_host_port_latch(&port, &se);
    hd_app_step(&app);
    const hd_hal_command_t *c = hd_host_port_command(&port);
    if (app.fault != HD_FAULT_NONE || app.mode == HD_MODE_OFF) {
        FUZZ_ASSERT(c->enable == 0u);
    }
    hd_host_port_end_period(&port);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_stream_t s;
    fz_init(&s, data, size);
    hd_host_port_init(&port);
    hd_host_port_bind(&port);
    memset(&app, 0, sizeof app);
    hd_app_init(&app);
    FUZZ_ASSERT(app.pstore_status == HD_PSTORE_BLANK);
    uint32_t mot = 0, out = 0;
    for (uint32_t k = 0; k < 256u && fz_left(&s) >= 6u; k++) {
        const uint8_t op = fz_u8(&s);
        const uint8_t arg = fz_u8(&s);
        const int32_t val = fz_i32(&s);
        switch (op % 8u) {
        case 0: case 7: {
            uint32_t id = arg % (HD_PARAM_COUNT + 2u);
            int32_t raw = val;
            if (op % 8u == 7u) {
                id = arg % HD_PARAM_COUNT;
                raw = (val & 1) ? hd_param_table[id].max : hd_param_table[id].min;
            }
            const int32_t old = hd_app_param_get(&app, id);
            const int32_t rc = hd_app_param_set(&app, id, raw);
            if (rc == 0) {
                FUZZ_ASSERT(id < HD_PARAM_COUNT);
                FUZZ_ASSERT(hd_app_param_get(&app, id) == raw);
                FUZZ_ASSERT(raw >= hd_param_table[id].min && raw <= hd_param_table[id].max);
            } else {
                FUZZ_ASSERT(rc == -1);
                FUZZ_ASSERT(hd_app_param_get(&app, id) == old);
            }
            break;
        }
        case 1: {
            const int32_t m = (int32_t)(arg % 10u);
            const int32_t faulted = app.fault != HD_FAULT_NONE;
            const int32_t rc = hd_app_set_mode(&app, m);
            if (faulted && m != HD_MODE_OFF) {
                FUZZ_ASSERT(rc == -1);
            }
            if (m > HD_MODE_STAB) {         /* the highest mode (hd_app.h) */
                FUZZ_ASSERT(rc == -1);
            }
            break;
        }
        case 2: {
            const uint32_t n = (uint32_t)(arg % 16u) + 1u;
            const uint32_t dm = (uint32_t)val & 0xFFFu, dout = ((uint32_t)val >> 12) & 0xFFu;
            for (uint32_t i = 0; i < n; i++) {
                mot += (val < 0) ? (0u - dm) : dm;
                out += (val < 0) ? (0u - dout) : dout;
                period(mot, out, val >> 8, (arg & 0x80u) ? ((uint32_t)arg & 0xFu) : HD_HAL_VALID_ALL);
            }
            break;
        }
        case 3:
            hd_app_fault_reset(&app);
            FUZZ_ASSERT(app.fault == HD_FAULT_NONE);
            break;
        case 4: {
            int32_t v[HD_PARAM_COUNT];
            uint32_t seq = 0;
            if (hd_app_param_save(&app) == 0) {
                FUZZ_ASSERT(hd_pstore_load(v, &seq) == HD_PSTORE_OK);
                FUZZ_ASSERT(seq == app.pstore_seq);
                FUZZ_ASSERT(memcmp(v, app.param, sizeof v) == 0);
            } else {
                FUZZ_ASSERT(app.mode != HD_MODE_OFF);
            }
            break;
        }
        case 5:
            if (arg % 3u == 0u) {
                hd_app_set_position(&app, (hd_angle_t)val * 256);
            } else if (arg % 3u == 1u) {
                hd_app_set_velocity(&app, val);
            } else {
                hd_app_set_torque(&app, val);
            }
            break;
        default:
            (void)hd_app_move_to(&app, (hd_angle_t)val * 256);
            hd_app_set_rate(&app, val >> (arg % 16u));
            break;
        }
    }
    hd_host_port_bind(NULL);
    return 0;
}
