"""Run the identification experiments on any CiA 402 drive through its standard objects only.

A drive without hdservo's manufacturer objects (no capture 0x5000, no excitation
generator 0x5010, no process data 0x5F00, no tables 0x5100) is driven from the
host:

* **set-points** are generated on the host and streamed as synchronous RPDOs
  (transmission type 1: applied at the next SYNC): RPDO1 = target position
  0x607A + velocity offset 0x60B1 (CSP), RPDO2 = target velocity 0x60FF +
  target torque 0x6071 + torque offset 0x60B2 (CSV, CST, and the torque
  feed-forward of every mode);
* **measurements** come from synchronous TPDOs (transmission type 1: one frame
  per SYNC): TPDO1 = statusword 0x6041 + position actual 0x6064, TPDO2 =
  velocity actual 0x606C + torque actual 0x6077 (+ current actual 0x6078 when
  the drive has it), TPDO3 = the second encoder 0x60E4:1 (additional position
  actual value) when the drive has one;
* the PDO configuration is written over SDO with python canopen's PDO API
  (``node.tpdo`` / ``node.rpdo``: ``read``, ``clear``, ``add_variable``,
  ``save``) in PRE-OPERATIONAL, and the drive's own configuration is written
  back when the session ends;
* **time** is the SYNC count: the k-th TPDO frame of each map after a start
  belongs to the k-th SYNC.  Against the virtual drive in lock-step
  (``--pacing sync``) the host sends SYNCs in bursts and waits for their
  TPDOs: every run is reproducible.  Against a free-running drive the host is
  the SYNC producer and paces itself by the clock (:attr:`StdRunner.lockstep`
  False); the period statistics of the SYNCs it actually sent are in the
  metadata (``sync_stats``) of every experiment, with the round trip from a
  SYNC to its last TPDO.

The columns returned are those of :class:`~.experiments.SimRunner`, so the fits
of :mod:`hdservo.ident` run unchanged: ``load_angle_rad`` from 0x6064,
``motor_torque_Nm`` = 0x6077 torque / gear ratio, ``motor_angle_rad`` from the
second encoder (TE and the FRF need it; without one they are refused with one
line).

Before an experiment starts the bus load of the configured PDOs at the SYNC rate
is checked against the bitrate (:func:`bus_load`); above
:data:`BUS_LOAD_LIMIT` the experiment is refused.

Every SDO request the host sends to the drive is recorded from the bus
(:class:`SdoGuard`): :attr:`StdRunner.vendor_access` lists any manufacturer
object (0x2000-0x5FFF) touched, which this path never does.
"""
from __future__ import annotations

import math
import struct
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Optional, Sequence

import numpy as np

from ..errors import UserError
from ..phase import unwrap_count
from . import experiments as ex
from .drive_runner import schroeder_multisine

TURN = 2.0 * math.pi
#: refuse an experiment whose PDO traffic would take more than this share of the bitrate
BUS_LOAD_LIMIT = 0.70
#: manufacturer-specific profile area (CiA 301): hdservo's objects live here
VENDOR_RANGE = (0x2000, 0x5FFF)

#: CiA 402 modes of operation (0x6060)
MODE_CODES = {"CSP": 8, "CSV": 9, "CST": 10, "PP": 1, "PV": 3}


# ----------------------------------------------------------------- bus arithmetic


def frame_bits(data_bytes: int) -> int:
    """Worst-case length (bits) of a CAN 2.0A frame with ``data_bytes`` bytes, bit stuffing and the 3-bit
    interframe space included: 8 n + 47 + floor((34 + 8 n - 1) / 4)."""
    if not 0 <= data_bytes <= 8:
        raise ValueError(f"a classic CAN frame has 0..8 data bytes, not {data_bytes}")
    n = 8 * data_bytes
    return n + 47 + (34 + n - 1) // 4


def bus_load(frame_bytes: Sequence[int], sync_hz: float, bitrate: float) -> float:
    """Share of the bitrate taken by the frames sent every SYNC (the SYNC itself included).

    Parameters
    ----------
    frame_bytes : sequence of int
        Data length of every frame per SYNC period (RPDOs, TPDOs), not the SYNC.
    sync_hz : float
        SYNC rate (Hz).
    bitrate : float
        Bus bitrate (bit/s).

    Returns
    -------
    float
        Bus load, 0..1 (may exceed 1: the bus cannot carry it).
    """
    bits = frame_bits(0) + sum(frame_bits(int(b)) for b in frame_bytes)
    return bits * sync_hz / bitrate


def check_bus_load(frame_bytes: Sequence[int], sync_hz: float, bitrate: float,
                   limit: float = BUS_LOAD_LIMIT) -> float:
    """:func:`bus_load`, refused with one line (:class:`UserError`) above ``limit``."""
    load = bus_load(frame_bytes, sync_hz, bitrate)
    if load > limit:
        raise UserError(f"bus load {100 * load:.0f} % of {bitrate / 1000:.0f} kbit/s for {len(frame_bytes)} PDOs "
                        f"per SYNC at {sync_hz:.0f} Hz is above {100 * limit:.0f} %: lower the SYNC rate "
                        "(longer SYNC period) or raise the bitrate")
    return load


