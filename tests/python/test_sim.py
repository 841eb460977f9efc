"""Python binding of the simulator, the `hdservo-sim` program and `hdservo sim`."""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hdservo import logio, sim

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[2]

SCEN = REPO_ROOT / "sim" / "scenarios"
ARCSEC = math.pi / 180 / 3600


@pytest.fixture(scope="module")
def hdservo_sim() -> Path:
    exe = REPO_ROOT / "build" / "bin" / "hdservo-sim"
    subprocess.run(["make", "--no-print-directory", "-j2", "build/bin/hdservo-sim"], cwd=REPO_ROOT, check=True,
                   stdout=subprocess.DEVNULL)
    return exe


def _scenario(tmp_path: Path, body: str, name: str = "s.toml") -> Path:
    p = tmp_path / name
    p.write_text(body)
    return p


def test_step_scenario_settles_on_the_setpoint() -> None:
    r = sim.run_scenario(SCEN / "step.toml")
    t, sp, y = r["t_s"], r["setpoint_rad"], r["load_angle_rad"]
    assert len(t) == 5000 and t[1] - t[0] == pytest.approx(1e-4)
    assert sp[0] == 0.0 and sp[-1] == pytest.approx(100 * ARCSEC)
    # settled within 10 arcsec of the 100 arcsec step after 0.4 s, and it moved
    assert abs(np.mean(y[t > 0.4]) - sp[-1]) < 10 * ARCSEC
    assert np.max(np.abs(r["torque_cmd_Nm"])) > 0.01
    assert r.meta["gear_ratio"] == 100 and r.meta["sample_period_s"] == pytest.approx(1e-4)
    assert r.meta["effects"]["hysteresis_preisach"] is True
    assert r["fault_code"].max() == 0
    assert r.app_time_s > 0 and r.plant_time_s > 0


def test_same_scenario_twice_gives_byte_identical_logs(tmp_path: Path, hdservo_sim: Path) -> None:
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}.csv"
        subprocess.run([str(hdservo_sim), "run", str(SCEN / "step.toml"), "-o", str(out), "-q",
                        "--duration", "0.1"], check=True)
        outs.append(out)
    assert outs[0].read_bytes() == outs[1].read_bytes()
    a = outs[0].with_suffix(".json").read_text()
    assert a == outs[1].with_suffix(".json").read_text()
    # and the binding gives the same numbers as the program (to the bit)
    log = logio.read_log(outs[0])
    r = sim.run_scenario(SCEN / "step.toml", duration_s=0.1)
    for name, col in log.columns.items():
        assert np.array_equal(col, r[name]), name
    # another seed changes the noisy signals
    r2 = sim.run_scenario(SCEN / "step.toml", duration_s=0.1, seed=99)
    assert not np.array_equal(r2["motor_current_A"], r["motor_current_A"])


