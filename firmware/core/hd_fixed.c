/*
 * hd_fixed.c - fixed-point base library (contract: hd_fixed.h).
 *
 * Implementation rules:
 *  - Signed values are never shifted: a negative value is turned into its
 *    magnitude as uint64_t (well-defined modular conversion), shifted and
 *    rounded there, and turned back with hd__neg_mag() which never forms an
 *    out-of-range signed value.
 *  - Rounding is half away from zero, done on the magnitude as
 *    (m >> s) + bit (s-1) of m, so it cannot overflow.
 *  - Out-of-contract shift counts are clamped (documented per function) so
 *    that no call can reach a shift >= the type width.
 *
 * Tables (hd_math_tables.h) were computed once in double precision and
 * rounded to nearest; tools/gen_math_tables.py regenerates them.
 * Accuracy and cost numbers: docs/fixed-point.md.
 */
#include "hd_fixed.h"
#include "hd_math_tables.h"

/* ---- internal helpers (static, no state) ----------------------------- */

#define HD__U64_2P63 ((uint64_t)1 << 63)

/* |x| as uint64 (|INT64_MIN| = 2^63 is representable). */
static uint64_t hd__mag64(int64_t x)
{
    return (x < 0) ? ((uint64_t)0 - (uint64_t)x) : (uint64_t)x;
}

/* -m for 0 <= m <= 2^63, without forming an out-of-range signed value. */
static int64_t hd__neg_mag(uint64_t m)
{
    return (m == 0u) ? 0 : (-(int64_t)(m - 1u) - 1);
}

/* sign * m saturated to int64. */
static int64_t hd__signed_sat64(uint64_t m, bool neg)
{
    if (neg) {
        return (m >= HD__U64_2P63) ? INT64_MIN : hd__neg_mag(m);
    }
    return (m > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)m;
}

/* round_half_up(m / 2^s) on a magnitude, 0 <= s <= 63.  Never overflows. */
static uint64_t hd__ushr_rnd(uint64_t m, uint32_t s)
{
    if (s == 0u) {
        return m;
    }
    return (m >> s) + ((m >> (s - 1u)) & 1u);
}

/* floor(un / ud) and the remainder for ud < 2^16, by long division in base 2^16:
 * each step divides (r * 2^16 + digit) < ud * 2^16 <= 2^32 in 32 bits, so the M4
 * needs four UDIVs instead of the __aeabi_uldivmod loop.  Exact. */
static uint32_t hd__udiv_digit(uint32_t *r, uint32_t digit, uint32_t ud)
{
    const uint32_t cur = (*r << 16) | digit;           /* < ud * 2^16 <= 2^32 */
    const uint32_t qd = cur / ud;
    *r = cur - qd * ud;
    return qd;
}

static uint64_t hd__udiv64_small(uint64_t un, uint32_t ud, uint64_t *rem)
{
    const uint32_t hi = (uint32_t)(un >> 32);
    const uint32_t lo = (uint32_t)un;
    uint32_t r = 0u;
    const uint32_t q3 = hd__udiv_digit(&r, hi >> 16, ud);
    const uint32_t q2 = hd__udiv_digit(&r, hi & 0xFFFFu, ud);
    const uint32_t q1 = hd__udiv_digit(&r, lo >> 16, ud);
    const uint32_t q0 = hd__udiv_digit(&r, lo & 0xFFFFu, ud);
    *rem = r;
    return ((uint64_t)((q3 << 16) | q2) << 32) | ((q1 << 16) | q0);
}

/* floor((u1 * 2^32 + u0) / v) and the remainder, u1 < v, v >= 2^16 (Hacker's
 * Delight divlu, base 2^16): v is normalised so its top bit is set, each of the
 * two 16-bit quotient digits is estimated with one 32-bit UDIV by the top half
 * of v and corrected at most twice.  Every intermediate fits 32 bits (the
 * products q * vn0 are formed only when q < 2^16, rhat * 2^16 only when
 * rhat < 2^16).  Exact: the same quotient and remainder as the 64-bit '/'. */
