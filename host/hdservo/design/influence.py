"""Influence laws: how each nonlinearity parameter moves each servo figure.

Each parameter is scaled by ``1 +- h`` (default h = 0.2) on the axis file, every
other parameter kept, and the figures are measured twice:

* **simulation** -- the C simulator (firmware + plant in lock-step, every plant
  effect on) through :mod:`hdservo.sim`, short scenarios, one process per
  scaled axis (:mod:`concurrent.futures`);
* **describing function** -- the quasi-linear loop of :mod:`hdservo.analysis`
  with the parameter's own nonlinearity replaced by its describing function at
  the amplitude the test scenario drives it to.

The result is the normalised elasticity ``E = d ln(figure) / d ln(parameter)``
by a central difference in logs, ``(ln y+ - ln y-) / (ln(1+h) - ln(1-h))``:
E = 0.5 means +10 % parameter -> about +5 % figure.

Figures (simulation scenario; describing-function counterpart). The drive keeps its
default gains and runs no compensator; base rocking is off except for stabilisation:

======================  ===============================================  ==========================
figure                  simulation                                       describing function
======================  ===============================================  ==========================
min_smooth_rate_deg_s   lowest smooth constant rate, bisected in log     none (sticking is not a
                        rate over 1e-4-0.1 deg/s (10 steps, 0.7 %);      harmonic balance)
                        a rung: 2 s settle, 6 fixed-angle windows of
                        rate x 1 s on the output encoder, smooth =
                        monotone, stability and accuracy <= 10 %
positioning_arcsec      steps of +-0.02 and +-0.05 deg, mean |true       none (the static friction
                        angle - target| over the last 0.1 s of 0.6 s    band is not a DF effect)
tracking_rms_arcsec     1 Hz, 0.1 deg sine, RMS of true angle - ref      |1 - T(j w)| A / sqrt 2 of
                        over 0.5-3 s                                     the equivalent loop
stabilisation_arcsec    1 Hz, 0.5 deg base rocking, STAB mode, RMS       none (the gyro loop is not
                        inertial angle over 1-5 s, line removed          in the DF loop model)
bandwidth_Hz            position multisine 1-80 Hz, 60 arcsec peak,      -3 dB of the equivalent
                        -3 dB of true output / reference                 closed loop
first_resonance_Hz      plant alone, motor-torque multisine 5-150 Hz     peak of twist / torque of
                        (output peak 2 T1), gear twist / torque averaged the two-mass plant with
                        over 3 periods, peak after a +-4 Hz moving       the element's DF, same
                        average                                          lines and smoothing
======================  ===============================================  ==========================

The describing functions are evaluated at the amplitudes of the nominal runs (sqrt 2 x RMS
output velocity for friction, x N at the motor; twist for stiffness and hysteresis).
"""
from __future__ import annotations

import concurrent.futures as cf
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..errors import UserError

ARCSEC = math.pi / (180.0 * 3600.0)
DEG = math.pi / 180.0

#: parameter name -> (axis keys scaled together, description)
PARAMETERS: Dict[str, Tuple[Tuple[str, ...], str]] = {
    "breakaway": (("friction_motor.fs_pos_Nm", "friction_motor.fs_neg_Nm",
                   "friction_load.fs_pos_Nm", "friction_load.fs_neg_Nm"),
                  "breakaway (static) friction level, motor and load side"),
    "coulomb": (("friction_motor.fc_pos_Nm", "friction_motor.fc_neg_Nm",
                 "friction_load.fc_pos_Nm", "friction_load.fc_neg_Nm"),
                "Coulomb (running) friction level, motor and load side"),
    "stribeck_velocity": (("friction_motor.vs_rad_s", "friction_load.vs_rad_s"),
                          "Stribeck velocity, motor and load side"),
    "k1": (("stiffness.k1_Nm_per_rad",), "gear stiffness below T1"),
    "k2": (("stiffness.k2_Nm_per_rad",), "gear stiffness T1-T2"),
    "k3": (("stiffness.k3_Nm_per_rad",), "gear stiffness above T2"),
    "t1": (("stiffness.t1_Nm",), "first stiffness breakpoint"),
    "t2": (("stiffness.t2_Nm",), "second stiffness breakpoint"),
    "hysteresis_width": (tuple(f"hysteresis_maxwell.e{i}_w_Nm" for i in range(1, 5))
                         + ("hysteresis_preisach.t_sat_Nm",),
                         "hysteresis loop width (Maxwell-slip slip torques, Preisach saturation)"),
    "te_amplitude": (tuple(f"transmission_error.wg{i}_amp_rad" for i in range(1, 4))
                     + ("transmission_error.out1_amp_rad",),
                     "transmission-error amplitude (all harmonics)"),
}

