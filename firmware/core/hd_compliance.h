/*
 * hd_compliance.h - torsional twist of a three-slope gear stiffness at a given
 * transmitted torque (the inverse of the piecewise-linear torque-twist curve).
 *
 *   |T| <= T1:        phi = |T| / K1
 *   T1 < |T| <= T2:   phi = T1 / K1 + (|T| - T1) / K2
 *   |T| > T2:         phi = T1 / K1 + (T2 - T1) / K2 + (|T| - T2) / K3
 *   sign(phi) = sign(T)
 * (the sim plant's T_s(phi), docs/plant.md, solved for phi).  Used by the
 * compensator bank to predict how far the output lags the output-referred motor
 * angle under load: the compliance part of the semi-closed position estimate.
 *
 * Formats:
 *   T, t1, t2          Q15.16 N.m, output side (0 <= t1 <= t2)
 *   c1, c2, c3         compliance 2^-44 turn per N.m (1/K from Q23.8 N.m/turn:
 *                      c = round(2^52 / K), int32 for K >= 2^13 N.m/turn; computed
 *                      once by hd_compliance_design, never in the control period)
 *   phi                2^-32 turn (int32; saturated)
 * Each segment product |T| c is < 2^31 x 2^31 (exact int64); the sum is rounded
 * once (>> 28 with rounding).  No division in hd_compliance_twist.
 */
#ifndef HD_COMPLIANCE_H
#define HD_COMPLIANCE_H

#include <stdint.h>
#include "hd_units.h"

typedef struct {
    int32_t c1, c2, c3;      /* 2^-44 turn / N.m */
    int32_t t1, t2;          /* Q15.16 N.m */
} hd_compliance_cfg_t;

/** Config from the slopes (Q23.8 N.m/turn, each >= 2^13) and breakpoints (Q15.16 N.m).
 *  0 ok, -1 bad (slope below 2^13 N.m/turn, t1 < 0 or t2 < t1); cfg untouched on error. */
int32_t hd_compliance_design(hd_compliance_cfg_t *c, int32_t k1, int32_t k2, int32_t k3, int32_t t1, int32_t t2);
/** Twist at the transmitted torque t (Q15.16 N.m), 2^-32 turn. */
int32_t hd_compliance_twist(const hd_compliance_cfg_t *c, int32_t t);

#endif
