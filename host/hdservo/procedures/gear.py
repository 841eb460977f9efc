"""Catalogue gear tests (harmonic-drive.md 2.2, 9.1): stiffness, hysteresis loss, lost motion,
starting torque, transmission accuracy.

Set-up (:data:`GEAR_SETUP`): payload removed, base still.  The torque-twist
tests load the output through the rig (torque motor + load cell on the output
flange; on the virtual drive the simulator's external output torque and the
gear's true transmitted torque as the load cell) while the drive holds the
input in CSP; twist is measured by the drive's own encoders,
``phi = theta_M / N - theta_L``.  Holding the input by the servo instead of a
clamp lets the wave generator turn by the twist x N (a few degrees), so the
kinematic transmission error adds up to about +-2 % to the measured
compliance on the reference axis (2xWG line, 0.3', 100:1).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional

import numpy as np

from . import metrics as mt
from .results import Result, figure, save_figure
from .runner import Bench, Progress, RigSetup
from ..phase import unwrap_turns

GEAR_SETUP = RigSetup("gear", payload=False)
RATED_NM = 67.0          #: reference axis rated torque (0x6076 is read from the drive)


# ---- torque-twist loop ----------------------------------------------------------------

def torque_loop(bench: Bench, peak_Nm: float, cycles: int, rate_Nm_s: float,
                progress: Optional[Progress] = None) -> dict[str, np.ndarray]:
    """Cycle the output torque 0 -> +peak -> 0 -> -peak -> 0 (``cycles`` times) and record twist.

    Returns
    -------
    dict
        ``torque_Nm`` (load cell: gear torque), ``applied_Nm`` (rig command),
        ``twist_rad`` (encoders, zero at the start), ``twist_true_rad`` (rig
        instrument, virtual rig only), ``t_s``.
    """
    quarter = peak_Nm / rate_Nm_s
    # the rig runs the whole profile in drive time (queued ramps), so the record length does not
    # depend on the host's latency; margin for the start (capture trigger -> rig command)
    total = cycles * 4 * quarter * 1.1 + 1.0
    frames = 2700
    decim = max(1, int(math.ceil(total / frames / 1e-4)))
    frames = int(math.ceil(total / (decim * 1e-4)))
    targets = [t for _ in range(cycles) for t in (peak_Nm, 0.0, -peak_Nm, 0.0)]
    bench.rig.brake(False)
    with bench.params({"torque_limit": max(60.0, 1.3 * peak_Nm), "follow_err_max": 0.01}):
        bench.enable("CYCLIC SYNCHRONOUS POSITION")
        bench.wait(0.2)

        def run() -> None:
            # external torque opposite to the gear torque
            bench.rig.load_torque_profile([(-t, rate_Nm_s) for t in targets])
            if progress:
                progress(0.0, f"torque loop +-{peak_Nm:.3g} N.m x {cycles} queued on the rig")

        with bench.rig.record(decim) as rec:
            cap = bench.capture(["tick", "pos_mot_lo", "pos_out_lo"], frames, decim, action=run)
        fault = bench.fault()
        bench.disable()
    if fault:
        raise RuntimeError(f"the drive faulted during the torque loop (fault code {fault})")
    tick = cap["tick"].astype(float)
    mot = unwrap_turns(cap["pos_mot_lo"], centred=False) * 2 * math.pi
    out = unwrap_turns(cap["pos_out_lo"], centred=False) * 2 * math.pi
    phi = mot / bench.ratio - out
    phi -= phi[0]
    res = {"t_s": (tick - tick[0]) * 1e-4, "twist_rad": phi}
    if rec:
        rt = rec["tick"]
        res["torque_Nm"] = np.interp(tick, rt, rec["gear_torque_Nm"])
        res["applied_Nm"] = -np.interp(tick, rt, rec["applied_torque_Nm"])
        tt = np.interp(tick, rt, rec["torsion_rad"])
        res["twist_true_rad"] = tt - tt[0]
        # the loop must be complete inside the capture (every reversal and the final return to 0)
        ap = res["applied_Nm"]
        tol = 0.01 * peak_Nm
        nb = len(mt.branches(ap)[0])
        if ap.max() < peak_Nm - tol or ap.min() > -peak_Nm + tol or abs(ap[-1]) > tol or nb != 2 * cycles + 1:
            raise RuntimeError(f"the torque loop is not complete in the capture ({nb} "
                               f"branches, expected {2 * cycles + 1}; applied torque at the end {ap[-1]:+.3g} N.m)")
    else:  # pragma: no cover - real bench without a recorded load cell
        raise RuntimeError("no load-cell record")
    return res


def midline(torque_Nm: np.ndarray, twist_rad: np.ndarray, ref_Nm: np.ndarray,
            n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Mean of the loading and unloading branches of the LAST cycle at n torque levels per sign.

    ``ref_Nm`` is the commanded torque (branches), ``torque_Nm`` the load cell.
    """
    idx, dirs = mt.branches(ref_Nm)
    t, p = np.asarray(torque_Nm), np.asarray(twist_rad)
    lv_t: list[float] = []
    lv_p: list[float] = []
    top = float(np.max(np.abs(t)))
    last = idx[-3:] if len(idx) >= 3 else idx
    for lev in np.concatenate([-np.linspace(top * 0.98, top * 0.02, n), np.linspace(top * 0.02, top * 0.98, n)]):
        vals = [mt.twist_at_torque(t[i], p[i], lev) for i in last]
        vals = [v for v in vals if math.isfinite(v)]
        if len(vals) >= 2:
            lv_t.append(float(lev))
            lv_p.append(float(np.mean(vals)))
    return np.array(lv_t), np.array(lv_p)


