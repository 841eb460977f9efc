"""Logic of tests/results/27_semi_decomposition.py (no positioning run)."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np

from hdservo.procedures import metrics as mt

ROOT = Path(__file__).resolve().parents[2]


def _script():
    spec = importlib.util.spec_from_file_location("semi_decomposition", ROOT / "tests" / "results" / "27_semi_decomposition.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def _stops(twist_up: list, twist_dn: list) -> dict:
    def side(tw: list) -> dict:
        t = np.asarray(tw, float)
        return {"motor_dev_arcsec": np.full(t.shape, 5.0).tolist(), "te_arcsec": np.full(t.shape, -1.0).tolist(),
                "twist_arcsec": t.tolist(), "gear_torque_Nm": np.full(t.shape, 7.0).tolist(),
                "out_dev_arcsec": (4.0 - t).tolist()}
    return {"up": side(twist_up), "down": side(twist_dn)}


def test_row_parts_reads_each_rows_stops(tmp_path: Path) -> None:
    m = _script()
    parts = mt.stop_error_parts(_stops([[8.0, 9.0], [8.2, 9.2], [8.1, 9.1]], [[7.0, 8.0], [7.2, 8.2], [7.1, 8.1]]))
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "test.json").write_text(json.dumps(
        {"results": {"positioning": {"figures": {"stop_error_parts_arcsec": parts}}}}))
    doc = {"controllers": {"a@semi-closed": {"json": "a/test.json", "headline": {"positioning_accuracy_arcsec": 2.5}},
                           "b@semi-closed": {"json": "b/test.json", "headline": {}}}}
    rows = m.row_parts(tmp_path, doc)
    assert rows["a@semi-closed"]["A_arcsec"] == 2.5
    got = rows["a@semi-closed"]["parts"]["parts"]["minus_twist_arcsec"]
    assert got["direction"] == parts["parts"]["minus_twist_arcsec"]["direction"]
    assert abs(got["direction"] - 1.0) < 1e-9              # 1" more twist after an approach from below
    assert rows["b@semi-closed"]["parts"] is None          # a row whose procedure wrote nothing
    text = m.table(rows)
    assert "a@semi-closed: 2.50" in text and "b@semi-closed: no stops recorded" in text
    assert "gear torque 7.00 N.m" in text
