"""The Preisach hysteresis model in double precision: density, Everett function, operator.

This module is the one home of the Everett integration and of the recursive
Preisach operator; the firmware image of a quantised table lives in
:mod:`hdservo.preisach_table`, the identification from reversal curves in
:mod:`hdservo.ident.hysteresis` and the describing functions in
:mod:`hdservo.analysis.hysteresis`, all built on the pieces here.

The model is defined by its Everett function ``E(alpha, beta)`` on the
Preisach plane ``u_min <= beta <= alpha <= u_max``.  For a density
``mu(alpha, beta) >= 0``::

    E(alpha, beta) = integral of mu over {beta <= b <= a <= alpha}

On a grid ``u_0 < u_1 < ... < u_{L-1}`` the plane splits into cells; cell
``(i, j)`` (``i > j``) holds ``alpha`` in ``[u_{i-1}, u_i]`` and ``beta`` in
``[u_j, u_{j+1}]`` (the diagonal cells ``i - 1 == j`` only their half with
``beta <= alpha``), and ``E(u_i, u_j)`` is the sum of the masses of the cells
``(ia, jb)`` with ``j <= jb < ia <= i`` (:func:`cells_of`).

Between grid levels the Everett function is interpolated as the firmware does
(bilinear; in a diagonal cell linear in ``alpha - beta``, so that E vanishes on
``alpha = beta``; :func:`everett_at`).  The output follows from the online
recursive algorithm (stacks of alternating dominant extrema with
wiping-out; :class:`PreisachModel`)::

    ascending from the latest minimum m (output y_m):   y = y_m + 2 E(u, m)
    descending from the latest maximum M (output y_M):  y = y_M - 2 E(M, u)

starting at negative saturation ``y = -E(u_max, u_min)``.
"""
from __future__ import annotations

import math
from typing import Callable, Iterator, List, Tuple

import numpy as np

#: An Everett function ``E(alpha, beta)`` (output units), 0 for ``alpha <= beta``.
Everett = Callable[[float, float], float]
#: A Preisach density ``mu(alpha, beta)`` (vectorised; output units per input unit squared).
Density = Callable[[np.ndarray, np.ndarray], np.ndarray]


# ----------------------------------------------------------------- densities


