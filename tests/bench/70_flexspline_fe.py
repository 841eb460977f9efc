#!/usr/bin/env python3
"""Cost of one design-flow FE evaluation -> build/bench/flexspline_fe.json.

``hdservo.design.fe_gear.candidate_figures`` (static two-zone stiffness with the
ellipse imposed, the rim-clamped stiffness, the torsional mode with the mesh/bearing
spring and the tilting mode) for CSF-25-100 with a 0.5 kg·m² load at the default mesh
level, one BLAS thread, the FE cache empty.  Records the process CPU time (the one-core
figure, robust to other load on the machine) and the wall time, each as a ratio to the
30 s budget, and the unknowns per harmonic.  Never fails on the numbers.
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
DST = ROOT / "build" / "bench" / "flexspline_fe.json"
BUDGET_S = 30.0


def main() -> int:
    from hdservo.design import catalogue as cat
    from hdservo.design import fe_gear as fg
    from hdservo.design import flexspline_fe as fe
    gear = cat.find_gear(25, 100)
    fg.candidate_figures(gear, 0.5, level=1)          # imports and first-call set-up out of the measurement
    fg._unit_stiffness.cache_clear()
    c0, w0 = time.process_time(), time.perf_counter()
    fig = fg.candidate_figures(gear, 0.5)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    out = {"gear": gear.name, "load_inertia_kgm2": 0.5, "mesh_level": fe.DEFAULT_LEVEL,
           "harmonics": fe.DEFAULT_HARMONICS, "dofs_per_harmonic": fig["dofs"], "cpu_s": cpu, "wall_s": wall,
           "budget_s": BUDGET_S, "cpu_over_budget": cpu / BUDGET_S, "wall_over_budget": wall / BUDGET_S,
           "torsional_Hz": fig["torsional_Hz"], "tilting_Hz": fig["tilting_Hz"]}
    DST.parent.mkdir(parents=True, exist_ok=True)
    DST.write_text(json.dumps(out, indent=1))
    print(f"flexspline FE evaluation ({fig['dofs']} unknowns per harmonic, level {fe.DEFAULT_LEVEL}): "
          f"CPU {cpu:.2f} s = {100 * cpu / BUDGET_S:.1f} % of the {BUDGET_S:.0f} s budget, wall {wall:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
