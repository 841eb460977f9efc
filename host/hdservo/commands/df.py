"""``hdservo df``: describing-function analysis of the axis's nonlinearities.

``hdservo df [--axis AXIS.toml] [--nonlinearity NAME ...] [--gains FILE.toml ...] [--set NAME=VALUE ...]
[--json OUT] [--out-dir DIR] [--format png|pdf]``

For each nonlinearity: N(A) table, predicted limit cycles (amplitude,
frequency, Loeb stability) and the margins / bandwidth of the equivalently
linearised loop against amplitude.  See docs/describing-functions.md.
Exit 0 on success, 2 on bad input (one line naming the file and key).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any, Dict

from ..errors import UserError
from . import progress_lines
from ..fileio import write_json_atomic

NAME = "df"
HELP = "describing-function analysis: N(A), limit cycles, margins against amplitude"


def register(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``hdservo df``."""
    from ..analysis.catalogue import NAMES
    parser.add_argument("--axis", metavar="AXIS.toml", default=None,
                        help="axis file (simulator format); default sim/axes/reference.toml, "
                             "else the built-in reference axis")
    parser.add_argument("--nonlinearity", metavar="NAME", nargs="+", default=None,
                        help=f"which ones (default all): {', '.join(NAMES)}")
    parser.add_argument("--gains", metavar="FILE.toml", nargs="+", action="extend", default=[],
                        help="gains TOML file(s) (a [gains] table or a model's [controller.gains])")
    parser.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                        help="override one of the drive's parameter-table gains (pos_kp, pos_ki, vel_kp, vel_ki, "
                             "...; repeatable, after the files)")
    parser.add_argument("--json", metavar="PATH", default=None, help="write the results as JSON here")
    parser.add_argument("--out-dir", metavar="DIR", default=None, help="write the plots into this directory")
    parser.add_argument("--plots", dest="out_dir", help=argparse.SUPPRESS)   # older spelling
    parser.add_argument("--format", choices=("png", "pdf"), default="png", help="plot format (default png)")


def write_json(path: Path, data: Dict[str, Any]) -> None:
    """Write strict JSON atomically (numpy and non-finite values handled), making the directory."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, data, indent=1)


def run(args: argparse.Namespace) -> int:
    """Run the analysis; see the module docstring."""
    from ..analysis.axis import AxisFileError, load_axis, load_gains
    from ..analysis.catalogue import NAMES, build
    from ..analysis.loop import LoopModel
    from ..analysis.report import analyse

    names = args.nonlinearity or list(NAMES)
    for n in names:
        if n not in NAMES:
            raise UserError(f"--nonlinearity {n}: unknown name (expected one of: {', '.join(NAMES)})")
    try:
        axis, notes = load_axis(Path(args.axis) if args.axis else None)
        gains, gnotes = load_gains([*args.gains, *args.set] or None)
        entries = [build(n, axis) for n in names]
    except AxisFileError as e:
        raise UserError(str(e)) from None
    except (KeyError, ValueError) as e:
        raise UserError(f"{args.axis or 'reference axis'}: {e}") from None
    say = progress_lines("df")
    for line in notes + gnotes:
        print(f"note: {line}")
    model = LoopModel(axis, gains)
    plot_dir = Path(args.out_dir) if args.out_dir else None
    results: Dict[str, Any] = {}
    for k, e in enumerate(entries):
        say(f"[{k + 1}/{len(entries)}] {e.name} ({e.insertion})")
        try:
            results[e.name] = analyse(e, model, plot_dir, args.format, say)
        except ValueError as err:
            raise UserError(f"{e.name}: {err}") from None
    for name, r in results.items():
        lcs = r["limit_cycles"]
        nom = r["linear_model_margins"]
        pms = [m["phase_margin_deg"] for m in r["margins_vs_amplitude"] if m.get("phase_margin_deg") is not None]
        lc_txt = "; ".join(f"A={c['amplitude']:.3g} {r['amplitude_unit']} at {c['frequency_Hz']:.3g} Hz "
                           f"({'stable' if c['stable'] else 'unstable'})" for c in lcs) or "none"
        pm_txt = f"PM {min(pms):.1f}..{max(pms):.1f} deg over A" if pms else "PM n/a"
        nom_pm = nom.get("phase_margin_deg")
        print(f"{name:15s} [{r['insertion']}] limit cycles: {lc_txt}; {pm_txt} "
              f"(linear model {nom_pm:.1f} deg)" if nom_pm is not None else
              f"{name:15s} [{r['insertion']}] limit cycles: {lc_txt}; {pm_txt}")
    if args.json:
        write_json(Path(args.json), {"axis_notes": notes, "gains_notes": gnotes, "gains": gains,
                                     "results": results})
        print(f"wrote {args.json}")
    if plot_dir is not None:
        print(f"wrote {3 * len(results)} plots to {plot_dir}")
    return 0
