"""The standard closed-loop cases in the simulator: runs, figures and plots of any controller configuration.

The standard cases are the closed-loop part of the "proof" that a compensator
helps: every case runs the firmware application against the simulated axis
(:func:`hdservo.sim.run_scenario`) with every plant effect of the axis file on
(noise, quantisation, friction, hysteresis, transmission error, gravity, base
rocking, ...), and is reduced to a few figures in arcsec at the output:

* ``step_100arcsec``, ``step_1deg``: rise time (10-90 %), overshoot, settling
  time to a 2 arcsec and a 10 arcsec band, final error;
* ``ramp_1degps``: tracking error of a 1 deg/s ramp;
* ``tracking``: constant-rate references at 0.001, 0.01 and 0.1 deg/s (RMS and
  max tracking error after the start transient, and the rate fluctuation);
* ``reversal``: 1 deg amplitude, 0.1 Hz sinusoid, peak error around each
  velocity reversal;
* ``ptp_12``: 12 point-to-point moves from 0 to targets spread over +-55 deg
  (final error per target).

The same cases run with any controller configuration (the scenario
``[controller]`` table: ``mode``, ``gains``, ``compensators``, ...) through
:func:`run_cases`, so a later comparison runs exactly these cases with the
compensators on and compares with :func:`improvement`.

Error convention: ``e = setpoint - true output angle`` (``setpoint_rad`` minus
``load_angle_true_rad``, both relative to the housing), in arcsec.  The true
angle is used because it is what the payload does; the output encoder reading
differs from it only by its quantisation and noise (0.08 arcsec LSB on the
reference axis).
"""
from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import filters, resources, sim
from .fileio import json_ready, save_figure_atomic
from .plotting import pyplot
from .tomltext import basic_string

#: arcsec per radian.
from .units import ARCSEC_PER_RAD  # noqa: E402
#: rad per degree.
RAD_PER_DEG = math.pi / 180.0

#: Axes the baseline runs on: name -> axis spec ("reference" is built in, the others are
#: shipped axis files, see :func:`hdservo.resources.axis_file`).
AXES: dict[str, str] = {
    "reference": "reference",
    "csf17_50": "csf17_50",
}

#: Constant-rate tracking speeds, deg/s (keys of the "tracking" figures).
TRACKING_SPEEDS_DEG_S: tuple[float, ...] = (0.001, 0.01, 0.1)
#: Targets of the 12 point-to-point moves, deg (each move starts at 0).
PTP_TARGETS_DEG: tuple[float, ...] = tuple(-55.0 + 10.0 * k for k in range(12))


# ------------------------------------------------------------------ case definitions

@dataclass(frozen=True)
class Case:
    """One standard closed-loop case.

    Attributes
    ----------
    name : str
        Case name (key of the figures; point-to-point moves share ``group``).
    kind : str
        Analysis: ``"step"``, ``"tracking"``, ``"reversal"`` or ``"ptp"``.
    setpoint : dict
        The scenario ``[setpoint]`` table (position mode, rad, rad/s, rad/s^2, s).
    duration_s : float
        Run length, s.
    log_decimation : int
        One log row every N 100 us periods.
    skip_s : float
        Start transient excluded from tracking statistics, s after ``t0_s``.
    group : str
        Figures key the case contributes to (``"ptp_12"`` for the moves,
        otherwise ``name``).
    label : str
        Human label for plots and reports.
    """

    name: str
    kind: str
    setpoint: dict[str, Any]
    duration_s: float
    log_decimation: int = 1
    skip_s: float = 0.0
    group: str = ""
    label: str = ""

    @property
    def key(self) -> str:
        """Figures key (``group`` or ``name``)."""
        return self.group or self.name


def speed_key(v_deg_s: float) -> str:
    """JSON key of a tracking speed: 0.001 -> ``"0.001"`` (deg/s)."""
    return f"{v_deg_s:g}"