static uint32_t hd__divlu(uint32_t u1, uint32_t u0, uint32_t v0, uint32_t *r)
{
    const uint32_t b = 65536u;
    const uint32_t s = (uint32_t)__builtin_clz(v0);          /* v0 != 0; s <= 15 */
    const uint32_t v = v0 << s;
    const uint32_t vn1 = v >> 16;
    const uint32_t vn0 = v & 0xFFFFu;
    const uint32_t un32 = (s == 0u) ? u1 : ((u1 << s) | (u0 >> (32u - s)));
    const uint32_t un10 = u0 << s;
    const uint32_t un1 = un10 >> 16;
    const uint32_t un0 = un10 & 0xFFFFu;
    uint32_t q1 = un32 / vn1;
    uint32_t rhat = un32 - (q1 * vn1);
    uint32_t k;
    for (k = 0u; (k < 2u) && (rhat < b) && ((q1 >= b) || ((q1 * vn0) > ((b * rhat) + un1))); k++) {
        q1--;
        rhat += vn1;
    }
    {
        const uint32_t un21 = ((un32 * b) + un1) - (q1 * v);   /* < v, modular arithmetic exact */
        uint32_t q0 = un21 / vn1;
        rhat = un21 - (q0 * vn1);
        for (k = 0u; (k < 2u) && (rhat < b) && ((q0 >= b) || ((q0 * vn0) > ((b * rhat) + un0))); k++) {
            q0--;
            rhat += vn1;
        }
        *r = (((un21 * b) + un0) - (q0 * v)) >> s;
        return (q1 << 16) + q0;
    }
}

/* floor(un / ud) and the remainder for ud < 2^32 without __aeabi_uldivmod. Exact. */
static uint64_t hd__udiv64_32(uint64_t un, uint32_t ud, uint64_t *rem)
{
    if (ud < 65536u) {
        return hd__udiv64_small(un, ud, rem);
    }
    {
        const uint32_t hi = (uint32_t)(un >> 32);
        const uint32_t qh = hi / ud;
        uint32_t r;
        const uint32_t ql = hd__divlu(hi - (qh * ud), (uint32_t)un, ud, &r);
        *rem = r;
        return ((uint64_t)qh << 32) | ql;
    }
}

/* ---- saturation ------------------------------------------------------ */

int32_t hd_sat32(int64_t x)
{
    if (x > (int64_t)INT32_MAX) {
        return INT32_MAX;
    }
    if (x < (int64_t)INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)x;
}

int64_t hd_satn(int64_t x, uint32_t n)
{
    /* n outside [1, 63] is clamped: n = 0 acts as 1, n >= 64 returns x. */
    if (n >= 64u) {
        return x;
    }
    if (n == 0u) {
        n = 1u;
    }
    {
        const int64_t hi = (int64_t)(((uint64_t)1 << (n - 1u)) - 1u);
        const int64_t lo = -hi - 1;
        if (x > hi) {
            return hi;
        }
        if (x < lo) {
            return lo;
        }
        return x;
    }
}

int32_t hd_clamp32(int32_t x, int32_t lo, int32_t hi)
{
    if (x < lo) {
        return lo;
    }
    if (x > hi) {
        return hi;
    }
    return x;
}

int64_t hd_clamp64(int64_t x, int64_t lo, int64_t hi)
{
    if (x < lo) {
        return lo;
    }
    if (x > hi) {
        return hi;
    }
    return x;
}

/* ---- saturating add / sub / neg / abs -------------------------------- */

int32_t hd_add_sat(int32_t a, int32_t b)
{
    return hd_sat32((int64_t)a + (int64_t)b); /* HD_ADD_SAT_SATURATION */
}

int32_t hd_sub_sat(int32_t a, int32_t b)
{
    return hd_sat32((int64_t)a - (int64_t)b);
}

int32_t hd_neg_sat(int32_t x)
{
    return (x == INT32_MIN) ? INT32_MAX : -x;
}

int32_t hd_abs_sat(int32_t x)
{
    if (x == INT32_MIN) {
        return INT32_MAX;
    }
    return (x < 0) ? -x : x;
}

int64_t hd_add64_sat(int64_t a, int64_t b)
{
    if (b > 0 && a > INT64_MAX - b) {
        return INT64_MAX;
    }
    if (b < 0 && a < INT64_MIN - b) {
        return INT64_MIN;
    }
    return a + b;
}

