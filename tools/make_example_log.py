#!/usr/bin/env python3
"""Write the example log shipped with the package (host/hdservo/data/examples/).

A closed-loop run of the simulated reference axis (every plant effect on, seed 1): the
drive's position loop follows a slow chirp of 0.9 rad with its velocity limit at 0.5 rad/s,
logged at 1 kHz for 2 s.  The log keeps the four columns the model-discrepancy workflow
reads (``t_s``, ``motor_angle_rad``, ``load_angle_rad``, ``motor_torque_Nm`` = Kt x the
measured current), rounded to 1 nrad and 0.1 uN.m so that the file stays below 100 kB.

Run from the checkout after ``make sim``::

    .venv/bin/python tools/make_example_log.py [--out OTHER.csv]
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from hdservo import logio, sim

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "host" / "hdservo" / "data" / "examples" / "chirp_reference.csv"

DURATION_S = 2.0
LOG_DECIMATION = 10           # 10 kHz loop -> 1 kHz log
AMPLITUDE_RAD = 0.9
F0_HZ = 0.04
PEAK_SPEED_RAD_S = 2.5
VEL_LIMIT_RAD_S = 0.5

SCENARIO = f"""[scenario]
name = "chirp_reference"
axis = "reference"
duration_s = {DURATION_S}
seed = 1
log_decimation = {LOG_DECIMATION}

[controller]
mode = "position"

[controller.gains]
follow_err_max = 0.2
vel_trip = 0.48
pos_vlim = {VEL_LIMIT_RAD_S / (2 * math.pi):.6g}

[setpoint]
type = "chirp"
amplitude_rad = {AMPLITUDE_RAD}
f0_Hz = {F0_HZ}
f1_Hz = {PEAK_SPEED_RAD_S / (2 * math.pi * AMPLITUDE_RAD):.6g}
t0_s = 0.05
t1_s = {DURATION_S}
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT, help="log CSV to write (default: the shipped example)")
    out = ap.parse_args(argv).out
    with tempfile.TemporaryDirectory() as td:
        scenario = Path(td) / "chirp_reference.toml"
        scenario.write_text(SCENARIO)
        res = sim.run_scenario(scenario)
    cols = res.columns
    meta = dict(res.meta)
    meta.pop("columns", None)
    meta["scenario"] = "chirp_reference (tools/make_example_log.py)"
    kt = sim.axis_param("motor.kt_Nm_per_A")
    out.parent.mkdir(parents=True, exist_ok=True)
    logio.write_log(out, {"t_s": cols["t_s"],
                          "motor_angle_rad": np.round(cols["motor_angle_rad"], 9),
                          "load_angle_rad": np.round(cols["load_angle_rad"], 9),
                          "motor_torque_Nm": np.round(kt * cols["motor_current_A"], 7)}, meta)
    print(f"wrote {out} ({len(cols['t_s'])} rows, {out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