def standard_cases(quick: bool = False) -> list[Case]:
    """The standard baseline cases.

    Parameters
    ----------
    quick : bool
        Short durations (tests): the same cases, each run a few seconds at
        most, the tracking transients shortened accordingly.  Figures from a
        quick run are not the baseline figures.

    Returns
    -------
    list of Case
    """
    t0 = 0.1
    cases: list[Case] = []
    # steps: 3 s; the final error is the mean over the last 1 s (one base-rocking period)
    for name, amp_arcsec, dur in (("step_100arcsec", 100.0, 3.0), ("step_1deg", 3600.0, 3.0)):
        cases.append(Case(name, "step", {"type": "step", "initial_rad": 0.0,
                                         "amplitude_rad": amp_arcsec / ARCSEC_PER_RAD, "t0_s": t0},
                          duration_s=dur if not quick else 1.2, label=f"{amp_arcsec:g} arcsec step"
                          if amp_arcsec < 3600 else "1 deg step"))
    # 1 deg/s ramp: 6 s, statistics after 1 s
    cases.append(Case("ramp_1degps", "tracking", {"type": "ramp", "initial_rad": 0.0,
                                                  "rate_rad_s": 1.0 * RAD_PER_DEG, "t0_s": t0},
                      duration_s=t0 + (6.0 if not quick else 1.0), log_decimation=10,
                      skip_s=1.0 if not quick else 0.3, label="1 deg/s ramp"))
    # constant slow rates: travel >= 720 arcsec (0.001 deg/s: 200 s); transient skipped
    for v, dur, skip in ((0.001, 220.0, 20.0), (0.01, 75.0, 5.0), (0.1, 22.0, 2.0)):
        cases.append(Case(f"tracking_{speed_key(v)}", "tracking",
                          {"type": "ramp", "initial_rad": 0.0, "rate_rad_s": v * RAD_PER_DEG, "t0_s": t0},
                          duration_s=t0 + (dur if not quick else 3.0), log_decimation=10,
                          skip_s=skip if not quick else 1.5, label=f"{v:g} deg/s"))
    # reversals: A (1 - cos) form (phase -pi/2) so that the run starts at rest;
    # reversals at t0 + k / (2 f); 4 of them in 22 s
    f = 0.1
    cases.append(Case("reversal", "reversal", {"type": "sine", "initial_rad": 0.0,
                                               "amplitude_rad": 1.0 * RAD_PER_DEG, "frequency_Hz": f,
                                               "phase_rad": -math.pi / 2, "t0_s": t0},
                      duration_s=t0 + (22.0 if not quick else 7.0), log_decimation=10,
                      label="1 deg, 0.1 Hz sine"))
    targets = PTP_TARGETS_DEG if not quick else PTP_TARGETS_DEG[5:7]
    for tgt in targets:
        vmax, amax = 30.0 * RAD_PER_DEG, 100.0 * RAD_PER_DEG
        d = abs(tgt) * RAD_PER_DEG
        t_move = d / vmax + vmax / amax if d > vmax ** 2 / amax else 2 * math.sqrt(d / amax)
        cases.append(Case(f"ptp_{tgt:+g}deg", "ptp",
                          {"type": "move", "initial_rad": 0.0, "target_rad": tgt * RAD_PER_DEG,
                           "max_velocity_rad_s": vmax, "max_accel_rad_s2": amax, "t0_s": t0},
                          duration_s=t0 + t_move + (2.5 if not quick else 1.2), log_decimation=10,
                          group="ptp_12", label=f"move to {tgt:+g} deg"))
    return cases


# ------------------------------------------------------------------ controller configuration

def velocity_pi(j_total_kgm2: float, f_v_hz: float = 25.0) -> dict[str, float]:
    """Velocity PI of the design rule (docs/control.md) for a total inertia, inside the drive's ranges.

    ``kp = J 2 pi f_v`` (N.m.s/rad) and ``ki = kp 2 pi f_v / 4`` (N.m/rad): the PI zero a quarter of
    the crossover.  ``vel_ki`` is a Q15.16 word in the drive (at most 32000 N.m/rad, reached at
    J = 5.2 kg.m^2 with f_v = 25 Hz); beyond, ki stays at the drive's maximum and the PI zero moves
    down (ki / kp), which keeps the crossover and adds phase margin.  kp likewise stays inside its
    range (5000 N.m.s/rad, J = 32 kg.m^2).

    Parameters
    ----------
    j_total_kgm2 : float
        Total inertia referred to the output, J_L + N^2 J_m, kg.m^2 (> 0).
    f_v_hz : float
        Velocity-loop crossover, Hz (> 0).

    Returns
    -------
    dict
        ``{"vel_kp": kp, "vel_ki": ki}`` in the parameter-table units.

    Raises
    ------
    ValueError
        A non-finite or non-positive inertia or bandwidth.
    """
    from .params_gen import BY_NAME
    if not (math.isfinite(j_total_kgm2) and j_total_kgm2 > 0):
        raise ValueError(f"total inertia {j_total_kgm2!r} kg.m^2: expected a finite number > 0")
    if not (math.isfinite(f_v_hz) and f_v_hz > 0):
        raise ValueError(f"velocity bandwidth {f_v_hz!r} Hz: expected a finite number > 0")
    kp = min(j_total_kgm2 * 2.0 * math.pi * f_v_hz, BY_NAME["vel_kp"].max)
    return {"vel_kp": kp, "vel_ki": min(kp * 2.0 * math.pi * f_v_hz / 4.0, BY_NAME["vel_ki"].max)}


#: the gear's torque the drive of a comparison may command, as a multiple of the gear's catalogue
#: torque T2 (``stiffness.t2_Nm``): the same figure ``hdservo identify --torque-max`` cycles the gear to
GEAR_TORQUE_PER_T2 = 1.3


def axis_torque_limit(ratio: float, kt_Nm_per_A: float, peak_current_A: float, t2_Nm: float) -> float:
    """The drive's output torque limit ``torque_limit`` a comparison runs with on an axis, N.m.

    One rule for every row of a comparison (the fair PID and every compensated row alike):
    the peak torque the motor gives at the output, ``N Kt I_peak``, bounded by the gear's
    torque ``1.3 T2`` (the stiffness cycle's amplitude of identification), and never below the
    parameter's default (60 N.m, the limit the reference design runs with), nor above the
    parameter's range.  A drive is commissioned for its axis: a large gear with high friction
    needs more than the default to move, a small gear keeps the default, whose clamp its own
    motor never reaches.

    Parameters
    ----------
    ratio : float
        Gear ratio N (> 0).
    kt_Nm_per_A : float
        Motor torque constant, N.m/A (> 0).
    peak_current_A : float
        Current loop's peak current, A (> 0).
    t2_Nm : float
        The gear's catalogue torque T2 (the second stiffness knee), N.m (> 0).

    Returns
    -------
    float
        ``torque_limit`` in N.m at the output.

    Raises
    ------
    ValueError
        A non-finite or non-positive input.
    """
    from .params_gen import BY_NAME
    for name, v in (("gear ratio", ratio), ("motor kt", kt_Nm_per_A), ("peak current", peak_current_A),
                    ("gear T2", t2_Nm)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"torque limit rule: {name} {v!r}: expected a finite number > 0")
    p = BY_NAME["torque_limit"]
    reach = min(ratio * kt_Nm_per_A * peak_current_A, GEAR_TORQUE_PER_T2 * t2_Nm)
    return float(min(max(reach, p.default), p.max))