SIM_FIGURES = ("min_smooth_rate_deg_s", "positioning_arcsec", "tracking_rms_arcsec",
               "stabilisation_arcsec", "bandwidth_Hz", "first_resonance_Hz")
#: figures with a describing-function prediction
DF_FIGURES = ("tracking_rms_arcsec", "bandwidth_Hz", "first_resonance_Hz")

# test scenarios (short, so a full sweep runs in minutes)
#: min smooth rate: settle time, window duration (window angle = rate x duration), windows,
#: smoothness bound, bisection bracket and steps
RAMP_SETTLE_S, RAMP_WINDOW_S, RAMP_WINDOWS, SMOOTH_BOUND = 2.0, 1.0, 6, 0.1
RATE_LO_DEG_S, RATE_HI_DEG_S, RATE_STEPS = 1e-4, 0.1, 10
STEPS_DEG, DWELL_S = (0.02, -0.02, 0.05, -0.05), 0.6
SINE_HZ, SINE_DEG, SINE_S = 1.0, 0.1, 3.0
BASE_HZ, BASE_DEG, STAB_S = 1.0, 0.5, 5.0
MS_AMP_ARCSEC, MS_F0, MS_F1, MS_LINES = 60.0, 1.0, 80.0, 17
#: resonance test: lines, spacing, and the output torque peak in units of the axis's T1
OL_F0, OL_F1, OL_DF, OL_PEAK_OVER_T1 = 5.0, 150.0, 0.5, 2.0
#: resonance test: periods simulated (the first is discarded) and the smoothing half-width of
#: the FRF magnitude before its peak is taken (the line-to-line scatter of a nonlinear plant's
#: FRF is +-20 %; a 2 Hz peak on one line is not a resonance)
OL_PERIODS, OL_SMOOTH_HZ = 4, 4.0
DT = 1e-4


def elasticity(y_minus: float, y_plus: float, h: float = 0.2) -> Optional[float]:
    """Normalised elasticity d ln y / d ln p by a central difference in logs.

    Parameters
    ----------
    y_minus, y_plus : float
        Figure at parameter x (1 - h) and x (1 + h).
    h : float
        Relative step, 0 < h < 1.

    Returns
    -------
    float or None
        None if either figure is missing or not positive (no log).
    """
    if not 0.0 < h < 1.0:
        raise UserError(f"elasticity step h = {h}: expected 0 < h < 1")
    if y_minus is None or y_plus is None or not (y_minus > 0 and y_plus > 0):
        return None
    if not (math.isfinite(y_minus) and math.isfinite(y_plus)):
        return None
    return (math.log(y_plus) - math.log(y_minus)) / (math.log1p(h) - math.log1p(-h))


def parameter_values(axis: str) -> Dict[str, float]:
    """Values of every key of :data:`PARAMETERS` on an axis file, as the simulator reads it."""
    from .. import sim
    return {k: sim.axis_param(k, axis) for keys, _ in PARAMETERS.values() for k in keys}


#: agreement rule of the describing function with the simulation: |E_df - E_sim| <= ABS + REL |E_sim|
AGREE_ABS, AGREE_REL = 0.1, 0.25


def agreement(e_sim: Optional[float], e_df: Optional[float]) -> str:
    """Classify one cell: ``agrees``, ``differs``, ``no DF`` (no describing-function
    prediction) or ``no sim`` (the simulated figure has no log, e.g. no -3 dB crossing).

    Agreement means ``|E_df - E_sim| <= AGREE_ABS + AGREE_REL |E_sim|``.
    """
    if e_df is None:
        return "no DF"
    if e_sim is None:
        return "no sim"
    return "agrees" if abs(e_df - e_sim) <= AGREE_ABS + AGREE_REL * abs(e_sim) else "differs"


def scaled(axis: Mapping[str, float], parameter: str, factor: float) -> Dict[str, float]:
    """Plant overrides ``{"section.key": value}`` scaling one parameter's keys by ``factor``."""
    if parameter not in PARAMETERS:
        raise UserError(f"influence parameter '{parameter}': expected one of {', '.join(PARAMETERS)}")
    return {k: float(axis[k]) * factor for k in PARAMETERS[parameter][0]}


# ------------------------------------------------------------------ simulation figures
def _ctl(mode: str, compensators: Sequence[str] = ()) -> Dict[str, Any]:
    """Scenario ``[controller]`` table: default gains, the given compensators."""
    return {"mode": mode, "gains": "defaults", "compensators": list(compensators)}


def _run(axis: str, ctl: Mapping[str, Any], sp: Mapping[str, Any], dur: float, plant: Mapping[str, float],
         seed: int, extra: Optional[Mapping[str, Any]] = None) -> Any:
    """One closed-loop run, base rocking off unless ``extra`` turns it on, every row logged."""
    from .predict import run
    plant = {"base.enabled": 0.0, **plant, **(extra or {})}
    return run(axis, ctl, sp, dur, decimation=1, seed=seed, plant=plant, name="influence")


