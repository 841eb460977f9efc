#!/usr/bin/env python3
"""Preisach online-recursive vs brute-force cost on the Cortex-M4.

Reads ``build/bench/cm4_cost.json`` (written by ``10_cm4_cost.sh``; format
``{"kernels": {name: {"instructions": N}}}``) and writes
``build/bench/preisach_ratio.json`` with, for L = 32 and 64, the instructions of
one online step, one brute-force relay-plane step (same table, same integers,
L(L-1)/2 relays) and their ratio.  Never fails on the numbers; exits 1 only if
the input is missing or malformed.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo.fileio import write_json_atomic  # noqa: E402

SRC = ROOT / "build" / "bench" / "cm4_cost.json"
DST = ROOT / "build" / "bench" / "preisach_ratio.json"


def main() -> int:
    """Compute the ratios; returns the process exit code."""
    try:
        kernels = json.loads(SRC.read_text())["kernels"]
    except (OSError, ValueError, KeyError) as exc:
        print(f"{SRC}: cannot read kernel costs ({exc}); run tests/bench/10_cm4_cost.sh first")
        return 1
    out: dict[str, dict[str, float]] = {}
    for levels in (32, 64):
        try:
            on = float(kernels[f"preisach_online_L{levels}"]["instructions"])
            bf = float(kernels[f"preisach_bruteforce_L{levels}"]["instructions"])
        except (KeyError, TypeError) as exc:
            print(f"{SRC}: missing Preisach kernel cost ({exc})")
            return 1
        out[f"L{levels}"] = {"online_instructions": on, "bruteforce_instructions": bf,
                             "relays": levels * (levels - 1) // 2,
                             "ratio_bruteforce_over_online": bf / on if on > 0 else float("nan")}
        print(f"preisach L={levels}: online {on:.0f} instr/step, brute force {bf:.0f} "
              f"instr/step, ratio {bf / on:.0f}x")
    write_json_atomic(DST, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
