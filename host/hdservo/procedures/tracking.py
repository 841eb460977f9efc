"""Figures where compensation matters: slow sinusoid tracking, reversal glitch, settling into +-1".

* :func:`tracking` -- the output follows a position sinusoid streamed by the host (CSP,
  lock-step, one set-point + velocity offset per SYNC) of peak rate 0.01 deg/s and 0.1 deg/s
  (period :data:`TRACK_PERIOD_S`, starting at rest: ``r(t) = A (1 - cos(w t))``,
  ``A = v_peak / w``).  After a lead-in of 3/4 period one whole period is captured (output
  encoder and the drive's reference); the tracking error is output minus the streamed
  set-point.  Headline: RMS and peak |error| per rate, and the reversal (quadrant) glitch: the
  largest |error| within :data:`REVERSAL_WINDOW` of a period after each velocity reversal, over
  both rates.
* :func:`settling` -- profile-position moves of +-1 deg (the drive's own trajectory); the
  settling time is the time from the reference's arrival until the output encoder, averaged over
  :data:`SETTLE_AVG_S`, stays within +-1 arcsec of the target for the rest of the record (at least
  :data:`SETTLE_HOLD_S`).  Headline: the slowest move.

The metrics (:func:`tracking_metrics`, :func:`settling_time`) are pure functions of the
records, tested on synthetic signals in ``tests/python/test_tracking.py``.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

from . import metrics as mt
from .closedloop import AXIS_SETUP, TURN, pp_move_start
from .results import Result, figure, save_figure
from .runner import DT, Bench, Progress
from ..phase import unwrap_pair

#: Peak rates of the tracking sinusoids, deg/s.
TRACK_RATES_DEG_S: tuple[float, ...] = (0.01, 0.1)
#: Period of the tracking sinusoids, s (two velocity reversals per period).
TRACK_PERIOD_S = 4.0
#: Reversal window: the glitch is looked for from the reversal to this fraction of a period after it
#: (a quarter period: until the next velocity peak; the stick after a slow reversal lasts that long).
REVERSAL_WINDOW = 0.25
#: Settling: move size (deg), band (arcsec), record after the reference's arrival (s).
SETTLE_STEP_DEG = 1.0
SETTLE_BAND_ARCSEC = 1.0
SETTLE_RECORD_S = 2.5
#: Settling: the band is judged on the output's moving mean over this window, s (10 ms: the encoder
#: noise and vibration above 100 Hz -- a friction feed-forward's dither at rest -- are not a position
#: error here; the stabilisation and hold figures report them).
SETTLE_AVG_S = 0.01
#: Settling: the output must stay in the band at least this long before the record ends, s (a
#: move whose error enters the band only in the last samples has not settled).
SETTLE_HOLD_S = 0.5


def rate_tag(rate_deg_s: float) -> str:
    """Key tag of a rate: 0.01 -> ``0p01`` (``tracking_rms_0p01_arcsec``)."""
    return f"{rate_deg_s:g}".replace(".", "p").replace("-", "m")


def sine_setpoints(rate_deg_s: float, period_s: float, n: int, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Set-points of the tracking sinusoid: position (rad, from 0) and velocity (rad/s), ``n`` samples.

    ``r(t) = A (1 - cos(w t))`` with ``w = 2 pi / period_s`` and ``A = v / w`` (peak rate ``v``):
    starts at rest, velocity reversals at t = period/2, period, ...
    """
    w = TURN / period_s
    v = math.radians(rate_deg_s)
    t = np.arange(n) * dt_s
    return v / w * (1.0 - np.cos(w * t)), v * np.sin(w * t)


def align_lag(ref: np.ndarray, cmd: np.ndarray, max_lag: int = 4) -> int:
    """Samples by which the drive's captured reference trails the streamed set-points.

    The lag ``d`` in 0..``max_lag`` that minimises the median |ref[i] - cmd[i - d]| (the
    drive takes a set-point in the period after its SYNC).
    """
    n = min(ref.size, cmd.size) - max_lag
    best, best_d = math.inf, 0
    for d in range(max_lag + 1):
        e = float(np.median(np.abs(ref[max_lag:max_lag + n] - cmd[max_lag - d:max_lag - d + n])))
        if e < best:
            best, best_d = e, d
    return best_d


