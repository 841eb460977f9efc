"""Decoded logs: CSV with SI unit suffixes plus a JSON sidecar (the log format of docs/sim.md).

A log ``run.csv`` is one row per sample, a header naming every column with
its SI unit suffix (``t_s``, ``motor_angle_rad``, ``load_velocity_rad_s``,
``motor_torque_Nm`` ...), numbers printed so that they round-trip (``%.17g``
on the C side, ``repr`` here).  Its sidecar ``run.json`` describes the
recording: gear ratio, sample period, encoder resolutions, firmware/OD
version, what was running (scenario), which plant effects were on, seed.

Reading is strict: a bad file raises :class:`LogError` whose message is one
line ``FILE:LINE:COL: expected ..., found ...``.  Writing goes to temporary
files that are renamed into place only when complete, so a failed write
never leaves half a log behind.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from .errors import UserError
from .fileio import write_json_atomic, write_text_atomic

#: Format tag and version written into (and required in) every sidecar.
FORMAT = "hdservo-log"
FORMAT_VERSION = 1

#: Unit suffixes accepted at the end of a column name, longest first
#: (``_rad_s2`` must win over ``_s``).  Dimensionless columns end in
#: ``_code``, ``_count`` or ``_flag``.
UNIT_SUFFIXES: tuple[str, ...] = (
    "_Nm_s_per_rad", "_Nm_per_rad", "_rad_s2", "_rad_s", "_rad", "_Nm", "_A", "_V",
    "_W", "_K", "_Hz",
    # linear axes (e.g. the EMPS prismatic axis): metres, m/s, m/s^2, newtons
    "_m_s2", "_m_s", "_m", "_N",
    "_s", "_code", "_count", "_flag",
)

#: Suffixes of a linear axis; a known signal may carry them instead of its rotary unit
#: (``setpoint_m`` on a prismatic axis, see ``column_roles`` in the EMPS sidecar).
LINEAR_SUFFIXES: tuple[str, ...] = ("_m_s2", "_m_s", "_m", "_N")

#: Signals whose unit is fixed: base name -> the only accepted suffix.
KNOWN_SIGNALS: dict[str, str] = {
    "t": "_s",
    "motor_angle": "_rad",
    "load_angle": "_rad",
    "motor_velocity": "_rad_s",
    "load_velocity": "_rad_s",
    "motor_torque": "_Nm",
    "motor_current": "_A",
    "load_torque": "_Nm",
    "setpoint": "_rad",
    "torsion": "_rad",
    "gyro_rate": "_rad_s",
    "fault": "_code",
}

#: Suffixes that name a non-SI unit (caught to give a helpful message).
_NON_SI = ("_deg", "_degs", "_deg_s", "_arcsec", "_arcmin", "_rpm", "_mNm", "_mA",
           "_ms", "_us", "_turn", "_turns", "_counts")

#: Sidecar keys that must be present, with their expected JSON type.
REQUIRED_META: dict[str, type] = {"gear_ratio": float, "sample_period_s": float}
#: Optional sidecar keys with their expected type when present.
OPTIONAL_META: dict[str, type] = {
    "motor_encoder_counts_per_rev": int,
    "load_encoder_counts_per_rev": int,
    "firmware_version": str,
    "od_version": str,
    "source": str,
    "scenario": str,
    "effects": dict,
    "seed": int,
    "columns": list,
}


class LogError(UserError, ValueError):
    """A log or sidecar file is malformed; the message is one line naming the place."""


@dataclass
class Log:
    """A decoded log.

    Attributes
    ----------
    columns : dict of str to numpy.ndarray
        Column name (with SI unit suffix) -> 1-D float64 array, in file order.
    meta : dict
        The JSON sidecar (gear ratio, sample period in s, ...).
    path : pathlib.Path or None
        Where the CSV was read from, if it was read.
    """

    columns: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)
    path: Path | None = None

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            where = f"{self.path}: " if self.path else ""
            raise LogError(f"{where}no column '{name}' (have: {', '.join(self.columns)})") from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    @property
    def t(self) -> np.ndarray:
        """Sample times in s (column ``t_s``)."""
        return self["t_s"]

    def __len__(self) -> int:
        return len(self.columns["t_s"]) if "t_s" in self.columns else 0


def sidecar_path(csv_path: str | os.PathLike[str]) -> Path:
    """The sidecar of ``run.csv`` is ``run.json`` (same directory, same stem)."""
    p = Path(csv_path)
    return p.with_suffix(".json")


def unit_of(column: str) -> str | None:
    """The SI unit suffix a column name ends in (``'_rad_s'``), or None."""
    for suf in UNIT_SUFFIXES:
        if column.endswith(suf) and len(column) > len(suf):
            return suf
    return None


def check_column_name(column: str) -> str | None:
    """Why a column name is not acceptable, or None if it is.

    Returns
    -------
    str or None
        A phrase ``expected ..., found ...`` for the error message.
    """
    if not column or not all(c.isalnum() or c == "_" for c in column):
        return f"expected a column name of letters, digits and '_', found '{column}'"
    for base, suf in KNOWN_SIGNALS.items():
        rest = column[len(base):]
        if (column.startswith(base + "_") and rest != suf and rest not in LINEAR_SUFFIXES
                and (rest in _NON_SI or rest in UNIT_SUFFIXES)):
            return f"expected '{base}{suf}' (SI unit suffix '{suf}'), found '{column}'"
    for bad in _NON_SI:
        if column.endswith(bad):
            return f"expected an SI unit suffix (one of {' '.join(UNIT_SUFFIXES)}), found '{bad}' in '{column}'"
    if unit_of(column) is None:
        return f"expected an SI unit suffix (one of {' '.join(UNIT_SUFFIXES)}) on column '{column}'"
    return None


# ---------------------------------------------------------------------------- reading

def _fail(path: Path, line: int, col: int, msg: str) -> LogError:
    return LogError(f"{path}:{line}:{col}: {msg}")


def _read_header(path: Path, first: str) -> list[str]:
    names = first.split(",")
    col = 1
    seen: set[str] = set()
    for name in names:
        stripped = name.strip()
        why = check_column_name(stripped)
        if why:
            raise _fail(path, 1, col, why)
        if stripped in seen:
            raise _fail(path, 1, col, f"expected each column once, found '{stripped}' twice")
        seen.add(stripped)
        col += len(name) + 1
    names = [n.strip() for n in names]
    if names[0] != "t_s":
        raise _fail(path, 1, 1, f"expected the first column to be 't_s', found '{names[0]}'")
    return names


def _slow_parse(path: Path, lines: list[str], ncol: int) -> np.ndarray:
    """Cell-by-cell parse that names the first bad place."""
    out = np.empty((len(lines) - 1, ncol))
    for i, line in enumerate(lines[1:]):
        lineno = i + 2
        cells = line.split(",")
        if len(cells) != ncol:
            raise _fail(path, lineno, len(line) + 1,
                        f"expected {ncol} values, found {len(cells)}")
        col = 1
        for j, cell in enumerate(cells):
            try:
                v = float(cell)
            except ValueError:
                raise _fail(path, lineno, col, f"expected a number, found '{cell.strip()[:40]}'") from None
            if not math.isfinite(v):
                raise _fail(path, lineno, col, f"expected a finite number, found '{cell.strip()}'")
            out[i, j] = v
            col += len(cell) + 1
    return out


def read_csv(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read the CSV part of a log.

    Parameters
    ----------
    path : path-like
        The ``.csv`` file.

    Returns
    -------
    dict of str to numpy.ndarray
        Column name -> float64 values (SI units as the suffix says).

    Raises
    ------
    LogError
        Unreadable, empty, truncated (no final newline or short row), a
        non-finite or non-numeric value, a column without an SI unit suffix,
        ``t_s`` missing or not strictly increasing.
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise LogError(f"{p}: cannot read: {e.strerror or e}") from None
    if not raw.strip():
        raise LogError(f"{p}:1:1: expected a header line of column names, found an empty file")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise LogError(f"{p}:{line}:1: expected ASCII text, found byte 0x{raw[e.start]:02x}") from None
    if "\r" in text:
        text = text.replace("\r\n", "\n")
    lines = text.split("\n")
    if lines[-1] != "":
        raise _fail(p, len(lines), len(lines[-1]) + 1,
                    "expected a newline at the end of the last row (file truncated?)")
    lines.pop()
    names = _read_header(p, lines[0])
    ncol = len(names)
    if len(lines) < 2:
        raise _fail(p, 2, 1, "expected at least one row of data, found end of file")
    data: np.ndarray | None = None
    try:
        data = np.loadtxt(lines[1:], delimiter=",", dtype=np.float64, ndmin=2)
        if data.shape != (len(lines) - 1, ncol) or not np.all(np.isfinite(data)):
            data = None
    except ValueError:
        data = None
    if data is None:
        data = _slow_parse(p, lines, ncol)
    t = data[:, 0]
    if t.size > 1:
        d = np.diff(t)
        bad = np.flatnonzero(~(d > 0))
        if bad.size:
            k = int(bad[0]) + 1
            raise _fail(p, k + 2, 1, f"expected t_s to increase, found {t[k]!r} after {t[k - 1]!r}")
    return {n: data[:, j].copy() for j, n in enumerate(names)}


def _type_ok(value: Any, want: type) -> bool:
    if want is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        try:
            return math.isfinite(value)
        except OverflowError:       # a JSON integer beyond the float range
            return False
    if want is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, want)


_TYPE_WORD = {float: "a finite number", int: "an integer", str: "a string", dict: "an object",
              list: "an array"}


def read_meta(path: str | os.PathLike[str], require_tag: bool = True) -> dict[str, Any]:
    """Read and validate a sidecar ``.json``.

    Parameters
    ----------
    path : path-like
        The sidecar.
    require_tag : bool
        If False, a sidecar without ``format`` / ``version`` is accepted (a user's own
        log with only ``gear_ratio`` and ``sample_period_s``); a tag that is present
        must still be this format's.

    Raises
    ------
    LogError
        Missing file, invalid JSON (with line and column), wrong format tag,
        a required key missing or a key of the wrong type.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise LogError(f"{p}: cannot read the log sidecar: {e.strerror or e}") from None
    except UnicodeDecodeError:
        raise LogError(f"{p}:1:1: expected UTF-8 JSON") from None
    try:
        meta = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as e:
        raise LogError(f"{p}:{e.lineno}:{e.colno}: expected JSON: {e.msg}") from None
    except ValueError as e:
        raise LogError(f"{p}: {e}") from None
    if not isinstance(meta, dict):
        raise LogError(f"{p}:1:1: expected a JSON object")
    if (require_tag or "format" in meta) and meta.get("format") != FORMAT:
        raise LogError(f"{p}: expected \"format\": \"{FORMAT}\", found {json.dumps(meta.get('format'))}")
    if (require_tag or "version" in meta) and meta.get("version") != FORMAT_VERSION:
        raise LogError(f"{p}: expected \"version\": {FORMAT_VERSION}, found {json.dumps(meta.get('version'))}")
    for key, want in REQUIRED_META.items():
        if key not in meta:
            raise LogError(f"{p}: expected key \"{key}\" ({_TYPE_WORD[want]})")
    for key, want in {**REQUIRED_META, **OPTIONAL_META}.items():
        if key in meta and not _type_ok(meta[key], want):
            raise LogError(f"{p}: key \"{key}\": expected {_TYPE_WORD[want]}, found {json.dumps(meta[key])}")
    if meta["gear_ratio"] == 0 or meta["sample_period_s"] <= 0:
        raise LogError(f"{p}: expected a non-zero gear_ratio and a positive sample_period_s")
    return meta


