"""host/hdservo/gains.py: the baseline gains have margins, and the parameter
table's defaults are the reference-axis design."""
from __future__ import annotations

import math

from hdservo import gains, params_gen


def test_reference_axis_margins() -> None:
    d = gains.design(gains.REFERENCE)
    assert 45 < d.f_res_hz < 55                      # torsional mode of DESIGN.md (40-70 Hz)
    assert d.vel_phase_margin_deg > 45 and d.vel_gain_margin_db > 10
    assert d.pos_phase_margin_deg > 60 and d.pos_gain_margin_db > 6
    assert d.vel_crossover_hz > 15 and d.pos_crossover_hz > 5


def test_second_axis_margins() -> None:
    d = gains.design(gains.SECOND)
    assert d.vel_phase_margin_deg > 45 and d.vel_gain_margin_db > 10
    assert d.pos_phase_margin_deg > 60 and d.pos_gain_margin_db > 6


def test_defaults_are_the_reference_design() -> None:
    d = gains.design(gains.REFERENCE)
    p = params_gen.BY_NAME
    assert math.isclose(p["vel_kp"].default, d.vel_kp_Nms_per_rad, rel_tol=2e-3)
    assert math.isclose(p["vel_ki"].default, d.vel_ki_Nm_per_rad, rel_tol=2e-3)
    assert math.isclose(p["pos_kp"].default, d.pos_kp_per_s, rel_tol=2e-3)
    assert math.isclose(p["j_total"].default, d.j_total_kgm2, rel_tol=1e-3)
