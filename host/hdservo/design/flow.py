"""The design flow: requirements -> feasible parts -> simulated figures -> ranked designs.

Steps (``docs/design-flow.md``):

1. :func:`enumerate_candidates`: every gear (catalogue series/size/ratio) x motor;
   the sensors of each pair are the cheapest ones (fewest bits, noisiest gyro)
   that pass the sensor rules; :func:`feasibility` applies the hard checks
   (peak torque, continuous torque, speed, resonance, encoder resolution,
   encoder accuracy, gyro noise, gyro range) with the spec's margin and the
   soft ones (lost motion, transmission accuracy vs accuracy) as warnings;
2. :func:`shortlist`: feasible candidates ordered by cost index (gear + motor
   mass, CSG x 1.2, plus a sensor grade), one per gear size, the best
   ``options.candidates`` of them;
3. per candidate: :func:`hdservo.design.axis_builder.build_axis` (axis TOML),
   then for each controller option (:func:`controller_options`: the flow's own
   compensators and the demo's best combination of :mod:`hdservo.compsetup`)
   :func:`tune` (cascade gains from :mod:`hdservo.gains`, compensators and
   their parameters from :mod:`hdservo.compsetup`), :func:`evaluate` (simulated
   figures, :mod:`hdservo.design.predict`) and the margin against each
   requirement; the candidate keeps its best option (:func:`option_key`);
4. :func:`rank`: by the smallest simulated margin (all requirements met first),
   then by cost.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import catalogue as cat
from . import structure as st
from .axis_builder import Candidate, gear_friction, write_axis
from .spec import Spec

from ..units import DEG  # noqa: E402
#: relative cost of the gyro grades (cheapest first)
GYRO_ORDER = ("gyro-mems-consumer", "gyro-mems-industrial", "gyro-fog-tactical", "gyro-fog-navigation")
#: share of the positioning accuracy the output encoder's installed accuracy may take (p-p = 2 x +-acc)
ENCODER_ACCURACY_SHARE = 0.7
#: share of the stabilisation budget the gyro noise may take
GYRO_NOISE_SHARE = 0.3
#: stabilisation window used in the gyro-noise rule and the simulation, s
STAB_WINDOW_S = 5.0
#: output-encoder counts required per second at the minimum smooth rate
MIN_COUNTS_PER_S_OUTPUT = 10.0
#: motor-encoder counts (output referred) required per second at the minimum smooth rate
MIN_COUNTS_PER_S_MOTOR = 10.0
#: lost motion above this multiple of the positioning accuracy is flagged (soft)
LOST_MOTION_FACTOR = 10.0
#: how the positioning figures are simulated (:func:`hdservo.design.predict.positioning`): the test
#: procedure's continuous sweep on the served simulator; the per-target in-process runs ("scenario")
#: start every move from a fresh plant and gave twice the sub-arcsecond A / R of the final approach
POSITIONING_METHOD = "procedure"
#: compensators of the flow's own controller option ("flow"; the other option is the demo's best
#: combination, :func:`controller_options`)
COMPENSATORS: Tuple[str, ...] = ("lugre",)


@dataclass
class ControllerOption:
    """One controller configuration the flow evaluates on every candidate.

    Attributes
    ----------
    name : str
        ``flow`` (:data:`COMPENSATORS` on the flow's gains) or ``best`` (the demo's best combination).
    compensators : tuple of str
        ``cb_enable`` names (:data:`hdservo.compsetup.ENABLE_BITS`; ``approach`` = the drive's
        one-direction final approach of PTP moves).
    extra_gains : dict
        Drive parameters (table units) set on top of the flow's tuning (e.g. ``pos_kp``).
    proc_args : dict
        Extra ``hdservo test`` options per procedure (e.g. ``{"stabilisation": ["--stab-mode", "stab"]}``).
    source : str
        Where the option comes from (one line).
    """

    name: str
    compensators: Tuple[str, ...]
    extra_gains: Dict[str, float] = field(default_factory=dict)
    proc_args: Dict[str, List[str]] = field(default_factory=dict)
    source: str = ""

    def to_json(self) -> Dict[str, Any]:
        return {"name": self.name, "compensators": list(self.compensators), "extra_gains": dict(self.extra_gains),
                "proc_args": {k: list(v) for k, v in self.proc_args.items()}, "source": self.source}


def controller_options(axis: str = "reference") -> List[ControllerOption]:
    """The controller options of the flow: its own (:data:`COMPENSATORS`) and the demo's best combination.

    The best combination is read when called, through :func:`hdservo.compare.best_controller`
    (``hdservo.compsetup.BEST_NAMES``, ``best_gains(axis)``, ``BEST_PROC_ARGS``: the same
    definition ``hdservo compare`` and ``make demo`` use), so a change there reaches the flow.
    """
    from .. import compare
    best = compare.best_controller(axis)
    return [ControllerOption("flow", tuple(COMPENSATORS), {}, {}, "hdservo.design.flow.COMPENSATORS"),
            ControllerOption("best", tuple(best.compensators), {k: float(v) for k, v in best.gains.items()},
                             {k: list(v) for k, v in best.proc_args.items()}, best.description)]


def stab_mode(option: Optional[ControllerOption]) -> str:
    """Drive mode of the stabilisation procedure for an option: ``stab`` unless its proc_args say otherwise."""
    if option is None or "stabilisation" not in option.proc_args:
        return "stab"
    from .. import compare
    return str(getattr(compare.procedure_args("stabilisation", option.proc_args["stabilisation"]), "stab_mode",
                       "stab"))


@dataclass
class Check:
    """One feasibility check.

    Attributes
    ----------
    name : str
    value, limit : float
        Achieved value and the requirement it is compared with (units in ``unit``).
    unit : str
    margin : float
        Relative margin: (value - limit)/limit when larger is better, (limit - value)/limit otherwise.
    hard : bool
        A failed hard check rejects the candidate; soft ones only warn.
    ok : bool
    """

    name: str
    value: float
    limit: float
    unit: str
    margin: float
    hard: bool = True
    ok: bool = True


def _check(name: str, value: float, limit: float, unit: str, larger_better: bool, need: float,
           hard: bool = True) -> Check:
    m = (value - limit) / limit if larger_better else (limit - value) / limit
    return Check(name, float(value), float(limit), unit, float(m), hard, bool(m >= need))


# ------------------------------------------------------------------ loads

def required_torques(spec: Spec, c: Candidate) -> Dict[str, float]:
    """Output torques the candidate must deliver, N·m.

    ``accel`` = (J_L + N² J_in) a_max; ``friction`` = the gear's output backdriving
    torque (breakaway at the output); ``base`` = J_L x base angular acceleration;
    ``peak_dynamic`` = accel + unbalance + friction + base; ``peak`` = max(spec
    peak, peak_dynamic); ``continuous`` = unbalance + Coulomb friction + base +
    duty_rms_fraction x accel.
    """
    n = c.gear.ratio
    j = spec.load_inertia_kgm2 + n * n * c.input_inertia_kgm2
    acc = j * spec.max_accel_deg_s2 * DEG
    fr = gear_friction(c.gear)
    wb = 2 * math.pi * spec.base_frequency_Hz
    base = spec.load_inertia_kgm2 * spec.base_amplitude_deg * DEG * wb * wb
    dyn = acc + spec.unbalance_Nm + fr.backdriving_output_Nm + base
    cont = spec.unbalance_Nm + fr.coulomb_output_Nm + base + spec.options.duty_rms_fraction * acc
    return {"j_total_kgm2": j, "accel": acc, "friction": fr.backdriving_output_Nm, "base": base,
            "peak_dynamic": dyn, "peak": max(spec.peak_torque_Nm, dyn), "continuous": cont}


def resonance(spec: Spec, c: Candidate) -> Tuple[float, float]:
    """(locked-motor anti-resonance sqrt(K1/J_L), coupled two-mass resonance), Hz."""
    return st.two_mass_resonance(c.gear.k1_Nm_per_rad, spec.load_inertia_kgm2, c.input_inertia_kgm2, c.gear.ratio)


@lru_cache(maxsize=64)
def _fe_figures(gear: cat.GearRow, load_inertia_kgm2: float, level: int) -> Dict[str, Any]:
    from . import fe_gear
    return fe_gear.candidate_figures(gear, load_inertia_kgm2, level=level)


def fe_resonance(spec: Spec, c: Candidate, level: Optional[int] = None) -> Dict[str, Any]:
    """FE figures of the candidate's flexspline with the spec's load (:func:`hdservo.design.fe_gear.candidate_figures`):
    flexspline stiffness, the first torsional mode (FE flexspline, the catalogue K1's remainder as the tooth-mesh
    and WG-bearing spring, motor locked) and the first tilting mode of the load on the flexspline alone.

    Evaluated once per gear and load (cached); ``level`` is the FE mesh level (default
    :data:`hdservo.design.flexspline_fe.DEFAULT_LEVEL`).
    """
    from .flexspline_fe import DEFAULT_LEVEL
    lv = DEFAULT_LEVEL if level is None else int(level)
    return dict(_fe_figures(c.gear, float(spec.load_inertia_kgm2), lv))


def torque_limit(c: Candidate) -> float:
    """Drive torque limit of the design: min(N Kt I_peak, gear repeated peak), N·m (output)."""
    return float(min(c.gear.ratio * c.motor.kt_Nm_per_A * c.motor.peak_current_A, c.gear.repeated_peak_torque_Nm))


def feasibility(spec: Spec, c: Candidate) -> List[Check]:
    """Every feasibility check of a candidate (see the module docstring and docs/design-flow.md)."""
    o = spec.options
    need = o.margin
    g, m = c.gear, c.motor
    n = g.ratio
    tq = required_torques(spec, c)
    checks = [
        _check("peak torque (motor peak x N x eta)", m.peak_torque_Nm * n * o.efficiency, tq["peak"], "N·m",
               True, need),
        _check("peak torque (gear repeated peak)", g.repeated_peak_torque_Nm, tq["peak"], "N·m", True, need),
        _check("continuous torque (motor x N x eta)", m.continuous_torque_Nm * n * o.efficiency, tq["continuous"],
               "N·m", True, need),
        _check("continuous torque (gear rated)", g.rated_torque_Nm, tq["continuous"], "N·m", True, need),
    ]
    rpm = spec.max_rate_deg_s / 360.0 * 60.0 * n
    checks.append(_check("max speed (motor)", m.max_speed_rpm, rpm, "rpm", True, need))
    checks.append(_check("max speed (gear input)", g.max_input_speed_rpm, rpm, "rpm", True, need))
    fa, fr = resonance(spec, c)
    checks.append(_check("first resonance (locked motor, K1)", fa, spec.min_resonance_Hz, "Hz", True, need))
    checks += sensor_checks(spec, c)
    lm = g.lost_motion_max_arcmin * 60.0
    checks.append(_check("lost motion vs accuracy (output-encoder loop)", lm,
                         LOST_MOTION_FACTOR * spec.positioning_arcsec, "arcsec", False, 0.0, hard=False))
    ta = g.transmission_accuracy_max_arcmin * 60.0
    checks.append(_check("transmission accuracy vs accuracy (semi-closed fallback)", ta,
                         LOST_MOTION_FACTOR * spec.positioning_arcsec, "arcsec", False, 0.0, hard=False))
    return checks


def sensor_checks(spec: Spec, c: Candidate) -> List[Check]:
    """Encoder and gyro checks of a candidate."""
    need = spec.options.margin
    out: List[Check] = []
    enc = c.output_encoder
    lsb_out = 1296000.0 / 2 ** int(enc.bits_per_rev or 0)
    rate = spec.min_smooth_rate_deg_s * 3600.0           # arcsec/s
    out.append(_check("output encoder counts/s at min rate", rate / lsb_out, MIN_COUNTS_PER_S_OUTPUT, "1/s", True,
                      need))
    lsb_mot = 1296000.0 / 2 ** int(c.motor_encoder.bits_per_rev or 0) / c.gear.ratio
    out.append(_check("motor encoder counts/s at min rate (output-referred)", rate / lsb_mot,
                      MIN_COUNTS_PER_S_MOTOR, "1/s", True, need))
    out.append(_check("output encoder accuracy (2 x +-acc) vs positioning", 2.0 * float(enc.accuracy_arcsec or 0),
                      ENCODER_ACCURACY_SHARE * spec.positioning_arcsec, "arcsec", False, 0.0))
    out.append(_check("output encoder LSB + noise vs repeatability",
                      lsb_out + 4.0 * float(enc.noise_arcsec_rms or 0), spec.repeatability_arcsec, "arcsec", False,
                      need))
    from .predict import gyro_noise_arcsec_rms
    gy = c.gyro
    noise = gyro_noise_arcsec_rms(float(gy.noise_density_deg_s_rtHz or 0) * DEG, STAB_WINDOW_S, 10.0)
    out.append(_check("gyro noise (integrated) vs stabilisation", noise,
                      GYRO_NOISE_SHARE * spec.stabilisation_arcsec_rms, "arcsec RMS", False, 0.0))
    out.append(_check("gyro range vs max rate", float(gy.range_deg_s or 0), spec.max_rate_deg_s, "deg/s", True, need))
    return out


# ------------------------------------------------------------------ enumeration

@dataclass
class Evaluated:
    """A candidate with its checks (and later its simulated figures)."""

    candidate: Candidate
    checks: List[Check]
    cost: float
    sim: Dict[str, Any] = field(default_factory=dict)
    margins: Dict[str, float] = field(default_factory=dict)
    controller: Dict[str, Any] = field(default_factory=dict)
    tuning: Dict[str, Any] = field(default_factory=dict)
    axis_path: Optional[str] = None
    #: the controller option kept (:func:`evaluate`) and every option's margins and headline figures
    option: Optional[str] = None
    options: Dict[str, Any] = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        """Every hard check passes."""
        return all(ch.ok for ch in self.checks if ch.hard)

    @property
    def min_margin(self) -> float:
        """Smallest margin of the hard checks."""
        return min(ch.margin for ch in self.checks if ch.hard)


def cost_index(c: Candidate) -> float:
    """Relative cost: gear mass x (1.2 for CSG) + motor mass + sensor grade, kg-equivalent."""
    g = c.gear.mass_kg * (1.2 if c.gear.series == "CSG" else 1.0)
    sens = (0.05 * ((c.motor_encoder.bits_per_rev or 17) - 17) + 0.1 * ((c.output_encoder.bits_per_rev or 24) - 24)
            + (0.2 * GYRO_ORDER.index(c.gyro.name) if c.gyro.name in GYRO_ORDER else 0.0))
    return g + c.motor.mass_kg + sens


def enumerate_candidates(spec: Spec, gears: Optional[Sequence[cat.GearRow]] = None,
                         motors: Optional[Sequence[cat.MotorRow]] = None,
                         sensors: Optional[Sequence[cat.SensorRow]] = None) -> List[Evaluated]:
    """Every gear x motor pair with its cheapest passing sensor set, checked.

    Parameters
    ----------
    spec : Spec
    gears, motors, sensors : sequence, optional
        Catalogue rows; default the packaged catalogues.

    Returns
    -------
    list of Evaluated
        All pairs (feasible or not), sorted feasible first, then by cost.
    """
    gears = [g for g in (gears or cat.load_gears()) if g.series in spec.options.series]
    motors = list(motors or cat.load_motors())
    sensors = list(sensors or cat.load_sensors())
    menc = sorted([s for s in sensors if s.kind == "motor_encoder"], key=lambda s: s.bits_per_rev or 0)
    oenc = sorted([s for s in sensors if s.kind == "output_encoder"], key=lambda s: s.bits_per_rev or 0)
    gyros = sorted([s for s in sensors if s.kind == "rate_gyro"],
                   key=lambda s: GYRO_ORDER.index(s.name) if s.name in GYRO_ORDER else -(s.noise_density_deg_s_rtHz
                                                                                          or 0))
    out: List[Evaluated] = []
    for g in gears:
        for m in motors:
            best: Optional[Evaluated] = None
            for me in menc:
                for oe in oenc:
                    for gy in gyros:
                        c = Candidate(g, m, me, oe, gy)
                        sc = sensor_checks(spec, c)
                        if all(ch.ok for ch in sc if ch.hard):
                            best = Evaluated(c, feasibility(spec, c), cost_index(c))
                            break
                    if best:
                        break
                if best:
                    break
            if best is None:     # no sensor set passes: keep the best-grade set to show why
                c = Candidate(g, m, menc[-1], oenc[-1], gyros[-1])
                best = Evaluated(c, feasibility(spec, c), cost_index(c))
            out.append(best)
    out.sort(key=lambda e: (not e.feasible, e.cost, -e.min_margin))
    return out


def shortlist(evals: Sequence[Evaluated], k: int) -> List[Evaluated]:
    """The ``k`` cheapest feasible candidates, at most one per gear size and ratio (the CSF
    and CSG of one size and ratio share stiffness and accuracy: only the cheaper is kept)."""
    seen = set()
    out: List[Evaluated] = []
    for e in evals:
        if not e.feasible:
            continue
        key = (e.candidate.gear.size, e.candidate.gear.ratio)
        if key in seen:
            continue
        seen.add(key)
        out.append(e)
        if len(out) >= k:
            break
    return out


# ------------------------------------------------------------------ controller

def tune(spec: Spec, c: Candidate, axis_path: str,
         option: Optional[ControllerOption] = None) -> Tuple[Dict[str, Any], Dict[str, Any]]:
    """Cascade gains and compensators of a candidate axis.

    Velocity PI at f_v = min(25 Hz, f_r / 2) and position P at 0.38 f_v
    (no position integrator: with the gear's lost motion and stick-slip it
    hunts in a +-35..50 arcsec limit cycle in the simulator) from :func:`hdservo.gains.design` (which also
    gives the margins); notch at the coupled resonance
    (:func:`hdservo.closedloop_cases.axis_controller`); torque limit
    :func:`torque_limit`; trajectory limits = spec max rate / accel;
    compensators of ``option`` (default the flow's own, :data:`COMPENSATORS`) with parameters from
    :func:`hdservo.compsetup.compensator_params` of the axis, then the option's ``extra_gains``.

    Returns
    -------
    controller : dict
        Scenario ``[controller]`` table.
    tuning : dict
        Targets and achieved crossovers/margins (:class:`hdservo.gains.Design`), the option,
        and ``overridden`` (flow gain -> the option's value).
    """
    from dataclasses import asdict

    from .. import closedloop_cases as baseline, compsetup, gains
    opt = option or ControllerOption("flow", tuple(COMPENSATORS))
    fa, fr = resonance(spec, c)
    f_v = min(25.0, 0.5 * fr)
    f_p = 0.38 * f_v
    ax = gains.Axis(c.name, c.gear.ratio, c.input_inertia_kgm2, spec.load_inertia_kgm2, c.gear.k1_Nm_per_rad,
                    c.motor.kt_Nm_per_A)
    d = gains.design(ax, f_v_hz=f_v, f_p_hz=f_p)
    base = baseline.axis_controller(axis_path)
    g = dict(base["gains"])
    kpp = d.pos_kp_per_s
    g.update({"vel_kp": d.vel_kp_Nms_per_rad, "vel_ki": d.vel_ki_Nm_per_rad, "pos_kp": kpp, "pos_ki": 0.0,
              "torque_limit": torque_limit(c), "traj_vmax": spec.max_rate_deg_s / 360.0,
              "traj_amax": spec.max_accel_deg_s2 / 360.0})
    base["gains"] = g
    overridden = {k: {"flow": g[k], "option": float(v)} for k, v in opt.extra_gains.items() if k in g}
    # a Preisach compensator needs its table file: beside the candidate's axis file
    ctl = compsetup.controller(axis_path, list(opt.compensators), base=base, extra_gains=opt.extra_gains,
                               table_dir=Path(axis_path).parent)
    tuning = asdict(d)
    tuning.update({"f_v_target_Hz": f_v, "f_p_target_Hz": f_p, "pos_ki_per_s2": 0.0,
                   "torque_limit_Nm": torque_limit(c), "compensators": list(opt.compensators),
                   "option": opt.to_json(), "overridden": overridden,
                   "pos_kp_applied_per_s": float(ctl["gains"]["pos_kp"])})
    return ctl, tuning


# ------------------------------------------------------------------ evaluation

def evaluate_option(spec: Spec, c: Candidate, axis_path: str, option: Optional[ControllerOption] = None, *,
                    quick: bool = False, progress: Optional[Callable[[str], None]] = None) -> Dict[str, Any]:
    """Simulated figures and margins of one candidate with one controller option.

    Returns
    -------
    dict
        ``option`` (name), ``controller``, ``tuning``, ``figures``, ``margins``.
    """
    from . import predict as pr
    ctl, tuning = tune(spec, c, axis_path, option)
    rates = sorted({spec.min_smooth_rate_deg_s, 10 * spec.min_smooth_rate_deg_s}
                   | (set() if quick else {100 * spec.min_smooth_rate_deg_s, 1000 * spec.min_smooth_rate_deg_s}))
    f: Dict[str, Any] = {}
    f["min_rate"] = pr.min_smooth_rate(axis_path, ctl, rates, windows=4 if quick else 10,
                                       settle_s=1.0 if quick else 5.0, progress=progress)
    half = spec.travel_deg / 2
    targets = [-half, half] if quick else list(np.linspace(-half, half, 12))
    f["positioning"] = pr.positioning(axis_path, ctl, targets, runs=2 if quick else 3,
                                      vmax_deg_s=spec.max_rate_deg_s, amax_deg_s2=spec.max_accel_deg_s2,
                                      method=POSITIONING_METHOD, progress=progress)
    f["stabilisation"] = pr.stabilisation(axis_path, ctl, spec.base_amplitude_deg, spec.base_frequency_Hz,
                                          duration_s=2.0 if quick else STAB_WINDOW_S,
                                          loop_bw_Hz=tuning["pos_bandwidth_hz"], progress=progress,
                                          design_mode=stab_mode(option))
    if progress:
        progress("peak torque, bandwidth")
    f["peak_torque"] = pr.peak_torque(axis_path, ctl, torque_limit(c))
    f["bandwidth"] = pr.bandwidth(axis_path, ctl, periods=1 if quick else 2)
    fa, fr = resonance(spec, c)
    fem = fe_resonance(spec, c)
    f["resonance"] = {"locked_motor_Hz": fa, "coupled_Hz": fr, "source": "two-mass model, catalogue K1",
                      "fe_torsional_Hz": fem["torsional_Hz"], "fe_tilting_Hz": fem["tilting_Hz"], "fe": fem,
                      "design_Hz": min(fa, fem["torsional_Hz"]),
                      "design_source": "lower of the two-mass and the FE torsional mode (motor locked)"}
    enc_acc = 2.0 * float(c.output_encoder.accuracy_arcsec or 0.0)
    f["positioning"]["A_with_encoder_arcsec"] = f["positioning"]["A_arcsec"] + enc_acc
    return {"option": (option.name if option else "flow"), "controller": ctl, "tuning": tuning, "figures": f,
            "margins": margins(spec, f)}


def option_key(m: Dict[str, float]) -> Tuple[bool, float, float]:
    """Order of margin sets: every requirement met first, then the larger smallest margin (capped at
    50 %, 1 % steps), then the larger sum of the negative margins (less shortfall)."""
    mm = min(m.values()) if m else -math.inf
    short = sum(min(v, 0.0) for v in m.values())
    return (mm < 0.0, -round(min(mm, 0.5), 2), -short)


def evaluate(spec: Spec, e: Evaluated, axis_path: str, *, quick: bool = False,
             progress: Optional[Callable[[str], None]] = None,
             options: Optional[Sequence[ControllerOption]] = None) -> Dict[str, Any]:
    """Simulated figures of one candidate (fills ``e.sim``, ``e.margins``, ``e.controller``, ``e.options``).

    Every controller option (default :func:`controller_options`) is simulated; the candidate
    keeps the option with the best margins (:func:`option_key`).

    Parameters
    ----------
    spec : Spec
    e : Evaluated
    axis_path : str
        Where the candidate's axis TOML is (written before).
    quick : bool
        Short runs (tests): 2 ladder rungs, 2 targets, 2 runs, 2 s stabilisation.
    options : sequence of ControllerOption, optional
        Controller options to compare (default :func:`controller_options`).

    Returns
    -------
    dict
        The figures of the kept option (also stored in ``e.sim``).
    """
    opts = list(options) if options is not None else controller_options(axis_path)
    results = []
    for o in opts:
        sub = (lambda s, o=o: progress(f"[{o.name}] {s}")) if progress else None
        results.append(evaluate_option(spec, e.candidate, axis_path, o, quick=quick, progress=sub))
    best = min(results, key=lambda r: option_key(r["margins"]))
    e.controller, e.tuning, e.sim, e.margins = best["controller"], best["tuning"], best["figures"], best["margins"]
    e.option = best["option"]
    e.options = {r["option"]: {"margins": r["margins"], "predicted": headline(r["figures"]),
                               "option": r["tuning"]["option"], "controller": r["controller"],
                               "tuning": r["tuning"], "figures": r["figures"]} for r in results}
    return e.sim


def headline(f: Dict[str, Any]) -> Dict[str, Optional[float]]:
    """The predicted figures compared with the requirements (units in the keys)."""
    stab = f["stabilisation"]
    rate_rows = {r["rate_deg_s"]: r for r in f["min_rate"]["ladder"]}
    slow = rate_rows[min(rate_rows)]
    return {
        "min_smooth_rate_deg_s": f["min_rate"]["min_smooth_rate_deg_s"],
        "rate_stability_at_min_rate": slow["stability"],
        "positioning_accuracy_arcsec": f["positioning"]["A_arcsec"],
        "positioning_accuracy_with_encoder_arcsec": f["positioning"]["A_with_encoder_arcsec"],
        "repeatability_arcsec": f["positioning"]["R_arcsec"],
        "stabilisation_rms_arcsec": stab["predicted_rms_arcsec"],
        "stabilisation_hold_rms_arcsec": stab["hold_rms_arcsec"],
        "peak_torque_Nm": f["peak_torque"]["peak_torque_Nm"],
        "bandwidth_Hz": f["bandwidth"]["bandwidth_Hz"],
        "resonance_Hz": f["resonance"].get("design_Hz", f["resonance"]["locked_motor_Hz"]),
    }


def margins(spec: Spec, f: Dict[str, Any]) -> Dict[str, float]:
    """Relative margin of each simulated figure against its requirement (>= 0 = met).

    Minimum smooth rate: 1 - max(stability, accuracy)/bound at the required
    rate (-1 when the rung is not monotone); positioning uses A including the
    encoder's installed accuracy; stabilisation the predicted (inertial +
    gyro noise) RMS.
    """
    h = headline(f)
    mr = f["min_rate"]
    rung = min(mr["ladder"], key=lambda r: abs(r["rate_deg_s"] - spec.min_smooth_rate_deg_s))
    m_rate = (1.0 - max(rung["stability"], rung["accuracy"]) / mr["bound"]) if rung["monotone"] else -1.0
    out = {
        "min_smooth_rate": float(m_rate),
        "positioning_accuracy": (spec.positioning_arcsec - h["positioning_accuracy_with_encoder_arcsec"])
        / spec.positioning_arcsec,
        "repeatability": (spec.repeatability_arcsec - h["repeatability_arcsec"]) / spec.repeatability_arcsec,
        "stabilisation": (spec.stabilisation_arcsec_rms - h["stabilisation_rms_arcsec"]) / spec.stabilisation_arcsec_rms,
        "peak_torque": (h["peak_torque_Nm"] - spec.peak_torque_Nm) / spec.peak_torque_Nm,
        "resonance": (h["resonance_Hz"] - spec.min_resonance_Hz) / spec.min_resonance_Hz,
    }
    return {k: float(v) for k, v in out.items()}


#: smallest margin above which candidates count as equally safe in :func:`rank` (cost decides then)
RANK_MARGIN_CAP = 0.5


def rank(evals: Sequence[Evaluated]) -> List[Evaluated]:
    """Order simulated candidates (docs/design-flow.md section 3, "Ranking").

    1. every requirement met first;
    2. the larger smallest margin, capped at :data:`RANK_MARGIN_CAP` (50 %) and rounded to 1 %:
       beyond the cap more margin buys nothing;
    3. the lower cost index (rounded to 0.01);
    4. the larger smallest margin without the cap (1 %): between equally cheap candidates
       above the cap, the safer one;
    5. the shortlist order (cost index, then catalogue order), so that a remaining tie does not
       hang on sub-percent differences of simulated figures (sorting is stable).
    """
    def key(e: Evaluated) -> Tuple[bool, float, float, float]:
        mm = min(e.margins.values()) if e.margins else -math.inf
        capped = round(min(mm, RANK_MARGIN_CAP), 2) if math.isfinite(mm) else -math.inf
        return (mm < 0.0, -capped, round(e.cost, 2), -round(mm, 2) if math.isfinite(mm) else math.inf)
    return sorted(evals, key=key)


# ------------------------------------------------------------------ the whole flow

@dataclass
class FlowResult:
    """Outcome of :func:`run_flow`."""

    spec: Spec
    all_candidates: List[Evaluated]
    simulated: List[Evaluated]
    chosen: Optional[Evaluated]


def run_flow(spec: Spec, workdir: "str | Path", *, quick: bool = False, candidates: Optional[int] = None,
             progress: Optional[Callable[[str], None]] = None) -> FlowResult:
    """Run the design flow; axis TOMLs of the simulated candidates go to ``workdir``.

    Parameters
    ----------
    spec : Spec
    workdir : path-like
        Existing directory for the candidates' axis files (``axis_<slug>.toml``).
    quick : bool
        Short simulations (tests).
    candidates : int, optional
        Override of ``spec.options.candidates``.
    progress : callable, optional
        Called with a short text before each step.

    Returns
    -------
    FlowResult
    """
    evals = enumerate_candidates(spec)
    k = candidates if candidates is not None else spec.options.candidates
    short = shortlist(evals, k)
    for i, e in enumerate(short):
        if progress:
            progress(f"candidate {i + 1}/{len(short)}: {e.candidate.name}")
        path = Path(workdir) / f"axis_{e.candidate.slug}.toml"
        write_axis(e.candidate, spec, path)
        e.axis_path = str(path)
        evaluate(spec, e, str(path), quick=quick,
                 progress=(lambda s, i=i: progress(f"  [{i + 1}] {s}")) if progress else None)
    ranked = rank(short)
    return FlowResult(spec, evals, ranked, ranked[0] if ranked else None)


__all__ = ["COMPENSATORS", "Check", "ControllerOption", "Evaluated", "FlowResult", "controller_options", "cost_index",
           "enumerate_candidates", "evaluate", "evaluate_option", "feasibility", "headline", "margins", "option_key",
           "rank", "required_torques", "resonance", "fe_resonance", "run_flow", "sensor_checks", "shortlist", "stab_mode",
           "torque_limit", "tune"]
