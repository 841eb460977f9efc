#!/usr/bin/env python3
"""FE flexspline model -> build/results/flexspline_fe.json and three plots.

The FE against closed forms in limiting cases (thin tube in torsion and bending, ring
ovalisation) over three mesh levels; the convergence of a CSF-25-100 cup (stiffness,
torsional and tilting modes with a 0.5 kg·m² load, the pitch-drive example's); the
elasticities of stiffness and modes to wall, diaphragm, boss radius, length, diameter,
face width and rim thickening, and sweeps of the modes over +-30 %; the FE flexspline
against the analytic cup + diaphragm relation per size; the series rule's held-out
(leave-one-size-out) errors against catalogue K1 and K3.  Never fails on the numbers
(docs/design-flow.md reports them).  Plots: flexspline_fe_convergence.png,
flexspline_fe_sensitivity.png, flexspline_fe_modes.png.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "host"))

from hdservo.design import catalogue as cat  # noqa: E402
from hdservo.design import fe_gear as fg  # noqa: E402
from hdservo.design import fe_study as fs  # noqa: E402
from hdservo.design import flexspline_fe as fe  # noqa: E402
from hdservo.design import structure as st  # noqa: E402

OUT = REPO / "build" / "results"
SIZE, RATIO, LOAD = 25, 100, 0.5


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    gear = cat.find_gear(SIZE, RATIO)
    s = st.structure_for(SIZE, RATIO)
    k_fe = fg.flexspline_stiffness(s)
    rule = fg.load_rule()
    k1_rule = fg.predict(fg.Case(gear, s, k_fe), "k1", rule)
    spring, src = fg.rim_spring(gear.k1_Nm_per_rad, k_fe, k1_rule["rest"])
    doc = {"gear": gear.name, "load_inertia_kgm2": LOAD, "rim_spring_Nm_per_rad": spring, "rim_spring_source": src,
           "default_level": fe.DEFAULT_LEVEL, "harmonics": fe.DEFAULT_HARMONICS}
    print("closed forms ...", flush=True)
    doc["closed_forms"] = fs.closed_forms()
    print("convergence ...", flush=True)
    doc["convergence"] = fs.convergence(s, LOAD)
    print("sensitivity ...", flush=True)
    doc["sensitivity"] = fs.sensitivity(s, LOAD, spring)
    doc["sweeps"] = {n: fs.sweep(s, LOAD, spring, n, [0.7, 0.85, 1.0, 1.15, 1.3], level=1)
                     for n in ("wall", "diaphragm", "boss", "length", "diameter")}
    print("FE vs analytic per size ...", flush=True)
    doc["fe_vs_analytic"] = [{"size": z, "ratio": RATIO, "fe": fg.flexspline_stiffness(st.structure_for(z, RATIO)),
                              "analytic": st.flexspline_stiffness(st.structure_for(z, RATIO))}
                             for z in (14, 17, 20, 25, 32, 40, 50)]
    print("held-out sizes ...", flush=True)
    doc["held_out"] = fs.held_out()
    doc["rule"] = rule.__dict__
    doc["plots"] = fs.plot(doc, OUT)
    (OUT / "flexspline_fe.json").write_text(json.dumps(doc, indent=1))
    for c in doc["closed_forms"]:
        print(f"level {c['level']}: torsion {100 * c['torsion_err']:+.3f} %, bending {100 * c['bending_err']:+.3f} %, "
              f"ring {100 * c['ring_err']:+.3f} %")
    for c in doc["convergence"]:
        print(f"level {c['level']} ({c['dofs']} unknowns): K {c['stiffness_Nm_per_rad']:.5g} N·m/rad, torsional "
              f"{c['torsional_clamped_Hz']:.3f} Hz, tilting {c['tilting_Hz']:.3f} Hz, {c['seconds']:.2f} s")
    for n, v in doc["sensitivity"].items():
        print(f"S[{n}]: K {v['stiffness_Nm_per_rad']:+.3f}, torsional {v['torsional_Hz']:+.3f}, "
              f"tilting {v['tilting_Hz']:+.3f}")
    for lv, v in doc["held_out"]["summary"].items():
        print(f"held-out {lv}: max |err| {100 * v['max_abs']:.1f} %, RMS {100 * v['rms']:.1f} %, per size "
              + ", ".join(f"{k}: {100 * e:.0f} %" for k, e in v["per_size_max_abs"].items()))
    print(f"wrote {OUT / 'flexspline_fe.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
