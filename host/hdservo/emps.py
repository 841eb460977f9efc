"""EMPS benchmark: importer and inverse-model least-squares (IDIM-LS) reproduction.

EMPS (Janot, Gautier, Brunot 2019) is a real prismatic axis (DC motor, ball
screw, translating load) under a position-P / velocity-P controller.  The data
ship with the package in ``hdservo/data/emps`` (see ``PROVENANCE.md`` there:
source, checksums, citation).  This module

* reads the records (CSV, or the original ``.mat`` through scipy) into arrays
  with honest names and units: position ``qm`` in m, reference ``qg`` in m,
  controller output ``vir`` in V, force on the load side ``gtau*vir`` in N;
* converts a record into the hdservo log shape (docs/sim.md, logs) with
  linear-axis column names and a sidecar that states which rotary column each
  one plays the role of;
* reproduces the published IDIM-LS results with the authors' processing
  (zero-phase Butterworth, central differences, MATLAB-style ``decimate``).

Every problem with an input file raises :class:`hdservo.errors.UserError` with one
line naming the file, the line and what was expected.
"""
from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.io
import scipy.signal as sig

from . import resources
from .errors import UserError
from .fileio import write_json_atomic, write_text_atomic

#: Environment variable that overrides the default data directory.
ENV_DATA_DIR = "HDSERVO_EMPS_DIR"
#: The EMPS records and their provenance, shipped as package data.
DEFAULT_DATA_DIR = resources.data_path("emps")
#: Training (estimation) and test (validation) record names.
TRAIN_RECORD = "DATA_EMPS"
TEST_RECORD = "DATA_EMPS_PULSES"
#: Samples per record in the published benchmark (used to detect truncation).
BENCHMARK_SAMPLES = 24841
CONSTANTS_FILE = "EMPS_constants.csv"
REFERENCE_FILE = "reference_results.csv"

REQUIRED_COLUMNS: Tuple[str, ...] = ("t", "qm", "qg", "vir")
OPTIONAL_COLUMNS: Tuple[str, ...] = ("pulses_N",)
REQUIRED_CONSTANTS: Tuple[str, ...] = ("gtau", "kp", "kv", "Ts")

# ---- authors' processing (PROVENANCE.md, "Processing recipe") -------------------
BUTTER_ORDER = 4          #: order of the zero-phase position low-pass
BUTTER_CUTOFF_HZ = 100.0  #: its cutoff (5 x the 20 Hz position bandwidth), Hz
DROP_SAMPLES = 49         #: MATLAB keeps sample 50 onward (1-based)
DECIMATION = 10           #: parallel decimation factor

#: Reproduction targets of the brief: parameters (percent of the published value)
#: and relative errors (percentage points).
PARAM_TOL_PCT = 0.5
ERROR_TOL_PCT_POINTS = 0.1

SYMMETRIC_PARAMS: Tuple[str, ...] = ("M", "Fv", "Fc", "offset")
ASYMMETRIC_PARAMS: Tuple[str, ...] = ("M", "Fv_plus", "Fc_plus", "Fv_minus", "Fc_minus")

#: hdservo log columns of an EMPS record -> the rotary log column whose role
#: each one plays (the log format of docs/sim.md).  The axis is prismatic, so the names
#: keep the true SI units (m, N, V) instead of borrowing ``_rad``/``_Nm``.
LOG_COLUMN_ROLES: Dict[str, Optional[str]] = {
    "t_s": "t_s",
    "load_position_m": "load_angle_rad",
    "motor_force_N": "motor_torque_Nm",
    "setpoint_m": "setpoint_rad",
    "motor_command_V": None,
    "pulse_command_V": None,
}


# =================================================================================
# Importer
# =================================================================================

