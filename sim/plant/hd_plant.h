/*
 * hd_plant.h - the simulated harmonic-drive servo axis (double precision).
 *
 * Plain C99 + libm.  No globals, no allocation: everything lives in the
 * hd_plant struct, noise comes from a seeded PRNG inside it, so two runs with
 * the same parameters, seed and inputs are identical to the bit.
 *
 * Coordinates (see docs/plant.md for the equations):
 *   theta_m   motor (wave-generator) angle relative to the housing/base, rad
 *   theta_l   load (output flange) angle relative to the housing/base, rad
 *   theta_b   base angle in inertial space (base rocking), rad
 *   twist     phi = theta_m/N + e_te(theta_m, theta_l) - theta_l   (rad, output side)
 *   transmitted torque T = T_spring(phi) + T_hyst(phi) + c*dphi/dt  (N.m, output side)
 *   J_m*(dd theta_m + dd theta_b) = Kt*i + T_cog - T*(1/N + de_te/dtheta_m) - F_m
 *   J_l*(dd theta_l + dd theta_b) = T - F_l + T_grav + T_ext
 * All parameters are SI, output-referred for the gear and load, motor-referred
 * for the motor, current loop, cogging and motor-side friction.
 *
 * Parameter names for axis files: "<section>.<key>", e.g.
 * "stiffness.k1_Nm_per_rad"; hd_plant_param_set() maps them onto the struct
 * (booleans and integers are passed as doubles: true = 1, false = 0).
 * hd_plant_param_count()/hd_plant_param_at() enumerate every key with its unit.
 *
 * Typical use (harness):
 *   hd_plant_params prm; hd_plant_defaults_reference(&prm);
 *   hd_plant_param_set(&prm, "gravity.enabled", 0.0);
 *   hd_plant p; if (hd_plant_init(&p, &prm, seed, msg, sizeof msg) != 0) ...
 *   for (...) { in.current_cmd_A = ...; const hd_plant_output *o = hd_plant_step(&p, &in, 1e-4); }
 */
#ifndef HD_PLANT_H
#define HD_PLANT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HD_PLANT_MAX_HARM     4   /* harmonics per list (cogging, TE wg, TE output) */
#define HD_PLANT_MAX_MAXWELL  8   /* Maxwell-slip elements */
#define HD_PLANT_PREISACH_L  32   /* Preisach input levels (Everett table L+1 x L+1) */
#define HD_PLANT_PREISACH_STACK 80 /* memory depth (oldest pair merged when full) */
#define HD_PLANT_HT_JMAX 10  /* highest degree of the harmonics' Taylor series (internal) */
#define HD_PLANT_HT_NTAB 58  /* octaves of the series' degree table (internal) */
#define HD_PLANT_POW_MAX (48 * HD_PLANT_MAX_HARM + 1) /* power-chain entries (24 per integer order <= 4096) */

/* Error codes (negative) returned by the functions below. */
#define HD_PLANT_OK        0
#define HD_PLANT_EUNKNOWN (-1)   /* unknown parameter key */
#define HD_PLANT_ETYPE    (-2)   /* bool not 0/1, integer not integral, NaN */
#define HD_PLANT_ERANGE   (-3)   /* value outside the allowed range */
#define HD_PLANT_EINVAL   (-4)   /* inconsistent parameter set (init) */

/* ---- friction (one per side) --------------------------------------------------
 * Static map (Stribeck, direction-asymmetric):
 *   g(v)  = Fc + (Fs - Fc)*exp(-|v/vs|^delta)   with (Fc,Fs) = (*_pos,*_neg) by sign of v
 *   F(v)  = g(v)*sgn(v) + viscous*v
 * LuGre (lugre_enabled): dz/dt = v - sigma0*|v|*z/g(v),
 *   F = sigma0*z + sigma1*dz/dt + viscous*v   (sigma2 == viscous)
 * Without LuGre: static map with stick/slip (Karnopp with a sticking state):
 * at rest the friction holds any torque up to the breakaway Fs. */
typedef struct {
    int    enabled;
    double fc_pos_Nm, fc_neg_Nm;     /* Coulomb level per direction, > 0 */
    double fs_pos_Nm, fs_neg_Nm;     /* static (breakaway) level per direction, >= Fc */
    double vs_rad_s;                 /* Stribeck velocity, > 0 */
    double delta;                    /* Stribeck shape exponent (2 = Gaussian) */
    double viscous_Nms_per_rad;      /* viscous coefficient (= LuGre sigma2) */
    int    lugre_enabled;            /* LuGre presliding dynamics */
    double sigma0_Nm_per_rad;        /* bristle stiffness */
    double sigma1_Nms_per_rad;       /* bristle damping */
    double stick_velocity_rad_s;     /* static model: |v| below this counts as rest */
} hd_plant_friction_params;

