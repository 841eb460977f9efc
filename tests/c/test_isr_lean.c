/*
 * test_isr_lean.c - the bit-identical shortcuts of the control period against
 * the general forms they replace:
 *   hdf_div64_rnd_u16        vs hd_div64_rnd (division by a small constant)
 *   hd_blend_update (inline) vs the ramp rule of hd_blend.h, step by step
 *   hd_app: motor current    vs hd_div_q(motor torque, Kt, 16) over the Kt range
 *   hd_app: encoder steps    vs the wrapped counter difference x 2^(32 - bits)
 *   hd_app: travel limits    follow a parameter change (precomputed at apply)
 *   hd_foc: Clarke / Park    rounding floor((x + 2^(q-1)) / 2^q) vs the 2^62-biased
 *                            unsigned shift (round half up, saturated)
 *   hd_pid: limits and the   int32 x 2^s (s <= 32) and the measurement step x 2^16 vs
 *           derivative step  the saturating shift hd_shl64_sat
 *   hd_divinv_rnd            vs hd_div64_rnd (division by a parameter via its reciprocal)
 *   hd_stribeck_g_inv        vs hd_stribeck_g (LuGre's g(v))
 *   hd_app: acceleration FF  one precomputed gain aff_gain j_total 2 pi (parameter set)
 *                            vs the exact product, and it follows a parameter change
 *   hd_app: motor velocity   / N in 32-bit words vs hd_sat32(hd_div64_rnd(vel48, N 2^16))
 *   hd_biquad: chain         clamps only its input vs the sections one by one (each clamping)
 *   hd_velobs: step without  err (the period's motor observer) vs hd_velobs_step
 * The hal is a stub: the sensor sample is set by the test, the command recorded,
 * NVM blank (defaults) and read-only.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "hd_app.h"
#include "hd_fixed.h"
#include "hd_blend.h"
#include "hd_foc.h"
#include "hd_stribeck.h"

/* ---- stub hal ------------------------------------------------------------ */

static hd_hal_sensors_t stub_sn;
static hd_hal_command_t stub_cmd;
static uint32_t stub_tick;

uint32_t hd_hal_tick(void) { return stub_tick; }
void hd_hal_read_sensors(hd_hal_sensors_t *s) { *s = stub_sn; }
void hd_hal_write_command(const hd_hal_command_t *c) { stub_cmd = *c; stub_tick++; }
bool hd_hal_can_send(const hd_can_frame_t *f) { (void)f; return true; }
bool hd_hal_can_recv(hd_can_frame_t *f) { (void)f; return false; }
void hd_hal_can_status(hd_hal_can_status_t *st) { memset(st, 0, sizeof *st); }
void hd_hal_can_recover(void) { }
uint32_t hd_hal_nvm_size(void) { return 20480u; }
uint32_t hd_hal_nvm_page_size(void) { return 1024u; }
int32_t hd_hal_nvm_read(uint32_t off, void *buf, uint32_t len) { (void)off; memset(buf, 0xFF, len); return 0; }
int32_t hd_hal_nvm_write(uint32_t off, const void *buf, uint32_t len) { (void)off; (void)buf; (void)len; return -1; }
int32_t hd_hal_nvm_erase(uint32_t off, uint32_t len) { (void)off; (void)len; return -1; }

static hd_app_t app;   /* large (capture buffer): static */

