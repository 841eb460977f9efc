#!/usr/bin/env python3
"""Held-out errors of the structure relations (leave-one-size-out, leave-one-ratio-out).

Refits the stiffness (c_m, e0, g, f0; T1/T2 coefficients), hysteresis (loss fraction) and
friction (starting-torque scaling, backdriving factor) relations of hdservo.design.structure
with one catalogue size (or ratio) left out at a time and predicts the left-out rows
(hdservo.design.crossval).  Writes build/results/crossval.json and crossval.png (held-out
error per row and parameter against the targets).  About 30 s on one core.

Usage: tests/results/44_crossval.py [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo.design import catalogue as cat  # noqa: E402
from hdservo.design import crossval as cv  # noqa: E402


def plot(res: dict, path: Path) -> None:
    """One panel per relation/grouping: held-out error per row, target band shaded."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [k for k in res if res[k]["points"]]
    fig, axes = plt.subplots(len(keys), 1, figsize=(10, 2.6 * len(keys)), squeeze=False)
    for ax, k in zip(axes[:, 0], keys):
        pts = res[k]["points"]
        rows = list(dict.fromkeys(p["row"] for p in pts))
        pars = list(dict.fromkeys(p["parameter"] for p in pts))
        for j, par in enumerate(pars):
            xs = [rows.index(p["row"]) + 0.12 * (j - len(pars) / 2) for p in pts if p["parameter"] == par]
            ys = [100 * p["error"] for p in pts if p["parameter"] == par]
            ax.plot(xs, ys, "o", ms=4, label=f"{par} (target ±{100 * cv.TARGETS.get(par, 0):.0f} %)")
        tgt = max(cv.TARGETS.get(p, 0.0) for p in pars)
        ax.axhspan(-100 * tgt, 100 * tgt, color="0.9")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xticks(range(len(rows)))
        ax.set_xticklabels(rows, rotation=90, fontsize=6)
        ax.set_ylabel("held-out error %")
        ax.set_title(k, fontsize=9)
        ax.legend(fontsize=6, ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "build" / "results"))
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    res = cv.cross_validate(cat.load_gears())
    tmp = out / "crossval.json.tmp"
    tmp.write_text(json.dumps(res, indent=1))
    tmp.replace(out / "crossval.json")
    plot(res, out / "crossval.png")
    for k, v in res.items():
        for par, s in v["summary"].items():
            print(f"{k:22s} {par:18s} n={s['n']:2d} max|e|={100 * s['max_abs']:5.1f} % "
                  f"rms={100 * s['rms']:5.1f} % worst {s['worst_row']} "
                  f"within target {100 * s.get('within', float('nan')):.0f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
