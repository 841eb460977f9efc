/*
 * hd_plant_params.c - parameter defaults, validation and the name -> field
 * table used by axis files ("section.key" = value, SI units in the key).
 */
#include "hd_plant.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define P hd_plant_params
#define BIG 1e30

#define D(nm, fld, lo, hi, unit, help) { nm, offsetof(P, fld), HD_PARAM_DOUBLE, lo, hi, unit, help }
#define B(nm, fld, help)               { nm, offsetof(P, fld), HD_PARAM_BOOL, 0.0, 1.0, "bool", help }
#define I(nm, fld, lo, hi, help)       { nm, offsetof(P, fld), HD_PARAM_INT, lo, hi, "", help }

#define COG(i) \
    D("cogging.h" #i "_order", cog_order[i - 1], 0.0, 1e4, "1/rev", "cycles per motor revolution (0 = unused)"), \
    D("cogging.h" #i "_amp_Nm", cog_amp_Nm[i - 1], -BIG, BIG, "N.m", "amplitude at the motor"), \
    D("cogging.h" #i "_phase_rad", cog_phase_rad[i - 1], -BIG, BIG, "rad", "phase")
#define TEW(i) \
    D("transmission_error.wg" #i "_order", te_wg_order[i - 1], 0.0, 1e4, "1/rev", "cycles per wave-generator revolution (0 = unused)"), \
    D("transmission_error.wg" #i "_amp_rad", te_wg_amp_rad[i - 1], -BIG, BIG, "rad", "amplitude at the output"), \
    D("transmission_error.wg" #i "_phase_rad", te_wg_phase_rad[i - 1], -BIG, BIG, "rad", "phase")
#define TEO(i) \
    D("transmission_error.out" #i "_order", te_out_order[i - 1], 0.0, 1e4, "1/rev", "cycles per output revolution (0 = unused)"), \
    D("transmission_error.out" #i "_amp_rad", te_out_amp_rad[i - 1], -BIG, BIG, "rad", "amplitude at the output"), \
    D("transmission_error.out" #i "_phase_rad", te_out_phase_rad[i - 1], -BIG, BIG, "rad", "phase")
#define MXW(i) \
    D("hysteresis_maxwell.e" #i "_k_Nm_per_rad", maxwell_k_Nm_per_rad[i - 1], 0.0, BIG, "N.m/rad", "element stiffness"), \
    D("hysteresis_maxwell.e" #i "_w_Nm", maxwell_w_Nm[i - 1], 0.0, BIG, "N.m", "element slip torque")
#define FRIC(sec, f, vunit) \
    B(sec ".enabled", f.enabled, "friction on this side"), \
    D(sec ".fc_pos_Nm", f.fc_pos_Nm, 0.0, BIG, "N.m", "Coulomb level, positive direction"), \
    D(sec ".fc_neg_Nm", f.fc_neg_Nm, 0.0, BIG, "N.m", "Coulomb level, negative direction"), \
    D(sec ".fs_pos_Nm", f.fs_pos_Nm, 0.0, BIG, "N.m", "breakaway (static) level, positive direction"), \
    D(sec ".fs_neg_Nm", f.fs_neg_Nm, 0.0, BIG, "N.m", "breakaway (static) level, negative direction"), \
    D(sec ".vs_rad_s", f.vs_rad_s, 1e-12, BIG, "rad/s", "Stribeck velocity"), \
    D(sec ".delta", f.delta, 0.1, 10.0, "", "Stribeck shape exponent"), \
    D(sec ".viscous_Nms_per_rad", f.viscous_Nms_per_rad, 0.0, BIG, "N.m.s/rad", "viscous coefficient (LuGre sigma2)"), \
    B(sec ".lugre_enabled", f.lugre_enabled, "LuGre presliding dynamics (else static map + stick/slip)"), \
    D(sec ".sigma0_Nm_per_rad", f.sigma0_Nm_per_rad, 1e-9, BIG, "N.m/rad", "LuGre bristle stiffness"), \
    D(sec ".sigma1_Nms_per_rad", f.sigma1_Nms_per_rad, 0.0, BIG, "N.m.s/rad", "LuGre bristle damping"), \
    D(sec ".stick_velocity_rad_s", f.stick_velocity_rad_s, 0.0, BIG, vunit, "static model: rest threshold")

static const hd_plant_param_desc k_table[] = {
    D("gear.ratio", ratio, 1e-6, 1e6, "", "gear ratio N (motor turns per output turn)"),
    D("motor.jm_kgm2", jm_kgm2, 1e-12, BIG, "kg.m^2", "rotor + wave-generator inertia"),
    D("motor.kt_Nm_per_A", kt_Nm_per_A, 1e-9, BIG, "N.m/A", "torque constant"),
    B("current_loop.enabled", current_loop_enabled, "first-order current-loop lag"),
    D("current_loop.bandwidth_Hz", current_bandwidth_Hz, 1e-3, 1e7, "Hz", "current-loop bandwidth"),
    D("current_loop.peak_A", current_peak_A, 1e-9, BIG, "A", "peak current (command clamp)"),
    B("cogging.enabled", cogging_enabled, "cogging / torque ripple (motor-angle harmonics)"),
    COG(1), COG(2), COG(3), COG(4),
    B("transmission_error.enabled", te_enabled, "kinematic transmission error"),
    TEW(1), TEW(2), TEW(3), TEW(4),
    TEO(1), TEO(2), TEO(3), TEO(4),
    B("stiffness.enabled", stiffness_enabled, "three-slope torsional stiffness"),
    D("stiffness.k1_Nm_per_rad", k1_Nm_per_rad, 0.0, BIG, "N.m/rad", "stiffness below T1"),
    D("stiffness.k2_Nm_per_rad", k2_Nm_per_rad, 0.0, BIG, "N.m/rad", "stiffness between T1 and T2"),
    D("stiffness.k3_Nm_per_rad", k3_Nm_per_rad, 0.0, BIG, "N.m/rad", "stiffness above T2"),
    D("stiffness.t1_Nm", t1_Nm, 0.0, BIG, "N.m", "first breakpoint torque"),
    D("stiffness.t2_Nm", t2_Nm, 0.0, BIG, "N.m", "second breakpoint torque"),
    D("stiffness.damping_Nms_per_rad", damping_Nms_per_rad, 0.0, BIG, "N.m.s/rad", "torsional damping"),
    B("stiffness_cubic.enabled", cubic_enabled, "cubic stiffness k1*phi + k3*phi^3 (adds)"),
    D("stiffness_cubic.k1_Nm_per_rad", cubic_k1_Nm_per_rad, 0.0, BIG, "N.m/rad", "linear term"),
    D("stiffness_cubic.k3_Nm_per_rad3", cubic_k3_Nm_per_rad3, 0.0, BIG, "N.m/rad^3", "cubic term"),
    B("hysteresis_maxwell.enabled", maxwell_enabled, "Maxwell-slip torsional hysteresis"),
    I("hysteresis_maxwell.n_elements", maxwell_n, 0.0, (double)HD_PLANT_MAX_MAXWELL, "elements used"),
    MXW(1), MXW(2), MXW(3), MXW(4), MXW(5), MXW(6), MXW(7), MXW(8),
    B("hysteresis_preisach.enabled", preisach_enabled, "Preisach torsional hysteresis"),
    D("hysteresis_preisach.u_max_rad", preisach_u_max_rad, 1e-12, BIG, "rad", "twist range of the relay plane"),
    D("hysteresis_preisach.t_sat_Nm", preisach_t_sat_Nm, 0.0, BIG, "N.m", "output at saturation"),
    D("hysteresis_preisach.r0_rad", preisach_r0_rad, 1e-12, BIG, "rad", "relay half-width scale"),
    D("hysteresis_preisach.s_rad", preisach_s_rad, 1e-12, BIG, "rad", "relay centre spread"),
    FRIC("friction_motor", fric_m, "rad/s"),
    FRIC("friction_load", fric_l, "rad/s"),
    B("friction_drift.enabled", drift_enabled, "friction scaled by a ramp over time (both sides)"),
    D("friction_drift.t_start_s", drift_t_start_s, 0.0, BIG, "s", "ramp start (simulated time)"),
    D("friction_drift.ramp_s", drift_ramp_s, 1e-6, BIG, "s", "ramp duration"),
    D("friction_drift.scale", drift_scale, 0.0, 100.0, "", "friction scale at the end of the ramp (1 = none)"),
    D("friction_drift.hold_s", drift_hold_s, 0.0, BIG, "s", "time at the full scale before the return leg"),
    D("friction_drift.return_s", drift_return_s, 0.0, BIG, "s", "return ramp back to 1 after the hold (0 = no return)"),
    B("inertia_drift.enabled", jdrift_enabled, "load inertia scaled by a ramp over time (payload change)"),
    D("inertia_drift.t_start_s", jdrift_t_start_s, 0.0, BIG, "s", "ramp start (simulated time)"),
    D("inertia_drift.ramp_s", jdrift_ramp_s, 1e-6, BIG, "s", "ramp duration (short: a step)"),
    D("inertia_drift.scale", jdrift_scale, 1e-3, 1000.0, "", "load inertia scale at the end of the ramp"),
    B("stiffness_drift.enabled", kdrift_enabled, "stiffness scaled by a ramp over time"),
    D("stiffness_drift.t_start_s", kdrift_t_start_s, 0.0, BIG, "s", "ramp start (simulated time)"),
    D("stiffness_drift.ramp_s", kdrift_ramp_s, 1e-6, BIG, "s", "ramp duration"),
    D("stiffness_drift.scale", kdrift_scale, 1e-3, 100.0, "", "stiffness scale at the end of the ramp"),
    B("gravity_drift.enabled", gdrift_enabled, "gravity unbalance ramping to a new m*g*l"),
    D("gravity_drift.t_start_s", gdrift_t_start_s, 0.0, BIG, "s", "ramp start (simulated time)"),
    D("gravity_drift.ramp_s", gdrift_ramp_s, 1e-6, BIG, "s", "ramp duration"),
    D("gravity_drift.mgl_Nm", gdrift_mgl_Nm, -BIG, BIG, "N.m", "unbalance m*g*l at the end of the ramp"),
    D("load.jl_kgm2", jl_kgm2, 1e-12, BIG, "kg.m^2", "load inertia"),
    B("gravity.enabled", gravity_enabled, "gravity unbalance"),
    D("gravity.mgl_Nm", mgl_Nm, -BIG, BIG, "N.m", "unbalance m*g*l"),
    D("gravity.offset_rad", gravity_offset_rad, -BIG, BIG, "rad", "angle offset of the unbalance"),
    B("base.enabled", base_enabled, "internal sinusoidal base rocking"),
    D("base.amplitude_rad", base_amp_rad, -BIG, BIG, "rad", "rocking amplitude"),
    D("base.frequency_Hz", base_freq_Hz, 0.0, 1e6, "Hz", "rocking frequency"),
    D("base.phase_rad", base_phase_rad, -BIG, BIG, "rad", "rocking phase"),
    B("encoder_motor.enabled", enc_m_enabled, "motor encoder noise (quantisation always applies)"),
    I("encoder_motor.bits", enc_m_bits, 1.0, 31.0, "resolution, bits per motor revolution"),
    D("encoder_motor.noise_counts", enc_m_noise_counts, 0.0, BIG, "count", "noise standard deviation"),
    D("encoder_motor.offset_turn", enc_m_offset_turn, -BIG, BIG, "turn", "zero offset"),
    B("encoder_load.enabled", enc_l_enabled, "output encoder noise (quantisation always applies)"),
    I("encoder_load.bits", enc_l_bits, 1.0, 31.0, "resolution, bits per output revolution"),
    D("encoder_load.noise_counts", enc_l_noise_counts, 0.0, BIG, "count", "noise standard deviation"),
    D("encoder_load.offset_turn", enc_l_offset_turn, -BIG, BIG, "turn", "zero offset"),
    B("gyro.enabled", gyro_enabled, "payload rate gyro imperfections"),
    D("gyro.noise_rad_s_per_rtHz", gyro_noise_rad_s_per_rtHz, 0.0, BIG, "rad/s/sqrt(Hz)", "rate noise density (angle random walk)"),
    D("gyro.bandwidth_Hz", gyro_bandwidth_Hz, 1e-3, 1e7, "Hz", "first-order bandwidth"),
    D("gyro.bias_rad_s", gyro_bias_rad_s, -BIG, BIG, "rad/s", "constant bias"),
    B("current_sensor.enabled", isense_enabled, "current sensor noise and offset"),
    D("current_sensor.noise_A", isense_noise_A, 0.0, BIG, "A", "noise standard deviation per sample"),
    D("current_sensor.offset_A", isense_offset_A, -BIG, BIG, "A", "offset"),
    I("integrator.substeps", substeps, 1.0, 64.0, "RK4 sub-steps per control period"),
};

size_t hd_plant_param_count(void)
{
    return sizeof k_table / sizeof k_table[0];
}

const hd_plant_param_desc *hd_plant_param_at(size_t i)
{
    return i < hd_plant_param_count() ? &k_table[i] : NULL;
}

const hd_plant_param_desc *hd_plant_param_find(const char *name)
{
    size_t i;
    if (name == NULL) return NULL;
    for (i = 0; i < hd_plant_param_count(); i++)
        if (strcmp(k_table[i].name, name) == 0) return &k_table[i];
    return NULL;
}

int hd_plant_param_set(hd_plant_params *prm, const char *name, double value)
{
    const hd_plant_param_desc *d = hd_plant_param_find(name);
    unsigned char *base = (unsigned char *)prm;
    if (d == NULL) return HD_PLANT_EUNKNOWN;
    if (isnan(value)) return HD_PLANT_ETYPE;
    if (d->type != HD_PARAM_DOUBLE && value != floor(value)) return HD_PLANT_ETYPE;
    if (value < d->min || value > d->max) return d->type == HD_PARAM_BOOL ? HD_PLANT_ETYPE : HD_PLANT_ERANGE;
    if (d->type == HD_PARAM_DOUBLE) {
        double v = value;
        memcpy(base + d->offset, &v, sizeof v);
    } else {
        int v = (int)value;
        memcpy(base + d->offset, &v, sizeof v);
    }
    return HD_PLANT_OK;
}

int hd_plant_param_get(const hd_plant_params *prm, const char *name, double *value)
{
    const hd_plant_param_desc *d = hd_plant_param_find(name);
    const unsigned char *base = (const unsigned char *)prm;
    if (d == NULL) return HD_PLANT_EUNKNOWN;
    if (d->type == HD_PARAM_DOUBLE) {
        double v;
        memcpy(&v, base + d->offset, sizeof v);
        *value = v;
    } else {
        int v;
        memcpy(&v, base + d->offset, sizeof v);
        *value = (double)v;
    }
    return HD_PLANT_OK;
}

const char *hd_plant_strerror(int code)
{
    switch (code) {
    case HD_PLANT_OK: return "ok";
    case HD_PLANT_EUNKNOWN: return "unknown parameter key";
    case HD_PLANT_ETYPE: return "wrong type (expected a boolean, an integer or a number)";
    case HD_PLANT_ERANGE: return "value out of range";
    case HD_PLANT_EINVAL: return "inconsistent parameter set";
    default: return "unknown error";
    }
}

static void friction_defaults(hd_plant_friction_params *f, double fs, double fc, double asym,
                              double vs, double visc, double sigma0, double sigma1, double vstick)
{
    f->enabled = 1;
    f->fs_pos_Nm = fs;
    f->fs_neg_Nm = fs * (1.0 - asym);
    f->fc_pos_Nm = fc;
    f->fc_neg_Nm = fc * (1.0 - asym);
    f->vs_rad_s = vs;
    f->delta = 2.0;
    f->viscous_Nms_per_rad = visc;
    f->lugre_enabled = 1;
    f->sigma0_Nm_per_rad = sigma0;
    f->sigma1_Nms_per_rad = sigma1;
    f->stick_velocity_rad_s = vstick;
}

void hd_plant_defaults_reference(hd_plant_params *prm)
{
    const double arcmin = 2.908882086657216e-4; /* rad */
    const double k1 = 3.1e4;
    int i;
    memset(prm, 0, sizeof *prm);
    prm->ratio = 100.0;
    prm->jm_kgm2 = 8e-5;
    prm->kt_Nm_per_A = 0.1;
    prm->current_loop_enabled = 1;
    prm->current_bandwidth_Hz = 2000.0;
    prm->current_peak_A = 20.0;

    /* cogging: 36 and 72 per motor rev (e.g. 12 slots / 18 poles), ~0.6 % of rated motor torque */
    prm->cogging_enabled = 1;
    prm->cog_order[0] = 36.0; prm->cog_amp_Nm[0] = 4e-3; prm->cog_phase_rad[0] = 0.3;
    prm->cog_order[1] = 72.0; prm->cog_amp_Nm[1] = 1e-3; prm->cog_phase_rad[1] = 1.1;

    /* TE: 2x WG dominant (0.3' amplitude), 1x and 4x WG, 1x output; <= 0.98' p-p in total */
    prm->te_enabled = 1;
    prm->te_wg_order[0] = 2.0; prm->te_wg_amp_rad[0] = 0.30 * arcmin; prm->te_wg_phase_rad[0] = 0.4;
    prm->te_wg_order[1] = 1.0; prm->te_wg_amp_rad[1] = 0.05 * arcmin; prm->te_wg_phase_rad[1] = -1.2;
    prm->te_wg_order[2] = 4.0; prm->te_wg_amp_rad[2] = 0.04 * arcmin; prm->te_wg_phase_rad[2] = 2.0;
    prm->te_out_order[0] = 1.0; prm->te_out_amp_rad[0] = 0.10 * arcmin; prm->te_out_phase_rad[0] = 0.7;

    /* CSF-25-100 three-slope stiffness; damping ~3 % of the first torsional mode */
    prm->stiffness_enabled = 1;
    prm->k1_Nm_per_rad = k1;
    prm->k2_Nm_per_rad = 5.0e4;
    prm->k3_Nm_per_rad = 5.7e4;
    prm->t1_Nm = 14.0;
    prm->t2_Nm = 48.0;
    prm->damping_Nms_per_rad = 6.0;
    prm->cubic_enabled = 0;                 /* alternative to the three-slope (harmonic-drive.md 5.2) */
    prm->cubic_k1_Nm_per_rad = 3.49e4;
    prm->cubic_k3_Nm_per_rad3 = 5.5e9;

    /* hysteresis loss 1' in total: 0.5' Maxwell-slip (2*sum w/K1) + 0.5' Preisach (from the Everett table) */
    prm->maxwell_enabled = 1;
    prm->maxwell_n = 4;
    for (i = 0; i < 4; i++) {
        double w = 0.25 * 0.5 * 0.5 * arcmin * k1;    /* sum w = K1 * (0.5')/2 */
        double slip = (double)(i + 1) * 1e-4;          /* rad of twist until the element slips */
        prm->maxwell_w_Nm[i] = w;
        prm->maxwell_k_Nm_per_rad[i] = w / slip;
    }
    prm->preisach_enabled = 1;
    prm->preisach_u_max_rad = 5e-4;
    prm->preisach_t_sat_Nm = 7.15;                   /* calibrated: 0.50' of loss with this density (docs/plant.md) */
    prm->preisach_r0_rad = 1e-4;
    prm->preisach_s_rad = 2e-4;

    /* motor side (incl. wave-generator bearing and mesh): breakaway 0.1 N.m input,
     * Stribeck velocity 2 rad/s at the motor (1.15 deg/s at the output), presliding ~1 mrad,
     * sigma1 = sqrt(sigma0*J) (bristle damping ratio ~0.5 on the bare motor) */
    friction_defaults(&prm->fric_m, 0.10, 0.07, 0.05, 2.0, 5e-4, 100.0, 0.09, 1e-3);
    /* output crossed-roller bearing: breakaway 0.6 N.m, presliding ~2e-5 rad */
    friction_defaults(&prm->fric_l, 0.60, 0.40, 0.08, 0.02, 0.3, 3e4, 120.0, 1e-5);

    prm->drift_enabled = 0;
    prm->drift_t_start_s = 0.0;
    prm->drift_ramp_s = 10.0;
    prm->drift_scale = 1.0;
    prm->drift_hold_s = 0.0;
    prm->drift_return_s = 0.0;
    prm->jdrift_enabled = 0;
    prm->jdrift_t_start_s = 0.0;
    prm->jdrift_ramp_s = 1e-3;
    prm->jdrift_scale = 1.0;
    prm->kdrift_enabled = 0;
    prm->kdrift_t_start_s = 0.0;
    prm->kdrift_ramp_s = 10.0;
    prm->kdrift_scale = 1.0;
    prm->gdrift_enabled = 0;
    prm->gdrift_t_start_s = 0.0;
    prm->gdrift_ramp_s = 10.0;
    prm->gdrift_mgl_Nm = 0.0;

    prm->jl_kgm2 = 0.5;
    prm->gravity_enabled = 1;
    prm->mgl_Nm = 2.0;
    prm->gravity_offset_rad = 0.0;
    prm->base_enabled = 1;
    prm->base_amp_rad = 0.5 * 0.017453292519943295;   /* 0.5 deg */
    prm->base_freq_Hz = 1.0;
    prm->base_phase_rad = 0.0;

    prm->enc_m_enabled = 1;
    prm->enc_m_bits = 17;
    prm->enc_m_noise_counts = 0.2;
    prm->enc_m_offset_turn = 0.0;
    prm->enc_l_enabled = 1;
    prm->enc_l_bits = 24;
    prm->enc_l_noise_counts = 1.0;
    prm->enc_l_offset_turn = 0.0;

    /* fibre-optic gyro, tactical grade: ARW 0.01 deg/sqrt(h), 500 Hz, bias 0.5 deg/h */
    prm->gyro_enabled = 1;
    prm->gyro_noise_rad_s_per_rtHz = 0.01 * 0.017453292519943295 / 60.0;
    prm->gyro_bandwidth_Hz = 500.0;
    prm->gyro_bias_rad_s = 0.5 * 0.017453292519943295 / 3600.0;

    prm->isense_enabled = 1;
    prm->isense_noise_A = 0.01;
    prm->isense_offset_A = 0.0;

    prm->substeps = 1;
}

void hd_plant_defaults_minimal(hd_plant_params *prm)
{
    hd_plant_defaults_reference(prm);
    prm->current_loop_enabled = 0;
    prm->cogging_enabled = 0;
    prm->te_enabled = 0;
    prm->stiffness_enabled = 1;
    prm->k2_Nm_per_rad = prm->k1_Nm_per_rad;
    prm->k3_Nm_per_rad = prm->k1_Nm_per_rad;
    prm->damping_Nms_per_rad = 0.0;
    prm->cubic_enabled = 0;
    prm->maxwell_enabled = 0;
    prm->preisach_enabled = 0;
    prm->fric_m.enabled = 0;
    prm->fric_l.enabled = 0;
    prm->gravity_enabled = 0;
    prm->base_enabled = 0;
    prm->enc_m_enabled = 0;
    prm->enc_l_enabled = 0;
    prm->gyro_enabled = 0;
    prm->isense_enabled = 0;
}

static int fail(char *msg, size_t n, const char *what)
{
    if (msg != NULL && n > 0) snprintf(msg, n, "%s", what);
    return HD_PLANT_EINVAL;
}

static int check_fric(const hd_plant_friction_params *f, const char *side, char *msg, size_t n)
{
    char buf[160];
    if (!f->enabled) return HD_PLANT_OK;
    if (f->fs_pos_Nm < f->fc_pos_Nm || f->fs_neg_Nm < f->fc_neg_Nm) {
        snprintf(buf, sizeof buf, "%s: fs_pos_Nm/fs_neg_Nm must be >= fc_pos_Nm/fc_neg_Nm", side);
        return fail(msg, n, buf);
    }
    if (f->lugre_enabled && (f->fc_pos_Nm <= 0.0 || f->fc_neg_Nm <= 0.0)) {
        snprintf(buf, sizeof buf, "%s: LuGre needs fc_pos_Nm and fc_neg_Nm > 0", side);
        return fail(msg, n, buf);
    }
    if (!(f->vs_rad_s > 0.0) || !(f->delta > 0.0) || !(f->sigma0_Nm_per_rad > 0.0)) {
        snprintf(buf, sizeof buf, "%s: vs_rad_s, delta and sigma0_Nm_per_rad must be > 0", side);
        return fail(msg, n, buf);
    }
    return HD_PLANT_OK;
}

int hd_plant_check(const hd_plant_params *prm, char *msg, size_t n)
{
    size_t i;
    int rc;
    /* every field within its table range */
    for (i = 0; i < hd_plant_param_count(); i++) {
        double v = 0.0;
        char buf[200];
        (void)hd_plant_param_get(prm, k_table[i].name, &v);
        if (isnan(v) || v < k_table[i].min || v > k_table[i].max) {
            snprintf(buf, sizeof buf, "%s = %g outside [%g, %g]", k_table[i].name, v, k_table[i].min, k_table[i].max);
            return fail(msg, n, buf);
        }
    }
    if (prm->stiffness_enabled) {
        if (!(prm->k1_Nm_per_rad > 0.0 && prm->k2_Nm_per_rad > 0.0 && prm->k3_Nm_per_rad > 0.0))
            return fail(msg, n, "stiffness: k1/k2/k3_Nm_per_rad must be > 0");
        if (!(prm->t2_Nm >= prm->t1_Nm))
            return fail(msg, n, "stiffness: t2_Nm must be >= t1_Nm");
    }
    if (prm->cogging_enabled)
        for (i = 0; i < HD_PLANT_MAX_HARM; i++)
            if (prm->cog_order[i] == 0.0 && prm->cog_amp_Nm[i] != 0.0)
                return fail(msg, n, "cogging: a harmonic with non-zero amplitude needs order > 0");
    if (prm->preisach_enabled && prm->preisach_t_sat_Nm < 0.0)
        return fail(msg, n, "hysteresis_preisach: t_sat_Nm must be >= 0");
    rc = check_fric(&prm->fric_m, "friction_motor", msg, n);
    if (rc != HD_PLANT_OK) return rc;
    return check_fric(&prm->fric_l, "friction_load", msg, n);
}
