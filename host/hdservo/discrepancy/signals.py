"""Log -> states for the discrepancy workflow, with IDIM-style parallel filtering.

A log (the log format of docs/sim.md) gives the measured motor torque and one or two angles.
States are obtained the usual inverse-dynamics way: the angles are low-passed
zero-phase (Butterworth, cutoff ``fc_Hz``) and differentiated by central
differences.  Every regression column is built from these states at the log rate
and then passed, together with the measured torque, through the same zero-phase
decimation filter (:meth:`Signals.dec`), so that noise above the band of interest is
removed from both sides of the equation alike ("parallel filtering", Gautier).

Units: angles in rad (motor angle on the motor side, load angle at the output),
velocities rad/s, accelerations rad/s^2, torques N.m at the motor.  A linear axis
(EMPS, ``column_roles`` in the sidecar) uses m, m/s, N with ratio 1.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import scipy.signal as sps

from ..errors import UserError
from .. import logio

#: Angle low-pass cutoff relative to the sample rate (never above :data:`FC_MAX_HZ`).
FC_REL = 0.1
#: Upper limit of the angle low-pass cutoff, Hz (passes the 40-70 Hz torsional mode).
FC_MAX_HZ = 200.0
#: Decimated rate relative to the angle cutoff.
DEC_RATE_REL = 5.0


@dataclass
class Signals:
    """Filtered states of one log.

    Attributes
    ----------
    kind : str
        ``"two_mass"`` (motor and load angle) or ``"rigid"`` (one angle).
    ratio : float
        Gear ratio N (motor angle / load angle), 1 for a rigid single-coordinate log.
    dt : float
        Log sample period, s.
    fc_Hz : float
        Angle low-pass cutoff, Hz.
    q : int
        Decimation factor of the regression data.
    t : numpy.ndarray
        Log time, s.
    tau : numpy.ndarray
        Measured motor torque, N.m (N for a linear axis), log rate.
    th_m, w_m, a_m : numpy.ndarray
        Motor angle rad, velocity rad/s, acceleration rad/s^2 (motor side); for a
        rigid log the single coordinate.
    th_l, w_l, a_l : numpy.ndarray or None
        Load angle, velocity, acceleration (output side); None if absent.
    raw_th_m, raw_th_l : numpy.ndarray or None
        Unfiltered angles (for harmonics of the angle).
    units : dict
        Unit strings for plots (``angle``, ``torque``).
    meta : dict
        The sidecar.
    source : str
        The log's path (``"log"`` for a log not read from a file), named in error messages.
    """

    kind: str
    ratio: float
    dt: float
    fc_Hz: float
    q: int
    t: np.ndarray
    tau: np.ndarray
    th_m: np.ndarray
    w_m: np.ndarray
    a_m: np.ndarray
    th_l: np.ndarray | None
    w_l: np.ndarray | None
    a_l: np.ndarray | None
    raw_th_m: np.ndarray
    raw_th_l: np.ndarray | None
    units: dict[str, str] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    source: str = "log"          #: where the log came from (its path), for error messages
    #: The angle signals the log carries: ``"both"`` encoders, ``"motor"`` or ``"output"`` alone
    #: (the identifiability table, :data:`hdservo.discrepancy.IDENTIFIABLE`).
    angles: str = "both"
    _dec_cache: dict[int, np.ndarray] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ derived
    @property
    def has_load(self) -> bool:
        """True if a load angle is available (two encoders)."""
        return self.th_l is not None

    @property
    def phi(self) -> np.ndarray:
        """Measured twist theta_m/N - theta_l at the output, rad (zeros without a load angle)."""
        if self.th_l is None:
            return np.zeros_like(self.th_m)
        return self.th_m / self.ratio - self.th_l

    @property
    def dphi(self) -> np.ndarray:
        """Twist rate, rad/s."""
        if self.w_l is None:
            return np.zeros_like(self.w_m)
        return self.w_m / self.ratio - self.w_l

    @property
    def ddphi(self) -> np.ndarray:
        """Twist acceleration, rad/s^2."""
        if self.a_l is None:
            return np.zeros_like(self.a_m)
        return self.a_m / self.ratio - self.a_l

    @property
    def v_out(self) -> np.ndarray:
        """Output-side velocity used for friction signs, rad/s (load if present, else motor/N)."""
        return self.w_l if self.w_l is not None else self.w_m / self.ratio

    def dec(self, x: np.ndarray) -> np.ndarray:
        """Parallel filter: the angles' zero-phase Butterworth low-pass, then subsampling
        by :attr:`q`.  Applied alike to the measured torque and to every regression column.

        The decimated Nyquist rate is ``DEC_RATE_REL/2 = 2.5`` times the cutoff, where the
        zero-phase 4th-order Butterworth already attenuates by about 2 x 64 dB, so no
        separate anti-alias filter is needed.
        """
        x = _lowpass(np.asarray(x, dtype=float), self.fc_Hz, 1.0 / self.dt)
        if self.q <= 1:
            return x
        return np.ascontiguousarray(x[:: self.q])

    @property
    def t_dec(self) -> np.ndarray:
        """Time of the decimated samples, s."""
        return self.t[:: self.q] if self.q > 1 else self.t

    def n_dec(self) -> int:
        """Number of decimated samples."""
        return len(self.t[:: self.q]) if self.q > 1 else len(self.t)


def states_of(x: np.ndarray, fc: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Filtered angle, velocity, acceleration of a raw angle (the pipeline of :func:`from_log`)."""
    xf = _lowpass(x, fc, 1.0 / dt)
    v = _diff(xf, dt)
    return xf, v, _diff(v, dt)


