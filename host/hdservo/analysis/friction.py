"""Describing functions of friction: Coulomb and Stribeck (harmonic-drive.md 4.1, 7).

Friction is a static map of *velocity*: ``F(v) = g(v) sgn(v) + f_v v`` with
``g(v) = F_c + (F_s - F_c) exp(-|v/v_s|^delta)`` (Stribeck; ``F_s = F_c`` gives
Coulomb).  Its DF with respect to the velocity amplitude ``A_v`` is real:

* Coulomb + viscous: ``N_v = f_v + 4 F_c / (pi A_v)``
* Stribeck: ``N_v = f_v + 4 F_c/(pi A_v) + 4 (F_s - F_c)/(pi A_v) I(A_v/v_s)`` with
  ``I(a) = int_0^{pi/2} exp(-(a sin t)^delta) sin t dt``; for ``delta = 2``
  ``I(a) = D(a)/a`` (D = Dawson's integral), otherwise by adaptive quadrature.

With respect to the *position* amplitude ``A`` at angular frequency ``w``
(``x = A sin wt``, ``v = A w cos wt``): ``N_x(A) = j w N_v(A w)``
(:class:`FrictionOnPosition`), e.g. Coulomb ``j 4 F_c / (pi A)``, an
equivalent viscous coefficient ``c_eq = 4 F_c / (pi A w)``.

Direction-asymmetric friction has a bias term that a single-input DF ignores;
the analysis uses the mean of the two directions' levels.
"""
from __future__ import annotations

import math
from typing import Any, Dict

import numpy as np
from scipy import integrate, special

from .dfbase import HdNonlinearity


class StribeckFriction(HdNonlinearity):
    """Static Stribeck friction map torque(velocity).

    Parameters
    ----------
    fc : float
        Coulomb level F_c (N m, > 0 unless ``fs`` is 0 too).
    fs : float
        Static (breakaway) level F_s (N m, >= 0).
    vs : float
        Stribeck velocity v_s (rad/s, > 0).
    delta : float
        Stribeck shape exponent (dimensionless, > 0; 2 = Gaussian).
    fv : float
        Viscous coefficient f_v (N m s/rad, >= 0).
    side : str
        ``"motor"`` or ``"load"``: where the friction acts (for reports only).
    """

    kind = "stribeck"
    input_name = "velocity"
    input_unit = "rad/s"
    output_name = "friction torque"
    output_unit = "N*m"

    def __init__(self, fc: float, fs: float, vs: float, delta: float = 2.0, fv: float = 0.0,
                 side: str = "motor") -> None:
        super().__init__()
        if fc < 0 or fs < 0 or fv < 0:
            raise ValueError("friction levels and viscous coefficient must be >= 0")
        if vs <= 0 or delta <= 0:
            raise ValueError("Stribeck velocity and exponent must be > 0")
        self.fc, self.fs, self.vs, self.delta, self.fv = float(fc), float(fs), float(vs), float(delta), float(fv)
        self.side = side

    def _isstatic(self) -> bool:
        return True

    def __call__(self, v: float) -> float:
        if v == 0.0:
            return 0.0
        g = self.fc + (self.fs - self.fc) * math.exp(-abs(v / self.vs) ** self.delta)
        return math.copysign(g, v) + self.fv * v

    @staticmethod
    def stribeck_integral(a: float, delta: float) -> float:
        """``I(a) = int_0^{pi/2} exp(-(a sin t)^delta) sin t dt`` (dimensionless).

        Closed form ``D(a)/a`` (Dawson's integral) for ``delta = 2``;
        adaptive quadrature otherwise.
        """
        if a <= 0.0:
            return 1.0
        if delta == 2.0:
            return float(special.dawsn(a)) / a
        val, _ = integrate.quad(lambda t: math.exp(-(a * math.sin(t)) ** delta) * math.sin(t),
                                0.0, math.pi / 2, limit=200, epsabs=1e-13, epsrel=1e-11)
        return val

    def describing_function(self, A: float) -> complex:
        """N_v(A_v) (N m s/rad), real; ``inf`` at ``A_v = 0`` when F_c or F_s > 0."""
        if A < 0:
            raise ValueError("cannot evaluate a describing function for A < 0")
        if A == 0:
            return complex(math.inf if (self.fc > 0 or self.fs > 0) else self.fv)
        n = self.fv + 4.0 * self.fc / (math.pi * A)
        if self.fs != self.fc:
            n += 4.0 * (self.fs - self.fc) / (math.pi * A) * self.stribeck_integral(A / self.vs, self.delta)
        return complex(n)

    def amplitude_scale(self) -> float:
        return self.vs

    def to_dict(self) -> Dict[str, Any]:
        d = super().to_dict()
        d.update(side=self.side, fc_Nm=self.fc, fs_Nm=self.fs, vs_rad_s=self.vs, delta=self.delta,
                 viscous_Nms_per_rad=self.fv)
        return d


class CoulombFriction(StribeckFriction):
    """Coulomb + viscous friction ``F = F_c sgn(v) + f_v v`` (N m of rad/s).

    Parameters
    ----------
    fc : float
        Coulomb level (N m, >= 0).
    fv : float
        Viscous coefficient (N m s/rad, >= 0).
    side : str
        ``"motor"`` or ``"load"``.
    """

    kind = "coulomb"

    def __init__(self, fc: float, fv: float = 0.0, side: str = "motor") -> None:
        super().__init__(fc=fc, fs=fc, vs=1.0, delta=2.0, fv=fv, side=side)

    def amplitude_scale(self) -> float:
        return 1.0

    def to_dict(self) -> Dict[str, Any]:
        d = super().to_dict()
        for k in ("fs_Nm", "vs_rad_s", "delta"):
            d.pop(k)
        return d


class FrictionOnPosition(HdNonlinearity):
    """A velocity friction map seen from the position, at a fixed frequency.

    ``N_x(A) = j w N_v(A w)``: the first harmonic of ``F(v)`` for
    ``x = A sin wt`` relative to ``x``.

    Parameters
    ----------
    friction : StribeckFriction
        The velocity map.
    omega : float
        Angular frequency of the position oscillation (rad/s, > 0).
    """

    kind = "friction_on_position"
    input_name = "position"
    input_unit = "rad"
    output_name = "friction torque"
    output_unit = "N*m"

    def __init__(self, friction: StribeckFriction, omega: float) -> None:
        super().__init__()
        if omega <= 0:
            raise ValueError("omega must be > 0")
        self.friction, self.omega = friction, float(omega)
        self.kind = f"{friction.kind}_on_position"

    def __call__(self, x: float) -> float:
        raise NotImplementedError("friction on position needs the velocity: use describing_function")

    def describing_function(self, A: float) -> complex:
        """N_x(A) (N m/rad), purely imaginary: an equivalent damping ``Im N_x / w``."""
        return 1j * self.omega * self.friction.describing_function(A * self.omega)

    def numerical_df(self, A: float, num_points: int | None = None) -> complex:
        """First harmonic of ``F(A w cos theta)`` relative to ``A sin theta``."""
        n = int(num_points or self.num_points)
        theta = 2.0 * np.pi * np.arange(n) / n
        y = np.array([self.friction(float(v)) for v in A * self.omega * np.cos(theta)])
        b1 = 2.0 / n * float(y @ np.sin(theta))
        a1 = 2.0 / n * float(y @ np.cos(theta))
        return complex(b1, a1) / A

    def to_dict(self) -> Dict[str, Any]:
        d = self.friction.to_dict()
        d.update(kind=self.kind, input=f"{self.input_name} [{self.input_unit}]", omega_rad_s=self.omega)
        return d