typedef struct {
    /* [gear] */
    double ratio;                    /* N, motor turns per output turn, > 0 */

    /* [motor] */
    double jm_kgm2;                  /* rotor + wave generator inertia */
    double kt_Nm_per_A;              /* torque constant */

    /* [current_loop]  i' = (sat(i_cmd) - i)/tau, tau = 1/(2 pi bw) when enabled,
     * i = sat(i_cmd) instantly when disabled; saturation always applies. */
    int    current_loop_enabled;
    double current_bandwidth_Hz;
    double current_peak_A;           /* |i_cmd| clamp, > 0 */

    /* [cogging]  T_cog = sum_k a_k*sin(n_k*theta_m + p_k)  (motor side) */
    int    cogging_enabled;
    double cog_order[HD_PLANT_MAX_HARM];     /* cycles per motor rev (integer >= 0; 0 = unused) */
    double cog_amp_Nm[HD_PLANT_MAX_HARM];
    double cog_phase_rad[HD_PLANT_MAX_HARM];

    /* [transmission_error]  e_te = sum a_k*sin(n_k*theta_m + p_k)   (WG harmonics)
     *                             + sum b_j*sin(m_j*theta_l + q_j)  (output harmonics), rad at the output */
    int    te_enabled;
    double te_wg_order[HD_PLANT_MAX_HARM];    /* cycles per WG rev (integer >= 0; 0 = unused) */
    double te_wg_amp_rad[HD_PLANT_MAX_HARM];
    double te_wg_phase_rad[HD_PLANT_MAX_HARM];
    double te_out_order[HD_PLANT_MAX_HARM];   /* cycles per output rev */
    double te_out_amp_rad[HD_PLANT_MAX_HARM];
    double te_out_phase_rad[HD_PLANT_MAX_HARM];

    /* [stiffness]  three-slope, sum-of-saturations form (harmonic-drive.md 5.1):
     * T = K3*phi + (K1-K2)*sat_phi1(phi) + (K2-K3)*sat_phi2(phi), phi1 = T1/K1, phi2 = phi1+(T2-T1)/K2
     * plus linear damping c*dphi/dt (c applies whenever stiffness or cubic is on). */
    int    stiffness_enabled;
    double k1_Nm_per_rad, k2_Nm_per_rad, k3_Nm_per_rad;
    double t1_Nm, t2_Nm;
    double damping_Nms_per_rad;

    /* [stiffness_cubic]  T += k1*phi + k3*phi^3   (adds to the three-slope if both are on) */
    int    cubic_enabled;
    double cubic_k1_Nm_per_rad;
    double cubic_k3_Nm_per_rad3;

    /* [hysteresis_maxwell]  T_h = sum_i clamp(k_i*(phi - xi_i), +-w_i), elements slip at w_i.
     * Torque cycles beyond every element's slip: hysteresis loss (width at zero
     * torque, K1 region) = 2*sum(w_i)/K1. */
    int    maxwell_enabled;
    int    maxwell_n;                              /* elements used, 0..HD_PLANT_MAX_MAXWELL */
    double maxwell_k_Nm_per_rad[HD_PLANT_MAX_MAXWELL];
    double maxwell_w_Nm[HD_PLANT_MAX_MAXWELL];     /* slip torque of each element */

    /* [hysteresis_preisach]  T_h = (t_sat/u_max)*sat(phi, u_max) - P[phi], P = classical
     * Preisach operator (relays on -u_max <= beta <= alpha <= u_max, density
     * mu ~ exp(-r/r0)*exp(-m^2/(2 s^2)), r = (alpha-beta)/2, m = (alpha+beta)/2, P = +-t_sat
     * at saturation).  A relay output lags its input, so P alone would generate energy
     * as a torque; k*u - P[u] (stop = identity - play) dissipates and adds no net torque
     * beyond +-u_max.  The loop width follows from the Everett table (docs/plant.md). */
    int    preisach_enabled;
    double preisach_u_max_rad;        /* input (twist) range; clamped beyond */
    double preisach_t_sat_Nm;         /* output at positive saturation */
    double preisach_r0_rad;           /* relay half-width scale */
    double preisach_s_rad;            /* relay centre spread */

    /* [friction_motor], [friction_load] */
    hd_plant_friction_params fric_m;  /* motor side, N.m and rad/s at the motor */
    hd_plant_friction_params fric_l;  /* output bearing side, N.m and rad/s at the output */

    /* [friction_drift]  both friction sides (levels Fc, Fs and the viscous term) scaled by
     * s(t) = 1 + (scale - 1) * clamp((t - t_start_s) / ramp_s, 0, 1): warm-up or wear
     * during a run, for the online identification (docs/sim.md).  Applied once per
     * control period to the values the plant was initialised with. */
    int    drift_enabled;
    double drift_t_start_s;           /* ramp start, s of simulated time */
    double drift_ramp_s;              /* ramp duration, s (> 0) */
    double drift_scale;               /* friction scale at the end of the ramp */
    double drift_hold_s;              /* time at the full scale before the return leg, s */
    double drift_return_s;            /* return ramp back to 1 (cold -> warm -> cold), s; 0: none */

    /* [inertia_drift], [stiffness_drift], [gravity_drift]  parameter drifts during a run
     * (payload change, compliance loss, unbalance appearing), each with the same ramp
     * w(t) = clamp((t - t_start_s) / ramp_s, 0, 1) (a short ramp_s is a step):
     *   J_l(t) = J_l * (1 + (scale - 1) w)             load inertia
     *   K(t)   = K * (1 + (scale - 1) w)               three-slope and cubic stiffness
     *                                                  (slopes and breakpoint torques, so
     *                                                  the breakpoint twists stay)
     *   mgl(t) = mgl0 + (mgl_Nm - mgl0) w              mgl0 = gravity.mgl_Nm (0 if off)
     * Applied once per control period from the values the plant was initialised with. */
    int    jdrift_enabled;
    double jdrift_t_start_s;
    double jdrift_ramp_s;
    double jdrift_scale;              /* load inertia scale at the end of the ramp */
    int    kdrift_enabled;
    double kdrift_t_start_s;
    double kdrift_ramp_s;
    double kdrift_scale;              /* stiffness scale at the end of the ramp */
    int    gdrift_enabled;
    double gdrift_t_start_s;
    double gdrift_ramp_s;
    double gdrift_mgl_Nm;             /* unbalance m*g*l at the end of the ramp */

    /* [load] */
    double jl_kgm2;                   /* load (payload + flange) inertia */

    /* [gravity]  T_grav = -mgl*cos(theta_l + theta_b + offset) (pitch axis) */
    int    gravity_enabled;
    double mgl_Nm;
    double gravity_offset_rad;

    /* [base]  internal base rocking theta_b = a*sin(2 pi f t + p) (added to the input) */
    int    base_enabled;
    double base_amp_rad;
    double base_freq_Hz;
    double base_phase_rad;

    /* [encoder_motor], [encoder_load]  raw = floor((theta/2pi + offset_turn)*2^bits + noise) */
    int    enc_m_enabled;             /* off: no noise (quantisation always applies) */
    int    enc_m_bits;                /* 1..31 */
    double enc_m_noise_counts;        /* std of additive noise, counts */
    double enc_m_offset_turn;
    int    enc_l_enabled;
    int    enc_l_bits;
    double enc_l_noise_counts;
    double enc_l_offset_turn;

    /* [gyro]  payload rate gyro: inertial rate theta_l' + theta_b' + bias + white noise
     * (noise density = angle random walk) through a first-order low-pass */
    int    gyro_enabled;              /* off: exact inertial rate */
    double gyro_noise_rad_s_per_rtHz;
    double gyro_bandwidth_Hz;
    double gyro_bias_rad_s;

    /* [current_sensor] */
    int    isense_enabled;            /* off: exact current */
    double isense_noise_A;            /* std per sample */
    double isense_offset_A;

    /* [integrator] */
    int    substeps;                  /* fixed RK4 sub-steps per hd_plant_step call, 1..64 */
} hd_plant_params;

