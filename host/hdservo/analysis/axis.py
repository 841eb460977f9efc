"""Axis parameters and controller gains for the describing-function analysis.

Axis files are the simulator's TOML files (the shipped ones are found by
:func:`hdservo.resources.axis_file`): tables
``[section]`` with SI-suffixed keys, addressed as ``"section.key"`` (see
``sim/plant/hd_plant.h``).  Only the keys the analysis needs are read; the rest
are ignored.  Missing keys keep the built-in reference-axis values
(:data:`REFERENCE_AXIS`, the same numbers as ``hd_plant_defaults_reference``).

Gains are the drive's parameter-table names (``firmware/params/params.toml``):
``pos_kp`` (1/s), ``pos_ki`` (1/s^2), ``vel_kp`` (N m s/rad, output torque per
output velocity error), ``vel_ki`` (N m/rad), ``vel_kd`` (N m s^2/rad),
``vel_d_fc`` (Hz), ``vel_fb_src`` (0 motor encoder / N, 1 output encoder),
``obs_mot_bw``/``obs_out_bw`` (Hz), ``obs_zeta``, the torque-filter biquads
``f1_*``/``f2_*`` and ``filt_enable``; two model (not drive) entries:
``loop_period_s`` (s) and ``delay_periods`` (command delay in loop periods, see
:mod:`hdservo.analysis.loop`).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Tuple

from .. import resources
from ..fw_const import LOOP_HZ
from ..params_gen import BY_NAME as PARAM_DEFS

ARCMIN_RAD = math.pi / (180.0 * 60.0)

#: Reference axis (docs/reference-axis.md; sim/plant hd_plant_defaults_reference), "section.key" -> value.
REFERENCE_AXIS: Dict[str, float] = {
    "gear.ratio": 100.0,
    "motor.jm_kgm2": 8e-5,
    "motor.kt_Nm_per_A": 0.1,
    "current_loop.enabled": 1.0,
    "current_loop.bandwidth_Hz": 2000.0,
    "current_loop.peak_A": 20.0,
    "stiffness.enabled": 1.0,
    "stiffness.k1_Nm_per_rad": 3.1e4,
    "stiffness.k2_Nm_per_rad": 5.0e4,
    "stiffness.k3_Nm_per_rad": 5.7e4,
    "stiffness.t1_Nm": 14.0,
    "stiffness.t2_Nm": 48.0,
    "stiffness.damping_Nms_per_rad": 6.0,
    "stiffness_cubic.enabled": 0.0,
    "stiffness_cubic.k1_Nm_per_rad": 3.49e4,
    "stiffness_cubic.k3_Nm_per_rad3": 5.5e9,
    "hysteresis_maxwell.enabled": 1.0,
    "hysteresis_maxwell.n_elements": 4.0,
    "hysteresis_preisach.enabled": 1.0,
    "hysteresis_preisach.u_max_rad": 5e-4,
    "hysteresis_preisach.t_sat_Nm": 7.15,
    "hysteresis_preisach.r0_rad": 1e-4,
    "hysteresis_preisach.s_rad": 2e-4,
    "load.jl_kgm2": 0.5,
    # Lost motion is not a plant parameter; docs/reference-axis.md: ~1 arcmin.
    "lost_motion.b_rad": ARCMIN_RAD,
}
for _i in range(4):
    _w = 0.25 * 0.5 * 0.5 * ARCMIN_RAD * 3.1e4
    REFERENCE_AXIS[f"hysteresis_maxwell.e{_i + 1}_w_Nm"] = _w
    REFERENCE_AXIS[f"hysteresis_maxwell.e{_i + 1}_k_Nm_per_rad"] = _w / ((_i + 1) * 1e-4)
for _side, (_fs, _fc, _asym, _vs, _visc) in {"friction_motor": (0.10, 0.07, 0.05, 2.0, 5e-4),
                                             "friction_load": (0.60, 0.40, 0.08, 0.02, 0.3)}.items():
    REFERENCE_AXIS.update({f"{_side}.enabled": 1.0, f"{_side}.fs_pos_Nm": _fs,
                           f"{_side}.fs_neg_Nm": _fs * (1 - _asym), f"{_side}.fc_pos_Nm": _fc,
                           f"{_side}.fc_neg_Nm": _fc * (1 - _asym), f"{_side}.vs_rad_s": _vs,
                           f"{_side}.delta": 2.0, f"{_side}.viscous_Nms_per_rad": _visc})

#: Drive parameters the loop model reads; their values are the defaults of
#: firmware/params/params.toml (through the generated params_gen).
_GAIN_PARAMS = ("pos_kp", "pos_ki", "vel_kp", "vel_ki", "vel_kd", "vel_d_fc", "vel_fb_src", "obs_mot_bw",
                "obs_out_bw", "obs_zeta", "f1_b0", "f1_b1", "f1_b2", "f1_a1", "f1_a2", "f2_b0", "f2_b1",
                "f2_b2", "f2_a1", "f2_a2", "filt_enable")

#: Drive gains of the reference axis: the drive's parameter defaults, the loop period
#: and the modelled computation + zero-order-hold delay (periods).
REFERENCE_GAINS: Dict[str, float] = {
    **{name: float(PARAM_DEFS[name].default) for name in _GAIN_PARAMS},
    "loop_period_s": 1.0 / LOOP_HZ, "delay_periods": 1.5,
}

class AxisFileError(ValueError):
    """A bad axis or gains file: the message names the file, the place and what was expected."""


def _flatten(d: Mapping[str, Any], prefix: str = "") -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _number(path: Path | str, key: str, v: Any) -> float:
    if isinstance(v, bool):
        return 1.0 if v else 0.0
    if isinstance(v, (int, float)) and math.isfinite(float(v)):
        return float(v)
    raise AxisFileError(f"{path}: key '{key}': expected a finite number or boolean, found {v!r}")


def read_toml(path: Path) -> Dict[str, Any]:
    """Parse a TOML file; errors become one-line :class:`AxisFileError`."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise AxisFileError(f"{path}: file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise AxisFileError(f"{path}: invalid TOML: {e}") from None
    except OSError as e:
        raise AxisFileError(f"{path}: cannot read: {e.strerror}") from None


