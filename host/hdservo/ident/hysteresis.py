"""Torsional hysteresis: Maxwell-slip (stop operators, NNLS) and Preisach (Everett from FORCs).

Maxwell-slip (harmonic-drive.md 4.3, 6.2): element j is a stop operator of
threshold Delta_j (rad of twist) and stiffness k_j (N.m/rad); its force
saturates at w_j = k_j Delta_j.  With the thresholds fixed on a grid the
torque is linear in k_j >= 0 -> non-negative least squares (here jointly
with the elastic curve, see :mod:`.stiffness`).  Keys written: the plant's
``hysteresis_maxwell.eK_k_Nm_per_rad``, ``eK_w_Nm``.

Preisach (6.3-6.4): input = transmitted torque T (N.m), output = twist
(rad), the firmware's ``HD_PREISACH_UNIT_TORQUE_TWIST`` direction.  From
first-order reversal curves (negative saturation -> alpha -> down)::

    E(alpha, beta) = (phi(alpha) - phi(alpha, beta)) / 2

is sampled on the FORC branches, interpolated to the uniform grid of the
table (L levels, spacing a power of two in Q15.16 N.m so that the firmware
lattice matches), and projected onto Everett functions of a *non-negative*
density: the cell masses mu_ij >= 0 are found by NNLS so that
``E(a_i, b_j) = sum of mu over {b_j <= b < a <= a_i}``; positivity and
monotonicity (E rises with alpha, falls with beta) follow.  Prediction uses
the recursive memory (stack of alternating extrema, wiping-out) with the
firmware's interpolation (bilinear; linear on diagonal cells), both from
:mod:`hdservo.preisach`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy.optimize import nnls

from .. import preisach_table as pt
from ..errors import UserError
from ..preisach import PreisachModel, cell_sum_matrix, everett_at

#: Twist LSB of the firmware output format: 2^-32 turn, rad.
TWIST_LSB_RAD = 2.0 * math.pi / 2.0 ** 32
#: Torque LSB of the firmware input format: Q15.16 N.m.
TORQUE_LSB_NM = 2.0 ** -16


# ----------------------------------------------------------------- Maxwell-slip


def stop_operators(phi: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """Unit-stiffness stop operators: column j = clamp(phi - xi_j, +-Delta_j), xi_j dragged along.

    The elements start relaxed at phi[0]; after the input has moved more than
    2 Delta_j in one direction the initial state is forgotten.

    Returns
    -------
    numpy.ndarray, shape (len(phi), len(thresholds))
        Element deflections (rad); multiply by k_j for N.m.
    """
    d = np.asarray(thresholds, dtype=float)
    x = np.asarray(phi, dtype=float)
    xi = np.full(d.shape, x[0])
    out = np.empty((len(x), len(d)))
    for i, p in enumerate(x):
        e = p - xi
        xi = np.where(e > d, p - d, np.where(e < -d, p + d, xi))
        out[i] = p - xi
    return out


@dataclass
class MaxwellSlip:
    """Maxwell-slip elements (stiffness k_j N.m/rad, break force w_j N.m)."""

    k_Nm_per_rad: list[float]
    w_Nm: list[float]

    @property
    def thresholds_rad(self) -> list[float]:
        return [w / k if k > 0 else 0.0 for k, w in zip(self.k_Nm_per_rad, self.w_Nm)]

    def torque(self, phi: np.ndarray) -> np.ndarray:
        if not self.k_Nm_per_rad:
            return np.zeros(len(phi))
        return stop_operators(phi, np.array(self.thresholds_rad)) @ np.array(self.k_Nm_per_rad)

    def loss_rad(self, k1_Nm_per_rad: float) -> float:
        """Hysteresis loss it causes on a large cycle in the K1 region, 2 sum(w)/K1 (rad)."""
        return 2.0 * sum(self.w_Nm) / k1_Nm_per_rad

    def reduce(self, n: int) -> "MaxwellSlip":
        """Keep at most n elements: merge neighbours (by threshold) with the smallest weights."""
        k = list(self.k_Nm_per_rad)
        d = list(self.thresholds_rad)
        while len(k) > n:
            j = int(np.argmin([k[i] + k[i + 1] for i in range(len(k) - 1)]))
            kk = k[j] + k[j + 1]
            dd = (k[j] * d[j] + k[j + 1] * d[j + 1]) / kk
            k[j:j + 2] = [kk]
            d[j:j + 2] = [dd]
        return MaxwellSlip(k, [a * b for a, b in zip(k, d)])

    def to_dict(self) -> dict[str, Any]:
        return {"n_elements": len(self.k_Nm_per_rad), "k_Nm_per_rad": self.k_Nm_per_rad, "w_Nm": self.w_Nm,
                "thresholds_rad": self.thresholds_rad}


def maxwell_from_weights(k: np.ndarray, thresholds: np.ndarray, rel_tol: float = 1e-3) -> MaxwellSlip:
    """Elements with non-negligible weight from an NNLS solution on a threshold grid."""
    keep = k > rel_tol * max(float(np.max(k)), 1e-300)
    return MaxwellSlip([float(v) for v in k[keep]], [float(a * b) for a, b in zip(k[keep], thresholds[keep])])


# ----------------------------------------------------------------- Preisach / Everett


@dataclass
class Everett:
    """Everett function on a uniform grid (input N.m, output rad).

    Attributes
    ----------
    u0_Nm, step_Nm : float
        Grid level i is ``u0 + i*step``.
    table : numpy.ndarray
        L x L, ``table[i, j] = E(u_i, u_j)`` for j <= i (zero diagonal), rad.
    offset_rad : float
        Twist at the centre of the major loop (output = offset + P[T]).
    """

    u0_Nm: float
    step_Nm: float
    table: np.ndarray
    offset_rad: float = 0.0

    @property
    def levels(self) -> int:
        return int(self.table.shape[0])

    @property
    def u_max_Nm(self) -> float:
        return self.u0_Nm + (self.levels - 1) * self.step_Nm

    def __call__(self, a: float, b: float) -> float:
        """E(a, b) with the firmware interpolation (bilinear; linear on diagonal cells)."""
        return everett_at(self.table, self.u0_Nm, self.step_Nm, a, b)

    def simulate(self, u: Sequence[float]) -> np.ndarray:
        """Output (rad) for an input sequence (N.m), memory starting at negative saturation."""
        model = PreisachModel(self, self.u_max_Nm, u_min=self.u0_Nm, y_sat=float(self.table[-1, 0]))
        return model.run(u) + self.offset_rad

    def to_dict(self) -> dict[str, Any]:
        return {"levels": self.levels, "u0_Nm": self.u0_Nm, "step_Nm": self.step_Nm, "offset_rad": self.offset_rad,
                "e_total_rad": float(self.table[-1, 0])}


def split_reversals(cmd: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges of monotone stretches of a piecewise-linear command (dwells belong to the previous one,
    a leading dwell to the first)."""
    d = np.sign(np.diff(cmd))
    nz = np.flatnonzero(d)
    if len(nz):
        # a dwell before the first change (a held set-point over CAN) belongs to the first stretch
        d[:nz[0]] = d[nz[0]]
    for i in range(1, len(d)):
        if d[i] == 0:
            d[i] = d[i - 1]
    edges = [0] + [i + 1 for i in range(1, len(d)) if d[i] != d[i - 1]] + [len(cmd) - 1]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def everett_from_forcs(T: np.ndarray, phi: np.ndarray, cmd: np.ndarray, levels: int, step_Nm: float,
                       u0_Nm: float, signed: bool = False) -> tuple[Everett, dict[str, Any]]:
    """Everett table from first-order reversal curves.

    Parameters
    ----------
    T, phi : numpy.ndarray
        Measured input (torque, N.m) and output (twist, rad); :func:`gear_table_from_forcs` passes
        the twist as the input and the torque as the output (the same reversals: the gear's
        branches are monotone).
    cmd : numpy.ndarray
        The commanded torque (its direction changes mark the reversals).
    levels, step_Nm, u0_Nm : int, float, float
        Table grid (L levels, spacing, first level), in the input's unit.
    signed : bool
        Cell masses of either sign instead of a non-negative density (NNLS).  The gear's twist ->
        torque operator has a negative Preisach part (the plant's P_mean - P, docs/plant.md): a
        non-negative projection would distort it.  Signed masses reproduce any grid table, so the
        table is then the interpolated samples themselves (no projection).

    Returns
    -------
    Everett, dict
        The projected table and diagnostics (raw E samples, FORC count).
    """
    stretches = split_reversals(cmd)
    # descending stretches that start at a maximum (alpha) reached from a minimum
    forcs = []
    for (a0, a1), (b0, b1) in zip(stretches[:-1], stretches[1:]):
        if cmd[a1] > cmd[a0] and cmd[b1] < cmd[b0]:
            seg = slice(b0, b1 + 1)
            k = a0 + int(np.argmax(T[a0:b1 + 1]))       # reversal at the torque maximum
            alpha, y_a = float(T[k]), float(np.mean(phi[max(k - 2, 0):k + 3]))
            tb, pb = T[k:b1 + 1], phi[k:b1 + 1]
            forcs.append((alpha, y_a, tb, pb))
    if len(forcs) < 3:
        raise UserError(f"preisach: found {len(forcs)} reversal curves, expected at least 3")
    grid = u0_Nm + step_Nm * np.arange(levels)
    # E on each FORC at the grid betas (bin means of the branch)
    alphas = np.array([f[0] for f in forcs])
    order = np.argsort(alphas)
    Ef = np.full((len(forcs), levels), np.nan)
    for r, idx in enumerate(order):
        alpha, y_a, tb, pb = forcs[idx]
        e = 0.5 * (y_a - pb)
        for j, b in enumerate(grid):
            if b > alpha:
                break
            m = np.abs(tb - b) <= 0.5 * step_Nm
            if m.sum() >= 2:
                # local linear fit through the bin -> value at b
                A = np.column_stack([np.ones(m.sum()), tb[m] - b])
                Ef[r, j] = float(np.linalg.lstsq(A, e[m], rcond=None)[0][0])
            elif b >= tb.min():
                Ef[r, j] = float(np.interp(b, tb[::-1], e[::-1]))
    al = alphas[order]
    # interpolate across alpha to the grid
    target = np.zeros((levels, levels))
    weight = np.zeros((levels, levels))
    for i in range(1, levels):
        for j in range(i):
            col = Ef[:, j]
            ok = ~np.isnan(col) & (al >= grid[j])
            if ok.sum() == 0:
                continue
            x, y = np.concatenate([[grid[j]], al[ok]]), np.concatenate([[0.0], col[ok]])
            srt = np.argsort(x)
            target[i, j] = float(np.interp(grid[i], x[srt], y[srt]))
            weight[i, j] = 1.0 if grid[i] <= al[ok].max() + 0.5 * step_Nm else 0.2
    if signed:
        E = np.tril(target, -1)
        fit_rms = 0.0
    else:
        A, cells, pts = cell_sum_matrix(levels)
        w = np.array([weight[i, j] for i, j in pts])
        b = np.array([target[i, j] for i, j in pts])
        mu, _ = nnls(A * w[:, None], b * w, maxiter=50 * A.shape[1])
        E = np.zeros((levels, levels))
        for r, (i, j) in enumerate(pts):
            E[i, j] = float(A[r] @ mu)
        fit_rms = float(np.sqrt(np.mean(((A @ mu) - b) ** 2)))
    # offset: centre of the major loop (twist at the lowest and highest torque)
    lo = phi[np.argmin(T)]
    hi = phi[np.argmax(T)]
    ev = Everett(u0_Nm=float(u0_Nm), step_Nm=float(step_Nm), table=E)
    ev.offset_rad = 0.5 * (float(lo) + float(hi)) - 0.0
    # the model spans +-E_total around the offset: align with the measured extremes
    ev.offset_rad = float(0.5 * (lo + hi))
    return ev, {"forcs": len(forcs), "alphas_Nm": al.tolist(), "fit_rms_rad": fit_rms}


