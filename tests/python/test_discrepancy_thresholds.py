"""The per-signal-set size thresholds: the false-alarm rule, its inputs in the package data
(measured on calibration logs only) and their use by the workflow."""
from __future__ import annotations

from pathlib import Path

import pytest

from hdservo import logio
from hdservo.discrepancy import signals, thresholds, workflow
from oracles import discrepancy_cases as cases
from oracles import discrepancy_corpus as corpus


def test_rule_is_the_quantile_plus_margin_never_below_the_default() -> None:
    # 20 clean logs: 18 silent, two with a significant candidate explaining 40 % and 70 %
    sizes = [0.0] * 18 + [0.4, 0.7]
    # the 95 % quantile interpolates at rank 0.95 * 19 = 18.05, between 0.4 and 0.7
    assert thresholds.rule(sizes, 0.30, 0.95, 0.01) == pytest.approx(0.4 + 0.05 * (0.7 - 0.4) + 0.01)
    assert thresholds.rule(sizes, 0.30, 0.90, 0.01) == 0.30          # the 90 % quantile is 0 (silent logs)
    assert thresholds.rule([0.2, 0.25], 0.30, 0.95, 0.01) == 0.30    # below the default: the default
    assert thresholds.rule([], 0.30, 0.95, 0.01) == 0.30             # no clean log of that set
    assert thresholds.rule(sizes, 0.30, 0.95, 0.01, min_logs=20) > 0.30
    assert thresholds.rule(sizes[1:], 0.30, 0.95, 0.01, min_logs=20) == 0.30   # 19 logs: too few
    assert thresholds.from_inputs({"default": 0.3, "quantile": 1.0, "margin": 0.01,
                                   "largest_sizes": {"output": [0.0, 0.45]}}) == \
        {"both": 0.3, "motor": 0.3, "output": pytest.approx(0.46)}


def test_package_data_holds_calibration_inputs_with_provenance() -> None:
    doc = thresholds.load()
    assert doc["default"] == workflow.Settings().frac_min
    assert doc["min_logs"] == round(1 / (1 - doc["quantile"]))
    assert doc["set"] == "calibration"
    lo, hi = doc["seeds_analysed"]
    assert corpus.CALIBRATION_SEEDS.start <= lo <= hi < corpus.CALIBRATION_SEEDS.stop
    assert all(s in corpus.CALIBRATION_SEEDS for s in doc["census_seeds"])
    for a, seeds in doc["clean_seeds"].items():
        assert a in thresholds.SETS
        # one input per clean calibration log of that signal set, each a clean log of it
        assert len(doc["largest_sizes"][a]) == len(seeds)
        for s in seeds:
            assert s in corpus.CALIBRATION_SEEDS and s not in corpus.HELD_APART_SEEDS
            c = corpus.draw(s)
            assert c.hidden == [] and c.angles == a
        assert all(0.0 <= x <= 1.0 for x in doc["largest_sizes"][a])


def test_workflow_settings_are_the_rule_on_the_package_data() -> None:
    want = thresholds.from_inputs(thresholds.load())
    s = workflow.Settings()
    for a in thresholds.SETS:
        assert s.for_signals(a).frac_min == pytest.approx(want[a])


class _Stop(Exception):
    pass


def test_run_names_with_the_threshold_of_the_logs_signal_set(tmp_path: Path, monkeypatch) -> None:
    p = cases.make_log(cases.Case(None, axis="reference", loop="closed", seed=1), tmp_path / "l.csv")
    sig = signals.from_log(logio.read_log(p))
    assert sig.angles == "both"
    seen: list[float] = []

    def naming(st_, lib, s):
        seen.append(s.frac_min)
        raise _Stop

    monkeypatch.setattr(workflow, "_name_effects", naming)
    monkeypatch.setattr(workflow, "FRAC_MIN_BY_SIGNALS", {"both": 0.77, "output": 0.55})
    with pytest.raises(_Stop):
        workflow.run(sig)
    with pytest.raises(_Stop):                                    # explicit settings keep their own
        workflow.run(sig, workflow.Settings(frac_min_by_signals={"motor": 0.9}))
    assert seen == [0.77, 0.30]