def tracking_metrics(t_s: np.ndarray, err_rad: np.ndarray, vel_rad_s: np.ndarray,
                     window_s: float) -> dict[str, Any]:
    """RMS, peak and reversal-glitch peak of a tracking error, arcsec.

    Parameters
    ----------
    t_s : array
        Sample times, s.
    err_rad : array
        Tracking error (output - set-point), rad.
    vel_rad_s : array
        Set-point velocity at the same samples, rad/s (its sign changes are the reversals).
    window_s : float
        Length of the window after each reversal in which the glitch is looked for, s.

    Returns
    -------
    dict
        ``rms_arcsec``, ``peak_arcsec``, ``reversal_peak_arcsec`` (None without a reversal),
        ``reversals`` (count), ``reversal_t_s`` (times, s).
    """
    e = np.asarray(err_rad, float) / mt.ARCSEC
    v = np.asarray(vel_rad_s, float)
    s = np.sign(v)
    nz = np.flatnonzero(s != 0)
    rev = [int(nz[k + 1]) for k in range(nz.size - 1) if s[nz[k + 1]] != s[nz[k]]]
    peaks = []
    for i in rev:
        m = (t_s >= t_s[i]) & (t_s <= t_s[i] + window_s)
        peaks.append(float(np.max(np.abs(e[m]))))
    return {"rms_arcsec": float(np.sqrt(np.mean(e * e))), "peak_arcsec": float(np.max(np.abs(e))),
            "reversal_peak_arcsec": max(peaks) if peaks else None, "reversals": len(rev),
            "reversal_t_s": [float(t_s[i]) for i in rev]}


