"""Describing-function limit-cycle prediction against the project's C simulator (issue 8 acceptance).

Friction hunting: the reference axis's position loop detuned with integral action (pos_ki),
motor-side Stribeck friction as the dominant nonlinearity; prediction from the axis file and
the drive's gains only (hdservo.analysis.simcheck), simulation by hdservo.sim (firmware + plant).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from hdservo.analysis.catalogue import build
from hdservo.analysis.loop import LoopModel
from oracles.simcheck import ARCSEC_RAD, HuntingCase, check, predict, scenario_text, axis_file
from hdservo.analysis.axis import load_axis, load_gains

pytest.importorskip("hdservo.sim")


def test_friction_hunting_matches_c_simulator():
    """Acceptance: amplitude within 30 %, frequency within 15 % of the simulated cycle."""
    r = check(HuntingCase(pos_ki=2000.0))
    assert r.cycle is not None and r.cycle.stable and r.cycle.residual < 1e-6
    assert r.sim_cycles >= 8                       # sustained: 8+ whole periods after the transient
    assert 50 * ARCSEC_RAD < r.sim_pos_amp_rad < 500 * ARCSEC_RAD
    assert abs(r.amplitude_error) < 0.30, r.to_dict()
    assert abs(r.frequency_error) < 0.15, r.to_dict()
    # the DF's own variable: motor-velocity amplitude vs the first harmonic of the simulated one
    assert r.cycle.amplitude == pytest.approx(r.sim_vel_h1_rad_s, rel=0.30)


def test_no_hunting_without_position_integral_action():
    """pos_ki = 0: no cycle predicted, and the simulated axis comes to rest."""
    r = check(HuntingCase(pos_ki=0.0, duration_s=2.0, settle_s=1.0))
    assert r.cycle is None
    assert r.sim_pos_amp_rad < 1.0 * ARCSEC_RAD


def test_cycle_amplitude_of_the_nonlinearity_input_is_the_cycle_amplitude():
    ax, _ = load_axis(None)
    gains, _ = load_gains(["pos_ki=2000"])
    m = LoopModel(ax, gains)
    e = build("stribeck_motor", ax)
    assert m.cycle_amplitude(e.insertion, "z", 2.5, 30.0) == pytest.approx(2.5, rel=1e-9)
    # far below the torsional mode the load follows the motor: theta_L ~ (A / N) / w
    th = m.cycle_amplitude(e.insertion, "theta_L", 2.5, 2 * math.pi * 2.0)
    assert th == pytest.approx(2.5 / 100 / (2 * math.pi * 2.0), rel=0.05)


def test_scenario_text_carries_the_case():
    text = scenario_text(HuntingCase(pos_ki=1234.0), axis_file())
    assert "pos_ki = 1234.0" in text and 'mode = "position"' in text
    assert "friction_motor" not in text            # friction stays as in the axis file
    assert "base.enabled = false" in text and "hysteresis_preisach.enabled = false" in text
