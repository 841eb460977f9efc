"""Python binding of the simulator (ctypes on ``build/lib/libhdsim.so``).

Three uses, all filled by the C side into numpy arrays (no per-sample Python loop):

* :func:`run_scenario` -- the firmware application against the simulated
  axis in lock-step (the same code as ``hdservo-sim run``), returning the log
  columns and the sidecar metadata;
* :func:`simulate_open_loop` -- the plant alone for given input sequences
  (motor torque command, optional external load torque), with the axis
  parameters overridden by a ``{"section.key": value}`` dict, for fitting by
  simulation error;
* both take ``effects={"friction_motor": False, ...}`` to switch any plant
  effect on or off (``"section"`` -> ``section.enabled``,
  ``"section.x"`` -> ``section.x_enabled``).

The library is found by :func:`hdservo.resources.sim_library` (inside the package when
installed from a wheel, ``build/lib/libhdsim.so`` in a checkout after ``make sim``).
"""
from __future__ import annotations

import ctypes
import json
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from . import resources
from .errors import UserError

#: Firmware loop period of the reference axis, s.
LOOP_PERIOD_S = 1e-4

_ERRLEN = 2048
_lib: ctypes.CDLL | None = None
_lock = threading.Lock()


class SimError(UserError):
    """The simulator refused its input (bad scenario, parameter, ...); one line."""


def _c_double_p(a: np.ndarray) -> Any:
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def library_path() -> Path:
    """Path of ``libhdsim.so`` (see :func:`hdservo.resources.sim_library`)."""
    return resources.sim_library()


def load_library() -> ctypes.CDLL:
    """Load (building first if needed) and declare the C API; cached."""
    global _lib
    with _lock:
        if _lib is not None:
            return _lib
        path = library_path()
        if not path.is_file():
            raise SimError(f"{path}: simulator library not found (HDSERVO_SIMLIB names a missing file)")
        lib = ctypes.CDLL(str(path))
        vp, cp, sz = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t
        dp = ctypes.POINTER(ctypes.c_double)
        i32, i64, u64 = ctypes.c_int32, ctypes.c_int64, ctypes.c_uint64
        sig = {
            "hd_simlib_open": (vp, [cp, cp, sz]),
            "hd_simlib_set_param": (i32, [vp, cp, ctypes.c_double, cp, sz]),
            "hd_simlib_set_seed": (None, [vp, u64]),
            "hd_simlib_set_duration": (i32, [vp, ctypes.c_double, cp, sz]),
            "hd_simlib_prepare": (i64, [vp, cp, sz]),
            "hd_simlib_ncol": (i32, []),
            "hd_simlib_column": (cp, [vp, i32]),
            "hd_simlib_run": (i32, [vp, dp, cp, sz]),
            "hd_simlib_run_columns": (i32, [vp, dp, cp, sz]),
            "hd_simlib_meta": (cp, [vp]),
            "hd_simlib_write_log": (i32, [vp, dp, i64, cp, cp, sz]),
            "hd_simlib_timing": (None, [vp, dp, dp]),
            "hd_simlib_close": (None, [vp]),
            "hd_simlib_ol_ncol": (i32, []),
            "hd_simlib_ol_column": (cp, [i32]),
            "hd_simlib_open_loop": (i32, [cp, ctypes.POINTER(cp), dp, i32, u64, ctypes.c_double, i64,
                                          dp, dp, dp, cp, sz]),
            "hd_simlib_plant_open": (vp, [cp, ctypes.POINTER(cp), dp, i32, u64, cp, sz]),
            "hd_simlib_plant_run": (i32, [vp, ctypes.c_double, i64, dp, dp, cp, sz]),
            "hd_simlib_plant_close": (None, [vp]),
            "hd_simlib_replay_windows": (i32, [cp, ctypes.POINTER(cp), dp, i32, ctypes.c_double, i64, dp, i64,
                                               ctypes.POINTER(i64), dp, dp, dp, cp, sz]),
            "hd_simlib_max_maxwell": (i32, []),
            "hd_simlib_param_count": (i32, []),
            "hd_simlib_param_name": (cp, [i32]),
            "hd_simlib_param_unit": (cp, [i32]),
            "hd_simlib_param_type": (i32, [i32]),
            "hd_simlib_axis_param": (i32, [cp, cp, dp, cp, sz]),
        }
        for name, (res, args) in sig.items():
            fn = getattr(lib, name)
            fn.restype = res
            fn.argtypes = args
        _lib = lib
        return lib


