"""Describing functions of nonlinear torsional stiffness (harmonic-drive.md 5, 7).

* Three-slope (sum-of-saturations form)::

      T(phi) = K3 phi + (K1 - K2) sat_phi1(phi) + (K2 - K3) sat_phi2(phi)
      phi1 = T1/K1,  phi2 = phi1 + (T2 - T1)/K2
      N(A) = K3 + (K1 - K2) g(phi1/A) + (K2 - K3) g(phi2/A)

  with ``g`` the unit saturation DF (:func:`~hdservo.analysis.dfbase.sat_df`).
* Cubic: ``T = k1 phi + k3 phi^3``, ``N(A) = k1 + 3/4 k3 A^2``.

Both are real (no hysteresis): they shift the torsional resonance with the
twist amplitude.
"""
from __future__ import annotations

import math
from typing import Any, Dict

from .dfbase import HdNonlinearity, sat_df


class _Stiffness(HdNonlinearity):
    input_name = "twist"
    input_unit = "rad"
    output_name = "spring torque"
    output_unit = "N*m"

    def _isstatic(self) -> bool:
        return True


class ThreeSlopeStiffness(_Stiffness):
    """Catalogue three-slope torque/twist curve of a harmonic drive.

    Parameters
    ----------
    k1, k2, k3 : float
        Slopes below T1, between T1 and T2, above T2 (N m/rad, > 0).
    t1, t2 : float
        Breakpoint torques (N m, 0 <= t1 <= t2).
    """

    kind = "three_slope"

    def __init__(self, k1: float, k2: float, k3: float, t1: float, t2: float) -> None:
        super().__init__()
        if min(k1, k2, k3) <= 0:
            raise ValueError("stiffness slopes must be > 0")
        if not 0 <= t1 <= t2:
            raise ValueError("breakpoint torques need 0 <= t1 <= t2")
        self.k1, self.k2, self.k3, self.t1, self.t2 = map(float, (k1, k2, k3, t1, t2))
        self.phi1 = self.t1 / self.k1
        self.phi2 = self.phi1 + (self.t2 - self.t1) / self.k2

    @staticmethod
    def _sat(x: float, d: float) -> float:
        return max(-d, min(d, x))

    def __call__(self, phi: float) -> float:
        return (self.k3 * phi + (self.k1 - self.k2) * self._sat(phi, self.phi1)
                + (self.k2 - self.k3) * self._sat(phi, self.phi2))

    def describing_function(self, A: float) -> complex:
        """N(A) (N m/rad), real; K1 for A <= phi1, tends to K3 for large A."""
        if A < 0:
            raise ValueError("cannot evaluate a describing function for A < 0")
        if A == 0:
            return complex(self.k1)
        g1 = sat_df(self.phi1 / A) if self.phi1 > 0 else 0.0
        g2 = sat_df(self.phi2 / A) if self.phi2 > 0 else 0.0
        return complex(self.k3 + (self.k1 - self.k2) * g1 + (self.k2 - self.k3) * g2)

    def amplitude_scale(self) -> float:
        return self.phi2 if self.phi2 > 0 else 1e-4

    def to_dict(self) -> Dict[str, Any]:
        d = super().to_dict()
        d.update(k1_Nm_per_rad=self.k1, k2_Nm_per_rad=self.k2, k3_Nm_per_rad=self.k3,
                 t1_Nm=self.t1, t2_Nm=self.t2, phi1_rad=self.phi1, phi2_rad=self.phi2)
        return d


class CubicStiffness(_Stiffness):
    """Cubic (odd Taylor) compliance ``T = k1 phi + k3 phi^3``.

    Parameters
    ----------
    k1 : float
        Linear term (N m/rad).
    k3 : float
        Cubic term (N m/rad^3).
    """

    kind = "cubic"

    def __init__(self, k1: float, k3: float) -> None:
        super().__init__()
        self.k1, self.k3 = float(k1), float(k3)

    def __call__(self, phi: float) -> float:
        return self.k1 * phi + self.k3 * phi ** 3

    def describing_function(self, A: float) -> complex:
        """N(A) = k1 + 3/4 k3 A^2 (N m/rad)."""
        if A < 0:
            raise ValueError("cannot evaluate a describing function for A < 0")
        return complex(self.k1 + 0.75 * self.k3 * A * A)

    def amplitude_scale(self) -> float:
        return math.sqrt(self.k1 / self.k3) if self.k3 > 0 and self.k1 > 0 else 1e-3

    def to_dict(self) -> Dict[str, Any]:
        d = super().to_dict()
        d.update(k1_Nm_per_rad=self.k1, k3_Nm_per_rad3=self.k3)
        return d
