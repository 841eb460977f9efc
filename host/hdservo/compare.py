"""Closed-loop comparison: the test procedures with the PID baseline, each compensator and the best combination.

``hdservo compare`` (:mod:`hdservo.commands.compare`) runs the standard test
procedures of ``hdservo test`` (:data:`hdservo.commands.test.PROCEDURES`,
their own defaults and option parser) once per *controller*:

* ``pid`` -- the drive's PID baseline, every compensator off (``cb_enable`` 0);
* one controller per compensator of the bank (``stribeck``, ``lugre``,
  ``maxwell``, ``preisach``, ``te``, ``compliance``, ``backstep``): that compensator alone on
  top of the PID;
* ``best`` -- the best combination (docs/compensators.md section 8): its
  compensators plus the loop retuning it allows.  Taken from
  ``hdservo.compsetup`` (``BEST_NAMES``, ``best_gains(axis)``) when that module
  defines it, otherwise from :data:`BEST_NAMES_DEFAULT` /
  :func:`best_gains_default`.

Each procedure opens its own bench (:func:`hdservo.procedures.runner.open_bench`:
on the virtual drive a fresh ``hdservo-sim serve`` with the procedure's rig
set-up).  With an identified model (``--model``) the compensator parameters
and tables computed from it (:func:`hdservo.download.plan_download`)
are written to the drive and read back (:func:`~hdservo.download.write_verified`)
before every compensated procedure, then the controller's gains, then
``cb_enable``; without a model the drive's own compensator defaults are used.

Output directory layout (``OUT``):

* ``OUT/compare.json`` -- ``{"format": "hdservo-compare", "version": 1, ...}``
  (see :func:`run_compare`), written last and atomically;
* ``OUT/<controller>/test.json`` -- the ``hdservo-test`` JSON of that controller;
* ``OUT/<controller>/plots/*.png`` -- the procedures' plots;
* ``OUT/plots/compare_<figure>.png`` -- one bar chart per headline figure.

Paths inside ``compare.json`` are relative to ``OUT``.
"""
from __future__ import annotations

import argparse
import math
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence

import numpy as np

from .fileio import write_json_atomic
from .progress import Bar

FORMAT = "hdservo-compare"
VERSION = 1

#: Compensators of the bank compared one by one (the experimental DOB is left out; docs/compensators.md 8).
SINGLES: tuple[str, ...] = ("stribeck", "lugre", "maxwell", "preisach", "te", "compliance", "backstep")
#: Procedures run by default: the ones behind the headline figures.
DEFAULT_PROCEDURES: tuple[str, ...] = ("min-rate", "positioning", "stabilisation", "bandwidth", "peak-torque",
                                        "tracking", "settling")
#: Best combination when hdservo.compsetup does not define one (docs/compensators.md section 8).
BEST_NAMES_DEFAULT: tuple[str, ...] = ("lugre",)
#: Retuned gains of the default best combination, table units (position P 1/s, scheduled position integral 1/s^2).
BEST_GAINS_DEFAULT: dict[str, float] = {"pos_kp": 60.0, "cb_pki": 900.0}
#: Velocity-loop integral of the default best combination relative to the axis' PID design (12000 / 8019).
BEST_VEL_KI_RATIO = 12000.0 / 8019.0

#: Shortened procedure options (``--quick``): parsed by ``hdservo test``'s option parser.
QUICK_ARGS: tuple[str, ...] = ("--runs", "3", "--targets=-50,-20,10,40", "--windows", "5", "--settle", "3",
                               "--duration", "4", "--moves", "2")


@dataclass(frozen=True)
class Figure:
    """A headline figure: key in the procedures' ``headline``, unit, direction, target.

    Attributes
    ----------
    key : str
        Headline key (``hdservo.procedures.results``).
    label : str
        Human name.
    unit : str
        Unit of the value (also in the key).
    lower_is_better : bool
        Direction of "better".
    target : float or None
        Requirement of the reference axis (docs/reference-axis.md) (None: no target).
    procedure : str
        The procedure that measures it.
    short : str
        Axis label (without the unit).
    """

    key: str
    label: str
    unit: str
    lower_is_better: bool
    target: Optional[float]
    procedure: str
    short: str = ""

    def target_text(self) -> str:
        """``<= 10 arcsec`` style text, or ``-``."""
        if self.target is None:
            return "-"
        return f"{'<=' if self.lower_is_better else '>='} {self.target:g} {self.unit}"

    def meets(self, value: Optional[float]) -> Optional[bool]:
        """Whether ``value`` meets the target (None: no target or no value)."""
        if self.target is None or value is None:
            return None if self.target is None else False
        return value <= self.target if self.lower_is_better else value >= self.target

    def verdict(self, value: Optional[float], ref: Optional[float], tol: float = 0.01) -> str:
        """``better``, ``same`` (within ``tol`` relative), ``worse`` or ``n/a`` of ``value`` against ``ref``.

        A missing value (e.g. no smooth rate at all) counts as the worst possible.
        """
        if value is None and ref is None:
            return "n/a"
        if value is None:
            return "worse"
        if ref is None:
            return "better"
        scale = max(abs(value), abs(ref), 1e-300)
        if abs(value - ref) <= tol * scale:
            return "same"
        return "better" if (value < ref) == self.lower_is_better else "worse"


#: The headline figures of the comparison, summary and report (docs/reference-axis.md).
FIGURES: tuple[Figure, ...] = (
    Figure("min_smooth_rate_deg_s", "minimum smooth rate", "deg/s", True, 0.001, "min-rate", "min. smooth rate"),
    Figure("positioning_accuracy_arcsec", "positioning accuracy (ISO 230-2 A)", "arcsec", True, 10.0, "positioning",
           "accuracy A"),
    Figure("repeatability_arcsec", "repeatability (ISO 230-2 R)", "arcsec", True, 2.0, "positioning",
           "repeatability R"),
    Figure("stabilisation_rms_arcsec", "stabilisation precision (RMS, base 0.5 deg at 1 Hz)", "arcsec", True, 20.0,
           "stabilisation", "inertial error RMS"),
    Figure("bandwidth_hz", "closed-loop bandwidth (-3 dB)", "Hz", False, None, "bandwidth", "bandwidth"),
    Figure("peak_torque_Nm", "peak output torque", "N.m", False, 30.0, "peak-torque", "peak torque"),
    Figure("tracking_rms_0p01_arcsec", "tracking error RMS, sinusoid peak 0.01 deg/s", "arcsec", True, None,
           "tracking", "tracking RMS 0.01 deg/s"),
    Figure("tracking_peak_0p01_arcsec", "tracking error peak, sinusoid peak 0.01 deg/s", "arcsec", True, None,
           "tracking", "tracking peak 0.01 deg/s"),
    Figure("tracking_rms_0p1_arcsec", "tracking error RMS, sinusoid peak 0.1 deg/s", "arcsec", True, None,
           "tracking", "tracking RMS 0.1 deg/s"),
    Figure("tracking_peak_0p1_arcsec", "tracking error peak, sinusoid peak 0.1 deg/s", "arcsec", True, None,
           "tracking", "tracking peak 0.1 deg/s"),
    Figure("reversal_peak_arcsec", "reversal (quadrant) glitch peak", "arcsec", True, None, "tracking",
           "reversal peak"),
    Figure("settling_1deg_s", "settling time into +-1 arcsec after a 1 deg move", "s", True, None, "settling",
           "settling 1 deg"),
)
FIGURE_BY_KEY: dict[str, Figure] = {f.key: f for f in FIGURES}


@dataclass
class Controller:
    """One configuration of the drive's controller.

    Attributes
    ----------
    name : str
        ``pid``, a compensator name, ``best`` or a custom label.
    compensators : list of str
        Names of :data:`hdservo.compsetup.ENABLE_BITS` switched on (``cb_enable``).
    gains : dict
        Drive parameters set (by name, table units) before the procedure, e.g. retuned loop gains.
    description : str
        One line for the report.
    proc_args : dict
        Extra ``hdservo test`` options per procedure for this controller (e.g. a drive mode the
        procedure offers), ``{"stabilisation": ["--opt", "value"]}``.
    feedback : str
        Feedback configuration (a key of :data:`FEEDBACKS`).
    kind : str
        Role in the ablation: ``baseline`` (the fair PID), ``compensator`` (fair PID + one),
        ``selection`` (a row the forward selection measures: the current best + one candidate),
        ``best``, ``leave-one-out``, ``strategy`` (motion strategies on top of the best),
        ``extra`` (labelled extra rows such as the PID in position hold) or ``custom``.
    components : list of str
        Compensators and motion strategies of the row (what the ablation reports).
    """

    name: str
    compensators: list[str] = field(default_factory=list)
    gains: dict[str, float] = field(default_factory=dict)
    description: str = ""
    proc_args: dict[str, list[str]] = field(default_factory=dict)
    feedback: str = "full-closed"
    kind: str = "custom"
    components: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "compensators": list(self.compensators), "gains": dict(self.gains),
                "description": self.description, "proc_args": {k: list(v) for k, v in self.proc_args.items()},
                "feedback": self.feedback, "kind": self.kind, "components": list(self.components)}