int64_t hd_sub64_sat(int64_t a, int64_t b)
{
    if (b < 0 && a > INT64_MAX + b) {
        return INT64_MAX;
    }
    if (b > 0 && a < INT64_MIN + b) {
        return INT64_MIN;
    }
    return a - b;
}

int64_t hd_neg64_sat(int64_t x)
{
    return (x == INT64_MIN) ? INT64_MAX : -x;
}

int64_t hd_abs64_sat(int64_t x)
{
    if (x == INT64_MIN) {
        return INT64_MAX;
    }
    return (x < 0) ? -x : x;
}

/* ---- shifts with defined rounding ------------------------------------ */

int64_t hd_asr64_floor(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;            /* same result as any s >= 63: 0 or -1 */
    }
    if (x >= 0) {
        return (int64_t)((uint64_t)x >> s);
    }
    /* x < 0: floor(x / 2^s) = -1 - floor((-1 - x) / 2^s), and -1 - x >= 0. */
    return -1 - (int64_t)((uint64_t)(-1 - x) >> s);
}

int64_t hd_asr64_rnd(int64_t x, uint32_t s)
{
    if (s > 63u) {
        s = 63u;            /* out of contract: clamped */
    }
    if (s == 0u) {
        return x;
    }
    /* s >= 1: the rounded magnitude is <= 2^62 + 1, so the casts are exact. */
    if (x >= 0) {
        return (int64_t)hd__ushr_rnd((uint64_t)x, s);
    }
    return -(int64_t)hd__ushr_rnd(hd__mag64(x), s);
}

int32_t hd_asr32_rnd(int64_t x, uint32_t s)
{
    return hd_sat32(hd_asr64_rnd(x, s));
}

int64_t hd_shl64_sat(int64_t x, uint32_t s)
{
    if (x == 0) {
        return 0;
    }
    if (s >= 63u) {         /* only x = -1, s = 63 is exact (INT64_MIN) */
        return (x > 0) ? INT64_MAX : INT64_MIN;
    }
    {
        const int64_t lim = (int64_t)((uint64_t)INT64_MAX >> s); /* 2^(63-s) - 1 */
        if (x > lim) {
            return INT64_MAX;
        }
        if (x < -lim - 1) {
            return INT64_MIN;
        }
        return x * (int64_t)((uint64_t)1 << s);   /* exact, no overflow */
    }
}

int32_t hd_shl32_sat(int32_t x, uint32_t s)
{
    if (x == 0) {
        return 0;
    }
    if (s > 31u) {
        return (x > 0) ? INT32_MAX : INT32_MIN;
    }
    /* |x| * 2^31 <= 2^62: exact in int64. */
    return hd_sat32((int64_t)x * (int64_t)((uint64_t)1 << s));
}

/* ---- multiply -------------------------------------------------------- */

int32_t hd_mul_q(int32_t a, int32_t b, uint32_t q)
{
    const int64_t p = (int64_t)a * (int64_t)b;   /* |p| <= 2^62: exact */
    if (q > 62u) {
        q = 62u;            /* out of contract: clamped */
    }
    return hd_asr32_rnd(p, q); /* HD_MUL_Q_ROUNDING (tests/checks/30_golden_bite.sh edits this line) */
}

