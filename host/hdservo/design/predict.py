"""Performance figures of a candidate axis, predicted offline in the simulator.

Each figure is the simulator counterpart of a test procedure
(:mod:`hdservo.procedures.closedloop`), run as closed-loop scenarios through
:func:`hdservo.sim.run_scenario` (firmware + plant in lock-step, every plant
effect on) and reduced with the procedures' own metric functions
(:mod:`hdservo.procedures.metrics`), so that the numbers mean the same thing:

========================  ===================================================================
figure                    scenario(s)
========================  ===================================================================
min smooth rate           constant-rate ramp per ladder rung; fixed-angle timing of the output
                          encoder (``rate_stability``), smooth = monotone, stability and
                          accuracy <= 0.1 (``min_smooth_rate``)
positioning (ISO 230-2)   ``method="procedure"`` (the flow's): the test procedure on the
                          served simulator in lock-step (repeats bit for bit); ``scenario``:
                          per target and direction one move of ``overrun`` onto the target
                          (the drive's PTP trajectory, with its one-direction final approach
                          when "approach" is on); the plant is shifted to the target angle
                          (gravity offset, TE and cogging phases), so a short move reproduces
                          the approach; runs = noise seeds; deviation = mean true output angle
                          after the dwell
stabilisation             base rocking; (a) the drive holds its position, (b) the position
                          reference is the negative base angle (ideal inertial reference),
                          (c) the drive's gyro stabilisation mode (STAB, CiA 402 mode -1) with the
                          controller's compensators: the design figure is (c), true inertial
                          angle; also the RMS of the integrated payload gyro, line removed
                          (``inertial_angle_from_gyro``: the procedure's headline);
                          :func:`stabilisation_procedure`: the procedure itself in lock-step
                          on the served simulator (the verification's prediction)
peak torque               torque mode, output locked (load inertia 2e4 kg m^2), request 1.5 x
                          the drive's torque limit (the procedure's saturated last step);
                          delivered = mean |transmitted gear torque| over 0.5-0.9 of the 0.2 s
                          hold (the plant replayed open loop with the drive's torque command:
                          the virtual rig's load cell, hysteresis torque included)
bandwidth                 the procedure itself (``closedloop.bandwidth``: Schroeder multisine
                          ``metrics.schroeder_multisine``, 17 log-spaced lines 1-80 Hz, 60 arcsec
                          peak, 1 kHz set-points, output encoder over the drive's reference) on
                          the simulator served as a virtual drive with the controller's
                          parameters; -3 dB (``bandwidth_3db``)
========================  ===================================================================

Angles in the figures are in arcsec unless the key says otherwise.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence

import numpy as np

from .. import sim
from ..closedloop_cases import _toml_table
from ..procedures import metrics as mt

from ..units import ARCSEC, DEG  # noqa: E402
LOOP_S = 1e-4


def run(axis: str, controller: Mapping[str, Any], setpoint: Mapping[str, Any], duration_s: float, *,
        decimation: int = 10, seed: int = 1, plant: Optional[Mapping[str, Any]] = None,
        name: str = "design") -> sim.SimResult:
    """Run one closed-loop scenario on an axis file.

    Parameters
    ----------
    axis : str
        Axis TOML path.
    controller : mapping
        Scenario ``[controller]`` table (``mode``, ``gains``, ``compensators``, ...).
    setpoint : mapping
        Scenario ``[setpoint]`` table (unit of the mode: rad, rad/s or N·m).
    duration_s : float
        Run length, s.
    decimation : int
        One log row every N loop periods (100 µs).
    seed : int
        Sensor-noise seed.
    plant : mapping, optional
        ``{"section.key": value}`` overrides (SI).

    Returns
    -------
    hdservo.sim.SimResult
    """
    lines = _toml_table("scenario", {"name": name, "axis": str(Path(axis).resolve()),
                                     "duration_s": float(duration_s), "seed": int(seed),
                                     "log_decimation": int(decimation)})
    lines += [""] + _toml_table("controller", dict(controller))
    lines += [""] + _toml_table("setpoint", dict(setpoint))
    with tempfile.TemporaryDirectory(prefix="hdservo-design-") as d:
        path = Path(d) / "scenario.toml"
        path.write_text("\n".join(lines) + "\n")
        return sim.run_scenario(path, params=dict(plant or {}))


def _mode(ctl: Mapping[str, Any], mode: str) -> Dict[str, Any]:
    c = dict(ctl)
    c["mode"] = mode
    return c


# ------------------------------------------------------------------ minimum smooth rate

def min_smooth_rate(axis: str, ctl: Mapping[str, Any], rates_deg_s: Sequence[float], *, bound: float = 0.1,
                    windows: int = 10, window_s: float = 1.0, settle_s: float = 5.0,
                    progress: Optional[Callable[[str], None]] = None) -> Dict[str, Any]:
    """Minimum smooth rate over a ladder of constant rates (fixed-angle timing).

    Parameters
    ----------
    axis : str
        Axis TOML path.
    ctl : mapping
        Controller table (position mode).
    rates_deg_s : sequence of float
        Ladder, deg/s.
    bound : float
        Stability/accuracy bound of a smooth rung (0.1 = 10 %).
    windows : int
        Fixed-angle windows timed per rung.
    window_s : float
        Nominal duration of one window, s (window angle = rate x window_s).
    settle_s : float
        Time at rate before timing starts, s (1 s for rates >= 0.5 deg/s).

    Returns
    -------
    dict
        ``min_smooth_rate_deg_s`` (None if the fastest rung fails), ``ladder``
        (per rung: ``rate_deg_s``, ``stability``, ``accuracy``, ``monotone``, ...),
        ``series`` (per rung window rates / commanded, for plots).
    """
    ladder: List[Dict[str, Any]] = []
    series: Dict[str, List[float]] = {}
    for rate in sorted(rates_deg_s, reverse=True):
        if progress:
            progress(f"min smooth rate: {rate:g} deg/s")
        st = settle_s if rate < 0.5 else min(settle_s, 1.0)
        t0 = 0.1
        r = run(axis, _mode(ctl, "position"), {"type": "ramp", "initial_rad": 0.0, "rate_rad_s": rate * DEG,
                                               "t0_s": t0}, t0 + st + windows * window_s, decimation=10)
        t = np.asarray(r["t_s"])
        m = t >= t0 + st
        ang = np.asarray(r["load_angle_rad"])[m]
        s = mt.rate_stability(t[m], ang, rate * DEG, rate * DEG * window_s)
        w = mt.fixed_angle_rates(t[m], ang, rate * DEG * window_s)
        series[f"{rate:g}"] = (w / (rate * DEG)).tolist()
        ladder.append({"rate_deg_s": rate, **{k: (float(v) if not isinstance(v, bool) else v) for k, v in s.items()},
                       "fault_code": int(np.max(r["fault_code"]))})
    best = mt.min_smooth_rate(ladder, bound)
    return {"min_smooth_rate_deg_s": best, "bound": bound, "ladder": ladder, "series": series}


# ------------------------------------------------------------------ positioning

def shifted_plant(axis: str, angle_rad: float) -> Dict[str, float]:
    """Plant overrides that make an axis starting at 0 behave as if it started at ``angle_rad``.

    Shifts the gravity offset, the output-side TE phases (order x angle) and the
    wave-generator TE and cogging phases (order x N x angle).
    """
    n = sim.axis_param("gear.ratio", axis)
    out: Dict[str, float] = {"gravity.offset_rad": sim.axis_param("gravity.offset_rad", axis) + angle_rad}
    for i in range(1, 5):
        for key, scale in ((f"transmission_error.out{i}", 1.0), (f"transmission_error.wg{i}", n),
                           (f"cogging.h{i}", n)):
            o = sim.axis_param(f"{key}_order", axis)
            if o:
                ph = sim.axis_param(f"{key}_phase_rad", axis) + o * scale * angle_rad
                out[f"{key}_phase_rad"] = math.remainder(ph, 2 * math.pi)
    return out


#: tries of a procedure run on the served simulator (a fresh virtual drive each) before a
#: communication error is passed on (load average 15 on the 2 shared cores lost SDO answers)
PROCEDURE_ATTEMPTS = 3
#: ``trajectory`` values of :func:`positioning`
TRAJECTORIES = ("drive", "move")


def _gain(ctl: Mapping[str, Any], name: str) -> float:
    """A drive parameter of a controller table (table unit), else the parameter table's default."""
    from ..params_gen import BY_NAME as PARAMS
    g = ctl.get("gains", {})
    if isinstance(g, Mapping) and name in g:
        return float(g[name])
    return float(PARAMS[name].default)


