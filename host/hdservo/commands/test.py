"""``hdservo test PROCEDURE``: the standard test procedures against a drive (docs/procedures.md).

The procedures run on the drive python-can's settings name (``-i/-c/-b``, else
its config file and ``CAN_*`` variables; without any of them the command
refuses), and the rig steps are printed for the operator.  ``--sim [AXIS]`` (or
``-i virtual-drive``) runs them on a simulated axis instead (the reference axis,
or AXIS; a virtual drive per procedure, said on stderr, stopped afterwards).
Every run prints a summary, ``--json PATH`` writes the figures, ``--out-dir DIR``
the PNG plots (``--pdf`` adds PDFs).

``--model MODEL.toml`` downloads the compensator parameters and tables of an
identified model (the code of ``hdservo download``: ``plan_download`` +
``write_verified``, every item read back) into the drive before each
procedure (the virtual drive is a new process per procedure and keeps no
parameters), ``--set NAME=VALUE`` writes drive parameters by name after it,
``--compensators`` sets ``cb_enable`` last, so that
``serve -> identify -> download -> test`` is a plain CLI chain.
``--stab-mode`` chooses how the stabilisation test drives the axis: ``hold``
(CSP hold, the PID baseline; default), ``stab`` (the drive's gyro
stabilisation mode, CiA 402 mode -1) or ``auto`` (``stab`` when 0x6502
advertises mode -1).
"""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import Any, Callable

from ..errors import UserError
from ..drive import DriveError, add_bus_arguments, choose_drive
from ..procedures import closedloop as cl
from ..procedures import frequency as fq
from ..procedures import gear
from ..procedures import standard as std
from ..procedures import tracking as tr
from ..procedures.results import Result, write_json
from ..procedures.runner import Progress, RigSetup, Target, open_bench

NAME = "test"
HELP = "run the standard test procedures (gear catalogue tests, FRF, closed-loop figures) on a drive"

#: name -> (set-up factory, lock-step, runner(bench, args, progress))
Proc = tuple[Callable[[argparse.Namespace], RigSetup], bool, Callable[..., Result]]

PROCEDURES: dict[str, Proc] = {
    "stiffness": (lambda a: gear.GEAR_SETUP, False,
                  lambda b, a, p: gear.stiffness(b, cycles=a.cycles or 2, progress=p)),
    "hysteresis": (lambda a: gear.GEAR_SETUP, False,
                   lambda b, a, p: gear.hysteresis(b, cycles=a.cycles or 3, progress=p)),
    "lost-motion": (lambda a: gear.GEAR_SETUP, False,
                    lambda b, a, p: gear.lost_motion(b, cycles=a.cycles or 3, progress=p)),
    "starting-torque": (lambda a: gear.GEAR_SETUP, False, lambda b, a, p: gear.starting_torque(b, progress=p)),
    "transmission": (lambda a: gear.GEAR_SETUP, False,
                     lambda b, a, p: gear.transmission(b, rate_deg_s=a.te_rate, progress=p)),
    "resonance": (lambda a: cl.AXIS_SETUP, True,
                  lambda b, a, p: fq.resonance(b, rms_Nm=a.excitation_Nm, progress=p)),
    "frf": (lambda a: cl.AXIS_SETUP, True, lambda b, a, p: fq.frf(b, rms_Nm=a.excitation_Nm, progress=p)),
    "min-rate": (lambda a: cl.AXIS_SETUP, False,
                 lambda b, a, p: cl.min_rate(b, rates_deg_s=a.rates, bound=a.bound, windows=a.windows,
                                             settle_s=a.settle, progress=p,
                                             stop_at_failure=not a.full_ladder)),
    "stabilisation": (lambda a: cl.stab_setup(a.base_amplitude_deg, a.base_frequency_hz), False,
                      lambda b, a, p: cl.stabilisation(b, duration_s=a.duration, progress=p,
                                                       mode=getattr(a, "stab_mode", "hold"))),
    "positioning": (lambda a: cl.AXIS_SETUP, False,
                    lambda b, a, p: cl.positioning(b, targets_deg=a.targets, runs=a.runs, progress=p,
                                                   exercise=a.exercise)),
    # lock-step on the virtual drive: the saturated step lasts its drive time whatever the host's latency
    # (with fast pacing a slow capture upload let the drive run on past torque_sat_time: a TORQUE_SAT fault)
    "peak-torque": (lambda a: cl.AXIS_SETUP, True,
                    lambda b, a, p: cl.peak_torque(b, request_Nm=a.peak_request, progress=p)),
    "bandwidth": (lambda a: cl.AXIS_SETUP, True,
                  lambda b, a, p: cl.bandwidth(b, amplitude_arcsec=a.amplitude_arcsec, progress=p)),
    "tracking": (lambda a: cl.AXIS_SETUP, True,
                 lambda b, a, p: tr.tracking(b, rates_deg_s=a.track_rates, period_s=a.track_period, progress=p)),
    "settling": (lambda a: cl.AXIS_SETUP, False,
                 lambda b, a, p: tr.settling(b, step_deg=a.step_deg, moves=a.moves, progress=p)),
}


