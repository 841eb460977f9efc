#!/usr/bin/env python3
"""Prediction vs measurement for the pitch-drive design (docs/design-flow.md section 6).

Serves the axis the flow chose (report/axis_chosen.toml) as a virtual drive, identifies it
over CAN (`hdservo identify all --sim ...`), downloads the identified compensator
parameters (the `hdservo download` code, read back) into each procedure's drive together
with the flow's gains, runs the test procedures (`hdservo test` code; stabilisation in
the drive's STAB mode) and compares every predicted figure with the measured one
(pass at 20 %; the positioning and the stabilisation predicted and measured by the same
procedure in lock-step with the same sensor seed).  Writes verify/{model.toml, verify.json,
verify.md} beside this file.

    .venv/bin/python examples/pitch_drive/verify.py            # about 5 min on 2 loaded cores
    .venv/bin/python examples/pitch_drive/verify.py --procedures peak-torque,stabilisation
    .venv/bin/python examples/pitch_drive/verify.py --option flow   # the other controller option -> verify_flow/
    .venv/bin/python examples/pitch_drive/verify.py --scatter-seeds 2,3   # positioning per seed, A/R on the median
    .venv/bin/python examples/pitch_drive/verify.py --annotate --note "..."   # explain a finished run's figures
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "host"))

from hdservo.design import verify as vf  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--procedures", default="min-rate,positioning,stabilisation,peak-torque,bandwidth")
    p.add_argument("--identify", default="all", help="hdservo identify target (default all)")
    p.add_argument("--option", default=None,
                   help="controller option of the chosen design to verify (flow, best; default: the one the flow kept)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default verify/, or verify_OPTION/)")
    p.add_argument("--note", action="append", default=None,
                   help="with --annotate: a note for verify.md (repeatable)")
    p.add_argument("--annotate", action="store_true",
                   help="measure nothing: set the notes (--note) of the finished run in the output directory "
                        "and render its verify.md again")
    p.add_argument("--tolerance", type=float, default=0.2)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--scatter-seeds", default="",
                   help="further sensor-noise seeds for the positioning, e.g. 2,3: predicted and measured per seed "
                        "(lock-step), A and R judged on the median over the seeds; the seed band is reported")
    a = p.parse_args()
    out = a.out or (HERE / ("verify" if a.option is None else f"verify_{a.option}"))
    if a.annotate:
        if not (out / "verify.json").is_file():
            print(f"verify.py: --annotate: no finished run in {out} (verify.json missing)", file=sys.stderr)
            return 2
        res = vf.annotate(out, a.note or [])
        print(vf.markdown(res))
        return 0
    try:
        seeds = [int(x) for x in a.scatter_seeds.split(",") if x.strip()]
    except ValueError:
        print(f"verify.py: --scatter-seeds: expected comma-separated integers, got '{a.scatter_seeds}'",
              file=sys.stderr)
        return 2
    if a.seed in seeds:
        print(f"verify.py: --scatter-seeds: seed {a.seed} is the base run (--seed); give the others", file=sys.stderr)
        return 2
    plan = vf.Plan(axis=HERE / "report" / "axis_chosen.toml", design=HERE / "design.json", out=out,
                   procedures=[x for x in a.procedures.split(",") if x], identify_target=a.identify,
                   tolerance=a.tolerance, seed=a.seed, option=a.option, scatter_seeds=seeds)
    try:
        vf.select_option(json.loads(plan.design.read_text()), a.option)
    except ValueError as e:
        print(f"verify.py: --option {e}", file=sys.stderr)
        return 2
    res = vf.verify(plan)
    print(vf.markdown(res))
    return 0 if res["passed"] == res["judged"] else 1


if __name__ == "__main__":
    sys.exit(main())