/* xorshift64: deterministic pseudo-random words */
static uint64_t rng_s;
static uint64_t rnd64(void)
{
    rng_s ^= rng_s << 13;
    rng_s ^= rng_s >> 7;
    rng_s ^= rng_s << 17;
    return rng_s;
}
static int64_t s64(uint64_t u)
{
    return (u > (uint64_t)INT64_MAX) ? -(int64_t)(~u) - 1 : (int64_t)u;
}
static int32_t s32(uint32_t u)
{
    return (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u;
}

static int setUp(void **state)
{
    (void)state;
    rng_s = 0x9E3779B97F4A7C15ull;
    memset(&stub_sn, 0, sizeof stub_sn);
    memset(&stub_cmd, 0, sizeof stub_cmd);
    stub_tick = 0;
    stub_sn.valid = HD_HAL_VALID_ALL;
    return 0;
}

static int tearDown(void **state)
{
    (void)state;
    return 0;
}

/* ---- hdf_div64_rnd_u16 ------------------------------------------------------ */

static void test_div64_rnd_u16_matches_div64_rnd(void **state)
{
    static const uint32_t dens[] = {0u, 1u, 2u, 3u, 7u, 625u, 9999u, 10000u, 10001u, 65535u, 65536u, 100000u};
    static const int64_t edges[] = {0, 1, -1, 4999, 5000, 5001, -4999, -5000, -5001, 15000, -15000,
                                    INT32_MAX, INT32_MIN, (int64_t)1 << 48, -((int64_t)1 << 48),
                                    INT64_MAX, INT64_MAX - 1, INT64_MIN, INT64_MIN + 1,
                                    INT64_MAX / 10000 * 10000 + 5000, INT64_MIN / 10000 * 10000 - 5000};
    uint32_t i, j, k;
    (void)state;
    for (i = 0; i < sizeof dens / sizeof dens[0]; i++) {
        const uint32_t d = dens[i];
        for (j = 0; j < sizeof edges / sizeof edges[0]; j++) {
            assert_true(hdf_div64_rnd_u16(edges[j], d) == hd_div64_rnd(edges[j], (int64_t)d));
        }
        for (k = 0; k < 200000u; k++) {
            /* every magnitude: a random word shifted right by 0..63 bits, both signs,
             * and exact half-way points of the divisor */
            const int64_t x = s64(rnd64() >> (k % 64u));
            assert_true(hdf_div64_rnd_u16(x, d) == hd_div64_rnd(x, (int64_t)d));
            if (d > 1u && d < 65536u) {
                const int64_t h = (x / 4 / (int64_t)d) * (int64_t)d + (int64_t)(d / 2u);
                assert_true(hdf_div64_rnd_u16(h, d) == hd_div64_rnd(h, (int64_t)d));
                assert_true(hdf_div64_rnd_u16(-h, d) == hd_div64_rnd(-h, (int64_t)d));
            }
        }
    }
    /* the drive's divisor, a constant at the call sites */
    assert_true(hdf_div64_rnd_u16(15000, (uint32_t)HD_LOOP_HZ) == 2);
    assert_true(hdf_div64_rnd_u16(-15000, (uint32_t)HD_LOOP_HZ) == -2);
    assert_true(hdf_div64_rnd_u16(14999, (uint32_t)HD_LOOP_HZ) == 1);
}

/* ---- hd_blend_update -------------------------------------------------------- */

/* the ramp rule of hd_blend.h: w moves by ceil(2^30 / ramp_ticks) towards the
 * target each update, at once with ramp_ticks == 0 */
static int32_t blend_ref(int32_t w, int32_t target, uint32_t ramp)
{
    const int32_t tgt = (target > 0) ? HD_Q30_ONE : 0;
    int64_t step;
    if (ramp == 0u) {
        return tgt;
    }
    step = (((int64_t)1 << 30) + (int64_t)ramp - 1) / (int64_t)ramp;
    if (w < tgt) {
        return ((int64_t)tgt - w <= step) ? tgt : (int32_t)(w + step);
    }
    if (w > tgt) {
        return ((int64_t)w - tgt <= step) ? tgt : (int32_t)(w - step);
    }
    return w;
}

static void test_blend_update_follows_ramp_rule(void **state)
{
    static const uint32_t ramps[] = {0u, 1u, 2u, 3u, 4u, 7u, 100u, 1000u, 3u};
    hd_blend_t b;
    uint32_t i, k, moves = 0u;
    (void)state;
    hd_blend_init(&b, 4u, false);
    for (i = 0; i < sizeof ramps / sizeof ramps[0]; i++) {
        b.ramp_ticks = ramps[i];
        for (k = 0; k < 3000u; k++) {
            if ((rnd64() % 97u) == 0u) {
                hd_blend_set_enabled(&b, (rnd64() & 1u) != 0u);
            }
            const int32_t want = blend_ref(b.w, b.target, b.ramp_ticks);
            const int32_t w_before = b.w;
            assert_int_equal(hd_blend_update(&b), want);
            assert_int_equal(b.w, want);
            assert_true(hd_blend_active(&b) == ((b.w != 0) || (b.target != 0)));
            assert_int_equal(hd_blend_apply(&b, 123456789), (b.w >= HD_Q30_ONE) ? 123456789
                             : hd_mul_q(123456789, b.w, 30u));
            moves += (b.w != w_before) ? 1u : 0u;
        }
    }
    assert_true(moves > 100u);    /* the sequences did ramp, not only sit at the target */
}

/* ---- hd_app ------------------------------------------------------------------ */

static void app_start(uint32_t mot, uint32_t out)
{
    stub_sn.motor_enc_raw = mot;
    stub_sn.output_enc_raw = out;
    hd_app_init(&app);
    assert_int_equal(hd_app_param_set(&app, HD_P_FAULT_ENABLE, 0), 0);
    hd_app_step(&app);
}

/* the motor torque command = round(output torque / N) (hd_div64_rnd, saturated) over
 * gear ratios 1 .. 1000 and output torques up to the limit, signs and half-way points */
static void test_app_motor_torque_is_div64_rnd(void **state)
{
    static const int32_t ns[] = {1, 2, 3, 7, 100, 160, 999, 1000};
    const int32_t tlim = 1000 * 65536;   /* the parameter maxima */
    static const int32_t torques[] = {0, 1, -1, 2, -2, 3, -3, 50, -50, 150, -150,
                                      1000 * 65536, -1000 * 65536, 1000 * 65536 - 1};
    uint32_t i, j, n = 0u;
    (void)state;
    app_start(0u, 0u);
    assert_int_equal(hd_app_param_set(&app, HD_P_TORQUE_LIMIT, tlim), 0);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_TORQUE), 0);
    for (i = 0; i < sizeof ns / sizeof ns[0]; i++) {
        assert_int_equal(hd_app_param_set(&app, HD_P_GEAR_RATIO, ns[i]), 0);
        for (j = 0; j < sizeof torques / sizeof torques[0] + 2000u; j++) {
            const int32_t scale = (int32_t)(1u << (uint32_t)(rnd64() % 20u));
            int32_t t = (j < sizeof torques / sizeof torques[0]) ? torques[j] : s32((uint32_t)rnd64()) / scale;
            t = (t > tlim) ? tlim : (t < -tlim) ? -tlim : t;
            hd_app_set_torque(&app, t);
            hd_app_step(&app);
            assert_int_equal(stub_cmd.enable, 1);
            assert_int_equal(stub_cmd.torque, hd_sat32(hd_div64_rnd(t, ns[i])));
            n += (stub_cmd.torque != 0) ? 1u : 0u;
        }
    }
    assert_true(n > 1000u);
}

