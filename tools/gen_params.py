#!/usr/bin/env python3
"""Generate the parameter tables from firmware/params/params.toml.

Outputs (paths relative to the output root, default: the repository):

* ``firmware/app/hd_param_table.h`` / ``.c`` -- C ids, raw defaults, ranges, Q-formats
* ``host/hdservo/params_gen.py``               -- Python constants
* ``docs/parameters.md``                       -- the parameter reference

Usage::

    tools/gen_params.py [--out-dir DIR] [--input FILE]

Bad input prints one line ``params.toml: entry N (name): what was expected``
and exits 1; nothing is written (every output goes to a temp file first and is
renamed only when all outputs were produced).
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import tomllib
import zlib
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_INPUT = ROOT / "firmware" / "params" / "params.toml"
OUT_C_H = Path("firmware/app/hd_param_table.h")
OUT_C_C = Path("firmware/app/hd_param_table.c")
OUT_PY = Path("host/hdservo/params_gen.py")
OUT_MD = Path("docs/parameters.md")

TYPES = {"i32": (-(2 ** 31), 2 ** 31 - 1), "u32": (0, 2 ** 31 - 1)}
NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")
FIELDS = ("name", "index", "sub", "type", "unit", "frac", "min", "max", "default", "desc")


class ParamError(Exception):
    """One-line description of a defect in the data file."""


@dataclass(frozen=True)
class Param:
    """One parameter: SI values and their raw (fixed-point) equivalents."""

    name: str
    index: int
    sub: int
    type: str
    unit: str
    frac: int
    min: float
    max: float
    default: float
    desc: str
    raw_min: int
    raw_max: int
    raw_default: int


def to_raw(value: float, frac: int) -> int:
    """Round ``value * 2**frac`` to nearest, ties away from zero (as the firmware)."""
    x = value * (2.0 ** frac)
    return int(x + 0.5) if x >= 0 else -int(-x + 0.5)


def load(path: Path) -> tuple[int, list[Param]]:
    """Parse and validate the data file.

    Returns
    -------
    (version, params)
    """
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise ParamError(f"{path.name}: {e}") from None
    meta = data.get("meta", {})
    version = meta.get("version")
    if not isinstance(version, int) or not 1 <= version <= 0xFFFF:
        raise ParamError(f"{path.name}: [meta] version must be an integer 1..65535")
    entries = data.get("param")
    if not isinstance(entries, list) or not entries:
        raise ParamError(f"{path.name}: expected at least one [[param]] table")
    out: list[Param] = []
    seen_names: set[str] = set()
    seen_idx: set[tuple[int, int]] = set()
    for i, e in enumerate(entries, 1):
        where = f"{path.name}: entry {i} ({e.get('name', '?')})"
        for f in FIELDS:
            if f not in e:
                raise ParamError(f"{where}: missing field '{f}'")
        extra = set(e) - set(FIELDS)
        if extra:
            raise ParamError(f"{where}: unknown field(s) {sorted(extra)}")
        name = e["name"]
        if not isinstance(name, str) or not NAME_RE.match(name) or name in seen_names:
            raise ParamError(f"{where}: name must be a unique lower_snake identifier")
        idx, sub = e["index"], e["sub"]
        if not isinstance(idx, int) or not 0x2000 <= idx <= 0x5FFF:
            raise ParamError(f"{where}: index must be in the manufacturer range 0x2000-0x5FFF")
        if not isinstance(sub, int) or not 1 <= sub <= 254 or (idx, sub) in seen_idx:
            raise ParamError(f"{where}: sub must be 1..254 and unique per index")
        typ = e["type"]
        if typ not in TYPES:
            raise ParamError(f"{where}: type must be one of {sorted(TYPES)}")
        frac = e["frac"]
        if not isinstance(frac, int) or not 0 <= frac <= 32:
            raise ParamError(f"{where}: frac must be an integer 0..32")
        vals = []
        for f in ("min", "max", "default"):
            v = e[f]
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ParamError(f"{where}: {f} must be a number")
            vals.append(float(v))
        raws = [to_raw(v, frac) for v in vals]
        lo, hi = TYPES[typ]
        for f, r in zip(("min", "max", "default"), raws):
            if not lo <= r <= hi:
                raise ParamError(f"{where}: {f} does not fit {typ} with frac {frac} (raw {r})")
        if not raws[0] <= raws[2] <= raws[1]:
            raise ParamError(f"{where}: expected min <= default <= max")
        seen_names.add(name)
        seen_idx.add((idx, sub))
        out.append(Param(name, idx, sub, typ, str(e["unit"]), frac, vals[0], vals[1], vals[2],
                         str(e["desc"]), raws[0], raws[1], raws[2]))
    return version, out


def table_hash(params: list[Param]) -> int:
    """CRC-32 of the layout (name, index, sub, type, frac per entry)."""
    text = "".join(f"{p.name},{p.index},{p.sub},{p.type},{p.frac}\n" for p in params)
    return zlib.crc32(text.encode()) & 0xFFFFFFFF


def _c_str(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def gen_c_header(version: int, params: list[Param]) -> str:
    lines = [
        "/* GENERATED by tools/gen_params.py from firmware/params/params.toml: do not edit. */",
        "/*",
        " * hd_param_table.h - the drive parameter table: ids, raw defaults, ranges, formats.",
        " * Raw value = round(SI value * 2^frac), stored as int32 (u32 entries are >= 0).",
        " */",
        "#ifndef HD_PARAM_TABLE_H",
        "#define HD_PARAM_TABLE_H",
        "",
        "#include <stdint.h>",
        "",
        f"#define HD_PARAM_VERSION {version}u",
        f"#define HD_PARAM_TABLE_HASH 0x{table_hash(params):08X}u",
        f"#define HD_PARAM_COUNT {len(params)}u",
        "",
        "typedef enum {",
    ]
    for i, p in enumerate(params):
        lines.append(f"    HD_P_{p.name.upper()} = {i},")
    lines += [
        "} hd_param_id_t;",
        "",
        "#define HD_PTYPE_I32 0u",
        "#define HD_PTYPE_U32 1u",
        "",
        "typedef struct {",
        "    const char *name;",
        "    uint16_t index;     /* CANopen object index */",
        "    uint8_t  sub;       /* CANopen subindex */",
        "    uint8_t  type;      /* HD_PTYPE_* */",
        "    uint8_t  frac;      /* fractional bits of the raw value */",
        "    int32_t  min, max, def;  /* raw */",
        "    const char *unit;",
        "} hd_param_desc_t;",
        "",
        "extern const hd_param_desc_t hd_param_table[HD_PARAM_COUNT];",
        "",
        "#endif",
        "",
    ]
    return "\n".join(lines)


def gen_c_source(params: list[Param]) -> str:
    lines = [
        "/* GENERATED by tools/gen_params.py from firmware/params/params.toml: do not edit. */",
        '#include "hd_param_table.h"',
        "",
        "const hd_param_desc_t hd_param_table[HD_PARAM_COUNT] = {",
    ]
    for p in params:
        t = "HD_PTYPE_U32" if p.type == "u32" else "HD_PTYPE_I32"

        def lit(v: int) -> str:
            return "INT32_MIN" if v == -(2 ** 31) else f"{v}"
        lines.append(
            f"    {{{_c_str(p.name)}, 0x{p.index:04X}u, {p.sub}u, {t}, {p.frac}u, "
            f"{lit(p.raw_min)}, {lit(p.raw_max)}, {lit(p.raw_default)}, {_c_str(p.unit)}}},")
    lines += ["};", ""]
    return "\n".join(lines)


def gen_python(version: int, params: list[Param]) -> str:
    lines = [
        '"""GENERATED by tools/gen_params.py from firmware/params/params.toml: do not edit.',
        "",
        "Drive parameters: CANopen address, type, unit, fractional bits and SI range/default.",
        '"""',
        "from __future__ import annotations",
        "",
        "from typing import NamedTuple",
        "",
        f"VERSION = {version}",
        f"TABLE_HASH = 0x{table_hash(params):08X}",
        "",
        "",
        "class ParamDef(NamedTuple):",
        '    """One parameter (SI min/max/default; raw = round(SI * 2**frac))."""',
        "",
        "    id: int",
        "    name: str",
        "    index: int",
        "    sub: int",
        "    type: str",
        "    unit: str",
        "    frac: int",
        "    min: float",
        "    max: float",
        "    default: float",
        "    raw_min: int",
        "    raw_max: int",
        "    raw_default: int",
        "    desc: str",
        "",
        "",
        "PARAMS: tuple[ParamDef, ...] = (",
    ]
    for i, p in enumerate(params):
        lines.append(
            f"    ParamDef({i}, {p.name!r}, 0x{p.index:04X}, {p.sub}, {p.type!r}, {p.unit!r}, {p.frac}, "
            f"{p.min!r}, {p.max!r}, {p.default!r}, {p.raw_min}, {p.raw_max}, {p.raw_default}, {p.desc!r}),")
    lines += [
        ")",
        "BY_NAME: dict[str, ParamDef] = {p.name: p for p in PARAMS}",
        "",
    ]
    return "\n".join(lines)


