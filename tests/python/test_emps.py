"""EMPS real-data importer and the reproduction of the published IDIM-LS results.

The published numbers are read from ``reference_results.csv`` in the shipped data
directory (never copied here).  The reproduction tests skip, with the reason,
only when that directory is absent; the bad-input tests build their own files.
"""
from __future__ import annotations

import csv
import json
import math
import os
import shutil
from pathlib import Path
from typing import Dict

import numpy as np
import pytest

from hdservo import cli, emps
from hdservo.cli import UserError


def _data_dir() -> Path:
    env = os.environ.get(emps.ENV_DATA_DIR)
    return Path(env) if env else emps.DEFAULT_DATA_DIR


DATA = _data_dir()
needs_data = pytest.mark.skipif(
    not (DATA / "DATA_EMPS.csv").is_file(),
    reason=f"EMPS data not found at {DATA} (set {emps.ENV_DATA_DIR})")


def _published() -> Dict[str, Dict[str, Dict[str, float]]]:
    """reference_results.csv as {case: {quantity: {'value': v, 'std': s}}}."""
    out: Dict[str, Dict[str, Dict[str, float]]] = {}
    with (DATA / "reference_results.csv").open(newline="") as f:
        for row in csv.DictReader(f):
            entry = {"value": float(row["value"])}
            if row["std"]:
                entry["std"] = float(row["std"])
            out.setdefault(row["case"], {})[row["quantity"]] = entry
    return out


@pytest.fixture(scope="module")
def verified():
    report, rep = emps.verify(DATA)
    return report, rep, _published()


# ---- reproduction -------------------------------------------------------------------

@needs_data
@pytest.mark.parametrize("case,block,names", [
    ("idim_ls_symmetric", "symmetric", emps.SYMMETRIC_PARAMS),
    ("idim_ls_asymmetric", "asymmetric", emps.ASYMMETRIC_PARAMS),
])
def test_parameters_within_half_percent(verified, case, block, names):
    report, rep, pub = verified
    assert tuple(report[block]) == names + ("relative_error_pct",)
    for name in names:
        ref = pub[case][name]["value"]
        assert report[block][name] == pytest.approx(ref, rel=0.005), name


@needs_data
def test_relative_errors_within_a_tenth_of_a_point(verified):
    report, rep, pub = verified
    pairs = [
        (report["symmetric"]["relative_error_pct"], pub["idim_ls_symmetric"]),
        (report["asymmetric"]["relative_error_pct"], pub["idim_ls_asymmetric"]),
        (report["cross_test_relative_error_pct"], pub["cross_test_pulses"]),
    ]
    for mine, ref in pairs:
        assert abs(mine - ref["relative_error_pct"]["value"]) <= 0.1
    # and the other error measures the document prints
    assert rep.symmetric.error_norm == pytest.approx(
        pub["idim_ls_symmetric"]["error_norm"]["value"], rel=1e-3)
    assert rep.cross_test.error_std == pytest.approx(
        pub["cross_test_pulses"]["error_std"]["value"], rel=1e-3)
    assert report["deviation"]["within_tolerance"] is True


@needs_data
def test_processing_matches_rows_conditioning_and_qr(verified):
    """N = 2480 rows, condition numbers, |diag R|: these pin down the processing."""
    _, rep, pub = verified
    for res, case in ((rep.symmetric, "idim_ls_symmetric"), (rep.asymmetric, "idim_ls_asymmetric"),
                      (rep.cross_test, "cross_test_pulses")):
        assert res.n_rows == 2480
        assert res.cond == pytest.approx(pub[case]["cond_observation_matrix"]["value"], rel=1e-4)
    for res, case in ((rep.symmetric, "idim_ls_symmetric"), (rep.cross_test, "cross_test_pulses")):
        ref = [pub[case][f"absdiagR_{n}"]["value"] for n in emps.SYMMETRIC_PARAMS]
        np.testing.assert_allclose(res.abs_diag_R, ref, rtol=1e-4)
    ref_std = [pub["idim_ls_symmetric"][n]["std"] for n in emps.SYMMETRIC_PARAMS]
    np.testing.assert_allclose(rep.symmetric.std, ref_std, rtol=2e-3)


