"""CANopen conformance of the virtual drive (hdservo-sim serve) with python ``canopen`` over socketcand.

Each test starts ``build/bin/hdservo-sim serve`` on an ephemeral loopback port
and always kills it.  Time limits are checked in SIMULATED time (socketcand
timestamps and the drive's loop tick), never in wall-clock time.
"""
from __future__ import annotations

import logging
import queue
import struct
import subprocess
import time
import zlib
from pathlib import Path
from typing import Iterator

import can
import canopen
import pytest

from vdrive import NODE, SIM, Server  # tests/python/vdrive.py

ROOT = Path(__file__).resolve().parents[2]
EDS = ROOT / "host" / "hdservo" / "data" / "hdservo.eds"

logging.getLogger("can.interfaces.socketcand").setLevel(logging.ERROR)
pytestmark = pytest.mark.skipif(not SIM.exists(), reason="build/bin/hdservo-sim not built (make sim)")




def _connect(srv: Server) -> tuple[canopen.Network, canopen.BaseNode402]:
    net = canopen.Network()
    net.connect(interface="socketcand", host="127.0.0.1", port=srv.port, channel="can0")
    node = canopen.BaseNode402(NODE, str(EDS))
    net.add_node(node)
    return net, node


@pytest.fixture
def drive() -> Iterator[tuple[canopen.Network, canopen.BaseNode402]]:
    srv = Server("--pacing", "realtime")
    net = None
    try:
        net, node = _connect(srv)
        yield net, node
    finally:
        if net is not None:
            net.disconnect()
        srv.stop()


def _frames(net: canopen.Network) -> "queue.Queue[can.Message]":
    q: "queue.Queue[can.Message]" = queue.Queue()

    class L(can.Listener):
        def on_message_received(self, msg: can.Message) -> None:
            q.put(msg)

    net.notifier.add_listener(L())
    return q


def _wait_for(q: "queue.Queue[can.Message]", pred, timeout: float = 5.0) -> can.Message:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            m = q.get(timeout=0.05)
        except queue.Empty:
            continue
        if pred(m):
            return m
    raise AssertionError("expected frame not seen")


def test_nmt_and_heartbeat(drive) -> None:
    net, node = drive
    q = _frames(net)
    hb = _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE)
    assert hb.data[0] in (0x7F, 0x00)
    h1 = _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE and m.data[0] == 0x7F)
    h2 = _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE and m.data[0] == 0x7F)
    assert abs((h2.timestamp - h1.timestamp) - 0.100) < 1e-6        # 0x1017 = 100 ms, simulated time
    node.nmt.send_command(0x01)
    _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE and m.data[0] == 0x05)
    node.nmt.send_command(0x02)
    _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE and m.data[0] == 0x04)
    node.nmt.send_command(0x82)                                       # reset communication
    _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE and m.data[0] == 0x00)   # boot-up
    node.sdo[0x1017].raw = 20
    a = _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE and m.data[0] == 0x7F)
    b = _wait_for(q, lambda m: m.arbitration_id == 0x700 + NODE and m.data[0] == 0x7F)
    assert abs((b.timestamp - a.timestamp) - 0.020) < 1e-6


def test_sdo_every_data_type(drive) -> None:
    _, node = drive
    t = node.sdo["sdo_test"]
    cases = {"test_bool": [0, 1], "test_i8": [-100, 0, 100], "test_i16": [-32768, 32767],
             "test_i32": [-2 ** 31, 2 ** 31 - 1], "test_i64": [-2 ** 63, 2 ** 63 - 1, 0x0102030405060708],
             "test_u8": [0, 255], "test_u16": [0, 65535], "test_u32": [10, 1000000],
             "test_u64": [0, 2 ** 63 - 1]}
    for name, values in cases.items():
        for v in values:
            t[name].raw = v
            assert t[name].raw == v, name
    assert node.sdo[0x1008].raw == "hdservo harmonic-drive servo"       # visible string, segmented
    assert node.sdo[0x1000].raw == 0x00020192
    assert node.sdo[0x1018][1].raw == 0x00000EDA
    # drive parameter with its scale (SI through the EDS factor)
    node.sdo[0x2100][1].raw = 40 * 65536
    assert node.sdo[0x2100][1].raw == 40 * 65536
    assert abs(node.sdo[0x2100][1].phys - 40.0) < 1e-9


def _table(n: int, seed: int) -> bytes:
    body = bytes((i * 131 + seed) & 0xFF for i in range(n - 4))
    return body + struct.pack("<I", zlib.crc32(body))


