"""Run test procedures against a drive: a real one (python-can settings) or a virtual one.

A procedure gets a :class:`Bench`: the drive (:class:`hdservo.drive.Drive`,
SDO/PDO only), the test rig (:class:`VirtualRig` for the simulator,
:class:`ManualRig` for a real bench: it prints what the operator must do) and
drive-time helpers that work the same on every pacing:

* ``bench.wait(s)`` lets ``s`` seconds of DRIVE time pass (loop ticks, never
  wall-clock comparisons); in lock-step it sends SYNCs;
* ``bench.capture(...)`` records signals at loop rate in the drive's capture
  buffer while an action runs, then uploads them;
* ``bench.stream(values)`` sends one RPDO set-point per SYNC (lock-step on the
  virtual drive, wall-clock paced on a real one): excitation from the host.

Without drive options :func:`open_bench` starts ``hdservo-sim serve`` (the
reference axis, or ``axis``) on an ephemeral loopback port with ``--rig`` and
the plant overrides of the procedure's :class:`RigSetup`, and always stops it.
"""
from __future__ import annotations

import contextlib
import math
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Optional, Sequence

import can
import numpy as np

from ..errors import UserError
from ..pdo import STATUS_PDO
from ..progress import Fraction
from ..serve_proc import ServeProcess
from ..drive import Drive, DriveError
from ..params_gen import BY_NAME as PARAMS

from ..fw_const import LOOP_HZ, SIGNALS as SIG  # noqa: E402  (generated from the C headers)
from ..units import TURN  # noqa: E402

DT = 1.0 / LOOP_HZ
CAPTURE_WORDS = 8192


class RigError(UserError):
    """The rig cannot do what a procedure needs (one line)."""


@dataclass
class RigSetup:
    """Mechanical set-up a procedure needs (the test rig, not the drive).

    Attributes
    ----------
    name : str
        ``gear`` (payload removed, base still), ``axis`` (payload on, base
        still) or ``stabilisation`` (payload on, base rocking).
    payload : bool
        Pitch payload mounted (gravity unbalance acts).
    base_amp_rad, base_freq_Hz : float
        Base rocking (swing table): amplitude, rad, and frequency, Hz; 0 = still.
    plant : dict
        Extra plant overrides for the virtual rig only (tests), ``section.key`` -> value.
    """

    name: str = "axis"
    payload: bool = True
    base_amp_rad: float = 0.0
    base_freq_Hz: float = 1.0
    plant: dict[str, float] = field(default_factory=dict)

    def sets(self) -> list[str]:
        """``--set`` options of the virtual drive for this set-up."""
        out = [f"gravity.enabled={'true' if self.payload else 'false'}"]
        if self.base_amp_rad > 0.0:
            out += ["base.enabled=true", f"base.amplitude_rad={self.base_amp_rad!r}",
                    f"base.frequency_Hz={self.base_freq_Hz!r}"]
        else:
            out += ["base.enabled=false"]
        for k, v in self.plant.items():
            val = ("true" if v else "false") if isinstance(v, bool) else repr(float(v)) if not isinstance(v, int) else str(v)
            out.append(f"{k}={val}")
        return out

    def instructions(self) -> str:
        """What the operator of a real bench must set up."""
        parts = ["payload mounted" if self.payload else "payload removed (gear only, no output load)"]
        parts.append(f"base rocking {self.base_amp_rad / math.pi * 180:.3g} deg at {self.base_freq_Hz:g} Hz"
                     if self.base_amp_rad > 0 else "base still")
        return ", ".join(parts)


# ---- progress ---------------------------------------------------------------------------

#: a procedure's progress indicator, ``progress(frac, text)`` (:class:`hdservo.progress.Fraction`)
Progress = Fraction


# ---- the virtual drive process -------------------------------------------------------------

def find_sim() -> Path:
    """The hdservo-sim program (see :func:`hdservo.serve_proc.find_sim`)."""
    from ..serve_proc import find_sim as fs
    return fs()


