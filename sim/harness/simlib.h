/*
 * simlib.h - the C API of build/lib/libhdsim.so, loaded by the Python binding
 * host/hdservo/sim.py through ctypes.  Plain types only (no structs cross
 * the boundary); every function that can fail takes (err, errlen) and writes
 * one line there.  The caller allocates every output array; the C side fills
 * it (no per-sample Python loop).
 */
#ifndef HD_SIMLIB_H
#define HD_SIMLIB_H

#include <stddef.h>
#include <stdint.h>

typedef struct hd_simlib hd_simlib_t;

/* ---- closed loop (scenario) ---- */
hd_simlib_t *hd_simlib_open(const char *scenario_path, char *err, size_t errlen);
/* Override one plant parameter ("section.key", bools as 0/1) before prepare. */
int32_t hd_simlib_set_param(hd_simlib_t *h, const char *key, double value, char *err, size_t errlen);
void hd_simlib_set_seed(hd_simlib_t *h, uint64_t seed);
int32_t hd_simlib_set_duration(hd_simlib_t *h, double duration_s, char *err, size_t errlen);
/* Build the run; returns the number of log rows, or -1. */
int64_t hd_simlib_prepare(hd_simlib_t *h, char *err, size_t errlen);
int32_t hd_simlib_ncol(void);
const char *hd_simlib_column(const hd_simlib_t *h, int32_t col);
/* Run to the end; rows = n_rows x ncol doubles, row-major. 0 ok. */
int32_t hd_simlib_run(hd_simlib_t *h, double *rows, char *err, size_t errlen);
/* The same, column-major: cols = ncol x n_rows doubles, one contiguous column each. 0 ok. */
int32_t hd_simlib_run_columns(hd_simlib_t *h, double *cols, char *err, size_t errlen);
/* Sidecar JSON of the prepared run (valid until close). */
const char *hd_simlib_meta(hd_simlib_t *h);
int32_t hd_simlib_write_log(hd_simlib_t *h, const double *rows, int64_t n_rows, const char *csv_path,
                            char *err, size_t errlen);
/* After run: seconds in hd_app_step and hd_plant_step (timing is on in prepare). */
void hd_simlib_timing(const hd_simlib_t *h, double *app_s, double *plant_s);
void hd_simlib_close(hd_simlib_t *h);

/* ---- plant open loop ---- */
int32_t hd_simlib_ol_ncol(void);
const char *hd_simlib_ol_column(int32_t col);
/* Simulate the plant alone for n periods of dt_s: torque_Nm[i] (motor torque
 * command, through the current loop) and load_Nm[i] (external output torque,
 * may be NULL) applied over [i*dt, (i+1)*dt); out row i = state at (i+1)*dt.
 * axis: "reference", "minimal" or an axis file; keys/values: n_over overrides. */
int32_t hd_simlib_open_loop(const char *axis, const char *const *keys, const double *values, int32_t n_over,
                            uint64_t seed, double dt_s, int64_t n, const double *torque_Nm,
                            const double *load_Nm, double *out, char *err, size_t errlen);

/* A plant stepped by the caller (an outer controller in the caller's language): open,
 * then run n periods of dt_s with torque_Nm[i] (out rows as hd_simlib_open_loop, time
 * continuing from the previous call), then close. */
typedef struct hd_simlib_plant hd_simlib_plant_t;
hd_simlib_plant_t *hd_simlib_plant_open(const char *axis, const char *const *keys, const double *values,
                                        int32_t n_over, uint64_t seed, char *err, size_t errlen);
int32_t hd_simlib_plant_run(hd_simlib_plant_t *h, double dt_s, int64_t n, const double *torque_Nm, double *out,
                            char *err, size_t errlen);
void hd_simlib_plant_close(hd_simlib_plant_t *h);

/* Replay measured inputs over windows, each started from a given state (multiple
 * shooting; the model-discrepancy workflow's simulator check).  Window w covers rows
 * [start[w], start[w+1]) (the last one to n); x0 + 4*w = (theta_m rad, omega_m rad/s,
 * theta_l rad, omega_l rad/s) at row start[w], and the current-loop state starts at
 * torque_Nm[start[w]] / Kt (no start-up transient of a log's steady current).  Row i
 * of out (n x 2: true motor angle, true load angle, rad) is the state at row i;
 * torque_Nm[i] acts over [t_i, t_i + dt_s).  Rows before start[0] and rows of a
 * window whose integration diverged are NaN.  start must increase, 0 <= start < n.
 * xi0 (may be NULL): per window the HD_PLANT_MAX_MAXWELL Maxwell-slip element positions
 * (rad of twist) at its start, i.e. the hysteresis memory the measured twist left there;
 * NULL relaxes the elements at the start twist. */
int32_t hd_simlib_replay_windows(const char *axis, const char *const *keys, const double *values, int32_t n_over,
                                 double dt_s, int64_t n, const double *torque_Nm, int64_t n_win,
                                 const int64_t *start, const double *x0, const double *xi0, double *out,
                                 char *err, size_t errlen);
/* Number of Maxwell-slip elements the plant holds (the row length of xi0). */
int32_t hd_simlib_max_maxwell(void);

/* ---- plant parameter table ---- */
int32_t hd_simlib_param_count(void);
const char *hd_simlib_param_name(int32_t i);
const char *hd_simlib_param_unit(int32_t i);
int32_t hd_simlib_param_type(int32_t i);     /* 0 double, 1 bool, 2 int */
/* Value of a parameter for an axis ("reference", "minimal" or file). 0 ok. */
int32_t hd_simlib_axis_param(const char *axis, const char *name, double *value, char *err, size_t errlen);

#endif /* HD_SIMLIB_H */
