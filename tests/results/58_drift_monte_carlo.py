#!/usr/bin/env python3
"""Adaptive control under drifting parameters: Monte Carlo over the model error.

Controllers (the fair-comparison rule of ``hdservo.compsetup``: every row runs with
the axis' PID design and ``FAIR_GAINS``):

* ``pid`` -- the fair PID, every compensator off;
* ``fixed`` -- Stribeck friction feed-forward from the model given to the drive;
* ``online`` -- the same feed-forward fed by the drive's online Stribeck
  estimator (``fe_enable`` 1, ``fe_feed`` 1), started from the same model;
* ``backstep`` -- adaptive backstepping, its initial parameters from the model.

Run-in (default; ``--no-run-in`` leaves it out): every case starts with two cycles of the
normal motion profile of the online identification (:func:`run_in_legs`), the same for every
controller; the case's setpoint follows.  The drive's online estimator runs during normal
motion: the first cycle fills its bins on the nominal axis, the drift happens at the start
of the second, which runs on the drifted axis before the figure is measured.

Scenarios (plant options of ``sim/plant``, docs/sim.md "Parameter drifts"), timed on a
window W: with the run-in the first :data:`RUN_IN_DRIFT_SHARE` of its last cycle, without it
each case's measurement window (after the case's transient skip S):

* ``nominal`` -- the axis file as is;
* ``friction_warm_cold`` -- friction x1.5 over 0.05-0.35 W, held, back to x1 over 0.65-0.95 W
  (with the run-in: back to x1 over 0.65-0.95 of the measurement window);
* ``inertia_x2`` -- load inertia doubled in one step at 0.3 W;
* ``gravity_appears`` -- an extra unbalance ramps in over 0.1-0.5 W; its size is the
  axis' output-side breakaway torque (motor static friction x ratio + load static friction);
* ``stiffness_m20`` -- stiffness -20 % over 0.1-0.5 W.

Monte Carlo: run r draws one factor in [1 - 0.3, 1 + 0.3] per model group (motor friction
levels, motor Stribeck velocity, motor viscous term, the same three of the load side,
load inertia, stiffness, unbalance) for the model given to the drive; every controller
and scenario of run r uses the same draw and the same sensor-noise seed (common random
numbers).  Tasks run in parallel processes.

Figures per run (arcsec): tracking RMS at 0.01 and 0.1 deg/s, peak error at the
reversals of a 1 deg 0.1 Hz sine, positioning accuracy A = span (max - min) of the
signed final errors over the point-to-point targets (ISO 230-2 A with one approach per
target).  Statistics: median and 95th percentile over the runs.  Gain of a controller =
median of the PID / median of the controller (> 1: better than the PID); retention =
gain under drift / gain on the nominal axis.  Target (per drift scenario, tracking RMS
checked on the figures where the fixed-model compensation gains >= 1.5 on the nominal axis):
wherever the fixed-model compensation loses its gain under a drift (retention < 0.9), each
adaptive variant keeps a gain >= 2 over the PID.

Writes build/results/drift_mc.json and build/results/drift_mc_<axis>.png.
Options: ``--runs N`` (default 50), ``--jobs N``, ``--quick`` (short cases), ``--no-run-in``,
``--axis NAME``, ``--out DIR``, ``--controllers a,b``, ``--scenarios a,b`` (subsets),
``--checkpoint FILE`` (each finished run is appended to FILE as a JSON line; runs already
in FILE for the same axis, seed and case set are not run again, so an interrupted study
resumes and a study can be run controller by controller).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo import closedloop_cases as bl  # noqa: E402
from hdservo import compsetup as cs  # noqa: E402
from hdservo import sim  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402
from hdservo.ident import stribeck_online as so  # noqa: E402

OUT = ROOT / "build" / "results"
FORMAT = "hdservo-drift-mc"
VERSION = 1
#: Relative model error of the Monte Carlo (uniform, +-).
MODEL_ERROR = 0.3
RUNS_DEFAULT = 50
CONTROLLERS: tuple[str, ...] = ("pid", "fixed", "online", "backstep")
ADAPTIVE: tuple[str, ...] = ("online", "backstep")
SCENARIOS: tuple[str, ...] = ("nominal", "friction_warm_cold", "inertia_x2", "gravity_appears", "stiffness_m20")
#: Figure key -> unit; lower is better for every one.
FIGURES: dict[str, str] = {"tracking_0.01_rms_arcsec": "arcsec", "tracking_0.1_rms_arcsec": "arcsec",
                           "reversal_peak_arcsec": "arcsec", "positioning_A_arcsec": "arcsec"}
#: Figure of the plots' and tests' headline.
TARGET_FIGURE = "tracking_0.01_rms_arcsec"
#: Gain the adaptive variants keep under drift (median PID / median controller).
TARGET_GAIN = 2.0
#: The target is checked on the figures where the fixed-model compensation gains at least this on
#: the nominal axis (the figures the compensation is for).
MIN_NOMINAL_GAIN = 1.5
#: The fixed-model compensation "loses" its gain under a drift when it keeps less than this share.
LOSS_RETENTION = 0.9
#: Run-in (default on): cycles of the normal motion profile before every case, the same
#: for every controller; the drift happens at the start of the last cycle (:func:`with_run_in`).
RUN_IN_DEFAULT = True
#: Cycles of the normal motion profile in the run-in.
RUN_IN_CYCLES = 2
#: Acceleration of the run-in's moves, deg/s^2 (the normal profile's).
RUN_IN_AMAX_DEG_S2 = 100.0
#: Rest at the start position between the run-in's end and the case's setpoint, s.
RUN_IN_HOLD_S = 1.0
#: With a run-in, the drifts take place within this share of its last cycle, from its start.
RUN_IN_DRIFT_SHARE = 0.1
#: Model groups perturbed together: group -> keys of the axis model (SI).
MODEL_GROUPS: dict[str, tuple[str, ...]] = {
    "motor_levels": ("friction_motor.fc_pos_Nm", "friction_motor.fc_neg_Nm", "friction_motor.fs_pos_Nm",
                     "friction_motor.fs_neg_Nm"),
    "motor_vs": ("friction_motor.vs_rad_s",),
    "motor_viscous": ("friction_motor.viscous_Nms_per_rad",),
    "load_levels": ("friction_load.fc_pos_Nm", "friction_load.fc_neg_Nm", "friction_load.fs_pos_Nm",
                    "friction_load.fs_neg_Nm"),
    "load_vs": ("friction_load.vs_rad_s",),
    "load_viscous": ("friction_load.viscous_Nms_per_rad",),
    "inertia": ("load.jl_kgm2",),
    "stiffness": ("stiffness.k1_Nm_per_rad",),
    "unbalance": ("gravity.mgl_Nm",),
}


# ------------------------------------------------------------------ cases and scenarios

def cases(quick: bool = False) -> list[bl.Case]:
    """The cases behind the four figures.

    Parameters
    ----------
    quick : bool
        Short durations (tests): tracking 3 s, reversal 7 s (one reversal), 2 targets.

    Returns
    -------
    list of Case
        ``tracking_0.01`` (20 s after a 5 s transient), ``tracking_0.1`` (8 s after 2 s),
        ``reversal`` (12 s: 2 reversals), 4 point-to-point moves (-55, -25, 5, 35 deg).
    """
    std = bl.standard_cases(quick=quick)
    out: list[bl.Case] = []
    ptp = [c for c in std if c.kind == "ptp"]
    for c in std:
        if c.name in ("tracking_0.01", "tracking_0.1"):
            if not quick:
                dur, skip = (20.0, 5.0) if c.name == "tracking_0.01" else (8.0, 2.0)
                c = dataclasses.replace(c, duration_s=0.1 + skip + dur, skip_s=skip)
            out.append(c)
        elif c.kind == "reversal":
            out.append(c if quick else dataclasses.replace(c, duration_s=0.1 + 12.0))
    out += ptp if quick else ptp[::3]
    return out


def _window(case: bl.Case) -> tuple[float, float]:
    """Start and length of a case's measurement window, s (after its transient skip)."""
    t0 = float(case.setpoint.get("t0_s", 0.1)) - 0.1      # 0 without a run-in
    s = t0 + float(case.skip_s)
    return s, max(float(case.duration_s) - s, 1e-3)


