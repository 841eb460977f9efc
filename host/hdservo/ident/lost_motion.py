"""Lost motion at reversals: Maxwell-slip elements on the output travel, from the twist.

After a reversal the output-side friction and the gear's presliding turn the transmitted
torque over within a small output travel, and the gear twists by that torque change: a
motor-encoder loop sees the output lag behind the wave generator.  The Maxwell-slip
compensator of the drive (``mx_*``, docs/compensators.md section 3) predicts this twist from
the output position reference with stop elements; here they are identified from the twist
measured directly, not from a friction model: with the small position sine of
:class:`.experiments.LostMotionSine`,

    twist(t) = motor / N - output + TE(motor)  ~=  c0 + sum_j g_j S_j(x(t)),

where ``S_j`` is the unit stop operator of threshold ``d_j`` on the output angle x (the same
``clamp(s + dx, -d, d)`` the firmware runs) and ``g_j >= 0`` its twist gain (rad of twist per
rad of travel).  The thresholds lie on a geometric grid from 1/4096 of the amplitude up to its half; the gains come
from non-negative least squares (the offset c0 of either sign is free), the first quarter
period is left out (the elements start relaxed), and at most ``max_elements`` are kept (merged
neighbours, :meth:`.hysteresis.MaxwellSlip.reduce`).

Model keys (``[lost_motion]``): ``n_elements``, ``eK_gain`` (rad/rad), ``eK_d_rad``;
``hdservo download`` turns them into ``mx_kK = gain x mx_stiffness`` and ``mx_dK = d``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import nnls

from ..errors import UserError
from .experiments import ExperimentData
from .hysteresis import MaxwellSlip, stop_operators
from .stiffness import twist_of
from .te import TEResult

#: Thresholds of the grid (geometric from amplitude / 4096 to amplitude / 2, a factor 1.39 apart).
GRID_POINTS = 24
#: Elements whose gain is below this fraction of the largest are dropped.
REL_TOL = 1e-3


@dataclass
class LostMotionResult:
    """Identified lost-motion elements (output-referred).

    Attributes
    ----------
    gain : list of float
        Twist per output travel of each element, rad/rad (>= 0).
    d_rad : list of float
        Element thresholds (half the travel it takes to turn over), output rad.
    lost_motion_rad : float
        Twist change across a full reversal, ``2 sum gain_j d_j``, rad.
    rms_residual_rad : float
        RMS of the fit residual over the fitted samples, rad.
    amplitude_rad : float
        Output travel amplitude of the experiment (half peak to peak), rad.
    """

    gain: list[float]
    d_rad: list[float]
    lost_motion_rad: float
    rms_residual_rad: float
    amplitude_rad: float

    def to_dict(self) -> dict[str, Any]:
        return {"n_elements": len(self.gain), "gain": self.gain, "d_rad": self.d_rad,
                "lost_motion_rad": self.lost_motion_rad, "lost_motion_arcsec": self.lost_motion_rad * 180 / math.pi * 3600,
                "rms_residual_rad": self.rms_residual_rad, "amplitude_rad": self.amplitude_rad}

    def predict(self, x_rad: np.ndarray) -> np.ndarray:
        """Twist (rad, offset-free) the elements predict along the output travel ``x_rad``."""
        if not self.gain:
            return np.zeros(len(x_rad))
        return stop_operators(np.asarray(x_rad, dtype=float), np.array(self.d_rad)) @ np.array(self.gain)


def fit_lost_motion(data: ExperimentData, te: TEResult | None = None, max_elements: int = 8) -> LostMotionResult:
    """Maxwell-slip lost-motion elements from a ``lost_motion`` experiment.

    Parameters
    ----------
    data : ExperimentData
        ``lost_motion`` data (``motor_angle_rad``, ``load_angle_rad``; one or more segments).
    te : TEResult, optional
        Identified transmission error, removed from the twist.
    max_elements : int
        Most elements kept (the drive holds 8).

    Returns
    -------
    LostMotionResult

    Raises
    ------
    UserError
        Wrong data kind, or fewer than two reversals of the output.
    """
    if data.kind != "lost_motion":
        raise UserError(f"lost motion: expected lost_motion data, found '{data.kind}'")
    n = data.gear_ratio
    rows_a: list[np.ndarray] = []
    rows_b: list[np.ndarray] = []
    amp = 0.0
    thr: np.ndarray | None = None
    segs = [int(s["index"]) for s in data.segments] or [0]
    for i in segs:
        seg = data.segment(i)
        x = np.asarray(seg["load_angle_rad"], dtype=float)
        if len(x) < 16:
            continue
        a = 0.5 * float(np.ptp(x))
        if thr is None:
            amp = a
            thr = a * np.geomspace(1.0 / 4096.0, 0.5, GRID_POINTS)
        phi = twist_of(seg, n, te)
        S = stop_operators(x, thr)
        # leave out the first quarter period: the elements start relaxed (the travel to the first
        # reversal saturates them); a quarter period = up to the first extreme of x
        k0 = int(np.argmax(np.abs(x - x[0])))
        keep = slice(k0, None)
        ones = np.ones((len(x), 1))
        rows_a.append(np.hstack([S, ones, -ones])[keep])
        rows_b.append(phi[keep])
    if thr is None or not rows_a:
        raise UserError("lost motion: no segment with data")
    A, b = np.vstack(rows_a), np.concatenate(rows_b)
    # reversals of the travel in the fitted part: at least two (one loop) to see the hysteresis
    xs = np.concatenate([np.asarray(data.segment(i)["load_angle_rad"], dtype=float) for i in segs])
    dx = np.diff(xs[np.abs(np.diff(xs, prepend=xs[0])) > 0.0])
    if int(np.sum(np.diff(np.sign(dx[np.abs(dx) > 0])) != 0)) < 2:
        raise UserError("lost motion: fewer than 2 reversals of the output in the data")
    sc = np.maximum(np.abs(A).max(axis=0), 1e-300)
    z, _ = nnls(A / sc, b, maxiter=50 * A.shape[1])
    z = z / sc
    g = z[:len(thr)]
    resid = b - A @ z
    keep_el = g > REL_TOL * max(float(np.max(g)), 1e-300)
    mw = MaxwellSlip([float(v) for v in g[keep_el]], [float(v * d) for v, d in zip(g[keep_el], thr[keep_el])])
    if len(mw.k_Nm_per_rad) > max_elements:
        mw = mw.reduce(max_elements)
    gain, d = list(mw.k_Nm_per_rad), list(mw.thresholds_rad)
    return LostMotionResult(gain=gain, d_rad=d, lost_motion_rad=2.0 * float(sum(a * b for a, b in zip(gain, d))),
                            rms_residual_rad=float(np.sqrt(np.mean(resid ** 2))), amplitude_rad=amp)