def test_block_and_segmented_64k_domain(drive) -> None:
    _, node = drive
    dom = node.sdo[0x5F20][11]
    blob = _table(65536, 7)
    with dom.open("wb", size=len(blob), block_transfer=True) as f:
        f.write(blob)
    with dom.open("rb", block_transfer=True) as f:
        assert f.read() == blob
    with dom.open("rb") as f:                                        # segmented upload
        assert f.read() == blob
    small = _table(1000, 3)
    with dom.open("wb", size=len(small)) as f:                       # segmented download
        f.write(small)
    with dom.open("rb", block_transfer=True) as f:
        assert f.read() == small
    # a table whose own CRC fails is refused, the old one stays
    bad = bytearray(_table(4000, 9))
    bad[100] ^= 0xFF
    with pytest.raises(canopen.SdoAbortedError) as e:
        with dom.open("wb", size=len(bad), block_transfer=True) as f:
            f.write(bytes(bad))
    assert e.value.code == 0x08000020
    with dom.open("rb", block_transfer=True) as f:
        assert f.read() == small


def _abort(fn) -> int:
    with pytest.raises(canopen.SdoAbortedError) as e:
        fn()
    return e.value.code


def _raw_sdo(net: canopen.Network, q: "queue.Queue[can.Message]", data: bytes) -> bytes:
    net.send_message(0x600 + NODE, data)
    return bytes(_wait_for(q, lambda m: m.arbitration_id == 0x580 + NODE).data)


def test_abort_codes(drive) -> None:
    net, node = drive
    sdo = node.sdo
    t = sdo["sdo_test"]
    assert _abort(lambda: sdo.upload(0x1234, 0)) == 0x06020000
    assert _abort(lambda: sdo.upload(0x1018, 9)) == 0x06090011
    assert _abort(lambda: sdo.download(0x1000, 0, b"\0\0\0\0")) == 0x06010002
    assert _abort(lambda: sdo.upload(0x5F20, 10)) == 0x06010001
    assert _abort(lambda: sdo.download(0x5F20, 8, b"\1\0")) == 0x06070013
    assert _abort(lambda: sdo.download(0x5F20, 7, b"\1\0\0\0")) == 0x06070012
    assert _abort(lambda: sdo.download(0x5F20, 8, b"\0" * 10, force_segment=True)) == 0x06070012
    assert _abort(lambda: setattr(t["test_u32"], "raw", 5)) == 0x06090032
    assert _abort(lambda: setattr(t["test_u32"], "raw", 2000000)) == 0x06090031
    assert _abort(lambda: setattr(sdo[0x6060], "raw", 7)) == 0x06090030
    assert _abort(lambda: setattr(sdo[0x1010][1], "raw", 1)) == 0x08000020
    assert _abort(lambda: setattr(sdo[0x1A01][1], "raw", 0x5F000120)) == 0x08000022
    q = _frames(net)
    # invalid command specifier
    r = _raw_sdo(net, q, bytes([0xE0, 0, 0x10, 0, 0, 0, 0, 0]))
    assert r[0] == 0x80 and struct.unpack_from("<I", r, 4)[0] == 0x05040001
    # toggle bit
    r = _raw_sdo(net, q, bytes([0x21, 0x20, 0x5F, 5, 8, 0, 0, 0]))
    assert r[0] == 0x60
    r = _raw_sdo(net, q, bytes([0x10, 1, 2, 3, 4, 5, 6, 7]))
    assert struct.unpack_from("<I", r, 4)[0] == 0x05030000
    # block size 0 and sequence number 0
    r = _raw_sdo(net, q, bytes([0xA4, 0x20, 0x5F, 11, 0, 0, 0, 0]))
    assert struct.unpack_from("<I", r, 4)[0] == 0x05040002
    r = _raw_sdo(net, q, bytes([0xC6, 0x20, 0x5F, 11, 100, 0, 0, 0]))
    assert r[0] & 0xE0 == 0xA0
    r = _raw_sdo(net, q, bytes([0x00, 1, 2, 3, 4, 5, 6, 7]))
    assert struct.unpack_from("<I", r, 4)[0] == 0x05040003
    # block CRC
    r = _raw_sdo(net, q, bytes([0xC6, 0x20, 0x5F, 11, 7, 0, 0, 0]))
    net.send_message(0x600 + NODE, bytes([0x81, 1, 2, 3, 4, 5, 6, 7]))
    r = bytes(_wait_for(q, lambda m: m.arbitration_id == 0x580 + NODE).data)
    assert r[0] == 0xA2 and r[1] == 1
    r = _raw_sdo(net, q, bytes([0xC1, 0x12, 0x34, 0, 0, 0, 0, 0]))
    assert struct.unpack_from("<I", r, 4)[0] == 0x05040004
    # time-out: a segmented download left hanging (1 s of simulated time)
    r = _raw_sdo(net, q, bytes([0x21, 0x20, 0x5F, 5, 8, 0, 0, 0]))
    assert r[0] == 0x60
    r = bytes(_wait_for(q, lambda m: m.arbitration_id == 0x580 + NODE, timeout=10).data)
    assert struct.unpack_from("<I", r, 4)[0] == 0x05040000
    # PDO mapping aborts
    sdo[0x1801][1].raw = 0x80000281
    sdo[0x1A01][0].raw = 0
    assert _abort(lambda: setattr(sdo[0x1A01][1], "raw", 0x60400010)) == 0x06040041
    sdo[0x1A01][1].raw = 0x5F000940
    sdo[0x1A01][2].raw = 0x5F000120
    assert _abort(lambda: setattr(sdo[0x1A01][0], "raw", 2)) == 0x06040042
    # the drive still answers
    assert sdo[0x1000].raw == 0x00020192


