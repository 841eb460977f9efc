"""Gear stiffness from the FE flexspline plus the tooth mesh and wave-generator bearing in series.

The FE model (:mod:`hdservo.design.flexspline_fe`) gives the flexspline alone.  A
catalogue stiffness (K1 at low torque, K3 at high torque) also contains, in series:

* the wave-generator bearing, Hertz ball contacts seen through the flank angle
  (:func:`hdservo.design.structure.bearing_twist`, no fitted constant), as the secant over
  the catalogue's torque range of that stiffness (0..T1 for K1, T2..2 T2 for K3);
* the tooth mesh: per-pair stiffness times the number of pairs in contact, times r²,
  ``K_mesh = c b r² z (200/z)^g``: c lumps the per-pair stiffness per unit face width
  and the engaged fraction at that torque level, g the module dependence.

So ``1/K = 1/K_FE + 1/K_brg + 1/K_mesh`` with two constants (c, g) per level, fitted to
the catalogue by least squares on log K.  :func:`cross_validate` holds out one size at
a time (all its ratios), fits on the others and predicts the held-out rows: those are
the errors reported (docs/design-flow.md), not the fit residuals.  The constants of the
fit on every size are stored in ``data/flexspline_fe.toml`` (a test refits them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from ..errors import UserError
from ..tomltext import read_toml_file
from . import flexspline_fe as fe
from . import structure as st
from .catalogue import DATA_DIR, GearRow, load_gears

RULE_FILE = DATA_DIR / "flexspline_fe.toml"
#: stiffness levels of the rule
LEVELS = ("k1", "k3")


@dataclass(frozen=True)
class MeshRule:
    """Tooth-mesh constants of the series rule (one pair per stiffness level).

    Attributes
    ----------
    k1_mesh_N_per_m2, k3_mesh_N_per_m2 : float
        c: mesh stiffness per tooth, per unit face width, with the engaged fraction of that
        level folded in, N/m².
    k1_module_exponent, k3_module_exponent : float
        g of the factor (200/z)^g, -.
    """

    k1_mesh_N_per_m2: float
    k1_module_exponent: float
    k3_mesh_N_per_m2: float
    k3_module_exponent: float


def load_rule(path: Path = RULE_FILE) -> MeshRule:
    """Read the ``[mesh_rule]`` constants (one error line for a bad file)."""
    doc = read_toml_file(path)
    sec = doc.get("mesh_rule")
    if not isinstance(sec, dict):
        raise UserError(f"{path}: missing table [mesh_rule]")
    vals = {}
    for f in fields(MeshRule):
        v = sec.get(f.name)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise UserError(f"{path}: [mesh_rule] {f.name}: expected a finite number, got {v!r}")
        vals[f.name] = float(v)
    return MeshRule(**vals)


# --------------------------------------------------------------------------- FE flexspline
@lru_cache(maxsize=256)
def _unit_stiffness(g_unit: fe.CupGeometry, level: int, harmonics: int) -> Tuple[float, float]:
    r = fe.CupModel(g_unit, level).torsion(harmonics)
    return r["stiffness_Nm_per_rad"], r["ring_stiffness_Nm_per_rad"]


def scaled(g: fe.CupGeometry, factor: float) -> fe.CupGeometry:
    """The geometry with every length multiplied by ``factor``."""
    return replace(g, **{k: getattr(g, k) * factor for k in
                         ("boss_radius_m", "diaphragm_m", "bore_radius_m", "wall_m", "length_m", "rim_width_m",
                          "rim_extra_m")})


def flexspline_stiffness(s: st.Structure, level: int = fe.DEFAULT_LEVEL,
                         harmonics: int = fe.DEFAULT_HARMONICS, ring: bool = False) -> float:
    """FE torsional stiffness of the flexspline of ``s`` (two-zone tooth load), N·m/rad.

    Linear elasticity is scale-free: a geometry scaled by lambda is lambda³ stiffer.  The FE
    runs once per shape on the geometry scaled to d = 1 m (cached) and is scaled by d³,
    so the catalogue's geometrically similar sizes cost one solve per ratio.  ``ring``: the
    rim's tooth surface turned as a rigid ring instead (the rim of the torsional modes).
    """
    g = fe.cup_geometry(s)
    d = s.pitch_diameter_m
    gu = scaled(g, 1.0 / d)
    gu = replace(gu, **{k: round(getattr(gu, k), 12) for k in ("boss_radius_m", "diaphragm_m", "bore_radius_m",
                                                              "wall_m", "length_m", "rim_width_m", "rim_extra_m")})
    return _unit_stiffness(gu, int(level), int(harmonics))[1 if ring else 0] * d ** 3


# --------------------------------------------------------------------------- series elements
def bearing_secant(s: st.Structure, t_lo: float, t_hi: float) -> float:
    """Secant stiffness of the wave-generator bearing between output torques t_lo and t_hi, N·m/rad."""
    p = st.bearing_twist(s, np.array([t_lo, t_hi]))
    return float((t_hi - t_lo) / (p[1] - p[0]))


def mesh_stiffness(s: st.Structure, c: float, g: float) -> float:
    """Tooth-mesh torsional stiffness ``c b r² z (200/z)^g``, N·m/rad."""
    r = 0.5 * s.pitch_diameter_m
    return c * s.face_width_m * r * r * s.teeth * (200.0 / s.teeth) ** g


def torque_range(level: str, t1: float, t2: float) -> Tuple[float, float]:
    """Catalogue torque range of a stiffness level: K1 0..T1, K3 T2..2 T2 (N·m)."""
    if level == "k1":
        return 0.0, t1
    if level == "k3":
        return t2, 2.0 * t2
    raise ValueError(f"stiffness level '{level}': expected one of {', '.join(LEVELS)}")


def gear_stiffness(s: st.Structure, level: str, t1: float, t2: float, c: float, g: float,
                   k_fe: Optional[float] = None) -> Dict[str, float]:
    """Series stiffness of one level and its parts.

    Returns
    -------
    dict
        ``k`` (gear), ``flexspline``, ``bearing``, ``mesh`` (N·m/rad) and ``rest`` (bearing and
        mesh in series: the rim spring of the FE torsional mode).
    """
    lo, hi = torque_range(level, t1, t2)
    kf = flexspline_stiffness(s) if k_fe is None else k_fe
    kb = bearing_secant(s, lo, hi)
    km = mesh_stiffness(s, c, g)
    rest = 1.0 / (1.0 / kb + 1.0 / km)
    return {"k": 1.0 / (1.0 / kf + 1.0 / rest), "flexspline": kf, "bearing": kb, "mesh": km, "rest": rest}


# --------------------------------------------------------------------------- fit and cross-validation
@dataclass(frozen=True)
class Case:
    """One catalogue row with its structure and FE flexspline stiffness."""

    row: GearRow
    s: st.Structure
    k_fe: float


def cases(rows: Optional[Iterable[GearRow]] = None, series: str = "CSF") -> List[Case]:
    """Catalogue rows of ``series`` with their structure (``structure_for``) and FE stiffness."""
    out = []
    for g in rows if rows is not None else load_gears():
        if g.series != series:
            continue
        s = st.structure_for(g.size, g.ratio)
        out.append(Case(g, s, flexspline_stiffness(s)))
    return out


def _catalogue_k(c: Case, level: str) -> float:
    return c.row.k1_Nm_per_rad if level == "k1" else c.row.k3_Nm_per_rad


def fit(train: Sequence[Case], level: str) -> Tuple[float, float]:
    """Least-squares (c, g) on log K of ``train`` at ``level``."""
    from scipy.optimize import least_squares

    def res(x: np.ndarray) -> np.ndarray:
        return np.array([math.log(gear_stiffness(c.s, level, c.row.t1_Nm, c.row.t2_Nm, math.exp(x[0]), x[1],
                                                 c.k_fe)["k"] / _catalogue_k(c, level)) for c in train])
    r = least_squares(res, x0=np.array([math.log(1e8), 0.5]), bounds=([-np.inf, -2.0], [np.inf, 2.0]),
                      method="trf", xtol=1e-12, ftol=1e-12)
    return float(math.exp(r.x[0])), float(r.x[1])


def fit_rule(all_cases: Optional[Sequence[Case]] = None) -> MeshRule:
    """The rule's constants fitted on every catalogue row (the stored values)."""
    cs = list(all_cases) if all_cases is not None else cases()
    c1, g1 = fit(cs, "k1")
    c3, g3 = fit(cs, "k3")
    return MeshRule(c1, g1, c3, g3)


