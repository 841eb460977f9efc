"""``hdservo demo`` (``make demo``): the whole flow on a virtual axis (the reference axis, or ``--axis FILE``), end to end.

1. start the virtual axis (``hdservo-sim serve --rig`` on an ephemeral loopback port);
2. identify the axis over CAN (``hdservo identify all --sim``; the identification starts its own
   lock-step virtual drive with the test-rig channel it needs for the locked-output experiments);
3. download the compensator parameters and tables computed from the identified model to the
   running virtual drive, every item read back (``hdservo download``);
4. run the test procedures in the ablation (``hdservo compare --model``, per feedback
   configuration: the fair PID, + each compensator, the best combination chosen by the
   documented rule, best minus each part, motion strategies; each procedure starts a virtual
   drive with its rig set-up -- payload, base rocking, output lock -- and the identified
   parameters are downloaded to it again, since a virtual drive keeps no parameters between
   processes);
5. write the HTML report (``hdservo report``);
6. print where it is, a summary table and the ablation table, write ``OUT/summary.json``
   (``{figure: {"pid": .., "compensated": ..}, "conditions": ..}``) and ``OUT/ablation.json``,
   stop the virtual drive, print the run time.

``--seeds 1,2,3``: step 4 runs one ``hdservo compare`` process per sensor-noise seed (``--jobs``
at a time) into ``OUT/compare/seed-S/``, and ``summary.json`` / ``ablation.json`` hold the medians
over the seeds with every seed's values (:mod:`hdservo.seeds`); the report shows the first seed.

Outputs under ``OUT`` (default ``build/demo``): ``model.toml`` (+ ``model.preisach.bin``),
``identify.json``, ``identify-plots/``, ``download.json``, ``compare/``, ``report.html``,
``summary.json``, ``ablation.json`` (:data:`OUTPUTS`; removed at the start, so nothing is reused from an earlier run).
"""
from __future__ import annotations

import argparse
import math
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Sequence

from ..errors import UserError
from ..progress import Bar, echo

NAME = "demo"
HELP = ("end-to-end demo on a virtual axis (reference, or --axis FILE): identify, download, ablation of the fair PID "
        "and the compensators, report")

STEPS = 6
#: What the demo writes into its output directory (removed first; nothing else there is touched).
OUTPUTS = ("model.toml", "model.preisach.bin", "identify.json", "identify.txt", "identify-plots", "download.json",
           "download.txt", "compare", "report.html", "summary.json", "ablation.json")


def register(p: argparse.ArgumentParser) -> None:
    """Options of ``hdservo demo``."""
    from .. import compare as cmp
    p.add_argument("--out-dir", type=Path, default=Path("build") / "demo", metavar="DIR",
                   help="output directory (default build/demo)")
    p.add_argument("--axis", default="reference", metavar="FILE",
                   help="axis file of the virtual axis (default: the reference axis)")
    p.add_argument("--controllers", default="ablation",
                   help="'ablation' (default) or controllers as in hdservo compare (e.g. pid,best)")
    p.add_argument("--feedback", default=None, metavar="CONFIGS",
                   help="feedback configurations (default: full-closed, plus semi-closed when the drive has them)")
    p.add_argument("--jobs", type=int, default=2, help="controllers run at the same time (default 2)")
    p.add_argument("--procedures", default=",".join(cmp.DEFAULT_PROCEDURES), help="procedures run per controller")
    p.add_argument("--quick", action="store_true", help="shortened procedures (hdservo compare --quick)")
    p.add_argument("--seed", type=int, default=None, help="sensor-noise seed of the virtual drives (default 1)")
    p.add_argument("--torque-max", type=float, default=None, metavar="NM",
                   help="stiffness-cycle amplitude of the identification, N.m output (catalogue: >= 1.3 T2 of the "
                        "gear; default that of hdservo identify, 67)")
    p.add_argument("--seeds", default=None, metavar="LIST",
                   help="sensor-noise seeds, e.g. 1,2,3: the comparison runs once per seed (parallel processes, "
                        "--jobs at a time) and summary.json / ablation.json hold the medians with every seed's "
                        "values; the identification runs with the first seed")


