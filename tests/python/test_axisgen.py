"""hdservo.axisgen: random plausible axes from a fixed seed, readable by the simulator."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from hdservo import axisgen as ag
from hdservo import closedloop_cases as bl
from hdservo import sim

import ident_truth as truth


def test_same_seed_same_axes_other_seed_other_axes() -> None:
    a, b, c = ag.random_axes(4, seed=5), ag.random_axes(4, seed=5), ag.random_axes(4, seed=6)
    assert [x.params for x in a] == [x.params for x in b]
    assert [x.params for x in a] != [x.params for x in c]
    assert ag.random_axes(0) == []
    with pytest.raises(ValueError):
        ag.random_axes(-1)


def test_axes_stay_in_catalogue_ranges_and_the_design_rule_range() -> None:
    axes = ag.random_axes(40, seed=ag.DEFAULT_SEED)
    assert len({a.ratio for a in axes}) >= 4            # the draw covers the ratios, not one axis
    for a in axes:
        p, s = a.params, a.summary()
        assert a.ratio in ag.CATALOGUE[a.size] and 30 <= s["ratio"] <= 160
        st = p["stiffness"]
        assert st["k1_Nm_per_rad"] < st["k2_Nm_per_rad"] < st["k3_Nm_per_rad"] and st["t1_Nm"] < st["t2_Nm"]
        assert s["f_res_k1_Hz"] >= ag.MIN_RESONANCE_HZ
        assert ag.LOAD_RATIO_RANGE[0] <= s["jl_over_j1"] <= ag.LOAD_RATIO_RANGE[1]
        assert s["peak_torque_Nm"] >= 1.3 * st["t2_Nm"] - 1e-9
        assert 0.005 <= s["vs_out_rad_s"] <= 0.05
        for side in ("friction_motor", "friction_load"):
            f = p[side]
            assert 0 < f["fc_pos_Nm"] < f["fs_pos_Nm"] and 0 < f["fc_neg_Nm"] < f["fs_neg_Nm"]


def test_written_axis_is_read_by_the_simulator_and_the_truth_helpers(tmp_path: Path) -> None:
    paths = ag.write_axes(tmp_path, 2, seed=3)
    axes = ag.random_axes(2, seed=3)
    assert [p.name for p in paths] == [f"{a.name}.toml" for a in axes]
    for p, a in zip(paths, axes):
        assert sim.axis_param("gear.ratio", str(p)) == a.ratio
        assert sim.axis_param("stiffness.k1_Nm_per_rad", str(p)) == pytest.approx(
            a.params["stiffness"]["k1_Nm_per_rad"], rel=1e-9)
        with open(p, "rb") as f:
            t = truth.friction_total(tomllib.load(f))        # shared output-referred Stribeck velocity
        assert t["fs_pos_Nm"] == pytest.approx(a.summary()["fs_total_Nm"], rel=1e-9)
        g = bl.axis_controller(str(p))["gains"]               # the baseline design rule reads it
        assert g["vel_kp"] > 0
    assert not list(tmp_path.glob(".*tmp*"))