/* Runtime inputs for one control period. */
typedef struct {
    double current_cmd_A;             /* q-axis current command */
    double torque_cmd_Nm;             /* alternative: adds torque_cmd/Kt to the current command */
    double load_torque_Nm;            /* external torque on the output (disturbance) */
    double base_rate_rad_s;           /* external base motion (added to the internal generator) */
    double base_accel_rad_s2;
} hd_plant_input;

/* Sensors and true states after one step. */
typedef struct {
    double   t_s;                     /* plant time at the end of the step */
    /* sensors */
    uint32_t enc_motor_raw;           /* single-turn count, 0..2^bits-1 */
    int64_t  enc_motor_count;         /* multi-turn count (unwrapped) */
    int      enc_motor_valid;         /* 0 during a dropout fault (counts frozen) */
    uint32_t enc_load_raw;
    int64_t  enc_load_count;
    int      enc_load_valid;
    double   current_meas_A;
    double   gyro_rad_s;              /* inertial payload rate */
    /* true states (for logging) */
    double   motor_angle_rad, motor_velocity_rad_s;
    double   load_angle_rad, load_velocity_rad_s;       /* relative to the base */
    double   base_angle_rad, base_rate_rad_s;
    double   load_inertial_rate_rad_s;
    double   current_A;               /* actual current after loop lag and saturation */
    double   motor_torque_Nm;         /* Kt*i */
    double   twist_rad;               /* phi */
    double   te_rad;                  /* kinematic transmission error e_te */
    double   transmitted_torque_Nm;   /* T (output side) */
    double   hysteresis_torque_Nm;    /* part of T from Maxwell-slip + Preisach */
    double   friction_motor_Nm;       /* F_m (motor side, opposes motion) */
    double   friction_load_Nm;        /* F_l (output side) */
    double   cogging_torque_Nm;
    double   gravity_torque_Nm;
    int      current_saturated;       /* command clamped this step */
    int      brake_engaged;
} hd_plant_output;

