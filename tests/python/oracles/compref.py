"""Double-precision reference models of the firmware compensators.

Each function mirrors one C module in ``firmware/core`` (same equations and the
same discretisation, no quantisation), taking the *integer* parameters and
signals of the firmware and returning real-valued results in the firmware's
LSB units, so that tests can state tolerances in LSB.  Formats
(``firmware/core/hd_units.h``):

* output velocity: 2^-32 turn/s; angle: 2^-32 turn (Q32.32 turns);
* torque: Q15.16 N.m (LSB 2^-16 N.m); acceleration 2^-24 turn/s^2;
* stiffness-like gains (sigma0, k_i, k1, ke): Q23.8 N.m/turn;
* viscous-like gains (fv, sigma1, sigma2): Q15.16 N.m/(turn/s).

See docs/compensators.md for the equations and the measured tolerances.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from hdservo.fw_const import LOOP_HZ  # noqa: E402
TS = 1.0 / LOOP_HZ
Q16, Q30, Q32, Q48 = 2.0**16, 2.0**30, 2.0**32, 2.0**48


def sign_smooth(x: np.ndarray, eps: float) -> np.ndarray:
    """C1 smooth sign t(3 - t^2)/2, t = x/eps, +-1 beyond +-eps; plain sign if eps <= 0."""
    x = np.asarray(x, dtype=float)
    if eps <= 0:
        return np.sign(x)
    t = np.clip(x / eps, -1.0, 1.0)
    return t * (3.0 - t * t) / 2.0


def stribeck_g(v: np.ndarray, fc: float, fs: float, vs: float, delta: int) -> np.ndarray:
    """g(v) = fc + (fs - fc) exp(-|v/vs|^delta); all in the caller's units (vs > 0)."""
    v = np.asarray(v, dtype=float)
    if vs <= 0:
        return np.full_like(v, fc)
    d = 1 if delta == 1 else 2
    return fc + (fs - fc) * np.exp(-np.abs(v / vs) ** d)


def stribeck_map(v: np.ndarray, pos: Sequence[int], neg: Sequence[int], delta: int,
                 eps_v: int, tau_max: int) -> np.ndarray:
    """Stribeck feed-forward torque [Q16 LSB] for velocity v [2^-32 turn/s].

    Parameters
    ----------
    v : numpy.ndarray
        Velocity used by the map, 2^-32 turn/s.
    pos, neg : sequence of int
        (fc, fs, vs, fv) for v >= 0 / v < 0: Q16 N.m, Q16 N.m, 2^-32 turn/s,
        Q16 N.m/(turn/s).
    delta : int
        Stribeck exponent (1 or 2).
    eps_v : int
        Smooth-sign half width, 2^-32 turn/s.
    tau_max : int
        Output clamp, Q16 N.m.

    Returns
    -------
    numpy.ndarray
        Torque in Q16 LSB (real-valued).
    """
    v = np.asarray(v, dtype=float)
    out = np.empty_like(v)
    for sel, p in ((v >= 0, pos), (v < 0, neg)):
        fc, fs, vs, fv = (float(x) for x in p)
        g = stribeck_g(v[sel], fc, fs, vs, delta)
        out[sel] = sign_smooth(v[sel], eps_v) * g + fv * v[sel] / Q32
    return np.clip(out, -tau_max, tau_max)


