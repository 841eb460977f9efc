"""A baseline residual that is mostly a constant is measured and reported.

On one-encoder calibration logs with a hidden gravity unbalance that the workflow misses,
the rigid baseline's equation error is 89-99.7 % a constant: the offset is held at the
standstill torque, which the static friction anchors only within its band, and the
torque while moving differs from it.  A centred unbalance cannot make up a constant, so
its explained fraction is taken against that constant (docs/discrepancy.md, "Single
effects missed on calibration logs").  The run reports the share
(``baseline_constant_share``) and says so in ``notes``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hdservo import logio
from hdservo.discrepancy import regression as bl
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_corpus as corpus

#: Calibration logs (never held-apart ones), motor encoder only, gravity unbalance hidden:
#: 26 (2 kHz, 1.13x) is missed by the size rule, 331 (1 kHz, 1.39x) is named.
MISSED, NAMED = 26, 331


def _fit(resid: dict[str, np.ndarray]) -> bl.Fit:
    return bl.Fit(theta=np.zeros(1), names=["x"], resid=resid, rss_w=0.0, n_params=1)


def test_constant_share_splits_the_sum_of_squares_into_mean_and_spread() -> None:
    rng = np.random.default_rng(1)
    noise = rng.standard_normal(4000)
    noise -= noise.mean()
    noise /= noise.std()                      # mean 0, RMS 1 exactly
    # constant 2 on unit spread: 4 / (4 + 1)
    assert abs(bl.constant_share(_fit({"R": 2.0 + noise})) - 0.8) < 1e-12
    assert abs(bl.constant_share(_fit({"R": noise}))) < 1e-12
    assert bl.constant_share(_fit({"R": np.zeros(10)})) == 0.0
    # pooled over the equations with their weights: M carries no constant, R is all
    # constant; weighted 1:1 half the sum of squares is the constant, 1:3 a tenth
    eqs = {"M": noise, "R": np.ones(4000)}
    assert abs(bl.constant_share(_fit(eqs)) - 0.5) < 1e-12
    assert abs(bl.constant_share(_fit(eqs), {"M": 3.0, "R": 1.0}) - 0.1) < 1e-12
    assert abs(bl.residual_mean(_fit(eqs)) - 0.5) < 1e-12


def _run(tmp_path: Path, seed: int) -> workflow.Result:
    case = corpus.draw(seed)
    assert case.angles == "motor" and [e for e, _ in case.hidden] == ["gravity_unbalance"]
    p = corpus.make_log(case, tmp_path / f"l{seed}.csv")
    return workflow.run(signals.from_log(logio.read_log(p, require_tag=False), case.structure))


def test_a_residual_that_is_mostly_a_constant_is_reported(tmp_path: Path) -> None:
    res = _run(tmp_path, MISSED)
    share = res.to_json()["baseline_constant_share"]
    assert share >= workflow.CONSTANT_NOTE_SHARE
    assert share == bl.constant_share(res.base_fit, res.state.weights)
    notes = [n for n in res.notes if "a constant (" in n]
    assert len(notes) == 1 and f"{100 * share:.0f} % a constant" in notes[0]
    assert "standstill torque" in notes[0]      # the rigid baseline's offset is held there
    # sized against that constant, the unbalance explains almost nothing of the residual
    grav = next(c for c in res.ranking_first if c["effect"] == "gravity_unbalance")
    assert grav["explained_fraction"] < 0.05


def test_a_residual_without_a_large_constant_has_no_note(tmp_path: Path) -> None:
    res = _run(tmp_path, NAMED)
    assert res.to_json()["baseline_constant_share"] < workflow.CONSTANT_NOTE_SHARE
    assert not [n for n in res.notes if "a constant (" in n]
    assert "gravity_unbalance" in res.named
