"""Drive configuration files: every drive parameter in SI units, as TOML, with a signature.

A file written by :func:`to_toml` (``hdservo config dump``)::

    [meta]
    format = 1
    param_layout_hash = 0xADB4A22B      # the drive's 0x5101:5 when it was dumped
    [params]
    pos_kp = 40.0                       # 1/s: Position loop proportional gain ...

Values are ``raw / 2**frac`` of the drive's raw words (exact in binary floating point),
so a dump read back by :func:`parse` gives the same raw words: dump -> edit -> restore
round trips bit for bit.  :func:`parse` checks everything before anything is written:
the signature (a file of another parameter layout is refused unless forced, then
matched by name), each value's type and range; unknown names are listed, not fatal.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from .params_gen import BY_NAME, TABLE_HASH, ParamDef

#: File format written and read here.
FORMAT = 1


def raw_of(p: ParamDef, value: float) -> int:
    """Raw word of an SI value (round half away from zero), as the drive stores it."""
    x = float(value) * 2.0 ** p.frac
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def si_of(p: ParamDef, raw: int) -> float | int:
    """SI value of a raw word (an int for integer parameters)."""
    return int(raw) if p.frac == 0 else int(raw) / 2.0 ** p.frac


def to_toml(raw: Mapping[str, int], layout_hash: int, header: str = "") -> str:
    """A configuration file of the raw parameter words ``raw`` (name -> raw).

    Parameters
    ----------
    raw : mapping of str to int
        Raw words by parameter name (every name must be in the parameter table).
    layout_hash : int
        The drive's parameter layout hash (0x5101:5).
    header : str
        Comment lines put first (without the ``#``).
    """
    out = [f"# {line}".rstrip() for line in header.splitlines()]
    out += ["[meta]", f"format = {FORMAT}", f"param_layout_hash = 0x{layout_hash:08X}", "", "[params]"]
    for name in sorted(raw, key=lambda n: (BY_NAME[n].index, BY_NAME[n].sub)):
        p = BY_NAME[name]
        v = si_of(p, raw[name])
        out.append(f"{name} = {v!r}  # {p.unit}: {p.desc}")
    return "\n".join(out) + "\n"


@dataclass
class Parsed:
    """A checked configuration file."""
    raw: dict[str, int]                       #: name -> raw word to write
    unknown: list[str] = field(default_factory=list)   #: names not in this parameter table
    layout_hash: int | None = None            #: the file's signature


def parse(text: str, drive_hash: int | None = None, force: bool = False, where: str = "config") -> Parsed:
    """Check a configuration file; ValueError (one line: what, where, expected) on the first problem.

    Parameters
    ----------
    text : str
        The TOML text.
    drive_hash : int, optional
        The target drive's parameter layout hash (0x5101:5); default: this host's table.
    force : bool
        Accept a file of another layout (values matched by name, each still checked).
    where : str
        The file name, for the messages.
    """
    try:
        data: dict[str, Any] = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{where}: not TOML ({e})") from None
    meta, params = data.get("meta"), data.get("params")
    if not isinstance(meta, dict) or not isinstance(params, dict):
        raise ValueError(f"{where}: expected the tables [meta] and [params] (hdservo config dump)")
    if meta.get("format") != FORMAT:
        raise ValueError(f"{where}: [meta] format = {meta.get('format')!r}, expected {FORMAT}")
    h = meta.get("param_layout_hash")
    if not isinstance(h, int):
        raise ValueError(f"{where}: [meta] param_layout_hash missing (expected the 0x... of the dump)")
    want = TABLE_HASH if drive_hash is None else drive_hash
    if h != want and not force:
        raise ValueError(f"{where}: parameter layout 0x{h:08X} is not the drive's 0x{want:08X} "
                         "(another firmware's table; --force matches the values by name)")
    raw: dict[str, int] = {}
    unknown: list[str] = []
    for name, v in params.items():
        p = BY_NAME.get(name)
        if p is None:
            unknown.append(name)
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise ValueError(f"{where}: [params] {name} = {v!r}: expected a number in {p.unit}")
        if not p.min <= float(v) <= p.max:
            raise ValueError(f"{where}: [params] {name} = {v!r} outside [{p.min}, {p.max}] {p.unit}")
        r = raw_of(p, float(v))
        if not p.raw_min <= r <= p.raw_max:
            raise ValueError(f"{where}: [params] {name} = {v!r} rounds to raw {r} outside [{p.raw_min}, {p.raw_max}]")
        raw[name] = r
    return Parsed(raw=raw, unknown=sorted(unknown), layout_hash=h)


def read_file(path: Path, drive_hash: int | None = None, force: bool = False) -> Parsed:
    """:func:`parse` of a file; ValueError with one line when it cannot be read."""
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: cannot read ({e.__class__.__name__}: {e})") from None
    return parse(text, drive_hash, force, str(path))