/* the motor current command = round(motor torque 2^16 / Kt) over the whole Kt range,
 * both branches of the 32-bit division (Kt < 1 N.m/A) and the general one */
static void test_app_current_is_div_q(void **state)
{
    static const int32_t kts[] = {66, 100, 6554, 12345, 65535, 65536, 65537, 1000000, 6553600};
    static const int32_t torques[] = {0, 1, -1, 2, -2, 32767, -32768, 65536 * 5, -65536 * 5,
                                      65536 * 1000, -65536 * 1000, INT32_MAX, INT32_MIN + 1};
    uint32_t i, j, n = 0u;
    (void)state;
    app_start(0u, 0u);
    assert_int_equal(hd_app_param_set(&app, HD_P_GEAR_RATIO, 1), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_TORQUE_LIMIT, 1000 * 65536), 0);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_TORQUE), 0);
    for (i = 0; i < sizeof kts / sizeof kts[0]; i++) {
        assert_int_equal(hd_app_param_set(&app, HD_P_KT, kts[i]), 0);
        for (j = 0; j < sizeof torques / sizeof torques[0] + 2000u; j++) {
            /* the edges, then random torques of every magnitude (a random word / 2^0..2^19) */
            const int32_t scale = (int32_t)(1u << (uint32_t)(rnd64() % 20u));
            const int32_t t = (j < sizeof torques / sizeof torques[0]) ? torques[j] : s32((uint32_t)rnd64()) / scale;
            hd_app_set_torque(&app, t);
            hd_app_step(&app);
            assert_int_equal(stub_cmd.enable, 1);
            assert_int_equal(stub_cmd.current, hd_div_q(stub_cmd.torque, kts[i], 16u));
            n += (stub_cmd.current != 0) ? 1u : 0u;
        }
    }
    assert_true(n > 1000u);
}

/* position unwrapping: each period adds the wrapped counter step x 2^(32 - bits),
 * for the smallest, default and largest encoder resolutions; steps up to just
 * under half a counter turn each way, and the exact half (-half) */
static void test_app_encoder_steps(void **state)
{
    static const int32_t mbits[] = {8, 17, 24};
    static const int32_t obits[] = {12, 24, 30};
    uint32_t i, k;
    (void)state;
    for (i = 0; i < 3u; i++) {
        const uint32_t mb = (uint32_t)mbits[i], ob = (uint32_t)obits[i];
        const uint32_t mmask = (1u << mb) - 1u, omask = (1u << ob) - 1u;
        uint32_t mraw = 5u, oraw = 7u;
        int64_t pm, po;
        app_start(0u, 0u);
        assert_int_equal(hd_app_param_set(&app, HD_P_MOTOR_ENC_BITS, mbits[i]), 0);
        assert_int_equal(hd_app_param_set(&app, HD_P_OUTPUT_ENC_BITS, obits[i]), 0);
        app.started = 0;                 /* re-initialise the positions from this sample */
        stub_sn.motor_enc_raw = mraw;
        stub_sn.output_enc_raw = oraw;
        hd_app_step(&app);
        pm = app.pos_mot;
        po = app.pos_out;
        for (k = 0; k < 20000u; k++) {
            uint32_t dm, dout;
            switch (k % 4u) {
            case 0u: dm = (1u << (mb - 1u)) - 1u; dout = 0u - ((1u << (ob - 1u)) - 1u); break;
            case 1u: dm = 1u << (mb - 1u); dout = 1u << (ob - 1u); break;     /* exactly -half */
            default: dm = (uint32_t)rnd64(); dout = (uint32_t)rnd64() >> (k % 32u); break;
            }
            const int64_t sm = (int64_t)((dm & mmask) ^ (1u << (mb - 1u))) - ((int64_t)1 << (mb - 1u));
            const int64_t so = (int64_t)((dout & omask) ^ (1u << (ob - 1u))) - ((int64_t)1 << (ob - 1u));
            mraw = (mraw + dm) & mmask;
            oraw = (oraw + dout) & omask;
            stub_sn.motor_enc_raw = mraw;
            stub_sn.output_enc_raw = oraw;
            hd_app_step(&app);
            pm += sm * ((int64_t)1 << (32u - mb));
            po += so * ((int64_t)1 << (32u - ob));
            assert_true(app.pos_mot == pm);
            assert_true(app.pos_out == po);
        }
    }
}

