"""Calibration of the discrepancy workflow's decision rules -> build/results/discrepancy_calibration.json.

Runs the workflow (with the simulator's stop rule, as 47_discrepancy_heldout.py does) on the
corpus' CALIBRATION seeds (1-1000; never the held-apart ones) and reports:

* per hidden effect (single hidden effects the log's signals can show): named first,
  missed (nothing named), wrong (another effect named first);
* false alarms on clean logs and spurious names, per signal set;
* per candidate effect, its first-ranking evidence (size: the largest explained fraction,
  total Delta BIC) when it is hidden and when it is not, as quantiles;
* the size threshold each signal set needs by the documented rule (:func:`choose_frac_min`):
  on the clean logs, the 95 % quantile of the largest size among the significant
  candidates (a false-alarm quantile), never below the workflow's default.

Environment: ``HDSERVO_CALIB_N`` (logs, default 120), ``HDSERVO_CALIB_JOBS`` (worker
processes, default 2), ``HDSERVO_CALIB_FROM`` (a previous JSON of this script: recompute
the report from its cases without running anything; several JSONs separated by ``:`` are
merged by seed), ``HDSERVO_CALIB_CLEAN`` (signal sets, default ``motor,output``, empty for none: also every
clean calibration seed of those sets, a census of the logs the threshold rule needs where
the first seeds hold few; they enter the rule's inputs, not the report's figures),
``HDSERVO_CALIB_TWO`` (default 0: how many calibration seeds with two hidden effects the log's
signals can show to add, in seed order beyond the first seeds: a census of the two-effect logs,
which enter :func:`two_effects` and not the report's other figures),
``HDSERVO_CALIB_SETS`` (signal sets: of the first seeds, only the logs of these sets; a run
after a change that acts on those sets only, merged before the previous run with
``HDSERVO_CALIB_FROM``), ``HDSERVO_CALIB_OUT`` (the JSON written), ``HDSERVO_CALIB_PACKAGE=1`` (also
write the rule's inputs to the package data, host/hdservo/data/discrepancy_thresholds.json,
from which the workflow computes its thresholds).  Heavy: run under ``nice``.
"""
from __future__ import annotations

import importlib.util
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, Iterable, Sequence

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "host"))
sys.path.insert(0, str(REPO / "tests" / "python"))

from hdservo.fileio import write_json_atomic  # noqa: E402

N_LOGS = int(os.environ.get("HDSERVO_CALIB_N", "120"))
JOBS = int(os.environ.get("HDSERVO_CALIB_JOBS", "2"))
#: The false-alarm quantile of the threshold rule (the held-apart target is <= 5 % false alarms).
FALSE_ALARM_QUANTILE = 0.95


def _heldout() -> Any:
    spec = importlib.util.spec_from_file_location("heldout47", Path(__file__).with_name("47_discrepancy_heldout.py"))
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def analyse(seed: int) -> dict[str, Any]:
    """One calibration log through the workflow and the simulator loop (47's :func:`analyse`),
    with the default size threshold for every signal set: the rule's inputs (which
    candidates are significant) must not depend on the thresholds they set."""
    from hdservo.discrepancy import workflow
    workflow.FRAC_MIN_BY_SIGNALS.clear()       # this worker process only
    return _heldout().analyse(seed)


def confusion(records: Iterable[dict[str, Any]]) -> dict[str, dict[str, int]]:
    """Per hidden effect, over the single hidden effects the signals can show: ``named_first``,
    ``missed`` (nothing named), ``wrong`` (another effect named first) and ``n``."""
    out: dict[str, dict[str, int]] = {}
    for r in records:
        if r.get("error") or len(r["hidden"]) != 1 or not r["identifiable"]:
            continue
        e = r["hidden"][0]
        c = out.setdefault(e, {"named_first": 0, "missed": 0, "wrong": 0, "n": 0})
        c["n"] += 1
        if not r["named"]:
            c["missed"] += 1
        elif r["named"][0] == e:
            c["named_first"] += 1
        else:
            c["wrong"] += 1
    return dict(sorted(out.items()))


def _q(x: Sequence[float], qs: Sequence[float] = (0.05, 0.5, 0.95)) -> list[float] | None:
    import numpy as np
    v = [float(a) for a in x if a is not None and math.isfinite(float(a))]
    return [float(np.quantile(v, q)) for q in qs] if v else None


