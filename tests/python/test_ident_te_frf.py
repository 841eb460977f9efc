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
def test_frf_resonances(name: str) -> None:
    d = cache.runner(name, effects=cache.HIDE_FOR_FRF).run(ex.FRFExcitation(amplitudes_rad_s=(0.04,)))
    res = frf.fit_frf(d)[-1]
    fa, fr_ = truth.frf_truth(truth.axis(name))
    assert res.f_antiresonance_Hz == pytest.approx(fa, rel=0.02)
    assert res.f_resonance_Hz == pytest.approx(fr_, rel=0.02)