def period_stats(times_s: Sequence[float]) -> dict[str, float]:
    """Statistics (s) of the intervals between consecutive SYNC send times: count, mean, std, min,
    max, 99th percentile."""
    t = np.asarray(times_s, dtype=float)
    if len(t) < 2:
        return {"count": float(len(t))}
    d = np.diff(t)
    return {"count": float(len(d)), "mean_s": float(np.mean(d)), "std_s": float(np.std(d)),
            "min_s": float(np.min(d)), "max_s": float(np.max(d)), "p99_s": float(np.percentile(d, 99))}


# ----------------------------------------------------------------- SDO guard


class SdoGuard:
    """Records the object of every SDO request the host sends to one node.

    It wraps the ``send`` of the python-can bus under the canopen network (every frame the
    host puts on the bus passes it; a bus does not hand the host its own frames back, so a
    receive listener would see none).  The initiate frames of expedited/segmented (client
    command 1 download, 2 upload) and block transfers (5 upload, 6 download; sub-command 0 =
    initiate) carry the index (bytes 1-2) and sub-index (byte 3); segment frames carry none.
    """

    def __init__(self, node_id: int) -> None:
        self.cob = 0x600 + node_id
        self.accessed: list[tuple[int, int]] = []
        self._lock = threading.Lock()
        self._bus: Any = None
        self._send: Any = None

    def attach(self, bus: Any) -> None:
        """Watch every frame sent on ``bus`` (a python-can bus) until :meth:`detach`."""
        if self._bus is not None:
            return
        orig = bus.send

        def send(msg: Any, *args: Any, **kw: Any) -> Any:
            if msg.arbitration_id == self.cob and len(msg.data) >= 4:
                self.note(bytes(msg.data))
            return orig(msg, *args, **kw)

        self._bus, self._send = bus, orig
        bus.send = send

    def detach(self) -> None:
        """Stop watching (the bus's own ``send`` back)."""
        if self._bus is not None:
            try:
                del self._bus.send
            except AttributeError:
                self._bus.send = self._send
            self._bus = self._send = None

    def note(self, data: bytes) -> None:
        """Record the object of one client request frame (ignored unless it is an initiate)."""
        ccs = data[0] >> 5
        initiate = ccs in (1, 2) or (ccs == 5 and data[0] & 0x03 == 0) or (ccs == 6 and data[0] & 0x01 == 0)
        if initiate:
            index, sub = struct.unpack_from("<HB", data, 1)
            with self._lock:
                self.accessed.append((index, sub))

    def vendor(self) -> list[tuple[int, int]]:
        """Every (index, sub) requested in the manufacturer range 0x2000-0x5FFF, in order."""
        with self._lock:
            return [a for a in self.accessed if VENDOR_RANGE[0] <= a[0] <= VENDOR_RANGE[1]]


# ----------------------------------------------------------------- units


@dataclass(frozen=True)
class StdUnits:
    """Scaling of the standard objects of the drive (output side unless said).

    Parameters
    ----------
    position_per_turn : float
        0x6064/0x607A counts per output turn (hdservo and its virtual drive: 2^24).
    velocity_per_turn_s : float
        0x606C/0x60FF/0x60B1 counts per output turn/s (hdservo: 2^32).
    encoder2_per_turn : float
        0x60E4:1 counts per turn (hdservo and its virtual drive: 2^24).
    encoder2_output_units : bool
        0x60E4:1 is the motor angle divided by the gear ratio, in output turns (True, hdservo's
        motor encoder in the unit of 0x6064), or counts per motor turn (False).
    torque_on_output : bool
        0x6071/0x6077/0x60B2 act on the output (True, hdservo) or on the motor shaft.
    """

    position_per_turn: float = 2.0 ** 24
    velocity_per_turn_s: float = 2.0 ** 32
    encoder2_per_turn: float = 2.0 ** 24
    encoder2_output_units: bool = True
    torque_on_output: bool = True


@dataclass
class PdoSnapshot:
    """One PDO's configuration as read from the drive (restored at the end of a session)."""

    enabled: bool
    cob_id: Optional[int]
    rtr_allowed: bool
    trans_type: Optional[int]
    inhibit_time: Optional[int]
    event_timer: Optional[int]
    sync_start_value: Optional[int]
    entries: list[tuple[int, int, int]]

    @classmethod
    def of(cls, m: Any) -> "PdoSnapshot":
        return cls(m.enabled, m.cob_id, m.rtr_allowed, m.trans_type, m.inhibit_time, m.event_timer,
                   m.sync_start_value, [(v.index, v.subindex, v.length) for v in m.map])

    def apply(self, m: Any) -> None:
        m.clear()
        for index, sub, length in self.entries:
            m.add_variable(index, sub, length)
        m.enabled, m.cob_id, m.rtr_allowed = self.enabled, self.cob_id, self.rtr_allowed
        m.trans_type, m.inhibit_time, m.event_timer = self.trans_type, self.inhibit_time, self.event_timer
        m.sync_start_value = self.sync_start_value


# ----------------------------------------------------------------- the runner


