"""Prediction vs measurement: the design flow's chosen axis served as a virtual drive.

Chain (docs/design-flow.md section 6):

1. **identify** the axis over CAN: ``hdservo identify all --sim AXIS`` (the
   virtual drive, lock-step), with the flow's velocity-loop gains;
2. **download**: the identified model -> compensator parameters and tables
   (:func:`hdservo.download.plan_download`, written and read back with
   :func:`~hdservo.download.write_verified`: the code of ``hdservo
   download``);
3. **test**: the procedures of ``hdservo test`` (:mod:`hdservo.procedures.closedloop`)
   on the virtual drive, configured as the flow assumed: the flow's gains
   (``drive_params.json``: PI/P, notch, torque limit, trajectory limits), the
   downloaded compensator parameters and ``cb_enable`` = the flow's
   compensators; the stabilisation test in the drive's STAB mode (CiA 402
   mode -1, :func:`stabilisation_stab`);
4. **compare** every predicted figure with the measured one, pass when
   |measured/predicted - 1| <= tolerance (20 %).  The positioning and the
   stabilisation are predicted by the procedure itself on the served simulator
   with the true model and measured by the same procedure, both in lock-step
   (``--pacing sync``) with the same sensor seed: the runs repeat bit for bit and
   see the same sensor-noise samples, so the only difference is the model
   (identified vs true).  With further seeds (``Plan.scatter_seeds``) A and R are
   judged on the median over the seeds, prediction and measurement seed by seed;
   the per-seed values and the seed band (:func:`band_pass`) are reported.

The virtual drive has no non-volatile parameter store and ``hdservo test``
starts one drive process per procedure, so step 2 is repeated into each
procedure's drive before it runs (:func:`configure`).
"""
from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence

import numpy as np

from ..fileio import write_json_atomic, write_text_atomic
from ..procedures import closedloop as cl
from ..procedures import metrics as mt
from ..procedures.results import Result
from ..procedures.runner import DT, Bench, RigSetup, Target, open_bench
from ..report.builder import Document

#: flow gains that are drive parameters (the compensator parameters come from the identified model)
GAIN_KEYS = ("vel_kp", "vel_ki", "f1_b0", "f1_b1", "f1_b2", "f1_a1", "f1_a2", "pos_kp", "pos_ki",
             "torque_limit", "traj_vmax", "traj_amax")
STAB_MODE = -1          #: CiA 402 manufacturer mode of the gyro stabilisation (docs/control.md)


@dataclass
class Plan:
    """What to verify.

    Attributes
    ----------
    axis : Path
        Axis TOML of the chosen candidate (``report/axis_chosen.toml``).
    design : Path
        The flow's JSON (``--json``): predicted figures of ``chosen``.
    out : Path
        Output directory (model, JSON, Markdown).
    procedures : sequence of str
        Procedures to run (``min-rate``, ``positioning``, ``stabilisation``,
        ``peak-torque``, ``bandwidth``).
    identify_target : str
        ``hdservo identify`` target (``all``; ``friction`` in the short test).
    tolerance : float
        Relative tolerance of a pass.
    runs, targets_deg, rates_deg_s, windows, settle_s, stab_duration_s, bw_amplitude_arcsec
        Procedure options; None = the protocol the flow predicted with.
    seed : int
        Sensor-noise seed of the virtual drive.
    scatter_seeds : sequence of int
        Further sensor-noise seeds for the positioning: predicted (the procedure on
        the served simulator, true model) and measured (the identified model's drive)
        once per seed, both in lock-step; A and R are then judged on the median over
        ``seed`` and these seeds (plain rule), the seed band (:func:`band_pass`) is
        reported.  () = the one seed.
    script : str
        The example script that runs the chain, named in ``verify.md`` (a path relative
        to the repository).
    """

    axis: Path
    design: Path
    out: Path
    procedures: Sequence[str] = ("min-rate", "positioning", "stabilisation", "peak-torque", "bandwidth")
    identify_target: str = "all"
    tolerance: float = 0.2
    runs: Optional[int] = None
    targets_deg: Optional[Sequence[float]] = None
    rates_deg_s: Optional[Sequence[float]] = None
    windows: int = 10
    settle_s: float = 5.0
    stab_duration_s: float = 5.0
    bw_amplitude_arcsec: float = 60.0
    seed: int = 1
    notes: list[str] = field(default_factory=list)
    #: controller option of the chosen candidate to verify (``flow``, ``best``; None = the one the flow kept)
    option: Optional[str] = None
    #: predicted figures recomputed with the current :mod:`hdservo.design.predict` before comparing
    #: (``bandwidth``, ``peak_torque``: their definitions were aligned with the procedures after
    #: the flow's JSON was written; ``positioning``, ``stabilisation``: the procedure in lock-step on
    #: the served simulator with the plan's seed, the measurement's protocol); () = the JSON as it is
    repredict: Sequence[str] = ("bandwidth", "peak_torque", "positioning", "stabilisation")
    scatter_seeds: Sequence[int] = ()
    script: str = "examples/pitch_drive/verify.py"