/* Fault injection (all cleared by hd_plant_init). */
typedef enum { HD_PLANT_ENC_MOTOR = 0, HD_PLANT_ENC_LOAD = 1 } hd_plant_encoder_id;
typedef struct {
    int64_t  glitch_counts[2];        /* added to the next sample only */
    uint32_t dropout_steps[2];        /* samples left with frozen count and valid = 0 */
    double   current_limit_A;         /* < 0: none; else extra clamp of |i_cmd| */
    double   load_step_Nm;            /* persistent extra load torque */
} hd_plant_faults;

/* Preisach memory: stacks of alternating dominant extrema (u, y). */
typedef struct {
    double   min_u[HD_PLANT_PREISACH_STACK], min_y[HD_PLANT_PREISACH_STACK];
    double   max_u[HD_PLANT_PREISACH_STACK], max_y[HD_PLANT_PREISACH_STACK];
    int32_t  n_min, n_max;            /* stack depths (>= 1, bottoms are sentinels) */
    int32_t  dir;                     /* +1 ascending, -1 descending */
    double   u_prev, y;
    double   inv_du;                  /* L / (2 u_max): grid cells per rad (set by the reset) */
} hd_plant_preisach_state;

typedef struct {
    hd_plant_params prm;              /* copy, with derived values below */
    /* derived */
    double   phi1, phi2;              /* three-slope breakpoints */
    double   tau_i;                   /* current-loop time constant */
    double   inv_ratio;               /* 1/N */
    double   inv_jm, inv_jl;          /* 1/J of the motor and load sides (stages multiply) */
    double   mx_slip[HD_PLANT_MAX_MAXWELL]; /* w/k: deflection at which a Maxwell-slip element slips */
    double   harm_cp[3][HD_PLANT_MAX_HARM], harm_sp[3][HD_PLANT_MAX_HARM]; /* cos/sin of phases */
    int32_t  harm_int[3][HD_PLANT_MAX_HARM];  /* integer order: evaluated by powers of one sincos */
    int32_t  has_te_out;
    double   preisach_kp;             /* t_sat/u_max */
    double   preisach_pm[HD_PLANT_PREISACH_L + 1]; /* major-loop centre line at the grid nodes */
    double   preisach_inv_du;         /* L/(2 u_max) */
    double   everett[(HD_PLANT_PREISACH_L + 1) * (HD_PLANT_PREISACH_L + 1)];
    /* continuous state */
    double   t;                       /* s */
    double   th_m, w_m, th_l, w_l;    /* rad, rad/s (relative to base) */
    double   i;                       /* A */
    double   z_m, z_l;                /* LuGre bristle deflections, rad */
    int32_t  stuck_m, stuck_l;        /* static-friction sticking flags */
    double   xi[HD_PLANT_MAX_MAXWELL];/* Maxwell-slip element positions, rad */
    hd_plant_preisach_state pz;
    double   base_ext_angle;          /* integral of the external base rate */
    double   gyro_f;                  /* gyro low-pass state */
    /* runtime switches */
    int32_t  brake;
    hd_plant_faults faults;
    /* PRNG (xoshiro256**) */
    uint64_t rng[4];
    /* encoder hold values for dropouts */
    int64_t  enc_last[2];
    hd_plant_output out;
    int32_t  diverged;                /* the state became non-finite (hd_plant_diverged) */
    /* ---- internal caches of hd_plant.c (derived at init or memoised; no API) ---- */
    double   zig_x[129], zig_r[128];  /* Gaussian ziggurat tables (128 layers) */
    int32_t  hn[3], hn_int[3];        /* active harmonics per list (cogging, TE wg, TE out), integer-order ones */
    int32_t  h_libm;                  /* some active order is not an integer */
    int32_t  hidx[3][HD_PLANT_MAX_HARM];      /* power-chain entry of each harmonic (-1: libm) */
    int32_t  pw_n[2], pw_a[2][HD_PLANT_POW_MAX], pw_b[2][HD_PLANT_POW_MAX]; /* chains: theta_m, theta_l */
    uint32_t pw_ord[2][HD_PLANT_POW_MAX];
    double   hfo[3][HD_PLANT_MAX_HARM], hamp[3][HD_PLANT_MAX_HARM], hampn[3][HD_PLANT_MAX_HARM];
    double   hc0[3][HD_PLANT_MAX_HARM], hs0[3][HD_PLANT_MAX_HARM]; /* cos/sin(n theta + phase) of each integer-
                                                                     order harmonic at the anchor angle ha_th */
    double   hmax[2];                 /* largest integer order on chain 0 (theta_m) and 1 (theta_l) */
    int32_t  h_rot_ok;                /* 1: harmonics by Taylor series about an anchor (tests set 0: power chain) */
    double   ha_th[2];                /* anchor angles of the series: theta_m (chain 0), theta_l (chain 1) */
    int32_t  ha_valid, ha_n;          /* anchor set; re-anchorings by rotation since the last libm seed */
    int32_t  ht_deg[2];               /* highest degree whose coefficients are formed, per chain (-1: none) */
    double   ht_xb[HD_PLANT_HT_JMAX + 1];  /* radius of degree J in n_max |d| */
    int32_t  ht_jtab[HD_PLANT_HT_NTAB];    /* degree by the binary exponent of n_max |d| */
    double   ht_w[3][HD_PLANT_MAX_HARM][HD_PLANT_HT_JMAX + 2];  /* signed a n^j / j! per harmonic */
    double   ht_e[3][HD_PLANT_HT_JMAX + 2], ht_d[3][HD_PLANT_HT_JMAX + 1]; /* series of the sums, derivatives */
    double   hcp[3][HD_PLANT_MAX_HARM], hsp[3][HD_PLANT_MAX_HARM], hph[3][HD_PLANT_MAX_HARM];
    double   k_dt, k_h, k_inv_h, k_E, k_Efac, k_gyro_a, k_gyro_sd, k_rot_c, k_rot_s, k_rot2_c, k_rot2_s; /* per-dt */
    double   enc_scale[2];
    double   fr_v[2], fr_g[2], fr_ig[2]; /* last Stribeck level g(v) per side, 1/g */
    double   fr_ya[2], fr_ea[2];      /* Stribeck exponential anchor: y, exp(-y) from libm */
    double   fr_inv_vs[2];            /* 1/vs per side */
    double   fr_fc[2][2], fr_dfs[2][2]; /* [side][v < 0]: Fc, Fs - Fc */
    hd_plant_friction_params fr_base[2]; /* friction as initialised (the drift scales it) */
    double   fr_scale;                /* friction scale in force ([friction_drift]) */
    double   pd_jl, pd_k[5], pd_cubic[2], pd_mgl; /* inertia, stiffness (k1 k2 k3 t1 t2), cubic
                                                    (k1 k3), mgl as initialised (drifts scale them) */
    double   pd_w[3];                 /* last ramp weight of each drift (inertia, stiffness, gravity) */
    double   pd_ks;                   /* stiffness scale in force ([stiffness_drift]) */
    int32_t  end_valid;               /* end-of-sub-step evaluation below is current */
    double   end_th_m, end_th_l, end_phi, end_te, end_de_m, end_de_l, end_Tsh, end_Th, end_Tcog;
    double   end_cm, end_sm, end_cl, end_sl;
    int32_t  hy_lin_ok;               /* 1: stages take the hysteresis torque from its linear piece
                                         (tests set 0: the operators evaluated at every stage) */
    int32_t  hy_ok[2];                /* the piece below is formed for the last end evaluation */
    int64_t  n_hy_lin;                /* stages that took the hysteresis torque from the piece (tests) */
    double   hy_s[2], hy_b[2];        /* from the end evaluation's twist, up [0] / down [1]: slope of the
                                         hysteresis torque (N.m/rad) and the twist up to which it holds */
    int32_t  trig_n;                  /* end evaluations since cos/sin came from libm */
    int64_t  n_end_eval;              /* end evaluations so far (tests count the work an option costs) */
    int32_t  k1_valid, k1_ok, k1_brake;  /* end-of-period evaluation reusable as the next first stage */
    double   k1_rest_m, k1_rest_l, k1_gf, k1_Fm, k1_Fl, k1_w_m, k1_w_l;
    double   base_t, base_h, base_c, base_s, grav_a, grav_c, grav_s; /* base-generator / gravity phase */
} hd_plant;

