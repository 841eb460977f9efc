#!/usr/bin/env python3
"""Where the motor-side twist torque estimate pays: semi-closed positioning with each source.

For each axis (``--seeds`` of :func:`hdservo.axisgen.random_axes`, axis 0, plus ``--axes`` files) and
each velocity-loop crossover of ``--bandwidths`` (the design rule's PI at that crossover,
:func:`hdservo.closedloop_cases.velocity_pi`), ``hdservo compare``'s code runs the positioning
procedure (``--quick``, semi-closed, sensor-noise seed ``--seed``) with the fair PID and with
Stribeck + TE + Preisach twice, the twist torque from the model (``pr_t_src`` 1) and from the motor
side (``pr_t_src`` 2), the axis' true model downloaded with the Preisach table built from the
axis file's spring and hysteresis sections (:func:`hdservo.compsetup.preisach_table`, the plant's
twist -> torque operator; docs/compensators.md section 13).
:func:`band_summary` gives, below and above the rule's edge (``compsetup.RESONANCE_LOOP_RATIO``
x the crossover), the range of A(model) / A(motor side): the rule is right when the motor side
never loses much below the edge and never gains much above it.

Writes ``build/results/twist_source_edge.json``.
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

from hdservo import axisgen, compsetup  # noqa: E402
from hdservo import closedloop_cases as cl  # noqa: E402
from hdservo import compare as cmp  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402
from hdservo.ident.model_toml import write_toml  # noqa: E402

DEFAULT_SEEDS = (7, 35, 42, 43, 46, 55, 103)
DEFAULT_BANDWIDTHS = (25.0,)


def true_model(axis_path: Path, directory: Path) -> Path:
    """The axis' true model as ``hdservo identify`` writes it, with its Preisach table; returns the model path."""
    from test_download_any_axis import _true_model      # every section identification writes
    a = tomllib.loads(axis_path.read_text())
    compsetup.write_preisach_table(str(axis_path), directory / "preisach.bin")
    tm = _true_model(a)
    tm["identified"] = {"preisach_table": "preisach.bin"}
    mp = directory / "true_model.toml"
    write_toml(mp, tm)
    return mp


def run_axis(axis_path: Path, f_v_hz: float, directory: Path, seed: int = 1) -> dict[str, Any]:
    """A of the fair PID and of Stribeck + TE + Preisach with each twist torque source; returns the row."""
    a = tomllib.loads(axis_path.read_text())
    n, jl, jm, k1 = (float(a["gear"]["ratio"]), float(a["load"]["jl_kgm2"]), float(a["motor"]["jm_kgm2"]),
                     float(a["stiffness"]["k1_Nm_per_rad"]))
    jt = jl + n * n * jm
    vg = cl.velocity_pi(jt, f_v_hz)
    rows = [cmp.fair_row([], "semi-closed", "baseline", name="pid", axis=str(axis_path))]
    for src in (1, 2):
        rows.append(cmp.fair_row(["stribeck", "te", "preisach"], "semi-closed", "custom", name=f"src{src}",
                                 axis=str(axis_path)))
        rows[-1].gains["pr_t_src"] = float(src)
    for r in rows:
        r.gains.update(vg)
    directory.mkdir(parents=True, exist_ok=True)
    doc = cmp.run_compare(directory / "compare", rows, ["positioning"], proc_extra=cmp.QUICK_ARGS,
                          axis=str(axis_path), seed=seed, model=true_model(axis_path, directory),
                          progress=False, jobs=1)
    acc = doc["figures"]["positioning_accuracy_arcsec"]["values"]
    f_v = compsetup.velocity_loop_hz(vg["vel_kp"], jt)
    return {"axis": axis_path.stem, "f_load_hz": compsetup.load_resonance_hz(k1, jl), "f_v_hz": f_v,
            "resonance_over_loop": compsetup.load_resonance_hz(k1, jl) / f_v,
            "a_pid_arcsec": acc.get(cmp.row_name("pid", "semi-closed")),
            "a_model_arcsec": acc.get(cmp.row_name("src1", "semi-closed")),
            "a_motor_arcsec": acc.get(cmp.row_name("src2", "semi-closed"))}


def band_summary(rows: Sequence[Mapping[str, Any]], edge: float) -> dict[str, Optional[list[float]]]:
    """Range [min, max] of A(model) / A(motor side) of the rows below and at or above ``edge`` (None: no row).

    A ratio above 1 means the motor-side estimate positions better.
    """
    out: dict[str, Optional[list[float]]] = {}
    for band, keep in (("below", lambda r: r < edge), ("above", lambda r: r >= edge)):
        g = [float(r["a_model_arcsec"]) / float(r["a_motor_arcsec"]) for r in rows
             if keep(float(r["resonance_over_loop"])) and r.get("a_model_arcsec") and r.get("a_motor_arcsec")]
        out[band] = [min(g), max(g)] if g else None
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=list(DEFAULT_SEEDS), help="axisgen seeds (axis 0)")
    ap.add_argument("--axes", type=Path, nargs="*", default=[ROOT / "sim" / "axes" / "reference.toml",
                                                              ROOT / "sim" / "axes" / "csf17_50.toml"])
    ap.add_argument("--bandwidths", type=float, nargs="+", default=list(DEFAULT_BANDWIDTHS),
                    help="velocity-loop crossovers, Hz")
    ap.add_argument("--seed", type=int, default=1, help="sensor-noise seed")
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "build" / "results")
    a = ap.parse_args(argv)
    t0 = time.monotonic()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        paths = [axisgen.write_axes(Path(d) / f"seed{s}", 1, seed=s)[0] for s in a.seeds] + list(a.axes)
        for i, p in enumerate(paths):
            for f in a.bandwidths:
                row = run_axis(Path(p), f, Path(d) / f"run{i}_{f:g}", a.seed)
                print(f"{row['axis']}: f_load / f_v = {row['resonance_over_loop']:.2f}: A pid {row['a_pid_arcsec']:.2f}\", "
                      f"model {row['a_model_arcsec']:.2f}\", motor side {row['a_motor_arcsec']:.2f}\"", flush=True)
                rows.append(row)
    doc = {"rows": rows, "edge": compsetup.RESONANCE_LOOP_RATIO,
           "model_over_motor": band_summary(rows, compsetup.RESONANCE_LOOP_RATIO),
           "run_time_s": time.monotonic() - t0}
    a.out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(a.out / "twist_source_edge.json", doc)
    print(f"A(model) / A(motor side) below / above {compsetup.RESONANCE_LOOP_RATIO:g} x f_v: {doc['model_over_motor']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