def best_gains_default(axis: str = "reference") -> dict[str, float]:
    """Retuned gains of the default best combination for an axis (table units).

    Parameters
    ----------
    axis : str
        Axis spec (``reference`` or an axis TOML path).

    Returns
    -------
    dict
        ``pos_kp`` (1/s), ``cb_pki`` (1/s^2), ``vel_ki`` (N.m/rad): 1.5x the axis' PID design.
    """
    from . import closedloop_cases as bl
    try:
        base = bl.axis_controller(axis)["gains"]
    except Exception:   # noqa: BLE001 - an axis the baseline cannot read: the reference design
        base = "defaults"
    from .params_gen import BY_NAME
    vel_ki = 8019.0 if base == "defaults" else float(base["vel_ki"])
    return dict(BEST_GAINS_DEFAULT, vel_ki=min(vel_ki * BEST_VEL_KI_RATIO, BY_NAME["vel_ki"].max))


def best_controller(axis: str = "reference") -> Controller:
    """The best combination: ``hdservo.compsetup.BEST_NAMES`` / ``best_gains`` when defined, else the defaults.

    ``hdservo.compsetup.BEST_PROC_ARGS`` (procedure -> extra ``hdservo test`` options), when
    defined, becomes the controller's ``proc_args``.
    """
    from . import compsetup
    names = getattr(compsetup, "BEST_NAMES", None)
    gains_fn = getattr(compsetup, "best_gains", None)
    src = "hdservo.compsetup"
    if names is None or gains_fn is None:
        names, gains_fn, src = BEST_NAMES_DEFAULT, best_gains_default, "hdservo.compare defaults"
    gains = {k: float(v) for k, v in gains_fn(axis).items()}
    desc = (f"best combination ({src}): {' + '.join(names)} with "
            + ", ".join(f"{k} = {v:.6g}" for k, v in gains.items()))
    pa = {str(k): [str(x) for x in v] for k, v in dict(getattr(compsetup, "BEST_PROC_ARGS", {}) or {}).items()}
    if pa:
        desc += "; procedure options: " + "; ".join(f"{k}: {' '.join(v)}" for k, v in pa.items())
    return Controller("best", list(names), gains, desc, pa)


#: Feedback configurations of the drive: name -> value of the drive parameter :data:`FEEDBACK_PARAM`
#: (0 position and velocity on the output side as wired today, 1 semi-closed: position and velocity on
#: the motor encoder, 2 dual-loop: velocity on the motor encoder, position on the output encoder).
FEEDBACKS: dict[str, int] = {"full-closed": 0, "semi-closed": 1, "dual-loop": 2}
FEEDBACK_PARAM = "fb_config"
#: Loop gains read back from the drive into each procedure's conditions (``loop_gains``).
LOOP_GAIN_NAMES: tuple[str, ...] = ("pos_kp", "pos_ki", "vel_kp", "vel_ki")
#: Rule of the best combination (:func:`choose_best`): a compensator qualifies when, on top of the fair
#: PID in the same feedback configuration, it improves at least one figure by at least this fraction ...
RULE_GAIN = 0.20
#: ... and worsens none by more than this fraction.
RULE_LOSS = 0.10
#: Figures the rule does not judge: the settling time into +-1 arcsec is all-or-nothing near the band
#: (a proportional position loop that ends 1.1 arcsec off never settles), so it is reported, not used.
RULE_SKIP: tuple[str, ...] = ("settling_1deg_s",)


def feedback_names(text: str) -> list[str]:
    """Feedback configurations from ``full-closed,semi-closed`` (short forms ``full``, ``semi``, ``dual``).

    Raises
    ------
    ValueError
        An unknown name (message lists the valid ones).
    """
    short = {"full": "full-closed", "semi": "semi-closed", "dual": "dual-loop"}
    out: list[str] = []
    for raw in text.split(","):
        n = short.get(raw.strip(), raw.strip())
        if not n:
            continue
        if n not in FEEDBACKS:
            raise ValueError(f"--feedback: unknown configuration '{raw.strip()}'; expected some of "
                             f"{', '.join(FEEDBACKS)} (or full, semi, dual)")
        if n not in out:
            out.append(n)
    if not out:
        raise ValueError("--feedback: none given")
    return out


def drive_has_feedback_param() -> bool:
    """True when the drive parameter table has :data:`FEEDBACK_PARAM` (the firmware offers configurations)."""
    from .params_gen import BY_NAME
    return FEEDBACK_PARAM in BY_NAME


def default_feedbacks() -> list[str]:
    """Feedback configurations compared by default: full-closed, and semi-closed when the drive has them."""
    return ["full-closed", "semi-closed"] if drive_has_feedback_param() else ["full-closed"]


def row_name(base: str, feedback: str = "full-closed") -> str:
    """Row name: ``base`` in full-closed, ``base@feedback`` in the other configurations."""
    return base if feedback == "full-closed" else f"{base}@{feedback}"


def feedback_gains(feedback: str) -> dict[str, float]:
    """Drive parameters of a feedback configuration (none for full-closed, the drive's default)."""
    if feedback not in FEEDBACKS:
        raise ValueError(f"unknown feedback configuration '{feedback}'; expected one of {', '.join(FEEDBACKS)}")
    return {} if feedback == "full-closed" else {FEEDBACK_PARAM: float(FEEDBACKS[feedback])}


def design_gains(axis: str = "reference") -> dict[str, float]:
    """The axis' PID design (velocity PI at 25 Hz, notch at the coupled resonance; :func:`hdservo.closedloop_cases.axis_controller`).

    Empty for the reference axis (the drive's defaults are its design) and for an axis the
    baseline cannot read.
    """
    from . import closedloop_cases as bl
    try:
        g = bl.axis_controller(axis)["gains"]
    except Exception:      # noqa: BLE001 - an axis the design rules cannot read keeps the drive's own gains
        return {}
    return {} if g == "defaults" else {k: float(v) for k, v in g.items()}


def fair_row(parts: Sequence[str], feedback: str = "full-closed", kind: str = "custom",
             name: Optional[str] = None, axis: str = "reference") -> Controller:
    """A row on the fair footing: the fair loop gains and procedure options plus ``parts``.

    Parameters
    ----------
    parts : sequence of str
        Compensators (:data:`hdservo.compsetup.ENABLE_BITS`) and motion strategies
        (:data:`hdservo.compsetup.STRATEGIES`); empty = the fair PID.
    feedback : str
        Feedback configuration.
    kind : str
        Role (see :class:`Controller`).
    name : str, optional
        Row base name (default ``pid`` or the parts joined by ``+``).
    axis : str
        Axis spec: its PID design (:func:`design_gains`) is part of every row's gains.

    Returns
    -------
    Controller
        Gains = the axis' PID design + fair gains + each part's settings + the feedback configuration.

    Raises
    ------
    ValueError
        An unknown part.
    """
    from . import compsetup as cs
    comps: list[str] = []
    gains: dict[str, float] = design_gains(axis)
    fair = {k: float(v) for k, v in cs.fair_gains(axis).items()}
    gains.update(fair)
    for part in parts:
        if part in cs.STRATEGIES:
            en, prm = cs.STRATEGIES[part]
            comps += [c for c in en if c not in comps]
            gains.update(prm)
        elif part in cs.ENABLE_BITS:
            if part not in comps:
                comps.append(part)
            gains.update(cs.COMPONENT_PARAMS.get(part, {}))
        else:
            raise ValueError(f"unknown component '{part}': expected compensators from "
                             f"{', '.join(cs.ENABLE_BITS)} or motion strategies {', '.join(cs.STRATEGIES)}")
    gains.update(feedback_gains(feedback))
    base = name or ("pid" if not parts else "+".join(parts))
    what = "fair PID" + ("".join(f" + {p}" for p in parts))
    desc = (f"{what}, {feedback}; loop gains of the compensated set ("
            + ", ".join(f"{k} = {v:.4g}" for k, v in fair.items())
            + "), stabilisation in the gyro mode")
    return Controller(row_name(base, feedback), comps, gains, desc, {k: list(v) for k, v in cs.FAIR_PROC_ARGS.items()},
                      feedback, kind, list(parts))


def pid_hold_row(axis: str = "reference") -> Controller:
    """The PID of the axis' design gains with the stabilisation in position hold: an extra, labelled row."""
    return Controller("pid-hold", [], design_gains(axis), "extra row, not a baseline: PID with the axis' design gains "
                      "(position P of the PID design), stabilisation in position hold (CSP)", {}, "full-closed",
                      "extra", ["pid design gains", "position hold"])


def controllers_from_names(names: Sequence[str], axis: str = "reference",
                           feedbacks: Sequence[str] = ("full-closed",)) -> list[Controller]:
    """Controllers by name, on the fair footing, for each feedback configuration.

    Names: ``pid`` (the fair PID), ``best`` (the default best combination,
    :data:`hdservo.compsetup.DEFAULT_BEST`), ``pid-hold`` (extra row: the PID design in position
    hold; full-closed only), or compensators / motion strategies joined by ``+`` (e.g.
    ``stribeck+te``, ``best+hold+approach``; ``best`` inside a name stands for its parts).

    Raises
    ------
    ValueError
        An unknown name (message names it and the valid ones).
    """
    from . import compsetup as cs
    out: list[Controller] = []
    seen: set[str] = set()
    for fb in feedbacks:
        for raw in names:
            n = raw.strip()
            if not n or (n, fb) in seen:
                continue
            seen.add((n, fb))
            if n == "pid-hold":
                if fb == "full-closed":
                    out.append(pid_hold_row(axis))
                continue
            if n == "pid":
                out.append(fair_row([], fb, "baseline", axis=axis))
                continue
            parts: list[str] = []
            for p in n.split("+"):
                parts += list(cs.DEFAULT_BEST) if p == "best" else [p]
            bad = [p for p in parts if p not in cs.ENABLE_BITS and p not in cs.STRATEGIES]
            if bad:
                raise ValueError(f"unknown controller '{n}': expected pid, best, pid-hold, or compensators and "
                                 f"motion strategies joined by '+' from {', '.join(cs.ENABLE_BITS)}, "
                                 f"{', '.join(cs.STRATEGIES)}")
            kind = "best" if n == "best" else ("strategy" if any(p in cs.STRATEGIES for p in parts) else
                                               "compensator")
            out.append(fair_row(parts, fb, kind, name=n, axis=axis))
    if not out:
        raise ValueError("no controllers given")
    return out