def _reject_constant(name: str) -> Any:
    raise ValueError(f"expected finite numbers, found {name}")


def read_log(path: str | os.PathLike[str], require_sidecar: bool = True, require_tag: bool = True) -> Log:
    """Read a log (CSV + sidecar).

    Parameters
    ----------
    path : path-like
        The ``.csv`` file; the sidecar is the ``.json`` beside it.
    require_sidecar : bool
        If False a missing sidecar gives empty ``meta``.
    require_tag : bool
        If False the sidecar's ``format`` / ``version`` tag may be absent (:func:`read_meta`).

    Returns
    -------
    Log
    """
    p = Path(path)
    cols = read_csv(p)
    side = sidecar_path(p)
    meta: dict[str, Any] = {}
    if side.exists() or require_sidecar:
        meta = read_meta(side, require_tag=require_tag)
        listed = meta.get("columns")
        if listed is not None and list(listed) != list(cols):
            raise LogError(f"{side}: key \"columns\": expected the CSV header {list(cols)}, found {listed}")
    return Log(columns=cols, meta=meta, path=p)


# ---------------------------------------------------------------------------- writing

def format_csv(columns: Mapping[str, Iterable[float]]) -> str:
    """The CSV text of a log (header + one row per sample, round-trip floats)."""
    names = list(columns)
    arrays = [np.asarray(columns[n], dtype=np.float64) for n in names]
    n = len(arrays[0]) if arrays else 0
    rows = [",".join(names)]
    mat = np.column_stack(arrays) if arrays else np.empty((0, 0))
    for i in range(n):
        rows.append(",".join(repr(float(v)) for v in mat[i]))
    return "\n".join(rows) + "\n"