/* the travel limits are compared in Q32.32; a parameter change takes effect at once */
static void test_app_travel_limit_follows_parameter(void **state)
{
    (void)state;
    app_start(0u, 0u);
    assert_int_equal(hd_app_param_set(&app, HD_P_FAULT_ENABLE, (int32_t)HD_FCHK_TRAVEL), 0);
    /* output at +0.25 turn (24-bit encoder), limit 0.25 turn + 1 LSB of Q8.24: inside */
    assert_int_equal(hd_app_param_set(&app, HD_P_TRAVEL_MAX, (1 << 22) + 1), 0);
    stub_sn.output_enc_raw = 1u << 22;
    app.started = 0;
    hd_app_step(&app);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_TORQUE), 0);
    hd_app_step(&app);
    assert_int_equal(app.fault, HD_FAULT_NONE);
    /* limit exactly at the position: still inside (pos_out > max trips) */
    assert_int_equal(hd_app_param_set(&app, HD_P_TRAVEL_MAX, 1 << 22), 0);
    hd_app_step(&app);
    assert_int_equal(app.fault, HD_FAULT_NONE);
    /* one LSB below it: trips at the next period */
    assert_int_equal(hd_app_param_set(&app, HD_P_TRAVEL_MAX, (1 << 22) - 1), 0);
    hd_app_step(&app);
    assert_int_equal(app.fault, HD_FAULT_TRAVEL);
    /* the lower limit the same way */
    hd_app_fault_reset(&app);
    assert_int_equal(hd_app_param_set(&app, HD_P_TRAVEL_MAX, 1 << 23), 0);
    assert_int_equal(hd_app_param_set(&app, HD_P_TRAVEL_MIN, (1 << 22) + 1), 0);
    assert_int_equal(hd_app_set_mode(&app, HD_MODE_TORQUE), 0);
    hd_app_step(&app);
    assert_int_equal(app.fault, HD_FAULT_TRAVEL);
}

/* round(x / 2^q) half up, saturated, by a shift of x + 2^62 + 2^(q-1) as an unsigned
 * value (the general form the FOC's rounding replaces); |x| < 2^62 */
static int32_t ref_rnd_sat(int64_t x, uint32_t q)
{
    const uint64_t u = ((uint64_t)x + ((uint64_t)1 << 62) + ((uint64_t)1 << (q - 1u))) >> q;
    const int64_t r = (int64_t)u - ((int64_t)1 << (62u - q));
    return (r > (int64_t)INT32_MAX) ? INT32_MAX : ((r < (int64_t)INT32_MIN) ? INT32_MIN : (int32_t)r);
}

static uint64_t xs_state = 0x9E3779B97F4A7C15ull;
static uint32_t xs32(void)
{
    xs_state ^= xs_state << 13;
    xs_state ^= xs_state >> 7;
    xs_state ^= xs_state << 17;
    return (uint32_t)(xs_state >> 32);
}

/* The PID's integrator limits out_max / out_min x 2^shift (shift <= 32) and its
 * derivative target dmeas x 2^16 (|dmeas| < 2^32) are plain products: equal to the
 * saturating shift for every shift, at the int32 edges and for random words. */
static void test_pid_shift_products_match_shl64_sat(void **state)
{
    static const int32_t edge[] = {INT32_MIN, INT32_MIN + 1, -65536, -1, 0, 1, 65535, INT32_MAX - 1, INT32_MAX};
    uint32_t sh;
    int k;
    (void)state;
    for (sh = 0u; sh <= 32u; sh++) {
        for (k = 0; k < (int)(sizeof edge / sizeof edge[0]); k++) {
            assert_true((int64_t)edge[k] * ((int64_t)1 << sh) == hd_shl64_sat((int64_t)edge[k], sh));
        }
        for (k = 0; k < 2000; k++) {
            const int32_t x = s32((uint32_t)rnd64());
            assert_true((int64_t)x * ((int64_t)1 << sh) == hd_shl64_sat((int64_t)x, sh));
        }
    }
    for (k = 0; k < 20000; k++) {
        const int32_t a = (k < 2) ? ((k == 0) ? INT32_MIN : INT32_MAX) : s32((uint32_t)rnd64());
        const int32_t b = (k < 2) ? ((k == 0) ? INT32_MAX : INT32_MIN) : s32((uint32_t)rnd64());
        const int64_t dmeas = (int64_t)a - (int64_t)b;
        assert_true(dmeas * 65536 == hd_shl64_sat(dmeas, 16u));
    }
}

