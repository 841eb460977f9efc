/*
 * hd_plant_preisach.h - classical Preisach operator for the simulated gear
 * (double precision): Everett table on an (L+1)x(L+1) grid over [-u_max, u_max]
 * and the recursive memory (stacks of alternating dominant extrema with
 * wiping-out), harmonic-drive.md sections 6.3-6.4.  Internal to sim/plant.
 */
#ifndef HD_PLANT_PREISACH_H
#define HD_PLANT_PREISACH_H

#include "hd_plant.h"

/* Fill E[(L+1)*(L+1)] (E[i*(L+1)+j], alpha index i, beta index j, zero for i <= j)
 * for the density mu ~ exp(-r/r0)*exp(-m^2/(2 s^2)), scaled so E(u_max, -u_max) = t_sat. */
void hd_plant_preisach_everett(double *E, double u_max, double t_sat, double r0, double s);

/* Everett function at (alpha, beta), interpolated (bilinear; linear on diagonal cells so E(u,u) = 0). */
double hd_preisach_E(const double *E, double u_max, double alpha, double beta);

/* Demagnetised initial state at u = 0 (output ~0): decaying alternating sequence. */
void hd_plant_preisach_reset(hd_plant_preisach_state *s, const double *E, double u_max);

/* Output for input u (clamped to +-u_max) from memory s.  With commit != NULL the
 * memory after the move is written there (commit may equal s); with NULL s is only read. */
double hd_plant_preisach_eval(const hd_plant_preisach_state *s, const double *E, double u_max, double u,
                        hd_plant_preisach_state *commit);

/* Slope dy/du of the output from memory s (no move committed) for inputs moving from
 * s->u_prev in direction dir (+1 up, -1 down), and the input (bound) up to which that
 * slope holds: y(u) = s->y + slope (u - s->u_prev) between s->u_prev and bound. */
void hd_plant_preisach_piece(const hd_plant_preisach_state *s, const double *E, double u_max, int32_t dir,
                             double *slope, double *bound);

#endif
