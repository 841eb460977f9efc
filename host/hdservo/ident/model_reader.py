"""Reading an identified model TOML (``hdservo identify -o``): the one checked reader.

``hdservo download``, ``compare --model``, ``test --model`` and ``design verify``
read a model through :func:`read_model`, which checks every key they use before
any drive is contacted: each section is a table, each known key has the right
type (a finite number, an integer, a string), positive where the compensator
arithmetic divides by it, and the keys that come in groups are complete
(``[gear] ratio``; the six Stribeck keys of ``[friction_total]``; ``k1`` of a
``[stiffness]`` with a spring; ``eK_k``/``eK_w`` for every Maxwell element and
``eK_gain``/``eK_d_rad`` for every lost-motion element;
order/amplitude/phase of every TE harmonic).  A bad file is one
:class:`ModelError` line ``FILE: key 'section.key': expected ..., got ...``.
Keys the reader does not know are kept as they are (a model may carry notes).

The two Preisach operators have their own sections: ``[preisach_host_model]`` (the host's
torque -> twist model, never downloaded) and ``[preisach_drive_table]`` (the drive's
twist -> torque table, the image ``file`` downloaded to 0x5100:1, its CRC-32 ``crc``); a
``direction`` key, when present, must name the section's own direction.  Files written before
these sections carried both in ``[identified]`` as ``preisach_u0_Nm``, ``preisach_step_Nm``,
``preisach_levels``, ``preisach_offset_rad`` (the host's model) and ``preisach_table``,
``preisach_crc`` (the drive's table); they read as before, and :func:`preisach_table_file` /
:func:`preisach_table_crc` give the drive's table of either layout.
"""
from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path
from typing import Any

from ..errors import UserError

#: A checked model: section -> key -> value (numbers as float, counts as int).
Model = dict[str, dict[str, Any]]

#: Known keys of each section and their kind: "num" finite number, "pos" finite number > 0, "nonneg" >= 0, "int" integer >= 0, "str" string.
KEYS: dict[str, dict[str, str]] = {
    "gear": {"ratio": "pos"},
    "stiffness": {"k1_Nm_per_rad": "pos", "k2_Nm_per_rad": "num", "k3_Nm_per_rad": "num", "t1_Nm": "num",
                  "t2_Nm": "num", "damping_Nms_per_rad": "num"},
    "stiffness_cubic": {"k1_Nm_per_rad": "num", "k3_Nm_per_rad3": "num"},
    "hysteresis_maxwell": {"n_elements": "int"},
    "lost_motion": {"n_elements": "int"},
    "transmission_error": {},
    "load": {"jl_kgm2": "pos"},
    "motor": {"jm_kgm2": "pos"},
    "gravity": {"mgl_Nm": "num", "offset_rad": "num"},
    "friction_total": {"fc_pos_Nm": "num", "fc_neg_Nm": "num", "fs_pos_Nm": "num", "fs_neg_Nm": "num",
                       "vs_rad_s": "pos", "delta": "pos", "viscous_Nms_per_rad": "num"},
    "friction_motor": {"sigma0_Nm_per_rad": "nonneg", "sigma1_Nms_per_rad": "nonneg",
                       "presliding_breakaway_pos_Nm": "num", "presliding_breakaway_neg_Nm": "num"},
    "identified": {"hysteresis_loss_rad": "num", "lost_motion_rad": "num", "f_antiresonance_Hz": "num",
                   "f_resonance_Hz": "num", "frf_small_signal_k_Nm_per_rad": "num", "preisach_offset_rad": "num",
                   "preisach_u0_Nm": "num", "preisach_step_Nm": "num", "preisach_levels": "int",
                   "preisach_crc": "int", "preisach_table": "str",
                   "lost_motion_reversal_rad": "num"},
    "preisach_host_model": {"direction": "str", "u0_Nm": "num", "step_Nm": "pos", "levels": "int",
                            "offset_rad": "num"},
    "preisach_drive_table": {"direction": "str", "file": "str", "crc": "int", "levels": "int", "u0_rad": "num",
                             "step_rad": "pos", "sub_bits": "int", "twist_offset_rad": "num"},
}
#: The direction (input -> output) each Preisach section names in its ``direction`` key.
DIRECTIONS: dict[str, str] = {"preisach_host_model": "torque -> twist", "preisach_drive_table": "twist -> torque"}
#: Keys a section needs when it is present.
_REQUIRED: dict[str, tuple[str, ...]] = {
    "gear": ("ratio",),
    "friction_total": ("fc_pos_Nm", "fc_neg_Nm", "fs_pos_Nm", "fs_neg_Nm", "vs_rad_s", "viscous_Nms_per_rad"),
}
#: Most Maxwell-slip elements / TE harmonics a model may list.
MAX_ELEMENTS = 64

_EXPECT = {"num": "a finite number", "pos": "a finite number > 0", "nonneg": "a finite number >= 0",
           "int": "an integer >= 0", "str": "a string"}


class ModelError(UserError, ValueError):
    """A model file is unreadable or a key is missing or of the wrong type; one line."""


def _got(v: Any) -> str:
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return "an array"
    s = repr(v)
    return s if len(s) <= 40 else s[:37] + "..."


def check_value(where: str, key: str, v: Any, kind: str) -> float | int | str:
    """``v`` checked against ``kind`` (see :data:`KEYS`); ModelError naming ``where`` and ``key``."""
    bad = ModelError(f"{where}: key '{key}': expected {_EXPECT[kind]}, got {_got(v)}")
    if kind == "str":
        if not isinstance(v, str):
            raise bad
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise bad
    if kind == "int":
        if not isinstance(v, int) or v < 0:
            raise bad
        return int(v)
    try:
        x = float(v)
    except OverflowError:
        raise bad from None
    if not math.isfinite(x) or (kind == "pos" and not x > 0) or (kind == "nonneg" and not x >= 0):
        raise bad
    return x