/* The PID's unsaturated read-outs (hdf_asr32_rnd_fit): the velocity loop's P term
 * kp e / 2^32 for every int32 pair, and the I term of an integrator clamped to
 * [out_min, out_max] 2^shift for shift 1..32, ties included, are the saturating
 * rounded shift's value (hdf_asr32_rnd). */
static void test_pid_fit_readouts_match_asr32_rnd(void **state)
{
    static const int32_t edge[] = {INT32_MIN, INT32_MIN + 1, -65536, -1, 0, 1, 65535, INT32_MAX - 1, INT32_MAX};
    uint32_t sh;
    int j;
    int k;
    (void)state;
    for (j = 0; j < (int)(sizeof edge / sizeof edge[0]); j++) {
        for (k = 0; k < (int)(sizeof edge / sizeof edge[0]); k++) {
            const int64_t x = (int64_t)edge[j] * (int64_t)edge[k];
            assert_int_equal(hdf_asr32_rnd(x, 32u), hdf_asr32_rnd_fit(x, 32u));
        }
    }
    for (k = 0; k < 20000; k++) {
        const int64_t x = (int64_t)s32((uint32_t)rnd64()) * (int64_t)s32((uint32_t)rnd64());
        assert_int_equal(hdf_asr32_rnd(x, 32u), hdf_asr32_rnd_fit(x, 32u));
    }
    for (sh = 1u; sh <= 32u; sh++) {
        const int64_t one = (int64_t)1 << sh;
        for (k = 0; k < 4000; k++) {
            const int32_t lo = (k < 2) ? INT32_MIN : s32((uint32_t)rnd64());
            const int32_t hi = (k < 2) ? INT32_MAX : s32((uint32_t)rnd64());
            const int32_t mn = (lo < hi) ? lo : hi;
            const int32_t mx = (lo < hi) ? hi : lo;
            /* an integrator value: random, a limit, or a tie next to a limit, then clamped */
            int64_t integ = s64(rnd64()) >> (rnd64() % 40u);
            if (k % 4 == 1) {
                integ = (int64_t)mx * one - one / 2;
            } else if (k % 4 == 2) {
                integ = (int64_t)mn * one + one / 2;
            } else if (k % 4 == 3) {
                integ = (k % 8 == 3) ? (int64_t)mx * one : (int64_t)mn * one;
            }
            integ = hdf_clamp64(integ, (int64_t)mn * one, (int64_t)mx * one);
            assert_int_equal(hdf_asr32_rnd(integ, sh), hdf_asr32_rnd_fit(integ, sh));
        }
    }
}

/* Division by a fixed divisor through its reciprocal: the value of hd_div64_rnd for every
 * divisor scale (1, powers of two and their neighbours, 16-bit, 32-bit edges, random) and
 * dividends at the edges (0, +-1, multiples of d and half-way points, INT64_MIN / MAX) and
 * random of every magnitude. */
static void test_divinv_matches_div64_rnd(void **state)
{
    static const uint32_t dl[] = {1u, 2u, 3u, 7u, 10u, 255u, 256u, 257u, 10000u, 65535u, 65536u, 65537u,
                                  0x7FFFFFFFu, 0x80000000u, 0x80000001u, 0xFFFFFFFEu, 0xFFFFFFFFu};
    hd_divinv_t v;
    uint32_t i;
    int k;
    (void)state;
    for (i = 0; i < sizeof dl / sizeof dl[0] + 400u; i++) {
        const uint32_t d = (i < sizeof dl / sizeof dl[0]) ? dl[i]
                           : (uint32_t)(rnd64() >> (32u + (uint32_t)(rnd64() % 32u))) | 1u;
        const int64_t dd = (int64_t)d;
        const int64_t e[] = {0, 1, -1, dd, -dd, dd - 1, dd + 1, dd / 2, dd / 2 + 1, -(dd / 2), -(dd / 2) - 1,
                             3 * dd + dd / 2, INT64_MAX, INT64_MIN, INT64_MAX - 1, INT64_MIN + 1,
                             (INT64_MAX / dd) * dd, -(INT64_MAX / dd) * dd};
        hd_divinv_init(&v, d);
        for (k = 0; k < (int)(sizeof e / sizeof e[0]); k++) {
            assert_true(hd_divinv_rnd(e[k], &v) == hd_div64_rnd(e[k], dd));
        }
        for (k = 0; k < 500; k++) {
            const int64_t n = s64(rnd64()) >> (rnd64() % 64u);
            assert_true(hd_divinv_rnd(n, &v) == hd_div64_rnd(n, dd));
        }
    }
}

/* LuGre's Stribeck level with the reciprocal of vs equals the division form for every
 * vs scale and velocity (both exponents). */