def lugre_run(v: np.ndarray, e: np.ndarray, fc: int, fs: int, vs: int, delta: int,
              sigma0: int, sigma1: int, sigma2: int, k_obs: int, tau_max: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """LuGre observer with the exact exponential update (hd_lugre.h).

    Parameters
    ----------
    v : numpy.ndarray
        Velocity, 2^-32 turn/s, one per period.
    e : numpy.ndarray
        Position error, 2^-32 turn.
    fc, fs, vs, delta : int
        Stribeck curve g(v) (Q16 N.m, Q16 N.m, 2^-32 turn/s, exponent).
    sigma0 : int
        Q23.8 N.m/turn.
    sigma1, sigma2 : int
        Q16 N.m/(turn/s).
    k_obs : int
        Q16 1/s.
    tau_max : int
        Q16 N.m.

    Returns
    -------
    tau : numpy.ndarray
        Friction estimate, Q16 LSB (real).
    z : numpy.ndarray
        Bristle deflection, 2^-48 turn (real).
    """
    s0 = sigma0 / 256.0                     # N.m/turn
    s1 = sigma1 / Q16                       # N.m/(turn/s)
    s2 = sigma2 / Q16
    k = k_obs / Q16
    z = 0.0                                 # turn
    tau = np.empty(len(v))
    zs = np.empty(len(v))
    for i, (vi, ei) in enumerate(zip(np.asarray(v, float), np.asarray(e, float))):
        vt = vi / Q32                                   # turn/s
        g = max(float(stribeck_g(np.array(vi), fc, fs, vs, delta)) / Q16, 2.0**-16)
        z1 = z
        if vi != 0:
            zss = np.sign(vt) * g / s0
            a = s0 * abs(vt) * TS / g
            z1 = zss + (z - zss) * np.exp(-a)
        z1 -= k * TS * ei / Q32
        dz = z1 - z
        z = z1
        f = s0 * z1 + s1 * dz / TS + s2 * vt
        tau[i] = float(np.clip(f * Q16, -tau_max, tau_max))
        zs[i] = z1 * Q48
    return tau, zs


def maxwell_run(x: np.ndarray, k: Sequence[int], d: Sequence[int], compliance: int,
                tau_max: int) -> tuple[np.ndarray, np.ndarray]:
    """Maxwell-slip elements driven by x [2^-32 turn] (hd_maxwell.h).

    Returns
    -------
    tau : numpy.ndarray
        Hysteresis torque, Q16 LSB (real).
    dth : numpy.ndarray
        Lost-motion correction tau * compliance (2^-44 turn/N.m), 2^-32 turn (real, from the real tau).
    """
    x = np.asarray(x, dtype=float)
    s = np.zeros(len(k))
    kk = np.asarray(k, float) / 256.0         # N.m/turn
    dd = np.asarray(d, float)
    tau = np.empty(len(x))
    dth = np.empty(len(x))
    xp = x[0] if len(x) else 0.0
    for i, xi in enumerate(x):
        s = np.clip(s + (xi - xp), -dd, dd)
        xp = xi
        t = float(np.sum(kk * s / Q32)) * Q16
        tau[i] = float(np.clip(t, -tau_max, tau_max))
        dth[i] = tau[i] / Q16 * compliance / 2.0**44 * Q32
    return tau, dth


def te_run(theta_m: np.ndarray, order: Sequence[int], amp: Sequence[int], phase: Sequence[int],
           k1: int, tau_max: int) -> tuple[np.ndarray, np.ndarray]:
    """TE model and its corrections (hd_te_comp.h).

    Returns
    -------
    dth : numpy.ndarray
        -TE, 2^-32 turn (real).
    tau : numpy.ndarray
        -k1 TE, Q16 LSB (real).
    """
    th = np.asarray(theta_m, dtype=np.int64)
    frac = (th & 0xFFFFFFFF).astype(float) / Q32
    te = np.zeros(len(th))
    for o, a, p in zip(order, amp, phase):
        te += a * np.sin(2 * np.pi * ((o * frac + p / Q32) % 1.0))
    tau = np.clip(-te * k1 / 2.0**24, -tau_max, tau_max)
    return -te, tau


def backstep_run(cfg: Sequence[int], th0: Sequence[int], theta: np.ndarray, theta_d: np.ndarray,
                 omega: np.ndarray, omega_d: np.ndarray, acc_d: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Adaptive backstepping law + projected adaptation (hd_backstep.h), open-loop inputs.

    Parameters
    ----------
    cfg : sequence of int
        c1 c2 j ke eps_w w_s e1_max u_max gamma_dt[4] th_min[4] th_max[4] (firmware formats).
    th0 : sequence of int
        Initial parameters, Q16.
    theta, theta_d : numpy.ndarray
        Angles, 2^-32 turn (int64).
    omega, omega_d : numpy.ndarray
        Velocities, 2^-32 turn/s.
    acc_d : numpy.ndarray
        Reference acceleration, 2^-24 turn/s^2.

    Returns
    -------
    u : numpy.ndarray
        Torque, Q16 LSB (real).
    th : numpy.ndarray
        Parameters per period, shape (n, 4), Q16.48 LSB (real).
    """
    c1, c2, j, ke, eps_w, w_s, e1_max, u_max = (float(x) for x in cfg[:8])
    gdt = np.asarray(cfg[8:12], float) / 2.0**24
    lo = np.asarray(cfg[12:16], float) * Q32
    hi = np.maximum(np.asarray(cfg[16:20], float) * Q32, lo)
    th = np.clip(np.asarray(th0, float) * Q32, lo, hi)
    n = len(theta)
    u_out = np.empty(n)
    th_out = np.empty((n, 4))
    for i in range(n):
        e1 = float(np.clip(float(np.int64(theta[i]) - np.int64(theta_d[i])), -e1_max, e1_max))
        w = float(omega[i])
        alpha1 = omega_d[i] - c1 / Q16 * e1
        e2 = w - alpha1
        dalpha1 = acc_d[i] - c1 / Q16 * (w - omega_d[i]) / 2.0**8
        # the friction regressor: the reference velocity while it cruises (unchanged within
        # HD_BS_WD_STEADY = 64 since the last period), the measured one otherwise
        wd_prev = float(omega_d[i - 1]) if i > 0 else 0.0
        cruise = omega_d[i] != 0 and abs(float(omega_d[i]) - wd_prev) <= 64
        wr = float(omega_d[i]) if cruise else w
        sg = float(sign_smooth(np.array(wr), eps_w))
        phi = np.array([sg, np.exp(-(wr / w_s) ** 2) * sg if w_s > 0 else 0.0, wr / Q32, 1.0])
        u = j / Q16 * (dalpha1 - c2 / Q16 * e2 / 2.0**8) * Q16 / 2.0**24 \
            - ke / 256.0 * e1 / Q32 * Q16 + float(np.dot(th, phi)) / Q32
        ub = float(np.clip(u, -u_max, u_max))
        u_out[i] = ub
        if ub == u:
            # while the axis can stick (the reference at most 4 w_s fast and not cruising, the
            # axis at most w_s fast), T_load's box is widened by the friction bounds (Fc + Fs - Fc)
            lo_i, hi_i = lo.copy(), hi.copy()
            if (omega_d[i] != 0 and abs(float(omega_d[i])) <= 4.0 * w_s and not cruise
                    and abs(w) <= w_s):
                fs = (max(float(cfg[16]), 0.0) + max(float(cfg[17]), 0.0)) * Q32
                lo_i[3] -= fs
                hi_i[3] += fs
            th = np.clip(th - gdt * phi * e2 * 2.0**16, lo_i, hi_i)   # Q7.24 * 2^-32 turn/s -> Q48
        th_out[i] = th
    return u_out, th_out


# ---- Preisach ---------------------------------------------------------------------

def everett_lattice(grid: np.ndarray, sub_bits: int, a: int, b: int) -> float:
    """Interpolated Everett value (no rounding) at lattice (a, b), as hd_preisach_everett."""
    if a <= b:
        return 0.0
    n = 1 << sub_bits
    ia, fa = divmod(a, n)
    ib, fb = divmod(b, n)
    if sub_bits == 0:
        return float(grid[a, b])
    fa_, fb_ = fa / n, fb / n

    def e(i: int, j: int) -> float:
        return float(grid[i, j]) if i >= j and i < grid.shape[0] else 0.0

    if ia == ib:
        return (fa_ - fb_) * e(ia + 1, ia)
    return ((1 - fa_) * (1 - fb_) * e(ia, ib) + fa_ * (1 - fb_) * e(ia + 1, ib)
            + (1 - fa_) * fb_ * e(ia, ib + 1) + fa_ * fb_ * e(ia + 1, ib + 1))


def preisach_bruteforce(grid: np.ndarray, sub_bits: int, p_seq: Sequence[int],
                        deadband: int = 0) -> np.ndarray:
    """Relay-plane summation in double over the lattice (the unrounded model).

    Parameters
    ----------
    grid : numpy.ndarray
        L x L Everett grid (table entries, output LSB).
    sub_bits : int
        Lattice steps per grid cell = 2**sub_bits.
    p_seq : sequence of int
        Lattice inputs, 0..P.
    deadband : int
        Reversal dead-band in lattice steps (same filter as the firmware).

    Returns
    -------
    numpy.ndarray
        Output per sample, output LSB (real).
    """
    levels = grid.shape[0]
    ptop = (levels - 1) << sub_bits
    E = np.zeros((ptop + 2, ptop + 2))
    for a in range(ptop + 1):
        for b in range(a):
            E[a, b] = everett_lattice(grid, sub_bits, a, b)
    mu = np.zeros((ptop + 1, ptop + 1))
    for a in range(1, ptop + 1):
        for b in range(a):
            mu[a, b] = E[a, b] - E[a - 1, b] - E[a, b + 1] + (E[a - 1, b + 1] if a - 1 > b + 1 else 0.0)
    aa, bb = np.meshgrid(np.arange(ptop + 1), np.arange(ptop + 1), indexing="ij")
    valid = aa > bb
    state = np.zeros_like(valid)
    p_prev, direction = 0, 1
    out = np.empty(len(p_seq))
    y = -E[ptop, 0]
    for i, p in enumerate(p_seq):
        p = int(min(max(p, 0), ptop))
        if p != p_prev:
            d = 1 if p > p_prev else -1
            if not (d != direction and abs(p - p_prev) <= deadband):
                direction, p_prev = d, p
                state = np.where(valid & (aa <= p), True, np.where(bb >= p, False, state))
                y = 2.0 * float(np.sum(mu[state & valid])) - E[ptop, 0]
        out[i] = y
    return out
