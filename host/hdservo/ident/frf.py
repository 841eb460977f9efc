"""Frequency response: closed-loop H1-type estimate, coherence, two-mass model.

Experiment (:class:`.experiments.FRFExcitation`): velocity-mode multisine on
a constant bias speed, so neither the motor nor the load reverses (friction
stays sliding: viscous only) and the gear stays in one stiffness region.
With reference r, motor torque u (x N, output side) and motor angle y
(/ N, output side), averaged over whole multisine periods (Welch, one
period per segment, transient dropped)::

    G = S_ry / S_ru        (unbiased by the feedback; = H1 = S_uy/S_uu open loop)
    coherence gamma^2 = |S_ru|^2 / (S_rr S_uu)

Two-mass model (output side; J1 = N^2 J_m, J2 = J_L, K, c, viscous b1, b2)::

    G(s) = (J2 s^2 + (b2 + c) s + K) / ( (J1 s^2 + b1 s + K + c s)(J2 s^2 + b2 s + K + c s) - (K + c s)^2 )

fitted by least squares on the complex log of G over the coherent lines;
anti-resonance f_a = sqrt(K/J2)/2pi, resonance f_r = sqrt(K (1/J1 + 1/J2))/2pi.
The dip and peak of the measured |G| (parabolic refinement) are reported too.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import csd, welch

from ..errors import UserError
from .experiments import ExperimentData


def two_mass(s: np.ndarray, j1: float, j2: float, k: float, c: float, b1: float, b2: float) -> np.ndarray:
    """Motor angle / motor torque (output side), rad/(N.m)."""
    ks = k + c * s
    num = j2 * s ** 2 + (b2 + c) * s + k
    den = (j1 * s ** 2 + b1 * s + ks) * (j2 * s ** 2 + b2 * s + ks) - ks ** 2
    return num / den


@dataclass
class FRFResult:
    """FRF of one amplitude and the two-mass fit."""

    amplitude_rad_s: float
    f_Hz: np.ndarray
    G: np.ndarray
    coherence: np.ndarray
    j1_kgm2: float
    j2_kgm2: float
    k_Nm_per_rad: float
    c_Nms_per_rad: float
    b1_Nms_per_rad: float
    b2_Nms_per_rad: float
    f_antiresonance_Hz: float
    f_resonance_Hz: float
    f_dip_Hz: float
    f_peak_Hz: float
    fit_rms_log: float

    def model(self, f: np.ndarray) -> np.ndarray:
        return two_mass(2j * math.pi * f, self.j1_kgm2, self.j2_kgm2, self.k_Nm_per_rad, self.c_Nms_per_rad,
                        self.b1_Nms_per_rad, self.b2_Nms_per_rad)

    def to_dict(self) -> dict[str, Any]:
        return {"amplitude_rad_s": self.amplitude_rad_s, "j1_kgm2": self.j1_kgm2, "j2_kgm2": self.j2_kgm2,
                "k_Nm_per_rad": self.k_Nm_per_rad, "c_Nms_per_rad": self.c_Nms_per_rad,
                "b1_Nms_per_rad": self.b1_Nms_per_rad, "b2_Nms_per_rad": self.b2_Nms_per_rad,
                "f_antiresonance_Hz": self.f_antiresonance_Hz, "f_resonance_Hz": self.f_resonance_Hz,
                "f_dip_Hz": self.f_dip_Hz, "f_peak_Hz": self.f_peak_Hz, "fit_rms_log": self.fit_rms_log,
                "min_coherence_fit_band": float(np.min(self.coherence)) if len(self.coherence) else None}


def _parabolic(f: np.ndarray, y: np.ndarray, i: int) -> float:
    if 0 < i < len(y) - 1:
        a, b, c = y[i - 1], y[i], y[i + 1]
        den = a - 2 * b + c
        if den != 0:
            return float(f[i] + 0.5 * (a - c) / den * (f[1] - f[0]))
    return float(f[i])


def estimate_frf(seg: dict[str, np.ndarray], desc: dict[str, Any], ratio: float, dt: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(f, G, coherence) at the excited lines of one multisine segment."""
    t = seg["t_s"] - seg["t_s"][0]
    m = t >= float(desc["settle_s"]) + float(desc["period_s"])   # one period of transient dropped
    r = seg["setpoint_velocity_rad_s"][m]
    u = seg["motor_torque_Nm"][m] * ratio
    y = seg["motor_angle_rad"][m] / ratio
    y = y - np.polyval(np.polyfit(t[m], y, 1), t[m])              # remove the bias rotation
    nper = int(round(float(desc["period_s"]) / dt))
    if len(r) < 2 * nper:
        raise UserError("frf: fewer than two excitation periods after the transient")
    kw = dict(fs=1.0 / dt, window="boxcar", nperseg=nper, noverlap=0, detrend="constant")
    f, s_ry = csd(r, y, **kw)
    _, s_ru = csd(r, u, **kw)
    _, s_rr = welch(r, **kw)
    _, s_uu = welch(u, **kw)
    lines = np.linspace(float(desc["f0_Hz"]), float(desc["f1_Hz"]), int(desc["lines"]))
    idx = np.unique(np.clip(np.round(lines / (f[1] - f[0])).astype(int), 1, len(f) - 1))
    G = s_ry[idx] / s_ru[idx]
    coh = np.abs(s_ru[idx]) ** 2 / (s_rr[idx].real * s_uu[idx].real)
    return f[idx], G, coh


