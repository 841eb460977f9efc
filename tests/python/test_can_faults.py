"""CAN-side fault reactions of the virtual drive (hdservo.faults_can): host heartbeat loss,
error passive, bus-off with recovery (fault and quick-stop options), bus-off and power loss
in the middle of a table download; the injection interface of ``hdservo-sim serve``
(bad options and rig commands); the host client under frame loss.  The 20 % frame-loss
row with the host tool runs in ``make results`` only (about 40 s)."""
from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest

from oracles import faults_can
from hdservo.drive import Drive, DriveError
from hdservo.serve_proc import ServeError
from vdrive import SIM

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")


def _assert_row(row: dict) -> None:
    bad = {k: v for k, v in row["checks"].items() if not v}
    assert row["pass"] and not bad, f"{row['scenario']}: failed {sorted(bad)}; observed {row['observed']}"


@pytest.mark.parametrize("case", [faults_can.case_heartbeat_loss, faults_can.case_bus_off_burst,
                                  faults_can.case_bus_off_quick_stop, faults_can.case_error_passive,
                                  faults_can.case_table_download_bus_off, faults_can.case_power_loss_table],
                         ids=lambda c: c.__name__)
def test_can_fault_row(case) -> None:
    _assert_row(case(ROOT))


def test_rig_can_commands_and_bad_input() -> None:
    v = faults_can._VDrive(ROOT)
    try:
        st = v.rig("can status")
        assert st["can"] == "active" and st["tec"] == "0" and st["bus_off"] == "0"
        assert v.rig("can errors 16 0")["can"] == "passive"
        assert v.rig("can busoff")["can"] == "bus-off"
        for bad in ("can drop 1.5", "can drop x", "can errors 1", "can errors -1 0", "can frob"):
            with pytest.raises(ServeError, match="error can"):
                v.rig(bad)
    finally:
        v.stop()


@pytest.mark.parametrize("args, msg", [(["--can-drop", "2"], "--can-drop must be a probability 0..1"),
                                       (["--can-seed", "-1"], "--can-seed must be an integer 0..2^32-1"),
                                       (["--nvm"], "--nvm needs a value")])
def test_serve_bad_injection_options(args: list[str], msg: str) -> None:
    p = subprocess.run([str(SIM), "serve", *args], capture_output=True, text=True, timeout=30)
    assert p.returncode == 2
    assert p.stderr.strip().splitlines() == [f"hdservo-sim serve: error: {msg}"]


def test_serve_nvm_file_of_wrong_size(tmp_path: Path) -> None:
    f = tmp_path / "nvm.bin"
    f.write_bytes(b"\xff" * 100)
    p = subprocess.run([str(SIM), "serve", "--port", "0", "--nvm", str(f)], capture_output=True, text=True,
                       timeout=30)
    assert p.returncode == 1
    assert p.stderr.strip().splitlines() == [
        f"hdservo-sim serve: error: --nvm {f}: expected a file of exactly 32768 bytes (or none yet)"]
    assert f.read_bytes() == b"\xff" * 100


def test_client_under_frame_loss_retries_or_fails_with_one_line() -> None:
    """30 % of the frames lost: every SDO read ends (3 attempts x 0.3 s, bounded), with the value or a
    DriveError line (time-out, or a late duplicate answer the client refuses)."""
    v = faults_can._VDrive(ROOT, "--can-drop", "0.3", "--can-seed", "11")
    d = None
    try:
        d = Drive.connect(1, interface="socketcand", host="127.0.0.1", port=v.port, channel="can0")
        ok = failed = 0
        for _ in range(20):
            t0 = time.monotonic()
            try:
                assert d.read(0x1000) == 0x00020192
                ok += 1
            except DriveError as e:
                assert "\n" not in str(e) and str(e).startswith("read 0x1000:0: ")
                failed += 1
            assert time.monotonic() - t0 < 10.0        # 3 x 0.3 s, plus scheduling on a loaded machine
        assert ok > 0                                  # the retries get most reads through
        st = v.rig("can status")
        assert int(st["lost_rx"]) + int(st["lost_tx"]) > 0
    finally:
        if d is not None:
            d.close()
        v.stop()
