"""Bad input to the host tools (DESIGN.md section 9): every command that reads a
file is given empty, truncated, malformed, NaN-containing, wrong-unit,
missing-column and very large inputs.  Each must print ONE error line on stderr
that names the file (and where it is known, line:column) and what was expected,
exit non-zero (2, the CLI's user-error status), print no traceback, and leave
no output file behind (not even a half-written one).

Commands covered: logs through hdservo.logio (``discrepancy``, ``identify
--data``, including logs the fits cannot use), scenario TOML (``sim``, through
the C reader of sim/harness), axis/model TOML (``df --axis``, ``discrepancy
--model``), identified models (``download``, ``compare --model``, ``test
--model``: refused before any drive is contacted), EMPS import (``emps export
--data``).  The C TOML reader itself is fuzzed
(tests/fuzz/fuzz_toml.c).
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
import subprocess
import sys
import traceback
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
os.environ.setdefault("MPLBACKEND", "Agg")

GOOD_META = {"format": "hdservo-log", "gear_ratio": 100, "sample_period_s": 0.001}
HEADER = "t_s,motor_angle_rad,load_angle_rad,motor_torque_Nm,setpoint_rad\n"


def _rows(n: int) -> str:
    return "".join(f"{i * 0.001:.3f},{i * 1e-3:.6g},{i * 1e-5:.6g},0.1,{i * 1e-5:.6g}\n" for i in range(n))


LOGS = {
    "empty": "",
    "header_only": HEADER,
    "truncated_row": HEADER + _rows(20) + "0.02,0.01\n",
    "malformed_number": HEADER + _rows(5) + "0.005,abc,0,0.1,0\n" + _rows(5),
    "nan": HEADER + _rows(5) + "0.005,nan,0,0.1,0\n",
    "wrong_unit": "t_s,motor_angle_deg,load_angle_rad,motor_torque_Nm,setpoint_rad\n" + _rows(20),
    "missing_time_column": "motor_angle_rad,load_angle_rad\n0,0\n1,1\n",
    "binary_garbage": "\x00\x01\xff\xfe" * 100,
}


def _cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """Run ``hdservo ARGS`` in this process (imports once: fast) and return what
    a subprocess would: exit status, stdout, stderr."""
    sys.path.insert(0, str(ROOT / "host"))
    from hdservo.cli import main

    out, err = io.StringIO(), io.StringIO()
    old = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = main(args)
            except SystemExit as e:
                rc = e.code if isinstance(e.code, int) else 1
            except Exception:  # noqa: BLE001 - a traceback is exactly the failure to report
                traceback.print_exc()
                rc = 1
    finally:
        os.chdir(old)
    return subprocess.CompletedProcess(args, rc, out.getvalue(), err.getvalue())


def _assert_one_line_error(p: subprocess.CompletedProcess, fname: str, outputs: list[Path]) -> None:
    assert p.returncode != 0, f"exit 0 on bad input; stdout: {p.stdout[-300:]}"
    err = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert "Traceback" not in p.stderr, p.stderr[-2000:]
    assert len(err) == 1, f"expected one error line, got {len(err)}: {p.stderr[-1500:]}"
    assert fname in err[0], f"error line does not name {fname}: {err[0]}"
    for o in outputs:
        assert not o.exists(), f"{o} left behind"
        assert not list(o.parent.glob(o.name + "*tmp*")), f"temporary file of {o} left behind"


def _write_log(d: Path, name: str, text: str, meta: dict | None = GOOD_META) -> Path:
    p = d / f"{name}.csv"
    p.write_bytes(text.encode("latin-1"))
    if meta is not None:
        (d / f"{name}.json").write_text(json.dumps(meta))
    return p


@pytest.mark.parametrize("case", sorted(LOGS))
def test_discrepancy_bad_log(tmp_path: Path, case: str) -> None:
    log = _write_log(tmp_path, case, LOGS[case])
    out = tmp_path / "out.json"
    _assert_one_line_error(_cli(["discrepancy", str(log), "--json", str(out)], tmp_path), log.name, [out])


@pytest.mark.parametrize("case", ["empty", "truncated_row", "nan", "wrong_unit", "missing_time_column"])
def test_identify_bad_log(tmp_path: Path, case: str) -> None:
    log = _write_log(tmp_path, case, LOGS[case])
    out, model = tmp_path / "out.json", tmp_path / "model.toml"
    _assert_one_line_error(_cli(["identify", "friction", "--data", str(log), "--json", str(out), "-o", str(model), "-q"],
                                tmp_path), log.name, [out, model])


@pytest.mark.parametrize("meta", [None, {}, {"format": "hdservo-log", "gear_ratio": "x", "sample_period_s": 0.001},
                                  "not json {",
                                  {"format": "hdservo-log", "version": 1, "gear_ratio": 10 ** 400,
                                   "sample_period_s": 0.001}])
def test_bad_sidecar(tmp_path: Path, meta) -> None:
    log = tmp_path / "l.csv"
    log.write_text(HEADER + _rows(50))
    if meta is not None:
        (tmp_path / "l.json").write_text(meta if isinstance(meta, str) else json.dumps(meta))
    out = tmp_path / "out.json"
    p = _cli(["discrepancy", str(log), "--json", str(out)], tmp_path)
    _assert_one_line_error(p, "l.", [out])


def test_very_large_log_line(tmp_path: Path) -> None:
    """A 20 MB single line (no newline) must be refused cleanly, not parsed into memory forever."""
    log = _write_log(tmp_path, "huge", HEADER.rstrip("\n") + ",x" * 10_000_000)
    out = tmp_path / "out.json"
    _assert_one_line_error(_cli(["discrepancy", str(log), "--json", str(out)], tmp_path), log.name, [out])


SCENARIOS = {
    "empty": "",
    "malformed": "[scenario\nduration_s = 1\n",
    "nan": "[scenario]\nduration_s = nan\n",
    "wrong_unit_key": "[scenario]\nduration_ms = 100\n",
    "wrong_type": "[scenario]\nduration_s = \"long\"\n",
    "huge_duration": "[scenario]\nduration_s = 1e12\n",
    "truncated": "[scenario]\nname = \"x\n",
    "binary": "\x00\xff" * 50,
}


@pytest.mark.parametrize("case", sorted(SCENARIOS))
def test_sim_bad_scenario(tmp_path: Path, case: str) -> None:
    if not (ROOT / "build" / "lib" / "libhdsim.so").exists():
        pytest.skip("build/lib/libhdsim.so not built")
    sc = tmp_path / f"{case}.toml"
    sc.write_bytes(SCENARIOS[case].encode("latin-1"))
    out = tmp_path / "out.csv"
    _assert_one_line_error(_cli(["sim", str(sc), "-o", str(out)], tmp_path), sc.name, [out, tmp_path / "out.json"])


def test_sim_output_directory(tmp_path: Path) -> None:
    """``-o DIR/sub/log.csv`` creates the directories; a path through a file is one error line."""
    if not (ROOT / "build" / "lib" / "libhdsim.so").exists():
        pytest.skip("build/lib/libhdsim.so not built")
    sc = ROOT / "sim" / "scenarios" / "step.toml"
    out = tmp_path / "new" / "sub" / "log.csv"
    p = _cli(["sim", str(sc), "-o", str(out), "--json", str(tmp_path / "j" / "run.json")], tmp_path)
    assert p.returncode == 0, p.stderr
    assert out.is_file() and out.with_suffix(".json").is_file() and (tmp_path / "j" / "run.json").is_file()
    (tmp_path / "afile").write_text("x")
    bad = tmp_path / "afile" / "log.csv"
    _assert_one_line_error(_cli(["sim", str(sc), "-o", str(bad)], tmp_path), "afile", [bad])


AXES = {
    "empty_file_is_not_an_axis": "",
    "malformed": "[stiffness\n",
    "nan": "[stiffness]\nk1_Nm_per_rad = nan\n",
    "wrong_unit_key": "[stiffness]\nk1_Nm_per_deg = 3.1e4\n",
    "wrong_type": "[stiffness]\nk1_Nm_per_rad = \"stiff\"\n",
}


@pytest.mark.parametrize("case", sorted(AXES))
def test_df_bad_axis(tmp_path: Path, case: str) -> None:
    ax = tmp_path / f"{case}.toml"
    ax.write_text(AXES[case])
    out = tmp_path / "out.json"
    p = _cli(["df", "--axis", str(ax), "--json", str(out), "--quiet"], tmp_path)
    if case == "empty_file_is_not_an_axis" and p.returncode == 0:
        pytest.skip("df accepts an empty axis file as 'all defaults'")
    _assert_one_line_error(p, ax.name, [out])


EMPS = {
    "empty": "",
    "header_only": "t,qm,qg,vir\n",
    "missing_column": "t,qm,qg\n0,0,0\n0.001,0,0\n",
    "malformed": "t,qm,qg,vir\n0,0,0,1\n0.001,zz,0,1\n",
    "nan": "t,qm,qg,vir\n0,0,0,1\n0.001,nan,0,1\n",
}


@pytest.mark.parametrize("case", sorted(EMPS))
def test_emps_bad_import(tmp_path: Path, case: str) -> None:
    src = ROOT.parent / "shared" / "data" / "emps"
    d = tmp_path / "emps"
    d.mkdir()
    if (src / "EMPS_constants.csv").exists():
        (d / "EMPS_constants.csv").write_text((src / "EMPS_constants.csv").read_text())
    else:   # shared data absent: a valid constants file, so only the record under test is bad
        (d / "EMPS_constants.csv").write_text(
            "name,value,unit,meaning\ngtau,35.15,N/V,g\nkp,160.18,1/s,p\nkv,243.45,V/(m/s),v\n"
            "Ts,0.001,s,t\nvir_saturation,10,V,s\n")
    (d / "DATA_EMPS.csv").write_text(EMPS[case])
    out = tmp_path / "emps.csv"
    p = _cli(["emps", "export", "--data", str(d), "--format", "csv", "-o", str(out)], tmp_path)
    _assert_one_line_error(p, "DATA_EMPS", [out, tmp_path / "emps.json"])


# ------------------------------------------------------------------ identified models (download, compare, test)

GOOD_MODEL = ("[gear]\nratio = 100.0\n[friction_total]\nfc_pos_Nm = 7.4\nfc_neg_Nm = 7.0\nfs_pos_Nm = 10.5\n"
              "fs_neg_Nm = 10.0\nvs_rad_s = 0.02\ndelta = 2.0\nviscous_Nms_per_rad = 5.3\n"
              "[stiffness]\nk1_Nm_per_rad = 31000.0\nk2_Nm_per_rad = 50000.0\n"
              "[hysteresis_maxwell]\nn_elements = 1\ne1_k_Nm_per_rad = 10000.0\ne1_w_Nm = 1.0\n")

#: case -> (model text, the key the error line must name)
BAD_MODELS = {
    "ratio_not_a_number": ("[gear]\nratio = \"abc\"\n", "gear.ratio"),
    "ratio_zero": ("[gear]\nratio = 0\n", "gear.ratio"),
    "no_gear": ("[stiffness]\nk1_Nm_per_rad = 3.0\n", "gear.ratio"),
    "gear_not_a_table": ("gear = 5\n", "gear"),
    "k1_missing": (GOOD_MODEL.replace("k1_Nm_per_rad = 31000.0\n", ""), "stiffness.k1_Nm_per_rad"),
    "string_for_number": (GOOD_MODEL.replace("fc_pos_Nm = 7.4", "fc_pos_Nm = \"7.4\""), "friction_total.fc_pos_Nm"),
    "nan": (GOOD_MODEL.replace("vs_rad_s = 0.02", "vs_rad_s = nan"), "friction_total.vs_rad_s"),
    "maxwell_element_missing": (GOOD_MODEL.replace("n_elements = 1", "n_elements = 2"),
                                "hysteresis_maxwell.e2_k_Nm_per_rad"),
    "negative_count": (GOOD_MODEL.replace("n_elements = 1", "n_elements = -1"), "hysteresis_maxwell.n_elements"),
    "te_harmonic_incomplete": ("[gear]\nratio = 100.0\n[transmission_error]\nwg1_order = 2\nwg1_amp_rad = 1e-5\n",
                               "transmission_error.wg1_phase_rad"),
    "bool_for_number": ("[gear]\nratio = 100.0\n[load]\njl_kgm2 = true\n", "load.jl_kgm2"),
    "not_utf8": ("[gear]\nratio = 100.0\n# \xff\xfe\n", ":3"),
    "not_toml": ("[gear\nratio = 100.0\n", "expected TOML"),
}


@pytest.fixture
def no_drive(monkeypatch):
    """Record (and refuse) every attempt to contact a drive or start a virtual one."""
    from hdservo.drive import Drive
    from hdservo.serve_proc import ServeProcess
    calls: list[str] = []

    def connect(*a, **k):
        calls.append("Drive.connect")
        raise AssertionError("a drive was contacted")

    def serve(self, *a, **k):
        calls.append("ServeProcess")
        raise AssertionError("a virtual drive was started")
    monkeypatch.setattr(Drive, "connect", classmethod(lambda cls, *a, **k: connect()))
    monkeypatch.setattr(ServeProcess, "__init__", serve)
    return calls


def _bad_model(tmp_path: Path, case: str) -> tuple[Path, str]:
    text, key = BAD_MODELS[case]
    m = tmp_path / f"{case}.toml"
    m.write_bytes(text.encode("latin-1"))
    return m, key


@pytest.mark.parametrize("case", sorted(BAD_MODELS))
def test_download_bad_model(tmp_path: Path, case: str, no_drive: list) -> None:
    m, key = _bad_model(tmp_path, case)
    out = tmp_path / "d.json"
    p = _cli(["download", str(m), "-q", "-i", "socketcand", "--port", "1", "--json", str(out)], tmp_path)
    _assert_one_line_error(p, m.name, [out])
    assert key in p.stderr, p.stderr
    assert no_drive == [], "the model must be refused before any drive is contacted"


@pytest.mark.parametrize("case", ["ratio_not_a_number", "k1_missing", "string_for_number"])
def test_compare_and_test_bad_model(tmp_path: Path, case: str, no_drive: list) -> None:
    m, key = _bad_model(tmp_path, case)
    out = tmp_path / "out.json"
    for args in (["compare", "--model", str(m), "--out-dir", str(tmp_path / "cmp"), "--json", str(out), "-q",
                  "--procedures", "positioning", "--controllers", "pid"],
                 ["test", "positioning", "--model", str(m), "--json", str(out), "-q"]):
        p = _cli(args, tmp_path)
        _assert_one_line_error(p, m.name, [out])
        assert key in p.stderr, p.stderr
    assert no_drive == []


def test_good_model_passes_the_reader(tmp_path: Path) -> None:
    """The same reader accepts a complete model (the bad cases above are refused for their defect only)."""
    from hdservo.ident.model_reader import read_model
    m = tmp_path / "good.toml"
    m.write_text(GOOD_MODEL)
    got = read_model(m)
    assert got["gear"]["ratio"] == 100.0 and got["hysteresis_maxwell"]["n_elements"] == 1
    assert got["friction_total"]["vs_rad_s"] == 0.02


def test_discrepancy_model_not_utf8(tmp_path: Path) -> None:
    log = _write_log(tmp_path, "ok", HEADER + _rows(50), {**GOOD_META, "version": 1})
    m = tmp_path / "base.toml"
    m.write_bytes(b"[model]\nstructure = \"rigid\"\n# \xff\xfe\n")
    out = tmp_path / "out.json"
    p = _cli(["discrepancy", str(log), "--model", str(m), "--json", str(out)], tmp_path)
    _assert_one_line_error(p, m.name, [out])
    assert "UTF-8" in p.stderr


# ------------------------------------------------------------------ identify --data: logs it cannot use

def _exp_log(d: Path, name: str, kind: str, segments, rows: str | None = None) -> Path:
    p = d / f"{name}.csv"
    n = 1500          # 1.5 s: the gravity fit skips the first second
    p.write_text(rows if rows is not None else
                 "t_s,motor_angle_rad,load_angle_rad,motor_torque_Nm,segment_code\n"
                 + "".join(f"{i * 0.001!r},{100 * math.sin(3 * i * 0.001)!r},{math.sin(3 * i * 0.001)!r},"
                           f"{0.5 + 0.1 * math.cos(3 * i * 0.001)!r},0\n" for i in range(n)))
    meta = {**GOOD_META, "version": 1, "experiment": kind}
    if segments is not None:
        meta["segments"] = segments
    (d / f"{name}.json").write_text(json.dumps(meta))
    return p


UNUSABLE = {
    "segment_not_listed": [{"index": 1, "settle_s": 0.01}],
    "segment_null_field": [{"index": 0, "settle_s": None}],
    "segment_not_object": [3],
    "segment_index_string": [{"index": "0"}],
    "segments_not_list": {"index": 0},
    "settle_missing": [{"index": 0}],
    "nothing_usable": None,
}


@pytest.mark.parametrize("case", sorted(UNUSABLE))
def test_identify_friction_unusable_logs(tmp_path: Path, case: str) -> None:
    g = _exp_log(tmp_path, "grav", "gravity_sine", UNUSABLE[case] if case != "settle_missing" else [{"index": 0}])
    s = _exp_log(tmp_path, "sweep", "friction_sweep", UNUSABLE[case])
    out, model = tmp_path / "out.json", tmp_path / "model.toml"
    p = _cli(["identify", "friction", "--data", str(g), "--data", str(s), "--json", str(out), "-o", str(model),
              "-q"], tmp_path)
    _assert_one_line_error(p, ".", [out, model])
    assert "grav." in p.stderr or "sweep." in p.stderr, p.stderr


def test_identify_two_logs_of_one_experiment(tmp_path: Path) -> None:
    g = _exp_log(tmp_path, "grav", "gravity_sine", [{"index": 0}])
    model = tmp_path / "model.toml"
    p = _cli(["identify", "friction", "--data", str(g), "--data", str(g), "-o", str(model), "-q"], tmp_path)
    _assert_one_line_error(p, "grav.csv", [model])
    assert "second 'gravity_sine'" in p.stderr