def _err_buf() -> ctypes.Array[ctypes.c_char]:
    return ctypes.create_string_buffer(_ERRLEN)


def _raise(err: ctypes.Array[ctypes.c_char]) -> None:
    raise SimError(err.value.decode(errors="replace") or "simulator error")


# ------------------------------------------------------------------ parameters

@dataclass(frozen=True)
class ParamInfo:
    """One plant parameter: ``name`` ("section.key"), SI ``unit``, ``kind`` (double/bool/int)."""

    name: str
    unit: str
    kind: str


_PARAM_TABLES: dict[int, tuple[ParamInfo, ...]] = {}


def param_table() -> list[ParamInfo]:
    """Every plant parameter the axis files and overrides may set.

    Read once per loaded library (the table is compiled in); each run's effect and
    parameter look-ups would otherwise rebuild it (about 0.2 ms each).
    """
    lib = load_library()
    table = _PARAM_TABLES.get(id(lib))
    if table is None:
        kinds = {0: "double", 1: "bool", 2: "int"}
        table = tuple(ParamInfo(lib.hd_simlib_param_name(i).decode(), lib.hd_simlib_param_unit(i).decode(),
                                kinds.get(lib.hd_simlib_param_type(i), "?"))
                      for i in range(lib.hd_simlib_param_count()))
        _PARAM_TABLES[id(lib)] = table
    return list(table)


def effect_names() -> list[str]:
    """Names accepted in ``effects=``: ``section`` for ``section.enabled``,
    ``section.x`` for ``section.x_enabled``."""
    names = []
    for p in param_table():
        if p.kind != "bool":
            continue
        if p.name.endswith(".enabled"):
            names.append(p.name[: -len(".enabled")])
        elif p.name.endswith("_enabled"):
            names.append(p.name[: -len("_enabled")])
    return names


def effect_key(effect: str) -> str:
    """Parameter key that switches ``effect`` (``"friction_motor"`` -> ``"friction_motor.enabled"``)."""
    table = {p.name for p in param_table() if p.kind == "bool"}
    for cand in (f"{effect}.enabled", f"{effect}_enabled"):
        if cand in table:
            return cand
    raise SimError(f"unknown effect '{effect}' (expected one of: {', '.join(effect_names())})")


def axis_param(name: str, axis: str | os.PathLike[str] = "reference") -> float:
    """Value of one plant parameter for an axis ("reference", "minimal" or a TOML file)."""
    lib = load_library()
    v = ctypes.c_double()
    err = _err_buf()
    if lib.hd_simlib_axis_param(str(axis).encode(), name.encode(), ctypes.byref(v), err, _ERRLEN) != 0:
        _raise(err)
    return float(v.value)


def _overrides(params: Mapping[str, float | bool] | None,
               effects: Mapping[str, bool] | None) -> list[tuple[str, float]]:
    out: list[tuple[str, float]] = []
    for k, v in (params or {}).items():
        if isinstance(v, bool):
            out.append((k, 1.0 if v else 0.0))
        else:
            try:
                out.append((k, float(v)))
            except (TypeError, ValueError):
                raise SimError(f"plant parameter '{k}': expected a number or bool, found {v!r}") from None
    for e, on in (effects or {}).items():
        out.append((effect_key(e), 1.0 if on else 0.0))
    return out


# ------------------------------------------------------------------ closed loop

@dataclass
class SimResult:
    """A closed-loop run.

    Attributes
    ----------
    columns : dict of str to numpy.ndarray
        Log columns (SI units as the suffix says), see docs/sim.md.
    meta : dict
        The sidecar (gear ratio, sample period in s, effects, seed, ...).
    app_time_s, plant_time_s : float
        Wall time spent in the firmware step and the plant step, s.
    """

    columns: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)
    app_time_s: float = 0.0
    plant_time_s: float = 0.0

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]


