"""Run the identification experiments on a drive over CAN (:mod:`hdservo.drive`).

The experiment designs of :mod:`.experiments` are executed through the CANopen
client and return the same :class:`~.experiments.ExperimentData` columns as the
simulator runner, so every fit works unchanged:

* ``velocity`` segments (friction sweep, TE rotation): CiA 402 cyclic
  synchronous velocity (CSV), one target velocity per segment;
* ``position`` segments (gravity sine): CSV with the derivative of the
  position sine as target velocity, updated every ``setpoint_ticks`` loop
  periods by RPDO3 (the fits use the measured angle, not the reference);
* ``velocity_multisine`` (FRF): the Schroeder multisine of the scenario
  generator (``sim/harness/scenario.c``) computed on the host and sent as
  RPDO3 target velocity every SYNC period; the reference column is the value
  the drive received (G = S_ry/S_ru needs only r, y, u);
* ``locked`` segments (stiffness, FORCs, minor loops): a test-rig feature:
  output brake on, cyclic synchronous torque (CST) ramps by RPDO3 and the rig's
  torque sensor.  On the virtual drive that is ``hdservo-sim serve --rig``
  (brake, reference instruments: the gear's transmitted torque, plus the
  emulated sensor noise/LSB of :class:`~.experiments.SimRunner`).  Without a
  rig these segments run on the simulator binding and the report says so
  (:attr:`DriveRunner.notes`).

Measured signals come from the drive's default stream (TPDO2..4: loop tick +
output phase / motor phase / motor torque every ``stream_ticks`` periods),
joined by loop tick; angles are unwrapped from the 2^-32-turn phases.

Time.  On the virtual drive the runner starts ``hdservo-sim serve --pacing
sync`` and advances the drive by SYNC (``sync_periods`` loop periods each,
several SYNCs in flight for constant segments, one round trip per set-point
change): every experiment is exactly reproducible and independent of the host
load.  On a real drive (free-running) it waits for the streamed loop tick.
"""
from __future__ import annotations

import contextlib
import logging
import math
import os
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Optional, Sequence

import numpy as np

from ..errors import UserError
from .. import progress as progress_mod
from ..pdo import PdoDecoder
from . import experiments as ex

from ..fw_const import LOOP_HZ  # noqa: E402
from ..phase import unwrap_turns  # noqa: E402
from ..units import TURN  # noqa: E402

DT = 1.0 / LOOP_HZ


# ----------------------------------------------------------------- virtual drive process


class VirtualDrive:
    """``hdservo-sim serve`` on an ephemeral loopback port, lock-step pacing; :meth:`stop` always ends it.

    Parameters
    ----------
    axis : str
        ``reference``, ``minimal`` or an axis TOML file.
    seed : int
        Sensor-noise seed of the simulated axis.
    sync_periods : int
        Loop periods (100 us each) per SYNC.
    sets : sequence of str
        ``SECTION.KEY=VALUE`` plant overrides (bench conditions: base motion off).
    pacing : str
        ``sync`` (lock-step, the identification runner) or ``realtime``/``fast``.
    rig : bool
        Ask for the test-rig interface (``--rig``: output brake, reference
        instruments on stdin/stdout).  If the program refuses it, the drive is
        started without and :attr:`rig` is False.
    profile : str
        ``hdservo`` (every object) or ``generic`` (``--profile generic``: CiA 301/402
        standard objects only, vendor accesses refused and logged, never a rig).
    """

    def __init__(self, axis: str = "reference", seed: int = 1, sync_periods: int = 10,
                 sets: Sequence[str] = ("base.enabled=false",), rig: bool = True, node_id: int = 1,
                 pacing: str = "sync", profile: str = "hdservo") -> None:
        from ..serve_proc import find_sim
        from ..serve_proc import ServeError, ServeProcess
        self.sim = find_sim()
        self.node_id = node_id
        self.sync_periods = sync_periods
        base = ["--node-id", str(node_id), "--axis", str(axis), "--pacing", pacing,
                "--sync-periods", str(sync_periods), "--seed", str(seed), "-q"]
        for s in sets:
            base += ["--set", s]
        if profile != "hdservo":
            base += ["--profile", profile]
            rig = False
        self.rig = False
        self.proc: Optional[ServeProcess] = None
        err: Optional[ServeError] = None
        for with_rig in ((True, False) if rig else (False,)):
            try:
                self.proc = ServeProcess(self.sim, base + (["--rig"] if with_rig else []))
            except ServeError as e:
                err = e
                continue
            self.port = self.proc.port
            self.rig = with_rig
            break
        else:
            assert err is not None
            raise UserError(str(err))
        self._tmp: Optional[tempfile.TemporaryDirectory[str]] = tempfile.TemporaryDirectory(
            prefix="hdservo-ident-rig-")

    def rig_cmd(self, line: str, timeout: float = 30.0) -> dict[str, str]:
        """One rig command (serve.c ``--rig``); the fields of its ``ok`` answer."""
        if not self.rig or self.proc is None:
            raise UserError("the virtual drive has no rig interface")
        return self.proc.rig(line, timeout)

    def record_path(self) -> Path:
        assert self._tmp is not None
        return Path(self._tmp.name) / "rig.csv"

    def stop(self) -> str:
        """Terminate the process (SIGTERM, then SIGKILL); returns its stderr."""
        out = self.proc.stop() if self.proc is not None else ""
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
        return out


