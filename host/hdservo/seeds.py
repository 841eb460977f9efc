"""Medians over sensor-noise seeds of the demo's summary and ablation documents.

One comparison (``hdservo compare``) per seed gives a summary
(:func:`hdservo.compare.summary_doc`) and an ablation document
(:func:`hdservo.compare.ablation_doc`); the targets of the project are medians over
seeds, so :func:`merge_summaries` and :func:`merge_ablations` put the median of
every figure in the place of the single value and keep every seed's value beside
it (``per_seed``).  A missing value of a seed (a failed procedure) is kept as None
in ``per_seed`` and left out of the median; the median is None when no seed has
a value.  Ratios to the baseline are ratios of the medians.
"""
from __future__ import annotations

import statistics
from typing import Any, Mapping, Optional, Sequence


def parse_seeds(text: str) -> list[int]:
    """``"1,2,3"`` -> ``[1, 2, 3]`` (distinct non-negative integers, order kept).

    Raises
    ------
    ValueError
        Empty, not an integer, negative or repeated.
    """
    out: list[int] = []
    for part in str(text).split(","):
        p = part.strip()
        try:
            v = int(p)
        except ValueError:
            raise ValueError(f"--seeds {text}: '{p}' is not an integer (expected e.g. 1,2,3)") from None
        if v < 0:
            raise ValueError(f"--seeds {text}: seed {v} is negative")
        if v in out:
            raise ValueError(f"--seeds {text}: seed {v} given twice")
        out.append(v)
    if not out:
        raise ValueError(f"--seeds {text}: no seed")
    return out


def median(values: Sequence[Optional[float]]) -> Optional[float]:
    """Median of the values that are not None (None when there is none)."""
    got = [float(v) for v in values if v is not None]
    return float(statistics.median(got)) if got else None


def _ratio(v: Optional[float], base: Optional[float]) -> Optional[float]:
    return None if v is None or base is None or base == 0 else v / base


def merge_summaries(summaries: Sequence[Mapping[str, Any]], seeds: Sequence[int]) -> dict[str, Any]:
    """Median summary: ``{figure: {"pid", "compensated", "per_seed": {"pid": [..], "compensated": [..]}}, ...}``.

    Parameters
    ----------
    summaries : sequence of dict
        One :func:`hdservo.compare.summary_doc` per seed, in the order of ``seeds``.
    seeds : sequence of int
        The sensor-noise seeds.

    Returns
    -------
    dict
        Every figure of the summaries with the medians, ``conditions`` of the first seed with
        ``per_seed`` conditions of the compensated row (its components may differ per seed),
        ``seeds`` and ``statistic`` ("median").
    """
    if len(summaries) != len(seeds) or not summaries:
        raise ValueError("one summary per seed expected")
    out: dict[str, Any] = {}
    for key, first in summaries[0].items():
        if key == "conditions" or not isinstance(first, Mapping) or "pid" not in first:
            continue
        per = {role: [s.get(key, {}).get(role) for s in summaries] for role in ("pid", "compensated")}
        out[key] = {"pid": median(per["pid"]), "compensated": median(per["compensated"]), "per_seed": per}
    cond = dict(summaries[0].get("conditions", {}))
    cond["per_seed"] = [s.get("conditions", {}) for s in summaries]
    out["conditions"] = cond
    out["seeds"] = list(seeds)
    out["statistic"] = "median"
    return out


def merge_ablations(docs: Sequence[Mapping[str, Any]], seeds: Sequence[int]) -> dict[str, Any]:
    """Median ablation: each row's figures are medians over the seeds that ran the row.

    Parameters
    ----------
    docs : sequence of dict
        One :func:`hdservo.compare.ablation_doc` per seed, in the order of ``seeds``.
    seeds : sequence of int

    Returns
    -------
    dict
        ``{"baseline", "rule", "best": {feedback: [components per seed]}, "feedbacks": {feedback:
        {"rule", "best", "steps", "leave_one_out"}}`` (the rule's text, and per seed the chosen parts,
        the reasons of the forward selection and the leave-one-out judgements), ``"seeds", "statistic",
        "rows": [{"name", "feedback", "kind", "components", "baseline_row", "figures",
        "ratio_to_baseline", "per_seed": {"figures": {k: [..]}, "ratio_to_baseline": {k: [..]},
        "components": [..]}}]}``; ``ratio_to_baseline`` is the row's median over the baseline
        row's median (same feedback configuration).
    """
    if len(docs) != len(seeds) or not docs:
        raise ValueError("one ablation document per seed expected")
    names: list[str] = []
    for d in docs:
        names += [r["name"] for r in d.get("rows", []) if r["name"] not in names]
    by_seed = [{r["name"]: r for r in d.get("rows", [])} for d in docs]
    rows: list[dict[str, Any]] = []
    for n in names:
        present = [b[n] for b in by_seed if n in b]
        first = present[0]
        keys = list(first.get("figures", {}))
        per_fig = {k: [b[n]["figures"].get(k) if n in b else None for b in by_seed] for k in keys}
        per_ratio = {k: [b[n].get("ratio_to_baseline", {}).get(k) if n in b else None for b in by_seed] for k in keys}
        rows.append({"name": n, "feedback": first.get("feedback"), "kind": first.get("kind"),
                     "components": list(first.get("components", [])), "baseline_row": first.get("baseline_row"),
                     "figures": {k: median(v) for k, v in per_fig.items()},
                     "per_seed": {"figures": per_fig, "ratio_to_baseline": per_ratio,
                                  "components": [list(b[n].get("components", [])) if n in b else None
                                                 for b in by_seed]}})
    med = {r["name"]: r for r in rows}
    for r in rows:
        base = med.get(r["baseline_row"] or "")
        r["ratio_to_baseline"] = {k: _ratio(v, base["figures"].get(k) if base else None)
                                  for k, v in r["figures"].items()}
    best: dict[str, list[Any]] = {}
    for d in docs:
        for fb, parts in (d.get("best") or {}).items():
            best.setdefault(fb, []).append(parts)
    fbs: dict[str, dict[str, Any]] = {}
    for d in docs:
        for fb, v in (d.get("feedbacks") or {}).items():
            e = fbs.setdefault(fb, {"rule": v.get("rule"), "best": [], "steps": [], "leave_one_out": []})
            e["best"].append(v.get("best"))
            e["steps"].append(list(v.get("steps", [])))
            e["leave_one_out"].append(v.get("leave_one_out", {}))
    return {"baseline": docs[0].get("baseline", "pid"), "rule": docs[0].get("rule"), "best": best,
            "feedbacks": fbs, "seeds": list(seeds), "statistic": "median", "rows": rows}


__all__ = ["median", "merge_ablations", "merge_summaries", "parse_seeds"]
