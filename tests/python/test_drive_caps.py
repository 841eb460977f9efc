"""Any CiA 402 drive: the generic profile of the virtual drive, capability detection
(:mod:`hdservo.drive_caps`), ``hdservo drive info`` and the commands' refusal before they start.

* ``hdservo-sim serve --profile generic`` refuses every manufacturer object (0x2000-0x5FFF)
  with abort 0x06020000 (a PDO mapping of one with 0x06040041), logs each on stderr and
  counts it in the exit statistics; the standard objects answer, 0x60E4:1 is the motor
  encoder in 0x6064's unit; the simulated bench (--rig) is not part of the drive.
* ``hdservo drive info`` reports each profile's capabilities; the probe of the generic
  drive never touches a vendor object (the server's count stays 0).
* A command that needs hdservo's vendor objects refuses in one line against the generic
  drive, before it touches any vendor object or writes any file.
"""
from __future__ import annotations

import json
import math
import subprocess
import time
from pathlib import Path
from typing import Any

import canopen
import pytest

from hdservo import drive_caps
from hdservo.cli import main
from hdservo.drive import EDS_PATH, Drive, DriveError

from vdrive import NODE, SIM, Server  # tests/python/vdrive.py

pytestmark = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")

VENDOR_PROBES = ((0x5000, 1), (0x2000, 1), (0x5F00, 1), (0x5100, 1), (0x5010, 2))


def _stats(stderr: str) -> dict[str, Any]:
    """The exit statistics line of the virtual drive."""
    lines = [x for x in stderr.splitlines() if x.startswith("{")]
    assert lines, stderr
    return json.loads(lines[-1])


def _node(port: int) -> tuple[canopen.Network, canopen.RemoteNode]:
    net = canopen.Network()
    net.connect(interface="socketcand", host="127.0.0.1", port=port, channel="can0")
    node = canopen.RemoteNode(NODE, str(EDS_PATH))
    node.sdo.RESPONSE_TIMEOUT = 2.0         # a loaded machine (the drive answers in microseconds)
    net.add_node(node)
    return net, node


def _abort(fn: Any) -> int:
    try:
        fn()
    except canopen.SdoAbortedError as e:
        return int(e.code)
    return 0


def test_generic_profile_refuses_and_logs_every_vendor_access() -> None:
    srv = Server("--profile", "generic", "--pacing", "fast", "-q")
    try:
        net, node = _node(srv.port)
        try:
            aborts = [_abort(lambda i=i, s=s: node.sdo.upload(i, s)) for i, s in VENDOR_PROBES]
            # a download, and mapping a vendor object into a PDO, are refused too
            dl = _abort(lambda: node.sdo.download(0x2000, 1, (100).to_bytes(4, "little")))
            node.sdo.download(0x1A03, 0, b"\x00")
            mp = _abort(lambda: node.sdo.download(0x1A03, 1, (0x5F000120).to_bytes(4, "little")))
            # the standard objects answer
            dtype = int.from_bytes(node.sdo.upload(0x1000, 0), "little")
            product = int.from_bytes(node.sdo.upload(0x1018, 2), "little")
            pos = int.from_bytes(node.sdo.upload(0x6064, 0), "little", signed=True)
            mot = int.from_bytes(node.sdo.upload(0x60E4, 1), "little", signed=True)
            modes = int.from_bytes(node.sdo.upload(0x6502, 0), "little")
        finally:
            net.disconnect()
    finally:
        err = srv.stop()
    assert aborts == [0x06020000] * len(VENDOR_PROBES)
    assert dl == 0x06020000 and mp == 0x06040041
    assert dtype == 0x00020192 and product == 0x0047454E and modes & 0x380 == 0x380
    # 0x60E4:1 is the motor encoder / N in 0x6064's unit (2^-24 turn): at rest, within the twist
    assert abs(mot - pos) < 2 ** 24 * 1e-3
    for i, s in VENDOR_PROBES + ((0x2000, 1), (0x5F00, 1)):
        assert f"vendor-object access 0x{i:04X}:{s} refused" in err
    st = _stats(err)
    assert st["profile"] == "generic" and st["vendor_refused"] == len(VENDOR_PROBES) + 2