def final_approach(ctl: Mapping[str, Any]) -> Optional[Dict[str, float]]:
    """The drive's one-direction final approach of a controller table, or None when it is off.

    On when ``"approach"`` is among ``ctl["compensators"]`` (cb_enable bit 128): ``dir``
    (+1/-1), ``dist_arcsec``, ``vmax_deg_s``, ``dwell_s`` (parameters ``appr_*``, table
    defaults unless the table sets them).
    """
    if "approach" not in list(ctl.get("compensators", [])):
        return None
    return {"dir": _gain(ctl, "appr_dir"), "dist_arcsec": _gain(ctl, "appr_dist") * 1296000.0,
            "vmax_deg_s": _gain(ctl, "appr_vmax") * 360.0, "dwell_s": _gain(ctl, "appr_dwell")}


def positioning(axis: str, ctl: Mapping[str, Any], targets_deg: Sequence[float], *, runs: int = 3,
                overrun_deg: float = 1.0, dwell_s: float = 1.5, measure_s: float = 0.2,
                vmax_deg_s: float = 60.0, amax_deg_s2: float = 100.0, trajectory: str = "drive",
                method: str = "scenario", seed: int = 1, lockstep: bool = True,
                progress: Optional[Callable[[str], None]] = None) -> Dict[str, Any]:
    """ISO 230-2 positioning accuracy A and repeatability R (arcsec).

    Parameters
    ----------
    axis : str
        Axis TOML path.
    ctl : mapping
        Controller table.
    targets_deg : sequence of float
        Target angles, deg.
    runs : int
        Runs per target and direction (noise seeds 1..runs), >= 2.
    overrun_deg : float
        Approach distance, deg (the move starts this far before the target).
    dwell_s, measure_s : float
        Wait after the move and averaging time, s.
    vmax_deg_s, amax_deg_s2 : float
        Move profile limits (``move``; ``drive`` uses the table's ``traj_*``, which the
        flow sets to the same values).
    trajectory : {"drive", "move"}
        ``drive`` (default): every move is the drive's own point-to-point trajectory
        (scenario set-point ``ptp``, jerk-limited, ``traj_vmax``/``traj_amax``/``traj_jmax``),
        as the procedure's profile-position moves, so the drive's one-direction final
        approach (:func:`final_approach`, "approach" among the compensators) ends every
        move that arrives against ``appr_dir`` with a leg of ``appr_dist`` at ``appr_vmax``;
        the dwell starts after that leg.  ``move``: the simulator's trapezoidal set-point
        (no final approach).
    method : {"scenario", "procedure"}
        ``scenario`` (default): one in-process run per target, direction and run (noise
        seeds 1..runs), each from a fresh plant at rest ``overrun`` before the target.
        ``procedure``: the positioning test procedure itself
        (:func:`hdservo.procedures.closedloop.positioning`: one continuous sweep up and down
        per run, the drive's profile moves, true output angle) on the simulator served as a
        virtual drive (sensor seed ``seed``) configured with ``ctl``
        (:func:`configure_drive`): the plant keeps its history from move to move, which
        decides sub-arcsecond residuals (with the final approach the scenario runs give
        about twice the procedure's A and R).  ``trajectory`` is then always the drive's.
    lockstep : bool
        ``procedure`` only: run the virtual drive in lock-step (``--pacing sync``: its time
        advances only on the host's SYNCs), so that the run repeats bit for bit for a
        given ``seed`` (default).  False: fast pacing, where the drive's time runs on during
        the host's SDO round trips and the dwell before each measurement depends on the
        host's timing (the same seed gave A 0.41" and 0.50", 1.93" and 0.31").

    Returns
    -------
    dict
        ``A_arcsec``, ``R_arcsec``, ``B_arcsec``, ``E_arcsec``, ``iso230_2`` (full
        figures), ``up_arcsec``/``down_arcsec`` (deviations, runs x targets),
        ``targets_deg``, ``trajectory``, ``final_approach`` (None when off).
    """
    if trajectory not in TRAJECTORIES:
        raise ValueError(f"positioning trajectory '{trajectory}': expected one of {', '.join(TRAJECTORIES)}")
    if method == "procedure":
        return _positioning_procedure(axis, ctl, targets_deg, runs=runs, overrun_deg=overrun_deg, dwell_s=dwell_s,
                                      measure_s=measure_s, seed=seed, lockstep=lockstep, progress=progress)
    if method != "scenario":
        raise ValueError(f"positioning method '{method}': expected 'scenario' or 'procedure'")
    tg = np.asarray(targets_deg, float)
    ov = overrun_deg * DEG
    up = np.zeros((runs, tg.size))
    dn = np.zeros((runs, tg.size))
    appr = final_approach(ctl) if trajectory == "drive" else None
    if trajectory == "drive":
        vmax, amax = _gain(ctl, "traj_vmax") * 2 * math.pi, _gain(ctl, "traj_amax") * 2 * math.pi
        jmax = _gain(ctl, "traj_jmax") * 2 * math.pi
    else:
        vmax, amax, jmax = vmax_deg_s * DEG, amax_deg_s2 * DEG, math.inf
    t_move = ov / vmax + vmax / amax if ov > vmax ** 2 / amax else 2.0 * math.sqrt(ov / amax)
    t_move += amax / jmax                      # jerk phases (drive trajectory)
    if appr is not None:                       # worst case: the extra stop and the final leg
        t_move += t_move + appr["dwell_s"] + appr["dist_arcsec"] / 3600.0 / appr["vmax_deg_s"] + 0.3
    t0 = 0.1
    dur = t0 + t_move + dwell_s + measure_s
    for i, p in enumerate(tg):
        if progress:
            progress(f"positioning: target {p:+.1f} deg")
        for sgn, arr in ((1.0, up), (-1.0, dn)):
            plant = shifted_plant(axis, p * DEG - sgn * ov)
            for j in range(runs):
                sp = ({"type": "ptp", "initial_rad": 0.0, "target_rad": sgn * ov, "t0_s": t0}
                      if trajectory == "drive" else
                      {"type": "move", "initial_rad": 0.0, "target_rad": sgn * ov, "max_velocity_rad_s": vmax,
                       "max_accel_rad_s2": amax, "t0_s": t0})
                r = run(axis, _mode(ctl, "position"), sp, dur, decimation=10, seed=j + 1, plant=plant)
                t = np.asarray(r["t_s"])
                y = np.asarray(r["load_angle_true_rad"])[t >= t[-1] - measure_s]
                arr[j, i] = (float(np.mean(y)) - sgn * ov) / ARCSEC
    iso = mt.iso230_2(np.zeros(tg.size), up, dn)
    return {"A_arcsec": iso["A"], "R_arcsec": iso["R"], "B_arcsec": iso["B"], "E_arcsec": iso["E"],
            "iso230_2": iso, "up_arcsec": up.tolist(), "down_arcsec": dn.tolist(), "targets_deg": tg.tolist(),
            "runs": runs, "trajectory": trajectory, "final_approach": appr, "method": "scenario"}