def predict(c: Case, level: str, rule: MeshRule) -> Dict[str, float]:
    """Predicted stiffness of one case at ``level`` with the constants of ``rule``."""
    cm = rule.k1_mesh_N_per_m2 if level == "k1" else rule.k3_mesh_N_per_m2
    gm = rule.k1_module_exponent if level == "k1" else rule.k3_module_exponent
    return gear_stiffness(c.s, level, c.row.t1_Nm, c.row.t2_Nm, cm, gm, c.k_fe)


def cross_validate(all_cases: Optional[Sequence[Case]] = None) -> List[Dict[str, float]]:
    """Leave-one-size-out predictions of K1 and K3.

    For each size: fit (c, g) of each level on the other sizes, predict every ratio of the
    held-out size.  Returns one dict per row: ``size``, ``ratio``, ``k_fe``, and per level
    ``<level>_cat``, ``<level>_pred``, ``<level>_err`` (pred/cat - 1), ``<level>_fe_share``
    (flexspline share of the predicted compliance).
    """
    cs = list(all_cases) if all_cases is not None else cases()
    out = []
    for size in sorted({c.row.size for c in cs}):
        train = [c for c in cs if c.row.size != size]
        test = [c for c in cs if c.row.size == size]
        consts = {lv: fit(train, lv) for lv in LEVELS}
        for c in test:
            rec: Dict[str, float] = {"size": c.row.size, "ratio": c.row.ratio, "k_fe": c.k_fe}
            for lv in LEVELS:
                p = gear_stiffness(c.s, lv, c.row.t1_Nm, c.row.t2_Nm, *consts[lv], k_fe=c.k_fe)
                cat = _catalogue_k(c, lv)
                rec.update({f"{lv}_cat": cat, f"{lv}_pred": p["k"], f"{lv}_err": p["k"] / cat - 1.0,
                            f"{lv}_fe_share": p["k"] / p["flexspline"], f"{lv}_c": consts[lv][0],
                            f"{lv}_g": consts[lv][1]})
            out.append(rec)
    return out


