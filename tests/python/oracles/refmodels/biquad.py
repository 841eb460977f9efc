"""Biquad chain reference (firmware/core/hd_biquad.c): scipy lfilter in double."""
from __future__ import annotations

import numpy as np
from scipy import signal

from hdservo.filters import Biquad


def chain(sections: list[Biquad], x: np.ndarray) -> np.ndarray:
    """Filter ``x`` through the sections in order (real arithmetic)."""
    y = np.asarray(x, dtype=float)
    for s in sections:
        b, a = s.tf()
        y = signal.lfilter(b, a, y)
    return y
