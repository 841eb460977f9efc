"""Logic of the held-apart validation (tests/results/47_discrepancy_heldout.py) and its corpus
(oracles/discrepancy_corpus.py) on a tiny grid; the full corpus runs in `make results`."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from hdservo import logio
from hdservo.discrepancy import EFFECT_NAMES, IDENTIFIABLE, not_identifiable_parts
from oracles import discrepancy_corpus as corpus

REPO = Path(__file__).parents[2]


def _script():
    spec = importlib.util.spec_from_file_location("heldout", REPO / "tests" / "results" / "47_discrepancy_heldout.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def test_split_is_fixed_and_disjoint() -> None:
    assert corpus.split_is_disjoint()
    assert corpus.CALIBRATION_SEEDS == range(1, 1001) and corpus.HELD_APART_SEEDS == range(100001, 101001)
    assert corpus.draw(100001).label == corpus.draw(100001).label          # a seed draws one case


def test_draws_cover_the_ranges() -> None:
    cases = [corpus.draw(s) for s in range(1, 121)]
    ratios = {c.axis["gear"]["ratio"] for c in cases}
    assert ratios <= {30, 50, 80, 100, 120, 160} and len(ratios) >= 5
    mb = [c.motor_bits for c in cases if c.motor_bits]
    lb = [c.load_bits for c in cases if c.load_bits]
    assert min(mb) >= 14 and max(mb) <= 20 and min(lb) >= 18 and max(lb) <= 24
    assert {c.angles for c in cases} == {"both", "motor", "output"}
    assert {c.log_rate_Hz for c in cases} == {1000.0, 2000.0, 10000.0}
    assert {c.controller["kind"] for c in cases} == {"drive", "ppi"}
    assert {c.controller["fb_config"] for c in cases if c.controller["kind"] == "drive"} == {0, 1, 2}
    assert {c.controller["rate_Hz"] for c in cases if c.controller["kind"] == "ppi"} == {1000.0, 2000.0}
    assert {len(c.hidden) for c in cases} == {0, 1, 2}
    sizes = [g for c in cases for _, g in c.hidden]
    assert 0.5 <= min(sizes) and max(sizes) <= 1.5
    assert {e for c in cases for e, _ in c.hidden} == set(EFFECT_NAMES)
    for c in cases:
        names = [e for e, _ in c.hidden]
        assert len(set(names)) == len(names)
        assert "unmodelled_compliance" not in names or c.angles == "both"
        # the table's rows, and a Coulomb-only asymmetry only where the baseline has no offset
        coulomb = {"asymmetric_friction"} if not_identifiable_parts(c.structure) else set()
        assert set(c.identifiable()) == (set(names) & set(IDENTIFIABLE[c.angles])) - coulomb


def test_ppi_cascade_log_is_a_users_log_that_tracks(tmp_path: Path) -> None:
    seed = next(s for s in range(1, 200) if corpus.draw(s).controller["kind"] == "ppi"
                and corpus.draw(s).angles == "both" and corpus.draw(s).log_rate_Hz == 1000.0)
    case = corpus.draw(seed)
    p = corpus.make_log(case, tmp_path / "l.csv")
    import json
    assert set(json.loads(p.with_suffix(".json").read_text())) == {"gear_ratio", "sample_period_s"}
    log = logio.read_log(p, require_tag=False)
    assert log.meta["sample_period_s"] == pytest.approx(1e-3)
    ref = corpus.reference(case.motion, log.t)
    err = log["load_angle_rad"] - ref
    assert float(np.ptp(ref)) > 0.3 and float(np.sqrt(np.mean(err ** 2))) < 0.1 * float(np.ptp(ref))


def test_score_and_confidence_intervals() -> None:
    m = _script()
    lo, hi = m.wilson(9, 10)
    assert lo == pytest.approx(0.5958, abs=1e-3) and hi == pytest.approx(0.9821, abs=1e-3)
    med, a, b = m.median_ci(list(range(1, 21)))
    assert med == 10.5 and a == 6 and b == 15
    r = [
        {"hidden": ["cogging_torque"], "identifiable": ["cogging_torque"], "named": ["cogging_torque"], "sim_shrink": 4.0},
        {"hidden": ["cogging_torque"], "identifiable": ["cogging_torque"], "named": ["backlash", "cogging_torque"],
         "sim_shrink": 1.5},
        {"hidden": ["hysteresis"], "identifiable": ["hysteresis"], "named": ["hysteresis", "backlash"], "sim_shrink": 2.0},
        {"hidden": [], "identifiable": [], "named": [], "sim_shrink": None},
        {"hidden": [], "identifiable": [], "named": ["current_loop_lag"], "sim_shrink": None},
        {"hidden": ["gravity_unbalance", "backlash"], "identifiable": ["gravity_unbalance", "backlash"],
         "hidden_by_size": ["backlash", "gravity_unbalance"], "named": ["backlash", "gravity_unbalance"],
         "sim_shrink": 9.0},
        {"hidden": ["hysteresis"], "identifiable": [], "named": [], "sim_shrink": None},
        {"hidden": ["hysteresis"], "identifiable": ["hysteresis"], "named": [], "error": "UserError: x"},
        # named in the other order, but ordered right by explained variance
        {"hidden": ["stribeck_friction", "cogging_torque"], "identifiable": ["stribeck_friction", "cogging_torque"],
         "hidden_by_size": ["cogging_torque", "stribeck_friction"], "named": ["stribeck_friction", "cogging_torque"],
         "named_by_size": ["cogging_torque", "stribeck_friction"], "sim_shrink": None},
    ]
    s = m.score(r)
    assert s["single_named_first"]["k"] == 2 and s["single_named_first"]["n"] == 3
    assert s["single_named_first_per_effect"]["cogging_torque"]["k"] == 1
    assert s["false_alarm"]["k"] == 1 and s["false_alarm"]["n"] == 2
    assert s["spurious"]["k"] == 2 and s["spurious"]["n"] == 6
    assert s["two_both_named"]["k"] == 2 and s["two_named_in_order"]["k"] == 2
    assert s["median_sim_shrink"]["median"] == 4.0 and s["median_sim_shrink"]["n"] == 3
    assert s["hidden_not_identifiable_silent"]["k"] == 1 and s["refused_or_failed"] == 1
    assert math.isnan(m.wilson(0, 0)[0])
