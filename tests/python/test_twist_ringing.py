"""Logic of tests/results/27_twist_ringing.py on synthetic signals and one short run."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _script():
    spec = importlib.util.spec_from_file_location("twist_ringing_results", ROOT / "tests" / "results" / "27_twist_ringing.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def test_swing_ratio_of_a_rigid_and_a_ringing_load() -> None:
    m = _script()
    t = np.arange(0.0, 1.0, 1e-4)
    a_ref = 2.0
    a = np.where(t < 0.3, a_ref, np.where(t < 0.6, -a_ref, 0.0))          # rigid: the reference itself
    v = np.cumsum(a) * 1e-4
    assert m.swing_ratio(t, v, a_ref) == pytest.approx(1.0, abs=0.02)
    ring = a + 3.0 * a_ref * np.sin(2 * math.pi * 30.0 * t) * (t > 0.6) * np.exp(-(t - 0.6) * 5)
    v2 = np.cumsum(ring) * 1e-4
    assert m.swing_ratio(t, v2, a_ref) > 2.5                                  # the ringing: ~3.5x
    assert m.swing_ratio(t, v2, a_ref, after_s=0.62) > 2.0                    # left at the stop
    assert m.swing_ratio(t, v, a_ref, after_s=0.62) == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(ValueError):
        m.swing_ratio(t, v, 0.0)
    with pytest.raises(ValueError):
        m.swing_ratio(t, v, a_ref, after_s=2.0)


def test_edge_ratio() -> None:
    m = _script()
    rows = [{"resonance_over_loop": 0.9, "swing_ratio": 3.0}, {"resonance_over_loop": 1.4, "swing_ratio": 2.5},
            {"resonance_over_loop": 2.0, "swing_ratio": 1.2}]
    assert m.edge_ratio(rows, 2.0) == 1.4
    assert m.edge_ratio(rows, 5.0) is None


def test_one_move_on_the_reference_axis() -> None:
    m = _script()
    from hdservo import resources
    row = m.run_one(Path(resources.axis_file("reference")), 25.0)
    assert row["f_v_hz"] == pytest.approx(25.0, rel=1e-3)
    assert row["f_load_hz"] == pytest.approx(39.6, abs=0.1)
    assert row["swing_ratio"] > 1.0                  # a real load never swings less than the reference
    assert 0.0 < row["stop_swing_ratio"] < row["swing_ratio"]