def grid_for(torque_range_Nm: float, levels: int) -> tuple[float, float]:
    """(u0, step) of a centred table grid whose step is a power of two in N.m (Q15.16 lattice)."""
    raw = 2.0 * torque_range_Nm / (levels - 1)
    step = 2.0 ** math.ceil(math.log2(raw))
    return -0.5 * (levels - 1) * step, step


#: Twist lattice step of the identified twist -> torque table, 2^-32 turn (2^10: 1.46 urad, 0.30"; the
#: axis-file table's ``compsetup.TABLE_LATTICE_LSB``): the drive's inverse rounds the twist to half of it.
TWIST_LATTICE_LSB = 2 ** 10
#: Grid levels of the identified twist -> torque table at most: the firmware's limit (64; 8.3 KB of
#: table, one bisection trial per period, a new twist every 5 cycles at 64 levels, docs/compensators.md).
TWIST_LEVELS_MAX = 64


@dataclass
class GearTable:
    """The gear's twist -> torque operator identified from the reversal curves (the table the drive runs
    through its inverse).

    Attributes
    ----------
    everett : Everett
        Input twist (rad, centred: ``u0_Nm``/``step_Nm`` hold rad here), output torque, N.m.
    table : hdservo.preisach_table.PreisachTable
        Firmware image, unit generic (twist in 2^-32 turn -> torque Q15.16 N.m).
    twist_offset_rad : float
        Measured twist at the centre of the major loop (subtracted before the fit).
    """

    everett: Everett
    table: pt.PreisachTable
    twist_offset_rad: float

    def to_dict(self) -> dict[str, Any]:
        return {"levels": self.everett.levels, "u0_rad": self.everett.u0_Nm, "step_rad": self.everett.step_Nm,
                "sub_bits": self.table.sub_bits, "in_shift": self.table.in_shift, "crc": int(self.table.crc),
                "twist_offset_rad": self.twist_offset_rad, "e_total_Nm": float(self.everett.table[-1, 0])}