int64_t hd_mul64x32_q(int64_t a, int32_t b, uint32_t q)
{
    if (a >= (int64_t)INT32_MIN && a <= (int64_t)INT32_MAX) {
        /* |a*b| <= 2^62: the 64-bit product is exact (one SMULL on the M4);
         * hd_asr64_rnd rounds half away like the 96-bit path below */
        return hd_asr64_rnd((int64_t)(int32_t)a * (int64_t)b, (q > 62u) ? 62u : q);
    }
    const bool neg = (a < 0) != (b < 0);
    const uint64_t ua = hd__mag64(a);                 /* <= 2^63 */
    const uint32_t ub = (uint32_t)hd__mag64(b);       /* <= 2^31 */
    const uint64_t al = (uint64_t)(uint32_t)ua;
    const uint64_t ah = ua >> 32;                      /* <= 2^31 */
    /* 96-bit magnitude product as (hi:lo) = ah*ub*2^32 + al*ub. */
    const uint64_t plo = al * (uint64_t)ub;            /* < 2^63 */
    const uint64_t pmid = ah * (uint64_t)ub;           /* <= 2^62 */
    uint64_t lo = plo + (pmid << 32);
    uint64_t hi = (pmid >> 32) + ((lo < plo) ? 1u : 0u);
    uint64_t m;

    if (q > 62u) {
        q = 62u;            /* out of contract: clamped */
    }
    if (q > 0u) {
        /* add half an output LSB, then shift the 128-bit value right by q */
        const uint64_t half = (uint64_t)1 << (q - 1u);
        const uint64_t lo2 = lo + half;
        hi += (lo2 < lo) ? 1u : 0u;
        lo = lo2;
        m = (lo >> q) | (hi << (64u - q));
        hi >>= q;
    } else {
        m = lo;
    }
    if (hi != 0u) {
        return neg ? INT64_MIN : INT64_MAX;
    }
    return hd__signed_sat64(m, neg);
}

int64_t hd_mac64(int64_t acc, int32_t a, int32_t b)
{
    return hd_add64_sat(acc, (int64_t)a * (int64_t)b);
}

/* ---- divide ---------------------------------------------------------- */

int32_t hd_div_q(int32_t num, int32_t den, uint32_t q)
{
    const bool neg = (num < 0) != (den < 0);
    uint64_t un;
    uint64_t ud;
    uint64_t quo;
    uint64_t rem;

    if (den == 0) {
        return (num > 0) ? INT32_MAX : ((num < 0) ? INT32_MIN : 0);
    }
    if (q > 31u) {
        q = 31u;            /* out of contract: clamped */
    }
    un = hd__mag64(num) << q;                          /* <= 2^62 */
    ud = hd__mag64(den);                               /* <= 2^31 */
    quo = hd__udiv64_32(un, (uint32_t)ud, &rem);
    if (rem >= ud - rem) { /* HD_DIV_Q_ROUNDING: 2*rem >= ud, half away */
        quo += 1u;
    }
    return hd_sat32(hd__signed_sat64(quo, neg));
}

int64_t hd_div64_rnd(int64_t num, int64_t den)
{
    const bool neg = (num < 0) != (den < 0);
    uint64_t un;
    uint64_t ud;
    uint64_t quo;
    uint64_t rem;

    if (den == 0) {
        return (num > 0) ? INT64_MAX : ((num < 0) ? INT64_MIN : 0);
    }
    un = hd__mag64(num);                               /* <= 2^63 */
    ud = hd__mag64(den);
    if (ud <= 0xFFFFFFFFu) {
        quo = hd__udiv64_32(un, (uint32_t)ud, &rem);
    } else {
        quo = un / ud;
        rem = un - quo * ud;
    }
    if (rem >= ud - rem) {
        quo += 1u;                                     /* quo <= 2^62 + 1 here */
    }
    return hd__signed_sat64(quo, neg);
}

void hd_divinv_init(hd_divinv_t *v, uint32_t d)
{
    v->d = d;
    v->m = (d == 0u) ? 0u : (UINT64_MAX / d);
}

/* the high word of the 128-bit product a b (four 32x32 products) */
static uint64_t hd__mulhi64(uint64_t a, uint64_t b)
{
    const uint64_t al = a & 0xFFFFFFFFu;
    const uint64_t ah = a >> 32;
    const uint64_t bl = b & 0xFFFFFFFFu;
    const uint64_t bh = b >> 32;
    const uint64_t ll = al * bl;
    const uint64_t lh = al * bh;
    const uint64_t hl = ah * bl;
    const uint64_t mid = (ll >> 32) + (lh & 0xFFFFFFFFu) + (hl & 0xFFFFFFFFu);   /* < 3 * 2^32 */
    return ah * bh + (lh >> 32) + (hl >> 32) + (mid >> 32);
}

