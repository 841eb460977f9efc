"""Closed-loop figures of merit (harmonic-drive.md 9.3): minimum smooth rate, stabilisation
precision, positioning accuracy/repeatability (ISO 230-2), peak output torque, bandwidth.

Set-ups: :data:`AXIS_SETUP` (payload on, base still) for everything except the
stabilisation test (:func:`stab_setup`: base rocking, default 0.5 deg at 1 Hz).
Moves use the drive's own trajectory generator (CiA 402 profile position,
``traj_vmax``/``traj_amax`` as the profile), so the host never has to stream
set-points for them; the bandwidth test streams a position multisine in
lock-step (one RPDO per SYNC).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

from . import metrics as mt
from .results import Result, figure, save_figure
from .runner import DT, Bench, Progress, RigSetup
from ..phase import unwrap_pair, unwrap_turns

AXIS_SETUP = RigSetup("axis", payload=True)
from ..units import TURN  # noqa: E402
#: capture frames of a three-signal record (8192-word buffer)
CAPTURE_FRAMES_3 = 2700


def stab_setup(amp_deg: float = 0.5, freq_Hz: float = 1.0) -> RigSetup:
    """Swing-table set-up of the stabilisation test."""
    return RigSetup("stabilisation", payload=True, base_amp_rad=math.radians(amp_deg), base_freq_Hz=freq_Hz)


# ---- profile-position helpers ----------------------------------------------------------

def pp_move(bench: Bench, target_rad: float, timeout_s: float = 600.0) -> None:
    """Profile-position move to ``target_rad`` (output); returns when the trajectory has arrived."""
    d = bench.drive
    want = (bench.target_position_raw(target_rad) << 8) & 0xFFFFFFFF
    pp_move_start(bench, target_rad)
    waited = 0.0
    last, still = -1, 0.0
    while True:
        now = int(bench.read(0x5F00, 8))
        if now == want:
            return
        still = still + 0.05 if now == last else 0.0
        last = now
        if still >= 0.5:                 # reference stopped short of the target: new set-point edge again
            pp_move_start(bench, target_rad)
            still = 0.0
        bench.wait(0.05)
        waited += 0.05
        if waited > timeout_s:
            raise RuntimeError(f"profile move to {math.degrees(target_rad):.4f} deg did not arrive")
        if bench.fault():
            raise RuntimeError(f"the drive faulted during a move (fault code {bench.fault()})")


def pp_halt(bench: Bench, settle_s: float = 0.1) -> None:
    """Stop a running profile move where it is (CiA 402 halt, controlword bit 8) and release the halt.

    The drive ramps the move to rest at ``traj_amax`` (at most 1 deg/s / 100 deg/s^2 = 10 ms
    for the min-rate rungs) without reversing; ``settle_s`` of drive time later the halt is
    released and the axis stays at rest until the next set-point.  Raises RuntimeError when the
    reference still moves (a drive without halt).
    """
    d = bench.drive
    d.halt(True)
    bench.wait(settle_s)
    before = int(bench.read(0x5F00, 8))
    bench.wait(0.05)
    stopped = int(bench.read(0x5F00, 8)) == before
    d.halt(False)
    if not stopped:
        raise RuntimeError("the drive did not halt the profile move (controlword bit 8)")


def reference_angle_rad(bench: Bench) -> float:
    """Position reference of the drive, rad: the output angle (0x5F00:9, Q32.32 turns) plus the
    wrapped difference of the low words of reference (0x5F00:8) and output."""
    load = int(bench.read(0x5F00, 9))
    d = (int(bench.read(0x5F00, 8)) - load) & 0xFFFFFFFF
    d = d - (1 << 32) if d >= 1 << 31 else d
    return (load + d) / 2.0 ** 32 * TURN


def pp_move_start(bench: Bench, target_rad: float, tries: int = 5) -> None:
    """Start a profile move (new set-point edge) without waiting for its end.

    The edge is repeated when the reference has not started moving within
    20 ms of drive time (the virtual drive occasionally misses it right
    after an earlier command; see the note in docs/procedures.md).
    """
    d = bench.drive
    raw = bench.target_position_raw(target_rad)
    want = (raw << 8) & 0xFFFFFFFF
    d.write(0x607A, 0, raw)
    for _ in range(tries):
        before = int(bench.read(0x5F00, 8))
        if before == want:
            return
        for cw in (0x0F, 0x1F, 0x0F):
            d.write(0x6040, 0, cw)
            if bench.lockstep:      # the drive samples the controlword once per loop period: let it see each
                bench.sync()
        bench.wait(0.02)
        if int(bench.read(0x5F00, 8)) != before:
            return
    raise RuntimeError(f"the drive did not accept the profile move to {math.degrees(target_rad):.4f} deg")


# ---- minimum smooth rate ------------------------------------------------------------------

#: how far ahead of the rung's start the rung's profile move aims, in multiples of the rung's own
#: travel (settle + record): the slack the move has before it arrives and stops
RATE_REACH = 3.0
#: records of one rung taken again when the reference stopped (arrived) within the record
RATE_ATTEMPTS = 3


def reference_moved_throughout(ref_lo: np.ndarray) -> bool:
    """True when a captured reference (wrapped 2^-32-turn words) advanced between every two samples.

    A reference that stood still for a sample (the profile move had arrived at its target)
    means the record is not a constant-rate run.
    """
    r = unwrap_turns(ref_lo, centred=False)
    d = np.diff(r)
    return bool(d.size > 0 and (np.all(d > 0) or np.all(d < 0)))


#: Default min-rate ladder, deg/s: the decades down to the 0.001 deg/s requirement and three rungs below it,
#: so that the figure can tell two drives apart that both meet the requirement (docs/procedures.md).
RATE_LADDER_DEG_S: tuple[float, ...] = (1.0, 0.1, 0.01, 0.001, 0.0005, 0.0002, 0.0001)
#: Smallest fixed-angle window, arcsec: the 0.001 deg/s rung's 1 s window (47 counts of a 24-bit output
#: encoder).  Slower rungs keep this angle (longer windows) instead of shrinking it into the encoder noise.
MIN_WINDOW_ARCSEC = 3.6
#: Extra record length of a rung, in windows: the record covers ``windows + RECORD_MARGIN_WINDOWS`` windows
#: at the commanded rate, so that ``windows`` whole windows are timed even when the output lags the
#: reference by a fraction of a window at the end of the record (an exact ``windows`` record gave
#: ``windows - 1`` or ``windows`` by chance; with the reference 19 % slow it gave 4 of 5).
RECORD_MARGIN_WINDOWS = 0.5
#: Settling of a rung below 0.5 deg/s: at least this many windows.  The start transient (the loop taking
#: up the gear's presliding compliance) is an angle, ~10 s at 0.0002 deg/s on the reference axis; with a
#: fixed 5 s both the PID and the compensated drive fail the slow rungs on it, not on stick-slip.
SETTLE_WINDOWS = 4.0


def rate_window_rad(rate_deg_s: float, window_s: float = 1.0, min_window_arcsec: float = MIN_WINDOW_ARCSEC) -> float:
    """Fixed-angle window of a rung, rad: ``rate x window_s``, at least ``min_window_arcsec``."""
    return max(math.radians(abs(rate_deg_s)) * window_s, min_window_arcsec * mt.ARCSEC)


def rung_settle_s(rate_deg_s: float, settle_s: float = 5.0, window_s: float = 1.0,
                  min_window_arcsec: float = MIN_WINDOW_ARCSEC, settle_windows: float = SETTLE_WINDOWS) -> float:
    """Settling time of a rung, s: ``settle_s`` but at least ``settle_windows`` windows below 0.5 deg/s
    (the start transient is an angle: the loop takes up the gear's presliding compliance), at most 1 s above."""
    if rate_deg_s >= 0.5:
        return min(settle_s, 1.0)
    return max(settle_s, settle_windows * rate_window_rad(rate_deg_s, window_s, min_window_arcsec)
               / math.radians(rate_deg_s))


def rate_run(bench: Bench, rate_deg_s: float, windows: int, window_s: float, settle_s: float,
             min_window_arcsec: float = MIN_WINDOW_ARCSEC) -> dict[str, Any]:
    """One rung: constant rate through the profile generator; fixed-angle timing on the output encoder.

    The window angle is :func:`rate_window_rad` (``rate x window_s``, at least
    ``min_window_arcsec``); the record covers ``windows`` + :data:`RECORD_MARGIN_WINDOWS` windows
    at the commanded rate (so ``windows`` windows are timed).  ``reference_accuracy`` is
    |reference rate - cmd| / cmd of the drive's own reference over the record (least-squares
    slope): the profile generator's share of the rate error.
    The rung is a profile move at ``traj_vmax`` = rate towards a target :data:`RATE_REACH` x the
    rung's travel ahead; the record (output encoder and the drive's reference) starts after
    ``settle_s``.  With fast pacing the drive's time runs on (~20x real time) while the host is
    busy, so a host stall between the settling and the record (a loaded machine) can let the
    move arrive before or during the record: then the reference stood still in the record, which
    is taken again (:data:`RATE_ATTEMPTS`; ``attempts`` in the result).  The rung ends with a
    halt (:func:`pp_halt`): the move stops where it is, forward, instead of running on to its far
    target (the drive refuses a new profile set-point while a move runs, so an earlier "stop just
    ahead of the reference" was never taken and sent the axis back after the arrival).
    """
    rate = math.radians(rate_deg_s)
    win = rate_window_rad(rate_deg_s, window_s, min_window_arcsec)
    dur = (windows + RECORD_MARGIN_WINDOWS) * win / rate
    frames = CAPTURE_FRAMES_3
    decim = max(1, int(math.ceil(dur / frames / DT)))
    frames = int(math.ceil(dur / (decim * DT)))
    attempts = 0
    with bench.params({"traj_vmax": rate / TURN}):
        while True:
            attempts += 1
            far = bench.load_angle_rad() + rate * (settle_s + dur) * RATE_REACH + math.radians(0.01)
            pp_move_start(bench, far)
            bench.wait(settle_s)
            cap = bench.capture(["pos_out_lo", "pos_out_hi", "pos_ref_lo"], frames, decim)
            fault = bench.fault()
            if fault:
                raise RuntimeError(f"the drive faulted at {rate_deg_s} deg/s (fault code {fault})")
            valid = reference_moved_throughout(cap["pos_ref_lo"])
            if valid or attempts >= RATE_ATTEMPTS:
                break
        # end of the rung: halt (controlword bit 8) stops the move where it is, at traj_amax (the
        # reference never reverses; a new profile set-point would be refused while the move runs)
        pp_halt(bench)
    ang = unwrap_turns(cap["pos_out_lo"], centred=False) * TURN
    t = np.arange(ang.size) * decim * DT
    st = mt.rate_stability(t, ang, rate, win)
    # the drive's own reference over the record: its rate error is the profile generator's, not the axis'
    ref = unwrap_turns(cap["pos_ref_lo"], centred=False) * TURN
    ref_rate = float(np.polyfit(t, ref, 1)[0]) if ref.size > 1 else float("nan")
    return {"rate_deg_s": rate_deg_s, "window_arcsec": win / mt.ARCSEC, "window_s": win / rate, **st,
            "reference_accuracy": abs(ref_rate - rate) / rate,
            "attempts": attempts, "reference_moved_throughout": valid, "t_s": t, "angle_rad": ang}


def min_rate(bench: Bench, rates_deg_s: Sequence[float] = RATE_LADDER_DEG_S, bound: float = 0.1,
             windows: int = 10, window_s: float = 1.0, settle_s: float = 5.0,
             accuracy_bound: Optional[float] = None, progress: Optional[Progress] = None,
             min_window_arcsec: float = MIN_WINDOW_ARCSEC, stop_at_failure: bool = True,
             settle_windows: float = SETTLE_WINDOWS) -> Result:
    """Minimum smooth rate over a rate ladder (fixed-angle timing).

    Each rung moves at a constant commanded rate (profile position with
    ``traj_vmax`` = rate), waits ``settle_s`` and times ``windows`` windows of
    ``rate x window_s`` output angle, at least ``min_window_arcsec`` (the
    rungs below 0.001 deg/s keep 3.6 arcsec: 2 s windows at 0.0005 deg/s,
    5 s at 0.0002, 10 s at 0.0001 deg/s).  A rung is smooth when the angle
    never goes back by a window, every window's rate has the commanded sign,
    and the rate fluctuation (stability sigma(omega_i)/mean) is <= ``bound``;
    the rate accuracy |mean - cmd|/cmd is reported (and also judged when
    ``accuracy_bound`` is given).  The minimum smooth rate is the slowest rung
    with every faster rung smooth too (:func:`metrics.min_smooth_rate`).

    Parameters
    ----------
    rates_deg_s : sequence of float
        Ladder, deg/s (> 0; run fastest first).
    bound : float
        Bound on the rate stability (-).
    windows : int
        Fixed-angle windows per rung.
    window_s : float
        Nominal window duration, s (window angle = rate x window_s).
    settle_s : float
        Drive time at the rate before the record, s (at most 1 s above 0.5 deg/s).
    settle_windows : float
        Below 0.5 deg/s the settling lasts at least this many windows (4: 5 s at 0.001 deg/s,
        8 / 20 / 40 s at 0.0005 / 0.0002 / 0.0001 deg/s).
    min_window_arcsec : float
        Smallest window angle, arcsec.
    stop_at_failure : bool
        Skip the rungs slower than the first one that is not smooth (they cannot change the
        figure; listed in ``figures["skipped_deg_s"]`` and a note).
    """
    if not rates_deg_s or min(rates_deg_s) <= 0:
        raise ValueError(f"min-rate: the ladder needs rates > 0 deg/s, got {list(rates_deg_s)}")
    ladder = []
    bench.rig.brake(False)
    bench.enable("PROFILED POSITION")
    # let the just-enabled hold settle (compensator ramp cb_ramp_ticks, 0.2 s) before the first
    # set-point: while the hold reference still moves, pp_move_start takes that motion for the
    # start of the move, the set-point edge is lost and the first rung never moves
    bench.wait(0.5)
    order = sorted(rates_deg_s, reverse=True)
    skipped: list[float] = []
    for k, rate in enumerate(order):
        settle = rung_settle_s(rate, settle_s, window_s, min_window_arcsec, settle_windows)
        rr = rate_run(bench, rate, windows, window_s, settle, min_window_arcsec)
        rr["settle_s"] = settle
        ladder.append(rr)
        bench.wait(0.2)
        if progress:
            progress((k + 1) / len(rates_deg_s), f"{rate:g} deg/s: stability {rr['stability']:.3g}")
        if stop_at_failure and mt.min_smooth_rate([rr], bound, accuracy_bound) is None:
            skipped = [float(x) for x in order[k + 1:]]     # slower rungs cannot change the figure
            break
    bench.disable()
    best = mt.min_smooth_rate(ladder, bound, accuracy_bound)
    r = Result("min-rate", conditions={"ladder_deg_s": list(rates_deg_s), "bound": bound, "accuracy_bound": accuracy_bound, "windows": windows,
                                       "window_s": window_s, "min_window_arcsec": min_window_arcsec,
                                       "settle_s": settle_s, "settle_windows": settle_windows,
                                       "stop_at_failure": stop_at_failure,
                                       "setup": AXIS_SETUP.name})
    r.figures = {"ladder": [{k: v for k, v in x.items() if k not in ("t_s", "angle_rad")} for x in ladder],
                 "skipped_deg_s": skipped}
    if skipped:
        r.notes.append(f"rungs {', '.join(f'{x:g}' for x in skipped)} deg/s not run: the "
                       f"{ladder[-1]['rate_deg_s']:g} deg/s rung was not smooth")
    r.headline = {"min_smooth_rate_deg_s": best}
    r.series = {"ladder": ladder}

    r.plot = _plot_min_rate
    return r


def _plot_min_rate(res: Result, d: Path, fmt: str) -> list[Path]:
    """Window rate over commanded rate per fixed-angle window, one line per rung, with the bound."""
    fig, ax = figure()
    a = ax[0][0]
    for x in res.series["ladder"]:
        w = mt.fixed_angle_rates(x["t_s"], x["angle_rad"], x["window_arcsec"] * mt.ARCSEC)
        if w.size:
            a.plot(np.arange(w.size) + 1, np.degrees(w) / x["rate_deg_s"], "o-", ms=3, label=f"{x['rate_deg_s']:g} deg/s")
    bound = res.conditions["bound"]
    a.axhspan(1 - bound, 1 + bound, color="0.9")
    a.set_xlabel("fixed-angle window (-)")
    a.set_ylabel("window rate / commanded rate (-)")
    a.grid(True)
    a.legend()
    return save_figure(fig, d, res.name, fmt, label=res.label)


# ---- stabilisation ------------------------------------------------------------------------

#: CiA 402 manufacturer mode of the drive's gyro stabilisation (STAB, app mode 8; docs/control.md)
STAB_MODE = -1
#: 0x6502 (supported drive modes) bit of manufacturer mode -1
STAB_MODE_BIT = 1 << 16
#: ``mode`` values of :func:`stabilisation`
STAB_MODES = ("hold", "stab", "auto")


def drive_has_stab(bench: Bench) -> bool:
    """True when the drive advertises manufacturer mode -1 (STAB) in 0x6502 (bit 16)."""
    try:
        return bool(int(bench.read(0x6502)) & STAB_MODE_BIT)
    except Exception:      # noqa: BLE001 - no 0x6502 (or an SDO abort): no STAB mode
        return False


def enable_stab(bench: Bench, rate_rad_s: float = 0.0) -> None:
    """Enable the drive in STAB (0x6060 = -1) with the commanded inertial rate ``rate_rad_s`` (0x60FF).

    0x60FF is in 2^-32 turn/s units here as for the CSV target (the payload
    gyro's scale).  Raises RuntimeError when the drive does not reach
    OPERATION ENABLED.
    """
    d = bench.drive
    if d.state() == "FAULT":
        d.fault_reset()
    d.write(0x60FF, 0, int(round(rate_rad_s / TURN * 2 ** 32)) if rate_rad_s else 0)
    d.write(0x6060, 0, STAB_MODE)
    for cw in (0x06, 0x07, 0x0F):
        d.write(0x6040, 0, cw)
        bench.wait(0.002)
    for _ in range(200):
        if d.state() == "OPERATION ENABLED":
            return
        bench.wait(0.005)
    raise RuntimeError(f"the drive did not enable in STAB mode (state {d.state()})")


def stabilisation(bench: Bench, duration_s: float = 5.0, settle_s: float = 1.0,
                  progress: Optional[Progress] = None, mode: str = "hold") -> Result:
    """Stabilisation precision: inertial pointing error while the base rocks.

    The payload rate gyro (capture, 1 kHz) is integrated to the inertial
    angle (bias and start angle removed by a straight line); RMS and peak.
    The virtual rig also records the true inertial angle (reference
    instrument).

    Parameters
    ----------
    bench : Bench
        The drive and rig (set-up :func:`stab_setup`).
    duration_s, settle_s : float
        Analysed record and the time before it, s.
    progress : Progress, optional
        Progress indicator.
    mode : {"hold", "stab", "auto"}
        ``hold``: the drive holds its encoder position in CSP (the PID
        baseline: the payload rocks with the base); ``stab``: the drive's gyro
        stabilisation mode (STAB, CiA 402 manufacturer mode -1, commanded
        inertial rate 0x60FF = 0, the drive's compensators); ``auto``: ``stab``
        when the drive advertises mode -1 in 0x6502 (bit 16), else ``hold``.

    Returns
    -------
    Result
        Headline ``stabilisation_rms_arcsec``, ``stabilisation_peak_arcsec``;
        ``conditions["drive_mode"]`` says which mode ran.
    """
    if mode not in STAB_MODES:
        raise ValueError(f"stabilisation mode '{mode}': expected one of {', '.join(STAB_MODES)}")
    stab = mode == "stab" or (mode == "auto" and drive_has_stab(bench))
    decim = 10
    frames = int(round(duration_s / (decim * DT)))
    if frames * 2 > 8192:
        frames = 4096
        decim = int(math.ceil(duration_s / (frames * DT)))
    bench.rig.brake(False)
    if stab:
        enable_stab(bench)
    else:
        bench.enable("CYCLIC SYNCHRONOUS POSITION")
    bench.wait(settle_s)
    rec: dict[str, np.ndarray] = {}
    if bench.rig.virtual:
        with bench.rig.record(decim) as rec:
            cap = bench.capture(["tick", "gyro"], frames, decim)
    else:
        cap = bench.capture(["tick", "gyro"], frames, decim)
    fault = bench.fault()
    bench.disable()
    if fault:
        raise RuntimeError(f"the drive faulted during the {'STAB ' if stab else ''}stabilisation test "
                           f"(fault code {fault})")
    tick = cap["tick"].astype(float)
    t = (tick - tick[0]) * DT
    gyro = cap["gyro"].astype(float) / 2 ** 32 * TURN
    ang = mt.inertial_angle_from_gyro(t, gyro)
    pe = mt.pointing_error(ang)
    setup = bench.rig.setup
    base_rms = setup.base_amp_rad / math.sqrt(2) / mt.ARCSEC
    r = Result("stabilisation", conditions={"duration_s": duration_s, "sample_period_s": decim * DT,
                                            "base_amplitude_deg": math.degrees(setup.base_amp_rad),
                                            "base_frequency_Hz": setup.base_freq_Hz, "setup": setup.name,
                                            "drive_mode": "STAB (CiA 402 mode -1)" if stab else "CSP hold"})
    r.figures = {"gyro_rms_arcsec": pe["rms_arcsec"], "gyro_peak_arcsec": pe["peak_arcsec"],
                 "base_rms_arcsec": base_rms,
                 "isolation_dB": 20 * math.log10(pe["rms_arcsec"] / base_rms) if base_rms > 0 else None}
    r.series = {"t_s": t, "gyro_angle_rad": ang}
    if rec:
        ti = np.interp(tick, rec["tick"], rec["inertial_angle_rad"])
        ti = ti - np.polyval(np.polyfit(t, ti, 1), t)
        tp = mt.pointing_error(ti)
        r.figures.update({"true_rms_arcsec": tp["rms_arcsec"], "true_peak_arcsec": tp["peak_arcsec"]})
        r.series["true_angle_rad"] = ti
    r.headline = {"stabilisation_rms_arcsec": pe["rms_arcsec"], "stabilisation_peak_arcsec": pe["peak_arcsec"]}

    r.plot = _plot_stabilisation
    return r


def _plot_stabilisation(res: Result, d: Path, fmt: str) -> list[Path]:
    """Inertial pointing error over time: integrated gyro, and the rig's true angle where there is one."""
    fig, ax = figure()
    a = ax[0][0]
    s = res.series
    a.plot(s["t_s"], s["gyro_angle_rad"] / mt.ARCSEC, lw=0.8, label="gyro (integrated)")
    if "true_angle_rad" in s:
        a.plot(s["t_s"], s["true_angle_rad"] / mt.ARCSEC, lw=0.6, ls="--", label="true inertial (rig)")
    a.set_xlabel("time (s)")
    a.set_ylabel("inertial pointing error (arcsec)")
    a.grid(True)
    a.legend()
    return save_figure(fig, d, res.name, fmt, label=res.label)


# ---- positioning (ISO 230-2) ------------------------------------------------------------------

#: The virtual rig's instruments kept at every positioning stop (means over the measuring window):
#: the gear's transmitted torque, its twist, the transmission error and the motor angle / N, the last
#: three as deviations in arcsec; the output's deviation from the target is
#: ``motor_dev_arcsec + te_arcsec - twist_arcsec`` (plant: theta_L = theta_M / N + TE - twist).
RIG_AT_STOPS: tuple[str, ...] = ("out_dev_arcsec", "motor_dev_arcsec", "te_arcsec", "twist_arcsec",
                                 "gear_torque_Nm")


def rig_at_stop(rec: "dict[str, np.ndarray]", ratio: float, target_rad: float) -> dict[str, float]:
    """The rig's instruments at one stop (:data:`RIG_AT_STOPS`) from a record of the measuring window.

    Parameters
    ----------
    rec : dict of ndarray
        The virtual rig's record (``load_angle_true_rad``, ``motor_angle_true_rad``, ``te_rad``,
        ``torsion_rad``, ``gear_torque_Nm``; rad and N.m, output side).
    ratio : float
        Gear ratio N.
    target_rad : float
        The stop's target, rad (output).

    Returns
    -------
    dict
        Means over the window: the output's and the motor angle / N's deviation from the target,
        the TE and the twist (arcsec), the gear torque (N.m); a channel the record lacks is NaN.
    """
    def mean(k: str) -> float:
        return float(np.mean(rec[k])) if k in rec and len(rec[k]) else float("nan")
    return {"out_dev_arcsec": (mean("load_angle_true_rad") - target_rad) / mt.ARCSEC,
            "motor_dev_arcsec": (mean("motor_angle_true_rad") / ratio - target_rad) / mt.ARCSEC,
            "te_arcsec": mean("te_rad") / mt.ARCSEC, "twist_arcsec": mean("torsion_rad") / mt.ARCSEC,
            "gear_torque_Nm": mean("gear_torque_Nm")}


#: positioning: unmeasured exercise runs before the first run (the default of every row)
EXERCISE_RUNS = 1


def positioning(bench: Bench, targets_deg: Optional[Sequence[float]] = None, runs: int = 5,
                overrun_deg: float = 1.0, dwell_s: float = 1.5, measure_s: float = 0.2,
                progress: Optional[Progress] = None, exercise: int = EXERCISE_RUNS) -> Result:
    """Positioning accuracy and repeatability, ISO 230-2 style (5 bidirectional runs, 12 targets).

    Before the first run the axis is exercised with ``exercise`` runs that
    are not measured (the same approaches, stops and dwells as a run; ISO 230-2
    allows this warm-up): a gear in service always has a load history, and
    without it the first run starts from the hysteresis' virgin state and lands
    apart from the later runs.  A plain move over the range and back is not
    enough: the state at a stop depends on the stops and dwells before it.

    Each run approaches every target from below (ascending order) and
    then from above (descending), with an ``overrun`` past the first/last
    target so that every approach has the right direction; position measured
    after ``dwell_s`` as the mean over ``measure_s``: by the reference
    instrument (virtual rig: true output angle) or, on a real bench, the
    output encoder.

    Parameters
    ----------
    exercise : int
        Unmeasured exercise runs before the first run (0 = none).
    """
    if exercise < 0:
        raise ValueError(f"positioning: exercise runs must be >= 0, got {exercise}")
    if targets_deg is None:
        targets_deg = list(np.linspace(-55.0, 55.0, 12))
    tg = np.radians(np.asarray(targets_deg, float))
    m = tg.size
    up = np.zeros((runs, m))
    dn = np.zeros((runs, m))
    up_enc = np.zeros((runs, m))
    dn_enc = np.zeros((runs, m))
    # virtual rig: its instruments at every stop (run x target), per approach direction
    stop_rig: dict[str, dict[str, np.ndarray]] = {d: {k: np.full((runs, m), np.nan) for k in RIG_AT_STOPS}
                                                  for d in ("up", "down")}
    bench.rig.brake(False)
    bench.enable("PROFILED POSITION")
    ov = math.radians(overrun_deg)
    total = runs * 2 * m
    done = 0

    def measure(direction: str, j: int, i: int) -> tuple[float, float]:
        bench.wait(dwell_s)
        decim = 10
        frames = max(2, int(round(measure_s / (decim * DT))))
        if bench.rig.virtual:
            with bench.rig.record(decim) as rec:
                cap = bench.capture(["pos_out_lo", "pos_out_hi"], frames, decim)
            ref = float(np.mean(rec["load_angle_true_rad"]))
            for k, v in rig_at_stop(rec, bench.ratio, float(tg[i])).items():
                stop_rig[direction][k][j, i] = v
        else:
            cap = bench.capture(["pos_out_lo", "pos_out_hi"], frames, decim)
            ref = float("nan")
        enc = float(np.mean((cap["pos_out_hi"] * 2.0 ** 32 + cap["pos_out_lo"]) / 2.0 ** 32 * TURN))
        return (ref if math.isfinite(ref) else enc), enc

    for k in range(exercise):
        # the whole approach sequence of a run, its dwells included, nothing measured: the gear's
        # state at each stop depends on the stops and dwells before it, not only on the range
        if progress:
            progress(0.0, f"exercise run {k + 1} of {exercise}")
        pp_move(bench, tg[0] - ov)
        for i in range(m):
            pp_move(bench, tg[i])
            bench.wait(dwell_s + measure_s)
        pp_move(bench, tg[-1] + ov)
        for i in reversed(range(m)):
            pp_move(bench, tg[i])
            bench.wait(dwell_s + measure_s)
    for j in range(runs):
        pp_move(bench, tg[0] - ov)
        for i in range(m):
            pp_move(bench, tg[i])
            up[j, i], up_enc[j, i] = measure("up", j, i)
            done += 1
            if progress:
                progress(done / total, f"run {j + 1} up {math.degrees(tg[i]):+.1f} deg")
        pp_move(bench, tg[-1] + ov)
        for i in reversed(range(m)):
            pp_move(bench, tg[i])
            dn[j, i], dn_enc[j, i] = measure("down", j, i)
            done += 1
            if progress:
                progress(done / total, f"run {j + 1} down {math.degrees(tg[i]):+.1f} deg")
    bench.disable()
    iso = mt.iso230_2(tg / mt.ARCSEC, up / mt.ARCSEC, dn / mt.ARCSEC)
    iso_enc = mt.iso230_2(tg / mt.ARCSEC, up_enc / mt.ARCSEC, dn_enc / mt.ARCSEC)
    r = Result("positioning", conditions={"targets_deg": list(map(float, targets_deg)), "runs": runs,
                                          "exercise_runs": exercise, "overrun_deg": overrun_deg, "dwell_s": dwell_s,
                                          "measure_s": measure_s,
                                          "reference": "rig (true output angle)" if bench.rig.virtual
                                          else "output encoder", "setup": AXIS_SETUP.name})
    r.figures = {"iso230_2_arcsec": iso, "output_encoder_iso230_2_arcsec": {k: iso_enc[k] for k in
                                                                          ("A", "R", "B", "E", "M")}}
    if bench.rig.virtual:
        r.figures["rig_at_stops"] = {d: {k: v.tolist() for k, v in q.items()} for d, q in stop_rig.items()}
        r.figures["stop_error_parts_arcsec"] = mt.stop_error_parts(r.figures["rig_at_stops"])
    r.headline = {"positioning_accuracy_arcsec": iso["A"], "repeatability_arcsec": iso["R"],
                  "reversal_arcsec": iso["B"], "systematic_deviation_arcsec": iso["E"]}
    r.series = {"targets_deg": np.asarray(targets_deg, float), "up": (up - tg) / mt.ARCSEC, "down": (dn - tg) / mt.ARCSEC}

    r.plot = _plot_positioning
    return r


def _plot_positioning(res: Result, d: Path, fmt: str) -> list[Path]:
    """Positional deviation at each target, every run, per approach direction."""
    fig, ax = figure()
    a = ax[0][0]
    s = res.series
    for j in range(s["up"].shape[0]):
        a.plot(s["targets_deg"], s["up"][j], "^-", color="C0", ms=3, lw=0.5, label="approach +" if j == 0 else None)
        a.plot(s["targets_deg"], s["down"][j], "v-", color="C1", ms=3, lw=0.5, label="approach -" if j == 0 else None)
    a.set_xlabel("target (deg)")
    a.set_ylabel("positional deviation (arcsec)")
    a.set_title(f"A = {res.headline['positioning_accuracy_arcsec']:.3g}\", R = {res.headline['repeatability_arcsec']:.3g}\"")
    a.grid(True)
    a.legend()
    return save_figure(fig, d, res.name, fmt, label=res.label)


# ---- peak output torque ------------------------------------------------------------------------

#: peak torque: request of the saturated last step, x the drive's torque_limit (default definition)
PEAK_OVERDRIVE = 1.5
#: peak torque: averaging window within each step, fractions of the hold time (the prediction uses it too)
PEAK_WINDOW = (0.5, 0.9)


def peak_torque(bench: Bench, request_Nm: Optional[float] = None, steps: int = 6, hold_s: float = 0.2,
                progress: Optional[Progress] = None, overdrive: float = PEAK_OVERDRIVE) -> Result:
    """Peak output torque: locked-output stall with a staircase of torque steps.

    Definition (shared with :func:`hdservo.design.predict.peak_torque`, docs/procedures.md):
    the output torque the axis delivers into a locked output **with the
    drive's own ``torque_limit`` in force**: CST steps at ``k/steps`` x
    torque_limit (k = 1 .. steps-1), then a last step requesting ``overdrive``
    x torque_limit (the drive saturates at its limit); each step is held
    ``hold_s`` (shorter than the saturation-time fault ``torque_sat_time``)
    and the delivered torque is the mean |output torque| over
    ``PEAK_WINDOW`` = 0.5 .. 0.9 of the hold.  The headline is the delivered
    torque of the saturated last step.  The saturation-time fault is widened
    to 5 s for the test (the capture upload adds drive time to the saturated
    step in fast pacing) and the command is zeroed right after that capture.  Output torque = the load cell on the
    locked output (virtual rig: the gear's transmitted torque) or, on a real
    bench, N Kt i from the drive's current sensor (motor friction included).

    With an explicit ``request_Nm`` the older test runs instead: steps up to
    the request with ``torque_limit`` raised to 1.1 x the request for the
    test (what the axis delivers when asked for that torque); the headline is
    then the largest delivered step.
    """
    rated = bench.rated_torque_Nm()
    limit = float(bench.drive.get_param("torque_limit"))
    definition, req, levels, params = _peak_levels(bench, limit, request_Nm, steps, overdrive)
    bench.rig.brake(True)
    with bench.params(params):
        bench.enable("CYCLIC SYNCHRONOUS TORQUE")
        delivered, from_current = _torque_staircase(bench, levels, rated, hold_s, progress)
        bench.drive.write(0x6071, 0, 0)
        bench.wait(0.1)
        fault = bench.fault()
        bench.disable()
    bench.rig.brake(False)
    n = len(delivered)
    if definition == "limit" and n == len(levels) and not fault:
        peak = float(delivered[-1])
    else:
        peak = float(max(delivered)) if delivered else None
    r = Result("peak-torque", conditions={"request_Nm": req, "torque_limit_Nm": limit, "steps": len(levels),
                                          "hold_s": hold_s, "window": list(PEAK_WINDOW), "definition": definition,
                                          "measured_by": "load cell (rig)" if bench.rig.virtual else "N Kt i",
                                          "setup": "axis, output locked"})
    r.figures = {"commanded_Nm": levels[:n].tolist(), "delivered_Nm": delivered,
                 "from_current_Nm": from_current, "fault_code": fault}
    r.headline = {"peak_torque_Nm": peak}
    r.series = {"cmd": levels[:n], "delivered": np.array(delivered), "current": np.array(from_current)}
    r.plot = _plot_peak_torque
    return r


def _peak_levels(bench: Bench, limit: float, request_Nm: Optional[float], steps: int,
                 overdrive: float) -> tuple[str, float, np.ndarray, dict[str, float]]:
    """The staircase of :func:`peak_torque`: (definition, request N.m, step levels N.m, drive parameters
    set for the test)."""
    if request_Nm is None:
        req = overdrive * limit
        levels = np.append(np.linspace(limit / steps, limit, steps)[:-1], req)
        # the saturated step lasts hold_s of drive time plus the capture upload (drive time runs on in fast
        # pacing): the saturation-time fault is widened to 5 s for the test, the command zeroed right after
        return "limit", req, levels, {"torque_sat_time": max(float(bench.drive.get_param("torque_sat_time")), 50000.0)}
    req = float(request_Nm)
    return "request", req, np.linspace(req / steps, req, steps), {"torque_limit": max(1.1 * req, 1.0)}


def _torque_staircase(bench: Bench, levels: np.ndarray, rated: float, hold_s: float,
                      progress: Optional[Progress]) -> tuple[list[float], list[float]]:
    """Hold each CST level ``hold_s`` and average |output torque| over :data:`PEAK_WINDOW` of the hold;
    returns (delivered N.m: load cell on the virtual rig, else N Kt i; N Kt i N.m).  Stops at a fault."""
    delivered: list[float] = []
    from_current: list[float] = []
    w0, w1 = PEAK_WINDOW
    for k, lev in enumerate(levels):
        bench.drive.write(0x6071, 0, int(round(lev / rated * 1000)))
        bench.wait(hold_s * w0)
        frames = max(4, int(hold_s * (w1 - w0) / (10 * DT)))
        if bench.rig.virtual:
            with bench.rig.record(10) as rec:
                cap = bench.capture(["current"], frames, 10)
            delivered.append(float(np.mean(np.abs(rec["gear_torque_Nm"]))))
        else:
            cap = bench.capture(["current"], frames, 10)
        if k + 1 == len(levels):
            bench.drive.write(0x6071, 0, 0)          # leave the saturated (last) step at once
        i = float(np.mean(np.abs(cap["current"]))) / 2 ** 16
        from_current.append(i * bench.kt * bench.ratio)
        if not bench.rig.virtual:
            delivered.append(from_current[-1])
        if progress:
            progress((k + 1) / len(levels), f"{lev:.3g} N.m commanded: {delivered[-1]:.3g} N.m delivered")
        if bench.fault():
            break
        if k + 1 < len(levels):
            bench.wait(hold_s * (1.0 - w1))
    return delivered, from_current


def _plot_peak_torque(res: Result, d: Path, fmt: str) -> list[Path]:
    """Delivered output torque (load cell and N Kt i) against the commanded output torque."""
    fig, ax = figure()
    a = ax[0][0]
    s = res.series
    a.plot(s["cmd"], s["delivered"], "o-", label="delivered (load cell)")
    a.plot(s["cmd"], s["current"], "s--", label="N Kt i")
    a.plot(s["cmd"], s["cmd"], "k:", label="commanded")
    a.set_xlabel("commanded output torque (N.m)")
    a.set_ylabel("output torque (N.m)")
    a.grid(True)
    a.legend()
    return save_figure(fig, d, res.name, fmt, label=res.label)


# ---- closed-loop bandwidth ----------------------------------------------------------------------

#: bandwidth multisine: set-points per period, lines, lowest line index, highest line frequency
BW_PERIOD_SAMPLES = 2048
BW_LINES = 18
BW_FIRST_LINE = 2
BW_F_HI_HZ = 80.0


def bandwidth_lines(period_samples: int = BW_PERIOD_SAMPLES, setpoint_rate_Hz: float = 1000.0,
                    count: int = BW_LINES, f_hi_Hz: float = BW_F_HI_HZ) -> list[int]:
    """DFT lines of the bandwidth multisine: ``count`` log-spaced from line 2 to ``f_hi_Hz`` (deduplicated).

    With the defaults (2048 set-points at 1 kHz: 0.488 Hz spacing) 18 lines 0.98 .. 79.6 Hz.
    """
    return sorted(set(int(round(x)) for x in np.geomspace(BW_FIRST_LINE, period_samples * f_hi_Hz / setpoint_rate_Hz,
                                                          count)))


def bandwidth_signal(amplitude_arcsec: float, period_samples: int = BW_PERIOD_SAMPLES,
                     lines: Optional[Sequence[int]] = None, setpoint_rate_Hz: float = 1000.0) -> np.ndarray:
    """One period of the bandwidth excitation, rad: Schroeder multisine of peak ``amplitude_arcsec``.

    :func:`bandwidth` streams it (one set-point per SYNC); the design
    prediction (:func:`hdservo.design.predict.bandwidth`) uses the same signal.
    """
    ln = bandwidth_lines(period_samples, setpoint_rate_Hz) if lines is None else list(lines)
    return mt.schroeder_multisine(period_samples, ln) * amplitude_arcsec * mt.ARCSEC


def bandwidth(bench: Bench, amplitude_arcsec: float = 60.0, period_samples: int = 2048,
              lines: Optional[Sequence[int]] = None, periods: int = 2,
              progress: Optional[Progress] = None) -> Result:
    """Closed-loop bandwidth: -3 dB of the position response to a small multisine.

    A Schroeder-phased multisine of peak ``amplitude_arcsec`` on the CSP
    target, one set-point per SYNC (``sync_periods`` loop periods), periodic
    over ``period_samples`` set-points; after ``periods - 1`` periods of
    transient one exact period of the drive's own reference and output angle
    is captured; H = Y/R at the excited lines.
    """
    k = bench.sync_periods
    fs_sp = 1.0 / (k * DT)
    if lines is None:
        lines = bandwidth_lines(period_samples, fs_sp)
    sig = bandwidth_signal(amplitude_arcsec, period_samples, lines, fs_sp)
    decim = k // 2 if k % 2 == 0 and k >= 2 else k
    frames = period_samples * k // decim
    if frames * 2 > 8192:
        decim = k
        frames = period_samples
    bench.rig.brake(False)
    bench.enable("CYCLIC SYNCHRONOUS POSITION")
    hold = bench.load_angle_rad()
    bench.wait(0.2)
    send = lambda v: bench.rpdo_position(hold + v)   # noqa: E731
    bench.stream(np.tile(sig, periods - 1), send)
    cap = bench.capture(["pos_ref_lo", "pos_out_lo"], frames, decim,
                        action=lambda: bench.stream(np.tile(sig, 2), send))
    fault = bench.fault()
    bench.disable()
    if fault:
        raise RuntimeError(f"the drive faulted during the bandwidth test (fault code {fault})")
    ref, out = unwrap_pair(cap["pos_ref_lo"], cap["pos_out_lo"], centred=False)
    ref, out = ref * TURN, out * TURN
    n = frames
    h = mt.line_response(ref[:n], out[:n], lines)
    f = np.asarray(lines, float) / (period_samples * k * DT)
    bw = mt.bandwidth_3db(f, h)
    mag = 20 * np.log10(np.abs(h))
    ph = np.degrees(np.unwrap(np.angle(h)))
    r = Result("bandwidth", conditions={"amplitude_arcsec": amplitude_arcsec, "lines_Hz": f.tolist(),
                                        "setpoint_rate_Hz": fs_sp, "setup": AXIS_SETUP.name})
    r.figures = {"f_Hz": f.tolist(), "magnitude_dB": mag.tolist(), "phase_deg": ph.tolist()}
    r.headline = {"bandwidth_hz": bw}
    r.series = {"f": f, "mag": mag, "ph": ph}

    def plot(res: Result, d: Path, fmt: str) -> list[Path]:
        fig, ax = figure(2, 1, (8, 6))
        s = res.series
        ax[0][0].semilogx(s["f"], s["mag"], "o-")
        ax[0][0].axhline(-3, color="k", ls=":")
        ax[0][0].set_ylabel("|theta_L / theta_ref| (dB)")
        ax[1][0].semilogx(s["f"], s["ph"], "o-")
        ax[1][0].set_ylabel("phase (deg)")
        ax[1][0].set_xlabel("frequency (Hz)")
        for a in (ax[0][0], ax[1][0]):
            a.grid(True, which="both")
        return save_figure(fig, d, res.name, fmt, label=res.label)
    r.plot = plot
    return r


__all__ = ["AXIS_SETUP", "RIG_AT_STOPS", "rig_at_stop", "MIN_WINDOW_ARCSEC", "PEAK_OVERDRIVE", "RATE_LADDER_DEG_S", "SETTLE_WINDOWS", "PEAK_WINDOW", "STAB_MODE", "STAB_MODES", "bandwidth", "bandwidth_lines",
           "bandwidth_signal", "drive_has_stab", "enable_stab", "min_rate", "peak_torque", "positioning", "pp_move",
           "rate_window_rad", "reference_angle_rad", "rung_settle_s", "stab_setup", "stabilisation"]
