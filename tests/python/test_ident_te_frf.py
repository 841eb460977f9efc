"""Transmission error and FRF identification on simulator data."""
from __future__ import annotations

import math

import pytest

import ident_cache as cache
import ident_truth as truth
from hdservo.ident import experiments as ex
from hdservo.ident import frf

AXES = ["reference", "csf17_50"]


@pytest.mark.parametrize("name", AXES)
def test_te_2x_line(name: str) -> None:
    r = cache.te(name)
    a = truth.axis(name)["transmission_error"]
    k = next(i for i in range(1, 5) if a[f"wg{i}_order"] == 2)
    amp, ph = r.line(2)
    assert amp == pytest.approx(a[f"wg{k}_amp_rad"], rel=0.05)
    d = (ph - a[f"wg{k}_phase_rad"] + math.pi) % (2 * math.pi) - math.pi
    assert abs(math.degrees(d)) < 5.0


@pytest.mark.parametrize("name", AXES)
def test_frf_resonances_with_hysteresis_on(name: str) -> None:
    """Every effect on.  At small amplitude every hysteresis element sticks: the resonances are those
    of the linearised gear (spring K1 + Maxwell-slip k + Preisach small-signal slope, computed from
    the plant's parameters); with growing amplitude the elements slip and the resonances fall
    towards the K1 two-mass values (amplitude dependence, docs/identification.md)."""
    d = cache.runner(name).run(ex.FRFExcitation(amplitudes_rad_s=(0.005, 0.04, 0.16)))
    res = frf.fit_frf(d)
    a = truth.axis(name)
    fa, fr_ = truth.frf_small_signal_truth(a)
    assert res[0].f_antiresonance_Hz == pytest.approx(fa, rel=0.02)
    assert res[0].f_resonance_Hz == pytest.approx(fr_, rel=0.02)
    fa1, fr1 = truth.frf_truth(a)
    f = [r.f_antiresonance_Hz for r in res]
    assert f[0] > f[1] > f[2] > 0.98 * fa1          # softening with amplitude, never below K1
    assert f[2] < 0.95 * f[0]
    assert min(r.f_resonance_Hz for r in res) > 0.98 * fr1