def twist_grid(range_rad: float, levels_max: int = TWIST_LEVELS_MAX) -> tuple[int, int, int, int]:
    """Lattice of the twist -> torque table over the measured twist +-``range_rad``.

    Rule: the lattice step stays at :data:`TWIST_LATTICE_LSB` (coarser only when ``levels_max`` grid
    cells of the most sub-steps cannot span the range); the grid step is that lattice step times the
    fewest power-of-two sub-steps that span the range with at most ``levels_max`` levels, and the
    levels are as many as fit *inside* the measured range, so that every level has reversal data.

    Returns
    -------
    tuple of int
        (levels, sub_bits, in_shift, u0) with u0 in 2^-32 turn.
    """
    span = 2.0 * float(range_rad) / TWIST_LSB_RAD
    if not span > 0.0:
        raise UserError(f"preisach: measured twist range {range_rad} rad, expected > 0")
    need = span / ((levels_max - 1) * TWIST_LATTICE_LSB)
    sub = min(max(0, math.ceil(math.log2(need))), pt.SUB_MAX) if need > 1 else 0
    in_shift = max(int(math.log2(TWIST_LATTICE_LSB)), math.ceil(math.log2(span / ((levels_max - 1) << sub))))
    cell = (1 << in_shift) << sub
    levels = min(levels_max, int(math.floor(span / cell)) + 1)
    if levels < pt.L_MIN:
        raise UserError(f"preisach: measured twist range {range_rad:.3g} rad spans {levels} grid level(s), "
                        f"expected at least {pt.L_MIN}")
    return levels, sub, in_shift, -((levels - 1) * cell) // 2