def test_hdservo_sim_errors_are_one_line_and_leave_nothing(tmp_path: Path, hdservo_sim: Path) -> None:
    bad = _scenario(tmp_path, "[scenario]\nduration_s = 1\n[controller]\nmode = \"position\"\n"
                              "[setpoint]\ntype = \"step\"\namplitude_deg = 1\n")
    out = tmp_path / "o.csv"
    p = subprocess.run([str(hdservo_sim), "run", str(bad), "-o", str(out)], capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1
    assert p.stderr.startswith("hdservo-sim: error: ") and "missing key 'setpoint.amplitude_rad'" in p.stderr
    assert not out.exists() and list(tmp_path.iterdir()) == [bad]
    p = subprocess.run([str(hdservo_sim), "run", str(SCEN / "step.toml"), "-o", str(tmp_path / "nodir" / "x.csv")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "cannot write" in p.stderr
    p = subprocess.run([str(hdservo_sim), "jump"], capture_output=True, text=True)
    assert p.returncode == 2 and "unknown command" in p.stderr


def test_cli_sim_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from hdservo.cli import main
    out = tmp_path / "cli.csv"
    rc = main(["sim", str(SCEN / "step.toml"), "-o", str(out), "--duration", "0.05",
               "--set", "gravity.enabled=false", "--json", str(tmp_path / "s.json")])
    assert rc == 0
    log = logio.read_log(out)
    assert len(log) == 500 and log.meta["effects"]["gravity"] is False
    capsys.readouterr()
    rc = main(["sim", str(SCEN / "step.toml"), "-o", str(tmp_path / "x.csv"), "--set", "stiffness.k9=1"])
    err = capsys.readouterr().err
    assert rc == 2 and err.strip().count("\n") == 0 and "stiffness.k9" in err
    assert not (tmp_path / "x.csv").exists()


def test_bad_scenario_names_file_line_column(tmp_path: Path) -> None:
    p = _scenario(tmp_path, "[scenario]\nduration_s = 1\n[controller]\nmode = \"position\"\n[plant]\n"
                            "stiffness.k1_Nm_per_rad = -5\n")
    with pytest.raises(sim.SimError) as ei:
        sim.run_scenario(p)
    assert str(ei.value).startswith(f"{p}:6:27: plant.stiffness.k1_Nm_per_rad:")
    with pytest.raises(sim.SimError, match="unknown effect 'frction'"):
        sim.run_scenario(SCEN / "step.toml", effects={"frction": False})


def test_open_loop_minimal_axis_matches_rigid_body_physics() -> None:
    """Every effect off: a constant motor torque accelerates motor + load as one rigid-ish body."""
    n = 2000
    tau = 0.02
    r = sim.simulate_open_loop(np.full(n, tau), axis="minimal")
    N = sim.axis_param("gear.ratio", "minimal")
    jm = sim.axis_param("motor.jm_kgm2", "minimal")
    jl = sim.axis_param("load.jl_kgm2", "minimal")
    acc = tau * N / (jl + N * N * jm)            # output-side acceleration, rad/s^2
    t = r["t_s"]
    assert t[0] == pytest.approx(1e-4) and t[-1] == pytest.approx(0.2)
    # mean velocity over the last 20 ms (torsional ringing averages out) vs a*t
    sel = t > 0.18
    assert np.mean(r["load_velocity_rad_s"][sel]) == pytest.approx(acc * np.mean(t[sel]), rel=0.03)


def test_open_loop_effect_switches_change_the_response() -> None:
    n = 3000
    u = np.concatenate([np.linspace(0, 0.3, n // 2), np.linspace(0.3, -0.3, n - n // 2)])
    base = sim.simulate_open_loop(u, effects={"gravity": False})
    nofric = sim.simulate_open_loop(u, effects={"gravity": False, "friction_motor": False, "friction_load": False})
    assert np.max(np.abs(nofric["load_angle_true_rad"])) > np.max(np.abs(base["load_angle_true_rad"]))
    assert np.all(nofric["friction_motor_Nm"] == 0.0)
    assert np.any(base["friction_motor_Nm"] != 0.0)
    # parameter overrides reach the plant: a stiffer gear twists less under the same external load
    lt = np.full(n, 10.0)
    zero = np.zeros(n)
    soft = sim.simulate_open_loop(zero, load_torque_Nm=lt, axis="minimal",
                                  params={"stiffness.k1_Nm_per_rad": 1e4, "load.jl_kgm2": 0.5})
    stiff = sim.simulate_open_loop(zero, load_torque_Nm=lt, axis="minimal",
                                   params={"stiffness.k1_Nm_per_rad": 4e4, "load.jl_kgm2": 0.5})
    assert np.max(np.abs(soft["torsion_rad"])) > 2.0 * np.max(np.abs(stiff["torsion_rad"]))
    with pytest.raises(sim.SimError, match="expected shape"):
        sim.simulate_open_loop(zero, load_torque_Nm=lt[:-1])
    with pytest.raises(sim.SimError, match="unknown parameter"):
        sim.simulate_open_loop(zero, params={"nope.x": 1.0})


def test_faults_reach_plant_and_drive() -> None:
    r = sim.run_scenario(SCEN / "faults.toml")
    t = r["t_s"]
    # load step of 5 N.m at 0.1 s reaches the plant
    assert np.all(r["load_disturbance_Nm"][t < 0.0999] == 0.0)
    assert np.all(r["load_disturbance_Nm"][(t > 0.1005)] == 5.0)
    # current limit 2 A from 0.2 s: the actual current (Kt*i) stays within 2 A * Kt
    kt = sim.axis_param("motor.kt_Nm_per_A")
    late = (t > 0.2005) & (t < 0.399)
    assert np.max(np.abs(r["motor_torque_Nm"][late])) <= 2.0 * kt + 1e-12
    # output-encoder glitch of 100000 counts at 0.4 s: the drive trips on the encoder jump (code 5)
    assert np.all(r["fault_code"][t < 0.4] == 0)
    assert r["fault_code"][-1] == 5
    trip = t[np.argmax(r["fault_code"] != 0)]
    assert 0.4 < trip < 0.4005
    assert np.all(r["torque_cmd_Nm"][t > trip + 2e-4] == 0.0)


def test_encoder_dropout_invalidates_the_sample_and_faults_the_drive(tmp_path: Path) -> None:
    p = _scenario(tmp_path, "[scenario]\nduration_s = 0.1\n[controller]\nmode = \"position\"\n"
                            "[[fault]]\nt_s = 0.05\ntype = \"encoder_dropout\"\nencoder = \"motor\"\n"
                            "duration_s = 0.01\n")
    r = sim.run_scenario(p)
    t, valid = r["t_s"], r["sensor_valid_code"].astype(int)
    assert np.all(valid[t < 0.05] == 15)
    dropped = (valid & 1) == 0
    assert dropped.any() and 0.05 < t[np.argmax(dropped)] < 0.0502
    assert np.count_nonzero(dropped) == 100          # 10 ms at 10 kHz
    assert r["fault_code"][-1] == 6                  # HD_FAULT_SENSOR