def _amp(x: np.ndarray) -> float:
    """Equivalent sine amplitude sqrt(2) x RMS of a signal about its mean."""
    x = np.asarray(x, dtype=float)
    return float(math.sqrt(2.0) * np.std(x))


def rung_smooth(axis: str, plant: Mapping[str, float], rate_deg_s: float, seed: int = 1) -> bool:
    """One constant-rate rung: monotone, stability and accuracy <= SMOOTH_BOUND (the
    procedure's criterion, :func:`hdservo.procedures.metrics.min_smooth_rate`), on the
    output encoder, ``RAMP_WINDOWS`` fixed-angle windows of ``rate x RAMP_WINDOW_S``."""
    from ..procedures import metrics as mt
    rate = rate_deg_s * DEG
    t0 = 0.05
    r = _run(axis, _ctl("position"), {"type": "ramp", "initial_rad": 0.0, "rate_rad_s": rate, "t0_s": t0},
             t0 + RAMP_SETTLE_S + RAMP_WINDOWS * RAMP_WINDOW_S, plant, seed)
    t = np.asarray(r["t_s"])
    m = t >= t0 + RAMP_SETTLE_S
    s = mt.rate_stability(t[m], np.asarray(r["load_angle_rad"])[m], rate, rate * RAMP_WINDOW_S)
    return bool(s["monotone"]) and s["stability"] <= SMOOTH_BOUND and s["accuracy"] <= SMOOTH_BOUND


def sim_min_smooth_rate(axis: str, plant: Mapping[str, float], seed: int = 1,
                        amps: Optional[Dict[str, float]] = None) -> Optional[float]:
    """Lowest smooth rate by bisection in log rate between RATE_LO and RATE_HI, deg/s.

    A continuous counterpart of the ladder's minimum smooth rate (a decade ladder moves in
    steps of 2-2.5x, too coarse for an elasticity).  ``RATE_STEPS`` bisections give a
    resolution of (RATE_HI / RATE_LO)^(2^-RATE_STEPS).  Returns RATE_LO if that rate is
    smooth (the figure is then censored), None if RATE_HI is not.
    """
    lo, hi = math.log(RATE_LO_DEG_S), math.log(RATE_HI_DEG_S)
    if not rung_smooth(axis, plant, RATE_HI_DEG_S, seed):
        return None
    if rung_smooth(axis, plant, RATE_LO_DEG_S, seed):
        return RATE_LO_DEG_S
    for _ in range(RATE_STEPS):
        mid = 0.5 * (lo + hi)
        if rung_smooth(axis, plant, math.exp(mid), seed):
            hi = mid
        else:
            lo = mid
    return float(math.exp(hi))


def sim_positioning(axis: str, plant: Mapping[str, float], seed: int = 1,
                    amps: Optional[Dict[str, float]] = None) -> float:
    """Mean |true angle - target| at the end of the STEPS_DEG steps, arcsec."""
    errs = []
    for step in STEPS_DEG:
        a = step * DEG
        r = _run(axis, _ctl("position"), {"type": "step", "initial_rad": 0.0, "amplitude_rad": a, "t0_s": 0.02},
                 0.02 + DWELL_S, plant, seed)
        t = np.asarray(r["t_s"])
        m = t >= t[-1] - 0.1
        errs.append(abs(float(np.mean(np.asarray(r["load_angle_true_rad"])[m])) - a))
    return float(np.mean(errs)) / ARCSEC


def sim_tracking(axis: str, plant: Mapping[str, float], seed: int = 1,
                 amps: Optional[Dict[str, float]] = None) -> float:
    """RMS of true output angle - reference during a sine, arcsec.

    ``amps`` (if given) receives the output velocity and twist amplitudes of the run.
    """
    r = _run(axis, _ctl("position"), {"type": "sine", "initial_rad": 0.0, "amplitude_rad": SINE_DEG * DEG,
                                      "frequency_Hz": SINE_HZ, "phase_rad": 0.0, "t0_s": 0.0},
             SINE_S, plant, seed)
    t = np.asarray(r["t_s"])
    m = t >= 0.5
    e = np.asarray(r["load_angle_true_rad"])[m] - np.asarray(r["setpoint_rad"])[m]
    if amps is not None:
        amps["tracking_vel"] = _amp(np.asarray(r["load_velocity_rad_s"])[m])
        amps["tracking_twist"] = _amp(np.asarray(r["torsion_rad"])[m])
    return float(np.sqrt(np.mean(e ** 2))) / ARCSEC