#: procedures on the CiA 402 standard objects alone (``--standard-objects``, procedures/standard.py)
STD_PROCEDURES: dict[str, Callable[..., Result]] = {
    "min-rate": lambda r, a, p: std.min_rate(r, rates_deg_s=a.rates, bound=a.bound, windows=a.windows,
                                             settle_s=a.settle, progress=p),
    "positioning": lambda r, a, p: std.positioning(r, targets_deg=a.targets, runs=a.runs, progress=p,
                                                   exercise=a.exercise),
    "bandwidth": lambda r, a, p: std.bandwidth(r, amplitude_arcsec=a.amplitude_arcsec),
    "peak-torque": lambda r, a, p: std.peak_torque(r, request_Nm=a.peak_request or 0.0,
                                                   output_locked=a.output_locked),
}


def _floats(text: str) -> list[float]:
    try:
        v = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got '{text}'") from None
    if not v or not all(math.isfinite(x) for x in v):
        raise argparse.ArgumentTypeError(f"expected comma-separated finite numbers, got '{text}'")
    return v


def _param(text: str) -> tuple[str, float]:
    """``NAME=VALUE`` of ``--set`` (a drive parameter name and a finite number)."""
    key, sep, val = text.partition("=")
    try:
        v = float(val)
    except ValueError:
        v = float("nan")
    if not sep or not key.strip() or not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE with a finite number, got '{text}'")
    return key.strip(), v


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got '{text}'") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected a positive number, got '{text}'")
    return v


