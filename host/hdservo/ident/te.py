"""Transmission error: harmonic analysis in the wave-generator-angle domain.

Measured TE (harmonic-drive.md 3.1): ``y = theta_l - theta_m / N = e - phi``
with ``e`` the kinematic error and ``phi`` the twist, which is constant in a
steady constant-speed window apart from slow gravity/friction drifts.  Per
window the fit removes an offset and a linear + quadratic drift in the
motor angle (only the offset when the windows span a large part of an
output revolution); the WG orders ``n`` (cycles per motor = WG revolution) are
shared by all windows (both directions)::

    e(theta_m) = sum_n a_n sin(n theta_m + p_n)           (rad at the output)

the same form as the plant's ``transmission_error.wgK_*`` keys.  Orders per
output revolution are fitted too when a window spans enough of a turn
(:data:`OUT_SPAN_MIN_TURN`).  Amplitudes are divided by the gain with which the load follows
a kinematic error through the spring, ``1/(1 - (f/f_a)^2)``, when the
anti-resonance ``f_a`` is known (FRF); at the default 0.05 rad/s this is a
0.2 % correction on the reference axis.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence

import numpy as np

from ..errors import UserError
from .experiments import ExperimentData


#: Output-side line n is fitted when a window spans at least n times this part of a turn: over a fifth
#: of a turn a line per output revolution is told apart from the windows' offsets, a second order
#: beside it needs twice that (over a short span the low orders and the offset look alike).
OUT_SPAN_MIN_TURN = 0.2


@dataclass
class TEResult:
    """Identified kinematic transmission error.

    Attributes
    ----------
    wg_orders : list of int
        Orders per WG revolution.
    wg_amp_rad, wg_phase_rad : list of float
        Amplitude (rad, output side) and phase (rad) of ``a sin(n theta_m + p)``.
    out_orders, out_amp_rad, out_phase_rad : list
        The same per output revolution (empty when not identifiable).
    peak_to_peak_rad : float
        Peak-to-peak of the identified WG-order TE over one WG revolution.
    residual_rms_rad : float
        RMS of the fit residual, rad.
    """

    wg_orders: list[int]
    wg_amp_rad: list[float]
    wg_phase_rad: list[float]
    out_orders: list[int] = field(default_factory=list)
    out_amp_rad: list[float] = field(default_factory=list)
    out_phase_rad: list[float] = field(default_factory=list)
    peak_to_peak_rad: float = 0.0
    residual_rms_rad: float = 0.0
    samples: int = 0
    plot_data: dict[str, Any] = field(default_factory=dict, repr=False)

    def evaluate(self, theta_m: np.ndarray, theta_l: np.ndarray | None = None) -> np.ndarray:
        """Kinematic error e (rad, output) at motor angle ``theta_m`` (and output angle ``theta_l``)."""
        th = np.asarray(theta_m, dtype=float)
        e = np.zeros_like(th)
        for n, a, p in zip(self.wg_orders, self.wg_amp_rad, self.wg_phase_rad):
            e += a * np.sin(n * th + p)
        if theta_l is not None:
            tl = np.asarray(theta_l, dtype=float)
            for n, a, p in zip(self.out_orders, self.out_amp_rad, self.out_phase_rad):
                e += a * np.sin(n * tl + p)
        return e

    def line(self, order: int) -> tuple[float, float]:
        """(amplitude rad, phase rad) of one WG order."""
        i = self.wg_orders.index(order)
        return self.wg_amp_rad[i], self.wg_phase_rad[i]

    def to_dict(self) -> dict[str, Any]:
        return {"wg_orders": self.wg_orders, "wg_amp_rad": self.wg_amp_rad, "wg_phase_rad": self.wg_phase_rad,
                "out_orders": self.out_orders, "out_amp_rad": self.out_amp_rad, "out_phase_rad": self.out_phase_rad,
                "peak_to_peak_rad": self.peak_to_peak_rad, "residual_rms_rad": self.residual_rms_rad,
                "samples": self.samples}


def _steady_rows(data: ExperimentData,
                 twist_model: Optional[Callable[[int], np.ndarray]] = None) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray],
                                                list[np.ndarray], list[float]]:
    """Per segment past its ``settle_s`` (segments with fewer than 20 such samples left out): the
    kinematic error theta_L - theta_M / N (rad), theta_M, theta_L (rad), the segment index per
    sample and the output speed (rad/s, slope of theta_L)."""
    N = data.gear_ratio
    rows_y, rows_m, rows_l, seg_id = [], [], [], []
    speeds = []
    for seg in data.segments:
        c = data.segment(seg["index"])
        t = c["t_s"]
        m = t >= t[0] + float(seg.get("settle_s", 0.0))
        if m.sum() < 20:
            continue
        th_m, th_l = c["motor_angle_rad"][m], c["load_angle_rad"][m]
        rows_y.append(th_l - th_m / N + (twist_model(seg["index"])[m] if twist_model is not None else 0.0))
        rows_m.append(th_m)
        rows_l.append(th_l)
        seg_id.append(np.full(m.sum(), len(seg_id)))
        speeds.append(abs(np.polyfit(t[m], th_l, 1)[0]))
    return rows_y, rows_m, rows_l, seg_id, speeds


def _te_design(th_m: np.ndarray, th_l: np.ndarray, sid: np.ndarray, wg_orders: Sequence[int],
               out_orders: Sequence[int], n_drift: int = 3) -> tuple[np.ndarray, int]:
    """Regressors of the TE fit: a drift per segment (offset, linear, quadratic: the first ``n_drift``,
    in its normalised motor angle),
    then sin/cos of each WG order of theta_M and each output order of theta_L; returns (A, segments)."""
    cols = []
    nseg = int(sid.max()) + 1
    for s in range(nseg):
        msk = (sid == s).astype(float)
        x = (th_m - th_m[sid == s].mean()) / max(np.ptp(th_m[sid == s]), 1e-12)
        cols += [msk, msk * x, msk * x * x][:n_drift]
    for n in wg_orders:
        cols += [np.sin(n * th_m), np.cos(n * th_m)]
    for n in out_orders:
        cols += [np.sin(n * th_l), np.cos(n * th_l)]
    return np.column_stack(cols), nseg


def _harmonics(h: np.ndarray, count: int, offset: int) -> tuple[list[float], list[float]]:
    """Amplitude (rad) and phase (rad, sin reference) of ``count`` sin/cos pairs of ``h`` from ``offset``."""
    amp, ph = [], []
    for k in range(count):
        s_, c_ = h[offset + 2 * k], h[offset + 2 * k + 1]
        amp.append(math.hypot(s_, c_))
        ph.append(math.atan2(c_, s_))
    return amp, ph


def fit_te(data: ExperimentData, wg_orders: Sequence[int] = (1, 2, 3, 4, 6), out_orders: Sequence[int] = (1, 2),
           f_antiresonance_Hz: float | None = None,
           twist_model: Optional[Callable[[int], np.ndarray]] = None) -> TEResult:
    """Fit the TE harmonics from a slow constant-rotation experiment.

    Parameters
    ----------
    data : ExperimentData
        ``te_rotation`` data: ``motor_angle_rad``, ``load_angle_rad`` per segment
        with ``settle_s`` in each segment description.
    wg_orders, out_orders : sequence of int
        Candidate orders per WG / output revolution.
    f_antiresonance_Hz : float, optional
        Anti-resonance (Hz) for the spring-following correction.
    twist_model : callable, optional
        Predicted twist (rad) of every sample of segment ``index``, e.g. the hysteresis model
        at the unbalance the gear holds.  Over an output revolution the twist of the
        unbalance is itself a line per output revolution, which the fit would otherwise take
        for kinematic error; it is added back (``e = y + phi``) before the fit.

    Returns
    -------
    TEResult
    """
    if data.kind != "te_rotation":
        raise UserError(f"te: expected te_rotation data, found '{data.kind}'")
    N = data.gear_ratio
    rows_y, rows_m, rows_l, seg_id, speeds = _steady_rows(data, twist_model)
    if not rows_y:
        raise UserError("te: no steady-state samples (segments too short)")
    y = np.concatenate(rows_y)
    th_m = np.concatenate(rows_m)
    th_l = np.concatenate(rows_l)
    sid = np.concatenate(seg_id)
    span_l = max(float(np.ptp(r)) for r in rows_l)
    use_out = [n for n in out_orders if span_l >= n * OUT_SPAN_MIN_TURN * 2 * math.pi]
    # per window an offset and a linear + quadratic drift; over a whole output revolution only the
    # offset (a drift polynomial there would take part of the output-side lines; the unbalance's
    # twist, the drift it stood for, is then a line itself: see twist_model)
    n_drift = 1 if use_out else 3
    A, nseg = _te_design(th_m, th_l, sid, wg_orders, use_out, n_drift)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    res = y - A @ coef
    h = coef[n_drift * nseg:]
    v = float(np.mean(speeds))
    gains = [1.0 / abs(1.0 - (n * N * v / (2 * math.pi) / f_antiresonance_Hz) ** 2) if f_antiresonance_Hz else 1.0
             for n in wg_orders]
    wg_amp, wg_ph = _harmonics(h, len(wg_orders), 0)
    wg_amp = [a_ / g_ for a_, g_ in zip(wg_amp, gains)]
    out_amp, out_ph = _harmonics(h, len(use_out), 2 * len(wg_orders))
    r = TEResult(wg_orders=list(wg_orders), wg_amp_rad=wg_amp, wg_phase_rad=wg_ph, out_orders=use_out,
                 out_amp_rad=out_amp, out_phase_rad=out_ph, residual_rms_rad=float(np.sqrt(np.mean(res ** 2))),
                 samples=int(len(y)))
    g = np.linspace(0, 2 * math.pi, 721)
    r.peak_to_peak_rad = float(np.ptp(r.evaluate(g)))
    # angle-domain plot data: TE minus the drift terms, vs WG angle mod 2 pi
    drift = A[:, :n_drift * nseg] @ coef[:n_drift * nseg]
    r.plot_data = {"wg_angle_rad": np.mod(th_m, 2 * math.pi), "te_rad": y - drift, "residual_rad": res}
    return r
