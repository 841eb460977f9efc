"""Stribeck feed-forward levels of an identified model: the motor side's share of the total friction.

On the measured velocity the feed-forward is a relay at standstill; relaying the output-side friction
too (behind the gear's spring) scatters the stops (docs/compensators.md, "Unseen axes").  The share
comes from the locked-output presliding breakaway (motor side alone) and the friction sweep (total).
"""
from __future__ import annotations

import pytest

from hdservo import compsetup as cs
from hdservo import download as dl
from hdservo import sim

TOTAL = {"fc_pos_Nm": 2.6, "fc_neg_Nm": 2.5, "fs_pos_Nm": 3.7, "fs_neg_Nm": 3.5, "vs_rad_s": 0.01,
         "delta": 2.0, "viscous_Nms_per_rad": 3.0}


def _model(bk_pos: float | None, bk_neg: float | None, ratio: float = 80.0) -> dict:
    fm: dict = {"sigma0_Nm_per_rad": 38.0}
    if bk_pos is not None:
        fm["presliding_breakaway_pos_Nm"] = bk_pos
    if bk_neg is not None:
        fm["presliding_breakaway_neg_Nm"] = bk_neg
    return {"gear": {"ratio": ratio}, "friction_total": dict(TOTAL), "friction_motor": fm}


def _params(model: dict) -> dict:
    over, notes = dl.model_overrides(model, lambda k: float(sim.axis_param(k, "reference")))
    return cs.compensator_params("reference", model=over), over, notes


def test_share_from_the_presliding_breakaway() -> None:
    m = _model(0.0324, 0.0336)                              # motor units, N = 80
    share = 80 * (0.0324 + 0.0336) / (3.7 + 3.5)
    assert dl.motor_share(m) == pytest.approx(share)
    assert dl.motor_share(_model(0.1, 0.1)) == 1.0          # at most the total
    assert dl.motor_share(_model(None, 0.03)) is None        # no presliding fit: no share
    assert dl.motor_share({"gear": {"ratio": 80.0}, "friction_total": dict(TOTAL)}) is None


def test_stribeck_levels_are_the_motor_share_of_the_total() -> None:
    m = _model(0.0324, 0.0336)
    share = dl.motor_share(m)
    p, over, notes = _params(m)
    assert over[cs.MOTOR_SHARE_KEY] == pytest.approx(share)
    assert any("motor side's share" in n for n in notes)
    for k, tot in (("str_fs_pos", 3.7), ("str_fs_neg", 3.5), ("str_fc_pos", 2.6), ("str_fc_neg", 2.5)):
        assert p[k] == pytest.approx(share * tot, rel=1e-12), k
    # the viscous part is no relay: the whole viscous friction stays fed forward
    assert p["str_fv_pos"] == pytest.approx(3.0 * 2 * 3.141592653589793, rel=1e-12)
    # LuGre (reference velocity) and backstepping keep the total
    assert p["lug_fs"] == pytest.approx(3.6, rel=1e-12)
    p1, _, _ = _params({k: v for k, v in _model(None, None).items()})
    assert p1["str_fs_pos"] == pytest.approx(3.7, rel=1e-12)
    for k in p1:
        if k.startswith("bs_"):
            assert p[k] == p1[k], k


def test_axis_file_levels_unchanged() -> None:
    """Without an identified model the true sides are summed as before (reference 100 x 0.1 + 0.6)."""
    assert cs.compensator_params("reference")["str_fs_pos"] == pytest.approx(10.6)
