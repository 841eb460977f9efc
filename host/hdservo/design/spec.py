"""Requirements file of the design flow (``SPEC.toml``): format and validated loader.

Every number carries its unit in its key name.  Angles are in the units the
requirements are usually written in (deg, deg/s, arcsec), torques in N·m,
inertias in kg·m², frequencies in Hz.  A bad file raises :class:`SpecError`
(a :class:`hdservo.errors.UserError`) whose message is one line naming the file,
the key and what was expected, e.g.::

    SPEC.toml: [load] inertia_kgm2: expected a positive number, got 'heavy'

Format (``docs/design-flow.md`` section 1)::

    [spec]
    name = "pitch drive"                  # free text (optional)

    [load]
    inertia_kgm2 = 0.5                    # payload inertia about the axis
    unbalance_Nm = 2.0                    # m g l (gravity torque at worst angle)

    [motion]
    max_rate_deg_s = 60.0
    max_accel_deg_s2 = 100.0
    min_smooth_rate_deg_s = 0.001         # requirement: smooth at or below this rate
    travel_deg = 110.0                    # optional, default 110 (positioning targets span +-travel/2)

    [accuracy]
    positioning_arcsec = 10.0             # ISO 230-2 A (bidirectional accuracy)
    repeatability_arcsec = 2.0            # ISO 230-2 R

    [stabilisation]
    precision_arcsec_rms = 20.0           # inertial pointing error, RMS
    base_amplitude_deg = 0.5              # base rocking amplitude ...
    base_frequency_Hz = 1.0               # ... and frequency

    [torque]
    peak_output_Nm = 30.0                 # deliverable peak output torque

    [structure]
    min_resonance_Hz = 35.0               # first torsional resonance with the load (locked motor)

    [design]                              # options of the flow (all optional)
    series = ["CSF", "CSG"]               # gear series to consider
    efficiency = 0.7                      # gear efficiency used in the torque checks
    margin = 0.1                          # margin every hard check must clear (0.1 = 10 %)
    candidates = 3                        # how many to simulate
    current_loop_bandwidth_Hz = 2000.0
    duty_rms_fraction = 0.5               # RMS / peak of the dynamic torque over a duty cycle
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Tuple

from ..errors import UserError
from ..tomltext import read_toml_file


class SpecError(UserError):
    """A bad requirements file: one line (file, key, expected)."""


@dataclass(frozen=True)
class DesignOptions:
    """Options of the flow (``[design]``).

    Attributes
    ----------
    series : tuple of str
        Gear series considered (``CSF``, ``CSG``).
    efficiency : float
        Gear efficiency in the torque checks, 0-1.
    margin : float
        Relative margin every hard feasibility check must clear (0.1 = 10 %).
    candidates : int
        Number of best feasible candidates simulated.
    current_loop_bandwidth_Hz : float
        Current-loop bandwidth of the drive, Hz.
    duty_rms_fraction : float
        RMS of the acceleration torque over the duty cycle as a fraction of its peak.
    """

    series: Tuple[str, ...] = ("CSF", "CSG")
    efficiency: float = 0.7
    margin: float = 0.1
    candidates: int = 3
    current_loop_bandwidth_Hz: float = 2000.0
    duty_rms_fraction: float = 0.5


@dataclass(frozen=True)
class Spec:
    """Requirements of one axis (units in the field names).

    Attributes
    ----------
    name : str
        Free text.
    load_inertia_kgm2 : float
        Payload inertia about the axis, kg·m².
    unbalance_Nm : float
        Gravity unbalance m·g·l, N·m.
    max_rate_deg_s, max_accel_deg_s2 : float
        Largest output rate (deg/s) and acceleration (deg/s²).
    min_smooth_rate_deg_s : float
        The axis must move smoothly at this rate, deg/s.
    travel_deg : float
        Travel spanned by the positioning test, deg.
    positioning_arcsec, repeatability_arcsec : float
        ISO 230-2 accuracy A and repeatability R, arcsec.
    stabilisation_arcsec_rms : float
        Inertial pointing error (RMS) with the base rocking, arcsec.
    base_amplitude_deg, base_frequency_Hz : float
        Base rocking amplitude (deg) and frequency (Hz).
    peak_torque_Nm : float
        Deliverable peak output torque, N·m.
    min_resonance_Hz : float
        Lowest acceptable first torsional resonance with the load, Hz.
    options : DesignOptions
    source : str
        File the spec came from (for messages).
    """

    name: str
    load_inertia_kgm2: float
    unbalance_Nm: float
    max_rate_deg_s: float
    max_accel_deg_s2: float
    min_smooth_rate_deg_s: float
    positioning_arcsec: float
    repeatability_arcsec: float
    stabilisation_arcsec_rms: float
    base_amplitude_deg: float
    base_frequency_Hz: float
    peak_torque_Nm: float
    min_resonance_Hz: float
    travel_deg: float = 110.0
    options: DesignOptions = field(default_factory=DesignOptions)
    source: str = ""

    def as_dict(self) -> Dict[str, Any]:
        """JSON-able dict of the spec."""
        d = asdict(self)
        d["options"]["series"] = list(self.options.series)
        return d


#: (section, key, Spec field, lower bound (exclusive), upper bound (inclusive), required)
_FIELDS: List[Tuple[str, str, str, float, float, bool]] = [
    ("load", "inertia_kgm2", "load_inertia_kgm2", 0.0, 1e4, True),
    ("load", "unbalance_Nm", "unbalance_Nm", -1e-300, 1e5, True),
    ("motion", "max_rate_deg_s", "max_rate_deg_s", 0.0, 3600.0, True),
    ("motion", "max_accel_deg_s2", "max_accel_deg_s2", 0.0, 1e5, True),
    ("motion", "min_smooth_rate_deg_s", "min_smooth_rate_deg_s", 0.0, 10.0, True),
    ("motion", "travel_deg", "travel_deg", 0.0, 360.0, False),
    ("accuracy", "positioning_arcsec", "positioning_arcsec", 0.0, 3600.0, True),
    ("accuracy", "repeatability_arcsec", "repeatability_arcsec", 0.0, 3600.0, True),
    ("stabilisation", "precision_arcsec_rms", "stabilisation_arcsec_rms", 0.0, 3600.0, True),
    ("stabilisation", "base_amplitude_deg", "base_amplitude_deg", -1e-300, 30.0, True),
    ("stabilisation", "base_frequency_Hz", "base_frequency_Hz", 0.0, 100.0, True),
    ("torque", "peak_output_Nm", "peak_torque_Nm", 0.0, 1e5, True),
    ("structure", "min_resonance_Hz", "min_resonance_Hz", 0.0, 1e4, True),
]

#: [design] keys: key -> (lower exclusive, upper inclusive, integer)
_OPTIONS: Dict[str, Tuple[float, float, bool]] = {
    "efficiency": (0.0, 1.0, False),
    "margin": (-1e-300, 2.0, False),
    "candidates": (0.0, 20.0, True),
    "current_loop_bandwidth_Hz": (0.0, 20000.0, False),
    "duty_rms_fraction": (0.0, 1.0, False),
}


def _number(path: str, sec: str, key: str, v: Any, lo: float, hi: float, integer: bool = False) -> float:
    what = "an integer" if integer else "a number"
    rng = f"in ({lo:g}, {hi:g}]" if lo > -1e-300 else f"in [0, {hi:g}]"
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        raise SpecError(f"{path}: [{sec}] {key}: expected {what} {rng}, got {v!r}")
    x = float(v)
    if not math.isfinite(x) or not (x > lo if lo > -1e-300 else x >= 0.0) or x > hi:
        raise SpecError(f"{path}: [{sec}] {key}: expected {what} {rng}, got {v!r}")
    return x


def parse_spec(doc: Mapping[str, Any], path: str = "SPEC.toml") -> Spec:
    """Validate a parsed SPEC document and build the :class:`Spec`.

    Parameters
    ----------
    doc : mapping
        The TOML document (tables ``spec``, ``load``, ``motion``, ``accuracy``,
        ``stabilisation``, ``torque``, ``structure``, optional ``design``).
    path : str
        File name used in messages.

    Returns
    -------
    Spec

    Raises
    ------
    SpecError
        Unknown table or key, missing key, wrong type or out-of-range value.
    """
    known = {s for s, *_ in _FIELDS} | {"spec", "design"}
    for sec, val in doc.items():
        if sec not in known:
            raise SpecError(f"{path}: [{sec}]: unknown table; expected one of {', '.join(sorted(known))}")
        if not isinstance(val, dict):
            raise SpecError(f"{path}: {sec}: expected a table [{sec}], got a value")
    vals: Dict[str, Any] = {}
    for sec in {s for s, *_ in _FIELDS}:
        keys = {k for s, k, *_ in _FIELDS if s == sec}
        for k in doc.get(sec, {}):
            if k not in keys:
                raise SpecError(f"{path}: [{sec}] {k}: unknown key; expected one of {', '.join(sorted(keys))}")
    for sec, key, fname, lo, hi, req in _FIELDS:
        table = doc.get(sec, {})
        if key not in table:
            if req:
                raise SpecError(f"{path}: [{sec}] {key}: missing; expected a number")
            continue
        vals[fname] = _number(path, sec, key, table[key], lo, hi)
    head = doc.get("spec", {})
    for k in head:
        if k != "name":
            raise SpecError(f"{path}: [spec] {k}: unknown key; expected name")
    name = head.get("name", Path(path).parent.name or "axis")
    if not isinstance(name, str):
        raise SpecError(f"{path}: [spec] name: expected a string, got {name!r}")
    opt: Dict[str, Any] = {}
    for k, v in doc.get("design", {}).items():
        if k == "series":
            if (not isinstance(v, list) or not v or any(s not in ("CSF", "CSG") for s in v)):
                raise SpecError(f"{path}: [design] series: expected a non-empty list of \"CSF\"/\"CSG\", got {v!r}")
            opt["series"] = tuple(v)
        elif k in _OPTIONS:
            lo, hi, integer = _OPTIONS[k]
            x = _number(path, "design", k, v, lo, hi, integer)
            opt[k] = int(x) if integer else x
        else:
            raise SpecError(f"{path}: [design] {k}: unknown key; expected one of "
                            f"{', '.join(sorted(list(_OPTIONS) + ['series']))}")
    if vals["repeatability_arcsec"] > vals["positioning_arcsec"]:
        raise SpecError(f"{path}: [accuracy] repeatability_arcsec: expected <= positioning_arcsec "
                        f"({vals['positioning_arcsec']:g}), got {vals['repeatability_arcsec']:g}")
    if vals["min_smooth_rate_deg_s"] >= vals["max_rate_deg_s"]:
        raise SpecError(f"{path}: [motion] min_smooth_rate_deg_s: expected < max_rate_deg_s "
                        f"({vals['max_rate_deg_s']:g}), got {vals['min_smooth_rate_deg_s']:g}")
    return Spec(name=name, options=DesignOptions(**opt), source=str(path), **vals)


def load_spec(path: "str | Path") -> Spec:
    """Read and validate ``SPEC.toml``.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    Spec

    Raises
    ------
    SpecError
        Unreadable file, invalid TOML (with line/column) or a bad value.
    """
    p = Path(path)
    return parse_spec(read_toml_file(p, SpecError), str(p))


__all__ = ["DesignOptions", "Spec", "SpecError", "load_spec", "parse_spec"]