def _loop_plot(title: str) -> Any:
    def plot(r: Result, out: Path, fmt: str) -> list[Path]:
        fig, ax = figure()
        a = ax[0][0]
        s = r.series
        a.plot(s["twist_rad"] / mt.ARCMIN, s["torque_Nm"], lw=0.8, label="encoders")
        if "twist_true_rad" in s:
            a.plot(s["twist_true_rad"] / mt.ARCMIN, s["torque_Nm"], lw=0.6, ls="--", label="true twist (rig)")
        if "mid_t" in s:
            a.plot(s["mid_p"] / mt.ARCMIN, s["mid_t"], "k.", ms=2, label="midline")
        a.set_xlabel("twist (arcmin, output)")
        a.set_ylabel("gear torque (N.m)")
        a.set_title(title)
        a.grid(True)
        a.legend()
        return save_figure(fig, out, r.name, fmt, label=r.label)
    return plot


def stiffness(bench: Bench, peak_Nm: Optional[float] = None, cycles: int = 2, rate_Nm_s: float = 40.0,
              progress: Optional[Progress] = None) -> Result:
    """Torsional stiffness curve: K1/K2/K3, T1/T2 of the three-slope catalogue model.

    A loop to +-peak (default the rated torque, 0x6076), ``cycles`` >= 2 so that
    the midline of the last cycle is made of established branches (not the
    virgin curve); the three-slope model is fitted to that midline.
    """
    peak = bench.rated_torque_Nm() if peak_Nm is None else peak_Nm
    d = torque_loop(bench, peak, cycles, rate_Nm_s, progress)
    mt_, mp = midline(d["torque_Nm"], d["twist_rad"], d["applied_Nm"])
    fit = mt.three_slope_fit(mt_, mp)
    r = Result("stiffness", conditions={"peak_Nm": peak, "cycles": cycles, "rate_Nm_s": rate_Nm_s,
                                        "setup": GEAR_SETUP.name})
    r.figures = {**fit, "twist_at_t1_arcmin": fit["t1_Nm"] / fit["k1_Nm_per_rad"] / mt.ARCMIN,
                 "twist_at_peak_arcmin": float(np.max(np.abs(d["twist_rad"]))) / mt.ARCMIN}
    if "twist_true_rad" in d:
        mt2, mp2 = midline(d["torque_Nm"], d["twist_true_rad"], d["applied_Nm"])
        r.figures["true_twist_fit"] = mt.three_slope_fit(mt2, mp2)
    r.headline = {"k1_Nm_per_rad": fit["k1_Nm_per_rad"], "k2_Nm_per_rad": fit["k2_Nm_per_rad"],
                  "k3_Nm_per_rad": fit["k3_Nm_per_rad"], "t1_Nm": fit["t1_Nm"], "t2_Nm": fit["t2_Nm"]}
    r.series = {**d, "mid_t": mt_, "mid_p": mp}
    r.plot = _loop_plot("torsional stiffness (input held, output loaded)")
    return r


