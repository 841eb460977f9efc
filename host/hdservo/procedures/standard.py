"""Closed-loop test procedures on any CiA 402 drive through its standard objects only.

The procedures of :mod:`.closedloop` use hdservo's capture buffer (0x5000) and
parameters; these run on a :class:`~hdservo.ident.std_runner.StdRunner`
instead: the host streams cyclic synchronous position (CSP, 0x607A with the
velocity offset 0x60B1) one set-point per SYNC and measures the output from
the synchronous TPDO of position actual 0x6064.  The figures are those of
:mod:`.closedloop` (same metrics, same headline names):

* :func:`min_rate` - minimum smooth rate over a rate ladder (fixed-angle
  timing of 0x6064, :func:`~.metrics.rate_stability`);
* :func:`positioning` - ISO 230-2 accuracy and repeatability from host-made
  smooth moves (measured by the drive's own position 0x6064: without a
  reference instrument the figures are the encoder's view);
* :func:`bandwidth` - -3 dB of theta_out / theta_ref for a Schroeder
  multisine on 0x607A (:func:`~.closedloop.bandwidth_signal`);
* :func:`peak_torque` - needs the output locked by the operator; the torque
  is the drive's torque actual value 0x6077 (a drive estimate, not a load
  cell).  On a drive without a brake it is refused with one line.

Every target is relative to where the axis stands when the procedure starts.
"""
from __future__ import annotations

import math
from typing import Any, Callable, Optional, Sequence

import numpy as np

from ..errors import UserError
from . import metrics as mt
from .closedloop import (MIN_WINDOW_ARCSEC, RATE_LADDER_DEG_S, RECORD_MARGIN_WINDOWS, bandwidth_lines,
                         bandwidth_signal, rate_window_rad, rung_settle_s)
from .results import Result

Progress = Callable[[float, str], None]


def _setup(runner: Any) -> dict[str, Any]:
    return {"path": "CiA 402 standard objects (CSP 0x607A/0x60B1, 0x6064 by synchronous TPDO)",
            "sync_period_s": runner.sync_period_s, "lockstep": runner.lockstep}


def min_rate(runner: Any, rates_deg_s: Sequence[float] = RATE_LADDER_DEG_S, bound: float = 0.1, windows: int = 10,
             window_s: float = 1.0, settle_s: float = 5.0, min_window_arcsec: float = MIN_WINDOW_ARCSEC,
             progress: Optional[Progress] = None) -> Result:
    """Minimum smooth rate: each rung a host ramp on 0x607A at the rate (velocity offset 0x60B1 = rate).

    Parameters
    ----------
    runner : StdRunner
        Opened standard-objects runner.
    rates_deg_s : sequence of float
        Rate ladder, deg/s (fastest first; the ladder stops at the first rung that is not smooth).
    bound : float
        Smooth: monotone and rate fluctuation (std / mean of the window rates) <= bound.
    windows, window_s, settle_s, min_window_arcsec
        As :func:`hdservo.procedures.closedloop.min_rate`.
    """
    ladder = []
    dt = runner.sync_period_s
    for i, r in enumerate(sorted(rates_deg_s, reverse=True)):
        rate = math.radians(r)
        win = rate_window_rad(r, window_s, min_window_arcsec)
        settle = rung_settle_s(r, settle_s, window_s, min_window_arcsec)
        dur = (windows + RECORD_MARGIN_WINDOWS) * win / rate
        n = int(math.ceil((settle + dur) / dt))
        ref = rate * np.arange(n) * dt
        tr = runner.track(ref, label=f"min rate: {r:g} deg/s")
        m = tr["t_s"] >= tr["t_s"][0] + settle
        st = mt.rate_stability(tr["t_s"][m], tr["load_angle_rad"][m], rate, win)
        ladder.append({"rate_deg_s": r, "window_arcsec": win / mt.ARCSEC, **st})
        if progress:
            progress((i + 1) / len(rates_deg_s), f"{r:g} deg/s: stability {st['stability']:.3g}")
        if not (st["monotone"] and st["stability"] <= bound):
            break
    best = mt.min_smooth_rate(ladder, bound)
    res = Result("min-rate", conditions={"rates_deg_s": list(rates_deg_s), "bound": bound, "windows": windows,
                                         "window_s": window_s, **_setup(runner)})
    res.figures = {"ladder": ladder}
    res.headline = {"min_smooth_rate_deg_s": best}
    return res