def _say(msg: str) -> None:
    """The default progress report: an INFO line of the ``hdservo.verify`` logger."""
    logging.getLogger("hdservo.verify").info("[verify] %s", msg)


# ------------------------------------------------------------------ steps 1 and 2

def identify(axis: Path, gains: Mapping[str, float], model: Path, target: str = "all", seed: int = 1,
             quiet: bool = True) -> dict[str, Any]:
    """``hdservo identify TARGET --sim AXIS -o MODEL --json`` on the virtual drive over CAN.

    The flow's velocity-loop gains are passed with ``--set`` (the drive's
    defaults are tuned for the reference axis).  Returns the identification
    JSON report; raises RuntimeError on a failure.
    """
    rep = model.with_suffix(".ident.json")
    # run beside the model with a relative axis path: the model's header names the axis, no absolute path
    cwd = model.resolve().parent
    ax = os.path.relpath(Path(axis).resolve(), cwd)
    cmd = [sys.executable, "-m", "hdservo.cli", "identify", target, f"--sim={ax}", "-o", model.name,
           "--json", rep.name, "--seed", str(seed)]
    for k in ("vel_kp", "vel_ki"):
        cmd += ["--set", f"{k}={gains[k]!r}"]
    if quiet:
        cmd.append("-q")
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd)
    if r.returncode != 0:
        raise RuntimeError(f"hdservo identify failed: {(r.stderr.strip().splitlines() or ['?'])[-1]}")
    return json.loads(rep.read_text())


def download_plan(model: Path, axis: Path) -> dict[str, Any]:
    """The download of ``hdservo download MODEL --axis AXIS`` (parameters, groups, Preisach image)."""
    from .. import download as dl
    return dl.plan_download(model, str(axis))


def configure(bench: Bench, gains: Mapping[str, float], plan: Mapping[str, Any], compensators: Sequence[str],
              extra: Optional[Mapping[str, float]] = None) -> dict[str, Any]:
    """Configure one procedure's drive as the flow assumed (power stage off).

    The flow's gains by SDO, then the identified compensator parameters and
    tables (``write_verified``, read back), then the controller option's own
    drive parameters (``extra``, e.g. the best combination's ``pos_kp`` and
    ``str_w_ref``: set after the model as ``hdservo compare`` does), then ``cb_enable``.
    """
    from .. import download as dl
    from ..compsetup import enable_mask
    d = bench.drive
    for k in GAIN_KEYS:
        if k in gains:
            d.set_param(k, float(gains[k]))
    done = dl.write_verified(d, plan, tables=True)
    for k, v in dict(extra or {}).items():
        d.set_param(k, float(v))
    mask = enable_mask(list(compensators))
    d.set_param("cb_enable", float(mask))
    if int(d.get_param("cb_enable")) != mask:
        raise RuntimeError("cb_enable: read-back differs")
    return {"params": done["params"], "tables": done["tables"], "extra": dict(extra or {}), "cb_enable": mask}


# ------------------------------------------------------------------ STAB-mode stabilisation

def _enable_stab(bench: Bench) -> None:
    cl.enable_stab(bench)


def stabilisation_stab(bench: Bench, duration_s: float = 5.0, settle_s: float = 1.0) -> Result:
    """The ``stabilisation`` procedure with the drive in its gyro stabilisation mode.

    Now :func:`hdservo.procedures.closedloop.stabilisation` with ``mode="stab"``
    (``hdservo test stabilisation --stab-mode stab``): STAB (CiA 402 mode -1,
    commanded inertial rate 0x60FF = 0) instead of the CSP hold.
    """
    return cl.stabilisation(bench, duration_s=duration_s, settle_s=settle_s, mode="stab")


# ------------------------------------------------------------------ step 3

def _procedure(name: str, plan: Plan, flow: Mapping[str, Any]) -> tuple[RigSetup, bool, Callable[[Bench], Result]]:
    """Set-up, lock-step and runner of one procedure, with the protocol the flow predicted with."""
    spec = flow["spec"]
    pred = flow["chosen"]["figures"]
    if name == "min-rate":
        rates = list(plan.rates_deg_s or [r["rate_deg_s"] for r in pred["min_rate"]["ladder"]])
        return cl.AXIS_SETUP, False, lambda b: cl.min_rate(b, rates_deg_s=rates, bound=pred["min_rate"]["bound"],
                                                           windows=plan.windows, settle_s=plan.settle_s)
    if name == "positioning":
        tg = list(plan.targets_deg or pred["positioning"]["targets_deg"])
        runs = plan.runs or int(pred["positioning"]["runs"])
        # lock-step: the measurement repeats bit for bit, as the prediction (predict.positioning)
        return cl.AXIS_SETUP, True, lambda b: cl.positioning(b, targets_deg=tg, runs=runs)
    if name == "stabilisation":
        st = spec.get("stabilisation", {})
        setup = cl.stab_setup(float(st.get("base_amplitude_deg", 0.5)), float(st.get("base_frequency_Hz", 1.0)))
        mode = stab_mode_of(flow)
        return setup, True, lambda b: cl.stabilisation(b, duration_s=plan.stab_duration_s, mode=mode)
    if name == "peak-torque":
        # lock-step: the saturated step lasts its drive time, however late the host answers
        return cl.AXIS_SETUP, True, lambda b: cl.peak_torque(b)
    if name == "bandwidth":
        return cl.AXIS_SETUP, True, lambda b: cl.bandwidth(b, amplitude_arcsec=plan.bw_amplitude_arcsec)
    raise ValueError(f"unknown procedure '{name}'")


