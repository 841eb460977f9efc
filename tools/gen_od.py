#!/usr/bin/env python3
"""Generate the CANopen object dictionary from firmware/params/{params,canopen}.toml.

Second generator stage next to ``tools/gen_params.py``: it reads the same
parameter file (``params.toml``, the drive parameters 0x2000-0x4FFF) plus
``canopen.toml`` (CiA 301 communication objects, CiA 402 objects,
manufacturer process data and domains) and writes, relative to the output
root (default: the repository):

* ``firmware/canopen/hd_co_od.h`` / ``.c``  -- sorted C entry table + data struct
* ``host/hdservo/data/hdservo.eds``         -- EDS (loads in python ``canopen``)
* ``host/hdservo/data/hdservo.dbc``         -- DBC of the default PDOs of node 1
* ``host/hdservo/od_gen.py``                -- Python constants
* ``docs/od.md``                            -- object dictionary reference

Usage::

    tools/gen_od.py [--out-dir DIR] [--params FILE] [--canopen FILE]

Bad input prints one line naming the file and the object and exits 1;
nothing is written unless every output was produced.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
import gen_params  # noqa: E402  (same directory)

DEFAULT_PARAMS = ROOT / "firmware" / "params" / "params.toml"
DEFAULT_CANOPEN = ROOT / "firmware" / "params" / "canopen.toml"
OUT_H = Path("firmware/canopen/hd_co_od.h")
OUT_C = Path("firmware/canopen/hd_co_od.c")
OUT_EDS = Path("host/hdservo/data/hdservo.eds")
OUT_DBC = Path("host/hdservo/data/hdservo.dbc")
OUT_PY = Path("host/hdservo/od_gen.py")
OUT_MD = Path("docs/od.md")

# name: (CANopen data type code, bytes, C type, min, max)
TYPES: dict[str, tuple[int, int, str, int, int]] = {
    "bool": (0x01, 1, "uint8_t", 0, 1),
    "i8": (0x02, 1, "int8_t", -2 ** 7, 2 ** 7 - 1),
    "i16": (0x03, 2, "int16_t", -2 ** 15, 2 ** 15 - 1),
    "i32": (0x04, 4, "int32_t", -2 ** 31, 2 ** 31 - 1),
    "u8": (0x05, 1, "uint8_t", 0, 2 ** 8 - 1),
    "u16": (0x06, 2, "uint16_t", 0, 2 ** 16 - 1),
    "u32": (0x07, 4, "uint32_t", 0, 2 ** 32 - 1),
    "vstr": (0x09, 0, "", 0, 0),
    "domain": (0x0F, 0, "", 0, 0),
    "i64": (0x15, 8, "int64_t", -2 ** 63, 2 ** 63 - 1),
    "u64": (0x1B, 8, "uint64_t", 0, 2 ** 63 - 1),  # range checks stop at INT64_MAX
}
ACCESS = {"ro": "HD_CO_A_RO", "wo": "HD_CO_A_WO", "rw": "HD_CO_A_RW", "const": "HD_CO_A_CONST"}
NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")
NODEID_RE = re.compile(r"^\$NODEID\s*\+\s*(0x[0-9A-Fa-f]+|\d+)$")


class OdError(Exception):
    """One-line description of a defect in a data file."""


@dataclass
class Var:
    """One OD entry (index, sub) with everything the outputs need."""

    index: int
    sub: int
    name: str
    type: str
    access: str
    kind: str = "var"            # var | param | domain | str | special
    arg: int = 0                 # param id / domain id
    pdo: str = ""                # "t", "r" or ""
    flags: list[str] = field(default_factory=list)
    default: int = 0
    nodeid: bool = False         # default is $NODEID + default
    string: str = ""
    min: int = 0
    max: int = 0
    unit: str = ""
    desc: str = ""
    factor: float = 1.0
    cfield: str = ""             # C field designator in hd_co_od_data_t


@dataclass
class Obj:
    """One object: a VAR (one entry, sub 0) or a RECORD/ARRAY."""

    index: int
    name: str
    objtype: str                 # var | record | array
    desc: str
    subs: list[Var]


@dataclass
class Pdo:
    """Default configuration of one PDO."""

    direction: str               # "t" | "r"
    num: int
    trans: int
    enabled: bool
    mapping: list[tuple[int, int]]
    event: int = 0
    inhibit: int = 0             # 100 us units (0x1800:3): least time between two sends of a TPDO


@dataclass
class Od:
    """The whole dictionary."""

    meta: dict
    objects: list[Obj]
    pdos: list[Pdo]
    param_version: int
    param_hash: int


def _int(v: object, where: str, what: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise OdError(f"{where}: {what} must be an integer")
    return v


def _parse_var(e: dict, meta: dict, where: str, index: int, sub: int, name: str,
               params: dict[str, tuple[int, "gen_params.Param"]] | None = None) -> Var:
    typ = e.get("type")
    if typ not in TYPES:
        raise OdError(f"{where}: type must be one of {sorted(TYPES)}")
    acc = e.get("access", "rw")
    if acc not in ACCESS:
        raise OdError(f"{where}: access must be one of {sorted(ACCESS)}")
    kind = e.get("kind", "var")
    arg = 0
    if kind.startswith("domain:"):
        if typ != "domain":
            raise OdError(f"{where}: kind domain:N needs type domain")
        try:
            arg = int(kind.split(":", 1)[1])
        except ValueError:
            raise OdError(f"{where}: kind domain:N needs an integer N") from None
        kind = "domain"
    elif kind.startswith("param:"):
        # a standard object that *is* a drive parameter (e.g. 0x6081 = traj_vmax): one
        # value, reached under two indexes; limits and default are the parameter's
        pname = kind.split(":", 1)[1]
        if params is None or pname not in params:
            raise OdError(f"{where}: kind param:NAME names no parameter of params.toml ({pname!r})")
        arg, prm = params[pname]
        tmin_, tmax_ = TYPES[typ][3], TYPES[typ][4]
        if "default" in e or "min" in e or "max" in e:
            raise OdError(f"{where}: kind param:NAME takes default/min/max from the parameter; remove them")
        if not (tmin_ <= prm.raw_min and prm.raw_max <= tmax_):
            raise OdError(f"{where}: parameter {pname} range [{prm.raw_min}, {prm.raw_max}] does not fit type {typ}")
        e = {**e, "default": prm.raw_default, "min": prm.raw_min, "max": prm.raw_max}
        kind = "param"
    elif kind not in ("var", "special"):
        raise OdError(f"{where}: kind must be var, special, domain:N or param:NAME")
    if typ == "domain" and kind != "domain":
        raise OdError(f"{where}: type domain needs kind domain:N")
    pdo = e.get("pdo", "")
    if pdo not in ("", "t", "r"):
        raise OdError(f"{where}: pdo must be 't' or 'r'")
    flags = list(e.get("flags", []))
    for f in flags:
        if f not in ("store", "cos"):
            raise OdError(f"{where}: unknown flag {f!r}")
    _, size, _, tmin, tmax = TYPES[typ]
    v = Var(index, sub, name, typ, acc, kind, arg, pdo, flags, unit=str(e.get("unit", "")),
            desc=str(e.get("desc", "")))
    d = e.get("default", 0 if typ != "vstr" else "")
    if isinstance(d, str) and d.startswith("@"):
        key = d[1:]
        if key not in meta:
            raise OdError(f"{where}: default {d} names no [meta] key")
        d = meta[key]
    if typ == "vstr":
        if not isinstance(d, str) or acc != "const":
            raise OdError(f"{where}: vstr needs a string default and access const")
        v.kind, v.string = "str", d
        return v
    if typ == "domain":
        return v
    if isinstance(d, str):
        m = NODEID_RE.match(d.strip())
        if not m:
            raise OdError(f"{where}: default must be an integer or '$NODEID+N'")
        v.nodeid, d = True, int(m.group(1), 0)
    v.default = _int(d, where, "default")
    v.min = _int(e.get("min", tmin), where, "min")
    v.max = _int(e.get("max", tmax), where, "max")
    if not tmin <= v.min <= v.max <= tmax:
        raise OdError(f"{where}: expected {tmin} <= min <= max <= {tmax} for {typ}")
    if not v.nodeid and not (v.min <= v.default <= v.max) and kind != "special":
        raise OdError(f"{where}: default {v.default} outside [{v.min}, {v.max}]")
    if size == 0:
        raise OdError(f"{where}: type {typ} has no size")
    return v


def _pdo_objects(pdos: list[Pdo], n_pdo: int, n_map: int) -> list[Obj]:
    out: list[Obj] = []
    for direction, comm_base, map_base, cob_base in (("r", 0x1400, 0x1600, 0x200), ("t", 0x1800, 0x1A00, 0x180)):
        arr = "rpdo" if direction == "r" else "tpdo"
        for i in range(n_pdo):
            p = next((q for q in pdos if q.direction == direction and q.num == i + 1), None)
            trans = p.trans if p else 255
            enabled = p.enabled if p else False
            cob = cob_base + 0x100 * i
            cobv = Var(comm_base + i, 1, "cob_id", "u32", "rw", default=cob | (0 if enabled else 0x80000000),
                       nodeid=True, min=0, max=0xFFFFFFFF, flags=["store"], cfield=f"{arr}_cob[{i}]",
                       desc="COB-ID (bit 31 = not valid)")
            subs = [Var(comm_base + i, 0, "highest_sub_index_supported", "u8", "const",
                        default=6 if direction == "t" else 5, min=0, max=255, cfield="")]
            subs[0].kind = "special"
            subs.append(cobv)
            subs.append(Var(comm_base + i, 2, "transmission_type", "u8", "rw", default=trans, min=0,
                            max=255, flags=["store"], cfield=f"{arr}_type[{i}]"))
            subs.append(Var(comm_base + i, 3, "inhibit_time", "u16", "rw", default=p.inhibit if p else 0, min=0,
                            max=0xFFFF, flags=["store"], unit="100 us", cfield=f"{arr}_inhibit[{i}]"))
            subs.append(Var(comm_base + i, 5, "event_timer", "u16", "rw", default=p.event if p else 0, min=0,
                            max=0xFFFF, flags=["store"], unit="ms", cfield=f"{arr}_event[{i}]"))
            if direction == "t":
                subs.append(Var(comm_base + i, 6, "sync_start_value", "u8", "rw", default=0, min=0,
                                max=240, flags=["store"], cfield=f"{arr}_sync_start[{i}]"))
            out.append(Obj(comm_base + i, f"{'receive' if direction == 'r' else 'transmit'}_pdo_"
                           f"communication_parameter_{i + 1}", "record", "PDO communication parameter", subs))
            mp = p.mapping if p else []
            msubs = [Var(map_base + i, 0, "number_of_mapped_objects", "u8", "rw", default=len(mp), min=0,
                         max=n_map, flags=["store"], cfield=f"{arr}_nmap[{i}]")]
            for k in range(n_map):
                val = 0
                if k < len(mp):
                    val = mp[k][0] << 16 | mp[k][1] << 8 | mp[k][2]
                msubs.append(Var(map_base + i, k + 1, f"mapped_object_{k + 1}", "u32", "rw", default=val,
                                 min=0, max=0xFFFFFFFF, flags=["store"], cfield=f"{arr}_map[{i}][{k}]"))
            out.append(Obj(map_base + i, f"{'receive' if direction == 'r' else 'transmit'}_pdo_"
                           f"mapping_parameter_{i + 1}", "record", "PDO mapping parameter", msubs))
    return out


def load(params_path: Path, canopen_path: Path) -> Od:
    """Parse and validate both data files into one dictionary."""
    try:
        pversion, params = gen_params.load(params_path)
    except gen_params.ParamError as e:
        raise OdError(str(e)) from None
    try:
        data = tomllib.loads(canopen_path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise OdError(f"{canopen_path.name}: {e}") from None
    fname = canopen_path.name
    meta = data.get("meta", {})
    for k in ("od_version", "vendor_id", "product_code", "revision", "device_name", "n_pdo", "n_map"):
        if k not in meta:
            raise OdError(f"{fname}: [meta] misses '{k}'")
    pmap = {p.name: (i, p) for i, p in enumerate(params)}
    objects: list[Obj] = []
    for n, e in enumerate(data.get("object", []), 1):
        name = e.get("name", "?")
        where = f"{fname}: object {n} ({name})"
        index = _int(e.get("index"), where, "index")
        if not 0x1000 <= index <= 0x9FFF:
            raise OdError(f"{where}: index must be 0x1000-0x9FFF")
        if not isinstance(name, str) or not NAME_RE.match(name):
            raise OdError(f"{where}: name must be lower_snake")
        objtype = e.get("objtype", "var")
        desc = str(e.get("desc", ""))
        if objtype == "var":
            v = _parse_var(e, meta, where, index, 0, name, pmap)
            v.desc = desc
            objects.append(Obj(index, name, "var", desc, [v]))
            continue
        if objtype not in ("record", "array"):
            raise OdError(f"{where}: objtype must be var, record or array")
        subs: list[Var] = []
        for k, s in enumerate(e.get("sub", []), 1):
            sw = f"{where} sub entry {k}"
            sub = _int(s.get("sub"), sw, "sub")
            count = _int(s.get("count", 1), sw, "count")
            sname = s.get("name", "?")
            if not isinstance(sname, str) or not NAME_RE.match(sname):
                raise OdError(f"{sw}: name must be lower_snake")
            for c in range(count):
                nm = sname if count == 1 else f"{sname}_{c + 1}"
                subs.append(_parse_var(s, meta, sw, index, sub + c, nm, pmap))
        if not subs:
            raise OdError(f"{where}: a {objtype} needs [[object.sub]] entries")
        if subs[0].sub != 0:
            hv = Var(index, 0, "highest_sub_index_supported", "u8", "const", kind="special",
                     default=max(s.sub for s in subs), min=0, max=255)
            subs.insert(0, hv)
        seen = set()
        for s in subs:
            if s.sub in seen or not 0 <= s.sub <= 254:
                raise OdError(f"{where}: sub {s.sub} duplicated or out of 0..254")
            seen.add(s.sub)
        objects.append(Obj(index, name, objtype, desc, subs))
    # PDOs
    pdos: list[Pdo] = []
    n_pdo, n_map = int(meta["n_pdo"]), int(meta["n_map"])
    for direction in ("rpdo", "tpdo"):
        for n, e in enumerate(data.get(direction, []), 1):
            where = f"{fname}: {direction} {n}"
            num = _int(e.get("num"), where, "num")
            if not 1 <= num <= n_pdo:
                raise OdError(f"{where}: num must be 1..{n_pdo}")
            trans = _int(e.get("trans", 255), where, "trans")
            if not (trans <= 240 or trans in (254, 255)):
                raise OdError(f"{where}: trans must be 0..240, 254 or 255")
            mp: list[tuple[int, int]] = []
            for m in e.get("map", []):
                try:
                    a, b = str(m).split(":")
                    mp.append((int(a, 0), int(b, 0)))
                except ValueError:
                    raise OdError(f"{where}: map entry {m!r} must be 'index:sub'") from None
            if len(mp) > n_map:
                raise OdError(f"{where}: more than {n_map} mapped objects")
            event = _int(e.get("event", 0), where, "event")
            if not 0 <= event <= 0xFFFF:
                raise OdError(f"{where}: event must be 0..65535 ms")
            inhibit = _int(e.get("inhibit", 0), where, "inhibit")
            if not 0 <= inhibit <= 0xFFFF:
                raise OdError(f"{where}: inhibit must be 0..65535 (100 us units)")
            pdos.append(Pdo(direction[0], num, trans, bool(e.get("enabled", True)), mp, event,  # type: ignore[arg-type]
                            inhibit))
    # manufacturer parameters from params.toml
    by_index: dict[int, list[Var]] = {}
    for i, p in enumerate(params):
        v = Var(p.index, p.sub, p.name, p.type, "rw", kind="param", arg=i, flags=["store"],
                default=p.raw_default, min=p.raw_min, max=p.raw_max, unit=p.unit, desc=p.desc,
                factor=2.0 ** -p.frac)
        by_index.setdefault(p.index, []).append(v)
    for index, subs in sorted(by_index.items()):
        subs.sort(key=lambda s: s.sub)
        hv = Var(index, 0, "highest_sub_index_supported", "u8", "const", kind="special",
                 default=max(s.sub for s in subs), min=0, max=255)
        objects.append(Obj(index, f"params_{index:04x}", "record", "Drive parameters (params.toml)",
                           [hv] + subs))
    objects.sort(key=lambda o: o.index)
    for a, b in zip(objects, objects[1:]):
        if a.index == b.index:
            raise OdError(f"{fname}: index 0x{a.index:04X} defined twice ({a.name}, {b.name})")
    # resolve PDO mapping sizes and check them
    entries = {(v.index, v.sub): v for o in objects for v in o.subs}
    for p in pdos:
        bits = 0
        resolved = []
        for idx, sub in p.mapping:
            v = entries.get((idx, sub))
            where = f"{fname}: {'t' if p.direction == 't' else 'r'}pdo {p.num}"
            if v is None or v.pdo != p.direction:
                raise OdError(f"{where}: 0x{idx:04X}:{sub} is not {p.direction.upper()}PDO-mappable")
            nb = TYPES[v.type][1] * 8
            bits += nb
            resolved.append((idx, sub, nb))
        if bits > 64:
            raise OdError(f"{where}: mapping exceeds 64 bits")
        p.mapping = resolved  # type: ignore[assignment]
    # the PDO objects, with the resolved sizes
    if any(0x1400 <= o.index <= 0x1BFF for o in objects):
        raise OdError(f"{fname}: 0x1400-0x1BFF are generated from [[rpdo]]/[[tpdo]]")
    objects += _pdo_objects(pdos, n_pdo, n_map)
    objects.sort(key=lambda o: o.index)
    # C field names
    used: set[str] = set()
    for o in objects:
        for v in o.subs:
            if v.kind != "var" or v.cfield:
                continue
            base = v.name if o.objtype == "var" else f"{o.name}_{v.name}" if not v.name.startswith(o.name) else v.name
            if base in used:
                base = f"{base}_{v.index:04x}_{v.sub}"
            used.add(base)
            v.cfield = base
    return Od(meta, objects, pdos, pversion, gen_params.table_hash(params))


# ------------------------------------------------------------------ C ----
def _field_decls(od: Od) -> list[str]:
    n_pdo, n_map = int(od.meta["n_pdo"]), int(od.meta["n_map"])
    lines = []
    for o in od.objects:
        if 0x1400 <= o.index <= 0x1BFF:
            continue
        for v in o.subs:
            if v.kind == "var":
                lines.append(f"    {TYPES[v.type][2]} {v.cfield};  /* 0x{v.index:04X}:{v.sub} */")
    for arr in ("rpdo", "tpdo"):
        lines += [
            f"    uint32_t {arr}_cob[{n_pdo}];",
            f"    uint32_t {arr}_map[{n_pdo}][{n_map}];",
            f"    uint16_t {arr}_inhibit[{n_pdo}];",
            f"    uint16_t {arr}_event[{n_pdo}];",
            f"    uint8_t  {arr}_type[{n_pdo}];",
            f"    uint8_t  {arr}_nmap[{n_pdo}];",
        ]
    lines.append(f"    uint8_t  tpdo_sync_start[{n_pdo}];")
    return lines


def _c_lit(v: int) -> str:
    if v == -2 ** 63:
        return "INT64_MIN"
    return f"INT64_C({v})"


def _is_stored(v: Var) -> bool:
    """An entry 0x1010 keeps in the stored-object record (hd_co.c is_stored())."""
    return v.kind == "var" and "store" in v.flags and 0 < TYPES[v.type][1] <= 4


def gen_c_header(od: Od) -> str:
    n = sum(len(o.subs) for o in od.objects)
    n_stored = sum(1 for o in od.objects for v in o.subs if _is_stored(v))
    m = od.meta
    lines = [
        "/* GENERATED by tools/gen_od.py from firmware/params/{params,canopen}.toml: do not edit. */",
        "/*",
        " * hd_co_od.h - the CANopen object dictionary of the drive: the sorted entry",
        " * table (const) and the per-device data it points into (hd_co_od_data_t,",
        " * a member of hd_co_t).  Entry layout: hd_co_types.h.",
        " */",
        "#ifndef HD_CO_OD_H",
        "#define HD_CO_OD_H",
        "",
        "#include <stdint.h>",
        '#include "hd_co_types.h"',
        "",
        f"#define HD_CO_OD_VERSION {int(m['od_version'])}u",
        f"#define HD_CO_OD_PARAM_HASH 0x{od.param_hash:08X}u",
        f"#define HD_CO_OD_COUNT {n}u",
        "/* entries 0x1010 keeps in the stored-object record: hd_co_store_words() less",
        " * its layout word; the host's od_gen.STORED lists them for hdservo config */",
        f"#define HD_CO_OD_STORED {n_stored}u",
        f"#define HD_CO_N_PDO {int(m['n_pdo'])}u",
        f"#define HD_CO_N_MAP {int(m['n_map'])}u",
        f"#define HD_CO_VENDOR_ID 0x{int(m['vendor_id']):08X}u",
        f"#define HD_CO_PRODUCT_CODE 0x{int(m['product_code']):08X}u",
        f"#define HD_CO_REVISION 0x{int(m['revision']):08X}u",
        "",
        "typedef struct {",
        *_field_decls(od),
        "} hd_co_od_data_t;",
        "",
        "extern const hd_co_entry_t hd_co_od[HD_CO_OD_COUNT];",
        "",
        "#endif",
        "",
    ]
    return "\n".join(lines)


def gen_c_source(od: Od) -> str:
    lines = [
        "/* GENERATED by tools/gen_od.py from firmware/params/{params,canopen}.toml: do not edit. */",
        "#include <stddef.h>",
        '#include "hd_co_od.h"',
        "",
        "#define OFF(f) ((uint16_t)offsetof(hd_co_od_data_t, f))",
        "",
        "const hd_co_entry_t hd_co_od[HD_CO_OD_COUNT] = {",
    ]
    for o in od.objects:
        for v in o.subs:
            flags = []
            if v.pdo == "t":
                flags.append("HD_CO_F_TPDO")
            if v.pdo == "r":
                flags.append("HD_CO_F_RPDO")
            if "store" in v.flags:
                flags.append("HD_CO_F_STORE")
            if "cos" in v.flags:
                flags.append("HD_CO_F_COS")
            if v.nodeid:
                flags.append("HD_CO_F_NODEID")
            fl = "|".join(flags) if flags else "0"
            kind = {"var": "HD_CO_K_VAR", "param": "HD_CO_K_PARAM", "domain": "HD_CO_K_DOMAIN",
                    "str": "HD_CO_K_STR", "special": "HD_CO_K_SPECIAL"}[v.kind]
            arg = f"OFF({v.cfield})" if v.kind == "var" else f"{v.arg}u"
            s = '"' + v.string.replace('"', '\\"') + '"' if v.kind == "str" else "NULL"
            lines.append(
                f"    {{0x{v.index:04X}u, {v.sub}u, 0x{TYPES[v.type][0]:02X}u, {ACCESS[v.access]}, "
                f"(uint8_t)({fl}), {kind}, {arg}, {_c_lit(v.min)}, {_c_lit(v.max)}, "
                f"{_c_lit(v.default)}, {s}}},  /* {v.name} */")
    lines += ["};", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------- EDS ----
def _eds_name(s: str) -> str:
    return s


def _eds_var(v: Var, section: str) -> list[str]:
    code = TYPES[v.type][0]
    acc = v.access
    lines = [f"[{section}]", f"ParameterName={_eds_name(v.name)}", "ObjectType=0x7",
             f"DataType=0x{code:04X}", f"AccessType={acc}"]
    if v.type == "vstr":
        lines.append(f"DefaultValue={v.string}")
    elif v.type != "domain":
        if v.nodeid:
            lines.append(f"DefaultValue=$NODEID+0x{v.default:X}")
        else:
            lines.append(f"DefaultValue={v.default}" if v.default < 0 else f"DefaultValue=0x{v.default:X}")
        tmin, tmax = TYPES[v.type][3], TYPES[v.type][4]
        if (v.min, v.max) != (tmin, tmax) and v.kind != "special":
            lines.append(f"LowLimit={v.min}")
            lines.append(f"HighLimit={v.max}")
    lines.append(f"PDOMapping={1 if v.pdo else 0}")
    if v.factor != 1.0:
        lines.append(f"Factor={v.factor!r}")
    if v.unit:
        lines.append(f"Unit={v.unit}")
    if v.desc:
        lines.append(f"Description={v.desc}")
    lines.append("")
    return lines


def gen_eds(od: Od) -> str:
    m = od.meta
    mand = [o.index for o in od.objects if o.index in (0x1000, 0x1001, 0x1018)]
    opt = [o.index for o in od.objects if o.index < 0x2000 and o.index not in mand or o.index >= 0x6000]
    manu = [o.index for o in od.objects if 0x2000 <= o.index < 0x6000]
    lines = [
        "[FileInfo]",
        "FileName=hdservo.eds",
        "FileVersion=1",
        f"FileRevision={int(m['od_version'])}",
        "EDSVersion=4.0",
        "Description=hdservo harmonic-drive servo (GENERATED by tools/gen_od.py: do not edit)",
        f"CreationTime={m.get('eds_time', '12:00PM')}",
        f"CreationDate={m.get('eds_date', '01-01-2025')}",
        "CreatedBy=tools/gen_od.py",
        f"ModificationTime={m.get('eds_time', '12:00PM')}",
        f"ModificationDate={m.get('eds_date', '01-01-2025')}",
        "ModifiedBy=tools/gen_od.py",
        "",
        "[DeviceInfo]",
        "VendorName=hdservo",
        f"VendorNumber=0x{int(m['vendor_id']):08X}",
        f"ProductName={m['device_name']}",
        f"ProductNumber=0x{int(m['product_code']):08X}",
        f"RevisionNumber=0x{int(m['revision']):08X}",
        "OrderCode=hdservo",
    ]
    for rate in (10, 20, 50, 125, 250, 500, 800, 1000):
        lines.append(f"BaudRate_{rate}={1 if rate in (125, 250, 500, 1000) else 0}")
    lines += [
        "SimpleBootUpMaster=0",
        "SimpleBootUpSlave=1",
        "Granularity=8",
        "DynamicChannelsSupported=0",
        "CompactPDO=0",
        "GroupMessaging=0",
        f"NrOfRXPDO={int(m['n_pdo'])}",
        f"NrOfTXPDO={int(m['n_pdo'])}",
        "LSS_Supported=0",
        "",
        "[DummyUsage]",
    ]
    for d in range(1, 8):
        lines.append(f"Dummy{d:04X}=0")
    lines += ["", "[Comments]", "Lines=0", ""]
    for title, idxs in (("MandatoryObjects", mand), ("OptionalObjects", opt), ("ManufacturerObjects", manu)):
        lines.append(f"[{title}]")
        lines.append(f"SupportedObjects={len(idxs)}")
        for i, x in enumerate(idxs, 1):
            lines.append(f"{i}=0x{x:04X}")
        lines.append("")
    for o in od.objects:
        if o.objtype == "var":
            lines += _eds_var(o.subs[0], f"{o.index:04X}")
            continue
        lines += [f"[{o.index:04X}]", f"ParameterName={_eds_name(o.name)}",
                  f"ObjectType={'0x9' if o.objtype == 'record' else '0x8'}", f"SubNumber={len(o.subs)}", ""]
        for v in o.subs:
            lines += _eds_var(v, f"{o.index:04X}sub{v.sub:X}")
    return "\r\n".join(lines) + "\r\n"


# ---------------------------------------------------------------- DBC ----
def gen_dbc(od: Od) -> str:
    entries = {(v.index, v.sub): v for o in od.objects for v in o.subs}
    lines = ['VERSION "hdservo od %d"' % int(od.meta["od_version"]), "", "", "NS_ :", "", "BS_:", "",
             "BU_: HOST DRIVE", "", ""]
    comments = []
    for p in sorted(od.pdos, key=lambda q: (q.direction, q.num)):
        if not p.enabled or not p.mapping:
            continue
        node = 1
        cob = (0x180 if p.direction == "t" else 0x200) + 0x100 * (p.num - 1) + node
        nbytes = sum(nb for _, _, nb in p.mapping) // 8  # type: ignore[misc]
        mname = f"{'TPDO' if p.direction == 't' else 'RPDO'}{p.num}"
        sender = "DRIVE" if p.direction == "t" else "HOST"
        recv = "HOST" if p.direction == "t" else "DRIVE"
        lines.append(f"BO_ {cob} {mname}: {nbytes} {sender}")
        bit = 0
        for idx, sub, nb in p.mapping:  # type: ignore[misc]
            v = entries[(idx, sub)]
            signed = "-" if v.type.startswith("i") else "+"
            sname = v.name
            lines.append(f" SG_ {sname} : {bit}|{nb}@1{signed} (1,0) [0|0] \"{v.unit}\" {recv}")
            comments.append(f'CM_ SG_ {cob} {sname} "0x{idx:04X}:{sub} {v.desc}";')
            bit += nb
        lines.append("")
    lines.append("")
    lines += comments
    lines.append("")
    return "\n".join(lines)


# ------------------------------------------------------------- Python ----
def gen_python(od: Od) -> str:
    lines = [
        '"""GENERATED by tools/gen_od.py from firmware/params/{params,canopen}.toml: do not edit.',
        "",
        "CANopen object dictionary constants: (index, sub) of every entry by name.",
        '"""',
        "from __future__ import annotations",
        "",
        "from typing import NamedTuple",
        "",
        f"OD_VERSION = {int(od.meta['od_version'])}",
        f"PARAM_HASH = 0x{od.param_hash:08X}",
        f"VENDOR_ID = 0x{int(od.meta['vendor_id']):08X}",
        f"PRODUCT_CODE = 0x{int(od.meta['product_code']):08X}",
        f"REVISION = 0x{int(od.meta['revision']):08X}",
        f"N_PDO = {int(od.meta['n_pdo'])}",
        "",
        "",
        "class OdEntry(NamedTuple):",
        '    """One object dictionary entry."""',
        "",
        "    index: int",
        "    sub: int",
        "    name: str",
        "    type: str",
        "    access: str",
        "    pdo: str",
        "    unit: str",
        "    factor: float",
        "",
        "",
        "ENTRIES: tuple[OdEntry, ...] = (",
    ]
    for o in od.objects:
        for v in o.subs:
            lines.append(f"    OdEntry(0x{v.index:04X}, {v.sub}, {v.name!r}, {v.type!r}, {v.access!r}, "
                         f"{v.pdo!r}, {v.unit!r}, {v.factor!r}),")
    lines += [")", "BY_NAME: dict[str, OdEntry] = {e.name: e for e in ENTRIES if e.name != "
              "'highest_sub_index_supported' and not e.name.startswith('mapped_object_')}", "", "",
              "class StoredEntry(NamedTuple):",
              '    """One communication / CiA 402 setting 0x1010 saves (flag "store"; not the drive parameters)."""',
              "",
              "    index: int",
              "    sub: int",
              "    name: str",
              "    type: str",
              "    nodeid: bool      #: default is $NODEID + default (a COB-ID)",
              "    default: int",
              "    min: int",
              "    max: int",
              "    unit: str",
              "",
              "",
              "#: The stored objects in dictionary order (the drive's hd_co_store_* image, is_stored()).",
              "STORED: tuple[StoredEntry, ...] = ("]
    for o in od.objects:
        for v in o.subs:
            if _is_stored(v):
                lines.append(f"    StoredEntry(0x{v.index:04X}, {v.sub}, {v.name!r}, {v.type!r}, {v.nodeid!r}, "
                             f"{v.default}, {v.min}, {v.max}, {v.unit!r}),")
    lines += [")", "",
              "# SDO abort codes the drive produces",
              "ABORT_CODES: dict[int, str] = {"]
    for code, text in ABORTS:
        lines.append(f"    0x{code:08X}: {text!r},")
    lines += ["}", ""]
    return "\n".join(lines)


