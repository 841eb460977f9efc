"""Normalised sensitivities of resonance and lost motion, and their plot."""
from __future__ import annotations

import math

import pytest

from hdservo.cli import UserError
from hdservo.design import sensitivity as se
from hdservo.design import structure as st

S = st.structure_for(25, 100)
CAL = st.load_calibration()
AXIS = se.Axis(load_inertia_kgm2=0.5, motor_inertia_kgm2=8e-5, test_torque_Nm=66.9)
SENS = se.sensitivities(S, CAL, AXIS)


def test_all_finite_and_complete():
    for out in se.OUTPUTS:
        assert len(SENS[out]) == len(se.PARAMETERS)
        assert all(math.isfinite(v) for v in SENS[out].values())


def test_resonance_dominated_by_pitch_diameter_and_inertia_exact():
    res = SENS["resonance"]
    top = se.ranked(res)
    assert top[0][0].startswith("pitch diameter") and top[0][1] > 0
    # two-mass: S_JL = -1/2 * (1/J_L) / (1/J_L + 1/(N^2 J_m)) exactly
    jl, jm, n = 0.5, 8e-5, 100.0
    expect = -0.5 * (1 / jl) / (1 / jl + 1 / (n * n * jm))
    assert res["load inertia J_L [kg m^2]"] == pytest.approx(expect, abs=2e-3)
    # every stiffness element grows with E, but the calibrated mesh constant does not scale with E
    assert 0.0 < res["Young's modulus E [Pa]"] < 0.5
    # sqrt law: f ~ K^(1/2), so no single structural parameter exceeds 1.5
    assert all(abs(v) <= 1.5 for v in res.values())


def test_lost_motion_falls_with_every_stiffening_parameter():
    lm = SENS["lost_motion"]
    assert se.ranked(lm)[0][0].startswith("pitch diameter")
    for key in ("pitch diameter d [m]", "face width b [m]", "wall thickness t [m]",
                "mesh stiffness per width c_m [N/m^2]", "teeth engaged at zero torque f0 [-]",
                "Young's modulus E [Pa]"):
        assert lm[key] < 0, key
    assert lm["cup length L [m]"] > 0
    assert lm["load inertia J_L [kg m^2]"] == pytest.approx(0.0, abs=1e-9)
    # the mesh (engagement) dominates the flexspline cup for lost motion
    assert abs(lm["mesh stiffness per width c_m [N/m^2]"]) > abs(lm["wall thickness t [m]"])


def test_plot_written(tmp_path):
    p = se.plot_sensitivities(SENS, tmp_path / "sens.png", title="CSF-25-100")
    data = p.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert not list(tmp_path.glob("*.tmp"))
    with pytest.raises(UserError):
        se.sensitivities(S, CAL, AXIS, rel_step=0.5)
