"""The run-in of a position setpoint (moves before t0_s) and the estimator's state in the sidecar."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hdservo import sim

DEG = math.pi / 180.0


def _scenario(tmp_path: Path, setpoint: str, gains: str = "", mode: str = "position") -> Path:
    p = tmp_path / "s.toml"
    p.write_text(f"""[scenario]
axis = "reference"
duration_s = 4.0
seed = 1
log_decimation = 10

[controller]
mode = "{mode}"
{gains}

[setpoint]
{setpoint}
""")
    return p


#: Three moves (+0.2 deg at 1 deg/s, -0.1 deg at 0.5 deg/s, back to 0 at 2 deg/s) from 0.1 s.
RUN_IN = """run_in_targets_rad = [{a}, {b}, 0.0]
run_in_speeds_rad_s = [{v1}, {v2}, {v3}]
run_in_accel_rad_s2 = {acc}
run_in_t0_s = 0.1""".format(a=0.2 * DEG, b=-0.1 * DEG, v1=1.0 * DEG, v2=0.5 * DEG, v3=2.0 * DEG, acc=20.0 * DEG)


def _move_time(d: float, v: float, a: float) -> float:
    ta = v / a
    return 2.0 * math.sqrt(d / a) if a * ta * ta > d else 2.0 * ta + (d - a * ta * ta) / v


def test_run_in_moves_through_its_targets_then_the_setpoint_starts(tmp_path: Path) -> None:
    """Before t0 the setpoint runs the trapezoid moves one after another and rests where the
    setpoint starts; the axis follows them; from t0 the case's own setpoint (a ramp) runs as
    it would without a run-in."""
    body = f"""type = "ramp"
initial_rad = {0.5 * DEG}
rate_rad_s = {0.01 * DEG}
t0_s = 2.0
{RUN_IN}"""
    r = sim.run_scenario(_scenario(tmp_path, body))
    t, sp, y = r["t_s"], r["setpoint_rad"] - 0.5 * DEG, r["load_angle_true_rad"] - 0.5 * DEG
    acc = 20.0 * DEG
    ends = np.cumsum([0.1, _move_time(0.2 * DEG, 1.0 * DEG, acc), _move_time(0.3 * DEG, 0.5 * DEG, acc),
                      _move_time(0.1 * DEG, 2.0 * DEG, acc)])
    assert ends[-1] < 2.0
    assert np.all(sp[t < 0.1] == 0.0)
    # each move ends at its target (the log row nearest its end: within 1 ms of braking)
    for end, target in zip(ends[1:], (0.2 * DEG, -0.1 * DEG, 0.0)):
        k = int(np.argmin(np.abs(t - end)))
        assert sp[k] == pytest.approx(target, abs=1e-6)
    assert np.max(sp) <= 0.2 * DEG + 1e-15 and np.min(sp) >= -0.1 * DEG - 1e-15
    assert np.all(sp[(t > ends[-1]) & (t < 2.0)] == 0.0)
    # continuous: no step between log rows (1 ms) larger than the fastest move's 2 deg/s allows
    assert np.max(np.abs(np.diff(sp))) <= 2.0 * DEG * 1e-3 * 1.001
    after = t >= 2.0
    assert sp[after] == pytest.approx(0.01 * DEG * (t[after] - 2.0), abs=1e-12)
    # the axis went there too (within 0.02 deg of the peak)
    assert np.max(y) > 0.18 * DEG and np.min(y) < -0.08 * DEG


@pytest.mark.parametrize("extra, mode, what", [
    ("run_in_targets_rad = [0.001, 0.002]\nrun_in_speeds_rad_s = [0.01, 0.01]\nrun_in_accel_rad_s2 = 1.0",
     "position", "last target 0"),
    ("run_in_targets_rad = [0.001, 0.0]\nrun_in_speeds_rad_s = [0.01]\nrun_in_accel_rad_s2 = 1.0",
     "position", "as many speeds"),
    ("run_in_targets_rad = [0.5, 0.0]\nrun_in_speeds_rad_s = [0.01, 0.01]\nrun_in_accel_rad_s2 = 1.0",
     "position", "by t0_s"),
    ("run_in_targets_rad = [0.001, 0.0]\nrun_in_speeds_rad_s = [0.01, -0.01]\nrun_in_accel_rad_s2 = 1.0",
     "position", "speeds > 0"),
    ("run_in_targets_rad = [0.001, 0.0]\nrun_in_speeds_rad_s = [0.01, 0.01]", "position", "together"),
    ("run_in_targets_rad = [0.001, 0.0]\nrun_in_speeds_rad_s = [0.01, 0.01]\nrun_in_accel_rad_s2 = 1.0",
     "velocity", "controller mode \\\"position\\\""),
])
def test_bad_run_in_is_refused_with_one_line(tmp_path: Path, extra: str, mode: str, what: str) -> None:
    unit = "rad" if mode == "position" else "rad_s"
    body = f'type = "constant"\ninitial_{unit} = 0.0\nt0_s = 1.0\n{extra}'
    with pytest.raises(sim.SimError) as ei:
        sim.run_scenario(_scenario(tmp_path, body, mode=mode))
    msg = str(ei.value)
    assert "\n" not in msg and "s.toml" in msg and "run_in" in msg
    assert what.replace("\\", "") in msg


def test_sidecar_reports_the_estimator_at_the_end_of_the_run_in(tmp_path: Path) -> None:
    """With fe_enable the sidecar has the model in force and the estimator's state when the
    setpoint starts and at the end of the run; without the estimator it has no such entry."""
    body = f"""type = "constant"
initial_rad = 0.0
t0_s = 2.0
{RUN_IN}"""
    gains = "[controller.gains]\nfe_enable = 1\n"
    r = sim.run_scenario(_scenario(tmp_path, body, gains))
    fe = r.meta["fric_est"]
    for st in (fe["run_in_end"], fe["end"]):
        assert len(st["fits"]) == 2 and st["scale"] > 0.0
        assert set(st["estimate"]) == {"pos", "neg"}
    # no fit yet: the estimate is the map in force (the parameter defaults)
    assert fe["run_in_end"]["estimate"]["pos"]["fc_Nm"] == pytest.approx(fe["model"]["pos"]["fc_Nm"])
    assert fe["model"]["pos"]["fc_Nm"] > 0.0
    assert "fric_est" not in sim.run_scenario(_scenario(tmp_path, body)).meta