def default_controller_names() -> list[str]:
    """The explicit equivalent of the ablation's first stage: ``pid``, each compensator of :data:`SINGLES`, ``best``."""
    return ["pid", *SINGLES, "best"]


def ratio(f: Figure, value: Optional[float], base: Optional[float]) -> Optional[float]:
    """``value / base`` of a figure (None when either is missing or the base is 0)."""
    if value is None or base is None or base == 0:
        return None
    return float(value) / float(base)


def worse_factor(f: Figure, value: Optional[float], base: Optional[float]) -> Optional[float]:
    """How much worse than ``base`` ``value`` is, as a factor (< 1 better, > 1 worse; direction of ``f``).

    A missing value against a present base is infinitely worse, the reverse infinitely better;
    None when both are missing or the base is 0.
    """
    if value is None and base is None:
        return None
    if value is None:
        return math.inf
    if base is None:
        return 0.0
    if f.lower_is_better:
        return None if base == 0 else (value / base if value > 0 or base > 0 else 1.0)
    return None if value == 0 else base / value


def qualifies(headline: Mapping[str, Any], base: Mapping[str, Any], keys: Sequence[str]) -> tuple[bool, str]:
    """The rule of the best combination for one row against the fair PID (:data:`RULE_GAIN`, :data:`RULE_LOSS`).

    A figure counts when both rows measured it (a key absent from a headline: the procedure
    failed); None (measured, no value: e.g. no smooth rung) is the worst value.  The figures of
    :data:`RULE_SKIP` are not judged.

    Returns
    -------
    (bool, str)
        Whether the row improves a figure by >= 20 % and worsens none by > 10 %, and why (one line).
    """
    w = {k: worse_factor(FIGURE_BY_KEY[k], headline.get(k), base.get(k)) for k in keys
         if k in FIGURE_BY_KEY and k not in RULE_SKIP and k in headline and k in base}   # absent = not measured
    w = {k: v for k, v in w.items() if v is not None}
    gains = [k for k, v in w.items() if v <= 1.0 - RULE_GAIN]
    losses = [k for k, v in w.items() if v > 1.0 + RULE_LOSS]
    if not gains:
        return False, "improves no figure by 20 %"
    if losses:
        return False, "worsens " + ", ".join(f"{k} (x{w[k]:.3g})" for k in losses) + " by more than 10 %"
    return True, "improves " + ", ".join(f"{k} (x{w[k]:.3g})" for k in gains)


def geo_mean_factor(headline: Mapping[str, Any], base: Mapping[str, Any], keys: Sequence[str]) -> float:
    """Geometric mean of the finite worse-factors (:func:`worse_factor`; 1 = the PID, < 1 better)."""
    w = [worse_factor(FIGURE_BY_KEY[k], headline.get(k), base.get(k)) for k in keys
         if k in FIGURE_BY_KEY and k not in RULE_SKIP and k in headline and k in base]
    fin = [max(x, 1e-6) for x in w if x is not None and math.isfinite(x)]
    pen = sum(1 for x in w if x is not None and math.isinf(x))
    return math.exp(sum(math.log(x) for x in fin) / max(1, len(fin))) * (10.0 ** pen)


def part_pays(best: Mapping[str, Any], without: Mapping[str, Any], keys: Sequence[str]) -> tuple[bool, str]:
    """Whether one part of the best combination pays in it: the leave-one-out judgement.

    Parameters
    ----------
    best : mapping
        Headline of the best combination.
    without : mapping
        Headline of the best combination minus the part.
    keys : sequence of str
        The figures judged (:data:`RULE_SKIP` figures are not).

    Returns
    -------
    (bool, str)
        True when the combination is at least :data:`RULE_GAIN` better on one figure than the
        combination without the part (the part's own gain, beyond the run-to-run scatter of a
        single figure), and why: the figures it buys and those it costs, as factors of the
        combination against the combination without it (< 1 better).
    """
    w = {k: worse_factor(FIGURE_BY_KEY[k], best.get(k), without.get(k)) for k in keys
         if k in FIGURE_BY_KEY and k not in RULE_SKIP and k in best and k in without}
    w = {k: v for k, v in w.items() if v is not None}
    gains = [k for k, v in w.items() if v <= 1.0 - RULE_GAIN]
    losses = [k for k, v in w.items() if v > 1.0 + RULE_LOSS]
    cost = ("; costs " + ", ".join(f"{k} (x{w[k]:.3g})" for k in losses)) if losses else ""
    if not gains:
        return False, f"adds no figure by 20 % to the rest of the combination{cost}"
    return True, "buys " + ", ".join(f"{k} (x{w[k]:.3g})" for k in gains) + cost


#: Rows the forward selection (:func:`choose_best`) measures at most per feedback configuration beyond
#: stage 1: it bounds the run time (a step measures the current best plus each remaining candidate).
SELECTION_MAX_ROWS = 8
#: The rule of the best combination, as stored in ``ablation.json`` (``feedbacks[fb].rule``).
RULE_TEXT = ("greedy forward selection per feedback configuration: (1) measure the fair PID and the fair PID + "
             "each compensator (in semi-closed and dual-loop also TE + each motor-side predictor); (2) start "
             "from the friction compensator (stribeck, lugre, backstep) that qualifies against the fair PID "
             "with the smallest geometric-mean factor (else the qualifying compensator of any group with the "
             "smallest factor, else the one with the smallest factor below 1, else none); (3) measure the "
             "current best + each candidate of the groups not yet used (lost motion / hysteresis, transmission "
             "error with its measured pairs, compliance; the Preisach twist with neither compliance nor "
             "Maxwell-slip) and accept the one with the smallest geometric-mean factor against the current "
             f"best among those that improve at least one figure by >= {RULE_GAIN:.0%} against the current "
             f"best, are better than it on balance (factor < 1) and worsen no figure by more than {RULE_LOSS:.0%} "
             "against the fair PID; repeat until none does, the groups are used up or "
             f"{SELECTION_MAX_ROWS} rows are measured. A row qualifies against the fair PID when it improves "
             f"at least one figure by >= {RULE_GAIN:.0%} and worsens none by more than {RULE_LOSS:.0%}; "
             "the settling time is reported, not judged; the factor is the geometric mean of the row's value "
             "ratios to the row it is judged against (< 1 better)")


def step_qualifies(headline: Mapping[str, Any], current: Mapping[str, Any], base: Mapping[str, Any],
                   keys: Sequence[str]) -> tuple[bool, str]:
    """The forward selection's judgement of the current best + a candidate (:func:`choose_best`).

    Parameters
    ----------
    headline : mapping
        Headline of the current best + the candidate.
    current : mapping
        Headline of the current best.
    base : mapping
        Headline of the fair PID (same feedback configuration).
    keys : sequence of str
        The figures judged (:data:`RULE_SKIP` figures are not).

    Returns
    -------
    (bool, str)
        True when the row improves at least one figure by :data:`RULE_GAIN` against the current
        best, is better than it on balance (geometric-mean factor < 1), and worsens no figure by
        more than :data:`RULE_LOSS` against the fair PID; and why (one line).  The losses are
        judged against the fair PID because the current best may already hold a figure far
        below the PID's (in semi-closed the friction feed-forward makes the stops repeat to a
        fraction of an arcsecond while they miss the target by tens): a candidate that gives
        part of such a gain back for a larger gain elsewhere still leaves the combination
        better than the PID on every figure and better than the current best on balance.
    """
    wc = {k: worse_factor(FIGURE_BY_KEY[k], headline.get(k), current.get(k)) for k in keys
          if k in FIGURE_BY_KEY and k not in RULE_SKIP and k in headline and k in current}
    wb = {k: worse_factor(FIGURE_BY_KEY[k], headline.get(k), base.get(k)) for k in keys
          if k in FIGURE_BY_KEY and k not in RULE_SKIP and k in headline and k in base}
    gains = [k for k, v in wc.items() if v is not None and v <= 1.0 - RULE_GAIN]
    losses = [k for k, v in wb.items() if v is not None and v > 1.0 + RULE_LOSS]
    g = geo_mean_factor(headline, current, keys)
    if not gains:
        return False, "improves no figure by 20 % against the current best"
    if losses:
        return False, ("worsens " + ", ".join(f"{k} (x{wb[k]:.3g} of the fair PID)" for k in losses)
                       + " by more than 10 %")
    if not g < 1.0:
        return False, f"not better than the current best on balance (geometric-mean factor {g:.3g})"
    return True, "improves " + ", ".join(f"{k} (x{wc[k]:.3g})" for k in gains) + " against the current best"


def combo_key(parts: Sequence[str]) -> tuple[str, ...]:
    """Order-free key of a combination (``te+preisach`` and ``preisach+te`` are one row)."""
    out: list[str] = []
    for c in parts:
        out += [x for x in c.split("+") if x not in out]
    return tuple(sorted(out))


def _ordered(parts: Sequence[str]) -> list[str]:
    """Parts in the order of :data:`SINGLES`, others after them."""
    flat = list(combo_key(parts))
    return [c for c in SINGLES if c in flat] + [c for c in flat if c not in SINGLES]


