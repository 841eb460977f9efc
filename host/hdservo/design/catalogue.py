"""Typed, validated loaders for the component catalogues in :mod:`hdservo.data`.

Three CSV catalogues ship with the package (``host/hdservo/data/``):

* ``harmonic_drives.csv`` -- cup-type harmonic drives (CSF/CSG), sizes 14-50,
  ratios 50-160: torque ratings, three-slope stiffness, accuracy bounds,
  inertia, mass, speed limits, starting torque where published;
* ``motors.csv`` -- representative frameless PMSM classes;
* ``sensors.csv`` -- representative motor encoders, output ring encoders and
  rate gyros.

Every row names, per value group, a key of ``sources.toml`` which cites the
catalogue table or states the rule by which a value was derived or estimated.

Lines starting with ``#`` are comments.  A bad file raises
:class:`CatalogueError` (a :class:`hdservo.errors.UserError`) whose message is one
line naming the file, the line, the row and the field.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Type, TypeVar

from .. import resources
from ..errors import UserError
from ..tomltext import read_toml_file

#: Directory of the catalogue data files (installed as package data).
DATA_DIR: Path = resources.DATA_DIR

SOURCE_KINDS = ("catalogue", "derived", "estimated", "representative")


class CatalogueError(UserError):
    """A catalogue file is malformed; the message is one line (file, line, row, field)."""


# --------------------------------------------------------------------------- sources
@dataclass(frozen=True)
class Source:
    """One entry of ``sources.toml``.

    Attributes
    ----------
    key : str
        Name used in the ``src_*`` / ``source`` columns.
    kind : str
        ``catalogue``, ``derived``, ``estimated`` or ``representative``.
    citation : str
        Where the figures come from.
    rule : str
        How derived/estimated values were obtained, or notes on the figures.
    """

    key: str
    kind: str
    citation: str
    rule: str


def load_sources(path: Optional[Path] = None) -> Dict[str, Source]:
    """Load and validate ``sources.toml``.

    Parameters
    ----------
    path : Path, optional
        File to read; default the packaged ``sources.toml``.

    Returns
    -------
    dict of str to Source
    """
    path = Path(path) if path is not None else DATA_DIR / "sources.toml"
    doc = read_toml_file(path, CatalogueError)
    out: Dict[str, Source] = {}
    for key, entry in doc.items():
        if not isinstance(entry, dict):
            raise CatalogueError(f"{path}: [{key}]: expected a table with kind, citation, rule")
        for name in ("kind", "citation", "rule"):
            if not isinstance(entry.get(name), str) or not entry[name].strip():
                raise CatalogueError(f"{path}: [{key}] field '{name}': expected a non-empty string")
        if entry["kind"] not in SOURCE_KINDS:
            raise CatalogueError(f"{path}: [{key}] field 'kind': expected one of "
                                 f"{', '.join(SOURCE_KINDS)}, got '{entry['kind']}'")
        out[key] = Source(key, entry["kind"], entry["citation"], entry["rule"])
    return out


# --------------------------------------------------------------------------- rows
@dataclass(frozen=True)
class GearRow:
    """One harmonic drive (series, size, ratio). Torques at the output in N·m,
    stiffness in N·m/rad at the output, angles in arcmin, inertia at the input
    (wave generator side) in kg·m²."""

    series: str
    size: int
    ratio: int
    rated_torque_Nm: float
    repeated_peak_torque_Nm: float
    average_torque_Nm: float
    momentary_peak_torque_Nm: float
    src_torque: str
    t1_Nm: float
    t2_Nm: float
    k1_Nm_per_rad: float
    k2_Nm_per_rad: float
    k3_Nm_per_rad: float
    src_stiffness: str
    hysteresis_loss_max_arcmin: float
    lost_motion_max_arcmin: float
    transmission_accuracy_max_arcmin: float
    repeatability_max_arcmin: float
    src_accuracy: str
    input_inertia_kgm2: float
    mass_kg: float
    max_input_speed_rpm: float
    avg_input_speed_rpm: float
    src_inertia_mass_speed: str
    starting_torque_input_Nm: Optional[float]
    backdriving_torque_output_Nm: Optional[float]
    src_starting: Optional[str]

    @property
    def name(self) -> str:
        """Catalogue designation, e.g. ``CSF-25-100``."""
        return f"{self.series}-{self.size}-{self.ratio}"


@dataclass(frozen=True)
class MotorRow:
    """A frameless PMSM class (representative figures, see ``source``)."""

    name: str
    outer_diameter_mm: float
    stack_length_mm: float
    kt_Nm_per_A: float
    continuous_torque_Nm: float
    peak_torque_Nm: float
    continuous_current_A: float
    peak_current_A: float
    resistance_ohm: float
    rotor_inertia_kgm2: float
    max_speed_rpm: float
    mass_kg: float
    source: str


@dataclass(frozen=True)
class SensorRow:
    """An encoder (``motor_encoder``/``output_encoder``) or a ``rate_gyro``.

    Encoders use ``bits_per_rev``, ``accuracy_arcsec``, ``noise_arcsec_rms``;
    gyros use ``noise_density_deg_s_rtHz`` ((°/s)/√Hz), ``bias_instability_deg_h``,
    ``bandwidth_Hz`` and ``range_deg_s``.  Fields that do not apply are None.
    """

    name: str
    kind: str
    bits_per_rev: Optional[int]
    accuracy_arcsec: Optional[float]
    noise_arcsec_rms: Optional[float]
    update_rate_Hz: float
    noise_density_deg_s_rtHz: Optional[float]
    bias_instability_deg_h: Optional[float]
    bandwidth_Hz: Optional[float]
    range_deg_s: Optional[float]
    source: str

    @property
    def lsb_rad(self) -> Optional[float]:
        """Angular quantum of an encoder in rad (None for a gyro)."""
        return None if self.bits_per_rev is None else 2.0 * math.pi / 2 ** self.bits_per_rev


# --------------------------------------------------------------------------- parsing
T = TypeVar("T")


class _Ctx:
    """Location of the value being parsed, for one-line error messages."""

    def __init__(self, path: Path, line: int, row: str) -> None:
        self.path, self.line, self.row = path, line, row

    def fail(self, field: str, what: str) -> CatalogueError:
        return CatalogueError(f"{self.path}:{self.line}: row '{self.row}' field '{field}': {what}")


def _num(ctx: _Ctx, field: str, text: str, *, optional: bool = False, positive: bool = True,
         integer: bool = False) -> Any:
    text = text.strip()
    if text == "":
        if optional:
            return None
        raise ctx.fail(field, "expected a number, got an empty cell")
    try:
        val = int(text) if integer else float(text)
    except ValueError:
        kind = "an integer" if integer else "a number"
        raise ctx.fail(field, f"expected {kind}, got '{text}'") from None
    if not math.isfinite(val) or (positive and val <= 0):
        raise ctx.fail(field, f"expected a finite positive value, got '{text}'")
    return val


def _read_csv(path: Path) -> Tuple[List[str], List[Tuple[int, List[str]]]]:
    """Return the header and (line number, cells) of every data row."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise CatalogueError(f"{path}: cannot read: {e.strerror}") from None
    except UnicodeDecodeError:
        raise CatalogueError(f"{path}: not UTF-8 text") from None
    numbered = [(i + 1, ln) for i, ln in enumerate(lines)
                if ln.strip() and not ln.lstrip().startswith("#")]
    if not numbered:
        raise CatalogueError(f"{path}: no header line")
    rows = list(csv.reader([ln for _, ln in numbered]))
    header = [h.strip() for h in rows[0]]
    return header, [(numbered[i][0], r) for i, r in enumerate(rows) if i > 0]