def select_option(flow: dict[str, Any], name: Optional[str]) -> dict[str, Any]:
    """Make controller option ``name`` of the chosen candidate the one verified (in place).

    The flow simulates every option on every candidate and keeps the best; ``chosen.options``
    holds each option's controller, tuning and figures.  ``name`` None (or the kept one)
    leaves ``flow`` as it is.  Raises ValueError for an option the JSON does not hold.
    """
    ch = flow["chosen"]
    if name is None or name == ch.get("option"):
        return flow
    opts = ch.get("options") or {}
    if name not in opts or "controller" not in opts[name]:
        raise ValueError(f"{name!r}: not a controller option of the chosen design in the flow JSON; expected one "
                         f"of {', '.join(sorted(opts)) or '(none stored)'}")
    o = opts[name]
    ch.update({"option": name, "controller": o["controller"], "tuning": o["tuning"], "figures": o["figures"],
               "margins": o["margins"], "predicted": o["predicted"]})
    return flow


def option_of(flow: Mapping[str, Any]) -> dict[str, Any]:
    """The controller option of the flow's chosen design (``tuning.option``; older JSON: the flow's own)."""
    opt = dict(flow["chosen"].get("tuning", {}).get("option") or {})
    opt.setdefault("name", "flow")
    opt.setdefault("extra_gains", {})
    opt.setdefault("proc_args", {})
    return opt


def stab_mode_of(flow: Mapping[str, Any]) -> str:
    """Drive mode of the stabilisation test for the chosen option (``stab`` unless its proc_args say otherwise)."""
    from ..compare import procedure_args
    pa = option_of(flow)["proc_args"].get("stabilisation")
    return "stab" if not pa else str(getattr(procedure_args("stabilisation", pa), "stab_mode", "stab"))


def measure(plan: Plan, flow: Mapping[str, Any], dl_plan: Mapping[str, Any],
            progress: Callable[[str], None] = _say) -> dict[str, dict[str, Any]]:
    """Run the procedures on freshly configured virtual drives; ``{name: {headline, figures, conditions, wall_s}}``."""
    ctl = flow["chosen"]["controller"]
    gains = ctl["gains"]
    comps = list(ctl.get("compensators", []))
    out: dict[str, dict[str, Any]] = {}
    for name in plan.procedures:
        setup, lockstep, fn = _procedure(name, plan, flow)
        t0 = time.monotonic()
        progress(f"test {name}")
        with open_bench(Target(axis=str(plan.axis), seed=plan.seed), setup, lockstep=lockstep) as bench:
            cfg = configure(bench, gains, dl_plan, comps, option_of(flow)["extra_gains"])
            res = fn(bench)
        out[name] = {"headline": res.headline, "figures": res.figures, "conditions": res.conditions,
                     "configured": cfg, "wall_s": round(time.monotonic() - t0, 1)}
        if name == "positioning" and plan.scatter_seeds:
            rows = [_iso_row(plan.seed, res.figures["iso230_2_arcsec"])]
            for s in plan.scatter_seeds:
                progress(f"test positioning, sensor seed {s}")
                with open_bench(Target(axis=str(plan.axis), seed=int(s)), setup, lockstep=lockstep) as bench:
                    configure(bench, gains, dl_plan, comps, option_of(flow)["extra_gains"])
                    rows.append(_iso_row(int(s), fn(bench).figures["iso230_2_arcsec"]))
            out[name]["scatter"] = rows
            out[name]["wall_s"] = round(time.monotonic() - t0, 1)
    return out


def _iso_row(seed: int, iso: Mapping[str, Any]) -> dict[str, Any]:
    return {"seed": int(seed), "A_arcsec": float(iso["A"]), "R_arcsec": float(iso["R"]), "B_arcsec": float(iso["B"])}


def predict_scatter(flow: dict[str, Any], axis: Path, seeds: Sequence[int], base_seed: int = 1,
                    progress: Callable[[str], None] = _say) -> list[dict[str, Any]]:
    """Predicted positioning A/R/B (arcsec) per sensor-noise seed, stored in ``chosen.figures.positioning.scatter``.

    The first row is the figure in the JSON (``base_seed``; re-predicted in lock-step by
    :func:`repredict`); the other ``seeds`` run the same procedure on the served simulator
    in lock-step (:func:`predict.positioning`, ``method="procedure"``) with the chosen
    controller.
    """
    from . import predict as pr
    ctl = flow["chosen"]["controller"]
    p = flow["chosen"]["figures"]["positioning"]
    rows = [{"seed": int(p.get("seed", base_seed)), "A_arcsec": float(p["A_arcsec"]), "R_arcsec": float(p["R_arcsec"]),
             "B_arcsec": float(p["B_arcsec"])}]
    for s in seeds:
        progress(f"predict positioning, sensor seed {s}")
        q = pr.positioning(str(axis), ctl, p["targets_deg"], runs=int(p["runs"]), method="procedure", seed=int(s),
                           lockstep=True)
        rows.append({"seed": int(s), "A_arcsec": float(q["A_arcsec"]), "R_arcsec": float(q["R_arcsec"]),
                     "B_arcsec": float(q["B_arcsec"])})
    p["scatter"] = rows
    return rows