def _simulator_keys() -> set:
    """Names of every simulator axis parameter (from libhdsim), or an empty set
    when the simulator library is not available (then unknown keys pass)."""
    try:
        from .. import sim
        return {p.name for p in sim.param_table()}
    except Exception:  # noqa: BLE001 - the check is best effort without the library
        return set()


def load_axis(path: Path | None) -> Tuple[Dict[str, float], List[str]]:
    """Axis parameters: the reference axis overridden by an axis TOML file.

    Parameters
    ----------
    path : pathlib.Path or None
        Axis TOML (simulator format); None: the shipped ``reference`` axis file
        (:func:`hdservo.resources.axis_file`) if it is installed, else the built-in
        reference axis.

    Returns
    -------
    params : dict
        ``"section.key"`` -> value (SI units as the key says).
    notes : list of str
        What was used (for the report).
    """
    params = dict(REFERENCE_AXIS)
    notes: List[str] = []
    if path is None:
        try:
            path = resources.axis_file("reference")
        except resources.ResourceError:
            notes.append("no axis file given and the reference axis file is not installed: "
                         "using the built-in reference axis (docs/reference-axis.md)")
            return params, notes
    doc = _flatten(read_toml(path))
    used = 0
    for key, v in doc.items():
        if key in params or key.startswith(("hysteresis_maxwell.e", "friction_")):
            params[key] = _number(path, key, v)
            used += 1
    known = _simulator_keys()
    for key in doc:
        if known and key not in params and key not in known and not key.startswith("axis."):
            raise AxisFileError(f"{path}: unknown key '{key}': expected a simulator axis parameter "
                                "(docs/plant.md; misspelt, or a wrong unit suffix?)")
    notes.append(f"axis file {path}: {used} keys used, others from the reference axis")
    for key in ("gear.ratio", "motor.jm_kgm2", "load.jl_kgm2"):
        if params[key] <= 0:
            raise AxisFileError(f"{path}: key '{key}': expected a value > 0, found {params[key]}")
    return params, notes


def load_gains(spec: List[str] | None) -> Tuple[Dict[str, float], List[str]]:
    """Controller gains: parameter-table defaults, then a TOML file and/or NAME=VALUE items.

    Parameters
    ----------
    spec : list of str or None
        Items ``PATH.toml`` (a flat table of gain names, a ``[gains]`` table,
        or a drive ``params.toml`` with ``[[param]]`` entries) and
        ``NAME=VALUE`` overrides, applied in order.

    Returns
    -------
    gains : dict
        Gain name -> value (units as in the parameter table).
    notes : list of str
        Where they came from.
    """
    gains = dict(REFERENCE_GAINS)
    notes: List[str] = []
    notes.append("gains: the drive's parameter defaults (firmware/params/params.toml)")
    for item in spec or []:
        if "=" in item and not item.endswith(".toml"):
            name, _, val = item.partition("=")
            name = name.strip()
            if name not in REFERENCE_GAINS:
                raise AxisFileError(f"--set {item}: unknown gain '{name}' "
                                    f"(expected one of: {', '.join(sorted(REFERENCE_GAINS))})")
            try:
                gains[name] = float(val)
            except ValueError:
                raise AxisFileError(f"--set {item}: expected NAME=NUMBER") from None
            notes.append(f"gains: {name} = {gains[name]:g} (command line)")
        else:
            p = Path(item)
            doc = read_toml(p)
            if "param" in doc:
                _apply_params_toml(gains, p, doc)
            else:
                flat = doc.get("gains", doc)
                if not isinstance(flat, dict):
                    raise AxisFileError(f"{p}: key 'gains': expected a table")
                for k, v in flat.items():
                    if k not in REFERENCE_GAINS:
                        raise AxisFileError(f"{p}: key '{k}': unknown gain (expected one of: "
                                            f"{', '.join(sorted(REFERENCE_GAINS))})")
                    gains[k] = _number(p, k, v)
            notes.append(f"gains: from {p}")
    for k in ("pos_kp", "pos_ki", "vel_kp", "vel_ki", "vel_kd", "obs_mot_bw", "obs_out_bw", "obs_zeta"):
        if gains[k] < 0:
            raise AxisFileError(f"gain '{k}': expected a value >= 0, found {gains[k]:g}")
    return gains, notes


def _apply_params_toml(gains: Dict[str, float], path: Path, doc: Mapping[str, Any]) -> None:
    entries = doc.get("param", [])
    if not isinstance(entries, list):
        raise AxisFileError(f"{path}: key 'param': expected an array of tables [[param]]")
    for i, e in enumerate(entries):
        if not isinstance(e, dict):
            raise AxisFileError(f"{path}: [[param]] #{i + 1}: expected a table")
        name = e.get("name")
        if name in REFERENCE_GAINS and "default" in e:
            gains[name] = _number(path, f"param[{i}].default ({name})", e["default"])