def _say(bar: Bar, text: str) -> None:
    """Enter the next of the demo's steps: the bar shows it (a log line off a terminal)."""
    bar.step(text)


def _hdservo(argv: Sequence[str], what: str, log: Path) -> None:
    """Run ``hdservo ARGV`` (same interpreter); its progress goes to stderr, its stdout to the terminal and ``log``."""
    cmd = [sys.executable, "-m", "hdservo.cli", *argv]
    with open(log, "w") as f:
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
        assert p.stdout is not None
        for line in p.stdout:
            f.write(line)
            echo(f"  {line.rstrip()}")
        rc = p.wait()
    if rc != 0:
        raise UserError(f"{what} failed (exit {rc}; command: hdservo {' '.join(argv)})")


def run(args: argparse.Namespace) -> int:
    """Run the six steps; returns 0 when everything ran (targets met or not)."""
    from .. import compare as cmp
    from ..procedures.runner import VirtualDriveProcess
    from ..report import ReportError, build_report, verify_report
    t0 = time.monotonic()
    out: Path = args.out_dir
    axis = args.axis
    if axis != "reference":
        ap = Path(axis)
        if not ap.is_file():
            raise UserError(f"--axis {axis}: no such axis file")
        from .. import sim
        try:
            sim.axis_param("gear.ratio", str(ap))
        except Exception as e:       # noqa: BLE001 - any reader error is the file's fault
            raise UserError(f"--axis {axis}: not a readable axis file ({e})") from None
        axis = str(ap.resolve())
    if args.jobs < 1:
        raise UserError(f"--jobs {args.jobs}: must be >= 1")
    from .. import seeds as sd
    if args.seeds is not None and args.seed is not None:
        raise UserError("--seed and --seeds: give one (--seeds N is one seed)")
    try:
        seeds = sd.parse_seeds(args.seeds) if args.seeds is not None else [1 if args.seed is None else args.seed]
    except ValueError as e:
        raise UserError(str(e)) from None
    seed = seeds[0]
    if args.torque_max is not None and not (math.isfinite(args.torque_max) and args.torque_max > 0):
        raise UserError(f"--torque-max {args.torque_max}: expected a positive number of N.m")
    tmax = [] if args.torque_max is None else ["--torque-max", repr(float(args.torque_max))]
    ablation = args.controllers.strip() == "ablation"
    try:
        fbs = cmp.feedback_names(args.feedback) if args.feedback is not None else cmp.default_feedbacks()
        ctls = [] if ablation else cmp.controllers_from_names(args.controllers.split(","), axis, fbs)
    except ValueError as e:
        raise UserError(str(e)) from None
    procs = [x.strip() for x in args.procedures.split(",") if x.strip()]
    extra = list(cmp.QUICK_ARGS) if args.quick else []
    from . import test as tc
    bad = [x for x in procs if x not in tc.PROCEDURES]
    if bad or not procs:
        raise UserError(f"--procedures: unknown '{bad[0] if bad else ''}'; expected some of "
                        f"{', '.join(sorted(tc.PROCEDURES))}")
    try:
        for c in ctls or [cmp.fair_row([], "full-closed")]:
            for x in procs:
                cmp.procedure_args(x, [*extra, *c.proc_args.get(x, [])])
    except ValueError as e:
        raise UserError(str(e)) from None
    if out.exists() and not out.is_dir():
        raise UserError(f"--out-dir {out}: not a directory")
    out.mkdir(parents=True, exist_ok=True)
    for name in OUTPUTS:                         # a fresh run: nothing stale in the report (only our own files)
        q = out / name
        if q.is_dir() and not q.is_symlink():
            shutil.rmtree(q)
        elif q.exists() or q.is_symlink():
            q.unlink()
    model = out / "model.toml"
    aname = "reference" if axis == "reference" else Path(axis).name
    what = (f"ablation over {', '.join(fbs)}" if ablation else f"{len(ctls)} controllers")
    print(f"hdservo demo: axis {aname}, {what} x {len(procs)} procedures, outputs in {out}/", flush=True)

    print(f"hdservo demo: using a simulated drive (virtual drive, axis {aname}); your real drive is not touched",
          file=sys.stderr, flush=True)
    bar = Bar("demo", STEPS, enabled=not args.quiet)
    _say(bar, f"starting the virtual axis {aname} (hdservo-sim serve)")
    drive = VirtualDriveProcess(axis, pacing="fast", seed=seed)
    try:
        print(f"  virtual drive: CANopen node 1 on socketcand 127.0.0.1:{drive.port}", flush=True)

        _say(bar, "identifying the axis over CAN (hdservo identify all)")
        _hdservo(["identify", "all", f"--sim={axis}", "-o", str(model), "--json", str(out / "identify.json"),
                  "--out-dir", str(out / "identify-plots"), "--seed", str(seed), *tmax], "identification",
                 out / "identify.txt")

        _say(bar, f"downloading the compensator parameters to the virtual drive (port {drive.port})")
        _hdservo(["download", str(model), "-i", "socketcand", "-c", "can0", "--host", "127.0.0.1",
                  "--port", str(drive.port), "--json", str(out / "download.json")], "download",
                 out / "download.txt")

        _say(bar, "running the procedures: fair PID, each compensator, best, leave-one-out (hdservo compare)")
        if len(seeds) == 1:
            kw = dict(proc_extra=extra, axis=axis, seed=seed, model=model, jobs=args.jobs,
                      progress=not args.quiet, echo=lambda s: echo(f"  {s}"))
            try:
                if ablation:
                    doc = cmp.run_ablation(out / "compare", fbs, procs, **kw)
                else:
                    doc = cmp.run_compare(out / "compare", ctls, procs, **kw)
            except ValueError as e:
                raise UserError(str(e)) from None
            compare_json = out / "compare" / "compare.json"
            summ, abl = cmp.summary_doc(doc), cmp.ablation_doc(doc)
        else:
            docs = _compare_per_seed(out / "compare", seeds, axis, model, args, fbs, procs)
            doc = docs[0]
            compare_json = out / "compare" / f"seed-{seed}" / "compare.json"
            summ = sd.merge_summaries([cmp.summary_doc(d) for d in docs], seeds)
            abl = sd.merge_ablations([cmp.ablation_doc(d) for d in docs], seeds)

        _say(bar, "writing the report (hdservo report)")
        cmp._write_json_atomic(out / "summary.json", summ)
        cmp._write_json_atomic(out / "ablation.json", abl)
        seed_line = (f"seed {seed}" if len(seeds) == 1 else
                     f"seed {seed} shown; summary.json / ablation.json: medians of seeds {','.join(map(str, seeds))}")
        try:
            info = build_report(out / "report.html", compare=compare_json,
                                identify=out / "identify.json", download=out / "download.json",
                                title=f"hdservo demo: axis {aname}, fair PID baseline vs compensation",
                                summary_lines=[f"hdservo demo on the virtual axis {aname} ({seed_line}); "
                                               f"compensated = '{doc['best']}': "
                                               f"{doc['controllers'][doc['best']]['description']}"])
            verified = verify_report(out / "report.html")     # every plot file exists, holds data, is embedded
        except ReportError as e:
            raise UserError(f"report: {e}") from None
        _say(bar, "stopping the virtual drive")
    finally:
        drive.stop()
        bar.close()
    el = time.monotonic() - t0
    print()
    print(cmp.summary_table(doc, [c for c in (doc["reference"], doc["best"]) if c in doc["controllers"]]))
    print()
    print(cmp.ablation_table(doc))
    for fb, inf in doc.get("ablation", {}).get("feedbacks", {}).items():
        print(f"best combination, {fb}: {' + '.join(inf['best']) or 'none (no compensator pays)'}")
        for line in cmp.selection_lines(inf.get("rule", [])):
            print(f"  {line}")
        for part, j in inf.get("leave_one_out", {}).items():
            print(f"  leave-one-out, {part}: {'pays' if j['pays'] else 'does not pay'} ({j['text']})")
    v = doc["verdict"]
    met = [k for k, ok in v["targets_met"].items() if ok]
    miss = [k for k, ok in v["targets_met"].items() if not ok]
    print(f"compensated ({v['controller']}): {len(met)} of {len(v['targets_met'])} targets met"
          + (f"; not met: {', '.join(miss)}" if miss else ""))
    print(f"compensated better than PID on every figure: {'yes' if v['better_everywhere'] else 'no'} "
          f"({', '.join(f'{k} {x}' for k, x in v['better_than_reference'].items())})")
    for c, d in doc["controllers"].items():
        for proc, notes in d["failures"].items():
            print(f"FAILED {c}/{proc}: {'; '.join(notes)}")
    print(f"report:  {out / 'report.html'} ({info['bytes'] / 1e6:.1f} MB, {len(verified)} plots embedded and "
          f"checked against their files)")
    if len(seeds) > 1:
        print()
        print(median_table(summ))
    print(f"summary: {out / 'summary.json'}; ablation: {out / 'ablation.json'}; all controllers: "
          f"{compare_json}")
    print(f"demo: done in {el:.0f} s ({int(el // 60)} min {int(el % 60)} s); virtual drive stopped")
    return 0