def register(p: argparse.ArgumentParser) -> None:
    """Options of ``hdservo test``."""
    p.add_argument("procedure", choices=sorted(PROCEDURES) + ["all"], help="procedure to run ('all' = every one)")
    add_bus_arguments(p)
    p.add_argument("--seed", type=int, default=None, help="with --sim only: sensor-noise seed (default 1)")
    p.add_argument("--compensators", default=None,
                   help="comma-separated compensators to enable (cb_enable), e.g. stribeck,lugre; '' = none")
    p.add_argument("--model", type=Path, metavar="MODEL.toml",
                   help="identified model (hdservo identify -o): download its compensator parameters and tables "
                        "into the drive before each procedure, read back (keys it lacks from the --sim axis, else the "
                        "reference axis)")
    p.add_argument("--set", dest="params", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="drive parameter by name, written (and read back) before each procedure after --model; "
                        "repeatable, e.g. --set vel_kp=200 --set torque_limit=90")
    p.add_argument("--params", dest="params", type=_param, action="append", help=argparse.SUPPRESS)  # older spelling
    p.add_argument("--json", type=Path, metavar="PATH", help="write the results as JSON")
    p.add_argument("--out-dir", type=Path, metavar="DIR", help="write PNG plots into this directory")
    p.add_argument("--plots", dest="out_dir", type=Path, help=argparse.SUPPRESS)   # older spelling
    p.add_argument("--pdf", action="store_true", help="also write PDF plots")
    g = p.add_argument_group("procedure options")
    g.add_argument("--cycles", type=int, default=None, help="torque-loop cycles (stiffness 2, hysteresis 3, lost motion 3)")
    g.add_argument("--te-rate", type=_positive, default=10.0, help="transmission test rate, deg/s (default 10)")
    g.add_argument("--excitation-Nm", type=_positive, default=6.0, help="FRF torque excitation RMS, N.m (default 6)")
    g.add_argument("--rates", type=_floats, default=list(cl.RATE_LADDER_DEG_S),
                   help="min-rate ladder, deg/s (default " + ",".join(f"{r:g}" for r in cl.RATE_LADDER_DEG_S)
                        + f"; windows of rate x 1 s, at least {cl.MIN_WINDOW_ARCSEC:g} arcsec)")
    g.add_argument("--bound", type=_positive, default=0.1, help="min-rate bound on the rate stability sigma/mean (0.1)")
    g.add_argument("--windows", type=int, default=10, help="min-rate fixed-angle windows per rung (10, 1 s each)")
    g.add_argument("--settle", type=_positive, default=5.0, help="min-rate settling time per rung, s (5)")
    g.add_argument("--full-ladder", action="store_true",
                   help="min-rate: run every rung (default: stop after the first rung that is not smooth)")
    g.add_argument("--base-amplitude-deg", type=_positive, default=0.5, help="stabilisation base rocking, deg (0.5)")
    g.add_argument("--base-frequency-hz", type=_positive, default=1.0, help="stabilisation base rocking, Hz (1)")
    g.add_argument("--duration", type=_positive, default=5.0, help="stabilisation record, s (5)")
    g.add_argument("--stab-mode", choices=list(cl.STAB_MODES), default="hold",
                   help="stabilisation: 'hold' = CSP hold (PID baseline, default), 'stab' = the drive's gyro "
                        "stabilisation mode (CiA 402 mode -1), 'auto' = stab when 0x6502 advertises mode -1")
    g.add_argument("--targets", type=_floats, default=None, help="positioning targets, deg (12 over -55..55)")
    g.add_argument("--runs", type=int, default=5, help="positioning bidirectional runs (5)")
    g.add_argument("--exercise", type=int, default=cl.EXERCISE_RUNS,
                   help=f"positioning: unmeasured exercise runs before the first run "
                        f"({cl.EXERCISE_RUNS}; 0 = none)")
    g.add_argument("--peak-request", type=_positive, default=None, help="peak-torque request, N.m (torque_limit)")
    g.add_argument("--track-rates", type=_floats, default=list(tr.TRACK_RATES_DEG_S),
                   help="tracking: peak rates of the sinusoids, deg/s (default "
                        + ",".join(f"{r:g}" for r in tr.TRACK_RATES_DEG_S) + ")")
    g.add_argument("--track-period", type=_positive, default=tr.TRACK_PERIOD_S,
                   help=f"tracking: period of the sinusoids, s (default {tr.TRACK_PERIOD_S:g})")
    g.add_argument("--step-deg", type=_positive, default=tr.SETTLE_STEP_DEG,
                   help=f"settling: move size, deg (default {tr.SETTLE_STEP_DEG:g})")
    g.add_argument("--moves", type=int, default=4, help="settling: moves, alternating + and - (default 4)")
    g.add_argument("--amplitude-arcsec", type=_positive, default=1800.0,
                   help="bandwidth multisine peak, arcsec (1800 = 0.5 deg)")
    s = p.add_argument_group("any CiA 402 drive (docs/generic-drive.md)")
    s.add_argument("--standard-objects", action="store_true",
                   help="run min-rate, positioning, bandwidth or peak-torque through CiA 402 standard objects only "
                        "(host-streamed CSP/CST set-points, 0x6064/0x6077 by synchronous TPDO); with --sim the "
                        "virtual drive runs its generic profile")
    s.add_argument("--gear-ratio", type=_positive, default=None, metavar="N",
                   help="with --standard-objects: gear ratio when the drive has no 0x6091")
    s.add_argument("--sync-period", type=_positive, default=None, metavar="S",
                   help="with --standard-objects: SYNC period, s (default 0.001)")
    s.add_argument("--output-locked", action="store_true",
                   help="with --standard-objects peak-torque: the operator has locked the output")


