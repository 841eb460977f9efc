"""NMT transitions, COB-ID rules and the table commit interlock of the virtual drive, seen
from an outside master.

The drive (``hdservo-sim serve``, the drive firmware on the simulated axis) is reached only
through python-can frames and python ``canopen`` with the drive's EDS; nothing of the
``hdservo`` package is used but the process that starts the virtual drive (tests/python/vdrive.py).

What is checked (docs/can.md, "NMT and the CiA 402 abort connection option"):

- every NMT command (start, stop, enter pre-operational, reset communication, reset node) in
  every reachable CiA 402 state (switch on disabled, ready to switch on, switched on, operation
  enabled, fault) ends in the documented 402 state with the power stage (statusword bit 4) on
  or off as documented; operation enabled also with the 0x6007 options 0, 2 and 3;
- COB-IDs: CiA 301 restricted identifiers and the node's own service identifiers are refused
  with SDO abort 0x06090030 and the old value stays; the node still answers SDO after a refused
  SYNC identifier; the invalid-then-new-identifier sequence moves a TPDO;
- a table download (0x5100:3, segmented) that is running when the drive is enabled is aborted
  with 0x08000022 and the table in force stays.
"""
from __future__ import annotations

import logging
import queue
import struct
import time
import zlib
from pathlib import Path
from typing import Callable, Iterator

import can
import canopen
import pytest

from vdrive import NODE, SIM, Server  # tests/python/vdrive.py

ROOT = Path(__file__).resolve().parents[2]
EDS = ROOT / "host" / "hdservo" / "data" / "hdservo.eds"

logging.getLogger("can.interfaces.socketcand").setLevel(logging.ERROR)
pytestmark = pytest.mark.skipif(not SIM.exists(), reason="build/bin/hdservo-sim not built (make sim)")

NMT_START, NMT_STOP, NMT_PREOP, NMT_RESET_NODE, NMT_RESET_COMM = 0x01, 0x02, 0x80, 0x81, 0x82
SW_VOLTAGE = 0x0010                       # statusword bit 4: voltage enabled (power stage on)
EMCY_COMM = 0x8100                        # 0x603F after an NMT-ended connection with 0x6007 = 1
AB_VALUE, AB_STATE, AB_CMD = 0x06090030, 0x08000022, 0x05040001
CSV = 9
VEL = int(2 ** 32 / 360)                  # 1 deg/s in 2^-32 turn/s (0x60FF)


def _state(sw: int) -> str:
    """CiA 402 state name of a statusword."""
    if sw & 0x4F == 0x40:
        return "SWITCH ON DISABLED"
    if sw & 0x4F == 0x08:
        return "FAULT"
    return {0x21: "READY TO SWITCH ON", 0x23: "SWITCHED ON", 0x27: "OPERATION ENABLED",
            0x07: "QUICK STOP ACTIVE"}.get(sw & 0x6F, f"other 0x{sw:04X}")


