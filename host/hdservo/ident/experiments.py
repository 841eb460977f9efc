"""Identification experiments: defined once, run on the simulator now and on a drive later.

Every experiment is a small dataclass holding its design (speeds, torque
levels, excitation) and produces an :class:`ExperimentData`: log columns
with SI suffixes (the log format of docs/sim.md) cut into *segments* (one per
constant-velocity point, torque cycle, ...) plus metadata.  The same data
can be written as a log (CSV + JSON sidecar, :mod:`hdservo.logio`) and read
back for ``hdservo identify --data LOG.csv``.

Runners execute the designs:

* :class:`SimRunner` -- the simulator through :mod:`hdservo.sim`.  Closed-loop
  experiments (velocity / torque modes) go through the firmware application
  (scenario files written on the fly); locked-output experiments use the
  plant alone with the output clamped (``load.jl_kgm2`` = 1e9 kg.m^2, i.e. a
  fixture; base still) and a rig torque sensor between gear and clamp
  (transmitted torque + white noise + ADC quantisation, emulated here).
* :class:`.drive_runner.DriveRunner` -- a drive over CAN (:mod:`hdservo.drive`):
  the bus the caller gives, or a virtual drive it starts (:func:`drive_runner`, ``bus=None``;
  ``hdservo identify --sim``).

Bench conditions for every experiment: base motion off (the axis is on a
still bench); everything else as the axis file says.
"""
from __future__ import annotations

import math
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .. import logio
from ..errors import UserError
from ..tomltext import basic_string

#: Firmware loop period, s.
LOOP_S = 1e-4
#: Clamp inertia used to lock the output in the simulator, kg.m^2.
CLAMP_INERTIA_KGM2 = 1e9


# ----------------------------------------------------------------- data