def _groups_of(parts: Sequence[str]) -> set[str]:
    """The :data:`hdservo.compsetup.GROUPS` a set of compensators belongs to (one group per single part)."""
    from . import compsetup as cs
    return {g for g, members in cs.GROUPS.items() for p in combo_key(parts) if p in members}


def _excluded(parts: Sequence[str]) -> Optional[tuple[str, str]]:
    """The first :data:`hdservo.compsetup.EXCLUSIVE` pair that ``parts`` hold both of (None: none)."""
    from . import compsetup as cs
    k = combo_key(parts)
    return next(((a, b) for a, b in cs.EXCLUSIVE if a in k and b in k), None)


def _missing(headline: Mapping[str, Any], base: Mapping[str, Any], keys: Sequence[str]) -> list[str]:
    """Judged figures the fair PID has and the row lacks (one of its procedures failed)."""
    return [k for k in keys if k in FIGURE_BY_KEY and k not in RULE_SKIP and k in base and k not in headline]


def _seed(single: Mapping[str, Mapping[str, Any]], base: Mapping[str, Any], keys: Sequence[str],
          why: list[str]) -> Optional[str]:
    """Stage 2 of the rule: the starting row of the forward selection (None: no compensator beats the PID)."""
    from . import compsetup as cs
    ok: dict[str, float] = {}
    factor: dict[str, float] = {}
    for c, h in single.items():
        gone = _missing(h, base, keys)
        if gone:                    # a failed procedure: the row's figures are incomplete, it cannot be chosen
            why.append(f"{c} on the fair PID: not a candidate (a procedure failed: no {', '.join(gone)})")
            continue
        q, text = qualifies(h, base, keys)
        factor[c] = geo_mean_factor(h, base, keys)
        why.append(f"{c} on the fair PID: {'qualifies' if q else 'does not qualify'} ({text}; "
                   f"geometric-mean factor {factor[c]:.3g})")
        if q and _excluded([c]) is None:
            ok[c] = factor[c]
    friction = [c for c in ok if c in cs.GROUPS.get("friction", ())]
    if friction:
        top = min(friction, key=lambda c: ok[c])
        why.append(f"seed: {top}, the qualifying friction compensator with the smallest factor ({ok[top]:.3g})")
        return top
    if ok:
        top = min(ok, key=lambda c: ok[c])
        why.append(f"seed: {top}; no friction compensator qualifies, {top} is the qualifying row with the "
                   f"smallest factor ({ok[top]:.3g})")
        return top
    if factor:
        top = min(factor, key=lambda c: factor[c])
        if factor[top] < 1.0:
            why.append(f"seed: {top}; no compensator qualifies: the best on balance (factor {factor[top]:.3g}) "
                       "is taken")
            return top
    why.append("no compensator qualifies and none beats the fair PID on balance: the best combination is the PID")
    return None


def choose_best(single: Mapping[str, Mapping[str, Any]], base: Mapping[str, Any], keys: Sequence[str],
                measure: Optional[Callable[[Sequence[Sequence[str]]], Mapping[tuple[str, ...], Mapping[str, Any]]]]
                = None, max_rows: int = SELECTION_MAX_ROWS) -> tuple[list[str], list[str]]:
    """The best combination by greedy forward selection: the documented rule (docs/compensators.md, :data:`RULE_TEXT`).

    Parameters
    ----------
    single : mapping
        Stage 1: compensator (or measured pair such as ``te+preisach``) -> headline of the fair
        PID + it, in one feedback configuration.
    base : mapping
        Headline of the fair PID (same feedback configuration).
    keys : sequence of str
        The figures judged.
    measure : callable, optional
        Measures combinations on the fair footing: a list of part lists -> ``{combo_key(parts):
        headline}``.  Called once per step with the current best + each candidate not measured
        yet.  None: only the rows of ``single`` are known (a combination not measured there is
        skipped).
    max_rows : int
        Rows ``measure`` is asked for at most over all steps; the candidates with the smallest
        stage-1 factor are measured first.

    Returns
    -------
    (list of str, list of str)
        The chosen compensators (in :data:`SINGLES` order) and the reason lines of every step:
        each stage-1 row against the fair PID, the seed, each candidate against the current best
        and why the selection stops.
    """
    from . import compsetup as cs
    why: list[str] = []
    known: dict[tuple[str, ...], Mapping[str, Any]] = {combo_key([c]): h for c, h in single.items()}
    seed = _seed(single, base, keys, why)
    if seed is None:
        return [], why
    first = {c: geo_mean_factor(h, base, keys) for c, h in single.items() if not _missing(h, base, keys)}
    current = list(combo_key([seed]))
    cur_h = known[combo_key(current)]
    used = _groups_of(current)
    budget = max(0, int(max_rows))
    step = 0
    while True:
        step += 1
        cand: dict[tuple[str, ...], str] = {}
        for g, members in cs.GROUPS.items():
            if g in used:
                continue
            for c in members:
                if c not in first:             # a pair not measured in this configuration, or a failed row
                    continue
                new = [p for p in c.split("+") if p not in current]
                if not new or len(new) < len(c.split("+")) or _groups_of(new) & used:
                    continue                   # overlaps the current best or a group it used
                if _excluded(current + new) is not None:
                    continue
                k = combo_key(current + new)
                if k not in cand or first[c] < first[cand[k]]:
                    cand[k] = c
        if not cand:
            why.append(f"step {step}: stop, no group left to add to {'+'.join(_ordered(current))}")
            break
        order = sorted(cand, key=lambda k: (first[cand[k]], cand[k]))
        todo = [k for k in order if k not in known]
        take = todo[:budget]
        for k in todo[budget:]:
            why.append(f"step {step}: {'+'.join(_ordered(list(k)))} not measured (at most {max_rows} rows)")
        if take and measure is not None:
            got = measure([_ordered(list(k)) for k in take])
            budget -= len(take)
            known.update({combo_key(list(k)): h for k, h in got.items()})
        judged: dict[tuple[str, ...], float] = {}
        for k in order:
            if k not in known:
                continue
            name = "+".join(_ordered(list(k)))
            gone = _missing(known[k], base, keys)
            if gone:
                why.append(f"step {step}: {name}: not a candidate (a procedure failed: no {', '.join(gone)})")
                continue
            q, text = step_qualifies(known[k], cur_h, base, keys)
            g = geo_mean_factor(known[k], cur_h, keys)
            why.append(f"step {step}: {name} against {'+'.join(_ordered(current))}: "
                       f"{'qualifies' if q else 'does not qualify'} ({text}; geometric-mean factor {g:.3g})")
            if q:
                judged[k] = g
        if not judged:
            why.append(f"step {step}: stop, no candidate qualifies against {'+'.join(_ordered(current))}")
            break
        top = min(judged, key=lambda k: (judged[k], len(k), "+".join(k)))     # a tie: the fewer parts
        added = [p for p in top if p not in current]
        current = list(top)
        cur_h = known[top]
        used |= _groups_of(added)
        why.append(f"step {step}: accepted {cand[top]} (factor {judged[top]:.3g} against the previous best): "
                   f"best = {'+'.join(_ordered(current))}")
    return _ordered(current), why


def selection_lines(why: Sequence[str]) -> list[str]:
    """The decisions of the forward selection from :func:`choose_best`'s reasons: the seed, each step's
    accepted candidate and why it stops (the per-candidate judgements stay in the JSON)."""
    return [w for w in why if w.startswith("seed:") or w.startswith("no compensator qualifies and none")
            or (w.startswith("step ") and (": accepted " in w or ": stop" in w))]


# ---------------------------------------------------------------------------------- progress

#: the comparison's progress over rows x procedures (:class:`hdservo.progress.Bar`: tqdm on a terminal)
StageBar = Bar


# ---------------------------------------------------------------------------------- running

def procedure_args(procedure: str, extra: Sequence[str] = ()) -> argparse.Namespace:
    """The options ``hdservo test PROCEDURE EXTRA...`` would have (its parser and defaults).

    Raises
    ------
    ValueError
        An option ``hdservo test`` does not accept (message from its parser).
    """
    from .commands import test as tc
    p = argparse.ArgumentParser(prog="hdservo test", add_help=False, exit_on_error=False)
    tc.register(p)
    err: list[str] = []

    def fail(msg: str) -> None:       # argparse calls error() for some problems even with exit_on_error=False
        err.append(msg)
        raise ValueError(msg)

    p.error = fail  # type: ignore[method-assign]
    try:
        ns = p.parse_args([procedure, *extra])
    except (argparse.ArgumentError, ValueError) as e:
        raise ValueError(f"procedure options {' '.join(extra)!r}: {err[0] if err else e}") from None
    if ns.runs < 2 or ns.windows < 2:
        raise ValueError("procedure options: --runs and --windows must be >= 2")
    return ns


def _write_json_atomic(path: Path, doc: Mapping[str, Any]) -> None:
    """Write ``doc`` as JSON (the directory made first) with :func:`hdservo.fileio.write_json_atomic`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, doc)


def _configure(drive: Any, ctl: Controller, plan: Optional[Mapping[str, Any]],
               preisach_blob: Optional[bytes]) -> list[str]:
    """Write the model's parameters/tables (compensated controllers) and ``cb_enable`` for ``ctl``; returns notes."""
    from .download import write_verified
    from .procedures.runner import apply_compensators
    notes: list[str] = []
    if ctl.compensators:              # the model's parameters matter only with a compensator on
        if plan is not None:
            done = write_verified(drive, plan, tables=True)
            notes.append(f"model download: {done['params']} parameters, tables "
                         f"{', '.join(f'0x5100:{s}' for s in done['tables']) or 'none'} (read back)")
        elif preisach_blob is not None and "preisach" in ctl.compensators:
            drive.download_table(1, preisach_blob)
            notes.append("Preisach table of the axis model downloaded (0x5100:1)")
    note = apply_compensators(drive, list(ctl.compensators))
    if note:
        notes.append(note)
    return notes


