"""On simulator logs with nothing hidden the workflow names nothing (fast subset)."""
from __future__ import annotations

from pathlib import Path

import pytest

from hdservo import logio
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_cases as cases


@pytest.mark.parametrize("axis,loop,seed", [("reference", "closed", 1), ("csf17_50", "open", 2)])
def test_no_hidden_effect_names_nothing(tmp_path: Path, axis: str, loop: str, seed: int) -> None:
    c = cases.Case(None, axis=axis, loop=loop, seed=seed)
    p = cases.make_log(c, tmp_path / "l.csv")
    r = workflow.run(signals.from_log(logio.read_log(p)))
    assert r.named == []
    b = r.baseline
    # the baseline fit recovers the axis file (J_l, K1 = K2 = K3 in these cases)
    jl = 0.5 if axis == "reference" else 0.1
    k = 3.1e4 if axis == "reference" else 8.1e3
    assert b["J_l_kgm2"] == pytest.approx(jl, rel=0.1)
    assert b["K_Nm_per_rad"] == pytest.approx(k, rel=0.1)
