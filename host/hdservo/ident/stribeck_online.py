"""Fast online Stribeck identification: RLS on the model made linear by a grid over vs.

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
in float, i.e. a 20 Hz sample rate costs 0.05 % of the CPU; the firmware
rules ask for fixed point (P needs ~40 bits of dynamic range: int64
accumulators, Q-scaled columns), or the drive streams the block means and
the host runs this.  Measured convergence is in docs/identification.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

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