def sim_stabilisation(axis: str, plant: Mapping[str, float], seed: int = 1,
                      amps: Optional[Dict[str, float]] = None) -> float:
    """RMS inertial payload angle under base rocking, STAB mode, line removed, arcsec."""
    extra = {"base.enabled": 1.0, "base.amplitude_rad": BASE_DEG * DEG, "base.frequency_Hz": BASE_HZ}
    r = _run(axis, _ctl("stabilise"), {"type": "constant", "initial_rad_s": 0.0}, STAB_S, plant, seed, extra)
    t = np.asarray(r["t_s"])
    m = t >= 1.0
    ang = np.asarray(r["load_angle_true_rad"])[m] + np.asarray(r["base_angle_true_rad"])[m]
    ang = ang - np.polyval(np.polyfit(t[m], ang, 1), t[m])
    return float(np.sqrt(np.mean(ang ** 2))) / ARCSEC


def _lines(f0: float, f1: float, n: int, df: float) -> np.ndarray:
    f = np.unique(np.round(np.logspace(math.log10(f0), math.log10(f1), n) / df) * df)
    return f[f > 0]


def _multisine(t: np.ndarray, freqs: np.ndarray, peak: float) -> np.ndarray:
    k = np.arange(1, freqs.size + 1)
    ph = -math.pi * k * (k - 1) / freqs.size  # Schroeder phases
    x = np.sum(np.sin(2 * math.pi * freqs[:, None] * t[None, :] + ph[:, None]), axis=0)
    return peak * x / np.max(np.abs(x))


def _line_ratio(t: np.ndarray, y: np.ndarray, u: np.ndarray, freqs: np.ndarray) -> np.ndarray:
    e = np.exp(-2j * math.pi * freqs[:, None] * t[None, :])
    return (e @ y) / (e @ u)


def crossing_3db(freqs: np.ndarray, mag: np.ndarray) -> Optional[float]:
    """First frequency where ``mag`` falls below 1/sqrt(2), interpolated in log f, Hz."""
    lo = 1.0 / math.sqrt(2.0)
    below = np.where(mag < lo)[0]
    if below.size == 0:
        return None
    i = int(below[0])
    if i == 0:
        return float(freqs[0])
    x0, x1 = math.log(freqs[i - 1]), math.log(freqs[i])
    y0, y1 = mag[i - 1], mag[i]
    return float(math.exp(x0 + (lo - y0) / (y1 - y0) * (x1 - x0)))


def peak_frequency(freqs: np.ndarray, mag: np.ndarray) -> float:
    """Frequency of the largest ``mag``, refined by a parabola in log magnitude, Hz."""
    i = int(np.argmax(mag))
    if 0 < i < mag.size - 1:
        a, b, c = np.log(mag[i - 1:i + 2])
        den = a - 2 * b + c
        d = 0.5 * (a - c) / den if den != 0 else 0.0
        return float(freqs[i] + d * (freqs[i + 1] - freqs[i - 1]) / 2.0)
    return float(freqs[i])


def smoothed_peak(freqs: np.ndarray, mag: np.ndarray, half_width_Hz: float = OL_SMOOTH_HZ) -> float:
    """Peak of ``mag`` after a moving average over +-``half_width_Hz`` (equally spaced lines), Hz."""
    df = float(freqs[1] - freqs[0])
    n = max(1, int(round(half_width_Hz / df)))
    kern = np.ones(2 * n + 1) / (2 * n + 1)
    sm = np.convolve(mag, kern, mode="same")
    norm = np.convolve(np.ones_like(mag), kern, mode="same")  # edges: average of what is there
    return peak_frequency(freqs, sm / norm)


def resonance_lines() -> np.ndarray:
    """Excited lines of the resonance test, Hz."""
    return np.arange(OL_F0, OL_F1 + 0.5 * OL_DF, OL_DF)


def resonance_test_torque(axis: str) -> float:
    """Motor-torque peak of the resonance test, ``OL_PEAK_OVER_T1 x T1 / N`` of the axis file, N·m."""
    from .. import sim
    return OL_PEAK_OVER_T1 * sim.axis_param("stiffness.t1_Nm", axis) / sim.axis_param("gear.ratio", axis)