@dataclass
class ExperimentData:
    """Recorded data of one experiment.

    Attributes
    ----------
    kind : str
        Experiment name (``friction_sweep``, ``gravity_sine``, ``te_rotation``,
        ``locked_cycle``, ``forc``, ``minor_loops``, ``frf``).
    columns : dict of str to numpy.ndarray
        Log columns (SI suffix in every name), ``segment_code`` = segment index.
    meta : dict
        Gear ratio, sample period (s), the experiment design, per-segment
        descriptions under ``segments`` (list of dicts).
    """

    kind: str
    columns: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise UserError(f"{self.kind} data: no column '{name}' (have: {', '.join(self.columns)})") from None

    @property
    def segments(self) -> list[dict[str, Any]]:
        """Per-segment descriptions (``index`` = value of ``segment_code``)."""
        return [_Fields(f"{self.kind} data: segment {s.get('index')}", s) for s in self.meta.get("segments", [])]

    def segment(self, i: int) -> dict[str, np.ndarray]:
        """Columns restricted to segment ``i`` (a missing column is a UserError naming it)."""
        m = self.columns["segment_code"] == i
        return _Fields(f"{self.kind} data", {k: v[m] for k, v in self.columns.items()})

    @property
    def gear_ratio(self) -> float:
        return float(self.meta["gear_ratio"])

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write as an hdservo log (CSV + sidecar), atomically."""
        cols = dict(self.columns)
        # a log needs strictly increasing time: segments are concatenated with their own clocks
        t = np.asarray(cols["t_s"], dtype=float)
        if np.any(np.diff(t) <= 0):
            dt = float(self.meta.get("sample_period_s", LOOP_S))
            cols["t_s"] = np.arange(len(t)) * dt
            cols["segment_time_s"] = t
        cols = {"t_s": cols.pop("t_s"), **cols}
        meta = {**self.meta, "experiment": self.kind, "source": self.meta.get("source", "hdservo identify")}
        logio.write_log(path, cols, meta)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "ExperimentData":
        """Read a log written by :meth:`save` (or a drive capture in the same form)."""
        log = logio.read_log(path)
        kind = log.meta.get("experiment")
        if not isinstance(kind, str):
            raise UserError(f"{logio.sidecar_path(path)}: expected key \"experiment\" naming the "
                            f"identification experiment (one of {', '.join(EXPERIMENTS)})")
        if kind not in EXPERIMENTS:
            raise UserError(f"{logio.sidecar_path(path)}: \"experiment\": expected one of "
                            f"{', '.join(EXPERIMENTS)}, found '{kind}'")
        cols = dict(log.columns)
        if "segment_time_s" in cols:
            cols["t_s"] = cols.pop("segment_time_s")
        if "segment_code" not in cols:
            cols["segment_code"] = np.zeros(len(cols["t_s"]))
        _check_segments(Path(path), kind, cols["segment_code"], log.meta)
        return cls(kind=kind, columns=cols, meta=dict(log.meta))


class _Fields(dict):  # type: ignore[type-arg]
    """A dict whose missing key is a one-line UserError naming what lacks it (logs given with --data)."""

    def __init__(self, what: str, items: Mapping[str, Any]) -> None:
        super().__init__(items)
        self.what = what

    def __missing__(self, key: str) -> Any:
        raise UserError(f"{self.what}: expected '{key}', have {', '.join(map(str, self)) or 'nothing'}")


def _check_segments(path: Path, kind: str, code: np.ndarray, meta: Mapping[str, Any]) -> None:
    """The sidecar's ``segments`` against the log's ``segment_code`` (UserError: one line naming the file).

    Each segment is an object with an integer ``index`` >= 0, the others numbers, strings or
    booleans; every index has samples and every ``segment_code`` value is a listed index.
    """
    side = logio.sidecar_path(path)
    codes = np.unique(code)
    if codes.size and (np.any(codes != np.round(codes)) or np.any(codes < 0)):
        raise UserError(f"{path}: column 'segment_code': expected segment indices (integers >= 0)")
    if "segments" not in meta:
        return
    segs = meta["segments"]
    if not isinstance(segs, list) or not segs:
        raise UserError(f"{side}: key \"segments\": expected a non-empty array of objects")
    seen: set[int] = set()
    for j, s in enumerate(segs):
        if not isinstance(s, dict):
            raise UserError(f"{side}: \"segments\"[{j}]: expected an object, found {json_text(s)}")
        i = s.get("index")
        if isinstance(i, bool) or not isinstance(i, int) or i < 0 or i in seen:
            raise UserError(f"{side}: \"segments\"[{j}] \"index\": expected a new integer >= 0, found {json_text(i)}")
        seen.add(i)
        for k, v in s.items():
            if isinstance(v, (str, bool, list, dict)) or (isinstance(v, int) and abs(v) < 2 ** 63) \
                    or (isinstance(v, float) and math.isfinite(v)):
                continue
            raise UserError(f"{side}: \"segments\"[{j}] \"{k}\": expected a finite number or a string, "
                                f"found {json_text(v)}")
    have = {int(c) for c in codes}
    if have - seen:
        raise UserError(f"{path}: segment_code {min(have - seen)} is not a segment of {side} "
                        f"(listed: {sorted(seen)})")
    if seen - have:
        raise UserError(f"{path}: segment {min(seen - have)} listed in {side} has no samples")


def json_text(v: Any) -> str:
    """Short JSON-like text of a value for a message."""
    s = repr(v)
    return s if len(s) <= 40 else s[:37] + "..."


def concat(kind: str, parts: Sequence[tuple[dict[str, np.ndarray], dict[str, Any]]],
           meta: Mapping[str, Any]) -> ExperimentData:
    """Join segments (columns, description) into one :class:`ExperimentData`."""
    names = list(parts[0][0])
    cols: dict[str, list[np.ndarray]] = {k: [] for k in names}
    segs = []
    for i, (c, d) in enumerate(parts):
        n = len(c["t_s"])
        for k in names:
            cols[k].append(np.asarray(c[k], dtype=float))
        cols.setdefault("segment_code", []).append(np.full(n, float(i)))
        segs.append({"index": i, **d})
    out = {k: np.concatenate(v) for k, v in cols.items()}
    return ExperimentData(kind=kind, columns=out, meta={**dict(meta), "segments": segs})


# ----------------------------------------------------------------- designs


@dataclass
class FrictionSweep:
    """Constant-velocity sweep, both directions, log-spaced speeds (velocity mode).

    Each point: settle, then a steady-state window whose length is a whole
    number of wave-generator half-revolutions when that is at most
    ``max_window_s`` (removes the 2x-WG and cogging ripple), else
    ``max_window_s``.  Torque = motor torque x N (output side); the mean
    velocity of the window comes from the output encoder.
    """

    v_min_rad_s: float = 6e-4
    v_max_rad_s: float = 0.6
    points: int = 10
    settle_s: float = 0.6
    settle_angle_rad: float = 5e-4      # + the time to wind the gear up at this speed
    min_window_s: float = 0.4
    max_window_s: float = 2.5
    kind: str = "friction_sweep"

    def speeds(self) -> np.ndarray:
        """Speeds, rad/s (output), descending (fast points first)."""
        return np.geomspace(self.v_max_rad_s, self.v_min_rad_s, self.points)

    def window_s(self, v: float, ratio: float) -> float:
        half_rev = math.pi / ratio / abs(v)          # output angle of a WG half-revolution / speed
        if half_rev <= self.max_window_s:
            return max(1, math.ceil(self.min_window_s / half_rev)) * half_rev
        return self.max_window_s

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        out = []
        for v in self.speeds():
            for sgn in (1.0, -1.0):
                settle = self.settle_s + self.settle_angle_rad / v
                out.append({"mode": "velocity", "velocity_rad_s": sgn * v, "settle_s": settle,
                            "window_s": self.window_s(v, ratio)})
        return out


@dataclass
class GravitySine:
    """Slow large position sines (position mode) at two frequencies.

    Fits unbalance torque a.cos + b.sin, Coulomb, viscous and inertia: with one
    sine the acceleration -w^2 theta is collinear with sin(theta); two
    frequencies separate them.
    """

    amplitudes_rad: tuple[float, ...] = (1.5, 0.8)
    frequencies_Hz: tuple[float, ...] = (0.05, 0.1)
    kind: str = "gravity_sine"

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        return [{"mode": "position", "amplitude_rad": a, "frequency_Hz": f, "duration_s": 1.0 / f}
                for a, f in zip(self.amplitudes_rad, self.frequencies_Hz)]


@dataclass
class TERotation:
    """Slow constant rotation, both directions, whole WG revolutions over an output span (velocity mode).

    The speed keeps the 2x-WG line far below the anti-resonance (the load
    follows the kinematic error through the spring without amplification).
    """

    velocity_rad_s: float = 0.05
    wg_revs: int = 4
    #: output span of the rotation, rad (0: the WG revolutions alone, +v then -v).  The output-side
    #: lines (per output revolution) need a large part of a turn; a pitch axis has no whole one (the
    #: drive's travel limits, +-0.3 turn = +-1.88 rad by default), so the windows go +span/2, -span,
    #: +span/2 (on a drive: about the start and back to it; the simulator starts each window at 0),
    #: whole WG revolutions each
    output_span_rad: float = 1.7
    settle_s: float = 1.0
    kind: str = "te_rotation"

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        def win(span: float) -> float:
            wg = max(float(self.wg_revs), math.floor(span * ratio / (2.0 * math.pi)))   # whole WG revolutions
            return wg * 2.0 * math.pi / ratio / self.velocity_rad_s
        legs = ((1.0, 0.0), (-1.0, 0.0)) if self.output_span_rad <= 0 else \
            ((1.0, 0.5 * self.output_span_rad), (-1.0, self.output_span_rad), (1.0, 0.5 * self.output_span_rad))
        return [{"mode": "velocity", "velocity_rad_s": s * self.velocity_rad_s, "settle_s": self.settle_s,
                 "window_s": win(span)} for s, span in legs]


@dataclass
class LockedCycle:
    """Locked output, quasi-static torque cycles 0 -> +T -> 0 -> -T -> 0 (catalogue test).

    ``levels`` are fractions of ``torque_max_Nm`` cycled in turn (1.0 = the
    hysteresis-loss cycle, 0.04 x rated = lost motion).  Output torque from
    the rig torque sensor, twist from the motor encoder.
    """

    torque_max_Nm: float = 67.0
    rated_torque_Nm: float | None = None
    cycles: int = 3
    rate_Nm_s: float = 60.0
    lost_motion_fraction: float = 0.04
    kind: str = "locked_cycle"

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        rated = self.rated_torque_Nm or self.torque_max_Nm
        return [{"mode": "locked", "torque_amplitude_Nm": self.torque_max_Nm, "cycles": self.cycles,
                 "rate_Nm_s": self.rate_Nm_s, "purpose": "stiffness"},
                {"mode": "locked", "torque_amplitude_Nm": self.lost_motion_fraction * rated, "cycles": self.cycles,
                 "rate_Nm_s": self.rate_Nm_s / 10.0, "purpose": "lost_motion"}]


@dataclass
class ForcSet:
    """First-order reversal curves, locked output: -Tf -> alpha_i -> -Tf for ``levels-1`` alphas.

    The Everett grid has ``levels`` points over [-Tf, Tf] (firmware table L).
    """

    torque_range_Nm: float = 28.0
    levels: int = 32
    rate_Nm_s: float = 120.0
    kind: str = "forc"

    def alphas(self) -> np.ndarray:
        return np.linspace(-self.torque_range_Nm, self.torque_range_Nm, self.levels)[1:]

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        return [{"mode": "locked", "turning_points_Nm": [float(-self.torque_range_Nm)]
                 + [v for a in self.alphas() for v in (float(a), float(-self.torque_range_Nm))],
                 "rate_Nm_s": self.rate_Nm_s}]


@dataclass
class MinorLoops:
    """Validation minor loops (not used in fitting): from negative saturation, nested reversals."""

    torque_range_Nm: float = 28.0
    rate_Nm_s: float = 120.0
    kind: str = "minor_loops"

    def turning_points(self) -> list[float]:
        f = [-1.0, 0.62, -0.37, 0.41, -0.13, 0.23, -0.55, 0.81, 0.05, 0.33, -0.71]
        return [x * self.torque_range_Nm for x in f]

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        return [{"mode": "locked", "turning_points_Nm": self.turning_points(), "rate_Nm_s": self.rate_Nm_s}]


@dataclass
class PreslidingSteps:
    """Locked output, small torque reversals below and beyond the input-side breakaway (LuGre presliding).

    From ``+preload`` (motor sliding positive, bristles saturated) the command
    reverses by ``d_i = fraction_i x breakaway_Nm`` and comes back, for each
    fraction (the small ones stay in presliding, those > 2 reach sliding in
    the other direction), then the same mirrored at ``-preload``.  Torques are
    output-referred commands; the commanded turning points are *not* shifted
    by the friction (the fit needs the motor-side friction itself).  With the
    output locked the load-side friction does not act: what is identified is
    the motor-side LuGre (sigma0, breakaway), from ``tau_m - T/N`` (rig torque
    sensor T) against the motor encoder.
    """

    breakaway_Nm: float = 10.0
    preload_Nm: float = 20.0
    fractions: tuple[float, ...] = (0.3, 0.6, 1.0, 1.5, 2.5)
    rate_Nm_s: float = 30.0
    kind: str = "presliding"

    def turning_points(self) -> list[float]:
        out: list[float] = []
        for sgn in (1.0, -1.0):
            a = sgn * self.preload_Nm
            out.append(a)
            for f in self.fractions:
                out += [a - sgn * f * self.breakaway_Nm, a]
        return out

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        return [{"mode": "locked", "turning_points_Nm": self.turning_points(), "rate_Nm_s": self.rate_Nm_s,
                 "friction_shift": False}]


@dataclass
class LostMotionSine:
    """Small slow position sine about the start (position mode): the lost motion at reversals.

    The output travels +-``amplitude_rad`` at a peak speed of ``2 pi f amplitude`` (0.36 deg/s
    with the defaults); near each reversal the speed passes through zero slowly, so the reversal
    goes through the presliding of the output-side friction quasi-statically.  The twist between
    the two encoders (motor / N - output, TE removed) against the output travel since the last
    reversal is the lost-motion curve the Maxwell-slip compensator predicts (:mod:`.lost_motion`).
    The amplitude is a hundred times the presliding distances of gear friction (1e-5 .. 1e-4 rad)
    and small enough that the unbalance torque stays nearly constant (0.6 % of mgl); over CAN the
    segment runs in cyclic synchronous velocity, whose loop needs a few 1e-4 rad of travel to
    break away (at +-1e-3 rad the output of the reference axis moved +-3e-5 rad and slid nowhere).
    """

    amplitude_rad: float = 1e-2
    frequency_Hz: float = 0.1
    cycles: float = 2.5
    kind: str = "lost_motion"

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        return [{"mode": "position", "amplitude_rad": self.amplitude_rad, "frequency_Hz": self.frequency_Hz,
                 "duration_s": self.cycles / self.frequency_Hz}]


@dataclass
class FRFExcitation:
    """Velocity-mode multisine on a constant bias speed (no velocity reversal: friction slides).

    The closed-loop FRF is G = S_ry / S_ru (r reference, u motor torque,
    y motor angle), unbiased by the feedback.  Run at each amplitude.
    """

    bias_rad_s: float = 0.08
    amplitudes_rad_s: tuple[float, ...] = (0.02, 0.04)
    f0_Hz: float = 1.0
    f1_Hz: float = 200.0
    lines: int = 200
    periods: int = 8
    kind: str = "frf"

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        period = (self.lines - 1) / (self.f1_Hz - self.f0_Hz)
        return [{"mode": "velocity_multisine", "bias_rad_s": self.bias_rad_s, "amplitude_rad_s": a,
                 "f0_Hz": self.f0_Hz, "f1_Hz": self.f1_Hz, "lines": self.lines, "period_s": period,
                 "settle_s": 1.0, "duration_s": 1.0 + self.periods * period} for a in self.amplitudes_rad_s]


EXPERIMENTS: dict[str, type] = {c.kind: c for c in (FrictionSweep, GravitySine, TERotation, LockedCycle,  # type: ignore[attr-defined]
                                                    ForcSet, MinorLoops, FRFExcitation, PreslidingSteps,
                                                    LostMotionSine)}


def describe(design: Any) -> dict[str, Any]:
    """JSON-friendly description of an experiment design."""
    d = asdict(design)
    return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


# ----------------------------------------------------------------- torque profiles


def triangle_profile(turning_points: Sequence[float], rate: float, dt: float, start: float = 0.0,
                     dwell_s: float = 0.0) -> np.ndarray:
    """Piecewise-linear sequence through ``turning_points`` at ``rate`` (units/s), sampled every dt."""
    pts = [start, *turning_points]
    out = [np.array([start])]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(round(abs(b - a) / rate / dt)))
        out.append(a + (b - a) * np.arange(1, n + 1) / n)
        if dwell_s > 0:
            out.append(np.full(int(round(dwell_s / dt)), b))
    return np.concatenate(out)


def cycle_points(amplitude: float, cycles: int) -> list[float]:
    """0 -> +A -> 0 -> -A -> 0 repeated."""
    return [v for _ in range(cycles) for v in (amplitude, 0.0, -amplitude, 0.0)]


# ----------------------------------------------------------------- simulator runner


def _block_mean(x: np.ndarray, k: int) -> np.ndarray:
    n = (len(x) // k) * k
    return x[:n].reshape(-1, k).mean(axis=1)


@dataclass
class SimRunner:
    """Run experiment designs on the simulator.

    Parameters
    ----------
    axis : str or path-like
        "reference" or an axis TOML file.
    seed : int
        Noise seed (each segment gets seed + its index).
    params, effects : mapping, optional
        Extra plant overrides / effect switches (tests hide or reveal effects).
    torque_sensor_noise_Nm, torque_sensor_lsb_Nm : float
        Rig torque sensor of the locked-output fixture: white noise (std, N.m)
        and quantisation step (N.m).
    decimation : int
        Loop periods per recorded sample (block mean of the locked-output
        signals, every n-th row of closed-loop logs).
    progress : callable, optional
        ``progress(message)`` for each segment run.
    gains : mapping, optional
        Drive gain overrides for the closed-loop experiments, by parameter
        name in its table unit (``vel_kp``, ``vel_ki``, ``pos_kp``, ...); the
        drive must be tuned for the axis (the defaults suit the reference axis).
    """

    axis: str | os.PathLike[str] = "reference"
    seed: int = 1
    params: Mapping[str, float | bool] = field(default_factory=dict)
    effects: Mapping[str, bool] = field(default_factory=dict)
    torque_sensor_noise_Nm: float = 0.01
    torque_sensor_lsb_Nm: float = 0.005
    decimation: int = 10
    progress: Callable[[str], None] | None = None
    gains: Mapping[str, float] = field(default_factory=dict)

    # -- helpers
    def _axis_ref(self) -> str:
        a = str(self.axis)
        if a in ("reference", "minimal"):
            return a
        p = Path(a)
        if not p.is_file():
            raise UserError(f"{a}: axis file not found")
        return str(p.resolve())

    def ratio(self) -> float:
        from .. import sim
        return float(self.params.get("gear.ratio", sim.axis_param("gear.ratio", self._axis_ref())))

    def commissioned_inertia_kgm2(self) -> float:
        """Total inertia J_L + N^2 J_m the simulated drive is commissioned with (its ``j_total``), kg.m^2."""
        from .. import sim
        ax = self._axis_ref()
        val = {k: float(self.params.get(k, sim.axis_param(k, ax))) for k in ("gear.ratio", "motor.jm_kgm2",
                                                                              "load.jl_kgm2")}
        return val["load.jl_kgm2"] + val["gear.ratio"] ** 2 * val["motor.jm_kgm2"]

    def torque_limit_Nm(self) -> float:
        """The simulated drive's torque limit (a gain set here, else the drive's default), N.m output side."""
        from ..params_gen import BY_NAME
        return float(self.gains.get("torque_limit", BY_NAME["torque_limit"].default))

    def set_gains(self, gains: Mapping[str, float]) -> None:
        """Drive gains for the following closed-loop experiments (by parameter name, table units)."""
        self.gains = {**dict(self.gains), **{k: float(v) for k, v in gains.items()}}

    def _bench(self) -> dict[str, float | bool]:
        return {"base.enabled": False, **dict(self.params)}

    def _say(self, msg: str) -> None:
        if self.progress:
            self.progress(msg)

    def _scenario(self, tmp: Path, name: str, mode: str, setpoint: Mapping[str, Any], duration: float,
                  seed: int) -> Path:
        lines = ["[scenario]", f"name = {basic_string(name)}", f"axis = {basic_string(str(self._axis_ref()))}", f"duration_s = {float(duration)!r}",
                 f"seed = {seed}", f"log_decimation = {self.decimation}", "", "[controller]", f"mode = {basic_string(mode)}", ""]
        if self.gains:
            lines += ["[controller.gains]"] + [f"{k} = {float(v)!r}" for k, v in self.gains.items()] + [""]
        lines += ["[setpoint]"]
        for k, v in setpoint.items():
            lines.append(f"{k} = {basic_string(v)}" if isinstance(v, str) else f"{k} = {float(v)!r}")
        p = tmp / f"{name}.toml"
        p.write_text("\n".join(lines) + "\n")
        return p

    def _closed(self, tmp: Path, name: str, mode: str, setpoint: Mapping[str, Any], duration: float,
                seed: int) -> dict[str, np.ndarray]:
        from .. import sim
        scen = self._scenario(tmp, name, mode, setpoint, duration, seed)
        r = sim.run_scenario(scen, params=self._bench(), effects=dict(self.effects))
        if np.any(r["fault_code"] != 0):
            k = int(np.argmax(r["fault_code"] != 0))
            raise UserError(f"simulated experiment '{name}': drive fault {int(r['fault_code'][k])} at "
                            f"t = {r['t_s'][k]:.3f} s")
        keep = ["t_s", "motor_angle_rad", "load_angle_rad", "motor_torque_Nm", "torque_cmd_Nm"]
        for extra in ("setpoint_velocity_rad_s", "setpoint_rad", "setpoint_torque_Nm"):
            if extra in r.columns:
                keep.append(extra)
        return {k: r[k] for k in keep}

    def _locked(self, torque_out_Nm: np.ndarray, seed: int) -> dict[str, np.ndarray]:
        """Plant alone, output clamped; input = output-side torque command (N.m), converted to the motor."""
        from .. import sim
        ratio = self.ratio()
        prm = {**self._bench(), "load.jl_kgm2": CLAMP_INERTIA_KGM2}
        cmd = np.asarray(torque_out_Nm, dtype=float) / ratio
        o = sim.simulate_open_loop(cmd, params=prm, effects=dict(self.effects), axis=self._axis_ref(),
                                   dt_s=LOOP_S, seed=seed)
        rng = np.random.default_rng(seed + 7919)
        ts = o["transmitted_torque_Nm"] + rng.normal(0.0, self.torque_sensor_noise_Nm, len(cmd))
        if self.torque_sensor_lsb_Nm > 0:
            ts = np.round(ts / self.torque_sensor_lsb_Nm) * self.torque_sensor_lsb_Nm
        k = self.decimation
        cols = {"t_s": o["t_s"][k - 1::k][: len(cmd) // k],
                "motor_angle_rad": _block_mean(o["motor_angle_rad"], k),
                "load_angle_rad": _block_mean(o["load_angle_rad"], k),
                "motor_torque_Nm": _block_mean(o["motor_torque_Nm"], k),
                "torque_cmd_Nm": _block_mean(cmd, k),
                "load_torque_Nm": _block_mean(ts, k)}
        return cols

    def _meta(self, design: Any) -> dict[str, Any]:
        return {"gear_ratio": self.ratio(), "sample_period_s": LOOP_S * self.decimation,
                "source": "simulator", "axis": str(self.axis), "seed": int(self.seed),
                "design": describe(design)}

    # -- experiments
    def run(self, design: Any) -> ExperimentData:
        """Run one design and return its data."""
        ratio = self.ratio()
        plan = design.plan(ratio)
        parts: list[tuple[dict[str, np.ndarray], dict[str, Any]]] = []
        with tempfile.TemporaryDirectory(prefix="hdservo-ident-") as td:
            tmp = Path(td)
            for i, seg in enumerate(plan):
                seed = self.seed + i
                self._say(f"{design.kind}: segment {i + 1}/{len(plan)} {_seg_label(seg)}")
                mode = seg["mode"]
                if mode == "velocity":
                    dur = seg["settle_s"] + seg["window_s"]
                    cols = self._closed(tmp, f"{design.kind}_{i}", "velocity",
                                        {"type": "step", "initial_rad_s": 0.0,
                                         "amplitude_rad_s": seg["velocity_rad_s"], "t0_s": 0.0}, dur, seed)
                elif mode == "position":
                    cols = self._closed(tmp, f"{design.kind}_{i}", "position",
                                        {"type": "sine", "initial_rad": 0.0, "amplitude_rad": seg["amplitude_rad"],
                                         "frequency_Hz": seg["frequency_Hz"], "phase_rad": 0.0, "t0_s": 0.0},
                                        seg["duration_s"], seed)
                elif mode == "velocity_multisine":
                    cols = self._closed(tmp, f"{design.kind}_{i}", "velocity",
                                        {"type": "multisine", "initial_rad_s": seg["bias_rad_s"],
                                         "amplitude_rad_s": seg["amplitude_rad_s"], "f0_Hz": seg["f0_Hz"],
                                         "f1_Hz": seg["f1_Hz"], "lines": seg["lines"], "t0_s": seg["settle_s"]},
                                        seg["duration_s"], seed)
                elif mode == "locked":
                    if "turning_points_Nm" in seg:
                        pts = seg["turning_points_Nm"]
                    else:
                        pts = cycle_points(seg["torque_amplitude_Nm"], seg["cycles"])
                    if seg.get("friction_shift", True):
                        pts = _compensate_friction(pts, self, seed)
                    prof = triangle_profile(pts, seg["rate_Nm_s"], LOOP_S, dwell_s=0.05)
                    cols = self._locked(prof, seed)
                else:  # pragma: no cover - designs are ours
                    raise ValueError(mode)
                parts.append((cols, seg))
        return concat(design.kind, parts, self._meta(design))


def _seg_label(seg: Mapping[str, Any]) -> str:
    if "velocity_rad_s" in seg:
        return f"v = {seg['velocity_rad_s']:+.4g} rad/s"
    if "amplitude_rad_s" in seg:
        return f"amplitude {seg['amplitude_rad_s']:.3g} rad/s"
    if "torque_amplitude_Nm" in seg:
        return f"+-{seg['torque_amplitude_Nm']:.3g} N.m"
    return ""


def _compensate_friction(points: Sequence[float], runner: SimRunner, seed: int) -> list[float]:
    """Shift the commanded turning points by the input friction so the gear torque reaches the targets.

    With the output locked the gear sees T = N (tau - F_m): a maximum is
    commanded higher, a minimum lower, by the input friction measured on a
    short calibration cycle (the same rig sensor; no model knowledge).  The
    command ramps through the friction band at the same rate, so every
    reversal passes through presliding quasi-statically.  Only the reversal
    levels matter; the fits use the measured torque.
    """
    key = ("friction", id(runner), str(runner.axis))
    f = _CAL.get(key)
    if f is None:
        amp = max(max(abs(float(p)) for p in points), 1.0)
        cal = triangle_profile([amp, -amp, amp], amp * 2.0, LOOP_S)
        c = runner._locked(cal, seed + 104729)
        r = runner.ratio()
        d = c["torque_cmd_Nm"] * r - c["load_torque_Nm"]
        slope = np.gradient(c["torque_cmd_Nm"])
        up, dn = d[slope > 0], d[slope < 0]
        f = (float(np.median(up)) if len(up) else 0.0, float(np.median(dn)) if len(dn) else 0.0)
        _CAL[key] = f
    out, prev = [], 0.0
    for p in points:
        out.append(float(p) + (f[0] if p > prev else f[1]))
        prev = float(p)
    return out


_CAL: dict[tuple[Any, ...], tuple[float, float]] = {}


def drive_runner(**can_settings: Any) -> Any:
    """A :class:`.drive_runner.DriveSession` (context manager yielding the runner) for a drive over CAN.

    Parameters
    ----------
    **can_settings
        ``bus`` (python-can settings, None = start the virtual drive),
        ``node_id``, ``axis``, ``seed``, ``progress``, ``rig``: see
        :class:`.drive_runner.DriveSession`.
    """
    from .drive_runner import DriveSession
    return DriveSession(**can_settings)
