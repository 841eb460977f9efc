"""Describing functions of hysteresis and lost motion (harmonic-drive.md 6, 7).

* Lost motion / backlash: friction-controlled play of total width ``b``
  (Gelb and Vander Velde #48)::

      N_b(A) = 1/2 [1 + g(1 - b/A)] - j (2b/A - (b/A)^2)/pi     for A > b/2, else 0

* Jenkins element (spring k in series with a Coulomb slider of slip torque W,
  threshold Delta = W/k) = stop operator = identity - play::

      N_J(A) = k [1 - N_b(A; 2 Delta)]  for A > Delta,  k for A <= Delta

  (positive imaginary part: the loop area W(A) = pi A^2 Im N is dissipated).
* Maxwell-slip: a parallel sum of Jenkins elements, ``N = sum_i N_J,i``.
* Preisach: no closed form; first harmonic of the steady symmetric cycle of a
  :class:`~hdservo.preisach.PreisachModel` (reset per amplitude).  As in
  the simulated plant (docs/plant.md) the torque is ``P_mean(phi) - P[phi]``:
  a relay's output lags its input, so ``P`` alone (positive density) has
  ``Im N < 0`` and, used as a torque, would deliver energy every cycle;
  ``P_mean - P`` has ``Im N = -Im N_P > 0``, the dissipative orientation
  (``oint T dphi = pi A^2 Im N > 0``, like the damper ``N = j c w``).
"""
from __future__ import annotations

from typing import Any, Dict, Sequence

import numpy as np

from .dfbase import HdNonlinearity, backlash_df
from ..preisach import PreisachModel


class LostMotion(HdNonlinearity):
    """Friction-controlled backlash (play operator) of total width ``b``.

    The output stays where it is until the input has crossed the gap, then
    follows the input offset by ``b/2``.

    Parameters
    ----------
    b : float
        Total lost motion (input units, rad for an angle, >= 0).
    """

    kind = "lost_motion"
    input_name = "position before the gap"
    input_unit = "rad"
    output_name = "position after the gap"
    output_unit = "rad"

    def __init__(self, b: float) -> None:
        super().__init__()
        if b < 0:
            raise ValueError("lost motion must be >= 0")
        self.b = float(b)
        self.reset()

    def reset(self) -> None:
        self.center = 0.0

    def __call__(self, x: float) -> float:
        h = self.b / 2.0
        if x - self.center > h:
            self.center = x - h
        elif x - self.center < -h:
            self.center = x + h
        return self.center

    def describing_function(self, A: float) -> complex:
        """N_b(A) (dimensionless): 0 inside the gap, -> 1 for A >> b."""
        if A < 0:
            raise ValueError("cannot evaluate a describing function for A < 0")
        return backlash_df(A, self.b)

    def small_signal_gain(self) -> complex:
        return 0j if self.b > 0 else complex(1.0)

    def amplitude_scale(self) -> float:
        return self.b if self.b > 0 else 1e-4

    def to_dict(self) -> Dict[str, Any]:
        d = super().to_dict()
        d.update(b_rad=self.b)
        return d