def run_in_legs(cycles: int = 2, v_min_deg_s: float = 0.01, v_max_deg_s: float = 10.0
                ) -> tuple[list[float], list[float], list[float]]:
    """The run-in: ``cycles`` cycles of the normal motion profile, then back to the start.

    The profile is the online identification's (:func:`hdservo.ident.stribeck_online.normal_profile`):
    10 log-spaced speeds from ``v_min`` to ``v_max``, a move each way per speed, each entered in
    its own direction; a last move at ``v_max`` returns to the start so that the case's
    setpoint begins where the run-in ends.

    Returns
    -------
    (list of float, list of float, list of float)
        Move end positions relative to the start (rad), cruise speeds (rad/s) and the start
        time of each cycle after the run-in's start (s; trapezoid moves at
        :data:`RUN_IN_AMAX_DEG_S2`, one after another), with the run-in's length last.
    """
    legs = so.normal_profile(v_min_deg_s, v_max_deg_s) * cycles
    targets = [float(g.target_rad) for g in legs] + [0.0]
    speeds = [float(g.v_rad_s) for g in legs] + [math.radians(v_max_deg_s)]
    per = len(legs) // cycles
    amax = math.radians(RUN_IN_AMAX_DEG_S2)
    t, prev, starts = 0.0, 0.0, []
    for i, (x, v) in enumerate(zip(targets, speeds)):
        if i % per == 0 and len(starts) < cycles:
            starts.append(t)
        d = abs(x - prev)
        ta = v / amax
        t += 2.0 * math.sqrt(d / amax) if amax * ta * ta > d else 2.0 * ta + (d - amax * ta * ta) / v
        prev = x
    return targets, speeds, starts + [t]


