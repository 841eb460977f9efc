#!/usr/bin/env python3
"""Confusion table of the model-discrepancy workflow on simulator logs -> build/results/discrepancy.json.

For every effect name (and "none"), both axis files, closed and open loop, seeds 1..5
(``HDSERVO_DISC_SEEDS`` overrides the count, ``HDSERVO_DISC_SEED_OFFSET`` shifts them
for an unseen set, written to ``discrepancy_seeds<a>-<b>.json``; seed parity selects the parameter size, the
seed sets the experiment and the noise): 20 logs per row.  Each log is simulated with
exactly that effect hidden (hdservo.discrepancy.cases) -- cached under
build/cache/discrepancy/ keyed by the case and a hash of cases.py and the simulator --
the workflow is run, and what it named first and the RMS figures before/after (first and
last model of the loop) are recorded: the equation error over all equations, over the
equations the named effect acts in, and the simulation error.  Also runs EMPS (if the
data are present).  Prints a summary; never fails on the numbers (they are reported in
docs/discrepancy.md).
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

# one BLAS thread per worker process: the fits are small, and several threads per
# process on a shared two-core machine make them ~6x slower
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "host"))
sys.path.insert(0, str(REPO / "tests" / "python"))

from hdservo import emps, logio  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402
from hdservo.cli import UserError  # noqa: E402
from hdservo.discrepancy import EFFECT_NAMES, realdata, signals, simerr, workflow  # noqa: E402
from oracles import discrepancy_cases as cases  # noqa: E402

#: Seeds 1..HDSERVO_DISC_SEEDS, shifted by HDSERVO_DISC_SEED_OFFSET (an unseen seed set:
#: offset 5 -> seeds 6..10, written to discrepancy_seeds6-10.json instead).
SEED_OFFSET = int(os.environ.get("HDSERVO_DISC_SEED_OFFSET", "0"))
SEEDS = tuple(range(1 + SEED_OFFSET, int(os.environ.get("HDSERVO_DISC_SEEDS", "5")) + 1 + SEED_OFFSET))
#: HDSERVO_DISC_ROWS: comma-separated hidden-effect names ("none" for the null row) to run
#: only those rows (written to ..._rows.json so the full table is not overwritten).
ROWS = tuple(r for r in os.environ.get("HDSERVO_DISC_ROWS", "").split(",") if r)
#: Held-out validation axes (tests/results/axes/): never used to choose a constant of the
#: workflow, run only when asked for with HDSERVO_DISC_AXES (comma-separated axis names;
#: default the two axis files of the simulator), written to ..._axes-<names>.json.
HELD_OUT = {p.stem: str(p) for p in sorted((REPO / "tests" / "results" / "axes").glob("*.toml"))}
DEFAULT_AXES = ("reference", "csf17_50")
AXES = tuple(a for a in os.environ.get("HDSERVO_DISC_AXES", ",".join(DEFAULT_AXES)).split(",") if a)
#: HDSERVO_DISC_SUBSAMPLE=k: analyse every k-th sample of each log (log rate 10 kHz / k, as a
#: logger at that rate would record it; the logs are simulated at 10 kHz as always).
SUBSAMPLE = int(os.environ.get("HDSERVO_DISC_SUBSAMPLE", "1"))
OUT_NAME = ("discrepancy" + ("" if SEED_OFFSET == 0 else f"_seeds{SEEDS[0]}-{SEEDS[-1]}")
            + ("_rows" if ROWS else "") + ("" if AXES == DEFAULT_AXES else "_axes-" + "-".join(AXES))
            + ("" if SUBSAMPLE == 1 else f"_sub{SUBSAMPLE}") + ".json")
CACHE = REPO / "build" / "cache" / "discrepancy"


def _source_hash() -> str:
    """Hash of what a synthetic log depends on (case generator, simulator, axis files)."""
    h = hashlib.sha256()
    files = [REPO / "host" / "hdservo" / "discrepancy" / "cases.py", *sorted((REPO / "host" / "hdservo").glob("sim*.py")),
             *sorted((REPO / "sim").rglob("*.toml")), *(Path(HELD_OUT[a]) for a in AXES if a in HELD_OUT),
             *sorted((REPO / "sim").rglob("*.py")), *sorted((REPO / "sim").rglob("*.c"))]
    for f in files:
        if f.is_file():
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def _log_for(c: "cases.Case", tag: str) -> Path:
    """The case's log from the cache, simulated (and cached atomically) if absent."""
    d = CACHE / tag
    p = d / f"{c.label}.csv"
    if p.is_file() and p.with_suffix(".json").is_file():
        return p
    d.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=d) as td:
        q = cases.make_log(c, Path(td) / p.name)
        shutil.move(str(q.with_suffix(".json")), p.with_suffix(".json"))
        shutil.move(str(q), p)
    return p


def _nan_none(x: float) -> float | None:
    return x if x == x else None


def _rms_eqs(fit, eqs: list[str]) -> float:
    import numpy as np
    return float(np.sqrt(np.mean(np.concatenate([fit.resid[e] for e in eqs]) ** 2)))