def band_pass(predicted: Sequence[float], measured: Sequence[float], tol: float) -> dict[str, Any]:
    """Judge a figure with run-to-run scatter on its seed band.

    Parameters
    ----------
    predicted, measured : sequence of float
        The figure per sensor-noise seed (same unit, > 0).
    tol : float
        Relative tolerance (0.2).

    Returns
    -------
    dict
        ``pass`` (the mean measured value lies in [(1 - tol) min(predicted), (1 + tol) max(predicted)]),
        ``predicted_mean``, ``measured_mean``, ``predicted_band`` and ``measured_band`` ([min, max]),
        ``rel_error`` of the means, ``scatter`` (max - min over mean, predicted and measured).
    """
    p = np.asarray(predicted, dtype=float)
    m = np.asarray(measured, dtype=float)
    if p.size == 0 or m.size == 0 or np.any(p <= 0):
        raise ValueError("band_pass: needs at least one predicted (> 0) and one measured value")
    pm, mm = float(p.mean()), float(m.mean())
    return {"pass": bool((1.0 - tol) * p.min() <= mm <= (1.0 + tol) * p.max()), "predicted_mean": pm,
            "measured_mean": mm, "predicted_band": [float(p.min()), float(p.max())],
            "measured_band": [float(m.min()), float(m.max())], "rel_error": mm / pm - 1.0,
            "scatter": {"predicted": float(np.ptp(p)) / pm, "measured": float(np.ptp(m)) / mm if mm > 0 else None}}


# ------------------------------------------------------------------ step 4

def repredict(flow: dict[str, Any], axis: Path, figures: Sequence[str], seed: int = 1,
              progress: Callable[[str], None] = _say, stab_duration_s: float = 5.0) -> dict[str, Any]:
    """Recompute predicted figures of the chosen candidate in place (``flow["chosen"]["figures"]``).

    ``figures``: ``bandwidth`` (:func:`predict.bandwidth`, the procedure's excitation),
    ``peak_torque`` (:func:`predict.peak_torque`, the procedure's definition), ``positioning``
    (:func:`predict.positioning`, the procedure in lock-step, sensor seed ``seed``) and
    ``stabilisation`` (:func:`predict.stabilisation_procedure`, the procedure in lock-step in
    the option's drive mode, seed ``seed``, ``stab_duration_s``).  Returns the old headline
    values ``{figure: value}`` for the record.
    """
    from . import predict as pr
    ctl = flow["chosen"]["controller"]
    f = flow["chosen"]["figures"]
    spec = flow.get("spec", {})
    old: dict[str, Any] = {}
    for name in figures:
        progress(f"re-predict {name} for the chosen axis")
        if name == "bandwidth":
            old[name] = f.get("bandwidth", {}).get("bandwidth_Hz")
            f["bandwidth"] = pr.bandwidth(str(axis), ctl)
        elif name == "peak_torque":
            old[name] = f.get("peak_torque", {}).get("peak_torque_Nm")
            f["peak_torque"] = pr.peak_torque(str(axis), ctl, float(ctl["gains"]["torque_limit"]))
        elif name == "positioning":
            p = f["positioning"]
            old[name] = p.get("A_arcsec")
            q = pr.positioning(str(axis), ctl, p["targets_deg"], runs=int(p["runs"]), method="procedure",
                               seed=int(seed), lockstep=True)
            q["A_with_encoder_arcsec"] = q["A_arcsec"] + (p.get("A_with_encoder_arcsec", p["A_arcsec"]) - p["A_arcsec"])
            f["positioning"] = q
        elif name == "stabilisation":
            s = f["stabilisation"]
            mode = "hold" if s.get("design_mode") == "hold" else "stab"
            old[name] = s.get(f"{mode}_true_rms_arcsec")
            st = spec.get("stabilisation", {})
            q = pr.stabilisation_procedure(str(axis), ctl, float(st.get("base_amplitude_deg", 0.5)),
                                           float(st.get("base_frequency_Hz", 1.0)), duration_s=stab_duration_s,
                                           seed=int(seed), mode=mode)
            q["design_json"] = {k: s.get(k) for k in (f"{mode}_true_rms_arcsec", f"{mode}_rms_arcsec")}
            f["stabilisation"] = q
        else:
            raise ValueError(f"repredict: unknown figure '{name}'")
    return old


def _rung_stability(ladder: Sequence[Mapping[str, Any]], rate: Optional[float]) -> Optional[float]:
    for r in ladder:
        if rate is not None and abs(r["rate_deg_s"] - rate) <= 1e-12 * max(1.0, rate):
            return float(r["stability"])
    return None