def test_hdservo_profile_answers_the_same_accesses() -> None:
    srv = Server("--pacing", "fast", "-q")
    try:
        net, node = _node(srv.port)
        try:
            aborts = [_abort(lambda i=i, s=s: node.sdo.upload(i, s)) for i, s in VENDOR_PROBES]
        finally:
            net.disconnect()
    finally:
        err = srv.stop()
    assert aborts == [0] * len(VENDOR_PROBES)
    st = _stats(err)
    assert st["profile"] == "hdservo" and st["vendor_refused"] == 0 and "vendor-object" not in err


def test_bad_profile_names_are_one_line() -> None:
    for extra, words in ((["--profile", "cia"], "--profile 'cia': expected hdservo or generic"),):
        p = subprocess.run([str(SIM), "serve", "--port", "0", *extra], capture_output=True, text=True, timeout=20)
        lines = p.stderr.strip().splitlines()
        assert p.returncode == 2 and len(lines) == 1 and words in lines[0], (extra, p.stderr)


def test_generic_nmt_reset_keeps_the_generic_identity_and_pdos() -> None:
    srv = Server("--profile", "generic", "--pacing", "fast", "-q")
    try:
        net, node = _node(srv.port)
        try:
            # reset communication: the defaults of 0x1000-0x1FFF.  The drive handles frames in
            # order, so the uploads below see the reset done (waiting for the boot-up message
            # instead would race with it: it can come before the wait starts)
            node.nmt.send_command(0x82)
            product = int.from_bytes(node.sdo.upload(0x1018, 2), "little")
            tpdo2 = int.from_bytes(node.sdo.upload(0x1A01, 1), "little")
            node.sdo.download(0x1011, 1, (0x64616F6C).to_bytes(4, "little"))     # 0x1011 restore: 'load'
            tpdo1 = [int.from_bytes(node.sdo.upload(0x1A00, k), "little") for k in range(5)]
        finally:
            net.disconnect()
    finally:
        err = srv.stop()
    assert product == 0x0047454E and tpdo2 == 0x60640020
    # the generic profile's own defaults, not the firmware's (whose TPDO1 maps the 0x5F00 loop tick)
    assert tpdo1 == [3, 0x60410010, 0x60610008, 0x10010008, 0]
    assert _stats(err)["vendor_refused"] == 0


def test_probe_of_the_generic_drive_touches_no_vendor_object() -> None:
    srv = Server("--profile", "generic", "--pacing", "fast", "-q")
    try:
        with Drive.connect(NODE, interface="socketcand", host="127.0.0.1", port=srv.port, channel="can0") as d:
            caps = drive_caps.probe(d.node.sdo)
    finally:
        err = srv.stop()
    assert _stats(err)["vendor_refused"] == 0
    assert not caps.vendor_probed and not caps.is_hdservo
    assert caps.modes == ("PP", "CSP", "CSV", "CST") and caps.has("sync") and caps.has("cia402")
    assert caps.objects["position_actual"].mapped == "TPDO2"
    assert caps.objects["second_encoder"].mapped == "TPDO3" and caps.objects["second_encoder"].mappable
    assert caps.missing(["hdservo.capture", "second_encoder", "torque_offset"]) == ["hdservo.capture"]
    with pytest.raises(drive_caps.CapabilityError, match=r"lacks what identify needs: .*capture \(0x5000\)"):
        caps.require(*drive_caps.COMMAND_NEEDS["identify"], command="identify")