def hf_noise_std(x: np.ndarray, fc: float, fs: float) -> float:
    """Standard deviation of a sensor's white noise from the signal's content above
    f_lo = max(``fc``, fs/4).

    The motion (and the torque that moves the axis) has no content above the angle
    cutoff fc; a white noise of variance s^2 puts the fraction 1 - f_lo/(fs/2) of it
    above f_lo.  In closed loop the measured current also carries real current up to
    the current loop's bandwidth (the loops feed the encoder noise back): between fc
    and ~1 kHz the torque's spectrum of a closed-loop simulator log is up to 4x its
    white level, flat above (docs/discrepancy.md).  So the level is taken from
    the upper half of the spectrum, above fs/4 (above any current-loop bandwidth of a
    drive sampled at fs), where only the sensor's noise is left.  Same unit as ``x``.
    """
    x = np.asarray(x, dtype=float)
    f_lo = max(fc, fs / 4.0)
    hp = x - _lowpass(x, f_lo, fs)
    # the part of a white noise's variance the zero-phase high-pass (1 - |H|^2) passes
    _, h = sps.sosfreqz(sps.butter(4, f_lo / (fs / 2.0), output="sos"), worN=4096)
    frac = max(float(np.mean((1.0 - np.abs(h) ** 2) ** 2)), 0.1)
    return float(np.sqrt(np.mean(hp ** 2) / frac))


def _diff(x: np.ndarray, dt: float) -> np.ndarray:
    return np.gradient(x, dt)


def _lowpass(x: np.ndarray, fc: float, fs: float) -> np.ndarray:
    sos = sps.butter(4, fc / (fs / 2.0), output="sos")
    return sps.sosfiltfilt(sos, x, padtype="odd", padlen=min(len(x) - 1, 300))


def resolve_columns(log: logio.Log) -> dict[str, str]:
    """Map rotary roles to the log's column names (identity unless ``column_roles`` says otherwise).

    Returns
    -------
    dict
        role (``motor_angle_rad``, ``load_angle_rad``, ``motor_torque_Nm``) -> column name.
    """
    out: dict[str, str] = {}
    roles = log.meta.get("column_roles") or {}
    for col, role in roles.items():
        if role and col in log.columns:
            out[role] = col
    for role in ("motor_angle_rad", "load_angle_rad", "motor_torque_Nm"):
        if role not in out and role in log.columns:
            out[role] = role
    return out