def _load_rows(path: Path, cls: Type[T], row_name: Callable[[Dict[str, str]], str],
               parse: Callable[[_Ctx, Dict[str, str]], Dict[str, Any]],
               sources: Dict[str, Source], source_fields: Sequence[str]) -> List[T]:
    header, rows = _read_csv(path)
    expected = [f.name for f in fields(cls)]  # type: ignore[arg-type]
    missing = [c for c in expected if c not in header]
    if missing:
        raise CatalogueError(f"{path}: header: missing column(s) {', '.join(missing)}")
    unknown = [c for c in header if c not in expected]
    if unknown:
        raise CatalogueError(f"{path}: header: unknown column(s) {', '.join(unknown)}")
    out: List[T] = []
    for line, cells in rows:
        if len(cells) != len(header):
            raise CatalogueError(f"{path}:{line}: expected {len(header)} cells, got {len(cells)}")
        rec = {h: c.strip() for h, c in zip(header, cells)}
        ctx = _Ctx(path, line, row_name(rec))
        values = parse(ctx, rec)
        for sf in source_fields:
            key = values.get(sf)
            if key is not None and key not in sources:
                raise ctx.fail(sf, f"expected a key of sources.toml, got '{key}'")
        out.append(cls(**values))
    if not out:
        raise CatalogueError(f"{path}: no data rows")
    return out


