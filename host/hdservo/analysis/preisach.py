"""A small double-precision Preisach hysteresis model (harmonic-drive.md 6.3, 6.4).

The model is defined by its Everett function ``E(alpha, beta)`` on the
Preisach plane ``-u_max <= beta <= alpha <= u_max``; the output follows from
the online recursive algorithm (stacks of alternating dominant extrema with
wiping-out)::

    ascending from the latest minimum m (output y_m):   y = y_m + 2 E(u, m)
    descending from the latest maximum M (output y_M):  y = y_M - 2 E(M, u)

starting at negative saturation ``y = -E(u_max, -u_max)``.  The Everett
function can be any callable, or an :class:`EverettTable` (values on a grid of
``L + 1`` input levels, bilinear interpolation), e.g. built from a Preisach
density with :func:`everett_table_from_density`.
"""
from __future__ import annotations

import math
from typing import Callable, List, Tuple

import numpy as np

Everett = Callable[[float, float], float]


class EverettTable:
    """Everett function tabulated on a regular grid, bilinear interpolation.

    Parameters
    ----------
    table : numpy.ndarray
        ``(L+1, L+1)`` array, ``table[a, b] = E(u_a, u_b)`` with
        ``u_i = -u_max + i * 2 u_max / L`` (output units); entries with
        ``b >= a`` must be 0.
    u_max : float
        Input range half-width (input units, > 0).

    Notes
    -----
    Off the diagonal the interpolation is bilinear; in a diagonal cell
    ``E = E(u_{i+1}, u_i) (f_a - f_b)`` so that E is continuous and vanishes
    on ``alpha = beta``.
    """

    def __init__(self, table: np.ndarray, u_max: float) -> None:
        t = np.asarray(table, dtype=float)
        if t.ndim != 2 or t.shape[0] != t.shape[1] or t.shape[0] < 2:
            raise ValueError("Everett table must be a square (L+1)x(L+1) array, L >= 1")
        if u_max <= 0:
            raise ValueError("u_max must be > 0")
        self.table = np.tril(t, -1)
        self.u_max = float(u_max)
        self.levels = t.shape[0] - 1
        self.du = 2.0 * self.u_max / self.levels

    def __call__(self, alpha: float, beta: float) -> float:
        if alpha <= beta:
            return 0.0
        L = self.levels
        xa = min(max((alpha + self.u_max) / self.du, 0.0), float(L))
        xb = min(max((beta + self.u_max) / self.du, 0.0), float(L))
        ia, ib = min(int(xa), L - 1), min(int(xb), L - 1)
        fa, fb = xa - ia, xb - ib
        t = self.table
        if ia < ib:
            return 0.0
        if ia == ib:  # diagonal cell: linear in alpha - beta, continuous with the neighbours
            return float(t[ia + 1, ia] * (fa - fb)) if fa > fb else 0.0
        return float((1 - fa) * (1 - fb) * t[ia, ib] + fa * (1 - fb) * t[ia + 1, ib]
                     + (1 - fa) * fb * t[ia, ib + 1] + fa * fb * t[ia + 1, ib + 1])


def everett_table_from_density(density: Callable[[np.ndarray, np.ndarray], np.ndarray],
                               u_max: float, levels: int, y_sat: float | None = None,
                               sub: int = 4) -> EverettTable:
    """Integrate a Preisach density into an Everett table.

    Parameters
    ----------
    density : callable
        ``mu(alpha, beta)`` (vectorised, output units per input unit^2), >= 0.
    u_max : float
        Input range half-width (input units).
    levels : int
        Number of grid intervals L (table is (L+1)x(L+1)).
    y_sat : float, optional
        If given, scale so that the output at saturation, ``E(u_max, -u_max)``,
        equals this value (output units).
    sub : int
        Midpoint sub-samples per cell and axis for the integration.

    Returns
    -------
    EverettTable
    """
    L = int(levels)
    du = 2.0 * u_max / L
    # Cell masses: mass[i, j] = integral over alpha in cell i, beta in cell j, beta <= alpha.
    h = du / sub
    off = (np.arange(sub) + 0.5) * h
    mass = np.zeros((L, L))
    u = -u_max + du * np.arange(L)
    oa, ob = np.meshgrid(off, off, indexing="ij")
    for i in range(L):
        for j in range(i + 1):
            a = u[i] + oa
            b = u[j] + ob
            mu = density(a, b) * (b <= a)
            mass[i, j] = float(mu.sum()) * h * h
    # E(u_a, u_b) = sum of cell masses with b <= j <= i < a.
    E = np.zeros((L + 1, L + 1))
    for bb in range(L):
        col = np.cumsum(mass[bb:, bb:].sum(axis=1))  # rows i = bb..L-1, all j in bb..i
        E[bb + 1:, bb] = col
    if y_sat is not None and E[L, 0] > 0:
        E *= y_sat / E[L, 0]
    return EverettTable(E, u_max)