def with_run_in(case: bl.Case, run_in: bool) -> bl.Case:
    """The case with the run-in before its setpoint (and the same setpoint, later), or as is.

    The run-in (:func:`run_in_legs`, :data:`RUN_IN_CYCLES` cycles) starts at the case's t0
    (0.1 s); the case's setpoint starts :data:`RUN_IN_HOLD_S` after its end (rounded up to
    0.1 s), the case's duration after that and its skip are kept.
    """
    if not run_in:
        return case
    tg, sp, starts = run_in_legs(RUN_IN_CYCLES)
    t_run = float(case.setpoint.get("t0_s", 0.1))
    t0 = math.ceil((t_run + starts[-1] + RUN_IN_HOLD_S) * 10.0) / 10.0
    setpoint = {**case.setpoint, "t0_s": t0, "run_in_targets_rad": tg, "run_in_speeds_rad_s": sp,
                "run_in_accel_rad_s2": math.radians(RUN_IN_AMAX_DEG_S2), "run_in_t0_s": t_run}
    return dataclasses.replace(case, setpoint=setpoint, duration_s=float(case.duration_s) + (t0 - t_run))


def _drift_window(case: bl.Case) -> tuple[float, float]:
    """Start and length of the window a drift is timed on, s.

    Without a run-in the case's measurement window (the drift happens while the figure is
    measured).  With one, the first :data:`RUN_IN_DRIFT_SHARE` of the run-in's last cycle:
    the drive has run the profile on the nominal axis before (the estimator's bins are
    established, as in a drive that has been in service), the drift happens, and the last
    cycle runs on the drifted axis before the measurement.
    """
    if "run_in_t0_s" not in case.setpoint:
        return _window(case)
    _, _, starts = run_in_legs(RUN_IN_CYCLES)
    t_run = float(case.setpoint["run_in_t0_s"])
    return t_run + starts[-2], RUN_IN_DRIFT_SHARE * (starts[-1] - starts[-2])


def breakaway_Nm(axis: str) -> float:
    """Output-side breakaway torque of an axis: motor static friction x ratio + load static friction, N.m."""
    spec = bl._axis_spec(axis)
    n = float(sim.axis_param("gear.ratio", spec))
    tot = 0.0
    for sec, scale in (("friction_motor", n), ("friction_load", 1.0)):
        if bool(sim.axis_param(f"{sec}.enabled", spec)):
            tot += scale * max(float(sim.axis_param(f"{sec}.fs_pos_Nm", spec)),
                               float(sim.axis_param(f"{sec}.fs_neg_Nm", spec)))
    return tot


def scenario_plant(name: str, case: bl.Case, axis: str) -> dict[str, float | bool]:
    """Plant overrides of a drift scenario for one case (docs/sim.md "Parameter drifts").

    Parameters
    ----------
    name : str
        A key of :data:`SCENARIOS`.
    case : Case
        The case (its window times the drift).
    axis : str
        Axis spec (the unbalance of ``gravity_appears`` is its breakaway torque).

    Returns
    -------
    dict
        ``{"section.key": value}`` (SI); empty for ``nominal``.
    """
    s, w = _drift_window(case)
    if name == "nominal":
        return {}
    if name == "friction_warm_cold":
        if "run_in_t0_s" in case.setpoint:
            # warm during the run-in, back to cold over 0.65-0.95 of the measurement window
            ms, mw = _window(case)
            t_warm = s + 0.35 * w
            return {"friction_drift.enabled": True, "friction_drift.t_start_s": s + 0.05 * w,
                    "friction_drift.ramp_s": 0.3 * w, "friction_drift.scale": 1.5,
                    "friction_drift.hold_s": ms + 0.65 * mw - t_warm, "friction_drift.return_s": 0.3 * mw}
        return {"friction_drift.enabled": True, "friction_drift.t_start_s": s + 0.05 * w,
                "friction_drift.ramp_s": 0.3 * w, "friction_drift.scale": 1.5,
                "friction_drift.hold_s": 0.3 * w, "friction_drift.return_s": 0.3 * w}
    if name == "inertia_x2":
        return {"inertia_drift.enabled": True, "inertia_drift.t_start_s": s + 0.3 * w,
                "inertia_drift.ramp_s": 1e-3, "inertia_drift.scale": 2.0}
    if name == "gravity_appears":
        spec = bl._axis_spec(axis)
        mgl0 = float(sim.axis_param("gravity.mgl_Nm", spec)) if bool(sim.axis_param("gravity.enabled", spec)) else 0.0
        return {"gravity_drift.enabled": True, "gravity_drift.t_start_s": s + 0.1 * w,
                "gravity_drift.ramp_s": 0.4 * w, "gravity_drift.mgl_Nm": mgl0 + breakaway_Nm(axis)}
    if name == "stiffness_m20":
        return {"stiffness_drift.enabled": True, "stiffness_drift.t_start_s": s + 0.1 * w,
                "stiffness_drift.ramp_s": 0.4 * w, "stiffness_drift.scale": 0.8}
    raise ValueError(f"unknown scenario {name!r}; expected one of {', '.join(SCENARIOS)}")


