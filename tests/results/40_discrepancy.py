#!/usr/bin/env python3
"""Confusion table of the model-discrepancy workflow on simulator logs -> build/results/discrepancy.json.

For every effect name (and "none"), both axis files, closed and open loop, two seeds
(seed parity selects the parameter size): simulate a log with exactly that effect hidden
(hdservo.discrepancy.cases), run the workflow, record what it named first and the RMS
of the equation error before/after (first and last model of the loop).  Also runs EMPS (if the data are present).
Prints a summary; never fails on the numbers (they are reported in docs/discrepancy.md).
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "host"))

from hdservo import emps, logio  # noqa: E402
from hdservo.cli import UserError  # noqa: E402
from hdservo.discrepancy import EFFECT_NAMES, cases, realdata, signals, workflow  # noqa: E402

SEEDS = (1, 2)
#: Worker processes (the machine has two cores).
WORKERS = 2


def _one(args: tuple[str, str, str, int]) -> dict:
    """Simulate and analyse one case (runs in a worker process)."""
    eff, axis, loop, seed = args
    c = cases.Case(None if eff == "none" else eff, axis=axis, loop=loop, seed=seed, size=seed % 2)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as td:
        p = cases.make_log(c, Path(td) / f"{c.label}.csv")
        try:
            sig = signals.from_log(logio.read_log(p), c.structure)
            r = workflow.run(sig)
            got = r.named[0] if r.named else "none"
            all_named = r.named
            rb = r.rms_history[0]
            ra = r.rms_history[-1]
            first = r.ranking_first[:3]
        except UserError as e:
            got, all_named, rb, ra, first = f"error: {e}", [], float("nan"), float("nan"), []
    return {"case": c.label, "hidden": eff, "named": got, "all_named": all_named,
            "rms_before_Nm": rb, "rms_after_Nm": ra, "shrink": rb / ra if ra and ra == ra else None,
            "first_ranking": [{k: x[k] for k in ("effect", "delta_bic", "explained_fraction")} for x in first],
            "wall_s": time.monotonic() - t0}


def main() -> int:
    out_dir = REPO / "build" / "results"
    out_dir.mkdir(parents=True, exist_ok=True)
    names = ["none", *EFFECT_NAMES]
    confusion: dict[str, dict[str, int]] = {a: {} for a in names}
    t0 = time.monotonic()
    jobs = [(eff, axis, loop, seed) for eff in names for axis in ("reference", "csf17_50")
            for loop in ("closed", "open") for seed in SEEDS]
    rows = []
    with ProcessPoolExecutor(max_workers=WORKERS) as ex:
        for row in ex.map(_one, jobs):
            rows.append(row)
            confusion[row["hidden"]][row["named"]] = confusion[row["hidden"]].get(row["named"], 0) + 1
            print(f"{row['case']:48s} -> {row['named']:22s} {row['rms_before_Nm']:.3g} -> {row['rms_after_Nm']:.3g}",
                  flush=True)
    summary = {}
    for eff in names:
        tot = sum(confusion[eff].values())
        ok = confusion[eff].get(eff, 0)
        sh = [r["shrink"] for r in rows if r["hidden"] == eff and r["named"] == eff and r["shrink"]]
        summary[eff] = {"cases": tot, "correct": ok, "rate": ok / tot if tot else None,
                        "min_shrink_when_named": min(sh) if sh else None,
                        "median_shrink_when_named": float(sorted(sh)[len(sh) // 2]) if sh else None}
    result = {"confusion": confusion, "summary": summary, "cases": rows, "wall_s": time.monotonic() - t0,
              "rms_unit": workflow.SIGNAL_TEXT}
    try:
        d = emps.resolve_data_dir()
        rec = emps.load_benchmark_record(d, emps.TRAIN_RECORD)
        with tempfile.TemporaryDirectory() as td:
            p = Path(td) / "emps.csv"
            emps.write_log(rec, p)
            r = workflow.run(signals.from_log(logio.read_log(p)))
        named = r.named[0] if r.named else None
        chk = realdata.idim_relative_error(rec, named, r.iterations[0]["params"] if r.iterations else {})
        result["emps"] = {"named_effects": r.named, "idim": chk, "baseline": r.baseline}
        print(f"EMPS: named {r.named}, IDIM relative error {chk['relative_error_pct']:.3f} %")
    except UserError as e:
        result["emps"] = {"skipped": str(e)}
    logio._atomic_write(out_dir / "discrepancy.json", json.dumps(result, indent=2) + "\n")
    for eff, s in summary.items():
        print(f"{eff:24s} {s['correct']}/{s['cases']} named correctly; min shrink {s['min_shrink_when_named']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
