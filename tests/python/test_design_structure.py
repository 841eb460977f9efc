"""Structure-to-model relations, calibration against the catalogue, and the
two-mass resonance (hdservo.design.structure)."""
from __future__ import annotations

import math
from dataclasses import asdict, replace

import numpy as np
import pytest

from hdservo.cli import UserError
from hdservo.design import catalogue as cat
from hdservo.design import structure as st

CAL = st.load_calibration()
ROWS = cat.load_gears()
PRED = {(r["size"], r["ratio"]): r for r in st.predicted_vs_catalogue(CAL, ROWS)}


def test_geometry_rules():
    s = st.structure_for(25, 100)
    assert s.pitch_diameter_m == pytest.approx(63.5e-3)          # size = d in 0.1 inch
    assert 0.01 <= s.wall_m / s.pitch_diameter_m <= 0.015
    assert 0.8 <= s.cup_length_m / s.pitch_diameter_m <= 1.0
    assert s.teeth == 200 and s.module_m == pytest.approx(63.5e-3 / 200)
    assert s.shear_modulus_Pa == pytest.approx(206e9 / 2.6)
    with pytest.raises(UserError):
        st.structure_for(0, 100)


def test_thin_tube_and_annular_plate_formulas():
    s = st.structure_for(25, 100)
    r, t, g = s.mid_radius_m, s.wall_m, s.shear_modulus_Pa
    assert st.cup_stiffness(s) == pytest.approx(
        g * 2 * math.pi * r ** 3 * t / (s.cup_length_m - s.face_width_m / 2))
    # doubling the wall about doubles the cup stiffness (the mid radius shrinks by t/2)
    ratio = st.cup_stiffness(replace(s, wall_m=2 * t)) / st.cup_stiffness(s)
    assert ratio == pytest.approx(2.0 * ((r - t / 2) / r) ** 3)
    a = s.hub_radius_m
    assert st.diaphragm_stiffness(s) == pytest.approx(
        4 * math.pi * g * s.diaphragm_m / (1 / a ** 2 - 1 / r ** 2))


@pytest.mark.parametrize("size", [14, 17, 20, 25, 32, 40, 50])
def test_k1_within_20_percent_of_catalogue(size):
    """Structure-predicted K1 vs catalogue K1 for every CSF ratio of this size
    (N = 50 and the N >= 80 class rows)."""
    rows = [r for (sz, _), r in PRED.items() if sz == size]
    assert any(r["ratio"] == 50 for r in rows) and any(r["ratio"] >= 80 for r in rows)
    for r in rows:
        assert abs(r["k1_err"]) <= 0.20, (size, r["ratio"], r["k1_err"])


def test_k2_k3_and_breakpoints_follow_catalogue():
    errs2 = [abs(r["k2_err"]) for r in PRED.values()]
    errs3 = [abs(r["k3_err"]) for r in PRED.values()]
    assert max(errs2) <= 0.25 and max(errs3) <= 0.25
    assert np.sqrt(np.mean(np.square(errs2 + errs3))) <= 0.15
    assert max(abs(r["t1_err"]) for r in PRED.values()) <= 0.20
    assert max(abs(r["t2_err"]) for r in PRED.values()) <= 0.25   # size 17: +21 %


def test_stiffening_with_torque():
    """More teeth engage as the torque rises: K1 < K2 < K3 and the incremental
    stiffness grows monotonically; K3/K1 within the catalogue 1.3-2.0."""
    for size in (14, 25, 50):
        s = st.structure_for(size, 100)
        ts = st.three_slope(s, CAL)
        assert ts.k1_Nm_per_rad < ts.k2_Nm_per_rad < ts.k3_Nm_per_rad
        assert 1.3 <= ts.k3_Nm_per_rad / ts.k1_Nm_per_rad <= 2.0
        torques = np.linspace(0.05, 2.0, 12) * ts.t2_Nm
        kinc = [st.incremental_stiffness(s, CAL, t) for t in torques]
        assert all(b >= a for a, b in zip(kinc, kinc[1:]))
    phi = st.twist(st.structure_for(25, 100), CAL, [-10.0, 10.0])
    assert phi[0] == pytest.approx(-phi[1])                    # odd


def test_reference_axis_twist_and_compliance_split():
    s = st.structure_for(25, 100)
    # twist at T1 of CSF-25-100 ~ 1.55 arcmin (research §2.1)
    phi_t1 = st.twist(s, CAL, [14.0])[0] / st.ARCMIN
    assert 1.3 <= phi_t1 <= 1.8
    shares = st.compliance_shares(s, CAL, 14.0)
    assert sum(shares.values()) == pytest.approx(1.0)
    assert shares["mesh"] == max(shares.values())              # mesh + engagement dominates at low torque
    assert 0.05 <= shares["cup"] <= 0.3


def test_calibration_reproduces_stored_constants():
    fresh = st.calibrate(ROWS)
    for k, v in asdict(CAL).items():
        assert getattr(fresh, k) == pytest.approx(v, rel=2e-3, abs=1e-9), k


def test_hysteresis_lost_motion_friction():
    s = st.structure_for(25, 100)
    ref = cat.find_gear(25, 100, rows=ROWS)
    h = st.hysteresis_loss(s, CAL, ref.rated_torque_Nm) / st.ARCMIN
    assert h == pytest.approx(1.0, rel=1e-3)                   # calibration point
    for size in (14, 17, 20, 32, 40, 50):
        g = cat.find_gear(size, 100, rows=ROWS)
        hs = st.hysteresis_loss(st.structure_for(size, 100), CAL, g.rated_torque_Nm) / st.ARCMIN
        lm = st.lost_motion(st.structure_for(size, 100), CAL, g.rated_torque_Nm) / st.ARCMIN
        assert 0.5 <= hs <= 1.5, (size, hs)                    # catalogue bound <= 1'
        assert 0.3 <= lm <= 1.5, (size, lm)                    # catalogue bound <= 1'
    # starting torque through the two published points; backdriving ~ 1.1 N x starting
    for size, n in ((17, 100), (25, 50)):
        g = cat.find_gear(size, n, rows=ROWS)
        fr = st.friction(st.structure_for(size, n), CAL)
        assert fr.starting_input_Nm == pytest.approx(g.starting_torque_input_Nm, rel=1e-3)
        assert 0.8 <= fr.backdriving_output_Nm / g.backdriving_torque_output_Nm <= 1.4
        assert fr.coulomb_output_Nm < fr.backdriving_output_Nm


def test_two_mass_resonance_reference_axis():
    # research §1: f_a = 39.6 Hz (K1), f_r = 50.5 Hz with J_L 0.5, J_m 8e-5, N 100
    fa, fr = st.two_mass_resonance(3.1e4, 0.5, 8e-5, 100)
    assert fa == pytest.approx(39.6, abs=0.1)
    assert fr == pytest.approx(50.5, abs=0.1)
    with pytest.raises(UserError):
        st.two_mass_resonance(3.1e4, 0.0, 8e-5, 100)


def test_bad_geometry_file(tmp_path):
    p = tmp_path / "g.toml"
    p.write_text(st.GEOMETRY_FILE.read_text().replace("wall_over_d = 0.012", 'wall_over_d = "thin"'))
    with pytest.raises(UserError, match=r"\[geometry\] wall_over_d: expected a finite number"):
        st.structure_for(25, 100, p)