class MaxwellSlip(HdNonlinearity):
    """Maxwell-slip hysteresis: parallel Jenkins (elasto-slide) elements.

    ``T = sum_i clamp(k_i (phi - xi_i), +-w_i)``; an element slips (its
    anchor ``xi_i`` moves) when its torque would exceed ``w_i``.  One element
    is a Jenkins element.

    Parameters
    ----------
    k : sequence of float
        Element stiffnesses (N m/rad, > 0).
    w : sequence of float
        Element slip torques (N m, >= 0).
    k_parallel : float
        Stiffness of a linear spring in parallel (N m/rad, >= 0), e.g. the
        gear's elastic stiffness when the element models the whole torsion path.
    """

    kind = "maxwell_slip"
    input_name = "twist"
    input_unit = "rad"
    output_name = "torque"
    output_unit = "N*m"

    def __init__(self, k: Sequence[float], w: Sequence[float], k_parallel: float = 0.0) -> None:
        super().__init__()
        self.k = np.asarray(k, dtype=float).ravel()
        self.w = np.asarray(w, dtype=float).ravel()
        if self.k.size != self.w.size or self.k.size == 0:
            raise ValueError("Maxwell-slip needs as many slip torques as stiffnesses (>= 1)")
        if np.any(self.k <= 0) or np.any(self.w < 0) or k_parallel < 0:
            raise ValueError("Maxwell-slip stiffnesses must be > 0 and slip torques >= 0")
        self.k_parallel = float(k_parallel)
        self.delta = self.w / self.k
        self.reset()

    def reset(self) -> None:
        self.xi = np.zeros_like(self.k)

    def __call__(self, phi: float) -> float:
        f = self.k * (phi - self.xi)
        over = f > self.w
        under = f < -self.w
        self.xi = np.where(over, phi - self.delta, np.where(under, phi + self.delta, self.xi))
        return float(np.clip(f, -self.w, self.w).sum()) + self.k_parallel * phi

    def describing_function(self, A: float) -> complex:
        """N(A) = k_parallel + sum_i k_i [1 - N_b(A; 2 Delta_i)] (N m/rad)."""
        if A < 0:
            raise ValueError("cannot evaluate a describing function for A < 0")
        n = complex(self.k_parallel)
        for ki, di in zip(self.k, self.delta):
            n += ki * (1.0 - backlash_df(A, 2.0 * di)) if A > di else ki
        return n

    def amplitude_scale(self) -> float:
        return float(np.max(self.delta)) if np.max(self.delta) > 0 else 1e-4

    def to_dict(self) -> Dict[str, Any]:
        d = super().to_dict()
        d.update(k_Nm_per_rad=self.k.tolist(), w_Nm=self.w.tolist(), delta_rad=self.delta.tolist(),
                 k_parallel_Nm_per_rad=self.k_parallel)
        return d


class PreisachHysteresis(HdNonlinearity):
    """Preisach hysteresis torque (optionally plus a parallel linear spring), numerical DF.

    ``T = k_parallel phi + P_mean(phi) - P[phi]`` (``orientation="plant"``, the
    simulated plant's torque, dissipative) or ``T = k_parallel phi + P[phi]``
    (``orientation="operator"``, the raw operator, e.g. for an Everett function
    that already describes a dissipative element such as a Jenkins stop).

    Parameters
    ----------
    model : PreisachModel
        The operator (input twist in rad, output torque in N m).
    k_parallel : float
        Linear spring in parallel (N m/rad, >= 0).
    num_points : int
        Samples per cycle of the numerical first harmonic.
    orientation : str
        ``"plant"`` (default) or ``"operator"``.
    """

    kind = "preisach"
    input_name = "twist"
    input_unit = "rad"
    output_name = "torque"
    output_unit = "N*m"

    def __init__(self, model: PreisachModel, k_parallel: float = 0.0, num_points: int = 1024,
                 orientation: str = "plant") -> None:
        super().__init__()
        if orientation not in ("plant", "operator"):
            raise ValueError(f"unknown Preisach orientation '{orientation}' (expected 'plant' or 'operator')")
        self.orientation = orientation
        self.model = model
        self.k_parallel = float(k_parallel)
        self.num_points = int(num_points)

    def reset(self) -> None:
        self.model.reset()

    def __call__(self, phi: float) -> float:
        """Advance to twist ``phi`` (rad); torque (N m)."""
        p = self.model(phi)
        if self.orientation == "plant":
            return self.model.mean(phi) - p + self.k_parallel * phi
        return p + self.k_parallel * phi

    def describing_function(self, A: float) -> complex:
        """First harmonic of the steady symmetric cycle +-A (N m/rad)."""
        return self.numerical_df(A)

    def small_signal_gain(self) -> complex:
        return self.numerical_df(1e-6 * self.model.u_max)

    def amplitude_scale(self) -> float:
        return self.model.u_max / 2.0

    def to_dict(self) -> Dict[str, Any]:
        d = super().to_dict()
        d.update(u_max_rad=self.model.u_max, y_sat_Nm=self.model.y_sat, k_parallel_Nm_per_rad=self.k_parallel,
                 orientation=("P_mean - P (plant)" if self.orientation == "plant" else "P (operator)"))
        return d