def _positioning_procedure(axis: str, ctl: Mapping[str, Any], targets_deg: Sequence[float], *, runs: int,
                           overrun_deg: float, dwell_s: float, measure_s: float, seed: int, lockstep: bool = True,
                           progress: Optional[Callable[[str], None]] = None) -> Dict[str, Any]:
    """:func:`positioning` with ``method="procedure"`` (the test procedure on the served simulator)."""
    from ..drive import DriveError
    from ..procedures import closedloop as cl
    from ..procedures.runner import Target, open_bench
    ax = axis if axis in ("reference", "minimal") else str(Path(axis).resolve())
    if progress:
        progress(f"positioning: procedure on the served simulator, {len(targets_deg)} targets x {runs} runs")
    for attempt in range(PROCEDURE_ATTEMPTS):   # again after lost SDO answers on a heavily loaded host
        try:
            with open_bench(Target(axis=ax, seed=seed), cl.AXIS_SETUP, lockstep=lockstep) as bench:
                cfg = configure_drive(bench.drive, ctl)
                res = cl.positioning(bench, targets_deg=list(targets_deg), runs=runs, overrun_deg=overrun_deg,
                                     dwell_s=dwell_s, measure_s=measure_s)
            break
        except DriveError:
            if attempt == PROCEDURE_ATTEMPTS - 1:
                raise
    iso = res.figures["iso230_2_arcsec"]
    return {"A_arcsec": iso["A"], "R_arcsec": iso["R"], "B_arcsec": iso["B"], "E_arcsec": iso["E"],
            "iso230_2": iso, "up_arcsec": np.asarray(res.series["up"]).tolist(),
            "down_arcsec": np.asarray(res.series["down"]).tolist(), "targets_deg": [float(x) for x in targets_deg],
            "runs": runs, "trajectory": "drive", "final_approach": final_approach(ctl), "method": "procedure",
            "seed": seed, "lockstep": bool(lockstep), "cb_enable": cfg["cb_enable"]}


