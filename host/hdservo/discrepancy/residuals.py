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


def line_statistics(d: "Design", resid: np.ndarray, angle: np.ndarray, speed: np.ndarray, orders: np.ndarray,
                    min_samples: int = 50) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per order of an angle, the line's power in a residual over the samples where the
    line lies inside the log's band.

    A line of order p (cycles per revolution) of an angle turning at speed w is at
    p |w| / 2 pi Hz; above the angle low-pass' cutoff ``fc_Hz`` the parallel filter has
    taken it out of the torque and of every column alike, so those samples carry nothing of
    it.  For each order the residual is regressed on cos/sin(p angle) over the used samples
    below that speed only, and the statistic is the regression's sum of squares over the
    residual's mean square there (chi-square with 2 degrees of freedom for a white residual
    without the line, whatever the number of samples).

    Parameters
    ----------
    d : Design
        The design whose used samples ``resid`` belongs to (first equation block).
    resid : numpy.ndarray
        Residual over the used decimated samples, N.m.
    angle : numpy.ndarray
        Angle at the log rate, rad.
    speed : numpy.ndarray
        Speed of the angle over the used decimated samples, rad/s.
    orders : numpy.ndarray
        Orders searched (cycles per revolution).
    min_samples : int
        Fewest in-band samples for an order to be tested.

    Returns
    -------
    stat, amplitude, n : numpy.ndarray
        Per order: the statistic (NaN where not tested), the line's amplitude (N.m) and
        the number of in-band samples.
    """
    q = max(d.sig.q, 1)
    ang = angle[::q][: len(d.mask)][d.mask]
    r = np.asarray(resid, dtype=float)[: len(ang)]
    w = np.abs(np.asarray(speed, dtype=float))[: len(ang)]
    stat = np.full(len(orders), np.nan)
    amp = np.zeros(len(orders))
    n = np.zeros(len(orders), dtype=int)
    for i, p in enumerate(orders):
        sel = float(p) * w / (2 * np.pi) < d.sig.fc_Hz
        n[i] = int(sel.sum())
        if n[i] < min_samples:
            continue
        rs = r[sel] - np.mean(r[sel])
        X = np.column_stack([np.cos(p * ang[sel]), np.sin(p * ang[sel])])
        X = X - X.mean(axis=0)
        G = X.T @ X
        # the in-band samples must cover the line's period (else cos/sin are a drift)
        if np.linalg.cond(G) > 100.0:
            continue
        coef = np.linalg.solve(G, X.T @ rs)
        ms = float(np.mean(rs ** 2))
        if ms <= 0:
            continue
        stat[i] = float(coef @ G @ coef) / ms
        amp[i] = float(np.hypot(*coef))
    return stat, amp, n


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
