"""A diverging plant (every stiffness at 1e9 N.m/rad, Preisach hysteresis on) ends a run
with the one-line "the simulation diverged" error: in the Python binding (in-process, so a
crash there would take the interpreter with it), in `hdservo sim` and in `hdservo-sim run`."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hdservo import sim

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[2]

STIFF = {"stiffness.k1_Nm_per_rad": 1e9, "stiffness.k2_Nm_per_rad": 1e9, "stiffness.k3_Nm_per_rad": 1e9,
         "stiffness_cubic.k1_Nm_per_rad": 1e9, "stiffness_cubic.k3_Nm_per_rad3": 1e9}

SCENARIO = """[scenario]
name = "diverge"
axis = "reference"
duration_s = 0.2
seed = 1
log_decimation = 10
[controller]
mode = "position"
[setpoint]
type = "step"
amplitude_rad = 4.84813681109536e-4
t0_s = 0.01
[plant]
""" + "".join(f"{k} = {v:g}\n" for k, v in STIFF.items())


@pytest.fixture()
def scenario(tmp_path: Path) -> Path:
    p = tmp_path / "diverge.toml"
    p.write_text(SCENARIO)
    return p


def test_binding_raises_the_package_error_in_a_child_interpreter(scenario: Path) -> None:
    # in a child first: on a crash the child dies with a signal, not this test run
    code = ("import sys\nfrom hdservo import sim\n"
            "try:\n    sim.run_scenario(sys.argv[1])\n"
            "except sim.SimError as e:\n    print('SimError:', e)\n    sys.exit(3)\n")
    p = subprocess.run([sys.executable, "-c", code, str(scenario)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 3, (p.returncode, p.stderr[-500:])
    assert "the simulation diverged at t = " in p.stdout


def test_binding_raises_the_package_error(scenario: Path) -> None:
    with pytest.raises(sim.SimError, match=r"diverge\.toml: the simulation diverged at t = [0-9.e-]+ s"):
        sim.run_scenario(scenario)
    # the same through parameter overrides of a good scenario
    with pytest.raises(sim.SimError, match="the simulation diverged"):
        sim.run_scenario(REPO_ROOT / "sim" / "scenarios" / "step.toml", params=STIFF, duration_s=0.2)


def test_cli_sim_prints_one_line_and_writes_nothing(scenario: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.csv"
    p = subprocess.run([sys.executable, "-m", "hdservo.cli", "sim", str(scenario), "-o", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, (p.returncode, p.stderr[-500:])
    assert p.stderr.count("\n") == 1 and "the simulation diverged" in p.stderr
    assert "Traceback" not in p.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["diverge.toml"]


def test_hdservo_sim_run_prints_one_line_and_writes_nothing(scenario: Path, tmp_path: Path) -> None:
    subprocess.run(["make", "--no-print-directory", "build/bin/hdservo-sim"], cwd=REPO_ROOT, check=True,
                   stdout=subprocess.DEVNULL)
    out = tmp_path / "out.csv"
    p = subprocess.run([str(REPO_ROOT / "build" / "bin" / "hdservo-sim"), "run", str(scenario), "-o", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, (p.returncode, p.stderr[-500:])
    assert p.stderr.startswith("hdservo-sim: error: ") and p.stderr.count("\n") == 1
    assert "diverge.toml: the simulation diverged at t = " in p.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["diverge.toml"]
