"""Hysteresis is named only when it shows its loop: it must explain the equation error
better than its memoryless twin, the elements' first-loading springs sat_D(phi)/N at the
same slip twists (``workflow.twin_evidence``, ``workflow.beats_twin``).

Between two reversals of a symmetric twist cycle the twelve free-sign Maxwell-slip
elements can follow any odd memoryless spring, so they also fit a lost-motion zone, a
stiffening, or the small plant-vs-baseline mismatch of a clean log; what only hysteresis
has is the torque at equal twist depending on the direction the twist came from.

Calibration seeds of the corpus (never held-apart ones), logs from the C simulator:

* 65: no hidden effect, the drive at 1 kHz, 20/20-bit encoders.  The hysteresis candidate
  passes every other rule (47 % of the simulation error) and was named, but its twin
  explains as much of the equation error (loop Delta BIC about 7): hysteresis is not
  named now.
* 173: hysteresis hidden (1.27x), the drive at 1 kHz, 19/24 bits: the loop is clear and
  hysteresis is still named first (as on every calibration hysteresis log measured,
  docs/discrepancy.md "Hysteresis or a memoryless spring").
"""
from __future__ import annotations

from pathlib import Path

import pytest

from hdservo import logio
from hdservo.discrepancy import effects as fx
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_corpus as corpus


def _run(seed: int, tmp_path: Path) -> workflow.Result:
    case = corpus.draw(seed)
    log = corpus.make_log(case, tmp_path / f"s{seed}.csv")
    return workflow.run(signals.from_log(logio.read_log(log, require_tag=False), case.structure))


@pytest.fixture(scope="module")
def clean65(tmp_path_factory: pytest.TempPathFactory) -> workflow.Result:
    return _run(65, tmp_path_factory.mktemp("s65"))


def _hysteresis(res: workflow.Result) -> dict:
    (h,) = [c for c in res.ranking_first if c["effect"] == "hysteresis"]
    return h


def test_a_clean_log_whose_hysteresis_has_no_loop_does_not_name_it(clean65: workflow.Result) -> None:
    case = corpus.draw(65)
    assert case.hidden == [] and case.angles == "both"
    res = clean65
    assert "hysteresis" not in res.named
    h = _hysteresis(res)
    assert h["significant"] is False
    s = workflow.Settings().for_signals(res.angles)
    # every rule but the loop passes: without it the candidate would be named
    assert workflow.size(h) >= s.frac_min
    assert workflow.admissible(h, s) and h["total_delta_bic"] > s.bic_min
    assert h["twin_delta_bic"] < s.bic_min
    assert not workflow.beats_twin(h, s)


def test_hidden_hysteresis_shows_its_loop_and_is_named_first(tmp_path: Path) -> None:
    case = corpus.draw(173)
    assert [e for e, _ in case.hidden] == ["hysteresis"] and case.angles == "both"
    res = _run(173, tmp_path)
    h = _hysteresis(res)
    s = workflow.Settings().for_signals(res.angles)
    assert h["twin_delta_bic"] > 10 * s.bic_min
    assert h["significant"] is True
    assert res.named[:1] == ["hysteresis"]


def test_the_twin_has_the_same_slip_twists_and_no_memory(clean65: workflow.Result) -> None:
    """The twin's columns are the elements' first-loading curves sat_D(phi)/N at the same
    slip twists, taken along the measured twist (no state function), like the stops."""
    res = clean65
    d = res.state.design
    hyst = fx.Hysteresis()
    (v,) = list(hyst.variants(d, next(iter(res.base_fit.resid.values()))))
    tw = hyst.twin(d, v)
    assert tw.hyper["thresholds_rad"] == v.hyper["thresholds_rad"]
    assert len(tw.columns) == len(v.columns)
    phi = d.sig.phi
    for c, D in zip(tw.columns, v.hyper["thresholds_rad"]):
        assert c.fn is None                        # taken along the measured twist, like the stops
        assert abs(float(c.M[0]) * d.sig.ratio - max(-D, min(D, float(phi[0])))) < 1e-12
