"""logio: DESIGN.md section 7 logs round-trip; bad files give one clear line."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hdservo import logio
from hdservo.logio import LogError

META = {"gear_ratio": 100.0, "sample_period_s": 1e-4, "motor_encoder_counts_per_rev": 131072,
        "seed": 3, "effects": {"friction_motor": True}}


def _write_good(tmp_path: Path) -> Path:
    t = np.arange(50) * 1e-4
    cols = {"t_s": t, "motor_angle_rad": np.sin(t * 7.0) / 3.0, "load_velocity_rad_s": -t * 1e-7,
            "motor_torque_Nm": np.full(50, 0.1), "fault_code": np.zeros(50)}
    p = tmp_path / "run.csv"
    logio.write_log(p, cols, META)
    return p


def test_round_trip_is_exact(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    log = logio.read_log(p)
    t = np.arange(50) * 1e-4
    assert list(log.columns) == ["t_s", "motor_angle_rad", "load_velocity_rad_s", "motor_torque_Nm", "fault_code"]
    assert np.array_equal(log["motor_angle_rad"], np.sin(t * 7.0) / 3.0)   # bit-exact
    assert log.meta["gear_ratio"] == 100.0 and log.meta["format"] == "hdservo-log"
    assert log.meta["columns"] == list(log.columns)
    assert len(log) == 50
    assert not list(tmp_path.glob("*.tmp"))


def _expect(path: Path, fragment: str) -> str:
    with pytest.raises(LogError) as ei:
        logio.read_log(path)
    msg = str(ei.value)
    assert "\n" not in msg
    assert path.stem in msg
    assert fragment in msg, msg
    return msg


def test_empty_file(tmp_path: Path) -> None:
    p = tmp_path / "e.csv"
    p.write_text("")
    assert _expect(p, "empty file").startswith(f"{p}:1:1:")


def test_truncated_file(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) - 7])
    _expect(p, "truncated")


def test_short_row(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    lines = p.read_text().splitlines()
    lines[5] = ",".join(lines[5].split(",")[:-1])
    p.write_text("\n".join(lines) + "\n")
    msg = _expect(p, "expected 5 values, found 4")
    assert f"{p}:6:" in msg


def test_nan_value(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    lines = p.read_text().splitlines()
    cells = lines[3].split(",")
    cells[2] = "nan"
    lines[3] = ",".join(cells)
    p.write_text("\n".join(lines) + "\n")
    msg = _expect(p, "expected a finite number, found 'nan'")
    col = len(cells[0]) + len(cells[1]) + 3
    assert f"{p}:4:{col}:" in msg


def test_not_a_number(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    text = p.read_text().replace(",0.1,", ",0.1x,", 1)
    p.write_text(text)
    _expect(p, "expected a number, found '0.1x'")


def test_missing_column(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    lines = p.read_text().splitlines()
    lines = [",".join(line.split(",")[1:]) for line in lines]   # drop t_s
    p.write_text("\n".join(lines) + "\n")
    _expect(p, "expected the first column to be 't_s'")
    log = logio.read_log(_write_good(tmp_path))
    with pytest.raises(LogError, match="no column 'load_angle_rad'"):
        log["load_angle_rad"]


def test_wrong_unit_suffix(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    text = p.read_text().replace("motor_angle_rad", "motor_angle_deg", 1)
    p.write_text(text)
    msg = _expect(p, "expected 'motor_angle_rad' (SI unit suffix '_rad'), found 'motor_angle_deg'")
    assert f"{p}:1:5:" in msg
    text = text.replace("motor_angle_deg", "encoder_counts", 1)
    p.write_text(text)
    _expect(p, "expected an SI unit suffix")
    text = text.replace("encoder_counts", "something", 1)
    p.write_text(text)
    _expect(p, "expected an SI unit suffix")


def test_time_not_increasing(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    lines = p.read_text().splitlines()
    lines[4], lines[5] = lines[5], lines[4]
    p.write_text("\n".join(lines) + "\n")
    _expect(p, "expected t_s to increase")


def test_sidecar_problems(tmp_path: Path) -> None:
    p = _write_good(tmp_path)
    side = p.with_suffix(".json")
    side.unlink()
    _expect(p, "cannot read the log sidecar")
    assert logio.read_log(p, require_sidecar=False).meta == {}
    side.write_text('{"format": "hdservo-log", "version": 1,\n "gear_ratio": NaN}')
    with pytest.raises(LogError, match="finite"):
        logio.read_log(p)
    side.write_text('{"format": "hdservo-log", "version": 1, "gear_ratio": 100}')
    with pytest.raises(LogError, match='expected key "sample_period_s"'):
        logio.read_log(p)
    side.write_text('{"format": "hdservo-log", "version": 1,\n "gear_ratio": 100, "sample_period_s": "x"}')
    with pytest.raises(LogError, match='"sample_period_s": expected a finite number'):
        logio.read_log(p)
    side.write_text('{"format": "hdservo-log", \n "version": 1,,}')
    with pytest.raises(LogError, match=r"run.json:2:15: expected JSON"):
        logio.read_log(p)


def test_write_refuses_bad_input_and_leaves_nothing(tmp_path: Path) -> None:
    p = tmp_path / "bad.csv"
    with pytest.raises(LogError, match="expected 't_s' as the first column"):
        logio.write_log(p, {"x_rad": [1.0]}, META)
    with pytest.raises(LogError, match="finite"):
        logio.write_log(p, {"t_s": [0.0, 1.0], "x_rad": [1.0, float("nan")]}, META)
    with pytest.raises(LogError, match="SI unit suffix"):
        logio.write_log(p, {"t_s": [0.0], "x_deg": [1.0]}, META)
    with pytest.raises(LogError, match="sample_period_s"):
        logio.write_log(p, {"t_s": [0.0]}, {"gear_ratio": 100.0})
    assert list(tmp_path.iterdir()) == []


def test_reads_c_harness_format(tmp_path: Path) -> None:
    """A header + %.17g rows as written by sim/harness/logwrite.c."""
    p = tmp_path / "c.csv"
    p.write_text("t_s,torsion_rad,gyro_rate_rad_s,sensor_valid_code\n0,0.10000000000000001,-1e-09,15\n"
                 "0.0001,0.33333333333333331,2.5,15\n")
    p.with_suffix(".json").write_text(json.dumps({"format": "hdservo-log", "version": 1, "gear_ratio": 100,
                                                  "sample_period_s": 1e-4}))
    log = logio.read_log(p)
    assert log["torsion_rad"][1] == 1.0 / 3.0
    assert log["sensor_valid_code"].tolist() == [15.0, 15.0]