@contextlib.contextmanager
def chosen_drive(choice: Any, node_id: int) -> Iterator[Any]:
    """The drive a :class:`hdservo.drive.DriveChoice` names, connected; closed afterwards.

    Without a bus in the choice a simulated drive of its axis and profile is started
    (realtime pacing, no test rig) and stopped again, whatever happens inside.

    Raises
    ------
    hdservo.drive.DriveError
        The drive does not answer.
    """
    from ..drive import Drive
    vd = None
    drive = None
    try:
        bus = choice.bus
        if bus is None:
            vd = VirtualDrive(axis=choice.axis or "reference", rig=False, node_id=node_id, pacing="realtime",
                              profile=choice.profile)
            bus = {"interface": "socketcand", "channel": "can0", "host": "127.0.0.1", "port": vd.port}
        drive = Drive.connect(node_id, **bus)
        yield drive
    finally:
        if drive is not None:
            drive.close()
        if vd is not None:
            vd.stop()


# ----------------------------------------------------------------- stream collector


class _Stream:
    """Collects the default stream (load phase, motor phase, motor torque, each with the loop tick) by tick.

    Frames are decoded by the EDS's TPDO maps (:class:`hdservo.pdo.PdoDecoder`).
    """

    #: streamed object (EDS name) -> column of the collected data
    SIGNALS = {"load_phase": "load", "motor_phase": "motor", "motor_torque": "torque"}

    def __init__(self, decoder: "PdoDecoder") -> None:
        import can
        self.data: dict[str, list[tuple[int, int]]] = {k: [] for k in self.SIGNALS.values()}
        self.last_tick = -1
        self.cond = threading.Condition()
        self.on = False
        outer = self

        class L(can.Listener):
            def on_message_received(self, m: Any) -> None:
                fr = decoder.decode(m.arbitration_id, bytes(m.data))
                if fr is None:
                    return
                hit = [(col, fr.values[obj]) for obj, col in outer.SIGNALS.items() if obj in fr.values]
                if not hit:
                    return
                name, val = hit[0]
                tick = fr.tick
                with outer.cond:
                    if outer.on:
                        outer.data[name].append((tick, val))
                    if name == "load":
                        outer.last_tick = tick
                        outer.cond.notify_all()

        self.listener = L()

    def start(self) -> None:
        with self.cond:
            for v in self.data.values():
                v.clear()
            self.on = True

    def stop(self) -> dict[str, np.ndarray]:
        """Stop recording; returns tick-joined raw arrays ``tick``, ``load``, ``motor``, ``torque``."""
        with self.cond:
            self.on = False
            d = {k: np.array(v, dtype=np.int64).reshape(-1, 2) for k, v in self.data.items()}
        ticks = d["load"][:, 0]
        for k in ("motor", "torque"):
            ticks = np.intersect1d(ticks, d[k][:, 0])
        out: dict[str, np.ndarray] = {"tick": ticks}
        for k, v in d.items():
            _, idx = np.unique(v[:, 0], return_index=True)
            u = v[idx]
            pos = np.searchsorted(u[:, 0], ticks)
            out[k] = u[pos, 1]
        return out

    def wait_tick(self, tick: int, timeout: float) -> bool:
        end = time.monotonic() + timeout
        with self.cond:
            while self.last_tick < tick:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self.cond.wait(min(left, 0.2))
        return True


def schroeder_multisine(t: np.ndarray, f0: float, f1: float, lines: int) -> np.ndarray:
    """Unit-RMS-per-line Schroeder multisine of the scenario generator: sum_k sin(2 pi f_k t - pi k (k+1)/n) / sqrt(n)."""
    y = np.zeros_like(t, dtype=float)
    for k in range(lines):
        f = f0 if lines == 1 else f0 + (f1 - f0) * k / (lines - 1)
        y += np.sin(2 * math.pi * f * t - math.pi * k * (k + 1) / lines)
    return y / math.sqrt(lines)


