"""Biquad designer for the drive's torque filters (notch, low-pass).

Designs second-order sections in double precision (bilinear transform with
frequency pre-warping at the loop rate), quantises them to the firmware's
Q2.30 format (``firmware/core/hd_biquad.h``), checks that the quantised poles
are inside the unit circle and that a notch reaches its depth, and exports the
raw coefficient words for the parameter table.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from .fw_const import LOOP_HZ  # noqa: E402

FS_HZ = float(LOOP_HZ)
Q30 = float(1 << 30)
Q30_MIN = -(1 << 31)
Q30_MAX = (1 << 31) - 1


class FilterDesignError(ValueError):
    """A filter cannot be designed or quantised as asked."""


@dataclass(frozen=True)
class Biquad:
    """One section, a0 = 1: H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)."""

    b: tuple[float, float, float]
    a: tuple[float, float]

    def tf(self) -> tuple[np.ndarray, np.ndarray]:
        """Numerator and denominator arrays (a with the leading 1)."""
        return np.array(self.b), np.array([1.0, *self.a])

    def response(self, f_hz: np.ndarray | float, fs_hz: float = FS_HZ) -> np.ndarray:
        """Complex frequency response at ``f_hz`` (Hz)."""
        b, a = self.tf()
        _, h = signal.freqz(b, a, worN=np.atleast_1d(np.asarray(f_hz, dtype=float)), fs=fs_hz)
        return h


def _round_half_away(x: float) -> int:
    return int(np.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


def notch(f0_hz: float, width_hz: float, depth_db: float, fs_hz: float = FS_HZ) -> Biquad:
    """Notch with finite depth.

    Parameters
    ----------
    f0_hz : centre frequency, Hz (0 < f0 < fs/2)
    width_hz : -3 dB-ish width of the denominator (2 zeta f0), Hz
    depth_db : gain at f0, dB (negative, e.g. -20)
    """
    if not 0 < f0_hz < fs_hz / 2 or width_hz <= 0 or depth_db >= 0:
        raise FilterDesignError(f"notch: need 0 < f0 < fs/2, width > 0, depth < 0 (got {f0_hz}, {width_hz}, {depth_db})")
    wp = 2 * fs_hz * np.tan(np.pi * f0_hz / fs_hz)      # pre-warped
    z2 = width_hz / (2 * f0_hz)
    z1 = z2 * 10 ** (depth_db / 20)
    b, a = signal.bilinear([1, 2 * z1 * wp, wp ** 2], [1, 2 * z2 * wp, wp ** 2], fs_hz)
    b, a = b / a[0], a / a[0]
    return Biquad((float(b[0]), float(b[1]), float(b[2])), (float(a[1]), float(a[2])))


def lowpass(fc_hz: float, zeta: float = 0.7071067811865476, fs_hz: float = FS_HZ) -> Biquad:
    """Second-order low-pass, unity DC gain, corner ``fc_hz`` (Hz), damping ``zeta``."""
    if not 0 < fc_hz < fs_hz / 2 or zeta <= 0:
        raise FilterDesignError(f"lowpass: need 0 < fc < fs/2 and zeta > 0 (got {fc_hz}, {zeta})")
    wp = 2 * fs_hz * np.tan(np.pi * fc_hz / fs_hz)
    b, a = signal.bilinear([wp ** 2], [1, 2 * zeta * wp, wp ** 2], fs_hz)
    b, a = b / a[0], a / a[0]
    return Biquad((float(b[0]), float(b[1]), float(b[2])), (float(a[1]), float(a[2])))


def quantise(bq: Biquad) -> tuple[int, int, int, int, int]:
    """Raw Q2.30 words (b0, b1, b2, a1, a2), rounded half away from zero.

    Raises
    ------
    FilterDesignError
        if a coefficient is outside [-2, 2) or the quantised poles are not
        strictly inside the unit circle.
    """
    vals = (*bq.b, *bq.a)
    raw = []
    for v in vals:
        r = _round_half_away(v * Q30)
        if not Q30_MIN <= r <= Q30_MAX:
            raise FilterDesignError(f"coefficient {v!r} outside the Q2.30 range [-2, 2)")
        raw.append(r)
    if pole_radius(dequantise(tuple(raw))) >= 1.0:
        raise FilterDesignError("quantised poles on or outside the unit circle")
    return tuple(raw)  # type: ignore[return-value]


def dequantise(raw: tuple[int, int, int, int, int]) -> Biquad:
    """Biquad with the exact values of the raw Q2.30 words."""
    b0, b1, b2, a1, a2 = (r / Q30 for r in raw)
    return Biquad((b0, b1, b2), (a1, a2))


def pole_radius(bq: Biquad) -> float:
    """Largest pole magnitude."""
    return float(np.max(np.abs(np.roots([1.0, *bq.a]))))


def notch_depth_db(bq: Biquad, f0_hz: float, fs_hz: float = FS_HZ) -> float:
    """Gain at ``f0_hz`` in dB."""
    return float(20 * np.log10(abs(bq.response(f0_hz, fs_hz)[0])))


def export_params(prefix: str, raw: tuple[int, int, int, int, int]) -> dict[str, int]:
    """Parameter-table entries ``<prefix>_b0`` .. ``<prefix>_a2`` with raw words."""
    return dict(zip((f"{prefix}_{k}" for k in ("b0", "b1", "b2", "a1", "a2")), raw))