@dataclass(frozen=True)
class EmpsRecord:
    """One EMPS record on the load side of the prismatic axis.

    Attributes
    ----------
    name : str
        Record name (file stem), e.g. ``"DATA_EMPS"``.
    t_s : numpy.ndarray
        Time, s.
    position_m : numpy.ndarray
        Measured motor position converted to the load side (``qm``), m.
    reference_m : numpy.ndarray
        Position reference sent to the controller (``qg``), m.
    command_V : numpy.ndarray
        Controller output as measured by the dSPACE card (``vir``), V.
    pulses_V : numpy.ndarray or None
        Injected pulses (``pulses_N``, volt units despite the name, already
        included in ``command_V``), V; ``None`` in the training record.
    meta : dict
        ``source_file``, ``record``, ``n_samples``, ``sample_period_s``,
        ``measured_sample_period_s``, ``gtau_N_per_V``, ``kp_1_per_s``,
        ``kv_V_s_per_m`` and, when known, ``vir_saturation_V``.
    """

    name: str
    t_s: np.ndarray
    position_m: np.ndarray
    reference_m: np.ndarray
    command_V: np.ndarray
    pulses_V: Optional[np.ndarray]
    meta: Dict[str, Any] = field(default_factory=dict)

    @property
    def force_N(self) -> np.ndarray:
        """Motor force on the load side, ``gtau * vir``, N."""
        return self.meta["gtau_N_per_V"] * self.command_V

    @property
    def sample_period_s(self) -> float:
        """Nominal sample period, s."""
        return float(self.meta["sample_period_s"])


def resolve_data_dir(explicit: Optional[str] = None) -> Path:
    """Find the EMPS data directory.

    Parameters
    ----------
    explicit : str, optional
        A directory given on the command line (``--data``); wins over the rest.

    Returns
    -------
    pathlib.Path
        ``explicit``, else ``$HDSERVO_EMPS_DIR``, else the records shipped
        with the package (``hdservo/data/emps``).

    Raises
    ------
    UserError
        If the chosen directory does not exist.
    """
    if explicit:
        path, how = Path(explicit), "--data"
    elif os.environ.get(ENV_DATA_DIR):
        path, how = Path(os.environ[ENV_DATA_DIR]), ENV_DATA_DIR
    else:
        path, how = DEFAULT_DATA_DIR, "records shipped with hdservo"
    if not path.is_dir():
        raise UserError(f"{path}: EMPS data directory not found ({how}); expected a directory "
                        f"holding {TRAIN_RECORD}.csv; pass --data DIR or set {ENV_DATA_DIR}")
    return path