def _check_params(pairs: list[tuple[str, float]]) -> dict[str, float]:
    """``--set`` pairs -> {name: value}; unknown names and out-of-range values are errors."""
    from ..params_gen import BY_NAME as PARAMS
    out: dict[str, float] = {}
    for k, v in pairs:
        p = PARAMS.get(k)
        if p is None:
            raise UserError(f"--set {k}: not a drive parameter (docs/parameters.md)")
        if not p.min <= v <= p.max:
            raise UserError(f"--set {k}={v:g}: outside [{p.min:g}, {p.max:g}] {p.unit}")
        out[k] = v
    return out


def _check_out(path: Path | None, what: str) -> None:
    if path is None:
        return
    parent = path.parent if what == "json" else path
    probe = parent if parent.exists() else parent.parent
    if path.exists() and what == "json" and path.is_dir():
        raise UserError(f"--json {path}: is a directory")
    if probe.exists() and not os.access(probe, os.W_OK):
        raise UserError(f"--{what} {path}: not writable")



def _model_plan(model: Path | None, axis: str) -> dict | None:
    """The download plan of ``--model`` (keys it lacks from ``axis``), or None without one."""
    if model is None:
        return None
    from ..download import plan_download
    plan = dict(plan_download(model, axis))
    plan["model_file"] = model.name
    return plan

def run(args: argparse.Namespace) -> int:
    """Run one procedure (or all), print the summary, write JSON/plots."""
    if args.runs < 2:
        raise UserError("--runs must be >= 2 (ISO 230-2 needs a standard deviation)")
    if args.exercise < 0:
        raise UserError(f"--exercise {args.exercise}: expected a whole number of runs >= 0")
    if args.windows < 2:
        raise UserError("--windows must be >= 2")
    if min(args.rates) <= 0:
        raise UserError(f"--rates {','.join(f'{r:g}' for r in args.rates)}: every rate must be > 0 deg/s")
    if min(args.track_rates) <= 0:
        raise UserError(f"--track-rates {','.join(f'{r:g}' for r in args.track_rates)}: every rate must be > 0 deg/s")
    if args.moves < 1:
        raise UserError("--moves must be >= 1")
    if args.cycles is not None and args.cycles < 1:
        raise UserError("--cycles must be >= 1")
    _check_out(args.json, "json")
    _check_out(args.out_dir, "out-dir")
    if args.standard_objects:
        return _run_standard(args)
    std_opts = [o for o, v in (("--gear-ratio", args.gear_ratio), ("--sync-period", args.sync_period),
                               ("--output-locked", args.output_locked or None)) if v is not None]
    if std_opts:
        raise UserError(f"{', '.join(std_opts)}: options of --standard-objects")
    comps = None if args.compensators is None else [c.strip() for c in args.compensators.split(",") if c.strip()]
    params = _check_params(getattr(args, "params", []) or [])
    # the user's files are checked before a drive is chosen: a bad file is the first error
    model = getattr(args, "model", None)
    if model is not None and not model.is_file():
        raise UserError(f"--model {model}: no such file")
    plan = _model_plan(model, getattr(args, "sim", None) or "reference")
    choice = choose_drive(args, sim_only=("seed",))
    axis = choice.axis or "reference"
    if model is not None and axis != (getattr(args, "sim", None) or "reference"):
        plan = _model_plan(model, axis)
    seed = 1 if args.seed is None else args.seed
    target = Target(bus=choice.bus, node_id=args.node_id, axis=axis, seed=seed, compensators=comps,
                    download=plan, params=params, profile=choice.profile)
    choice.announce("test")
    from ..drive_caps import preflight
    preflight(choice, args.node_id, "test")
    names = sorted(PROCEDURES) if args.procedure == "all" else [args.procedure]
    results: list[Result] = []
    for name in names:
        setup_f, lockstep, fn = PROCEDURES[name]
        prog = Progress(name, enabled=not args.quiet)
        try:
            with open_bench(target, setup_f(args), lockstep=lockstep) as bench:
                res = fn(bench, args, prog)
        except (DriveError, RuntimeError, ValueError) as e:
            raise UserError(f"{name}: {e}") from None
        res.notes.extend(target.notes)
        results.append(res)
        print(res.summary())
    meta: dict[str, Any] = {"target": "virtual drive (hdservo-sim serve)" if target.virtual else choice.describe(),
                            "axis": choice.axis_name if target.virtual else None, "seed": seed if target.virtual else None,
                            "compensators": comps, "model": str(model) if model is not None else None,
                            "params": params or None, "notes": target.notes}
    if args.out_dir is not None:
        for res in results:
            if res.plot is not None:
                res.plot(res, args.out_dir, "pdf" if args.pdf else "png")
    if args.json is not None:
        write_json(args.json, results, meta)
    return 0


