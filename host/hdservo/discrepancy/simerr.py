"""Simulation error: the fitted model simulated with the measured inputs, compared with the log.

The equation error (:mod:`hdservo.discrepancy.regression`) judges the model on measured,
twice-differentiated states; the simulation error judges what the model *does* when it
is driven by the measured input: it integrates the accelerations, so it weighs slow
disagreements (a friction force that holds the axis longer, a softer spring that lets
it twist further) far above the differentiated encoder noise, and it sees the
sticking phases the equation error has to leave out (Karnopp stiction below).

Closed loop without knowing the controller: every simulation starts from the measured
(filtered) state and runs over a short window (``horizon_s``, 50 ms by default; all
windows side by side), so a free integrator cannot drift far.  With two encoders each
side is simulated on its own, driven by what acts on it:

* motor side: J_m a_m = tau - (the motor-equation terms), with the *measured* load angle
  (the spring anchors it: a wrong model gives a bounded error, not a drift);
* load side: J_l a_l / N = -(R - M terms), with the *measured* motor angle.

A rigid model (one coordinate) is simulated as one mass.  Every term is evaluated on the
simulated state through :attr:`Column.fn`; terms without a state function (the stop
operators of the hysteresis candidate, accelerations of the compliance candidate) are
taken along the measured trajectory.  Friction columns (:attr:`Column.fric`) are
switched to the static force when the simulated side stands still (Karnopp): it stays
put while the other forces stay inside the friction the model has at zero speed, which
is where a Stribeck hump (static above Coulomb friction) shows.  The integration runs at
:data:`SUBSTEPS` sub-steps per decimated sample with the measured inputs (torque, the
other side's state) interpolated linearly between samples, so that a stop and a
breakaway are timed to a fraction of the decimated period.

Units: error in rad at the output (motor side divided by N; m for a linear axis).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .regression import Column, Design

#: Simulation window, s.
HORIZON_S = 0.05

#: Integration sub-steps per decimated sample.  The other side's measured state and the
#: torque are interpolated linearly between the decimated samples; the dynamics and the
#: Karnopp stick/slip run at dt / SUBSTEPS (1 kHz / 4 = 4 kHz: the breakaway and the stop
#: are timed to 0.25 ms instead of 1 ms).  Null log reference closed s7: motor-side
#: simulation error 5.7 -> 1.0 urad (1 -> 2 -> 8 sub-steps: 5.7, 1.1, 0.98 urad).
SUBSTEPS = 4


def _state(d: Design) -> dict[str, np.ndarray]:
    s = d.sig
    out = {"thm": d.dec("state:thm", s.th_m), "wm": d.dec("state:wm", s.w_m)}
    if s.th_l is not None:
        out["thl"] = d.dec("state:thl", s.th_l)
        out["wl"] = d.dec("state:wl", s.w_l)
    else:
        out["thl"] = out["thm"] / s.ratio
        out["wl"] = out["wm"] / s.ratio
    return out


def _windows(d: Design, horizon_s: float, phase: int = 0) -> tuple[dict[str, np.ndarray], int, float, int, np.ndarray]:
    """The decimated state and the window geometry every simulation-error function shares
    (``phase``: first window start, decimated samples; the windows tile the record from there).

    Returns
    -------
    x : dict
        :func:`_state` (angles rad, velocities rad/s, decimated).
    n : int
        Decimated samples.
    dt : float
        Decimated sample period, s.
    H : int
        Samples per window (at least 2).
    starts : numpy.ndarray
        First sample of each window.
    """
    x = _state(d)
    n = len(x["thm"])
    dt = d.sig.dt * max(d.sig.q, 1)
    H = window_samples(d, horizon_s)
    return x, n, dt, H, np.arange(max(0, int(phase)), n - H - 1, H)


def window_samples(d: Design, horizon_s: float) -> int:
    """Decimated samples per window of ``horizon_s`` (at least 2)."""
    return max(2, int(round(horizon_s / (d.sig.dt * max(d.sig.q, 1)))))


def _acting_terms(cols: Sequence[Column], theta: np.ndarray, side: str, rigid: bool) -> list[tuple[Column, float]]:
    """The (column, coefficient) pairs that act on ``side``'s equation.

    Left out: the inertia columns (they are the side's J), zero coefficients, columns
    without a motor-equation part (motor side), the same series in both equations (load
    side: R - M = 0) and columns without an R part (rigid).
    """
    terms = []
    for c, a in zip(cols, theta):
        if c.role or a == 0.0:
            continue
        if rigid and c.R is None:
            continue
        if not rigid and side == "m" and c.M is None:
            continue
        if not rigid and side == "l" and c.M is c.R:
            continue
        terms.append((c, float(a)))
    return terms


class _SideEquation:
    """One side's equation of motion in the windows: what acts on it, evaluated at the
    simulated state of this side and the measured state of the other.

    Parameters
    ----------
    d : Design
        The design (decimated columns).
    x : dict
        Measured state at the decimated samples (:func:`_state`).
    side : str
        ``"m"`` (motor, or the rigid axis) or ``"l"`` (load).
    terms : list
        :func:`_acting_terms` of this side.
    """

    def __init__(self, d: Design, x: dict[str, np.ndarray], side: str, terms: list[tuple[Column, float]]) -> None:
        self.d, self.x, self.side, self.terms = d, x, side, terms
        self.rigid = d.sig.kind == "rigid"
        self.fr = "m" if side == "m" else "l"

    def other(self, key: str, k: np.ndarray, lam: float) -> np.ndarray:
        """The other side's measured state at k + lam (linear between the decimated samples)."""
        v = self.x[key]
        return v[k] if lam == 0.0 else v[k] + lam * (v[k + 1] - v[k])

    def value(self, c: Column, th_: np.ndarray, w_: np.ndarray, k: np.ndarray, lam: float = 0.0) -> np.ndarray:
        """The column's value in this side's equation (motor: M, rigid: R, load: R - M)."""
        side, rigid = self.side, self.rigid
        if c.fn is not None:
            if side == "m":
                m, r = c.fn(th_, w_, self.other("thl", k, lam), self.other("wl", k, lam))
            else:
                m, r = c.fn(self.other("thm", k, lam), self.other("wm", k, lam), th_, w_)
            if rigid:
                return np.zeros_like(th_) if r is None else np.asarray(r, dtype=float) * np.ones_like(th_)
            if side == "m":
                return np.zeros_like(th_) if m is None else np.asarray(m, dtype=float) * np.ones_like(th_)
            rr = 0.0 if r is None else r
            mm = 0.0 if m is None else m
            return (rr - mm) * np.ones_like(th_)
        mm = self.d.dec(f"{c.key or c.name}:M", c.M)[k] if c.M is not None else 0.0
        rr = self.d.dec(f"{c.key or c.name}:R", c.R)[k] if c.R is not None else 0.0
        if rigid:
            return rr * np.ones_like(th_)
        return (mm if side == "m" else rr - mm) * np.ones_like(th_)

    def forces(self, th: np.ndarray, w: np.ndarray, k: np.ndarray, lam: float,
               f_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(external force, friction force) on this side, in its own unit."""
        ext = f_k * (1.0 if self.side == "m" else 0.0)
        fric = np.zeros_like(th)
        for c, a in self.terms:
            v = self.value(c, th, w, k, lam)
            if c.fric == self.fr:
                fric = fric + a * v
            else:
                ext = ext - a * v
        return ext, fric

    def static_band(self, th: np.ndarray, k: np.ndarray, lam: float, eps: float) -> tuple[np.ndarray, np.ndarray]:
        """The friction just above zero speed in each direction (the static friction band)."""
        tiny = 1e-3 * eps * np.ones_like(th)
        fp = sum((a * self.value(c, th, tiny, k, lam) for c, a in self.terms if c.fric == self.fr), np.zeros_like(th))
        fn_ = sum((a * self.value(c, th, -tiny, k, lam) for c, a in self.terms if c.fric == self.fr),
                  np.zeros_like(th))
        return fp, fn_


def _karnopp_step(eq: _SideEquation, th: np.ndarray, w: np.ndarray, k: np.ndarray, lam: float, f_k: np.ndarray,
                  eps: float, J: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """One sub-step ``h`` (s) of this side's angle and speed with Karnopp stick/slip.

    Below ``eps`` the side sticks while the other forces stay inside the static friction;
    a velocity sign change inside a step ends at zero (the next step decides).
    """
    ext, fric = eq.forces(th, w, k, lam, f_k)
    slow = np.abs(w) < eps
    if np.any(slow):
        fp, fn_ = eq.static_band(th, k, lam, eps)
        stuck = slow & (ext <= fp) & (ext >= fn_)
        brk = slow & ~stuck
        fric = np.where(brk, np.where(ext > fp, fp, fn_), fric)
    else:
        stuck = slow
    acc = (ext - fric) / J
    w_new = w + acc * h
    w_new = np.where((np.sign(w_new) * np.sign(w) < 0), 0.0, w_new)
    w_new = np.where(stuck, 0.0, w_new)
    return th + w_new * h, w_new


def _side_sim(d: Design, cols: Sequence[Column], theta: np.ndarray, force: np.ndarray, side: str,
              horizon_s: float, substeps: int | None = None, phase: int = 0) -> np.ndarray:
    """Simulate one side over windows; returns simulated-minus-measured angle at the dec rate (own unit)."""
    s = d.sig
    x, n, dt, H, starts = _windows(d, horizon_s, phase)
    err = np.full(n, np.nan)
    if side == "m":
        th, w, eps = x["thm"][starts].copy(), x["wm"][starts].copy(), d.v_eps * s.ratio
        role = "J" if s.kind == "rigid" else "Jm"
    else:
        th, w, eps = x["thl"][starts].copy(), x["wl"][starts].copy(), d.v_eps
        role = "Jl"
    names = [c.role for c in cols]
    if role not in names:
        return err
    J = float(theta[names.index(role)])
    if side == "l":
        J = J / s.ratio
    if not J > 0:
        return np.full(n, np.inf)
    eq = _SideEquation(d, x, side, _acting_terms(cols, theta, side, s.kind == "rigid"))
    meas = x["thm"] if side == "m" else x["thl"]
    S = max(1, int(SUBSTEPS if substeps is None else substeps))
    h = dt / S
    for j in range(H):
        k = starts + j
        # the inputs (torque, the other side's measured state, columns without a state
        # function) are held over the step; the dynamics and the stick/slip logic run
        # at dt / S
        for i in range(S):
            lam = i / S
            f_k = force[k] if lam == 0.0 else force[k] + lam * (force[k + 1] - force[k])
            th, w = _karnopp_step(eq, th, w, k, lam, f_k, eps, J, h)
        err[k + 1] = th - meas[k + 1]
    return err


def side_error(d: Design, cols: Sequence[Column], theta: np.ndarray, side: str, tau: np.ndarray | None = None,
               tau_key: str = "tau", horizon_s: float = HORIZON_S, substeps: int | None = None) -> np.ndarray:
    """Simulation error of one side (``"m"``: motor or rigid, ``"l"``: load), rad at the output
    (``substeps`` as in :func:`simulation_error`)."""
    s = d.sig
    force = d.dec(tau_key, s.tau if tau is None else tau)
    with np.errstate(over="ignore", invalid="ignore"):      # a diverging candidate gives inf, judged later
        e = _side_sim(d, cols, theta, force, side, horizon_s, substeps)
    if side == "m":
        e = e / s.ratio
    return e[~np.isnan(e)]


def simulation_error(d: Design, cols: Sequence[Column], theta: np.ndarray, tau: np.ndarray | None = None,
                     tau_key: str = "tau", horizon_s: float = HORIZON_S,
                     substeps: int | None = None, phase: int = 0) -> np.ndarray:
    """Simulation error of a fitted model over windows of ``horizon_s``, rad at the output.

    Each side obeys J acc = F - sum(coef * column value) with F the measured torque
    (motor side, rigid) or 0 (load side; its column values are R - M).

    Parameters
    ----------
    d : Design
    cols : sequence of Column
        The model's columns (baseline + added effects), in the order of ``theta``.
    theta : numpy.ndarray
        Their fitted coefficients.
    tau : numpy.ndarray, optional
        The input torque at the log rate, N.m at the motor (default: the measured one).
    tau_key : str
    horizon_s : float
        Window length, s.
    substeps : int, optional
        Integration sub-steps per decimated sample (default :data:`SUBSTEPS`).
    phase : int
        Start of the first window, decimated samples (the record before it is left out).

    Returns
    -------
    numpy.ndarray
        Simulated minus measured angle at the decimated rate, rad at the output (m for a
        linear axis): the motor side's divided by N, then (two-mass) the load side's,
        concatenated; NaN-free (window starts and the tail are left out).
    """
    s = d.sig
    force = d.dec(tau_key, s.tau if tau is None else tau)
    with np.errstate(over="ignore", invalid="ignore"):      # a diverging candidate gives inf, judged later
        parts = [_side_sim(d, cols, theta, force, "m", horizon_s, substeps, phase) / s.ratio]
        if s.kind == "two_mass":
            parts.append(_side_sim(d, cols, theta, force, "l", horizon_s, substeps, phase))
    e = np.concatenate(parts)
    return e[np.isfinite(e) | np.isinf(e)]


def region_mask(d: Design, bands: dict[str, float] | None, horizon_s: float = HORIZON_S,
                phase: int = 0) -> np.ndarray:
    """Samples of :func:`simulation_error` where an effect acting below a speed band can show.

    The simulation error is causal within a window: an effect that acts only while a side
    is slower than ``bands[side]`` (e.g. Stribeck friction around stops and reversals)
    cannot have changed the simulated angle before that side's *measured* speed first
    entered the band in the window (the simulated state starts at the measured one).  A
    sample is in the region if its window's measured speed on that side has been below
    the band at or before the previous step; the region is the same for the model
    before and after the effect is added.

    Parameters
    ----------
    d : Design
    bands : dict of str to float, or None
        Speed band per side (``"m"`` motor/rigid rad/s at the motor, ``"l"`` output
        rad/s); None selects the whole record.
    horizon_s : float
        Window length, s (as in :func:`simulation_error`).
    phase : int
        First window start, decimated samples (as in :func:`simulation_error`).

    Returns
    -------
    numpy.ndarray of bool
        Aligned with the output of :func:`simulation_error`.
    """
    s = d.sig
    x, n, _, H, starts = _windows(d, horizon_s, phase)
    sides = ["m"] + (["l"] if s.kind == "two_mass" else [])
    parts = []
    for side in sides:
        valid = np.zeros(n, dtype=bool)
        sel = np.zeros(n, dtype=bool)
        w = x["wm"] if side == "m" else x["wl"]
        band = None if bands is None else bands.get(side)
        slow = np.ones(n, dtype=bool) if bands is None else (
            np.abs(w) < band if band is not None else np.zeros(n, dtype=bool))
        hit = np.zeros(len(starts), dtype=bool)
        for j in range(H):
            k = starts + j
            hit |= slow[k]
            valid[k + 1] = True
            sel[k + 1] = hit
        parts.append(sel[valid])
    return np.concatenate(parts)