# ------------------------------------------------------------------ model and controllers

def model_factors(run: int, seed: int = 1) -> dict[str, float]:
    """Model-error factors of Monte Carlo run ``run``: group -> factor in [1 - e, 1 + e], e = MODEL_ERROR."""
    rng = np.random.default_rng([seed, run])
    return {g: float(1.0 + MODEL_ERROR * rng.uniform(-1.0, 1.0)) for g in MODEL_GROUPS}


def perturbed_model(axis: str, factors: Mapping[str, float]) -> dict[str, float]:
    """The model given to the drive: the axis' true values times the group factors (SI).

    With it the motor side's share of the total friction, as ``hdservo download`` writes it
    (:func:`hdservo.download.motor_share`: motor breakaway x ratio / total breakaway, here
    of the perturbed levels): the Stribeck levels and the online estimator's feed
    (``fe_share``) relay that share, in every friction feed-forward of the study.
    """
    spec = bl._axis_spec(axis)
    out: dict[str, float] = {}
    for g, keys in MODEL_GROUPS.items():
        for k in keys:
            out[k] = float(sim.axis_param(k, spec)) * float(factors[g])
    n = float(sim.axis_param("gear.ratio", spec))
    on = {sec: bool(sim.axis_param(f"{sec}.enabled", spec)) for sec in ("friction_motor", "friction_load")}
    fsm = n * (out["friction_motor.fs_pos_Nm"] + out["friction_motor.fs_neg_Nm"]) if on["friction_motor"] else 0.0
    fsl = (out["friction_load.fs_pos_Nm"] + out["friction_load.fs_neg_Nm"]) if on["friction_load"] else 0.0
    if fsm > 0.0:
        out[cs.MOTOR_SHARE_KEY] = min(1.0, fsm / (fsm + fsl))
    return out


def controller_table(name: str, axis: str, model: Mapping[str, float]) -> dict[str, Any]:
    """Scenario ``[controller]`` table of a controller with a (perturbed) model.

    Parameters
    ----------
    name : str
        A key of :data:`CONTROLLERS`.
    axis : str
        Axis spec.
    model : mapping
        ``{"section.key": value}`` given to the drive (SI).

    Returns
    -------
    dict
    """
    spec = bl._axis_spec(axis)
    params = cs.compensator_params(spec, model=model)
    gains = dict(cs.FAIR_GAINS)
    if name == "pid":
        return cs.controller(axis, [], params=params, extra_gains=gains)
    if name in ("fixed", "online"):
        gains.update(cs.COMPONENT_PARAMS["stribeck"])
        if name == "online":
            gains.update({"fe_enable": 1.0, "fe_feed": 1.0})
        return cs.controller(axis, ["stribeck"], params=params, extra_gains=gains)
    if name == "backstep":
        return cs.controller(axis, ["backstep"], params=params, extra_gains=gains)
    raise ValueError(f"unknown controller {name!r}; expected one of {', '.join(CONTROLLERS)}")


# ------------------------------------------------------------------ one run

def figures_of(figs: Mapping[str, Any]) -> dict[str, float | None]:
    """The four figures of one run from :func:`hdservo.closedloop_cases.collect` output (arcsec)."""
    trk = figs.get("tracking", {})
    out: dict[str, float | None] = {
        "tracking_0.01_rms_arcsec": trk.get("0.01", {}).get("rms_arcsec"),
        "tracking_0.1_rms_arcsec": trk.get("0.1", {}).get("rms_arcsec"),
        "reversal_peak_arcsec": figs.get("reversal", {}).get("peak_arcsec"),
        "positioning_A_arcsec": None}
    fe = figs.get("ptp_12", {}).get("final_error_arcsec")
    if fe:
        out["positioning_A_arcsec"] = float(np.max(fe) - np.min(fe))
    return {k: (None if v is None or not math.isfinite(float(v)) else float(v)) for k, v in out.items()}


