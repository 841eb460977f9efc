#!/usr/bin/env python3
"""Influence laws: elasticity of each servo figure to each nonlinearity parameter.

Every parameter of hdservo.design.influence.PARAMETERS (breakaway and Coulomb friction,
Stribeck velocity, K1/K2/K3, T1/T2, hysteresis width, TE amplitude) is scaled by 0.8 and 1.2
on the reference axis; the six figures are simulated (C simulator, two processes) and
predicted by the describing-function loop, and d ln(figure) / d ln(parameter) is formed by
central differences.  The same sweep runs on the held-out CSF-20-80 axis
(tests/results/axes/csf20_80.toml) to show which laws carry over.  Writes
build/results/influence.json and influence_<axis>.png (heat maps, simulation beside describing
function).  About 5 min on the 2 loaded cores.

The package's stored table (host/hdservo/data/influence.json, used by `hdservo design`)
is the reference axis's elasticity section; --store rewrites it.

Usage: tests/results/46_influence.py [--axis AXIS.toml ...] [--workers 2] [--out DIR] [--store]
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo.cli import UserError  # noqa: E402
from hdservo.design import influence as inf  # noqa: E402


def plot(res: dict, path: Path) -> None:
    """Two heat maps (simulation, describing function) of the elasticities."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    pars, figs = list(res["elasticity"]), res["figures"]
    fig, axes = plt.subplots(1, 2, figsize=(14, 6), constrained_layout=True)
    for ax, src in zip(axes, ("sim", "df")):
        m = np.array([[res["elasticity"][p][f][src] if res["elasticity"][p][f][src] is not None else np.nan
                       for f in figs] for p in pars], dtype=float)
        im = ax.imshow(np.clip(m, -2, 2), cmap="RdBu_r", vmin=-2, vmax=2, aspect="auto")
        for i in range(len(pars)):
            for j in range(len(figs)):
                ax.text(j, i, "-" if math.isnan(m[i, j]) else f"{m[i, j]:+.2f}", ha="center",
                        va="center", fontsize=7,
                        color="w" if not math.isnan(m[i, j]) and abs(m[i, j]) > 1.2 else "k")
        ax.set_xticks(range(len(figs)))
        ax.set_xticklabels(figs, rotation=30, ha="right", fontsize=8)
        ax.set_yticks(range(len(pars)))
        ax.set_yticklabels(pars if src == "sim" else [], fontsize=8)
        ax.set_title({"sim": "simulation", "df": "describing function"}[src]
                     + f": d ln(figure) / d ln(parameter), ±{100 * res['h']:.0f} %", fontsize=9)
    fig.colorbar(im, ax=axes, shrink=0.8)
    fig.suptitle(f"influence laws, axis {res['axis']}", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(res: dict) -> None:
    """Print the elasticities, simulation / describing function, and the agreement counts."""
    print(f"axis {res['axis']}: nominal " + ", ".join(f"{k} {v:.4g}" for k, v in res["nominal"].items()
                                                   if v is not None))
    print(f"{'parameter':18s} " + " ".join(f"{f[:14]:>15s}" for f in res["figures"]))
    for p, row in res["elasticity"].items():
        cells = []
        for f in res["figures"]:
            s, d = row[f]["sim"], row[f]["df"]
            cells.append(f"{'-' if s is None else f'{s:+.2f}':>7s}/{'-' if d is None else f'{d:+.2f}':<7s}")
        print(f"{p:18s} " + " ".join(cells))
    cnt: dict = {}
    for row in res["elasticity"].values():
        for f, c in row.items():
            cnt.setdefault(f, {}).setdefault(c["agreement"], 0)
            cnt[f][c["agreement"]] += 1
    for f, c in cnt.items():
        print(f"DF vs simulation, {f}: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--axis", action="append",
                    help="axis TOML (repeatable; default the reference axis and the held-out CSF-20-80 axis)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "build" / "results"))
    ap.add_argument("--store", action="store_true",
                    help="also rewrite the package's influence table from the first axis")
    a = ap.parse_args()
    axes = a.axis or [str(ROOT / "sim" / "axes" / "reference.toml"),
                      str(ROOT / "tests" / "results" / "axes" / "csf20_80.toml")]
    out = Path(a.out)
    results = []
    for axis in axes:
        try:
            res = inf.sweep(axis, workers=a.workers, progress=lambda s: print(s, file=sys.stderr))
        except UserError as e:
            print(f"46_influence: {e}", file=sys.stderr)
            return 2
        res["axis"] = Path(axis).name
        results.append(res)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / "influence.json.tmp"
    tmp.write_text(json.dumps({"axes": results}, indent=1))
    tmp.replace(out / "influence.json")
    for res in results:
        plot(res, out / f"influence_{Path(res['axis']).stem}.png")
        table(res)
    if a.store:
        keep = {k: results[0][k] for k in ("axis", "h", "seed", "parameters", "figures", "nominal", "elasticity")}
        t2 = inf.TABLE_FILE.with_suffix(".json.tmp")
        t2.write_text(json.dumps(keep, indent=1) + "\n")
        t2.replace(inf.TABLE_FILE)
    return 0


if __name__ == "__main__":
    sys.exit(main())