# ------------------------------------------------------------------ stabilisation

def gyro_noise_arcsec_rms(noise_rad_s_per_rtHz: float, window_s: float, f_hi_Hz: float) -> float:
    """RMS angle error of a rate-gyro-referenced loop due to the gyro white noise.

    The loop follows the integrated gyro noise between ``1/window_s`` (slower
    drift is removed with the straight line) and the loop bandwidth ``f_hi_Hz``:
    sigma = n / (2 pi) sqrt(1/f_lo - 1/f_hi), n the noise density in rad/s/sqrt(Hz).

    Returns
    -------
    float
        arcsec RMS.
    """
    f_lo = 1.0 / window_s
    if f_hi_Hz <= f_lo:
        return 0.0
    return noise_rad_s_per_rtHz / (2 * math.pi) * math.sqrt(1.0 / f_lo - 1.0 / f_hi_Hz) / ARCSEC


def stabilisation(axis: str, ctl: Mapping[str, Any], base_amp_deg: float, base_freq_Hz: float, *,
                  duration_s: float = 5.0, settle_s: float = 1.0, loop_bw_Hz: float = 10.0,
                  progress: Optional[Callable[[str], None]] = None, design_mode: str = "stab") -> Dict[str, Any]:
    """Stabilisation precision with the base rocking (arcsec RMS of the inertial angle).

    Parameters
    ----------
    axis : str
        Axis TOML path (its ``base.*`` keys are overridden).
    ctl : mapping
        Controller table.
    base_amp_deg, base_freq_Hz : float
        Base rocking.
    duration_s, settle_s : float
        Analysed window and the time before it, s.
    loop_bw_Hz : float
        Closed-loop bandwidth used for the gyro-noise term, Hz.
    design_mode : {"stab", "auto", "hold"}
        Drive mode of the stabilisation test the design figure stands for (the procedure's
        ``--stab-mode``): ``stab``/``auto`` (the simulated drive has STAB) -> the ``stab`` run,
        ``hold`` -> the ``hold`` run.

    Returns
    -------
    dict
        Per scenario ``hold`` (drive holds its encoder position), ``inertial``
        (position reference = - base angle, an ideal inertial reference) and
        ``stab`` (the drive's gyro stabilisation mode, ``mode = "stabilise"``,
        inertial rate 0, the controller's compensators): ``*_rms_arcsec`` and
        ``*_peak_arcsec`` of the integrated payload gyro (the procedure's
        headline definition), ``*_true_rms_arcsec`` of the true inertial angle
        (the virtual rig's reference); ``gyro_noise_rms_arcsec`` (analytic term
        of a gyro-referenced loop), ``ideal_reference_rms_arcsec`` (RSS of the
        inertial run and that term: the figure before STAB existed),
        ``predicted_rms_arcsec`` (= ``stab_true_rms_arcsec``: the design figure),
        ``base_rms_arcsec``, traces for plots.
    """
    plant = {"base.enabled": True, "base.amplitude_rad": base_amp_deg * DEG, "base.frequency_Hz": base_freq_Hz,
             "base.phase_rad": 0.0}
    out: Dict[str, Any] = {}
    for tag, mode, sp in (("hold", "position", {"type": "constant", "initial_rad": 0.0}),
                          ("inertial", "position", {"type": "sine", "initial_rad": 0.0,
                                                    "amplitude_rad": -base_amp_deg * DEG,
                                                    "frequency_Hz": base_freq_Hz, "phase_rad": 0.0, "t0_s": 0.0}),
                          ("stab", "stabilise", {"type": "constant", "initial_rad_s": 0.0})):
        if progress:
            progress(f"stabilisation: {tag}")
        r = run(axis, _mode(ctl, mode), sp, settle_s + duration_s, decimation=10, plant=plant)
        t = np.asarray(r["t_s"])
        m = t >= settle_s
        ang = mt.inertial_angle_from_gyro(t[m], np.asarray(r["gyro_rate_rad_s"])[m])
        pe = mt.pointing_error(ang)
        out[f"{tag}_rms_arcsec"] = pe["rms_arcsec"]
        out[f"{tag}_peak_arcsec"] = pe["peak_arcsec"]
        out[f"{tag}_trace"] = {"t_s": (t[m] - t[m][0]).tolist()[::5], "angle_arcsec": (ang / ARCSEC).tolist()[::5]}
        out[f"{tag}_fault_code"] = int(np.max(r["fault_code"]))
        # true inertial angle (the virtual rig's reference instrument), line removed like the gyro angle
        tm = t[m]
        ti = np.asarray(r["load_angle_true_rad"])[m] + np.asarray(r["base_angle_true_rad"])[m]
        ti = ti - np.polyval(np.polyfit(tm, ti, 1), tm)
        out[f"{tag}_true_rms_arcsec"] = mt.pointing_error(ti)["rms_arcsec"]
    n = sim.axis_param("gyro.noise_rad_s_per_rtHz", axis)
    out["gyro_noise_rms_arcsec"] = gyro_noise_arcsec_rms(n, duration_s, loop_bw_Hz)
    # the design figure: the drive's gyro stabilisation mode (STAB, CiA 402 mode -1), true inertial
    # error; the simulated gyro has its noise, so the loop's following of it is included
    if design_mode not in ("stab", "auto", "hold"):
        raise ValueError(f"stabilisation design_mode '{design_mode}': expected stab, auto or hold")
    out["design_mode"] = "hold" if design_mode == "hold" else "stab"
    out["predicted_rms_arcsec"] = out[f"{out['design_mode']}_true_rms_arcsec"]
    out["ideal_reference_rms_arcsec"] = math.hypot(out["inertial_rms_arcsec"], out["gyro_noise_rms_arcsec"])
    out["base_rms_arcsec"] = base_amp_deg * DEG / math.sqrt(2) / ARCSEC
    return out


