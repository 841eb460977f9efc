"""The comparison's drive torque limit from the axis (closedloop_cases.axis_torque_limit)."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from hdservo import axisgen as ag
from hdservo import closedloop_cases as bl
from hdservo import compare as cmp
from hdservo.params_gen import BY_NAME

ROOT = Path(__file__).resolve().parents[2]
#: the drawn CSF-40-120 whose breakaway friction + unbalance exceeds the parameter's default 60 N.m
SEED_71 = 71


@pytest.fixture(scope="module")
def axis71(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, ag.GeneratedAxis]:
    d = tmp_path_factory.mktemp("axis71")
    (path,) = ag.write_axes(d, 1, seed=SEED_71)
    (ax,) = ag.random_axes(1, seed=SEED_71)
    return str(path), ax


def test_rule_from_motor_and_gear() -> None:
    default = BY_NAME["torque_limit"].default
    # motor reach below 1.3 T2: the motor's reach; 1.3 T2 below it: the gear's torque
    assert bl.axis_torque_limit(120, 0.1, 20.0, 200.0) == pytest.approx(240.0)
    assert bl.axis_torque_limit(120, 0.2, 20.0, 100.0) == pytest.approx(130.0)
    # both below the default: the default (a small gear keeps the drive's default)
    assert bl.axis_torque_limit(50, 0.05, 20.0, 12.0) == default
    # never beyond the parameter's range
    assert bl.axis_torque_limit(160, 1.0, 20.0, 5000.0) == BY_NAME["torque_limit"].max
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="expected a finite number > 0"):
            bl.axis_torque_limit(100, bad, 20.0, 48.0)


def test_seed71_axis_gets_the_torque_it_needs(axis71: tuple[str, ag.GeneratedAxis]) -> None:
    path, ax = axis71
    p = ax.params
    assert (ax.size, ax.ratio) == (40, 120)
    n, kt, ipk = p["gear"]["ratio"], p["motor"]["kt_Nm_per_A"], p["current_loop"]["peak_A"]
    t2 = p["stiffness"]["t2_Nm"]
    want = min(n * kt * ipk, 1.3 * t2)
    g = bl.axis_controller(path)["gains"]
    assert g["torque_limit"] == pytest.approx(want, rel=1e-6)
    # it covers what the axis needs to move: breakaway friction of both sides + unbalance, with margin
    need = n * p["friction_motor"]["fs_pos_Nm"] + p["friction_load"]["fs_pos_Nm"] + p["gravity"]["mgl_Nm"]
    assert g["torque_limit"] > 2.0 * need > BY_NAME["torque_limit"].default
    # every row of a comparison runs with it: the fair PID and the compensated rows alike
    rows = [cmp.fair_row([], axis=path), cmp.fair_row(["stribeck"], axis=path),
            *cmp.controllers_from_names(["pid", "best"], path)]
    assert {r.gains["torque_limit"] for r in rows} == {g["torque_limit"]}


def test_shipped_axes_keep_the_default_limit() -> None:
    default = BY_NAME["torque_limit"].default
    assert default == 60.0
    assert bl.axis_controller("reference")["gains"] == "defaults"
    assert bl.axis_controller("csf17_50")["gains"]["torque_limit"] == default
    assert cmp.design_gains(str(ROOT / "sim" / "axes" / "csf17_50.toml"))["torque_limit"] == default


def test_seed71_comparison_procedure_runs_without_fault(axis71: tuple[str, ag.GeneratedAxis],
                                                        tmp_path: Path) -> None:
    # one comparison procedure on the virtual drive of the seed-71 axis, over CAN (under the
    # default 60 N.m it faults: following error while the axis breaks away)
    path, _ = axis71
    out = tmp_path / "compare.json"
    env = {"PYTHONPATH": str(ROOT / "host"), "PATH": "/usr/bin:/bin"}
    p = subprocess.run([sys.executable, "-m", "hdservo.cli", "compare", "--controllers", "pid",
                        "--feedback", "full-closed", "--procedures", "positioning", "--quick", "--jobs", "1",
                        "--out-dir", str(tmp_path / "out"), "--json", str(out), "-q", f"--sim={path}"],
                       capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    pid = json.loads(out.read_text())["controllers"]["pid"]
    assert pid["failures"] == {}
    assert pid["gains"]["torque_limit"] == pytest.approx(bl.axis_controller(path)["gains"]["torque_limit"])
    # the axis positions: ISO 230-2 accuracy within 1 arcmin
    assert 0.0 < pid["headline"]["positioning_accuracy_arcsec"] < 60.0