def test_pdo_remap_and_stream_2khz_10s() -> None:
    srv = Server("--pacing", "fast")
    net = None
    try:
        net, node = _connect(srv)
        node.tpdo.read()
        tp = node.tpdo[2]
        tp.clear()
        tp.add_variable("drive_status", "loop_tick")
        tp.add_variable("drive_status", "load_velocity")
        tp.trans_type = 254
        tp.enabled = True
        tp.save()
        for n in (3, 4):
            node.tpdo[n].enabled = False
            node.tpdo[n].save()
        node.sdo["tpdo_stream_period"]["tpdo_stream_period_2"].raw = 5      # every 5 loop ticks = 2 kHz
        q = _frames(net)
        node.nmt.send_command(0x01)
        ticks: list[int] = []
        end = time.monotonic() + 120
        while len(ticks) < 20001 and time.monotonic() < end:
            try:
                m = q.get(timeout=1.0)
            except queue.Empty:
                continue
            if m.arbitration_id == 0x280 + NODE:
                assert len(m.data) == 8
                ticks.append(struct.unpack_from("<I", m.data, 0)[0])
        assert len(ticks) == 20001
        steps = {b - a for a, b in zip(ticks, ticks[1:])}
        assert steps == {5}, f"lost or repeated ticks: {sorted(steps)[:10]}"
    finally:
        if net is not None:
            net.disconnect()
        srv.stop()


def test_402_state_machine_with_fault_and_reset(drive) -> None:
    net, node = drive
    node.tpdo.read()
    node.rpdo.read()
    node.setup_402_state_machine(read_pdos=False)
    node.nmt.state = "OPERATIONAL"                 # event TPDO1 (statusword) goes out once
    node.tpdo[1].wait_for_reception(2.0)
    assert node.state == "SWITCH ON DISABLED"
    node.op_mode = "CYCLIC SYNCHRONOUS POSITION"
    for st in ("READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED"):
        node.state = st
        assert node.state == st
    assert node.sdo["drive_status"]["power_enabled"].raw == 1
    node.state = "SWITCHED ON"
    assert node.sdo["drive_status"]["power_enabled"].raw == 0
    node.state = "OPERATION ENABLED"
    node.op_mode = "CYCLIC SYNCHRONOUS VELOCITY"
    assert node.op_mode == "CYCLIC SYNCHRONOUS VELOCITY"
    node.state = "SWITCH ON DISABLED"
    # fault through a lost host heartbeat, then fault reset
    node.sdo[0x1016][1].raw = (127 << 16) | 50
    hb = net.send_periodic(0x700 + 127, [0x05], 0.01)
    node.state = "OPERATION ENABLED"
    hb.stop()
    end = time.monotonic() + 10
    while not node.is_faulted() and time.monotonic() < end:
        time.sleep(0.01)
    assert node.is_faulted()
    assert node.sdo[0x603F].raw == 0x8130
    node.reset_from_fault()                       # canopen: fault reset, then on to OPERATION ENABLED
    assert node.state == "OPERATION ENABLED"
    assert node.sdo[0x1001].raw == 0
    assert node.sdo[0x603F].raw == 0
    node.state = "SWITCH ON DISABLED"
    assert node.state == "SWITCH ON DISABLED"


def test_heartbeat_loss_fault_and_emcy_in_time(drive) -> None:
    net, node = drive
    node.sdo[0x1016][1].raw = (127 << 16) | 100
    hb = net.send_periodic(0x700 + 127, [0x05], 0.01)
    time.sleep(0.1)
    node.sdo[0x6060].raw = 9
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    assert node.sdo[0x6041].raw & 0x6F == 0x27
    q = _frames(net)
    hb.stop()
    time.sleep(0.02)                                             # a heartbeat still in flight has arrived
    u0 = node.sdo["drive_status"]["uptime_ticks"].raw           # every host heartbeat was sent before this
    emcy = _wait_for(q, lambda m: m.arbitration_id == 0x80 + NODE and m.data[0:2] == b"\x30\x81", timeout=10)
    assert emcy.data[2] & 0x10                                  # communication error bit
    assert emcy.timestamp - u0 * 1e-4 <= 0.100 + 1e-4           # within 0x1016's 100 ms, simulated time
    assert node.sdo[0x6041].raw & 0x4F == 0x08                  # FAULT
    assert node.sdo["drive_status"]["power_enabled"].raw == 0
    assert node.sdo[0x1003][1].raw & 0xFFFF == 0x8130