@pytest.mark.parametrize("sim, hdservo", [("reference", True), ("generic:reference", False)])
def test_drive_info_both_profiles(tmp_path: Path, capsys: pytest.CaptureFixture[str], sim: str,
                                  hdservo: bool) -> None:
    js = tmp_path / "info.json"
    rc = main(["drive", "info", "--json", str(js), f"--sim={sim}"])
    out = capsys.readouterr()
    assert rc == 0, out.err
    doc = json.loads(js.read_text())
    assert doc["profile"] == 402 and doc["modes"] == ["PP", "CSP", "CSV", "CST"] and doc["sync"]
    assert doc["hdservo_firmware"] is hdservo
    assert all(doc["feedback"][k]["present"] for k in drive_caps.FEEDBACK)
    assert all(doc["setpoints"][k]["present"] for k in drive_caps.SETPOINTS)
    if hdservo:
        assert doc["vendor_extensions"] == {k: True for k in drive_caps.VENDOR_OBJECTS}
        assert all(c["ok"] for c in doc["commands"].values())
        assert "hdservo vendor extensions: capture yes" in out.out
    else:
        assert doc["vendor_extensions"] is None and doc["identity"]["product_code"] == "0x0047454E"
        assert doc["commands"]["download"]["missing"] == ["hdservo.parameters", "hdservo.tables"]
        assert doc["feedback"]["position_actual"]["mapped"] == "TPDO2"
        assert "generic CiA 402 profile" in out.err and "0x2000-0x5FFF not probed" in out.out


MODEL = """[gear]
ratio = 100.0
[transmission_error]
wg1_order = 1
wg1_amp_rad = 1.45e-5
wg1_phase_rad = -1.2
"""


@pytest.mark.parametrize("argv, words", [
    (["identify", "friction", "-q", "-o", "{tmp}/m.toml"], "identify needs: hdservo vendor object: drive parameters"),
    (["download", "{tmp}/model.toml", "-q"], "download needs: hdservo vendor object: drive parameters"),
    (["config", "get", "pos_kp"], "config needs: hdservo vendor object: drive parameters"),
    (["record", "-o", "{tmp}/r.csv", "--duration", "0.1"], "record needs: hdservo vendor object: drive parameters"),
])
def test_vendor_commands_refuse_the_generic_drive_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                              argv: list[str], words: str) -> None:
    (tmp_path / "model.toml").write_text(MODEL)
    srv = Server("--profile", "generic", "--pacing", "realtime", "-q")
    try:
        rc = main([a.format(tmp=tmp_path) for a in argv]
                  + ["-i", "socketcand", "--host", "127.0.0.1", "--port", str(srv.port)])
    finally:
        err = srv.stop()
    lines = capsys.readouterr().err.strip().splitlines()
    lines = [x for x in lines if not x.startswith("[")]        # progress lines
    assert rc == 2 and len(lines) == 1 and words in lines[0], lines
    assert "0x1018" not in lines[0] and "vendor 0x00000EDA product 0x0047454E" in lines[0]
    # refused before anything: no vendor object touched, no file written
    assert _stats(err)["vendor_refused"] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.toml"]