static void test_stribeck_g_inv_matches_g(void **state)
{
    static const int32_t vs_list[] = {1, 2, 3, 1000, 65535, 65536, 65537, 1 << 20, 0x40000000, INT32_MAX};
    hd_stribeck_dir_t p;
    hd_divinv_t v;
    uint32_t i, d;
    int k;
    (void)state;
    p.fc = 5 << 16;
    p.fs = 8 << 16;
    p.fv = 0;
    for (i = 0; i < sizeof vs_list / sizeof vs_list[0]; i++) {
        p.vs = vs_list[i];
        hd_divinv_init(&v, (uint32_t)p.vs);
        for (d = 1u; d <= 2u; d++) {
            for (k = 0; k < 3000; k++) {
                const int32_t vel = (k == 0) ? INT32_MIN : ((k == 1) ? INT32_MAX : (k == 2) ? 0
                                    : (int32_t)(s32((uint32_t)rnd64()) >> (rnd64() % 32u)));
                assert_int_equal(hd_stribeck_g_inv(&p, d, vel, &v), hd_stribeck_g(&p, d, vel));
            }
        }
    }
}

static void test_foc_rounding_matches_biased_form(void **st)
{
    (void)st;
    static const int32_t edge[] = {INT32_MIN, INT32_MIN + 1, -65537, -65536, -32768, -1, 0, 1, 32767, 32768,
                                   65536, INT32_MAX - 1, INT32_MAX};
    const int64_t inv_sqrt3 = 619925131;            /* 1/sqrt(3), Q30, as in hd_foc.c */
    uint32_t i;
    for (i = 0; i < 200000u + 169u; i++) {
        const int32_t a = (i < 169u) ? edge[i / 13u] : (int32_t)xs32();
        const int32_t b = (i < 169u) ? edge[i % 13u] : (int32_t)xs32();
        int32_t al;
        int32_t be;
        int32_t d;
        int32_t q;
        const uint32_t ang = xs32();
        int32_t sn;
        int32_t cs;
        hd_foc_clarke(a, b, &al, &be);
        assert_int_equal(al, a);
        assert_int_equal(be, ref_rnd_sat(((int64_t)a + 2 * (int64_t)b) * inv_sqrt3, 30u));
        hd_sincos_turn_fast(ang, &sn, &cs);        /* |sn|, |cs| <= 2^30 */
        if ((i % 4u) == 0u) {
            /* +-0.5: every odd sum is a tie (half up, not half away) */
            sn = ((i % 8u) == 0u) ? (1 << 29) : -(1 << 29);
            cs = 1 << 29;
        }
        hd_foc_park(a, b, sn, cs, &d, &q);
        assert_int_equal(d, ref_rnd_sat((int64_t)a * cs - (int64_t)b * (int64_t)(-sn), 30u));
        assert_int_equal(q, ref_rnd_sat((int64_t)a * (int64_t)(-sn) + (int64_t)b * cs, 30u));
    }
}

/* The acceleration feed-forward's gain is formed when a parameter is set: for
 * inertias and FF gains over their ranges it is aff_gain j_total 2 pi in Q32.32
 * to within 1 LSB (2 pi as the drive's Q28 constant, round(2 pi 2^28)), and the period's product aff_k acc / 2^40 is the exact torque
 * (Q15.16 N.m) to within 1 LSB for accelerations of every magnitude. */
static void test_app_aff_gain_precomputed(void **state)
{
    static const int32_t js[] = {0, 1, 655, 85197, 65536 * 10, 65536 * 1000, 65536 * 30000};
    static const int32_t gs[] = {0, 1, 1 << 29, 1 << 30, (1 << 30) + (1 << 29)};
    uint32_t i, j, k;
    (void)state;
    app_start(0u, 0u);
    for (i = 0; i < sizeof js / sizeof js[0]; i++) {
        for (j = 0; j < sizeof gs / sizeof gs[0]; j++) {
            assert_int_equal(hd_app_param_set(&app, HD_P_J_TOTAL, js[i]), 0);
            assert_int_equal(hd_app_param_set(&app, HD_P_AFF_GAIN, gs[j]), 0);
            const long double kx = (long double)js[i] / 65536.0L * (1686629713.0L / 268435456.0L) *
                                   (long double)gs[j] / 1073741824.0L;          /* N.m per turn/s^2 */
            assert_true(fabsl((long double)app.aff_k - kx * 4294967296.0L) <= 1.0L);
            for (k = 0; k < 2000u; k++) {
                const int32_t acc = s32((uint32_t)rnd64()) / (int32_t)(1u << (uint32_t)(rnd64() % 24u));
                const long double t = kx * (long double)acc / 16777216.0L * 65536.0L;   /* Q16 N.m */
                if (fabsl(t) < 2.0e9L) {
                    const int32_t got = hdf_sat32(hdf_mul64x32_q(app.aff_k, acc, 40u));
                    assert_true(fabsl((long double)got - t) <= 1.0L);
                }
            }
        }
    }
}