@needs_data
def test_cli_writes_exact_json_atomically(tmp_path, capsys):
    out = tmp_path / "verify" / "emps.json"
    assert cli.main(["emps", "verify", "--data", str(DATA), "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert set(doc) == {"symmetric", "asymmetric", "cross_test_relative_error_pct",
                        "published", "deviation"}
    assert list(doc["symmetric"]) == ["M", "Fv", "Fc", "offset", "relative_error_pct"]
    assert list(doc["asymmetric"]) == ["M", "Fv_plus", "Fc_plus", "Fv_minus", "Fc_minus",
                                       "relative_error_pct"]
    assert all(isinstance(v, float) for v in doc["symmetric"].values())
    assert [p.name for p in out.parent.iterdir()] == ["emps.json"]
    assert "published" in capsys.readouterr().out


@needs_data
def test_mat_and_csv_records_are_identical():
    consts = emps.load_constants(DATA)
    a = emps.load_record(DATA / "DATA_EMPS_PULSES.csv", consts)
    b = emps.load_record(DATA / "DATA_EMPS_PULSES.mat", consts)
    for name in ("t_s", "position_m", "reference_m", "command_V", "pulses_V"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.meta["gtau_N_per_V"] == b.meta["gtau_N_per_V"]
    assert a.meta["n_samples"] == 24841 and a.sample_period_s == 0.001
    # pulses (PROVENANCE.md): 25, one per second from t = 0.344 s, 500 samples long
    # (the last one is cut by the end of the record), amplitude 5
    edges = np.diff(np.r_[0, (a.pulses_V > 0).astype(int), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    assert len(starts) == 25 and a.t_s[starts[0]] == pytest.approx(0.344, abs=1e-6)
    assert np.all(np.diff(starts) == 1000) and np.all((ends - starts)[:-1] == 500)
    assert set(np.unique(a.pulses_V)) == {0.0, 5.0}


# ---- log conversion ---------------------------------------------------------------------

def _write_constants(d: Path) -> None:
    (d / emps.CONSTANTS_FILE).write_text(
        "name,value,unit,meaning\ngtau,35.0,N/V,x\nkp,160,1/s,x\nkv,243,V/(m/s),x\n"
        "Ts,0.001,s,x\nvir_saturation,10,V,x\n")


def _good_rows(n: int = 5) -> str:
    return "".join(f"{k * 0.001!r},{k * 1e-4!r},{k * 2e-4!r},{0.5 + k!r}\n" for k in range(n))


def test_log_conversion_mapping_and_sidecar(tmp_path):
    _write_constants(tmp_path)
    src = tmp_path / "rec.csv"
    src.write_text("t,qm,qg,vir\n" + _good_rows())
    rec = emps.load_record(src)
    cols = emps.to_log_columns(rec)
    np.testing.assert_allclose(cols["motor_force_N"], 35.0 * (0.5 + np.arange(5)))
    np.testing.assert_array_equal(cols["load_position_m"], rec.position_m)
    np.testing.assert_array_equal(cols["setpoint_m"], rec.reference_m)
    out = tmp_path / "log" / "rec_log.csv"
    emps.write_log(rec, out)
    header = out.read_text().splitlines()[0].split(",")
    assert header == ["t_s", "load_position_m", "motor_force_N", "setpoint_m", "motor_command_V"]
    side = json.loads(out.with_suffix(".json").read_text())
    assert side["sample_period_s"] == 0.001 and side["axis_kind"] == "prismatic"
    assert side["column_roles"]["load_position_m"] == "load_angle_rad"
    assert side["column_roles"]["motor_force_N"] == "motor_torque_Nm"
    back = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(back[:, 2], rec.force_N)
    assert side["columns"] == header and side["gear_ratio"] == 1.0


def test_log_sidecar_is_a_valid_hdservo_sidecar(tmp_path):
    """The shared log reader accepts the sidecar (format tag, gear ratio, period)."""
    logio = pytest.importorskip("hdservo.logio", reason="hdservo.logio not present")
    _write_constants(tmp_path)
    src = tmp_path / "rec.csv"
    src.write_text("t,qm,qg,vir\n" + _good_rows())
    out = tmp_path / "rec_log.csv"
    emps.write_log(emps.load_record(src), out)
    meta = logio.read_meta(out.with_suffix(".json"))
    assert meta["sample_period_s"] == 0.001


# ---- bad input -------------------------------------------------------------------------

def _bad(tmp_path: Path, body: str, name: str = "bad.csv") -> str:
    _write_constants(tmp_path)
    p = tmp_path / name
    p.write_text(body)
    with pytest.raises(UserError) as ei:
        emps.load_record(p)
    msg = str(ei.value)
    assert "\n" not in msg and msg.startswith(str(p))
    return msg


def test_rejects_empty_file(tmp_path):
    assert "line 1: empty file" in _bad(tmp_path, "")


def test_rejects_header_only(tmp_path):
    assert "line 2: no data rows" in _bad(tmp_path, "t,qm,qg,vir\n")


def test_rejects_missing_column(tmp_path):
    msg = _bad(tmp_path, "t,qm,qg\n0,0,0\n")
    assert "line 1: missing column 'vir'" in msg


def test_rejects_truncated_last_line(tmp_path):
    body = "t,qm,qg,vir\n" + _good_rows(4) + "0.004,0.0004,"
    assert "line 6: expected 4 comma-separated values" in _bad(tmp_path, body)
    assert "truncated" in _bad(tmp_path, body)


def test_rejects_number_cut_in_half(tmp_path):
    body = "t,qm,qg,vir\n" + _good_rows(4) + "0.004,0.0004,0.0008,1e"
    msg = _bad(tmp_path, body)
    assert "line 6: last line is incomplete" in msg and "truncated" in msg


def test_rejects_nan(tmp_path):
    body = "t,qm,qg,vir\n" + _good_rows(3) + "0.003,nan,0.0006,3.5\n"
    assert "line 5, column 'qm': expected a finite number, found 'nan'" in _bad(tmp_path, body)


def test_rejects_text_in_number(tmp_path):
    body = "t,qm,qg,vir\n" + _good_rows(2) + "0.002,0.0002,abc,2.5\n"
    assert "line 4, column 'qg': expected a number, found 'abc'" in _bad(tmp_path, body)


def test_rejects_time_going_backwards(tmp_path):
    body = "t,qm,qg,vir\n" + _good_rows(3) + "0.001,0,0,0\n"
    assert "line 5, column 't': time does not increase" in _bad(tmp_path, body)


def test_rejects_missing_file_and_constants(tmp_path):
    with pytest.raises(UserError, match=r"nope\.csv: file not found"):
        emps.load_record(tmp_path / "nope.csv", {"gtau": 1, "kp": 1, "kv": 1, "Ts": 0.001})
    (tmp_path / "r.csv").write_text("t,qm,qg,vir\n" + _good_rows())
    with pytest.raises(UserError, match=r"EMPS_constants\.csv: file not found"):
        emps.load_record(tmp_path / "r.csv")


def test_rejects_corrupt_mat(tmp_path):
    msg = _bad(tmp_path, "not a mat file", name="DATA_EMPS.mat")
    assert "not a readable MATLAB .mat file" in msg


def test_benchmark_record_must_have_published_length(tmp_path):
    """A file cut exactly at a line end is caught by the published sample count."""
    _write_constants(tmp_path)
    (tmp_path / "DATA_EMPS.csv").write_text("t,qm,qg,vir\n" + _good_rows(400))
    with pytest.raises(UserError, match=r"DATA_EMPS\.csv: 400 samples, expected 24841"):
        emps.load_benchmark_record(tmp_path, "DATA_EMPS")


def test_cli_bad_data_dir_one_line_exit_2_no_output(tmp_path, capsys):
    out = tmp_path / "emps.json"
    rc = cli.main(["emps", "verify", "--data", str(tmp_path / "absent"), "--json", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "EMPS data directory not found" in err and not out.exists()


@needs_data
def test_cli_truncated_record_leaves_no_json(tmp_path, capsys):
    d = tmp_path / "emps"
    d.mkdir()
    for name in ("EMPS_constants.csv", "reference_results.csv", "DATA_EMPS_PULSES.csv"):
        shutil.copy(DATA / name, d / name)
    lines = (DATA / "DATA_EMPS.csv").read_text().splitlines(keepends=True)
    (d / "DATA_EMPS.csv").write_text("".join(lines[:1000]) + lines[1000][:17])
    out = tmp_path / "emps.json"
    rc = cli.main(["emps", "verify", "--data", str(d), "--json", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "DATA_EMPS.csv: line 1001" in err and "truncated" in err
    assert not out.exists()


def test_matlab_decimate_keeps_last_sample():
    """MATLAB alignment: 2480 outputs, the last one is input sample N-1."""
    n, r = 24792, 10
    k = np.arange(n)
    x = np.sin(2 * math.pi * k / 100.0)           # 10 Hz at 1 kHz: inside the pass band
    y = emps.matlab_decimate(x, r)
    assert len(y) == math.ceil(n / r) == 2480
    kept = k[n - 1::-r][::-1]                     # ..., n-11, n-1

    def misfit(idx: np.ndarray) -> float:         # after fitting the pass-band gain
        inner = slice(50, -50)
        g = np.dot(y[inner], x[idx][inner]) / np.dot(x[idx][inner], x[idx][inner])
        assert 0.98 < g < 1.01
        return float(np.max(np.abs(y[inner] - g * x[idx][inner])))

    assert misfit(kept) < 1e-3
    assert misfit(kept - 1) > 0.05 and misfit(kept - 2) > 0.05
