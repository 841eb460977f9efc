"""Out-of-sample (cross-validated) errors of the structure relations.

The relations of :mod:`hdservo.design.structure` carry constants fitted to the
catalogue.  Their fit errors say how well the constants reproduce the rows they
were fitted to; a designer choosing a size that is not in the fit needs the
error on rows the fit never saw.  This module refits each relation with one
group of catalogue rows left out (one size: all its ratios; or one ratio: all
its sizes), predicts the left-out rows and reports the held-out error
``predicted / catalogue - 1`` per parameter:

==============  =============================================================  ==================
relation        fitted on the training rows                                    held-out parameters
==============  =============================================================  ==================
stiffness       c_m, e0, g, f0 by :func:`structure.fit_mesh_constants`;        K1, K2, K3 (at the
                T1/T2 coefficients by :func:`structure.fit_breakpoints`        catalogue T1, T2),
                                                                               T1, T2
hysteresis      loss fraction eta: geometric mean over the training rows of    hysteresis loss at
                (catalogue loss) / (2 phi(T_rated)), phi from the fold's own   rated torque
                stiffness fit
friction        c, q of ``T_start = c (d/d25)^3 (100/N)^q`` through the        starting torque,
                training rows with a published starting torque; with one      backdriving torque
                such row q is not identifiable and is set to
                :data:`UNIDENTIFIED_RATIO_EXPONENT`; backdriving factor =
                mean of backdriving / (N T_start) over the training rows
==============  =============================================================  ==================

The held-out row never enters the fit of its own prediction: :func:`leave_one_group_out`
passes the fit only the training rows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Dict, Generic, Hashable, List, Optional, Sequence, TypeVar

import numpy as np

from ..errors import UserError
from . import structure as st
from .catalogue import GearRow

M = TypeVar("M")

#: ratio exponent q of the starting-torque scaling when the training rows hold only one
#: published starting torque (q is then not identifiable): size scaling only
UNIDENTIFIED_RATIO_EXPONENT = 0.0

#: held-out targets per parameter (relative error bound); design-flow acceptance levels
TARGETS: Dict[str, float] = {"k1": 0.20, "k2": 0.20, "k3": 0.20, "t1": 0.20, "t2": 0.20,
                             "hysteresis_loss": 0.30, "starting_torque": 0.30,
                             "backdriving_torque": 0.30}


@dataclass(frozen=True)
class HeldOut:
    """One held-out prediction.

    Attributes
    ----------
    relation : str
        ``stiffness``, ``hysteresis`` or ``friction``.
    grouping : str
        ``size`` or ``ratio``: what one fold leaves out.
    fold : str
        The left-out group, e.g. ``size 25``.
    row : str
        Catalogue designation of the predicted row, e.g. ``CSF-25-100``.
    parameter : str
        ``k1``, ``k2``, ``k3``, ``t1``, ``t2``, ``hysteresis_loss``,
        ``starting_torque`` or ``backdriving_torque``.
    predicted, observed : float
        Prediction and catalogue value (N·m/rad, N·m or rad).
    """

    relation: str
    grouping: str
    fold: str
    row: str
    parameter: str
    predicted: float
    observed: float

    @property
    def error(self) -> float:
        """Relative held-out error, predicted / observed - 1."""
        return self.predicted / self.observed - 1.0


@dataclass(frozen=True)
class Relation(Generic[M]):
    """A relation to cross-validate.

    Attributes
    ----------
    name : str
        Relation name (``stiffness`` ...).
    fit : callable
        ``fit(training rows) -> model``; must use only the rows it is given.
    predict : callable
        ``predict(model, row) -> {parameter: value}``.
    observe : callable
        ``observe(row) -> {parameter: catalogue value}``; parameters absent from the
        row's catalogue data are left out of the dict.
    usable : callable
        ``usable(row) -> bool``: rows that carry data for this relation.
    """

    name: str
    fit: Callable[[Sequence[GearRow]], M]
    predict: Callable[[M, GearRow], Dict[str, float]]
    observe: Callable[[GearRow], Dict[str, float]]
    usable: Callable[[GearRow], bool]


GROUPINGS: Dict[str, Callable[[GearRow], Hashable]] = {
    "size": lambda g: g.size,
    "ratio": lambda g: g.ratio,
}


def leave_one_group_out(rows: Sequence[GearRow], relation: Relation[M], grouping: str = "size",
                        min_train: int = 1) -> List[HeldOut]:
    """Held-out predictions of ``relation``, leaving out one group at a time.

    Parameters
    ----------
    rows : sequence of GearRow
        Catalogue rows (only ``relation.usable`` rows are used).
    relation : Relation
        What to fit and predict.
    grouping : str
        ``size`` (leave one size out, all its ratios) or ``ratio``.
    min_train : int
        Folds with fewer usable training rows are skipped (nothing to fit).

    Returns
    -------
    list of HeldOut
        One entry per held-out row and parameter.
    """
    if grouping not in GROUPINGS:
        raise UserError(f"cross-validation grouping '{grouping}': expected one of "
                        f"{', '.join(GROUPINGS)}")
    key = GROUPINGS[grouping]
    data = [r for r in rows if relation.usable(r)]
    out: List[HeldOut] = []
    for gval in sorted({key(r) for r in data}):  # type: ignore[type-var]
        train = [r for r in data if key(r) != gval]
        test = [r for r in data if key(r) == gval]
        if len(train) < min_train:
            continue
        model = relation.fit(train)
        for r in test:
            pred = relation.predict(model, r)
            for par, obs in relation.observe(r).items():
                out.append(HeldOut(relation.name, grouping, f"{grouping} {gval}", r.name, par,
                                   float(pred[par]), float(obs)))
    return out


def summary(points: Sequence[HeldOut]) -> Dict[str, Dict[str, object]]:
    """Held-out error statistics per parameter.

    Returns
    -------
    dict
        ``{parameter: {n, max_abs, rms, mean, worst_row, worst_error, target, within}}``;
        errors relative (0.1 = 10 %); ``within`` is the fraction of held-out rows
        inside the target, ``meets`` whether all are.
    """
    out: Dict[str, Dict[str, object]] = {}
    for par in dict.fromkeys(p.parameter for p in points):
        sel = [p for p in points if p.parameter == par]
        e = np.array([p.error for p in sel])
        worst = sel[int(np.argmax(np.abs(e)))]
        tgt = TARGETS.get(par)
        rec: Dict[str, object] = {"n": len(sel), "max_abs": float(np.max(np.abs(e))),
                                  "rms": float(np.sqrt(np.mean(e ** 2))), "mean": float(np.mean(e)),
                                  "worst_row": worst.row, "worst_error": worst.error, "target": tgt}
        if tgt is not None:
            rec["within"] = float(np.mean(np.abs(e) <= tgt))
            rec["meets"] = bool(np.all(np.abs(e) <= tgt))
        out[par] = rec
    return out


# --------------------------------------------------------------------------- the relations
def _structure(g: GearRow) -> st.Structure:
    return st.structure_for(g.size, g.ratio)


def fit_stiffness(train: Sequence[GearRow]) -> st.Calibration:
    """Mesh constants and breakpoint coefficients fitted to ``train`` only."""
    cases = [(_structure(g), g) for g in train]
    cal = st.fit_mesh_constants(cases)
    t1c, t2c = st.fit_breakpoints(cases)
    return replace(cal, t1_coefficient_N_per_m2=t1c, t2_coefficient_N_per_m2=t2c)


def predict_stiffness(cal: st.Calibration, g: GearRow) -> Dict[str, float]:
    """K1-K3 at the row's catalogue T1, T2 and the predicted T1, T2."""
    s = _structure(g)
    ts = st.three_slope(s, cal, (g.t1_Nm, g.t2_Nm))
    t1, t2 = st.breakpoints(s, cal)
    return {"k1": ts.k1_Nm_per_rad, "k2": ts.k2_Nm_per_rad, "k3": ts.k3_Nm_per_rad,
            "t1": t1, "t2": t2}


