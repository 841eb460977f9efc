"""Velocity-loop tuning for the closed-loop identification experiments.

The closed-loop experiments (FRF, TE rotation, gravity sine, friction sweep)
run in the drive's velocity loop.  A velocity PI tuned for one inertia
limit-cycles on a much lighter axis (the reference defaults, 1.3 kg.m^2, give a
CSF-17-50 class axis of 0.175 kg.m^2 a 7x too high gain: the torque saturates
at +-50 N.m and every friction window is noise), and is sluggish on a heavier
one.  So the loop is set by the design rule of the baseline PID
(docs/control.md, :func:`hdservo.closedloop_cases.axis_controller`) from the
axis' total inertia:

* before the first experiment, from the inertia the drive is commissioned with
  (``j_total``, J_L + N^2 J_m, the drive's acceleration feed-forward);
* after the FRF, from the identified two-mass inertia J1 + J2 whenever it
  differs from the one in use by more than :data:`RETUNE_TOLERANCE`.

Gains a user fixes (``--gain``) are never changed.
"""
from __future__ import annotations

import math
from typing import Any, Mapping

#: velocity-loop crossover of the design rule, Hz (docs/control.md)
VELOCITY_BANDWIDTH_HZ = 25.0
#: relative inertia difference above which the FRF's inertia replaces the one in use
RETUNE_TOLERANCE = 0.1


def velocity_pi(j_total_kgm2: float, f_v_hz: float = VELOCITY_BANDWIDTH_HZ) -> dict[str, float]:
    """Velocity PI of the design rule for a total inertia (:func:`hdservo.closedloop_cases.velocity_pi`).

    Parameters
    ----------
    j_total_kgm2 : float
        Total inertia referred to the output, J_L + N^2 J_m, kg.m^2 (> 0).
    f_v_hz : float
        Velocity-loop crossover, Hz.

    Returns
    -------
    dict
        ``{"vel_kp": kp, "vel_ki": ki}`` in the parameter-table units
        (N.m.s/rad, N.m/rad): ``kp = J 2 pi f_v``, ``ki = kp 2 pi f_v / 4``, each at most the
        drive's maximum (``vel_ki`` 32000 N.m/rad: J above 5.2 kg.m^2 gets a lower PI zero).

    Raises
    ------
    ValueError
        A non-finite or non-positive inertia or bandwidth.
    """
    from ..closedloop_cases import velocity_pi as rule
    return rule(j_total_kgm2, f_v_hz)


def frf_inertia(frf_results: Any) -> float | None:
    """Total inertia J1 + J2 (kg.m^2) of the smallest-amplitude FRF fit, or None when it is unusable.

    Parameters
    ----------
    frf_results : sequence of hdservo.ident.frf.FRFResult
        Fits per excitation amplitude.
    """
    if not frf_results:
        return None
    f = min(frf_results, key=lambda r: r.amplitude_rad_s)
    j = float(f.j1_kgm2) + float(f.j2_kgm2)
    ok = math.isfinite(j) and j > 0 and f.j1_kgm2 > 0 and f.j2_kgm2 > 0
    return j if ok else None


def needs_retune(j_in_use_kgm2: float, j_new_kgm2: float, tolerance: float = RETUNE_TOLERANCE) -> bool:
    """True when ``j_new`` differs from ``j_in_use`` by more than ``tolerance`` (relative)."""
    return abs(j_new_kgm2 / j_in_use_kgm2 - 1.0) > tolerance


def without(gains: Mapping[str, float], fixed: Any) -> dict[str, float]:
    """``gains`` without the names in ``fixed`` (the user's own gains stay)."""
    return {k: v for k, v in gains.items() if k not in set(fixed)}
