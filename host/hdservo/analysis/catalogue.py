"""The named nonlinearities of an axis, each with its insertion point and amplitude range.

Names (``hdservo df --nonlinearity NAME``):

==================  ==================  ==========================================================
name                insertion point     model (axis-file keys)
==================  ==================  ==========================================================
coulomb_motor       motor_friction      F_c = mean(fc_pos, fc_neg) + viscous  ([friction_motor])
stribeck_motor      motor_friction      F_c, F_s, v_s, delta, viscous         ([friction_motor])
coulomb_load        load_friction       as coulomb_motor                      ([friction_load])
stribeck_load       load_friction       as stribeck_motor                     ([friction_load])
three_slope         torsion             K1/K2/K3, T1/T2                       ([stiffness])
cubic               torsion             k1, k3                                ([stiffness_cubic])
maxwell_slip        torsion             K1 spring + Jenkins elements          ([hysteresis_maxwell])
preisach            torsion             K1 spring + P_mean - P (as the plant) ([hysteresis_preisach])
lost_motion         position_feedback   play of total width b                 ([lost_motion] b_rad)
==================  ==================  ==========================================================
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Mapping, Tuple

import numpy as np

from .dfbase import HdNonlinearity
from .friction import CoulombFriction, StribeckFriction
from .hysteresis import LostMotion, MaxwellSlip, PreisachHysteresis
from ..preisach import PreisachModel, everett_table_plant
from .stiffness import CubicStiffness, ThreeSlopeStiffness

NAMES = ("coulomb_motor", "stribeck_motor", "coulomb_load", "stribeck_load", "three_slope", "cubic",
         "maxwell_slip", "preisach", "lost_motion")


@dataclass
class Entry:
    """A nonlinearity placed in the loop.

    Attributes
    ----------
    name : str
        Catalogue name.
    nl : HdNonlinearity
        The element.
    insertion : str
        Insertion point (see :mod:`hdservo.analysis.loop`).
    amplitudes : numpy.ndarray
        Default amplitude sweep (input units), increasing.
    """

    name: str
    nl: HdNonlinearity
    insertion: str
    amplitudes: np.ndarray


def _friction(ax: Mapping[str, float], side: str, stribeck: bool) -> StribeckFriction:
    g = lambda k: float(ax[f"{side}.{k}"])  # noqa: E731
    fc = 0.5 * (g("fc_pos_Nm") + g("fc_neg_Nm"))
    fs = 0.5 * (g("fs_pos_Nm") + g("fs_neg_Nm"))
    where = "motor" if side == "friction_motor" else "load"
    if stribeck:
        return StribeckFriction(fc, fs, g("vs_rad_s"), g("delta"), g("viscous_Nms_per_rad"), side=where)
    return CoulombFriction(fc, g("viscous_Nms_per_rad"), side=where)


def build(name: str, ax: Mapping[str, float], n_amp: int = 60) -> Entry:
    """Build one catalogue entry from the axis parameters.

    Parameters
    ----------
    name : str
        One of :data:`NAMES`.
    ax : mapping
        Axis parameters ``"section.key"`` -> value.
    n_amp : int
        Points in the default amplitude sweep.
    """
    k1 = float(ax["stiffness.k1_Nm_per_rad"])
    if name in ("coulomb_motor", "stribeck_motor", "coulomb_load", "stribeck_load"):
        side = "friction_motor" if name.endswith("motor") else "friction_load"
        nl = _friction(ax, side, name.startswith("stribeck"))
        vs = float(ax[f"{side}.vs_rad_s"])
        return Entry(name, nl, "motor_friction" if side == "friction_motor" else "load_friction",
                     np.logspace(np.log10(vs) - 3, np.log10(vs) + 3, n_amp))
    if name == "three_slope":
        nl = ThreeSlopeStiffness(k1, ax["stiffness.k2_Nm_per_rad"], ax["stiffness.k3_Nm_per_rad"],
                                 ax["stiffness.t1_Nm"], ax["stiffness.t2_Nm"])
        return Entry(name, nl, "torsion", np.logspace(np.log10(nl.phi1) - 1.5, np.log10(nl.phi2) + 1.5, n_amp))
    if name == "cubic":
        nl = CubicStiffness(ax["stiffness_cubic.k1_Nm_per_rad"], ax["stiffness_cubic.k3_Nm_per_rad3"])
        a = nl.amplitude_scale()
        return Entry(name, nl, "torsion", np.logspace(np.log10(a) - 2.5, np.log10(a), n_amp))
    if name == "maxwell_slip":
        n = int(ax["hysteresis_maxwell.n_elements"])
        k = [float(ax[f"hysteresis_maxwell.e{i + 1}_k_Nm_per_rad"]) for i in range(n)]
        w = [float(ax[f"hysteresis_maxwell.e{i + 1}_w_Nm"]) for i in range(n)]
        if n == 0:
            k, w = [1e-9], [0.0]
        nl = MaxwellSlip(k, w, k_parallel=k1)
        d = nl.amplitude_scale()
        return Entry(name, nl, "torsion", np.logspace(np.log10(d) - 1.5, np.log10(d) + 1.5, n_amp))
    if name == "preisach":
        u = float(ax["hysteresis_preisach.u_max_rad"])
        table = everett_table_plant(u, float(ax["hysteresis_preisach.t_sat_Nm"]),
                                    float(ax["hysteresis_preisach.r0_rad"]), float(ax["hysteresis_preisach.s_rad"]))
        nl = PreisachHysteresis(PreisachModel(table, u), k_parallel=k1, num_points=512, orientation="plant")
        return Entry(name, nl, "torsion", np.logspace(np.log10(u) - 2, np.log10(u), max(12, n_amp // 3)))
    if name == "lost_motion":
        b = float(ax["lost_motion.b_rad"])
        nl = LostMotion(b)
        return Entry(name, nl, "position_feedback", b / 2 * np.logspace(1e-3, 2, n_amp))
    raise KeyError(name)


def build_all(ax: Mapping[str, float], names: Tuple[str, ...] = NAMES) -> Dict[str, Entry]:
    """Entries for several names (dict keyed by name)."""
    return {n: build(n, ax) for n in names}