def stabilisation_procedure(axis: str, ctl: Mapping[str, Any], base_amp_deg: float, base_freq_Hz: float, *,
                            duration_s: float = 5.0, settle_s: float = 1.0, seed: int = 1,
                            mode: str = "stab") -> Dict[str, Any]:
    """Stabilisation precision by the test procedure itself on the served simulator, in lock-step.

    :func:`hdservo.procedures.closedloop.stabilisation` (``mode``: ``stab`` = the drive's
    gyro stabilisation mode, ``hold`` = CSP hold) on the simulator served as a virtual
    drive (``hdservo-sim serve --pacing sync``, sensor seed ``seed``, swing table
    ``stab_setup``) configured with ``ctl`` (:func:`configure_drive`).  The run repeats
    bit for bit, and a measurement on a drive started with the same seed and protocol
    sees the same gyro-noise samples at the same ticks.  That matters: the true inertial
    figure is dominated by the integrated gyro noise the loop follows, whose 5 s RMS
    scatters 5.3-7.9" over seeds on the pitch-drive axis; the in-process run
    (:func:`stabilisation`) draws the same seed's noise at other ticks.

    Returns
    -------
    dict
        ``{tag}_rms_arcsec``, ``{tag}_peak_arcsec`` (integrated payload gyro, line removed),
        ``{tag}_true_rms_arcsec`` (rig true inertial angle, line removed) with ``tag`` =
        ``stab`` or ``hold``; ``design_mode``, ``predicted_rms_arcsec`` (the true inertial
        RMS), ``method`` = ``procedure``, ``seed``, ``duration_s``.
    """
    from ..procedures import closedloop as cl
    from ..procedures.runner import Target, open_bench
    if mode not in ("stab", "hold"):
        raise ValueError(f"stabilisation_procedure mode '{mode}': expected stab or hold")
    ax = axis if axis in ("reference", "minimal") else str(Path(axis).resolve())
    with open_bench(Target(axis=ax, seed=seed), cl.stab_setup(base_amp_deg, base_freq_Hz), lockstep=True) as bench:
        configure_drive(bench.drive, ctl)
        res = cl.stabilisation(bench, duration_s=duration_s, settle_s=settle_s, mode=mode)
    f = res.figures
    return {f"{mode}_rms_arcsec": f["gyro_rms_arcsec"], f"{mode}_peak_arcsec": f["gyro_peak_arcsec"],
            f"{mode}_true_rms_arcsec": f["true_rms_arcsec"], "design_mode": mode,
            "predicted_rms_arcsec": f["true_rms_arcsec"], "method": "procedure", "seed": seed,
            "duration_s": duration_s, "base_rms_arcsec": f["base_rms_arcsec"]}