def run_procedure(name: str, ctl: Controller, args: argparse.Namespace, *, bus: Optional[dict[str, Any]],
                  node_id: int, axis: str, seed: int, plan: Optional[Mapping[str, Any]],
                  preisach_blob: Optional[bytes], progress_enabled: bool, profile: str = "hdservo") -> Any:
    """One procedure with one controller; returns its :class:`~hdservo.procedures.results.Result`.

    A drive fault or a procedure error is recorded in the result's notes
    (``failed: ...``, no headline) instead of being raised.  The conditions carry the
    controller, its feedback configuration and the loop gains read back from the drive.
    """
    from .commands import test as tc
    from .progress import Fraction
    from .procedures.runner import Target
    setup_f, lockstep, fn = tc.PROCEDURES[name]
    first_error: Optional[str] = None
    for attempt in range(1 + PROCEDURE_RETRIES):
        target = Target(bus=bus, node_id=node_id, axis=axis, seed=seed, compensators=None, profile=profile)
        prog = Fraction(f"{ctl.name}/{name}", enabled=progress_enabled)
        res = _attempt(name, ctl, args, target, setup_f, lockstep, fn, prog, plan, preisach_blob)
        failed = [n for n in res.notes if n.startswith("failed:")]
        if not failed:
            if first_error is not None:
                res.notes.append(f"ran again after a failed attempt ({first_error})")
            return res
        first_error = first_error or failed[0]
    return res


#: A procedure that fails (a drive or transport error, e.g. an SDO answer lost on a loaded host) is run
#: once more on a fresh drive before it is recorded as failed.
PROCEDURE_RETRIES = 1


def _attempt(name: str, ctl: Controller, args: argparse.Namespace, target: Any, setup_f: Any, lockstep: bool,
             fn: Any, prog: Any, plan: Optional[Mapping[str, Any]], preisach_blob: Optional[bytes]) -> Any:
    """One attempt of :func:`run_procedure`."""
    from .errors import UserError
    from .download import DownloadTransportError
    from .drive import DriveError
    from .procedures.results import Result
    from .procedures.runner import open_bench
    loop: dict[str, float] = {}
    try:
        with open_bench(target, setup_f(args), lockstep=lockstep) as bench:
            notes = _configure(bench.drive, ctl, plan, preisach_blob)
            with bench.params(ctl.gains):        # restored afterwards (a real drive keeps its own gains)
                for k, v in ctl.gains.items():
                    back = float(bench.drive.get_param(k))
                    if not math.isclose(back, float(v), rel_tol=1e-3, abs_tol=1e-6):
                        raise RuntimeError(f"gain {k}: read back {back:.6g}, wrote {v:.6g}")
                if ctl.gains:
                    notes.append("gains (read back): " + ", ".join(f"{k} = {v:.6g}" for k, v in ctl.gains.items()))
                for k in LOOP_GAIN_NAMES:
                    try:
                        loop[k] = float(bench.drive.get_param(k))
                    except (DriveError, KeyError, ValueError):
                        pass
                res = fn(bench, args, prog)
    except (DriveError, RuntimeError, ValueError, KeyError) as e:
        res = Result(name, notes=[f"failed: {e}"])
        res.conditions = {"controller": ctl.name, "feedback": ctl.feedback}
        return res
    except DownloadTransportError as e:    # a table transfer broke off on a loaded host: one failed attempt
        res = Result(name, notes=[f"failed: {e}"])
        res.conditions = {"controller": ctl.name, "feedback": ctl.feedback}
        return res
    except UserError:          # the bench cannot be set up at all (no simulator, a rig refused): stop with one line
        raise
    except Exception as e:     # noqa: BLE001 - a transport library's own error (e.g. a timed-out block upload) is one failed run
        res = Result(name, notes=[f"failed: {type(e).__name__}: {e}"])
        res.conditions = {"controller": ctl.name, "feedback": ctl.feedback}
        return res
    res.notes.extend(notes + [n for n in target.notes if n not in notes])
    res.conditions = {**res.conditions, "controller": ctl.name, "feedback": ctl.feedback, "loop_gains": loop}
    res.label = f"{ctl.name} ({ctl.feedback})"
    return res


def _measure_row(ctl: Controller, procedures: Sequence[str], pargs: Mapping[str, argparse.Namespace],
                 kw: Mapping[str, Any], bar: "StageBar", echo: Callable[[str], None]) -> list[Any]:
    """Every procedure with one controller (no plotting: may run in a worker thread); returns the results."""
    results = []
    for name in procedures:
        bar.show(f"{ctl.name} / {name} ...")
        res = run_procedure(name, ctl, pargs[name], **kw)
        results.append(res)
        head = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in res.headline.items())
        fails = [n for n in res.notes if n.startswith("failed:")]
        echo(f"{ctl.name:>10s} {name:<14s} {head or '; '.join(fails) or '(no headline)'}")
        bar.step(f"{ctl.name} / {name} done")
    return results


def _write_row(out_dir: Path, ctl: Controller, results: Sequence[Any], kw: Mapping[str, Any],
               pdf: bool) -> dict[str, Any]:
    """A row's ``test.json`` and plots (main thread: matplotlib); returns its document entry."""
    from .procedures.results import write_json
    cdir = out_dir / ctl.name
    plots: list[str] = []
    pdir = cdir / "plots"
    for res in results:
        if res.plot is not None:
            for p in res.plot(res, pdir, "pdf" if pdf else "png"):
                if p.suffix == ".png":
                    plots.append(str(p.relative_to(out_dir)))
    bus = kw.get("bus")
    meta = {"target": "virtual drive (hdservo-sim serve)" if bus is None else f"drive {bus}",
            "axis": kw.get("axis") if bus is None else None, "seed": kw.get("seed") if bus is None else None,
            "compensators": list(ctl.compensators), "controller": ctl.to_json(), "notes": []}
    write_json(cdir / "test.json", list(results), meta)
    headline: dict[str, Any] = {}
    loop: dict[str, float] = {}
    for r in results:
        headline.update(r.to_json()["headline"])
        if not loop and r.conditions.get("loop_gains"):
            loop = dict(r.conditions["loop_gains"])
    return {**ctl.to_json(), "headline": headline, "json": str((cdir / "test.json").relative_to(out_dir)),
            "plots": plots, "loop_gains": loop,
            "failures": {r.name: [n for n in r.notes if n.startswith("failed:")] for r in results
                         if any(n.startswith("failed:") for n in r.notes)}}


def _run_rows(out_dir: Path, rows: Sequence[Controller], procedures: Sequence[str], proc_extra: Sequence[str],
              kw: Mapping[str, Any], bar: "StageBar", echo: Callable[[str], None], pdf: bool,
              jobs: int) -> dict[str, dict[str, Any]]:
    """Run ``rows`` (``jobs`` at a time, each row's procedures in turn); name -> document entry, in row order."""
    from concurrent.futures import ThreadPoolExecutor
    pargs = {c.name: {p: procedure_args(p, [*proc_extra, *c.proc_args.get(p, [])]) for p in procedures}
             for c in rows}
    if jobs <= 1 or len(rows) <= 1:
        res = {c.name: _measure_row(c, procedures, pargs[c.name], kw, bar, echo) for c in rows}
    else:
        with ThreadPoolExecutor(max_workers=jobs) as ex:     # each procedure runs its own virtual drive process
            futs = {c.name: ex.submit(_measure_row, c, procedures, pargs[c.name], kw, bar, echo) for c in rows}
            res = {n: f.result() for n, f in futs.items()}
    return {c.name: _write_row(out_dir, c, res[c.name], kw, pdf) for c in rows}


def _prepare(procedures: Sequence[str], model: Optional[Path], axis: str, bus: Optional[dict[str, Any]],
             need_preisach: bool) -> tuple[Optional[Mapping[str, Any]], Optional[bytes]]:
    from .commands import test as tc
    bad = [p for p in procedures if p not in tc.PROCEDURES]
    if bad:
        raise ValueError(f"unknown procedure '{bad[0]}'; expected some of {', '.join(sorted(tc.PROCEDURES))}")
    plan = None
    blob = None
    if model is not None:
        from .download import plan_download
        # the twist torque rule takes the velocity loop every row runs (the axis' PID design), the
        # backstepping law's clamp the torque limit every row runs
        dg = design_gains(axis)
        plan = plan_download(model, axis, vel_kp=dg.get("vel_kp"), torque_limit=dg.get("torque_limit"))
    elif bus is None and need_preisach:
        from . import compsetup
        blob = compsetup.preisach_table(axis).to_bytes()
    return plan, blob


