"""The drive's online Stribeck identification (hd_fric_est, object 0x5200) over CAN, its profile
and comparison logic, and `identify friction --online` bad input."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from hdservo.cli import main
from hdservo.ident import stribeck_online as so
from hdservo.ident.friction import StribeckResult

import ident_truth as truth


def _truth(axis: str) -> StribeckResult:
    t = truth.friction_total(truth.axis(axis))
    return StribeckResult(t["fc_pos_Nm"], t["fc_neg_Nm"], t["fs_pos_Nm"], t["fs_neg_Nm"], t["vs_rad_s"], 2.0,
                          t["viscous_Nms_per_rad"])


def test_identify_friction_online_over_can(tmp_path: Path, capsys) -> None:
    """`identify friction --sim --online`: the virtual drive's estimator, read over CAN during 20 s of the
    normal profile, lands within the targets (levels 5 %, vs 15 %) of the batch fit and of the axis's own
    friction; before its first fit it does not count."""
    js = tmp_path / "r.json"
    rc = main(["identify", "friction", "--sim", "--online", "--json", str(js), "-q"])
    out = capsys.readouterr().out
    assert rc == 0 and "drive online Stribeck:" in out and "inside the targets" in out
    o = json.loads(js.read_text())["stribeck_drive_online"]
    hist = o["history"]
    assert hist[0]["fits_pos"] == 0 and hist[-1]["fits_pos"] > 0 and hist[-1]["fits_neg"] > 0
    assert o["time_to_target_s"] is not None and o["time_to_target_s"] <= 20.0
    e = o["final_rel_error"]
    assert all(abs(e[k]) <= 0.05 for k in so.LEVELS)
    assert abs(e["vs_pos_rad_s"]) <= 0.15 and abs(e["vs_neg_rad_s"]) <= 0.15
    assert hist[-1]["conf_pos"] == 1.0 and hist[-1]["samples"] > 1000
    # the common mode read over CAN (0x5200:15, :16; a drive without them aborts the read): no drift
    # and no unbalance on this run, so the scale stays near 1 and the bias near 0 (against the axis'
    # breakaway level), and the summary prints them
    fs = max(o["batch"]["fs_pos_Nm"], o["batch"]["fs_neg_Nm"])
    assert all(0.9 <= h["scale"] <= 1.1 for h in hist)
    assert abs(hist[-1]["bias_Nm"]) <= 0.05 * fs
    assert "common-mode scale" in out
    # and against the axis's own friction (the truth the batch fit estimates)
    last = so.DriveEstimate(**hist[-1])
    assert last.within(_truth("reference"))


def test_profile_rule() -> None:
    legs = so.normal_profile(0.01, 10.0, 4, 0.5, 100.0, 0.05)
    assert len(legs) == 24
    fast = math.radians(10.0)
    for k in range(4):
        p = legs[6 * k: 6 * k + 6]
        v = p[2].v_rad_s
        # the two slow moves, centred on the start, each entered in its own direction at the fast speed
        assert p[2].target_rad == pytest.approx(-p[5].target_rad) and p[5].v_rad_s == v
        assert p[0].target_rad < p[1].target_rad < p[2].target_rad < p[3].target_rad
        assert p[3].target_rad > p[4].target_rad > p[5].target_rad
        assert all(q.v_rad_s == fast for q in (p[0], p[1], p[3], p[4]))
        # constant-velocity part of each slow move = cruise_s
        travel = 2 * p[2].target_rad
        assert travel / v - v / math.radians(100.0) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        so.normal_profile(1.0, 0.5)


def _est(t: float, scale: float, fits: int = 3, vs: float = 0.02) -> so.DriveEstimate:
    return so.DriveEstimate(t, 7.4 * scale, 10.6 * scale, vs, 5.3 * scale, 7.0 * scale, 10.0 * scale, vs,
                            5.3 * scale, 1.0, 1.0, fits, fits, 100)


def test_convergence_logic() -> None:
    ref = StribeckResult(7.4, 7.0, 10.6, 10.0, 0.02, 2.0, 5.3)
    # initial values equal to the reference do not count before the first fit
    h = [_est(1.0, 1.0, fits=0), _est(2.0, 1.2), _est(3.0, 1.0), _est(4.0, 1.03, vs=0.022)]
    assert so.watch_convergence(h, ref, 0.0) == pytest.approx(3.0)
    # leaving the tolerance resets; vs outside 15 % fails
    h2 = h + [_est(5.0, 1.0, vs=0.0235), _est(6.0, 1.0)]
    assert so.watch_convergence(h2, ref, 0.0) == pytest.approx(6.0)
    assert so.watch_convergence(h2[:-1], ref, 0.0) is None
    # a drifting reference: the scale of the plant at each reading
    drift = [_est(10.0, 1.0), _est(20.0, 1.15), _est(30.0, 1.3)]
    assert so.watch_convergence(drift, ref, 10.0, lambda t: so.drift_scale(t, 10.0, 20.0, 1.3)) == 0.0
    assert so.watch_convergence(drift, ref, 10.0) is None
    assert so.drift_scale(5.0, 10.0, 20.0, 1.3) == 1.0 and so.drift_scale(40.0, 10.0, 20.0, 1.3) == 1.3


def test_raw_units() -> None:
    raw = [7 << 16, 10 << 16, 1 << 22, 33 << 16, 6 << 16, 9 << 16, 1 << 23, 30 << 16, 1000, 250, 5, 6, 77]
    e = so.DriveEstimate.from_raw(1.5, raw)
    assert (e.fc_pos_Nm, e.fs_pos_Nm, e.fc_neg_Nm, e.fs_neg_Nm) == (7.0, 10.0, 6.0, 9.0)
    assert e.vs_pos_rad_s == pytest.approx(2 * math.pi * 2.0 ** -10)
    assert e.fv_pos_Nms_per_rad == pytest.approx(33 / (2 * math.pi))
    assert (e.conf_pos, e.conf_neg, e.fits_pos, e.fits_neg, e.samples) == (1.0, 0.25, 5, 6, 77)
    assert (e.scale, e.bias_Nm) == (1.0, 0.0)           # a 13-word reading: no common mode
    e2 = so.DriveEstimate.from_raw(1.5, raw + [3 << 15, -(5 << 14)])
    assert (e2.scale, e2.bias_Nm) == (1.5, -1.25) and e2.samples == 77


def test_read_drive_estimate_subs() -> None:
    """The reading asks 0x5200:1..13 and the common mode :15 (scale) and :16 (bias), not :14."""
    asked: list[tuple[int, int]] = []

    def read(index: int, sub: int) -> int:
        asked.append((index, sub))
        return {15: 1 << 17, 16: 1 << 15}.get(sub, 1)

    e = so.read_drive_estimate(read, 2.0)
    assert asked == [(0x5200, s) for s in list(range(1, 14)) + [15, 16]]
    assert (e.scale, e.bias_Nm) == (2.0, 0.5)


@pytest.mark.parametrize("argv, word", [
    (["identify", "stiffness", "--sim", "--online"], "friction only"),
    (["identify", "friction", "--offline", "reference", "--online"], "--offline"),
    (["identify", "friction", "--sim", "--online-s", "5"], "--online-s"),
    (["identify", "friction", "--sim", "--online", "--online-s", "0"], "--online-s"),
])
def test_online_bad_input_is_one_line(argv: list[str], word: str, capsys) -> None:
    rc = main(argv + ["-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and word in err[0] and "Traceback" not in err[0]