def compare(flow: Mapping[str, Any], measured: Mapping[str, Mapping[str, Any]], tol: float = 0.2) -> list[dict[str, Any]]:
    """Rows ``{figure, definition, predicted, measured, unit, rel_error, pass}`` for what was measured."""
    f = flow["chosen"]["figures"]
    rows: list[dict[str, Any]] = []

    def row(fig: str, unit: str, p: Optional[float], m: Optional[float], definition: str, judged: bool = True) -> None:
        rel = None if p in (None, 0) or m is None else m / p - 1.0
        rows.append({"figure": fig, "unit": unit, "predicted": p, "measured": m, "rel_error": rel,
                     "pass": (rel is not None and abs(rel) <= tol) if judged else None, "definition": definition})

    def median_row(fig: str, key: str, pred: Sequence[Mapping[str, Any]], meas: Sequence[Mapping[str, Any]],
                   definition: str) -> None:
        ps, ms = [int(r["seed"]) for r in pred], [int(r["seed"]) for r in meas]
        if sorted(ps) != sorted(ms):
            raise ValueError(f"compare: {fig}: predicted seeds {ps} and measured seeds {ms} differ")
        pv = {int(r["seed"]): float(r[key]) for r in pred}
        mv = {int(r["seed"]): float(r[key]) for r in meas}
        b = band_pass([pv[k] for k in ms], [mv[k] for k in ms], tol)
        p_med, m_med = float(np.median([pv[k] for k in ms])), float(np.median([mv[k] for k in ms]))
        rel = m_med / p_med - 1.0 if p_med > 0 else None
        b["per_seed_rel_error"] = [mv[k] / pv[k] - 1.0 if pv[k] > 0 else None for k in ms]
        rows.append({"figure": fig, "unit": "arcsec", "predicted": p_med, "measured": m_med, "rel_error": rel,
                     "pass": rel is not None and abs(rel) <= tol, "band": b, "statistic": "median",
                     "seeds": {"predicted": ms, "measured": ms}, "definition": definition})

    if "min-rate" in measured:
        mr = measured["min-rate"]
        p_best = f["min_rate"]["min_smooth_rate_deg_s"]
        m_best = mr["headline"]["min_smooth_rate_deg_s"]
        row("min smooth rate", "deg/s", p_best, m_best,
            f"slowest ladder rung with stability sigma/mean <= {f['min_rate']['bound']:g} (fixed-angle 1 s windows)")
        row("rate stability at that rung", "-", _rung_stability(f["min_rate"]["ladder"], p_best),
            _rung_stability(mr["figures"]["ladder"], p_best),
            "sigma/mean of the window rates (informative: both far below the bound)", judged=False)
    if "positioning" in measured:
        iso = measured["positioning"]["figures"]["iso230_2_arcsec"]
        p = f["positioning"]
        d = f"ISO 230-2, true output angle, {len(p.get('targets_deg') or []) or 12} targets, bidirectional"
        ps, ms = p.get("scatter"), measured["positioning"].get("scatter")
        if ps and ms:
            seeds = ", ".join(str(int(r["seed"])) for r in ms)
            db = (f"{d}; median over sensor seeds {seeds} (prediction and measurement with the same seeds, "
                  "lock-step); per-seed values and the seed band below")
            median_row("positioning accuracy A (median of seeds)", "A_arcsec", ps, ms, db)
            median_row("repeatability R (median of seeds)", "R_arcsec", ps, ms, db)
            s0 = int(ms[0]["seed"])
            row(f"positioning accuracy A, seed {s0}", "arcsec", p["A_arcsec"], iso["A"], d + " (single run)",
                judged=False)
            row(f"repeatability R, seed {s0}", "arcsec", p["R_arcsec"], iso["R"], d + " (single run)", judged=False)
        else:
            row("positioning accuracy A", "arcsec", p["A_arcsec"], iso["A"], d)
            row("repeatability R", "arcsec", p["R_arcsec"], iso["R"], d)
        row("reversal value B", "arcsec", p["B_arcsec"], iso["B"], d, judged=False)
    if "stabilisation" in measured:
        s = f["stabilisation"]
        m = measured["stabilisation"]["figures"]
        tag = "hold" if s.get("design_mode") == "hold" else "stab"
        base = flow.get("spec", {})
        amp, freq = float(base.get("base_amplitude_deg", 0.5)), float(base.get("base_frequency_Hz", 1.0))
        row("stabilisation RMS (true inertial)", "arcsec", s.get(f"{tag}_true_rms_arcsec"), m.get("true_rms_arcsec"),
            f"{'STAB mode' if tag == 'stab' else 'CSP hold'}, base {amp:g} deg at {freq:g} Hz, 5 s, line removed; rig / "
            "simulator true inertial angle")
        row("stabilisation RMS (integrated gyro)", "arcsec", s.get(f"{tag}_rms_arcsec"), m.get("gyro_rms_arcsec"),
            "same, payload gyro integrated (the procedure's headline)")
    if "peak-torque" in measured:
        row("peak output torque", "N.m", f["peak_torque"]["peak_torque_Nm"],
            measured["peak-torque"]["headline"]["peak_torque_Nm"],
            "locked output, drive torque_limit in force, 1.5 x limit requested; mean |gear torque| 0.5-0.9 of "
            "the 0.2 s hold (load cell / transmitted torque)")
    if "bandwidth" in measured:
        row("position bandwidth (-3 dB)", "Hz", f["bandwidth"]["bandwidth_Hz"],
            measured["bandwidth"]["headline"]["bandwidth_hz"],
            "60 arcsec peak Schroeder multisine, 17 log-spaced lines 1-80 Hz on the CSP target; output encoder "
            "over the drive's reference; -3 dB re the lowest line")
    return rows