def evidence_stats(records: Iterable[dict[str, Any]]) -> dict[str, Any]:
    """Per candidate effect: quantiles (5/50/95 %) of its first-ranking size and total Delta
    BIC on logs where it is hidden and where it is not, and how often it is significant."""
    acc: dict[str, dict[str, list[float]]] = {}
    for r in records:
        if r.get("error"):
            continue
        for c in r.get("ranking_first", []):
            a = acc.setdefault(c["effect"], {"size_hidden": [], "size_not": [], "bic_hidden": [], "bic_not": [],
                                             "sig_hidden": [], "sig_not": []})
            k = "hidden" if c["effect"] in r["hidden"] else "not"
            a[f"size_{k}"].append(c.get("size", float("nan")))
            a[f"bic_{k}"].append(c.get("total_delta_bic") if c.get("total_delta_bic") is not None else float("nan"))
            a[f"sig_{k}"].append(1.0 if c.get("significant") else 0.0)
    out = {}
    for e, a in sorted(acc.items()):
        out[e] = {"n_hidden": len(a["size_hidden"]), "n_not_hidden": len(a["size_not"]),
                  "size_q05_q50_q95_hidden": _q(a["size_hidden"]), "size_q05_q50_q95_not_hidden": _q(a["size_not"]),
                  "total_dbic_q05_q50_q95_hidden": _q(a["bic_hidden"]),
                  "total_dbic_q05_q50_q95_not_hidden": _q(a["bic_not"]),
                  "significant_hidden": int(sum(a["sig_hidden"])), "significant_not_hidden": int(sum(a["sig_not"]))}
    return out


#: A threshold sits this far above the size it must silence (the rule is size >= threshold).
MARGIN = 0.01
#: Fewest clean logs of a signal set the quantile is taken on: 1/(1 - q) = 20 (below it
#: the 95 % quantile is the largest value, one log's outlier); fewer keep the default.
MIN_CLEAN_LOGS = round(1.0 / (1.0 - FALSE_ALARM_QUANTILE))


def largest_sizes(records: Iterable[dict[str, Any]]) -> dict[str, list[float]]:
    """Per signal set, per clean log (nothing hidden): the largest size among its first
    ranking's significant candidates, 0 when there is none (the rule's inputs)."""
    per: dict[str, list[float]] = {}
    for r in records:
        if r.get("error") or r["hidden"]:
            continue
        xs = [float(c["size"]) for c in r.get("ranking_first", [])
              if c.get("significant") and c.get("size") is not None and math.isfinite(float(c["size"]))]
        per.setdefault(r["angles"], []).append(max(xs) if xs else 0.0)
    return per


def choose_frac_min(records: Iterable[dict[str, Any]], default: float,
                    q: float = FALSE_ALARM_QUANTILE, min_logs: int = MIN_CLEAN_LOGS) -> dict[str, float]:
    """Size threshold per signal set by the false-alarm rule on the clean calibration logs.

    For every clean log (nothing hidden), the largest size among its first ranking's
    significant candidates (0 when there is none): a threshold above it keeps that log
    silent.  The threshold of a signal set is the ``q`` quantile of those values over its
    clean logs plus :data:`MARGIN`, never below ``default``; a set with fewer than
    ``min_logs`` clean logs keeps ``default`` (:func:`hdservo.discrepancy.thresholds.rule`).
    """
    from hdservo.discrepancy import thresholds
    per = largest_sizes(records)
    return {a: thresholds.rule(per.get(a, []), default, q, MARGIN, min_logs) for a in thresholds.SETS}


def threshold_inputs(records: list[dict[str, Any]], default: float, wall_s: float | None = None) -> dict[str, Any]:
    """The rule's inputs as package data (hdservo/data/discrepancy_thresholds.json), with
    their provenance: the calibration seeds analysed, the clean ones per signal set."""
    seeds = sorted(int(r["seed"]) for r in records if "seed" in r and not r.get("census"))
    census = sorted(int(r["seed"]) for r in records if r.get("census"))
    clean = {}
    for r in records:
        if not r.get("error") and not r["hidden"]:
            clean.setdefault(r["angles"], []).append(int(r["seed"]))
    return {"rule": "frac_min[set] = max(default, quantile(largest_sizes[set], q) + margin); a set with fewer "
                    "than min_logs clean logs keeps the default (hdservo.discrepancy.thresholds)",
            "largest_sizes_are": "per clean calibration log: the largest size (explained fraction) among its "
                                 "first ranking's significant candidates, 0 when none is significant",
            "source": "tests/results/48_discrepancy_calibration.py on the corpus' calibration seeds "
                      "(tests/python/oracles/discrepancy_corpus.py)",
            "set": "calibration", "seeds_analysed": [seeds[0], seeds[-1]] if seeds else [],
            "n_logs": len(seeds),
            "census_seeds": census, "census_is": "every clean calibration seed (1-1000) of the one-encoder signal "
                                                 "sets beyond the first seeds, by the corpus' own draw",
            "wall_s": wall_s,
            "errors": sorted(int(r["seed"]) for r in records if r.get("error")),
            "default": default, "quantile": FALSE_ALARM_QUANTILE, "margin": MARGIN, "min_logs": MIN_CLEAN_LOGS,
            "clean_seeds": {a: sorted(v) for a, v in sorted(clean.items())},
            "largest_sizes": {a: v for a, v in sorted(largest_sizes(records).items())}}