def observe_stiffness(g: GearRow) -> Dict[str, float]:
    """Catalogue K1-K3, T1, T2."""
    return {"k1": g.k1_Nm_per_rad, "k2": g.k2_Nm_per_rad, "k3": g.k3_Nm_per_rad,
            "t1": g.t1_Nm, "t2": g.t2_Nm}


def fit_hysteresis(train: Sequence[GearRow]) -> st.Calibration:
    """Stiffness fitted to ``train``, then the loss fraction eta as the geometric mean
    over ``train`` of catalogue loss / (2 phi(T_rated))."""
    cal = fit_stiffness(train)
    eta = [g.hysteresis_loss_max_arcmin * st.ARCMIN
           / (2.0 * float(st.twist(_structure(g), cal, [g.rated_torque_Nm])[0])) for g in train]
    return replace(cal, hysteresis_loss_fraction=float(np.exp(np.mean(np.log(eta)))))


def predict_hysteresis(cal: st.Calibration, g: GearRow) -> Dict[str, float]:
    """Hysteresis loss at the row's rated torque, rad."""
    return {"hysteresis_loss": st.hysteresis_loss(_structure(g), cal, g.rated_torque_Nm)}


def observe_hysteresis(g: GearRow) -> Dict[str, float]:
    """Catalogue hysteresis loss (an upper bound in the shipped catalogue), rad."""
    return {"hysteresis_loss": g.hysteresis_loss_max_arcmin * st.ARCMIN}


