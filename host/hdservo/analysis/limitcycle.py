"""Limit cycles (harmonic balance + Loeb criterion) and margins versus amplitude.

A limit cycle of amplitude A (at the nonlinearity's input) and angular
frequency w solves ``1 + H(jw) N(A) = 0``.  Candidates come from
python-control's :func:`control.describing_function_response` (crossings of
the Nyquist curve of H with ``-1/N(A)``); each is polished by a Newton solve
in (log A, log w).

Loeb criterion: perturb the amplitude; the root ``s = sigma + jw`` of
``1 + H(s) N(A) = 0`` moves by ``ds/dA = -H N'(A) / (H'(s) N)``.  The cycle
is stable (an attractor for the amplitude) when ``Re(ds/dA) < 0``: a larger
amplitude decays, a smaller one grows.

Equivalent linearisation: with N(A) in place of the nonlinearity, the loop
broken at the torque command gives gain/phase margins and crossover; the
closed loop ``theta_L/r`` its -3 dB bandwidth.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional

import control as ct
import numpy as np
from scipy import optimize

from .dfbase import HdNonlinearity
from .loop import equivalent_loop, freqresp


@dataclass
class LimitCycle:
    """A predicted limit cycle.

    Attributes
    ----------
    amplitude : float
        Amplitude at the nonlinearity's input (its input unit).
    omega_rad_s : float
        Angular frequency (rad/s).
    stable : bool
        Loeb criterion: True if the amplitude is attracted to this cycle.
    dsigma_dA : float
        Real part of ds/dA (1/s per input unit); < 0 is stable.
    residual : float
        ``|1 + H(jw) N(A)|`` at the solution (dimensionless).
    """

    amplitude: float
    omega_rad_s: float
    stable: bool
    dsigma_dA: float
    residual: float

    @property
    def frequency_Hz(self) -> float:
        """Frequency (Hz)."""
        return self.omega_rad_s / (2 * math.pi)

    def to_dict(self) -> Dict[str, Any]:
        return {"amplitude": self.amplitude, "omega_rad_s": self.omega_rad_s,
                "frequency_Hz": self.frequency_Hz, "stable": self.stable,
                "dsigma_dA": self.dsigma_dA, "residual": self.residual}


def _H_at(H: ct.StateSpace, w: float) -> complex:
    return complex(freqresp(H, np.array([w]))[0, 0, 0])


def _dN(nl: HdNonlinearity, A: float) -> complex:
    h = A * (1e-2 if nl.kind == "preisach" else 1e-5)
    return (nl.describing_function(A + h) - nl.describing_function(A - h)) / (2 * h)


def loeb(H: ct.StateSpace, nl: HdNonlinearity, A: float, w: float) -> float:
    """``Re(ds/dA)`` at a limit cycle (1/s per input unit); negative = stable."""
    N = nl.describing_function(A)
    hw = w * 1e-6
    dH_dw = (_H_at(H, w + hw) - _H_at(H, w - hw)) / (2 * hw)
    dH_ds = -1j * dH_dw
    ds_dA = -_H_at(H, w) * _dN(nl, A) / (dH_ds * N)
    return float(ds_dA.real)


def _polish(H: ct.StateSpace, nl: HdNonlinearity, A0: float, w0: float) -> tuple[float, float, float]:
    def f(x: np.ndarray) -> np.ndarray:
        A, w = math.exp(x[0]), math.exp(x[1])
        r = 1 + _H_at(H, w) * nl.describing_function(A)
        return np.array([r.real, r.imag])

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = optimize.root(f, [math.log(A0), math.log(w0)], method="hybr")
    A, w = (math.exp(sol.x[0]), math.exp(sol.x[1])) if sol.success else (A0, w0)
    res = float(np.hypot(*f(np.log([A, w]))))
    res0 = float(np.hypot(*f(np.log([A0, w0]))))
    if not np.isfinite(res) or res > res0:
        return A0, w0, res0
    return A, w, res


def find_limit_cycles(H: ct.StateSpace, nl: HdNonlinearity, amplitudes: np.ndarray,
                      omega: np.ndarray) -> List[LimitCycle]:
    """Predicted limit cycles of the loop ``H`` closed through ``nl``.

    Parameters
    ----------
    H : control.StateSpace
        Linear part, ``H = -P_zw`` (z units per w unit).
    nl : HdNonlinearity
        The nonlinearity (its DF may be analytic or numerical).
    amplitudes : numpy.ndarray
        Increasing amplitudes to scan (nonlinearity input units).
    omega : numpy.ndarray
        Increasing angular frequencies to scan (rad/s).

    Returns
    -------
    list of LimitCycle
        Sorted by amplitude; duplicates merged.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        resp = ct.describing_function_response(H, nl, amplitudes, omega=omega, refine=False,
                                               warn_nyquist=False)
    out: List[LimitCycle] = []
    for A0, w0 in resp.intersections:
        if not (np.isfinite(A0) and np.isfinite(w0)) or A0 <= 0 or w0 <= 0:
            continue
        A, w, res = _polish(H, nl, float(A0), float(w0))
        if any(abs(A - c.amplitude) < 1e-6 * A and abs(w - c.omega_rad_s) < 1e-6 * w for c in out):
            continue
        d = loeb(H, nl, A, w)
        out.append(LimitCycle(A, w, d < 0, d, res))
    out.sort(key=lambda c: c.amplitude)
    return out