def sim_bandwidth(axis: str, plant: Mapping[str, float], seed: int = 1,
                  amps: Optional[Dict[str, float]] = None) -> Optional[float]:
    """-3 dB of true output / reference for a position multisine (1 s period), Hz."""
    freqs = _lines(MS_F0, MS_F1, MS_LINES, MS_F0)
    r = _run(axis, _ctl("position"), {"type": "multisine", "initial_rad": 0.0,
                                      "amplitude_rad": MS_AMP_ARCSEC * ARCSEC, "f0_Hz": MS_F0,
                                      "f1_Hz": MS_F1, "lines": MS_LINES, "t0_s": 0.0}, 2.0, plant, seed)
    t = np.asarray(r["t_s"])
    m = t >= t[-1] - 1.0 / MS_F0 + 0.5 * DT
    ref = np.asarray(r["setpoint_rad"])[m]
    y = np.asarray(r["load_angle_true_rad"])[m]
    if amps is not None:
        amps["bandwidth_vel"] = _amp(np.asarray(r["load_velocity_rad_s"])[m])
        amps["bandwidth_twist"] = _amp(np.asarray(r["torsion_rad"])[m])
    h = _line_ratio(t[m], y - np.mean(y), ref - np.mean(ref), freqs)
    return crossing_3db(freqs, np.abs(h))


def sim_first_resonance(axis: str, plant: Mapping[str, float], seed: int = 1,
                        amps: Optional[Dict[str, float]] = None) -> Optional[float]:
    """Peak of gear twist / motor torque of the plant alone under a torque multisine, Hz.

    The motor-torque peak is ``OL_PEAK_OVER_T1 x T1 / N`` of the nominal axis, so the test
    spans the K1 region on every axis.
    """
    from .. import sim
    n_per = int(round(1.0 / OL_DF / DT))
    t = np.arange(OL_PERIODS * n_per) * DT
    freqs = resonance_lines()
    u = _multisine(t, freqs, resonance_test_torque(axis))
    out = sim.simulate_open_loop(u, params={"base.enabled": 0.0, **plant}, axis=axis, dt_s=DT, seed=seed)
    tw = np.asarray(out["torsion_rad"])
    h = np.zeros(freqs.size, dtype=complex)
    for k in range(1, OL_PERIODS):
        m = slice(k * n_per, (k + 1) * n_per)
        h += _line_ratio(t[m], tw[m] - np.mean(tw[m]), u[m], freqs) / (OL_PERIODS - 1)
    if amps is not None:
        m = slice(n_per, OL_PERIODS * n_per)
        amps["resonance_vel"] = _amp(np.asarray(out["load_velocity_rad_s"])[m])
        amps["resonance_twist"] = _amp(tw[m])
    return smoothed_peak(freqs, np.abs(h))


SIM_FUNCS: Dict[str, Callable[..., Optional[float]]] = {
    "min_smooth_rate_deg_s": sim_min_smooth_rate,
    "positioning_arcsec": sim_positioning,
    "tracking_rms_arcsec": sim_tracking,
    "stabilisation_arcsec": sim_stabilisation,
    "bandwidth_Hz": sim_bandwidth,
    "first_resonance_Hz": sim_first_resonance,
}


def sim_figures(axis: str, plant: Mapping[str, float], figures: Sequence[str] = SIM_FIGURES,
                seed: int = 1, amps: Optional[Dict[str, float]] = None) -> Dict[str, Optional[float]]:
    """Every requested simulated figure for one set of plant overrides.

    ``amps`` (if given) receives the velocity and twist amplitudes of the runs
    (the describing functions are evaluated there).
    """
    unknown = [f for f in figures if f not in SIM_FUNCS]
    if unknown:
        raise UserError(f"influence figure(s) {', '.join(unknown)}: expected some of {', '.join(SIM_FUNCS)}")
    return {f: SIM_FUNCS[f](axis, plant, seed, amps) for f in figures}


# ------------------------------------------------------------------ describing-function figures
#: the describing-function elements that carry each parameter; a parameter in two elements
#: gets the sum of the two single-element elasticities (first-order superposition)
DF_ELEMENTS: Dict[str, Tuple[str, ...]] = {
    "breakaway": ("stribeck_motor", "stribeck_load"),
    "coulomb": ("stribeck_motor", "stribeck_load"),
    "stribeck_velocity": ("stribeck_motor", "stribeck_load"),
    "k1": ("three_slope",), "k2": ("three_slope",), "k3": ("three_slope",),
    "t1": ("three_slope",), "t2": ("three_slope",),
    "hysteresis_width": ("maxwell_slip",),
    "te_amplitude": (),  # an additive position disturbance, not a describing-function element
}
_INSERTION = {"stribeck_motor": "motor_friction", "stribeck_load": "load_friction",
              "three_slope": "torsion", "maxwell_slip": "torsion"}
DF_OMEGA = 2 * math.pi * np.logspace(-1, math.log10(500.0), 1500)


def _closed(P: np.ndarray, N: complex, out: int, inp: int) -> np.ndarray:
    """Response out <- inp of a system with extra input w (index 1) and output z (last),
    closed by w = N z (the convention of :func:`hdservo.analysis.loop.equivalent_loop`)."""
    iz, iw = P.shape[0] - 1, 1
    return P[out, inp] + P[out, iw] * N * P[iz, inp] / (1.0 - N * P[iz, iw])


