"""``hdservo emps``: the EMPS real-data benchmark.

``hdservo emps verify [--data DIR] [--format auto|csv|mat] [--json OUT]``
    Reproduce the published IDIM-LS results (symmetric and asymmetric friction,
    cross-test on the pulses record) and compare them with
    ``reference_results.csv``.  Exit 0 when every parameter is within 0.5 % and
    every relative error within 0.1 percentage point of the published value, 1
    otherwise (the JSON is written in both cases), 2 on bad input.

``hdservo emps export [--data DIR] [--record NAME] -o LOG.csv``
    Write a record as an hdservo log (CSV + ``.json`` sidecar, see docs/emps.md).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .. import emps

NAME = "emps"
HELP = "EMPS real-data benchmark: import, and reproduce the published IDIM-LS results"


def register(parser: argparse.ArgumentParser) -> None:
    """Add the ``verify`` and ``export`` actions."""
    sub = parser.add_subparsers(dest="emps_command", metavar="ACTION", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--data", metavar="DIR", default=None,
                        help=f"EMPS data directory (default ${emps.ENV_DATA_DIR}, "
                             "else the records shipped with hdservo)")
    common.add_argument("--format", choices=("auto", "csv", "mat"), default="auto",
                        help="read the CSV files or the original .mat files (default auto: CSV)")
    v = sub.add_parser("verify", parents=[common],
                       help="reproduce the published IDIM-LS results and compare")
    v.add_argument("--json", metavar="OUT", default=None, help="write the results as JSON here")
    e = sub.add_parser("export", parents=[common], help="write a record as an hdservo log")
    e.add_argument("--record", default=emps.TRAIN_RECORD,
                   choices=(emps.TRAIN_RECORD, emps.TEST_RECORD), help="which record")
    e.add_argument("-o", "--output", metavar="LOG.csv", required=True,
                   help="log CSV to write (sidecar <name>.json beside it)")


def run(args: argparse.Namespace) -> int:
    """Run the chosen action; see the module docstring for exit statuses."""
    data_dir = emps.resolve_data_dir(args.data)
    if args.emps_command == "export":
        rec = emps.load_benchmark_record(data_dir, args.record, args.format)
        out = Path(args.output)
        emps.write_log(rec, out)
        print(f"wrote {out} and {out.with_suffix('.json')} ({rec.meta['n_samples']} samples)")
        return 0
    report, rep = emps.verify(data_dir, args.format)
    for line in emps.summary_lines(report, rep):
        print(line)
    if args.json:
        emps.write_json(args.json, report)
        print(f"wrote {args.json}")
    dev = report.get("deviation")
    return 0 if dev is None or dev["within_tolerance"] else 1