def fit_frf(data: ExperimentData, coherence_min: float = 0.9, f_fit_max_Hz: float | None = None
            ) -> list[FRFResult]:
    """FRF and two-mass fit for every amplitude of an ``frf`` experiment."""
    if data.kind != "frf":
        raise UserError(f"frf: expected frf data, found '{data.kind}'")
    N = data.gear_ratio
    dt = float(data.meta["sample_period_s"])
    out = []
    for desc in data.segments:
        seg = data.segment(desc["index"])
        f, G, coh = estimate_frf(seg, desc, N, dt)
        ok = coh >= coherence_min
        if f_fit_max_Hz:
            ok &= f <= f_fit_max_Hz
        if ok.sum() < 8:
            raise UserError(f"frf: only {int(ok.sum())} lines with coherence >= {coherence_min}")
        fo, Go = f[ok], G[ok]
        s = 2j * math.pi * fo
        # start: rigid body 1/(J s^2) below the mode, dip and peak of |G| w^2 above the viscous corner
        mag = np.abs(Go) * (2 * math.pi * fo) ** 2          # |G| w^2: flat 1/J outside the mode
        band = fo >= 5.0 * fo.min()
        ib = np.where(band)[0] if band.sum() >= 8 else np.arange(len(fo))
        i_dip = int(ib[np.argmin(mag[ib])])
        low = ib[fo[ib] <= 0.5 * fo[i_dip]]
        jt = float(1.0 / np.median(mag[low])) if len(low) else float(1.0 / mag[ib[0]])
        wa = 2 * math.pi * fo[i_dip]
        i_pk = i_dip + int(np.argmax(mag[i_dip:]))
        wr = 2 * math.pi * fo[i_pk] if i_pk > i_dip else 1.3 * wa
        ratio2 = max((wr / wa) ** 2 - 1.0, 0.05)           # J2/J1
        j1 = jt / (1 + ratio2)
        j2 = jt - j1
        k0 = wa ** 2 * j2

        def resid(p: np.ndarray) -> np.ndarray:
            j1_, j2_, k_, c_, b1_, b2_ = np.exp(p)
            e = np.log(two_mass(s, j1_, j2_, k_, c_, b1_, b2_) / Go)
            return np.concatenate([e.real, e.imag])

        p0 = np.log([j1, j2, k0, 0.02 * k0 / wa, 0.05 * jt * wa, 0.05 * jt * wa])
        lo = p0 - np.array([3, 3, 3, 12, 12, 12])
        hi = p0 + np.array([3, 3, 3, 6, 6, 6])
        sol = least_squares(resid, p0, bounds=(lo, hi), x_scale="jac", max_nfev=4000)
        j1_, j2_, k_, c_, b1_, b2_ = (float(v) for v in np.exp(sol.x))
        fa = math.sqrt(k_ / j2_) / (2 * math.pi)
        fr = math.sqrt(k_ * (1 / j1_ + 1 / j2_)) / (2 * math.pi)
        lm = np.log(mag)
        out.append(FRFResult(amplitude_rad_s=float(desc["amplitude_rad_s"]), f_Hz=f, G=G, coherence=coh[ok],
                             j1_kgm2=j1_, j2_kgm2=j2_, k_Nm_per_rad=k_, c_Nms_per_rad=c_, b1_Nms_per_rad=b1_,
                             b2_Nms_per_rad=b2_, f_antiresonance_Hz=fa, f_resonance_Hz=fr,
                             f_dip_Hz=_parabolic(fo, lm, i_dip), f_peak_Hz=_parabolic(fo, lm, i_pk),
                             fit_rms_log=float(np.sqrt(np.mean(sol.fun ** 2)))))
    return out