# ------------------------------------------------------------------ peak torque

def three_slope_torque(phi: np.ndarray, k1: float, k2: float, k3: float, t1: float, t2: float) -> np.ndarray:
    """Three-slope spring torque (docs/plant.md) at twist ``phi`` (rad), N·m."""
    p1 = t1 / k1
    p2 = p1 + (t2 - t1) / k2
    sat = lambda x, a: np.clip(x, -a, a)  # noqa: E731
    return k3 * phi + (k1 - k2) * sat(phi, p1) + (k2 - k3) * sat(phi, p2)


def peak_torque(axis: str, ctl: Mapping[str, Any], torque_limit_Nm: float, *,
                hold_s: float = 0.2, overdrive: Optional[float] = None) -> Dict[str, Any]:
    """Peak output torque against a locked output (the procedure's definition).

    Definition (shared with :func:`hdservo.procedures.closedloop.peak_torque`):
    the output torque delivered with the drive's ``torque_limit`` in force,
    requesting ``overdrive`` (1.5) x the limit; mean |output torque| over
    ``PEAK_WINDOW`` (0.5 .. 0.9) of the ``hold_s`` step.  The output torque is
    the plant's transmitted gear torque (spring + hysteresis elements: what
    the virtual rig's load cell records): the closed-loop run's torque
    command is replayed through the plant alone (:func:`hdservo.sim.simulate_open_loop`;
    in torque mode the command does not depend on the sensors, so the replay
    is the same trajectory).  The procedure steps up to the limit first; the
    output is locked, so only the saturated step is simulated.

    Parameters
    ----------
    axis : str
        Axis TOML path.
    ctl : mapping
        Controller table (torque mode is used; its ``torque_limit`` applies).
    torque_limit_Nm : float
        The drive's torque limit.
    hold_s : float
        Hold time of the step, s.
    overdrive : float, optional
        Request / torque limit (default :data:`closedloop.PEAK_OVERDRIVE` = 1.5).

    Returns
    -------
    dict
        ``peak_torque_Nm`` (transmitted gear torque), ``spring_torque_Nm`` (three-slope
        spring torque of the twist alone: the figure before the definitions were aligned),
        ``drive_torque_Nm`` (N Kt i), ``requested_Nm``, ``window``, ``fault_code``.
    """
    from ..procedures import closedloop as cl
    req = (cl.PEAK_OVERDRIVE if overdrive is None else float(overdrive)) * torque_limit_Nm
    plant = {"load.jl_kgm2": 2e4, "base.enabled": False, "gravity.enabled": False}
    t0 = 0.01
    r = run(axis, _mode(ctl, "torque"), {"type": "step", "initial_Nm": 0.0, "amplitude_Nm": req, "t0_s": t0},
            t0 + hold_s, decimation=1, plant=plant)
    t = np.asarray(r["t_s"])
    w0, w1 = cl.PEAK_WINDOW
    m = (t >= t0 + w0 * hold_s) & (t < t0 + w1 * hold_s)
    g = {k: sim.axis_param(f"stiffness.{k}", axis) for k in ("k1_Nm_per_rad", "k2_Nm_per_rad", "k3_Nm_per_rad",
                                                             "t1_Nm", "t2_Nm")}
    phi = np.asarray(r["torsion_rad"])[m]
    spring = three_slope_torque(phi, g["k1_Nm_per_rad"], g["k2_Nm_per_rad"], g["k3_Nm_per_rad"], g["t1_Nm"],
                                g["t2_Nm"])
    ax = axis if axis in ("reference", "minimal") else str(Path(axis).resolve())
    ol = sim.simulate_open_loop(np.asarray(r["torque_cmd_Nm"]), params=plant, axis=ax, dt_s=float(t[1] - t[0]))
    tr = np.abs(np.asarray(ol["transmitted_torque_Nm"]))[m]
    n = sim.axis_param("gear.ratio", axis)
    return {"peak_torque_Nm": float(np.mean(tr)), "spring_torque_Nm": float(np.mean(np.abs(spring))),
            "drive_torque_Nm": float(n * np.mean(np.abs(np.asarray(r["motor_torque_Nm"])[m]))),
            "requested_Nm": req, "window": [w0 * hold_s, w1 * hold_s], "fault_code": int(np.max(r["fault_code"]))}