def run_scenario(scenario: str | os.PathLike[str], *, params: Mapping[str, float | bool] | None = None,
                 effects: Mapping[str, bool] | None = None, seed: int | None = None,
                 duration_s: float | None = None, log_path: str | os.PathLike[str] | None = None) -> SimResult:
    """Run a scenario file in closed loop (firmware app + plant, lock-step).

    Parameters
    ----------
    scenario : path-like
        Scenario TOML (docs/sim.md).
    params : mapping, optional
        Plant parameter overrides ``{"stiffness.k1_Nm_per_rad": 2.9e4}`` (SI),
        applied after the axis file and the scenario's ``[plant]`` section.
    effects : mapping, optional
        ``{"friction_motor": False, "hysteresis_preisach": True}``.
    seed : int, optional
        Noise seed (overrides the scenario's).
    duration_s : float, optional
        Run length in s (overrides the scenario's).
    log_path : path-like, optional
        Also write the CSV + JSON sidecar there (atomically).

    Returns
    -------
    SimResult
    """
    lib = load_library()
    err = _err_buf()
    h = lib.hd_simlib_open(os.fsencode(os.fspath(scenario)), err, _ERRLEN)
    if not h:
        _raise(err)
    try:
        for k, v in _overrides(params, effects):
            if lib.hd_simlib_set_param(h, k.encode(), v, err, _ERRLEN) != 0:
                _raise(err)
        if seed is not None:
            if seed < 0:
                raise SimError(f"seed: expected a non-negative integer, found {seed}")
            lib.hd_simlib_set_seed(h, int(seed))
        if duration_s is not None and lib.hd_simlib_set_duration(h, float(duration_s), err, _ERRLEN) != 0:
            _raise(err)
        n = lib.hd_simlib_prepare(h, err, _ERRLEN)
        if n < 0:
            _raise(err)
        ncol = lib.hd_simlib_ncol()
        names = [lib.hd_simlib_column(h, j).decode() for j in range(ncol)]
        # column-major: each column is a contiguous block handed on without a copy
        data = np.empty((ncol, n), dtype=np.float64)
        if lib.hd_simlib_run_columns(h, _c_double_p(data), err, _ERRLEN) != 0:
            _raise(err)
        meta = json.loads(lib.hd_simlib_meta(h).decode())
        if log_path is not None:
            rows = np.ascontiguousarray(data.T)
            if lib.hd_simlib_write_log(h, _c_double_p(rows), n, os.fsencode(os.fspath(log_path)), err,
                                       _ERRLEN) != 0:
                _raise(err)
        ta, tp = ctypes.c_double(), ctypes.c_double()
        lib.hd_simlib_timing(h, ctypes.byref(ta), ctypes.byref(tp))
    finally:
        lib.hd_simlib_close(h)
    cols = {name: data[j] for j, name in enumerate(names)}
    return SimResult(columns=cols, meta=meta, app_time_s=ta.value, plant_time_s=tp.value)


# ------------------------------------------------------------------ open loop

def open_loop_columns() -> list[str]:
    """Column names returned by :func:`simulate_open_loop`."""
    lib = load_library()
    return [lib.hd_simlib_ol_column(j).decode() for j in range(lib.hd_simlib_ol_ncol())]


