"""Logic of tests/results/27_twist_source_edge.py (no positioning run)."""
from __future__ import annotations

import importlib.util
import tomllib
from pathlib import Path

import pytest

from hdservo import axisgen
from hdservo.download import plan_download

ROOT = Path(__file__).resolve().parents[2]


def _script():
    spec = importlib.util.spec_from_file_location("twist_source_edge", ROOT / "tests" / "results" / "27_twist_source_edge.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def test_band_summary() -> None:
    m = _script()
    rows = [{"resonance_over_loop": 0.7, "a_model_arcsec": 12.0, "a_motor_arcsec": 6.0},
            {"resonance_over_loop": 1.2, "a_model_arcsec": 5.0, "a_motor_arcsec": 5.0},
            {"resonance_over_loop": 1.5, "a_model_arcsec": 4.0, "a_motor_arcsec": 5.0},
            {"resonance_over_loop": 2.0, "a_model_arcsec": 8.0, "a_motor_arcsec": 8.0},
            {"resonance_over_loop": 3.0, "a_model_arcsec": None, "a_motor_arcsec": 8.0}]
    s = m.band_summary(rows, 1.5)
    assert s["below"] == [1.0, 2.0]
    assert s["above"] == pytest.approx([0.8, 1.0])
    assert m.band_summary(rows[:2], 1.5)["above"] is None


def test_true_model_downloads_with_the_axis_table(tmp_path: Path) -> None:
    m = _script()
    ax = axisgen.write_axes(tmp_path, 1, seed=103)[0]
    mp = m.true_model(ax, tmp_path)
    model = tomllib.loads(mp.read_text())
    assert model["identified"]["preisach_table"] == "preisach.bin"
    plan = plan_download(mp, str(ax))
    assert plan["preisach"] == (tmp_path / "preisach.bin").read_bytes()
    assert plan["params"]["pr_jl"] == pytest.approx(tomllib.loads(ax.read_text())["load"]["jl_kgm2"])