def df_figures(axis_params: Mapping[str, float], gains: Mapping[str, float], element: str,
               amps: Mapping[str, float]) -> Dict[str, Optional[float]]:
    """Describing-function counterparts of the figures with one element in the loop.

    Parameters
    ----------
    axis_params : mapping
        Axis ``"section.key"`` -> value.
    gains : mapping
        Drive gains (:func:`hdservo.analysis.axis.load_gains`).
    element : str
        ``stribeck_motor``, ``stribeck_load``, ``three_slope`` or ``maxwell_slip``.
    amps : mapping
        Output velocity (rad/s) and twist (rad) amplitudes of the nominal runs
        (``tracking_*``, ``bandwidth_*``, ``resonance_*``); the motor friction sees
        N x the output velocity.

    Returns
    -------
    dict
        ``tracking_rms_arcsec``, ``bandwidth_Hz``, ``first_resonance_Hz``.
    """
    from ..analysis import catalogue as dfcat
    from ..analysis.loop import LoopModel, equivalent_loop, freqresp

    ax = dict(axis_params)
    model = LoopModel(ax, dict(gains))
    n = float(ax["gear.ratio"])
    insertion = _INSERTION[element]
    nl = dfcat.build(element, ax).nl

    def gain(which: str) -> complex:
        if insertion == "torsion":
            a = amps[f"{which}_twist"]
        else:
            a = amps[f"{which}_vel"] * (n if insertion == "motor_friction" else 1.0)
        return complex(nl.describing_function(max(a, 1e-12)))

    def have(which: str) -> bool:
        return f"{which}_vel" in amps and f"{which}_twist" in amps

    out: Dict[str, Optional[float]] = {f: None for f in DF_FIGURES}
    if have("tracking"):
        w = 2 * math.pi * SINE_HZ
        O = freqresp(model.open_system(insertion), np.array([w]))
        T = equivalent_loop(O, gain("tracking"))["T"][0]
        out["tracking_rms_arcsec"] = float(abs(1.0 - T) * SINE_DEG * DEG / math.sqrt(2.0)) / ARCSEC
    if have("bandwidth"):
        O = freqresp(model.open_system(insertion), DF_OMEGA)
        out["bandwidth_Hz"] = crossing_3db(DF_OMEGA / (2 * math.pi),
                                           np.abs(equivalent_loop(O, gain("bandwidth"))["T"]))
    if have("resonance"):
        # plant alone: twist / torque with the element closed by its DF; twist = (w_m - w_L) / (j w)
        # on the simulation's lines, with the same smoothing
        om = 2 * math.pi * resonance_lines()
        P = freqresp(model.plant(insertion), om)
        N = gain("resonance")
        twist = (_closed(P, N, 2, 0) - _closed(P, N, 3, 0)) / (1j * om)
        out["first_resonance_Hz"] = smoothed_peak(om / (2 * math.pi), np.abs(twist))
    return out


def df_elasticities(axis_params: Mapping[str, float], gains: Mapping[str, float], parameter: str,
                    amps: Mapping[str, float], h: float = 0.2) -> Dict[str, Any]:
    """Describing-function elasticities of :data:`DF_FIGURES` to one parameter.

    Returns
    -------
    dict
        ``elasticity`` ``{figure: E or None}`` (None: the parameter is in no element)
        and ``points`` ``{element: {"minus": figures, "plus": figures}}``.
    """
    els = DF_ELEMENTS[parameter]
    pts: Dict[str, Dict[str, Dict[str, Optional[float]]]] = {}
    tot: Dict[str, Optional[float]] = {f: (0.0 if els else None) for f in DF_FIGURES}
    for el in els:
        lo = df_figures({**axis_params, **scaled(axis_params, parameter, 1.0 - h)}, gains, el, amps)
        hi = df_figures({**axis_params, **scaled(axis_params, parameter, 1.0 + h)}, gains, el, amps)
        pts[el] = {"minus": lo, "plus": hi}
        for f in DF_FIGURES:
            e = elasticity(lo[f], hi[f], h)  # type: ignore[arg-type]
            cur = tot[f]
            tot[f] = None if (e is None or cur is None) else cur + e
    return {"elasticity": tot, "points": pts}


# ------------------------------------------------------------------ the sweep
@dataclass(frozen=True)
class Point:
    """One scaled axis: parameter (``nominal`` for none) and factor."""

    parameter: str
    factor: float


def _sim_point(axis: str, axis_params: Mapping[str, float], p: Point, figures: Sequence[str],
               seed: int) -> Tuple[Point, Dict[str, Optional[float]], Dict[str, float]]:
    plant = {} if p.parameter == "nominal" else scaled(axis_params, p.parameter, p.factor)
    amps: Dict[str, float] = {}
    return p, sim_figures(axis, plant, figures, seed, amps), amps


