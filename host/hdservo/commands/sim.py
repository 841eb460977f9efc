"""``hdservo sim SCENARIO.toml -o LOG.csv``: run a closed-loop scenario offline.

Runs the drive firmware against the simulated axis through the ctypes
binding (:mod:`hdservo.sim`) and writes the log (CSV + JSON sidecar,
the log format of docs/sim.md).  Same engine as ``hdservo-sim run``.  SCENARIO is a file or the name of a
shipped scenario (:func:`hdservo.resources.scenario_file`).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from ..errors import UserError
from .. import resources, sim

NAME = "sim"
HELP = "run a closed-loop simulation scenario and write its log (CSV + JSON sidecar)"


def _kv(text: str) -> tuple[str, float]:
    key, sep, val = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected SECTION.KEY=VALUE, found '{text}'")
    if val in ("true", "false"):
        return key, 1.0 if val == "true" else 0.0
    try:
        return key, float(val)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{key}: expected a number or true/false, found '{val}'") from None


def register(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", type=Path,
                   help="scenario TOML (see docs/sim.md), or the name of a shipped scenario (e.g. step)")
    p.add_argument("-o", "--output", type=Path, required=True, help="log CSV to write (sidecar .json beside it)")
    p.add_argument("--seed", type=int, help="noise seed (overrides the scenario)")
    p.add_argument("--duration", type=float, metavar="S", help="run length in s (overrides the scenario)")
    p.add_argument("--set", type=_kv, action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="plant parameter override (repeatable), e.g. friction_motor.enabled=false")
    p.add_argument("--json", type=Path, metavar="PATH", help="also write a run summary as JSON")


def run(args: argparse.Namespace) -> int:
    if not args.scenario.is_file():
        if args.scenario.parent != Path(".") or args.scenario.suffix == ".toml":
            raise UserError(f"{args.scenario}: scenario file not found")
        try:
            args.scenario = resources.scenario_file(str(args.scenario))
        except resources.ResourceError as e:
            raise UserError(f"{args.scenario}: not a file, and {e}") from None
    for out in (args.output, args.json):
        if out is not None:
            try:
                out.parent.mkdir(parents=True, exist_ok=True)
            except OSError as e:
                raise UserError(f"{out}: cannot create its directory {out.parent}: {e.strerror or e}") from None
    t0 = time.monotonic()
    res = sim.run_scenario(args.scenario, params=dict(args.set), seed=args.seed,
                           duration_s=args.duration, log_path=args.output)
    wall = time.monotonic() - t0
    n = len(res["t_s"])
    simulated = float(res.meta.get("duration_s", 0.0))
    faults = sorted({int(v) for v in res["fault_code"] if v != 0})
    summary = {
        "scenario": str(args.scenario), "log": str(args.output), "rows": n,
        "simulated_s": simulated, "wall_s": wall,
        "realtime_factor": simulated / wall if wall > 0 else None,
        "app_time_s": res.app_time_s, "plant_time_s": res.plant_time_s,
        "fault_codes": faults,
    }
    print(f"{args.scenario}: {simulated:g} s simulated in {wall:.3g} s, {n} rows -> {args.output}"
          + (f" (drive faults: {faults})" if faults else ""))
    if args.json:
        from ..fileio import write_json_atomic
        write_json_atomic(args.json, summary)
    return 0