def tracking(bench: Bench, rates_deg_s: Sequence[float] = TRACK_RATES_DEG_S, period_s: float = TRACK_PERIOD_S,
             progress: Optional[Progress] = None) -> Result:
    """Sinusoid tracking at each peak rate (module docstring); lock-step CSP stream.

    Headline: ``tracking_rms_<tag>_arcsec`` and ``tracking_peak_<tag>_arcsec`` per rate
    (:func:`rate_tag`) and ``reversal_peak_arcsec`` (largest glitch over the rates).
    """
    if not rates_deg_s or min(rates_deg_s) <= 0 or period_s <= 0:
        raise ValueError("tracking: the rates (deg/s) and the period (s) must be > 0")
    k = bench.sync_periods
    dt = k * DT
    per = int(round(period_s / dt))
    lead = 3 * per // 4               # past the start transient; reversals at 1/4 and 3/4 of the record
    decim = k
    frames = per
    if frames * 2 > 8192:
        decim = k * int(math.ceil(frames * 2 / 8192))
        frames = per * k // decim
    n = lead + frames * decim // k + 2
    bench.rig.brake(False)
    runs = []
    for j, rate in enumerate(rates_deg_s):
        bench.enable("CYCLIC SYNCHRONOUS POSITION")
        hold = bench.load_angle_rad()
        bench.wait(0.2)
        pos, vel = sine_setpoints(rate, period_s, n, dt)
        cmd = np.round((hold + pos) / TURN * 2 ** 24) / 2 ** 24 * TURN       # what 0x607A holds
        send_i = iter(range(n))

        def send(_: float) -> None:
            i = next(send_i)
            bench.rpdo_position(hold + pos[i], vel[i])
        bench.stream(pos[:lead], send)
        cap = bench.capture(["pos_ref_lo", "pos_out_lo"], frames, decim,
                            action=lambda: bench.stream(pos[lead:], send))
        fault = bench.fault()
        bench.disable()
        if fault:
            raise RuntimeError(f"the drive faulted tracking {rate:g} deg/s (fault code {fault})")
        step = decim // k
        ref, out = unwrap_pair(cap["pos_ref_lo"], cap["pos_out_lo"], centred=False)
        ref, out = ref * TURN, out * TURN
        # the captured words are the low 32 bits: put them on the set-points' turn
        off = TURN * round((cmd[lead] - ref[0]) / TURN)
        ref, out = ref + off, out + off
        idx = lead + np.arange(frames) * step
        d = align_lag(ref, cmd[idx], max_lag=4)
        c_al = cmd[np.clip(idx - d * step, 0, n - 1)]
        v_al = vel[np.clip(idx - d * step, 0, n - 1)]
        t = np.arange(frames) * decim * DT
        m = tracking_metrics(t, out - c_al, v_al, REVERSAL_WINDOW * period_s)
        runs.append({"rate_deg_s": float(rate), "amplitude_arcsec": math.radians(rate) / (TURN / period_s) / mt.ARCSEC,
                     "lag_setpoints": d, **m, "t_s": t, "err_arcsec": (out - c_al) / mt.ARCSEC,
                     "cmd_deg": np.degrees(c_al - c_al[0])})
        if progress:
            progress((j + 1) / len(rates_deg_s), f"{rate:g} deg/s: RMS {m['rms_arcsec']:.3g}\", "
                                                  f"peak {m['peak_arcsec']:.3g}\"")
    r = Result("tracking", conditions={"rates_deg_s": [float(x) for x in rates_deg_s], "period_s": period_s,
                                       "profile": "A (1 - cos(2 pi t / period)), A = rate period / (2 pi)",
                                       "setpoints": f"CSP + velocity offset, one per {k} loop periods",
                                       "error": "output encoder - set-point",
                                       "reversal_window_s": REVERSAL_WINDOW * period_s, "setup": AXIS_SETUP.name})
    keep = ("rate_deg_s", "amplitude_arcsec", "lag_setpoints", "rms_arcsec", "peak_arcsec", "reversal_peak_arcsec",
            "reversals", "reversal_t_s")
    r.figures = {"runs": [{kk: x[kk] for kk in keep} for x in runs]}
    head: dict[str, Any] = {}
    for x in runs:
        tag = rate_tag(x["rate_deg_s"])
        head[f"tracking_rms_{tag}_arcsec"] = x["rms_arcsec"]
        head[f"tracking_peak_{tag}_arcsec"] = x["peak_arcsec"]
    glitches = [x["reversal_peak_arcsec"] for x in runs if x["reversal_peak_arcsec"] is not None]
    head["reversal_peak_arcsec"] = max(glitches) if glitches else None
    r.headline = head
    r.series = {"runs": runs}

    r.plot = _plot_tracking
    return r


def _plot_tracking(res: Result, dd: Path, fmt: str) -> list[Path]:
    """Tracking error over time, one panel per sinusoidal rate, velocity reversals dotted."""
    rr = res.series["runs"]
    fig, ax = figure(len(rr), 1, (8.0, 3.0 * len(rr)))
    for i, x in enumerate(rr):
        a = ax[i][0]
        a.plot(x["t_s"], x["err_arcsec"], lw=0.7, color="C0", label="tracking error (output - set-point)")
        for tr in x["reversal_t_s"]:
            a.axvline(tr, color="k", ls=":", lw=0.8)
        a.set_title(f"sinusoid, peak {x['rate_deg_s']:g} deg/s: RMS {x['rms_arcsec']:.3g}\", "
                    f"peak {x['peak_arcsec']:.3g}\" (dotted: velocity reversals)", fontsize=9)
        a.set_ylabel("error (arcsec)")
        a.grid(True)
        a.legend(fontsize=8, loc="upper right")
    ax[-1][0].set_xlabel("time (s)")
    return save_figure(fig, dd, res.name, fmt, label=res.label)


def moving_mean(t_s: np.ndarray, x: np.ndarray, avg_s: float) -> np.ndarray:
    """Causal moving mean of ``x`` over ``avg_s`` (uniform samples ``t_s``; shorter at the start).

    ``avg_s`` <= 0 or a single sample: ``x`` itself (as float).
    """
    e = np.asarray(x, float)
    t = np.asarray(t_s, float)
    if avg_s <= 0 or e.size < 2:
        return e
    n = max(1, int(round(avg_s / float(t[1] - t[0]))))
    c = np.concatenate([[0.0], np.cumsum(e)])
    idx = np.arange(e.size)
    lo = np.maximum(idx + 1 - n, 0)
    return (c[idx + 1] - c[lo]) / (idx + 1 - lo)


