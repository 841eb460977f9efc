"""Drive configuration files: every drive parameter in SI units and the CANopen settings, as TOML.

A file written by :func:`to_toml` (``hdservo config dump``)::

    [meta]
    format = 2
    param_layout_hash = 0xADB4A22B      # the drive's 0x5101:5 when it was dumped
    [params]
    pos_kp = 40.0                       # 1/s: Position loop proportional gain ...
    [objects]
    "0x1017:0" = 100                    # producer_heartbeat_time, ms
    "0x1800:1" = "$NODEID+0x180"        # cob_id_tpdo_1: follows the target's node ID

Values are ``raw / 2**frac`` of the drive's raw words (exact in binary floating point),
so a dump read back by :func:`parse` gives the same raw words: dump -> edit -> restore
round trips bit for bit.  ``[objects]`` holds every communication / CiA 402 setting
0x1010 saves (:data:`od_gen.STORED`: SYNC, heartbeats, PDO communication and mapping,
option codes, windows), raw integers; a COB-ID that is its default relative to the node
(low 11 bits = default + node ID, as the drive stores it) is written as ``$NODEID+0x...``
so a file dumped from node 1 gives node 2 its own COB-IDs.  :func:`parse` checks
everything before anything is written: the signature (a file of another parameter
layout is refused unless forced, then matched by name), each value's type and range;
unknown names and objects are listed, not fatal.  Format 1 files (no ``[objects]``)
are still read.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from .errors import UserError
from .od_gen import STORED, StoredEntry
from .params_gen import BY_NAME, TABLE_HASH, ParamDef


class ConfigError(UserError, ValueError):
    """A configuration file is unreadable or holds a bad value; one line (what, where, expected)."""

#: File format written here; :data:`FORMATS` are read.
FORMAT = 2
FORMATS = (1, 2)
#: Stored objects by (index, sub).
STORED_AT: dict[tuple[int, int], StoredEntry] = {(e.index, e.sub): e for e in STORED}


def raw_of(p: ParamDef, value: float) -> int:
    """Raw word of an SI value (round half away from zero), as the drive stores it."""
    x = float(value) * 2.0 ** p.frac
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def si_of(p: ParamDef, raw: int) -> float | int:
    """SI value of a raw word (an int for integer parameters)."""
    return int(raw) if p.frac == 0 else int(raw) / 2.0 ** p.frac


def object_key(e: StoredEntry) -> str:
    """The ``[objects]`` key of a stored object, ``"0xIIII:S"``."""
    return f"0x{e.index:04X}:{e.sub}"


def _node_relative(e: StoredEntry, value: int, node_id: int) -> bool:
    """True when the drive keeps ``value`` relative to its node ID (hd_co.c store_encode)."""
    return e.nodeid and (value & 0x7FF) == ((e.default + node_id) & 0x7FF)


def to_toml(raw: Mapping[str, int], layout_hash: int, header: str = "",
            objects: Mapping[tuple[int, int], int] | None = None, node_id: int = 1) -> str:
    """A configuration file of the raw parameter words ``raw`` (name -> raw) and stored objects.

    Parameters
    ----------
    raw : mapping of str to int
        Raw words by parameter name (every name must be in the parameter table).
    layout_hash : int
        The drive's parameter layout hash (0x5101:5).
    header : str
        Comment lines put first (without the ``#``).
    objects : mapping of (index, sub) to int, optional
        Values of stored objects (keys in :data:`STORED_AT`), read from the drive.
    node_id : int
        The node ID the objects were read from (for the ``$NODEID`` form of COB-IDs).
    """
    out = [f"# {line}".rstrip() for line in header.splitlines()]
    out += ["[meta]", f"format = {FORMAT}", f"param_layout_hash = 0x{layout_hash:08X}", "", "[params]"]
    for name in sorted(raw, key=lambda n: (BY_NAME[n].index, BY_NAME[n].sub)):
        p = BY_NAME[name]
        v = si_of(p, raw[name])
        out.append(f"{name} = {v!r}  # {p.unit}: {p.desc}")
    if objects:
        out += ["", "# CANopen / CiA 402 settings saved by 0x1010 (raw values; docs/od.md)", "[objects]"]
        for key in sorted(objects):
            e = STORED_AT[key]
            v = int(objects[key])
            text = f'"$NODEID+0x{v - node_id:X}"' if _node_relative(e, v, node_id) else (
                f"0x{v:08X}" if e.nodeid or e.name.startswith("mapped_object_") else str(v))
            pdo = {0x14: "RPDO", 0x16: "RPDO mapping", 0x18: "TPDO", 0x1A: "TPDO mapping"}.get(e.index >> 8)
            what = f"{pdo} {(e.index & 0xFF) + 1} {e.name}" if pdo else e.name
            out.append(f'"{object_key(e)}" = {text}  # {what}' + (f", {e.unit}" if e.unit else ""))
    return "\n".join(out) + "\n"


@dataclass
class Parsed:
    """A checked configuration file."""
    raw: dict[str, int]                       #: name -> raw word to write
    unknown: list[str] = field(default_factory=list)   #: names / object keys not of this drive
    layout_hash: int | None = None            #: the file's signature
    objects: dict[tuple[int, int], int] = field(default_factory=dict)  #: (index, sub) -> value for the target node


def parse(text: str, drive_hash: int | None = None, force: bool = False, where: str = "config",
          node_id: int = 1) -> Parsed:
    """Check a configuration file; ConfigError (a ValueError; one line: what, where, expected) on the first problem.

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
    node_id : int
        The target drive's node ID: ``$NODEID+x`` objects become ``x + node_id``.
    """
    try:
        data: dict[str, Any] = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{where}: not TOML ({e})") from None
    except RecursionError:
        raise ConfigError(f"{where}: not TOML (nested too deeply)") from None
    meta, params = data.get("meta"), data.get("params")
    if not isinstance(meta, dict) or not isinstance(params, dict):
        raise ConfigError(f"{where}: expected the tables [meta] and [params] (hdservo config dump)")
    if meta.get("format") not in FORMATS:
        raise ConfigError(f"{where}: [meta] format = {meta.get('format')!r}, expected one of {FORMATS}")
    h = meta.get("param_layout_hash")
    if not isinstance(h, int):
        raise ConfigError(f"{where}: [meta] param_layout_hash missing (expected the 0x... of the dump)")
    want = TABLE_HASH if drive_hash is None else drive_hash
    if h != want and not force:
        raise ConfigError(f"{where}: parameter layout 0x{h:08X} is not the drive's 0x{want:08X} "
                         "(another firmware's table; --force matches the values by name)")
    raw: dict[str, int] = {}
    unknown: list[str] = []
    for name, v in params.items():
        p = BY_NAME.get(name)
        if p is None:
            unknown.append(name)
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v):
            raise ConfigError(f"{where}: [params] {name} = {v!r}: expected a number in {p.unit}")
        if not p.min <= float(v) <= p.max:
            raise ConfigError(f"{where}: [params] {name} = {v!r} outside [{p.min}, {p.max}] {p.unit}")
        r = raw_of(p, float(v))
        if not p.raw_min <= r <= p.raw_max:
            raise ConfigError(f"{where}: [params] {name} = {v!r} rounds to raw {r} outside [{p.raw_min}, {p.raw_max}]")
        raw[name] = r
    objs = data.get("objects", {})
    if not isinstance(objs, dict):
        raise ConfigError(f"{where}: [objects] must be a table of \"0xIIII:S\" = value")
    objects: dict[tuple[int, int], int] = {}
    for key, v in objs.items():
        e = _stored_of(key)
        if e is None:
            unknown.append(key)
            continue
        objects[(e.index, e.sub)] = _object_value(e, v, node_id, f"{where}: [objects] \"{key}\"")
    return Parsed(raw=raw, unknown=sorted(unknown), layout_hash=h, objects=objects)


def _finite(v: int | float) -> bool:
    """True for a number that is finite as a float (a huge TOML integer is not)."""
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def _stored_of(key: str) -> StoredEntry | None:
    """The stored object of an ``[objects]`` key (``"0x1017:0"``), None if not one."""
    i, colon, sub = key.partition(":")
    try:
        return STORED_AT.get((int(i, 16), int(sub, 0))) if colon and i.lower().startswith("0x") else None
    except ValueError:
        return None


def _object_value(e: StoredEntry, v: Any, node_id: int, where: str) -> int:
    """Checked value of a stored object for node ``node_id`` (ConfigError: one line)."""
    if isinstance(v, str):
        rest = v.replace(" ", "")
        if not (e.nodeid and rest.upper().startswith("$NODEID+")):
            raise ConfigError(f"{where} = {v!r}: expected an integer" + (" or \"$NODEID+0x...\"" if e.nodeid else ""))
        try:
            v = int(rest[len("$NODEID+"):], 0) + node_id
        except ValueError:
            raise ConfigError(f"{where} = {v!r}: expected \"$NODEID+\" and an integer") from None
    if isinstance(v, bool) or not isinstance(v, int):
        raise ConfigError(f"{where} = {v!r}: expected an integer ({e.name})")
    if not e.min <= v <= e.max:
        raise ConfigError(f"{where} = {v} outside [{e.min}, {e.max}] ({e.name})")
    return v


def read_file(path: Path, drive_hash: int | None = None, force: bool = False, node_id: int = 1) -> Parsed:
    """:func:`parse` of a file; ConfigError (a ValueError) with one line when it cannot be read."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{path}: cannot read ({e.__class__.__name__}: {e})") from None
    return parse(text, drive_hash, force, str(path), node_id)