def gen_markdown(version: int, params: list[Param]) -> str:
    lines = [
        "<!-- GENERATED by tools/gen_params.py from firmware/params/params.toml: do not edit. -->",
        "# Drive parameters",
        "",
        f"Table version {version}, layout hash 0x{table_hash(params):08X}, {len(params)} parameters.",
        "Raw value = round(value x 2^frac) in a 32-bit word; defaults are the reference axis",
        "(CSF-25-100 pitch axis, docs/reference-axis.md). The parameter store (NVM) keeps two",
        "slots with sequence numbers and a CRC-32; a corrupt or incompatible store loads these defaults.",
        "",
        "| index:sub | name | type | unit | frac | min | max | default | description |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for p in params:
        lines.append(f"| 0x{p.index:04X}:{p.sub} | `{p.name}` | {p.type} | {p.unit} | {p.frac} | "
                     f"{p.min:g} | {p.max:g} | {p.default:g} | {p.desc} |")
    lines.append("")
    return "\n".join(lines)


def write_all(outputs: dict[Path, str], root: Path) -> None:
    """Write every file via temp + rename, only after all contents exist."""
    tmps: list[tuple[str, Path]] = []
    try:
        for rel, text in outputs.items():
            dst = root / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=dst.parent, prefix=".gen_params.")
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
            tmps.append((tmp, dst))
        for tmp, dst in tmps:
            os.replace(tmp, dst)
    finally:
        for tmp, _ in tmps:
            if os.path.exists(tmp):
                os.unlink(tmp)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", type=Path, default=DEFAULT_INPUT)
    ap.add_argument("--out-dir", type=Path, default=ROOT)
    a = ap.parse_args(argv)
    try:
        version, params = load(a.input)
    except ParamError as e:
        print(f"gen_params: {e}", file=sys.stderr)
        return 1
    outputs = {
        OUT_C_H: gen_c_header(version, params),
        OUT_C_C: gen_c_source(params),
        OUT_PY: gen_python(version, params),
        OUT_MD: gen_markdown(version, params),
    }
    write_all(outputs, a.out_dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
