#!/usr/bin/env python3
"""Per-phase instruction counts of hd_app_step from probe-image mark logs.

Called by ``tests/bench/15_phase_cost.sh``::

    phase_cost.py OUT.json CM4_COST.json KERNEL MARKS [KERNEL MARKS ...]

Each MARKS file is the ``tools/qemu-insncount`` log of one probe image: two
baseline marks, the marks of the kernel's set-up steps, then the kernel's
start mark, the ``len(PHASES) + 1`` phase marks of the measured hd_app_step
and the kernel's end mark.  The phases must be listed here in the order of
the ``PHASE_MARK()`` calls in ``hd_app_step`` (firmware/app/hd_app.c).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

PHASES = ["sensors", "references", "comp_bank", "hunt_breaker", "loops",
          "limits_faults", "command", "telemetry"]


def phase_counts(marks_path: Path) -> dict[str, int]:
    """Instructions per phase of the last hd_app_step in one mark log.

    Parameters
    ----------
    marks_path : Path
        Plugin log with ``MARK <count>`` lines (Cortex-M4 instructions).

    Returns
    -------
    dict[str, int]
        Phase name -> instructions; ``before_step`` is the kernel's work from its
        start mark to the step's entry (port work of isr_worst_case, the call),
        ``after_step`` from the step's last phase to the kernel's end mark.
    """
    marks = [int(ln.split()[1]) for ln in marks_path.read_text().splitlines() if ln.startswith("MARK ")]
    need = 2 + len(PHASES) + 1 + 1
    if len(marks) < need:
        raise ValueError(f"{marks_path}: {len(marks)} marks, expected at least {need}")
    base = marks[1] - marks[0]
    tail = marks[-(len(PHASES) + 3):]
    out = {"before_step": tail[1] - tail[0] - base}
    for i, name in enumerate(PHASES):
        out[name] = tail[i + 2] - tail[i + 1] - base
    out["after_step"] = tail[-1] - tail[-2] - base
    return out


def fold_ticks(res: dict[str, dict]) -> dict[str, dict]:
    """Per-tick probe results ``<base>.s<k>`` folded into ``<base>``.

    Parameters
    ----------
    res : dict[str, dict]
        Kernel name -> ``{"phases_instructions": .., "sum": ..}`` (Cortex-M4 instructions).

    Returns
    -------
    dict[str, dict]
        Per base: the phases of its worst tick (largest sum), ``worst_tick``, and per
        phase the instructions of every tick (``ticks``: phase -> list) and the worst
        over the ticks (``worst_instructions``: phase -> max).
    """
    bases: dict[str, dict[int, dict]] = {}
    for name, r in res.items():
        base, sep, tick = name.rpartition(".s")
        if sep and tick.isdigit():
            bases.setdefault(base, {})[int(tick)] = r
    out: dict[str, dict] = {}
    for base, per in bases.items():
        order = sorted(per)
        worst = max(order, key=lambda t: per[t]["sum"])
        phases = list(per[worst]["phases_instructions"])
        out[base] = {"phases_instructions": per[worst]["phases_instructions"], "sum": per[worst]["sum"],
                     "kernel_instructions": per[worst]["kernel_instructions"], "worst_tick": worst,
                     "ticks": {n: [per[t]["phases_instructions"][n] for t in order] for n in phases},
                     "worst_instructions": {n: max(per[t]["phases_instructions"][n] for t in order)
                                            for n in phases}}
        print(f"{base}: worst tick {worst}; comp_bank per tick " +
              ", ".join(str(v) for v in out[base]["ticks"]["comp_bank"]))
    return out


def main(argv: list[str]) -> int:
    """Write the per-phase JSON; 0 on success, 1 on a malformed log."""
    if len(argv) < 5 or (len(argv) - 3) % 2:
        print("usage: phase_cost.py OUT.json CM4_COST.json KERNEL MARKS [KERNEL MARKS ...]")
        return 2
    out_path, cost_path = Path(argv[1]), Path(argv[2])
    whole = json.loads(cost_path.read_text())["kernels"] if cost_path.exists() else {}
    res: dict[str, dict] = {}
    for k, m in zip(argv[3::2], argv[4::2]):
        try:
            ph = phase_counts(Path(m))
        except (OSError, ValueError) as e:
            print(f"phase_cost: {e}")
            return 1
        res[k] = {"phases_instructions": ph, "sum": sum(ph.values()),
                  "kernel_instructions": whole.get(k, {}).get("instructions")}
        print(f"{k}: " + ", ".join(f"{n} {v}" for n, v in ph.items()) + f" (sum {res[k]['sum']}, "
              f"kernel {res[k]['kernel_instructions']})")
    res.update(fold_ticks(res))
    out_path.write_text(json.dumps({"meta": {"unit": "Cortex-M4 instructions (QEMU TCG count)",
                                             "phases": PHASES}, "kernels": res}, indent=2) + "\n")
    print(f"wrote {out_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