# ------------------------------------------------------------------ bandwidth

def configure_drive(drive: Any, ctl: Mapping[str, Any]) -> Dict[str, Any]:
    """Write a controller table into a drive (power stage off): its gains by name, then ``cb_enable``.

    Gains that are not drive parameters are skipped (listed in ``skipped``).
    Returns ``{"params": count, "skipped": [...], "cb_enable": mask}``.
    """
    from ..compsetup import enable_mask
    from ..params_gen import BY_NAME as PARAMS
    done, skipped = 0, []
    for k, v in dict(ctl.get("gains", {})).items():
        if k in PARAMS:
            drive.set_param(k, float(v))
            done += 1
        else:
            skipped.append(k)
    mask = enable_mask(list(ctl.get("compensators", [])))
    drive.set_param("cb_enable", float(mask))
    return {"params": done, "skipped": skipped, "cb_enable": mask}


def bandwidth(axis: str, ctl: Mapping[str, Any], *, amplitude_arcsec: float = 60.0, f0_Hz: float = 1.0,
              f1_Hz: float = 60.0, periods: int = 2, excitation: str = "procedure", seed: int = 1,
              lines: Optional[Sequence[int]] = None) -> Dict[str, Any]:
    """Closed-loop position bandwidth (-3 dB of theta_L / theta_ref).

    Parameters
    ----------
    axis : str
        Axis TOML path.
    ctl : mapping
        Controller table (``gains`` by drive-parameter name, ``compensators``).
    amplitude_arcsec : float
        Multisine peak (``procedure``) or per-scenario amplitude (``scenario``), arcsec.
    f0_Hz, f1_Hz : float
        ``scenario`` only: band of the simulator's evenly spaced multisine (1 Hz lines).
    periods : int
        Excitation periods (the last one is analysed).
    excitation : {"procedure", "scenario"}
        ``procedure`` (default): the bandwidth test procedure itself
        (:func:`hdservo.procedures.closedloop.bandwidth`: Schroeder multisine of
        ``closedloop.bandwidth_lines`` = 17 log-spaced lines 1-80 Hz, peak
        ``amplitude_arcsec``, 1 kHz set-points streamed in lock-step, output encoder
        over the drive's own reference) on the simulator served as a virtual drive
        (``hdservo-sim serve``, same firmware and plant) configured with ``ctl``
        (:func:`configure_drive`): the same definition as the measurement.  The
        in-process scenario runner has no arbitrary-waveform set-point, hence the
        served simulator.  ``scenario``: the older in-process run (the simulator's
        multisine, 1 Hz lines ``f0_Hz``..``f1_Hz``, true output angle).
    seed : int
        Sensor-noise seed (``procedure``).
    lines : sequence of int, optional
        ``procedure`` only: DFT lines (default ``closedloop.bandwidth_lines()``).

    Returns
    -------
    dict
        ``bandwidth_Hz`` (-3 dB; None if not reached), ``f_Hz``, ``magnitude_dB``,
        ``phase_deg``, ``fault_code``, ``excitation`` (description).
    """
    if excitation == "scenario":
        return _bandwidth_scenario(axis, ctl, amplitude_arcsec=amplitude_arcsec, f0_Hz=f0_Hz, f1_Hz=f1_Hz,
                                   periods=periods)
    if excitation != "procedure":
        raise ValueError(f"bandwidth excitation '{excitation}': expected 'procedure' or 'scenario'")
    from ..procedures import closedloop as cl
    from ..procedures.runner import Target, open_bench
    ax = axis if axis in ("reference", "minimal") else str(Path(axis).resolve())
    with open_bench(Target(axis=ax, seed=seed), cl.AXIS_SETUP, lockstep=True) as bench:
        cfg = configure_drive(bench.drive, ctl)
        res = cl.bandwidth(bench, amplitude_arcsec=amplitude_arcsec, lines=lines, periods=max(1, int(periods)))
    fig = res.figures
    return {"bandwidth_Hz": res.headline["bandwidth_hz"], "f_Hz": list(fig["f_Hz"]),
            "magnitude_dB": list(fig["magnitude_dB"]), "phase_deg": list(fig["phase_deg"]), "fault_code": 0,
            "excitation": {"kind": "procedure", "signal": "metrics.schroeder_multisine",
                           "lines": len(fig["f_Hz"]), "amplitude_arcsec": amplitude_arcsec,
                           "setpoint_rate_Hz": res.conditions["setpoint_rate_Hz"], "periods": periods,
                           "configured_params": cfg["params"], "cb_enable": cfg["cb_enable"]}}