def resonance_rows(flow: Mapping[str, Any], ident: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Informative rows: the flow's first resonance against what the identification measured.

    Parameters
    ----------
    flow : mapping
        The flow's JSON; ``chosen.figures.resonance`` holds the design figure (Hz, the
        lower of the two-mass locked-motor value and the FE torsional mode) and the FE
        figures.
    ident : mapping
        The identification report (``model.ident.json``); its ``results.stiffness``
        (K1, N·m/rad, from the locked-output torque cycle) and ``results.frf`` (two-mass
        fits of the velocity FRF per excitation amplitude: load inertia j2 in kg·m²,
        anti-resonance in Hz) are used.

    Returns
    -------
    list of dict
        Rows as :func:`compare` makes them, ``pass`` None (reported, not judged):
        the locked-motor resonance sqrt(K1/J_L)/2π with the identified K1 and the FRF's
        load inertia, and the anti-resonance of the motor-side FRF at the smallest
        excitation (the locked-motor mode seen from the motor).  Empty when the
        identification did not produce the stiffness or the FRF (``identify friction``).
    """
    res = flow["chosen"]["figures"].get("resonance", {})
    pred = res.get("design_Hz", res.get("locked_motor_Hz"))
    r = ident.get("results", {}) or {}
    frf = sorted(r.get("frf") or [], key=lambda x: float(x.get("amplitude_rad_s", 0.0)))
    k1 = (r.get("stiffness") or {}).get("k1_Nm_per_rad")
    rows: list[dict[str, Any]] = []
    if pred is None or not frf:
        return rows

    def row(fig: str, m: Optional[float], definition: str) -> None:
        rel = None if m is None or not pred else m / pred - 1.0
        rows.append({"figure": fig, "unit": "Hz", "predicted": float(pred), "measured": m, "rel_error": rel,
                     "pass": None, "definition": definition})
    jl = float(frf[0]["j2_kgm2"])
    if k1 is not None and jl > 0:
        row("first resonance, identified K1 and J_L", float(np.sqrt(float(k1) / jl) / (2 * np.pi)),
            "sqrt(K1/J_L)/2pi, K1 from the locked-output torque cycle, J_L from the two-mass FRF fit; predicted: "
            "the flow's design figure (lower of two-mass and FE torsional mode, catalogue K1)")
    row("first resonance, FRF anti-resonance", float(frf[0]["f_antiresonance_Hz"]),
        f"anti-resonance of the motor-side velocity FRF at {float(frf[0]['amplitude_rad_s']):g} rad/s excitation "
        "(the locked-motor mode at small amplitude, where the gear is stiffer than its secant K1)")
    return rows


def _fmt4(v: Optional[float]) -> str:
    return "-" if v is None else f"{v:.4g}"


def _band_row(r: Mapping[str, Any], result: Mapping[str, Any]) -> list[str]:
    """One per-seed row: the seeds, predicted and measured per seed, errors, bands, scatter, band rule."""
    b = r["band"]
    key = "A_arcsec" if r["figure"].startswith("positioning") else "R_arcsec"
    order = r["seeds"]["measured"]
    pd = {int(x["seed"]): x[key] for x in result["scatter"]["predicted"]}
    md = {int(x["seed"]): x[key] for x in result["scatter"]["measured"]}
    ev = ", ".join("-" if e is None else f"{e * 100:+.0f} %" for e in b.get("per_seed_rel_error", []))
    sc = b["scatter"]
    return [r["figure"], ", ".join(str(x) for x in order), ", ".join(_fmt4(pd.get(k)) for k in order),
            ", ".join(_fmt4(md.get(k)) for k in order), ev or "-",
            f"{_fmt4(b['predicted_band'][0])}-{_fmt4(b['predicted_band'][1])}",
            f"{_fmt4(b['measured_band'][0])}-{_fmt4(b['measured_band'][1])}",
            f"{sc['predicted'] * 100:.0f} % / {(sc['measured'] or 0) * 100:.0f} %", "pass" if b["pass"] else "fail"]


def markdown(result: Mapping[str, Any]) -> str:
    """Markdown report of :func:`verify`'s result (:class:`hdservo.report.builder.Document`)."""
    tol = result["tolerance"]
    d = Document(f"Prediction vs measurement: {result['candidate']}")
    intro = (f"Generated by `{result.get('script', 'examples/pitch_drive/verify.py')}` "
             "(host/hdservo/design/verify.py): the chosen axis "
             "served as a virtual drive, identified over CAN (`hdservo identify "
             f"{result['identify_target']}`), the identified compensator parameters downloaded "
             "(`hdservo download` code, read back), the procedures of `hdservo test` run with the flow's gains and "
             f"controller option `{result.get('option', 'flow')}` (compensators "
             f"{', '.join(result['compensators']) or 'none'}"
             + ("; after the model: " + ", ".join(f"{k} = {v:g}" for k, v in result.get("option_gains", {}).items())
                if result.get("option_gains") else "") + "). Pass: |measured/predicted - 1| <= "
             f"{tol * 100:.0f} %.")
    d.heading("Predicted and measured figures")
    rows = []
    for r in result["rows"]:
        err = "-" if r["rel_error"] is None else f"{r['rel_error'] * 100:+.1f} %"
        ok = "(info)" if r["pass"] is None else ("PASS" if r["pass"] else "**FAIL**")
        rows.append([f"{r['figure']} [{r['unit']}]", _fmt4(r["predicted"]), _fmt4(r["measured"]), err, ok,
                     r["definition"]])
    d.table(["figure", "predicted", "measured", "error", "pass", "definition"], rows)
    d.para(f"Judged figures: {result['passed']} of {result['judged']} pass (PASS / **FAIL**; (info) rows are "
           "reported, not judged).")
    banded = [r for r in result["rows"] if r.get("band")]
    if banded:
        d.heading("Per seed")
        d.para("Positioning with each sensor-noise seed, prediction = the procedure on the served "
               "simulator with the true model, measurement = the identified model's drive, both in lock-step; "
               "information: the band rule passes when the measured mean lies in "
               f"[{1 - tol:g} x min, {1 + tol:g} x max] of the predicted seeds.")
        d.table(["figure", "seeds", "predicted per seed", "measured per seed", "error per seed", "predicted band",
                 "measured band", "scatter (max-min)/mean pred / meas", "band rule"],
                [_band_row(r, result) for r in banded])
    if result.get("repredicted"):
        d.heading("Re-predicted")
        d.para("Re-predicted with the current `hdservo.design.predict` (definitions aligned with the "
               "procedures; design.json value -> now): " + ", ".join(
                   f"{k} {_fmt4(v['design_json'])} -> {_fmt4(v['now'])}" for k, v in result["repredicted"].items()))
    if result.get("notes"):
        d.heading("Notes")
        for n in result["notes"]:
            d.para(f"* {n}")
    d.heading("Wall time")
    d.para("Wall time per step (s): " + ", ".join(f"{k} {v}" for k, v in result["wall_s"].items()))
    return d.markdown(intro=[intro])


