"""``hdservo compare``: the test procedures with the PID baseline, each compensator and the best combination.

The procedures run on the drive python-can's settings name (``-i/-c/-b``, else
its config file and ``CAN_*`` variables; without any of them the command
refuses); with ``--sim [AXIS]`` (or ``-i virtual-drive``) every procedure runs
on its own simulated axis (reference, or AXIS), exactly as ``hdservo test`` does.
``--model MODEL.toml`` (``hdservo identify -o``) downloads the compensator parameters computed from the identified model
(verified by read-back) before every compensated procedure.  Writes
``OUT/compare.json``, per-controller ``hdservo-test`` JSON and plots, and one
comparison chart per headline figure (layout: :mod:`hdservo.compare`); prints
a table with the targets of docs/reference-axis.md marked and the ablation table (each row's ratio to the fair PID of
its feedback configuration); with ``--controllers ablation`` (default) also ``OUT/ablation.json``.  ``hdservo report
OUT/compare.json`` turns it into one HTML file.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from ..errors import UserError
from .. import progress

NAME = "compare"
HELP = ("run the test procedures with the fair PID baseline, each compensator, the best combination and "
        "leave-one-out rows, per feedback configuration; compare")


def register(p: argparse.ArgumentParser) -> None:
    """Options of ``hdservo compare``."""
    from .. import compare as cmp
    from ..drive import add_bus_arguments
    p.add_argument("--out-dir", type=Path, default=Path("build") / "compare", metavar="DIR",
                   help="output directory (default build/compare)")
    p.add_argument("--controllers", default="ablation",
                   help="'ablation' (default: per feedback configuration the fair PID, + each compensator, the "
                        "best combination chosen by the documented rule, best minus each part, motion strategies) "
                        "or comma-separated: pid, best, pid-hold, compensators / strategies joined by '+'")
    p.add_argument("--feedback", default=None, metavar="CONFIGS",
                   help="feedback configurations, comma-separated: full-closed, semi-closed, dual-loop "
                        "(default: full-closed, plus semi-closed when the drive has fb_config)")
    p.add_argument("--jobs", type=int, default=2,
                   help="with --sim: controllers run at the same time, each on its own virtual drive (default 2)")
    p.add_argument("--procedures", default=",".join(cmp.DEFAULT_PROCEDURES),
                   help="comma-separated procedures of 'hdservo test' (default: the headline ones: "
                        f"{','.join(cmp.DEFAULT_PROCEDURES)})")
    p.add_argument("--model", type=Path, metavar="MODEL.toml",
                   help="identified model: its compensator parameters are downloaded before each compensated run "
                        "(default: the drive's own compensator parameters)")
    p.add_argument("--quick", action="store_true",
                   help=f"shortened procedures ({' '.join(cmp.QUICK_ARGS)})")
    p.add_argument("--proc-args", default=None, metavar="'OPTIONS'",
                   help="further 'hdservo test' procedure options for every procedure, e.g. '--runs 3'")
    add_bus_arguments(p)
    p.add_argument("--seed", type=int, default=None, help="with --sim only: sensor-noise seed (default 1)")
    p.add_argument("--json", type=Path, help="also write the comparison document here")
    p.add_argument("--pdf", action="store_true", help="also write PDF plots")


def _check_dir(path: Path, what: str) -> None:
    if path.exists() and not path.is_dir():
        raise UserError(f"{what} {path}: not a directory")
    probe = path
    while not probe.exists():
        probe = probe.parent
    if not os.access(probe, os.W_OK):
        raise UserError(f"{what} {path}: not writable")


def run(args: argparse.Namespace) -> int:
    """Check the input, run the comparison, print the table."""
    from .. import compare as cmp
    from ..drive import choose_drive
    # the user's files are checked before a drive is chosen: a bad file is the first error
    if args.model is not None and not args.model.is_file():
        raise UserError(f"--model {args.model}: no such file")
    if args.model is not None:              # a bad model is refused before anything runs
        from ..download import plan_download
        plan_download(args.model, getattr(args, "sim", None) or "reference")
    choice = choose_drive(args, sim_only=("seed",))
    bus = choice.bus
    axis = choice.axis or "reference"
    seed = 1 if args.seed is None else args.seed
    _check_dir(args.out_dir, "--out-dir")
    if args.json is not None:
        if args.json.is_dir():
            raise UserError(f"--json {args.json}: is a directory")
        _check_dir(args.json.parent, "--json")
    if args.jobs < 1:
        raise UserError(f"--jobs {args.jobs}: must be >= 1")
    ablation = args.controllers.strip() == "ablation"
    try:
        fbs = cmp.feedback_names(args.feedback) if args.feedback is not None else cmp.default_feedbacks()
        ctls = [] if ablation else cmp.controllers_from_names(args.controllers.split(","),
                                                              axis if bus is None else "reference", fbs)
        procs = [x.strip() for x in args.procedures.split(",") if x.strip()]
        if not procs:
            raise ValueError("--procedures: none given")
        extra = (list(cmp.QUICK_ARGS) if args.quick else []) + cmp.parse_proc_args(args.proc_args)
        from ..commands import test as tc
        bad = [x for x in procs if x not in tc.PROCEDURES]
        if bad:
            raise ValueError(f"--procedures: unknown '{bad[0]}'; expected some of {', '.join(sorted(tc.PROCEDURES))}")
        for x in procs:
            cmp.procedure_args(x, extra)
            for c in ctls:
                cmp.procedure_args(x, [*extra, *c.proc_args.get(x, [])])
    except ValueError as e:
        raise UserError(str(e)) from None
    choice.announce("compare")
    try:
        kw = dict(proc_extra=extra, bus=bus, node_id=args.node_id, axis=axis, seed=seed, model=args.model,
                  progress=not args.quiet, pdf=args.pdf, echo=(lambda s: None) if args.quiet else progress.echo,
                  jobs=args.jobs, profile=choice.profile)
        if ablation:
            doc = cmp.run_ablation(args.out_dir, fbs, procs, **kw)
        else:
            doc = cmp.run_compare(args.out_dir, ctls, procs, **kw)
    except ValueError as e:
        raise UserError(str(e)) from None
    if args.json is not None:
        cmp._write_json_atomic(args.json, doc)
    print(cmp.summary_table(doc))
    print()
    print(cmp.ablation_table(doc))
    for fb, info in doc.get("ablation", {}).get("feedbacks", {}).items():
        print(f"best combination, {fb}: {' + '.join(info['best']) or 'none (no compensator pays)'}")
        for line in cmp.selection_lines(info.get("rule", [])):
            print(f"  {line}")
        for part, j in info.get("leave_one_out", {}).items():
            print(f"  leave-one-out, {part}: {'pays' if j['pays'] else 'does not pay'} ({j['text']})")
    from ..analysis.selection import compare_lines
    for line in compare_lines(doc):
        print(line)
    v = doc["verdict"]
    if v["targets_met"]:
        met = [k for k, ok in v["targets_met"].items() if ok]
        print(f"{v['controller']}: {len(met)} of {len(v['targets_met'])} targets met"
              + (f" ({', '.join(met)})" if met else ""))
    if v["better_than_reference"]:
        print(f"{v['controller']} better than {v['reference']} on every figure: {v['better_everywhere']}")
    fails = {c: d["failures"] for c, d in doc["controllers"].items() if d["failures"]}
    for c, f in fails.items():
        for proc, notes in f.items():
            print(f"FAILED {c}/{proc}: {'; '.join(notes)}")
    print(f"wrote {args.out_dir / 'compare.json'} ({doc['run_time_s']:.0f} s)")
    return 0