def settling_time(t_s: np.ndarray, err_arcsec: np.ndarray, t_arrive_s: float, band_arcsec: float,
                  avg_s: float = 0.0, hold_s: float = 0.0) -> Optional[float]:
    """Time from ``t_arrive_s`` until ``|err|`` stays within ``band_arcsec`` to the end, s (None: never).

    Parameters
    ----------
    t_s : array
        Sample times, s (uniform).
    err_arcsec : array
        Output - target, arcsec.
    t_arrive_s : float
        The reference's arrival, s.
    band_arcsec : float
        Half width of the band, arcsec.
    avg_s : float
        The band is judged on the error's moving mean over this window, s (0: the samples
        themselves).  The window ends at each sample (causal), so it delays the settling time by
        at most ``avg_s``.
    hold_s : float
        The error must stay in the band at least this long before the end of the record, s;
        otherwise the move has not settled within the record (None).

    Returns
    -------
    float or None
        0 when the error is inside the band from the arrival on; None when it never settles.
    """
    t = np.asarray(t_s, float)
    e = np.abs(moving_mean(t, err_arcsec, avg_s))
    after = t >= t_arrive_s
    if not np.any(after):
        return None
    outside = np.flatnonzero(after & (e > band_arcsec))
    if outside.size == 0:
        return 0.0
    last = int(outside[-1])
    if last + 1 >= e.size or t[-1] - t[last + 1] < hold_s:
        return None
    return float(t[last + 1] - t_arrive_s)


