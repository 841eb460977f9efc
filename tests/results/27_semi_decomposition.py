#!/usr/bin/env python3
"""What the semi-closed positioning error is made of: the output deviation at every stop split by the rig.

For one axis (``--axis FILE``, the reference axis by default, or ``--seed S``: the first axis
:func:`hdservo.axisgen.random_axes` draws with that seed, as ``27_unseen_axes.py`` does) the fair
PID and the friction feed-forward with each twist prediction run the semi-closed positioning
procedure (``--quick``: 3 runs at -50, -20, 10, 40 deg), with the axis' true model downloaded
(``27_twist_source_edge.true_model``, the sections ``hdservo identify`` writes) or the model of
``--model``.  Each stop's output deviation is split into the motor angle / N's deviation (where the
loop put the motor: the predicted offset plus the loop error), the transmission error and minus the
gear's twist (:func:`hdservo.procedures.metrics.stop_error_parts`); per part the spread over the
targets, the difference between the approach directions, the run-to-run scatter and the first
run's offset.

Writes ``build/results/semi_decomposition.json``.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

from hdservo import axisgen  # noqa: E402
from hdservo import compare as cmp  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402

#: Rows (semi-closed): the fair PID, then the friction feed-forward with TE and each twist prediction.
DEFAULT_ROWS: tuple[str, ...] = ("pid", "stribeck+te", "stribeck+te+preisach", "stribeck+te+compliance")


def _edge_script() -> Any:
    spec = importlib.util.spec_from_file_location("twist_source_edge", ROOT / "tests" / "results" / "27_twist_source_edge.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def row_parts(compare_dir: Path, doc: Mapping[str, Any]) -> dict[str, Any]:
    """Per row of a comparison: its positioning headline and the split of its stops' deviations.

    Parameters
    ----------
    compare_dir : Path
        The comparison's output directory (``compare.json``'s ``json`` paths are relative to it).
    doc : mapping
        The comparison document.

    Returns
    -------
    dict
        Row name -> ``{"A_arcsec", "parts"}``; ``parts`` is the positioning result's
        ``stop_error_parts_arcsec`` (None when the procedure failed or ran without the virtual rig).
    """
    out: dict[str, Any] = {}
    for name, c in doc["controllers"].items():
        parts = None
        p = compare_dir / c["json"]
        if p.is_file():
            res = json.loads(p.read_text()).get("results", {}).get("positioning", {})
            parts = res.get("figures", {}).get("stop_error_parts_arcsec")
        out[name] = {"A_arcsec": c.get("headline", {}).get("positioning_accuracy_arcsec"), "parts": parts}
    return out


def table(rows: Mapping[str, Any]) -> str:
    """Plain-text table of :func:`row_parts`: per row A, then per part systematic / direction / scatter / first run."""
    keys = ("output", "motor_dev_arcsec", "te_arcsec", "minus_twist_arcsec")
    lines = ["row: A | " + " | ".join(f"{k}: E/B/s/first" for k in keys)]
    for name, r in rows.items():
        p = r["parts"]
        if p is None:
            lines.append(f"{name}: no stops recorded")
            continue
        cells = []
        for k in keys:
            s = p["output"] if k == "output" else p["parts"][k]
            cells.append("/".join(f"{s[q]:.2f}" for q in ("systematic", "direction", "scatter", "first_run")))
        a = r["A_arcsec"]
        lines.append(f"{name}: {'-' if a is None else f'{a:.2f}'} | " + " | ".join(cells)
                     + f" | gear torque {p['gear_torque_Nm']['mean']:.2f} N.m")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--axis", default="reference", help="axis TOML file or 'reference' (default)")
    ap.add_argument("--seed", type=int, default=None, help="instead of --axis: the first axis axisgen draws with this seed")
    ap.add_argument("--model", type=Path, default=None, help="identified model to download (default: the axis' true model)")
    ap.add_argument("--rows", default=",".join(DEFAULT_ROWS), help="comma-separated rows (hdservo compare names)")
    ap.add_argument("--noise-seed", type=int, default=1, help="sensor-noise seed (default 1)")
    ap.add_argument("--exercise", type=int, default=None,
                    help="positioning exercise passes before the first run (default: the procedure's)")
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "build" / "results")
    a = ap.parse_args(argv)
    work = a.out / "semi_decomposition"
    if a.seed is not None:
        axis = axisgen.write_axes(work / "axes", 1, a.seed)[0]
    else:
        axis = Path(a.axis) if a.axis != "reference" else ROOT / "sim" / "axes" / "reference.toml"
    work.mkdir(parents=True, exist_ok=True)
    model = a.model if a.model is not None else _edge_script().true_model(axis, work)
    rows = [cmp.fair_row([] if n == "pid" else n.split("+"), "semi-closed", "baseline" if n == "pid" else "custom",
                         name=n, axis=str(axis)) for n in a.rows.split(",") if n]
    t0 = time.monotonic()
    extra = [*cmp.QUICK_ARGS, *([] if a.exercise is None else ["--exercise", str(a.exercise)])]
    doc = cmp.run_compare(work / "compare", rows, ["positioning"], proc_extra=extra, axis=str(axis),
                          seed=a.noise_seed, model=model, progress=False, jobs=1)
    res = row_parts(work / "compare", doc)
    out = {"axis": str(axis.relative_to(ROOT) if axis.is_relative_to(ROOT) else axis.name), "axis_seed": a.seed,
           "model": "true" if a.model is None else a.model.name, "noise_seed": a.noise_seed,
           "exercise": a.exercise, "run_time_s": time.monotonic() - t0, "rows": res}
    write_json_atomic(a.out / "semi_decomposition.json", out)
    print(table(res))
    print(f"wrote {a.out / 'semi_decomposition.json'} ({out['run_time_s']:.0f} s)")
    return 0 if all(r["parts"] is not None for r in res.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