def _run_standard(args: argparse.Namespace) -> int:
    """``--standard-objects``: the procedures of :mod:`hdservo.procedures.standard` on any CiA 402 drive."""
    from ..ident.std_runner import StdSession
    names = sorted(STD_PROCEDURES) if args.procedure == "all" else [args.procedure]
    other = [n for n in names if n not in STD_PROCEDURES]
    if other:
        raise UserError(f"test {args.procedure}: not on the standard-objects path (needs hdservo's capture or a "
                        f"test rig); --standard-objects runs {', '.join(sorted(STD_PROCEDURES))}")
    vendor = [o for o, v in (("--model", args.model), ("--compensators", args.compensators),
                             ("--set", args.params or None)) if v is not None]
    if vendor:
        raise UserError(f"{', '.join(vendor)}: hdservo drive parameters, not on the standard-objects path")
    if "peak-torque" in names and (args.peak_request is None or not args.output_locked):
        raise UserError("peak-torque --standard-objects: needs --peak-request N.m and --output-locked (the operator "
                        "locks the output; the standard objects have no brake)")
    choice = choose_drive(args, sim_only=("seed",))
    if choice.virtual and args.gear_ratio is None:
        raise UserError("--standard-objects: the generic virtual drive has no 0x6091: give --gear-ratio")
    extra: dict[str, Any] = {"gear_ratio": args.gear_ratio}
    if choice.virtual:
        periods = 10 if args.sync_period is None else args.sync_period / 1e-4
        if abs(periods - round(periods)) > 1e-9:
            raise UserError(f"--sync-period {args.sync_period}: the virtual drive needs a multiple of 0.0001 s")
        kw: dict[str, Any] = {"axis": choice.axis or "reference", "seed": 1 if args.seed is None else args.seed,
                              "sync_periods": int(round(periods)), "sets": cl.AXIS_SETUP.sets(),
                              # the simulated bench locks the output, as the operator does on a real axis
                              "output_locked": bool(args.output_locked)}
    else:
        kw = {"bus": choice.bus}
        if args.sync_period is not None:
            extra["sync_period_s"] = args.sync_period
        if (choice.bus or {}).get("bitrate"):
            extra["bitrate"] = float(choice.bus["bitrate"])
    choice.announce("test")
    results: list[Result] = []
    for name in names:
        prog = Progress(name, enabled=not args.quiet)
        with StdSession(node_id=args.node_id, **kw, **extra) as r:
            res = STD_PROCEDURES[name](r, args, prog)
        results.append(res)
        print(res.summary())
    meta: dict[str, Any] = {"target": ("virtual drive (hdservo-sim serve --profile generic)" if choice.virtual
                                       else choice.describe()) + ", standard objects",
                            "axis": choice.axis_name if choice.virtual else None}
    if args.json is not None:
        write_json(args.json, results, meta)
    return 0