def settling(bench: Bench, step_deg: float = SETTLE_STEP_DEG, moves: int = 4, band_arcsec: float = SETTLE_BAND_ARCSEC,
             record_s: float = SETTLE_RECORD_S, progress: Optional[Progress] = None) -> Result:
    """Settling time into +-``band_arcsec`` after ``moves`` profile moves of +-``step_deg`` (alternating).

    Each move is captured (output encoder, drive reference; 1 ms samples) from its start to
    ``record_s`` after a generous estimate of the trajectory time; the arrival is the first
    sample at which the reference reaches the target.  Headline ``settling_1deg_s`` (for a
    1 deg step; ``settling_<tag>deg_s`` otherwise): the slowest move, None when one never settles.
    """
    if moves < 1 or step_deg <= 0 or band_arcsec <= 0 or record_s <= 0:
        raise ValueError("settling: moves >= 1 and a positive step, band and record are needed")
    vmax = float(bench.drive.get_param("traj_vmax")) * TURN          # rad/s
    amax = float(bench.drive.get_param("traj_amax")) * TURN          # rad/s^2
    step = math.radians(step_deg)
    t_move = 2.0 * math.sqrt(step / max(amax, 1e-9)) + step / max(vmax, 1e-9) + 0.2
    decim = 10
    frames = min(4000, int(math.ceil((t_move + record_s + 1.0) / (decim * DT))))
    bench.rig.brake(False)
    bench.enable("PROFILED POSITION")
    bench.wait(0.5)
    start = bench.load_angle_rad()
    out_moves = []
    for j in range(moves):
        sgn = 1.0 if j % 2 == 0 else -1.0
        target = start + sgn * step if j % 2 == 0 else start
        cap = bench.capture(["pos_ref_lo", "pos_out_lo"], frames, decim, action=lambda: pp_move_start(bench, target))
        ref, out = unwrap_pair(cap["pos_ref_lo"], cap["pos_out_lo"], centred=False)
        ref, out = ref * TURN, out * TURN
        t = np.arange(ref.size) * decim * DT
        final = ref[-1]
        arr = np.flatnonzero(np.abs(ref - final) < 0.5 / 2 ** 32 * TURN + 1e-15)
        # the first sample of the final run at the target
        moving = np.flatnonzero(np.abs(ref - final) >= 0.5 / 2 ** 32 * TURN + 1e-15)
        i_arr = int(moving[-1] + 1) if moving.size else int(arr[0])
        err = (out - final) / mt.ARCSEC
        ts = settling_time(t, err, float(t[min(i_arr, t.size - 1)]), band_arcsec, SETTLE_AVG_S, SETTLE_HOLD_S)
        out_moves.append({"direction": int(sgn), "settling_s": ts, "arrival_s": float(t[min(i_arr, t.size - 1)]),
                          "final_error_arcsec": float(np.mean(err[-max(1, err.size // 10):])),
                          "t_s": t, "err_arcsec": err})
        if progress:
            progress((j + 1) / moves, f"move {j + 1} ({'+' if sgn > 0 else '-'}{step_deg:g} deg): "
                                      f"{'never' if ts is None else f'{ts:.3g} s'}")
        fault = bench.fault()
        if fault:
            bench.disable()
            raise RuntimeError(f"the drive faulted during a settling move (fault code {fault})")
        bench.wait(0.2)
    bench.disable()
    vals = [x["settling_s"] for x in out_moves]
    worst = None if any(v is None for v in vals) else max(vals)
    key = "settling_1deg_s" if step_deg == 1.0 else f"settling_{rate_tag(step_deg)}deg_s"
    r = Result("settling", conditions={"step_deg": step_deg, "moves": moves, "band_arcsec": band_arcsec,
                                       "band_judged_on": f"moving mean over {SETTLE_AVG_S * 1e3:g} ms",
                                       "min_time_in_band_s": SETTLE_HOLD_S,
                                       "record_after_move_s": record_s, "measured_by": "output encoder",
                                       "profile": "drive trajectory (traj_vmax, traj_amax, traj_jmax)",
                                       "setup": AXIS_SETUP.name})
    r.figures = {"moves": [{k: v for k, v in x.items() if k not in ("t_s", "err_arcsec")} for x in out_moves]}
    r.headline = {key: worst}
    r.series = {"moves": out_moves, "band": band_arcsec}

    r.plot = _plot_settling
    return r


def _plot_settling(res: Result, dd: Path, fmt: str) -> list[Path]:
    """Output minus target after each move's reference arrives: the judged mean, the samples faint, the band."""
    fig, ax = figure(size=(8.0, 4.5))
    a = ax[0][0]
    for i, x in enumerate(res.series["moves"]):
        tt = x["t_s"] - x["arrival_s"]
        lab = f"move {i + 1} ({'+' if x['direction'] > 0 else '-'}): " + (
            "not settled" if x["settling_s"] is None else f"{x['settling_s']:.3g} s")
        ln = a.plot(tt, moving_mean(x["t_s"], x["err_arcsec"], SETTLE_AVG_S), lw=1.0, label=lab)
        a.plot(tt, x["err_arcsec"], lw=0.4, alpha=0.3, color=ln[0].get_color())
    b = res.series["band"]
    a.axhspan(-b, b, color="0.85", label=f"+-{b:g} arcsec band")
    a.set_ylim(-10 * b, 10 * b)
    a.set_xlim(-0.2, None)
    a.set_xlabel("time after the reference's arrival (s)")
    a.set_ylabel("output - target (arcsec)")
    a.set_title(f"settling after {res.conditions['step_deg']:g} deg moves: {SETTLE_AVG_S * 1e3:g} ms mean "
                f"(faint: samples)", fontsize=10)
    a.grid(True)
    a.legend(fontsize=8)
    return save_figure(fig, dd, res.name, fmt, label=res.label)


__all__ = ["REVERSAL_WINDOW", "SETTLE_AVG_S", "SETTLE_BAND_ARCSEC", "SETTLE_HOLD_S", "SETTLE_STEP_DEG",
           "TRACK_PERIOD_S", "TRACK_RATES_DEG_S", "align_lag", "moving_mean", "rate_tag", "settling", "settling_time",
           "sine_setpoints", "tracking", "tracking_metrics"]
