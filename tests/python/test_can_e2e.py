"""End to end over CAN against the virtual drive (``hdservo-sim serve``, socketcand):
compensator tables through the firmware adapter (firmware/canopen/hd_app_co.c),
capture arm / trigger / upload, and SYNC pacing.

Each test starts the drive on an ephemeral loopback port and always stops it.
No wall-clock limits are asserted: the drive is paced by SYNC (lock-step), and
every check is on ticks and values.
"""
from __future__ import annotations

import contextlib
import math
import queue
import struct
import subprocess
import time
import zlib
from typing import Iterator

import can
import canopen
import numpy as np
import pytest

from vdrive import NODE, SIM, Server  # tests/python/vdrive.py

from hdservo.drive import SIGNALS, TABLE_GROUPS, Drive, DriveError, group_payload
from hdservo.params_gen import BY_NAME as PARAMS
from hdservo.preisach_table import PreisachTable
from hdservo.serve_proc import connected

pytestmark = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")




def _drive(*extra: str) -> contextlib.AbstractContextManager[tuple[Server, Drive]]:
    return connected(Server(*extra), NODE)


@pytest.fixture
def rt_drive() -> Iterator[tuple[Server, Drive]]:
    with _drive("--pacing", "realtime") as sd:
        yield sd


def _frames(net: canopen.Network, cob: int | None = None) -> "queue.Queue[can.Message]":
    q: "queue.Queue[can.Message]" = queue.Queue()

    class L(can.Listener):
        def on_message_received(self, msg: can.Message) -> None:
            if cob is None or msg.arbitration_id == cob:
                q.put(msg)

    net.notifier.add_listener(L())
    return q


def _abort_code(fn) -> int:
    with pytest.raises(canopen.SdoAbortedError) as e:
        fn()
    return e.value.code


def _write_domain(d: Drive, sub: int, blob: bytes) -> None:
    with d.node.sdo[0x5100][sub].open("wb", size=len(blob), block_transfer=True) as f:
        f.write(blob)


def _with_trailer(payload: bytes) -> bytes:
    return payload + struct.pack("<I", zlib.crc32(payload))