def verify(plan: Plan, progress: Callable[[str], None] = _say) -> dict[str, Any]:
    """The whole chain; writes ``verify.json`` and ``verify.md`` into ``plan.out`` and returns the result."""
    flow = select_option(json.loads(plan.design.read_text()), plan.option)
    ctl = flow["chosen"]["controller"]
    plan.out.mkdir(parents=True, exist_ok=True)
    wall: dict[str, float] = {}
    repredicted: dict[str, Any] = {}
    want = [x for x in plan.repredict if {"bandwidth": "bandwidth", "peak_torque": "peak-torque",
                                          "positioning": "positioning", "stabilisation": "stabilisation"}[x]
            in plan.procedures]
    if want:
        t0 = time.monotonic()
        repredicted = repredict(flow, plan.axis, want, plan.seed, progress, plan.stab_duration_s)
        wall["repredict"] = round(time.monotonic() - t0, 1)
    if plan.scatter_seeds and "positioning" in plan.procedures:
        t0 = time.monotonic()
        predict_scatter(flow, plan.axis, plan.scatter_seeds, plan.seed, progress)
        wall["predict scatter"] = round(time.monotonic() - t0, 1)
    model = plan.out / "model.toml"
    t0 = time.monotonic()
    progress(f"identify {plan.identify_target} over CAN (virtual drive, axis {plan.axis.name})")
    ident = identify(plan.axis, ctl["gains"], model, plan.identify_target, plan.seed)
    wall["identify"] = round(time.monotonic() - t0, 1)
    dlp = download_plan(model, plan.axis)
    measured = measure(plan, flow, dlp, progress)
    for k, v in measured.items():
        wall[k] = v["wall_s"]
    rows = compare(flow, measured, plan.tolerance) + resonance_rows(flow, ident)
    judged = [r for r in rows if r["pass"] is not None]
    result: dict[str, Any] = {
        "format": "hdservo-design-verify", "version": 1, "candidate": flow["chosen"]["name"],
        "script": plan.script,
        "axis": plan.axis.name, "design": plan.design.name, "identify_target": plan.identify_target,
        "identify_notes": ident.get("notes", []), "download_notes": dlp["notes"],
        "compensators": list(ctl.get("compensators", [])), "option": option_of(flow)["name"],
        "option_gains": option_of(flow)["extra_gains"], "tolerance": plan.tolerance, "seed": plan.seed,
        "rows": rows, "judged": len(judged), "passed": sum(1 for r in judged if r["pass"]),
        "measured": measured, "notes": list(plan.notes), "wall_s": wall,
        "scatter": ({"predicted": flow["chosen"]["figures"]["positioning"]["scatter"],
                     "measured": measured["positioning"]["scatter"]}
                    if "scatter" in measured.get("positioning", {}) else None),
        "repredicted": {k: {"design_json": v, "now": predicted_headline(flow, k)} for k, v in repredicted.items()}}
    write_json_atomic(plan.out / "verify.json", result, indent=1, default=str)
    write_text_atomic(plan.out / "verify.md", markdown(result))
    return result


