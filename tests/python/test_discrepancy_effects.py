"""One hidden effect per simulator log: the workflow names it and the RMS gap shrinks >= 3x
(fast subset; the full confusion table is tests/results/40_discrepancy.py)."""
from __future__ import annotations

from pathlib import Path

import pytest

from hdservo import logio
from hdservo.discrepancy import cases, signals, workflow


@pytest.mark.parametrize("effect,axis,loop,seed", [
    ("transmission_error", "reference", "closed", 1),
    ("gravity_unbalance", "csf17_50", "open", 1),
])
def test_hidden_effect_is_named_and_gap_shrinks(tmp_path: Path, effect: str, axis: str, loop: str,
                                                seed: int) -> None:
    c = cases.Case(effect, axis=axis, loop=loop, seed=seed, size=seed % 2)
    p = cases.make_log(c, tmp_path / "l.csv")
    r = workflow.run(signals.from_log(logio.read_log(p), c.structure))
    assert r.named and r.named[0] == effect
    assert r.rms_history[0] / r.rms_history[-1] >= 3.0
    ev = r.iterations[0]["evidence"]
    assert ev["delta_bic"] > 10 and ev["p_value"] < 1e-3