/* Fill every field with the reference axis of DESIGN.md section 2 (all effects on). */
void hd_plant_defaults_reference(hd_plant_params *prm);
/* Same struct with every effect off (rigid-free two-mass, linear K1 spring, ideal sensors). */
void hd_plant_defaults_minimal(hd_plant_params *prm);

/* Validate params; on error returns HD_PLANT_EINVAL and writes one line into msg. */
int hd_plant_check(const hd_plant_params *prm, char *msg, size_t msg_len);

/* Copy params, validate, precompute tables, reset state (axis at rest, zero twist,
 * brake off, faults cleared), seed the PRNG.  Returns 0 or HD_PLANT_EINVAL (msg set). */
int hd_plant_init(hd_plant *p, const hd_plant_params *prm, uint64_t seed, char *msg, size_t msg_len);

/* Advance one control period dt_s (> 0) with prm.substeps fixed RK4 sub-steps;
 * sensors are sampled at the end of the period.  Returns &p->out. */
const hd_plant_output *hd_plant_step(hd_plant *p, const hd_plant_input *in, double dt_s);

/* 1 once a step left the state non-finite (the parameters or the inputs made the
 * integration diverge).  From then on hd_plant_step returns the diverged output
 * unchanged; hd_plant_init clears it. */
int hd_plant_diverged(const hd_plant *p);

