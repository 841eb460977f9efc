"""Stiffness, hysteresis loss and Maxwell-slip from locked-output cycles (simulator, both axes)."""
from __future__ import annotations

import pytest

import ident_cache as cache
import ident_truth as truth
from hdservo.ident import stiffness as stf

AXES = ["reference", "csf17_50"]


@pytest.mark.parametrize("name", AXES)
def test_three_slope_within_tolerance(name: str) -> None:
    s = stf.fit_stiffness(cache.locked(name, hide=True), cache.te(name))
    a = truth.axis(name)["stiffness"]
    for key, tol in (("k1_Nm_per_rad", 0.03), ("k2_Nm_per_rad", 0.03), ("k3_Nm_per_rad", 0.03),
                     ("t1_Nm", 0.05), ("t2_Nm", 0.05)):
        assert getattr(s, key) == pytest.approx(a[key], rel=tol), key


@pytest.mark.parametrize("name", AXES)
def test_maxwell_elements_reproduce_break_force(name: str) -> None:
    s = stf.fit_stiffness(cache.locked(name, hide=True), cache.te(name))
    hm = truth.axis(name)["hysteresis_maxwell"]
    wsum = sum(hm[f"e{i}_w_Nm"] for i in range(1, hm["n_elements"] + 1))
    assert sum(s.maxwell.w_Nm) == pytest.approx(wsum, rel=0.08)
    assert 1 <= len(s.maxwell.k_Nm_per_rad) <= 8


@pytest.mark.parametrize("name", AXES)
@pytest.mark.parametrize("hide", [False, True])
def test_hysteresis_loss_catalogue_definition(name: str, hide: bool) -> None:
    s = stf.fit_stiffness(cache.locked(name, hide=hide), cache.te(name))
    want = truth.hysteresis_loss(truth.axis(name), truth.TORQUE_MAX[name], preisach=not hide)
    assert s.hysteresis_loss_rad == pytest.approx(want, rel=0.05)
    assert s.lost_motion_rad is not None and 0 < s.lost_motion_rad < s.hysteresis_loss_rad * 2


def test_uncorrected_te_biases_the_loss() -> None:
    """The kinematic error rides on the motor-encoder twist; without the TE fit the loss is off."""
    d = cache.locked("reference", hide=True)
    with_te = stf.fit_stiffness(d, cache.te("reference")).hysteresis_loss_rad
    without = stf.fit_stiffness(d, None).hysteresis_loss_rad
    want = truth.hysteresis_loss(truth.axis("reference"), 67.0, preisach=False)
    assert abs(with_te / want - 1) < abs(without / want - 1)
