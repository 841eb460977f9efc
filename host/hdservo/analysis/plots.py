"""Plots of the describing-function analysis (PNG or PDF, units on every axis)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, List, Sequence

import numpy as np

from ..fileio import save_figure_atomic
from ..plotting import pyplot

plt = pyplot()


def _save(fig: Any, path: Path) -> None:
    """Write atomically (temp file + rename) and close the figure."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        save_figure_atomic(fig, path, dpi=110)
    finally:
        plt.close(fig)


def nyquist_plot(path: Path, name: str, H_vals: np.ndarray, N_vals: np.ndarray, cycles: Sequence[Dict[str, Any]],
                 H_at_cycles: Sequence[complex], unit: str) -> None:
    """Nyquist curve of H with -1/N(A); intersections marked.

    Parameters
    ----------
    path : pathlib.Path
        Output file (.png or .pdf).
    name : str
        Nonlinearity name (title).
    H_vals : numpy.ndarray
        H(jw) over the frequency grid (complex).
    N_vals : numpy.ndarray
        N(A) over the amplitude grid (complex).
    cycles : sequence of dict
        Limit cycles (``amplitude``, ``frequency_Hz``, ``stable``).
    H_at_cycles : sequence of complex
        H at each limit cycle.
    unit : str
        Unit of H, e.g. ``"(rad/s)/(N*m)"``.
    """
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    with np.errstate(divide="ignore", invalid="ignore"):
        m1n = -1.0 / N_vals
    ok = np.isfinite(m1n)
    ax.plot(H_vals.real, H_vals.imag, "C0-", label="H(jω) (ω > 0)")
    ax.plot(m1n[ok].real, m1n[ok].imag, "C3.-", ms=3, label="-1/N(A) (A increasing →)")
    for c, h in zip(cycles, H_at_cycles):
        ax.plot(h.real, h.imag, "ko" if c["stable"] else "kx", ms=8,
                label=f"{'stable' if c['stable'] else 'unstable'} LC {c['frequency_Hz']:.3g} Hz")
    if len(H_at_cycles):
        span = 2.5 * max(1.0, float(np.max(np.abs(np.asarray(H_at_cycles, dtype=complex)))))
    elif ok.any():
        span = 1.5 * max(1.0, float(np.median(np.abs(m1n[ok]))))
    else:
        span = 2.0
    ax.set_xlim(-span, span)
    ax.set_ylim(-span, span)
    ax.axhline(0, color="0.7", lw=0.5)
    ax.axvline(0, color="0.7", lw=0.5)
    ax.set_xlabel(f"Re [{unit}]")
    ax.set_ylabel(f"Im [{unit}]")
    ax.set_title(f"{name}: Nyquist of H and -1/N(A)")
    ax.legend(fontsize=8, loc="best")
    ax.grid(True, alpha=0.3)
    _save(fig, path)


def df_plot(path: Path, name: str, A: np.ndarray, N_vals: np.ndarray, a_unit: str, n_unit: str) -> None:
    """Gain and phase of N(A) against amplitude (log amplitude axis)."""
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.4, 5.6), sharex=True)
    ok = np.isfinite(N_vals)
    a1.semilogx(A[ok], np.abs(N_vals[ok]), "C0.-")
    a1.set_ylabel(f"|N(A)| [{n_unit}]")
    a1.grid(True, which="both", alpha=0.3)
    a2.semilogx(A[ok], np.degrees(np.angle(N_vals[ok])), "C1.-")
    a2.set_ylabel("phase of N(A) [deg]")
    a2.set_xlabel(f"amplitude A [{a_unit}]")
    a2.grid(True, which="both", alpha=0.3)
    a1.set_title(f"{name}: describing function")
    _save(fig, path)


def margins_plot(path: Path, name: str, rows: List[Dict[str, Any]], a_unit: str,
                 nominal: Dict[str, Any]) -> None:
    """Gain margin, phase margin and bandwidth of the equivalent linear loop against amplitude."""
    A = np.array([r["amplitude"] for r in rows])

    def col(k: str) -> np.ndarray:
        return np.array([np.nan if r.get(k) is None else r[k] for r in rows], dtype=float)

    fig, axs = plt.subplots(3, 1, figsize=(6.4, 7.2), sharex=True)
    for ax, key, lab in zip(axs, ("gain_margin_dB", "phase_margin_deg", "bandwidth_Hz"),
                            ("gain margin [dB]", "phase margin [deg]", "closed-loop bandwidth [Hz]")):
        ax.semilogx(A, col(key), "C0.-", label="with N(A)")
        if nominal.get(key) is not None:
            ax.axhline(nominal[key], color="C2", ls="--", lw=1, label="linear model")
        ax.set_ylabel(lab)
        ax.grid(True, which="both", alpha=0.3)
    axs[0].legend(fontsize=8)
    axs[0].set_title(f"{name}: loop at the torque command, equivalent linearisation")
    axs[-1].set_xlabel(f"amplitude A [{a_unit}]")
    _save(fig, path)
