"""``hdservo design SPEC.toml --json OUT.json --out-dir DIR``: requirements -> ranked axis designs.

See docs/design-flow.md.  Exit status 2 and one line on a bad SPEC.toml; no
output file is written unless the whole flow succeeded.
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from ..errors import UserError
from . import progress_lines

NAME = "design"
HELP = "design a harmonic-drive axis from requirements: feasible parts, simulated figures, ranking, report"


def register(p: argparse.ArgumentParser) -> None:
    p.add_argument("spec", type=Path, metavar="SPEC.toml", help="requirements file (docs/design-flow.md)")
    p.add_argument("--json", type=Path, metavar="OUT.json", help="write the design report as JSON")
    p.add_argument("--out-dir", type=Path, metavar="DIR", help="write report.md, PNG plots, axis_chosen.toml, "
                   "drive_params.json and the candidates' axis files here")
    p.add_argument("--report", type=Path, dest="out_dir", help=argparse.SUPPRESS)   # older spelling
    p.add_argument("--candidates", type=int, metavar="N", help="simulate the best N (default: SPEC [design])")
    p.add_argument("--quick", action="store_true", help="short simulations (smoke tests; not design figures)")
    p.add_argument("--feasibility-only", action="store_true", help="enumerate and check, no simulation")


def run(args: argparse.Namespace) -> int:
    from ..design import flow, report, spec as sp

    spec = sp.load_spec(args.spec)
    for out in (args.json, args.out_dir):
        if out is not None and not out.resolve().parent.is_dir():
            raise UserError(f"{out}: directory {out.resolve().parent} does not exist")
    if args.candidates is not None and not 1 <= args.candidates <= 20:
        raise UserError(f"--candidates: expected 1-20, got {args.candidates}")

    progress = progress_lines("design")

    with tempfile.TemporaryDirectory(prefix="hdservo-design-") as work:
        if args.feasibility_only:
            evals = flow.enumerate_candidates(spec)
            res = flow.FlowResult(spec, evals, [], None)
        else:
            res = flow.run_flow(spec, work, quick=args.quick, candidates=args.candidates, progress=progress)
        axis_files = {e.candidate.slug: Path(e.axis_path) for e in res.simulated if e.axis_path}
        doc = report.write_report(res, args.json, args.out_dir, axis_files)
    feas = doc["feasible"]
    print(f"{spec.name}: {feas} of {doc['enumerated']} gear x motor pairs feasible")
    for i, e in enumerate(res.simulated):
        h = flow.headline(e.sim)
        worst = min(e.margins, key=lambda k: e.margins[k])
        print(f"  {i + 1}. {e.candidate.name}: min rate {h['min_smooth_rate_deg_s']} deg/s, "
              f"A {h['positioning_accuracy_with_encoder_arcsec']:.3g}\", R {h['repeatability_arcsec']:.3g}\", "
              f"stab {h['stabilisation_rms_arcsec']:.3g}\" RMS, peak {h['peak_torque_Nm']:.3g} N.m, "
              f"f_res {h['resonance_Hz']:.1f} Hz; smallest margin {worst} {100 * e.margins[worst]:+.0f} %")
    if res.chosen:
        print(f"chosen: {res.chosen.candidate.name}")
    elif not args.feasibility_only:
        print("no feasible candidate")
        return 1
    return 0
