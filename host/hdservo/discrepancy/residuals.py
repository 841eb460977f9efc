"""Residual analysis: spectra, order analysis, whiteness (the simulation error is in simerr).

* Equation error: measured motor torque minus the model's torque computed from the
  measured (filtered) states, per equation (M, R), N.m at the motor
  (:func:`hdservo.discrepancy.regression.solve`).  Valid for open- and closed-loop data
  alike: it never integrates, so it cannot drift under feedback.
* Simulation error: :mod:`hdservo.discrepancy.simerr`.
* Spectra (Welch), order spectrum of a residual against an angle (bin means over one
  revolution, FFT -> amplitude per order), Ljung-Box whiteness test, effective sample
  count of a coloured residual.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.signal as sps
import scipy.stats as st

if TYPE_CHECKING:
    from .regression import Design


def order_spectrum(d: "Design", resid: np.ndarray, angle: np.ndarray, max_order: int = 200,
                   bins: int = 1024) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude of a residual per order of an angle (cycles per revolution).

    Parameters
    ----------
    d : Design
        The design whose used samples ``resid`` belongs to (first equation block).
    resid : numpy.ndarray
        Residual over the used decimated samples, N.m.
    angle : numpy.ndarray
        Angle at the log rate, rad.
    max_order : int
    bins : int
        Angle bins per revolution.

    Returns
    -------
    orders, amplitude : numpy.ndarray
        Orders 1..max_order and the amplitude of each line, N.m.
    """
    ang = d.sig.dec(angle)[d.mask] if d.sig.q > 1 else angle[d.mask]
    # decimation filters the angle (continuous, so fine) -- use the raw samples instead
    ang = angle[:: d.sig.q][: len(d.mask)][d.mask] if d.sig.q > 1 else angle[d.mask]
    r = resid[: len(ang)]
    idx = np.floor((np.mod(ang, 2 * np.pi) / (2 * np.pi)) * bins).astype(int) % bins
    s = np.bincount(idx, weights=r, minlength=bins)
    c = np.bincount(idx, minlength=bins)
    m = np.where(c > 0, s / np.maximum(c, 1), 0.0)
    m[c > 0] -= np.mean(m[c > 0])
    spec = np.abs(np.fft.rfft(m)) * 2 / bins
    k = np.arange(len(spec))
    sel = (k >= 1) & (k <= max_order)
    return k[sel], spec[sel]


def autocorr(x: np.ndarray, lags: int) -> np.ndarray:
    """Normalised autocorrelation r(1..lags)."""
    x = x - np.mean(x)
    n = len(x)
    f = np.fft.rfft(x, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[: lags + 1]
    return ac[1:] / max(ac[0], 1e-300)


def effective_n(x: np.ndarray, lags: int = 50) -> float:
    """Effective number of independent samples of a coloured residual, n / (1 + 2 sum r_k)."""
    r = autocorr(x, min(lags, len(x) // 4))
    # sum until the first non-positive correlation (initial positive sequence)
    s = 0.0
    for v in r:
        if v <= 0:
            break
        s += v
    return float(np.clip(len(x) / (1 + 2 * s), 10.0, len(x)))


def ljung_box(x: np.ndarray, lags: int = 20) -> dict[str, float]:
    """Ljung-Box whiteness test; returns Q, the lag count and the p-value."""
    n = len(x)
    r = autocorr(x, lags)
    q = n * (n + 2) * float(np.sum(r ** 2 / (n - np.arange(1, lags + 1))))
    return {"Q": q, "lags": float(lags), "p_value": float(st.chi2.sf(q, lags))}


def spectrum(x: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch amplitude spectral density of a residual (unit/sqrt(Hz)) at rate fs (Hz)."""
    f, p = sps.welch(x - np.mean(x), fs=fs, nperseg=min(len(x), 1024))
    return f, np.sqrt(p)