class VirtualDriveProcess(ServeProcess):
    """``hdservo-sim serve --rig`` on an ephemeral port; :meth:`stop` always ends it.

    Parameters
    ----------
    axis : str
        ``reference``, ``minimal`` or an axis TOML file.
    pacing : str
        ``fast`` (as fast as the client reads), ``sync`` (lock-step on SYNC) or ``realtime``.
    sets : sequence of str
        ``KEY=VALUE`` plant overrides.
    sync_periods : int
        Loop periods per SYNC (pacing ``sync``).
    seed : int
        Sensor-noise seed.
    profile : str
        ``hdservo``, or ``generic`` (standard objects only; no ``--rig``: the rig commands fail).
    """

    def __init__(self, axis: str = "reference", pacing: str = "fast", sets: Sequence[str] = (),
                 sync_periods: int = 10, seed: int = 1, node_id: int = 1, profile: str = "hdservo") -> None:
        args = ["--node-id", str(node_id), "--axis", axis, "--pacing", pacing,
                "--sync-periods", str(sync_periods), "--seed", str(seed)]
        args += ["--rig"] if profile == "hdservo" else ["--profile", profile]
        for s in sets:
            args += ["--set", s]
        super().__init__(find_sim(), args, error=RigError)


# ---- rigs --------------------------------------------------------------------------------

class Rig:
    """Interface of a test rig: output lock, output torque loading, reference instruments."""

    virtual = False
    setup: RigSetup

    def brake(self, on: bool) -> None:
        """Lock (True) or release the output."""
        raise NotImplementedError

    def load_torque(self, torque_Nm: float, rate_Nm_s: float = 0.0) -> None:
        """Apply an external torque on the output, ramped at ``rate_Nm_s`` (0 = step)."""
        raise RigError("this procedure needs a torque-loading rig with a load cell on the output; "
                       "the manual bench has none (run it on the virtual drive, or add a rig driver)")

    def load_torque_profile(self, ramps: Sequence[tuple[float, float]]) -> None:
        """Apply a sequence of ramps ``(torque_Nm, rate_Nm_s)``, each starting when the previous
        target is reached, timed by the rig itself (drive time), not by the host."""
        raise RigError("this procedure needs a torque-loading rig with a load cell on the output; "
                       "the manual bench has none (run it on the virtual drive, or add a rig driver)")

    @contextlib.contextmanager
    def record(self, decimation: int) -> Iterator[dict[str, np.ndarray]]:
        """Record the reference instruments while the block runs; the dict is filled on exit."""
        raise RigError("this rig has no reference instruments to record")
        yield {}  # pragma: no cover


class NoRig(Rig):
    """The generic CiA 402 virtual drive (``--profile generic``): a drive without a bench.

    Every rig action is refused at once, in one line (a drive from another vendor has no
    brake, load or reference instruments reachable over CAN).
    """

    def __init__(self, setup: RigSetup) -> None:
        self.setup = setup

    def brake(self, on: bool) -> None:
        raise RigError("the generic CiA 402 drive has no test rig (no output brake); "
                       "run this procedure on a bench or the hdservo profile")

    def load_torque(self, torque_Nm: float, rate_Nm_s: float = 0.0) -> None:
        raise RigError("the generic CiA 402 drive has no test rig (no output torque loading); "
                       "run this procedure on a bench or the hdservo profile")

    def load_torque_profile(self, ramps: Sequence[tuple[float, float]]) -> None:
        self.load_torque(0.0)

    def close(self) -> None:
        """Nothing to release."""


class ManualRig(Rig):
    """A real bench: prints what the operator must do (and waits for Enter on a terminal)."""

    def __init__(self, setup: RigSetup, interactive: Optional[bool] = None) -> None:
        self.setup = setup
        self.interactive = sys.stdin.isatty() if interactive is None else interactive
        self._say(f"set up the bench: {setup.instructions()}")

    def _say(self, what: str) -> None:
        print(f"RIG: {what}", file=sys.stderr)
        if self.interactive:
            input("     press Enter when done ")

    def brake(self, on: bool) -> None:
        self._say("lock the output flange (brake/clamp)" if on else "release the output flange")