#: Worker processes (the machine has two cores).
WORKERS = 2


def _one(args: tuple[str, str, str, int, str]) -> dict:
    """Simulate (or take from the cache) and analyse one case (runs in a worker process)."""
    eff, axis, loop, seed, tag = args
    c = cases.Case(None if eff == "none" else eff, axis=axis, loop=loop, seed=seed, size=seed % 2)
    t0 = time.monotonic()
    p = _log_for(c, tag)
    nan = float("nan")
    try:
        log = logio.read_log(p)
        if SUBSAMPLE > 1:
            log = logio.Log(columns={k: v[::SUBSAMPLE] for k, v in log.columns.items()},
                            meta={**log.meta, "sample_period_s": log.meta["sample_period_s"] * SUBSAMPLE}, path=p)
        sig = signals.from_log(log, c.structure)
        r = workflow.run(sig)
        got = r.named[0] if r.named else "none"
        all_named = r.named
        rb, ra = r.rms_history[0], r.rms_history[-1]
        sb, sa = r.sim_rms_history[0], r.sim_rms_history[-1]
        act = r.iterations[0]["acting_equations"] if r.iterations else list(r.base_fit.resid)
        ab, aa = _rms_eqs(r.base_fit, act), _rms_eqs(r.state.fit, act)
        first = r.ranking_first[:3]
        eqs = [e for e in act if e in r.floor] or list(r.floor)
        fl = (sum(r.floor[e] ** 2 for e in eqs) / len(eqs)) ** 0.5
        gb, ga = workflow.systematic_gap(ab, fl), workflow.systematic_gap(aa, fl)
        # over the region where the first named effect acts (its own signature band,
        # whole record for effects that act everywhere): first model -> last model
        lb = la = lsb = lsa = nan
        reg = None
        gap1: dict = {}
        sfl = {k: _nan_none(v) for k, v in r.sim_floor.items()}
        if r.iterations:
            it0 = r.iterations[0]
            top = r.state.added[0]
            bands = top[0].region_bands(r.state.design, top[1])
            rows = workflow._eq_region_rows(r.state.design, top[1], bands)
            rs = simerr.region_mask(r.state.design, bands)
            lb = workflow._region_rms(r.state.design, r.base_fit, top[1], rows)
            la = workflow._region_rms(r.state.design, r.state.fit, top[1], rows)
            lsb, lsa = workflow._masked_rms(r.sims[0], rs), workflow._masked_rms(r.sims[-1], rs)
            reg = it0["region"]
            # the RMS gap of the first named effect (workflow.rms_gap: systematic gap over
            # its region, in the residual where it stands highest above the noise floor)
            gap1 = it0["rms_gap"]
        strib = next((x for x in r.ranking_first if x["effect"] == "stribeck_friction"), None)
    except UserError as e:
        got, all_named, rb, ra, sb, sa, ab, aa, act, first = f"error: {e}", [], nan, nan, nan, nan, nan, nan, [], []
        fl = gb = ga = lb = la = lsb = lsa = nan
        reg = strib = None
        gap1, sfl = {}, None
    keys = ("effect", "score", "delta_bic", "explained_fraction", "sim_delta_bic", "sim_explained_fraction",
            "explained_fraction_local", "sim_explained_fraction_local", "region_share", "sim_region_share",
            "significant")
    return {"case": c.label, "hidden": eff, "named": got, "all_named": all_named,
            "rms_before_Nm": rb, "rms_after_Nm": ra, "shrink": rb / ra if ra and ra == ra else None,
            "acting_equations": act, "rms_acting_before_Nm": ab, "rms_acting_after_Nm": aa,
            "shrink_acting": ab / aa if aa and aa == aa else None,
            "noise_floor_acting_Nm": fl, "gap_acting_before_Nm": gb, "gap_acting_after_Nm": ga,
            # systematic gap (residual minus its sensor-noise floor, in quadrature): the
            # shrink is None when the final model's residual is at or below the floor
            "shrink_gap": gb / ga if ga and ga == ga else None, "gap_closed": bool(ga == 0.0 and gb > 0.0),
            "sim_rms_before_rad": sb, "sim_rms_after_rad": sa, "shrink_sim": sb / sa if sa and sa == sa else None,
            "region": reg, "rms_region_before_Nm": lb, "rms_region_after_Nm": la,
            "shrink_region": lb / la if la and la == la else None,
            "sim_rms_region_before_rad": lsb, "sim_rms_region_after_rad": lsa,
            "shrink_region_sim": lsb / lsa if lsa and lsa == lsa else None,
            "rms_gap": gap1, "shrink_rms_gap": gap1.get("shrink"), "rms_gap_closed": bool(gap1.get("closed")),
            "shrink_rms_gap_raw": gap1.get("raw_shrink"), "sim_floor_rad": sfl,
            "first_ranking": [{k: workflow._jsonable(x.get(k)) for k in keys} for x in first],
            # the Stribeck candidate against the baseline, wherever it ranks (false-alarm check
            # of the localised size rule on logs without Stribeck friction)
            "stribeck_first": {k: workflow._jsonable(strib.get(k)) for k in keys} if strib else None,
            "wall_s": time.monotonic() - t0}


