"""Fault-injection table: scenarios with injected faults, the reaction the drive
must show, and the reaction observed on the simulator.

Each closed-loop case is a scenario (TOML, run by ``build/bin/hdservo-faults``,
the same firmware and plant as ``hdservo-sim``) with ``[[fault]]`` entries
(docs/sim.md).  For each case the table states the expected fault code of the
application (``hd_fault_t`` in firmware/app/hd_app.h) and its EMCY code (the
CiA 402 mapping of firmware/canopen/hd_app_co.c), the largest output motion allowed
while the fault is latched, and that the runner's fault reset (at
``reset_at_s``, after the injected condition is gone) brings the drive back:
no fault latched again, the position loop holding.

The parameter-store cases (corruption at boot, power loss in the middle of a
save) run on the host port's flash-semantics NVM (``hdservo-faults nvm``).

The CAN-side cases (host heartbeat loss, error bursts to error passive and to
bus-off with recovery, bus-off with the quick-stop option, frame loss with SDO
traffic and a host tool, bus-off and power loss in the middle of a table
download) run on the virtual drive over CAN: :mod:`hdservo.faults_can`.

``build_table(root)`` returns the table; ``main()`` writes
``build/results/faults.json`` (temp file + rename) and prints a summary.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from hdservo.fw_const import FAULT_EMCY, FAULT_NAMES, PSTORE_STATUS
from hdservo.tomltext import basic_string

#: fault names, EMCY codes and store states of the firmware (generated from the C headers)
EMCY = {0: None, **{code: f"0x{emcy:04x}" for code, emcy in FAULT_EMCY.items()}}
PSTORE = PSTORE_STATUS

_HOLD = """[scenario]
name = "{name}"
axis = "reference"
duration_s = {duration}
seed = 5
[controller]
mode = "{mode}"
[setpoint]
type = "constant"
initial_{unit} = 0.0
[plant]
gravity.enabled = false
"""

# name, [[fault]] entries, expected fault codes (any of), max motion while
# faulted (rad at the output; None where an external load larger than the
# drive can hold keeps acting after the power stage is off: the model has no
# holding brake, so the motion is the load's, reported but not limited),
# reset time, duration; "mode": "velocity" for the cases where the load
# moved the axis far while the power stage was off: re-enabling a position
# hold would (correctly) trip the following-error check against the old
# reference, a velocity hold shows the recovery itself; their travel limits
# are opened to +-5 turns so that the over-travel check (correctly) does not
# keep the drive off after the load has pushed the axis 0.6 turn away.
CASES = [
    {"name": "output encoder jump (glitch 50000 counts, 1.07 deg)",
     "faults": [{"t_s": 0.1, "type": "encoder_glitch", "encoder": "load", "counts": 50000}],
     "expect": [5], "max_motion_rad": math.radians(0.5), "reset_at_s": 0.3, "duration": 0.6},
    {"name": "output encoder dropout 20 ms",
     "faults": [{"t_s": 0.1, "type": "encoder_dropout", "encoder": "load", "duration_s": 0.02}],
     "expect": [6], "max_motion_rad": math.radians(0.5), "reset_at_s": 0.3, "duration": 0.6},
    {"name": "motor encoder dropout 20 ms",
     "faults": [{"t_s": 0.1, "type": "encoder_dropout", "encoder": "motor", "duration_s": 0.02}],
     "expect": [6], "max_motion_rad": math.radians(0.5), "reset_at_s": 0.3, "duration": 0.6},
    {"name": "motor encoder glitch 2000 counts (no output-encoder fault expected, bounded disturbance)",
     "faults": [{"t_s": 0.1, "type": "encoder_glitch", "encoder": "motor", "counts": 2000}],
     "expect": [0], "max_motion_rad": math.radians(0.05), "reset_at_s": 0.3, "duration": 0.6},
    {"name": "current saturation: 0.5 A clamp against a 40 N.m load step",
     "faults": [{"t_s": 0.05, "type": "current_limit", "limit_A": 0.5},
                {"t_s": 0.1, "type": "load_step", "torque_Nm": 40.0},
                {"t_s": 0.8, "type": "load_step", "torque_Nm": 0.0},
                {"t_s": 0.8, "type": "current_limit", "limit_A": -1.0}],
     "expect": [1, 2], "max_motion_rad": None, "reset_at_s": 1.4, "duration": 1.8,
     "mode": "velocity", "gains": {"travel_min": -5.0, "travel_max": 5.0}},
    {"name": "load-torque shock 20 N.m (within the torque limit: no fault)",
     "faults": [{"t_s": 0.1, "type": "load_step", "torque_Nm": 20.0}],
     "expect": [0], "max_motion_rad": 0.0, "reset_at_s": 0.5, "duration": 0.6},
    {"name": "load-torque shock 150 N.m (beyond the torque limit)",
     "faults": [{"t_s": 0.1, "type": "load_step", "torque_Nm": 150.0},
                {"t_s": 0.7, "type": "load_step", "torque_Nm": 0.0}],
     "expect": [1, 4, 2], "max_motion_rad": None, "reset_at_s": 1.4, "duration": 1.8,
     "mode": "velocity", "gains": {"travel_min": -5.0, "travel_max": 5.0}},
]

#: fault scenarios without a row of their own (empty: every one is covered)
NOT_COVERED: list[dict[str, str]] = []


def _toml(case: dict) -> str:
    mode = case.get("mode", "position")
    text = _HOLD.format(name="fault", duration=case["duration"], mode=mode,
                        unit="rad" if mode == "position" else "rad_s")
    if case.get("gains"):
        text += "[controller.gains]\n" + "".join(f"{k} = {v}\n" for k, v in case["gains"].items())
    for f in case["faults"]:
        text += "[[fault]]\n" + "".join(
            f"{k} = {basic_string(v)}\n" if isinstance(v, str) else f"{k} = {v}\n" for k, v in f.items())
    return text


def _runner(root: Path) -> Path:
    b = root / "build" / "bin" / "hdservo-faults"
    if not b.exists():
        raise FileNotFoundError(f"{b}: not built (make build-tests)")
    return b


def run_case(root: Path, case: dict) -> dict:
    with tempfile.TemporaryDirectory() as d:
        sc = Path(d) / "fault.toml"
        sc.write_text(_toml(case))
        p = subprocess.run([str(_runner(root)), "run", str(sc), str(case["reset_at_s"])],
                           capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        raise RuntimeError(f"hdservo-faults run failed: {p.stderr.strip()}")
    obs = json.loads(p.stdout)
    code = obs["first_fault"]
    faulted = code != 0
    checks = {
        "fault code": code in case["expect"],
        "power stage off while faulted": obs["torque_off_while_faulted"] or not faulted,
        "motion while faulted within limit": (case["max_motion_rad"] is None or not faulted
                                              or obs["max_motion_while_faulted_rad"] <= case["max_motion_rad"]),
        "recovered by fault reset": (obs["fault_after_reset"] == 0 and obs["fault_at_end"] == 0
                                     and obs["set_mode_after_reset"] == 0
                                     and obs["mode_at_end"] == (3 if case.get("mode", "position") == "position" else 2)),
    }
    return {
        "scenario": case["name"],
        "injected": case["faults"],
        "expected": {"fault": [FAULT_NAMES[c] for c in case["expect"]],
                     "emcy": [EMCY[c] for c in case["expect"]],
                     "state": "FAULT (power stage off) until fault reset" if case["expect"] != [0] else "no fault",
                     "max_motion_while_faulted_rad": case["max_motion_rad"]},
        "observed": {"fault": FAULT_NAMES.get(code, str(code)), "emcy": EMCY.get(code), **obs},
        "checks": checks,
        "pass": all(checks.values()),
    }


def run_nvm(root: Path) -> list[dict]:
    p = subprocess.run([str(_runner(root)), "nvm"], capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        raise RuntimeError(f"hdservo-faults nvm failed: {p.stderr.strip()}")
    expect = {
        "blank NVM at boot": {"status": 1, "values": "defaults"},
        "two saves, boot": {"status": 0, "values": "new"},
        "newest slot one bit flipped": {"status": 0, "values": "old"},
        "both slots corrupt": {"status": 2, "values": "defaults"},
        "newest slot out-of-range value, CRC good": {"status": 0, "values": "old"},
        "other parameter-table version": {"status": 3, "values": "defaults"},
        "save again after the interrupted save": {"status": 0, "values": "new"},
    }
    rows = []
    for r in json.loads(p.stdout):
        name = r.pop("case")
        if name == "power loss during save":
            ok = r["boots_with_other"] == 0 and r["boots_with_old_set"] + r["boots_with_new_set"] == r["cut_points"]
            exp = {"values": "old or new set, never mixed or defaults"}
        else:
            exp = expect[name]
            ok = r.get("status") == exp["status"] and r.get("values") == exp["values"]
            exp = {"status": PSTORE[exp["status"]], "values": exp["values"]}
            r["status"] = PSTORE.get(r.get("status"), r.get("status"))
        rows.append({"scenario": f"parameter store: {name}", "expected": exp, "observed": r, "pass": ok})
    return rows


def build_table(root: Path) -> dict:
    from oracles.faults_can import run_can_cases
    rows = [run_case(root, c) for c in CASES] + run_nvm(root) + run_can_cases(root)
    return {"cases": rows, "not_covered": NOT_COVERED,
            "passed": sum(r["pass"] for r in rows), "failed": sum(not r["pass"] for r in rows)}


def main(argv: list[str] | None = None) -> int:
    root = Path(__file__).resolve().parents[3]
    out = root / "build" / "results" / "faults.json"
    table = build_table(root)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(table, f, indent=1)
    os.replace(tmp, out)
    for r in table["cases"]:
        if "checks" in r and "fault" not in r["expected"]:      # CAN-side rows: the checks say it
            bad = [k for k, v in r["checks"].items() if not v]
            print(f"{'ok  ' if r['pass'] else 'FAIL'} {r['scenario']}: "
                  + (f"{len(r['checks'])} checks" if not bad else "failed: " + "; ".join(bad)))
            continue
        exp = r["expected"].get("fault", r["expected"].get("values"))
        obs = r["observed"].get("fault", r["observed"].get("values", ""))
        print(f"{'ok  ' if r['pass'] else 'FAIL'} {r['scenario']}: expected {exp}, observed {obs}")
    for r in table["not_covered"]:
        print(f"--   {r['scenario']}: not covered ({r['why']})")
    print(f"faults: {table['passed']} passed, {table['failed']} failed -> {out.relative_to(root)}")
    return 0 if table["failed"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