class VirtualRig(Rig):
    """The simulator's rig features through ``hdservo-sim serve --rig`` (see serve.c)."""

    virtual = True

    def __init__(self, proc: VirtualDriveProcess, setup: RigSetup) -> None:
        self.proc = proc
        self.setup = setup
        self._tmp = tempfile.TemporaryDirectory(prefix="hdservo-rig-")

    def brake(self, on: bool) -> None:
        self.proc.rig(f"brake {1 if on else 0}")

    def load_torque(self, torque_Nm: float, rate_Nm_s: float = 0.0) -> None:
        self.proc.rig(f"torque {torque_Nm!r} {rate_Nm_s!r}")

    def load_torque_profile(self, ramps: Sequence[tuple[float, float]]) -> None:
        if not ramps or any(r <= 0 for _, r in ramps):
            raise ValueError("load_torque_profile: expected ramps with rates > 0")
        # rig command `then`: a ramp that starts when the applied torque is at its current target;
        # all lines in one write, so the drive queues them in the same loop period
        self.proc.rig_many([f"then {t!r} {r!r}" for t, r in ramps])

    @contextlib.contextmanager
    def record(self, decimation: int) -> Iterator[dict[str, np.ndarray]]:
        path = Path(self._tmp.name) / "rig.csv"
        out: dict[str, np.ndarray] = {}
        self.proc.rig(f"record {path} {int(decimation)}")
        try:
            yield out
        finally:
            self.proc.rig("record stop")
        data = np.genfromtxt(path, delimiter=",", names=True)
        data = np.atleast_1d(data)
        for name in data.dtype.names or ():
            out[name] = np.asarray(data[name], float)

    def close(self) -> None:
        self._tmp.cleanup()


# ---- the bench -------------------------------------------------------------------------------