ABORTS = [
    (0x05030000, "toggle bit not alternated"),
    (0x05040000, "SDO protocol timed out"),
    (0x05040001, "command specifier not valid or unknown"),
    (0x05040002, "invalid block size"),
    (0x05040003, "invalid sequence number"),
    (0x05040004, "CRC error"),
    (0x06010001, "attempt to read a write-only object"),
    (0x06010002, "attempt to write a read-only object"),
    (0x06020000, "object does not exist"),
    (0x06040041, "object cannot be mapped to the PDO"),
    (0x06040042, "mapped objects exceed the PDO length"),
    (0x06070010, "data type does not match, length of service parameter does not match"),
    (0x06070012, "length of service parameter too high"),
    (0x06070013, "length of service parameter too low"),
    (0x06090011, "sub-index does not exist"),
    (0x06090030, "invalid value for parameter"),
    (0x06090031, "value of parameter written too high"),
    (0x06090032, "value of parameter written too low"),
    (0x08000000, "general error"),
    (0x08000020, "data cannot be transferred or stored (table check failed)"),
    (0x08000022, "data cannot be transferred or stored because of the present device state"),
]


def gen_markdown(od: Od) -> str:
    lines = [
        "<!-- GENERATED by tools/gen_od.py from firmware/params/{params,canopen}.toml: do not edit. -->",
        "# Object dictionary",
        "",
        f"OD version {int(od.meta['od_version'])}; drive-parameter layout hash 0x{od.param_hash:08X}. "
        "Access: ro/rw/wo/const; PDO: T = TPDO-mappable, R = RPDO-mappable. "
        "Drive parameters (0x2000-0x4FFF) are described with units and Q-formats in "
        "[parameters.md](parameters.md). See [can.md](can.md) for the protocol.",
        "",
        "| index:sub | name | type | access | PDO | default | unit | description |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for o in od.objects:
        if o.objtype != "var":
            lines.append(f"| **0x{o.index:04X}** | **{o.name}** | {o.objtype} | | | | | {o.desc} |")
        for v in o.subs:
            if v.kind == "str":
                d = v.string
            elif v.type == "domain":
                d = ""
            elif v.nodeid:
                d = f"$NODEID+0x{v.default:X}"
            else:
                d = f"0x{v.default:X}" if v.default > 9 and v.type.startswith("u") else str(v.default)
            lines.append(f"| 0x{v.index:04X}:{v.sub} | `{v.name}` | {v.type} | {v.access} | "
                         f"{v.pdo.upper()} | {d} | {v.unit} | {v.desc} |")
    lines += ["", "## SDO abort codes", "", "| code | meaning |", "|---|---|"]
    for code, text in ABORTS:
        lines.append(f"| 0x{code:08X} | {text} |")
    lines.append("")
    return "\n".join(lines)


def write_all(outputs: dict[Path, str], root: Path) -> None:
    """Write every file via temp + rename, only after all contents exist."""
    tmps: list[tuple[str, Path]] = []
    try:
        for rel, text in outputs.items():
            dst = root / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=dst.parent, prefix=".gen_od.")
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
                f.write(text)
            tmps.append((tmp, dst))
        for tmp, dst in tmps:
            os.replace(tmp, dst)
    finally:
        for tmp, _ in tmps:
            if os.path.exists(tmp):
                os.unlink(tmp)


def outputs_for(od: Od) -> dict[Path, str]:
    """Every generated file, by path relative to the output root."""
    return {
        OUT_H: gen_c_header(od),
        OUT_C: gen_c_source(od),
        OUT_EDS: gen_eds(od),
        OUT_DBC: gen_dbc(od),
        OUT_PY: gen_python(od),
        OUT_MD: gen_markdown(od),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", type=Path, default=DEFAULT_PARAMS)
    ap.add_argument("--canopen", type=Path, default=DEFAULT_CANOPEN)
    ap.add_argument("--out-dir", type=Path, default=ROOT)
    a = ap.parse_args(argv)
    try:
        od = load(a.params, a.canopen)
    except OdError as e:
        print(f"gen_od: {e}", file=sys.stderr)
        return 1
    write_all(outputs_for(od), a.out_dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