def main() -> int:
    out_dir = REPO / "build" / "results"
    out_dir.mkdir(parents=True, exist_ok=True)
    names = ["none", *EFFECT_NAMES]
    bad = [r for r in ROWS if r not in names]
    if bad:
        print(f"HDSERVO_DISC_ROWS: unknown row {bad[0]!r}; expected names from {', '.join(names)}", file=sys.stderr)
        return 2
    if ROWS:
        names = [n for n in names if n in ROWS]
    if SUBSAMPLE < 1:
        print(f"HDSERVO_DISC_SUBSAMPLE={SUBSAMPLE}: expected an integer >= 1", file=sys.stderr)
        return 2
    known = [*cases.AXES, *HELD_OUT]
    bad = [a for a in AXES if a not in known]
    if bad:
        print(f"HDSERVO_DISC_AXES: unknown axis {bad[0]!r}; expected names from {', '.join(known)}", file=sys.stderr)
        return 2
    for a in AXES:  # the worker processes are forked after this, so they see the held-out axes too
        cases.AXES.setdefault(a, HELD_OUT.get(a, ""))
    confusion: dict[str, dict[str, int]] = {a: {} for a in names}
    t0 = time.monotonic()
    tag = _source_hash()
    jobs = [(eff, axis, loop, seed, tag) for eff in names for axis in AXES
            for loop in ("closed", "open") for seed in SEEDS]
    rows = []
    with ProcessPoolExecutor(max_workers=WORKERS) as ex:
        for row in ex.map(_one, jobs):
            rows.append(row)
            confusion[row["hidden"]][row["named"]] = confusion[row["hidden"]].get(row["named"], 0) + 1
            print(f"{row['case']:48s} -> {row['named']:22s} {row['rms_before_Nm']:.3g} -> {row['rms_after_Nm']:.3g}",
                  flush=True)
    summary = {}
    for eff in names:
        tot = sum(confusion[eff].values())
        ok = confusion[eff].get(eff, 0)
        summary[eff] = {"cases": tot, "correct": ok, "rate": ok / tot if tot else None}
        for k in ("shrink", "shrink_acting", "shrink_sim", "shrink_gap", "shrink_region", "shrink_region_sim",
                  "shrink_rms_gap", "shrink_rms_gap_raw"):
            good = [r for r in rows if r["hidden"] == eff and r["named"] == eff]
            closed = {"shrink_gap": "gap_closed", "shrink_rms_gap": "rms_gap_closed"}.get(k)
            # a closed gap (final residual at the noise floor) counts as an infinite shrink
            sh = sorted(float("inf") if closed and r[closed] else r[k] for r in good
                        if r[k] or (closed and r[closed]))
            summary[eff][f"min_{k}_when_named"] = (sh[0] if sh[0] != float("inf") else "closed") if sh else None
            med = sh[len(sh) // 2] if sh else None
            summary[eff][f"median_{k}_when_named"] = (float(med) if med != float("inf") else "closed") if sh else None
            summary[eff][f"cases_{k}_ge_3"] = sum(1 for x in sh if x >= 3.0)
        summary[eff]["cases_gap_closed"] = sum(1 for r in rows if r["hidden"] == eff and r["named"] == eff
                                               and r["gap_closed"])
        summary[eff]["rms_gap_residual"] = {v: sum(1 for r in rows if r["hidden"] == eff and r["named"] == eff
                                                   and r["rms_gap"].get("residual") == v)
                                            for v in ("equation", "simulation")}
    result = {"confusion": confusion, "summary": summary, "cases": rows, "wall_s": time.monotonic() - t0,
              "rms_unit": workflow.SIGNAL_TEXT}
    try:
        d = emps.resolve_data_dir()
        rec = emps.load_benchmark_record(d, emps.TRAIN_RECORD)
        with tempfile.TemporaryDirectory() as td:
            p = Path(td) / "emps.csv"
            emps.write_log(rec, p)
            r = workflow.run(signals.from_log(logio.read_log(p)))
        named = r.named[0] if r.named else None
        chk = realdata.idim_relative_error(rec, named, r.iterations[0]["params"] if r.iterations else {})
        result["emps"] = {"named_effects": r.named, "idim": chk, "baseline": r.baseline}
        print(f"EMPS: named {r.named}, IDIM relative error {chk['relative_error_pct']:.3f} %")
    except UserError as e:
        result["emps"] = {"skipped": str(e)}
    write_json_atomic(out_dir / OUT_NAME, result)
    for eff, s in summary.items():
        print(f"{eff:24s} {s['correct']}/{s['cases']} named correctly; min shrink all/acting/sim/gap "
              f"{s['min_shrink_when_named']} / {s['min_shrink_acting_when_named']} / {s['min_shrink_sim_when_named']}"
              f" / {s['min_shrink_gap_when_named']}; RMS gap shrink >= 3x in {s['cases_shrink_rms_gap_ge_3']}/{s['correct']}"
              f" (raw {s['cases_shrink_rms_gap_raw_ge_3']}/{s['correct']})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
