"""One-encoder logs: the rigid baseline's torque offset is estimated at standstill, and no
candidate takes up a constant torque while the axis moves.

On one coordinate a constant torque while moving is the offset, a Coulomb level that
differs between directions, or the mean of an unbalance over the angles travelled: the
standstill median anchors the offset only within the static friction band (a hold ends
wherever the axis stuck), so a candidate that could take up a constant would name a
false effect whenever a long hold ended on one side of that band.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hdservo import logio
from hdservo.discrepancy import effects as fx
from hdservo.discrepancy import regression as bl
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_corpus as corpus

#: Calibration logs (never held-apart ones): motor encoder only, plain P-PI cascade.
#: 70: asymmetric friction hidden at 1.24x, 2 kHz; 225: nothing hidden, 1 kHz (its
#: standstill offset is a long hold's torque: the constant columns named a false
#: asymmetric friction explaining 78 % of the simulation error).
ASYM, CLEAN = 70, 225


def _signals(tmp_path: Path, seed: int) -> signals.Signals:
    case = corpus.draw(seed)
    assert case.angles == "motor"
    p = corpus.make_log(case, tmp_path / f"l{seed}.csv")
    return signals.from_log(logio.read_log(p, require_tag=False), case.structure)


def test_clean_motor_only_log_names_nothing(tmp_path: Path) -> None:
    case = corpus.draw(CLEAN)
    assert case.hidden == []
    res = workflow.run(_signals(tmp_path, CLEAN))
    assert res.named == []
    first = {c["effect"]: c for c in res.ranking_first}
    for e in ("asymmetric_friction", "gravity_unbalance"):
        assert not first[e]["significant"] and first[e]["explained_fraction"] < 0.05


def test_candidates_cannot_make_up_a_constant_and_keep_the_physical_offset(tmp_path: Path) -> None:
    sig, d, cols, _ = workflow._prepare(_signals(tmp_path, ASYM), None)
    off = next(c for c in cols if c.name == "offset")
    # the offset is the standstill median, held fixed
    assert off.fixed is not None and off.fixed == bl.standstill_offset(d)
    st = workflow.State.start(d, cols)
    for eff in (fx.Asymmetric(), fx.Gravity()):
        (v,) = list(eff.variants(d, np.zeros(0)))
        assert "dFc_asym" not in [c.name for c in v.columns]
        for c in v.columns:
            # centred on the fitted samples: orthogonal to a constant there
            x = d.stack(c)
            assert abs(float(np.mean(x))) < 1e-3 * float(np.sqrt(np.mean(x ** 2)))
            assert c.shift != 0.0
        f = st.solve(v)
        p = f.params()
        # the physical offset is the fixed one less what the centring took off, so the
        # uncentred columns plus it give the same model torque
        shift = sum(p[c.name] * c.shift for c in v.columns)
        assert p["offset"] == pytest.approx(off.fixed - shift)
        # a rebuilt variant (noise images) has the same columns and centring
        w = eff.rebuild(d, v)
        assert [c.name for c in w.columns] == [c.name for c in v.columns]
        assert [c.shift for c in w.columns] == pytest.approx([c.shift for c in v.columns])


def test_a_baseline_without_offset_leaves_the_constant_to_the_asymmetry(tmp_path: Path) -> None:
    sig, d, cols, _ = workflow._prepare(_signals(tmp_path, ASYM), False)
    assert not any(c.name == "offset" for c in cols)
    (v,) = list(fx.Asymmetric().variants(d, np.zeros(0)))
    assert [c.name for c in v.columns] == ["dFv_asym", "dFc_asym"] and all(c.shift == 0.0 for c in v.columns)
    (g,) = list(fx.Gravity().variants(d, np.zeros(0)))
    assert all(c.shift == 0.0 for c in g.columns) and g.hyper == {}


def test_standstill_offset_needs_enough_standstill(tmp_path: Path) -> None:
    sig = _signals(tmp_path, ASYM)
    d = bl.make_design(sig)
    assert bl.standstill_offset(d) is not None
    moving = bl.Design(sig=d.sig, v_eps=0.0, mask=d.mask, equations=d.equations)   # nothing counts as standing
    assert bl.standstill_offset(moving) is None
    free = next(c for c in bl.baseline_columns(moving) if c.name == "offset")
    assert free.fixed is None
    assert np.isfinite(bl.solve(moving, bl.baseline_columns(moving), {}).params()["offset"])
