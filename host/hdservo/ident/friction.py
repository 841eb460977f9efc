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

from ..cli import UserError
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
    """Input-side LuGre presliding (motor units: N.m, rad at the motor)."""

    sigma0_Nm_per_rad: float
    breakaway_Nm: float
    sigma1_Nms_per_rad: float | None
    sigma1_source: str
    reversals: int
    residual_rms_Nm: float
    plot_data: dict[str, Any] = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {"sigma0_Nm_per_rad": self.sigma0_Nm_per_rad, "breakaway_Nm": self.breakaway_Nm,
                "sigma1_Nms_per_rad": self.sigma1_Nms_per_rad, "sigma1_source": self.sigma1_source,
                "reversals": self.reversals, "residual_rms_Nm": self.residual_rms_Nm,
                "side": "motor (input), motor units"}


def fit_presliding(data: ExperimentData, jm_kgm2: float | None = None) -> PreslidingResult:
    """sigma0 of the input-side friction from the locked-output cycles.

    Parameters
    ----------
    data : ExperimentData
        ``locked_cycle`` data with the rig torque sensor ``load_torque_Nm``.
    jm_kgm2 : float, optional
        Motor-side inertia (kg.m^2, from the FRF) for the sigma1 rule.
    """
    if data.kind not in ("locked_cycle", "forc", "minor_loops"):
        raise UserError(f"presliding: expected locked-output data, found '{data.kind}'")
    N = data.gear_ratio
    xs, fs, ids = [], [], []
    nrev = 0
    for seg in data.segments:
        c = data.segment(seg["index"])
        th = c["motor_angle_rad"]
        fm = c["motor_torque_Nm"] - c["load_torque_Nm"] / N
        # motion reversals: extrema of the (smoothed) motor angle with enough travel on both sides
        k = 15
        ths = np.convolve(th, np.ones(k) / k, mode="same")
        d = np.sign(np.diff(ths))
        for i in range(1, len(d)):
            if d[i] == 0:
                d[i] = d[i - 1]
        rev = np.where(d[1:] != d[:-1])[0] + 1
        # keep well-separated reversals
        keep = [r for j, r in enumerate(rev) if (j == 0 or r - rev[j - 1] > 200) and k < r < len(th) - 200]
        for r in keep:
            sgn = d[r] if r < len(d) else d[-1]
            x = (th[r:] - th[r]) * sgn
            f = fm[r:] * sgn
            # until the sliding level: first 1.5 x (sliding extent) of the presliding transition
            stop = np.argmax(x > 0.02) if np.any(x > 0.02) else len(x)
            if stop < 30:
                continue
            xs.append(x[:stop])
            fs.append(f[:stop])
            ids.append(np.full(stop, nrev))
            nrev += 1
    if nrev == 0:
        raise UserError("presliding: no motion reversals found in the locked-output data")
    x = np.concatenate(xs)
    f = np.concatenate(fs)
    rid = np.concatenate(ids)

    def resid(p: np.ndarray) -> np.ndarray:
        g, s0 = p[0], math.exp(p[1])
        off = p[2:][rid]
        return g * (1 - 2 * np.exp(-s0 * np.maximum(x - off, 0) / g)) - f

    g0 = float(np.median(f[x > 0.01])) if np.any(x > 0.01) else float(np.max(f))
    p0 = np.concatenate([[g0, math.log(3 * g0 / 0.003)], np.zeros(nrev)])
    sol = least_squares(resid, p0, x_scale="jac")
    g, s0 = float(sol.x[0]), math.exp(float(sol.x[1]))
    s1 = math.sqrt(s0 * jm_kgm2) if jm_kgm2 else None
    return PreslidingResult(sigma0_Nm_per_rad=s0, breakaway_Nm=g, sigma1_Nms_per_rad=s1,
                            sigma1_source="rule sqrt(sigma0*J_m), J_m from the FRF" if s1 else "not identified",
                            reversals=nrev, residual_rms_Nm=float(np.sqrt(np.mean(sol.fun ** 2))),
                            plot_data={"x_rad": x, "f_Nm": f, "fit_Nm": sol.fun + f})