class Master:
    """The outside master: a python ``canopen`` network plus a raw frame queue.

    Parameters
    ----------
    port : int
        socketcand port of the virtual drive on 127.0.0.1.
    """

    def __init__(self, port: int) -> None:
        self.net = canopen.Network()
        self.net.connect(interface="socketcand", host="127.0.0.1", port=port, channel="can0")
        self.node = canopen.RemoteNode(NODE, str(EDS))
        self.net.add_node(self.node)
        self.q: "queue.Queue[can.Message]" = queue.Queue()
        frames = self.q

        class _L(can.Listener):
            def on_message_received(self, msg: can.Message) -> None:
                frames.put(msg)

        self.net.notifier.add_listener(_L())

    # ---- raw frames --------------------------------------------------------------------
    def send(self, cob: int, data: bytes) -> None:
        """One frame to the bus."""
        self.net.send_message(cob, data)

    def drain(self) -> None:
        """Forget the frames received so far."""
        while True:
            try:
                self.q.get_nowait()
            except queue.Empty:
                return

    def wait_frame(self, pred: Callable[[can.Message], bool], timeout_s: float = 3.0) -> can.Message:
        """The next received frame for which ``pred`` holds (wall time ``timeout_s``, s)."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            try:
                m = self.q.get(timeout=0.05)
            except queue.Empty:
                continue
            if pred(m):
                return m
        raise AssertionError("expected frame not seen")

    def nmt(self, cmd: int) -> None:
        """NMT command to this node; a reset waits for the boot-up message."""
        self.drain()
        self.send(0x000, bytes([cmd, NODE]))
        if cmd in (NMT_RESET_NODE, NMT_RESET_COMM):
            self.wait_frame(lambda m: m.arbitration_id == 0x700 + NODE and bytes(m.data) == b"\x00")
        else:
            time.sleep(0.02)

    # ---- SDO -------------------------------------------------------------------------
    def _obj(self, index: int, sub: int) -> canopen.sdo.Variable:
        """The SDO variable index:sub (sub ignored for a plain variable)."""
        obj = self.node.sdo[index]
        if isinstance(obj, (canopen.sdo.Record, canopen.sdo.Array)):
            obj = obj[sub]
        return obj

    def read(self, index: int, sub: int = 0) -> int:
        """SDO upload of an integer object."""
        return int(self._obj(index, sub).raw)

    def write(self, index: int, sub: int, value: int) -> None:
        """SDO download of an integer object (its EDS type)."""
        self._obj(index, sub).raw = value

    def abort_of(self, index: int, sub: int, value: int) -> int:
        """The SDO abort code the drive answers a write with (0: accepted)."""
        try:
            self.write(index, sub, value)
        except canopen.SdoAbortedError as e:
            return int(e.code)
        return 0

    def statusword(self) -> int:
        """0x6041."""
        return self.read(0x6041)

    def wait_state(self, name: str, timeout_s: float = 3.0) -> int:
        """Poll the statusword until the 402 state is ``name``; returns the statusword."""
        end = time.monotonic() + timeout_s
        sw = self.statusword()
        while _state(sw) != name and time.monotonic() < end:
            time.sleep(0.01)
            sw = self.statusword()
        assert _state(sw) == name, f"402 state {_state(sw)} (0x{sw:04X}), expected {name}"
        return sw

    def close(self) -> None:
        self.net.disconnect()


@pytest.fixture(scope="module")
def master() -> Iterator[Master]:
    srv = Server("--pacing", "realtime")
    m = None
    try:
        m = Master(srv.port)
        yield m
    finally:
        if m is not None:
            m.close()
        srv.stop()


def _fresh(m: Master) -> None:
    """Back to the boot state: reset node, fault reset if a fault is latched."""
    m.nmt(NMT_RESET_NODE)
    m.write(0x1016, 1, 0)
    if _state(m.statusword()) == "FAULT":
        m.write(0x6040, 0, 0x00)
        m.write(0x6040, 0, 0x80)
    m.wait_state("SWITCH ON DISABLED")


def _prepare(m: Master, state: str) -> None:
    """Walk the 402 state machine to ``state`` over SDO (PRE-OPERATIONAL)."""
    if state == "FAULT":
        # a lost heartbeat of the consumed node 127 (0x1016): the drive's own fault path
        m.write(0x1016, 1, (127 << 16) | 20)
        m.send(0x700 + 127, b"\x05")
        m.wait_state("FAULT")
        m.write(0x1016, 1, 0)
        return
    m.write(0x6060, 0, CSV)
    walk = {"SWITCH ON DISABLED": [], "READY TO SWITCH ON": [0x06], "SWITCHED ON": [0x06, 0x07],
            "OPERATION ENABLED": [0x06, 0x0F]}[state]
    for cw in walk:
        m.write(0x6040, 0, cw)
    m.wait_state(state)
    if state == "OPERATION ENABLED":
        m.write(0x60FF, 0, VEL)                  # CSV: the axis turns


def _expected(state: str, cmd: int, option: int) -> str:
    """The documented 402 state after NMT ``cmd`` in ``state`` with 0x6007 = ``option``."""
    if cmd == NMT_RESET_NODE:
        return "FAULT" if state == "FAULT" or (state == "OPERATION ENABLED" and option == 1) \
            else "SWITCH ON DISABLED"
    if state != "OPERATION ENABLED" or cmd == NMT_START or option == 0:
        return state
    return "FAULT" if option == 1 else "SWITCH ON DISABLED"


STATES = ["SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED", "FAULT"]
CMDS = [NMT_START, NMT_STOP, NMT_PREOP, NMT_RESET_COMM, NMT_RESET_NODE]
CASES = [(s, c, 1) for s in STATES for c in CMDS] + \
        [("OPERATION ENABLED", c, o) for o in (0, 2, 3) for c in CMDS if c != NMT_START]


@pytest.mark.parametrize("state,cmd,option", CASES,
                         ids=[f"{s.replace(' ', '_').lower()}-nmt{c:02x}-opt{o}" for s, c, o in CASES])
def test_nmt_command_in_every_402_state(master: Master, state: str, cmd: int, option: int) -> None:
    m = master
    _fresh(m)
    m.write(0x6007, 0, option)
    _prepare(m, state)
    if cmd != NMT_START:
        m.nmt(NMT_START)                         # the commands that end a connection: from OPERATIONAL
    m.nmt(cmd)
    if cmd == NMT_STOP:
        # STOPPED: no SDO; quick stop (option 3) needs the standstill first
        time.sleep(0.3)
        m.nmt(NMT_PREOP)                         # from STOPPED: no 402 reaction
    want = _expected(state, cmd, option)
    sw = m.wait_state(want)
    assert bool(sw & SW_VOLTAGE) == (want == "OPERATION ENABLED"), f"power stage in {want}: 0x{sw:04X}"
    if want == "FAULT" and state != "FAULT":
        assert m.read(0x603F) == EMCY_COMM
    if want == "OPERATION ENABLED" and state == "OPERATION ENABLED":
        assert m.read(0x60FF) == VEL             # option 0: the command is unchanged, still turning


def test_quick_stop_option_ramps_down_on_leaving_operational(master: Master) -> None:
    """0x6007 = 3: QUICK STOP ACTIVE while the axis decelerates, then SWITCH ON DISABLED."""
    m = master
    _fresh(m)
    m.write(0x6007, 0, 3)
    m.write(0x605A, 0, 2)                        # quick stop at 0x6085
    m.write(0x6085, 0, int(20 / 360 * 2 ** 24))  # 20 deg/s^2: 1.5 s from 30 deg/s
    _prepare(m, "OPERATION ENABLED")
    m.write(0x60FF, 0, 30 * VEL)
    time.sleep(0.3)
    m.nmt(NMT_START)
    m.nmt(NMT_PREOP)
    sw = m.statusword()
    assert _state(sw) == "QUICK STOP ACTIVE" and sw & SW_VOLTAGE
    m.wait_state("SWITCH ON DISABLED", 10.0)


# ---- COB-IDs ----------------------------------------------------------------------------
def test_restricted_and_own_cob_ids_refused(master: Master) -> None:
    m = master
    _fresh(m)
    n = NODE
    # SYNC on the node's own SDO request id: refused, and the node still answers SDO
    assert m.abort_of(0x1005, 0, 0x600 + n) == AB_VALUE
    assert m.read(0x1000) == 0x00020192
    assert m.read(0x1005) == 0x80
    # CiA 301 restricted identifiers, through the invalid-first sequence of a PDO too
    for cob in (0x000, 0x001, 0x07F, 0x101, 0x180, 0x580 + n, 0x5FF, 0x600 + n, 0x67F, 0x6E0, 0x6FF,
                0x700 + n, 0x77F, 0x780, 0x7FF):
        assert m.abort_of(0x1400, 1, cob) == AB_VALUE, hex(cob)                 # RPDO1 (valid)
        m.write(0x1800, 1, 0x80000000 | (0x180 + n))                              # TPDO1 invalid
        assert m.abort_of(0x1800, 1, cob) == AB_VALUE, hex(cob)
        m.write(0x1800, 1, 0x180 + n)
        if cob > 0x80:
            assert m.abort_of(0x1014, 0, cob) == AB_VALUE, hex(cob)             # EMCY
        assert m.abort_of(0x1005, 0, cob) in (AB_VALUE, 0x06090032), hex(cob)   # SYNC (min 1)
    # the node's own services: SYNC, EMCY, the PDOs
    m.write(0x1801, 1, 0x80000000 | (0x280 + n))
    for cob in (0x080, 0x080 + n, 0x180 + n, 0x200 + n):
        assert m.abort_of(0x1801, 1, cob) == AB_VALUE, hex(cob)
    assert m.abort_of(0x1005, 0, 0x180 + n) == AB_VALUE
    assert m.abort_of(0x1014, 0, 0x180 + n) == AB_VALUE
    # 29-bit frames: bit 29
    assert m.abort_of(0x1801, 1, 0x20000000 | (0x2A0 + n)) == AB_VALUE
    # old values kept
    assert m.read(0x1005) == 0x80
    assert m.read(0x1014) == 0x80 + n
    assert m.read(0x1800, 1) == 0x180 + n
    assert m.read(0x1400, 1) == 0x200 + n
    assert m.read(0x1801, 1) == 0x80000000 | (0x280 + n)


def test_legal_cob_id_change_moves_the_tpdo(master: Master) -> None:
    m = master
    _fresh(m)
    n = NODE
    assert m.abort_of(0x1800, 1, 0x1A0 + n) == AB_VALUE      # a valid PDO: invalid first
    m.write(0x1800, 1, 0x80000000 | (0x180 + n))
    m.write(0x1800, 1, 0x1A0 + n)
    assert m.read(0x1800, 1) == 0x1A0 + n
    m.nmt(NMT_START)
    m.wait_frame(lambda f: f.arbitration_id == 0x1A0 + n)    # TPDO1 (event timer 100 ms) on its new id
    m.nmt(NMT_PREOP)
    m.drain()
    m.write(0x1005, 0, 0x0FF)                                 # a free id for SYNC
    assert m.read(0x1005) == 0x0FF


# ---- table commit interlock ----------------------------------------------------------------
TE_NAMES = ["te_n", "te_k1", "te_tau_max"] + [f"te_{k}{i}" for i in range(1, 5) for k in ("order", "amp", "phase")]
TE_MAGIC = 0x45544448                                         # "HDTE"


def _te_group(values: dict[str, int], version: int) -> bytes:
    """0x5100:3 image: magic, format 1, version, count, the values, CRC-32 trailer."""
    body = struct.pack(f"<4I{len(TE_NAMES)}i", TE_MAGIC, 1, version, len(TE_NAMES), *(values[k] for k in TE_NAMES))
    return body + struct.pack("<I", zlib.crc32(body))


def _where(m: Master, name: str) -> tuple[int, int]:
    """(index, sub) of a parameter by its EDS name."""
    for obj in m.node.object_dictionary.values():
        subs = obj.values() if isinstance(obj, (canopen.objectdictionary.ODRecord, canopen.objectdictionary.ODArray)) \
            else [obj]
        for v in subs:
            if v.name == name:
                return v.index, v.subindex
    raise KeyError(name)


def _sdo_abort_code(f: can.Message) -> int:
    assert f.data[0] == 0x80, f"SDO response 0x{f.data[0]:02X}, expected an abort"
    return int(struct.unpack_from("<I", bytes(f.data), 4)[0])


def test_table_download_aborted_when_the_drive_is_enabled(master: Master) -> None:
    m = master
    _fresh(m)
    n = NODE
    values = {k: m.read(*_where(m, k)) for k in TE_NAMES}
    values.update(te_n=2, te_order1=2, te_amp1=40000)
    good = _te_group(values, 5)
    with m.node.sdo[0x5100][3].open("wb", size=len(good)) as f:
        f.write(good)
    assert m.node.sdo[0x5100][3].open("rb").read() == good   # read back: the table in force
    new = _te_group(dict(values, te_amp1=30000), 6)
    m.write(0x6060, 0, CSV)
    m.nmt(NMT_START)
    m.drain()
    # segmented download by hand: initiate (size indicated), two segments

    def rx(f: can.Message) -> bool:
        return f.arbitration_id == 0x580 + n

    m.send(0x600 + n, struct.pack("<BHBI", 0x21, 0x5100, 3, len(new)))
    assert m.wait_frame(rx).data[0] == 0x60
    for seg, toggle in ((0, 0x00), (1, 0x10)):
        m.send(0x600 + n, bytes([toggle]) + new[7 * seg:7 * seg + 7])
        assert m.wait_frame(rx).data[0] == 0x20 | toggle
    # the drive enabled through RPDO1 (controlword, mode) while the transfer is open
    m.send(0x200 + n, struct.pack("<Hb", 0x06, CSV))
    m.send(0x200 + n, struct.pack("<Hb", 0x0F, CSV))
    assert _sdo_abort_code(m.wait_frame(rx)) == AB_STATE     # the client is told at once
    # the rest of the transfer lands nowhere
    m.send(0x600 + n, bytes([0x00]) + new[14:21])
    assert _sdo_abort_code(m.wait_frame(rx)) == AB_CMD
    assert _state(m.statusword()) == "OPERATION ENABLED"
    assert m.node.sdo[0x5100][3].open("rb").read() == good   # the old table stays
    assert m.read(*_where(m, "te_amp1")) == 40000
    # and with the power stage on a new download is refused at its start
    with pytest.raises(canopen.SdoAbortedError) as e:
        with m.node.sdo[0x5100][3].open("wb", size=len(new)) as f:
            f.write(new)
    assert e.value.code == AB_STATE
    m.send(0x200 + n, struct.pack("<Hb", 0x06, CSV))
    m.wait_state("READY TO SWITCH ON")
