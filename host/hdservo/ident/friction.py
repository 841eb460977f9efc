"""Friction: unbalance/inertia sweep, Stribeck static map, LuGre presliding.

All torques and velocities are output-referred (motor torque x N, output
encoder velocity): the sweep measures the *total* friction of the axis,
``N F_m(N v) + F_l(v)``.

Steps
-----
1. ``fit_gravity`` -- a slow large position sine: at speeds well above the
   Stribeck region ``N tau = J a + Fc+- + Fv v + gc cos(theta) + gs sin(theta)``
   (linear least squares) gives the unbalance (mgl, offset), Coulomb and
   viscous first guesses and the total inertia.
2. ``sweep_points`` -- each constant-velocity window: mean velocity from the
   output encoder (slope), mean torque minus the unbalance torque at the
   visited angles.
3. ``fit_stribeck`` -- linearised grid over the Stribeck velocity for a start
   (the model is linear in Fc, Fs - Fc, Fv once vs and delta are fixed), then
   nonlinear least squares on (Fc+, Fc-, Fs+, Fs-, vs, delta, Fv).
4. ``fit_presliding`` -- locked output: the input-side friction is
   ``F_m = tau_m - T/N`` (rig torque sensor T); after every motion reversal
   LuGre gives, quasi-statically, ``F = g (1 - 2 exp(-sigma0 x / g))`` in the
   displacement x since the reversal -> sigma0 (motor side).  sigma1 does
   not show in quasi-static data; it is set by the bristle-damping rule
   sigma1 = sqrt(sigma0 J_m) when J_m is known (FRF) and flagged as such.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

from ..errors import UserError
from .experiments import ExperimentData


# ----------------------------------------------------------------- model


def stribeck(v: np.ndarray, fc_pos: float, fc_neg: float, fs_pos: float, fs_neg: float, vs: float,
             delta: float, fv: float) -> np.ndarray:
    """Static Stribeck map, N.m: ``sgn(v) [Fc + (Fs - Fc) exp(-|v/vs|^delta)] + Fv v`` (per-direction Fc, Fs)."""
    v = np.asarray(v, dtype=float)
    pos = v >= 0
    fc = np.where(pos, fc_pos, fc_neg)
    fs = np.where(pos, fs_pos, fs_neg)
    g = fc + (fs - fc) * np.exp(-np.abs(v / vs) ** delta)
    return np.sign(v) * g + fv * v


@dataclass
class GravityResult:
    """Unbalance and coarse friction from the position sine.

    ``holding_torque(theta) = gc cos(theta) + gs sin(theta)`` (N.m) is what the
    motor supplies to hold the unbalance; mgl = hypot(gc, gs).
    """

    gc_Nm: float
    gs_Nm: float
    j_total_kgm2: float
    fc_pos_Nm: float
    fc_neg_Nm: float
    fv_Nms_per_rad: float
    samples: int
    residual_rms_Nm: float

    @property
    def mgl_Nm(self) -> float:
        return math.hypot(self.gc_Nm, self.gs_Nm)

    @property
    def offset_rad(self) -> float:
        # plant: T_g = -mgl cos(theta + off) -> holding = mgl cos(theta + off) = mgl(cos cos(off) - sin sin(off))
        return math.atan2(-self.gs_Nm, self.gc_Nm)

    def holding_torque(self, theta: np.ndarray) -> np.ndarray:
        return self.gc_Nm * np.cos(theta) + self.gs_Nm * np.sin(theta)

    def to_dict(self) -> dict[str, Any]:
        return {"mgl_Nm": self.mgl_Nm, "offset_rad": self.offset_rad, "j_total_kgm2": self.j_total_kgm2,
                "fc_pos_Nm": self.fc_pos_Nm, "fc_neg_Nm": self.fc_neg_Nm, "fv_Nms_per_rad": self.fv_Nms_per_rad,
                "samples": self.samples, "residual_rms_Nm": self.residual_rms_Nm}


def _deriv(x: np.ndarray, dt: float, win: int, order: int) -> np.ndarray:
    win = max(order + 3, win | 1)
    if len(x) <= win:
        return np.gradient(x, dt) if order == 1 else np.gradient(np.gradient(x, dt), dt)
    return savgol_filter(x, win, 3, deriv=order, delta=dt)


def fit_gravity(data: ExperimentData, v_min_rad_s: float = 0.15) -> GravityResult:
    """Unbalance, inertia, Coulomb and viscous friction from ``gravity_sine`` data.

    Parameters
    ----------
    data : ExperimentData
        Position-sine run: ``load_angle_rad``, ``motor_torque_Nm``.
    v_min_rad_s : float
        Only samples faster than this (rad/s, output) are used (outside the
        Stribeck region).
    """
    if data.kind != "gravity_sine":
        raise UserError(f"gravity: expected gravity_sine data, found '{data.kind}'")
    N = data.gear_ratio
    dt = float(data.meta["sample_period_s"])
    win = int(round(0.05 / dt))
    ths, vs, accs, taus = [], [], [], []
    for seg in data.segments:
        c = data.segment(seg["index"])
        skip = c["t_s"] >= c["t_s"][0] + 1.0        # start-up transient of the sine (velocity jump)
        ths.append(c["load_angle_rad"][skip])
        vs.append(_deriv(c["load_angle_rad"], dt, win, 1)[skip])
        accs.append(_deriv(c["load_angle_rad"], dt, 4 * win, 2)[skip])
        taus.append(c["motor_torque_Nm"][skip] * N)
    th, v, a, tau = (np.concatenate(x) for x in (ths, vs, accs, taus))
    m = np.abs(v) > v_min_rad_s
    if m.sum() < 50:
        raise UserError(f"gravity: fewer than 50 samples faster than {v_min_rad_s} rad/s")
    A = np.column_stack([(v > 0).astype(float), -(v < 0).astype(float), v, a, np.cos(th), np.sin(th)])[m]
    coef, *_ = np.linalg.lstsq(A, tau[m], rcond=None)
    res = tau[m] - A @ coef
    return GravityResult(gc_Nm=float(coef[4]), gs_Nm=float(coef[5]), j_total_kgm2=float(coef[3]),
                         fc_pos_Nm=float(coef[0]), fc_neg_Nm=float(coef[1]), fv_Nms_per_rad=float(coef[2]),
                         samples=int(m.sum()), residual_rms_Nm=float(np.sqrt(np.mean(res ** 2))))


@dataclass
class SweepPoints:
    """Steady-state points of a constant-velocity sweep (output-referred).

    Attributes
    ----------
    v_rad_s : numpy.ndarray
        Mean velocity of each window (output encoder slope), rad/s.
    torque_Nm : numpy.ndarray
        Mean friction torque of each window (unbalance removed), N.m.
    std_Nm : numpy.ndarray
        Standard deviation of the torque in the window, N.m.
    window_s, t_end_s : numpy.ndarray
        Window length and cumulative experiment time at the window end, s.
    samples : dict
        Per-window raw samples for the online identification: ``v``, ``f``, ``t``.
    """

    v_rad_s: np.ndarray
    torque_Nm: np.ndarray
    std_Nm: np.ndarray
    window_s: np.ndarray
    t_end_s: np.ndarray
    samples: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    rejected: list[dict[str, float]] = field(default_factory=list)


def sweep_points(data: ExperimentData, gravity: GravityResult | None = None,
                 max_speed_error: float = 0.25) -> SweepPoints:
    """Reduce a ``friction_sweep`` to one (velocity, torque) point per window.

    Windows whose mean speed misses the set speed by more than
    ``max_speed_error`` (relative) are rejected (listed in ``rejected``).
    """
    if data.kind != "friction_sweep":
        raise UserError(f"friction: expected friction_sweep data, found '{data.kind}'")
    N = data.gear_ratio
    dt = float(data.meta["sample_period_s"])
    vs, fs, ss, ws, te = [], [], [], [], []
    rejected: list[dict[str, float]] = []
    sv, sf, st = [], [], []
    t_acc = 0.0
    for seg in data.segments:
        c = data.segment(seg["index"])
        t = c["t_s"] - c["t_s"][0]
        settle = float(seg["settle_s"])
        m = t >= settle
        if m.sum() < 10:
            raise UserError(f"friction: segment {seg['index']} has fewer than 10 samples after settling")
        th = c["load_angle_rad"][m]
        tau = c["motor_torque_Nm"][m] * N
        if gravity is not None:
            tau = tau - gravity.holding_torque(th)
        v = float(np.polyfit(t[m], th, 1)[0])
        vset = float(seg.get("velocity_rad_s", v))
        if vset != 0 and abs(v / vset - 1.0) > max_speed_error:
            # not steady (stick-slip / hunting at the lowest speeds): not a point of the static map
            rejected.append({"index": int(seg["index"]), "velocity_set_rad_s": vset, "velocity_rad_s": v})
            t_acc += float(t[-1] + dt)
            continue
        vs.append(v)
        fs.append(float(np.mean(tau)))
        ss.append(float(np.std(tau)))
        ws.append(float(t[m][-1] - t[m][0] + dt))
        t_acc += float(t[-1] + dt)
        te.append(t_acc)
        # per-sample velocity for the online method: window-local slope over ~50 ms blocks
        k = max(1, int(round(0.05 / dt)))
        nb = len(th) // k
        if nb >= 2:
            tb = t[m][: nb * k].reshape(nb, k).mean(axis=1)
            thb = th[: nb * k].reshape(nb, k).mean(axis=1)
            vb = np.gradient(thb, tb)
            fb = tau[: nb * k].reshape(nb, k).mean(axis=1)
            sv.append(vb)
            sf.append(fb)
            st.append(t_acc - (t[-1] - tb))
    return SweepPoints(np.array(vs), np.array(fs), np.array(ss), np.array(ws), np.array(te),
                       samples={"v": np.concatenate(sv), "f": np.concatenate(sf), "t": np.concatenate(st)}
                       if sv else {}, rejected=rejected)


@dataclass
class StribeckResult:
    """Identified static Stribeck map (output-referred, N.m and rad/s)."""

    fc_pos_Nm: float
    fc_neg_Nm: float
    fs_pos_Nm: float
    fs_neg_Nm: float
    vs_rad_s: float
    delta: float
    viscous_Nms_per_rad: float
    residual_rms_Nm: float = 0.0
    max_rel_error: float = 0.0
    points: int = 0

    def params(self) -> tuple[float, ...]:
        return (self.fc_pos_Nm, self.fc_neg_Nm, self.fs_pos_Nm, self.fs_neg_Nm, self.vs_rad_s, self.delta,
                self.viscous_Nms_per_rad)

    def __call__(self, v: np.ndarray) -> np.ndarray:
        return stribeck(v, *self.params())

    @property
    def asymmetry(self) -> float:
        """(Fs+ - Fs-) / mean Fs."""
        return 2 * (self.fs_pos_Nm - self.fs_neg_Nm) / (self.fs_pos_Nm + self.fs_neg_Nm)

    def to_dict(self) -> dict[str, Any]:
        return {"fc_pos_Nm": self.fc_pos_Nm, "fc_neg_Nm": self.fc_neg_Nm, "fs_pos_Nm": self.fs_pos_Nm,
                "fs_neg_Nm": self.fs_neg_Nm, "vs_rad_s": self.vs_rad_s, "delta": self.delta,
                "viscous_Nms_per_rad": self.viscous_Nms_per_rad, "asymmetry": self.asymmetry,
                "residual_rms_Nm": self.residual_rms_Nm, "max_rel_error": self.max_rel_error,
                "points": self.points}


def linearised_grid(v: np.ndarray, f: np.ndarray, vs_grid: np.ndarray, delta: float = 2.0
                    ) -> tuple[float, np.ndarray, float]:
    """Best Stribeck velocity on a grid with closed-form LS for the linear parameters.

    For fixed vs and delta, ``f = sgn(v)[Fc+- + dF+- exp(-|v/vs|^d)] + Fv v``
    is linear in theta = (Fc+, dF+, Fc-, dF-, Fv).

    Returns
    -------
    vs : float
        Grid value with the smallest sum of squared errors.
    theta : numpy.ndarray
        (Fc+, Fs+ - Fc+, Fc-, Fs- - Fc-, Fv).
    sse : float
    """
    best = (math.inf, 0.0, np.zeros(5))
    pos = (v >= 0).astype(float)
    neg = 1.0 - pos
    for vs in vs_grid:
        e = np.exp(-np.abs(v / vs) ** delta)
        A = np.column_stack([pos, pos * e, -neg, -neg * e, v])
        th, *_ = np.linalg.lstsq(A, f, rcond=None)
        sse = float(np.sum((A @ th - f) ** 2))
        if sse < best[0]:
            best = (sse, float(vs), th)
    return best[1], best[2], best[0]


def fit_stribeck(points: SweepPoints, delta_free: bool = True) -> StribeckResult:
    """Nonlinear least squares on the sweep points (start from the linearised grid).

    Parameters
    ----------
    points : SweepPoints
        At least 8 points with both signs of velocity.
    delta_free : bool
        Fit the shape exponent too (else fixed at 2).
    """
    v, f = points.v_rad_s, points.torque_Nm
    if len(v) < 8 or not (np.any(v > 0) and np.any(v < 0)):
        raise UserError("friction: need at least 8 sweep points in both directions")
    av = np.abs(v[v != 0])
    grid = np.geomspace(av.min() / 2, av.max(), 60)
    vs0, th0, _ = linearised_grid(v, f, grid)
    x0 = np.array([th0[0], th0[2], th0[0] + th0[1], th0[2] + th0[3], math.log(vs0), 2.0, th0[4]])
    w = 1.0 / np.maximum(points.std_Nm / np.sqrt(np.maximum(points.window_s / 0.05, 1.0)), 1e-3 * np.abs(f).max())

    def resid(x: np.ndarray) -> np.ndarray:
        d = x[5] if delta_free else 2.0
        return (stribeck(v, x[0], x[1], x[2], x[3], math.exp(x[4]), d, x[6]) - f) * w / w.mean()

    lo = [0, 0, 0, 0, math.log(av.min() / 20), 0.3, 0]
    hi = [np.inf, np.inf, np.inf, np.inf, math.log(av.max() * 10), 5.0, np.inf]
    x0 = np.clip(x0, np.array(lo) + 1e-12, np.array(hi) - 1e-12)
    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac")
    x = sol.x
    d = float(x[5]) if delta_free else 2.0
    r = StribeckResult(float(x[0]), float(x[1]), float(x[2]), float(x[3]), math.exp(float(x[4])), d, float(x[6]))
    pred = r(v)
    r.residual_rms_Nm = float(np.sqrt(np.mean((pred - f) ** 2)))
    r.max_rel_error = float(np.max(np.abs(pred - f) / np.abs(f)))
    r.points = int(len(v))
    return r


# ----------------------------------------------------------------- LuGre presliding


@dataclass
class PreslidingResult:
    """Input-side (motor) LuGre presliding, motor units: N.m, rad at the motor.

    Attributes
    ----------
    sigma0_Nm_per_rad : float
        Bristle stiffness sigma0 (motor side), N.m/rad.
    breakaway_pos_Nm, breakaway_neg_Nm : float
        Friction level g reached in presliding (= Fs at these speeds), N.m (motor).
    sigma1_Nms_per_rad : float or None
        Bristle damping: not identified from the quasi-static test; when the
        motor inertia is known (FRF) the critical-damping rule
        sqrt(sigma0 J_m) is reported and flagged in ``sigma1_source``.
    """

    sigma0_Nm_per_rad: float
    breakaway_pos_Nm: float
    breakaway_neg_Nm: float
    sigma1_Nms_per_rad: float | None
    sigma1_source: str
    reversals: int
    residual_rms_Nm: float
    offset_Nm: float = 0.0
    plot_data: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def breakaway_Nm(self) -> float:
        return 0.5 * (self.breakaway_pos_Nm + self.breakaway_neg_Nm)

    def to_dict(self) -> dict[str, Any]:
        return {"sigma0_Nm_per_rad": self.sigma0_Nm_per_rad, "breakaway_pos_Nm": self.breakaway_pos_Nm,
                "breakaway_neg_Nm": self.breakaway_neg_Nm, "presliding_distance_rad":
                self.breakaway_Nm / self.sigma0_Nm_per_rad, "sigma1_Nms_per_rad": self.sigma1_Nms_per_rad,
                "sigma1_source": self.sigma1_source, "reversals": self.reversals,
                "residual_rms_Nm": self.residual_rms_Nm, "offset_Nm": self.offset_Nm,
                "side": "motor (input), motor units"}


def _legs(cmd: np.ndarray) -> list[tuple[int, int, int]]:
    """(start, stop, direction) of the monotone stretches of a piecewise-linear command (dwells join the leg before)."""
    d = np.sign(np.diff(cmd))
    tol = 1e-9 * max(1.0, float(np.max(np.abs(cmd))))
    d[np.abs(np.diff(cmd)) <= tol] = 0
    legs: list[tuple[int, int, int]] = []
    cur, start = 0, 0
    for i, v in enumerate(d):
        if v != 0 and v != cur:
            if cur != 0:
                legs.append((start, i, cur))
            cur, start = int(v), i
    if cur != 0:
        legs.append((start, len(cmd), cur))
    return legs


def lugre_presliding(s_legs: list[np.ndarray], dirs: list[int], sigma0: float, g_pos: float, g_neg: float,
                     z0: float) -> list[np.ndarray]:
    """Bristle force sigma0 z along monotone legs (quasi-static LuGre, rate independent).

    On a leg of direction d with travel s >= 0 since its reversal,
    ``dz/ds = 1 - sigma0 z d / g_d`` gives
    ``z(s) = d g_d/sigma0 + (z_start - d g_d/sigma0) exp(-sigma0 s / g_d)``;
    each leg starts where the previous one ended.
    """
    out = []
    z = z0
    for s, d in zip(s_legs, dirs):
        g = g_pos if d > 0 else g_neg
        zi = d * g / sigma0 + (z - d * g / sigma0) * np.exp(-sigma0 * s / g)
        out.append(sigma0 * zi)
        z = float(zi[-1]) if len(zi) else z
    return out


def _presliding_legs(data: ExperimentData, k: int) -> tuple[list[np.ndarray], list[np.ndarray], list[int],
                                                            list[np.ndarray]]:
    """Each monotone leg of the torque command: (travel past the reversal rad, motor-side friction
    N.m, direction, smoothed motor angle rad) per leg; the motor angle is averaged over ``k`` samples.

    The travel is the running maximum of the motor angle past the reversal point, so encoder noise
    never counts as travel; legs shorter than 5 samples are left out.
    """
    N = data.gear_ratio
    s_legs, f_legs, dirs, x_legs = [], [], [], []
    for seg in data.segments:
        c = data.segment(seg["index"])
        fm = c["motor_torque_Nm"] - c["load_torque_Nm"] / N
        th = c["motor_angle_rad"]
        if len(th) > 2 * k:
            pad = np.concatenate([np.full(k // 2, th[0]), th, np.full(k - 1 - k // 2, th[-1])])
            th = np.convolve(pad, np.ones(k) / k, mode="valid")
        cmd = c["torque_cmd_Nm"]
        for a, b, d in _legs(cmd):
            if b - a < 5:
                continue
            x = d * (th[a:b] - th[a])
            # reversal point: the motion may run on for a few samples after the command turns
            head = max(1, (b - a) // 5)
            x = x - min(0.0, float(np.min(x[:head])))
            s_legs.append(np.maximum.accumulate(np.maximum(x, 0.0)))
            f_legs.append(fm[a:b])
            x_legs.append(th[a:b])
            dirs.append(d)
    return s_legs, f_legs, dirs, x_legs


def _sigma0_start(s_legs: list[np.ndarray], f_legs: list[np.ndarray], dirs: list[int], g0: float) -> float:
    """Start value of sigma0 (N.m/rad): half the initial slope of the longest reversal."""
    j = int(np.argmax([float(np.ptp(f)) for f in f_legs]))
    sj, fj = s_legs[j], f_legs[j]
    m = (np.abs(fj - fj[0]) < 0.5 * g0) & (sj > 0)
    slope = float(np.polyfit(sj[m], fj[m], 1)[0]) * dirs[j] if m.sum() > 3 else 0.0
    sig0 = max(abs(slope) / 2.0, 1e-6 * g0 / max(float(np.max(sj)), 1e-12), 1e-9)
    if not math.isfinite(sig0) or sig0 <= 0:
        sig0 = 3 * g0 / max(float(np.max(sj)), 1e-9)
    return sig0


def _fit_lugre_legs(s_legs: list[np.ndarray], dirs: list[int], f_all: np.ndarray, sig0: float, g0: float) -> Any:
    """Least-squares fit of the chained quasi-static LuGre legs: log sigma0, log g+, log g-, the
    initial bristle state (tanh-bounded) and a torque offset; the best of three starts of the state."""
    def model(p: np.ndarray) -> np.ndarray:
        s0, gp, gn = math.exp(p[0]), math.exp(p[1]), math.exp(p[2])
        z0 = math.tanh(p[3]) * max(gp, gn) / s0
        return np.concatenate(lugre_presliding(s_legs, dirs, s0, gp, gn, z0)) + p[4]

    def resid(p: np.ndarray) -> np.ndarray:
        return model(p) - f_all

    best = None
    for z_start in (-2.0, 0.0, 2.0):
        p0 = np.array([math.log(sig0), math.log(g0), math.log(g0), z_start, 0.0])
        sol = least_squares(resid, p0, x_scale="jac", max_nfev=400)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    return best


def fit_presliding(data: ExperimentData, jm_kgm2: float | None = None, smooth_s: float = 0.01
                   ) -> PreslidingResult:
    """Motor-side LuGre sigma0 and breakaway from a locked-output ``presliding`` experiment.

    The motor-side friction is ``F = tau_m - T/N`` (motor torque minus the rig
    torque sensor over N; the motor inertia term is negligible at these rates)
    against the motor angle.  Each monotone leg of the command is a motion
    reversal: its travel ``s`` = running maximum of the (smoothed) motor angle
    past the reversal point (encoder noise never counts as travel), and the
    quasi-static LuGre solution (:func:`lugre_presliding`), chained across the
    legs, is fitted for sigma0, g+, g-, the initial bristle state and a torque
    offset (nonlinear least squares, 5 parameters).

    Parameters
    ----------
    data : ExperimentData
        ``presliding`` data (``motor_angle_rad``, ``motor_torque_Nm``,
        ``load_torque_Nm``, ``torque_cmd_Nm``); the older locked-output data
        (``locked_cycle``, ``forc``) works too.
    jm_kgm2 : float, optional
        Motor inertia, kg.m^2 (e.g. J1/N^2 of the FRF): sigma1 = sqrt(sigma0 J_m)
        is then reported as a *rule*, not a measurement.
    smooth_s : float
        Moving-average length for the motor angle, s.
    """
    if data.kind not in ("presliding", "locked_cycle", "forc", "minor_loops"):
        raise UserError(f"presliding: expected presliding (locked-output) data, found '{data.kind}'")
    dt = float(data.meta["sample_period_s"])
    s_legs, f_legs, dirs, x_legs = _presliding_legs(data, max(1, int(round(smooth_s / dt))))
    if len(dirs) < 3:
        raise UserError("presliding: fewer than 3 torque reversals in the data")
    f_all = np.concatenate(f_legs)
    g0 = float(np.percentile(np.abs(f_all), 98))
    best = _fit_lugre_legs(s_legs, dirs, f_all, _sigma0_start(s_legs, f_legs, dirs, g0), g0)
    s0, gp, gn = (math.exp(float(v)) for v in best.x[:3])
    s1 = math.sqrt(s0 * jm_kgm2) if jm_kgm2 else None
    src = ("rule sqrt(sigma0*J_m) (J_m from the FRF), not measured" if s1 else
           "not identified: at the presliding resonance (~sqrt(sigma0/J_m)) the bristle damping shows only in a "
           "few-count ring-down of the motor encoder")
    return PreslidingResult(sigma0_Nm_per_rad=s0, breakaway_pos_Nm=gp, breakaway_neg_Nm=gn,
                            sigma1_Nms_per_rad=s1, sigma1_source=src, reversals=len(dirs),
                            residual_rms_Nm=float(np.sqrt(np.mean(best.fun ** 2))), offset_Nm=float(best.x[4]),
                            plot_data={"theta_rad": np.concatenate(x_legs), "f_Nm": f_all,
                                       "fit_Nm": best.fun + f_all})