def check_model(data: Any, where: str = "model") -> Model:
    """Check a parsed model document; returns the checked sections (unknown keys kept).

    Parameters
    ----------
    data : Any
        The parsed TOML document.
    where : str
        The file name, for the messages.

    Raises
    ------
    ModelError
        The first problem, one line.
    """
    if not isinstance(data, dict):
        raise ModelError(f"{where}: expected a TOML document of tables")
    gear = data.get("gear")
    if "gear" in data and not isinstance(gear, dict):
        raise ModelError(f"{where}: key 'gear': expected a table [gear], got {_got(gear)}")
    if not isinstance(gear, dict) or "ratio" not in gear:
        raise ModelError(f"{where}: key 'gear.ratio': expected a finite number > 0, got nothing "
                         "(not an identified model from hdservo identify -o)")
    out: Model = {}
    for sec, body in data.items():
        if sec not in KEYS:
            out[sec] = body if not isinstance(body, dict) else dict(body)
            continue
        if not isinstance(body, dict):
            raise ModelError(f"{where}: key '{sec}': expected a table [{sec}], got {_got(body)}")
        kinds = dict(KEYS[sec])
        if sec in ("hysteresis_maxwell", "lost_motion"):
            n = check_value(where, f"{sec}.n_elements", body.get("n_elements", 0), "int")
            if int(n) > MAX_ELEMENTS:
                raise ModelError(f"{where}: key '{sec}.n_elements': expected at most {MAX_ELEMENTS}, got {n}")
            pair = ("k_Nm_per_rad", "w_Nm") if sec == "hysteresis_maxwell" else ("gain", "d_rad")
            for i in range(1, int(n) + 1):
                for k in pair:
                    kinds[f"e{i}_{k}"] = "nonneg"
            need = tuple(k for k in kinds if k != "n_elements")
        elif sec == "transmission_error":
            need = ()
            for pre in ("wg", "out"):
                i = 1
                while any(f"{pre}{i}_{s}" in body for s in ("order", "amp_rad", "phase_rad")):
                    if i > MAX_ELEMENTS:
                        raise ModelError(f"{where}: key '{sec}.{pre}{i}_order': expected at most "
                                         f"{MAX_ELEMENTS} harmonics")
                    kinds.update({f"{pre}{i}_order": "int", f"{pre}{i}_amp_rad": "num", f"{pre}{i}_phase_rad": "num"})
                    need += (f"{pre}{i}_order", f"{pre}{i}_amp_rad", f"{pre}{i}_phase_rad")
                    i += 1
        elif sec == "stiffness":
            # an FRF-only model has the damping alone; a spring needs its K1
            spring = any(k in body for k in ("k1_Nm_per_rad", "k2_Nm_per_rad", "k3_Nm_per_rad", "t1_Nm", "t2_Nm"))
            need = ("k1_Nm_per_rad",) if spring else ()
        else:
            need = _REQUIRED.get(sec, ())
        for k in need:
            if k not in body:
                raise ModelError(f"{where}: key '{sec}.{k}': expected {_EXPECT[kinds[k]]}, got nothing")
        out[sec] = {k: (check_value(where, f"{sec}.{k}", v, kinds[k]) if k in kinds else v) for k, v in body.items()}
        want = DIRECTIONS.get(sec)
        if want is not None and out[sec].get("direction", want) != want:
            raise ModelError(f"{where}: key '{sec}.direction': expected \"{want}\", got {_got(out[sec]['direction'])}")
    return out


def preisach_table_file(model: Model) -> str | None:
    """File name of the drive's twist -> torque Preisach image a checked model names, or None.

    ``[preisach_drive_table] file``; a file of the earlier layout names it as
    ``[identified] preisach_table``.
    """
    name = model.get("preisach_drive_table", {}).get("file")
    if name is None:
        name = model.get("identified", {}).get("preisach_table")
    return None if name is None else str(name)


def preisach_table_crc(model: Model) -> int | None:
    """CRC-32 of the drive's Preisach image a checked model records, or None.

    ``[preisach_drive_table] crc``; a file of the earlier layout records it as ``[identified] preisach_crc``.
    """
    crc = model.get("preisach_drive_table", {}).get("crc")
    if crc is None:
        crc = model.get("identified", {}).get("preisach_crc")
    return None if crc is None else int(crc)


def read_model(path: str | os.PathLike[str]) -> Model:
    """Read and check an identified model TOML.

    Parameters
    ----------
    path : path-like
        The model file (``hdservo identify -o MODEL.toml``).

    Returns
    -------
    Model
        Section -> key -> value; numbers are float (N.m, rad, s ... as the key's
        unit suffix says), counts int.

    Raises
    ------
    ModelError
        Missing, unreadable, not UTF-8, not TOML, or a key missing / of the wrong
        type: one line naming the file and the key.
    """
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"{p}: model file not found")
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise ModelError(f"{p}: cannot read: {e.strerror or e}") from None
    return parse_model(raw, str(p))


def parse_model(raw: bytes, where: str = "model") -> Model:
    """:func:`check_model` of the bytes of a model file (ModelError when not UTF-8 TOML)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise ModelError(f"{where}:{line}: expected UTF-8 TOML text, got byte 0x{raw[e.start]:02x}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ModelError(f"{where}: expected TOML: {e}") from None
    except RecursionError:
        raise ModelError(f"{where}: expected TOML: nested too deeply") from None
    return check_model(data, where)


__all__ = ["DIRECTIONS", "KEYS", "MAX_ELEMENTS", "Model", "ModelError", "check_model", "check_value", "parse_model",
           "preisach_table_crc", "preisach_table_file", "read_model"]
