#!/usr/bin/env python3
"""The demo's targets as medians over sensor-noise seeds 1-3, on the reference axis and csf17_50.

``hdservo demo --seeds 1,2,3 [--axis FILE] -o build/results/demo_seeds/<axis>`` (one comparison
per seed in parallel processes, medians in its summary.json / ablation.json), then collects
each axis' median summary, the improvement factors fair PID / compensated of the issue's
figures and the run time into ``build/results/demo_seeds.json``.  ``make demo`` runs one seed
(docs/demo.md); this is the three-seed run.  ``--quick`` passes ``--quick`` to the demo;
``--collect`` only collects the outputs of an earlier run (no demo is started).

Per axis the JSON also holds the per-compensator rule of the targets on the median ablation
(:func:`compensator_rule`: each compensator improves a headline figure by at least 20 % and
worsens none by more than 10 % in a configuration where it applies, alone against the fair PID
or as a part of the best combination) and the minimum smooth rate of the fair PID and the best
combination in every feedback configuration (:func:`min_rates`).
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo import compare as cmp  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402

AXES = {"reference": "reference", "csf17_50": str(ROOT / "sim" / "axes" / "csf17_50.toml")}
SEEDS = "1,2,3"
#: The compensators whose prediction the output encoder measures: they apply only where the position
#: loop does not close on the output encoder (semi-closed, dual-loop); the friction compensators apply
#: in every feedback configuration (docs/compensators.md, sections 9 and 10).
MOTOR_SIDE = ("maxwell", "preisach", "te", "compliance")


def applies(components: Sequence[str], feedback: str) -> bool:
    """Whether a row's compensators can act in ``feedback`` (motor-side predictors not in full-closed)."""
    return feedback != "full-closed" or not any(c in MOTOR_SIDE for c in components)


def _rows(ablation: Mapping[str, Any]) -> dict[str, Mapping[str, Any]]:
    return {r["name"]: r for r in ablation.get("rows", [])}


def _keys(row: Mapping[str, Any]) -> list[str]:
    return [k for k in row.get("figures", {}) if k in cmp.FIGURE_BY_KEY]


def losses(row: Mapping[str, Any], base: Mapping[str, Any], keys: Sequence[str]) -> list[str]:
    """The judged figures (not :data:`hdservo.compare.RULE_SKIP`) on which ``row`` is more than 10 % worse than ``base``."""
    out = []
    for k in keys:
        if k in cmp.RULE_SKIP or k not in row or k not in base:
            continue
        w = cmp.worse_factor(cmp.FIGURE_BY_KEY[k], row[k], base[k])
        if w is not None and w > 1.0 + cmp.RULE_LOSS:
            out.append(f"{k} (x{w:.3g})")
    return out


def compensator_rule(ablation: Mapping[str, Any]) -> dict[str, Any]:
    """The per-compensator target on a (median) ``ablation.json``.

    Parameters
    ----------
    ablation : mapping
        ``hdservo demo`` ablation document: rows with ``name``, ``feedback``, ``kind``,
        ``components``, ``baseline_row`` and ``figures`` (medians with ``--seeds``).

    Returns
    -------
    dict
        ``{"rows": [...], "compensators": {name: {"met", "where"}}}``.  One entry per row of kind
        ``compensator``: the row judged alone against the fair PID of its configuration
        (:func:`hdservo.compare.qualifies`: a figure at least 20 % better, none more than 10 %
        worse), whether it ``applies`` there, and per part of a best combination of two or more
        parts the leave-one-out judgement on the medians (:func:`hdservo.compare.part_pays`, the
        best combination at least 20 % better on a figure than without the part) with the best
        combination's own losses against the fair PID.  A compensator meets the target when, in a
        configuration where it applies, it qualifies alone or pays as a part of a best
        combination that worsens no figure by more than 10 % against the fair PID.
    """
    rows = _rows(ablation)
    out_rows: list[dict[str, Any]] = []
    verdict: dict[str, dict[str, Any]] = {}

    def note(name: str, ok: bool, where: str) -> None:
        v = verdict.setdefault(name, {"met": False, "where": []})
        v["met"] = v["met"] or ok
        if ok:
            v["where"].append(where)

    for r in ablation.get("rows", []):
        base = rows.get(r.get("baseline_row") or "")
        if base is None:
            continue
        fb = r.get("feedback", "full-closed")
        comps = list(r.get("components", []))
        if r.get("kind") == "compensator":
            ok, why = cmp.qualifies(r["figures"], base["figures"], _keys(base))
            ap = applies(comps, fb)
            out_rows.append({"row": r["name"], "feedback": fb, "components": comps, "applies": ap,
                             "judged": "alone against the fair PID", "meets": ok, "reason": why})
            note("+".join(comps), ok and ap, f"{r['name']} (alone)")
        elif r.get("kind") == "best" and len(comps) >= 2:
            lost = losses(r["figures"], base["figures"], _keys(base))
            for p in comps:
                minus = rows.get(cmp.row_name(f"best-{p}", fb))
                if minus is None:
                    continue
                pays, why = cmp.part_pays(r["figures"], minus["figures"], _keys(base))
                ok = pays and not lost
                ap = applies([p], fb)
                out_rows.append({"row": r["name"], "feedback": fb, "components": [p], "applies": ap,
                                 "judged": f"part of {'+'.join(comps)} (leave-one-out)", "meets": ok,
                                 "reason": why + ("; the best combination worsens " + ", ".join(lost)
                                                  + " against the fair PID" if lost else "")})
                note(p, ok and ap, f"{r['name']} (part of {'+'.join(comps)})")
    return {"rows": out_rows, "compensators": verdict}