def preisach_exponential_gaussian_density(r0: float, s: float) -> Density:
    """Density ``exp(-r/r0) exp(-m^2/(2 s^2))``, r = (alpha-beta)/2, m = (alpha+beta)/2.

    The form of the simulated plant's ``[hysteresis_preisach]`` section
    (unnormalised; scale the Everett function to the saturation output).

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


# ----------------------------------------------------------------- Everett integration


def cells_of(i: int, j: int) -> Iterator[Tuple[int, int]]:
    """The cells ``(ia, jb)`` whose masses sum to ``E(u_i, u_j)``: ``j <= jb < ia <= i``.

    The order (``ia`` ascending, then ``jb`` ascending) is the summation order
    of :func:`everett_from_masses`.
    """
    for ia in range(j + 1, i + 1):
        for jb in range(j, ia):
            yield ia, jb


def cell_masses(mu: Density, u_grid: np.ndarray, n_sub: int = 16) -> np.ndarray:
    """Masses of the grid cells of the Preisach plane, midpoint rule.

    Parameters
    ----------
    mu : callable
        Preisach density ``mu(alpha, beta) >= 0`` (output units per input unit squared).
    u_grid : numpy.ndarray
        The L increasing grid levels (input units).
    n_sub : int
        Midpoint-rule sub-samples per cell and axis; a diagonal cell counts only
        its sub-samples with ``beta <= alpha``.

    Returns
    -------
    numpy.ndarray
        L x L array, ``[i, j]`` (``i > j``) the mass of alpha in
        ``[u_{i-1}, u_i]``, beta in ``[u_j, u_{j+1}]`` (output units); 0 elsewhere.
    """
    u = np.asarray(u_grid, dtype=float)
    levels = len(u)
    cell = np.zeros((levels, levels))
    for i in range(1, levels):
        for j in range(i):
            a = u[i - 1] + (np.arange(n_sub) + 0.5) / n_sub * (u[i] - u[i - 1])
            b = u[j] + (np.arange(n_sub) + 0.5) / n_sub * (u[j + 1] - u[j])
            aa, bb = np.meshgrid(a, b, indexing="ij")
            w = (aa >= bb).astype(float) if i - 1 == j else 1.0
            cell[i, j] = np.sum(mu(aa, bb) * w) * (u[i] - u[i - 1]) * (u[j + 1] - u[j]) / n_sub**2
    return cell


def everett_from_masses(cell: np.ndarray) -> np.ndarray:
    """Everett grid from cell masses: ``E[i, j]`` = sum over :func:`cells_of` ``(i, j)``.

    Parameters
    ----------
    cell : numpy.ndarray
        L x L cell masses (:func:`cell_masses`, output units).

    Returns
    -------
    numpy.ndarray
        L x L array, lower triangle filled (output units), zero diagonal.
    """
    levels = cell.shape[0]
    e = np.zeros((levels, levels))
    for j in range(levels - 1):
        # one running sum down column j, in the order of cells_of: E[i, j] = E[i-1, j] + row i
        terms = [cell[ia, jb] for ia, jb in cells_of(levels - 1, j)]
        run = np.cumsum(terms)
        ends = np.cumsum(np.arange(1, levels - j)) - 1        # last term of rows ia = j+1 .. L-1
        e[j + 1:, j] = run[ends]
    return e


def everett_from_density(mu: Density, u_grid: np.ndarray, n_sub: int = 16) -> np.ndarray:
    """Everett grid ``E(alpha_i, beta_j)`` = integral of mu over ``{beta_j <= b <= a <= alpha_i}``.

    Parameters
    ----------
    mu : callable
        Preisach density ``mu(alpha, beta) >= 0`` (output units per input unit squared).
    u_grid : numpy.ndarray
        The L increasing input grid levels (input units).
    n_sub : int
        Midpoint-rule sub-samples per grid cell and axis.

    Returns
    -------
    numpy.ndarray
        L x L array (lower triangle filled, output units).
    """
    return everett_from_masses(cell_masses(mu, u_grid, n_sub))


def cell_sum_matrix(levels: int) -> tuple[np.ndarray, list[tuple[int, int]], list[tuple[int, int]]]:
    """The linear map from cell masses to Everett grid values (for fitting a density).

    Parameters
    ----------
    levels : int
        Grid levels L.

    Returns
    -------
    A, cells, points
        ``A`` is a 0/1 matrix with ``E[points[r]] = A[r] @ masses`` where
        ``masses[c]`` is the mass of ``cells[c]``; ``cells`` and ``points`` list
        ``(i, j)``, ``i > j``, row by row.
    """
    cells = [(ia, jb) for ia in range(1, levels) for jb in range(ia)]
    pts = [(i, j) for i in range(1, levels) for j in range(i)]
    A = np.zeros((len(pts), len(cells)))
    ci = {c: n for n, c in enumerate(cells)}
    for r, (i, j) in enumerate(pts):
        for c in cells_of(i, j):
            A[r, ci[c]] = 1.0
    return A, cells, pts


def everett_table_plant(u_max: float, t_sat: float, r0: float, s: float, levels: int = 32) -> "EverettTable":
    """The Everett table exactly as the simulated plant builds it (sim/plant/hd_plant_preisach.c).

    Density :func:`preisach_exponential_gaussian_density`; cell masses by the
    midpoint rule with one sample, a diagonal cell (half a cell) by its centroid
    ``(u_a + 2 du/3, u_a + du/3)`` times ``du^2/2``; scaled so that
    ``E(u_max, -u_max) = t_sat``.  The summation follows the C code line by
    line, so the table is the plant's to the last bit.

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


# ----------------------------------------------------------------- interpolation


def everett_at(table: np.ndarray, u0: float, step: float, alpha: float, beta: float) -> float:
    """Everett function between the levels of a uniform grid, the firmware's interpolation.

    Parameters
    ----------
    table : numpy.ndarray
        L x L, ``table[i, j] = E(u0 + i step, u0 + j step)`` for ``j < i``, zero
        diagonal (output units).
    u0, step : float
        First grid level and spacing (input units, ``step > 0``).
    alpha, beta : float
        Where to evaluate (input units); clamped to the grid.

    Returns
    -------
    float
        Bilinear off the diagonal; in a diagonal cell ``E(u_{i+1}, u_i) (f_a - f_b)``,
        so E is continuous and vanishes on ``alpha = beta`` (output units).
    """
    if alpha <= beta:
        return 0.0
    top = table.shape[0] - 1
    xa = min(max((alpha - u0) / step, 0.0), float(top))
    xb = min(max((beta - u0) / step, 0.0), float(top))
    ia, ib = min(int(xa), top - 1), min(int(xb), top - 1)
    fa, fb = xa - ia, xb - ib
    t = table
    if ia < ib:
        return 0.0
    if ia == ib:
        return float(t[ia + 1, ia] * (fa - fb)) if fa > fb else 0.0
    return float((1 - fa) * (1 - fb) * t[ia, ib] + fa * (1 - fb) * t[ia + 1, ib]
                 + (1 - fa) * fb * t[ia, ib + 1] + fa * fb * t[ia + 1, ib + 1])