def move_profile(start_rad: float, end_rad: float, vmax_rad_s: float, dt: float) -> np.ndarray:
    """Host-made smooth move (raised-cosine velocity, peak ``vmax``), one set-point per ``dt``, end included."""
    d = end_rad - start_rad
    if d == 0:
        return np.array([end_rad])
    T = max(2.0 * abs(d) / vmax_rad_s, 4 * dt)      # raised cosine: mean speed vmax / 2
    n = int(math.ceil(T / dt))
    s = np.arange(1, n + 1) / n
    return start_rad + d * (s - np.sin(2 * math.pi * s) / (2 * math.pi))


def positioning(runner: Any, targets_deg: Optional[Sequence[float]] = None, runs: int = 5, overrun_deg: float = 1.0,
                vmax_deg_s: float = 20.0, dwell_s: float = 1.5, measure_s: float = 0.2,
                progress: Optional[Progress] = None, exercise: int = 1) -> Result:
    """ISO 230-2 positioning (bidirectional, ``runs`` runs) with host-made moves on 0x607A.

    Before the first run the axis makes ``exercise`` runs that are not measured (the same
    approaches and dwells), as :func:`hdservo.procedures.closedloop.positioning` does.
    Each approach: a smooth move to the target, ``dwell_s`` of standstill, the mean of 0x6064
    over the last ``measure_s``.  All runs are one CSP stream (the axis never disables between
    targets).
    """
    if targets_deg is None:
        targets_deg = list(np.linspace(-55.0, 55.0, 12))
    tg = np.radians(np.asarray(targets_deg, float))
    if runs < 2 or tg.size < 1:
        raise UserError("positioning: needs at least 2 runs and 1 target")
    if exercise < 0:
        raise UserError(f"positioning: --exercise must be >= 0, got {exercise}")
    dt = runner.sync_period_s
    ov = math.radians(overrun_deg)
    vmax = math.radians(vmax_deg_s)
    hold = int(round(dwell_s / dt))
    pieces: list[np.ndarray] = [np.zeros(1)]
    marks: list[tuple[int, int, str]] = []     # (index of the end of the dwell, target, direction)
    pos = 0.0

    def go(to: float, mark: Optional[tuple[int, str]] = None) -> None:
        nonlocal pos
        pieces.append(move_profile(pos, to, vmax, dt))
        pieces.append(np.full(hold, to))
        pos = to
        if mark is not None:
            marks.append((sum(len(p) for p in pieces), mark[0], mark[1]))

    for _ in range(exercise):
        go(tg[0] - ov)
        for i in range(tg.size):
            go(float(tg[i]))
        go(tg[-1] + ov)
        for i in reversed(range(tg.size)):
            go(float(tg[i]))
    for _ in range(runs):
        go(tg[0] - ov)
        for i in range(tg.size):
            go(float(tg[i]), (i, "up"))
        go(tg[-1] + ov)
        for i in reversed(range(tg.size)):
            go(float(tg[i]), (i, "down"))
    go(0.0)
    ref = np.concatenate(pieces)
    tr = runner.track(ref, label="positioning")
    y = tr["load_angle_rad"]
    k = max(1, int(round(measure_s / dt)))
    up = np.zeros((runs, tg.size))
    dn = np.zeros((runs, tg.size))
    cnt = {"up": np.zeros(tg.size, int), "down": np.zeros(tg.size, int)}
    for end, i, d in marks:
        e = min(end - 1, len(y))              # y[j] is the output with ref[j] in force
        val = float(np.mean(y[e - k:e]))
        (up if d == "up" else dn)[cnt[d][i], i] = val
        cnt[d][i] += 1
    iso = mt.iso230_2(tg / mt.ARCSEC, up / mt.ARCSEC, dn / mt.ARCSEC)
    res = Result("positioning", conditions={"targets_deg": list(map(float, targets_deg)), "runs": runs,
                                            "exercise_runs": exercise, "overrun_deg": overrun_deg, "dwell_s": dwell_s, "measure_s": measure_s,
                                            "reference": "output position 0x6064 (the drive's encoder)",
                                            **_setup(runner)})
    res.figures = {"iso230_2_arcsec": iso}
    res.headline = {"positioning_accuracy_arcsec": iso["A"], "repeatability_arcsec": iso["R"],
                    "reversal_arcsec": iso["B"], "systematic_deviation_arcsec": iso["E"]}
    if progress:
        progress(1.0, f"A = {iso['A']:.3g} arcsec")
    return res


