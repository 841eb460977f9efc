"""The download rule of the twist torque estimate (``pr_t_src``, ``pr_jm``; docs/compensators.md 13).

The motor-side estimate (``pr_t_src`` 2) is chosen when the load's resonance against the held motor,
sqrt(K1 / J_L) / 2 pi, is below ``RESONANCE_LOOP_RATIO`` x the crossover of the velocity loop the drive
runs, vel_kp / (2 pi J_tot) (25 Hz by the design rule unless vel_kp reaches the drive's maximum or the
gains are set otherwise); ``pr_jm`` is the motor inertia referred to the output, N^2 J_m, from the
(identified) model.
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
    for f_v in (cs.VEL_LOOP_HZ, 12.0):
        edge = cs.RESONANCE_LOOP_RATIO * f_v
        jl_at_edge = 3.1e4 / (2 * math.pi * edge) ** 2
        assert cs.twist_torque_source(3.1e4, jl_at_edge * 1.01, f_v) == 2      # just below the edge frequency
        assert cs.twist_torque_source(3.1e4, jl_at_edge * 0.99, f_v) == 1
    assert cs.velocity_loop_hz(204.2, 1.3) == pytest.approx(25.0, rel=1e-3)     # the reference defaults
    assert cs.velocity_loop_hz(100.0, 0.0) == math.inf


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
    jt = g("load.jl_kgm2") + g("gear.ratio") ** 2 * g("motor.jm_kgm2")
    assert f < cs.RESONANCE_LOOP_RATIO * cs.velocity_loop_hz(cs.design_vel_kp(jt), jt)
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


def test_the_velocity_loop_the_drive_runs_decides(tmp_path: Path) -> None:
    # the same CSF-40-120 (29 Hz) with the velocity loop at 15 Hz (vel_kp set lower): 29 Hz is above
    # 1.5 x 15 Hz, so the model estimate; at the design rule's 25 Hz the motor side
    ax = axisgen.write_axes(tmp_path, 1, seed=7)[0]
    g = lambda k: sim.axis_param(k, str(ax))  # noqa: E731
    jt = g("load.jl_kgm2") + g("gear.ratio") ** 2 * g("motor.jm_kgm2")
    assert cs.compensator_params(str(ax), vel_kp=jt * 2 * math.pi * 15.0)["pr_t_src"] == 1
    assert cs.compensator_params(str(ax), vel_kp=jt * 2 * math.pi * 25.0)["pr_t_src"] == 2
    model = tmp_path / "model.toml"
    model.write_text("[gear]\nratio = 100\n[load]\njl_kgm2 = 0.5\n[motor]\njm_kgm2 = 8e-5\n"
                     "[stiffness]\nk1_Nm_per_rad = 31000.0\n")             # 39.6 Hz, J_tot 1.3 kg m^2
    assert plan_download(model, "reference")["params"]["pr_t_src"] == 1
    plan = plan_download(model, "reference", vel_kp=1.3 * 2 * math.pi * 30.0)  # a 30 Hz loop: edge 45 Hz
    assert plan["params"]["pr_t_src"] == 2
    assert any("30 Hz velocity loop" in n for n in plan["notes"])


def test_a_capped_velocity_gain_lowers_the_edge() -> None:
    # J_tot 61 kg m^2: the design rule's vel_kp is held at the drive's maximum (5000 N.m.s/rad), so the
    # loop runs at 5000 / (2 pi 61) = 13 Hz, not 25 Hz; a 30 Hz load resonance is above 1.5 x 13 Hz
    jl, n, jm = 60.0, 100.0, 1e-4
    model = {"gear.ratio": n, "load.jl_kgm2": jl, "motor.jm_kgm2": jm,
             "stiffness.k1_Nm_per_rad": (2 * math.pi * 30.0) ** 2 * jl}
    assert cs.design_vel_kp(jl + n * n * jm) == pytest.approx(5000.0)
    assert cs.compensator_params("reference", model=model)["pr_t_src"] == 1
    model["stiffness.k1_Nm_per_rad"] = (2 * math.pi * 18.0) ** 2 * jl          # 18 Hz: below 19.6 Hz
    assert cs.compensator_params("reference", model=model)["pr_t_src"] == 2
