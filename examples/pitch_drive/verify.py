#!/usr/bin/env python3
"""Prediction vs measurement for the pitch-drive design (docs/design-flow.md section 6).

Serves the axis the flow chose (report/axis_chosen.toml) as a virtual drive, identifies it
over CAN (`hdservo identify all --axis ...`), downloads the identified compensator
parameters (the `hdservo download` code, read back) into each procedure's drive together
with the flow's gains, runs the test procedures (`hdservo test` code; stabilisation in
the drive's STAB mode) and compares every predicted figure with the measured one
(pass at 20 %).  Writes verify/{model.toml, verify.json, verify.md} beside this file.

    .venv/bin/python examples/pitch_drive/verify.py            # about 5 min on 2 loaded cores
    .venv/bin/python examples/pitch_drive/verify.py --procedures peak-torque,stabilisation
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "host"))

from hdservo.design import verify as vf  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--procedures", default="min-rate,positioning,stabilisation,peak-torque,bandwidth")
    p.add_argument("--identify", default="all", help="hdservo identify target (default all)")
    p.add_argument("--out", type=Path, default=HERE / "verify")
    p.add_argument("--tolerance", type=float, default=0.2)
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args()
    plan = vf.Plan(axis=HERE / "report" / "axis_chosen.toml", design=HERE / "design.json", out=a.out,
                   procedures=[x for x in a.procedures.split(",") if x], identify_target=a.identify,
                   tolerance=a.tolerance, seed=a.seed)
    res = vf.verify(plan)
    print(vf.markdown(res))
    return 0 if res["passed"] == res["judged"] else 1


if __name__ == "__main__":
    sys.exit(main())
