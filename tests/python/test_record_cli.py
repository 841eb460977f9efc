"""``hdservo record`` on the virtual drive: the log it writes is an hdservo log (docs/sim.md)
(format tag, gear ratio and encoder resolutions from the drive, the drive's parameters) that
``hdservo discrepancy`` reads as it is; bad arguments are one error line."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hdservo import logio
from hdservo.cli import main
from hdservo.drive import Drive, align_motor_turns
from hdservo.phase import unwrap_tick
from hdservo.params_gen import BY_NAME, TABLE_HASH

from vdrive import SIM, Server  # tests/python/vdrive.py

pytestmark = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")


def _bus(port: int) -> list[str]:
    return ["-i", "socketcand", "--host", "127.0.0.1", "--port", str(port)]


def test_recorded_log_goes_into_discrepancy(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run.csv"
    srv = Server("--pacing", "realtime", "-q")
    try:
        with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=srv.port) as d:
            d.start()
            d.set_param("pos_kp", 20.0)          # a recognisable setting for the sidecar
            d.enable("CYCLIC SYNCHRONOUS POSITION")
            # the drive's own excitation keeps the axis moving after this client leaves:
            # a position chirp of 0.05 rad, 0.5 -> 3 Hz over 6 s (reversals, torsion, friction)
            d.excite("chirp", 0.05, injection="position", f0_Hz=0.5, f1_Hz=3.0, duration_s=6.0)
        assert main(["record", *_bus(srv.port), "--duration", "3", "-o", str(out)]) == 0     # 2 kHz default
    finally:
        srv.stop()
    assert "lost ticks" in capsys.readouterr().out
    log = logio.read_log(out)                                   # validates format, units, sidecar types
    m = log.meta
    assert m["format"] == logio.FORMAT and m["gear_ratio"] == BY_NAME["gear_ratio"].default
    assert m["motor_encoder_counts_per_rev"] == 2 ** BY_NAME["motor_enc_bits"].default
    assert m["load_encoder_counts_per_rev"] == 2 ** BY_NAME["output_enc_bits"].default
    assert m["sample_period_s"] == 5e-4 and m["param_layout_hash"] == f"0x{TABLE_HASH:08X}"
    assert m["drive_params"]["pos_kp"] == 20.0 and len(m["drive_params"]) == len(BY_NAME)
    # 3 s of wall time: a realtime-paced drive on a loaded machine may fall a little behind, so the
    # row count is bounded below loosely; that no sample is lost is the exact check
    assert log.t[0] == 0.0 and len(log.t) >= 4000 and m["lost_ticks"] == 0
    assert np.allclose(np.diff(log.t), m["sample_period_s"])
    assert float(log["load_angle_rad"].max() - log["load_angle_rad"].min()) > 0.08     # it moved
    twist = log["motor_angle_rad"] / m["gear_ratio"] - log["load_angle_rad"]
    assert float(abs(twist).max()) < 5e-3        # the motor's whole turns match the load (align_motor_turns)
    assert out.with_suffix(".log").stat().st_size > 0                                 # raw frames too
    js = tmp_path / "disc.json"
    capsys.readouterr()
    assert main(["discrepancy", str(out), "--json", str(js)]) == 0
    assert "validated for" not in capsys.readouterr().err   # 2 kHz, the drive's encoders: inside the validated range
    r = json.loads(js.read_text())
    assert r["validated_range"]["inside"] and not any("validated" in n for n in r["notes"])
    b = r["baseline"]
    # two-mass baseline from the drive's own log: inertias and stiffness of the reference axis' order
    assert 0.1 < b["J_l_kgm2"] < 2.0 and 1e4 < b["K_Nm_per_rad"] < 1e5, b


def test_record_bad_rate_is_one_line(capsys) -> None:
    assert main(["record", "-i", "socketcand", "--port", "1", "--rate", "3000", "-o", "x.csv"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--rate 3000" in err[0], err


def test_motor_turns_aligned_to_the_load_through_the_gear() -> None:
    # N = 100, load at 0.2 turn with a twist of 1e-5 turn; the motor's phase 0.99 turn (PDO)
    # is read as -0.01 turn: its whole turns since power-on (20 -> 19.99) come from the load
    m = align_motor_turns(-0.01, 0.2 - 1e-5, 100.0)
    assert m == pytest.approx(19.99, abs=1e-12)
    assert align_motor_turns(0.3, -0.01, 50.0) == 0.3 - 1          # -0.7: -0.014 turn at the output, not +0.006
    assert align_motor_turns(0.25, 0.005, 50.0) == 0.25            # already the nearest


def test_tick_unwrap_across_the_32_bit_wrap() -> None:
    ticks = [2 ** 32 - 10, 2 ** 32 - 5, 0, 5, 3, 2 ** 32 - 1]      # wrap, then frames a little out of order
    out, last = [], None
    for t in ticks:
        last = unwrap_tick(last, t)
        out.append(last)
    assert out == [2 ** 32 - 10, 2 ** 32 - 5, 2 ** 32, 2 ** 32 + 5, 2 ** 32 + 3, 2 ** 32 - 1]