def test_test_command_refuses_the_generic_sim_before_any_procedure(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    js = tmp_path / "t.json"
    rc = main(["test", "positioning", "--json", str(js), "--sim=generic:reference"])
    err = [x for x in capsys.readouterr().err.strip().splitlines() if not x.startswith("hdservo test: using")]
    assert rc == 2 and len(err) == 1 and "test needs: hdservo vendor object" in err[0], err
    assert not js.exists()


class _FakeSdo:
    """An SDO client over a dict: records every index asked for."""

    def __init__(self, values: dict[tuple[int, int], int]) -> None:
        self.values = values
        self.asked: list[int] = []

    def upload(self, index: int, sub: int) -> bytes:
        self.asked.append(index)
        if (index, sub) not in self.values:
            raise canopen.SdoAbortedError(0x06020000)
        return self.values[(index, sub)].to_bytes(4, "little")


def _third_party(vendor: int, product: int) -> dict[tuple[int, int], int]:
    return {(0x1000, 0): 0x00020192, (0x1018, 1): vendor, (0x1018, 2): product, (0x1018, 3): 1, (0x1018, 4): 7,
            (0x6502, 0): 0x000001A5, (0x6064, 0): 0, (0x606C, 0): 0, (0x6077, 0): 0, (0x607A, 0): 0,
            (0x60FF, 0): 0, (0x6071, 0): 0, (0x1005, 0): 0x80, (0x1800, 1): 0x181, (0x1A00, 0): 1,
            (0x1A00, 1): 0x60640020, (0x1400, 1): 0x201, (0x1600, 0): 0,
            # a vendor object that, on another vendor's drive, means something else
            (0x5000, 2): 3, (0x5F00, 1): 0}


def test_vendor_objects_are_probed_only_on_the_hdservo_identity() -> None:
    other = _FakeSdo(_third_party(0x0000009A, 0x00030924))
    caps = drive_caps.probe(other, use_eds=False)
    assert not any(0x2000 <= i <= 0x5FFF for i in other.asked)
    assert caps.modes == ("PP", "PV", "HM", "CSP", "CSV") and caps.objects["position_actual"].mapped == "TPDO1"
    assert caps.missing(["mode:CST", "hdservo.capture", "second_encoder", "mode:CSP"]) == \
        ["mode:CST", "hdservo.capture", "second_encoder"]
    assert caps.objects["position_actual"].mappable is None      # no EDS
    ours = _FakeSdo(_third_party(drive_caps.HDSERVO_VENDOR_ID, drive_caps.HDSERVO_PRODUCT_CODE))
    caps = drive_caps.probe(ours, use_eds=False)
    assert caps.vendor_probed and caps.has("hdservo.capture") and not caps.has("hdservo.tables")
    assert not caps.is_hdservo


def test_require_names_each_missing_capability_once() -> None:
    caps = drive_caps.probe(_FakeSdo(_third_party(0x9A, 0x1)), use_eds=False)
    with pytest.raises(drive_caps.CapabilityError) as e:
        drive_caps.require(caps, "mode:CST", "second_encoder", "position_actual", command="test")
    msg = str(e.value)
    assert "\n" not in msg and "mode CST (0x6502 bit 9)" in msg
    assert "0x60E4:1 additional position actual value" in msg and "0x6064" not in msg
    with pytest.raises(KeyError):
        caps.has("warp_drive")
    assert math.isfinite(float(caps.device_type or 0))


@pytest.mark.parametrize("mode", ["CYCLIC SYNCHRONOUS VELOCITY", "CYCLIC SYNCHRONOUS TORQUE"])
def test_generic_drive_enabled_through_the_canopen_402_profile(mode: str) -> None:
    srv = Server("--profile", "generic", "--pacing", "realtime", "-q")
    try:
        with Drive.connect(NODE, interface="socketcand", host="127.0.0.1", port=srv.port, channel="can0") as d:
            d.start()
            d.enable_402(mode)
            enabled, shown = d.state(), int(d.read(0x6061))
            if mode == "CYCLIC SYNCHRONOUS VELOCITY":
                # 0x60E4:1 (motor encoder / N) follows 0x6064 (output encoder) through a move of
                # 10 deg/s: the same unit, apart by the twist and the TE only (< 1e-4 turn)
                p0, m0 = int(d.read(0x6064)), int(d.read(0x60E4, 1))
                d.write(0x60FF, 0, round(10.0 / 360.0 * 2 ** 32))
                time.sleep(0.5)
                p1, m1 = int(d.read(0x6064)), int(d.read(0x60E4, 1))
                d.write(0x60FF, 0, 0)
                assert p1 - p0 > 0.004 * 2 ** 24, (p0, p1)          # it moved (> 1.4 deg)
                assert abs((m1 - m0) - (p1 - p0)) < 1e-4 * 2 ** 24, (m1 - m0, p1 - p0)
            if mode == "CYCLIC SYNCHRONOUS TORQUE":
                # 0x6078 current actual (per mille of 0x6075) follows the torque (per mille of 0x6076):
                # both ratings are the reference axis' (6.7 A = 67 N.m / (100 x 0.1 N.m/A))
                d.write(0x6071, 0, 100)
                time.sleep(0.3)
                torque, current = int(d.read(0x6077)), int(d.read(0x6078))
                d.write(0x6071, 0, 0)
                assert torque == 100 and 80 <= current <= 120, (torque, current)
            d.disable_402()
            disabled = d.state()
    finally:
        err = srv.stop()
    assert enabled == "OPERATION ENABLED" and shown == {"CYCLIC SYNCHRONOUS VELOCITY": 9,
                                                          "CYCLIC SYNCHRONOUS TORQUE": 10}[mode]
    assert disabled == "SWITCH ON DISABLED"
    assert _stats(err)["vendor_refused"] == 0


def test_enable_402_refuses_a_mode_the_drive_lacks() -> None:
    srv = Server("--profile", "generic", "--pacing", "realtime", "-q")
    try:
        with Drive.connect(NODE, interface="socketcand", host="127.0.0.1", port=srv.port, channel="can0") as d:
            d.start()
            with pytest.raises(DriveError, match="must be one of"):
                d.enable_402("HOMING")
            caps = d.capabilities()
    finally:
        srv.stop()
    assert "HM" not in caps.modes and caps.profile == 402


def test_sim_generic_spelling(tmp_path: Path) -> None:
    import argparse

    from hdservo.cli import UserError
    from hdservo.drive import add_bus_arguments, choose_drive

    def choice(arg: str) -> Any:
        p = argparse.ArgumentParser()
        add_bus_arguments(p)
        return choose_drive(p.parse_args([f"--sim={arg}"]))

    axis = tmp_path / "a.toml"
    axis.write_text("")
    got = [(c.profile, c.axis) for c in (choice("generic"), choice("generic:minimal"), choice(f"generic:{axis}"),
                                         choice("reference"))]
    assert got == [("generic", "reference"), ("generic", "minimal"), ("generic", str(axis.resolve())),
                   ("hdservo", "reference")]
    assert "generic CiA 402 profile" in choice("generic").describe()
    with pytest.raises(UserError, match="--sim generic:no/such.toml: no such axis file"):
        choice("generic:no/such.toml")


def test_generic_bench_rig_refuses_at_once() -> None:
    from hdservo.procedures.runner import NoRig, RigError, RigSetup
    rig = NoRig(RigSetup())
    for act in (lambda: rig.brake(True), lambda: rig.load_torque(5.0), lambda: rig.load_torque_profile([(1.0, 2.0)])):
        t0 = time.monotonic()
        with pytest.raises(RigError, match="generic CiA 402 drive has no test rig"):
            act()
        assert time.monotonic() - t0 < 1.0          # not a rig command waiting for an answer


class _StaleSdo(_FakeSdo):
    """An SDO client whose first answer to one object is a stale response to an earlier request."""

    RESPONSE_TIMEOUT = 0.01

    def __init__(self, values: dict[tuple[int, int], int], stale_at: tuple[int, int], times: int) -> None:
        super().__init__(values)
        self.stale_at, self.left = stale_at, times

    def upload(self, index: int, sub: int) -> bytes:
        if (index, sub) == self.stale_at and self.left > 0:
            self.left -= 1
            self.asked.append(index)
            raise canopen.SdoCommunicationError("Node returned a value for 0x1A02:01 instead, maybe there is "
                                                "another SDO client communicating on the same SDO channel?")
        return super().upload(index, sub)


def test_probe_asks_again_after_a_stale_sdo_response() -> None:
    """A late answer of a loaded link taken for the next upload is not the end of the probe."""
    sdo = _StaleSdo(_third_party(0x9A, 0x1), (0x6502, 0), times=2)
    caps = drive_caps.probe(sdo, use_eds=False)
    assert caps.modes == ("PP", "PV", "HM", "CSP", "CSV") and sdo.left == 0
    assert sdo.asked.count(0x6502) == 3                  # two stale answers, then the value
    # a drive that keeps answering out of turn, or does not answer at all, is still an error
    with pytest.raises(canopen.SdoCommunicationError, match="instead"):
        drive_caps.probe(_StaleSdo(_third_party(0x9A, 0x1), (0x6502, 0), times=drive_caps.STALE_ATTEMPTS), use_eds=False)

    class _Silent(_FakeSdo):
        def upload(self, index: int, sub: int) -> bytes:
            self.asked.append(index)
            raise canopen.SdoCommunicationError("No SDO response received")
    silent = _Silent({})
    with pytest.raises(canopen.SdoCommunicationError, match="No SDO response"):
        drive_caps.probe(silent, use_eds=False)
    assert len(silent.asked) == 1                        # a time-out is python canopen's to repeat, not ours