/* the loop's velocity feedback from the motor observer = round(vel48 / (N 2^16)), saturated
 * (hd_div64_rnd): gear ratios over the parameter range, the half-way points of each sign,
 * the saturation edges and random velocities of every magnitude */
static void test_app_motor_velocity_is_div64_rnd(void **state)
{
    static const int32_t ns[] = {1, 2, 3, 7, 100, 160, 999, 1000};
    uint32_t i, j, nsat = 0u, nmid = 0u;
    (void)state;
    app_start(0u, 0u);
    assert_int_equal(hd_app_param_set(&app, HD_P_VEL_FB_SRC, 0), 0);
    for (i = 0; i < sizeof ns / sizeof ns[0]; i++) {
        const int64_t d = (int64_t)ns[i] * 65536;
        const int64_t edges[] = {0, 1, -1, d / 2, -(d / 2), d / 2 - 1, -(d / 2) + 1, d + d / 2, -(d + d / 2),
                                 d * INT32_MAX, -d * INT32_MAX, d * INT32_MAX + d / 2 - 1, d * INT32_MAX + d / 2,
                                 -d * INT32_MAX - d / 2, -d * INT32_MAX - d / 2 - 1, d * 32768 * 65536,
                                 -d * 32768 * 65536, d * 32768 * 65536 - 1, INT64_MAX, INT64_MIN};
        const uint32_t ne = (uint32_t)(sizeof edges / sizeof edges[0]);
        assert_int_equal(hd_app_param_set(&app, HD_P_GEAR_RATIO, ns[i]), 0);
        for (j = 0; j < ne + 3000u; j++) {
            /* the observer steps before the division: its estimate on the (still) measurement
             * makes its error 0, so the step leaves vel as set */
            const int64_t v = (j < ne) ? edges[j] : s64(rnd64()) / (int64_t)(1ull << (uint32_t)(rnd64() % 63u));
            app.obs_mot.theta = app.pos_mot;
            app.obs_mot.frac = 0;
            app.obs_mot.vel = v;
            hd_app_step(&app);
            assert_true(app.obs_mot.vel == v);
            const int32_t want = hd_sat32(hd_div64_rnd(v, d));
            assert_int_equal(app.tel.vel_out, want);
            nsat += (want == INT32_MAX || want == INT32_MIN) ? 1u : 0u;
            nmid += (want != 0 && want != INT32_MAX && want != INT32_MIN) ? 1u : 0u;
        }
    }
    assert_true(nsat > 50u);
    assert_true(nmid > 5000u);
}

/* one section in the general form (hd_biquad.h): input clamped, the residual feedback
 * rounded, the output rounded and limited by 64-bit compares */
static int32_t ref_section(hd_biquad_state_t *s, const hd_biquad_coef_t *c, int32_t x_in)
{
    const int32_t x = (x_in > HD_BIQUAD_SIG_MAX) ? HD_BIQUAD_SIG_MAX
                      : (x_in < -HD_BIQUAD_SIG_MAX) ? -HD_BIQUAD_SIG_MAX : x_in;
    const int64_t r = (int64_t)c->a1 * s->e1 + (int64_t)c->a2 * s->e2;
    const int64_t acc = (int64_t)c->b0 * x + (int64_t)c->b1 * s->x1 + (int64_t)c->b2 * s->x2 -
                        (int64_t)c->a1 * s->y1 - (int64_t)c->a2 * s->y2 - hd_asr64_rnd(r, 30u);
    const int64_t yr = hd_asr64_rnd(acc, 30u);
    int32_t y, e;
    if (yr > (int64_t)HD_BIQUAD_SIG_MAX || yr < -(int64_t)HD_BIQUAD_SIG_MAX) {
        y = (yr > 0) ? HD_BIQUAD_SIG_MAX : -HD_BIQUAD_SIG_MAX;
        e = 0;
    } else {
        y = (int32_t)yr;
        e = (int32_t)(acc - yr * 1073741824);
    }
    s->x2 = s->x1;
    s->x1 = x;
    s->y2 = s->y1;
    s->y1 = y;
    s->e2 = s->e1;
    s->e1 = e;
    return y;
}

/* a chain of 1..4 sections clamps only its input and limits each output by 32-bit
 * compares: the same outputs and states as the general form (ref_section) stepped
 * section by section, with coefficients up to the Q2.30 range (outputs at and next to
 * the signal limit) and inputs beyond it */
