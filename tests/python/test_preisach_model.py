"""The Preisach model's one home (hdservo.preisach): integration, cell map, interpolation, operator."""
from __future__ import annotations

import numpy as np
import pytest

from hdservo.ident.hysteresis import Everett
from hdservo.preisach import (EverettTable, PreisachModel, cell_masses, cell_sum_matrix, cells_of, everett_at,
                              everett_from_density, everett_from_masses)


def test_everett_of_a_uniform_density_is_the_triangle_area() -> None:
    """mu = 1: E(a, b) = (a - b)^2 / 2, the area of the triangle b <= y <= x <= a; the midpoint
    rule counts the samples on a diagonal cell's diagonal whole, 1/n_sub of the half cell too much."""
    u = np.array([-1.0, -0.4, 0.1, 0.3, 1.0])            # uneven grid
    n_sub = 100
    e = everett_from_density(lambda a, b: np.ones_like(a), u, n_sub=n_sub)
    for i in range(len(u)):
        for j in range(i):
            exact = 0.5 * (u[i] - u[j]) ** 2
            assert exact <= e[i, j] <= exact * (1.0 + 1.0 / n_sub) + 1e-15
        assert e[i, i] == 0.0


def test_everett_from_masses_sums_the_cells_in_order() -> None:
    """Each entry is the sequential sum over cells_of, bit for bit, and the fitting matrix agrees."""
    rng = np.random.default_rng(5)
    L = 9
    cell = np.tril(rng.uniform(0.0, 1.0, (L, L)), -1)
    e = everett_from_masses(cell)
    A, cells, pts = cell_sum_matrix(L)
    masses = np.array([cell[c] for c in cells])
    for r, (i, j) in enumerate(pts):
        s = 0.0
        for c in cells_of(i, j):
            s += cell[c]
        assert e[i, j] == s
        assert A[r] @ masses == pytest.approx(s, rel=1e-12)
    assert np.all(np.triu(e) == 0.0)


def test_cell_masses_of_a_diagonal_cell_count_half() -> None:
    u = np.array([0.0, 1.0])
    m = cell_masses(lambda a, b: np.ones_like(a), u, n_sub=20)
    assert m[1, 0] == pytest.approx(0.5, rel=0.06)


def test_one_interpolation_for_both_table_kinds() -> None:
    """The describing-function table (symmetric, L+1 levels) and the identified table (u0, step)
    interpolate the same grid the same way."""
    rng = np.random.default_rng(7)
    L = 8
    t = np.tril(np.cumsum(rng.uniform(0, 1, (L + 1, L + 1)), axis=0), -1)
    tab = EverettTable(t, 2.0)
    ev = Everett(u0_Nm=-2.0, step_Nm=0.5, table=t)
    for a, b in rng.uniform(-2.5, 2.5, (300, 2)):
        assert tab(a, b) == ev(a, b) == everett_at(t, -2.0, 0.5, a, b)
    # at the grid levels the interpolation returns the table
    assert tab(1.5, -1.0) == pytest.approx(t[7, 2], rel=1e-12)
    assert tab(0.3, 0.3) == 0.0


def test_asymmetric_range_operator_saturates_and_wipes_out() -> None:
    """u_min != -u_max: starts at -E(u_max, u_min), reaches +E(u_max, u_min) at the top, and
    a closed minor loop returns to the output it started from (wiping-out)."""
    E = lambda a, b: 0.5 * (a - b) ** 2 if a > b else 0.0     # noqa: E731
    m = PreisachModel(E, 3.0, u_min=-1.0)
    assert m.y == -8.0
    ys = m.run([0.0, 1.0, 0.2, 1.0, 3.5])
    assert ys[-1] == pytest.approx(8.0)
    assert ys[1] == pytest.approx(ys[3])       # back at 1.0 after the 1.0 -> 0.2 -> 1.0 loop
    with pytest.raises(ValueError):
        PreisachModel(E, 1.0, u_min=1.0)
