"""Torsional stiffness (three-slope and cubic) and the catalogue hysteresis figures.

Experiment: output locked (clamp), quasi-static torque cycles
0 -> +T -> 0 -> -T -> 0 driven by the motor (:class:`.experiments.LockedCycle`).
The gear torque comes from the rig torque sensor between gear and clamp,
the twist from the motor encoder: ``phi = theta_m/N - theta_l + e(theta_m)``
with the kinematic error ``e`` from the TE fit (:mod:`.te`).

Why this isolates the gear: with the output locked the load-side friction
does not act (the load does not move) and the torque sensor sits after the
input friction, so neither the input-side LuGre presliding nor the output
bearing presliding enters the torque-twist relation; what remains is the
spring plus the gear's own hysteresis.

Fits
----
* three-slope ``T_s = K3 phi + (K1-K2) sat_phi1 + (K2-K3) sat_phi2`` jointly
  with Maxwell-slip elements on a threshold grid (linear in the slopes and
  the element stiffnesses for fixed knots; NNLS-type bounded LS inside, the
  knots phi1, phi2 by Nelder-Mead outside).  T1 = K1 phi1,
  T2 = T1 + K2 (phi2 - phi1).
* a direction-odd band ``d(t) g(phi)`` (free hat functions in ``|phi| < b``, ``d`` = branch
  direction) in both fits: on the branches of the major loop a closing (Preisach-type)
  hysteresis with no reversible part is exactly this, so inside the band the spring is fitted
  on the loop's centre line and the hysteresis does not bend it.  ``b`` is chosen from
  :data:`ODD_FRACTIONS` by the residual.
* cubic ``T = k1 phi + k3 phi^3`` (+ the same Maxwell elements and odd band).
* hysteresis loss (catalogue): twist difference at zero torque between the
  descending and ascending branches of the +-T cycle (points B-B');
  lost motion: twist between the +-4 % rated tips of the small cycle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear, minimize, nnls

from ..errors import UserError
from .experiments import ExperimentData
from .hysteresis import MaxwellSlip, maxwell_from_weights, split_reversals, stop_operators
from .te import TEResult

#: Half-widths of the direction-odd band tried by :func:`fit_stiffness` (fractions of the twist
#: amplitude).  At most 0.45: at least half of each branch stays outside the band, where the only
#: direction-odd torque is the Maxwell elements' sliding force, so that force is fixed by the data;
#: wider bands trade it against the band and the K2 region (over CAN: K2 -3.2 %, T2 -4 % at 0.65).
ODD_FRACTIONS = (0.25, 0.3, 0.35, 0.4, 0.45)


def twist_of(seg: dict[str, np.ndarray], ratio: float, te: TEResult | None) -> np.ndarray:
    """Twist (rad) from the encoders, TE removed when known."""
    phi = seg["motor_angle_rad"] / ratio - seg["load_angle_rad"]
    if te is not None:
        phi = phi + te.evaluate(seg["motor_angle_rad"])
    return phi


def sat(x: np.ndarray, d: float) -> np.ndarray:
    return np.clip(x, -d, d)


@dataclass
class StiffnessResult:
    """Three-slope and cubic stiffness, Maxwell-slip elements, catalogue figures."""

    k1_Nm_per_rad: float
    k2_Nm_per_rad: float
    k3_Nm_per_rad: float
    t1_Nm: float
    t2_Nm: float
    cubic_k1_Nm_per_rad: float
    cubic_k3_Nm_per_rad3: float
    hysteresis_loss_rad: float
    lost_motion_rad: float | None
    maxwell: MaxwellSlip
    residual_rms_Nm: float
    cubic_residual_rms_Nm: float
    te_corrected: bool
    odd_band_rad: float = 0.0
    plot_data: dict[str, Any] = field(default_factory=dict, repr=False)

    def three_slope(self, phi: np.ndarray) -> np.ndarray:
        p1 = self.t1_Nm / self.k1_Nm_per_rad
        p2 = p1 + (self.t2_Nm - self.t1_Nm) / self.k2_Nm_per_rad
        return (self.k3_Nm_per_rad * phi + (self.k1_Nm_per_rad - self.k2_Nm_per_rad) * sat(phi, p1)
                + (self.k2_Nm_per_rad - self.k3_Nm_per_rad) * sat(phi, p2))

    def to_dict(self) -> dict[str, Any]:
        return {"k1_Nm_per_rad": self.k1_Nm_per_rad, "k2_Nm_per_rad": self.k2_Nm_per_rad,
                "k3_Nm_per_rad": self.k3_Nm_per_rad, "t1_Nm": self.t1_Nm, "t2_Nm": self.t2_Nm,
                "cubic_k1_Nm_per_rad": self.cubic_k1_Nm_per_rad, "cubic_k3_Nm_per_rad3": self.cubic_k3_Nm_per_rad3,
                "hysteresis_loss_rad": self.hysteresis_loss_rad,
                "hysteresis_loss_arcmin": self.hysteresis_loss_rad / (math.pi / 180 / 60),
                "lost_motion_rad": self.lost_motion_rad,
                "lost_motion_arcmin": None if self.lost_motion_rad is None
                else self.lost_motion_rad / (math.pi / 180 / 60),
                "maxwell": self.maxwell.to_dict(), "residual_rms_Nm": self.residual_rms_Nm,
                "cubic_residual_rms_Nm": self.cubic_residual_rms_Nm, "te_corrected": self.te_corrected,
                "odd_band_rad": self.odd_band_rad}


def zero_crossing_twists(T: np.ndarray, phi: np.ndarray, cmd: np.ndarray, band: float) -> tuple[list[float], list[float]]:
    """Twist at T = 0 on descending and ascending stretches (local linear fit within +-band N.m)."""
    desc, asc = [], []
    for a, b in split_reversals(cmd):
        t, p = T[a:b + 1], phi[a:b + 1]
        m = np.abs(t) <= band
        if m.sum() < 5 or not (t.min() < -band / 2 and t.max() > band / 2):
            continue
        c = np.polyfit(t[m], p[m], 1)
        (desc if cmd[b] < cmd[a] else asc).append(float(c[1]))
    return desc, asc


def hysteresis_loss(T: np.ndarray, phi: np.ndarray, cmd: np.ndarray, t_max: float) -> float:
    """Catalogue hysteresis loss (rad): mean twist at T = 0 descending minus ascending (first stretch skipped)."""
    st = split_reversals(cmd)
    a0 = st[1][0] if len(st) > 1 else 0
    desc, asc = zero_crossing_twists(T[a0:], phi[a0:], cmd[a0:], 0.03 * t_max)
    if not desc or not asc:
        raise UserError("stiffness: the torque cycle does not cross zero in both directions")
    return float(np.mean(desc) - np.mean(asc))


def lost_motion(T: np.ndarray, phi: np.ndarray, cmd: np.ndarray) -> float:
    """Twist between the positive and negative tips of a small cycle (rad), first cycle skipped."""
    st = split_reversals(cmd)
    hi, lo = [], []
    for a, b in st[2:]:
        k = a + int(np.argmax(T[a:b + 1])) if cmd[b] < cmd[a] else a + int(np.argmin(T[a:b + 1]))
        (hi if cmd[b] < cmd[a] else lo).append(float(np.mean(phi[max(k - 3, 0):k + 4])))
    if not hi or not lo:
        raise UserError("stiffness: the lost-motion cycle has no complete reversal")
    return float(np.mean(hi) - np.mean(lo))


def _design(phi: np.ndarray, knots: tuple[float, float], stops: np.ndarray) -> np.ndarray:
    p1, p2 = knots
    return np.column_stack([phi, sat(phi, p1), sat(phi, p2), np.ones_like(phi), stops])


def branch_direction(cmd: np.ndarray) -> np.ndarray:
    """+1 on rising, -1 on falling stretches of the command (per sample)."""
    d = np.zeros(len(cmd))
    for a, b in split_reversals(cmd):
        d[a:b + 1] = 1.0 if cmd[b] > cmd[a] else -1.0
    return d


def odd_hats(phi: np.ndarray, direction: np.ndarray, half_width: float, n: int) -> np.ndarray:
    """Direction-odd basis ``direction * hat_j(phi)``: n hat functions on (-half_width, half_width).

    On the branches of a major loop a Preisach-type hysteresis that closes (no reversible part,
    zero outside its input range) is exactly ``direction * g(phi)``; these free columns absorb it
    so that the spring is fitted on the centre line of the loop there.
    """
    nodes = np.linspace(-half_width, half_width, n + 2)
    h = nodes[1] - nodes[0]
    cols = [np.clip(1.0 - np.abs(phi - c) / h, 0.0, None) for c in nodes[1:-1]]
    return direction[:, None] * np.column_stack(cols)


def _fit_knots(ph: np.ndarray, Tm: np.ndarray, stops: np.ndarray, odd: np.ndarray, span: float,
               nK: int) -> tuple[float, float, float, np.ndarray]:
    """The three-slope knots (rad of twist) with the spring, Maxwell-slip and odd-band weights.

    Coarse grid over the knot fractions of ``span``, then Nelder-Mead in log space; each trial
    solves the bounded linear least squares (NNLS).  Returns (SSE, phi1, phi2, weights).
    """
    def solve(knots: tuple[float, float]) -> tuple[float, np.ndarray]:
        A = np.column_stack([_design(ph, knots, stops)[:, :nK], odd])
        # free columns split into +/- parts so that plain NNLS handles the bounds (fast active set)
        B = np.column_stack([A, -A, stops])
        nf = A.shape[1]
        sc = np.linalg.norm(B, axis=0) + 1e-300
        z, rn = nnls(B / sc, Tm, maxiter=20 * B.shape[1])
        z = z / sc
        x = np.r_[z[:nK] - z[nf:nf + nK], z[2 * nf:]]
        xo = z[nK:nf] - z[nf + nK:2 * nf]
        return float(rn ** 2), np.r_[x, xo]

    # knots: coarse grid then Nelder-Mead (log space, ordered)
    best = (math.inf, (0.0, 0.0))
    for f1 in np.linspace(0.1, 0.6, 8):
        for f2 in np.linspace(f1 + 0.1, 0.95, 6):
            sse, _ = solve((f1 * span, f2 * span))
            if sse < best[0]:
                best = (sse, (f1 * span, f2 * span))

    def obj(x: np.ndarray) -> float:
        p1 = math.exp(x[0])
        p2 = p1 + math.exp(x[1])
        if p2 >= span:
            return 1e30
        return solve((p1, p2))[0]

    x0 = np.array([math.log(best[1][0]), math.log(best[1][1] - best[1][0])])
    opt = minimize(obj, x0, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-9, "maxiter": 400})
    p1 = math.exp(opt.x[0])
    p2 = p1 + math.exp(opt.x[1])
    sse, x = solve((p1, p2))
    return sse, p1, p2, x


def _centred_twist(T: np.ndarray, phi: np.ndarray, cmd: np.ndarray, t_max: float) -> np.ndarray:
    """The twist (rad) shifted so that the loop's centre line crosses T = 0 at zero twist.

    The encoders' zero is arbitrary: the centre is the mean of the descending and ascending
    zero crossings, where the odd-symmetric three-slope spring has its origin (an offset of a
    few % of phi1 moves the knots, T1, asymmetrically).
    """
    st0 = split_reversals(cmd)
    a0 = st0[1][0] if len(st0) > 1 else 0
    desc, asc = zero_crossing_twists(T[a0:], phi[a0:], cmd[a0:], 0.03 * t_max)
    return phi - 0.5 * (float(np.mean(desc)) + float(np.mean(asc)))


def _cubic_fit(ph: np.ndarray, Tm: np.ndarray, odd: np.ndarray, stops: np.ndarray) -> tuple[Any, np.ndarray]:
    """Cubic spring + the same odd band and stop grid (stop weights >= 0); returns (solution, residual N.m)."""
    Ac = np.column_stack([ph, ph ** 3, np.ones_like(ph), odd, stops])
    lo = np.r_[-np.inf, -np.inf, -np.inf, np.full(odd.shape[1], -np.inf), np.zeros(stops.shape[1])]
    solc = lsq_linear(Ac, Tm, bounds=(lo, np.full(Ac.shape[1], np.inf)), method="bvls")
    return solc, Tm - Ac @ solc.x


def fit_stiffness(data: ExperimentData, te: TEResult | None = None,
                  thresholds_rad: np.ndarray | None = None, max_elements: int = 8,
                  odd_fractions: tuple[float, ...] = ODD_FRACTIONS, odd_count: int = 16,
                  centre: bool = True) -> StiffnessResult:
    """Three-slope + Maxwell-slip, cubic, hysteresis loss and lost motion from ``locked_cycle`` data.

    Parameters
    ----------
    data : ExperimentData
        Segment 0: the +-T cycles; segment 1 (optional): the +-4 % rated cycles.
    te : TEResult, optional
        Kinematic error to remove from the motor-encoder twist.
    thresholds_rad : numpy.ndarray, optional
        Maxwell-slip threshold grid (rad of twist); default log-spaced
        2e-5 ... 1.5e-3 rad (16 values).
    max_elements : int
        Elements kept in the result (merged neighbours), the plant holds 8.
    odd_fractions : tuple of float
        Half-widths (fractions of the twist amplitude) tried for the direction-odd band
        (:func:`odd_hats`); the one with the smallest residual is kept.  Empty: no odd band
        (spring + Maxwell-slip only).
    odd_count : int
        Hat functions in the odd band.
    centre : bool
        Shift the twist so that the loop's centre line crosses T = 0 at zero twist (rad); the
        encoder zero is arbitrary.  False: the twist as measured (TE removed).
    """
    if data.kind != "locked_cycle":
        raise UserError(f"stiffness: expected locked_cycle data, found '{data.kind}'")
    N = data.gear_ratio
    seg0 = data.segment(0)
    T = seg0["load_torque_Nm"]
    cmd = seg0["torque_cmd_Nm"]
    phi = twist_of(seg0, N, te)
    t_max = float(np.max(np.abs(T)))
    loss = hysteresis_loss(T, phi, cmd, t_max)
    if centre:
        phi = _centred_twist(T, phi, cmd, t_max)
    lm = None
    if len(data.segments) > 1:
        s1 = data.segment(1)
        lm = lost_motion(s1["load_torque_Nm"], twist_of(s1, N, te), s1["torque_cmd_Nm"])
    # thin the samples for the fits (quasi-static: every 4th sample is plenty)
    k = max(1, len(phi) // 2500)
    st = split_reversals(cmd)
    start = st[1][0] if len(st) > 1 else 0
    # centre the twist: the encoder zero is arbitrary -> fitted constant; stops need the true path
    span = float(np.max(np.abs(phi[start:])))
    # elements must be able to slip on the cycle (threshold < half the twist amplitude), else they are
    # indistinguishable from the linear spring
    grid = thresholds_rad if thresholds_rad is not None else np.geomspace(2e-5, 0.45 * span, 14)
    stops = stop_operators(phi, grid)[start::k]
    ph, Tm = phi[start::k], T[start::k]
    nK = 4

    direction = branch_direction(cmd)[start::k]

    fits = []
    for fo in (odd_fractions or (0.0,)):
        odd = odd_hats(ph, direction, fo * span, odd_count) if fo > 0 else np.zeros((len(ph), 0))
        fits.append((_fit_knots(ph, Tm, stops, odd, span, nK), odd, fo))
    (sse, p1, p2, x), odd, odd_frac = min(fits, key=lambda f: f[0][0])
    k3 = x[0]
    k2 = k3 + x[2]
    k1 = k2 + x[1]
    t1 = k1 * p1
    t2 = t1 + k2 * (p2 - p1)
    x_odd = x[nK + len(grid):]
    x = x[:nK + len(grid)]
    mw = maxwell_from_weights(x[nK:], grid)
    if len(mw.k_Nm_per_rad) > max_elements:
        mw = mw.reduce(max_elements)
    resid = Tm - _design(ph, (p1, p2), stops) @ x - odd @ x_odd
    solc, rc = _cubic_fit(ph, Tm, odd, stops)
    r = StiffnessResult(k1_Nm_per_rad=float(k1), k2_Nm_per_rad=float(k2), k3_Nm_per_rad=float(k3), t1_Nm=float(t1),
                        t2_Nm=float(t2), cubic_k1_Nm_per_rad=float(solc.x[0]), cubic_k3_Nm_per_rad3=float(solc.x[1]),
                        hysteresis_loss_rad=loss, lost_motion_rad=lm, maxwell=mw,
                        residual_rms_Nm=float(np.sqrt(np.mean(resid ** 2))),
                        cubic_residual_rms_Nm=float(np.sqrt(np.mean(rc ** 2))), te_corrected=te is not None,
                        odd_band_rad=float(odd_frac * span))
    r.plot_data = {"phi_rad": ph, "T_Nm": Tm, "resid_Nm": resid, "offset_Nm": float(x[3]),
                   "cubic_resid_Nm": rc}
    return r