def _bandwidth_scenario(axis: str, ctl: Mapping[str, Any], *, amplitude_arcsec: float = 60.0, f0_Hz: float = 1.0,
                        f1_Hz: float = 60.0, periods: int = 2) -> Dict[str, Any]:
    """The in-process multisine bandwidth (1 Hz lines, true output angle): ``excitation="scenario"``."""
    n = int(round(f1_Hz - f0_Hz)) + 1
    t0 = 0.1
    period = 1.0 / ((f1_Hz - f0_Hz) / (n - 1))
    dur = t0 + period * (periods + 1)
    r = run(axis, _mode(ctl, "position"), {"type": "multisine", "initial_rad": 0.0,
                                           "amplitude_rad": amplitude_arcsec * ARCSEC, "f0_Hz": f0_Hz,
                                           "f1_Hz": f1_Hz, "lines": n, "t0_s": t0, "t1_s": dur + 1.0},
            dur, decimation=2, plant={"base.enabled": False})
    t = np.asarray(r["t_s"])
    m = t >= t0 + period - 1e-9
    ref = np.asarray(r["setpoint_rad"])[m]
    y = np.asarray(r["load_angle_true_rad"])[m]
    dt = float(t[1] - t[0])
    k = int(round(period * periods / dt))
    ref, y = ref[:k] - np.mean(ref[:k]), y[:k] - np.mean(y[:k])
    fr, fy = np.fft.rfft(ref), np.fft.rfft(y)
    f = np.fft.rfftfreq(k, dt)
    lines = [int(round((f0_Hz + i * (f1_Hz - f0_Hz) / (n - 1)) * k * dt)) for i in range(n)]
    h = fy[lines] / fr[lines]
    fl = f[lines]
    bw = mt.bandwidth_3db(fl, h)
    return {"bandwidth_Hz": bw, "f_Hz": fl.tolist(), "magnitude_dB": (20 * np.log10(np.abs(h))).tolist(),
            "phase_deg": np.degrees(np.unwrap(np.angle(h))).tolist(), "fault_code": int(np.max(r["fault_code"])),
            "excitation": {"kind": "scenario", "lines": n, "f0_Hz": f0_Hz, "f1_Hz": f1_Hz,
                           "amplitude_arcsec": amplitude_arcsec, "periods": periods}}


__all__ = ["TRAJECTORIES", "bandwidth", "configure_drive", "final_approach", "gyro_noise_arcsec_rms", "min_smooth_rate", "peak_torque", "positioning", "run",
           "shifted_plant", "stabilisation", "stabilisation_procedure", "three_slope_torque"]