# ----------------------------------------------------------------- the runner


def locked_setpoints(turning_points: Sequence[float], rate_Nm_s: float, dt_s: float, lsb_Nm: float,
                     dwell_s: float = 0.05) -> np.ndarray:
    """Torque set-points of a locked-output profile, turning points on the CAN set-point grid.

    The target torque travels in steps of ``lsb_Nm`` (1/1000 of the rated torque).  A turning
    point between two steps -- half a step is common: the friction shift is a median of an even
    number of samples -- lets the last ramp sample and the dwell at the same point round to
    neighbouring steps, and the command reverses by one step at the turning point; the fits
    (``hysteresis.split_reversals``) then see an extra reversal and the stretch through T = 0 is cut
    in two.  On the grid, every ramp sample rounds between its two turning points.

    Parameters
    ----------
    turning_points : sequence of float
        Turning points, N.m (output side), the profile starting from 0.
    rate_Nm_s, dt_s : float
        Ramp rate (N.m/s) and set-point period (s).
    lsb_Nm : float
        Set-point step, N.m (> 0).
    dwell_s : float
        Hold at each turning point, s.

    Returns
    -------
    numpy.ndarray
        Set-points, one per ``dt_s``.
    """
    pts = [round(float(p) / lsb_Nm) * lsb_Nm for p in turning_points]
    return ex.triangle_profile(pts, rate_Nm_s, dt_s, dwell_s=dwell_s)


