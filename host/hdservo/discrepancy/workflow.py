"""The discrepancy loop: fit the baseline, rank candidate effects by evidence, name one
only if significant, add it, re-fit, repeat.

Evidence of a candidate (its columns added to the current model and everything re-fitted
jointly): the drop of the weighted residual sum of squares, judged with the effective
sample count n_eff of the (coloured) residual:

* Delta BIC = n_eff ln(RSS_0/RSS_1) - (p + h) ln(n_eff)  (p linear, h searched parameters);
* F = ((RSS_0 - RSS_1)/p) / (RSS_1/(n_eff - k)), its p-value;
* the explained fraction 1 - RSS_1/RSS_0.

The best-ranked valid candidate is named when Delta BIC > ``bic_min``, p < ``p_max`` and
the explained fraction >= ``frac_min`` (a candidate that removes less than that is not
the missing physics but a fit to noise or to a neighbour of it).  The loop stops when no
candidate qualifies, after ``max_iter`` additions, or when the residual of the motor
equation passes the Ljung-Box whiteness test.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.stats as st

from . import baseline as bl
from . import effects as fx
from .residuals import effective_n, ljung_box
from .signals import Signals


@dataclass
class Settings:
    """Decision thresholds (docs/discrepancy.md)."""

    bic_min: float = 10.0
    p_max: float = 1e-3
    frac_min: float = 0.30
    max_iter: int = 3
    whiteness_p: float = 0.01


@dataclass
class Candidate:
    effect: fx.Effect
    variant: fx.Variant
    fit: bl.Fit
    evidence: dict[str, float]


@dataclass
class State:
    """The current model: baseline columns, added effects (with their variant), weights, fit."""

    design: bl.Design
    base_cols: list[bl.Column]
    added: list[tuple[fx.Effect, fx.Variant]] = field(default_factory=list)
    weights: dict[str, float] = field(default_factory=dict)
    fit: bl.Fit | None = None

    def columns(self, extra: fx.Variant | None = None) -> list[bl.Column]:
        cols = list(self.base_cols)
        for _, v in self.added:
            cols += v.columns
        if extra is not None:
            cols += extra.columns
        return cols

    def tau(self, extra: fx.Variant | None = None) -> tuple[np.ndarray | None, str]:
        for v in [x for _, x in self.added] + ([extra] if extra is not None else []):
            if v.tau is not None:
                return v.tau, v.tau_key
        return None, "tau"

    def solve(self, extra: fx.Variant | None = None) -> bl.Fit:
        tau, key = self.tau(extra)
        return bl.solve(self.design, self.columns(extra), self.weights, tau, key)


def _weighted(fit: bl.Fit, w: dict[str, float]) -> np.ndarray:
    return np.concatenate([fit.resid[e] * w.get(e, 1.0) for e in fit.resid])


def _neff(fit: bl.Fit, w: dict[str, float]) -> float:
    return float(sum(effective_n(fit.resid[e] * w.get(e, 1.0)) for e in fit.resid))


def evidence(cur: bl.Fit, new: bl.Fit, p: int, h: int, n_eff: float) -> dict[str, float]:
    """Evidence of a richer fit over the current one (see the module docstring)."""
    rss0, rss1 = cur.rss_w, max(new.rss_w, 1e-300)
    k = new.n_params
    dbic = n_eff * np.log(rss0 / rss1) - (p + h) * np.log(n_eff)
    pp = max(p, 1)
    F = ((rss0 - rss1) / pp) / (rss1 / max(n_eff - k, 1.0))
    pval = float(st.f.sf(F, pp, max(n_eff - k, 1.0))) if F > 0 else 1.0
    return {"delta_bic": float(dbic), "F": float(F), "p_value": pval,
            "explained_fraction": float(1 - rss1 / rss0), "n_eff": float(n_eff),
            "added_params": int(p + h)}


def rank(state: State, lib: list[fx.Effect]) -> list[Candidate]:
    """Best variant of every applicable, not yet added candidate, sorted by Delta BIC."""
    assert state.fit is not None
    named = {e.name for e, _ in state.added}
    d = state.design
    n_eff = _neff(state.fit, state.weights)
    first = next(iter(state.fit.resid.values()))
    out: list[Candidate] = []
    for eff in lib:
        if eff.name in named or not eff.applicable(d):
            continue
        best: Candidate | None = None
        for v in eff.variants(d, first):
            try:
                f = state.solve(v)
            except np.linalg.LinAlgError:
                continue
            if not eff.valid(f, v):
                continue
            ev = evidence(state.fit, f, len(v.columns), v.n_hyper, n_eff)
            if best is None or ev["delta_bic"] > best.evidence["delta_bic"]:
                best = Candidate(eff, v, f, ev)
        if best is not None:
            out.append(best)
    out.sort(key=lambda c: -c.evidence["delta_bic"])
    return out


def significant(c: Candidate, s: Settings) -> bool:
    e = c.evidence
    return e["delta_bic"] > s.bic_min and e["p_value"] < s.p_max and e["explained_fraction"] >= s.frac_min


@dataclass
class Result:
    """Outcome of :func:`run` (JSON shape in docs/discrepancy.md)."""

    baseline: dict[str, float]
    iterations: list[dict[str, Any]]
    named: list[str]
    final_model: dict[str, Any]
    rms_history: list[float]
    state: State
    base_fit: bl.Fit
    snapshots: list[bl.Fit]
    ranking_last: list[dict[str, Any]]
    whiteness: dict[str, float]
    base_rel_pct: float = 0.0
    ranking_first: list[dict[str, Any]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"baseline": self.baseline, "baseline_relative_error_pct": self.base_rel_pct, "iterations": self.iterations, "named_effects": self.named,
                "final_model": self.final_model, "residual_unit": "N.m at the motor (N for a linear axis)",
                "rms_history": self.rms_history, "first_ranking": self.ranking_first,
                "last_ranking": self.ranking_last,
                "final_whiteness": self.whiteness}


SIGNAL_TEXT = ("equation error of the measured motor torque (motor and rigid-body equations stacked), "
               "parallel low-pass filtered and decimated, moving samples only; RMS in N.m at the motor "
               "(N for a linear axis)")


def run(sig: Signals, settings: Settings | None = None, offset: bool | None = None,
        lib: list[fx.Effect] | None = None) -> Result:
    """Run the discrepancy workflow on prepared signals.

    Parameters
    ----------
    sig : Signals
    settings : Settings, optional
    offset : bool, optional
        Constant torque offset in the baseline (default: yes for rigid, no for two-mass).
    lib : list of Effect, optional
        Candidate library (default :func:`hdservo.discrepancy.effects.library`).
    """
    s = settings or Settings()
    lib = lib if lib is not None else fx.library()
    d = bl.make_design(sig)
    if int(d.mask.sum()) < 50:
        from ..cli import UserError
        raise UserError("log: fewer than 50 moving samples after filtering; the axis hardly moves")
    cols = bl.baseline_columns(d, offset)
    d._baseline_names = {c.name for c in cols}  # type: ignore[attr-defined]
    st_ = State(design=d, base_cols=cols)
    f0 = bl.solve(d, cols, {})
    st_.weights = bl.equation_weights(f0)
    st_.fit = st_.solve()
    base_fit = st_.fit
    baseline = base_fit.params()
    base_rel = relative_error_pct(st_)
    iterations: list[dict[str, Any]] = []
    snapshots = [base_fit]
    rms_hist = [base_fit.rms]
    last_rank: list[dict[str, Any]] = []
    first_rank: list[dict[str, Any]] | None = None
    for _ in range(s.max_iter):
        ranked = rank(st_, lib)
        last_rank = [{"effect": c.effect.name, **c.evidence, "hyper": _jsonable(c.variant.hyper)} for c in ranked]
        if first_rank is None:
            first_rank = last_rank
        top = next((c for c in ranked), None)
        if top is None or not significant(top, s):
            break
        rms_before = st_.fit.rms
        rel_before = relative_error_pct(st_)
        st_.added.append((top.effect, top.variant))
        st_.fit = st_.solve()
        iterations.append({
            "named_effect": top.effect.name,
            "evidence": {**top.evidence, "runner_up": ranked[1].effect.name if len(ranked) > 1 else None,
                         "runner_up_delta_bic": ranked[1].evidence["delta_bic"] if len(ranked) > 1 else None},
            "rms_before": rms_before, "rms_after": st_.fit.rms, "signal": SIGNAL_TEXT,
            "relative_error_pct_before": rel_before, "relative_error_pct_after": relative_error_pct(st_),
            "params": _jsonable(top.effect.params(st_.fit, top.variant)),
            "signature": top.effect.signature, "coordinate": top.effect.coordinate,
        })
        snapshots.append(st_.fit)
        rms_hist.append(st_.fit.rms)
        wm = ljung_box(next(iter(st_.fit.resid.values())))
        if wm["p_value"] > s.whiteness_p:
            break
    white = ljung_box(next(iter(st_.fit.resid.values())))
    final = {"structure": sig.kind, "params": st_.fit.params(),
             "relative_error_pct": relative_error_pct(st_),
             "effects": {it["named_effect"]: it["params"] for it in iterations}}
    return Result(baseline=baseline, iterations=iterations, named=[i["named_effect"] for i in iterations],
                  final_model=final, rms_history=rms_hist, state=st_, base_fit=base_fit, snapshots=snapshots,
                  ranking_last=last_rank, whiteness=white, base_rel_pct=base_rel,
                  ranking_first=first_rank or [])


def relative_error_pct(state: State) -> float:
    """100 ||tau - tau_model|| / ||tau|| over the used samples (the EMPS figure of merit), %."""
    assert state.fit is not None
    tau, key = state.tau()
    y = state.design.lhs(state.design.sig.tau if tau is None else tau, key)
    r = np.concatenate(list(state.fit.resid.values()))
    return float(100.0 * np.linalg.norm(r) / max(np.linalg.norm(y), 1e-300))


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x