@dataclass
class StdRunner:
    """Experiment designs of :mod:`.experiments` on a CiA 402 drive through standard objects.

    Parameters
    ----------
    network : canopen.Network
        Connected network (python-can bus underneath).
    node_id : int
        CANopen node id of the drive.
    gear_ratio : float, optional
        Gear ratio N (motor turns per output turn); None = read 0x6091:1/0x6091:2 (motor /
        shaft revolutions), refused with one line when the drive has no 0x6091.
    sync_period_s : float
        SYNC period (s): one set-point and one sample per SYNC.  Against the virtual drive in
        lock-step it must equal its ``--sync-periods`` x 100 us.
    lockstep : bool
        The drive advances only on SYNC (virtual drive ``--pacing sync``): SYNCs are sent in
        bursts and their TPDOs awaited.  False: the host sends SYNCs by the clock.
    bitrate : float
        Bus bitrate (bit/s) for the bus-load check.
    units : StdUnits
        Scaling of the drive's standard objects.
    eds : str, optional
        EDS of the drive (default: hdservo's, whose CiA 301/402 part is standard).
    progress : callable, optional
        ``progress(message)``.
    burst : int
        Lock-step: SYNCs sent before their TPDOs are awaited.  1 (default): a synchronous TPDO
        then samples the drive after exactly one SYNC period more than the previous one; the
        virtual drive reads frames that arrive together in one batch, so the TPDOs of a burst
        of SYNCs can carry the values of one instant.
    """

    network: Any
    node_id: int = 1
    gear_ratio: Optional[float] = None
    sync_period_s: float = 1e-3
    lockstep: bool = True
    bitrate: float = 1e6
    units: StdUnits = field(default_factory=StdUnits)
    eds: Optional[str] = None
    progress: Optional[Callable[[str], None]] = None
    burst: int = 1
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        import canopen
        from ..drive import EDS_PATH
        self.node = canopen.BaseNode402(self.node_id, self.eds or str(EDS_PATH))
        self.network.add_node(self.node)
        self.guard = SdoGuard(self.node_id)
        self.guard.attach(self.network.bus)
        self._saved: dict[str, dict[int, PdoSnapshot]] = {}
        #: per TPDO: (host clock at reception, frame timestamp, mapped raw values), one per SYNC
        self._rx: dict[int, list[tuple[float, float, tuple[int, ...]]]] = {}
        self._cond = threading.Condition()
        self._syncs = 0                      # SYNCs sent since the TPDOs were configured
        self._sync_times: list[float] = []   # host clock of each SYNC sent (s)
        self._rec_from: Optional[int] = None
        self._rated_Nm = 0.0
        self.has_encoder2 = False
        self.has_current = False
        self.modes: set[str] = set()
        self._rpdo_vars: dict[int, Any] = {}
        self._sp = {"pos": 0, "vel_off": 0, "vel": 0, "torque": 0, "t_off": 0}
        self._opened = False
        self._active_rpdos: tuple[int, ...] = (2,)

    # -- SDO helpers ----------------------------------------------------------
    def _read(self, index: int, sub: int = 0) -> int:
        return int.from_bytes(self.node.sdo.upload(index, sub), "little", signed=False)

    def _has(self, index: int, sub: int = 0) -> bool:
        import canopen
        try:
            self.node.sdo.upload(index, sub)
        except canopen.SdoAbortedError:
            return False
        return True

    def _write(self, index: int, sub: int, value: int, size: int) -> None:
        self.node.sdo.download(index, sub, int(value).to_bytes(size, "little", signed=value < 0))

    @property
    def vendor_access(self) -> list[tuple[int, int]]:
        """Manufacturer objects (index, sub) this session asked the drive for (empty on this path)."""
        return self.guard.vendor()

    def _say(self, msg: str) -> None:
        if self.progress:
            self.progress(msg)

    # -- lifecycle ----------------------------------------------------------
    def open(self) -> None:
        """Check the device is CiA 402, probe what it offers, map the PDOs, NMT start."""
        import canopen
        try:
            dev = self._read(0x1000)
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
            raise UserError(f"drive node {self.node_id}: no answer to 0x1000 device type ({e})") from None
        if dev & 0xFFFF != 402:
            raise UserError(f"drive node {self.node_id}: device type 0x{dev:08X} is not a CiA 402 drive "
                            "(0x1000 low 16 bits must be 402)")
        need = [(0x6040, 0), (0x6041, 0), (0x6060, 0), (0x6064, 0), (0x606C, 0), (0x6077, 0), (0x60FF, 0),
                (0x6076, 0)]
        missing = [f"0x{i:04X}" for i, s in need if not self._has(i, s)]
        if missing:
            raise UserError(f"drive node {self.node_id}: the standard-objects path needs {', '.join(missing)}")
        self._rated_Nm = self._read(0x6076) / 1000.0
        if self.gear_ratio is None:
            if not (self._has(0x6091, 1) and self._has(0x6091, 2)):
                raise UserError(f"drive node {self.node_id}: no gear ratio object 0x6091: give the gear ratio")
            self.gear_ratio = self._read(0x6091, 1) / max(1, self._read(0x6091, 2))
        self.has_encoder2 = self._has(0x60E4, 1) and self._entry_known(0x60E4, 1)
        self.has_current = self._has(0x6078) and self._entry_known(0x6078, 0)
        if self._has(0x6502):
            bits = self._read(0x6502)
            self.modes = {m for m, b in (("PP", 0), ("PV", 2), ("CSP", 7), ("CSV", 8), ("CST", 9))
                          if bits >> b & 1}
        else:
            self.modes = {m for m in ("CSP", "CSV", "CST") if self._has({"CSP": 0x607A, "CSV": 0x60FF,
                                                                          "CST": 0x6071}[m])}
        self._configure_pdos()
        self._opened = True

    def _entry_known(self, index: int, sub: int) -> bool:
        """The EDS describes the object (the PDO API maps it by its OD entry)."""
        try:
            o = self.node.object_dictionary[index]
            if sub and hasattr(o, "subindices"):
                o = o[sub]
        except KeyError:
            return False
        return True

    def _configure_pdos(self) -> None:
        node = self.node
        node.nmt.state = "PRE-OPERATIONAL"
        node.tpdo.read()
        node.rpdo.read()
        self._saved = {"tpdo": {n: PdoSnapshot.of(node.tpdo[n]) for n in node.tpdo.map},
                       "rpdo": {n: PdoSnapshot.of(node.rpdo[n]) for n in node.rpdo.map}}
        tp: dict[int, list[tuple[int, int]]] = {1: [(0x6041, 0), (0x6064, 0)],
                                                2: [(0x606C, 0), (0x6077, 0)] + ([(0x6078, 0)] if self.has_current
                                                                                 else [])}
        if self.has_encoder2:
            tp[3] = [(0x60E4, 1)]
        rp: dict[int, list[tuple[int, int]]] = {1: [(0x607A, 0), (0x60B1, 0)],
                                                2: [(0x60FF, 0), (0x6071, 0), (0x60B2, 0)]}
        for n, m in node.tpdo.map.items():
            m.clear()
            for i, s in tp.get(n, []):
                m.add_variable(i, s)
            m.enabled = n in tp
            m.trans_type = 1
            m.event_timer = 0 if m.event_timer is not None else None
            m.inhibit_time = 0 if m.inhibit_time is not None else None
            m.save()
            if n in tp:
                self._rx[n] = []
                m.add_callback(self._on_tpdo)
        self._rpdo_vars = {}
        for n, m in node.rpdo.map.items():
            m.clear()
            for i, s in rp.get(n, []):
                self._rpdo_vars[i] = m.add_variable(i, s)
            m.enabled = n in rp
            m.trans_type = 1
            m.save()
        self.tpdo_maps = sorted(tp)
        self.tpdo_bytes = [node.tpdo[n].length // 8 for n in tp]
        self.rpdo_bytes = {n: node.rpdo[n].length // 8 for n in rp}
        node.nmt.state = "OPERATIONAL"

    def close(self) -> None:
        """Power stage off, the drive's PDO configuration written back, listeners removed."""
        import canopen
        try:
            if self._opened:
                try:
                    self._set_controlword(0x00)
                    self._advance(2)
                except (UserError, canopen.SdoAbortedError, canopen.SdoCommunicationError):
                    pass
                self.node.nmt.state = "PRE-OPERATIONAL"
                for kind, maps in (("tpdo", self.node.tpdo), ("rpdo", self.node.rpdo)):
                    for n, snap in self._saved.get(kind, {}).items():
                        snap.apply(maps[n])
                        maps[n].save()
                self.node.nmt.state = "OPERATIONAL"
                self._opened = False
        finally:
            self.guard.detach()

    # -- TPDO reception, drive time -----------------------------------------
    def _on_tpdo(self, m: Any) -> None:
        n = next((k for k in self._rx if self.node.tpdo[k] is m), None)
        if n is None:
            return
        vals = tuple(int(v.raw) for v in m.map)
        with self._cond:
            self._rx[n].append((time.perf_counter(), float(m.timestamp or 0.0), vals))
            self._cond.notify_all()

    def _received(self) -> int:
        return min(len(v) for v in self._rx.values())

    def _send_sync(self) -> None:
        self._sync_times.append(time.perf_counter())
        self.network.send_message(0x80, b"")
        self._syncs += 1

    def _transmit_setpoints(self) -> None:
        sp = self._sp
        for idx, key in ((0x607A, "pos"), (0x60B1, "vel_off"), (0x60FF, "vel"), (0x6071, "torque"),
                         (0x60B2, "t_off")):
            self._rpdo_vars[idx].raw = sp[key]
        for n in self._active_rpdos:
            self.node.rpdo[n].transmit()

    def _wait_rx(self, count: int, timeout: float = 10.0) -> None:
        end = time.monotonic() + timeout
        with self._cond:
            while self._received() < count:
                left = end - time.monotonic()
                if left <= 0:
                    raise UserError(f"drive node {self.node_id}: no synchronous TPDO for SYNC {count} "
                                    f"(received {self._received()}); does the drive answer SYNC 0x080?")
                self._cond.wait(min(left, 0.2))

    def _advance(self, n: int) -> None:
        """Send ``n`` SYNCs with the set-points in force and wait for their TPDOs."""
        sent = 0
        while sent < n:
            k = min(self.burst, n - sent) if self.lockstep else 1
            for _ in range(k):
                if not self.lockstep:
                    self._pace()
                self._transmit_setpoints()
                self._send_sync()
            sent += k
            if self.lockstep:
                self._wait_rx(self._syncs)
        if not self.lockstep:
            self._wait_rx(self._syncs, timeout=1.0 + 10 * self.sync_period_s)

    def _pace(self) -> None:
        if not self._sync_times:
            return
        due = self._sync_times[-1] + self.sync_period_s
        while True:
            left = due - time.perf_counter()
            if left <= 0:
                return
            if left > 0.002:
                time.sleep(left - 0.001)

    def _stream(self, setpoints: Sequence[Mapping[str, int]]) -> None:
        """One set-point dict per SYNC (keys of ``_sp``), sent before that SYNC."""
        burst = self.burst if self.lockstep else 1
        for i, sp in enumerate(setpoints):
            self._sp.update(sp)
            if not self.lockstep:
                self._pace()
            self._transmit_setpoints()
            self._send_sync()
            if self.lockstep and (i + 1) % burst == 0:
                self._wait_rx(self._syncs)
        self._wait_rx(self._syncs)

    def _last(self, n: int) -> tuple[int, ...]:
        with self._cond:
            return self._rx[n][-1][2]

    # -- 402 state machine (canopen's profile tables) --------------------------
    def _set_controlword(self, cw: int) -> None:
        self._write(0x6040, 0, cw, 2)

    def state(self) -> str:
        """402 state from the statusword of the last TPDO1."""
        from canopen.profiles.p402 import State402
        sw = self._last(1)[0] & 0xFFFF
        for name, (mask, val) in State402.SW_MASK.items():
            if sw & mask == val:
                return name
        return f"UNKNOWN (0x{sw:04X})"

    def _fault_text(self) -> str:
        code = self._read(0x603F) if self._has(0x603F) else 0
        return f"error code 0x{code:04X} (0x603F)"

    def enable(self, mode: str) -> None:
        """Mode of operation, then the 402 transitions to OPERATION ENABLED with the set-points at the
        present position (``mode``: CSP, CSV or CST)."""
        from canopen.profiles.p402 import State402
        if mode not in self.modes:
            raise UserError(f"drive node {self.node_id}: mode {mode} not supported (0x6502: "
                            f"{', '.join(sorted(self.modes)) or 'none'})")
        self._advance(1)
        if self.state() == "FAULT":
            self._set_controlword(0x80)
            self._advance(2)
        self._write(0x6060, 0, MODE_CODES[mode], 1)
        # CSP needs RPDO1 (0x607A, 0x60B1) and RPDO2 (0x60B2); CSV and CST only RPDO2
        self._active_rpdos = (1, 2) if mode == "CSP" else (2,)
        pos = self._last(1)[1]
        self._sp.update(pos=pos - (1 << 32) if pos >= 1 << 31 else pos, vel_off=0, vel=0, torque=0, t_off=0)
        for target in ("READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED"):
            for _ in range(50):
                st = self.state()
                if st == target:
                    break
                if st == "FAULT":
                    raise UserError(f"drive node {self.node_id}: FAULT while enabling, {self._fault_text()}")
                cw = State402.TRANSITIONTABLE.get((st, target))
                if cw is None:
                    cw = State402.TRANSITIONTABLE[("SWITCH ON DISABLED", "READY TO SWITCH ON")]
                self._set_controlword(cw)
                self._advance(1)
            else:
                raise UserError(f"drive node {self.node_id}: did not reach {target} (state {self.state()})")

    def disable(self) -> None:
        """Controlword 0 (disable voltage): SWITCH ON DISABLED, power stage off, at the next SYNC."""
        self._set_controlword(0x00)
        self._advance(2)

    def _check(self, what: str) -> None:
        if self.state() != "OPERATION ENABLED":
            raise UserError(f"drive experiment '{what}': the drive left OPERATION ENABLED ({self.state()}, "
                            f"{self._fault_text()})")

    # -- conversions ------------------------------------------------------------
    def vel_raw(self, rad_s: float) -> int:
        """Output velocity (rad/s) in 0x60FF / 0x60B1 counts."""
        return int(round(rad_s / TURN * self.units.velocity_per_turn_s))

    def pos_raw(self, rad: float) -> int:
        """Output angle (rad) in 0x607A counts."""
        return int(round(rad / TURN * self.units.position_per_turn))

    def torque_raw(self, out_Nm: float) -> int:
        """Output torque (N.m) in thousandths of the rated torque 0x6076 on the side the drive works on."""
        t = out_Nm if self.units.torque_on_output else out_Nm / float(self.gear_ratio or 1.0)
        return max(-32768, min(32767, int(round(t / self._rated_Nm * 1000.0))))

    def _record_start(self) -> None:
        with self._cond:
            self._rec_from = self._received()

    def _record_stop(self) -> dict[str, np.ndarray]:
        """Columns of the SYNCs since :meth:`_record_start`, in SI units."""
        assert self._rec_from is not None
        N = float(self.gear_ratio or 1.0)
        with self._cond:
            k0, k1 = self._rec_from, self._received()
            rows = {n: np.array([v for _, _, v in self._rx[n][k0:k1]], dtype=np.int64) for n in self._rx}
            stamps = np.array([ts for _, ts, _ in self._rx[1][k0:k1]], dtype=float)
        pos = rows[1][:, 1].astype(np.int32).astype(float)
        torque = rows[2][:, 1].astype(np.int16).astype(float) * self._rated_Nm / 1000.0
        out_torque = torque if self.units.torque_on_output else torque * N
        cols = {"t_s": np.arange(k1 - k0) * self.sync_period_s, "_stamp_s": stamps,
                "load_angle_rad": unwrap_count(pos) / self.units.position_per_turn * TURN,
                "motor_torque_Nm": out_torque / N,
                "load_velocity_rad_s": rows[2][:, 0].astype(np.int32).astype(float) / self.units.velocity_per_turn_s
                * TURN}
        if self.has_current:
            cols["current_permille"] = rows[2][:, 2].astype(np.int16).astype(float)
        if self.has_encoder2:
            e2 = unwrap_count(rows[3][:, 0].astype(np.int32)) / self.units.encoder2_per_turn * TURN
            cols["motor_angle_rad"] = e2 * N if self.units.encoder2_output_units else e2
        return cols

    def _uniform(self, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Columns on a uniform grid of the SYNC period.

        Lock-step: the k-th SYNC is k periods of drive time, nothing to do.  Free-running: the
        host's SYNCs jitter, so every column (one value per SYNC) is interpolated from the
        timestamps of the TPDO1 frames (the bus's receive time; the virtual drive stamps its
        frames with its own time) onto the nominal period.
        """
        stamps = cols.pop("_stamp_s")
        if self.lockstep or len(stamps) < 2 or np.any(np.diff(stamps) < 0):
            return cols
        # SYNCs that reached the drive together are answered in the same drive period: keep one
        t, keep = np.unique(stamps[::-1] - stamps[0], return_index=True)
        keep = len(stamps) - 1 - keep
        grid = np.arange(int(t[-1] / self.sync_period_s) + 1) * self.sync_period_s
        out = {k: np.interp(grid, t, np.asarray(v)[keep]) for k, v in cols.items() if k != "t_s"}
        out["t_s"] = grid
        return out

    # -- experiments -------------------------------------------------------------
    def _segment(self, vel_rad_s: np.ndarray, label: str) -> dict[str, np.ndarray]:
        """CSV: one target velocity per SYNC; the columns of those SYNCs."""
        self._say(label)
        raw = [self.vel_raw(float(v)) for v in vel_rad_s]
        self._record_start()
        self._stream([{"vel": r} for r in raw])
        cols = self._record_stop()
        cols["setpoint_velocity_rad_s"] = np.array(raw, dtype=float) / self.units.velocity_per_turn_s * TURN
        cols["torque_cmd_Nm"] = cols["motor_torque_Nm"] * float(self.gear_ratio or 1.0)
        return self._uniform(cols)

    def _velocities(self, seg: Mapping[str, Any]) -> np.ndarray:
        dt = self.sync_period_s
        mode = seg["mode"]
        if mode == "velocity":
            n = int(round((float(seg["settle_s"]) + float(seg["window_s"])) / dt))
            return np.full(n, float(seg["velocity_rad_s"]))
        if mode == "position":
            a, f = float(seg["amplitude_rad"]), float(seg["frequency_Hz"])
            t = np.arange(int(round(float(seg["duration_s"]) / dt))) * dt + 0.5 * dt
            return a * TURN * f * np.cos(TURN * f * t)
        if mode == "velocity_multisine":
            t = np.arange(int(round(float(seg["duration_s"]) / dt))) * dt
            tau = t - float(seg["settle_s"])
            ms = schroeder_multisine(np.maximum(tau, 0.0), float(seg["f0_Hz"]), float(seg["f1_Hz"]),
                                     int(seg["lines"]))
            return float(seg["bias_rad_s"]) + np.where(tau >= 0, float(seg["amplitude_rad_s"]) * ms, 0.0)
        raise UserError(f"mode '{mode}' needs the output locked (a test rig): not on the standard-objects path")

    def run(self, design: Any) -> ex.ExperimentData:
        """Run one design (CSV segments) and return its data (columns of :class:`~.experiments.SimRunner`).

        An SDO exchange that fails half-way (abort, time-out) is one line (:class:`UserError`).
        """
        import canopen
        try:
            return self._run(design)
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
            raise UserError(f"{design.kind}: drive node {self.node_id}: {e}") from None

    def _run(self, design: Any) -> ex.ExperimentData:
        N = float(self.gear_ratio or 1.0)
        plan = design.plan(N)
        if any(s["mode"] == "locked" for s in plan):
            raise UserError(f"{design.kind}: needs the output locked and a torque sensor (a test rig); the "
                            "standard-objects path has none -- record the test on a rig and use --data")
        if design.kind in ("te_rotation", "frf") and not self.has_encoder2:
            raise UserError(f"{design.kind}: needs the motor and the output position; the drive has no second "
                            "encoder object 0x60E4:1")
        load = check_bus_load(self.frame_bytes("CSV"), 1.0 / self.sync_period_s, self.bitrate)
        parts = []
        self.enable("CSV")
        try:
            self._advance(int(round(0.02 / self.sync_period_s)) + 1)
            t_sync0 = len(self._sync_times)     # the statistics cover the experiment, not the enabling
            for i, seg in enumerate(plan):
                if seg["mode"] == "velocity_multisine":
                    seg = {**seg, "bias_rad_s": float(seg["bias_rad_s"]) * (1 if i % 2 == 0 else -1)}
                label = f"{design.kind}: segment {i + 1}/{len(plan)} {ex._seg_label(seg)}"
                cols = self._segment(self._velocities(seg), label)
                self._check(design.kind)
                if seg["mode"] == "position":
                    self._sp["vel"] = 0
                    self._advance(int(round(0.2 / self.sync_period_s)))
                if "motor_angle_rad" not in cols:
                    cols["motor_angle_rad"] = cols["load_angle_rad"] * N
                parts.append((cols, seg))
            self._sp["vel"] = 0
            self._advance(int(round(0.2 / self.sync_period_s)))
        finally:
            self.disable()
        meta = {"gear_ratio": N, "sample_period_s": self.sync_period_s, "source": "CiA 402 standard objects",
                "design": ex.describe(design), "lockstep": self.lockstep, "bus_load": load,
                "sync_stats": self.sync_stats(t_sync0), "encoder2": self.has_encoder2}
        clean = []
        for cols, seg in parts:
            if len(cols["t_s"]) < 10:
                raise UserError(f"{design.kind}: fewer than 10 samples in a segment")
            clean.append((cols, seg))
        return ex.concat(design.kind, clean, meta)

    def sync_stats(self, first: int = 0) -> dict[str, Any]:
        """Host SYNC period statistics since SYNC ``first`` and the SYNC -> last-TPDO round trip (s)."""
        times = self._sync_times[first:]
        out: dict[str, Any] = {"period": period_stats(times), "nominal_period_s": self.sync_period_s,
                               "lockstep": self.lockstep}
        with self._cond:
            n = min(len(times), self._received() - first)
            if n > 0:
                arr = np.array([max(self._rx[m][first + k][0] for m in self._rx) for k in range(n)])
                rt = arr - np.asarray(times[:n])
                out["round_trip"] = {"median_s": float(np.median(rt)), "p99_s": float(np.percentile(rt, 99)),
                                     "max_s": float(np.max(rt))}
        return out

    # -- closed-loop tracking with host feed-forward --------------------------------
    def track(self, ref_rad: np.ndarray, feedforward: Optional[Callable[[float, float], float]] = None,
              label: str = "tracking", velocity_offset: bool = True) -> dict[str, Any]:
        """CSP tracking of ``ref_rad`` (output angle per SYNC, relative to where the axis is).

        ``feedforward(theta_ref_rad, omega_ref_rad_s) -> N.m`` (output side) is sent in the torque
        offset 0x60B2 with each set-point (host-side compensation); None = the drive's loop alone.
        ``velocity_offset``: the reference's derivative goes in 0x60B1 (velocity feed-forward);
        False = position set-points alone.

        Returns
        -------
        dict
            ``t_s``, ``ref_rad``, ``load_angle_rad`` (arrays), ``rms_error_rad``, ``max_error_rad``
            (after the first 10 %), ``sync_stats``.
        """
        if feedforward is not None and "0x60B2" not in self.offsets():
            raise UserError("host feed-forward needs the torque offset 0x60B2")
        check_bus_load(self.frame_bytes("CSP"), 1.0 / self.sync_period_s, self.bitrate)
        self.enable("CSP")
        try:
            p0 = self._sp["pos"]
            theta0 = p0 / self.units.position_per_turn * TURN
            vel = np.gradient(ref_rad, self.sync_period_s)
            sps = []
            for th, w in zip(ref_rad, vel):
                sp = {"pos": p0 + self.pos_raw(float(th)), "vel_off": self.vel_raw(float(w)) if velocity_offset else 0}
                sp["t_off"] = self.torque_raw(feedforward(theta0 + float(th), float(w))) if feedforward else 0
                sps.append(sp)
            self._advance(int(round(0.05 / self.sync_period_s)))
            self._say(label)
            self._record_start()
            first = len(self._sync_times)       # the statistics cover the stream, not the enabling
            self._stream(sps)
            cols = self._record_stop()
            cols["_ref_rad"] = np.asarray(ref_rad, dtype=float)[:len(cols["t_s"])]
            self._check(label)
            self._sp.update(vel_off=0, t_off=0)
            self._advance(int(round(0.05 / self.sync_period_s)))
        finally:
            self.disable()
        # the set-point sent before SYNC k is in force from SYNC k: the sample of SYNC k + 1 sees it
        cols["_ref_rad"] = np.concatenate([[0.0], cols["_ref_rad"][:-1]])
        cols = self._uniform(cols)
        y = cols["load_angle_rad"][1:] - theta0
        r = cols["_ref_rad"][1:]
        e = r - y
        m = np.arange(len(e)) >= len(e) // 10
        return {"t_s": cols["t_s"][1:], "ref_rad": r, "load_angle_rad": y,
                "rms_error_rad": float(np.sqrt(np.mean(e[m] ** 2))), "max_error_rad": float(np.max(np.abs(e[m]))),
                "sync_stats": self.sync_stats(first)}

    def torque_staircase(self, torque_Nm: np.ndarray, label: str = "torque staircase") -> dict[str, np.ndarray]:
        """CST: one target torque 0x6071 (output N.m) per SYNC, then 0; the columns of those SYNCs
        with ``torque_Nm`` = torque actual value 0x6077 on the output side."""
        check_bus_load(self.frame_bytes("CST"), 1.0 / self.sync_period_s, self.bitrate)
        self.enable("CST")
        try:
            self._say(label)
            self._record_start()
            self._stream([{"torque": self.torque_raw(float(t))} for t in torque_Nm])
            cols = self._record_stop()
            self._sp["torque"] = 0
            self._advance(2)
            self._check(label)
        finally:
            self.disable()
        cols = self._uniform(cols)
        cols["torque_Nm"] = cols["motor_torque_Nm"] * float(self.gear_ratio or 1.0)
        return cols

    def frame_bytes(self, mode: str) -> list[int]:
        """Data length of every PDO per SYNC in ``mode``: the TPDOs and the RPDOs the mode sends."""
        rp = (1, 2) if mode == "CSP" else (2,)
        return list(self.tpdo_bytes) + [self.rpdo_bytes[n] for n in rp]

    def offsets(self) -> list[str]:
        """Offset objects mapped in the RPDOs (host-side compensation needs 0x60B2)."""
        return [f"0x{i:04X}" for i in (0x60B1, 0x60B2) if i in self._rpdo_vars]


# ----------------------------------------------------------------- session on the virtual drive


class StdSession:
    """Context manager: a :class:`StdRunner` on its own virtual drive (``hdservo-sim serve --pacing sync``),
    or on a bus given by python-can settings; the virtual drive always stops.

    Parameters
    ----------
    bus : dict, optional
        python-can settings of a real drive (``interface``, ``channel``, ``bitrate``...); None =
        start a virtual drive.
    node_id : int
        CANopen node id.
    axis : str
        Axis of the virtual drive (``reference``, ``minimal`` or a TOML path).
    profile : str
        Object dictionary of the virtual drive: ``generic`` (CiA 301/402 objects only, every
        vendor access refused and logged) or ``hdservo``.
    seed : int
        Sensor-noise seed of the virtual drive.
    sync_periods : int
        Virtual drive: 100 us loop periods per SYNC (the SYNC period of the runner).
    pacing : str
        Virtual drive: ``sync`` (lock-step, reproducible) or ``realtime`` (the drive runs by
        the clock and the host produces SYNC by its own clock, as with a real drive).
    sets : sequence of str
        ``SECTION.KEY=VALUE`` plant overrides of the virtual drive (default: base motion off).
    output_locked : bool
        Virtual drive: the simulated bench locks the output with its brake (the test-rig channel
        of the simulator, not an object of the drive), as an operator locks a real axis for the
        peak-torque test.
    runner_args : dict
        Further :class:`StdRunner` arguments (``gear_ratio``, ``units``, ``bitrate``, ``progress``).
    """

    def __init__(self, bus: Optional[dict[str, Any]] = None, node_id: int = 1, axis: str = "reference",
                 profile: str = "generic", seed: int = 1, sync_periods: int = 10, pacing: str = "sync",
                 sets: Sequence[str] = ("base.enabled=false",), output_locked: bool = False,
                 **runner_args: Any) -> None:
        if pacing not in ("sync", "realtime"):
            raise UserError(f"pacing must be sync or realtime, not {pacing!r}")
        self.bus, self.node_id, self.axis, self.profile, self.seed = bus, node_id, axis, profile, seed
        self.pacing, self.output_locked = pacing, output_locked
        self.sync_periods, self.sets, self.runner_args = sync_periods, tuple(sets), runner_args
        self.proc: Any = None
        self.network: Any = None
        self.runner: Optional[StdRunner] = None
        #: the virtual drive's stderr once it stopped (vendor accesses are logged there)
        self.server_log = ""

    def __enter__(self) -> StdRunner:
        import canopen
        try:
            args = dict(self.runner_args)
            if self.bus is None:
                from ..serve_proc import find_sim
                from ..serve_proc import ServeError, ServeProcess
                cmd = ["--node-id", str(self.node_id), "--axis", str(self.axis), "--pacing", self.pacing,
                       "--sync-periods", str(self.sync_periods), "--seed", str(self.seed), "--profile", self.profile]
                for s in self.sets:
                    cmd += ["--set", s]
                if self.output_locked:
                    cmd.append("--rig")
                try:
                    self.proc = ServeProcess(find_sim(), cmd)
                    if self.output_locked:
                        self.proc.rig("brake 1")
                except ServeError as e:
                    raise UserError(str(e)) from None
                bus: dict[str, Any] = {"interface": "socketcand", "channel": "can0", "host": "127.0.0.1",
                                       "port": self.proc.port}
                args.setdefault("sync_period_s", self.sync_periods * 1e-4)
                args["lockstep"] = self.pacing == "sync"
            else:
                bus = self.bus
                args.setdefault("lockstep", False)
            self.network = canopen.Network()
            try:
                self.network.connect(**bus)
            except (OSError, ValueError) as e:
                raise UserError(f"cannot open the CAN bus: {e}") from None
            self.runner = StdRunner(self.network, self.node_id, **args)
            try:
                self.runner.open()
            except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
                raise UserError(f"drive node {self.node_id}: setting up the PDOs: {e}") from None
            return self.runner
        except BaseException:
            self.__exit__(None, None, None)
            raise

    def __exit__(self, *exc: object) -> None:
        try:
            if self.runner is not None:
                self.runner.close()
        finally:
            try:
                if self.network is not None:
                    self.network.disconnect()
                    self.network = None
            finally:
                if self.proc is not None:
                    self.server_log = self.proc.stop()
                    self.proc = None


def friction_gravity_feedforward(stribeck: Any, gravity: Any) -> Callable[[float, float], float]:
    """Feed-forward torque (output side, N.m) from the identified model: Stribeck friction of the
    reference velocity (per direction) + the gravity holding torque of the reference angle.

    Parameters
    ----------
    stribeck : hdservo.ident.friction.StribeckResult
    gravity : hdservo.ident.friction.GravityResult
    """
    def ff(theta_rad: float, omega_rad_s: float) -> float:
        f = float(stribeck(np.array([omega_rad_s]))[0]) if abs(omega_rad_s) > 1e-9 else 0.0
        return f + float(gravity.holding_torque(np.array([theta_rad]))[0])
    return ff


__all__ = ["BUS_LOAD_LIMIT", "SdoGuard", "StdRunner", "StdSession", "StdUnits", "bus_load", "check_bus_load", "frame_bits",
           "friction_gravity_feedforward", "period_stats"]