def first_names_under(records: Iterable[dict[str, Any]], frac_min: dict[str, float]) -> dict[str, Any]:
    """The first names the recorded first rankings give with the size thresholds ``frac_min``
    (per signal set): the best-ranked significant candidate whose size reaches its signal
    set's threshold.  Per hidden effect named first / n, and clean logs with a name."""
    hit: dict[str, list[int]] = {}
    fa = [0, 0]
    for r in records:
        if r.get("error"):
            continue
        th = frac_min.get(r["angles"], 0.0)
        first = next((c["effect"] for c in r.get("ranking_first", [])
                      if c.get("significant") and c.get("size") is not None and float(c["size"]) >= th), None)
        if not r["hidden"]:
            fa[0] += first is not None
            fa[1] += 1
        elif len(r["hidden"]) == 1 and r["identifiable"]:
            h = hit.setdefault(r["hidden"][0], [0, 0])
            h[0] += first == r["hidden"][0]
            h[1] += 1
    return {"named_first": {e: {"k": k, "n": n} for e, (k, n) in sorted(hit.items())},
            "named_first_total": {"k": sum(k for k, _ in hit.values()), "n": sum(n for _, n in hit.values())},
            "false_alarm": {"k": fa[0], "n": fa[1]}}


def report(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The calibration report of analysed records (see the module docstring)."""
    from hdservo.discrepancy.workflow import Settings
    m = _heldout()
    by_set: dict[str, Any] = {}
    for a in ("both", "motor", "output"):
        rs = [r for r in records if r.get("angles") == a]
        if rs:
            by_set[a] = m.score(rs)
    chosen = choose_frac_min(records, Settings().frac_min)
    default = {a: Settings().frac_min for a in chosen}
    return {"summary": m.score(records), "per_signal_set": by_set, "confusion": confusion(records),
            "evidence": evidence_stats(records),
            "frac_min_rule": {"quantile": FALSE_ALARM_QUANTILE, "default": Settings().frac_min, "chosen": chosen,
                              "min_logs": MIN_CLEAN_LOGS,
                              "quantile_without_min_logs": choose_frac_min(records, Settings().frac_min, min_logs=0),
                              "first_names_default": first_names_under(records, default),
                              "first_names_chosen": first_names_under(records, chosen)}}


def census_seeds(sets: Sequence[str], seeds: Iterable[int]) -> list[int]:
    """The clean calibration seeds (nothing hidden) of the signal sets ``sets`` among ``seeds``
    (the corpus' own draw, nothing simulated)."""
    from oracles import discrepancy_corpus as corpus
    out = []
    for s in seeds:
        c = corpus.draw(s)
        if not c.hidden and c.angles in sets:
            out.append(int(s))
    return out


def two_effect_seeds(seeds: Iterable[int], n: int) -> list[int]:
    """The first ``n`` of ``seeds`` whose log hides two effects its signals can both show (the
    corpus' own draw, nothing simulated)."""
    from oracles import discrepancy_corpus as corpus
    out: list[int] = []
    for s in seeds:
        if len(out) >= n:
            break
        c = corpus.draw(s)
        if len(c.hidden) == 2 and len(c.identifiable()) == 2:
            out.append(int(s))
    return out


def two_effects(records: Iterable[dict[str, Any]]) -> dict[str, Any]:
    """Logs with two hidden effects the signals can show (first seeds and census alike):
    ``both_named`` (the simulator keeps both), ``both_by_workflow`` (the workflow names both,
    before the simulator's stop rule), ``lost_by_simulator`` (named by the workflow, dropped
    by the simulator), ``one_missed`` (the workflow names at most one of them) and
    ``spurious`` (a kept name not hidden), with the seeds of each."""
    out: dict[str, list[int]] = {"logs": [], "both_named": [], "both_by_workflow": [], "lost_by_simulator": [],
                                 "one_missed": [], "spurious": []}
    for r in records:
        if r.get("error") or len(r["hidden"]) != 2 or len(r["identifiable"]) != 2:
            continue
        h, kept, wf = set(r["hidden"]), set(r["named"]), set(r.get("named_workflow", r["named"]))
        s = int(r["seed"])
        out["logs"].append(s)
        if h <= kept:
            out["both_named"].append(s)
        if h <= wf:
            out["both_by_workflow"].append(s)
            if not h <= kept:
                out["lost_by_simulator"].append(s)
        else:
            out["one_missed"].append(s)
        if kept - h:
            out["spurious"].append(s)
    m = _heldout()
    n = len(out["logs"])
    return {**{k: sorted(v) for k, v in out.items()},
            **{f"{k}_fraction": m._frac(len(out[k]), n) for k in ("both_named", "both_by_workflow", "spurious")}}


def sample(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """The records of the first ``HDSERVO_CALIB_N`` seeds (the census' extra clean logs out)."""
    return [r for r in records if not r.get("census")]


def merged(paths: Sequence[str]) -> tuple[list[dict[str, Any]], float]:
    """Cases of previous runs (the first run's case of a seed wins) and their total run time, s."""
    recs: dict[int, dict[str, Any]] = {}
    wall = 0.0
    for p in paths:
        doc = json.loads(Path(p).read_text())
        wall += float(doc.get("wall_s") or 0.0)
        for r in doc["cases"]:
            recs.setdefault(int(r["seed"]), r)
    return [recs[k] for k in sorted(recs)], wall


def refresh(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """Records of a previous run under the current identifiability table: ``identifiable``
    again from the corpus' draw; candidates and names the log's signals cannot show (by
    the current table) taken out of ``ranking_first`` and ``named`` (``refreshed`` lists
    what was taken out).  The rest of a ranking does not depend on them."""
    from hdservo.discrepancy import IDENTIFIABLE
    from oracles import discrepancy_corpus as corpus
    out = []
    for r in records:
        ok = IDENTIFIABLE[r["angles"]]
        gone = sorted({c["effect"] for c in r.get("ranking_first", []) if c["effect"] not in ok}
                      | {e for e in r.get("named", []) if e not in ok})
        r = dict(r, identifiable=corpus.draw(int(r["seed"])).identifiable())
        if gone:
            r["ranking_first"] = [c for c in r.get("ranking_first", []) if c["effect"] in ok]
            r["named"] = [e for e in r["named"] if e in ok]
            r["refreshed"] = gone
        out.append(r)
    return out


def main() -> int:
    out = Path(os.environ.get("HDSERVO_CALIB_OUT") or REPO / "build" / "results" / "discrepancy_calibration.json")
    src = os.environ.get("HDSERVO_CALIB_FROM")
    t0 = time.time()
    if src:
        recs, wall = merged(src.split(os.pathsep))
        recs = refresh(recs)
    else:
        from oracles import discrepancy_corpus as corpus
        seeds = list(corpus.CALIBRATION_SEEDS)[:N_LOGS]
        only = [a for a in os.environ.get("HDSERVO_CALIB_SETS", "").split(",") if a]
        if only:                               # the first seeds' logs of these signal sets only
            seeds = [s for s in seeds if corpus.draw(s).angles in only]
        sets = [a for a in os.environ.get("HDSERVO_CALIB_CLEAN", "motor,output").split(",") if a]
        extra = [s for s in census_seeds(sets, corpus.CALIBRATION_SEEDS) if s not in seeds]
        n_two = int(os.environ.get("HDSERVO_CALIB_TWO", "0"))
        extra += [s for s in two_effect_seeds(corpus.CALIBRATION_SEEDS, n_two) if s not in seeds and s not in extra]
        recs = []
        with ProcessPoolExecutor(max_workers=JOBS) as ex:
            for r in ex.map(analyse, seeds + extra):
                r["census"] = r["seed"] in extra
                recs.append(r)
                print(f"{r['label']}: named {r['named']}{' ' + r['error'] if r['error'] else ''} "
                      f"({r['seconds']:.0f} s)", flush=True)
                if len(recs) % 10 == 0:         # a partial record survives an interrupted run
                    out.parent.mkdir(parents=True, exist_ok=True)
                    write_json_atomic(out.with_suffix(".partial.json"), {"cases": recs, "wall_s": time.time() - t0})
        wall = time.time() - t0
    from hdservo.discrepancy.workflow import Settings
    doc = {"set": "calibration", "report": report(sample(recs)), "cases": recs, "wall_s": wall,
           "threshold_inputs": threshold_inputs(recs, Settings().frac_min, wall)}
    doc["report"]["frac_min_rule"]["chosen_with_census"] = choose_frac_min(recs, Settings().frac_min)
    doc["report"]["two_effects"] = two_effects(recs)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out, doc)
    if os.environ.get("HDSERVO_CALIB_PACKAGE") == "1":
        pkg = REPO / "host" / "hdservo" / "data" / "discrepancy_thresholds.json"
        write_json_atomic(pkg, doc["threshold_inputs"])
        print(f"-> {pkg}")
    print(json.dumps({k: doc["report"][k] for k in ("confusion", "frac_min_rule")}, indent=1))
    print(json.dumps(doc["report"]["summary"], indent=1))
    print(f"-> {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