def restore_writes(objects: Mapping[tuple[int, int], int]) -> list[tuple[int, int, int]]:
    """The SDO writes that put ``objects`` into a drive, in an order the drive accepts.

    CiA 301 PDO reconfiguration: a PDO is made invalid first (COB-ID bit 31), its
    mapping cleared (sub 0 = 0), the entries written, the count set, then its
    communication parameters, and the COB-ID last.  Every other object is written
    first, in dictionary order.  Returns ``(index, sub, value)`` tuples.
    """
    pdo = lambda i: 0x1400 <= i <= 0x1BFF  # noqa: E731
    writes = [(i, s, v) for (i, s), v in sorted(objects.items()) if not pdo(i)]
    comms = sorted({i & ~0x200 for (i, _s) in objects if pdo(i)})     # 0x16xx -> 0x14xx, 0x1Axx -> 0x18xx
    for c in comms:
        m = c + 0x200
        cob = objects.get((c, 1))
        if cob is not None:
            writes.append((c, 1, cob | 0x80000000))
        maps = sorted((s, v) for (i, s), v in objects.items() if i == m and s > 0)
        if (m, 0) in objects or maps:
            writes.append((m, 0, 0))
            writes += [(m, s, v) for s, v in maps]
            if (m, 0) in objects:
                writes.append((m, 0, objects[(m, 0)]))
        writes += [(c, s, v) for (i, s), v in sorted(objects.items()) if i == c and s != 1]
        if cob is not None:
            writes.append((c, 1, cob))
    return writes


