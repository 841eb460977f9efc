"""Closed-loop comparison: the test procedures with the PID baseline, each compensator and the best combination.

``hdservo compare`` (:mod:`hdservo.commands.compare`) runs the standard test
procedures of ``hdservo test`` (:data:`hdservo.commands.test.PROCEDURES`,
their own defaults and option parser) once per *controller*:

* ``pid`` -- the drive's PID baseline, every compensator off (``cb_enable`` 0);
* one controller per compensator of the bank (``stribeck``, ``lugre``,
  ``maxwell``, ``preisach``, ``te``, ``backstep``): that compensator alone on
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
import json
import math
import os
import shlex
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence

FORMAT = "hdservo-compare"
VERSION = 1

#: Compensators of the bank compared one by one (the experimental DOB is left out; docs/compensators.md 8).
SINGLES: tuple[str, ...] = ("stribeck", "lugre", "maxwell", "preisach", "te", "backstep")
#: Procedures run by default: the ones behind the headline figures.
DEFAULT_PROCEDURES: tuple[str, ...] = ("min-rate", "positioning", "stabilisation", "bandwidth", "peak-torque")
#: Best combination when hdservo.compsetup does not define one (docs/compensators.md section 8).
BEST_NAMES_DEFAULT: tuple[str, ...] = ("lugre",)
#: Retuned gains of the default best combination, table units (position P 1/s, scheduled position integral 1/s^2).
BEST_GAINS_DEFAULT: dict[str, float] = {"pos_kp": 60.0, "cb_pki": 900.0}
#: Velocity-loop integral of the default best combination relative to the axis' PID design (12000 / 8019).
BEST_VEL_KI_RATIO = 12000.0 / 8019.0

#: Shortened procedure options (``--quick``): parsed by ``hdservo test``'s option parser.
QUICK_ARGS: tuple[str, ...] = ("--runs", "3", "--targets=-50,-20,10,40", "--windows", "5", "--settle", "3",
                               "--duration", "4")


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
    """

    name: str
    compensators: list[str] = field(default_factory=list)
    gains: dict[str, float] = field(default_factory=dict)
    description: str = ""
    proc_args: dict[str, list[str]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "compensators": list(self.compensators), "gains": dict(self.gains),
                "description": self.description, "proc_args": {k: list(v) for k, v in self.proc_args.items()}}


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
    vel_ki = 8019.0 if base == "defaults" else float(base["vel_ki"])
    return dict(BEST_GAINS_DEFAULT, vel_ki=vel_ki * BEST_VEL_KI_RATIO)


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


def controllers_from_names(names: Sequence[str], axis: str = "reference") -> list[Controller]:
    """Controllers by name: ``pid``, ``best``, a compensator, or ``a+b`` (several compensators, PID gains).

    Raises
    ------
    ValueError
        An unknown name (message names it and the valid ones).
    """
    from .compsetup import ENABLE_BITS
    out: list[Controller] = []
    seen: set[str] = set()
    for raw in names:
        n = raw.strip()
        if not n or n in seen:
            continue
        seen.add(n)
        if n == "pid":
            out.append(Controller("pid", [], {}, "PID baseline (cascaded PID, every compensator off)"))
        elif n == "best":
            out.append(best_controller(axis))
        else:
            parts = n.split("+")
            bad = [p for p in parts if p not in ENABLE_BITS]
            if bad:
                raise ValueError(f"unknown controller '{n}': expected pid, best, or compensators joined by '+' "
                                 f"from {', '.join(ENABLE_BITS)}")
            out.append(Controller(n, parts, {}, f"PID + {' + '.join(parts)} (parameters from the model)"))
    if not out:
        raise ValueError("no controllers given")
    return out


def default_controller_names() -> list[str]:
    """``pid``, each compensator of :data:`SINGLES`, ``best``."""
    return ["pid", *SINGLES, "best"]


# ---------------------------------------------------------------------------------- progress