def bandwidth(runner: Any, amplitude_arcsec: float = 60.0, period_samples: int = 2048,
              lines: Optional[Sequence[int]] = None, periods: int = 2) -> Result:
    """Closed-loop bandwidth: -3 dB of theta_out (0x6064) / theta_ref (0x607A) for a small multisine.

    ``periods`` periods are streamed, the last one is analysed at its excited DFT lines.  Position
    set-points alone (no velocity offset 0x60B1), as :func:`hdservo.procedures.closedloop.bandwidth`.
    """
    fs = 1.0 / runner.sync_period_s
    if lines is None:
        lines = bandwidth_lines(period_samples, fs)
    sig = bandwidth_signal(amplitude_arcsec, period_samples, lines, fs)
    ref = np.concatenate([np.zeros(1), np.tile(sig, periods), np.zeros(1)])
    tr = runner.track(ref, label="bandwidth", velocity_offset=False)
    # tr["ref_rad"][j] is the set-point in force at the sample tr["load_angle_rad"][j]
    r = tr["ref_rad"][1 + (periods - 1) * period_samples:1 + periods * period_samples]
    y = tr["load_angle_rad"][1 + (periods - 1) * period_samples:1 + periods * period_samples]
    h = mt.line_response(r, y, lines)
    f = np.asarray(lines, float) / (period_samples * runner.sync_period_s)
    bw = mt.bandwidth_3db(f, h)
    res = Result("bandwidth", conditions={"amplitude_arcsec": amplitude_arcsec, "lines_Hz": f.tolist(),
                                          "setpoint_rate_Hz": fs, **_setup(runner)})
    res.figures = {"f_Hz": f.tolist(), "magnitude_dB": (20 * np.log10(np.abs(h))).tolist(),
                   "phase_deg": np.degrees(np.unwrap(np.angle(h))).tolist()}
    res.headline = {"bandwidth_hz": bw}
    return res


def peak_torque(runner: Any, request_Nm: float, output_locked: bool = False, steps: int = 6,
                hold_s: float = 0.2) -> Result:
    """Peak output torque into a locked output: a CST staircase on 0x6071 up to ``request_Nm``.

    The delivered torque is the mean of the drive's torque actual value 0x6077 over 0.5 .. 0.9
    of each step (a drive estimate; a load cell on the rig is better).  ``output_locked`` must
    confirm that the operator locked the output: the standard objects have no brake.
    """
    if not output_locked:
        raise UserError("peak-torque: needs the output locked (a brake or a fixture); the standard objects "
                        "cannot lock it -- lock the output and confirm")
    levels = np.linspace(request_Nm / steps, request_Nm, steps)
    n = int(round(hold_s / runner.sync_period_s))
    prof = np.repeat(levels, n)
    d = runner.torque_staircase(prof)
    delivered = []
    for k in range(steps):
        seg = d["torque_Nm"][k * n + int(0.5 * n):k * n + int(0.9 * n)]
        delivered.append(float(np.mean(np.abs(seg))))
    res = Result("peak-torque", conditions={"request_Nm": request_Nm, "steps": steps, "hold_s": hold_s,
                                            "measured_by": "torque actual value 0x6077", **_setup(runner)})
    res.figures = {"commanded_Nm": levels.tolist(), "delivered_Nm": delivered}
    res.headline = {"peak_torque_Nm": max(delivered)}
    return res


__all__ = ["bandwidth", "min_rate", "move_profile", "peak_torque", "positioning"]
