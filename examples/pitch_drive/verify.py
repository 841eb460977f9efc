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

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "host"))

from hdservo.design.verify import example_main  # noqa: E402

if __name__ == "__main__":
    sys.exit(example_main(HERE, description=__doc__ or ""))
