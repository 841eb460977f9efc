#!/usr/bin/env python3
"""The demo's targets as medians over sensor-noise seeds 1-3, on the reference axis and csf17_50.

``hdservo demo --seeds 1,2,3 [--axis FILE] -o build/results/demo_seeds/<axis>`` (one comparison
per seed in parallel processes, medians in its summary.json / ablation.json), then collects
each axis' median summary, the improvement factors fair PID / compensated of the issue's
figures and the run time into ``build/results/demo_seeds.json``.  ``make demo`` runs one seed
(docs/demo.md); this is the three-seed run.  ``--quick`` passes ``--quick`` to the demo.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo.fileio import write_json_atomic  # noqa: E402

AXES = {"reference": "reference", "csf17_50": str(ROOT / "sim" / "axes" / "csf17_50.toml")}
SEEDS = "1,2,3"


def _unseen() -> Any:
    """The headline/target helpers of 27_unseen_axes.py (one definition)."""
    spec = importlib.util.spec_from_file_location("unseen_axes_results", Path(__file__).with_name("27_unseen_axes.py"))
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def main(argv: Optional[list[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", default=SEEDS)
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "build" / "results")
    a = ap.parse_args(argv)
    u = _unseen()
    doc: dict[str, Any] = {"seeds": a.seeds, "quick": a.quick, "axes": {}}
    rc_all = 0
    for name, axis in AXES.items():
        out = a.out / "demo_seeds" / name
        out.mkdir(parents=True, exist_ok=True)
        cmd = [str(ROOT / ".venv" / "bin" / "python"), "-m", "hdservo.cli", "demo", "--axis", axis,
               "--seeds", a.seeds, "--out-dir", str(out)] + (["--quick"] if a.quick else [])
        print(f"{name}: hdservo demo --seeds {a.seeds}", flush=True)
        t0 = time.monotonic()
        with open(out / "demo.log", "w") as log:
            rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
                                 env={**os.environ, "PYTHONPATH": str(ROOT / "host")})
        el = time.monotonic() - t0
        rc_all |= rc
        r: dict[str, Any] = {"demo_exit": rc, "run_time_s": el, "log": os.path.relpath(out / "demo.log", ROOT)}
        if (out / "summary.json").is_file():
            summ = json.loads((out / "summary.json").read_text())
            r["summary"] = summ
            r["headline"] = u.headline(summ)
            r["targets"] = u.targets(r["headline"], factor=1.0)
        doc["axes"][name] = r
        print(f"  exit {rc}, {el:.0f} s", flush=True)
    write_json_atomic(a.out / "demo_seeds.json", doc)
    print(f"wrote {a.out / 'demo_seeds.json'}")
    return 1 if rc_all else 0


if __name__ == "__main__":
    sys.exit(main())