int64_t hd_divinv_rnd(int64_t num, const hd_divinv_t *v)
{
    /* |num| m / 2^64 = (|num| / d)(1 - (1 + e) / 2^64), e = (2^64 - 1) mod d < d, and
     * |num| < 2^64: it lies in (|num| / d - 1, |num| / d], so its floor is the quotient
     * or one less; the remainder r = |num| - q d < 2 d then tells (d <= 2^32: no overflow) */
    const bool neg = num < 0;
    const uint64_t un = hd__mag64(num);
    const uint64_t d = v->d;
    uint64_t q = hd__mulhi64(un, v->m);
    uint64_t r = un - q * d;
    if (r >= d) {
        q += 1u;
        r -= d;
    }
    if (r >= d - r) {           /* half away, as hd_div64_rnd */
        q += 1u;
    }
    return hd__signed_sat64(q, neg);
}

/* ---- nonlinear functions -------------------------------------------- */

/*
 * exp(-x), x = n + f (n integer part, f = fh/256 + fl/65536):
 *   e^-x = e^-n * E1[fh] * E2[fl]
 * E1, E2 in Q31 (rounded to nearest); their product is rounded to Q32;
 * e^-n is a normalised mantissa m in [2^30, 2^31) with exponent z
 * (e^-n = m * 2^-(30+z)), so its relative error is < 2^-31 for every n and
 * the only rounding after the product is the final one.  Monotone by
 * construction: within one n the result is a rounded product of
 * non-increasing factors, and at n -> n+1 the exact values step down by a
 * relative 1.5e-5, far more than the relative error of E1*E2 (< 2e-9).
 * x >= 22 (22 << 16 in Q16) returns 0: e^-22 * 2^30 = 0.30 LSB.
 */
int32_t hd_exp_neg_q16(int32_t x_q16)
{
    uint32_t n;
    uint32_t fh;
    uint32_t fl;
    uint64_t e12;
    uint64_t r;

    if (x_q16 <= 0) {
        return HD_Q30_ONE;
    }
    if (x_q16 >= (int32_t)(HD_EXP_INT_N << 16)) {
        return 0;
    }
    n = (uint32_t)x_q16 >> 16;
    fh = ((uint32_t)x_q16 >> 8) & 0xFFu;
    fl = (uint32_t)x_q16 & 0xFFu;
    /* Q31 * Q31 = Q62 -> Q32 (<= 2^32) */
    e12 = hd__ushr_rnd((uint64_t)hd_exp_tab_frac_hi[fh] * hd_exp_tab_frac_lo[fl], 30u);
    /* m (< 2^31) * e12 (<= 2^32) < 2^63; shift 32 + z <= 63 */
    r = hd__ushr_rnd((uint64_t)hd_exp_tab_int_m[n] * e12, 32u + (uint32_t)hd_exp_tab_int_z[n]);
    return (int32_t)r;                                 /* <= 2^30 */
}

/*
 * sin/cos of a turn fraction.  angle = quadrant q (2 bits) | r (30 bits).
 * The pair is evaluated at p = r in quadrants 0 and 2 and at the mirror
 * p = 2^30 - r in quadrants 1 and 3 (0 <= p <= 2^30, a quarter turn), so
 * that a and -a, and a and a + half a turn, evaluate the very same point:
 * sin is exactly odd, cos exactly even, both exactly anti-periodic by half a
 * turn, and the quarter-turn points are exact (0 and +-1.0).
 * p = k*h + d with h = 1/1024 turn, k = p >> 22 (0..256), d = the low 22 bits:
 *   sin p = S[k] cos d + C[k] sin d,  cos p = C[k] cos d - S[k] sin d,
 * S[k] = sin(k*h), C[k] = S[256-k] from one quarter-wave table (Q31), and
 * d < 6.2e-3 rad with sin d = d - d^3/6 and cos d = 1 - d^2/2 + d^4/24
 * (truncation error < 8e-14 and < 2e-18), in Q36, rounded to Q32.
 */
