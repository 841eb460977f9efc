"""Unwrapping the drive's wrapping words: 2^-32-turn encoder phases and the 32-bit loop tick.

The drive sends each encoder angle as an unsigned 32-bit phase (2^32 per turn)
and its loop tick as an unsigned 32-bit count; both wrap.  Consecutive samples
are taken to be less than half a wrap apart (half a turn, 2^31 ticks), so each
step is the signed difference modulo 2^32.  :func:`unwrap_count` continues a
whole capture of 32-bit counts (in counts), :func:`unwrap_turns` a whole capture
of phases (in turns), :func:`unwrap_phase` and :func:`unwrap_tick` continue a
stream one frame at a time; all four follow the same rule.  :func:`unwrap_pair`
unwraps a reference and the output that follows it as one: the output is the
reference plus their signed difference, so the two never land a turn apart.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

WRAP = 2 ** 32
HALF = 2 ** 31


def _signed_step(d: "np.ndarray | int") -> "np.ndarray | int":
    """A difference of two 32-bit words as the signed step in [-2^31, 2^31)."""
    return ((d + HALF) % WRAP) - HALF


def unwrap_count(words: np.ndarray, centred: bool = True) -> np.ndarray:
    """Continuous count from a wrapping 32-bit count (signed or unsigned words).

    Parameters
    ----------
    words : numpy.ndarray
        The counts as read: unsigned (0 .. 2^32 - 1) or signed (-2^31 .. 2^31 - 1)
        32-bit words, integer-valued (a float array of whole numbers is taken as is).
    centred : bool
        The first sample in [-2^31, 2^31) (True) or in [0, 2^32) (False); a signed
        first word stays as it is with True.

    Returns
    -------
    numpy.ndarray
        The count (same unit as the words), float; empty for an empty input.
    """
    w = np.asarray(words).astype(np.int64)
    if w.size == 0:
        return np.zeros(0)
    d = _signed_step(np.diff(w))
    first = w[0] % WRAP
    if centred and first >= HALF:
        first -= WRAP
    return (first + np.concatenate([[0], np.cumsum(d)])).astype(float)


def unwrap_turns(words: np.ndarray, centred: bool = True) -> np.ndarray:
    """Continuous angle (turns) from wrapped unsigned 2^-32-turn phases.

    Parameters
    ----------
    words : numpy.ndarray
        The phases as read (0 .. 2^32 - 1, 2^-32 turn).
    centred : bool
        The first sample in [-0.5, 0.5) turn (True) or in [0, 1) turn (False).

    Returns
    -------
    numpy.ndarray
        Angle (turns), float; empty for an empty input.
    """
    return unwrap_count(words, centred) / float(WRAP)


def unwrap_pair(ref_words: np.ndarray, out_words: np.ndarray,
                centred: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A reference and the output that follows it (turns), unwrapped consistently.

    Unwrapping the two captures separately puts them a whole turn apart whenever
    their first samples fall on either side of the wrap (an axis at rest at the
    turn boundary: reference just above it, output just below), which reads as a
    one-turn (1,296,000 arcsec) error.  Here the reference is unwrapped and the
    output is the reference plus the signed difference of the two words, taken to
    be within half a turn (a following error that large is a fault anyway).

    Parameters
    ----------
    ref_words, out_words : numpy.ndarray
        The reference's and the output's phases as read, sample for sample
        (0 .. 2^32 - 1, 2^-32 turn); the same length.
    centred : bool
        The reference's first sample in [-0.5, 0.5) turn (True) or in [0, 1) turn (False).

    Returns
    -------
    tuple of numpy.ndarray
        The reference and the output (turns), float.

    Raises
    ------
    ValueError
        When the two captures differ in length.
    """
    r = np.asarray(ref_words).astype(np.int64)
    o = np.asarray(out_words).astype(np.int64)
    if r.shape != o.shape:
        raise ValueError(f"unwrap_pair: the reference has {r.size} samples, the output {o.size}; "
                         "expected the same number")
    ref = unwrap_turns(r, centred)
    return ref, ref + _signed_step(o - r) / float(WRAP)


def unwrap_phase(prev_turns: Optional[float], phase_u32: int) -> float:
    """Continue a multi-turn angle (turns) from a wrapped 2^32-per-turn phase.

    Parameters
    ----------
    prev_turns : float or None
        The previous unwrapped angle (turns); None for the first frame.
    phase_u32 : int
        The new phase (0 .. 2^32 - 1).

    Returns
    -------
    float
        The angle (turns) nearest ``prev_turns`` with this phase; the first
        frame in [-0.5, 0.5) turn.
    """
    frac = phase_u32 / float(WRAP)
    if prev_turns is None:
        return frac if frac < 0.5 else frac - 1.0
    base = math.floor(prev_turns)
    cands = (base - 1 + frac, base + frac, base + 1 + frac)
    return min(cands, key=lambda c: abs(c - prev_turns))


def unwrap_tick(prev: Optional[int], tick_u32: int) -> int:
    """Continue a loop-tick count from the drive's wrapping 32-bit tick (0x5F00, TPDO bytes 0-3).

    The tick wraps every 2^32 periods (5 days at 10 kHz); the unwrapped count is the one
    nearest ``prev`` (frames of a stream are at most 2^31 ticks apart).
    """
    if prev is None:
        return int(tick_u32)
    return prev + int(_signed_step(int(tick_u32) - prev))


__all__ = ["HALF", "WRAP", "unwrap_count", "unwrap_pair", "unwrap_phase", "unwrap_tick", "unwrap_turns"]