#: 0x5102, the drive's flash wear and 0x1010 save rate limit (firmware/canopen/hd_app_co.h).
NVM_WEAR_INDEX = 0x5102
#: page erase cycles the STM32G474 flash endures per page (datasheet, 10 000 cycles)
FLASH_ENDURANCE = 10_000


@dataclass(frozen=True)
class NvmWear:
    """The drive's NVM wear figures (0x5102).

    Attributes
    ----------
    erases_total : int
        Flash page erases of the NVM area, page erases (:1).
    erases_max_page : int
        Erases of the most erased page, page erases (:2; an upper bound on the STM32G474).
    saves_refused : int
        0x1010 saves refused by the rate limit since power-up (:3).
    save_credit : int
        Page erases the rate limit allows now (:4; a changing save is refused at <= 0).
    """

    erases_total: int
    erases_max_page: int
    saves_refused: int
    save_credit: int

    def line(self) -> str:
        """One status line: the figures and the most erased page's share of its endurance."""
        used = 100.0 * self.erases_max_page / FLASH_ENDURANCE
        return (f"NVM wear: {self.erases_total} page erases, most erased page {self.erases_max_page} "
                f"of {FLASH_ENDURANCE} ({used:.2f} %); save credit {self.save_credit} erases, "
                f"{self.saves_refused} saves refused by the rate limit")


def read_nvm_wear(drive: Any) -> NvmWear:
    """Read the drive's flash wear object 0x5102.

    Parameters
    ----------
    drive : hdservo.drive.Drive
        A connected drive (anything with ``read(index, sub)``).

    Returns
    -------
    NvmWear
        The four figures, page erases / saves (dimensionless counts).
    """
    r = [int(drive.read(NVM_WEAR_INDEX, k)) for k in (1, 2, 3, 4)]
    return NvmWear(erases_total=r[0], erases_max_page=r[1], saves_refused=r[2], save_credit=r[3])