def from_log(log: logio.Log, structure: str | None = None, fc_Hz: float | None = None) -> Signals:
    """Prepare the states of a log.

    Parameters
    ----------
    log : hdservo.logio.Log
        A validated log.
    structure : str, optional
        ``"two_mass"`` or ``"rigid"``; default: two-mass when both angles are
        present, rigid otherwise.
    fc_Hz : float, optional
        Angle low-pass cutoff, Hz (default ``min(FC_REL*fs, FC_MAX_HZ)``).

    Raises
    ------
    UserError
        No torque column, no angle, too short, or a two-mass structure asked for
        a log with one angle.
    """
    where = str(log.path) if log.path else "log"
    cols = resolve_columns(log)
    if "motor_torque_Nm" not in cols:
        raise UserError(f"{where}: expected a column 'motor_torque_Nm' (or a column_roles entry for it)")
    if "motor_angle_rad" not in cols and "load_angle_rad" not in cols:
        raise UserError(f"{where}: expected a column 'motor_angle_rad' and/or 'load_angle_rad'")
    dt = float(log.meta["sample_period_s"])
    t = log.t
    if len(t) < 400:
        raise UserError(f"{where}: expected at least 400 samples, found {len(t)}")
    check_uniform(t, dt, where)
    fs = 1.0 / dt
    fc = float(fc_Hz) if fc_Hz else min(FC_REL * fs, FC_MAX_HZ)
    q = max(1, int(fs / (DEC_RATE_REL * fc)))
    ratio = float(log.meta["gear_ratio"])
    linear = any(c.endswith("_m") for c in cols.values())
    units = {"angle": "m" if linear else "rad", "velocity": "m/s" if linear else "rad/s",
             "torque": "N" if linear else "N·m", "acc": "m/s²" if linear else "rad/s²"}
    tau = log[cols["motor_torque_Nm"]]
    both = "motor_angle_rad" in cols and "load_angle_rad" in cols
    if structure is None:
        structure = "two_mass" if both else "rigid"
    if structure == "two_mass" and not both:
        raise UserError(f"{where}: a two-mass model needs both 'motor_angle_rad' and 'load_angle_rad'")

    def states(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return states_of(x, fc, dt)

    if "motor_angle_rad" in cols:
        raw_m = log[cols["motor_angle_rad"]]
        rat = ratio
    else:                                    # single load coordinate: treat it as the "motor" with N = 1
        raw_m = log[cols["load_angle_rad"]]
        rat = 1.0
    th_m, w_m, a_m = states(raw_m)
    th_l = w_l = a_l = raw_l = None
    if "load_angle_rad" in cols and "motor_angle_rad" in cols:
        raw_l = log[cols["load_angle_rad"]]
        th_l, w_l, a_l = states(raw_l)
    return Signals(kind=structure, ratio=rat, dt=dt, fc_Hz=fc, q=q, t=t, tau=tau,
                   th_m=th_m, w_m=w_m, a_m=a_m, th_l=th_l, w_l=w_l, a_l=a_l,
                   raw_th_m=raw_m, raw_th_l=raw_l, units=units, meta=dict(log.meta), source=where,
                   angles="both" if both else "motor" if "motor_angle_rad" in cols else "output")


def check_uniform(t: np.ndarray, dt: float, where: str) -> None:
    """Refuse a log that is not sampled every ``dt`` (one error line: where, what, expected).

    The states come from filters and central differences that assume one sample every
    ``sample_period_s``: a logger that lost samples (a step of 1.5 dt or more) or a
    sidecar with the wrong period (mean step off by more than 1 %) would give wrong
    velocities, accelerations and every residual after them.  Timestamp jitter below
    half a period is accepted (the samples are taken as uniform).  The mean step is checked
    first, so a wrong period is named as such and not as a gap.
    """
    d = np.diff(t)
    if d.size == 0:
        return
    mean = float(t[-1] - t[0]) / d.size
    if abs(mean - dt) > 0.01 * dt:
        raise UserError(f"{where}: t_s advances {mean:.6g} s per sample on average, but the sidecar's "
                        f"sample_period_s is {dt:.6g} s (expected within 1 %)")
    bad = np.flatnonzero((d > 1.5 * dt) | (d < 0.5 * dt))
    if bad.size:
        k = int(bad[0])
        raise UserError(f"{where}: t_s steps by {d[k]:.6g} s at row {k + 2} (t_s = {t[k + 1]:.6g} s), expected one "
                        f"sample every sample_period_s = {dt:.6g} s; a log with lost samples must be cut or "
                        "filled there")


def read(path: str | Path, structure: str | None = None) -> Signals:
    """Read a log file and prepare its states (see :func:`from_log`)."""
    return from_log(logio.read_log(path), structure)