def _parse_float(path: Path, lineno: int, column: str, token: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise UserError(f"{path}: line {lineno}, column '{column}': expected a number, "
                        f"found {token.strip()!r}") from None
    if not math.isfinite(value):
        raise UserError(f"{path}: line {lineno}, column '{column}': expected a finite number, "
                        f"found {token.strip()!r}")
    return value


def _read_csv_table(path: Path, required: Sequence[str],
                    optional: Sequence[str] = ()) -> Tuple[Dict[str, np.ndarray], List[int]]:
    """Read a numeric CSV with a header line, checking every cell.

    Returns a dict column name -> float array for the required columns and the
    optional ones that are present, and the file line number of every row.
    """
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: file not found") from None
    except OSError as e:
        raise UserError(f"{path}: cannot read ({e.strerror})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise UserError(f"{path}: byte {e.start}: expected UTF-8 text") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise UserError(f"{path}: line 1: empty file, expected a header line "
                        f"'{','.join(required)}'")
    header = [h.strip() for h in lines[0].split(",")]
    for col in required:
        if col not in header:
            raise UserError(f"{path}: line 1: missing column '{col}' (header has "
                            f"{', '.join(header)}; expected {', '.join(required)})")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise UserError(f"{path}: line 1: duplicate column '{dup[0]}'")
    wanted = [c for c in header if c in required or c in optional]
    index = {c: header.index(c) for c in wanted}
    ncols = len(header)
    data_lines = [(i + 1, ln) for i, ln in enumerate(lines) if i > 0 and ln.strip()]
    if not data_lines:
        raise UserError(f"{path}: line 2: no data rows after the header, expected "
                        f"rows of {ncols} numbers")
    unterminated = not text.endswith(("\n", "\r"))
    last = data_lines[-1][0]
    rows = [ln.split(",") for _, ln in data_lines]
    for (lineno, _), fields in zip(data_lines, rows):
        if len(fields) != ncols:
            hint = " (file truncated?)" if lineno == last else ""
            raise UserError(f"{path}: line {lineno}: expected {ncols} comma-separated values "
                            f"({','.join(header)}), found {len(fields)}{hint}")
    out: Dict[str, np.ndarray] = {}
    for c in wanted:
        j = index[c]
        try:  # fast path; on failure, find and name the bad cell
            values = np.array([float(f[j]) for f in rows])
        except ValueError:
            values = np.empty(len(rows))
            for row, ((lineno, _), fields) in enumerate(zip(data_lines, rows)):
                try:
                    values[row] = _parse_float(path, lineno, c, fields[j])
                except UserError:
                    if lineno == last and unterminated:
                        raise UserError(f"{path}: line {lineno}: last line is incomplete, "
                                        f"expected {ncols} numbers and a line end "
                                        f"(file truncated?)") from None
                    raise
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            lineno = data_lines[int(bad[0])][0]
            raise UserError(f"{path}: line {lineno}, column '{c}': expected a finite number, "
                            f"found {rows[int(bad[0])][j].strip()!r}")
        out[c] = values
    return out, [lineno for lineno, _ in data_lines]


def load_constants(data_dir: Path) -> Dict[str, float]:
    """Read ``EMPS_constants.csv`` (``name,value,...``) into a dict.

    Returns
    -------
    dict
        At least ``gtau`` (N/V), ``kp`` (1/s), ``kv`` (V/(m/s)) and ``Ts`` (s);
        ``vir_saturation`` (V) when listed.
    """
    path = Path(data_dir) / CONSTANTS_FILE
    try:
        with path.open(newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        raise UserError(f"{path}: file not found (expected the EMPS constants "
                        f"{', '.join(REQUIRED_CONSTANTS)})") from None
    if not rows or "name" not in rows[0] or "value" not in rows[0]:
        raise UserError(f"{path}: line 1: expected a header with columns 'name' and 'value'")
    i_name, i_value = rows[0].index("name"), rows[0].index("value")
    consts: Dict[str, float] = {}
    for lineno, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) <= max(i_name, i_value):
            raise UserError(f"{path}: line {lineno}: expected at least "
                            f"{max(i_name, i_value) + 1} fields, found {len(row)}")
        consts[row[i_name].strip()] = _parse_float(path, lineno, "value", row[i_value])
    for name in REQUIRED_CONSTANTS:
        if name not in consts:
            raise UserError(f"{path}: missing constant '{name}' (expected rows "
                            f"{', '.join(REQUIRED_CONSTANTS)})")
        if consts[name] <= 0.0:
            raise UserError(f"{path}: constant '{name}' = {consts[name]!r}, expected > 0")
    return consts


def _read_mat(path: Path) -> Dict[str, Any]:
    try:
        mat = scipy.io.loadmat(str(path))
    except FileNotFoundError:
        raise UserError(f"{path}: file not found") from None
    except Exception as e:  # scipy raises several types for corrupt files
        raise UserError(f"{path}: not a readable MATLAB .mat file ({e})") from None
    out: Dict[str, Any] = {}
    for name in REQUIRED_COLUMNS + OPTIONAL_COLUMNS + ("gtau", "kp", "kv"):
        if name not in mat:
            if name in OPTIONAL_COLUMNS:
                continue
            raise UserError(f"{path}: missing variable '{name}' (expected "
                            f"{', '.join(REQUIRED_COLUMNS + ('gtau', 'kp', 'kv'))})")
        arr = np.asarray(mat[name], dtype=float).ravel()
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise UserError(f"{path}: variable '{name}', element {bad[0] + 1}: "
                            f"expected a finite number, found {arr[bad[0]]!r}")
        out[name] = arr
    return out


def load_record(path: Path | str, constants: Optional[Dict[str, float]] = None) -> EmpsRecord:
    """Read one EMPS record from ``.csv`` or ``.mat``.

    Parameters
    ----------
    path : path-like
        ``DATA_EMPS.csv``, ``DATA_EMPS_PULSES.mat``, ...
    constants : dict, optional
        Output of :func:`load_constants`.  Default: read ``EMPS_constants.csv``
        beside the record (the ``.mat`` files also carry ``gtau``, ``kp``, ``kv``
        and then win for those three).

    Returns
    -------
    EmpsRecord
    """
    path = Path(path)
    if constants is None:
        constants = load_constants(path.parent)
    consts = dict(constants)
    if path.suffix.lower() == ".mat":
        cols = _read_mat(path)
        for k in ("gtau", "kp", "kv"):
            consts[k] = float(cols.pop(k)[0])
        where = [f"element {k + 1}" for k in range(len(cols["t"]))]
    elif path.suffix.lower() == ".csv":
        cols, linenos = _read_csv_table(path, REQUIRED_COLUMNS, OPTIONAL_COLUMNS)
        where = [f"line {k}" for k in linenos]
    else:
        raise UserError(f"{path}: unknown file type '{path.suffix}', expected .csv or .mat")
    n = len(cols["t"])
    for name, arr in cols.items():
        if len(arr) != n:
            raise UserError(f"{path}: '{name}' has {len(arr)} samples, expected {n} like 't'")
    if n < 2:
        raise UserError(f"{path}: {n} sample(s), expected a time series")
    dt = np.diff(cols["t"])
    bad = np.flatnonzero(dt <= 0.0)
    if bad.size:
        k = int(bad[0]) + 1
        raise UserError(f"{path}: {where[k]}, column 't': time does not increase "
                        f"({cols['t'][k]!r} after {cols['t'][k - 1]!r})")
    ts = float(consts["Ts"])
    measured = float(np.mean(dt))
    if abs(measured - ts) > 0.01 * ts:
        raise UserError(f"{path}: mean time step {measured:.6g} s, expected the sample "
                        f"period Ts = {ts:.6g} s of {CONSTANTS_FILE} (within 1 %)")
    meta: Dict[str, Any] = {
        "source_file": path.name,
        "record": path.stem,
        "n_samples": n,
        "sample_period_s": ts,
        "measured_sample_period_s": measured,
        "gtau_N_per_V": float(consts["gtau"]),
        "kp_1_per_s": float(consts["kp"]),
        "kv_V_s_per_m": float(consts["kv"]),
    }
    if "vir_saturation" in consts:
        meta["vir_saturation_V"] = float(consts["vir_saturation"])
    return EmpsRecord(name=path.stem, t_s=cols["t"], position_m=cols["qm"],
                      reference_m=cols["qg"], command_V=cols["vir"],
                      pulses_V=cols.get("pulses_N"), meta=meta)


def load_benchmark_record(data_dir: Path, name: str, fmt: str = "auto") -> EmpsRecord:
    """Load a published record by name and check it has the benchmark length.

    Parameters
    ----------
    data_dir : pathlib.Path
        EMPS data directory.
    name : str
        ``"DATA_EMPS"`` or ``"DATA_EMPS_PULSES"``.
    fmt : {"auto", "csv", "mat"}
        ``auto`` takes the CSV and falls back to the ``.mat`` file.
    """
    csv_path, mat_path = data_dir / f"{name}.csv", data_dir / f"{name}.mat"
    if fmt == "auto":
        path = csv_path if csv_path.exists() or not mat_path.exists() else mat_path
    elif fmt in ("csv", "mat"):
        path = csv_path if fmt == "csv" else mat_path
    else:
        raise UserError(f"unknown format '{fmt}', expected auto, csv or mat")
    rec = load_record(path, load_constants(data_dir))
    if rec.meta["n_samples"] != BENCHMARK_SAMPLES:
        raise UserError(f"{path}: {rec.meta['n_samples']} samples, expected "
                        f"{BENCHMARK_SAMPLES} as published (file truncated?)")
    return rec


# ---- hdservo log shape -----------------------------------------------------------

def to_log_columns(rec: EmpsRecord) -> Dict[str, np.ndarray]:
    """The record as hdservo log columns (see :data:`LOG_COLUMN_ROLES`).

    ``load_position_m`` = ``qm`` (m), ``motor_force_N`` = ``gtau*vir`` (N),
    ``setpoint_m`` = ``qg`` (m), ``motor_command_V`` = ``vir`` (V) and, in the
    pulses record, ``pulse_command_V`` = ``pulses_N`` (V, already in ``vir``).
    """
    cols = {
        "t_s": rec.t_s,
        "load_position_m": rec.position_m,
        "motor_force_N": rec.force_N,
        "setpoint_m": rec.reference_m,
        "motor_command_V": rec.command_V,
    }
    if rec.pulses_V is not None:
        cols["pulse_command_V"] = rec.pulses_V
    return cols


def log_sidecar(rec: EmpsRecord) -> Dict[str, Any]:
    """JSON sidecar of :func:`to_log_columns` (the log format of docs/sim.md)."""
    cols = to_log_columns(rec)
    return {
        # same tag and version as the hdservo log sidecar (hdservo.logio)
        "format": "hdservo-log",
        "version": 1,
        "source": "EMPS benchmark (Janot, Gautier, Brunot 2019), nonlinearbenchmark.org",
        "record": rec.name,
        "source_file": rec.meta["source_file"],
        "axis_kind": "prismatic",
        "sample_period_s": rec.sample_period_s,
        "n_samples": rec.meta["n_samples"],
        "gear_ratio": 1.0,
        "gear_note": "every column is already on the load side (qm is the motor encoder "
                     "converted by the authors); the ball-screw lead is not published",
        "motor_encoder_counts_per_rev": 50000,
        "gains": {"gtau_N_per_V": rec.meta["gtau_N_per_V"],
                  "kp_1_per_s": rec.meta["kp_1_per_s"],
                  "kv_V_s_per_m": rec.meta["kv_V_s_per_m"]},
        "running": "closed loop: vir = kv*(kp*(qg - qm) - v), bang-bang acceleration "
                   "reference" + (", force pulses added to vir" if rec.pulses_V is not None
                                  else ""),
        "column_roles": {c: LOG_COLUMN_ROLES[c] for c in cols},
        "columns": list(cols),
    }


def write_json(path: Path | str, obj: Any) -> None:
    """Write ``obj`` as strict indented JSON (:func:`hdservo.fileio.write_json_atomic`), making its directory."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, obj)


def write_log(rec: EmpsRecord, csv_path: Path | str) -> None:
    """Write the record as an hdservo log CSV plus ``<name>.json`` sidecar."""
    csv_path = Path(csv_path)
    cols = to_log_columns(rec)
    names = list(cols)
    mat = np.column_stack([cols[c] for c in names])
    lines = [",".join(names)] + [",".join(repr(float(v)) for v in row) for row in mat]
    csv_path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(csv_path, "\n".join(lines) + "\n", newline="")
    write_json(csv_path.with_suffix(".json"), log_sidecar(rec))


# =================================================================================
# IDIM-LS
# =================================================================================

def matlab_filtfilt(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Zero-phase filtering with MATLAB's ``filtfilt`` end handling.

    Odd reflection padding of ``3*(max(len(a), len(b)) - 1)`` samples (scipy's
    default is longer and moves the EMPS estimates by 0.1-0.3 %).
    """
    pad = 3 * (max(len(a), len(b)) - 1)
    if len(x) <= pad:
        raise UserError(f"signal of {len(x)} samples is too short to filter, "
                        f"expected more than {pad}")
    return sig.filtfilt(b, a, x, padtype="odd", padlen=pad)


def matlab_decimate(x: np.ndarray, r: int) -> np.ndarray:
    """MATLAB ``decimate(x, r)``: Chebyshev-I IIR, zero phase, last sample kept.

    Order 8, 0.05 dB ripple, cutoff 0.8 x (Nyquist / r), reduced the way MATLAB
    does when the design is inaccurate; keeps samples ``nbeg-1::r`` with
    ``nbeg = r - (r*ceil(N/r) - N)``.
    """
    rip, order = 0.05, 8
    b, a = sig.cheby1(order, rip, 0.8 / r)
    while order > 1:
        _, h = sig.freqz(b, a, worN=[0.8 / r * np.pi])
        if np.all(b == 0) or abs(20 * np.log10(abs(h[0])) + rip) > 1e-6:
            order -= 1
            b, a = sig.cheby1(order, rip, 0.8 / r)
        else:
            break
    y = matlab_filtfilt(b, a, np.asarray(x, dtype=float))
    n = len(x)
    nbeg = r - (r * math.ceil(n / r) - n)
    return y[nbeg - 1::r]


def derivatives(position_m: np.ndarray, ts: float,
                cutoff_Hz: float = BUTTER_CUTOFF_HZ,
                order: int = BUTTER_ORDER) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Filtered position, velocity and acceleration.

    Parameters
    ----------
    position_m : numpy.ndarray
        Measured position, m.
    ts : float
        Sample period, s.
    cutoff_Hz : float
        Cutoff of the zero-phase Butterworth low-pass, Hz.
    order : int
        Butterworth order (the forward-backward pass doubles it).

    Returns
    -------
    qf, qd, qdd : numpy.ndarray
        Position (m), velocity (m/s) and acceleration (m/s^2); central
        differences inside, one-sided at the ends (MATLAB ``gradient``).
    """
    b, a = sig.butter(order, 2.0 * cutoff_Hz * ts)
    qf = matlab_filtfilt(b, a, position_m)
    qd = np.gradient(qf, ts)
    qdd = np.gradient(qd, ts)
    return qf, qd, qdd


def observation_matrix(qd: np.ndarray, qdd: np.ndarray, model: str) -> np.ndarray:
    """IDIM observation matrix of the force model.

    ``symmetric``: columns ``[qdd, qd, sign(qd), 1]`` for ``(M, Fv, Fc, offset)``.
    ``asymmetric``: ``[qdd, qd*(qd>0), (qd>0), qd*(qd<0), -(qd<0)]`` for
    ``(M, Fv+, Fc+, Fv-, Fc-)``, so every Coulomb level comes out positive.
    """
    if model == "symmetric":
        return np.column_stack([qdd, qd, np.sign(qd), np.ones_like(qd)])
    if model == "asymmetric":
        pos, neg = (qd > 0).astype(float), (qd < 0).astype(float)
        return np.column_stack([qdd, qd * pos, pos, qd * neg, -neg])
    raise ValueError(f"unknown friction model {model!r}")


PARAMS = {"symmetric": SYMMETRIC_PARAMS, "asymmetric": ASYMMETRIC_PARAMS}


@dataclass(frozen=True)
class IdimSystem:
    """Decimated IDIM system ``y = X theta`` of one record and one model.

    Attributes
    ----------
    X : numpy.ndarray
        Decimated observation matrix (rows x parameters), SI units per column.
    y : numpy.ndarray
        Decimated force ``gtau*vir``, N.
    abs_diag_R : numpy.ndarray
        |diag R| of the QR factorisation of the undecimated matrix.
    """

    model: str
    X: np.ndarray
    y: np.ndarray
    abs_diag_R: np.ndarray


def build_system(rec: EmpsRecord, model: str, drop: int = DROP_SAMPLES,
                 decimation: int = DECIMATION) -> IdimSystem:
    """Apply the authors' processing chain to one record (see module doc)."""
    if rec.meta["n_samples"] <= drop + 30 * decimation:
        raise UserError(f"{rec.meta['source_file']}: {rec.meta['n_samples']} samples, expected "
                        f"more than {drop + 30 * decimation} for IDIM-LS")
    _, qd, qdd = derivatives(rec.position_m, rec.sample_period_s)
    X = observation_matrix(qd, qdd, model)[drop:]
    y = rec.force_N[drop:]
    r = np.linalg.qr(X, mode="r")
    Xd = np.column_stack([matlab_decimate(c, decimation) for c in X.T])
    yd = matlab_decimate(y, decimation)
    return IdimSystem(model=model, X=Xd, y=yd, abs_diag_R=np.abs(np.diag(r)))


@dataclass(frozen=True)
class LsResult:
    """Least-squares estimate (or the residual of given parameters) on one system.

    Attributes
    ----------
    names : tuple of str
        Parameter names; units kg, N/(m/s), N.
    theta, std, rel_std_pct : numpy.ndarray
        Estimates, their standard deviations ``std(e)*sqrt(diag(inv(X'X)))`` and
        the relative standard deviations in percent.
    cond : float
        Condition number of the decimated observation matrix.
    error_norm : float
        2-norm of the force residual, N.
    relative_error_pct : float
        ``100*||y - X theta|| / ||y||``, percent.
    error_std : float
        Standard deviation of the residual (N-1 normalisation), N.
    n_rows : int
        Rows of the decimated system.
    abs_diag_R : numpy.ndarray
        |diag R| of the undecimated observation matrix.
    """

    names: Tuple[str, ...]
    theta: np.ndarray
    std: np.ndarray
    rel_std_pct: np.ndarray
    cond: float
    error_norm: float
    relative_error_pct: float
    error_std: float
    n_rows: int
    abs_diag_R: np.ndarray

    def params(self) -> Dict[str, float]:
        """Parameters as a name -> value dict."""
        return {n: float(v) for n, v in zip(self.names, self.theta)}


def solve(system: IdimSystem, theta: Optional[np.ndarray] = None) -> LsResult:
    """Ordinary least squares on ``system`` (or evaluate given ``theta``)."""
    X, y = system.X, system.y
    if np.linalg.matrix_rank(X) < X.shape[1]:
        raise UserError(f"IDIM-LS {system.model}: observation matrix is rank deficient "
                        f"(the record does not excite every parameter)")
    if theta is None:
        theta = np.linalg.lstsq(X, y, rcond=None)[0]
    e = y - X @ theta
    err_std = float(np.std(e, ddof=1))
    std = err_std * np.sqrt(np.diag(np.linalg.inv(X.T @ X)))
    return LsResult(names=PARAMS[system.model], theta=np.asarray(theta, dtype=float),
                    std=std, rel_std_pct=100.0 * std / np.abs(theta),
                    cond=float(np.linalg.cond(X)), error_norm=float(np.linalg.norm(e)),
                    relative_error_pct=float(100.0 * np.linalg.norm(e) / np.linalg.norm(y)),
                    error_std=err_std, n_rows=int(X.shape[0]), abs_diag_R=system.abs_diag_R)


@dataclass(frozen=True)
class Reproduction:
    """The three published IDIM-LS blocks, recomputed."""

    symmetric: LsResult
    asymmetric: LsResult
    cross_test: LsResult


def reproduce(train: EmpsRecord, test: EmpsRecord) -> Reproduction:
    """IDIM-LS on ``train`` (both models) and the symmetric cross-test on ``test``."""
    sym = solve(build_system(train, "symmetric"))
    asym = solve(build_system(train, "asymmetric"))
    cross = solve(build_system(test, "symmetric"), theta=sym.theta)
    return Reproduction(symmetric=sym, asymmetric=asym, cross_test=cross)


# ---- comparison with the published numbers --------------------------------------

def read_published(path: Path | str) -> Dict[str, Dict[str, float]]:
    """Read ``reference_results.csv`` into ``{case: {quantity: value}}``."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        raise UserError(f"{path}: file not found (expected the published EMPS results)") from None
    need = ("case", "quantity", "value")
    if not rows or any(c not in rows[0] for c in need):
        raise UserError(f"{path}: line 1: expected a header with columns {', '.join(need)}")
    ic, iq, iv = (rows[0].index(c) for c in need)
    out: Dict[str, Dict[str, float]] = {}
    for lineno, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) <= max(ic, iq, iv):
            raise UserError(f"{path}: line {lineno}: expected {len(rows[0])} fields, "
                            f"found {len(row)}")
        out.setdefault(row[ic], {})[row[iq]] = _parse_float(path, lineno, "value", row[iv])
    return out


def result_dict(rep: Reproduction) -> Dict[str, Any]:
    """The ``build/verify/emps.json`` core: estimates and relative errors."""
    sym = rep.symmetric.params()
    sym["relative_error_pct"] = rep.symmetric.relative_error_pct
    asym = rep.asymmetric.params()
    asym["relative_error_pct"] = rep.asymmetric.relative_error_pct
    return {"symmetric": sym, "asymmetric": asym,
            "cross_test_relative_error_pct": rep.cross_test.relative_error_pct}


def published_dict(pub: Dict[str, Dict[str, float]]) -> Dict[str, Any]:
    """The published numbers in the same shape as :func:`result_dict`."""
    try:
        sym = {p: pub["idim_ls_symmetric"][p] for p in SYMMETRIC_PARAMS + ("relative_error_pct",)}
        asym = {p: pub["idim_ls_asymmetric"][p]
                for p in ASYMMETRIC_PARAMS + ("relative_error_pct",)}
        cross = pub["cross_test_pulses"]["relative_error_pct"]
    except KeyError as e:
        raise UserError(f"{REFERENCE_FILE}: missing published value {e.args[0]!r}") from None
    return {"symmetric": sym, "asymmetric": asym, "cross_test_relative_error_pct": cross}


def deviation_dict(ours: Dict[str, Any], published: Dict[str, Any]) -> Dict[str, Any]:
    """Deviations: parameters in percent of the published value, relative errors in
    percentage points, and whether every one is within the targets."""
    dev: Dict[str, Any] = {}
    ok = True
    for block in ("symmetric", "asymmetric"):
        d: Dict[str, float] = {}
        for key, mine in ours[block].items():
            ref = published[block][key]
            if key == "relative_error_pct":
                d["relative_error_pct_points"] = mine - ref
                ok &= abs(mine - ref) <= ERROR_TOL_PCT_POINTS
            else:
                d[f"{key}_pct"] = 100.0 * (mine - ref) / abs(ref)
                ok &= abs(mine - ref) <= PARAM_TOL_PCT / 100.0 * abs(ref)
        dev[block] = d
    cross = ours["cross_test_relative_error_pct"] - published["cross_test_relative_error_pct"]
    dev["cross_test_relative_error_pct_points"] = cross
    ok &= abs(cross) <= ERROR_TOL_PCT_POINTS
    dev["tolerance"] = {"parameter_pct": PARAM_TOL_PCT,
                        "relative_error_pct_points": ERROR_TOL_PCT_POINTS}
    dev["within_tolerance"] = bool(ok)
    return dev


def verify(data_dir: Path, fmt: str = "auto") -> Tuple[Dict[str, Any], Reproduction]:
    """Load both records, reproduce IDIM-LS and compare with the published values.

    Returns
    -------
    report : dict
        :func:`result_dict` plus ``published`` and ``deviation`` blocks (these two
        only when ``reference_results.csv`` is present).
    rep : Reproduction
        The full results (standard deviations, condition numbers, ...).
    """
    train = load_benchmark_record(data_dir, TRAIN_RECORD, fmt)
    test = load_benchmark_record(data_dir, TEST_RECORD, fmt)
    rep = reproduce(train, test)
    report = result_dict(rep)
    ref_path = data_dir / REFERENCE_FILE
    if ref_path.exists():
        pub = published_dict(read_published(ref_path))
        report["published"] = pub
        report["deviation"] = deviation_dict(result_dict(rep), pub)
    return report, rep


def summary_lines(report: Dict[str, Any], rep: Reproduction) -> List[str]:
    """Human summary: each estimate next to the published one."""
    pub = report.get("published")
    lines = []
    blocks = (("symmetric", rep.symmetric), ("asymmetric", rep.asymmetric))
    for block, res in blocks:
        lines.append(f"IDIM-LS {block} ({res.n_rows} rows, cond {res.cond:.4f}):")
        for i, name in enumerate(res.names):
            ref = f"  published {pub[block][name]:>10.4f}" if pub else ""
            lines.append(f"  {name:<9}{res.theta[i]:>10.4f} +- {res.std[i]:.4f}{ref}")
        ref = f"  published {pub[block]['relative_error_pct']:.4f} %" if pub else ""
        lines.append(f"  relative error {res.relative_error_pct:.4f} %{ref}")
    ref = f"  published {pub['cross_test_relative_error_pct']:.4f} %" if pub else ""
    lines.append(f"cross-test on {TEST_RECORD} (cond {rep.cross_test.cond:.4f}): relative "
                 f"error {rep.cross_test.relative_error_pct:.4f} %{ref}")
    if pub:
        ok = report["deviation"]["within_tolerance"]
        lines.append("within tolerance (parameters 0.5 %, errors 0.1 points): "
                     + ("yes" if ok else "NO"))
    return lines