def run_compare(out_dir: Path, controllers: Sequence[Controller], procedures: Sequence[str], *,
                proc_extra: Sequence[str] = (), bus: Optional[dict[str, Any]] = None, node_id: int = 1,
                axis: str = "reference", seed: int = 1, model: Optional[Path] = None,
                progress: bool = True, pdf: bool = False,
                echo: Callable[[str], None] = lambda s: None, jobs: int = 1,
                profile: str = "hdservo") -> dict[str, Any]:
    """Run every procedure with every controller; write the outputs (module docstring); return the document.

    Parameters
    ----------
    out_dir : Path
        Output directory (created).
    controllers : sequence of Controller
        What to compare; ``pid`` (else the first) is the reference of the verdicts.
    procedures : sequence of str
        Names of :data:`hdservo.commands.test.PROCEDURES`.
    proc_extra : sequence of str
        Extra ``hdservo test`` options for every procedure (e.g. :data:`QUICK_ARGS`).
    bus : dict, optional
        python-can settings of a real drive; None = virtual drive of ``axis``.
    model : Path, optional
        Identified model (``hdservo identify -o``) whose compensator parameters are downloaded.
    progress : bool
        Progress bar and the procedures' progress lines on stderr.
    echo : callable
        Receives one human summary line per procedure run.
    jobs : int
        Controllers run at the same time (each procedure on its own virtual drive; 1 on a real drive).
    profile : str
        Object profile of the virtual drive (``hdservo`` or ``generic``); unused for a real drive.

    Returns
    -------
    dict
        The ``hdservo-compare`` document written to ``out_dir/compare.json``:
        ``controllers`` (name -> description, compensators, gains, feedback, kind, components,
        headline, loop gains, failures, ``json``, ``plots``), ``figures`` (key -> label, unit,
        target, values per controller, met per controller, verdict vs PID, ratio to the PID
        of the same feedback configuration), ``comparison_plots``, ``best``, ``reference``,
        ``conditions``, ``run_time_s``.

    Raises
    ------
    ValueError
        Bad procedure name or options (before anything runs).
    """
    for c in controllers:
        for p in procedures:
            procedure_args(p, [*proc_extra, *c.proc_args.get(p, [])])
    plan, blob = _prepare(procedures, model, axis, bus, any("preisach" in c.compensators for c in controllers))
    t0 = time.monotonic()
    out_dir.mkdir(parents=True, exist_ok=True)
    bar = StageBar("compare", len(controllers) * len(procedures), enabled=progress)
    bar.show("starting")
    kw = dict(bus=bus, node_id=node_id, axis=axis, seed=seed, plan=plan, preisach_blob=blob,
              progress_enabled=progress, profile=profile)
    try:
        doc_ctl = _run_rows(out_dir, controllers, procedures, proc_extra, kw, bar, echo, pdf,
                            jobs if bus is None else 1)
    finally:
        bar.close()
    return _finish(out_dir, doc_ctl, procedures, proc_extra, bus, axis, seed, model, plan, t0, None)


def run_ablation(out_dir: Path, feedbacks: Sequence[str], procedures: Sequence[str], *,
                 proc_extra: Sequence[str] = (), bus: Optional[dict[str, Any]] = None, node_id: int = 1,
                 axis: str = "reference", seed: int = 1, model: Optional[Path] = None,
                 progress: bool = True, pdf: bool = False, echo: Callable[[str], None] = lambda s: None,
                 jobs: int = 1, extras: bool = True, profile: str = "hdservo") -> dict[str, Any]:
    """The ablation per feedback configuration (docs/demo.md): fair PID, + each compensator, best, leave-one-out.

    Stage 1, per configuration: the fair PID and the fair PID + each compensator of
    :data:`SINGLES`, in semi-closed and dual-loop also the pairs of
    :data:`hdservo.compsetup.MOTOR_SIDE_PAIRS` (and, with ``extras``, the PID design in position
    hold, labelled).  The best
    combination is then chosen by :func:`choose_best`, a greedy forward selection that starts
    from these rows and measures, step by step, the current best plus each remaining candidate
    (rows of kind ``selection``, at most :data:`SELECTION_MAX_ROWS` per configuration).  Stage 2: the best
    combination, the best minus each of its parts (when it has two or more), and the motion
    strategies on top of it (``best+hold``, ``best+hold+approach``), each its own row.  A row whose
    configuration equals one already measured is not run again (``measured_as`` names it).

    Returns
    -------
    dict
        The ``hdservo-compare`` document (:func:`run_compare`) with ``ablation``: per configuration
        the chosen parts, the rule's reasons and the rows; ``OUT/ablation.json`` is written too
        (:func:`ablation_doc`).
    """
    stage1: list[Controller] = []
    ax = axis if bus is None else "reference"       # a real drive keeps its own design gains
    from . import compsetup as cs
    for fb in feedbacks:
        stage1.append(fair_row([], fb, "baseline", axis=ax))
        stage1 += [fair_row([c], fb, "compensator", axis=ax) for c in SINGLES]
        if fb != "full-closed":             # the motor-side output predictors also in pairs (cs.MOTOR_SIDE_PAIRS)
            stage1 += [fair_row(list(p), fb, "compensator", axis=ax) for p in cs.MOTOR_SIDE_PAIRS]
    if extras and "full-closed" in feedbacks:
        stage1.append(pid_hold_row(ax))
    for c in stage1:
        for p in procedures:
            procedure_args(p, [*proc_extra, *c.proc_args.get(p, [])])
    plan, blob = _prepare(procedures, model, axis, bus, True)
    t0 = time.monotonic()
    out_dir.mkdir(parents=True, exist_ok=True)
    n_est = len(stage1) + 4 * len(feedbacks)
    bar = StageBar("compare", n_est * len(procedures), enabled=progress)
    bar.show("starting: fair PID and each compensator")
    kw = dict(bus=bus, node_id=node_id, axis=axis, seed=seed, plan=plan, preisach_blob=blob,
              progress_enabled=progress, profile=profile)
    jb = jobs if bus is None else 1
    doc_ctl = _run_rows(out_dir, stage1, procedures, proc_extra, kw, bar, echo, pdf, jb)
    keys = [f.key for f in FIGURES if f.procedure in procedures]
    info: dict[str, Any] = {}
    stage2: list[Controller] = []
    alias: dict[str, tuple[Controller, str]] = {}
    for fb in feedbacks:
        base = doc_ctl[row_name("pid", fb)]["headline"]
        single = {c: doc_ctl[row_name("+".join([c]), fb)]["headline"] for c in SINGLES}
        single.update({"+".join(p): doc_ctl[row_name("+".join(p), fb)]["headline"] for p in cs.MOTOR_SIDE_PAIRS
                       if row_name("+".join(p), fb) in doc_ctl})
        def measure(combos: Sequence[Sequence[str]], fb: str = fb) -> dict[tuple[str, ...], Mapping[str, Any]]:
            return _measure_combos(combos, fb, ax, doc_ctl, out_dir, procedures, proc_extra, kw, bar, echo, pdf, jb)
        parts, why = choose_best(single, base, keys, measure)
        rows = [fair_row(parts, fb, "best", name="best", axis=ax)]
        if len(parts) >= 2:
            rows += [fair_row([x for x in parts if x != p], fb, "leave-one-out", name=f"best-{p}", axis=ax)
                     for p in parts]
        rows += [fair_row([*parts, "hold"], fb, "strategy", name="best+hold", axis=ax),
                 fair_row([*parts, "hold", "approach"], fb, "strategy", name="best+hold+approach", axis=ax)]
        known = _known_rows(doc_ctl, fb)
        for r in rows:
            same = known.get(tuple(sorted(r.components)))
            if same is not None:
                alias[r.name] = (r, same)
            else:
                stage2.append(r)
        info[fb] = {"best": parts, "rule": why, "best_row": row_name("best", fb)}
    bar.total = max(bar.done + len(stage2) * len(procedures), 1)
    try:
        doc_ctl.update(_run_rows(out_dir, stage2, procedures, proc_extra, kw, bar, echo, pdf, jb))
    finally:
        bar.close()
    for n, (r, same) in alias.items():
        doc_ctl[n] = {**doc_ctl[same], **r.to_json(), "plots": [], "measured_as": same,
                      "description": r.description + f" (the same configuration as row {same}: measured once)"}
    rank = {"baseline": 0, "compensator": 1, "selection": 2, "best": 3, "leave-one-out": 4, "strategy": 5}
    pos = {n: i for i, n in enumerate(doc_ctl)}
    fbi = {fb: i for i, fb in enumerate(feedbacks)}
    order = sorted(doc_ctl, key=lambda n: (doc_ctl[n].get("kind") == "extra",
                                           fbi.get(doc_ctl[n].get("feedback"), 99),
                                           rank.get(doc_ctl[n].get("kind"), 9), pos[n]))
    doc_ctl = {n: doc_ctl[n] for n in order}
    for fb in feedbacks:
        info[fb]["rows"] = [n for n, d in doc_ctl.items() if d.get("feedback") == fb]
        parts = info[fb]["best"]
        best_h = doc_ctl.get(row_name("best", fb), {}).get("headline")
        if len(parts) >= 2 and best_h is not None:
            loo: dict[str, dict[str, Any]] = {}
            for p in parts:
                minus = doc_ctl.get(row_name(f"best-{p}", fb), {}).get("headline")
                if minus is None:
                    continue
                ok, text = part_pays(best_h, minus, keys)
                loo[p] = {"pays": ok, "text": text}
                info[fb]["rule"].append(f"leave-one-out, {p}: {text}")
            info[fb]["leave_one_out"] = loo
    doc = _finish(out_dir, doc_ctl, procedures, proc_extra, bus, axis, seed, model, plan, t0,
                  {"baseline": "pid", "feedbacks": info, "rule": RULE_TEXT})
    _write_json_atomic(out_dir / "ablation.json", ablation_doc(doc))
    return doc


def _known_rows(doc_ctl: Mapping[str, Mapping[str, Any]], fb: str) -> dict[tuple[str, ...], str]:
    """Rows measured on the fair footing in ``fb``, by their compensators (:func:`combo_key`) -> row name."""
    return {combo_key(d.get("components", [])): n for n, d in doc_ctl.items()
            if d.get("feedback") == fb and d.get("kind") in ("baseline", "compensator", "selection")
            and "measured_as" not in d}