void hd_sincos_turn(uint32_t angle, int32_t *sin_q30, int32_t *cos_q30)
{
    const uint32_t quad = angle >> 30;
    const uint32_t r = angle & 0x3FFFFFFFu;
    const uint32_t p = ((quad & 1u) != 0u) ? (0x40000000u - r) : r;
    const uint32_t k = p >> 22;                                     /* 0..256 */
    const uint32_t l = p & 0x3FFFFFu;
    /* every factor below fits 32 bits (one UMULL each on the M4); cos d = 2^32 - cm */
    const uint32_t d36 = (uint32_t)hd__ushr_rnd((uint64_t)l * (uint32_t)HD_PI_Q29, 24u);        /* < 2^29 */
    const uint32_t d2_36 = (uint32_t)hd__ushr_rnd((uint64_t)d36 * d36, 36u);                  /* d^2, < 2^22 */
    const uint32_t d3_6 = (uint32_t)hd__ushr_rnd((uint64_t)d2_36 * d36, 36u) / 6u;            /* d^3/6 */
    const uint32_t d4_24 = (uint32_t)hd__ushr_rnd((uint64_t)d2_36 * d2_36, 36u) / 24u;        /* d^4/24 */
    const uint32_t sd32 = (uint32_t)hd__ushr_rnd((uint64_t)(d36 - d3_6), 4u);                 /* sin d, Q32 */
    const uint32_t cm = (uint32_t)hd__ushr_rnd((uint64_t)((d2_36 >> 1) - d4_24), 4u);         /* 1 - cos d, Q32 */
    const uint32_t sk = (uint32_t)hd_sin_tab_q31[k];
    const uint32_t ck = (uint32_t)hd_sin_tab_q31[256u - k];
    /* Q31 * Q32 = Q63; sums < 2^63 + 2^56 fit uint64 (x * (2^32 - cm) = x 2^32 - x cm, exact) */
    const uint64_t s63 = ((uint64_t)sk << 32) - (uint64_t)sk * cm + (uint64_t)ck * sd32;
    const uint64_t c63p = ((uint64_t)ck << 32) - (uint64_t)ck * cm;
    const uint64_t c63n = (uint64_t)sk * sd32;
    uint64_t s30 = hd__ushr_rnd(s63, 33u);
    uint64_t c30 = (c63p > c63n) ? hd__ushr_rnd(c63p - c63n, 33u) : 0u;
    int32_t s;
    int32_t c;

    if (s30 > (uint64_t)HD_Q30_ONE) {
        s30 = (uint64_t)HD_Q30_ONE;
    }
    if (c30 > (uint64_t)HD_Q30_ONE) {
        c30 = (uint64_t)HD_Q30_ONE;
    }
    s = (int32_t)s30;
    c = (int32_t)c30;
    /* q0: (s, c)  q1: (s, -c)  q2: (-s, -c)  q3: (-s, c) */
    *sin_q30 = (quad >= 2u) ? -s : s;
    *cos_q30 = (quad == 1u || quad == 2u) ? -c : c;
}

/*
 * Cheaper sin/cos for the current loop: the same quarter-wave table, then the
 * second-order expansion around the table point (d = offset in rad < pi/512):
 *   sin(a + d) = s (1 - d^2/2) + c d,  cos(a + d) = c (1 - d^2/2) - s d,
 * error < d^3/6 < 4e-8 (~43 LSB of Q30) plus truncation; five 32x32->64
 * products, no 64-bit shifts.
 */
void hd_sincos_turn_fast(uint32_t angle, int32_t *sin_q30, int32_t *cos_q30)
{
    const uint32_t quad = angle >> 30;
    const uint32_t r = angle & 0x3FFFFFFFu;
    const uint32_t p = ((quad & 1u) != 0u) ? (0x40000000u - r) : r;
    const uint32_t k = p >> 22;                                     /* 0..256 */
    const uint32_t l = p & 0x3FFFFFu;
    /* d = l 2^-22 pi / 512 rad = l pi 2^-31; in Q32 = l * pi 2^29 / 2^28, < 2^25 */
    const uint32_t d32 = (uint32_t)(((uint64_t)l * (uint32_t)HD_PI_Q29) >> 28);
    const uint32_t h32 = (uint32_t)(((uint64_t)d32 * d32) >> 33);   /* d^2 / 2, Q32 */
    const uint32_t sk = hd_sin_tab_q31[k];
    const uint32_t ck = hd_sin_tab_q31[256u - k];
    /* s (1 - d^2/2) >= 0 and c (1 - d^2/2) >= 0; the sums stay below 2^32 */
    const uint32_t s_a = sk - (uint32_t)(((uint64_t)sk * h32) >> 32) + (uint32_t)(((uint64_t)ck * d32) >> 32);
    const uint32_t c_a = ck - (uint32_t)(((uint64_t)ck * h32) >> 32);
    const uint32_t c_b = (uint32_t)(((uint64_t)sk * d32) >> 32);
    const uint32_t s31 = (s_a > 0x80000000u) ? 0x80000000u : s_a;
    const uint32_t c31 = (c_a > c_b) ? ((c_a - c_b > 0x80000000u) ? 0x80000000u : c_a - c_b) : 0u;
    const int32_t s = (int32_t)((s31 + 1u) >> 1);
    const int32_t c = (int32_t)((c31 + 1u) >> 1);
    /* q0: (s, c)  q1: (s, -c)  q2: (-s, -c)  q3: (-s, c) */
    *sin_q30 = (quad >= 2u) ? -s : s;
    *cos_q30 = (quad == 1u || quad == 2u) ? -c : c;
}

