"""Velocity tracking observer reference (firmware/core/hd_vel_observer.c)."""
from __future__ import annotations

import math
from dataclasses import dataclass

T_S = 1e-4


@dataclass
class ObserverRef:
    """Type-2 tracking loop on an angle (turns); velocity in turn/s.

    Parameters
    ----------
    bw_hz : bandwidth w / (2 pi), Hz
    zeta : damping ratio
    """

    bw_hz: float
    zeta: float
    theta: float = 0.0
    vel: float = 0.0
    kp_dt: float | None = None   # overrides 2 zeta w T (e.g. the firmware's quantised gain)
    ki_dt: float | None = None   # overrides w^2 T [1/s]

    def gains(self) -> tuple[float, float]:
        """(Kp T, Ki T) in use."""
        w = 2 * math.pi * self.bw_hz
        kp = 2 * self.zeta * w * T_S if self.kp_dt is None else self.kp_dt
        ki = w * w * T_S if self.ki_dt is None else self.ki_dt
        return kp, ki

    def step(self, theta_meas: float) -> float:
        """One period with the measured angle (turn); returns the velocity (turn/s)."""
        kp, ki = self.gains()
        e = theta_meas - self.theta
        self.vel += ki * e
        self.theta += T_S * self.vel + kp * e
        return self.vel

    def noise_gain(self) -> float:
        """RMS velocity noise per unit RMS of white angle noise (turn/s per turn), numerically."""
        import numpy as np
        from scipy import signal
        w = 2 * math.pi * self.bw_hz
        kp, ki = 2 * self.zeta * w * T_S, w * w * T_S
        # state x = [theta, vel]; e = m - theta
        a = np.array([[1 - kp - T_S * ki, T_S], [-ki, 1.0]])
        b = np.array([[kp + T_S * ki], [ki]])
        c = np.array([[0.0, 1.0]])
        _, h = signal.dimpulse((a, b, c, np.zeros((1, 1)), T_S), n=200000)
        return float(math.sqrt(np.sum(np.asarray(h[0]) ** 2)))