@dataclass
class DriveRunner:
    """Run experiment designs on a drive (real or virtual) over CAN.

    Parameters
    ----------
    drive : hdservo.drive.Drive
        Connected client (NMT state is set by :meth:`open`).
    lockstep : bool
        The drive advances only on SYNC (virtual drive ``--pacing sync``).
    sync_periods : int
        Loop periods per SYNC (lock-step); also the set-point period of the
        multisine.
    stream_ticks : int
        Loop periods per streamed sample (sample period = stream_ticks x 100 us).
    virtual : VirtualDrive, optional
        The virtual drive process (its rig for the locked-output segments).
    locked_fallback : SimRunner, optional
        Runs the locked-output segments on the simulator binding when there is
        no rig (noted in :attr:`notes`).
    progress : callable, optional
        ``progress(message)``.
    torque_sensor_noise_Nm, torque_sensor_lsb_Nm : float
        Emulated rig torque sensor on the virtual rig (as the simulator runner).
    seed : int
        Seed of the emulated sensor noise.
    """

    drive: Any
    lockstep: bool = True
    sync_periods: int = 10
    stream_ticks: int = 10
    virtual: Optional[VirtualDrive] = None
    locked_fallback: Optional[ex.SimRunner] = None
    progress: Optional[Callable[[str], None]] = None
    torque_sensor_noise_Nm: float = 0.01
    torque_sensor_lsb_Nm: float = 0.005
    seed: int = 1
    setpoint_ticks_position: int = 50
    setpoint_ticks_locked: int = 20
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._stream = _Stream(self.drive.pdo)
        self.drive.network.notifier.add_listener(self._stream.listener)
        self._tick = 0          # the drive's loop tick the host believes in (lock-step: exact)
        self._ratio: Optional[float] = None
        self._rated: Optional[float] = None
        self._cal: Optional[tuple[float, float]] = None
        self._last_torque = 0.0   # the last locked torque set-point sent (N.m, output side)
        self._gains_before: dict[str, float] = {}   # the drive's own gains, restored by close()

    # -- lifecycle ----------------------------------------------------------
    def open(self) -> None:
        """NMT start, stream configured, TPDO1 synchronous.

        In lock-step the start costs no drive time (no TPDO is awaited), and then a fixed 3
        SYNCs let the 402 state machine leave NOT READY TO SWITCH ON, so the experiments start
        at the same tick whatever the host's timing (a thread that pumped SYNCs until the
        first TPDO used to let a random number of periods pass).
        """
        d = self.drive
        d.start(wait_tpdo=not self.lockstep)
        d.configure_stream(self.stream_ticks)
        self._tick = int(d.read(0x5F00, 11))
        if self.lockstep:
            self._advance(3 * self.sync_periods)
        self._ratio = float(d.get_param("gear_ratio"))
        self._rated = float(d.read(0x6076)) / 1000.0

    def commissioned_inertia_kgm2(self) -> float:
        """The drive's commissioned total inertia ``j_total`` (J_L + N^2 J_m), kg.m^2."""
        return float(self.drive.get_param("j_total"))

    def torque_limit_Nm(self) -> float:
        """The drive's torque limit ``torque_limit`` (output side), N.m."""
        return float(self.drive.get_param("torque_limit"))

    def set_gains(self, gains: Mapping[str, float]) -> None:
        """Set drive gains for the following experiments; :meth:`close` restores the drive's own values."""
        for k, v in gains.items():
            if k not in self._gains_before:
                self._gains_before[k] = float(self.drive.get_param(k))
            self.drive.set_param(k, float(v))

    def close(self) -> None:
        """Power stage off, the drive's own gains back, detach (the caller closes the bus)."""
        try:
            self.drive.write(0x6040, 0, 0x00)
            self._advance(self.sync_periods)
        except Exception:       # noqa: BLE001 - best effort on the way out
            pass
        for k, v in self._gains_before.items():
            try:
                self.drive.set_param(k, v)
            except Exception:   # noqa: BLE001 - best effort on the way out
                pass
        try:
            self.drive.network.notifier.remove_listener(self._stream.listener)
        except (ValueError, AttributeError):
            pass

    def _say(self, msg: str) -> None:
        if self.progress:
            self.progress(msg)

    def _segment_progress(self, label: str) -> Callable[[float], None]:
        """Progress through one segment, ``f(fraction)``: a tqdm bar on a terminal (while the
        ``hdservo.progress`` logger shows INFO, i.e. not under ``-q``), else ``label: N %`` lines
        through the progress callback."""
        if not self.progress:
            return lambda frac: None
        if progress_mod.on_terminal():
            return progress_mod.Fraction(f"identify {label}",
                                         enabled=progress_mod.LOG.isEnabledFor(logging.INFO))
        return lambda frac: self._say(f"{label}: {int(round(100 * frac))} %")

    @staticmethod
    def _segment_done(bar: Callable[[float], None]) -> None:
        """End a terminal bar of :meth:`_segment_progress` (the log lines have no end line)."""
        if isinstance(bar, progress_mod.Fraction):
            bar(1.0)

    def ratio(self) -> float:
        assert self._ratio is not None, "open() first"
        return self._ratio

    # -- drive time ------------------------------------------------------------
    def _sync_burst(self, n: int) -> None:
        for _ in range(n):
            self.drive.network.send_message(0x80, b"")

    def _advance(self, ticks: int, burst: int = 40) -> None:
        """Let ``ticks`` loop periods of drive time pass (lock-step: SYNCs; else wait for the stream)."""
        from ..drive import DriveError
        if ticks <= 0:
            return
        if self.lockstep:
            n = -(-ticks // self.sync_periods)
            while n > 0:
                k = min(burst, n)
                self._sync_burst(k)
                self._tick += k * self.sync_periods
                n -= k
                if not self._stream.wait_tick(self._tick - self.stream_ticks, 10.0):
                    raise DriveError(f"the drive stopped streaming (last tick {self._stream.last_tick}, "
                                     f"expected {self._tick}); is it in --pacing sync?")
        else:
            target = self._stream.last_tick + ticks
            if not self._stream.wait_tick(target, ticks * DT * 5 + 5.0):
                raise DriveError(f"the drive stopped streaming (last tick {self._stream.last_tick})")
            self._tick = self._stream.last_tick

    def _wait_state(self, want: str) -> None:
        from ..drive import DriveError
        for _ in range(200):
            st = self.drive.state()
            if st == want:
                return
            self._advance(self.sync_periods)
        raise DriveError(f"drive did not reach {want} (state {self.drive.state()}, fault "
                         f"{int(self.drive.read(0x5F00, 10))})")

    def _enable(self, mode: str) -> None:
        from ..drive import DriveError
        d = self.drive
        if d.state() == "FAULT":
            d.fault_reset() if not self.lockstep else self._fault_reset()
        try:        # drive time passes after each controlword and between the polls (200 at most)
            d.enable(mode, settle=lambda: self._advance(self.sync_periods), timeout=4.0)
        except DriveError as e:
            raise DriveError(f"{e}, fault {int(d.read(0x5F00, 10))}") from None

    def _fault_reset(self) -> None:
        self.drive.write(0x6040, 0, 0x00)
        self._advance(self.sync_periods)
        self.drive.write(0x6040, 0, 0x80)
        self._advance(self.sync_periods)

    def _disable(self) -> None:
        self.drive.write(0x6040, 0, 0x00)
        self._advance(self.sync_periods)

    def _check_fault(self, what: str) -> None:
        code = int(self.drive.read(0x5F00, 10))
        if code:
            raise UserError(f"drive experiment '{what}': drive fault {code} (0x5F00:10) at tick {self._tick}")

    # -- set-points ---------------------------------------------------------------
    def _rpdo3(self, vel_rad_s: float = 0.0, torque_Nm: float = 0.0) -> tuple[float, float]:
        """RPDO3 (target velocity 2^-32 turn/s, target torque per mille of rated); returns the quantised values."""
        vraw = int(round(vel_rad_s / TURN * 2 ** 32))
        rated = self._rated or 67.0
        pm = max(-32768, min(32767, int(round(torque_Nm / rated * 1000.0))))
        self.drive.network.send_message(*self.drive.pdo.encode(3, target_velocity=vraw, target_torque=pm))
        return vraw * TURN / 2 ** 32, pm * rated / 1000.0

    def _profile(self, values: Sequence[float], every_ticks: int, send: Callable[[float], tuple[float, float]],
                 label: str) -> np.ndarray:
        """Send one set-point per ``every_ticks`` loop periods; returns (tick, velocity, torque) rows applied."""
        every = max(self.sync_periods, (every_ticks // self.sync_periods) * self.sync_periods)
        rows = np.zeros((len(values), 3))
        t0 = time.monotonic()
        n = len(values)
        step = max(1, n // 10)
        bar = self._segment_progress(label)
        for k, v in enumerate(values):
            if not self.lockstep:
                due = t0 + k * every * DT
                wait = due - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            vq, tq = send(float(v))
            rows[k] = (self._tick, vq, tq)
            self._advance(every, burst=every // self.sync_periods)
            if k % step == 0 and k:
                bar((100 * k // n) / 100.0)
        self._segment_done(bar)
        return rows

    # -- experiments -----------------------------------------------------------------------
    def _columns(self, raw: dict[str, np.ndarray], t_first_tick: int) -> dict[str, np.ndarray]:
        N = self.ratio()
        tick = raw["tick"].astype(np.int64)
        return {"t_s": (tick - t_first_tick) * DT,
                "motor_angle_rad": unwrap_turns(raw["motor"]) * TURN,
                "load_angle_rad": unwrap_turns(raw["load"]) * TURN,
                "motor_torque_Nm": raw["torque"].astype(np.int64).astype(np.int32).astype(float) / 65536.0,
                "_tick": tick.astype(float), "_N": np.full(len(tick), N)}

    @staticmethod
    def _hold(rows: np.ndarray, ticks: np.ndarray, col: int) -> np.ndarray:
        """Value of the set-point in force at each tick (applied from the period after ``rows[:, 0]``)."""
        if len(rows) == 0:
            return np.zeros(len(ticks))
        i = np.searchsorted(rows[:, 0], ticks - 1, side="right") - 1
        return np.where(i >= 0, rows[np.clip(i, 0, None), col], 0.0)

    def _velocity_segment(self, seg: Mapping[str, Any], label: str) -> dict[str, np.ndarray]:
        v = float(seg["velocity_rad_s"])
        dur = float(seg["settle_s"]) + float(seg["window_s"])
        start = self._tick
        self._stream.start()
        rows = np.array([[self._tick, *self._rpdo3(vel_rad_s=v)]])
        total = int(round(dur * LOOP_HZ))
        chunk = max(1, int(round(0.25 * total)))
        done = 0
        bar = self._segment_progress(label)
        while done < total:
            k = min(chunk, total - done)
            self._advance(k)
            done += k
            if done < total:
                bar((100 * done // total) / 100.0)
        self._segment_done(bar)
        raw = self._stream.stop()
        cols = self._columns(raw, start)
        cols["torque_cmd_Nm"] = cols["motor_torque_Nm"] * self.ratio()
        cols["setpoint_velocity_rad_s"] = self._hold(rows, raw["tick"], 1)
        return cols

    def _gravity_segment(self, seg: Mapping[str, Any], label: str) -> dict[str, np.ndarray]:
        a, f, dur = float(seg["amplitude_rad"]), float(seg["frequency_Hz"]), float(seg["duration_s"])
        every = self.setpoint_ticks_position
        t = np.arange(int(round(dur * LOOP_HZ / every))) * every * DT + 0.5 * every * DT
        vel = a * 2 * math.pi * f * np.cos(2 * math.pi * f * t)
        start = self._tick
        self._stream.start()
        rows = self._profile(vel, every, lambda x: self._rpdo3(vel_rad_s=x), label)
        raw = self._stream.stop()
        cols = self._columns(raw, start)
        cols["torque_cmd_Nm"] = cols["motor_torque_Nm"] * self.ratio()
        cols["setpoint_velocity_rad_s"] = self._hold(rows, raw["tick"], 1)
        return cols

    def _multisine_segment(self, seg: Mapping[str, Any], label: str) -> dict[str, np.ndarray]:
        bias, amp = float(seg["bias_rad_s"]), float(seg["amplitude_rad_s"])
        settle, dur = float(seg["settle_s"]), float(seg["duration_s"])
        every = self.sync_periods
        t = np.arange(int(round(dur * LOOP_HZ / every))) * every * DT
        tau = t - settle
        ms = schroeder_multisine(np.maximum(tau, 0.0), float(seg["f0_Hz"]), float(seg["f1_Hz"]), int(seg["lines"]))
        vel = bias + np.where(tau >= 0, amp * ms, 0.0)
        start = self._tick
        self._stream.start()
        rows = self._profile(vel, every, lambda x: self._rpdo3(vel_rad_s=x), label)
        raw = self._stream.stop()
        cols = self._columns(raw, start)
        cols["torque_cmd_Nm"] = cols["motor_torque_Nm"] * self.ratio()
        cols["setpoint_velocity_rad_s"] = self._hold(rows, raw["tick"], 1)
        return cols

    # -- locked output (rig) ----------------------------------------------------------
    def has_rig(self) -> bool:
        """True when the locked-output segments can run on the drive (virtual drive with ``--rig``)."""
        return self.virtual is not None and self.virtual.rig

    def _rig_torque(self, rec: Path, ticks: np.ndarray, seed: int) -> np.ndarray:
        data = np.atleast_1d(np.genfromtxt(rec, delimiter=",", names=True))
        if data.size < 2 or "gear_torque_Nm" not in (data.dtype.names or ()):
            raise UserError("virtual rig: the reference-instrument record has no gear torque")
        ts = np.interp(ticks, data["tick"].astype(float), data["gear_torque_Nm"].astype(float))
        rng = np.random.default_rng(seed + 7919)
        ts = ts + rng.normal(0.0, self.torque_sensor_noise_Nm, len(ts))
        if self.torque_sensor_lsb_Nm > 0:
            ts = np.round(ts / self.torque_sensor_lsb_Nm) * self.torque_sensor_lsb_Nm
        return ts

    def _locked_profile(self, profile: np.ndarray, every: int, label: str, seed: int) -> dict[str, np.ndarray]:
        assert self.virtual is not None
        rec = self.virtual.record_path()
        start = self._tick
        self._stream.start()
        self.virtual.rig_cmd(f"record {rec} {self.stream_ticks}")
        try:
            rows = self._profile(profile, every, lambda x: self._rpdo3(torque_Nm=x), label)
        finally:
            self.virtual.rig_cmd("record stop")
        raw = self._stream.stop()
        self._last_torque = float(rows[-1, 2]) if len(rows) else self._last_torque
        cols = self._columns(raw, start)
        cols["torque_cmd_Nm"] = self._hold(rows, raw["tick"], 2)
        cols["load_torque_Nm"] = self._rig_torque(rec, raw["tick"].astype(float), seed)
        return cols

    def _ramp_to_zero(self, rate: float) -> None:
        """Ramp the torque set-point from the last profile's end to 0 at ``rate`` (N.m/s), not recorded.

        Every locked profile starts at 0 N.m, as on the simulator binding (a fresh plant per
        segment); without this the friction calibration (ending at +amplitude) or a FORC set
        (ending at -Tf) would be followed by a set-point step of tens of N.m.
        """
        if abs(self._last_torque) < 1e-9:
            return
        every = self.setpoint_ticks_locked
        prof = ex.triangle_profile([0.0], rate, every * DT, start=self._last_torque, dwell_s=0.05)[1:]
        self._profile(prof, every, lambda x: self._rpdo3(torque_Nm=x), "locked: back to 0 N.m")
        self._last_torque = 0.0

    def _calibrate_friction(self, amp: float, seed: int) -> tuple[float, float]:
        """Input friction on rising/falling stretches of a locked triangle (as experiments._compensate_friction)."""
        if self._cal is None:
            every = self.setpoint_ticks_locked
            cal = ex.triangle_profile([amp, -amp, amp], amp * 2.0, every * DT)
            c = self._locked_profile(cal, every, "locked: friction calibration", seed + 104729)
            d = c["torque_cmd_Nm"] - c["load_torque_Nm"]
            slope = np.gradient(c["torque_cmd_Nm"])
            up, dn = d[slope > 0], d[slope < 0]
            self._cal = (float(np.median(up)) if len(up) else 0.0, float(np.median(dn)) if len(dn) else 0.0)
        return self._cal

    def _locked_segments(self, design: Any, plan: list[dict[str, Any]]) -> list[tuple[dict[str, np.ndarray],
                                                                                       dict[str, Any]]]:
        assert self.virtual is not None
        d = self.drive
        tmax = 0.0
        for seg in plan:
            pts = seg.get("turning_points_Nm") or [seg["torque_amplitude_Nm"]]
            tmax = max(tmax, max(abs(float(p)) for p in pts))
        old = {k: d.get_param(k) for k in ("torque_limit", "torque_sat_time")}
        parts = []
        self.virtual.rig_cmd("brake 1")
        try:
            d.set_param("torque_limit", min(1000.0, max(old["torque_limit"], 1.5 * tmax + 10.0)))
            d.set_param("torque_sat_time", 1e6)
            self._enable("CYCLIC SYNCHRONOUS TORQUE")
            self._advance(500)
            for i, seg in enumerate(plan):
                seed = self.seed + i
                label = f"{design.kind}: segment {i + 1}/{len(plan)} {ex._seg_label(seg)}"
                self._say(label)
                pts = (seg["turning_points_Nm"] if "turning_points_Nm" in seg
                       else ex.cycle_points(seg["torque_amplitude_Nm"], seg["cycles"]))
                shifted = [float(p) for p in pts]
                if seg.get("friction_shift", True):
                    f = self._calibrate_friction(max(max(abs(float(p)) for p in pts), 1.0), seed)
                    shifted, prev = [], 0.0
                    for p in pts:
                        shifted.append(float(p) + (f[0] if p > prev else f[1]))
                        prev = float(p)
                every = self.setpoint_ticks_locked
                self._ramp_to_zero(float(seg["rate_Nm_s"]))
                prof = locked_setpoints(shifted, float(seg["rate_Nm_s"]), every * DT, (self._rated or 67.0) / 1000.0)
                parts.append((self._locked_profile(prof, every, label, seed), seg))
                self._check_fault(design.kind)
            self._ramp_to_zero(float(plan[-1]["rate_Nm_s"]))
            self._rpdo3(torque_Nm=0.0)
            self._advance(200)
        finally:
            self._last_torque = 0.0
            try:
                self._disable()
                for k, v in old.items():
                    d.set_param(k, v)
            finally:
                self.virtual.rig_cmd("brake 0")
        return parts

    def run(self, design: Any) -> ex.ExperimentData:
        """Run one design and return its data (same columns as :class:`~.experiments.SimRunner`)."""
        N = self.ratio()
        plan = design.plan(N)
        meta = {"gear_ratio": N, "sample_period_s": self.stream_ticks * DT,
                "source": "virtual drive over CAN" if self.virtual else "drive over CAN",
                "design": ex.describe(design), "stream_ticks": self.stream_ticks,
                "lockstep": self.lockstep}
        if any(s["mode"] == "locked" for s in plan):
            if not self.has_rig():
                if self.locked_fallback is None:
                    raise UserError(f"{design.kind}: needs the output locked and a torque sensor (a test rig); "
                                    "this drive has no rig interface -- record the test on a rig and use --data")
                note = (f"{design.kind}: no rig interface on the drive; the locked-output experiment ran on "
                        "the simulator binding")
                if note not in self.notes:
                    self.notes.append(note)
                self._say(note)
                d = self.locked_fallback.run(design)
                d.meta["source"] = "simulator binding (no rig on the drive)"
                return d
            parts = self._locked_segments(design, plan)
            meta["locked_output"] = "virtual rig (serve --rig): brake, gear torque + emulated sensor"
            return self._finish(design, parts, meta)
        parts = []
        self._enable("CYCLIC SYNCHRONOUS VELOCITY")
        try:
            self._advance(200)
            for i, seg in enumerate(plan):
                label = f"{design.kind}: segment {i + 1}/{len(plan)} {ex._seg_label(seg)}"
                self._say(label)
                mode = seg["mode"]
                if mode == "velocity":
                    cols = self._velocity_segment(seg, label)
                elif mode == "position":
                    cols = self._gravity_segment(seg, label)
                    self._rpdo3(vel_rad_s=0.0)
                    self._advance(2000)
                elif mode == "velocity_multisine":
                    # alternate the bias direction: the output stays inside its travel
                    seg = {**seg, "bias_rad_s": float(seg["bias_rad_s"]) * (1 if i % 2 == 0 else -1)}
                    cols = self._multisine_segment(seg, label)
                else:  # pragma: no cover - designs are ours
                    raise ValueError(mode)
                self._check_fault(design.kind)
                parts.append((cols, seg))
            self._rpdo3(vel_rad_s=0.0)
            self._advance(2000)
        finally:
            self._disable()
        return self._finish(design, parts, meta)

    def _finish(self, design: Any, parts: list[tuple[dict[str, np.ndarray], dict[str, Any]]],
                meta: dict[str, Any]) -> ex.ExperimentData:
        clean = []
        for cols, seg in parts:
            c = {k: v for k, v in cols.items() if not k.startswith("_")}
            if len(c["t_s"]) < 10:
                raise UserError(f"{design.kind}: the drive streamed fewer than 10 samples in a segment")
            clean.append((c, seg))
        # every segment needs the same columns
        names = set.intersection(*(set(c) for c, _ in clean))
        clean = [({k: v for k, v in c.items() if k in names}, s) for c, s in clean]
        return ex.concat(design.kind, clean, meta)


# ----------------------------------------------------------------- opening


class DriveSession:
    """Context manager: a connected, started :class:`DriveRunner`; the virtual drive (if any) always stops.

    Parameters
    ----------
    bus : dict, optional
        python-can settings (``interface``, ``channel``, ``bitrate``, socketcand
        ``host``/``port``).  None = start a virtual drive of ``axis``.
    node_id : int
        CANopen node id.
    axis : str
        Axis of the virtual drive (``reference``, ``minimal`` or TOML path).
    seed : int
        Noise seed of the virtual drive and the emulated torque sensor.
    progress : callable, optional
    rig : bool
        Use the virtual drive's rig interface for the locked-output tests
        (False: those run on the simulator binding, noted in the report).
    sync_periods, stream_ticks : int
        See :class:`DriveRunner`.
    """

    def __init__(self, bus: Optional[dict[str, Any]] = None, node_id: int = 1, axis: str = "reference", seed: int = 1,
                 progress: Optional[Callable[[str], None]] = None, rig: bool = True, sync_periods: int = 10,
                 stream_ticks: int = 10, gains: Optional[Mapping[str, float]] = None,
                 profile: str = "hdservo") -> None:
        self.bus, self.node_id, self.axis, self.seed = bus, node_id, axis, seed
        self.profile = profile
        self.progress, self.rig, self.sync_periods, self.stream_ticks = progress, rig, sync_periods, stream_ticks
        self.gains = dict(gains or {})
        self.vd: Optional[VirtualDrive] = None
        self.drive: Any = None
        self.runner: Optional[DriveRunner] = None

    def __enter__(self) -> DriveRunner:
        from ..drive import Drive, DriveError
        try:
            if self.bus is None:
                if self.progress:
                    self.progress(f"starting the virtual drive (axis {self.axis}, lock-step pacing)")
                axis = self.axis if self.axis in ("reference", "minimal") else str(Path(self.axis).resolve())
                if axis not in ("reference", "minimal") and not Path(axis).is_file():
                    raise UserError(f"{self.axis}: axis file not found")
                self.vd = VirtualDrive(axis=axis, seed=self.seed, sync_periods=self.sync_periods, rig=self.rig,
                                       node_id=self.node_id, profile=self.profile)
                self.drive = Drive.connect(self.node_id, interface="socketcand", channel="can0", host="127.0.0.1",
                                           port=self.vd.port)
            else:
                self.drive = Drive.connect(self.node_id, **self.bus)
            from ..drive_caps import check
            check(self.drive, "identify")
            fallback = None
            if self.bus is None:
                fallback = ex.SimRunner(axis=self.axis, seed=self.seed, progress=self.progress, gains=self.gains)
            r = DriveRunner(self.drive, lockstep=self.bus is None, sync_periods=self.sync_periods,
                            stream_ticks=self.stream_ticks, virtual=self.vd, locked_fallback=fallback,
                            progress=self.progress, seed=self.seed)
            r.open()
            for k, v in self.gains.items():
                self.drive.set_param(k, v)
            if self.vd is not None and not self.vd.rig:
                r.notes.append("the virtual drive has no --rig interface: locked-output experiments run on the "
                               "simulator binding")
            self.runner = r
            return r
        except DriveError as e:
            self.__exit__(None, None, None)
            raise UserError(f"drive: {e}") from None
        except BaseException:
            self.__exit__(None, None, None)
            raise

    def __exit__(self, *exc: object) -> None:
        try:
            if self.runner is not None:
                self.runner.close()
            if self.drive is not None:
                self.drive.close()
        finally:
            if self.vd is not None:
                self.vd.stop()
                self.vd = None


__all__ = ["DriveRunner", "DriveSession", "VirtualDrive", "locked_setpoints", "schroeder_multisine", "unwrap_turns"]
