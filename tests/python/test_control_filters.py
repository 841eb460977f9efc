"""host/hdservo/filters.py: design, Q2.30 quantisation, stability and depth checks."""
from __future__ import annotations

import pytest

from hdservo import filters, params_gen


def test_notch_depth_and_passband() -> None:
    n = filters.notch(50.0, 40.0, -20.0)
    q = filters.dequantise(filters.quantise(n))
    assert abs(filters.notch_depth_db(q, 50.0) + 20.0) < 0.2
    assert abs(abs(q.response(5.0)[0]) - 1) < 0.02
    assert abs(abs(q.response(1000.0)[0]) - 1) < 0.01
    assert filters.pole_radius(q) < 1.0


def test_lowpass_dc_gain_and_corner() -> None:
    lp = filters.dequantise(filters.quantise(filters.lowpass(1000.0)))
    assert abs(abs(lp.response(0.0)[0]) - 1) < 1e-6
    assert abs(abs(lp.response(1000.0)[0]) - 2 ** -0.5) < 0.01


def test_quantise_rejects_bad() -> None:
    with pytest.raises(filters.FilterDesignError):
        filters.notch(6000.0, 10.0, -20.0)
    with pytest.raises(filters.FilterDesignError):
        filters.quantise(filters.Biquad((2.5, 0.0, 0.0), (0.0, 0.0)))
    with pytest.raises(filters.FilterDesignError):
        filters.quantise(filters.Biquad((1.0, 0.0, 0.0), (0.0, 1.0)))   # poles on the circle


def test_parameter_defaults_are_the_designed_filters() -> None:
    """The table's default torque filters are notch(50, 40, -20) and lowpass(1000)."""
    for prefix, bq in (("f1", filters.notch(50.0, 40.0, -20.0)), ("f2", filters.lowpass(1000.0))):
        raw = filters.export_params(prefix, filters.quantise(bq))
        for name, word in raw.items():
            assert abs(params_gen.BY_NAME[name].raw_default - word) <= 64, name
