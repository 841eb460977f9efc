"""The download rule of the twist torque estimate (``pr_t_src``, ``pr_jm``; docs/compensators.md 13).

The motor-side estimate (``pr_t_src`` 2) is chosen when the load's resonance against the held motor,
sqrt(K1 / J_L) / 2 pi, is below ``RESONANCE_LOOP_RATIO`` x the 25 Hz velocity loop; ``pr_jm`` is the
motor inertia referred to the output, N^2 J_m, from the (identified) model.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from hdservo import axisgen, compsetup as cs, sim
from hdservo.download import plan_download

ROOT = Path(__file__).parents[2]


def test_resonance_and_threshold() -> None:
    assert cs.load_resonance_hz(3.1e4, 0.5) == pytest.approx(math.sqrt(6.2e4) / (2 * math.pi))
    assert cs.load_resonance_hz(3.1e4, 0.0) == math.inf
    edge = cs.RESONANCE_LOOP_RATIO * cs.VEL_LOOP_HZ
    jl_at_edge = 3.1e4 / (2 * math.pi * edge) ** 2
    assert cs.twist_torque_source(3.1e4, jl_at_edge * 1.01) == 2      # just below the edge frequency
    assert cs.twist_torque_source(3.1e4, jl_at_edge * 0.99) == 1


@pytest.mark.parametrize("axis, src", [("reference", 1), (str(ROOT / "sim/axes/csf17_50.toml"), 1)])
def test_axis_files_keep_the_model_estimate(axis: str, src: int) -> None:
    p = cs.compensator_params(axis)
    n = sim.axis_param("gear.ratio", axis)
    assert p["pr_t_src"] == src
    assert p["pr_jm"] == pytest.approx(n * n * sim.axis_param("motor.jm_kgm2", axis))


def test_heavy_catalogue_axis_takes_the_motor_side(tmp_path: Path) -> None:
    # the CSF-40-120 of docs/compensators.md section 13 (seed 7, axis 0): load resonance 29 Hz
    ax = axisgen.write_axes(tmp_path, 1, seed=7)[0]
    g = lambda k: sim.axis_param(k, str(ax))  # noqa: E731
    f = cs.load_resonance_hz(g("stiffness.k1_Nm_per_rad"), g("load.jl_kgm2"))
    assert f < cs.RESONANCE_LOOP_RATIO * cs.VEL_LOOP_HZ
    p = cs.compensator_params(str(ax))
    assert p["pr_t_src"] == 2
    assert p["pr_jm"] == pytest.approx(g("gear.ratio") ** 2 * g("motor.jm_kgm2"))


def test_identified_inertias_decide(tmp_path: Path) -> None:
    # the identified model's K1 and J_L (FRF) decide, not the axis file's
    model = tmp_path / "model.toml"
    model.write_text("[gear]\nratio = 100\n[load]\njl_kgm2 = 5.0\n[motor]\njm_kgm2 = 1e-4\n"
                     "[stiffness]\nk1_Nm_per_rad = 31000.0\n")
    plan = plan_download(model, "reference")
    assert plan["params"]["pr_t_src"] == 2                               # sqrt(31000 / 5) / 2 pi = 12.5 Hz
    assert plan["params"]["pr_jm"] == pytest.approx(100 ** 2 * 1e-4)
    assert "pr_jm" in plan["sdo"]
    assert any("pr_t_src 2" in n and "12.5 Hz" in n for n in plan["notes"])     # the download says which
    model.write_text("[gear]\nratio = 100\n[load]\njl_kgm2 = 0.5\n")
    assert plan_download(model, "reference")["params"]["pr_t_src"] == 1  # 39.6 Hz