def _everett(levels: int, version: int, scale: int) -> PreisachTable:
    ent = [0] * (levels * (levels + 1) // 2)
    for i in range(levels):
        for j in range(i + 1):
            ent[i * (i + 1) // 2 + j] = scale * (i - j) * (i - j + 1)     # mu >= 0, E[i][i] = 0
    return PreisachTable(levels=levels, entries=np.array(ent, dtype=np.int64), sub_bits=2, in_shift=12,
                         u0=-(1 << 20), unit=1, version=version).seal()


# ---- tables -------------------------------------------------------------------------
def test_preisach_table_download_readback_and_refusal(rt_drive) -> None:
    _, d = rt_drive
    assert d.read_domain(0x5100, 1) == b""                      # nothing in force at power-up
    t1 = _everett(16, version=3, scale=1000).to_bytes()
    d.download_table(1, t1)                                      # block download + read-back compare
    back = d.read_domain(0x5100, 1)
    assert back == _with_trailer(t1)
    assert PreisachTable.from_bytes(back[:-4]).version == 3
    # a full-size table (L = 64) replaces it
    t2 = _everett(64, version=4, scale=7).to_bytes()
    d.download_table(1, t2)
    assert d.read_domain(0x5100, 1)[:-4] == t2

    bad_cases = {}
    # inner CRC broken, container trailer valid
    b = bytearray(t1)
    b[40 + 4 * 20] ^= 0x01
    bad_cases["inner crc"] = _with_trailer(bytes(b))
    # container trailer broken
    b = bytearray(_with_trailer(t1))
    b[-1] ^= 0x80
    bad_cases["trailer"] = bytes(b)
    # wrong image format version, resealed (CRC right)
    t = _everett(16, version=5, scale=1000)
    t.fmt = 2
    bad_cases["format"] = _with_trailer(t.seal().to_bytes())
    # non-zero diagonal, resealed
    t = _everett(16, version=5, scale=1000)
    t.entries[2] = 9
    bad_cases["diagonal"] = _with_trailer(t.seal().to_bytes())
    # header says more entries than were sent
    bad_cases["truncated"] = _with_trailer(t1[:-8])
    for name, blob in bad_cases.items():
        assert _abort_code(lambda: _write_domain(d, 1, blob)) == 0x08000020, name
        assert d.read_domain(0x5100, 1)[:-4] == t2, f"{name}: the table in force changed"
    # segmented (not block) download is accepted too
    with d.node.sdo[0x5100][1].open("wb", size=len(t1) + 4) as f:
        f.write(_with_trailer(t1))
    assert d.read_domain(0x5100, 1) == _with_trailer(t1)


def test_tables_refused_while_power_stage_on(rt_drive) -> None:
    _, d = rt_drive
    d.start()
    d.enable("CYCLIC SYNCHRONOUS VELOCITY")
    t1 = _everett(8, version=1, scale=100).to_bytes()
    assert _abort_code(lambda: _write_domain(d, 1, _with_trailer(t1))) == 0x08000022
    d.disable()
    d.download_table(1, t1)


def test_te_group_table_all_or_nothing(rt_drive) -> None:
    _, d = rt_drive
    magic, names = TABLE_GROUPS[3]
    old = {n: d.read(PARAMS[n].index, PARAMS[n].sub) for n in names}
    assert d.read_domain(0x5100, 3) == b""
    new = dict(old)
    new.update(te_n=2, te_order1=2, te_amp1=40000, te_order2=4, te_amp2=-12345, te_phase2=1 << 29)
    d.download_group(3, new, version=7)
    for n in names:
        assert d.read(PARAMS[n].index, PARAMS[n].sub) == new[n], n
    back = d.read_domain(0x5100, 3)
    assert back == _with_trailer(group_payload(3, new, 7))
    # one value out of range: refused, nothing changes
    bad = dict(new, te_amp1=5000, te_amp3=PARAMS["te_amp3"].raw_max + 1)
    assert _abort_code(lambda: _write_domain(d, 3, _with_trailer(group_payload(3, bad, 8)))) == 0x08000020
    for n in names:
        assert d.read(PARAMS[n].index, PARAMS[n].sub) == new[n], n
    # wrong count / magic
    p = bytearray(group_payload(3, new, 9))
    p[0] ^= 1
    assert _abort_code(lambda: _write_domain(d, 3, _with_trailer(bytes(p)))) == 0x08000020
    assert _abort_code(lambda: _write_domain(d, 3, _with_trailer(group_payload(3, new, 9)[:-4]))) == 0x08000020
    assert d.read_domain(0x5100, 3) == back
    with pytest.raises(DriveError):
        group_payload(3, {"te_n": 1})


# ---- faults ------------------------------------------------------------------------------
def test_heartbeat_loss_is_a_latched_app_fault(rt_drive) -> None:
    _, d = rt_drive
    status = d.node.sdo["drive_status"]
    d.write(0x1016, 1, (127 << 16) | 50)
    hb = d.network.send_periodic(0x700 + 127, [0x05], 0.01)
    try:
        d.start()
        d.enable("CYCLIC SYNCHRONOUS VELOCITY")
        assert status["power_enabled"].raw == 1
    finally:
        hb.stop()
    d._wait_state("FAULT", 20.0)
    assert status["fault_code"].raw == 8                          # HD_FAULT_COMM, latched in the app
    assert status["power_enabled"].raw == 0
    assert d.read(0x603F) == 0x8130
    with pytest.raises(DriveError):
        d.enable("CYCLIC SYNCHRONOUS VELOCITY")                  # refused until a fault reset
    d.write(0x1016, 1, 0)
    d.fault_reset()
    assert status["fault_code"].raw == 0
    d.enable("CYCLIC SYNCHRONOUS VELOCITY")
    assert status["power_enabled"].raw == 1
    d.disable()


# ---- capture, SYNC pacing ---------------------------------------------------------------
def _sync_until(d: Drive, pred, n_max: int = 200) -> None:
    for _ in range(n_max):
        if pred():
            return
        d.network.sync.transmit()
    assert pred()


def test_pp_profile_velocity_and_quick_stop_ramp_on_the_simulated_axis() -> None:
    """Over CAN on the simulated axis (10 periods per SYNC): a PP move cruises at the
    0x6081 the master wrote (= traj_vmax, read back at 0x2400:1), and a quick stop
    (controlword bit 2 = 0) ramps the axis to rest at 0x6085 -- QUICK STOP ACTIVE, then
    SWITCH ON DISABLED -- travelling v^2 / (2 qs) plus the velocity loop's lag, not the
    step-to-zero of before."""
    with _drive("--pacing", "sync", "--sync-periods", "10") as (_, d):

        def syncs(n: int) -> None:
            _syncs(d, n)

        def ref() -> int:
            return _setpoint_phase(d)

        v = 30.0 / 360.0                                          # turn/s (30 deg/s)
        d.write(0x6081, 0, round(v * 2 ** 32))
        assert int(d.read(0x2400, 1)) == round(v * 2 ** 32)      # the same parameter
        qs = int(d.read(0x6085)) / 2 ** 24                        # turn/s^2 (default 200 deg/s^2)
        _enable_pp(d)
        _pp_setpoint(d, math.pi)                                   # 180 deg: 6 s at 30 deg/s
        syncs(500)                                                # 0.5 s: past the ramp (0.3 s)
        r0 = ref()
        syncs(1000)                                               # 1 s of cruise
        cruise = ((ref() - r0) % 2 ** 32) / 2 ** 32               # turn in 1 s
        # the plan spreads its sub-period remainder over the move: within 1e-4 of v
        assert abs(cruise - v) < 1e-4 * v, cruise
        x0 = int(d.read(0x6064))                                  # 2^-24 turn
        d.write(0x6040, 0, 0x0B)                                  # quick stop
        syncs(1)
        assert d.read(0x6041) & 0x6F == 0x07                      # QUICK STOP ACTIVE
        _sync_until(d, lambda: d.read(0x6041) & 0x4F == 0x40, 400)   # then SWITCH ON DISABLED
        syncs(50)
        travel = (int(d.read(0x6064)) - x0) / 2 ** 24             # turn
        ramp = v * v / (2 * qs)                                   # 2.25 deg
        assert 0.8 * ramp <= travel <= ramp + v * 0.02, (travel, ramp)   # + 20 ms of lag
        d.write(0x6040, 0, 0x00)


def _syncs(d: Drive, n: int) -> None:
    """n SYNCs, then wait until the drive has run their periods (the loop tick stands: it
    answers SDOs between periods, so a read right after the SYNCs is early)."""
    for _ in range(n):
        d.network.sync.transmit()
    t = int(d.read(0x5F00, 1))
    while True:
        time.sleep(0.05)
        t2 = int(d.read(0x5F00, 1))
        if t2 == t:
            return
        t = t2


def _setpoint_phase(d: Drive) -> int:
    """The set-point phase (0x5F00:8), 2^-32 turn (wraps)."""
    return int(d.read(0x5F00, 8))


def _enable_pp(d: Drive) -> None:
    """NMT operational, profile position, the enable sequence (0x06, 0x07, 0x0F) to
    OPERATION ENABLED, then 20 SYNCs at rest (SYNC pacing)."""
    d.node.nmt.state = "OPERATIONAL"
    d.write(0x6060, 0, 1)
    _sync_until(d, lambda: d.read(0x6041) & 0x4F == 0x40)
    for cw in (0x06, 0x07, 0x0F):
        d.write(0x6040, 0, cw)
        _syncs(d, 1)
    _sync_until(d, lambda: d.read(0x6041) & 0x6F == 0x27)
    _syncs(d, 20)


def _pp_setpoint(d: Drive, rad: float) -> None:
    """A new PP set-point (0x607A, controlword bit 4 edge), one SYNC per controlword write."""
    d.set_position(rad)
    for cw in (0x0F, 0x1F, 0x0F):
        d.write(0x6040, 0, cw)
        _syncs(d, 1)


def test_capture_upload_matches_stream_under_sync_pacing() -> None:
    with _drive("--pacing", "sync", "--sync-periods", "10") as (srv, d):
        net = d.network
        d.write(0x1801, 2, 254)
        d.write(0x5F10, 2, 1)                                     # TPDO2: tick + output phase, every period
        d.node.nmt.state = "OPERATIONAL"
        stream = _frames(net, 0x280 + NODE)
        d.write(0x6060, 0, 9)                                     # CSV
        _sync_until(d, lambda: d.read(0x6041) & 0x4F == 0x40)    # SWITCH ON DISABLED (first periods)
        for cw in (0x06, 0x07, 0x0F):                             # one 402 transition per period batch
            d.write(0x6040, 0, cw)
            net.sync.transmit()
        _sync_until(d, lambda: d.read(0x6041) & 0x6F == 0x27)    # OPERATION ENABLED
        v_cmd = 0.2                                               # rad/s at the output
        d.set_velocity(v_cmd)
        for _ in range(100):                                      # 0.1 s to settle
            net.sync.transmit()
        sig = [SIGNALS["tick"], SIGNALS["pos_out_lo"], SIGNALS["vel_out"], SIGNALS["torque_cmd"]]
        net.sync.start(0.002)                                     # the drive runs while the host waits
        try:
            rows = d.capture(sig, samples=600, pretrigger=100)
        finally:
            net.sync.stop()
        # every streamed frame of the capture window has arrived once the last tick is seen
        last = rows[-1][0] & 0xFFFFFFFF
        phase: dict[int, int] = {}
        while last not in phase:
            m = stream.get(timeout=10)
            tick, ph = struct.unpack("<II", bytes(m.data))
            phase[tick] = ph
        assert len(rows) == 600
        ticks = [r[0] & 0xFFFFFFFF for r in rows]
        assert all(b - a == 1 for a, b in zip(ticks, ticks[1:])), "capture ticks not contiguous"
        missing = [t for t in ticks if t not in phase]
        assert not missing, f"{len(missing)} captured ticks not in the stream"
        assert all((r[1] & 0xFFFFFFFF) == phase[r[0] & 0xFFFFFFFF] for r in rows), "capture != TPDO"
        # plausible: the velocity estimate agrees with the position increments and the command
        dpos = [((b[1] - a[1] + 2 ** 31) % 2 ** 32) - 2 ** 31 for a, b in zip(rows, rows[1:])]
        v_pos = sum(dpos) / len(dpos) * 1e4 / 2 ** 32 * 2 * math.pi          # rad/s
        v_est = sum(r[2] for r in rows) / len(rows) / 2 ** 32 * 2 * math.pi
        assert abs(v_pos - v_cmd) < 0.2 * v_cmd, (v_pos, v_cmd)
        assert abs(v_est - v_pos) < 0.1 * v_cmd, (v_est, v_pos)
        t_lim = PARAMS["torque_limit"].max if "torque_limit" in PARAMS else 1e9
        assert all(abs(r[3]) / 65536.0 <= t_lim for r in rows)
        assert any(r[3] != 0 for r in rows)                      # the loop is working against friction
        d.write(0x6040, 0, 0x00)
        stats = srv.stop()
        assert '"transport_dropped": 0' in stats, stats


def test_pp_halt_stops_the_move_and_waits_for_a_new_set_point() -> None:
    """CiA 402 halt in profile position through ``Drive.halt``: the move stops short at
    traj_amax (the reference never passes v^2/(2a) beyond where the halt was seen), bit 10
    at rest, no resume when released, the next set-point lands exactly (10 periods / SYNC)."""
    with _drive("--pacing", "sync", "--sync-periods", "10") as (_, d):

        def syncs(n: int) -> None:
            _syncs(d, n)

        def ref() -> int:
            return _setpoint_phase(d)

        _enable_pp(d)
        _pp_setpoint(d, math.pi / 2)                               # 90 deg
        syncs(1000)                                               # 1 s: cruising at 60 deg/s
        p0 = ref()
        assert d.read(0x6041) & 0x0400 == 0                       # moving: not reached
        d.halt(True)
        assert d.read(0x6040) & 0x0100
        syncs(2000)
        p1 = ref()
        v = PARAMS["traj_vmax"].default                           # turn/s
        a = PARAMS["traj_amax"].default                           # turn/s^2
        travel = ((p1 - p0) % 2 ** 32) / 2 ** 32                  # turn after the halt
        assert travel <= v * v / (2 * a) + 0.001, travel          # 0.05 turn + 3.6 deg (host latency)
        assert (2 ** 30 - p1) % 2 ** 32 > 2 ** 27                 # > 11 deg short of the 90 deg target
        syncs(50)
        assert ref() == p1                                        # at rest
        assert d.read(0x6041) & 0x0400                            # target reached (halted)
        d.halt(False)
        syncs(200)
        assert ref() == p1                                        # not resumed
        _pp_setpoint(d, 0.2 * math.pi)                             # back to 36 deg
        _sync_until(d, lambda: ref() == round(0.1 * 2 ** 24) * 256, 2000)   # exactly on 0.1 turn
        syncs(50)
        assert d.read(0x6041) & 0x0400
        d.write(0x6040, 0, 0x00)


@pytest.mark.parametrize("k", [1, 7])
def test_sync_pacing_exact_periods_per_sync(k: int) -> None:
    with _drive("--pacing", "sync", "--sync-periods", str(k)) as (srv, d):
        net = d.network
        d.write(0x1801, 2, 1)                                     # TPDO2 synchronous: every SYNC
        d.write(0x1802, 2, 254)
        d.write(0x5F10, 3, 1)                                     # TPDO3 streamed every period
        for _ in range(3):                                        # the first periods (tick 0 before and
            net.sync.transmit()                                   # after the first step) run pre-operational
        d.node.nmt.state = "OPERATIONAL"                         # event TPDOs go out once here
        d.read(0x1000)                                            # ... and are received before this answer
        q = _frames(net)
        n_sync = 30
        sync_ticks: list[int] = []
        stream: list[int] = []

        def take(m: can.Message) -> bool:
            tick = struct.unpack_from("<I", bytes(m.data), 0)[0] if len(m.data) >= 4 else -1
            if m.arbitration_id == 0x380 + NODE:
                stream.append(tick)
            if m.arbitration_id == 0x280 + NODE:
                sync_ticks.append(tick)
                return True
            return False

        for _ in range(n_sync):
            net.sync.transmit()
            while not take(q.get(timeout=10)):
                pass
        # the TPDO3 stream of the last interval is complete once the drive answers an SDO
        # after it (frames leave in order)
        d.read(0x1000)
        while not q.empty():
            take(q.get_nowait())
        assert {b - a for a, b in zip(sync_ticks, sync_ticks[1:])} == {k}
        between = [t for t in stream if sync_ticks[0] < t <= sync_ticks[-1]]
        assert between == list(range(sync_ticks[0] + 1, sync_ticks[-1] + 1))
        assert len(between) == k * (n_sync - 1)