def _measure_combos(combos: Sequence[Sequence[str]], fb: str, ax: str, doc_ctl: dict[str, Any], out_dir: Path,
                    procedures: Sequence[str], proc_extra: Sequence[str], kw: Mapping[str, Any], bar: "StageBar",
                    echo: Callable[[str], None], pdf: bool, jobs: int) -> dict[tuple[str, ...], Mapping[str, Any]]:
    """The forward selection's rows of one step: each combination on the fair footing, measured once.

    A combination already in ``doc_ctl`` (same feedback configuration and compensators) is not
    run again.  New rows (kind ``selection``) are added to ``doc_ctl``.

    Returns
    -------
    dict
        :func:`combo_key` of each combination -> its headline.
    """
    known = _known_rows(doc_ctl, fb)
    rows = [fair_row(list(c), fb, "selection", axis=ax) for c in combos if combo_key(c) not in known]
    if rows:
        bar.total = bar.total + len(rows) * len(procedures)
        echo(f"forward selection, {fb}: measuring " + ", ".join(r.name for r in rows))
        doc_ctl.update(_run_rows(out_dir, rows, procedures, proc_extra, kw, bar, echo, pdf, jobs))
    known = _known_rows(doc_ctl, fb)
    return {combo_key(c): doc_ctl[known[combo_key(c)]]["headline"] for c in combos if combo_key(c) in known}


def _finish(out_dir: Path, doc_ctl: dict[str, Any], procedures: Sequence[str], proc_extra: Sequence[str],
            bus: Optional[dict[str, Any]], axis: str, seed: int, model: Optional[Path],
            plan: Optional[Mapping[str, Any]], t0: float, ablation: Optional[dict[str, Any]]) -> dict[str, Any]:
    """Figures, verdicts, ratios and charts of the rows; writes ``compare.json``; returns the document."""
    ref_name = "pid" if "pid" in doc_ctl else next(iter(doc_ctl))
    best_name = "best" if "best" in doc_ctl else list(doc_ctl)[-1]
    figs: dict[str, Any] = {}
    for f in FIGURES:
        if f.procedure not in procedures:
            continue
        vals = {c: d["headline"].get(f.key) for c, d in doc_ctl.items()}
        base = {c: vals.get(row_name("pid", d.get("feedback", "full-closed")), vals.get(ref_name))
                for c, d in doc_ctl.items()}
        figs[f.key] = {"label": f.label, "short": f.short or f.label, "unit": f.unit,
                       "lower_is_better": f.lower_is_better, "target": f.target,
                       "target_text": f.target_text(), "values": vals,
                       "meets_target": {c: f.meets(v) for c, v in vals.items()},
                       "vs_" + ref_name: {c: f.verdict(v, vals[ref_name]) for c, v in vals.items() if c != ref_name},
                       "ratio_to_pid": {c: ratio(f, v, base[c]) for c, v in vals.items()},
                       "best_measured": best_measured(f, vals)}
    doc: dict[str, Any] = {
        "format": FORMAT, "version": VERSION, "reference": ref_name, "best": best_name,
        "conditions": {"target": "virtual drive (hdservo-sim serve --rig)" if bus is None else f"drive {bus}",
                       "axis": axis if bus is None else None, "seed": seed if bus is None else None,
                       "procedures": list(procedures), "procedure_options": list(proc_extra),
                       "model": str(model) if model is not None else None,
                       "parameters": ("identified model, downloaded and read back before each compensated "
                                      "procedure" if model is not None else "the drive's compensator defaults"),
                       "fair_baseline": ("every row runs with the loop gains of the compensated set and the "
                                         "stabilisation in the gyro mode; ratios are to the fair PID of the same "
                                         "feedback configuration"),
                       "model_notes": list(plan["notes"]) if plan else []},
        "controllers": doc_ctl, "figures": figs}
    if ablation is not None:
        doc["ablation"] = ablation
    doc["comparison_plots"] = [str(p.relative_to(out_dir)) for p in comparison_plots(doc, out_dir / "plots")]
    doc["verdict"] = verdict(doc)
    doc["run_time_s"] = round(time.monotonic() - t0, 1)
    _write_json_atomic(out_dir / "compare.json", doc)
    return doc


def ablation_doc(doc: Mapping[str, Any]) -> dict[str, Any]:
    """``{"baseline": "pid", "rows": [{"name", "feedback", "kind", "components", "figures", "ratio_to_baseline"}]}``.

    Also ``best`` (the chosen parts per feedback configuration), ``feedbacks`` (per configuration:
    ``best``, ``rule`` -- the text of the rule, :data:`RULE_TEXT` --, ``steps`` -- the reason of
    every step of the forward selection and of each leave-one-out judgement -- and
    ``leave_one_out``) and ``leave_one_out`` (per
    configuration with a combination of two or more parts: per part ``{"pays", "text"}``,
    :func:`part_pays`).

    ``figures``: every figure of the row (None = no value); ``ratio_to_baseline``: value / the
    fair PID's value in the same feedback configuration (None when either is missing).
    """
    rows = []
    for n, d in doc["controllers"].items():
        fb = d.get("feedback", "full-closed")
        figs = {k: f["values"].get(n) for k, f in doc["figures"].items()}
        rows.append({"name": n, "feedback": fb, "kind": d.get("kind", "custom"),
                     "components": list(d.get("components", d.get("compensators", []))),
                     "baseline_row": row_name("pid", fb), "figures": figs,
                     "ratio_to_baseline": {k: f.get("ratio_to_pid", {}).get(n) for k, f in doc["figures"].items()}})
    ab = doc.get("ablation", {})
    return {"baseline": "pid", "rule": ab.get("rule"),
            "best": {fb: v.get("best") for fb, v in ab.get("feedbacks", {}).items()},
            "feedbacks": {fb: {"best": v.get("best"), "rule": ab.get("rule"), "steps": list(v.get("rule", [])),
                               "leave_one_out": v.get("leave_one_out", {})}
                          for fb, v in ab.get("feedbacks", {}).items()},
            "leave_one_out": {fb: v["leave_one_out"] for fb, v in ab.get("feedbacks", {}).items()
                              if "leave_one_out" in v}, "rows": rows}


def ablation_table(doc: Mapping[str, Any]) -> str:
    """Per feedback configuration: one line per row, each figure's value and its ratio to the fair PID."""
    keys = list(doc["figures"])
    lines: list[str] = []
    fbs: list[str] = []
    for d in doc["controllers"].values():
        if d.get("feedback", "full-closed") not in fbs:
            fbs.append(d.get("feedback", "full-closed"))
    w = 18
    for fb in fbs:
        names = [n for n, d in doc["controllers"].items() if d.get("feedback", "full-closed") == fb]
        lines.append(f"ablation, {fb}: value (ratio to the fair PID {row_name('pid', fb)})")
        head = f"{'row':<28s}" + "".join(f"{(doc['figures'][k].get('short') or k)[:w - 1]:>{w}s}" for k in keys)
        units = f"{'':<28s}" + "".join(f"{'(' + doc['figures'][k]['unit'] + ')':>{w}s}" for k in keys)
        lines += [head, units, "-" * len(head)]
        for n in names:
            row = f"{n[:27]:<28s}"
            for k in keys:
                v = doc["figures"][k]["values"].get(n)
                r = doc["figures"][k].get("ratio_to_pid", {}).get(n)
                cell = _num(v) + ("" if r is None or n == row_name("pid", fb) else f" ({r:.2g}x)")
                row += f"{cell:>{w}s}"
            lines.append(row)
        lines.append("")
    return "\n".join(lines)


def best_measured(f: Figure, values: Mapping[str, Optional[float]]) -> Optional[str]:
    """The controller with the best value of figure ``f`` (None when no controller has a value)."""
    have = {c: v for c, v in values.items() if v is not None}
    if not have:
        return None
    top = have[(min if f.lower_is_better else max)(have, key=lambda c: have[c])]
    return next(c for c, v in have.items() if f.verdict(v, top, tol=1e-6) in ("same", "better"))   # ties: first listed


def verdict(doc: Mapping[str, Any]) -> dict[str, Any]:
    """Targets met by the best combination and its verdict against the reference, per figure.

    Returns
    -------
    dict
        ``targets_met`` (figure -> bool, figures with a target), ``all_targets_met``,
        ``better_than_reference`` (figure -> better/same/worse/n/a), ``better_everywhere``
        (every figure strictly better), ``not_worse_anywhere``.
    """
    ref, best = doc["reference"], doc["best"]
    tm: dict[str, bool] = {}
    vs: dict[str, str] = {}
    for k, f in doc["figures"].items():
        if f["target"] is not None:
            tm[k] = bool(f["meets_target"].get(best))
        if best != ref:
            vs[k] = f["vs_" + ref].get(best, "n/a")
    return {"controller": best, "reference": ref, "targets_met": tm, "all_targets_met": all(tm.values()) if tm else None,
            "better_than_reference": vs, "better_everywhere": bool(vs) and all(v == "better" for v in vs.values()),
            "not_worse_anywhere": bool(vs) and all(v in ("better", "same") for v in vs.values())}