def estimator_state(meta: Mapping[str, Any]) -> dict[str, Any] | None:
    """The online friction estimator when the measurement starts, from a run's sidecar.

    Parameters
    ----------
    meta : mapping
        :attr:`hdservo.sim.SimResult.meta` (its ``fric_est``: the model given to the drive,
        the estimator at the end of the run-in and at the end of the run).

    Returns
    -------
    dict or None
        ``fits`` [pos, neg] (accepted fits), ``confidence`` [pos, neg], ``scale``, ``bias_Nm``
        and ``change`` {``fc_pos``, ``fs_pos``, ``vs_pos``, ``fc_neg``, ...}: the fed estimate
        relative to the model given to the drive (0: unchanged); None without the estimator.
    """
    fe = meta.get("fric_est")
    if not fe:
        return None
    st = fe.get("run_in_end", fe["end"])
    change = {}
    for d in ("pos", "neg"):
        for k, key in (("fc", "fc_Nm"), ("fs", "fs_Nm"), ("vs", "vs_rad_s")):
            m = float(fe["model"][d][key])
            change[f"{k}_{d}"] = float(st["estimate"][d][key]) / m - 1.0 if m > 0 else 0.0
    return {"fits": [int(x) for x in st["fits"]], "confidence": [float(x) for x in st["confidence"]],
            "scale": float(st["scale"]), "bias_Nm": float(st["bias_Nm"]), "change": change}


def run_task(task: tuple[str, str, str, int, int, bool] | tuple[str, str, str, int, int, bool, bool]
             ) -> dict[str, Any]:
    """One Monte Carlo sample: (axis, scenario, controller, run, seed, quick[, run_in]) -> figures row.

    With the online estimator the row also holds ``fric_est`` (:func:`estimator_state` of the
    reversal case: the estimate the reversal peak is measured with).
    """
    axis, scen, ctl, run, seed, quick = task[:6]
    run_in = bool(task[6]) if len(task) > 6 else False
    factors = model_factors(run, seed)
    table = controller_table(ctl, axis, perturbed_model(axis, factors))
    runs = []
    est = None
    for c0 in cases(quick):
        c = with_run_in(c0, run_in)
        r = bl.run_case(c, table, axis, seed + run, params=scenario_plant(scen, c, axis) or None)
        runs.append(bl.analyse(c, r))
        if c.kind == "reversal":
            est = estimator_state(r.meta)
    figs = bl.collect(runs)
    row = {"scenario": scen, "controller": ctl, "run": run, "factors": factors,
           "faults": int(figs["faults"]), **figures_of(figs)}
    if est is not None:
        row["fric_est"] = est
    return row


# ------------------------------------------------------------------ statistics