def _parse_gear(ctx: _Ctx, r: Dict[str, str]) -> Dict[str, Any]:
    v: Dict[str, Any] = {}
    if r["series"] not in ("CSF", "CSG"):
        raise ctx.fail("series", f"expected CSF or CSG, got '{r['series']}'")
    v["series"] = r["series"]
    v["size"] = _num(ctx, "size", r["size"], integer=True)
    v["ratio"] = _num(ctx, "ratio", r["ratio"], integer=True)
    for f in fields(GearRow):
        n = f.name
        if n in v:
            continue
        if n.startswith("src_"):
            v[n] = r[n] or None
            if v[n] is None and n != "src_starting":
                raise ctx.fail(n, "expected a source key, got an empty cell")
        else:
            v[n] = _num(ctx, n, r[n], optional=n in ("starting_torque_input_Nm",
                                                    "backdriving_torque_output_Nm"))
    if (v["starting_torque_input_Nm"] is None) != (v["src_starting"] is None):
        raise ctx.fail("src_starting", "expected a source exactly when a starting torque is given")
    if not v["t1_Nm"] < v["t2_Nm"]:
        raise ctx.fail("t2_Nm", f"expected T2 > T1 = {v['t1_Nm']:g} N·m")
    if not v["k1_Nm_per_rad"] <= v["k2_Nm_per_rad"] <= v["k3_Nm_per_rad"]:
        raise ctx.fail("k3_Nm_per_rad", "expected K1 <= K2 <= K3 (the gear stiffens with torque)")
    if not v["rated_torque_Nm"] <= v["repeated_peak_torque_Nm"] <= v["momentary_peak_torque_Nm"]:
        raise ctx.fail("momentary_peak_torque_Nm",
                       "expected rated <= repeated peak <= momentary peak torque")
    return v


def _parse_motor(ctx: _Ctx, r: Dict[str, str]) -> Dict[str, Any]:
    v: Dict[str, Any] = {"name": r["name"], "source": r["source"]}
    if not v["name"]:
        raise ctx.fail("name", "expected a name")
    for f in fields(MotorRow):
        if f.name not in v:
            v[f.name] = _num(ctx, f.name, r[f.name])
    if v["continuous_torque_Nm"] > v["peak_torque_Nm"]:
        raise ctx.fail("peak_torque_Nm", "expected peak torque >= continuous torque")
    kt_ip = v["kt_Nm_per_A"] * v["peak_current_A"]
    if not 0.7 <= v["peak_torque_Nm"] / kt_ip <= 1.05:
        raise ctx.fail("peak_torque_Nm", f"expected about Kt x peak current = {kt_ip:.3g} N·m "
                       "(0.7-1.05 of it, allowing for saturation)")
    return v