def _margins(L: np.ndarray, omega: np.ndarray) -> Dict[str, Optional[float]]:
    mag = np.abs(L)
    gm = pm = wc = wpc = None
    ic = np.where(np.diff(np.sign(mag - 1.0)) != 0)[0]
    for i in ic:
        t = (1.0 - mag[i]) / (mag[i + 1] - mag[i])
        w = omega[i] + t * (omega[i + 1] - omega[i])
        Lw = L[i] + t * (L[i + 1] - L[i])
        p = (180.0 + math.degrees(math.atan2(Lw.imag, Lw.real)) + 180.0) % 360.0 - 180.0
        if pm is None or abs(p) < abs(pm):
            pm, wc = p, w
    ip = np.where((np.diff(np.sign(L.imag)) != 0) & (L.real[:-1] < 0))[0]
    for i in ip:
        t = -L.imag[i] / (L.imag[i + 1] - L.imag[i])
        x = L.real[i] + t * (L.real[i + 1] - L.real[i])
        g = -20 * math.log10(abs(x)) if x != 0 else math.inf
        if gm is None or abs(g) < abs(gm):
            gm, wpc = g, omega[i] + t * (omega[i + 1] - omega[i])
    return {"gain_margin_dB": gm, "phase_crossover_Hz": None if wpc is None else wpc / (2 * math.pi),
            "phase_margin_deg": pm, "gain_crossover_Hz": None if wc is None else wc / (2 * math.pi)}


def loop_metrics(O: np.ndarray, omega: np.ndarray, N: complex) -> Dict[str, Optional[float]]:
    """Margins (torque-command break) and -3 dB bandwidth of ``theta_L/r`` with gain N.

    Parameters
    ----------
    O : numpy.ndarray
        Frequency response of the open system (3, 3, n) at ``omega`` (rad/s).
    omega : numpy.ndarray
        Angular frequencies (rad/s).
    N : complex
        Equivalent gain of the nonlinearity.
    """
    r = equivalent_loop(O, N)
    m = _margins(r["L"], omega)
    T = np.abs(r["T"])
    below = np.where(T < 1 / math.sqrt(2))[0]
    m["bandwidth_Hz"] = float(omega[below[0]] / (2 * math.pi)) if below.size else None
    m["peak_dB"] = float(20 * np.log10(T.max()))
    return m


def margins_vs_amplitude(O: np.ndarray, omega: np.ndarray, nl: HdNonlinearity,
                         amplitudes: np.ndarray, progress: Callable[[int, int], None] | None = None
                         ) -> List[Dict[str, Any]]:
    """Equivalent-linearisation loop metrics for each amplitude (list of dicts)."""
    rows = []
    for k, A in enumerate(amplitudes):
        N = nl.describing_function(float(A))
        row: Dict[str, Any] = {"amplitude": float(A)}
        if np.isfinite(N):
            row.update(loop_metrics(O, omega, N))
        rows.append(row)
        if progress:
            progress(k + 1, len(amplitudes))
    return rows
