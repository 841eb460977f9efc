"""Cogging where the log's band holds its line only at low motor speed.

A cogging line of order p per motor revolution is at p |w_m| / 2 pi Hz; above the angle
cutoff the parallel filter takes it out of torque and columns alike.  The order search
tests each order on the samples where its line is in band, and the candidate's size is
its explained fraction there (``Cogging.region_bands``).  Calibration logs only (never
held-apart ones).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hdservo import logio
from hdservo.discrepancy import effects as fx
from hdservo.discrepancy import residuals, signals, workflow
from oracles import discrepancy_corpus as corpus

#: Motor encoder only, P-PI at 10 kHz logging, cogging 0.63x at 72 lines per motor
#: revolution: the line is in band on 7 % of the moving samples.
SPARSE = 621
#: Both encoders, 14-bit motor encoder, cogging 0.75x at 36 lines: the coarse encoder's
#: acceleration noise is the size of the cogging torque over the whole record.
COARSE = 202


def _design(tmp_path: Path, seed: int) -> tuple[corpus.CorpusCase, workflow.State]:
    case = corpus.draw(seed)
    p = corpus.make_log(case, tmp_path / f"l{seed}.csv")
    sig = signals.from_log(logio.read_log(p, require_tag=False), case.structure)
    sig, d, cols, _ = workflow._prepare(sig, None)
    return case, workflow.State.start(d, cols)


def _settings(angles: str) -> workflow.Settings:
    s = workflow.Settings()
    s.frac_min_by_signals = {}
    return s.for_signals(angles)


def test_line_statistics_use_only_the_in_band_samples() -> None:
    """A line present only below the band's speed is found there; the samples above it
    (where the filter has removed it) do not count."""
    rng = np.random.default_rng(3)
    n = 4000
    th = np.cumsum(np.where(np.arange(n) < n // 4, 0.002, 0.05))          # slow, then fast
    w = np.gradient(th) / 1e-3
    p = 40
    r = rng.normal(0.0, 1.0, n)
    slow = p * w / (2 * math.pi) < 100.0
    r[slow] += 0.4 * np.cos(p * th[slow])

    class _Sig:
        q, fc_Hz = 1, 100.0

    class _D:
        sig, mask = _Sig(), np.ones(n, dtype=bool)
    orders = np.arange(5, 80)
    stat, amp, cnt = residuals.line_statistics(_D(), r, th, w, orders)   # type: ignore[arg-type]
    i = int(np.nanargmax(stat))
    assert orders[i] == p
    assert amp[i] == pytest.approx(0.4, rel=0.25)
    assert cnt[i] == int(slow.sum())
    # orders whose in-band samples cannot hold a period are not tested
    assert np.all(np.isnan(stat[cnt < 50]))


def test_order_search_offers_the_line_of_a_log_that_holds_it_at_low_speed_only(tmp_path: Path) -> None:
    case, st = _design(tmp_path, SPARSE)
    assert [e for e, _ in case.hidden] == ["cogging_torque"] and case.angles == "motor"
    p = int(case.axis["cogging"]["h1_order"])
    d = st.design
    wm = np.abs(d.dec("state:wm", d.sig.w_m)[d.mask])
    assert np.mean(p * wm / (2 * math.pi) < d.sig.fc_Hz) < 0.1
    first = next(iter(st.fit.resid.values()))
    orders = [v.hyper["order_per_motor_rev"] for v in fx.Cogging().variants(d, first)]
    assert orders and orders[0] == p


def test_coarse_encoder_cogging_is_sized_where_its_line_is_in_band(tmp_path: Path) -> None:
    case, st = _design(tmp_path, COARSE)
    assert [e for e, _ in case.hidden] == ["cogging_torque"] and case.motor_bits == 14
    p = int(case.axis["cogging"]["h1_order"])
    s = _settings(case.angles)
    (c,) = workflow.rank(st, [fx.Cogging()], s)
    assert c.variant.hyper["order_per_motor_rev"] == p
    assert workflow.significant(c, s)
    bands = c.effect.region_bands(st.design, c.variant)
    assert bands is not None and bands["m"] == pytest.approx(2 * math.pi * st.design.sig.fc_Hz / p)
    e = c.evidence
    # over the whole record the coarse encoder's noise dwarfs it; where its line is in
    # band it is the larger part of the residual
    assert e["explained_fraction"] < s.frac_min <= e["explained_fraction_local"]
