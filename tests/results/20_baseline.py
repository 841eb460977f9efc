#!/usr/bin/env python3
"""Closed-loop PID baseline in the simulator (issue 4, "proof", closed-loop part).

Runs the standard cases of hdservo.closedloop_cases (steps, 1 deg/s ramp, constant-rate
tracking at 0.001 / 0.01 / 0.1 deg/s, 1 deg 0.1 Hz reversals, 12 point-to-point
moves) on the reference axis and on the CSF-17-50 class axis, every plant
effect of the axis files on, PID baseline gains; repeats the tracking and
reversal cases with the base rocking off (the stabilisation disturbance, which
dominates the slow-rate error and no friction/hysteresis compensator removes).

Writes build/results/baseline.json and build/results/baseline_<axis>_*.png.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo import closedloop_cases as bl  # noqa: E402
from hdservo import sim  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402

OUT = ROOT / "build" / "results"
SEED = 1


def _write_json(path: Path, obj: object) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, obj, indent=1)


def _n(x: float | None, fmt: str = ".3g") -> str:
    return "n/a" if x is None else format(x, fmt)


def main() -> int:
    t_start = time.perf_counter()
    cases = bl.standard_cases()
    no_base_cases = [c for c in cases if c.kind in ("tracking", "reversal") and c.name != "ramp_1degps"]
    result: dict[str, object] = {
        "description": "PID baseline, every plant effect of the axis file on; error = setpoint - true output "
                       "angle, arcsec; see docs/control.md 'Closed-loop baseline in the simulator'",
        "seed": SEED,
        "cases": {c.name: {"kind": c.kind, "setpoint": c.setpoint, "duration_s": c.duration_s,
                           "skip_s": c.skip_s, "log_decimation": c.log_decimation} for c in cases},
    }
    for axis in bl.AXES:
        def prog(name: str, axis: str = axis) -> None:
            print(f"  {axis}: {name} ({time.perf_counter() - t_start:.0f} s)", flush=True)

        figs, runs = bl.run_cases(axis=axis, cases=cases, seed=SEED, progress=prog)
        nb, _ = bl.run_cases(axis=axis, cases=no_base_cases, seed=SEED, effects={"base": False}, progress=prog)
        figs["tracking_no_base"] = nb["tracking"]
        figs["reversal_no_base"] = nb["reversal"]
        spec = bl.AXES[axis]
        figs["effects"] = {e: bool(sim.axis_param(sim.effect_key(e), spec if spec == "reference"
                                                  else str(ROOT / spec))) for e in sim.effect_names()}
        files = bl.plot_axis(axis, runs, OUT)
        figs["plots"] = [str(p.relative_to(ROOT)) for p in files]
        result[axis] = figs

    _write_json(OUT / "baseline.json", result)

    for axis in bl.AXES:
        f = result[axis]
        assert isinstance(f, dict)
        print(f"\n{axis}: PID baseline (all effects on), arcsec at the output")
        for k in ("step_100arcsec", "step_1deg"):
            s = f[k]
            print(f"  {k:15s} rise {_n(s['rise_time_s'])} s, overshoot {s['overshoot_pct']:.2f} %, "
                  f"ts(10\") {_n(s['settling_time_s_10arcsec'])} s, ts(2\") {_n(s['settling_time_s_2arcsec'])} s, "
                  f"final {s['final_error_arcsec']:+.2f}")
        r = f["ramp_1degps"]
        print(f"  ramp 1 deg/s    RMS {r['rms_arcsec']:.3g}, max {r['max_arcsec']:.3g}")
        for v, tr in f["tracking"].items():
            nb = f["tracking_no_base"][v]
            print(f"  {v:>6s} deg/s    RMS {tr['rms_arcsec']:.3g}, max {tr['max_arcsec']:.3g}, "
                  f"rate dev {tr['rate_rms_dev_pct']:.3g} % RMS, start peak {tr['start_peak_arcsec']:.3g} | "
                  f"no base: RMS {nb['rms_arcsec']:.3g}, max {nb['max_arcsec']:.3g}, "
                  f"rate dev {nb['rate_rms_dev_pct']:.3g} %")
        rv = f["reversal"]
        print(f"  reversal        peak {rv['peak_arcsec']:.3g} (no base {f['reversal_no_base']['peak_arcsec']:.3g})")
        p = f["ptp_12"]
        print(f"  12 moves        max |final| {p['max_abs_final_error_arcsec']:.3g}, "
              f"RMS {p['rms_final_error_arcsec']:.3g}")
        print(f"  faults          {f['faults']}")
    print(f"\nwrote {(OUT / 'baseline.json').relative_to(ROOT)} ({time.perf_counter() - t_start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