def gear_table_from_forcs(T: np.ndarray, phi: np.ndarray, cmd: np.ndarray,
                          levels_max: int = TWIST_LEVELS_MAX, version: int = 1) -> GearTable:
    """The gear's twist -> torque table from the reversal curves of the ``forc`` experiment.

    The gear is a twist-input operator (spring, Maxwell-slip elements, Preisach part): fitted in
    that direction the table has the gear's minor loops; the torque -> twist Preisach model of the
    same curves (:func:`everett_from_forcs`) is congruent in torque, the gear is not, and its minor
    loops at swings of 0.25-1 T1 are 15-45 % narrower than the gear's.

    Parameters
    ----------
    T, phi : numpy.ndarray
        Measured torque (N.m) and twist (rad).
    cmd : numpy.ndarray
        The commanded torque.
    levels_max : int
        Grid levels at most (:func:`twist_grid`).
    version : int
        Table version.

    Returns
    -------
    GearTable
    """
    T = np.asarray(T, dtype=float)
    phi = np.asarray(phi, dtype=float)
    off = 0.5 * (float(phi[np.argmin(T)]) + float(phi[np.argmax(T)]))
    pc = phi - off
    rng = 0.5 * float(np.max(pc) - np.min(pc))
    levels, sub, in_shift, u0 = twist_grid(rng, levels_max)
    cell = (1 << in_shift) << sub
    ev, _ = everett_from_forcs(pc, T, cmd, levels, cell * TWIST_LSB_RAD, u0 * TWIST_LSB_RAD, signed=True)
    ev.offset_rad = 0.0
    tab = pt.quantise_everett(ev.table, 1.0 / TORQUE_LSB_NM, sub_bits=sub, in_shift=in_shift, u0=int(u0),
                              unit=pt.UNIT_GENERIC, version=version)
    return GearTable(everett=ev, table=tab, twist_offset_rad=off)


#: Lattice steps per grid cell of the identified table, as a power of two: the drive interpolates the
#: Everett function between the grid levels, so its torque input moves in steps of 1/16 of a grid step
#: (0.125 N.m on a 2 N.m grid).  With the input on the grid alone (0) a held torque anywhere inside one
#: 2 N.m cell gave one twist, and a slow change of the torque stepped the predicted twist by the whole
#: cell (13 arcsec on the reference axis).
TABLE_SUB_BITS = 4


