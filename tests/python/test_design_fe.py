"""1-D finite-element flexspline torsion model vs the analytic relation."""
from __future__ import annotations

from dataclasses import replace

import pytest

from hdservo.design import flexspline_fe as fe
from hdservo.design import structure as st


@pytest.mark.parametrize("size", [14, 17, 20, 25, 32, 40, 50])
@pytest.mark.parametrize("ratio", [50, 100])
def test_fe_agrees_with_analytic_within_20_percent(size, ratio):
    s = st.structure_for(size, ratio)
    k_fe = fe.solve(s).stiffness_Nm_per_rad
    k_an = st.flexspline_stiffness(s)
    assert abs(k_fe / k_an - 1.0) <= 0.20
    # thicker toothed rim and tapered diaphragm can only stiffen
    assert k_fe > k_an


def test_fe_reduces_to_analytic_for_uniform_sections():
    s = st.structure_for(25, 100)
    k_plain = fe.solve(s, taper=0.0, tooth_rim=False).stiffness_Nm_per_rad
    assert k_plain == pytest.approx(st.flexspline_stiffness(s), rel=0.03)


def test_fe_converges_and_twist_is_monotone():
    s = st.structure_for(25, 100)
    coarse = fe.solve(s, 20, 60).stiffness_Nm_per_rad
    fine = fe.solve(s, 160, 480)
    assert coarse == pytest.approx(fine.stiffness_Nm_per_rad, rel=5e-3)
    u = fine.twist_rad
    assert u[0] == 0.0 and all(b >= a for a, b in zip(u, u[1:]))


def test_fe_scales_with_wall_and_length():
    s = st.structure_for(25, 100)
    k0 = fe.solve(s).stiffness_Nm_per_rad
    assert fe.solve(replace(s, wall_m=1.2 * s.wall_m, diaphragm_m=1.2 * s.diaphragm_m)).stiffness_Nm_per_rad \
        == pytest.approx(1.2 * k0, rel=0.03)
    assert fe.solve(replace(s, cup_length_m=1.5 * s.cup_length_m)).stiffness_Nm_per_rad < k0