def min_rates(ablation: Mapping[str, Any]) -> dict[str, dict[str, Optional[float]]]:
    """Minimum smooth rate, deg/s, of the fair PID and the best combination per feedback configuration.

    None: the row has no smooth rung of the ladder (or the procedure did not run).
    """
    out: dict[str, dict[str, Optional[float]]] = {}
    for r in ablation.get("rows", []):
        if r.get("kind") in ("baseline", "best"):
            role = "pid" if r["kind"] == "baseline" else "compensated"
            out.setdefault(r.get("feedback", "full-closed"), {})[role] = r["figures"].get("min_smooth_rate_deg_s")
    return out


def _unseen() -> Any:
    """The headline/target helpers of 27_unseen_axes.py (one definition)."""
    spec = importlib.util.spec_from_file_location("unseen_axes_results", Path(__file__).with_name("27_unseen_axes.py"))
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def _earlier_run(path: Path, name: str, out: Path) -> tuple[int, Optional[float]]:
    """Exit status and run time of an axis' earlier run (``demo_seeds.json``, else the demo log's last line)."""
    if path.is_file():
        old = json.loads(path.read_text()).get("axes", {}).get(name)
        if old is not None:
            return int(old.get("demo_exit", 0)), old.get("run_time_s")
    done = [ln for ln in (out / "demo.log").read_text().splitlines() if ln.startswith("demo: done in ")] \
        if (out / "demo.log").is_file() else []
    return (0, float(done[-1].split()[3])) if done else (1, None)


def main(argv: Optional[list[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", default=SEEDS)
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "build" / "results")
    ap.add_argument("--collect", action="store_true", help="collect the outputs of an earlier run, run no demo")
    a = ap.parse_args(argv)
    u = _unseen()
    doc: dict[str, Any] = {"seeds": a.seeds, "quick": a.quick, "axes": {}}
    rc_all = 0
    for name, axis in AXES.items():
        out = a.out / "demo_seeds" / name
        out.mkdir(parents=True, exist_ok=True)
        cmd = [str(ROOT / ".venv" / "bin" / "python"), "-m", "hdservo.cli", "demo", "--axis", axis,
               "--seeds", a.seeds, "--out-dir", str(out)] + (["--quick"] if a.quick else [])
        if a.collect:
            rc, el = _earlier_run(a.out / "demo_seeds.json", name, out)
        else:
            print(f"{name}: hdservo demo --seeds {a.seeds}", flush=True)
            t0 = time.monotonic()
            with open(out / "demo.log", "w") as log:
                rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
                                     env={**os.environ, "PYTHONPATH": str(ROOT / "host")})
            el = time.monotonic() - t0
        rc_all |= rc
        r: dict[str, Any] = {"demo_exit": rc, "run_time_s": el, "log": os.path.relpath(out / "demo.log", ROOT)}
        if (out / "summary.json").is_file():
            summ = json.loads((out / "summary.json").read_text())
            r["summary"] = summ
            r["headline"] = u.headline(summ)
            r["targets"] = u.targets(r["headline"], factor=1.0)
        if (out / "ablation.json").is_file():
            abl = json.loads((out / "ablation.json").read_text())
            r["best"] = abl.get("best")
            r["compensator_rule"] = compensator_rule(abl)
            r["min_smooth_rate_deg_s"] = min_rates(abl)
        doc["axes"][name] = r
        print(f"{name}: exit {rc}, " + ("run time unknown" if el is None else f"{el:.0f} s"), flush=True)
    write_json_atomic(a.out / "demo_seeds.json", doc)
    print(f"wrote {a.out / 'demo_seeds.json'}")
    return 1 if rc_all else 0


if __name__ == "__main__":
    sys.exit(main())
