"""Stiffness, hysteresis loss and Maxwell-slip from locked-output cycles (simulator, both axes).

Every effect on: the plant's Preisach term, Maxwell-slip elements, TE, sensor noise and
quantisation; the fitter is given only the data (and the identified TE).
"""
from __future__ import annotations

import pytest

import ident_cache as cache
import ident_truth as truth
from hdservo.ident import stiffness as stf

AXES = ["reference", "csf17_50"]


@pytest.mark.parametrize("name", AXES)
def test_three_slope_within_tolerance(name: str) -> None:
    s = cache.stiffness(name)
    a = truth.axis(name)["stiffness"]
    for key, tol in (("k1_Nm_per_rad", 0.03), ("k2_Nm_per_rad", 0.03), ("k3_Nm_per_rad", 0.03),
                     ("t1_Nm", 0.05), ("t2_Nm", 0.05)):
        assert getattr(s, key) == pytest.approx(a[key], rel=tol), key


@pytest.mark.parametrize("name", AXES)
def test_maxwell_elements_reproduce_break_force(name: str) -> None:
    s = cache.stiffness(name)
    hm = truth.axis(name)["hysteresis_maxwell"]
    wsum = sum(hm[f"e{i}_w_Nm"] for i in range(1, hm["n_elements"] + 1))
    assert sum(s.maxwell.w_Nm) == pytest.approx(wsum, rel=0.08)
    assert 1 <= len(s.maxwell.k_Nm_per_rad) <= 8


@pytest.mark.parametrize("name", AXES)
def test_hysteresis_loss_catalogue_definition(name: str) -> None:
    s = cache.stiffness(name)
    want = truth.hysteresis_loss(truth.axis(name), truth.TORQUE_MAX[name])
    assert s.hysteresis_loss_rad == pytest.approx(want, rel=0.05)
    assert s.lost_motion_rad is not None and 0 < s.lost_motion_rad < s.hysteresis_loss_rad * 2


def test_without_the_odd_band_the_preisach_term_bends_the_spring() -> None:
    """The plant's Preisach loop sits inside the K1 region; a spring + Maxwell-slip fit alone
    absorbs it as a softer K1 / lower T2 (the reason for the odd band)."""
    a = truth.axis("reference")["stiffness"]
    plain = stf.fit_stiffness(cache.locked("reference"), cache.te("reference"), odd_fractions=())
    good = cache.stiffness("reference")
    assert abs(plain.k1_Nm_per_rad / a["k1_Nm_per_rad"] - 1) > 0.03
    assert plain.residual_rms_Nm > 1.5 * good.residual_rms_Nm
    assert good.odd_band_rad > 0.0


def test_uncorrected_te_biases_the_loss() -> None:
    """The kinematic error rides on the motor-encoder twist; without the TE fit the loss is off."""
    d = cache.locked("reference")
    seg = d.segment(0)
    T, cmd = seg["load_torque_Nm"], seg["torque_cmd_Nm"]
    t_max = float(abs(T).max())
    with_te = stf.hysteresis_loss(T, stf.twist_of(seg, d.gear_ratio, cache.te("reference")), cmd, t_max)
    without = stf.hysteresis_loss(T, stf.twist_of(seg, d.gear_ratio, None), cmd, t_max)
    want = truth.hysteresis_loss(truth.axis("reference"), 67.0)
    assert abs(with_te / want - 1) < abs(without / want - 1)
