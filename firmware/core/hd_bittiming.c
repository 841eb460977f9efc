/*
 * hd_bittiming.c - classic CAN bit timing (see hd_bittiming.h).
 */
#include "hd_bittiming.h"

const hd_bt_limits_t hd_bt_fdcan_nominal = {512u, 256u, 128u, 128u, 8u};

/* round(1000 * num / den) for num <= den, den > 0 */
static uint32_t permille(uint32_t num, uint32_t den)
{
    return (uint32_t)(((uint64_t)num * 2000u + den) / (2u * (uint64_t)den));
}

static uint32_t absdiff(uint32_t a, uint32_t b)
{
    return (a > b) ? (a - b) : (b - a);
}

int32_t hd_bittiming_check(const hd_bt_t *t, uint32_t f_clk_hz, uint32_t bitrate,
                           uint32_t sp_min, uint32_t sp_max, const hd_bt_limits_t *lim)
{
    if (bitrate == 0u || t->brp == 0u || t->brp > lim->brp_max || t->tseg1 == 0u ||
        t->tseg1 > lim->tseg1_max || t->tseg2 == 0u || t->tseg2 > lim->tseg2_max ||
        t->sjw == 0u || t->sjw > lim->sjw_max || t->sjw > t->tseg2 ||
        t->n_tq != 1u + t->tseg1 + t->tseg2 || t->n_tq < lim->tq_min) {
        return -1;
    }
    if ((uint64_t)bitrate * t->brp * t->n_tq != (uint64_t)f_clk_hz) {
        return -1;
    }
    const uint32_t sp = permille(1u + t->tseg1, t->n_tq);
    if (sp < sp_min || sp > sp_max || sp != t->sp_permille) {
        return -1;
    }
    return 0;
}

int32_t hd_bittiming_calc(uint32_t f_clk_hz, uint32_t bitrate, uint32_t sp_target,
                          uint32_t sp_min, uint32_t sp_max, const hd_bt_limits_t *lim, hd_bt_t *out)
{
    uint32_t brp;
    int32_t found = -1;
    uint32_t best_err = 0xFFFFFFFFu;
    hd_bt_t best = {0u, 0u, 0u, 0u, 0u, 0u};
    if (f_clk_hz == 0u || bitrate == 0u || sp_min > sp_max || sp_max >= 1000u || lim->tq_min < 4u) {
        return -1;
    }
    for (brp = 1u; brp <= lim->brp_max; brp++) {
        const uint64_t per_bit = (uint64_t)bitrate * brp;
        if ((uint64_t)f_clk_hz % per_bit != 0u) {
            continue;
        }
        const uint64_t n64 = (uint64_t)f_clk_hz / per_bit;
        if (n64 < lim->tq_min || n64 > 1u + (uint64_t)lim->tseg1_max + lim->tseg2_max) {
            continue;
        }
        const uint32_t n = (uint32_t)n64;
        /* every tseg2 that fits; keep the sample point closest to the target */
        uint32_t t2;
        for (t2 = 2u; t2 <= lim->tseg2_max && t2 + 2u <= n; t2++) {
            const uint32_t t1 = n - 1u - t2;
            if (t1 > lim->tseg1_max || t1 < 1u) {
                continue;
            }
            const uint32_t sp = permille(1u + t1, n);
            if (sp < sp_min || sp > sp_max) {
                continue;
            }
            /* error scaled by n so that candidates with different tq compare exactly:
             * |1000 (1 + t1) - sp_target n| / n, compared as cross products */
            const uint32_t err = absdiff(1000u * (1u + t1), sp_target * n);
            /* err/n < best_err/best.n  <=>  err * best.n < best_err * n */
            const int better = (found != 0) ||
                ((uint64_t)err * best.n_tq < (uint64_t)best_err * n) ||
                ((uint64_t)err * best.n_tq == (uint64_t)best_err * n && n > best.n_tq);
            if (better) {
                found = 0;
                best_err = err;
                best.brp = brp;
                best.tseg1 = t1;
                best.tseg2 = t2;
                best.sjw = (t2 < lim->sjw_max) ? t2 : lim->sjw_max;
                best.n_tq = n;
                best.sp_permille = sp;
            }
        }
    }
    if (found != 0) {
        return -1;
    }
    *out = best;
    return 0;
}

uint32_t hd_bittiming_fdcan_nbtp(const hd_bt_t *t)
{
    return ((t->sjw - 1u) << 25) | ((t->brp - 1u) << 16) | ((t->tseg1 - 1u) << 8) | (t->tseg2 - 1u);
}