def sweep(axis: str, parameters: Sequence[str] = tuple(PARAMETERS), figures: Sequence[str] = SIM_FIGURES,
          h: float = 0.2, workers: int = 2, seed: int = 1,
          progress: Optional[Callable[[str], None]] = None) -> Dict[str, Any]:
    """Elasticities of every figure to every parameter, simulation and describing function.

    Parameters
    ----------
    axis : str
        Axis TOML path.
    parameters : sequence of str
        Names of :data:`PARAMETERS`.
    figures : sequence of str
        Names of :data:`SIM_FIGURES`.
    h : float
        Relative step (0.2 = +-20 %).
    workers : int
        Processes for the simulations.
    seed : int
        Sensor-noise seed (the same for every point, so noise does not enter the difference).

    Returns
    -------
    dict
        ``nominal`` (figures), ``amplitudes`` (of the nominal runs, where the describing
        functions are evaluated), ``points`` (per parameter, ``minus``/``plus`` figures),
        ``elasticity`` ``{parameter: {figure: {"sim": E, "df": E}}}``.
    """
    from ..analysis.axis import AxisFileError, load_axis, load_gains

    try:
        ax, _ = load_axis(Path(axis))
    except AxisFileError as e:
        raise UserError(f"influence sweep: {e}") from None
    ax = {**ax, **parameter_values(axis)}
    gains, _ = load_gains(None)
    for p in parameters:
        scaled(ax, p, 1.0)  # validates the name
    pts = [Point("nominal", 1.0)] + [Point(p, 1.0 + s * h) for p in parameters for s in (-1, 1)]
    res: Dict[Point, Dict[str, Optional[float]]] = {}
    amps: Dict[str, float] = {}
    with cf.ProcessPoolExecutor(max_workers=max(1, workers)) as ex:
        futs = [ex.submit(_sim_point, axis, ax, p, list(figures), seed) for p in pts]
        for fu in cf.as_completed(futs):
            p, f, a = fu.result()
            res[p] = f
            if p.parameter == "nominal":
                amps = a
            if progress:
                progress(f"influence: {p.parameter} x {p.factor:g} done")
    el: Dict[str, Dict[str, Dict[str, Optional[float]]]] = {}
    dfp: Dict[str, Any] = {}
    for p in parameters:
        lo, hi = res[Point(p, 1.0 - h)], res[Point(p, 1.0 + h)]
        d = df_elasticities(ax, gains, p, amps, h)
        dfp[p] = d["points"]
        el[p] = {}
        for f in figures:
            es = elasticity(lo[f], hi[f], h)  # type: ignore[arg-type]
            ed = d["elasticity"].get(f)
            el[p][f] = {"sim": es, "df": ed, "agreement": agreement(es, ed)}  # type: ignore[dict-item]
    return {"axis": str(axis), "h": h, "seed": seed, "parameters": {p: PARAMETERS[p][1] for p in parameters},
            "figures": list(figures), "nominal": res[Point("nominal", 1.0)], "amplitudes": amps,
            "points": {p: {"minus": res[Point(p, 1.0 - h)], "plus": res[Point(p, 1.0 + h)]} for p in parameters},
            "df_points": dfp, "elasticity": el}


# ------------------------------------------------------------------ the shipped table
TABLE_FILE = Path(__file__).resolve().parent.parent / "data" / "influence.json"

#: the influence figure behind each requirement of the design flow (its margin names);
#: peak torque has none (motor and gear ratings set it, not a nonlinearity)
REQUIREMENT_FIGURE: Dict[str, str] = {
    "min_smooth_rate": "min_smooth_rate_deg_s",
    "positioning_accuracy": "positioning_arcsec",
    "repeatability": "positioning_arcsec",
    "stabilisation": "stabilisation_arcsec",
    "resonance": "first_resonance_Hz",
    "bandwidth": "bandwidth_Hz",
    "tracking": "tracking_rms_arcsec",
}

#: +1 if a larger figure is better, -1 if a smaller one is
FIGURE_BETTER: Dict[str, int] = {
    "min_smooth_rate_deg_s": -1, "positioning_arcsec": -1, "tracking_rms_arcsec": -1,
    "stabilisation_arcsec": -1, "bandwidth_Hz": +1, "first_resonance_Hz": +1,
}


def improving_direction(figure: str, e: float) -> str:
    """``raise`` or ``lower``: which way the parameter improves the figure (sign of E)."""
    return "raise" if e * FIGURE_BETTER[figure] > 0 else "lower"


