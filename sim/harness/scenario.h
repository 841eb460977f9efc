/*
 * scenario.h - closed-loop scenario files (TOML), see docs/sim.md.
 *
 *   [scenario]    name, axis (file or "reference"/"minimal"), duration_s, seed,
 *                 log_decimation
 *   [controller]  mode ("position" | "velocity" | "torque" | "off" | "stabilise"),
 *                 gains = "defaults" or a [controller.gains] table,
 *                 compensators = [ "name", ... ]
 *   [compensators.<name>]  drive parameters by name (table units, like gains);
 *                 [compensators.preisach] table = "file" (Preisach image, hdservo.compsetup)
 *   [setpoint]    type = constant | step | ramp | move | sine | chirp | multisine | prbs
 *                 (+ position mode: run_in_targets_rad, run_in_speeds_rad_s,
 *                 run_in_accel_rad_s2, run_in_t0_s: moves before t0, e.g. a normal
 *                 motion profile that lets the drive's estimators see the axis)
 *                 values carry the unit of the mode: _rad (position),
 *                 _rad_s (velocity), _Nm (torque), rates _rad_s / _rad_s2 / _Nm_per_s
 *   [disturbance] load_torque_Nm, load_step_Nm + load_step_t_s,
 *                 base_amp_rad + base_freq_Hz (+ base_phase_rad)
 *   [plant]       overrides of axis-file keys: friction_motor.enabled = false ...
 *   [[fault]]     t_s, type = encoder_glitch | encoder_dropout | current_limit | load_step,
 *                 encoder = "motor"|"load", counts, duration_s, limit_A, torque_Nm
 */
#ifndef HD_SCENARIO_H
#define HD_SCENARIO_H

#include <stddef.h>
#include <stdint.h>

#define HD_SC_PATH_MAX       1024
#define HD_SC_KEY_MAX        128
#define HD_SC_MAX_OVERRIDES  256
#define HD_SC_MAX_FAULTS     64
#define HD_SC_MAX_COMP       16
#define HD_SC_MAX_DURATION_S 3600.0
#define HD_SC_MAX_RUN_IN     512     /* moves of a setpoint's run-in */

typedef enum {
    HD_SC_MODE_OFF = 0,
    HD_SC_MODE_TORQUE,
    HD_SC_MODE_VELOCITY,
    HD_SC_MODE_POSITION,
    HD_SC_MODE_STABILISE    /* drive mode STAB: setpoint = commanded inertial rate, rad/s */
} hd_sc_mode_t;

typedef enum {
    HD_SP_CONSTANT = 0,
    HD_SP_STEP,
    HD_SP_RAMP,
    HD_SP_MOVE,
    HD_SP_SINE,
    HD_SP_CHIRP,
    HD_SP_MULTISINE,
    HD_SP_PRBS,
    HD_SP_PTP              /* drive point-to-point (mode PTP, hd_app_move_to) to target at t0 */
} hd_sp_type_t;

/* Setpoint profile, values in the unit of the mode (rad, rad/s or N.m at the motor). */
typedef struct {
    hd_sp_type_t type;
    double initial;        /* value before t0 (offset for sine/excitation) */
    double amplitude;      /* step height, sine/chirp/multisine/prbs amplitude */
    double t0_s;           /* start */
    double t1_s;           /* ramp end (<= 0: never ends); excitation end (<= 0: end of run) */
    double rate;           /* ramp slope per second */
    double target;         /* move end value */
    double max_velocity;   /* move: per second */
    double max_accel;      /* move: per second^2 */
    double frequency_Hz;   /* sine */
    double phase_rad;      /* sine */
    double f0_Hz, f1_Hz;   /* chirp sweep / multisine band */
    int32_t n_lines;       /* multisine lines */
    double bit_period_s;   /* prbs */
    /* run-in (position mode): moves from initial through initial + run_in_target[i] at
     * run_in_speed[i], from run_in_t0_s on; the last one ends at initial, before t0 */
    int32_t n_run_in;                          /* moves, 0 = no run-in */
    double run_in_t0_s;                        /* start of the first move */
    double run_in_accel;                       /* acceleration of every move, rad/s^2 */
    double run_in_target[HD_SC_MAX_RUN_IN];    /* end of each move relative to initial, rad */
    double run_in_speed[HD_SC_MAX_RUN_IN];     /* cruise speed of each move, rad/s */
    double run_in_start[HD_SC_MAX_RUN_IN + 1]; /* start of each move; [n_run_in]: end of the run-in, s */
} hd_sc_setpoint_t;

typedef enum {
    HD_FAULT_ENC_GLITCH = 0,
    HD_FAULT_ENC_DROPOUT,
    HD_FAULT_CURRENT_LIMIT,
    HD_FAULT_LOAD_STEP
} hd_fault_type_t;

typedef struct {
    double t_s;
    hd_fault_type_t type;
    int32_t encoder;       /* 0 motor, 1 load */
    int64_t counts;        /* glitch size */
    double duration_s;     /* dropout length */
    double limit_A;        /* current limit (< 0 removes) */
    double torque_Nm;      /* load step (0 removes) */
    int32_t line;          /* where it was defined */
} hd_sc_fault_t;

typedef struct {
    char key[HD_SC_KEY_MAX];
    double value;
    int32_t line;
} hd_sc_override_t;

typedef struct {
    char path[HD_SC_PATH_MAX];        /* scenario file as given */
    char name[HD_SC_KEY_MAX];
    char axis[HD_SC_PATH_MAX];        /* resolved axis file path, or "reference"/"minimal" */
    double duration_s;
    double dt_s;                      /* firmware loop period (1/HD_LOOP_HZ) */
    uint64_t seed;
    int32_t log_decimation;
    hd_sc_mode_t mode;
    int32_t n_gains;
    hd_sc_override_t gains[HD_SC_MAX_OVERRIDES];
    int32_t n_comp;
    char comp[HD_SC_MAX_COMP][HD_SC_KEY_MAX];
    char comp_table[HD_SC_PATH_MAX];  /* [compensators.preisach] table = "file" (resolved), "" = none */
    hd_sc_setpoint_t sp;
    double load_torque_Nm;
    double load_step_Nm, load_step_t_s;
    int32_t n_over;
    hd_sc_override_t over[HD_SC_MAX_OVERRIDES];   /* plant overrides */
    int32_t n_faults;
    hd_sc_fault_t faults[HD_SC_MAX_FAULTS];       /* sorted by t_s */
} hd_scenario_t;

/* Parse a scenario file.  0 ok, -1 with a one-line "FILE:LINE:COL: ..." in err. */
int hd_scenario_load(const char *path, hd_scenario_t *sc, char *err, size_t errlen);
/* Parse scenario text; base_dir is where relative axis paths start (may be NULL = "."). */
int hd_scenario_parse(const char *text, size_t len, const char *fname, hd_scenario_t *sc,
                      char *err, size_t errlen);

/* Setpoint at time t (s), unit of the mode.  Deterministic (prbs seeded by seed). */
double hd_scenario_setpoint(const hd_sc_setpoint_t *sp, double t, uint64_t seed);

const char *hd_scenario_mode_name(hd_sc_mode_t m);
const char *hd_scenario_fault_name(hd_fault_type_t f);

#endif /* HD_SCENARIO_H */