def hysteresis(bench: Bench, peak_Nm: Optional[float] = None, cycles: int = 3, rate_Nm_s: float = 40.0,
               progress: Optional[Progress] = None) -> Result:
    """Hysteresis loss at +-rated torque: twist difference at zero torque (B-B'), mean of cycles 2.."""
    peak = bench.rated_torque_Nm() if peak_Nm is None else peak_Nm
    d = torque_loop(bench, peak, cycles, rate_Nm_s, progress)
    h = mt.hysteresis_loss(d["torque_Nm"], d["twist_rad"], ref_Nm=d["applied_Nm"])
    r = Result("hysteresis", conditions={"peak_Nm": peak, "cycles": cycles, "rate_Nm_s": rate_Nm_s,
                                         "setup": GEAR_SETUP.name})
    r.figures = dict(h)
    if "twist_true_rad" in d:
        r.figures["true_twist_loss_arcmin"] = mt.hysteresis_loss(d["torque_Nm"], d["twist_true_rad"],
                                                                ref_Nm=d["applied_Nm"])["loss_arcmin"]
    r.headline = {"hysteresis_loss_arcmin": h["loss_arcmin"]}
    r.series = d
    r.plot = _loop_plot(f"hysteresis loop +-{peak:.3g} N.m")
    return r


def lost_motion(bench: Bench, fraction: float = 0.04, cycles: int = 3, rate_Nm_s: float = 4.0,
                progress: Optional[Progress] = None) -> Result:
    """Lost motion: twist between the loop tips at +-4 % of the rated torque, last cycle."""
    level = fraction * bench.rated_torque_Nm()
    d = torque_loop(bench, level, cycles, rate_Nm_s, progress)
    lm = mt.lost_motion(d["torque_Nm"], d["twist_rad"], level, ref_Nm=d["applied_Nm"])
    h = mt.hysteresis_loss(d["torque_Nm"], d["twist_rad"], ref_Nm=d["applied_Nm"])
    r = Result("lost-motion", conditions={"level_Nm": level, "fraction_of_rated": fraction, "cycles": cycles,
                                          "rate_Nm_s": rate_Nm_s, "setup": GEAR_SETUP.name})
    r.figures = {**lm, "loop_width_at_zero_arcmin": h["loss_arcmin"]}
    if "twist_true_rad" in d:
        r.figures["true_twist_lost_motion_arcmin"] = mt.lost_motion(d["torque_Nm"], d["twist_true_rad"], level,
                                                                    ref_Nm=d["applied_Nm"])["lost_motion_arcmin"]
    r.headline = {"lost_motion_arcmin": lm["lost_motion_arcmin"]}
    r.series = d
    r.plot = _loop_plot(f"lost motion loop +-{level:.3g} N.m")
    return r


# ---- starting torque --------------------------------------------------------------------

def starting_torque(bench: Bench, step_permille: int = 1, step_s: float = 0.01, max_Nm: float = 30.0,
                    threshold_motor_rad: float = 0.035, progress: Optional[Progress] = None) -> Result:
    """No-load starting torque at the input: quasi-static torque ramp until the wave generator turns.

    CST staircase of ``step_permille`` of the rated torque every ``step_s``
    (output-referred command); rotation begins when the motor has turned by
    ``threshold_motor_rad`` (well beyond the presliding range).  Both
    directions; reported at the input (motor) side, N.m.
    """
    rated = bench.rated_torque_Nm()
    out: dict[str, float] = {}
    traces: dict[str, Any] = {}
    bench.rig.brake(False)
    for k, sgn in enumerate((1, -1)):
        bench.enable("CYCLIC SYNCHRONOUS TORQUE")
        bench.wait(0.05)
        m0 = int(bench.read(0x5F00, 3))
        n = 0
        found = float("nan")
        tq: list[float] = []
        mv: list[float] = []
        while n * step_permille * rated / 1000.0 <= max_Nm:
            n += 1
            bench.drive.write(0x6071, 0, sgn * n * step_permille)
            bench.wait(step_s)
            m = int(bench.read(0x5F00, 3))
            d = ((m - m0 + 2 ** 31) % 2 ** 32 - 2 ** 31) / 2 ** 32 * 2 * math.pi
            tq.append(n * step_permille * rated / 1000.0)
            mv.append(abs(d))
            if abs(d) > threshold_motor_rad:
                found = (n - 0.5) * step_permille * rated / 1000.0   # mid-step: rotation began within it
                break
        bench.drive.write(0x6071, 0, 0)
        bench.wait(0.05)
        bench.disable()
        bench.wait(0.3)
        key = "positive" if sgn > 0 else "negative"
        out[key] = found / bench.ratio
        traces[key] = (np.array(tq), np.array(mv))
        if progress:
            progress((k + 1) / 2.0, f"{key}: {found / bench.ratio:.4g} N.m at the input")
    r = Result("starting-torque", conditions={"step_Nm_output": step_permille * rated / 1000.0, "step_s": step_s,
                                              "threshold_motor_rad": threshold_motor_rad, "setup": GEAR_SETUP.name})
    r.figures = {"starting_torque_pos_Nm": out["positive"], "starting_torque_neg_Nm": out["negative"],
                 "starting_torque_pos_Ncm": out["positive"] * 100, "starting_torque_neg_Ncm": out["negative"] * 100,
                 "output_referred_pos_Nm": out["positive"] * bench.ratio,
                 "output_referred_neg_Nm": out["negative"] * bench.ratio}
    r.headline = {"starting_torque_Nm": max(out["positive"], out["negative"])}
    r.series = traces

    def plot(res: Result, d: Path, fmt: str) -> list[Path]:
        fig, ax = figure()
        a = ax[0][0]
        for key, (tq, mv) in res.series.items():
            a.semilogy(tq / bench.ratio, np.maximum(mv, 1e-7), label=key)
        a.axhline(threshold_motor_rad, color="k", ls=":", label="threshold")
        a.set_xlabel("input torque command (N.m)")
        a.set_ylabel("motor rotation (rad)")
        a.grid(True)
        a.legend()
        return save_figure(fig, d, res.name, fmt, label=res.label)
    r.plot = plot
    return r


