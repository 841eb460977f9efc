#!/usr/bin/env python3
"""Wall time of the full identification on the simulator (reference axis) and of each step.

Simulated experiment time vs wall time per experiment, and the fit times, side by
side in one run.  Writes build/bench/identification.json.  Never fails on time.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo.ident import experiments as ex  # noqa: E402
from hdservo.ident import pipeline  # noqa: E402
from hdservo.fileio import write_json_atomic as write_json  # noqa: E402


def main() -> int:
    runner = ex.SimRunner(axis="reference", seed=1)
    pl = pipeline.Pipeline(runner=runner)
    t0 = time.perf_counter()
    pl.run("all")
    wall = time.perf_counter() - t0
    simulated = {}
    for kind, d in pl.data.items():
        simulated[kind] = sum(float(s.get("settle_s", 0.0)) + float(s.get("window_s", 0.0)) if "window_s" in s
                              else float(s.get("duration_s", 0.0)) for s in d.segments)
        if kind in ("locked_cycle", "forc", "minor_loops"):
            simulated[kind] = float(len(d["t_s"]) * d.meta["sample_period_s"])
    runs = {k[4:-2]: v for k, v in pl.timings.items() if k.startswith("run_")}
    fits = {k[4:-2]: v for k, v in pl.timings.items() if k.startswith("fit_")}
    out = {"axis": "reference", "wall_total_s": wall, "run_wall_s": runs, "fit_wall_s": fits,
           "simulated_s": simulated,
           "realtime_factor": {k: simulated[k] / runs[k] for k in runs if runs[k] > 0 and k in simulated},
           "share_running_experiments": sum(runs.values()) / wall,
           "note": "wall clock on a shared machine; compare the split, not absolute values"}
    path = ROOT / "build" / "bench" / "identification.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, out)
    print(f"identification (reference axis): {wall:.1f} s wall, experiments {sum(runs.values()):.1f} s "
          f"(simulated {sum(simulated.values()):.0f} s), fits {sum(fits.values()):.2f} s -> "
          f"{path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
