"""``hdservo report``: one self-contained HTML report from the JSON and plots of compare / test / identify.

``hdservo report build/compare/compare.json -o build/report.html`` (plus
``--identify IDENT.json``, ``--download DOWNLOAD.json``), or
``hdservo report --test RESULT.json --test-plots DIR -o report.html`` for a single
``hdservo test`` run.  Every plot is embedded as a base64 PNG (no external
files); a missing or blank plot is an error.  See :mod:`hdservo.report`.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import UserError

NAME = "report"
HELP = "assemble one self-contained HTML report (tables and every plot) from compare/test/identify JSON"


def register(p: argparse.ArgumentParser) -> None:
    """Options of ``hdservo report``."""
    p.add_argument("compare", type=Path, nargs="?", metavar="COMPARE.json",
                   help="hdservo compare output (OUT/compare.json)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="REPORT.html", help="the HTML file to write")
    p.add_argument("--test", type=Path, action="append", default=[], metavar="RESULT.json",
                   help="an 'hdservo test --json' result (repeatable)")
    p.add_argument("--test-plots", type=Path, action="append", default=[], metavar="DIR",
                   help="plot directory of the matching --test, i.e. its 'hdservo test --out-dir' "
                        "(repeatable, same order)")
    p.add_argument("--plots", dest="test_plots", type=Path, action="append", help=argparse.SUPPRESS)  # older spelling
    p.add_argument("--identify", type=Path, metavar="IDENT.json", help="'hdservo identify --json' report")
    p.add_argument("--download", type=Path, metavar="DOWNLOAD.json", help="'hdservo download --json' record")
    p.add_argument("--title", default="hdservo: harmonic-drive axis, PID baseline vs compensation")


def run(args: argparse.Namespace) -> int:
    """Build the report; one error line on bad input (nothing written)."""
    from ..report import ReportError, build_report
    if args.output.is_dir():
        raise UserError(f"-o {args.output}: is a directory")
    if len(args.test_plots) > len(args.test):
        raise UserError("--test-plots: one per --test")
    try:
        info = build_report(args.output, compare=args.compare, tests=args.test, test_plots=args.test_plots,
                            identify=args.identify, download=args.download, title=args.title)
    except ReportError as e:
        raise UserError(str(e)) from None
    print(f"wrote {info['path']} ({info['bytes'] / 1e6:.2f} MB, {len(info['plots'])} plots embedded)")
    return 0