def axis_controller(axis: str = "reference") -> dict[str, Any]:
    """The PID baseline ``[controller]`` table for an axis.

    The reference axis uses the parameter-table defaults (they are the
    reference design, docs/control.md).  Any other axis gets the same design
    rules applied to its own axis file (velocity PI at 25 Hz, :func:`velocity_pi`:
    ``kp = J_tot 2 pi 25``, ``ki = kp 2 pi 25 / 4`` within the drive's range; position P at 6 Hz as the
    defaults; notch at the coupled resonance ``sqrt(K1 (J1 + J2) / (J1 J2))``,
    40 Hz wide, -20 dB; drive torque limit by :func:`axis_torque_limit` from the axis' motor
    and gear) -- nothing is tuned by hand for either axis.  The reference axis' defaults
    include its torque limit, 60 N.m (the rule would give 1.3 T2 = 62.4 N.m, a clamp its
    procedures never reach).

    Parameters
    ----------
    axis : str
        A key of :data:`AXES` or an axis TOML path.

    Returns
    -------
    dict
        ``{"mode": "position", "gains": "defaults" | {name: value in table units},
        "compensators": []}``.
    """
    spec = _axis_spec(axis)
    if spec == "reference":
        return {"mode": "position", "gains": "defaults", "compensators": []}
    p = {k: sim.axis_param(k, spec) for k in ("gear.ratio", "motor.jm_kgm2", "load.jl_kgm2",
                                                "stiffness.k1_Nm_per_rad", "motor.kt_Nm_per_A",
                                                "current_loop.peak_A", "stiffness.t2_Nm")}
    j1 = p["gear.ratio"] ** 2 * p["motor.jm_kgm2"]
    j2 = p["load.jl_kgm2"]
    jt = j1 + j2
    f_res = math.sqrt(p["stiffness.k1_Nm_per_rad"] * jt / (j1 * j2)) / (2 * math.pi)
    raw = filters.quantise(filters.notch(f_res, 40.0, -20.0))
    gains: dict[str, float] = velocity_pi(jt, 25.0)
    for k, r in filters.export_params("f1", raw).items():
        gains[k] = r / filters.Q30            # table unit of a Q2.30 coefficient: exact
    gains["torque_limit"] = axis_torque_limit(p["gear.ratio"], p["motor.kt_Nm_per_A"], p["current_loop.peak_A"],
                                              p["stiffness.t2_Nm"])
    return {"mode": "position", "gains": gains, "compensators": []}


def _axis_spec(axis: str) -> str:
    if axis in ("reference", "minimal"):
        return axis
    if axis in AXES:
        return str(resources.axis_file(AXES[axis]))
    return str(Path(axis).resolve())


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if not math.isfinite(x):
            raise ValueError(f"non-finite value {x!r} in a scenario")
        return repr(x)
    if isinstance(v, str):
        return basic_string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise ValueError(f"cannot write {v!r} to a scenario")


def _toml_table(name: str, table: Mapping[str, Any]) -> list[str]:
    lines = [f"[{name}]"]
    subs = []
    for k, v in table.items():
        if isinstance(v, Mapping):
            subs.append((k, v))
        else:
            lines.append(f"{k} = {_toml_value(v)}")
    for k, v in subs:
        lines.append("")
        lines.extend(_toml_table(f"{name}.{k}", v))
    return lines


