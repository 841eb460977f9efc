"""The range of logs the discrepancy workflow is validated for, and the check of a log against it.

The held-apart corpus (docs/discrepancy.md, "Held-apart validation") covers logs sampled at
1-10 kHz, motor encoders of 14-20 bits and output encoders of 18-24 bits per revolution.
A log outside that range is still analysed, but its names and gaps are not covered by the
validation: the command says so in one line on stderr and in the JSON's ``notes``.

A finer encoder than the range only lowers the noise, so only a coarser one is flagged.
The resolution is the sidecar's ``*_encoder_counts_per_rev`` when present, else the
quantisation step of the angle column itself (:func:`quantum_bits`); an angle that is not
on a grid (a float from an estimator or a simulation without quantisation) has no
resolution to check.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

#: Sample rates the workflow is validated at, Hz (inclusive).
RATE_HZ: tuple[float, float] = (1000.0, 10000.0)
#: Motor encoder resolutions validated, bits per motor revolution (inclusive).
MOTOR_BITS: tuple[int, int] = (14, 20)
#: Output encoder resolutions validated, bits per output revolution (inclusive).
LOAD_BITS: tuple[int, int] = (18, 24)
#: Rate tolerance: a 1 kHz log whose sidecar period is 1.0005 ms is still a 1 kHz log.
_RATE_TOL = 0.01


@dataclass(frozen=True)
class LogRange:
    """What a log is: its rate and encoder resolutions (None: not known from the log).

    Attributes
    ----------
    rate_Hz : float
        Sample rate, Hz.
    motor_bits, load_bits : float or None
        Encoder resolution, bits per revolution of its shaft.
    """

    rate_Hz: float
    motor_bits: float | None
    load_bits: float | None


def quantum_bits(x: np.ndarray) -> float | None:
    """Resolution of a quantised angle, bits per revolution, or None if it is not on a grid.

    The smallest step between distinct values is the candidate quantum q; the angle is
    taken as quantised when 99 % of its distinct values lie within 1 % of q on the grid
    q·k from the first value.  Bits = log2(2π / q).

    Parameters
    ----------
    x : numpy.ndarray
        Angle samples, rad.
    """
    u = np.unique(np.asarray(x, dtype=float))
    if u.size < 3:
        return None
    d = np.diff(u)
    scale = max(float(np.max(np.abs(u))), 1e-300)
    d = d[d > 1e-12 * scale]
    if d.size == 0:
        return None
    q = float(np.min(d))
    k = (u - u[0]) / q
    if np.mean(np.abs(k - np.round(k)) < 0.01) < 0.99:
        return None
    return math.log2(2.0 * math.pi / q)


def log_range(meta: Mapping[str, Any], dt: float, motor: np.ndarray | None,
              load: np.ndarray | None) -> LogRange:
    """The rate and encoder resolutions of a log (sidecar first, then the data).

    Parameters
    ----------
    meta : mapping
        The sidecar.
    dt : float
        Sample period, s.
    motor, load : numpy.ndarray or None
        Raw motor / output angle, rad (None if the log has none).
    """
    def bits(key: str, x: np.ndarray | None) -> float | None:
        if x is None:
            return None
        c = meta.get(key)
        if isinstance(c, int) and not isinstance(c, bool) and c > 1:
            return math.log2(c)
        return quantum_bits(x)
    return LogRange(rate_Hz=1.0 / dt, motor_bits=bits("motor_encoder_counts_per_rev", motor),
                    load_bits=bits("load_encoder_counts_per_rev", load))


def outside(r: LogRange) -> list[str]:
    """What of a log lies outside the validated range, one phrase each (empty: inside)."""
    out: list[str] = []
    lo, hi = RATE_HZ
    if r.rate_Hz < lo * (1 - _RATE_TOL) or r.rate_Hz > hi * (1 + _RATE_TOL):
        out.append(f"sampled at {r.rate_Hz:.0f} Hz")
    if r.motor_bits is not None and r.motor_bits < MOTOR_BITS[0] - 0.05:
        out.append(f"motor encoder {r.motor_bits:.1f} bits")
    if r.load_bits is not None and r.load_bits < LOAD_BITS[0] - 0.05:
        out.append(f"output encoder {r.load_bits:.1f} bits")
    return out


def range_text() -> str:
    """The validated range in words."""
    return (f"{RATE_HZ[0] / 1000:g}-{RATE_HZ[1] / 1000:g} kHz, motor encoder >= {MOTOR_BITS[0]} bits, "
            f"output encoder >= {LOAD_BITS[0]} bits")


def warning(where: str, r: LogRange) -> str | None:
    """One line naming what lies outside the validated range, or None."""
    bad = outside(r)
    if not bad:
        return None
    return (f"{where}: {', '.join(bad)}: outside the range the workflow is validated for ({range_text()}); "
            "names and gaps are less reliable (docs/discrepancy.md)")


#: A two-encoder log whose twist spans fewer counts than this (99th percentile of its
#: magnitude over one count of the coarser encoder at the output) gets a note: the
#: corpus' lost-motion zones are 15 % x 0.5-1.5 of the peak twist wide per side, so at
#: 10 counts a zone is 1.5-4.5 counts across -- at the resolution itself.
TWIST_COUNTS_MIN = 10.0


def twist_resolution(r: LogRange, ratio: float) -> float | None:
    """One count of the coarser of the two encoders, rad at the output.

    Parameters
    ----------
    r : LogRange
        The log's rate and encoder resolutions.
    ratio : float
        Gear ratio N (motor angle / output angle).

    Returns
    -------
    float or None
        max(2π / 2^motor_bits / N, 2π / 2^output_bits); None unless both encoders'
        resolutions are known.
    """
    if r.motor_bits is None or r.load_bits is None:
        return None
    return max(2.0 * math.pi / 2.0 ** r.motor_bits / ratio, 2.0 * math.pi / 2.0 ** r.load_bits)


def twist_note(where: str, r: LogRange, ratio: float, twist_p99_rad: float) -> str | None:
    """One line when the log's twist spans fewer than :data:`TWIST_COUNTS_MIN` counts, else None.

    Parameters
    ----------
    where : str
        The log's name (starts the line).
    r : LogRange
        The log's rate and encoder resolutions.
    ratio : float
        Gear ratio N.
    twist_p99_rad : float
        99th percentile of the measured twist's magnitude, rad at the output.
    """
    q = twist_resolution(r, ratio)
    if q is None or not math.isfinite(twist_p99_rad) or twist_p99_rad >= TWIST_COUNTS_MIN * q:
        return None
    return (f"{where}: the twist spans {twist_p99_rad / q:.1f} counts of the coarser encoder (one count is "
            f"{q:.3g} rad at the output, expected >= {TWIST_COUNTS_MIN:g}): a lost-motion zone, hysteresis or "
            "stiffness change a few counts wide is not resolved, so backlash and hysteresis may go unnamed or "
            "be taken for each other")


def twist_p99(sig: Any) -> float:
    """99th percentile of the measured twist's magnitude, rad at the output (NaN without a
    load angle).

    Parameters
    ----------
    sig : hdservo.discrepancy.signals.Signals
    """
    if not getattr(sig, "has_load", False):
        return float("nan")
    return float(np.percentile(np.abs(sig.phi), 99))
