/*
 * hd_compliance.c - three-slope stiffness twist (contract: hd_compliance.h).
 */
#include "hd_compliance.h"
#include "hd_fixed.h"

#define HD_CP_K_MIN 2097152     /* 2^13 N.m/turn in Q23.8: smallest slope with an int32 compliance */

int32_t hd_compliance_design(hd_compliance_cfg_t *c, int32_t k1, int32_t k2, int32_t k3, int32_t t1, int32_t t2)
{
    if (k1 < HD_CP_K_MIN || k2 < HD_CP_K_MIN || k3 < HD_CP_K_MIN || t1 < 0 || t2 < t1) {
        return -1;
    }
    /* 2^52 / K <= 2^52 / 2^21 = 2^31: the bound itself only at K = 2^13 exactly */
    c->c1 = hd_sat32(hd_div64_rnd((int64_t)1 << 52, k1));
    c->c2 = hd_sat32(hd_div64_rnd((int64_t)1 << 52, k2));
    c->c3 = hd_sat32(hd_div64_rnd((int64_t)1 << 52, k3));
    c->t1 = t1;
    c->t2 = t2;
    return 0;
}

int32_t hd_compliance_twist(const hd_compliance_cfg_t *c, int32_t t)
{
    /* |T| as int64 (|INT32_MIN| fits), split over the three segments */
    const int64_t at = (t < 0) ? -(int64_t)t : (int64_t)t;
    const int64_t s1 = (at < c->t1) ? at : c->t1;
    const int64_t s2 = (at <= c->t1) ? 0 : ((at < c->t2) ? at - c->t1 : (int64_t)c->t2 - c->t1);
    const int64_t s3 = (at <= c->t2) ? 0 : at - c->t2;
    /* Q16 N.m x 2^-44 turn/N.m = 2^-60 turn; each product < 2^62, the sum < 2^63 */
    const int64_t acc = s1 * c->c1 + s2 * c->c2 + s3 * c->c3;
    const int32_t phi = hdf_sat32(hdf_asr64_rnd(acc, 28u));
    return (t < 0) ? -phi : phi;
}