/* Set the initial/current mechanical state (e.g. a pre-twisted axis); angles in rad. */
void hd_plant_set_state(hd_plant *p, double th_m, double w_m, double th_l, double w_l);

/* Total mechanical energy (kinetic + spring + cogging + gravity potentials), J.
 * Conservative parts only; meaningful for tests with dissipation off and no base motion. */
double hd_plant_energy(const hd_plant *p);

/* Runtime switches and fault injection. */
void hd_plant_set_brake(hd_plant *p, int engaged);                   /* output lock */
void hd_plant_fault_encoder_glitch(hd_plant *p, hd_plant_encoder_id e, int64_t counts);
void hd_plant_fault_encoder_dropout(hd_plant *p, hd_plant_encoder_id e, uint32_t steps);
void hd_plant_fault_current_limit(hd_plant *p, double limit_A);       /* < 0 removes */
void hd_plant_fault_load_step(hd_plant *p, double torque_Nm);         /* 0 removes */

/* ---- parameter table (name -> field) ----------------------------------------- */
typedef enum { HD_PARAM_DOUBLE = 0, HD_PARAM_BOOL = 1, HD_PARAM_INT = 2 } hd_param_type;
typedef struct {
    const char   *name;               /* "section.key" */
    size_t        offset;             /* into hd_plant_params */
    hd_param_type type;
    double        min, max;           /* allowed closed range */
    const char   *unit;               /* SI unit ("" for dimensionless, "bool") */
    const char   *help;
} hd_plant_param_desc;

size_t hd_plant_param_count(void);
const hd_plant_param_desc *hd_plant_param_at(size_t i);      /* NULL past the end */
const hd_plant_param_desc *hd_plant_param_find(const char *name);
/* Returns HD_PLANT_OK, HD_PLANT_EUNKNOWN, HD_PLANT_ETYPE or HD_PLANT_ERANGE. */
int hd_plant_param_set(hd_plant_params *prm, const char *name, double value);
int hd_plant_param_get(const hd_plant_params *prm, const char *name, double *value);
const char *hd_plant_strerror(int code);

#ifdef __cplusplus
}
#endif
#endif /* HD_PLANT_H */