def comparison_plots(doc: Mapping[str, Any], out_dir: Path) -> list[Path]:
    """One bar chart per headline figure over the controllers (target as a dashed line); returns the PNGs."""
    from .procedures.results import figure, save_figure
    paths: list[Path] = []
    names = list(doc["controllers"])
    for key, f in doc["figures"].items():
        vals = [f["values"].get(n) for n in names]
        fig, ax = figure(size=(8.0, 4.2))
        a = ax[0][0]
        have = [v for v in vals if v is not None and v > 0] + ([f["target"]] if f["target"] else [])
        logy = bool(have) and max(have) / min(have) > 30.0
        bottom = (min(have) / 3.0 if logy else 0.0) if have else 0.0
        for i, (n, v) in enumerate(zip(names, vals)):
            met = f["meets_target"].get(n)
            color = "C2" if met else ("C3" if met is False else "C0")
            if v is None:
                a.text(i, 0.5, "none", ha="center", va="bottom", transform=a.get_xaxis_transform(), rotation=90,
                       fontsize=8)
                continue
            a.bar(i, v - bottom if logy else v, bottom=bottom if logy else 0.0, color=color)
            a.text(i, v, f"{v:.3g}", ha="center", va="bottom", fontsize=8)
        if f["target"] is not None:
            a.axhline(f["target"], color="k", ls="--", lw=1.0, label=f"target {f['target_text']}")
            a.legend(loc="best", fontsize=8)
        if logy:
            a.set_yscale("log")
        a.set_xticks(range(len(names)))
        a.set_xticklabels(names, rotation=20)
        a.set_xlabel("controller (-)")
        a.set_ylabel(f"{f.get('short', f['label'])} ({f['unit']})")
        a.set_title(f"{f['label']}, every row (feedback configuration after '@', full-closed otherwise)\n"
                    + ("green = target met, red = not met" if f["target"] is not None else
                       "no absolute target: compare with the fair PID row 'pid'"), fontsize=9)
        a.grid(True, axis="y", which="both", alpha=0.4)
        fig.tight_layout()
        paths += [p for p in save_figure(fig, out_dir, f"compare_{key}") if p.suffix == ".png"]
    paths += ablation_plots(doc, out_dir)
    return paths


def ablation_plots(doc: Mapping[str, Any], out_dir: Path) -> list[Path]:
    """One chart per feedback configuration: each row's ratio to the fair PID per figure (log colour scale)."""
    from .procedures.results import figure, save_figure
    keys = [k for k in doc["figures"]]
    fbs: list[str] = []
    for d in doc["controllers"].values():
        if d.get("feedback", "full-closed") not in fbs:
            fbs.append(d.get("feedback", "full-closed"))
    paths: list[Path] = []
    for fb in fbs:
        names = [n for n, d in doc["controllers"].items() if d.get("feedback", "full-closed") == fb]
        if len(names) < 2 or not keys:
            continue
        m = np.full((len(names), len(keys)), np.nan)
        for i, n in enumerate(names):
            for j, k in enumerate(keys):
                f = FIGURE_BY_KEY.get(k)
                r = doc["figures"][k].get("ratio_to_pid", {}).get(n)
                if r is not None and r > 0 and f is not None:
                    m[i, j] = math.log10(r if f.lower_is_better else 1.0 / r)   # < 0: better than the PID
        fig, ax = figure(size=(1.1 * len(keys) + 3.5, 0.42 * len(names) + 2.6))
        a = ax[0][0]
        im = a.imshow(np.clip(m, -1.5, 1.5), cmap="RdYlGn_r", vmin=-1.5, vmax=1.5, aspect="auto")
        for i, n in enumerate(names):
            for j, k in enumerate(keys):
                r = doc["figures"][k].get("ratio_to_pid", {}).get(n)
                v = doc["figures"][k]["values"].get(n)
                a.text(j, i, "none" if v is None else (f"{r:.2g}x" if r is not None else _num(v)), ha="center",
                       va="center", fontsize=7)      # a value against a PID without one: the value itself
        a.set_xticks(range(len(keys)))
        a.set_xticklabels([f"{doc['figures'][k].get('short') or k} ({doc['figures'][k]['unit']})" for k in keys],
                          rotation=35, ha="right", fontsize=7)
        a.set_yticks(range(len(names)))
        a.set_yticklabels(names, fontsize=8)
        a.set_xlabel("figure (unit)")
        a.set_ylabel("row (controller)")
        a.set_title(f"ablation, {fb}: value / fair PID value per figure (green = better, red = worse)", fontsize=9)
        cb = fig.colorbar(im, ax=a)
        cb.set_label("log10 of the worse-factor (-)")
        fig.tight_layout()
        paths += [p for p in save_figure(fig, out_dir, f"ablation_{fb}") if p.suffix == ".png"]
    return paths


def summary_table(doc: Mapping[str, Any], columns: Optional[Sequence[str]] = None) -> str:
    """A fixed-width text table: figure, unit, target, one column per controller, best vs reference."""
    cols = list(columns) if columns is not None else list(doc["controllers"])
    ref, best = doc["reference"], doc["best"]
    w = max(11, *(len(c) + 2 for c in cols))
    head = f"{'figure':<30s}{'unit':>8s}{'target':>11s}" + "".join(f"{c:>{w}s}" for c in cols)
    show_vs = best != ref and best in cols
    if show_vs:
        head += f"  {best + ' vs ' + ref:<14s}"
    head += "  best measured"
    lines = [head, "-" * len(head)]
    for k, f in doc["figures"].items():
        tt = f["target_text"].split(" ")
        tgt = " ".join(tt[:2]) if f["target"] is not None else "-"
        row = f"{k:<30s}{f['unit']:>8s}{tgt:>11s}"
        for c in cols:
            v = f["values"].get(c)
            met = f["meets_target"].get(c)
            mark = "" if met is None else (" *" if met else "  ")
            row += f"{(_num(v) + mark):>{w}s}"
        if show_vs:
            row += f"  {f['vs_' + ref].get(best, 'n/a'):<14s}"
        bm = f.get("best_measured")
        row += f"  {bm} ({_num(f['values'].get(bm))})" if bm else "  -"
        lines.append(row)
    lines.append("(* = meets the target; 'none' = no value, e.g. no smooth rung)")
    return "\n".join(lines)


def _num(v: Any) -> str:
    if v is None:
        return "none"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


#: Summary keys of the semi-closed ISO 230-2 figures -> the figure they take from the semi-closed rows.
SEMI_CLOSED_SUMMARY: dict[str, str] = {"semi_closed_positioning_accuracy_arcsec": "positioning_accuracy_arcsec",
                                       "semi_closed_repeatability_arcsec": "repeatability_arcsec"}


def row_conditions(doc: Mapping[str, Any], name: Optional[str]) -> Optional[dict[str, Any]]:
    """Feedback configuration, drive mode per procedure, loop gains and components of a row (None: no row)."""
    d = doc["controllers"].get(name) if name else None
    if d is None:
        return None
    pa = d.get("proc_args", {})
    stab = "hold"
    if "stabilisation" in pa and "--stab-mode" in pa["stabilisation"]:
        stab = pa["stabilisation"][pa["stabilisation"].index("--stab-mode") + 1]
    return {"row": name, "feedback": d.get("feedback", "full-closed"),
            "mode": {"stabilisation": "gyro stabilisation mode (STAB, CiA 402 mode -1)" if stab == "stab"
                     else "position hold (CSP)", "other procedures": "position control (profile / cyclic position)"},
            "loop_gains": dict(d.get("loop_gains", {})), "gains_set": dict(d.get("gains", {})),
            "components": list(d.get("components", d.get("compensators", [])))}


def summary_doc(doc: Mapping[str, Any], compensated: Optional[str] = None) -> dict[str, Any]:
    """The demo summary: ``{figure: {"pid": value, "compensated": value}, ..., "conditions": {...}}``.

    ``pid`` is the fair PID (full-closed), ``compensated`` the best combination without motion
    strategies (full-closed); the semi-closed ISO 230-2 figures (:data:`SEMI_CLOSED_SUMMARY`) come
    from the semi-closed rows.  Every figure of :data:`FIGURES` is present (None when not run);
    ``conditions`` holds each one's feedback configuration, modes and loop gains.
    """
    ref = doc["reference"]
    comp = compensated or doc["best"]
    out: dict[str, Any] = {}
    for f in FIGURES:
        d = doc["figures"].get(f.key, {}).get("values", {})
        out[f.key] = {"pid": d.get(ref), "compensated": d.get(comp)}
    for key, src in SEMI_CLOSED_SUMMARY.items():
        d = doc["figures"].get(src, {}).get("values", {})
        out[key] = {"pid": d.get(row_name("pid", "semi-closed")), "compensated": d.get(row_name("best", "semi-closed"))}
    out["conditions"] = {"pid": row_conditions(doc, ref), "compensated": row_conditions(doc, comp)}
    return out


def parse_proc_args(text: Optional[str]) -> list[str]:
    """Split a ``--proc-args`` string into options (shell quoting)."""
    if not text:
        return []
    try:
        return shlex.split(text)
    except ValueError as e:
        raise ValueError(f"--proc-args: {e}") from None


__all__ = ["BEST_NAMES_DEFAULT", "FEEDBACKS", "RULE_GAIN", "RULE_LOSS", "SEMI_CLOSED_SUMMARY", "ablation_doc",
           "ablation_table", "choose_best", "fair_row", "feedback_names", "part_pays", "pid_hold_row", "qualifies", "ratio",
           "row_conditions", "row_name", "run_ablation", "worse_factor", "Controller", "DEFAULT_PROCEDURES", "FIGURES", "FIGURE_BY_KEY", "Figure", "FORMAT",
           "QUICK_ARGS", "SINGLES", "StageBar", "best_controller", "comparison_plots", "controllers_from_names",
           "default_controller_names", "parse_proc_args", "procedure_args", "run_compare", "summary_doc",
           "summary_table", "verdict"]
