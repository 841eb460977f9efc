"""Normalised sensitivities of the first resonance and the lost motion to the
structural parameters of a harmonic drive, and a bar plot of them.

``S = d ln(y) / d ln(p)`` by a central difference in ln p (default +-1 %):
a 1 % increase of p changes y by about S %.  Outputs:

* ``resonance``: first resonance of the two-mass axis (motor-side FRF resonance
  f_r, research §2.6) with the structural K1 (secant to the structural T1) and a
  given load and motor inertia;
* ``lost_motion``: twist between +-4 % of a fixed test torque (the catalogue
  rated torque of the nominal gear), so that a stiffer structure shows less.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Dict, List, Optional, Tuple

from ..errors import UserError
from ..fileio import save_figure_atomic
from ..plotting import pyplot
from .structure import (Calibration, Structure, breakpoints, lost_motion, three_slope,
                        two_mass_resonance)

#: (attribute, object, label with unit) of the perturbed parameters; object "s" =
#: Structure, "c" = Calibration, "axis" = load / motor inertia.
PARAMETERS: Tuple[Tuple[str, str, str], ...] = (
    ("pitch_diameter_m", "s", "pitch diameter d [m]"),
    ("wall_m", "s", "wall thickness t [m]"),
    ("cup_length_m", "s", "cup length L [m]"),
    ("face_width_m", "s", "face width b [m]"),
    ("diaphragm_m", "s", "diaphragm thickness h [m]"),
    ("hub_radius_m", "s", "hub radius a [m]"),
    ("youngs_modulus_Pa", "s", "Young's modulus E [Pa]"),
    ("ball_diameter_m", "s", "WG ball diameter D_w [m]"),
    ("pressure_angle_deg", "s", "pressure angle alpha [deg]"),
    ("mesh_stiffness_per_width_N_per_m2", "c", "mesh stiffness per width c_m [N/m^2]"),
    ("zero_torque_engaged_fraction", "c", "teeth engaged at zero torque f0 [-]"),
    ("clearance_spread_m", "c", "flank clearance spread e0 [m]"),
    ("load_inertia_kgm2", "axis", "load inertia J_L [kg m^2]"),
    ("motor_inertia_kgm2", "axis", "motor+WG inertia J_m [kg m^2]"),
)

OUTPUTS = ("resonance", "lost_motion")


@dataclass(frozen=True)
class Axis:
    """Load side of the sensitivity study.

    Attributes
    ----------
    load_inertia_kgm2 : float
        Load inertia at the output, kg·m².
    motor_inertia_kgm2 : float
        Motor rotor + wave generator at the input, kg·m².
    test_torque_Nm : float
        Rated torque defining the lost-motion test (+-4 % of it), N·m.
    """

    load_inertia_kgm2: float = 0.5
    motor_inertia_kgm2: float = 8e-5
    test_torque_Nm: float = 66.9


def outputs(s: Structure, cal: Calibration, axis: Axis) -> Dict[str, float]:
    """First resonance f_r in Hz and lost motion in rad."""
    k1 = three_slope(s, cal, breakpoints(s, cal)).k1_Nm_per_rad
    _, fr = two_mass_resonance(k1, axis.load_inertia_kgm2, axis.motor_inertia_kgm2, s.ratio)
    return {"resonance": fr, "lost_motion": lost_motion(s, cal, axis.test_torque_Nm)}


def sensitivities(s: Structure, cal: Calibration, axis: Axis = Axis(),
                  rel_step: float = 0.01) -> Dict[str, Dict[str, float]]:
    """Normalised sensitivities ``d ln(output) / d ln(param)``.

    Returns
    -------
    dict
        ``{output: {parameter label: S}}`` for :data:`OUTPUTS` and :data:`PARAMETERS`.
    """
    if not 0 < rel_step < 0.2:
        raise UserError(f"sensitivity: relative step must be in (0, 0.2), got {rel_step}")
    res: Dict[str, Dict[str, float]] = {o: {} for o in OUTPUTS}
    dl = math.log1p(rel_step) - math.log1p(-rel_step)
    for attr, obj, label in PARAMETERS:
        ys = []
        for f in (1.0 + rel_step, 1.0 - rel_step):
            s2, c2, a2 = s, cal, axis
            if obj == "s":
                s2 = replace(s, **{attr: getattr(s, attr) * f})
            elif obj == "c":
                c2 = replace(cal, **{attr: getattr(cal, attr) * f})
            else:
                a2 = replace(axis, **{attr: getattr(axis, attr) * f})
            ys.append(outputs(s2, c2, a2))
        for o in OUTPUTS:
            res[o][label] = (math.log(ys[0][o]) - math.log(ys[1][o])) / dl
    return res


def ranked(sens: Dict[str, float]) -> List[Tuple[str, float]]:
    """(label, S) sorted by decreasing abs(S)."""
    return sorted(sens.items(), key=lambda kv: -abs(kv[1]))


def plot_sensitivities(sens: Dict[str, Dict[str, float]], path: Path,
                       title: Optional[str] = None, fmt: Optional[str] = None) -> Path:
    """Write a horizontal bar plot (one panel per output) of the sensitivities.

    Parameters
    ----------
    sens : dict
        Result of :func:`sensitivities`.
    path : Path
        Output file (PNG by default; PDF if the suffix or ``fmt`` says so).
    title : str, optional
        Figure title.
    """
    plt = pyplot()
    path = Path(path)
    names = {"resonance": "first resonance f_r", "lost_motion": "lost motion (+-4 % rated)"}
    fig, axes = plt.subplots(1, len(sens), figsize=(6.0 * len(sens), 5.5), sharey=False)
    axes = [axes] if len(sens) == 1 else list(axes)
    for ax, (out, vals) in zip(axes, sens.items()):
        items = ranked(vals)[::-1]
        ax.barh([k for k, _ in items], [v for _, v in items],
                color=["tab:blue" if v >= 0 else "tab:red" for _, v in items])
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_xlabel("normalised sensitivity d ln(output) / d ln(parameter) [-]")
        ax.set_ylabel("structural parameter [unit]")
        ax.set_title(names.get(out, out))
        ax.grid(axis="x", alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    try:
        save_figure_atomic(fig, path, format=fmt or None, dpi=110)
    finally:
        plt.close(fig)
    return path
