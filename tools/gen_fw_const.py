#!/usr/bin/env python3
"""Generate ``host/hdservo/fw_const.py``: the firmware facts Python needs, read from the C.

The C headers are the one source of the loop rate, the Q formats of the signals, the
capture signal ids, the application fault codes with their EMCY codes, the excitation
kinds and injection points and the parameter-store status codes.  This script reads
them and writes one Python module; ``tests/checks/params_fresh.sh`` fails when the
committed module differs from a fresh run.

Usage::

    tools/gen_fw_const.py [--out-dir DIR]

A header that no longer has what is read here is one line on stderr and exit 1;
nothing is written.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT_PY = Path("host/hdservo/fw_const.py")

UNITS_H = "firmware/core/hd_units.h"
APP_H = "firmware/app/hd_app.h"
EXC_H = "firmware/core/hd_excitation.h"
PSTORE_H = "firmware/app/hd_param_store.h"
APP_CO_C = "firmware/canopen/hd_app_co.c"
CO_H = "firmware/canopen/hd_co.h"


class GenError(Exception):
    """A header lacks what the generator reads."""


def _read(rel: str) -> str:
    return (ROOT / rel).read_text(encoding="utf-8")


def _define(rel: str, name: str) -> int:
    m = re.search(rf"#define\s+{name}\s+(0x[0-9A-Fa-f]+|\d+)u?\b", _read(rel))
    if m is None:
        raise GenError(f"{rel}: #define {name} not found")
    return int(m.group(1), 0)


def _enum(rel: str, typedef: str, prefix: str) -> dict[str, int]:
    """Members of ``typedef enum {...} typedef;`` as {name without prefix, lower case: value}."""
    text = _read(rel)
    m = re.search(r"typedef\s+enum\s*\{(?P<body>[^}]*)\}\s*" + typedef + r"\s*;", text)
    if m is None:
        raise GenError(f"{rel}: typedef enum {typedef} not found")
    body = re.sub(r"/\*.*?\*/", "", m.group("body"), flags=re.S)
    out: dict[str, int] = {}
    for item in body.split(","):
        item = item.strip()
        if not item:
            continue
        mm = re.fullmatch(rf"{prefix}(\w+)\s*=\s*(0x[0-9A-Fa-f]+|\d+)u?", item)
        if mm is None:
            raise GenError(f"{rel}: {typedef}: member '{item}' has no explicit value")
        out[mm.group(1).lower()] = int(mm.group(2), 0)
    return out


def _fault_emcy(faults: dict[str, int]) -> dict[int, int]:
    """The EMCY code of each application fault, from ``hd_app_co_emcy_for_fault``."""
    text = _read(APP_CO_C)
    m = re.search(r"uint16_t\s+hd_app_co_emcy_for_fault\s*\([^)]*\)\s*\{(?P<body>.*?)\n\}", text, re.S)
    if m is None:
        raise GenError(f"{APP_CO_C}: hd_app_co_emcy_for_fault not found")
    out: dict[int, int] = {}
    for name, code in re.findall(r"case\s+HD_FAULT_(\w+)\s*:\s*return\s+(\w+)\s*;", m.group("body")):
        value = int(code.rstrip("u"), 0) if code[0].isdigit() else _define(CO_H, code)
        key = name.lower()
        if key not in faults:
            raise GenError(f"{APP_CO_C}: hd_app_co_emcy_for_fault: unknown fault HD_FAULT_{name}")
        out[faults[key]] = value
    return out


def render() -> str:
    """The text of fw_const.py."""
    loop_hz = _define(UNITS_H, "HD_LOOP_HZ")
    q = {name: _define(UNITS_H, f"HD_{name.upper()}_FRAC_BITS")
         for name in ("angle", "vel_out", "vel_mot", "acc", "torque", "current")}
    sigs = _enum(APP_H, "hd_sig_t", "HD_SIG_")
    sig_count = sigs.pop("count")
    faults = _enum(APP_H, "hd_fault_t", "HD_FAULT_")
    emcy = _fault_emcy(faults)
    modes = _enum(APP_H, "hd_mode_t", "HD_MODE_")
    inj = _enum(APP_H, "hd_inj_t", "HD_INJ_")
    exc = _enum(EXC_H, "hd_exc_kind_t", "HD_EXC_")
    pstore = _enum(PSTORE_H, "hd_pstore_status_t", "HD_PSTORE_")
    lines = [
        '"""Firmware facts for the host, generated from the C headers by tools/gen_fw_const.py.',
        "",
        "Do not edit: change the C and run ``tools/gen_fw_const.py``.",
        '"""',
        "from __future__ import annotations",
        "",
        f"#: control loop rate, Hz ({UNITS_H} HD_LOOP_HZ)",
        f"LOOP_HZ = {loop_hz}",
        "#: control period, s",
        "LOOP_DT_S = 1.0 / LOOP_HZ",
        "",
        f"#: fraction bits of the fixed-point signal formats ({UNITS_H})",
        "FRAC_BITS = {" + ", ".join(f'"{k}": {v}' for k, v in q.items()) + "}",
        "",
        f"#: capture signal ids (hd_sig_t, {APP_H})",
        "SIGNALS = {" + ", ".join(f'"{k}": {v}' for k, v in sigs.items()) + "}",
        f"SIGNAL_COUNT = {sig_count}",
        "",
        f"#: application fault codes (hd_fault_t, {APP_H})",
        "FAULTS = {" + ", ".join(f'"{k}": {v}' for k, v in faults.items()) + "}",
        "#: fault code -> name (upper case, as the drive's documentation writes it)",
        "FAULT_NAMES = {" + ", ".join(f'{v}: "{k.upper()}"' for k, v in faults.items()) + "}",
        f"#: fault code -> EMCY error code ({APP_CO_C} hd_app_co_emcy_for_fault)",
        "FAULT_EMCY = {" + ", ".join(f"{k}: 0x{v:04X}" for k, v in sorted(emcy.items())) + "}",
        "",
        f"#: drive modes (hd_mode_t, {APP_H})",
        "MODES = {" + ", ".join(f'"{k}": {v}' for k, v in modes.items()) + "}",
        f"#: excitation injection points (hd_inj_t, {APP_H})",
        "INJECTION = {" + ", ".join(f'"{k}": {v}' for k, v in inj.items()) + "}",
        f"#: excitation kinds (hd_exc_kind_t, {EXC_H})",
        "EXCITATION = {" + ", ".join(f'"{k}": {v}' for k, v in exc.items()) + "}",
        f"#: parameter-store boot status (hd_pstore_status_t, {PSTORE_H})",
        "PSTORE_STATUS = {" + ", ".join(f'{v}: "{k.upper()}"' for k, v in pstore.items()) + "}",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--out-dir", type=Path, default=ROOT, help="output root (default: the repository)")
    args = ap.parse_args(argv)
    try:
        text = render()
    except (GenError, OSError) as e:
        print(f"gen_fw_const.py: {e}", file=sys.stderr)
        return 1
    out = args.out_dir / OUT_PY
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=".fw_const.", suffix=".tmp")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
