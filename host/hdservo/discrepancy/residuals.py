"""Residual analysis: spectra, order analysis, whiteness (the simulation error is in simerr).

* Equation error: measured motor torque minus the model's torque computed from the
  measured (filtered) states, per equation (M, R), N.m at the motor
  (:func:`hdservo.discrepancy.regression.solve`).  Valid for open- and closed-loop data
  alike: it never integrates, so it cannot drift under feedback.
* Simulation error: :mod:`hdservo.discrepancy.simerr`.
* Spectra (Welch), order spectrum of a residual against an angle (bin means over one
  revolution, FFT -> amplitude per order), Ljung-Box whiteness test, effective sample
  count of a coloured residual.
* The lost-motion test of a backlash at the reversals of the transmitted torque
  (:func:`lost_motion`).
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



#: Torque band of the lost-motion test, as a fraction of the 99th percentile of the
#: transmitted torque: a reversal is the passage from below -band to above +band (or back).
LOST_MOTION_BAND = 0.05
#: Fewest usable reversals for the lost-motion test to report anything.
LOST_MOTION_MIN_EVENTS = 5


def lost_motion(d: "Design", params: dict[str, float]) -> dict[str, float]:
    """Lost motion at the reversals of the transmitted torque, against the spring's travel.

    At a reversal of the transmitted torque T a backlash of half gap b lets the motor
    travel through the zone, 2 b at the output, while the output stands still; a spring
    alone twists by the change of T times its compliance.  The twist change is resolved
    by the motor encoder times N even where the zone spans a few counts of the output
    encoder.

    1. T = N (tau - J_m a_m - Fv_m w_m - Fc_m sgn w_m), each term smoothed over a quarter
       period of the angle cutoff; a reversal is a passage of T from below -band to
       above +band (or back; band: :data:`LOST_MOTION_BAND` of the 99th percentile of
       abs(T)) during which the motor moves and keeps its direction (its Coulomb
       friction then has one sign).
    2. The spring's twist: phi = theta_m/N - theta_l regressed on a constant, N tau,
       N a_m, N w_m, N sgn w_m and sgn T over the samples outside the band where the
       motor moves.  T is then taken from that regression's inertia and friction and
       steps 1-2 run once more.
    3. Per reversal e = sgn(dT) (d phi - d phi_spring); a backlash gives e = 2 b.  The
       test is the one-sided Student t test of mean(e) > 0.

    Parameters
    ----------
    d : Design
        The design (a two-encoder log).
    params : dict
        Fitted parameters: ``K_Nm_per_rad`` (N.m/rad at the output; the test needs a
        spring, K > 0), ``J_m_kgm2`` (kg.m^2), ``Fv_motor_Nms_per_rad`` (N.m.s/rad),
        ``Fc_motor_Nm`` (N.m): the first pass' transmitted torque.

    Returns
    -------
    dict
        ``lost_motion_half_gap_rad``: mean(e) / 2, rad at the output;
        ``lost_motion_t``: its t statistic; ``lost_motion_p_value``: one-sided p of
        mean(e) > 0; ``lost_motion_events``: the reversals used;
        ``lost_motion_counts``: mean(e) in steps of the output encoder (the smallest
        non-zero step of the raw output angle).  Empty without an output angle, without
        a positive K, or with fewer than :data:`LOST_MOTION_MIN_EVENTS` reversals.
    """
    s = d.sig
    K = float(params.get("K_Nm_per_rad", 0.0))
    if s.th_l is None or s.raw_th_l is None or not K > 0:
        return {}
    N = s.ratio
    eps = d.v_eps * N
    moving = np.abs(s.w_m) > eps
    # smooth over a quarter period of the angle filter's cutoff (the states' bandwidth)
    w = max(1, int(round(0.25 / (s.fc_Hz * s.dt))))
    A = np.column_stack([N * s.tau, N * s.a_m, N * s.w_m, N * np.sign(s.w_m)])
    A = np.column_stack([np.convolve(a, np.ones(w) / w, mode="same") for a in A.T])
    T = A @ np.array([1.0, -params.get("J_m_kgm2", 0.0), -params.get("Fv_motor_Nms_per_rad", 0.0),
                      -params.get("Fc_motor_Nm", 0.0)])
    phi = s.phi
    spring = np.zeros_like(T)
    for _ in range(2):
        band = LOST_MOTION_BAND * float(np.percentile(np.abs(T), 99))
        side = np.where(T >= band, 1, np.where(T <= -band, -1, 0))
        # the twist the spring alone gives, phi regressed on the motor-side terms of T
        # (the output's quantisation is then noise of the regressed variable and does
        # not bias the coefficients as it biases the fitted K), with sgn(T) so that a
        # lost motion does not enter them; T is then taken from that regression's
        # inertia and friction (the second pass)
        out = (side != 0) & moving
        if int(out.sum()) < 10 or len(np.unique(side[out])) < 2:
            return {}
        X = np.column_stack([np.ones(int(out.sum())), A[out], np.sign(T[out])])
        sc = np.sqrt(np.sum(X ** 2, axis=0))
        sc[sc == 0] = 1.0
        coef, *_ = np.linalg.lstsq(X / sc, phi[out], rcond=None)
        coef = coef / sc
        if not coef[1] > 0:
            return {}
        spring = A @ coef[1:5]
        T = spring / coef[1]
    idx = np.flatnonzero(side != 0)
    ev = []
    for i0, i1 in zip(idx[:-1].tolist(), idx[1:].tolist()):
        if side[i0] == side[i1] or not (np.all(moving[i0:i1 + 1]) and abs(np.sum(np.sign(s.w_m[i0:i1 + 1])))
                                        == i1 + 1 - i0):
            continue
        dT = float(T[i1] - T[i0])
        ev.append(np.sign(dT) * (float(phi[i1] - phi[i0]) - float(spring[i1] - spring[i0])))
    if len(ev) < LOST_MOTION_MIN_EVENTS:
        return {}
    e = np.asarray(ev)
    sd = float(np.std(e, ddof=1))
    if not sd > 0:
        return {}
    tstat = float(np.mean(e)) / sd * float(np.sqrt(len(e)))
    steps = np.abs(np.diff(s.raw_th_l))
    steps = steps[steps > 0]
    q = float(np.min(steps)) if len(steps) else float("nan")
    return {"lost_motion_half_gap_rad": float(np.mean(e)) / 2, "lost_motion_t": tstat,
            "lost_motion_p_value": float(st.t.sf(tstat, len(e) - 1)), "lost_motion_events": float(len(e)),
            "lost_motion_counts": float(np.mean(e)) / q if q > 0 else float("nan")}