def write_log(path: str | os.PathLike[str], columns: Mapping[str, Iterable[float]],
              meta: Mapping[str, Any]) -> None:
    """Write a log atomically (CSV then sidecar, each via temp file + rename).

    Parameters
    ----------
    path : path-like
        Destination ``.csv``; the sidecar goes beside it as ``.json``.
    columns : mapping of str to array-like
        Column name with SI unit suffix -> values; ``t_s`` first, strictly
        increasing; all the same length; finite.
    meta : mapping
        Sidecar content; ``format``, ``version`` and ``columns`` are filled in.

    Raises
    ------
    LogError
        Bad column names, lengths or values, or missing required metadata.
    """
    p = Path(path)
    names = list(columns)
    if not names or names[0] != "t_s":
        raise LogError(f"{p}: expected 't_s' as the first column, found {names[:1]}")
    for name in names:
        why = check_column_name(name)
        if why:
            raise LogError(f"{p}: {why}")
    arrays = {k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}
    n = len(arrays["t_s"])
    for k, a in arrays.items():
        if a.ndim != 1 or len(a) != n:
            raise LogError(f"{p}: column '{k}': expected {n} values, found shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise LogError(f"{p}: column '{k}': expected finite values")
    if n == 0:
        raise LogError(f"{p}: expected at least one sample")
    full = {"format": FORMAT, "version": FORMAT_VERSION, **dict(meta), "columns": names}
    for key, want in REQUIRED_META.items():
        if key not in full or not _type_ok(full[key], want):
            raise LogError(f"{p}: sidecar key \"{key}\": expected {_TYPE_WORD[want]}")
    write_text_atomic(p, format_csv(arrays))
    write_json_atomic(sidecar_path(p), full)
