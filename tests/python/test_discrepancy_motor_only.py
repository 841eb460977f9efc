"""Motor-encoder-only logs: the rigid baseline's torque offset is estimated at standstill,
so a Coulomb level that differs between directions stays visible to the workflow."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hdservo import logio
from hdservo.discrepancy import regression as bl
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_corpus as corpus

#: A calibration log (never a held-apart one): motor encoder only, plain P-PI cascade at
#: 2 kHz, asymmetric friction hidden at 1.24x its typical size, nothing else.
SEED = 70


def _signals(tmp_path: Path) -> signals.Signals:
    case = corpus.draw(SEED)
    assert case.angles == "motor" and [e for e, _ in case.hidden] == ["asymmetric_friction"]
    p = corpus.make_log(case, tmp_path / "l.csv")
    return signals.from_log(logio.read_log(p, require_tag=False), case.structure)


def test_motor_only_log_names_asymmetric_friction(tmp_path: Path) -> None:
    sig = _signals(tmp_path)
    res = workflow.run(sig)
    assert res.named[:1] == ["asymmetric_friction"]
    d = bl.make_design(sig)
    cols = bl.baseline_columns(d)
    off = next(c for c in cols if c.name == "offset")
    # the offset is the standstill median, held fixed: the direction asymmetry of the
    # moving samples is not taken up by it
    assert off.fixed is not None and off.fixed == bl.standstill_offset(d)
    still_free = bl.solve(d, bl.baseline_columns(d, True), {}).params()["offset"]
    assert abs(off.fixed) < 0.2 * abs(still_free)
    assert res.baseline["offset"] == off.fixed


def test_standstill_offset_needs_enough_standstill(tmp_path: Path) -> None:
    sig = _signals(tmp_path)
    d = bl.make_design(sig)
    assert bl.standstill_offset(d) is not None
    moving = bl.Design(sig=d.sig, v_eps=0.0, mask=d.mask, equations=d.equations)   # nothing counts as standing
    assert bl.standstill_offset(moving) is None
    free = next(c for c in bl.baseline_columns(moving) if c.name == "offset")
    assert free.fixed is None
    assert np.isfinite(bl.solve(moving, bl.baseline_columns(moving), {}).params()["offset"])
