"""Discrepancy workflow on real data: EMPS (the records shipped with the package)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from hdservo import cli, emps
from hdservo.discrepancy import realdata


@pytest.fixture(scope="module")
def emps_train():
    try:
        d = emps.resolve_data_dir()
    except cli.UserError as e:
        pytest.skip(f"EMPS data not available: {e}")
    return emps.load_benchmark_record(d, emps.TRAIN_RECORD)


def test_emps_names_asymmetric_friction_and_reaches_published_error(emps_train, tmp_path: Path) -> None:
    log = tmp_path / "emps.csv"
    emps.write_log(emps_train, log)
    out = tmp_path / "out.json"
    assert cli.main(["discrepancy", str(log), "--json", str(out), "--out-dir", str(tmp_path / "plots")]) == 0
    res = json.loads(out.read_text())
    assert res["structure"] == "rigid"
    # the rigid baseline is the symmetric inverse model: close to the published IDIM-LS values
    b = res["baseline"]
    assert b["J"] == pytest.approx(95.1089, rel=0.02)
    assert b["Fv"] == pytest.approx(203.5034, rel=0.02)
    assert b["Fc"] == pytest.approx(20.3935, rel=0.02)
    assert res["named_effects"][0] == "asymmetric_friction"
    it = res["iterations"][0]
    assert it["rms_after"] < it["rms_before"]
    # the named effect, in the authors' IDIM-LS chain: training relative force error <= 3.2 %
    chk = realdata.idim_relative_error(emps_train, it["named_effect"], it["params"])
    assert chk["symmetric_relative_error_pct"] == pytest.approx(4.0834, abs=0.01)
    assert chk["relative_error_pct"] <= 3.2
    assert (tmp_path / "plots" / "gap.png").is_file()
