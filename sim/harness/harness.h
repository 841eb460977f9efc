/*
 * harness.h - closed-loop harness: the firmware application (firmware/app,
 * through the host port firmware/port/host) and the plant (sim/plant) in
 * lock-step at the firmware loop period.
 *
 * One period k (scenario time tau_k = k*dt):
 *   1. the plant's sensor sample (end of the previous plant step) is bridged
 *      to integers and latched into the host port;
 *   2. the scenario's reference for tau_k goes to the app's command API;
 *   3. hd_app_step() reads the sample and writes the command;
 *   4. faults due at tau_k are injected into the plant;
 *   5. the plant advances one period (its own RK4 sub-steps) under the
 *      command (zero-order hold) and the scenario's disturbances;
 *   6. every log_decimation-th period, one log row is written: the sample of
 *      step 1, the true plant state at the same instant, the reference and
 *      the command of this period.
 * The plant is powered one period before tau = 0 so that the first sample
 * exists; same scenario, same seed -> bit-identical rows.
 */
#ifndef HD_HARNESS_H
#define HD_HARNESS_H

#include <stddef.h>
#include <stdint.h>

#include "hd_plant.h"
#include "scenario.h"

/* Log columns (SI units, see docs/sim.md). */
enum {
    HD_COL_T = 0,            /* t_s */
    HD_COL_MOTOR_ANGLE,      /* motor_angle_rad: motor encoder, multi-turn */
    HD_COL_LOAD_ANGLE,       /* load_angle_rad: output encoder, multi-turn */
    HD_COL_MOTOR_VEL,        /* motor_velocity_rad_s: true */
    HD_COL_LOAD_VEL,         /* load_velocity_rad_s: true (relative to base) */
    HD_COL_MOTOR_TORQUE,     /* motor_torque_Nm: Kt * actual current */
    HD_COL_MOTOR_CURRENT,    /* motor_current_A: current sensor */
    HD_COL_SETPOINT,         /* setpoint_rad | setpoint_velocity_rad_s | setpoint_torque_Nm */
    HD_COL_TORQUE_CMD,       /* torque_cmd_Nm: motor-shaft command from the app */
    HD_COL_TORSION,          /* torsion_rad: true twist */
    HD_COL_GYRO,             /* gyro_rate_rad_s: gyro sensor */
    HD_COL_MOTOR_TRUE,       /* motor_angle_true_rad */
    HD_COL_LOAD_TRUE,        /* load_angle_true_rad */
    HD_COL_LOAD_VEL_EST,     /* load_velocity_est_rad_s: app's estimate */
    HD_COL_LOAD_DIST,        /* load_disturbance_Nm: external load torque */
    HD_COL_VALID,            /* sensor_valid_code: HD_HAL_VALID_* bits */
    HD_COL_FAULT,            /* fault_code: app fault */
    HD_COL_BASE_TRUE,        /* base_angle_true_rad: base angle in inertial space (true);
                                inertial payload angle = load_angle_true_rad + this */
    HD_SIM_NCOL
};

typedef struct hd_sim hd_sim_t;

/* Column name (depends on the mode only for the setpoint column). */
const char *hd_sim_column_name(int32_t col, int32_t mode);

/* Plant parameters of an axis: "reference", "minimal" or a TOML axis file
 * (starts from the reference defaults, or [axis] defaults = "minimal"; every
 * other key is "section.key" of the plant table). 0 ok, -1 with err. */
int hd_sim_axis_params(const char *axis, hd_plant_params *prm, char *err, size_t errlen);
/* Axis of the scenario plus its [plant] and [disturbance] overrides. */
int hd_sim_scenario_params(const hd_scenario_t *sc, hd_plant_params *prm, char *err, size_t errlen);

/* Create a run (plant + app + port), ready at period 0.  NULL with err. */
hd_sim_t *hd_sim_new(const hd_scenario_t *sc, const hd_plant_params *prm, char *err, size_t errlen);
void hd_sim_free(hd_sim_t *s);

int64_t hd_sim_n_periods(const hd_sim_t *s);
int64_t hd_sim_n_rows(const hd_sim_t *s);
int32_t hd_sim_mode(const hd_sim_t *s);

/* Time the app step and the plant step separately (clock_gettime per step). */
void hd_sim_enable_timing(hd_sim_t *s, int on);
/* Accumulated seconds spent in hd_app_step and hd_plant_step, and periods timed. */
void hd_sim_timing(const hd_sim_t *s, double *app_s, double *plant_s, int64_t *periods);

/* One period; if row != NULL it receives HD_SIM_NCOL values. */
void hd_sim_step(hd_sim_t *s, double *row);
/* -1 with "PATH: the simulation diverged at t = ..." in err once the plant state
 * became non-finite (hd_plant_diverged), else 0.  hd_sim_run checks it every
 * period; callers stepping with hd_sim_step check it themselves. */
int hd_sim_check_diverged(const hd_sim_t *s, char *err, size_t errlen);
/* Run every period, writing hd_sim_n_rows() rows (row-major) into rows. 0 ok. */
int hd_sim_run(hd_sim_t *s, double *rows, char *err, size_t errlen);
/* The same run, column-major: column c of the log is cols[c * n_rows ... (c + 1) * n_rows - 1]
 * (each column contiguous, so a caller can hand it on without a copy). 0 ok. */
int hd_sim_run_columns(hd_sim_t *s, double *cols, char *err, size_t errlen);

/* Sidecar JSON (complete object) into buf; returns its length (truncated if cap small). */
size_t hd_sim_meta_json(const hd_sim_t *s, char *buf, size_t cap);
/* Write rows as CSV + sidecar (temp + rename). 0 ok. */
int hd_sim_write_log(const hd_sim_t *s, const double *rows, int64_t n_rows, const char *csv_path,
                     char *err, size_t errlen);

/* Internals for tests. */
const void *hd_sim_app(const hd_sim_t *s);          /* hd_app_t * */
const hd_plant *hd_sim_plant(const hd_sim_t *s);
uint32_t hd_sim_port_violations(const hd_sim_t *s);

/* Bridge SI <-> firmware formats (round to nearest, saturate). */
int64_t hd_bridge_rad_to_q32_turns(double rad);
double  hd_bridge_q32_turns_to_rad(int64_t q);
int32_t hd_bridge_rad_s_to_vel_out(double rad_s);
double  hd_bridge_vel_out_to_rad_s(int32_t v);
int32_t hd_bridge_to_q16(double x);   /* N.m or A -> Q15.16 */
double  hd_bridge_from_q16(int32_t q);

#endif /* HD_HARNESS_H */
