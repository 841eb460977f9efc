/*
 * hd_sched.h - the compensator bank's schedule over the control periods.
 *
 * The loops (position, velocity), the observers, the torque filters and the
 * fast friction feed-forward run in every control period (HD_LOOP_HZ, one
 * "tick").  Compensators whose inputs change slowly run once per cycle of
 * HD_SCHED_CYCLE ticks, each in its own slot, so that no tick carries more
 * than one of them; between their updates their outputs are held (torques,
 * the Preisach and compliance twists: inputs low-passed) or linearly
 * extrapolated (TE and Maxwell-slip position corrections: they follow the
 * motor angle and the reference).  Rates, filter constants and ramps of a
 * decimated compensator are those of its own step (HD_SCHED_CYCLE periods).
 *
 *   every tick (10 kHz)   backstepping's law, scheduled position integral, Stribeck feed-forward
 *                         (measured / reference velocity), the sum of the
 *                         position corrections and its filter (dvel)
 *   slot 0                LuGre: g(v) and the bristles' steady state; backstepping
 *                         (after the loops): its Stribeck regressor's shape and the
 *                         adaptation of HD_SCHED_CYCLE periods (the law runs every tick
 *                         with the held estimates)
 *   slot 1                LuGre: the step's exponential factor; DOB
 *   slot 2                LuGre: bristle update, observer term, torque;
 *                         compliance twist at the held torque estimate
 *   slot 3                TE: motor-side harmonics and output-side lines
 *   slot 4                Maxwell-slip; transmitted-torque estimate (low-pass; with
 *                         pr_t_src 2 the low-pass in the next tick, before slot 5 reads it)
 *   slots 5 .. 7          Preisach twist at the held torque estimate: the
 *                         forward step of a torque -> twist table in slot 5,
 *                         or the inverse's bisection spread over the slots
 *                         (HD_SCHED_PR_TRIALS trials per tick; a new search
 *                         starts when the last one ended)
 *
 * Pure definitions, no state: the tick counter is the bank's (hd_comp_bank_t
 * tick), restarting with the bank.
 */
#ifndef HD_SCHED_H
#define HD_SCHED_H

#include <stdint.h>
#include "hd_units.h"

/* Ticks per schedule cycle (a power of two dividing HD_LOOP_HZ). */
#define HD_SCHED_CYCLE      8u
#define HD_SCHED_LOG2       3u
#define HD_SCHED_SLOW_HZ    (HD_LOOP_HZ / HD_SCHED_CYCLE)
/* Preisach inverse: bisection trials per tick (each a lattice search and an Everett sum). */
#define HD_SCHED_PR_TRIALS  1u

/* What a tick does besides the every-tick work. */
typedef enum {
    HD_SLOT_LUGRE_G = 0,        /* LuGre: g(v), z_ss */
    HD_SLOT_LUGRE_EXP = 1,      /* LuGre: exponential factor; DOB */
    HD_SLOT_LUGRE_FINISH = 2,   /* LuGre: bristles, torque; compliance twist */
    HD_SLOT_TE = 3,             /* transmission error (motor and output lines) */
    HD_SLOT_MAXWELL_EST = 4,    /* Maxwell-slip; transmitted-torque estimate */
    HD_SLOT_PREISACH = 5        /* Preisach (ticks 5 .. 7) */
} hd_slot_t;
#define HD_SLOT_DOB HD_SLOT_LUGRE_EXP
/* backstepping (hd_comp_bank_post, phase_loops): the regressor's Stribeck shape and the
 * adaptation in the tick of LuGre's g(v), the lightest slot */
#define HD_SLOT_BACKSTEP HD_SLOT_LUGRE_G

/** The slot kind of a tick count. */
static inline hd_slot_t hd_sched_slot(uint32_t tick)
{
    const uint32_t k = tick & (HD_SCHED_CYCLE - 1u);
    return (k >= (uint32_t)HD_SLOT_PREISACH) ? HD_SLOT_PREISACH : (hd_slot_t)k;
}

#endif