def scenario_text(case: Case, controller: Mapping[str, Any], axis: str = "reference", seed: int = 1,
                  plant: Mapping[str, Any] | None = None) -> str:
    """TOML text of the scenario of one case.

    Parameters
    ----------
    case : Case
    controller : mapping
        The ``[controller]`` table (``mode`` must be ``"position"`` or absent).
    axis : str
        A key of :data:`AXES` or an axis TOML path.
    seed : int
        Sensor-noise seed.
    plant : mapping, optional
        ``[plant]`` overrides ``{"section.key": value}`` (SI).

    Returns
    -------
    str
    """
    ctl = dict(controller)
    if ctl.setdefault("mode", "position") != "position":
        raise ValueError(f"baseline cases need controller mode 'position', found {ctl['mode']!r}")
    spec = _axis_spec(axis)
    lines = [f"# hdservo baseline case {case.name} ({case.label})"]
    lines += _toml_table("scenario", {"name": case.name, "axis": spec, "duration_s": float(case.duration_s),
                                      "seed": int(seed), "log_decimation": int(case.log_decimation)})
    lines.append("")
    lines += _toml_table("controller", ctl)
    lines.append("")
    lines += _toml_table("setpoint", case.setpoint)
    if plant:
        lines.append("")
        lines.append("[plant]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in plant.items()]
    return "\n".join(lines) + "\n"


def run_case(case: Case, controller: Mapping[str, Any], axis: str = "reference", seed: int = 1,
             effects: Mapping[str, bool] | None = None,
             params: Mapping[str, float | bool] | None = None) -> sim.SimResult:
    """Run one case in closed loop.

    Parameters
    ----------
    case : Case
    controller : mapping
        The scenario ``[controller]`` table.
    axis : str
        A key of :data:`AXES` or an axis TOML path.
    seed : int
        Sensor-noise seed.
    effects, params : mapping, optional
        Plant effect switches and parameter overrides (:func:`hdservo.sim.run_scenario`);
        the default (None) keeps every effect of the axis file on.

    Returns
    -------
    hdservo.sim.SimResult
    """
    text = scenario_text(case, controller, axis, seed)
    with tempfile.TemporaryDirectory(prefix="hdservo-baseline-") as d:
        path = Path(d) / f"{case.name}.toml"
        path.write_text(text)
        return sim.run_scenario(path, effects=effects, params=params)


# ------------------------------------------------------------------ figures

def error_arcsec(r: sim.SimResult | Mapping[str, np.ndarray]) -> np.ndarray:
    """Tracking error ``setpoint - true output angle``, arcsec."""
    return (np.asarray(r["setpoint_rad"]) - np.asarray(r["load_angle_true_rad"])) * ARCSEC_PER_RAD


def rms_max(e: np.ndarray) -> dict[str, float]:
    """RMS, max |e| and mean of an error signal (same unit as ``e``).

    Raises
    ------
    ValueError
        for an empty signal.
    """
    e = np.asarray(e, dtype=float)
    if e.size == 0:
        raise ValueError("rms_max: empty error signal")
    return {"rms": float(np.sqrt(np.mean(e * e))), "max": float(np.max(np.abs(e))), "mean": float(np.mean(e))}


def step_figures(t_s: np.ndarray, setpoint_rad: np.ndarray, y_rad: np.ndarray, t0_s: float,
                 bands_arcsec: Sequence[float] = (2.0, 10.0), final_window_s: float = 1.0) -> dict[str, Any]:
    """Step-response figures.

    Parameters
    ----------
    t_s : ndarray
        Time, s.
    setpoint_rad, y_rad : ndarray
        Reference and output angle, rad.
    t0_s : float
        Step time, s.
    bands_arcsec : sequence of float
        Settling bands, arcsec (settling time = last exit from the band, after t0).
    final_window_s : float
        Final error = mean error over the last ``final_window_s`` s.

    Returns
    -------
    dict
        ``amplitude_arcsec``, ``rise_time_s`` (10-90 % of the commanded step, None if
        not reached), ``overshoot_pct`` (peak beyond the command, % of the step,
        >= 0), ``settling_time_s_<b>arcsec`` (None if it never settles in the run),
        ``final_error_arcsec`` (mean), ``final_error_max_arcsec`` (max |e| in the
        final window), ``peak_error_arcsec`` after the step.
    """
    t = np.asarray(t_s, dtype=float)
    sp = np.asarray(setpoint_rad, dtype=float)
    y = np.asarray(y_rad, dtype=float)
    i0 = int(np.searchsorted(t, t0_s - 1e-9))
    y0 = float(np.mean(y[max(0, i0 - 10):i0])) if i0 > 0 else float(y[0])
    amp = float(sp[-1] - (sp[i0 - 1] if i0 > 0 else sp[0]))
    if amp == 0.0:
        raise ValueError("step_figures: the setpoint has no step")
    s = (y[i0:] - y0) / amp                  # normalised response
    tt = t[i0:]
    out: dict[str, Any] = {"amplitude_arcsec": amp * ARCSEC_PER_RAD}
    i10 = np.flatnonzero(s >= 0.1)
    i90 = np.flatnonzero(s >= 0.9)
    out["rise_time_s"] = float(tt[i90[0]] - tt[i10[0]]) if i10.size and i90.size else None
    out["overshoot_pct"] = float(max(0.0, (np.max(s) - 1.0) * 100.0))
    e = (sp[i0:] - y[i0:]) * ARCSEC_PER_RAD
    for b in bands_arcsec:
        outside = np.flatnonzero(np.abs(e) > b)
        if outside.size == 0:
            ts: float | None = 0.0
        elif outside[-1] == e.size - 1:
            ts = None
        else:
            ts = float(tt[outside[-1] + 1] - t0_s)
        out[f"settling_time_s_{b:g}arcsec"] = ts
    fin = e[tt >= tt[-1] - final_window_s]
    out["final_error_arcsec"] = float(np.mean(fin))
    out["final_error_max_arcsec"] = float(np.max(np.abs(fin)))
    out["peak_error_arcsec"] = float(np.max(np.abs(e)))
    return out


def tracking_figures(t_s: np.ndarray, e_arcsec: np.ndarray, v_rad_s: np.ndarray | None, t_from_s: float,
                     v_ref_rad_s: float | None = None, y_rad: np.ndarray | None = None,
                     avg_window_s: float = 0.01) -> dict[str, Any]:
    """Tracking figures of a constant-rate case over ``t >= t_from_s``.

    Parameters
    ----------
    t_s : ndarray
        Time, s.
    e_arcsec : ndarray
        Tracking error, arcsec.
    v_rad_s : ndarray or None
        Output velocity, rad/s (instantaneous, for the rate fluctuation).
    t_from_s : float
        Start of the statistics window, s (start transient excluded).
    v_ref_rad_s : float, optional
        Commanded rate, rad/s (enables the relative fluctuation figures).
    y_rad : ndarray, optional
        Output angle, rad: the rate averaged over ``avg_window_s`` is computed
        from its differences (what a slow observer or a camera sees).
    avg_window_s : float
        Averaging window of the smoothed rate, s.

    Returns
    -------
    dict
        ``rms_arcsec``, ``max_arcsec``, ``mean_arcsec``, ``window_s`` [from, to];
        with a velocity: ``rate_mean_deg_s``, ``rate_rms_dev_deg_s``,
        ``rate_pp_deg_s``; with ``v_ref_rad_s``: ``rate_rms_dev_pct`` (% of the
        commanded rate) and, with ``y_rad``, ``rate_avg_rms_dev_pct``,
        ``rate_avg_pp_pct`` (rate over ``avg_window_s``), and ``travel_arcsec``.
    """
    t = np.asarray(t_s, dtype=float)
    m = t >= t_from_s
    if not np.any(m):
        raise ValueError(f"tracking_figures: no samples after t = {t_from_s} s")
    f = rms_max(np.asarray(e_arcsec, dtype=float)[m])
    out: dict[str, Any] = {"rms_arcsec": f["rms"], "max_arcsec": f["max"], "mean_arcsec": f["mean"],
                           "window_s": [float(t[m][0]), float(t[m][-1])]}
    if v_rad_s is not None:
        v = np.asarray(v_rad_s, dtype=float)[m] / RAD_PER_DEG
        vm = float(np.mean(v))
        out["rate_mean_deg_s"] = vm
        out["rate_rms_dev_deg_s"] = float(np.sqrt(np.mean((v - vm) ** 2)))
        out["rate_pp_deg_s"] = float(np.max(v) - np.min(v))
        if v_ref_rad_s:
            vr = v_ref_rad_s / RAD_PER_DEG
            out["rate_rms_dev_pct"] = float(100.0 * np.sqrt(np.mean((v - vr) ** 2)) / abs(vr))
    if y_rad is not None and v_ref_rad_s:
        y = np.asarray(y_rad, dtype=float)[m]
        tm = t[m]
        dt = float(np.median(np.diff(tm))) if tm.size > 1 else 0.0
        k = max(1, int(round(avg_window_s / dt))) if dt > 0 else 1
        if y.size > k:
            va = (y[k:] - y[:-k]) / (tm[k:] - tm[:-k])
            rel = (va - v_ref_rad_s) / abs(v_ref_rad_s) * 100.0
            out["rate_avg_window_s"] = avg_window_s
            out["rate_avg_rms_dev_pct"] = float(np.sqrt(np.mean(rel ** 2)))
            out["rate_avg_pp_pct"] = float(np.max(rel) - np.min(rel))
        out["travel_arcsec"] = float((y[-1] - y[0]) * ARCSEC_PER_RAD)
    return out


def reversal_figures(t_s: np.ndarray, e_arcsec: np.ndarray, t_rev_s: Sequence[float],
                     half_window_s: float = 1.0) -> dict[str, Any]:
    """Peak error around velocity reversals.

    Parameters
    ----------
    t_s : ndarray
        Time, s.
    e_arcsec : ndarray
        Tracking error, arcsec.
    t_rev_s : sequence of float
        Reversal instants of the reference, s (those whose window lies inside
        the run are used).
    half_window_s : float
        Window [t_rev - w, t_rev + w] searched for the peak |e|, s.

    Returns
    -------
    dict
        ``peak_arcsec`` (largest |e| over all reversals), ``mean_peak_arcsec``,
        ``per_reversal_arcsec`` (list), ``t_reversal_s`` (list),
        ``rms_arcsec`` and ``max_arcsec`` over the whole run from the first window.
    """
    t = np.asarray(t_s, dtype=float)
    e = np.asarray(e_arcsec, dtype=float)
    peaks, used = [], []
    for tr in t_rev_s:
        if tr - half_window_s < t[0] or tr + half_window_s > t[-1]:
            continue
        m = (t >= tr - half_window_s) & (t <= tr + half_window_s)
        peaks.append(float(np.max(np.abs(e[m]))))
        used.append(float(tr))
    if not peaks:
        raise ValueError("reversal_figures: no reversal window inside the run")
    whole = rms_max(e[t >= used[0] - half_window_s])
    return {"peak_arcsec": max(peaks), "mean_peak_arcsec": float(np.mean(peaks)), "per_reversal_arcsec": peaks,
            "t_reversal_s": used, "half_window_s": half_window_s, "rms_arcsec": whole["rms"],
            "max_arcsec": whole["max"]}


def move_end_s(t_s: np.ndarray, setpoint_rad: np.ndarray) -> float:
    """Time at which the setpoint stops changing (end of a move), s."""
    sp = np.asarray(setpoint_rad, dtype=float)
    ch = np.flatnonzero(np.diff(sp) != 0.0)
    return float(t_s[ch[-1] + 1]) if ch.size else float(t_s[0])


def ptp_final(t_s: np.ndarray, e_arcsec: np.ndarray, t_end_s: float, window_s: float = 1.0,
              band_arcsec: float = 10.0) -> dict[str, Any]:
    """Final error of one point-to-point move.

    Parameters
    ----------
    t_s, e_arcsec : ndarray
        Time (s) and error (arcsec).
    t_end_s : float
        End of the reference move, s.
    window_s : float
        Final error = mean error over the last ``window_s`` s of the run.
    band_arcsec : float
        Band of the reported settling time.

    Returns
    -------
    dict
        ``final_error_arcsec``, ``final_error_max_arcsec``, ``settling_time_s``
        (after the end of the move, to ``band_arcsec``; None if never),
        ``peak_error_arcsec`` during the move.
    """
    t = np.asarray(t_s, dtype=float)
    e = np.asarray(e_arcsec, dtype=float)
    fin = e[t >= t[-1] - window_s]
    after = t >= t_end_s
    outside = np.flatnonzero(np.abs(e[after]) > band_arcsec)
    ta = t[after]
    if outside.size == 0:
        ts: float | None = 0.0
    elif outside[-1] == ta.size - 1:
        ts = None
    else:
        ts = float(ta[outside[-1] + 1] - t_end_s)
    return {"final_error_arcsec": float(np.mean(fin)), "final_error_max_arcsec": float(np.max(np.abs(fin))),
            "settling_time_s": ts, "peak_error_arcsec": float(np.max(np.abs(e)))}


# ------------------------------------------------------------------ running the set

@dataclass
class CaseRun:
    """A run case and its figures (``trace`` holds decimated signals for plots)."""

    case: Case
    figures: dict[str, Any]
    trace: dict[str, np.ndarray] = field(default_factory=dict)


def analyse(case: Case, r: sim.SimResult | Mapping[str, np.ndarray]) -> CaseRun:
    """Figures of one case from its run.

    Parameters
    ----------
    case : Case
    r : SimResult or mapping of columns
        Needs ``t_s``, ``setpoint_rad``, ``load_angle_true_rad`` and
        ``load_velocity_rad_s``; ``fault_code`` if present.

    Returns
    -------
    CaseRun
    """
    t = np.asarray(r["t_s"])
    e = error_arcsec(r)
    t0 = float(case.setpoint.get("t0_s", 0.0))
    sp = case.setpoint
    if case.kind == "step":
        fig = step_figures(t, r["setpoint_rad"], r["load_angle_true_rad"], t0)
    elif case.kind == "tracking":
        fig = tracking_figures(t, e, r["load_velocity_rad_s"], t0 + case.skip_s, float(sp["rate_rad_s"]),
                               r["load_angle_true_rad"])
        fig["rate_deg_s"] = float(sp["rate_rad_s"]) / RAD_PER_DEG
        st = (t >= t0) & (t < t0 + case.skip_s)
        fig["start_peak_arcsec"] = float(np.max(np.abs(e[st]))) if np.any(st) else 0.0
    elif case.kind == "reversal":
        f = float(sp["frequency_Hz"])
        ph = float(sp.get("phase_rad", 0.0))
        # reference ~ sin(2 pi f tau + ph): velocity zero where 2 pi f tau + ph = pi/2 + k pi
        k0 = math.ceil((ph - math.pi / 2) / math.pi + 1e-9)
        trev = []
        k = k0
        while True:
            tau = (math.pi / 2 + k * math.pi - ph) / (2 * math.pi * f)
            if tau > 0:
                if t0 + tau > t[-1]:
                    break
                trev.append(t0 + tau)
            k += 1
        fig = reversal_figures(t, e, trev, half_window_s=0.1 / f)
        fig["amplitude_deg"] = float(sp["amplitude_rad"]) / RAD_PER_DEG
        fig["frequency_Hz"] = f
    elif case.kind == "ptp":
        fig = ptp_final(t, e, move_end_s(t, r["setpoint_rad"]))
        fig["target_deg"] = float(sp["target_rad"]) / RAD_PER_DEG
    else:
        raise ValueError(f"unknown case kind {case.kind!r}")
    cols = r.columns if isinstance(r, sim.SimResult) else r
    if "fault_code" in cols:
        fig["fault_code"] = int(np.max(np.asarray(cols["fault_code"])))
    step = max(1, t.size // 4000)
    trace = {"t_s": t[::step], "e_arcsec": e[::step], "setpoint_rad": np.asarray(r["setpoint_rad"])[::step],
             "y_rad": np.asarray(r["load_angle_true_rad"])[::step]}
    return CaseRun(case, fig, trace)


def collect(runs: Sequence[CaseRun]) -> dict[str, Any]:
    """Figures dict of one axis from its case runs (the JSON layout of baseline.json).

    Returns
    -------
    dict
        ``tracking`` {speed key: figures}, ``step_100arcsec``, ``step_1deg``,
        ``ramp_1degps``, ``reversal``, ``ptp_12`` (``targets_deg``,
        ``final_error_arcsec`` per target, ``max_abs_final_error_arcsec``,
        ``rms_final_error_arcsec``, ``per_target``), and ``faults`` (max fault
        code over all runs, 0 = none).
    """
    out: dict[str, Any] = {"tracking": {}}
    ptp: list[dict[str, Any]] = []
    faults = 0
    for cr in runs:
        faults = max(faults, int(cr.figures.get("fault_code", 0)))
        if cr.case.kind == "ptp":
            ptp.append(cr.figures)
        elif cr.case.name.startswith("tracking_"):
            out["tracking"][speed_key(cr.figures["rate_deg_s"])] = cr.figures
        else:
            out[cr.case.key] = cr.figures
    if ptp:
        fe = np.array([p["final_error_arcsec"] for p in ptp])
        out["ptp_12"] = {"targets_deg": [p["target_deg"] for p in ptp], "final_error_arcsec": fe.tolist(),
                         "max_abs_final_error_arcsec": float(np.max(np.abs(fe))),
                         "rms_final_error_arcsec": float(np.sqrt(np.mean(fe ** 2))),
                         "max_settling_time_s_10arcsec": (None if any(p["settling_time_s"] is None for p in ptp)
                                                          else float(max(p["settling_time_s"] for p in ptp))),
                         "per_target": ptp}
    out["faults"] = faults
    return out


def run_cases(controller: Mapping[str, Any] | None = None, axis: str = "reference", *,
              cases: Sequence[Case] | None = None, seed: int = 1, effects: Mapping[str, bool] | None = None,
              params: Mapping[str, float | bool] | None = None,
              progress: Callable[[str], None] | None = None) -> tuple[dict[str, Any], list[CaseRun]]:
    """Run the standard cases with a controller configuration and return the figures.

    Parameters
    ----------
    controller : mapping, optional
        The scenario ``[controller]`` table (``gains``, ``compensators``, ...);
        None = the PID baseline of the axis (:func:`axis_controller`).  For a
        compensated run start from ``axis_controller(axis)`` and add to it.
    axis : str
        A key of :data:`AXES` (``"reference"``, ``"csf17_50"``) or an axis TOML path.
    cases : sequence of Case, optional
        Default :func:`standard_cases`.
    seed : int
        Sensor-noise seed of every run.
    effects, params : mapping, optional
        Plant effect switches / parameter overrides (default: the axis file as is,
        every effect on).
    progress : callable, optional
        Called with each case name before it runs.

    Returns
    -------
    figures : dict
        See :func:`collect`; plus ``axis`` and ``controller``.
    runs : list of CaseRun
        Per-case figures and decimated traces (for plots).
    """
    ctl = dict(axis_controller(axis) if controller is None else controller)
    runs = []
    for c in (standard_cases() if cases is None else cases):
        if progress:
            progress(c.name)
        runs.append(analyse(c, run_case(c, ctl, axis, seed, effects, params)))
    figs = collect(runs)
    figs["axis"] = axis
    figs["controller"] = json_ready(ctl)
    return figs, runs


def improvement(baseline: Mapping[str, Any], other: Mapping[str, Any], speed: str = "0.01") -> dict[str, float]:
    """How much better ``other`` is than ``baseline`` (figures of one axis).

    Parameters
    ----------
    baseline, other : mapping
        Figures dicts from :func:`run_cases` / baseline.json.
    speed : str
        Tracking speed key for the RMS ratio.

    Returns
    -------
    dict
        ``rms_ratio`` (baseline RMS / other RMS at ``speed``; the target is >= 5),
        ``reversal_peak_reduction_pct`` (100 (1 - other/baseline); target >= 70).
    """
    rb = baseline["tracking"][speed]["rms_arcsec"]
    ro = other["tracking"][speed]["rms_arcsec"]
    pb = baseline["reversal"]["peak_arcsec"]
    po = other["reversal"]["peak_arcsec"]
    return {"rms_ratio": float(rb / ro) if ro > 0 else float("inf"),
            "reversal_peak_reduction_pct": float(100.0 * (1.0 - po / pb))}


# ------------------------------------------------------------------ plots

def _plot_steps(name: str, steps: Sequence[CaseRun]) -> Any:
    """Step responses (setpoint and true output) and their error, one column per step case."""
    plt = pyplot()
    fig, axs = plt.subplots(2, len(steps), figsize=(5.5 * len(steps), 6.5), squeeze=False)
    for j, r in enumerate(steps):
        tr = r.trace
        t0 = float(r.case.setpoint["t0_s"])
        axs[0, j].plot(tr["t_s"] - t0, tr["setpoint_rad"] * ARCSEC_PER_RAD, "k--", lw=1, label="setpoint")
        axs[0, j].plot(tr["t_s"] - t0, tr["y_rad"] * ARCSEC_PER_RAD, lw=1, label="output (true)")
        axs[0, j].set_ylabel("output angle [arcsec]")
        f = r.figures
        axs[0, j].set_title(f"{name}: {r.case.label}\nrise {_fmt(f['rise_time_s'], 's')}, "
                            f"overshoot {f['overshoot_pct']:.1f} %, "
                            f"ts(2\") {_fmt(f['settling_time_s_2arcsec'], 's')}", fontsize=9)
        axs[0, j].legend(fontsize=8)
        axs[1, j].plot(tr["t_s"] - t0, tr["e_arcsec"], lw=1)
        for b in (2.0, 10.0):
            axs[1, j].axhline(b, color="grey", lw=0.5, ls=":")
            axs[1, j].axhline(-b, color="grey", lw=0.5, ls=":")
        lim = max(15.0, 1.2 * abs(f["final_error_arcsec"]) + 5)
        axs[1, j].set_ylim(-lim, lim)
        axs[1, j].set_ylabel("error [arcsec]")
        axs[1, j].set_xlabel("time after step [s]")
        for a in axs[:, j]:
            a.grid(True, alpha=0.3)
    return fig


def _plot_tracking(name: str, trk: Sequence[CaseRun]) -> Any:
    """Tracking error over time, one row per speed (the transient shaded)."""
    plt = pyplot()
    fig, axs = plt.subplots(len(trk), 1, figsize=(9, 2.4 * len(trk)), squeeze=False)
    for i, r in enumerate(trk):
        a = axs[i, 0]
        tr = r.trace
        a.plot(tr["t_s"], tr["e_arcsec"], lw=0.7)
        w0 = r.figures["window_s"][0]
        a.axvspan(tr["t_s"][0], w0, color="grey", alpha=0.15, lw=0)
        a.set_ylabel("error [arcsec]")
        a.set_title(f"{name}: {r.case.label}: RMS {r.figures['rms_arcsec']:.3g} arcsec, "
                    f"max {r.figures['max_arcsec']:.3g} arcsec (shaded: transient, excluded)", fontsize=9)
        a.grid(True, alpha=0.3)
    axs[-1, 0].set_xlabel("time [s]")
    return fig


def _plot_reversal(name: str, r: CaseRun) -> Any:
    """Setpoint and true output through the reversals, and the error (reversals dotted)."""
    plt = pyplot()
    tr = r.trace
    fig, axs = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    axs[0].plot(tr["t_s"], tr["setpoint_rad"] / RAD_PER_DEG, "k--", lw=1, label="setpoint")
    axs[0].plot(tr["t_s"], tr["y_rad"] / RAD_PER_DEG, lw=1, label="output (true)")
    axs[0].set_ylabel("output angle [deg]")
    axs[0].legend(fontsize=8)
    axs[1].plot(tr["t_s"], tr["e_arcsec"], lw=0.7)
    for trv in r.figures["t_reversal_s"]:
        for a in axs:
            a.axvline(trv, color="r", lw=0.6, ls=":")
    axs[1].set_ylabel("error [arcsec]")
    axs[1].set_xlabel("time [s]")
    axs[0].set_title(f"{name}: {r.case.label}: peak error at reversals {r.figures['peak_arcsec']:.3g} arcsec "
                     "(dotted: reversals)", fontsize=9)
    for a in axs:
        a.grid(True, alpha=0.3)
    return fig


def _plot_ptp(name: str, ptp: Sequence[CaseRun]) -> Any:
    """Final error per point-to-point target, and the error after the end of each move."""
    plt = pyplot()
    fig, axs = plt.subplots(2, 1, figsize=(9, 6))
    tg = [r.figures["target_deg"] for r in ptp]
    fe = [r.figures["final_error_arcsec"] for r in ptp]
    axs[0].bar(tg, fe, width=6.0)
    for b in (10.0, -10.0):
        axs[0].axhline(b, color="r", lw=0.6, ls=":")
    axs[0].set_xlabel("target [deg]")
    axs[0].set_ylabel("final error [arcsec]")
    axs[0].set_title(f"{name}: 12-position moves from 0, final error (dotted: 10 arcsec requirement)",
                     fontsize=9)
    for r in ptp:
        tr = r.trace
        te = move_end_s(tr["t_s"], tr["setpoint_rad"])
        axs[1].plot(tr["t_s"] - te, tr["e_arcsec"], lw=0.7)
    axs[1].set_ylim(-30, 30)
    axs[1].set_xlabel("time after end of move [s]")
    axs[1].set_ylabel("error [arcsec]")
    for a in axs:
        a.grid(True, alpha=0.3)
    return fig


def plot_axis(name: str, runs: Sequence[CaseRun], outdir: str | os.PathLike[str]) -> list[Path]:
    """PNG plots of one axis: step responses, tracking error per speed, ramp and
    reversal error, point-to-point final errors.

    Parameters
    ----------
    name : str
        Axis name (file prefix ``baseline_<name>_``).
    runs : sequence of CaseRun
    outdir : path-like

    Returns
    -------
    list of Path
        Files written.
    """
    plt = pyplot()
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    by = {r.case.name: r for r in runs}
    steps = [r for r in runs if r.case.kind == "step"]
    trk = [r for r in runs if r.case.kind == "tracking"]
    ptp = [r for r in runs if r.case.kind == "ptp"]
    figures: list[tuple[str, Callable[[], Any]]] = []
    if steps:
        figures.append(("steps", lambda: _plot_steps(name, steps)))
    if trk:
        figures.append(("tracking", lambda: _plot_tracking(name, trk)))
    if "reversal" in by:
        figures.append(("reversal", lambda: _plot_reversal(name, by["reversal"])))
    if ptp:
        figures.append(("ptp", lambda: _plot_ptp(name, ptp)))
    files: list[Path] = []
    for kind, draw in figures:
        fig = draw()
        fig.tight_layout()
        p = out / f"baseline_{name}_{kind}.png"
        save_figure_atomic(fig, p, dpi=110)
        plt.close(fig)
        files.append(p)
    return files


def _fmt(x: float | None, unit: str) -> str:
    return "n/a" if x is None else f"{x:.3g} {unit}"


def quick_cases() -> list[Case]:
    """Short versions of the standard cases (tests)."""
    return standard_cases(quick=True)


__all__ = ["ARCSEC_PER_RAD", "AXES", "Case", "CaseRun", "PTP_TARGETS_DEG", "TRACKING_SPEEDS_DEG_S", "analyse",
           "axis_controller", "axis_torque_limit", "collect", "error_arcsec", "improvement", "move_end_s", "plot_axis", "ptp_final",
           "quick_cases", "reversal_figures", "rms_max", "run_case", "run_cases", "scenario_text",
           "standard_cases", "speed_key", "step_figures", "tracking_figures"]
