"""Trajectory references (firmware/core/hd_trajectory.c): exact rate and sine."""
from __future__ import annotations

import math
from fractions import Fraction

from hdservo.fw_const import LOOP_HZ  # noqa: E402


def rate_position_p48(k: int, v_raw: int, p0_p48: int = 0) -> int:
    """Exact position (2^-48 turn) after ``k`` periods at ``v_raw`` (2^-32 turn/s)."""
    return p0_p48 + math.floor(Fraction(k * v_raw * 65536, LOOP_HZ))


def sine_position(k: int, center: float, amp: float, f_hz: float) -> float:
    """center + amp sin(2 pi f k T) (same units as center/amp)."""
    return center + amp * math.sin(2 * math.pi * f_hz * k / LOOP_HZ)