def _compare_per_seed(root: Path, seeds: Sequence[int], axis: str, model: Path, args: argparse.Namespace,
                      fbs: Sequence[str], procs: Sequence[str]) -> list[dict]:
    """One ``hdservo compare`` process per seed (``--jobs`` at a time, one row at a time each), in seed order.

    Each writes ``ROOT/seed-S/`` (its log ``compare.txt`` beside); a process that fails is one error
    line naming the seed and its log.
    """
    import json
    root.mkdir(parents=True, exist_ok=True)
    base = [sys.executable, "-m", "hdservo.cli", "compare", f"--sim={axis}", "--model", str(model),
            "--controllers", args.controllers, "--feedback", ",".join(fbs), "--procedures", ",".join(procs),
            "--jobs", "1", "-q"] + (["--quick"] if args.quick else [])
    pending = list(seeds)
    running: list[tuple[int, subprocess.Popen, object]] = []
    failed: list[str] = []
    while pending or running:
        while pending and len(running) < args.jobs:
            s = pending.pop(0)
            d = root / f"seed-{s}"
            d.mkdir(parents=True, exist_ok=True)
            log = open(d / "compare.txt", "w")
            print(f"  seed {s}: hdservo compare --out-dir {d} (log {d / 'compare.txt'})", flush=True)
            running.append((s, subprocess.Popen([*base, "--seed", str(s), "--out-dir", str(d)], stdout=log,
                                                stderr=subprocess.STDOUT), log))
        time.sleep(0.5)
        for item in list(running):
            s, p, log = item
            if p.poll() is None:
                continue
            log.close()             # type: ignore[attr-defined]
            running.remove(item)
            print(f"  seed {s}: done (exit {p.returncode})", flush=True)
            if p.returncode != 0:
                failed.append(f"seed {s} (exit {p.returncode}, log {root / f'seed-{s}' / 'compare.txt'})")
    if failed:
        raise UserError(f"comparison failed for {', '.join(failed)}")
    return [json.loads((root / f"seed-{s}" / "compare.json").read_text()) for s in seeds]


def median_table(summ: dict) -> str:
    """Medians over the seeds: figure, fair PID, compensated, ratio, and the per-seed values."""
    lines = [f"medians over seeds {','.join(map(str, summ['seeds']))} (per seed in brackets):",
             f"{'figure':<44s}{'fair PID':>12s}{'compensated':>14s}{'ratio':>8s}  per seed (pid / compensated)"]
    for k, v in summ.items():
        if k == "conditions" or not isinstance(v, dict) or "per_seed" not in v:
            continue
        p, c = v["pid"], v["compensated"]
        r = f"{c / p:.3g}" if p not in (None, 0) and c is not None else "-"
        per = ", ".join(f"{_g(a)} / {_g(b)}" for a, b in zip(v["per_seed"]["pid"], v["per_seed"]["compensated"]))
        lines.append(f"{k:<44s}{_g(p):>12s}{_g(c):>14s}{r:>8s}  [{per}]")
    return "\n".join(lines)


def _g(v: object) -> str:
    return "-" if v is None else f"{float(v):.4g}"  # type: ignore[arg-type]