def annotate(out: Path, notes: Sequence[str]) -> dict[str, Any]:
    """Set the notes of a finished verification (``out/verify.json``) and render ``verify.md`` again.

    For the explanation of a figure that does not match, written after looking at the run;
    nothing is measured again.  Returns the result.
    """
    res = json.loads((out / "verify.json").read_text())
    res["notes"] = [str(n) for n in notes]
    write_json_atomic(out / "verify.json", res, indent=1, default=str)
    write_text_atomic(out / "verify.md", markdown(res))
    return res


def example_main(here: Path, argv: Optional[Sequence[str]] = None, description: str = "") -> int:
    """Command line of an example's ``verify.py`` (``examples/*/verify.py``).

    Parameters
    ----------
    here : Path
        The example directory: ``design.json`` and ``report/axis_chosen.toml`` are read from it,
        ``verify/`` (or ``verify_OPTION/``) is written into it.
    argv : sequence of str, optional
        Arguments (default ``sys.argv[1:]``).
    description : str
        Help text (the script's docstring).

    Returns
    -------
    int
        0 when every judged figure passes, 1 when one fails, 2 on bad arguments.
    """
    import argparse
    name = f"{here.name}/verify.py"
    p = argparse.ArgumentParser(prog=name, description=description,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--procedures", default="min-rate,positioning,stabilisation,peak-torque,bandwidth")
    p.add_argument("--identify", default="all", help="hdservo identify target (default all)")
    p.add_argument("--option", default=None,
                   help="controller option of the chosen design to verify (flow, best; default: the one the flow kept)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default verify/, or verify_OPTION/)")
    p.add_argument("--note", action="append", default=None,
                   help="with --annotate: a note for verify.md (repeatable)")
    p.add_argument("--annotate", action="store_true",
                   help="measure nothing: set the notes (--note) of the finished run in the output directory "
                        "and render its verify.md again")
    p.add_argument("--tolerance", type=float, default=0.2)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--scatter-seeds", default="",
                   help="further sensor-noise seeds for the positioning, e.g. 2,3: predicted and measured per seed "
                        "(lock-step), A and R judged on the median over the seeds; the seed band is reported")
    a = p.parse_args(argv)
    out = a.out or (here / ("verify" if a.option is None else f"verify_{a.option}"))
    if a.annotate:
        if not (out / "verify.json").is_file():
            print(f"{name}: --annotate: no finished run in {out} (verify.json missing)", file=sys.stderr)
            return 2
        res = annotate(out, a.note or [])
        print(markdown(res))
        return 0
    try:
        seeds = [int(x) for x in a.scatter_seeds.split(",") if x.strip()]
    except ValueError:
        print(f"{name}: --scatter-seeds: expected comma-separated integers, got '{a.scatter_seeds}'",
              file=sys.stderr)
        return 2
    if a.seed in seeds:
        print(f"{name}: --scatter-seeds: seed {a.seed} is the base run (--seed); give the others", file=sys.stderr)
        return 2
    plan = Plan(axis=here / "report" / "axis_chosen.toml", design=here / "design.json", out=out,
                procedures=[x for x in a.procedures.split(",") if x], identify_target=a.identify,
                tolerance=a.tolerance, seed=a.seed, option=a.option, scatter_seeds=seeds,
                script=f"examples/{here.name}/verify.py")
    try:
        select_option(json.loads(plan.design.read_text()), a.option)
    except ValueError as e:
        print(f"{name}: --option {e}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)   # the progress lines
    res = verify(plan)
    print(markdown(res))
    return 0 if res["passed"] == res["judged"] else 1


def predicted_headline(flow: Mapping[str, Any], figure: str) -> Optional[float]:
    """The headline of a (re-)predicted figure of the chosen candidate: ``bandwidth`` Hz,
    ``peak_torque`` N.m, ``positioning`` A arcsec (the plan's seed), ``stabilisation`` true
    inertial RMS arcsec (the design mode)."""
    f = flow["chosen"]["figures"]
    if figure == "bandwidth":
        return f["bandwidth"].get("bandwidth_Hz")
    if figure == "peak_torque":
        return f["peak_torque"].get("peak_torque_Nm")
    if figure == "positioning":
        return f["positioning"].get("A_arcsec")
    if figure == "stabilisation":
        s = f["stabilisation"]
        return s.get(f"{'hold' if s.get('design_mode') == 'hold' else 'stab'}_true_rms_arcsec")
    raise ValueError(f"predicted_headline: unknown figure '{figure}'")


__all__ = ["GAIN_KEYS", "Plan", "annotate", "band_pass", "compare", "configure", "download_plan", "identify", "markdown", "measure",
           "option_of", "predict_scatter", "predicted_headline", "repredict", "select_option", "stab_mode_of",
           "stabilisation_stab", "verify"]