#: what changes each parameter in the hardware (docs/design-structure.md)
STRUCTURAL_LEVER: Dict[str, str] = {
    "breakaway": "gear size and ratio (starting torque ~ d^3), lubricant, temperature",
    "coulomb": "gear size and ratio, lubricant, temperature",
    "stribeck_velocity": "lubricant viscosity, temperature",
    "k1": "pitch diameter and face width (mesh ~70 % of the low-torque compliance)",
    "k2": "pitch diameter and face width",
    "k3": "pitch diameter, face width, cup wall",
    "t1": "face width (T1 ~ d^2 b)",
    "t2": "face width (T2 ~ d^2 b)",
    "hysteresis_width": "mesh micro-slip: a stiffer (larger) gear, preload",
    "te_amplitude": "gear accuracy grade, assembly (wave-generator and output bearing run-out)",
}


def load_table(path: Path = TABLE_FILE) -> Dict[str, Any]:
    """The influence table shipped as package data (``make results`` writes its source)."""
    import json
    try:
        doc = json.loads(Path(path).read_text())
    except OSError as e:
        raise UserError(f"{path}: cannot read: {e.strerror}") from None
    except ValueError as e:
        raise UserError(f"{path}: not valid JSON: {e}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("elasticity"), dict):
        raise UserError(f"{path}: expected an object with an 'elasticity' table")
    return doc


def ranked_levers(table: Mapping[str, Any], figure: str, source: str = "sim", top: int = 3
                  ) -> List[Tuple[str, float]]:
    """Parameters that move ``figure`` most (largest |elasticity|), strongest first."""
    el = table["elasticity"]
    rows = [(p, v[figure][source]) for p, v in el.items()
            if figure in v and v[figure].get(source) is not None]
    rows.sort(key=lambda r: -abs(r[1]))
    return [(p, float(e)) for p, e in rows[:top]]


def requirement_influence(requirements: Sequence[str], table: Optional[Mapping[str, Any]] = None,
                          top: int = 3) -> Dict[str, List[Dict[str, Any]]]:
    """For each requirement, the parameters that move its figure most.

    Returns
    -------
    dict
        ``{requirement: [{"parameter", "elasticity_sim", "elasticity_df", "meaning"}, ...]}``.
    """
    tab = table if table is not None else load_table()
    out: Dict[str, List[Dict[str, Any]]] = {}
    for req in requirements:
        fig = REQUIREMENT_FIGURE.get(req)
        if fig is None:
            continue
        rows = []
        for p, e in ranked_levers(tab, fig, "sim", top):
            d = tab["elasticity"][p][fig].get("df")
            rows.append({"parameter": p, "figure": fig, "elasticity_sim": e, "elasticity_df": d,
                         "agreement": agreement(e, d), "to_improve": improving_direction(fig, e),
                         "meaning": tab.get("parameters", {}).get(p, ""),
                         "lever": STRUCTURAL_LEVER.get(p, "")})
        out[req] = rows
    return out


def markdown_section(margins: Mapping[str, float], table: Optional[Mapping[str, Any]] = None) -> List[str]:
    """Markdown lines of the design report: per requirement, its binding parameter
    (the largest |elasticity| of its figure) and the runners-up.

    Parameters
    ----------
    margins : mapping
        Requirement -> relative margin of the chosen design (>= 0 = met).
    table : mapping, optional
        Influence table; default :func:`load_table`.
    """
    tab = table if table is not None else load_table()
    inf = requirement_influence(list(margins), tab)
    L = ["## Influence of the binding parameters", "",
         f"Elasticities d ln(figure) / d ln(parameter) at +-{100 * float(tab.get('h', 0.2)):.0f} % on the "
         f"`{tab.get('axis', 'reference')}` axis (simulation; describing function beside it where it has a "
         "prediction). A parameter change of x % moves the figure by about E x %. The laws are local: on "
         "another axis the stick-slip figures (minimum smooth rate, positioning) can change sign, so the "
         "table names the parameter to examine, and a sweep on the chosen axis "
         "(`tests/results/46_influence.py --axis`) gives its effect. Method and the full table: "
         "`docs/design-flow.md`.", "",
         "| requirement | margin | binding parameter | E sim | E DF | to improve | next | what changes it |",
         "|---|---|---|---|---|---|---|---|"]
    for req, rows in inf.items():
        if not rows:
            continue
        top, rest = rows[0], rows[1:]
        ed = "-" if top["elasticity_df"] is None else f"{top['elasticity_df']:+.2f}"
        nxt = ", ".join(f"{r['parameter']} {r['elasticity_sim']:+.2f}" for r in rest) or "-"
        L.append(f"| {req} | {100 * margins[req]:+.0f} % | {top['parameter']} | {top['elasticity_sim']:+.2f} | "
                 f"{ed} | {top['to_improve']} {top['parameter']} | {nxt} | {top['lever']} |")
    L.append("")
    return L