class StageBar:
    """A text progress bar over a known number of steps (stderr; ``\\r`` on a terminal, lines otherwise).

    Parameters
    ----------
    label : str
        Prefix, e.g. ``compare``.
    total : int
        Number of steps.
    enabled : bool
        False: print nothing.
    """

    def __init__(self, label: str, total: int, enabled: bool = True) -> None:
        self.label = label
        self.total = max(1, total)
        self.enabled = enabled
        self.t0 = time.monotonic()
        self.done = 0

    def show(self, text: str) -> None:
        """Print the bar at the current step with ``text``."""
        if not self.enabled:
            return
        frac = self.done / self.total
        width = 24
        fill = int(round(frac * width))
        el = time.monotonic() - self.t0
        eta = f", ~{el / frac * (1 - frac):.0f} s left" if 0 < frac < 1 else ""
        line = (f"[{self.label}] [{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {text} "
                f"({el:.0f} s{eta})")
        print(line, file=sys.stderr, flush=True)

    def step(self, text: str = "") -> None:
        """One step done."""
        self.done += 1
        self.show(text)


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
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(doc, f, indent=2, allow_nan=False)
            f.write("\n")
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _configure(drive: Any, ctl: Controller, plan: Optional[Mapping[str, Any]],
               preisach_blob: Optional[bytes]) -> list[str]:
    """Write the model's parameters/tables (compensated controllers) and ``cb_enable`` for ``ctl``; returns notes."""
    from .download import write_verified
    from .procedures.runner import apply_compensators
    notes: list[str] = []
    if ctl.compensators or ctl.gains:
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
    (``failed: ...``, no headline) instead of being raised.
    """
    from .commands import test as tc
    from .drive import DriveError
    from .procedures.results import Result
    from .procedures.runner import Progress, Target, open_bench
    setup_f, lockstep, fn = tc.PROCEDURES[name]
    target = Target(bus=bus, node_id=node_id, axis=axis, seed=seed, compensators=None, profile=profile)
    prog = Progress(f"{ctl.name}/{name}", enabled=progress_enabled)
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
                res = fn(bench, args, prog)
    except (DriveError, RuntimeError, ValueError) as e:
        res = Result(name, notes=[f"failed: {e}"])
        res.conditions = {"controller": ctl.name}
        return res
    res.notes.extend(notes + [n for n in target.notes if n not in notes])
    res.conditions = {**res.conditions, "controller": ctl.name}
    return res


def run_compare(out_dir: Path, controllers: Sequence[Controller], procedures: Sequence[str], *,
                proc_extra: Sequence[str] = (), bus: Optional[dict[str, Any]] = None, node_id: int = 1,
                axis: str = "reference", seed: int = 1, model: Optional[Path] = None,
                progress: bool = True, pdf: bool = False,
                echo: Callable[[str], None] = lambda s: None, profile: str = "hdservo") -> dict[str, Any]:
    """Run every procedure with every controller; write the outputs (module docstring); return the document.

    Parameters
    ----------
    out_dir : Path
        Output directory (created).
    controllers : sequence of Controller
        What to compare; ``pid`` first is the reference of the verdicts.
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
    profile : str
        Object profile of the virtual drive (``hdservo`` or ``generic``); unused for a real drive.

    Returns
    -------
    dict
        The ``hdservo-compare`` document written to ``out_dir/compare.json``:
        ``controllers`` (name -> description, compensators, gains, headline,
        failures, ``json``, ``plots``), ``figures`` (key -> label, unit,
        target, values per controller, met per controller, verdict vs PID),
        ``comparison_plots``, ``best``, ``reference``, ``conditions``, ``run_time_s``.

    Raises
    ------
    ValueError
        Bad procedure name or options (before anything runs).
    """
    from .commands import test as tc
    from .procedures.results import write_json
    bad = [p for p in procedures if p not in tc.PROCEDURES]
    if bad:
        raise ValueError(f"unknown procedure '{bad[0]}'; expected some of {', '.join(sorted(tc.PROCEDURES))}")
    pargs = {(c.name, p): procedure_args(p, [*proc_extra, *c.proc_args.get(p, [])])
             for c in controllers for p in procedures}
    plan = None
    blob = None
    if model is not None:
        from .download import plan_download
        plan = plan_download(model, axis)
    elif bus is None and any("preisach" in c.compensators for c in controllers):
        from . import compsetup
        blob = compsetup.preisach_table(axis).to_bytes()
    t0 = time.monotonic()
    out_dir.mkdir(parents=True, exist_ok=True)
    bar = StageBar("compare", len(controllers) * len(procedures), enabled=progress)
    bar.show("starting")
    doc_ctl: dict[str, Any] = {}
    for ctl in controllers:
        results = []
        for name in procedures:
            bar.show(f"{ctl.name} / {name} ...")
            res = run_procedure(name, ctl, pargs[(ctl.name, name)], bus=bus, node_id=node_id, axis=axis, seed=seed, plan=plan,
                                preisach_blob=blob, progress_enabled=progress, profile=profile)
            results.append(res)
            head = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in res.headline.items())
            fails = [n for n in res.notes if n.startswith("failed:")]
            echo(f"{ctl.name:>10s} {name:<14s} {head or '; '.join(fails) or '(no headline)'}")
            bar.step(f"{ctl.name} / {name} done")
        cdir = out_dir / ctl.name
        plots: list[str] = []
        pdir = cdir / "plots"
        for res in results:
            if res.plot is not None:
                for p in res.plot(res, pdir, "pdf" if pdf else "png"):
                    if p.suffix == ".png":
                        plots.append(str(p.relative_to(out_dir)))
        meta = {"target": "virtual drive (hdservo-sim serve)" if bus is None else f"drive {bus}",
                "axis": axis if bus is None else None, "seed": seed if bus is None else None,
                "compensators": list(ctl.compensators), "controller": ctl.to_json(), "notes": []}
        write_json(cdir / "test.json", results, meta)
        headline: dict[str, Any] = {}
        for r in results:
            headline.update(json.loads(json.dumps(r.to_json()["headline"])))
        doc_ctl[ctl.name] = {**ctl.to_json(), "headline": headline, "json": str((cdir / "test.json").relative_to(out_dir)),
                             "plots": plots,
                             "failures": {r.name: [n for n in r.notes if n.startswith("failed:")] for r in results
                                          if any(n.startswith("failed:") for n in r.notes)}}
    ref_name = "pid" if "pid" in doc_ctl else controllers[0].name
    best_name = "best" if "best" in doc_ctl else controllers[-1].name
    figs: dict[str, Any] = {}
    for f in FIGURES:
        if f.procedure not in procedures:
            continue
        vals = {c: d["headline"].get(f.key) for c, d in doc_ctl.items()}
        figs[f.key] = {"label": f.label, "short": f.short or f.label, "unit": f.unit, "lower_is_better": f.lower_is_better, "target": f.target,
                       "target_text": f.target_text(), "values": vals,
                       "meets_target": {c: f.meets(v) for c, v in vals.items()},
                       "vs_" + ref_name: {c: f.verdict(v, vals[ref_name]) for c, v in vals.items() if c != ref_name},
                       "best_measured": best_measured(f, vals)}
    doc: dict[str, Any] = {
        "format": FORMAT, "version": VERSION, "reference": ref_name, "best": best_name,
        "conditions": {"target": "virtual drive (hdservo-sim serve --rig)" if bus is None else f"drive {bus}",
                       "axis": axis if bus is None else None, "seed": seed if bus is None else None,
                       "procedures": list(procedures), "procedure_options": list(proc_extra),
                       "model": str(model) if model is not None else None,
                       "parameters": ("identified model, downloaded and read back before each compensated "
                                      "procedure" if model is not None else "the drive's compensator defaults"),
                       "model_notes": list(plan["notes"]) if plan else []},
        "controllers": doc_ctl, "figures": figs}
    doc["comparison_plots"] = [str(p.relative_to(out_dir)) for p in comparison_plots(doc, out_dir / "plots")]
    doc["verdict"] = verdict(doc)
    doc["run_time_s"] = round(time.monotonic() - t0, 1)
    _write_json_atomic(out_dir / "compare.json", doc)
    return doc


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
        a.set_title(f"{f['label']}\ngreen = target met, red = not met", fontsize=10)
        a.grid(True, axis="y", which="both", alpha=0.4)
        fig.tight_layout()
        paths += [p for p in save_figure(fig, out_dir, f"compare_{key}") if p.suffix == ".png"]
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
    lines.append("(* = meets the target of docs/reference-axis.md; 'none' = no value, e.g. no smooth rung)")
    return "\n".join(lines)


def _num(v: Any) -> str:
    if v is None:
        return "none"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def summary_doc(doc: Mapping[str, Any], compensated: Optional[str] = None) -> dict[str, Any]:
    """``{figure: {"pid": value, "compensated": value}}`` for every figure of :data:`FIGURES` (None when not run)."""
    ref = doc["reference"]
    comp = compensated or doc["best"]
    out: dict[str, Any] = {}
    for f in FIGURES:
        d = doc["figures"].get(f.key, {}).get("values", {})
        out[f.key] = {"pid": d.get(ref), "compensated": d.get(comp)}
    return out


def parse_proc_args(text: Optional[str]) -> list[str]:
    """Split a ``--proc-args`` string into options (shell quoting)."""
    if not text:
        return []
    try:
        return shlex.split(text)
    except ValueError as e:
        raise ValueError(f"--proc-args: {e}") from None


__all__ = ["BEST_NAMES_DEFAULT", "Controller", "DEFAULT_PROCEDURES", "FIGURES", "FIGURE_BY_KEY", "Figure", "FORMAT",
           "QUICK_ARGS", "SINGLES", "StageBar", "best_controller", "comparison_plots", "controllers_from_names",
           "default_controller_names", "parse_proc_args", "procedure_args", "run_compare", "summary_doc",
           "summary_table", "verdict"]
