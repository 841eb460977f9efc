"""Structure-to-model relations of a cup-type double-wave harmonic drive.

From the main structural parameters (flexspline pitch diameter, wall thickness,
cup length, face width, tooth count and module, diaphragm, material E/G,
wave-generator bearing) to the parameters of the hdservo axis model:

* torsional compliance at the output (wave generator locked) as springs in series

  - flexspline cup torsion  ``K_cup = G J / L``, ``J = 2 pi r^3 t``
  - diaphragm (annular plate) torsion ``K_dia = 4 pi G h / (1/a^2 - 1/r^2)``
  - wave-generator bearing: Hertz ball contacts, radial compliance seen through
    the flank angle, ``dphi = tan(alpha)^2 / (2 k_r r^2) dT``
  - tooth mesh: per-pair stiffness ``k_p = c_m b`` times the number of pairs in
    contact, which grows with the twist as teeth with larger initial clearance
    close (``n0`` pairs in contact at zero torque, ``n1`` more with clearances
    spread uniformly over ``[0, e0]``) -- this is the K1 -> K3 stiffening;

* the catalogue three-slope parameters (T1, T2, K1, K2, K3) read off that curve;
* hysteresis loss and lost motion; starting / running friction; first resonance
  with a given load (two-mass model).

Which constants are calibrated against the catalogue, and how, is stated in
``hdservo/data/flexspline_geometry.toml`` and docs/design-structure.md.
All quantities SI (m, N, N·m, rad, kg·m², Hz) unless the name says otherwise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from ..errors import UserError
from ..tomltext import read_toml_file
from .catalogue import DATA_DIR, GearRow, load_gears

ARCMIN = math.pi / (180.0 * 60.0)  #: one arcminute in rad
GEOMETRY_FILE = DATA_DIR / "flexspline_geometry.toml"


# --------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class Calibration:
    """Constants fitted to the catalogue (see :func:`calibrate`).

    Attributes
    ----------
    mesh_stiffness_per_width_N_per_m2 : float
        Per tooth-pair mesh stiffness per unit face width, N/m per m.
    zero_torque_engaged_fraction : float
        Fraction of all flexspline teeth in contact at zero torque, -.
    clearance_spread_m : float
        Spread of the initial flank clearances of the other engageable teeth, m.
    t1_coefficient_N_per_m2, t2_coefficient_N_per_m2 : float
        Catalogue breakpoints T1, T2 = coefficient · d² · b, N/m².
    hysteresis_loss_fraction : float
        Loop width at zero torque = 2 · fraction · elastic twist at the amplitude, -.
    starting_torque_coefficient_Nm : float
        Input starting torque of a size-25, N = 100 gear, N·m.
    starting_torque_ratio_exponent : float
        Exponent q of (100/N)^q in the starting-torque scaling, -.
    mesh_module_exponent : float
        Exponent g of the per-pair stiffness ``c_m b (200/z)^g`` (module dependence), -.
    """

    mesh_stiffness_per_width_N_per_m2: float
    zero_torque_engaged_fraction: float
    clearance_spread_m: float
    t1_coefficient_N_per_m2: float
    t2_coefficient_N_per_m2: float
    hysteresis_loss_fraction: float
    starting_torque_coefficient_Nm: float
    starting_torque_ratio_exponent: float
    mesh_module_exponent: float


@dataclass(frozen=True)
class Structure:
    """Structural parameters of one harmonic drive (SI units).

    Attributes
    ----------
    pitch_diameter_m : float
        Flexspline pitch diameter d, m.
    wall_m : float
        Wall thickness t of the smooth cup, m.
    cup_length_m : float
        Cup length L from the diaphragm to the open end, m.
    face_width_m : float
        Tooth face width b (toothed rim at the open end), m.
    tooth_rim_extra_m : float
        Extra equivalent wall thickness of the toothed rim, m.
    diaphragm_m : float
        Diaphragm thickness h, m.
    hub_radius_m : float
        Outer radius a of the bolted hub (inner edge of the diaphragm), m.
    teeth : float
        Flexspline tooth count z (= 2 N for a two-tooth difference), -.
    ratio : float
        Gear ratio N (circular spline fixed, flexspline output), -.
    youngs_modulus_Pa, poisson_ratio : float
        Flexspline material.
    ball_diameter_m : float
        Wave-generator bearing ball diameter D_w, m.
    balls_per_lobe : float
        Balls carrying each lobe's radial load, -.
    pressure_angle_deg : float
        Flank pressure angle alpha at the contact, deg.
    max_engaged_fraction : float
        Fraction of teeth in contact at high torque, -.
    """

    pitch_diameter_m: float
    wall_m: float
    cup_length_m: float
    face_width_m: float
    tooth_rim_extra_m: float
    diaphragm_m: float
    hub_radius_m: float
    teeth: float
    ratio: float
    youngs_modulus_Pa: float
    poisson_ratio: float
    ball_diameter_m: float
    balls_per_lobe: float
    pressure_angle_deg: float
    max_engaged_fraction: float

    @property
    def shear_modulus_Pa(self) -> float:
        """G = E / (2 (1 + nu)), Pa."""
        return self.youngs_modulus_Pa / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def module_m(self) -> float:
        """Tooth module m = d / z, m."""
        return self.pitch_diameter_m / self.teeth

    @property
    def mid_radius_m(self) -> float:
        """Mid-wall radius of the cup r_m = d/2 - t/2, m."""
        return 0.5 * (self.pitch_diameter_m - self.wall_m)


def _read_geometry_file(path: Path = GEOMETRY_FILE) -> Dict[str, Dict[str, float]]:
    doc = read_toml_file(path)
    for sec in ("geometry", "material", "calibrated"):
        if not isinstance(doc.get(sec), dict):
            raise UserError(f"{path}: missing table [{sec}]")
        for k, v in doc[sec].items():
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise UserError(f"{path}: [{sec}] {k}: expected a finite number, got {v!r}")
    return doc


def load_calibration(path: Path = GEOMETRY_FILE) -> Calibration:
    """Read the ``[calibrated]`` constants of ``flexspline_geometry.toml``."""
    sec = _read_geometry_file(path)["calibrated"]
    names = [f.name for f in fields(Calibration)]
    missing = [n for n in names if n not in sec]
    if missing:
        raise UserError(f"{path}: [calibrated]: missing {', '.join(missing)}")
    return Calibration(**{n: float(sec[n]) for n in names})


def structure_for(size: int, ratio: int, path: Path = GEOMETRY_FILE) -> Structure:
    """Structural parameters of catalogue size ``size`` and ratio ``ratio`` by the
    proportional rules of ``flexspline_geometry.toml`` (geometric similarity).

    Parameters
    ----------
    size : int
        Catalogue size number (about the pitch diameter in tenths of an inch).
    ratio : int
        Gear ratio N.
    """
    if size <= 0 or ratio <= 1:
        raise UserError(f"structure: size and ratio must be positive (got size {size}, ratio {ratio})")
    doc = _read_geometry_file(path)
    g, mat = doc["geometry"], doc["material"]
    d = size * g["pitch_diameter_per_size_m"]
    t = g["wall_over_d"] * d
    z = g["tooth_difference"] * ratio
    return Structure(
        pitch_diameter_m=d, wall_m=t, cup_length_m=g["cup_length_over_d"] * d,
        face_width_m=g["face_width_over_d"] * d,
        tooth_rim_extra_m=g["tooth_rim_extra_over_module"] * d / z,
        diaphragm_m=g["diaphragm_over_wall"] * t, hub_radius_m=g["hub_radius_over_r"] * d / 2,
        teeth=float(z), ratio=float(ratio), youngs_modulus_Pa=mat["youngs_modulus_Pa"],
        poisson_ratio=mat["poisson_ratio"], ball_diameter_m=g["ball_diameter_over_d"] * d,
        balls_per_lobe=g["balls_per_lobe"], pressure_angle_deg=g["pressure_angle_deg"],
        max_engaged_fraction=g["max_engaged_fraction"])


# --------------------------------------------------------------------------- linear springs
def cup_stiffness(s: Structure) -> float:
    """Torsional stiffness of the smooth cup, thin-walled tube ``G J / L``.

    ``J = 2 pi r_m^3 t``; the torque enters at mid face width, so the twisted
    length is ``L - b/2``.  Returns N·m/rad.
    """
    j = 2.0 * math.pi * s.mid_radius_m ** 3 * s.wall_m
    return s.shear_modulus_Pa * j / (s.cup_length_m - 0.5 * s.face_width_m)


def diaphragm_stiffness(s: Structure) -> float:
    """Torsional stiffness of the diaphragm as a uniform annular plate in shear.

    Shear stress ``tau = T / (2 pi rho^2 h)`` gives ``dtheta/drho = T / (2 pi G h rho^3)``,
    integrated from the hub radius a to the cup radius r:
    ``K = 4 pi G h / (1/a^2 - 1/r^2)``.  Returns N·m/rad.
    """
    a, r = s.hub_radius_m, s.mid_radius_m
    return 4.0 * math.pi * s.shear_modulus_Pa * s.diaphragm_m / (1.0 / a ** 2 - 1.0 / r ** 2)


def flexspline_stiffness(s: Structure) -> float:
    """Cup and diaphragm in series (the part the FE model checks), N·m/rad."""
    return 1.0 / (1.0 / cup_stiffness(s) + 1.0 / diaphragm_stiffness(s))


# --------------------------------------------------------------------------- nonlinear parts
def _hertz_c(s: Structure) -> float:
    """Ball load-deflection constant c of ``delta = c Q^(2/3)`` (both raceway contacts,
    ball on flat, Hertz), m/N^(2/3)."""
    e_star = s.youngs_modulus_Pa / (2.0 * (1.0 - s.poisson_ratio ** 2))
    rad = 0.5 * s.ball_diameter_m
    return 2.0 * (9.0 / (16.0 * e_star ** 2 * rad)) ** (1.0 / 3.0)


def bearing_preload_N(s: Structure) -> float:
    """Radial force forming the ellipse (ring with diametral loads, Roark):
    ``w0 = 0.149 F r^3 / (E I)`` with ``w0`` = one module, I of the toothed rim.  N."""
    r = s.pitch_diameter_m / 2
    t_rim = s.wall_m + s.tooth_rim_extra_m
    i = s.face_width_m * t_rim ** 3 / 12.0
    return s.module_m * s.youngs_modulus_Pa * i / (0.149 * r ** 3)


def bearing_twist(s: Structure, torque: np.ndarray) -> np.ndarray:
    """Output twist from the wave-generator bearing's Hertz compliance, rad.

    Per lobe the tangential mesh force ``T/(2r)`` has a radial component
    ``T tan(alpha) / (2 r)`` shared by ``balls_per_lobe`` balls on top of the
    ellipse-forming preload; the radial deflection lets the flank slide by
    ``delta_r tan(alpha)``.
    """
    t_abs = np.abs(np.asarray(torque, dtype=float))
    r = s.pitch_diameter_m / 2
    tan_a = math.tan(math.radians(s.pressure_angle_deg))
    c = _hertz_c(s)
    q0 = bearing_preload_N(s) / s.balls_per_lobe
    q = q0 + t_abs * tan_a / (2.0 * r * s.balls_per_lobe)
    delta_r = c * (q ** (2.0 / 3.0) - q0 ** (2.0 / 3.0))
    return np.sign(torque) * delta_r * tan_a / r


def mesh_twist(s: Structure, cal: Calibration, torque: np.ndarray) -> np.ndarray:
    """Output twist from the tooth mesh with progressive engagement, rad.

    ``n0 = f0 z`` pairs touch at zero torque; ``n1 = (f_max - f0) z`` more have
    initial clearances spread uniformly over ``[0, e0]``.  With per-pair stiffness
    ``k = c_m b (200/z)^g`` (g: calibrated module exponent; a larger module --
    lower ratio -- gives a stiffer pair) the tangential force at deflection u is
    ``F = k (n0 u + n1 u^2 / (2 e0))`` for ``u <= e0`` and
    ``F = k (n0 u + n1 (u - e0/2))`` beyond; ``F = T / r``, twist ``u / r``.
    """
    t = np.asarray(torque, dtype=float)
    r = s.pitch_diameter_m / 2
    k = (cal.mesh_stiffness_per_width_N_per_m2 * s.face_width_m
         * (200.0 / s.teeth) ** cal.mesh_module_exponent)
    n0 = cal.zero_torque_engaged_fraction * s.teeth
    n1 = max(s.max_engaged_fraction - cal.zero_torque_engaged_fraction, 0.0) * s.teeth
    e0 = cal.clearance_spread_m
    f = np.abs(t) / r / k  # = n0 u + ...
    if n1 <= 0.0 or e0 <= 0.0:
        u = f / n0
    else:
        f_knee = n0 * e0 + n1 * e0 / 2.0
        a2 = n1 / (2.0 * e0)
        with np.errstate(invalid="ignore"):
            u_low = (-n0 + np.sqrt(n0 * n0 + 4.0 * a2 * f)) / (2.0 * a2)
        u_high = (f + n1 * e0 / 2.0) / (n0 + n1)
        u = np.where(f <= f_knee, u_low, u_high)
    return np.sign(t) * u / r


def twist(s: Structure, cal: Calibration, torque: Sequence[float] | np.ndarray) -> np.ndarray:
    """Total output twist at torque T (wave generator locked), rad; odd in T."""
    t = np.asarray(torque, dtype=float)
    return t / flexspline_stiffness(s) + bearing_twist(s, t) + mesh_twist(s, cal, t)


def incremental_stiffness(s: Structure, cal: Calibration, torque: float) -> float:
    """dT/dphi at torque T by a central difference (step 1e-4 of T or 1e-3 N·m), N·m/rad."""
    h = max(1e-4 * abs(torque), 1e-3)
    p = twist(s, cal, [torque - h, torque + h])
    return float(2.0 * h / (p[1] - p[0]))


# --------------------------------------------------------------------------- catalogue view
@dataclass(frozen=True)
class ThreeSlope:
    """Catalogue three-slope stiffness: T1, T2 in N·m, K1-K3 in N·m/rad."""

    t1_Nm: float
    t2_Nm: float
    k1_Nm_per_rad: float
    k2_Nm_per_rad: float
    k3_Nm_per_rad: float


def breakpoints(s: Structure, cal: Calibration) -> Tuple[float, float]:
    """Catalogue torque breakpoints T1, T2 = coefficient · d² · b (mesh load capacity), N·m."""
    q = s.pitch_diameter_m ** 2 * s.face_width_m
    return cal.t1_coefficient_N_per_m2 * q, cal.t2_coefficient_N_per_m2 * q


def three_slope(s: Structure, cal: Calibration,
                t1_t2: Optional[Tuple[float, float]] = None) -> ThreeSlope:
    """Read the catalogue's K1, K2, K3 off the structural torque-twist curve.

    K1 = T1/phi(T1); K2 = (T2-T1)/(phi(T2)-phi(T1)); K3 = secant from T2 to 2 T2.

    Parameters
    ----------
    t1_t2 : (float, float), optional
        Breakpoints to use, N·m; default :func:`breakpoints`.
    """
    t1, t2 = t1_t2 if t1_t2 is not None else breakpoints(s, cal)
    p1, p2, p3 = (float(v) for v in twist(s, cal, [t1, t2, 2.0 * t2]))
    return ThreeSlope(float(t1), float(t2), t1 / p1, (t2 - t1) / (p2 - p1), t2 / (p3 - p2))


def compliance_shares(s: Structure, cal: Calibration, torque: float) -> Dict[str, float]:
    """Fraction of the secant compliance phi(T)/T owed to each element at torque T."""
    t = np.array([torque])
    parts = {
        "cup": torque / cup_stiffness(s),
        "diaphragm": torque / diaphragm_stiffness(s),
        "wg_bearing": float(bearing_twist(s, t)[0]),
        "mesh": float(mesh_twist(s, cal, t)[0]),
    }
    tot = sum(parts.values())
    return {k: v / tot for k, v in parts.items()}


# --------------------------------------------------------------------------- other outputs
def hysteresis_loss(s: Structure, cal: Calibration, amplitude_Nm: float) -> float:
    """Hysteresis loss (loop width at zero torque after +-amplitude), rad.

    Loss-factor view: the twist lost to mesh and bearing micro-slip is a fixed
    fraction of the elastic twist at the amplitude, ``2 eta phi(T_a)``
    (eta calibrated so CSF-25-100 meets the catalogue 1' at rated torque).
    """
    return float(2.0 * cal.hysteresis_loss_fraction * twist(s, cal, [amplitude_Nm])[0])


def lost_motion(s: Structure, cal: Calibration, rated_torque_Nm: float) -> float:
    """Lost motion: twist between +-4 % of rated torque, mid-curve plus half the
    hysteresis width at that amplitude on each side, rad."""
    ta = 0.04 * rated_torque_Nm
    phi = float(twist(s, cal, [ta])[0])
    return 2.0 * phi * (1.0 + cal.hysteresis_loss_fraction)


@dataclass(frozen=True)
class Friction:
    """No-load friction estimates.

    Attributes
    ----------
    starting_input_Nm : float
        No-load starting torque at the input (wave generator), N·m.
    backdriving_output_Nm : float
        No-load backdriving torque at the output, N·m.
    coulomb_output_Nm : float
        Running (Coulomb) friction at the output, N·m.
    """

    starting_input_Nm: float
    backdriving_output_Nm: float
    coulomb_output_Nm: float


#: backdriving ≈ (1-1.2) N x starting (research §2.4): 1.1 used
BACKDRIVE_FACTOR = 1.1
#: static / Coulomb ratio F_s/F_c = 1.4-2.0 for geared joints (research §4.1): 1.7 used
STATIC_OVER_COULOMB = 1.7


def friction(s: Structure, cal: Calibration) -> Friction:
    """Starting, backdriving and running friction by the empirical scaling
    ``T_start,in = c (d/d25)^3 (100/N)^q`` (c, q calibrated on CSF-17-100 and
    CSF-25-50; d^3 = load-capacity scaling assumed)."""
    d25 = 25 * 2.54e-3
    ts = (cal.starting_torque_coefficient_Nm * (s.pitch_diameter_m / d25) ** 3
          * (100.0 / s.ratio) ** cal.starting_torque_ratio_exponent)
    back = BACKDRIVE_FACTOR * s.ratio * ts
    return Friction(ts, back, back / STATIC_OVER_COULOMB)


def two_mass_resonance(stiffness_Nm_per_rad: float, load_inertia_kgm2: float,
                       motor_inertia_kgm2: float, ratio: float) -> Tuple[float, float]:
    """Anti-resonance and resonance of the two-mass axis (research §2.6), Hz.

    ``w_a = sqrt(K / J_L)``; ``w_r = w_a sqrt(1 + J_L / (N^2 J_m))``; J_m is the
    motor rotor plus wave generator at the input.
    """
    if min(stiffness_Nm_per_rad, load_inertia_kgm2, motor_inertia_kgm2, ratio) <= 0:
        raise UserError("two_mass_resonance: stiffness, inertias and ratio must be positive")
    wa = math.sqrt(stiffness_Nm_per_rad / load_inertia_kgm2)
    wr = wa * math.sqrt(1.0 + load_inertia_kgm2 / (ratio ** 2 * motor_inertia_kgm2))
    return wa / (2 * math.pi), wr / (2 * math.pi)


# --------------------------------------------------------------------------- calibration
#: weight of log K2 and log K3 residuals relative to log K1 in :func:`calibrate`
W23 = 0.3


def _with_x(base: Calibration, x: np.ndarray) -> Calibration:
    return replace(base, mesh_stiffness_per_width_N_per_m2=float(math.exp(x[0])),
                   clearance_spread_m=float(math.exp(x[1])),
                   mesh_module_exponent=float(x[2]), zero_torque_engaged_fraction=float(x[3]))


def _k_residuals(x: np.ndarray, base: Calibration, cases: List[Tuple[Structure, GearRow]]) -> np.ndarray:
    cal = _with_x(base, x)
    res = []
    for s, g in cases:
        ts = three_slope(s, cal, (g.t1_Nm, g.t2_Nm))
        res += [math.log(ts.k1_Nm_per_rad / g.k1_Nm_per_rad),
                W23 * math.log(ts.k2_Nm_per_rad / g.k2_Nm_per_rad),
                W23 * math.log(ts.k3_Nm_per_rad / g.k3_Nm_per_rad)]
    return np.array(res)


def calibration_cases(rows: Optional[Iterable[GearRow]] = None,
                      ratios: Sequence[int] = (50, 80, 100, 120, 160)) -> List[Tuple[Structure, GearRow]]:
    """(structure, catalogue row) of the CSF rows used for calibration."""
    rows = list(rows) if rows is not None else load_gears()
    return [(structure_for(g.size, g.ratio), g) for g in rows
            if g.series == "CSF" and g.ratio in ratios]


def fit_mesh_constants(cases: Sequence[Tuple[Structure, GearRow]]) -> Calibration:
    """Fit ``c_m``, ``e0``, ``g``, ``f0`` to the given (structure, catalogue row) pairs.

    Least squares on log K1 (weight 1), log K2 and log K3 (weight :data:`W23`), each
    evaluated at the row's catalogue T1, T2.  Only ``cases`` enter the fit (the
    cross-validation relies on this).  The other constants of the result are
    placeholders; see :func:`calibrate`.
    """
    from scipy.optimize import least_squares

    if not cases:
        raise UserError("stiffness fit: no catalogue rows to fit")
    base = Calibration(1e9, 0.05, 5e-6, 1.0, 1.0, 0.1, 0.1, 0.5, 0.0)
    x0 = np.array([math.log(2e8), math.log(2e-5), 0.5, 0.05])
    lo = [-np.inf, -np.inf, -2.0, 0.005]
    hi = [np.inf, np.inf, 2.0, 0.25]
    fit = least_squares(_k_residuals, x0=x0, args=(base, list(cases)), bounds=(lo, hi),
                        method="trf", x_scale=[1, 1, 0.3, 0.03], xtol=1e-12, ftol=1e-12)
    return _with_x(base, fit.x)


def fit_breakpoints(cases: Sequence[Tuple[Structure, GearRow]]) -> Tuple[float, float]:
    """T1, T2 coefficients (N/m²): geometric mean of T / (d² b) over ``cases``."""
    c1 = [g.t1_Nm / (s.pitch_diameter_m ** 2 * s.face_width_m) for s, g in cases]
    c2 = [g.t2_Nm / (s.pitch_diameter_m ** 2 * s.face_width_m) for s, g in cases]
    return float(np.exp(np.mean(np.log(c1)))), float(np.exp(np.mean(np.log(c2))))


def calibrate(rows: Optional[Iterable[GearRow]] = None) -> Calibration:
    """Fit the calibrated constants to the catalogue.

    * ``c_m``, ``e0``, ``g``, ``f0``: :func:`fit_mesh_constants` on every CSF row
      (sizes 14-50, N = 50-160).
    * T1, T2 coefficients: :func:`fit_breakpoints` over the same rows.
    * hysteresis fraction: CSF-25-100 hysteresis loss at rated torque = 1'.
    * starting torque: (c, q) through CSF-17-100 and CSF-25-50.

    :mod:`hdservo.design.crossval` gives the held-out errors of these fits.
    """
    rows = list(rows) if rows is not None else load_gears()
    cases = calibration_cases(rows)
    cal = fit_mesh_constants(cases)
    t1c, t2c = fit_breakpoints(cases)
    cal = replace(cal, t1_coefficient_N_per_m2=t1c, t2_coefficient_N_per_m2=t2c)
    # hysteresis: reference axis gear at rated torque -> 1 arcmin
    ref = next(g for g in rows if g.name == "CSF-25-100")
    s_ref = structure_for(25, 100)
    phi = float(twist(s_ref, cal, [ref.rated_torque_Nm])[0])
    cal = replace(cal, hysteresis_loss_fraction=ref.hysteresis_loss_max_arcmin * ARCMIN / (2 * phi))
    # starting torque through the two published points
    pts = [(g, structure_for(g.size, g.ratio)) for g in rows
           if g.series == "CSF" and g.starting_torque_input_Nm is not None]
    if len(pts) >= 2:
        d25 = 25 * 2.54e-3
        a = np.array([[1.0, math.log(100.0 / g.ratio)] for g, _ in pts])
        b = np.array([math.log(g.starting_torque_input_Nm / (s.pitch_diameter_m / d25) ** 3)
                      for g, s in pts])
        (lnc, q), *_ = np.linalg.lstsq(a, b, rcond=None)
        cal = replace(cal, starting_torque_coefficient_Nm=float(math.exp(lnc)),
                      starting_torque_ratio_exponent=float(q))
    return cal


def predicted_vs_catalogue(cal: Optional[Calibration] = None,
                           rows: Optional[Iterable[GearRow]] = None,
                           series: str = "CSF") -> List[Dict[str, float]]:
    """Predicted (structure -> model) vs catalogue three-slope values, one dict per row.

    K1-K3 are read off the structural torque-twist curve at the catalogue T1, T2
    (the catalogue defines K1 as the secant to its T1, so both sides use the same
    breakpoints); T1, T2 are predicted separately by :func:`breakpoints`.
    Keys: size, ratio, t1/t2 predicted and catalogue, k1..k3 predicted and
    catalogue, t*_err and k*_err (relative, predicted / catalogue - 1).
    """
    cal = cal if cal is not None else load_calibration()
    out = []
    for g in rows if rows is not None else load_gears():
        if g.series != series:
            continue
        s = structure_for(g.size, g.ratio)
        ts = three_slope(s, cal, (g.t1_Nm, g.t2_Nm))
        t1p, t2p = breakpoints(s, cal)
        rec = {"size": g.size, "ratio": g.ratio, "t1_pred": t1p, "t1_cat": g.t1_Nm,
               "t2_pred": t2p, "t2_cat": g.t2_Nm, "t1_err": t1p / g.t1_Nm - 1.0,
               "t2_err": t2p / g.t2_Nm - 1.0}
        for i, (kp, kc) in enumerate([(ts.k1_Nm_per_rad, g.k1_Nm_per_rad),
                                      (ts.k2_Nm_per_rad, g.k2_Nm_per_rad),
                                      (ts.k3_Nm_per_rad, g.k3_Nm_per_rad)], start=1):
            rec[f"k{i}_pred"], rec[f"k{i}_cat"], rec[f"k{i}_err"] = kp, kc, kp / kc - 1.0
        out.append(rec)
    return out