def everett_table_plant(u_max: float, t_sat: float, r0: float, s: float, levels: int = 32) -> EverettTable:
    """The Everett table exactly as the simulated plant builds it (sim/plant/hd_plant_preisach.c).

    Density :func:`preisach_exponential_gaussian_density`; cell masses by the
    midpoint rule, a diagonal cell (half a cell) by its centroid
    ``(u_a + 2 du/3, u_a + du/3)`` times ``du^2/2``; scaled so that
    ``E(u_max, -u_max) = t_sat``.

    Parameters
    ----------
    u_max : float
        Input range half-width (rad, > 0).
    t_sat : float
        Output at saturation (N m, >= 0).
    r0, s : float
        Density parameters (rad, > 0).
    levels : int
        Grid intervals L (the plant uses 32).

    Returns
    -------
    EverettTable
    """
    L = int(levels)
    du = 2.0 * u_max / L
    mu = preisach_exponential_gaussian_density(r0, s)
    u = -u_max + du * np.arange(L)
    E = np.zeros((L + 1, L + 1))
    for j in range(L):
        acc = 0.0
        for a in range(j, L):
            ub = u[j:a]
            row = float(np.sum(mu(np.full(ub.shape, u[a] + 0.5 * du), ub + 0.5 * du))) * du * du
            row += float(mu(np.array(u[a] + 2.0 * du / 3.0), np.array(u[a] + du / 3.0))) * 0.5 * du * du
            acc += row
            E[a + 1, j] = acc
    if E[L, 0] > 0:
        E *= t_sat / E[L, 0]
    return EverettTable(E, u_max)


class PreisachModel:
    """Classical Preisach operator evaluated with the recursive stack algorithm.

    Parameters
    ----------
    everett : callable
        ``E(alpha, beta)`` (output units), 0 for ``alpha <= beta``.
    u_max : float
        Input clamp (input units, > 0); also the saturation level of the plane.
    """

    def __init__(self, everett: Everett, u_max: float) -> None:
        if u_max <= 0:
            raise ValueError("u_max must be > 0")
        self.everett = everett
        self.u_max = float(u_max)
        self.y_sat = float(everett(self.u_max, -self.u_max))
        self.reset()

    def mean(self, u: float) -> float:
        """Centre line of the major loop, ``P_mean(u) = E(u, -u_max) - E(u_max, u)`` (output units).

        The mean of the ascending and descending major branches (input clamped
        to +-u_max); single-valued.
        """
        u = min(max(float(u), -self.u_max), self.u_max)
        return float(self.everett(u, -self.u_max) - self.everett(self.u_max, u))

    def demagnetise(self, cycles: int = 24) -> None:
        """The simulated plant's initial state: from negative saturation, a decaying
        alternating sequence ``+a_k, -a_k (1 - 0.5/cycles)``, ``a_k = u_max (cycles - k)/cycles``."""
        self.reset()
        for k in range(cycles):
            a = self.u_max * (cycles - k) / cycles
            self(a)
            self(-a * (1.0 - 0.5 / cycles))

    def reset(self) -> None:
        """Negative saturation: every relay at -1, output ``-E(u_max, -u_max)``."""
        self.mins: List[Tuple[float, float]] = [(-self.u_max, -self.y_sat)]
        self.maxs: List[Tuple[float, float]] = [(math.inf, math.nan)]
        self.direction = 1
        self.u_prev = -self.u_max
        self.y = -self.y_sat

    def __call__(self, u: float) -> float:
        """Advance to input ``u`` (input units) and return the output (output units)."""
        u = min(max(float(u), -self.u_max), self.u_max)
        if u == self.u_prev:
            return self.y
        d = 1 if u > self.u_prev else -1
        if d != self.direction:
            (self.maxs if d < 0 else self.mins).append((self.u_prev, self.y))
            self.direction = d
        E = self.everett
        if d > 0:
            while u >= self.maxs[-1][0]:
                self.maxs.pop()
                self.mins.pop()
            m, ym = self.mins[-1]
            self.y = ym + 2.0 * E(u, m)
        else:
            while len(self.mins) > 1 and u <= self.mins[-1][0]:
                self.mins.pop()
                self.maxs.pop()
            M, yM = self.maxs[-1]
            self.y = yM - 2.0 * E(M, u)
        self.u_prev = u
        return self.y


def preisach_exponential_gaussian_density(r0: float, s: float) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Density ``exp(-r/r0) exp(-m^2/(2 s^2))``, r = (alpha-beta)/2, m = (alpha+beta)/2.

    The form used by the simulated plant's ``[hysteresis_preisach]`` section
    (unnormalised; scale with ``y_sat``).

    Parameters
    ----------
    r0 : float
        Relay half-width scale (input units, > 0).
    s : float
        Relay centre spread (input units, > 0).
    """
    def mu(alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
        r = 0.5 * (alpha - beta)
        m = 0.5 * (alpha + beta)
        return np.exp(-r / r0) * np.exp(-m * m / (2.0 * s * s))
    return mu