@dataclass(frozen=True)
class FrictionFit:
    """Starting-torque scaling and backdriving factor fitted to training rows.

    Attributes
    ----------
    coefficient_Nm : float
        c of ``T_start = c (d/d25)^3 (100/N)^q``, N·m.
    ratio_exponent : float
        q, -.
    backdrive_factor : float
        backdriving torque / (N T_start), -.
    q_identified : bool
        False if the training rows could not determine q (one ratio or one row).
    """

    coefficient_Nm: float
    ratio_exponent: float
    backdrive_factor: float
    q_identified: bool


D25_M = 25 * 2.54e-3


def fit_friction(train: Sequence[GearRow]) -> FrictionFit:
    """Least squares in logs of the starting-torque scaling through ``train``.

    q is fitted only if the training rows span two or more ratios; otherwise it is
    :data:`UNIDENTIFIED_RATIO_EXPONENT`.
    """
    pts = [(g, _structure(g)) for g in train if g.starting_torque_input_Nm is not None]
    if not pts:
        raise UserError("friction fit: no training row has a published starting torque")
    y = np.array([math.log(g.starting_torque_input_Nm / (s.pitch_diameter_m / D25_M) ** 3)  # type: ignore[operator]
                  for g, s in pts])
    xq = np.array([math.log(100.0 / g.ratio) for g, _ in pts])
    if len({g.ratio for g, _ in pts}) >= 2:
        (lnc, q), *_ = np.linalg.lstsq(np.column_stack([np.ones_like(xq), xq]), y, rcond=None)
        ident = True
    else:
        q = UNIDENTIFIED_RATIO_EXPONENT
        lnc = float(np.mean(y - q * xq))
        ident = False
    back = [g.backdriving_torque_output_Nm / (g.ratio * g.starting_torque_input_Nm)  # type: ignore[operator]
            for g, _ in pts if g.backdriving_torque_output_Nm is not None]
    factor = float(np.mean(back)) if back else st.BACKDRIVE_FACTOR
    return FrictionFit(float(math.exp(lnc)), float(q), factor, ident)


def predict_friction(f: FrictionFit, g: GearRow) -> Dict[str, float]:
    """Starting torque at the input and backdriving torque at the output, N·m."""
    s = _structure(g)
    ts = f.coefficient_Nm * (s.pitch_diameter_m / D25_M) ** 3 * (100.0 / g.ratio) ** f.ratio_exponent
    return {"starting_torque": ts, "backdriving_torque": f.backdrive_factor * g.ratio * ts}


def observe_friction(g: GearRow) -> Dict[str, float]:
    """Published starting and backdriving torque, N·m."""
    out: Dict[str, float] = {}
    if g.starting_torque_input_Nm is not None:
        out["starting_torque"] = g.starting_torque_input_Nm
    if g.backdriving_torque_output_Nm is not None:
        out["backdriving_torque"] = g.backdriving_torque_output_Nm
    return out


def _csf(g: GearRow) -> bool:
    return g.series == "CSF"


STIFFNESS: Relation[st.Calibration] = Relation("stiffness", fit_stiffness, predict_stiffness,
                                               observe_stiffness, _csf)
HYSTERESIS: Relation[st.Calibration] = Relation("hysteresis", fit_hysteresis, predict_hysteresis,
                                                observe_hysteresis, _csf)
FRICTION: Relation[FrictionFit] = Relation(
    "friction", fit_friction, predict_friction, observe_friction,
    lambda g: _csf(g) and g.starting_torque_input_Nm is not None)

RELATIONS = {"stiffness": STIFFNESS, "hysteresis": HYSTERESIS, "friction": FRICTION}


def cross_validate(rows: Sequence[GearRow], groupings: Sequence[str] = ("size", "ratio"),
                   relations: Optional[Sequence[str]] = None) -> Dict[str, object]:
    """Leave-one-group-out errors of every relation and grouping.

    Returns
    -------
    dict
        ``{"<relation>/<grouping>": {"summary": summary(...), "points": [...]}}``.
    """
    out: Dict[str, object] = {}
    for name in relations if relations is not None else list(RELATIONS):
        rel = RELATIONS[name]
        for grp in groupings:
            pts = leave_one_group_out(rows, rel, grp)  # type: ignore[arg-type]
            out[f"{name}/{grp}"] = {
                "summary": summary(pts) if pts else {},
                "points": [{"fold": p.fold, "row": p.row, "parameter": p.parameter,
                            "predicted": p.predicted, "observed": p.observed, "error": p.error}
                           for p in pts]}
    return out