# --------------------------------------------------------------------------- design-flow figures
def rim_spring(k1_catalogue: float, k_fe: float, k1_rule_rest: float) -> Tuple[float, str]:
    """Tooth mesh and WG bearing in series at the K1 level, N·m/rad, and where it comes from.

    For a catalogue gear the spring is what the catalogue K1 leaves after the FE flexspline,
    ``1 / (1/K1 - 1/K_FE)``: the measured K1 is kept and the FE only splits it (the rule's K1
    has an artificial ratio trend among N >= 80, where the catalogue gives one value).  When the
    FE flexspline alone is not stiffer than K1 (no positive remainder) the rule's spring is used.
    """
    if k_fe > 1.001 * k1_catalogue:
        return 1.0 / (1.0 / k1_catalogue - 1.0 / k_fe), "catalogue K1 minus FE flexspline"
    return k1_rule_rest, "series rule (mesh_rule.k1_*)"


def candidate_figures(gear: GearRow, load_inertia_kgm2: float, *, rule: Optional[MeshRule] = None,
                      level: int = fe.DEFAULT_LEVEL) -> Dict[str, object]:
    """FE figures of a catalogue gear carrying a load (the design flow's resonance figures).

    The flexspline of ``structure_for(size, ratio)`` in the FE model: static stiffness (two-zone
    tooth load, WG ellipse of one module imposed); the first torsional mode with the load on the
    boss and the rim's tooth surface held by the tooth mesh and WG bearing in series at the K1
    level (:func:`rim_spring`; the motor locked); the first tilting mode of the load (inertia
    J_L/2 about a diameter, a thin disc) on the flexspline alone (no output bearing); and the
    series rule's K1 and K3 (:func:`predict`) as a check against the catalogue.

    Returns
    -------
    dict
        ``flexspline_stiffness_Nm_per_rad``, ``k1_rule_Nm_per_rad``, ``k3_rule_Nm_per_rad``,
        ``k1_catalogue_Nm_per_rad``, ``k3_catalogue_Nm_per_rad``, ``rim_spring_Nm_per_rad``,
        ``rim_spring_source``, ``modal_rim_spring_Nm_per_rad`` (the rim spring with the two-zone
        contact compliance added), ``torsional_Hz``, ``tilting_Hz``, ``flexspline_mass_kg``,
        ``mesh_level``, ``dofs``.
    """
    rule = rule if rule is not None else load_rule()
    s = st.structure_for(gear.size, gear.ratio)
    c = Case(gear, s, flexspline_stiffness(s, level))
    k1 = predict(c, "k1", rule)
    k3 = predict(c, "k3", rule)
    spring, src = rim_spring(gear.k1_Nm_per_rad, c.k_fe, k1["rest"])
    # the modal model holds the rim's tooth surface as a rigid ring (harmonic 0): the extra
    # compliance of the two-zone contact (static FE, zones minus ring) goes into its spring,
    # so the modal model's static stiffness is the catalogue K1 exactly
    k_ring = flexspline_stiffness(s, level, ring=True)
    modal_spring = 1.0 / (1.0 / spring + 1.0 / c.k_fe - 1.0 / k_ring)
    res = fe.analyse(fe.cup_geometry(s), load_inertia_kgm2, rim_spring_Nm_per_rad=modal_spring,
                     ellipse_m=s.module_m, level=level)
    return {"flexspline_stiffness_Nm_per_rad": c.k_fe, "k1_rule_Nm_per_rad": k1["k"],
            "k3_rule_Nm_per_rad": k3["k"], "k1_catalogue_Nm_per_rad": gear.k1_Nm_per_rad,
            "k3_catalogue_Nm_per_rad": gear.k3_Nm_per_rad, "rim_spring_Nm_per_rad": spring,
            "rim_spring_source": src, "modal_rim_spring_Nm_per_rad": modal_spring, "torsional_Hz": res.torsional_Hz, "tilting_Hz": res.tilting_Hz,
            "flexspline_mass_kg": res.flexspline_mass_kg, "mesh_level": res.level, "dofs": res.dofs}
