"""What a coarse two-encoder log shows: its twist resolution, and the note when the twist
spans only a few counts (lost motion and hysteresis a few counts wide are not resolved)."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from hdservo import logio
from hdservo.discrepancy import signals, validity
from oracles import discrepancy_corpus as corpus


def test_twist_resolution_is_one_count_of_the_coarser_encoder_at_the_output() -> None:
    r = validity.LogRange(1000.0, 14.0, 18.0)
    # 14 bits on the motor of N = 30: 1.28e-5 rad at the output; 18 bits: 2.40e-5 rad
    assert validity.twist_resolution(r, 30.0) == pytest.approx(2 * math.pi / 2 ** 18)
    assert validity.twist_resolution(r, 10.0) == pytest.approx(2 * math.pi / 2 ** 14 / 10.0)
    assert validity.twist_resolution(validity.LogRange(1000.0, None, 18.0), 30.0) is None
    q = 2 * math.pi / 2 ** 18
    assert validity.twist_note("l.csv", r, 30.0, 20 * q) is None
    line = validity.twist_note("l.csv", r, 30.0, 5 * q)
    assert line is not None and line.startswith("l.csv: the twist spans 5.0 counts") and "\n" not in line
    assert validity.twist_note("l.csv", r, 30.0, float("nan")) is None


@pytest.mark.parametrize("seed,noted", [(971, True), (34, False)])
def test_calibration_backlash_logs(tmp_path: Path, seed: int, noted: bool) -> None:
    """Calibration logs (never held-apart ones), drive at 1 kHz with a hidden lost-motion
    zone: seed 971 (14-bit motor on N = 30, 18-bit output encoder; the zone is 2 counts of
    the output encoder across, and the workflow does not rank backlash at all) gets the
    note; seed 34 (16/21 bits, the twist spans 67 counts; backlash is named) does not."""
    case = corpus.draw(seed)
    assert [e for e, _ in case.hidden] == ["backlash"] and case.angles == "both"
    log = logio.read_log(corpus.make_log(case, tmp_path / "l.csv"), require_tag=False)
    sig = signals.from_log(log)
    r = validity.log_range(log.meta, sig.dt, log["motor_angle_rad"], log["load_angle_rad"])
    assert (r.motor_bits, r.load_bits) == (pytest.approx(case.motor_bits), pytest.approx(case.load_bits))
    q = validity.twist_resolution(r, sig.ratio)
    st = case.axis["stiffness"]
    gap = 2 * st["t1_Nm"] / st["k1_Nm_per_rad"]                 # the zone's full width, rad
    note = validity.twist_note("l.csv", r, sig.ratio, validity.twist_p99(sig))
    assert (note is not None) == noted
    if noted:
        assert gap < 3 * q
