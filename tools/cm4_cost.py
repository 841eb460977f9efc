#!/usr/bin/env python3
"""Turn a cost-image run into ``build/bench/cm4_cost.json``.

Inputs are two runs of ``build/golden/cost_m4.elf`` under the QEMU plugin
``tools/qemu-insncount`` (semihosting stdout with ``COST <kernel>`` lines, and
the plugin log with one ``MARK <count>`` line per call of hd_gv_cost_mark).
The first two marks are the baseline (two back-to-back mark calls: the
``bl`` and the mark's ``bx lr``); each kernel then contributes two marks and
its cost is the instruction count between them minus the baseline, i.e. the
instructions of one call including argument set-up and result store.

Kernels of the control period are measured once per slot of the multi-rate
schedule (``firmware/app/hd_sched.h``: ``<name>.s0`` .. ``<name>.s<N-1>``, N =
``HD_SCHED_CYCLE``); the file then also holds ``<name>`` itself, the WORST slot
(``instructions``, ``worst_slot``, ``slots``).  A kernel with a missing slot is
an error, so the worst tick is never under-reported.

Usage::

    cm4_cost.py OUT.json STDOUT1 MARKS1 STDOUT2 MARKS2
"""
from __future__ import annotations

import json
import os
import re
import sys
import tempfile
from pathlib import Path

SCHED_H = Path(__file__).resolve().parents[1] / "firmware" / "app" / "hd_sched.h"


class CostError(Exception):
    """A run log that does not have the expected shape."""


def parse_run(stdout_path: Path, marks_path: Path) -> dict[str, int]:
    """Instructions per kernel call from one run.

    Parameters
    ----------
    stdout_path : Path
        Semihosting output of the cost image.
    marks_path : Path
        Plugin log (``MARK <n>`` lines, instruction counts).

    Returns
    -------
    dict[str, int]
        Kernel name -> instructions per call (Cortex-M4 instructions).
    """
    names = [ln.split(None, 1)[1].strip() for ln in stdout_path.read_text().splitlines()
             if ln.startswith("COST ")]
    if "DONE" not in stdout_path.read_text().split():
        raise CostError(f"{stdout_path}: the cost image did not print DONE")
    marks: list[int] = []
    for i, ln in enumerate(marks_path.read_text().splitlines(), 1):
        if ln.startswith("MARK "):
            try:
                marks.append(int(ln.split()[1]))
            except (IndexError, ValueError):
                raise CostError(f"{marks_path}:{i}: expected 'MARK <count>'") from None
    if len(marks) != 2 + 2 * len(names):
        raise CostError(f"{marks_path}: {len(marks)} marks for {len(names)} kernels; expected "
                        f"{2 + 2 * len(names)} (each cost() must call hd_gv_cost_mark exactly twice)")
    base = marks[1] - marks[0]
    out: dict[str, int] = {}
    for j, name in enumerate(names):
        out[name] = marks[3 + 2 * j] - marks[2 + 2 * j] - base
    return out


def sched_cycle(header: Path = SCHED_H) -> int:
    """Ticks per schedule cycle, ``HD_SCHED_CYCLE`` of ``hd_sched.h``.

    Parameters
    ----------
    header : Path
        The schedule header.

    Returns
    -------
    int
        Number of slots (ticks) of one cycle.
    """
    m = re.search(r"#define\s+HD_SCHED_CYCLE\s+(\d+)u?", header.read_text())
    if m is None:
        raise CostError(f"{header}: no HD_SCHED_CYCLE")
    return int(m.group(1))


def fold_slots(kernels: dict[str, int], cycle: int) -> dict[str, dict]:
    """Kernel entries with the per-slot kernels folded into their worst slot.

    Parameters
    ----------
    kernels : dict[str, int]
        Kernel name -> instructions; ``<base>.s<k>`` is slot k of ``<base>``.
    cycle : int
        Slots per schedule cycle; every base must have all of 0 .. cycle - 1.

    Returns
    -------
    dict[str, dict]
        Every kernel as ``{"instructions": n}``, plus per base
        ``{"instructions": worst, "worst_slot": k, "slots": [n0, n1, ...]}``.

    Raises
    ------
    CostError
        A base whose slots are not exactly 0 .. cycle - 1.
    """
    out: dict[str, dict] = {k: {"instructions": v} for k, v in kernels.items()}
    bases: dict[str, dict[int, int]] = {}
    for k, v in kernels.items():
        m = re.fullmatch(r"(.+)\.s(\d+)", k)
        if m:
            bases.setdefault(m.group(1), {})[int(m.group(2))] = v
    for b, sl in bases.items():
        if sorted(sl) != list(range(cycle)):
            raise CostError(f"kernel {b}: slots {sorted(sl)} measured, expected 0..{cycle - 1} "
                            f"(HD_SCHED_CYCLE {cycle})")
        per = [sl[i] for i in range(cycle)]
        worst = max(range(cycle), key=lambda i: per[i])
        out[b] = {"instructions": per[worst], "worst_slot": worst, "slots": per}
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 6:
        print(__doc__, file=sys.stderr)
        return 2
    out = Path(argv[1])
    try:
        run1 = parse_run(Path(argv[2]), Path(argv[3]))
        run2 = parse_run(Path(argv[4]), Path(argv[5]))
        kernels = fold_slots(run1, sched_cycle())
    except (CostError, OSError) as e:
        print(f"cm4_cost: {e}", file=sys.stderr)
        return 1
    doc = {
        "kernels": kernels,
        "meta": {
            "unit": "Cortex-M4 instructions per call (QEMU mps2-an386 TCG plugin count, not cycles)",
            "includes": "argument set-up, bl/return and result store of one call; baseline subtracted",
            "repeatable": run1 == run2,
        },
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.")
    with os.fdopen(fd, "w") as f:
        json.dump(doc, f, indent=1, sort_keys=False)
        f.write("\n")
    os.replace(tmp, out)
    width = max((len(k) for k in kernels), default=10)
    for k, v in kernels.items():
        extra = f"  (worst slot {v['worst_slot']} of {v['slots']})" if "slots" in v else ""
        print(f"  {k:<{width}}  {v['instructions']:6d} instructions{extra}")
    print(f"{len(run1)} kernels, repeatable across two runs: {run1 == run2}; wrote {out}")
    return 0 if run1 == run2 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