def simulate_open_loop(torque_Nm: Sequence[float] | np.ndarray, *,
                       load_torque_Nm: Sequence[float] | np.ndarray | None = None,
                       params: Mapping[str, float | bool] | None = None,
                       effects: Mapping[str, bool] | None = None,
                       axis: str | os.PathLike[str] = "reference",
                       dt_s: float = LOOP_PERIOD_S, seed: int = 0) -> dict[str, np.ndarray]:
    """Simulate the plant alone (no firmware) for given inputs.

    Parameters
    ----------
    torque_Nm : array-like, shape (n,)
        Motor torque command per period, N.m at the motor shaft (passes
        through the current loop: lag and saturation when enabled).
    load_torque_Nm : array-like, shape (n,), optional
        External torque on the output per period, N.m.
    params : mapping, optional
        ``{"section.key": value}`` overrides of the axis parameters (SI).
    effects : mapping, optional
        Effects on/off, as in :func:`run_scenario`.
    axis : str or path-like
        "reference", "minimal" or an axis TOML file.
    dt_s : float
        Period, s (inputs held over each period; the plant sub-steps inside).
    seed : int
        Sensor-noise seed.

    Returns
    -------
    dict of str to numpy.ndarray
        Row i is the state at t = (i+1)*dt_s after input i; columns as
        :func:`open_loop_columns` (angles in rad, velocities in rad/s,
        torques in N.m, current in A).
    """
    lib = load_library()
    u = np.ascontiguousarray(np.asarray(torque_Nm, dtype=np.float64))
    if u.ndim != 1:
        raise SimError(f"torque_Nm: expected a 1-D array, found shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise SimError("torque_Nm: expected finite values")
    n = u.size
    lt = None
    if load_torque_Nm is not None:
        lt = np.ascontiguousarray(np.asarray(load_torque_Nm, dtype=np.float64))
        if lt.shape != u.shape:
            raise SimError(f"load_torque_Nm: expected shape {u.shape}, found {lt.shape}")
        if not np.all(np.isfinite(lt)):
            raise SimError("load_torque_Nm: expected finite values")
    over = _overrides(params, effects)
    keys = (ctypes.c_char_p * max(1, len(over)))(*[k.encode() for k, _ in over])
    vals = np.array([v for _, v in over] or [0.0], dtype=np.float64)
    ncol = lib.hd_simlib_ol_ncol()
    out = np.empty((n, ncol), dtype=np.float64)
    err = _err_buf()
    rc = lib.hd_simlib_open_loop(str(axis).encode(), keys, _c_double_p(vals), len(over), int(seed),
                                 float(dt_s), n, _c_double_p(u), _c_double_p(lt) if lt is not None else None,
                                 _c_double_p(out), err, _ERRLEN)
    if rc != 0:
        _raise(err)
    return {name: np.ascontiguousarray(out[:, j]) for j, name in enumerate(open_loop_columns())}


# ------------------------------------------------------------------ windowed replay

def max_maxwell() -> int:
    """Number of Maxwell-slip elements the plant holds."""
    return int(load_library().hd_simlib_max_maxwell())


def replay_windows(torque_Nm: Sequence[float] | np.ndarray, starts: Sequence[int] | np.ndarray,
                   x0: np.ndarray, *, params: Mapping[str, float | bool] | None = None,
                   effects: Mapping[str, bool] | None = None,
                   axis: str | os.PathLike[str] = "minimal", dt_s: float = LOOP_PERIOD_S,
                   maxwell_xi: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Replay a measured torque through the plant over windows started from given states.

    Multiple shooting: each window starts from a measured state, so a closed-loop log can
    be replayed without its controller (the plant alone, open loop, drifts only within a
    window).

    Parameters
    ----------
    torque_Nm : array-like, shape (n,)
        Motor torque per row, N.m at the motor (passes the current loop when the axis
        enables it; its state starts at the window's first torque).
    starts : array-like of int, shape (w,)
        First row of each window, increasing; a window ends where the next begins.
    x0 : numpy.ndarray, shape (w, 4)
        State at each window's first row: motor angle rad, motor speed rad/s, load angle
        rad, load speed rad/s.
    params, effects : mapping, optional
        Overrides of the axis, as in :func:`simulate_open_loop`.
    axis : str or path-like
        "reference", "minimal" or an axis TOML file.
    dt_s : float
        Row period, s.
    maxwell_xi : numpy.ndarray, shape (w, :func:`max_maxwell`), optional
        Maxwell-slip element positions (rad of twist) at each window's start: the
        hysteresis memory there; default: every element relaxed at the start twist.

    Returns
    -------
    motor_angle_rad, load_angle_rad : numpy.ndarray, shape (n,)
        The simulated (true) angles per row; NaN before the first window and after a
        window's integration diverged.
    """
    lib = load_library()
    u = np.ascontiguousarray(np.asarray(torque_Nm, dtype=np.float64))
    if u.ndim != 1 or not np.all(np.isfinite(u)):
        raise SimError("torque_Nm: expected a 1-D array of finite values")
    st = np.ascontiguousarray(np.asarray(starts, dtype=np.int64))
    x = np.ascontiguousarray(np.asarray(x0, dtype=np.float64))
    if st.ndim != 1 or x.shape != (st.size, 4):
        raise SimError(f"x0: expected shape ({st.size}, 4), found {x.shape}")
    if not np.all(np.isfinite(x)):
        raise SimError("x0: expected finite values")
    xi = None
    if maxwell_xi is not None:
        mx = lib.hd_simlib_max_maxwell()
        xi = np.ascontiguousarray(np.asarray(maxwell_xi, dtype=np.float64))
        if xi.shape != (st.size, mx) or not np.all(np.isfinite(xi)):
            raise SimError(f"maxwell_xi: expected finite values of shape ({st.size}, {mx}), found {xi.shape}")
    over = _overrides(params, effects)
    keys = (ctypes.c_char_p * max(1, len(over)))(*[k.encode() for k, _ in over])
    vals = np.array([v for _, v in over] or [0.0], dtype=np.float64)
    out = np.empty((u.size, 2), dtype=np.float64)
    err = _err_buf()
    rc = lib.hd_simlib_replay_windows(os.fsencode(os.fspath(axis)), keys, _c_double_p(vals), len(over), float(dt_s),
                                      u.size, _c_double_p(u), st.size,
                                      st.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), _c_double_p(x),
                                      _c_double_p(xi) if xi is not None else None, _c_double_p(out), err, _ERRLEN)
    if rc != 0:
        _raise(err)
    return np.ascontiguousarray(out[:, 0]), np.ascontiguousarray(out[:, 1])


# ------------------------------------------------------------------ plant stepped by the caller

class Plant:
    """The plant alone, stepped by the caller (an outer controller written in Python).

    Parameters
    ----------
    axis : str or path-like
        "reference", "minimal" or an axis TOML file.
    params, effects : mapping, optional
        Overrides, as in :func:`simulate_open_loop`.
    seed : int
        Sensor-noise seed.

    Use as a context manager (or call :meth:`close`).
    """

    def __init__(self, axis: str | os.PathLike[str] = "reference", *,
                 params: Mapping[str, float | bool] | None = None, effects: Mapping[str, bool] | None = None,
                 seed: int = 0) -> None:
        self._lib = load_library()
        over = _overrides(params, effects)
        keys = (ctypes.c_char_p * max(1, len(over)))(*[k.encode() for k, _ in over])
        vals = np.array([v for _, v in over] or [0.0], dtype=np.float64)
        err = _err_buf()
        self._h = self._lib.hd_simlib_plant_open(os.fsencode(os.fspath(axis)), keys, _c_double_p(vals), len(over),
                                                 int(seed), err, _ERRLEN)
        if not self._h:
            _raise(err)
        self.columns = open_loop_columns()

    def run(self, torque_Nm: Sequence[float] | np.ndarray, dt_s: float = LOOP_PERIOD_S) -> np.ndarray:
        """Step ``len(torque_Nm)`` periods of ``dt_s`` s; rows (n, len(columns)) as
        :func:`simulate_open_loop`, time continuing from the previous call."""
        if not self._h:
            raise SimError("plant: already closed")
        u = np.ascontiguousarray(np.asarray(torque_Nm, dtype=np.float64).reshape(-1))
        out = np.empty((u.size, len(self.columns)), dtype=np.float64)
        err = _err_buf()
        if self._lib.hd_simlib_plant_run(self._h, float(dt_s), u.size, _c_double_p(u), _c_double_p(out), err,
                                         _ERRLEN) != 0:
            _raise(err)
        return out

    def close(self) -> None:
        """Free the plant."""
        if self._h:
            self._lib.hd_simlib_plant_close(self._h)
            self._h = None

    def __enter__(self) -> "Plant":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