class Bench:
    """A drive, its rig and drive-time helpers (see the module docstring).

    Parameters
    ----------
    drive : Drive
        Connected and started (NMT OPERATIONAL).
    rig : Rig
        The test rig.
    lockstep : bool
        The drive advances only on SYNC (virtual drive ``--pacing sync``).
    sync_periods : int
        Loop periods per SYNC; also the set-point period of :meth:`stream`.
    """

    def __init__(self, drive: Drive, rig: Rig, lockstep: bool = False, sync_periods: int = 10,
                 realtime: bool = False) -> None:
        self.drive = drive
        self.rig = rig
        self.lockstep = lockstep
        self.realtime = realtime
        self.sync_periods = sync_periods
        self.node_id = drive.node_id
        self._ev = threading.Event()
        self._cv = threading.Condition()
        self._answers = 0           # synchronous TPDO1 answers received (lock-step: one per SYNC)
        self._tick = 0
        self._listener: Optional[can.Listener] = None
        self.ratio = float(drive.get_param("gear_ratio"))
        self.kt = float(drive.get_param("kt"))
        if lockstep:
            self._attach_sync()
            for _ in range(3):          # let the 402 state machine leave NOT READY
                self.sync()

    # -- time --
    def _attach_sync(self) -> None:
        pdo = self.drive.pdo
        cob = pdo.cob_id(STATUS_PDO)
        ev = self._ev
        cv = self._cv
        bench = self

        class L(can.Listener):
            def on_message_received(self, m: can.Message) -> None:
                if m.arbitration_id != cob:
                    return
                fr = pdo.decode(cob, bytes(m.data))
                if fr is not None:
                    with cv:
                        bench._tick = fr.tick
                        bench._answers += 1
                        cv.notify_all()
                    ev.set()

        self._listener = L()
        self.drive.network.notifier.add_listener(self._listener)
        self.drive.write(0x1800 + STATUS_PDO - 1, 2, 1)   # the status TPDO synchronous: one answer per SYNC

    #: SYNCs sent at once by :meth:`wait` and :meth:`capture` in lock-step (the drive queues the
    #: credit; the host waits for every answer before its next request, so drive time stays exact)
    SYNC_BURST = 40

    def sync(self, n: int = 1) -> None:
        """``n`` SYNCs; lock-step: wait until the drive has answered every one (K periods follow each).

        A burst (``n`` > 1) gives the same drive time as ``n`` single SYNCs: the virtual
        drive adds K periods of credit per SYNC and reads no other frame while it has
        credit, and the host sends nothing else until all ``n`` answers are in.
        """
        with self._cv:
            want = self._answers + n
        self._ev.clear()
        for _ in range(n):
            self.drive.network.send_message(0x80, b"")
        if not self.lockstep:
            return
        with self._cv:
            if not self._cv.wait_for(lambda: self._answers >= want, 5.0 + 0.01 * n):
                raise DriveError("no answer to SYNC (is the drive in --pacing sync?)")

    #: attempts of :meth:`read`; the waits between them double from 0.05 s (3.15 s in all)
    READ_ATTEMPTS = 7

    def read(self, index: int, sub: int = 0) -> Any:
        """SDO read, repeated (up to :data:`READ_ATTEMPTS` times, doubling waits) after a failed transfer.

        With fast pacing the drive's 1 s SDO time-out is drive time; after an
        aborted block upload a stale frame can answer the next request.  On a
        loaded host (load average 8-9 on 2 cores) three reads 50 ms apart have
        all gone unanswered ("No SDO response received"), hence the backoff.
        """
        for attempt in range(self.READ_ATTEMPTS):
            try:
                return self.drive.read(index, sub)
            except DriveError:
                if attempt == self.READ_ATTEMPTS - 1:
                    raise
                time.sleep(0.05 * 2 ** attempt)

    def ticks(self) -> int:
        """Loop periods since power-up (0x5F00:11)."""
        return int(self.read(0x5F00, 11))

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` of drive time pass."""
        n = int(round(seconds * LOOP_HZ))
        if n <= 0:
            return
        if self.lockstep:
            k = -(-n // self.sync_periods)
            while k > 0:
                self.sync(min(k, self.SYNC_BURST))
                k -= self.SYNC_BURST
            return
        end = self.ticks() + n
        while True:
            left = end - self.ticks()
            if left <= 0:
                return
            time.sleep(min(0.05, left * DT * (1.0 if self.realtime else 0.1)))

    # -- state machine --
    def enable(self, mode: str) -> None:
        """Select a CiA 402 mode and enable (bumpless: targets start at the actual values)."""
        if not self.lockstep:
            if self.drive.state() == "FAULT":
                self.drive.fault_reset()
            self.drive.enable(mode)
            return
        self.drive.enable(mode, settle=self.sync)      # a SYNC after each controlword and between polls

    def disable(self) -> None:
        """Power stage off."""
        self.drive.write(0x6040, 0, 0x00)
        if self.lockstep:
            self.sync()

    def fault(self) -> int:
        """Application fault code (0x5F00:10), 0 = none."""
        return int(self.read(0x5F00, 10))

    @contextlib.contextmanager
    def params(self, values: Mapping[str, float]) -> Iterator[None]:
        """Set drive parameters by name for the block, restore the old values afterwards."""
        old: dict[str, float] = {}
        try:
            for k, v in values.items():
                old[k] = self.drive.get_param(k)
                self.drive.set_param(k, v)
            yield
        finally:
            for k, v in old.items():
                try:
                    self.drive.set_param(k, v)
                except DriveError:
                    pass

    # -- set-points --
    def target_position_raw(self, rad: float) -> int:
        """0x607A units (2^-24 turn)."""
        return int(round(rad / TURN * 2 ** 24))

    def rpdo_position(self, rad: float, vel_rad_s: float = 0.0) -> None:
        """RPDO2: target position (2^-24 turn) + velocity offset (2^-32 turn/s)."""
        self.drive.network.send_message(*self.drive.pdo.encode(
            2, target_position=self.target_position_raw(rad), velocity_offset=int(round(vel_rad_s / TURN * 2 ** 32))))

    def rpdo_torque(self, torque_Nm: float, rated_Nm: float) -> None:
        """RPDO3: target velocity 0, target torque (per mille of the rated torque), offset 0."""
        pm = max(-32768, min(32767, int(round(torque_Nm / rated_Nm * 1000.0))))
        self.drive.network.send_message(*self.drive.pdo.encode(3, target_torque=pm))

    def stream(self, values: Sequence[float], send: Callable[[float], None],
               progress: Optional[Callable[[float], None]] = None) -> None:
        """Send one set-point per SYNC period (``sync_periods`` loop periods each).

        Lock-step on the virtual drive; wall-clock paced on a real drive.
        """
        period = self.sync_periods * DT
        t0 = time.monotonic()
        n = len(values)
        for k, v in enumerate(values):
            send(float(v))
            if not self.lockstep:
                due = t0 + k * period
                d = due - time.monotonic()
                if d > 0:
                    time.sleep(d)
            self.sync()
            if progress and k % 200 == 0:
                progress(k / max(1, n))

    # -- capture --
    def capture(self, signals: Sequence[str], frames: int, decimation: int,
                action: Optional[Callable[[], None]] = None) -> dict[str, np.ndarray]:
        """Record ``signals`` (names of :data:`SIG`) for ``frames`` samples every ``decimation`` periods.

        The capture is armed and triggered, ``action()`` runs (set-points,
        rig commands), then the drive time runs on until the buffer is full.
        Returns raw int64 arrays by signal name (``*_lo`` words as unsigned).
        """
        if not 1 <= len(signals) <= 4:
            raise ValueError("capture takes 1 to 4 signals")
        if frames * len(signals) > CAPTURE_WORDS:
            raise ValueError(f"capture: {frames} x {len(signals)} words exceed the buffer ({CAPTURE_WORDS})")
        packed = 0
        for k in range(4):
            packed |= (SIG[signals[k]] if k < len(signals) else 0xFF) << (8 * k)
        d = self.drive
        d.write(0x5000, 3, packed)
        d.write(0x5000, 4, frames)
        d.write(0x5000, 5, decimation)
        d.write(0x5000, 6, 0)
        d.write(0x5000, 1, 1)
        d.write(0x5000, 1, 2)
        if action is not None:
            action()
        total = frames * decimation
        for _ in range(100000):
            if self.read(0x5000, 2) == 3:
                break
            if self.lockstep:
                k = max(1, min(200, total // self.sync_periods // 4))
                while k > 0:
                    self.sync(min(k, self.SYNC_BURST))
                    k -= self.SYNC_BURST
            else:
                time.sleep(min(0.05, total * DT * (0.05 if not self.realtime else 0.25)))
        else:  # pragma: no cover
            raise DriveError("capture did not finish")
        # the drive's SDO time-out is 1 s of DRIVE time: with fast pacing a busy host can miss it
        # during a block upload; the buffer keeps its data, so the upload is simply repeated
        for attempt in range(self.READ_ATTEMPTS):
            try:
                raw = d.read_domain(0x5000, 7)
                break
            except DriveError:
                if attempt == self.READ_ATTEMPTS - 1:
                    raise
                time.sleep(0.05 * 2 ** attempt)     # a loaded host: give the drive process time
        words = np.frombuffer(raw, dtype="<i4").astype(np.int64)
        n = len(signals)
        words = words[: (words.size // n) * n].reshape(-1, n)
        out = {}
        for k, s in enumerate(signals):
            w = words[:, k]
            out[s] = (w & 0xFFFFFFFF) if s.endswith("_lo") else w
        return out

    # -- conversions of captured words (angles: hdservo.phase.unwrap_turns) --
    def load_angle_rad(self) -> float:
        """Output angle by SDO (0x5F00:9, Q32.32 turns), rad."""
        return float(self.read(0x5F00, 9)) / 2.0 ** 32 * TURN

    def rated_torque_Nm(self) -> float:
        """0x6076 in N.m (stored in mN.m)."""
        return float(self.read(0x6076)) / 1000.0


# ---- opening a bench ---------------------------------------------------------------------------

@dataclass
class Target:
    """Where the procedures run: a real drive (bus settings) or the virtual one (axis)."""

    bus: Optional[dict[str, Any]] = None      #: python-can settings; None = virtual drive
    node_id: int = 1
    axis: str = "reference"
    seed: int = 1
    compensators: Optional[list[str]] = None
    plant: dict[str, float] = field(default_factory=dict)   #: virtual only: extra plant overrides
    interactive: Optional[bool] = None
    notes: list[str] = field(default_factory=list)
    #: compensator download (:func:`hdservo.download.plan_download`), written and read back
    #: into the drive before each procedure (the virtual drive keeps no parameters)
    download: Optional[Mapping[str, Any]] = None
    #: drive parameters by name (``--set NAME=VALUE``), written after the download, read back
    params: dict[str, float] = field(default_factory=dict)
    #: virtual only: the object profile of the virtual drive (``hdservo`` or ``generic``: CiA 301/402
    #: standard objects only, no test rig)
    profile: str = "hdservo"

    @property
    def virtual(self) -> bool:
        return self.bus is None


def apply_compensators(drive: Drive, names: Optional[list[str]]) -> str:
    """Set the drive's compensator enables by parameter name; returns a one-line note."""
    if names is None:
        return ""
    if "cb_enable" not in PARAMS:
        return "compensators: this drive's object dictionary has no 'cb_enable' parameter; nothing set"
    from ..compsetup import ENABLE_BITS
    bad = [n for n in names if n not in ENABLE_BITS]
    if bad:
        raise UserError(f"--compensators: unknown '{bad[0]}'; expected some of {', '.join(ENABLE_BITS)}")
    mask = 0
    for n in names:
        mask |= ENABLE_BITS[n]
    drive.set_param("cb_enable", float(mask))
    note = f"compensators: cb_enable = {mask} ({', '.join(names) or 'none'})"
    if "preisach" in names:
        note += "; the Preisach inverse needs its table downloaded (hdservo download)"
    return note


def configure_drive(drive: Drive, target: Target) -> list[str]:
    """Write the target's download plan and parameters into the drive (power stage off), read back.

    Order: the compensator download (``download.write_verified``: SDO
    parameters and tables, each read back), then ``target.params`` by name
    (read back within one raw step), then ``cb_enable`` (:func:`apply_compensators`).

    Returns
    -------
    list of str
        One-line notes (what was written).

    Raises
    ------
    UserError
        A refused write or a read-back mismatch.
    """
    notes: list[str] = []
    if target.download is not None:
        from ..download import write_verified
        done = write_verified(drive, target.download, tables=True)
        tabs = ", ".join(f"0x5100:{t}" for t in done["tables"]) or "none"
        src = target.download.get("model_file")
        notes.append(f"model{' ' + str(src) if src else ''}: {done['params']} compensator parameters and tables "
                     f"{tabs} downloaded, read back")
    if target.params:
        for name, v in target.params.items():
            p = PARAMS.get(name)
            if p is None:
                raise UserError(f"--set: unknown drive parameter '{name}'")
            if not p.min <= float(v) <= p.max:
                raise UserError(f"--set: {name} = {v:g} outside [{p.min:g}, {p.max:g}] {p.unit}")
            try:
                drive.set_param(name, float(v))
                back = float(drive.get_param(name))
            except DriveError as e:
                raise UserError(f"--set: {name}: {e}") from None
            if abs(back - float(v)) > 2.0 ** -p.frac * 1.01 + 1e-12 * abs(float(v)):
                raise UserError(f"--set: {name}: read back {back:g}, wrote {float(v):g}")
        notes.append("params: " + ", ".join(f"{k}={v:g}" for k, v in target.params.items()))
    note = apply_compensators(drive, target.compensators)
    if note:
        notes.append(note)
    return notes


def _start(drive: Drive, lockstep: bool) -> None:
    """NMT start.

    In lock-step the drive's time does not run until the :class:`Bench` sends its first
    SYNCs: the start costs no drive time, so every lock-step procedure starts at tick 0
    and repeats bit for bit (a helper thread that pumped SYNCs until the first TPDO
    arrived used to let a host-timing-dependent number of periods pass here).
    """
    drive.start(wait_tpdo=not lockstep)


@contextlib.contextmanager
def open_bench(target: Target, setup: RigSetup, lockstep: bool = False,
               sync_periods: int = 10) -> Iterator[Bench]:
    """A :class:`Bench` for one procedure; the virtual drive (if any) is always stopped afterwards."""
    if target.virtual:
        pacing = "sync" if lockstep else "fast"
        sets = setup.sets() + [f"{k}={v!r}" if not isinstance(v, bool) else f"{k}={'true' if v else 'false'}"
                               for k, v in target.plant.items()]
        proc = VirtualDriveProcess(target.axis, pacing, sets, sync_periods, target.seed, target.node_id,
                                   target.profile)
        rig: Rig = VirtualRig(proc, setup) if target.profile == "hdservo" else NoRig(setup)
        drive = None
        try:
            drive = Drive.connect(target.node_id, interface="socketcand", channel="can0", host="127.0.0.1",
                                  port=proc.port)
            _start(drive, lockstep)
            b = Bench(drive, rig, lockstep=lockstep, sync_periods=sync_periods)
            for note in configure_drive(drive, target):
                if note not in target.notes:
                    target.notes.append(note)
            yield b
        finally:
            try:
                if drive is not None:
                    try:
                        drive.write(0x6040, 0, 0x00)
                    except DriveError:
                        pass
                    drive.close()
            finally:
                proc.stop()
                rig.close()
    else:
        drive = Drive.connect(target.node_id, **(target.bus or {}))
        try:
            drive.start()
            rig = ManualRig(setup, target.interactive)
            b = Bench(drive, rig, lockstep=False, sync_periods=sync_periods, realtime=True)
            for note in configure_drive(drive, target):
                if note not in target.notes:
                    target.notes.append(note)
            yield b
        finally:
            try:
                drive.write(0x6040, 0, 0x00)
            except DriveError:
                pass
            drive.close()


__all__ = ["Bench", "ManualRig", "Progress", "Rig", "RigError", "RigSetup", "SIG", "Target", "VirtualDriveProcess",
           "VirtualRig", "NoRig", "apply_compensators", "configure_drive", "open_bench"]
