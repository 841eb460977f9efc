"""Minimum smooth rate (issue 8): the figure from the extended ladder, and the compensated drive's
slowest required rung on the virtual reference axis.

* the minimum smooth rate is the slowest rung of the ladder with every faster rung smooth
  (monotone and rate stability <= bound), whatever order the rungs were run or listed in;
  the windows of the rungs below 0.001 deg/s keep 3.6 arcsec, their settling at least 4 windows;
* the comparison tells a drive that is smooth down to 0.0001 deg/s from one that is
  smooth down to 0.0005 deg/s, and calls two drives smooth on the whole ladder "same";
* on the virtual drive, the best combination (Stribeck feed-forward on the measured
  velocity, on the reference velocity while the reference cruises) is smooth at
  0.001 deg/s; the same drive without the cruise switch (``str_cruise_ticks`` 0) is not
  (the feed-forward on the measured velocity is a relay in the velocity loop there), and the
  slower rungs after a failed one are not run.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from hdservo import compare as cmp
from hdservo import compsetup as cs
from hdservo.drive import DriveError
from hdservo.procedures import closedloop as cl
from hdservo.procedures import metrics as mt
from hdservo.procedures.runner import Target, open_bench

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "build" / "bin" / "hdservo-sim"


def _rung(rate: float, stability: float, monotone: bool = True) -> dict[str, object]:
    return {"rate_deg_s": rate, "stability": stability, "accuracy": 0.2, "monotone": monotone}


def test_ladder_extends_below_the_requirement_with_fixed_angle_windows() -> None:
    lad = cl.RATE_LADDER_DEG_S
    assert lad[:4] == (1.0, 0.1, 0.01, 0.001) and min(lad) == 0.0001 and list(lad) == sorted(lad, reverse=True)
    # window = rate x 1 s down to 0.001 deg/s, then 3.6 arcsec (longer windows, not smaller angles)
    assert cl.rate_window_rad(0.01) / mt.ARCSEC == pytest.approx(36.0)
    assert cl.rate_window_rad(0.001) / mt.ARCSEC == pytest.approx(3.6)
    for r in (0.0005, 0.0002, 0.0001):
        assert cl.rate_window_rad(r) / mt.ARCSEC == pytest.approx(3.6)
        assert cl.rate_window_rad(r) / math.radians(r) == pytest.approx(0.001 / r)
    # settling: 5 s, at least 4 windows below 0.5 deg/s (the start transient is an angle), 1 s above
    assert cl.rung_settle_s(1.0) == 1.0 and cl.rung_settle_s(0.01) == 5.0 and cl.rung_settle_s(0.001) == 5.0
    assert [cl.rung_settle_s(r) for r in (0.0005, 0.0002, 0.0001)] == pytest.approx([8.0, 20.0, 40.0])


def test_min_smooth_rate_from_the_extended_ladder() -> None:
    smooth_all = [_rung(r, 0.03) for r in cl.RATE_LADDER_DEG_S]
    assert mt.min_smooth_rate(smooth_all, 0.1) == 0.0001
    # listed in any order: judged fastest first
    assert mt.min_smooth_rate(list(reversed(smooth_all)), 0.1) == 0.0001
    # stick-slip at 0.0002 (stability 0.38): 0.0005, even though 0.0001 passes again
    pid_like = [_rung(r, 0.38 if r == 0.0002 else 0.03) for r in cl.RATE_LADDER_DEG_S]
    assert mt.min_smooth_rate(pid_like, 0.1) == 0.0005
    # a reversal (not monotone) fails a rung whatever its stability
    back = [_rung(r, 0.03, monotone=(r != 0.001)) for r in cl.RATE_LADDER_DEG_S]
    assert mt.min_smooth_rate(back, 0.1) == 0.01
    # the bound is inclusive
    assert mt.min_smooth_rate([_rung(1.0, 0.1), _rung(0.1, 0.1000001)], 0.1) == 1.0
    # the comparison: lower is better; the same rung is "same", never better
    f = cmp.FIGURE_BY_KEY["min_smooth_rate_deg_s"]
    assert f.verdict(0.0001, 0.0005) == "better" and f.verdict(0.0005, 0.0001) == "worse"
    assert f.verdict(0.0001, 0.0001) == "same"


@pytest.mark.skipif(not SIM.exists(), reason="build/bin/hdservo-sim not built (make sim)")
@pytest.mark.parametrize("cruise_ticks, smooth", [(None, True), (0, False)])
def test_best_combination_smooth_at_0p001_deg_s(cruise_ticks: int | None, smooth: bool) -> None:
    """One rung, 5 windows of 3.6 arcsec after 10 s (past the start transient): the best combination is smooth, without the cruise switch not."""
    params = {k: v for k, v in cs.compensator_params("reference").items() if k.startswith("str_")}
    params.update(cs.best_gains("reference"))
    if cruise_ticks is not None:
        params["str_cruise_ticks"] = cruise_ticks
    # The rung runs in drive time (settling, record), so host load cannot shorten it; what a loaded
    # machine can do is time out an SDO exchange (wall-clock, 3 x 0.3 s): the run is then repeated
    # once on a new virtual drive.  Any result that is measured is judged as it is.
    for attempt in range(2):
        t = Target(compensators=list(cs.BEST_NAMES), params=params)
        try:
            with open_bench(t, cl.AXIS_SETUP) as b:
                # without the cruise switch the 0.001 rung fails and the slower one is skipped (not run)
                r = cl.min_rate(b, rates_deg_s=(0.001,) if smooth else (0.0005, 0.001), windows=5, settle_s=10.0)
            break
        except DriveError as e:
            if attempt == 1 or "No SDO response" not in str(e):
                raise
    rung = r.figures["ladder"][0]
    assert rung["window_arcsec"] == pytest.approx(3.6) and rung["settle_s"] == 10.0
    # the drive's reference runs at the commanded rate (the profile generator used to run it 19 % slow
    # here, and the record then held 4.05 of its 5 windows: 3 or 4 timed windows by chance)
    assert rung["reference_accuracy"] < 1e-3, rung
    if smooth:
        assert rung["windows"] == 5, rung
        assert rung["monotone"] and rung["stability"] <= 0.1, rung
        assert rung["accuracy"] < 0.05, rung
        assert r.headline["min_smooth_rate_deg_s"] == 0.001
    else:
        assert rung["windows"] >= 4, rung
        assert not (rung["monotone"] and rung["stability"] <= 0.1), rung
        assert r.headline["min_smooth_rate_deg_s"] is None
        assert len(r.figures["ladder"]) == 1 and r.figures["skipped_deg_s"] == [0.0005]
        assert any("0.0005 deg/s not run" in n for n in r.notes)
