#!/usr/bin/env python3
"""Selection rules from measurements: Maxwell-slip vs Preisach, and which compensator for which need.

Per axis (reference, csf17_50): :func:`hdservo.analysis.selection.hysteresis_table` over load
amplitudes 0.1-1.0 x rated torque and minor-loop widths 0.05-0.3 (fractions of 2A), Preisach
tables of 16 levels.  The needs table comes from ``build/demo/ablation.json`` when ``make demo``
wrote it, the CPU costs from ``build/bench/cm4_cost.json`` when ``make bench`` wrote it
(otherwise those columns say not measured here), the parameter-drift row from
``build/results/drift_mc.json`` when 58_drift_monte_carlo.py wrote it (make results runs it before this script).  Every stated rule is checked on the tables.
Writes build/results/selection_rules.json (with axis names as arguments: only those,
to selection_rules.<names>.json).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo.analysis import selection as sel  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402

AXES = {"reference": "reference", "csf17_50": str(ROOT / "sim" / "axes" / "csf17_50.toml")}
ONLY = sys.argv[1:]          # axis names to run (default: all)
AMPLITUDES = (0.1, 0.3, 0.5, 0.7, 1.0)
WIDTHS = (0.05, 0.1, 0.3)
LEVELS = 16
SEED = 11


def main() -> int:
    t0 = time.time()
    costs = sel.cpu_costs(ROOT / "build" / "bench" / "cm4_cost.json")
    abl_path = ROOT / "build" / "demo" / "ablation.json"
    abl = json.loads(abl_path.read_text()) if abl_path.is_file() else {"rows": []}
    hyst = []
    for name, axis in AXES.items():
        if ONLY and name not in ONLY:
            continue
        rows = sel.hysteresis_table(axis, AMPLITUDES, WIDTHS, levels=LEVELS, seed=SEED)
        for r in rows:
            r.axis = name
        hyst += rows
    drift = sel.load_drift(ROOT / "build" / "results" / "drift_mc.json")
    needs = sel.needs_table(abl, costs, "full-closed", drift=sel.drift_gains(drift)) if abl["rows"] else []
    doc = sel.selection_doc(hyst, needs, costs, closed_loop=sel.closed_loop_benefit(abl), meta={
        "amplitudes_frac_rated": list(AMPLITUDES), "minor_widths_frac": list(WIDTHS), "levels": LEVELS,
        "seed": SEED, "ablation": "build/demo/ablation.json" if abl["rows"] else "not measured here",
        "drift": (f"build/results/drift_mc.json ({drift.get('runs_per_controller')} runs per controller)"
                  if drift else "not measured here"),
        "cm4_cost": "build/bench/cm4_cost.json" if any(v is not None for v in costs.values())
        else "not measured here", "run_time_s": time.time() - t0})
    out = ROOT / "build" / "results" / ("selection_rules.json" if not ONLY else
                                        f"selection_rules.{'+'.join(ONLY)}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out, doc)
    for r in doc["hysteresis"]:
        if r["note"]:
            print(f"{r['axis']:>9s} A {r['amplitude_frac']:.2f}: {r['note']}")
            continue
        print(f"{r['axis']:>9s} A {r['amplitude_frac']:.2f} ({r['amplitude_Nm']:.1f} N.m): major "
              f"M {r['major_err_arcsec']['maxwell']:.2f}\" P {r['major_err_arcsec']['preisach']:.2f}\"; minor "
              + ", ".join(f"w{w} M {r['minor_err_arcsec']['maxwell'][w]:.2f}\" P {r['minor_err_arcsec']['preisach'][w]:.2f}\""
                          for w in r["minor_err_arcsec"]["maxwell"]) + f"; loop width {r['loop_width_arcsec']:.1f}\"")
    print(f"semi-closed positioning gain: {doc['closed_loop_semi_positioning_gain']}")
    for n in doc["needs"]:
        print(f"need {n['need']}: {n['compensator']} {n['gain']}")
    bad = [r for r in doc["rules"] if not r["holds"]]
    for r in doc["rules"]:
        print(f"{'holds' if r['holds'] else 'FAILS'}: {r['text']}")
    print(f"wrote {out} ({time.time() - t0:.0f} s)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