def stats(values: Sequence[float | None]) -> dict[str, Any]:
    """Median and 95th percentile (linear interpolation) of the finite values; ``n`` used, ``missing``."""
    v = np.array([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    if v.size == 0:
        return {"median": None, "p95": None, "n": 0, "missing": len(values)}
    return {"median": float(np.median(v)), "p95": float(np.percentile(v, 95.0)), "n": int(v.size),
            "missing": len(values) - int(v.size)}


def summarise(rows: Sequence[Mapping[str, Any]], controllers: Sequence[str],
              scenarios: Sequence[str]) -> dict[str, Any]:
    """Statistics, gains, retentions and the target check of a set of rows.

    Returns
    -------
    dict
        ``stats`` {scenario: {controller: {figure: {median, p95, n, missing}}}},
        ``gain`` {scenario: {controller: {figure: median PID / median controller}}},
        ``retention`` {drift scenario: {controller: {figure: gain / nominal gain}}},
        ``target``: ``figures`` checked (fixed-model nominal gain >= MIN_NOMINAL_GAIN),
        ``per_scenario`` {drift scenario: {figure: gains, retentions, ``met``}},
        ``where_fixed_loses`` (``scenario/figure``: retention < LOSS_RETENTION) and ``met``
        (every adaptive variant keeps a gain >= TARGET_GAIN wherever the fixed-model
        compensation loses; None when it loses nowhere).
    """
    st: dict[str, Any] = {}
    for s in scenarios:
        st[s] = {}
        for c in controllers:
            sel = [r for r in rows if r["scenario"] == s and r["controller"] == c]
            st[s][c] = {f: stats([r[f] for r in sel]) for f in FIGURES}
            st[s][c]["faulted_runs"] = sum(1 for r in sel if r["faults"])
    gain: dict[str, Any] = {}
    for s in scenarios:
        gain[s] = {}
        for c in controllers:
            gain[s][c] = {}
            for f in FIGURES:
                p, x = st[s].get("pid", {}).get(f, {}).get("median"), st[s][c][f]["median"]
                gain[s][c][f] = (p / x) if p is not None and x is not None and x > 0 else None
    ret: dict[str, Any] = {}
    target: dict[str, Any] = {}
    drifts = [s for s in scenarios if s != "nominal"]
    for s in drifts:
        if "nominal" not in gain:
            break
        ret[s] = {c: {f: (gain[s][c][f] / gain["nominal"][c][f]
                          if gain[s][c][f] is not None and gain["nominal"][c][f] else None) for f in FIGURES}
                  for c in controllers}
    # figures the compensation is for: the fixed-model compensation gains >= MIN_NOMINAL_GAIN there
    figs = [f for f in FIGURES if "nominal" in gain and "fixed" in gain["nominal"]
            and (gain["nominal"]["fixed"][f] or 0.0) >= MIN_NOMINAL_GAIN]
    for s in ret:
        target[s] = {}
        for f in figs:
            fr = ret[s]["fixed"][f]
            entry: dict[str, Any] = {"fixed_gain": gain[s]["fixed"][f], "fixed_retention": fr,
                                     "fixed_loses_gain": fr is not None and fr < LOSS_RETENTION}
            keeps = []
            for a in ADAPTIVE:
                if a in controllers:
                    g = gain[s][a][f]
                    entry[f"{a}_gain"] = g
                    entry[f"{a}_retention"] = ret[s][a][f]
                    entry[f"{a}_keeps_gain"] = g is not None and g >= TARGET_GAIN
                    keeps.append(entry[f"{a}_keeps_gain"])
            entry["met"] = bool(keeps) and all(keeps)
            target[s][f] = entry
    losing = [(s, f) for s in target for f in target[s] if target[s][f]["fixed_loses_gain"]]
    target_all = {"figures": figs, "min_nominal_gain": MIN_NOMINAL_GAIN, "loss_retention": LOSS_RETENTION,
                  "gain_required": TARGET_GAIN, "per_scenario": target,
                  "where_fixed_loses": [f"{s}/{f}" for s, f in losing],
                  "met": (all(target[s][f]["met"] for s, f in losing) if losing else None)}
    return {"stats": st, "gain": gain, "retention": ret, "target": target_all}


def run_in_info(run_in: bool) -> dict[str, Any]:
    """How the cases start: the run-in's rule, moves and length, and where the drifts happen."""
    if not run_in:
        return {"enabled": False, "drifts": "in each case's measurement window"}
    tg, _, starts = run_in_legs(RUN_IN_CYCLES)
    c = with_run_in(cases(False)[0], True)
    t_run = float(c.setpoint["run_in_t0_s"])
    return {"enabled": True, "rule": f"{RUN_IN_CYCLES} cycles of hdservo.ident.stribeck_online.normal_profile "
                                     "(10 log-spaced speeds 0.01..10 deg/s, a move each way per speed, each "
                                     "entered in its own direction), then back to the start; the same for every "
                                     "controller and case",
            "cycles": RUN_IN_CYCLES, "moves": len(tg), "start_s": t_run,
            "cycle_start_s": [t_run + x for x in starts[:-1]], "end_s": t_run + starts[-1],
            "measurement_setpoint_start_s": float(c.setpoint["t0_s"]),
            "drifts": f"within the first {RUN_IN_DRIFT_SHARE:g} of the last cycle (friction_warm_cold: warm "
                      "there, back to cold over 0.65-0.95 of the measurement window)"}


def estimator_summary(rows: Sequence[Mapping[str, Any]], scenarios: Sequence[str]) -> dict[str, Any]:
    """What the online estimator did before the reversal case's measurement, per scenario.

    Returns
    -------
    dict
        {scenario: ``runs``, ``runs_fitted`` (an accepted fit in both directions),
        ``fits_median`` [pos, neg], ``max_abs_change_median`` (median over the runs of the
        largest relative change of fc, fs, vs of the fed estimate against the model given to
        the drive), ``scale_median``, ``bias_Nm_median``}; scenarios without online rows are left out.
    """
    out: dict[str, Any] = {}
    for s in scenarios:
        sel = [r["fric_est"] for r in rows if r["scenario"] == s and r.get("fric_est")]
        if not sel:
            continue
        out[s] = {"runs": len(sel), "runs_fitted": sum(1 for e in sel if min(e["fits"]) > 0),
                  "fits_median": [float(np.median([e["fits"][i] for e in sel])) for i in (0, 1)],
                  "max_abs_change_median": float(np.median([max(abs(v) for v in e["change"].values())
                                                            for e in sel])),
                  "scale_median": float(np.median([e["scale"] for e in sel])),
                  "bias_Nm_median": float(np.median([e["bias_Nm"] for e in sel]))}
    return out


# ------------------------------------------------------------------ plots

def plot(res: Mapping[str, Any], axis: str, out: Path) -> list[Path]:
    """Median bars with 95th-percentile whiskers per figure, scenario and controller."""
    from hdservo.plotting import pyplot
    plt = pyplot()
    st = res["stats"]
    scen, ctls = list(res["scenarios"]), list(res["controllers"])
    fig, axs = plt.subplots(1, len(FIGURES), figsize=(4.4 * len(FIGURES), 4.4))
    x = np.arange(len(scen))
    wdt = 0.8 / max(len(ctls), 1)
    for a, f in zip(np.atleast_1d(axs), FIGURES):
        positive = False
        for i, c in enumerate(ctls):
            med = np.array([st[s][c][f]["median"] or np.nan for s in scen], dtype=float)
            p95 = np.array([st[s][c][f]["p95"] or np.nan for s in scen], dtype=float)
            a.bar(x + (i - (len(ctls) - 1) / 2) * wdt, med, wdt, label=c,
                  yerr=[np.zeros_like(med), np.nan_to_num(np.clip(p95 - med, 0.0, None))], capsize=2)
            positive = positive or bool(np.any(med > 0.0))
        a.set_xticks(x)
        a.set_xticklabels(scen, rotation=40, fontsize=7, ha="right")
        if positive:                    # a figure the grid did not measure stays linear (empty)
            a.set_yscale("log")
        a.set_ylabel(f"{f} (median, bar to p95)", fontsize=8)
        a.grid(True, alpha=0.3, axis="y")
    np.atleast_1d(axs)[0].legend(fontsize=7)
    fig.suptitle(f"{axis}: drift scenarios, {res['runs_per_controller']} runs per controller, "
                 f"model error +-{100 * MODEL_ERROR:g} %", fontsize=10)
    fig.tight_layout()
    p = out / f"drift_mc_{Path(axis).stem}.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return [p]


# ------------------------------------------------------------------ main

def _task_key(task: tuple[str, str, str, int, int, bool] | tuple[str, str, str, int, int, bool, bool]) -> str:
    """Checkpoint key of a task: axis, scenario, controller, run, seed, quick (and ``run-in``)."""
    axis, scen, ctl, run_, seed, quick = task[:6]
    key = f"{axis}|{scen}|{ctl}|{run_}|{seed}|{int(quick)}"
    return key + "|run-in" if len(task) > 6 and task[6] else key


def load_checkpoint(path: Path | None) -> dict[str, dict[str, Any]]:
    """Rows of a checkpoint file (JSON lines ``{"key": ..., "row": ...}``) by task key.

    A missing file gives no rows; an unreadable line (a run cut off while it was written)
    is skipped, so that run is done again.
    """
    out: dict[str, dict[str, Any]] = {}
    if path is None or not path.is_file():
        return out
    for line in path.read_text().splitlines():
        try:
            rec = json.loads(line)
            out[str(rec["key"])] = dict(rec["row"])
        except (ValueError, KeyError, TypeError):
            continue
    return out


def timed_task(task: tuple[Any, ...]) -> dict[str, Any]:
    """:func:`run_task` with its own wall-clock time in the row (``run_time_s``, s), so that the time a
    run took travels with it through a checkpoint into the study that merges it."""
    t0 = time.perf_counter()
    row = run_task(task)
    return {**row, "run_time_s": time.perf_counter() - t0}


def time_of_runs(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Sum of the runs' own times (s) and how many rows carry one (checkpoint rows written without it
    count in ``runs_without_time``)."""
    t = [float(r["run_time_s"]) for r in rows if isinstance(r.get("run_time_s"), (int, float))]
    return {"run_time_s": float(sum(t)), "runs_timed": len(t), "runs_without_time": len(rows) - len(t)}


def run_tasks(tasks: Sequence[tuple[Any, ...]], jobs: int | None,
              checkpoint: Path | None = None) -> list[dict[str, Any]]:
    """Rows of the tasks, in task order; those in ``checkpoint`` are taken from it, the others
    run (in parallel processes when ``jobs`` > 1) and are appended to it as they finish.  Each row
    that runs here carries its own time, ``run_time_s`` (:func:`timed_task`)."""
    done = load_checkpoint(checkpoint)
    todo = [t for t in tasks if _task_key(t) not in done]
    fh = None
    if checkpoint is not None:
        checkpoint.parent.mkdir(parents=True, exist_ok=True)
        fh = checkpoint.open("a")

    def keep(t: tuple[Any, ...], row: dict[str, Any]) -> None:
        done[_task_key(t)] = row
        if fh is not None:
            fh.write(json.dumps({"key": _task_key(t), "row": row}) + "\n")
            fh.flush()

    try:
        nj = max(1, min(jobs or (os.cpu_count() or 1), max(len(todo), 1)))
        if nj == 1:
            for t in todo:
                keep(t, timed_task(t))
        else:
            ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else None)
            with ProcessPoolExecutor(max_workers=nj, mp_context=ctx) as ex:
                futs = {ex.submit(timed_task, t): t for t in todo}
                for f in as_completed(futs):
                    keep(futs[f], f.result())
    finally:
        if fh is not None:
            fh.close()
    return [done[_task_key(t)] for t in tasks]


def run(axis: str = "reference", runs: int = RUNS_DEFAULT, jobs: int | None = None, quick: bool = False,
        controllers: Sequence[str] = CONTROLLERS, scenarios: Sequence[str] = SCENARIOS, seed: int = 1,
        out: Path = OUT, plots: bool = True, checkpoint: Path | None = None,
        run_in: bool = RUN_IN_DEFAULT) -> dict[str, Any]:
    """Run the study and write ``out/drift_mc.json`` (and the plot); returns the JSON object.

    ``checkpoint``: a JSON-lines file of finished runs (:func:`run_tasks`), or None.
    ``run_in``: every case starts with the run-in (:func:`with_run_in`), the drifts in it.

    Times (s): ``run_time_s`` is the study's: the sum of its runs' own times, whichever
    invocation ran them (a study merged from a checkpoint counts the runs it took from there);
    ``wall_time_s`` is this invocation's wall-clock time and ``merge_time_s`` the part of it
    outside the runs it made (the checkpoint, the statistics, the plots, the file).
    """
    t0 = time.perf_counter()
    tasks = [(axis, s, c, r, seed, quick, run_in) for s in scenarios for c in controllers for r in range(runs)]
    t_runs = time.perf_counter()
    n_done = len(load_checkpoint(checkpoint).keys() & {_task_key(t) for t in tasks})
    rows = run_tasks(tasks, jobs, checkpoint)
    runs_wall = time.perf_counter() - t_runs if n_done < len(tasks) else 0.0
    res: dict[str, Any] = {"format": FORMAT, "version": VERSION, "axis": axis, "quick": quick,
                           "runs_per_controller": runs, "model_error": MODEL_ERROR, "seed": seed,
                           "controllers": list(controllers), "scenarios": list(scenarios),
                           "figures": dict(FIGURES), "model_groups": {g: list(k) for g, k in MODEL_GROUPS.items()},
                           "cases": [c.name for c in cases(quick)], "run_in": run_in_info(run_in)}
    res.update(summarise(rows, controllers, scenarios))
    res["estimator"] = estimator_summary(rows, scenarios)
    res["runs"] = rows
    out.mkdir(parents=True, exist_ok=True)
    res["plots"] = [p.name for p in plot(res, axis, out)] if plots else []
    res.update(time_of_runs(rows))
    res["wall_time_s"] = time.perf_counter() - t0
    res["merge_time_s"] = res["wall_time_s"] - runs_wall
    write_json_atomic(out / "drift_mc.json", res, indent=1)
    return res


def _names(text: str, allowed: Sequence[str], opt: str) -> list[str] | None:
    """A comma-separated subset of ``allowed`` in the order given; None (after one error line) if a name is unknown."""
    names = [x.strip() for x in text.split(",") if x.strip()]
    bad = [x for x in names if x not in allowed]
    if bad or not names:
        print(f"58_drift_monte_carlo: {opt}: unknown name {bad[0] if bad else repr(text)}; "
              f"expected a comma-separated subset of {', '.join(allowed)}", file=sys.stderr)
        return None
    return names


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--axis", default="reference", help="axis key or TOML path (default reference)")
    ap.add_argument("--runs", type=int, default=RUNS_DEFAULT, help="Monte Carlo runs per controller and scenario")
    ap.add_argument("--jobs", type=int, default=None, help="parallel processes (default: CPU count)")
    ap.add_argument("--quick", action="store_true", help="short cases (a smoke run, not the study)")
    ap.add_argument("--out", type=Path, default=OUT, help="output directory (default build/results)")
    ap.add_argument("--controllers", default=",".join(CONTROLLERS),
                    help=f"comma-separated controllers (default all: {','.join(CONTROLLERS)})")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS),
                    help=f"comma-separated scenarios (default all: {','.join(SCENARIOS)})")
    ap.add_argument("--checkpoint", type=Path, default=None,
                    help="JSON-lines file of finished runs: appended to, and runs in it are not run again")
    ap.add_argument("--no-run-in", action="store_true",
                    help="no run-in: each case starts its setpoint at once and the drift happens while it is measured")
    a = ap.parse_args(argv)
    if a.runs < 1:
        print(f"58_drift_monte_carlo: --runs: expected an integer >= 1, found {a.runs}", file=sys.stderr)
        return 2
    ctls = _names(a.controllers, CONTROLLERS, "--controllers")
    scens = _names(a.scenarios, SCENARIOS, "--scenarios")
    if ctls is None or scens is None:
        return 2
    res = run(a.axis, a.runs, a.jobs, a.quick, controllers=ctls, scenarios=scens, out=a.out,
              checkpoint=a.checkpoint, run_in=not a.no_run_in)
    for s in res["scenarios"]:
        for c in res["controllers"]:
            m = res["stats"][s][c]
            print(f"  {s:20s} {c:9s} " + " ".join(
                f"{f.split('_arcsec')[0]} {m[f]['median'] if m[f]['median'] is not None else float('nan'):.3g}"
                f"/{m[f]['p95'] if m[f]['p95'] is not None else float('nan'):.3g}" for f in FIGURES))
    t = res["target"]
    print(f"target on {', '.join(t['figures']) or 'no figure'}: fixed-model loses its gain in "
          f"{', '.join(t['where_fixed_loses']) or 'no scenario'}; adaptive gain >= {TARGET_GAIN:g} there: {t['met']}")
    print(f"wrote {a.out / 'drift_mc.json'} (runs {res['run_time_s']:.0f} s in all over {res['runs_timed']} timed "
          f"runs; this invocation {res['wall_time_s']:.0f} s, of which {res['merge_time_s']:.0f} s outside the runs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
