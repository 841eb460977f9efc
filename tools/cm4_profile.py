#!/usr/bin/env python3
"""Per-function instruction profile of one cost-image kernel -> ``build/bench/profile.json``.

``tests/bench/12_profile.sh`` runs the cost image once more under the QEMU plugin
``tools/qemu-insncount`` with ``window=K,pcs=FILE``: every guest instruction executed
between the kernel's two marks, by address.  This script

* ``window CM4_JSON STDOUT KERNEL``: prints the plugin's window index K of the kernel's
  worst tick (``KERNEL.s<worst_slot>`` of ``cm4_cost.json``; the marks of kernel j are
  2 + 2 j and 3 + 2 j, after the two baseline marks; STDOUT is the cost image's output with
  its ``COST`` lines);
* ``profile OUT_JSON CM4_JSON STDOUT KERNEL PCS MARKS NM``: sums the executed instructions per
  function (``arm-none-eabi-nm -n -S`` of the image: inlined helpers count in their caller;
  GCC's clone suffixes such as ``.isra.0`` are dropped) and writes ``kernel``, ``tick``,
  ``instructions`` (the window less the marks' baseline: the kernel's count in
  ``cm4_cost.json``, checked), ``by_symbol`` (largest first) and ``mark_baseline``.

A profile that does not add up to the kernel's count is an error (exit 1), never a file.
"""
from __future__ import annotations

import bisect
import json
import os
import sys
import tempfile
from pathlib import Path


class CostError(Exception):
    """A run log or listing that does not have the expected shape."""


def write_atomic(out: Path, doc: dict) -> None:
    """JSON to ``out`` through a temporary file and a rename (never half a file)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.")
    with os.fdopen(fd, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    os.replace(tmp, out)


def window_of(cm4: dict, stdout: Path, kernel: str) -> tuple[int, int]:
    """(mark index K that opens the window, tick) of the worst tick of ``kernel``."""
    k = cm4["kernels"].get(kernel)
    if k is None:
        raise CostError(f"{kernel}: not in cm4_cost.json")
    tick = int(k.get("worst_slot", 0))
    name = f"{kernel}.s{tick}" if "worst_slot" in k else kernel
    names = [ln.split(None, 1)[1].strip() for ln in stdout.read_text().splitlines() if ln.startswith("COST ")]
    if name not in names:
        raise CostError(f"{stdout}: no 'COST {name}' line")
    return 2 + 2 * names.index(name), tick


def symbols(nm_text: str) -> tuple[list[int], list[tuple[int, str]]]:
    """Function symbols of ``nm -n -S``: sorted starts and (end, name)."""
    starts: list[int] = []
    ends: list[tuple[int, str]] = []
    for ln in nm_text.splitlines():
        f = ln.split()
        if len(f) != 4 or f[2] not in "tTwW":
            continue
        a, size = int(f[0], 16) & ~1, int(f[1], 16)
        if size == 0:
            continue
        starts.append(a)
        ends.append((a + size, f[3].split(".")[0]))
    return starts, ends


def profile(pcs_text: str, nm_text: str) -> dict[str, int]:
    """Executed instructions per function of a ``PC <addr> <count>`` listing."""
    starts, ends = symbols(nm_text)
    out: dict[str, int] = {}
    for ln in pcs_text.splitlines():
        f = ln.split()
        if len(f) != 3 or f[0] != "PC":
            continue
        a, n = int(f[1], 0) & ~1, int(f[2])
        i = bisect.bisect_right(starts, a) - 1
        name = ends[i][1] if i >= 0 and a < ends[i][0] else "?"
        out[name] = out.get(name, 0) + n
    return dict(sorted(out.items(), key=lambda kv: (-kv[1], kv[0])))


def marks_of(path: Path) -> list[int]:
    return [int(ln.split()[1]) for ln in path.read_text().splitlines() if ln.startswith("MARK ")]


def main(argv: list[str]) -> int:
    try:
        if argv[:1] == ["window"] and len(argv) == 4:
            cm4 = json.loads(Path(argv[1]).read_text())
            k, _ = window_of(cm4, Path(argv[2]), argv[3])
            print(k)
            return 0
        if argv[:1] == ["profile"] and len(argv) == 8:
            out, cm4p, stdout, kernel, pcs, marks, nm = argv[1:]
            cm4 = json.loads(Path(cm4p).read_text())
            m = marks_of(Path(marks))
            k, t = window_of(cm4, Path(stdout), kernel)
            if len(m) < k + 2:
                raise CostError(f"{marks}: {len(m)} marks, the window of marks {k}, {k + 1} not closed")
            by = profile(Path(pcs).read_text(), Path(nm).read_text())
            window = sum(by.values())
            if window != m[k + 1] - m[k]:
                raise CostError(f"{pcs}: {window} instructions by address, the marks say {m[k + 1] - m[k]}")
            base = m[1] - m[0]
            want = int(cm4["kernels"][kernel]["instructions"])
            if window - base != want:
                raise CostError(f"profile of {kernel} tick {t}: {window - base} instructions, "
                                f"cm4_cost.json has {want}")
            doc = {"meta": {"unit": "Cortex-M4 instructions (QEMU TCG count) per function of the image, "
                                    "inlined helpers in their caller",
                            "window": "between the kernel's two marks; instructions = window - mark_baseline"},
                   "kernel": kernel, "tick": t, "instructions": window - base, "mark_baseline": base,
                   "by_symbol": by}
            write_atomic(Path(out), doc)
            print(f"  profile of {kernel} (tick {t}): {window - base} instructions; "
                  + ", ".join(f"{s} {n}" for s, n in list(by.items())[:6]) + ", ...")
            return 0
    except (CostError, OSError, ValueError, KeyError) as e:
        print(f"cm4_profile: {e}", file=sys.stderr)
        return 1
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