def _parse_sensor(ctx: _Ctx, r: Dict[str, str]) -> Dict[str, Any]:
    kinds = ("motor_encoder", "output_encoder", "rate_gyro")
    if r["kind"] not in kinds:
        raise ctx.fail("kind", f"expected one of {', '.join(kinds)}, got '{r['kind']}'")
    enc = r["kind"] != "rate_gyro"
    v: Dict[str, Any] = {"name": r["name"], "kind": r["kind"], "source": r["source"]}
    v["update_rate_Hz"] = _num(ctx, "update_rate_Hz", r["update_rate_Hz"])
    v["bits_per_rev"] = _num(ctx, "bits_per_rev", r["bits_per_rev"], integer=True, optional=not enc)
    for n in ("accuracy_arcsec", "noise_arcsec_rms"):
        v[n] = _num(ctx, n, r[n], optional=not enc)
    for n in ("noise_density_deg_s_rtHz", "bias_instability_deg_h", "bandwidth_Hz", "range_deg_s"):
        v[n] = _num(ctx, n, r[n], optional=enc)
    group = ("bits_per_rev", "accuracy_arcsec", "noise_arcsec_rms") if not enc else (
        "noise_density_deg_s_rtHz", "bias_instability_deg_h", "bandwidth_Hz", "range_deg_s")
    for n in group:
        if v[n] is not None:
            raise ctx.fail(n, f"expected an empty cell for kind '{r['kind']}'")
    if enc and not 12 <= v["bits_per_rev"] <= 32:
        raise ctx.fail("bits_per_rev", f"expected 12-32 bits, got {v['bits_per_rev']}")
    return v


def load_gears(path: Optional[Path] = None,
               sources: Optional[Dict[str, Source]] = None) -> List[GearRow]:
    """Load the harmonic-drive catalogue.

    Parameters
    ----------
    path : Path, optional
        CSV file; default the packaged ``harmonic_drives.csv``.
    sources : dict, optional
        Result of :func:`load_sources`; default the packaged sources.

    Returns
    -------
    list of GearRow
    """
    path = Path(path) if path is not None else DATA_DIR / "harmonic_drives.csv"
    src = sources if sources is not None else load_sources()
    rows = _load_rows(path, GearRow, lambda r: f"{r.get('series')}-{r.get('size')}-{r.get('ratio')}",
                      _parse_gear, src, [f.name for f in fields(GearRow) if f.name.startswith("src_")])
    seen: Dict[str, int] = {}
    for g in rows:
        if g.name in seen:
            raise CatalogueError(f"{path}: row '{g.name}': duplicate")
        seen[g.name] = 1
    return rows


def load_motors(path: Optional[Path] = None,
                sources: Optional[Dict[str, Source]] = None) -> List[MotorRow]:
    """Load the frameless-motor catalogue (``motors.csv``); see :func:`load_gears`."""
    path = Path(path) if path is not None else DATA_DIR / "motors.csv"
    src = sources if sources is not None else load_sources()
    return _load_rows(path, MotorRow, lambda r: r.get("name", "?"), _parse_motor, src, ["source"])


def load_sensors(path: Optional[Path] = None,
                 sources: Optional[Dict[str, Source]] = None) -> List[SensorRow]:
    """Load the encoder and gyro catalogue (``sensors.csv``); see :func:`load_gears`."""
    path = Path(path) if path is not None else DATA_DIR / "sensors.csv"
    src = sources if sources is not None else load_sources()
    return _load_rows(path, SensorRow, lambda r: r.get("name", "?"), _parse_sensor, src, ["source"])


def find_gear(size: int, ratio: int, series: str = "CSF",
              rows: Optional[Sequence[GearRow]] = None) -> GearRow:
    """Return the catalogue row ``SERIES-SIZE-RATIO``.

    Raises
    ------
    UserError
        If the catalogue has no such row.
    """
    for g in rows if rows is not None else load_gears():
        if g.series == series and g.size == size and g.ratio == ratio:
            return g
    raise UserError(f"no harmonic drive {series}-{size}-{ratio} in the catalogue "
                    "(sizes 14-50, ratios 50/80/100/120/160 where built)")