def quantise_table(ev: Everett, version: int = 1, sub_bits: int = TABLE_SUB_BITS) -> pt.PreisachTable:
    """Firmware image (magic, CRC) of an Everett table via :mod:`hdservo.preisach_table`.

    Input Q15.16 N.m (grid levels every 2^sub_bits lattice steps, in_shift = log2(step/LSB) -
    sub_bits), output 2^-32 turn.
    """
    shift = int(round(math.log2(ev.step_Nm / TORQUE_LSB_NM)))
    if not (0 <= shift <= pt.SHIFT_MAX) or abs(2.0 ** shift * TORQUE_LSB_NM - ev.step_Nm) > 1e-12:
        raise UserError(f"preisach: grid step {ev.step_Nm} N.m is not a power of two of the Q15.16 LSB")
    sub = max(0, min(int(sub_bits), shift))
    u0 = int(round(ev.u0_Nm / TORQUE_LSB_NM))
    return pt.quantise_everett(ev.table, 1.0 / TWIST_LSB_RAD, sub_bits=sub, in_shift=shift - sub, u0=u0,
                               unit=pt.UNIT_TORQUE_TWIST, version=version)


def dequantise_table(tab: pt.PreisachTable, offset_rad: float = 0.0) -> Everett:
    """Back from the firmware image (for checking the quantised model)."""
    g = tab.grid().astype(float) * TWIST_LSB_RAD
    step = 2.0 ** (tab.in_shift + tab.sub_bits) * TORQUE_LSB_NM
    return Everett(u0_Nm=tab.u0 * TORQUE_LSB_NM, step_Nm=step, table=g, offset_rad=offset_rad)


def dequantise_gear_table(tab: pt.PreisachTable) -> Everett:
    """Back from the twist -> torque image of :func:`gear_table_from_forcs` (input rad, output N.m)."""
    step = 2.0 ** (tab.in_shift + tab.sub_bits) * TWIST_LSB_RAD
    return Everett(u0_Nm=tab.u0 * TWIST_LSB_RAD, step_Nm=step, table=tab.grid().astype(float) * TORQUE_LSB_NM)


@dataclass
class MinorLoopCheck:
    """Preisach prediction of validation minor loops."""

    rms_error_rad: float
    loop_width_rad: float
    rms_over_width: float
    max_error_rad: float
    plot_data: dict[str, Any] = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {"rms_error_rad": self.rms_error_rad, "loop_width_rad": self.loop_width_rad,
                "rms_over_width": self.rms_over_width, "max_error_rad": self.max_error_rad}


def loop_width(T: np.ndarray, phi: np.ndarray, cmd: np.ndarray) -> float:
    """Largest output gap between a descending and the following ascending stretch at equal input
    (twist at equal torque, rad; or torque at equal twist, N.m)."""
    st = split_reversals(cmd)
    best = 0.0
    for (a0, a1), (b0, b1) in zip(st[:-1], st[1:]):
        if cmd[a1] < cmd[a0] and cmd[b1] > cmd[b0]:
            ta, pa = T[a0:a1 + 1][::-1], phi[a0:a1 + 1][::-1]     # descending, reversed -> increasing T
            tb, pb = T[b0:b1 + 1], phi[b0:b1 + 1]
            lo, hi = max(ta.min(), tb.min()), min(ta.max(), tb.max())
            if hi - lo <= 0:
                continue
            g = np.linspace(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), 20)
            sa = np.interp(g, np.maximum.accumulate(ta), pa)
            sb = np.interp(g, np.maximum.accumulate(tb), pb)
            # the larger gap, whichever branch lies above (twist: the descending one; torque at
            # equal twist, :func:`gear_table_from_forcs`: the ascending one)
            best = max(best, float(np.max(sa - sb)), float(np.max(sb - sa)))
    return best


def check_minor_loops(ev: Everett, T: np.ndarray, phi: np.ndarray, cmd: np.ndarray) -> MinorLoopCheck:
    """Predict the twist of held-out minor loops; error relative to the largest loop width."""
    pred = ev.simulate(T)
    # skip the first stretch (bringing the memory to negative saturation)
    st = split_reversals(cmd)
    start = st[1][0] if len(st) > 1 else 0
    e = pred[start:] - phi[start:]
    e = e - np.mean(e)          # the twist origin of a run is arbitrary (clamp/encoder zero)
    w = loop_width(T[start:], phi[start:], cmd[start:])
    rms = float(np.sqrt(np.mean(e ** 2)))
    return MinorLoopCheck(rms_error_rad=rms, loop_width_rad=w, rms_over_width=rms / w if w > 0 else math.inf,
                          max_error_rad=float(np.max(np.abs(e))),
                          plot_data={"T_Nm": T[start:], "phi_rad": phi[start:], "pred_rad": pred[start:] - np.mean(
                              pred[start:] - phi[start:])})
