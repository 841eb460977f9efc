"""Friction identification on simulator data (both axes, every effect on, noise and quantisation)."""
from __future__ import annotations

import pytest

import ident_cache as cache
import ident_truth as truth
from hdservo.ident import stribeck_online as so

AXES = ["reference", "csf17_50"]


@pytest.mark.parametrize("name", AXES)
def test_stribeck_batch_within_tolerance(name: str) -> None:
    _, _, res = cache.friction(name)
    t = truth.friction_total(truth.axis(name))
    for key, tol in (("fs_pos_Nm", 0.03), ("fs_neg_Nm", 0.03), ("fc_pos_Nm", 0.03), ("fc_neg_Nm", 0.03),
                     ("vs_rad_s", 0.10), ("viscous_Nms_per_rad", 0.05)):
        assert getattr(res, key) == pytest.approx(t[key], rel=tol), key
    # the direction asymmetry is seen with the right sign
    assert (res.fs_pos_Nm - res.fs_neg_Nm) * (t["fs_pos_Nm"] - t["fs_neg_Nm"]) > 0


@pytest.mark.parametrize("name", AXES)
def test_gravity_unbalance(name: str) -> None:
    g, _, _ = cache.friction(name)
    a = truth.axis(name)
    assert g.mgl_Nm == pytest.approx(a["gravity"]["mgl_Nm"], rel=0.05)
    assert abs(g.offset_rad - a["gravity"]["offset_rad"]) < 0.05


def test_online_stribeck_reaches_batch() -> None:
    _, pts, res = cache.friction("reference")
    c = so.convergence(pts.samples, res, tol=0.02)
    assert c["samples_to_tol"] is not None, c["final_rel_error"]
    assert c["sweep_time_s_to_tol"] <= c["sweep_time_s_total"]
    assert max(abs(v) for v in c["final_rel_error"].values()) <= 0.02


def test_linearised_grid_is_exact_on_noise_free_points() -> None:
    import numpy as np
    from hdservo.ident import friction as fr
    v = np.concatenate([np.geomspace(1e-3, 1, 12), -np.geomspace(1e-3, 1, 12)])
    f = fr.stribeck(v, 7.0, 6.5, 10.0, 9.5, 0.02, 2.0, 5.0)
    vs, th, sse = fr.linearised_grid(v, f, np.geomspace(0.005, 0.08, 41))
    assert vs == pytest.approx(0.02, rel=1e-9)
    assert th == pytest.approx([7.0, 3.0, 6.5, 3.0, 5.0], rel=1e-6)