class EverettTable:
    """Everett function tabulated on a regular grid over ``[-u_max, u_max]``, firmware interpolation.

    Parameters
    ----------
    table : numpy.ndarray
        ``(L+1, L+1)`` array, ``table[a, b] = E(u_a, u_b)`` with
        ``u_i = -u_max + i * 2 u_max / L`` (output units); entries with
        ``b >= a`` are ignored (taken as 0).
    u_max : float
        Input range half-width (input units, > 0).
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
        return everett_at(self.table, -self.u_max, self.du, alpha, beta)


def everett_table_from_density(density: Density, u_max: float, levels: int, y_sat: float | None = None,
                               sub: int = 4) -> EverettTable:
    """Integrate a Preisach density into an :class:`EverettTable` (:func:`everett_from_density`).

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
    u = -u_max + (2.0 * u_max / L) * np.arange(L + 1)
    E = everett_from_density(density, u, n_sub=sub)
    if y_sat is not None and E[L, 0] > 0:
        E *= y_sat / E[L, 0]
    return EverettTable(E, u_max)


# ----------------------------------------------------------------- the operator


class PreisachModel:
    """Classical Preisach operator evaluated with the recursive stack algorithm.

    Parameters
    ----------
    everett : callable
        ``E(alpha, beta)`` (output units), 0 for ``alpha <= beta``.
    u_max : float
        Upper input clamp (input units); also the saturation level of the plane.
    u_min : float, optional
        Lower input clamp (input units, < u_max); default ``-u_max``.
    y_sat : float, optional
        Output at positive saturation, ``E(u_max, u_min)`` (output units); default
        evaluates ``everett`` there (give it when the table corner is known exactly).
    """

    def __init__(self, everett: Everett, u_max: float, u_min: float | None = None,
                 y_sat: float | None = None) -> None:
        if u_min is None:
            if u_max <= 0:
                raise ValueError("u_max must be > 0")
            lo = -float(u_max)
        else:
            lo = float(u_min)
            if not u_max > lo:
                raise ValueError(f"u_max ({u_max}) must be > u_min ({u_min})")
        self.everett = everett
        self.u_max = float(u_max)
        self.u_min = lo
        self.y_sat = float(everett(self.u_max, self.u_min)) if y_sat is None else float(y_sat)
        self.reset()

    def mean(self, u: float) -> float:
        """Centre line of the major loop, ``P_mean(u) = E(u, u_min) - E(u_max, u)`` (output units).

        The mean of the ascending and descending major branches (input clamped
        to ``[u_min, u_max]``); single-valued.
        """
        u = min(max(float(u), self.u_min), self.u_max)
        return float(self.everett(u, self.u_min) - self.everett(self.u_max, u))

    def demagnetise(self, cycles: int = 24) -> None:
        """The simulated plant's initial state: from negative saturation, a decaying
        alternating sequence ``+a_k, -a_k (1 - 0.5/cycles)``, ``a_k = u_max (cycles - k)/cycles``."""
        self.reset()
        for k in range(cycles):
            a = self.u_max * (cycles - k) / cycles
            self(a)
            self(-a * (1.0 - 0.5 / cycles))

    def reset(self) -> None:
        """Negative saturation: every relay at -1, output ``-E(u_max, u_min)``."""
        self.mins: List[Tuple[float, float]] = [(self.u_min, -self.y_sat)]
        self.maxs: List[Tuple[float, float]] = [(math.inf, math.nan)]
        self.direction = 1
        self.u_prev = self.u_min
        self.y = -self.y_sat

    def __call__(self, u: float) -> float:
        """Advance to input ``u`` (input units) and return the output (output units)."""
        u = min(max(float(u), self.u_min), self.u_max)
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

    def run(self, u: "np.ndarray | list[float]") -> np.ndarray:
        """Outputs for an input sequence from the present state (output units)."""
        return np.array([self(x) for x in u], dtype=float)


__all__ = ["Density", "Everett", "EverettTable", "PreisachModel", "cell_masses", "cell_sum_matrix", "cells_of",
           "everett_at", "everett_from_density", "everett_from_masses", "everett_table_from_density",
           "everett_table_plant", "preisach_exponential_gaussian_density"]