static void test_biquad_chain_is_sections(void **state)
{
    uint32_t n, k, r, nlim = 0u;
    (void)state;
    for (r = 0; r < 40u; r++) {
        for (n = 1u; n <= HD_BIQUAD_MAX; n++) {
            hd_biquad_chain_cfg_t c;
            hd_biquad_chain_t s;
            hd_biquad_state_t ref[HD_BIQUAD_MAX];
            c.n = n;
            for (k = 0; k < n; k++) {
                /* every fourth run large coefficients (an unstable or limited section) */
                const uint32_t sh = ((r & 3u) == 0u) ? 0u : 2u + (uint32_t)(rnd64() % 4u);
                c.c[k].b0 = s32((uint32_t)rnd64()) >> sh;
                c.c[k].b1 = s32((uint32_t)rnd64()) >> sh;
                c.c[k].b2 = s32((uint32_t)rnd64()) >> sh;
                c.c[k].a1 = s32((uint32_t)rnd64()) >> sh;
                c.c[k].a2 = s32((uint32_t)rnd64()) >> (sh + 1u);
                hd_biquad_reset(&ref[k]);
            }
            hd_biquad_chain_reset(&s);
            for (k = 0; k < 300u; k++) {
                const int32_t x = (k % 7u == 0u) ? s32((uint32_t)rnd64())
                                                 : s32((uint32_t)rnd64()) >> (3u + (uint32_t)(rnd64() % 20u));
                int32_t y = x;
                uint32_t q;
                for (q = 0; q < n; q++) {
                    y = ref_section(&ref[q], &c.c[q], y);
                }
                assert_int_equal(hd_biquad_chain_step(&s, &c, x), y);
                for (q = 0; q < n; q++) {
                    assert_memory_equal(&s.s[q], &ref[q], sizeof ref[q]);
                }
                nlim += (y == HD_BIQUAD_SIG_MAX || y == -HD_BIQUAD_SIG_MAX) ? 1u : 0u;
            }
            /* a single section through hd_biquad_step (its own input clamp) */
            hd_biquad_reset(&ref[0]);
            hd_biquad_state_t one;
            hd_biquad_reset(&one);
            for (k = 0; k < 100u; k++) {
                const int32_t x = s32((uint32_t)rnd64()) >> (uint32_t)(rnd64() % 8u);
                assert_int_equal(hd_biquad_step(&one, &c.c[0], x), ref_section(&ref[0], &c.c[0], x));
                assert_memory_equal(&one, &ref[0], sizeof one);
            }
        }
    }
    assert_true(nlim > 100u);
    {
        /* at the limit exactly (kept, with its residual) and one LSB beyond (limited) */
        const hd_biquad_coef_t c1 = {1 << 30, 1, 0, 0, 0};
        static const int32_t xs[][2] = {{1 << 28, 1 << 29}, {-(1 << 28), -(1 << 29)}, {1 << 29, 1 << 29}};
        static const int32_t ys[] = {1 << 29, -(1 << 29), 1 << 29};
        static const int32_t es[] = {1 << 28, -(1 << 28), 0};
        for (k = 0; k < 3u; k++) {
            hd_biquad_state_t one;
            hd_biquad_reset(&one);
            (void)hd_biquad_step(&one, &c1, xs[k][0]);
            assert_int_equal(hd_biquad_step(&one, &c1, xs[k][1]), ys[k]);
            assert_int_equal(one.e1, es[k]);
        }
    }
}

/* the control period's motor observer step without err: theta, frac and vel are the words
 * of hd_velobs_step, err keeps its value */
static void test_velobs_vel_step_same_words(void **state)
{
    hd_velobs_cfg_t c;
    hd_velobs_t a, b;
    uint32_t k;
    (void)state;
    hd_velobs_design(&c, 300 * 411775, 45875);       /* 2 pi 300 Hz (Q16), zeta 0.7 */
    hd_velobs_reset(&a, 123456789);
    hd_velobs_reset(&b, 123456789);
    b.err = -777;
    for (k = 0; k < 20000u; k++) {
        /* slow motion with noise, jumps beyond the error limit every 1000 periods */
        const int64_t th = (int64_t)k * 3000000 + (int64_t)(s32((uint32_t)rnd64()) >> 12) +
                           ((k % 1000u == 500u) ? s64(rnd64()) >> 20 : 0);
        hd_velobs_step(&a, &c, th);
        hd_velobs_step_vel_inline(&b, &c, th);
        assert_true(a.theta == b.theta);
        assert_int_equal(a.frac, b.frac);
        assert_true(a.vel == b.vel);
        assert_int_equal(b.err, -777);
    }
    assert_true(a.vel != 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_div64_rnd_u16_matches_div64_rnd, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_pid_fit_readouts_match_asr32_rnd, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_blend_update_follows_ramp_rule, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_app_current_is_div_q, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_app_motor_torque_is_div64_rnd, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_app_encoder_steps, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_app_travel_limit_follows_parameter, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_pid_shift_products_match_shl64_sat, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_divinv_matches_div64_rnd, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_stribeck_g_inv_matches_g, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_foc_rounding_matches_biased_form, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_app_aff_gain_precomputed, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_app_motor_velocity_is_div64_rnd, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_biquad_chain_is_sections, setUp, tearDown),
        cmocka_unit_test_setup_teardown(test_velobs_vel_step_same_words, setUp, tearDown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
