"""PID reference (firmware/core/hd_pid.c) in real arithmetic.

Units follow the firmware: ``ref``/``meas``/``ff`` in input LSB, output in
output LSB; gains are real numbers (the firmware's raw gain / 2**shift).
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class PidRef:
    """Real-valued PID with conditional integration and filtered derivative on measurement.

    Parameters
    ----------
    kp : output LSB per input LSB
    ki_dt : Ki * T, output LSB per input LSB per period
    kd_fs : Kd / T
    alpha : derivative filter coefficient (0, 1]
    out_min, out_max : output limits
    """

    kp: float
    ki_dt: float
    kd_fs: float
    alpha: float
    out_min: float
    out_max: float
    integ: float = 0.0
    dfilt: float = 0.0
    meas_prev: float | None = None
    i_term: float = field(default=0.0)

    def step(self, ref: float, meas: float, ff: float) -> float:
        """One period; returns the limited output (real)."""
        e = ref - meas
        dmeas = 0.0 if self.meas_prev is None else meas - self.meas_prev
        self.meas_prev = meas
        self.dfilt += self.alpha * (dmeas - self.dfilt)
        p = self.kp * e
        d = -self.kd_fs * self.dfilt
        integ_new = min(max(self.integ + self.ki_dt * e, self.out_min), self.out_max)
        u = p + integ_new + d + ff
        if (u > self.out_max and integ_new > self.integ) or (u < self.out_min and integ_new < self.integ):
            integ_new = self.integ
            u = p + integ_new + d + ff
        self.integ = integ_new
        self.i_term = integ_new
        return min(max(u, self.out_min), self.out_max)
