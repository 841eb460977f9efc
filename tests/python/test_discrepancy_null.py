"""On simulator logs with nothing hidden the workflow names nothing (fast subset)."""
from __future__ import annotations

from pathlib import Path

import pytest

from hdservo import logio
from hdservo.discrepancy import cases, signals, workflow


@pytest.mark.parametrize("axis,loop,seed", [("reference", "closed", 1), ("reference", "closed", 2),
                                            ("csf17_50", "closed", 1)])
def test_no_hidden_effect_names_nothing(tmp_path: Path, axis: str, loop: str, seed: int) -> None:
    c = cases.Case(None, axis=axis, loop=loop, seed=seed)
    p = cases.make_log(c, tmp_path / "l.csv")
    r = workflow.run(signals.from_log(logio.read_log(p)))
    assert r.named == []
    if axis == "reference":
        # and the baseline fit recovers the reference axis (J_l 0.5 kg.m^2, K 3.1e4 N.m/rad)
        b = r.baseline
        assert b["J_l_kgm2"] == pytest.approx(0.5, rel=0.1)
        assert b["K_Nm_per_rad"] == pytest.approx(3.1e4, rel=0.1)
