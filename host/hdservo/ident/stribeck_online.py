"""Online Stribeck identification: the host-side RLS replay, and the drive's own estimator.

The first part replays recorded sweep windows through a bank of RLS filters
(a reference for the batch fit).  The second part (:func:`online_identification`)
watches the drive's fixed-point estimator (``firmware/core/hd_fric_est.h``,
object 0x5200) over CAN during a normal motion profile.

RLS on the model made linear by a grid over vs.

For a fixed Stribeck velocity vs (and shape delta = 2) the static map is
linear in theta = (Fc+, Fs+ - Fc+, Fc-, Fs- - Fc-, Fv)::

    f = phi(v)^T theta,  phi = [p, p e, -n, -n e, v],  e = exp(-(v/vs)^2),
    p = [v >= 0], n = 1 - p

One recursive least-squares filter runs per grid value (G filters, 5
parameters each, forgetting factor lambda).  Each keeps its running sum of
squared a-priori errors weighted as in exact recursive LS,
``S += e^2 / (1 + phi^T P phi)`` (exact SSE for lambda = 1); the estimate
is the filter with the smallest S.  Samples arrive in time order from the
sweep (one per ~50 ms steady-state block, :func:`.friction.sweep_points`).

Cost per sample and grid value: one exp, P phi (25 MAC), gain (5 div or
1 div + 5 MAC), theta update (5 MAC), P update (25+25 MAC), S update (6 MAC)
-> ~90 operations; G = 32 -> ~2900 operations per sample.  Memory per grid
value: P (15 unique of 25), theta 5, S 1 -> 21 words; G = 24 -> 504 words
(2 kB at 32 bit).  On a Cortex-M4 at 170 MHz that is ~15-25 us per sample
in float; the drive runs its own fixed-point estimator instead (binned steady
torque and a grid fit: hd_fric_est.h).  Measured convergence of both is in
docs/identification.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from .friction import StribeckResult


@dataclass
class OnlineStribeck:
    """Bank of RLS filters over a grid of Stribeck velocities.

    Parameters
    ----------
    vs_grid : numpy.ndarray
        Stribeck velocities, rad/s.
    lam : float
        Forgetting factor (1 = growing window).
    p0 : float
        Initial covariance (diagonal).
    delta : float
        Shape exponent (fixed).
    """

    vs_grid: np.ndarray
    lam: float = 1.0
    p0: float = 1e6
    delta: float = 2.0

    def __post_init__(self) -> None:
        g = len(self.vs_grid)
        self.P = np.repeat(np.eye(5)[None] * self.p0, g, axis=0)
        self.theta = np.zeros((g, 5))
        self.S = np.zeros(g)
        self.n = 0

    def update(self, v: float, f: float) -> None:
        """One sample: velocity (rad/s) and friction torque (N.m)."""
        p = 1.0 if v >= 0 else 0.0
        e = np.exp(-np.abs(v / self.vs_grid) ** self.delta)
        phi = np.column_stack([np.full_like(e, p), p * e, np.full_like(e, -(1 - p)), -(1 - p) * e,
                               np.full_like(e, v)])                       # (G, 5)
        Pphi = np.einsum("gij,gj->gi", self.P, phi)
        den = self.lam + np.einsum("gi,gi->g", phi, Pphi)
        err = f - np.einsum("gi,gi->g", phi, self.theta)
        K = Pphi / den[:, None]
        self.theta += K * err[:, None]
        self.P = (self.P - np.einsum("gi,gj->gij", K, Pphi)) / self.lam
        self.S = self.lam * self.S + err ** 2 * self.lam / den
        self.n += 1

    def best(self) -> StribeckResult:
        """Current estimate (filter with the smallest error sum)."""
        g = int(np.argmin(self.S))
        th = self.theta[g]
        vs = float(self.vs_grid[g])
        if 0 < g < len(self.S) - 1:
            # parabola through the three error sums in log(vs); parameters interpolated linearly
            a, b, c = self.S[g - 1], self.S[g], self.S[g + 1]
            den = a - 2 * b + c
            if den > 0:
                x = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
                lv = np.log(self.vs_grid)
                vs = float(np.exp(lv[g] + x * (lv[g + 1] - lv[g] if x > 0 else lv[g] - lv[g - 1])))
                nb = g + 1 if x > 0 else g - 1
                th = (1 - abs(x)) * self.theta[g] + abs(x) * self.theta[nb]
        return StribeckResult(fc_pos_Nm=float(th[0]), fc_neg_Nm=float(th[2]), fs_pos_Nm=float(th[0] + th[1]),
                              fs_neg_Nm=float(th[2] + th[3]), vs_rad_s=vs, delta=self.delta,
                              viscous_Nms_per_rad=float(th[4]))

    @staticmethod
    def ops_per_sample(grid: int) -> int:
        """Arithmetic operations per sample (see the module docstring)."""
        return 90 * grid

    @staticmethod
    def memory_words(grid: int) -> int:
        return 21 * grid


PARAMS = ("fc_pos_Nm", "fc_neg_Nm", "fs_pos_Nm", "fs_neg_Nm", "vs_rad_s", "viscous_Nms_per_rad")


def convergence(samples: dict[str, np.ndarray], batch: StribeckResult, tol: float = 0.02,
                vs_grid: np.ndarray | None = None, order: str = "time") -> dict[str, Any]:
    """Run the online identification over the sweep samples and find when it stays within tol of the batch.

    Parameters
    ----------
    samples : dict
        ``v`` (rad/s), ``f`` (N.m), ``t`` (s, cumulative sweep time at each sample).
    batch : StribeckResult
        The nonlinear least-squares result to compare with.
    tol : float
        Relative tolerance (0.02 = 2 %) on every parameter in :data:`PARAMS`.
    vs_grid : numpy.ndarray, optional
        Default: 32 log-spaced values over [|v|min, |v|max/10].
    order : str
        "time" (as recorded, fast points first) or "interleaved".

    Returns
    -------
    dict
        ``samples_to_tol`` and ``sweep_time_s_to_tol`` (None if never), the
        final estimate, its relative errors, cost figures.
    """
    v, f, t = samples["v"], samples["f"], samples["t"]
    if vs_grid is None:
        av = np.abs(v[v != 0])
        vs_grid = np.geomspace(av.min(), av.max() / 10, 32)
    rls = OnlineStribeck(np.asarray(vs_grid))
    ref = {k: getattr(batch, k) for k in PARAMS}
    inside_since: int | None = None
    hist = []
    for i in range(len(v)):
        rls.update(float(v[i]), float(f[i]))
        est = rls.best()
        errs = {k: abs(getattr(est, k) / ref[k] - 1.0) for k in PARAMS}
        ok = max(errs.values()) <= tol
        hist.append(max(errs.values()))
        if ok and inside_since is None:
            inside_since = i
        elif not ok:
            inside_since = None
    est = rls.best()
    return {"samples_to_tol": None if inside_since is None else inside_since + 1,
            "sweep_time_s_to_tol": None if inside_since is None else float(t[inside_since]),
            "sweep_time_s_total": float(t[-1]), "samples_total": int(len(v)), "tolerance": tol,
            "final": est.to_dict(), "final_rel_error": {k: getattr(est, k) / ref[k] - 1.0 for k in PARAMS},
            "grid_points": int(len(vs_grid)), "ops_per_sample": OnlineStribeck.ops_per_sample(len(vs_grid)),
            "memory_words": OnlineStribeck.memory_words(len(vs_grid)),
            "max_rel_error_history": hist}


# ----------------------------------------------------------------- the drive's own estimator

#: CANopen record of the drive's online Stribeck estimate (hd_fric_est.h, docs/od.md)
FE_INDEX = 0x5200
#: turn/s per raw velocity LSB (2^-32 turn/s) and N.m per raw torque LSB (Q15.16)
_V_LSB_TURN_S = 2.0 ** -32
_T_LSB_NM = 2.0 ** -16
#: sub-indices of the common-mode scale (2^-16 per LSB) and bias (Q15.16 N.m) of 0x5200
FE_SUB_SCALE = 15
FE_SUB_BIAS = 16
_SCALE_LSB = 2.0 ** -16
#: the targets of the online identification: levels within 5 %, Stribeck velocity within 15 % of the batch fit
TOL_LEVEL = 0.05
TOL_VS = 0.15
#: compared per direction: the levels, then the Stribeck velocity
LEVELS = ("fc_pos_Nm", "fs_pos_Nm", "fc_neg_Nm", "fs_neg_Nm")


@dataclass
class DriveEstimate:
    """One reading of the drive's online estimate (object 0x5200), output-referred SI units.

    Attributes
    ----------
    t_s : float
        Drive time of the reading, s (loop ticks since power-up).
    fc_pos_Nm, fs_pos_Nm, fc_neg_Nm, fs_neg_Nm : float
        Coulomb and static levels per direction (magnitudes), N.m.
    vs_pos_rad_s, vs_neg_rad_s : float
        Stribeck velocity per direction, rad/s.
    fv_pos_Nms_per_rad, fv_neg_Nms_per_rad : float
        Viscous coefficient per direction, N.m.s/rad.
    conf_pos, conf_neg : float
        Confidence per direction, 0..1.
    fits_pos, fits_neg, samples : int
        Accepted fits per direction and steady samples binned (counters of the drive).
    scale : float
        Common-mode friction scale of both directions (1.0: the bins' own level), dimensionless.
    bias_Nm : float
        Direction-independent torque taken off every sample (an unbalance that appeared
        after the bins were established), signed, N.m.
    """

    t_s: float
    fc_pos_Nm: float
    fs_pos_Nm: float
    vs_pos_rad_s: float
    fv_pos_Nms_per_rad: float
    fc_neg_Nm: float
    fs_neg_Nm: float
    vs_neg_rad_s: float
    fv_neg_Nms_per_rad: float
    conf_pos: float
    conf_neg: float
    fits_pos: int
    fits_neg: int
    samples: int
    scale: float = 1.0
    bias_Nm: float = 0.0

    @classmethod
    def from_raw(cls, t_s: float, raw: list[int]) -> "DriveEstimate":
        """From the raw words of 0x5200 (see docs/od.md).

        ``raw`` holds :1..:13 and, when it has 15 words, then :15 (scale, 2^-16) and :16
        (bias, Q15.16 N.m); with 13 words the scale is 1 and the bias 0.
        """
        two_pi = 2.0 * math.pi
        d = []
        for k in (0, 4):
            d += [raw[k] * _T_LSB_NM, raw[k + 1] * _T_LSB_NM, raw[k + 2] * _V_LSB_TURN_S * two_pi,
                  raw[k + 3] * _T_LSB_NM / two_pi]
        common = (raw[13] * _SCALE_LSB, raw[14] * _T_LSB_NM) if len(raw) >= 15 else (1.0, 0.0)
        return cls(t_s, *d, raw[8] / 1000.0, raw[9] / 1000.0, int(raw[10]), int(raw[11]), int(raw[12]),
                   *common)

    def rel_errors(self, ref: StribeckResult, scale: float = 1.0) -> dict[str, float]:
        """Relative errors against a batch fit whose levels and viscous term are scaled by ``scale``."""
        r = ref.to_dict()
        out: dict[str, float] = {k: getattr(self, k) / (scale * r[k]) - 1.0 for k in LEVELS}
        out["vs_pos_rad_s"] = self.vs_pos_rad_s / r["vs_rad_s"] - 1.0
        out["vs_neg_rad_s"] = self.vs_neg_rad_s / r["vs_rad_s"] - 1.0
        out["fv_pos_Nms_per_rad"] = self.fv_pos_Nms_per_rad / (scale * r["viscous_Nms_per_rad"]) - 1.0
        out["fv_neg_Nms_per_rad"] = self.fv_neg_Nms_per_rad / (scale * r["viscous_Nms_per_rad"]) - 1.0
        return out

    def within(self, ref: StribeckResult, scale: float = 1.0, tol_level: float = TOL_LEVEL,
               tol_vs: float = TOL_VS) -> bool:
        """True when the drive has fitted both directions (its initial values do not count) and every
        level is within ``tol_level`` and both vs within ``tol_vs`` of the reference."""
        if self.fits_pos == 0 or self.fits_neg == 0:
            return False
        e = self.rel_errors(ref, scale)
        return (all(abs(e[k]) <= tol_level for k in LEVELS) and abs(e["vs_pos_rad_s"]) <= tol_vs
                and abs(e["vs_neg_rad_s"]) <= tol_vs)

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def read_drive_estimate(read: Any, t_s: float) -> DriveEstimate:
    """Read 0x5200:1..13, :15 and :16 through ``read(index, sub)`` (an SDO read) at drive time ``t_s``."""
    subs = list(range(1, 14)) + [FE_SUB_SCALE, FE_SUB_BIAS]
    return DriveEstimate.from_raw(t_s, [int(read(FE_INDEX, s)) for s in subs])


@dataclass
class ProfileLeg:
    """One move of the normal motion profile: PP move to ``target_rad`` at ``v_rad_s`` (output)."""

    target_rad: float
    v_rad_s: float


def normal_profile(v_min_deg_s: float = 0.01, v_max_deg_s: float = 10.0, n_speeds: int = 10,
                   cruise_s: float = 0.55, amax_deg_s2: float = 100.0, run_in_deg: float = 0.05
                   ) -> list[ProfileLeg]:
    """Moves and reversals of a normal motion profile about the start position (one cycle).

    The rule: ``n_speeds`` log-spaced speeds from ``v_min`` to ``v_max``; at each
    speed one move forward and one back of ``L = v cruise_s + v^2 / amax`` each,
    centred on the start.  Each of them is entered in its own direction: a short
    positioning move at ``v_max`` overshoots by ``run_in_deg`` and comes back (the
    reversal happens at speed), so the slow move starts with the friction and the
    loops' integrators already on its side instead of winding them through twice the
    breakaway level at the slow rate (that transient is not steady friction and
    takes longer than the move at the slowest rates).

    Parameters
    ----------
    v_min_deg_s, v_max_deg_s : float
        Slowest and fastest speed, deg/s (> 0).
    n_speeds : int
        Speeds in the cycle (>= 2).
    cruise_s : float
        Constant-velocity time of each slow move, s: the estimator's settle time
        (fe_settle) plus its data (at least fe_n_min steps).
    amax_deg_s2 : float
        Profile acceleration, deg/s^2 (the accelerating and braking parts add ``v^2 / amax``).
    run_in_deg : float
        Overshoot of the positioning moves, deg.

    Returns
    -------
    list of ProfileLeg
        Targets relative to the start position, rad; six moves per speed.
    """
    if not (0 < v_min_deg_s < v_max_deg_s) or n_speeds < 2 or cruise_s <= 0 or amax_deg_s2 <= 0 \
            or run_in_deg <= 0:
        raise ValueError("normal_profile: need 0 < v_min < v_max, n_speeds >= 2, cruise_s, amax, run_in > 0")
    fast = math.radians(v_max_deg_s)
    d = math.radians(run_in_deg)
    legs = []
    for v in np.geomspace(v_min_deg_s, v_max_deg_s, n_speeds):
        v = float(v)
        half = math.radians(0.5 * (v * cruise_s + v * v / amax_deg_s2))
        legs += [ProfileLeg(-half - d, fast), ProfileLeg(-half, fast), ProfileLeg(half, math.radians(v)),
                 ProfileLeg(half + d, fast), ProfileLeg(half, fast), ProfileLeg(-half, math.radians(v))]
    return legs


def profile_cycle_s(legs: list[ProfileLeg], amax_deg_s2: float = 100.0) -> float:
    """Nominal duration of one cycle of legs (trapezoid moves, start to start), s."""
    t, prev = 0.0, 0.0
    for g in legs:
        d = abs(g.target_rad - prev)
        v, a = g.v_rad_s, math.radians(amax_deg_s2)
        t += d / v + v / a
        prev = g.target_rad
    return t


def watch_convergence(history: list[DriveEstimate], ref: StribeckResult, t0_s: float,
                      scale_at: Any = None, tol_level: float = TOL_LEVEL, tol_vs: float = TOL_VS
                      ) -> Optional[float]:
    """Time from ``t0_s`` after which every reading stays within tolerance of the reference.

    Parameters
    ----------
    history : list of DriveEstimate
        Readings in time order.
    ref : StribeckResult
        Batch fit.
    t0_s : float
        Drive time the count starts from (profile start, or the end of a drift ramp), s.
    scale_at : callable, optional
        ``scale_at(t_s)``: friction scale of the reference at drive time t (drift); default 1.
    tol_level, tol_vs : float
        Relative tolerances.

    Returns
    -------
    float or None
        Seconds after ``t0_s`` (None if the last reading is outside).
    """
    since: Optional[float] = None
    for e in history:
        if e.t_s < t0_s:
            continue
        s = 1.0 if scale_at is None else float(scale_at(e.t_s))
        if e.within(ref, s, tol_level, tol_vs):
            if since is None:
                since = e.t_s
        else:
            since = None
    return None if since is None else max(0.0, since - t0_s)


def run_profile(bench: Any, legs: list[ProfileLeg], duration_s: float,
                on_reading: Optional[Any] = None) -> tuple[float, list[DriveEstimate]]:
    """Run the profile (cycles of ``legs`` about the present position) for ``duration_s`` of drive time.

    The drive must have ``fe_enable`` = 1; the estimate is read after every move.

    Parameters
    ----------
    bench : hdservo.procedures.runner.Bench
        Enabled in PROFILED POSITION mode by this function.
    legs : list of ProfileLeg
        One cycle (:func:`normal_profile`).
    duration_s : float
        Profile time, s (the last cycle stops at the first leg end past it).
    on_reading : callable, optional
        Called with each :class:`DriveEstimate` (progress).

    Returns
    -------
    (float, list of DriveEstimate)
        Drive time of the profile start, s, and the readings.
    """
    from ..procedures.closedloop import pp_move
    from ..procedures.runner import DT
    from ..units import TURN
    bench.enable("PROFILED POSITION")
    start = float(bench.load_angle_rad())
    t0 = bench.ticks() * DT
    hist: list[DriveEstimate] = []
    k = 0
    while True:
        g = legs[k % len(legs)]
        bench.drive.set_param("traj_vmax", g.v_rad_s / TURN)
        pp_move(bench, start + g.target_rad)
        e = read_drive_estimate(bench.read, bench.ticks() * DT)
        hist.append(e)
        if on_reading is not None:
            on_reading(e)
        k += 1
        if e.t_s - t0 >= duration_s:
            break
    return t0, hist


def drift_scale(t_s: float, t_start_s: float, ramp_s: float, scale: float) -> float:
    """The plant's ``[friction_drift]`` scale at plant time ``t_s`` (docs/sim.md)."""
    x = (t_s - t_start_s) / ramp_s
    return 1.0 + (scale - 1.0) * min(1.0, max(0.0, x))


def online_identification(target: Any, batch: StribeckResult, duration_s: float = 20.0,
                          drift: Optional[dict[str, float]] = None, progress: Optional[Any] = None
                          ) -> dict[str, Any]:
    """Watch the drive's online Stribeck identification converge during a normal motion profile.

    The drive's estimator is switched on (``fe_enable`` = 1), the profile
    (:func:`normal_profile`) runs for ``duration_s`` of drive time and the
    estimate is read over CAN after every move and compared with ``batch``.
    The axis runs without its payload unbalance (rig set-up ``gear``): an
    unbalance present from the start of the estimation goes into the bins as
    asymmetric friction (one that appears later goes to the estimator's bias).

    Parameters
    ----------
    target : hdservo.procedures.runner.Target
        The drive (``bus`` None: the virtual drive of ``axis``, run in lock-step, so
        that the host's polling costs no drive time).
    batch : StribeckResult
        The batch fit to compare with (``hdservo identify friction``).
    duration_s : float
        Profile time, s of drive time.
    drift : dict, optional
        Virtual drive only: the plant's ``[friction_drift]`` (``t_start_s``, plant time,
        ``ramp_s``, ``scale``); the reference is then the batch fit scaled like the plant.
    progress : callable, optional
        ``progress(str)``.

    Returns
    -------
    dict
        ``history`` (readings; ``t_s`` from the profile start), ``final`` and
        ``final_rel_error``, ``time_to_target_s`` (levels within 5 %, vs within 15 % from
        then on, s after the profile start; None if not), with drift ``tracked_s`` (the
        same counted from the end of the ramp), the profile rule and the targets.
    """
    from ..procedures.runner import RigSetup, Target, open_bench
    legs = normal_profile()
    tgt = Target(bus=target.bus, node_id=target.node_id, axis=target.axis, seed=target.seed,
                 params={**target.params, "fe_enable": 1.0}, plant=dict(target.plant))
    if drift is not None:
        if not target.virtual:
            raise ValueError("friction drift is a simulator option (virtual drive only)")
        tgt.plant.update({"friction_drift.enabled": True, "friction_drift.t_start_s": float(drift["t_start_s"]),
                          "friction_drift.ramp_s": float(drift["ramp_s"]),
                          "friction_drift.scale": float(drift["scale"])})

    def report(e: DriveEstimate) -> None:
        if progress is not None:
            progress(f"t = {e.t_s:6.2f} s: fits {e.fits_pos}/{e.fits_neg}, confidence "
                     f"{e.conf_pos:.2f}/{e.conf_neg:.2f}, scale {e.scale:.3f}, bias {e.bias_Nm:+.4g} N.m")

    with open_bench(tgt, RigSetup("gear", payload=False), lockstep=target.virtual) as bench:
        t0, hist = run_profile(bench, legs, duration_s, on_reading=report)
    scale_at = None
    if drift is not None:
        d = drift

        def scale_at(t: float) -> float:
            return drift_scale(t, float(d["t_start_s"]), float(d["ramp_s"]), float(d["scale"]))
    out: dict[str, Any] = {
        "profile": {"rule": "normal_profile: 10 log-spaced speeds 0.01..10 deg/s, a move each way per speed, "
                            "each entered in its own direction", "cycle_s": profile_cycle_s(legs),
                    "moves_per_cycle": len(legs)},
        "targets": {"levels": TOL_LEVEL, "vs": TOL_VS, "time_s": 20.0, "drift_tracked_s": 10.0},
        "batch": batch.to_dict(), "t_profile_start_s": t0}
    out["time_to_target_s"] = watch_convergence(hist, batch, t0, scale_at)
    if drift is not None:
        t_end = float(drift["t_start_s"]) + float(drift["ramp_s"])
        out["drift"] = dict(drift)
        out["tracked_s"] = watch_convergence(hist, batch, t_end, scale_at)
    last = hist[-1]
    out["final_rel_error"] = last.rel_errors(batch, 1.0 if scale_at is None else scale_at(last.t_s))
    for e in hist:
        e.t_s -= t0
    out["history"] = [e.to_dict() for e in hist]
    out["final"] = last.to_dict()
    return out