# ---- transmission accuracy ---------------------------------------------------------------

def transmission(bench: Bench, rate_deg_s: float = 10.0, revolutions: float = 1.0, direction: int = 1,
                 progress: Optional[Progress] = None) -> Result:
    """Transmission accuracy over one output revolution at a constant slow rate (CSV), one direction."""
    rate = math.radians(rate_deg_s) * (1 if direction >= 0 else -1)
    span = revolutions * 2 * math.pi
    dur = span / abs(rate)
    frames = 4000
    decim = max(1, int(math.ceil(dur * 1.02 / frames / 1e-4)))
    frames = int(math.ceil(dur * 1.02 / (decim * 1e-4)))
    if decim * 1e-4 * abs(rate) * bench.ratio > math.pi:
        raise ValueError("transmission: the motor turns more than half a turn per sample; lower the rate")
    limits = {"travel_min": -2.0 * revolutions - 1, "travel_max": 2.0 * revolutions + 1}
    bench.rig.brake(False)
    with bench.params(limits):
        bench.enable("CYCLIC SYNCHRONOUS VELOCITY")
        bench.drive.set_velocity(rate)
        bench.wait(0.5 + 2.0 * abs(rate) / math.radians(100.0))
        if progress:
            progress(0.1, f"{rate_deg_s:g} deg/s, {dur:.0f} s of drive time")
        cap = bench.capture(["pos_mot_lo", "pos_out_lo"], frames, decim)
        fault = bench.fault()
        bench.drive.set_velocity(0.0)
        bench.wait(0.3)
        bench.disable()
    if fault:
        raise RuntimeError(f"the drive faulted during the transmission test (fault code {fault})")
    mot = unwrap_turns(cap["pos_mot_lo"], centred=False) * 2 * math.pi
    out = unwrap_turns(cap["pos_out_lo"], centred=False) * 2 * math.pi
    # the motor phase word is the motor angle within a motor turn: the whole turns follow from the output angle
    mot += 2 * math.pi * np.round((out[0] * bench.ratio - mot[0]) / (2 * math.pi))
    keep = np.abs(out - out[0]) <= span
    mot, out = mot[keep], out[keep]
    ta = mt.transmission_accuracy(mot, out, bench.ratio)
    r = Result("transmission", conditions={"rate_deg_s": rate_deg_s, "revolutions": revolutions,
                                           "direction": direction, "samples": int(mot.size),
                                           "sample_period_s": decim * 1e-4, "setup": GEAR_SETUP.name})
    r.figures = ta
    r.headline = {"transmission_accuracy_arcmin": ta["accuracy_arcmin"]}
    r.series = {"out_rad": out, "te_rad": mt.transmission_error(mot, out, bench.ratio)}

    def plot(res: Result, d: Path, fmt: str) -> list[Path]:
        fig, ax = figure()
        a = ax[0][0]
        s = res.series
        a.plot(np.degrees(s["out_rad"] - s["out_rad"][0]), s["te_rad"] / mt.ARCSEC, lw=0.6)
        a.set_xlabel("output angle (deg)")
        a.set_ylabel("transmission error (arcsec)")
        a.set_title(f"transmission accuracy {res.figures['accuracy_arcmin']:.3f} arcmin p-p")
        a.grid(True)
        return save_figure(fig, d, res.name, fmt, label=res.label)
    r.plot = plot
    return r


__all__ = ["GEAR_SETUP", "hysteresis", "lost_motion", "midline", "starting_torque", "stiffness", "torque_loop",
           "transmission"]