/* The sine of hd_sincos_turn_fast alone, the same words: the cosine's two
 * products and clamp are left out where only the sine is used (the excitation
 * generator's lines). */
int32_t hd_sin_turn_fast(uint32_t angle)
{
    const uint32_t quad = angle >> 30;
    const uint32_t r = angle & 0x3FFFFFFFu;
    const uint32_t p = ((quad & 1u) != 0u) ? (0x40000000u - r) : r;
    const uint32_t k = p >> 22;                                     /* 0..256 */
    const uint32_t l = p & 0x3FFFFFu;
    const uint32_t d32 = (uint32_t)(((uint64_t)l * (uint32_t)HD_PI_Q29) >> 28);
    const uint32_t h32 = (uint32_t)(((uint64_t)d32 * d32) >> 33);   /* d^2 / 2, Q32 */
    const uint32_t sk = hd_sin_tab_q31[k];
    const uint32_t ck = hd_sin_tab_q31[256u - k];
    const uint32_t s_a = sk - (uint32_t)(((uint64_t)sk * h32) >> 32) + (uint32_t)(((uint64_t)ck * d32) >> 32);
    const uint32_t s31 = (s_a > 0x80000000u) ? 0x80000000u : s_a;
    const int32_t s = (int32_t)((s31 + 1u) >> 1); /* HD_SIN_FAST_ROUNDING */
    return (quad >= 2u) ? -s : s;
}

int32_t hd_sign_smooth_q30(int32_t x, int32_t eps)
{
    uint64_t ux;
    uint64_t ue;
    uint64_t t31;
    uint64_t t2;
    uint64_t s;
    int32_t r;

    if (x == 0) {
        return 0;
    }
    ux = hd__mag64(x);
    ue = (eps > 0) ? (uint64_t)eps : 0u;
    if (ux >= ue) {
        return (x > 0) ? HD_Q30_ONE : -HD_Q30_ONE;
    }
    /* |t| = |x|/eps < 1 in Q31 (rounded), then s = t (3 - t^2) / 2 in Q30. */
    {
        const uint64_t num = ux << 31;
        const uint64_t quo = num / ue;
        const uint64_t rem = num - quo * ue;
        t31 = quo + ((rem >= ue - rem) ? 1u : 0u);     /* <= 2^31 */
    }
    t2 = hd__ushr_rnd(t31 * t31, 31u);                 /* t^2, Q31, <= 2^31 */
    s = hd__ushr_rnd(t31 * ((uint64_t)3u * ((uint64_t)1 << 31) - t2), 33u);
    if (s > (uint64_t)HD_Q30_ONE) {
        s = (uint64_t)HD_Q30_ONE;
    }
    r = (int32_t)s;
    return (x > 0) ? r : -r;
}

uint32_t hd_isqrt64(uint64_t x)
{
    /* Digit-by-digit (binary restoring) square root: 32 iterations, exact. */
    uint64_t rem = x;
    uint64_t root = 0u;
    uint64_t bit = (uint64_t)1 << 62;

    while (bit > rem) {
        bit >>= 2;
    }
    while (bit != 0u) {
        if (rem >= root + bit) {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    return (uint32_t)root;
}
