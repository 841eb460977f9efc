"""The discrepancy loop: fit the baseline, rank candidate effects by evidence, name one
only if significant, add it, re-fit, re-simulate, repeat.

Evidence of a candidate (its columns added to the current model and everything re-fitted
jointly) is taken from two residuals:

* the **equation error** (measured torque minus the model's torque from the measured
  states): the drop of the weighted residual sum of squares, judged with the effective
  sample count n_eff of the coloured residual -- Delta BIC = n_eff ln(RSS_0/RSS_1) -
  (p + h) ln(n_eff) (p linear, h searched parameters), the F-test p-value, the explained
  fraction 1 - RSS_1/RSS_0;
* the **simulation error** (:mod:`hdservo.discrepancy.simerr`: the fitted model driven
  by the measured torque over 50 ms windows from the measured state): the same three
  figures on its sum of squares.

Every variant of a candidate is scored on the equation error, its best ``sim_variants``
are simulated, and the variant with the largest :func:`score` (Delta BIC per effective
sample, summed over the two residuals) represents the candidate.  Candidates whose friction parameters the equation error cannot see
(Stribeck: the low-speed band is crossed next to the stops the fit must leave out) are
fitted on the simulation error instead (:func:`oe_fit`) and their coefficients kept fixed.
Candidates are ranked by :func:`score`; the best-ranked one that passes
:func:`significant` is named.  The loop stops when none passes, after ``max_iter``
additions, or when the residual of the motor equation passes the Ljung-Box test.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.stats as st

from . import identifiability, not_identifiable_parts
from . import regression as bl
from . import effects as fx
from ..fileio import json_ready
from .residuals import effective_n, ljung_box
from . import simerr
from . import thresholds
from .simerr import region_mask, side_error, simulation_error
from .signals import Signals


#: Size threshold per signal set where it differs from the default, by the false-alarm rule
#: on the clean logs of the corpus' calibration seeds (:mod:`hdservo.discrepancy.thresholds`:
#: the 95 % quantile of the largest significant candidate's size on clean logs, plus 0.01,
#: never below the default), computed from the rule's inputs in the package data.
FRAC_MIN_BY_SIGNALS: dict[str, float] = thresholds.frac_min_by_signals()


@dataclass
class Settings:
    """Decision thresholds (docs/discrepancy.md)."""

    bic_min: float = 10.0
    p_max: float = 1e-3
    frac_min: float = 0.30
    #: Size threshold of a later name (one named after another) that is significant in both
    #: residuals, offered when no candidate reaches ``frac_min``: the simulator judges every
    #: later name by the gap it closes below its control
    #: (:data:`hdservo.discrepancy.closeloop.CONFIRM_SHRINK_LATER`), so the workflow's size
    #: only has to offer it (docs/discrepancy.md, "Later names on calibration logs").
    frac_min_later: float = 0.15
    max_iter: int = 3
    whiteness_p: float = 0.01
    #: Variants per candidate (best by equation-error evidence) that are also simulated.
    sim_variants: int = 3
    #: ``frac_min`` per signal set (``both``, ``motor``, ``output``) where it differs from
    #: the default: :data:`FRAC_MIN_BY_SIGNALS`, set on the corpus' calibration logs.
    frac_min_by_signals: dict[str, float] = field(default_factory=lambda: dict(FRAC_MIN_BY_SIGNALS))

    def for_signals(self, angles: str) -> "Settings":
        """These settings with the size threshold of the log's signal set."""
        from dataclasses import replace
        return replace(self, frac_min=max(self.frac_min, self.frac_min_by_signals.get(angles, self.frac_min)))


#: Share of the baseline's equation error (:func:`hdservo.discrepancy.regression.constant_share`)
#: from which the constant is the larger part of it and the run says so in ``notes``.
CONSTANT_NOTE_SHARE = 0.5

#: Log-bisection steps of :func:`oe_fit` towards the best-scoring level when it is not
#: admissible.
OE_BISECT = 3


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
    sim: np.ndarray | None = None
    #: Integration sub-steps of its simulations (None: :data:`simerr.SUBSTEPS`).
    substeps: int | None = None
    #: Window of its simulations, s.
    horizon_s: float = simerr.HORIZON_S

    @classmethod
    def start(cls, d: bl.Design, cols: list[bl.Column]) -> "State":
        """The baseline model of a design: equation weights from an unweighted fit, the
        weighted fit and its simulation error."""
        st_ = cls(design=d, base_cols=cols)
        st_.weights = bl.equation_weights(bl.solve(d, cols, {}))
        st_.fit = st_.solve()
        st_.sim = st_.simulate(st_.fit)
        return st_

    def fixed(self, extra: fx.Variant | None = None) -> list[tuple[bl.Column, float]]:
        """Columns whose coefficient was fitted on the simulation error, with that value."""
        out = []
        for v in [x for _, x in self.added] + ([extra] if extra is not None else []):
            if v.fixed:
                out += [(c, v.fixed[c.name]) for c in v.columns if c.name in v.fixed]
        return out

    def simulate(self, fit: bl.Fit, extra: fx.Variant | None = None) -> np.ndarray:
        """Simulation error of a fit of the current model (+ ``extra``), rad at the output."""
        tau, key = self.tau(extra)
        cols = self.columns(extra)
        coef = dict(zip(fit.names, fit.theta))
        return simulation_error(self.design, cols, np.array([coef.get(c.name, 0.0) for c in cols]), tau, key,
                                horizon_s=self.horizon_s, substeps=self.substeps)

    def columns(self, extra: fx.Variant | None = None) -> list[bl.Column]:
        cols = list(self.base_cols)
        for _, v in self.added:
            cols += v.columns
        if extra is not None:
            cols += extra.columns
        return cols

    def tau(self, extra: fx.Variant | None = None) -> tuple[np.ndarray | None, str]:
        return torque_of([x for _, x in self.added] + ([extra] if extra is not None else []))

    def solve(self, extra: fx.Variant | None = None) -> bl.Fit:
        tau, key = self.tau(extra)
        return bl.solve(self.design, self.columns(extra), self.weights, tau, key, self.fixed(extra))


def torque_of(variants: list[fx.Variant]) -> tuple[np.ndarray | None, str]:
    """The input torque of a model made of ``variants`` (N.m at the motor) and its cache key:
    the first variant that replaces the measured torque (a current-loop lag) sets it;
    (None, "tau") means the measured torque."""
    for v in variants:
        if v.tau is not None:
            return v.tau, v.tau_key
    return None, "tau"


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


def _sse(e: np.ndarray) -> float:
    """Sum of squares of a candidate's simulation error; inf when it diverged (non-finite or
    overflowing: such a candidate is judged unfit, without a numpy warning)."""
    if not np.all(np.isfinite(e)):
        return np.inf
    with np.errstate(over="ignore"):
        s = float(np.sum(np.square(e)))
    return s if np.isfinite(s) else np.inf


def sim_evidence(sse0: float, e1: np.ndarray, p: int, n_eff: float) -> dict[str, float]:
    """Evidence of a candidate in the simulation error: Delta BIC, F-test p-value, explained fraction."""
    sse1 = _sse(e1)
    if not np.isfinite(sse1) or sse1 <= 0:
        return {"sim_delta_bic": -np.inf if not np.isfinite(sse1) else np.inf, "sim_p_value": 1.0,
                "sim_explained_fraction": -np.inf if not np.isfinite(sse1) else 1.0, "sim_n_eff": n_eff}
    pp = max(p, 1)
    F = ((sse0 - sse1) / pp) / (sse1 / max(n_eff - pp, 1.0))
    pval = float(st.f.sf(F, pp, max(n_eff - pp, 1.0))) if F > 0 else 1.0
    return {"sim_delta_bic": float(n_eff * np.log(sse0 / sse1) - p * np.log(n_eff)), "sim_p_value": pval,
            "sim_explained_fraction": float(1 - sse1 / sse0), "sim_n_eff": float(n_eff)}


def _fc_of(fit: bl.Fit, side: str) -> float:
    """The fitted Coulomb friction of a side (column units), for the output-error levels."""
    name = {"m": ("Fc_motor_Nm", "Fc"), "l": ("Fc_load_Nm",)}[side]
    for n in name:
        if n in fit.names:
            return abs(float(fit.theta[fit.names.index(n)]))
    return 0.0


def oe_fit(state: State, v: fx.Variant, s: Settings | None = None, refine: int = 0,
           by_sim: bool = False, admit: bool = True) -> fx.Variant | None:
    """Fit a variant's friction coefficients on both residuals jointly (output-error fitter).

    Each column acts on one side (:attr:`Column.fric`); its coefficient is a level g x
    the side's fitted Coulomb friction.  A level is judged like a variant in
    :func:`rank`: by the :func:`score` it gives (ln of the equation error's RSS ratio,
    the rest of the model re-fitted by least squares with this coefficient fixed, plus
    ln of the simulation error's SSE ratio, the other coefficients at their current
    fit), among the *admissible* levels first (neither residual significantly worse,
    :func:`admissible`; a level the simulation error wants but the equation error
    rejects is a worse fit of the one friction law both see).  Search: ``v.oe_levels``
    0.5 and 1, then 2 or 0.25 in the better direction, the geometric midpoints either
    side of the best; when the best-scoring level is not admissible, up to
    ``OE_BISECT`` log-bisections between it and the best admissible one (the largest
    admissible level towards it); then ``refine`` halvings of the log step around the best
    (2^(1/4), 2^(1/8), ...: used when the effect is added, :func:`refit_named`), and with
    ``by_sim`` the level kept is the admissible one with the lowest simulation error
    instead of the best joint score; ``admit`` False drops the admissibility rule (a
    level need only lower its side's simulation error: the re-fit).  Returns
    the variant with these coefficients fixed and
    ``oe_gain`` (the joint score of the chosen levels: what ranks the variants), or None
    if no admissible level lowers the simulation error.
    """
    assert state.fit is not None and state.sim is not None and v.oe_levels
    prob = _OeProblem.of(state, v, s or Settings(), admit)
    fixed: dict[str, float] = {c.name: 0.0 for c in v.columns}
    sse_side: dict[str, float] = {}         # each side's SSE with the variant's coefficients at 0
    sse_now: dict[str, float] = {}          # each side's SSE with the levels chosen so far
    best_score = 0.0
    levels = sorted(v.oe_levels)
    for j, c in enumerate(v.columns):
        side = c.fric or "m"
        fc = _fc_of(state.fit, side)
        if fc <= 0:
            continue
        if side not in sse_side:
            sse_side[side] = prob.side_sse(side)
            sse_now[side] = sse_side[side]
        # the whole record's SSE with the levels chosen so far (the other sides' gains
        # count: the score is the joint score of all the variant's levels)
        sse_tot_now = prob.sse_tot0 + sum(sse_now[k] - sse_side[k] for k in sse_side)
        th_now = np.concatenate([prob.theta0[: len(prob.base_cols)], [fixed[ci.name] for ci in v.columns]])

        def judge(g: float, j: int = j, name: str = c.name, side: str = side, fc: float = fc,
                  th_now: np.ndarray = th_now, sse_tot_now: float = sse_tot_now) -> Judged:
            return prob.judge(g * fc, j, name, side, th_now, fixed, sse_tot_now, sse_now[side])

        tried = _oe_search_levels(judge, levels, refine, by_sim)
        if not tried:
            continue
        g_best = max(tried, key=(_oe_key_sim if by_sim else _oe_key)(tried))
        ok, sc, sse = tried[g_best]
        if ok:
            fixed[c.name] = g_best * fc
            sse_now[side] = sse
            best_score = sc
    if not any(fixed.values()):
        return None
    return fx.Variant(dict(v.hyper), v.columns, v.tau, v.tau_key, v.n_hyper, fixed=fixed,
                      oe_levels=v.oe_levels, oe_gain=float(best_score))


#: One judged output-error level: (admissible and lowers its side's SSE, joint score, side SSE).
Judged = tuple[bool, float, float]


@dataclass
class _OeProblem:
    """What every level of one output-error fit (:func:`oe_fit`) is judged against."""

    state: State
    v: fx.Variant
    s: Settings
    admit: bool
    tau: np.ndarray | None
    key: str
    base_cols: list[bl.Column]
    cols: list[bl.Column]
    theta0: np.ndarray
    n_eff: float
    n_sim: float
    rss0: float
    sse_tot0: float

    @classmethod
    def of(cls, state: State, v: fx.Variant, s: Settings, admit: bool) -> "_OeProblem":
        """The current fit's coefficients, residual sizes and effective sample counts."""
        assert state.fit is not None and state.sim is not None
        tau, key = state.tau(v)
        base_cols = state.columns()
        coef = dict(zip(state.fit.names, state.fit.theta))
        theta0 = np.array([coef.get(c.name, 0.0) for c in base_cols] + [0.0] * len(v.columns))
        return cls(state=state, v=v, s=s, admit=admit, tau=tau, key=key, base_cols=base_cols,
                   cols=base_cols + v.columns, theta0=theta0, n_eff=_neff(state.fit, state.weights),
                   n_sim=effective_n(state.sim), rss0=state.fit.rss_w,
                   sse_tot0=float(np.sum(state.sim ** 2)))

    def side_sse(self, side: str) -> float:
        """One side's simulation-error SSE with the variant's coefficients at 0."""
        st_ = self.state
        e = side_error(st_.design, self.base_cols, self.theta0[: len(self.base_cols)], side, self.tau, self.key,
                       horizon_s=st_.horizon_s, substeps=st_.substeps)
        return float(np.sum(e ** 2))

    def judge(self, coef: float, j: int, name: str, side: str, th_now: np.ndarray, fixed: dict[str, float],
              sse_tot_now: float, sse_side_now: float) -> Judged:
        """Column ``j`` (``name``, acting on ``side``) at ``coef``, the others as in ``th_now`` / ``fixed``."""
        st_, v = self.state, self.v
        th = th_now.copy()
        th[len(self.base_cols) + j] = coef
        e = side_error(st_.design, self.cols, th, side, self.tau, self.key, horizon_s=st_.horizon_s,
                       substeps=st_.substeps)
        sse = _sse(e)
        fx_ = dict(fixed)
        fx_[name] = coef
        try:
            f = st_.solve(fx.Variant(dict(v.hyper), v.columns, v.tau, v.tau_key, v.n_hyper, fixed=fx_))
        except np.linalg.LinAlgError:
            return False, -np.inf, sse
        sse_all = sse_tot_now - sse_side_now + sse
        if not (np.isfinite(sse_all) and sse_all > 0 and f.rss_w > 0):
            return False, -np.inf, sse
        ev = {"n_eff": self.n_eff, "explained_fraction": 1.0 - f.rss_w / self.rss0,
              "sim_n_eff": self.n_sim, "sim_explained_fraction": 1.0 - sse_all / self.sse_tot0}
        sc = float(np.log(self.rss0 / f.rss_w) + np.log(self.sse_tot0 / sse_all))
        return bool((admissible(ev, self.s) or not self.admit) and sse < sse_side_now), sc, sse


def _oe_key(tried: dict[float, Judged]) -> Callable[[float], tuple[bool, float]]:
    """Order of levels by (admissible, joint score)."""
    return lambda g: (tried[g][0], tried[g][1])


def _oe_key_sim(tried: dict[float, Judged]) -> Callable[[float], tuple[bool, float]]:
    """Order of levels by (admissible, lowest simulation error)."""
    return lambda g: (tried[g][0], -tried[g][2])


def _oe_bracket(judge: Callable[[float], Judged], levels: list[float]) -> dict[float, Judged]:
    """Levels 0.5 and 1, then 2 or 0.25 in the better direction, then the geometric
    midpoints either side of the best (:func:`oe_fit`); empty if neither 0.5 nor 1 is a level."""
    tried = {g: judge(g) for g in (0.5, 1.0) if g in levels}
    if not tried:
        return tried
    key_ = _oe_key(tried)
    up = key_(1.0) > key_(0.5) if (1.0 in tried and 0.5 in tried) else 1.0 in tried
    nxt = [g for g in levels if (g > 1.0 if up else g < 0.5)]
    if nxt:
        g2 = min(nxt) if up else max(nxt)
        tried[g2] = judge(g2)
    g_best = max(tried, key=key_)
    for g in (g_best / np.sqrt(2.0), g_best * np.sqrt(2.0)):
        if g not in tried:
            tried[g] = judge(g)
    return tried


def _oe_bisect_to_admissible(judge: Callable[[float], Judged], tried: dict[float, Judged]) -> None:
    """When the best-scoring level is not admissible, move towards it from the best
    admissible one (or from an eighth of it) by ``OE_BISECT`` log-bisections, staying admissible."""
    g_best = max(tried, key=_oe_key(tried))
    g_top = max(tried, key=lambda g: tried[g][1])
    if tried[g_top][0]:
        return
    lo = g_best if tried[g_best][0] else g_top / 8.0
    hi = g_top
    if lo == g_top / 8.0:
        tried[lo] = judge(lo)
    for _ in range(OE_BISECT):
        mid = float(np.sqrt(lo * hi))
        tried[mid] = judge(mid)
        if tried[mid][0]:
            lo = mid
        else:
            hi = mid


def _oe_refine(judge: Callable[[float], Judged], tried: dict[float, Judged], refine: int, by_sim: bool) -> None:
    """``refine`` halvings of the log step around the best level (2^(1/4), 2^(1/8), ...)."""
    kf = (_oe_key_sim if by_sim else _oe_key)(tried)
    g_best = max(tried, key=kf)
    for r in range(refine):
        step = 2.0 ** (0.5 ** (r + 2))
        for g in (g_best / step, g_best * step):
            if g not in tried:
                tried[g] = judge(g)
        g_best = max(tried, key=kf)


def _oe_search_levels(judge: Callable[[float], Judged], levels: list[float], refine: int,
                      by_sim: bool) -> dict[float, Judged]:
    """Every level the search of :func:`oe_fit` judges, in the order judged: bracket, bisect
    towards admissibility, refine."""
    tried = _oe_bracket(judge, levels)
    if tried:
        _oe_bisect_to_admissible(judge, tried)
        _oe_refine(judge, tried, refine, by_sim)
    return tried


def rank(state: State, lib: list[fx.Effect], s: Settings | None = None,
         simulate: bool = True) -> list[Candidate]:
    """Best variant of every applicable, not yet added candidate, sorted by the total evidence.

    Every variant is scored on the equation error; the ``s.sim_variants`` best of each
    candidate are also simulated (:mod:`hdservo.discrepancy.simerr`) and the variant with
    the largest sum of both Delta BICs is kept.  Candidates are sorted by that sum.

    ``simulate=False`` (the current model is not a mechanical axis, so it cannot be
    simulated: :func:`run`) ranks on the equation error alone: the variants fitted on the
    simulation error are left out, and so is every variant whose fit is not a mechanical
    axis either (:func:`is_physical`); the score is the equation error's Delta BIC per
    effective sample.
    """
    assert state.fit is not None and state.sim is not None
    s = s or Settings()
    named = {e.name for e, _ in state.added}
    d = state.design
    n_eff = _neff(state.fit, state.weights)
    sse0 = float(np.sum(state.sim ** 2)) if simulate else np.nan
    n_sim = effective_n(state.sim) if simulate else np.nan
    first = next(iter(state.fit.resid.values()))
    out: list[Candidate] = []
    for eff in lib:
        if eff.name in named or not eff.applicable(d):
            continue
        cands: list[Candidate] = []
        for v in eff.variants(d, first):
            if v.oe_levels and not simulate:
                continue
            if v.oe_levels:
                v = oe_fit(state, v, s)
                if v is None:
                    continue
            try:
                f = state.solve(v)
            except np.linalg.LinAlgError:
                continue
            if not eff.valid(f, v) or (not simulate and not is_physical(f.params())):
                continue
            cands.append(Candidate(eff, v, f, evidence(state.fit, f, len(v.columns), v.n_hyper, n_eff)))
        # variants fitted on the simulation error are ranked on it (the equation error
        # cannot see them: oe_fit); the others by their equation-error evidence
        cands.sort(key=lambda c: -(c.variant.oe_gain if c.variant.oe_gain is not None else c.evidence["delta_bic"]))
        best: Candidate | None = None
        if not simulate:                     # the best variant on the equation error alone
            if cands:
                best = cands[0]
                best.evidence.update(local_evidence(state, best, None))
                best.evidence.update(best.effect.own_evidence(d, best.fit, best.variant))
                best.evidence["total_delta_bic"] = best.evidence["delta_bic"]
                best.evidence["score"] = score(best.evidence)
        for c in (cands[: s.sim_variants] if simulate else []):
            e1 = state.simulate(c.fit, c.variant)
            c.evidence.update(sim_evidence(sse0, e1, len(c.variant.columns) + c.variant.n_hyper, n_sim))
            c.evidence.update(local_evidence(state, c, e1))
            c.evidence.update(c.effect.own_evidence(d, c.fit, c.variant))
            c.evidence["total_delta_bic"] = c.evidence["delta_bic"] + c.evidence["sim_delta_bic"]
            c.evidence["score"] = score(c.evidence)
            # the candidate's representative: its best admissible variant (neither
            # residual significantly worse), else its best variant
            if best is None or ((admissible(c.evidence, s), c.evidence["score"])
                                > (admissible(best.evidence, s), best.evidence["score"])):
                best = c
        if best is not None:
            best.evidence.update(twin_evidence(state, best, sse0, n_eff, n_sim, simulate))
            out.append(best)
    out.sort(key=lambda c: -c.evidence["score"])
    return out


def twin_evidence(state: State, c: Candidate, sse0: float, n_eff: float, n_sim: float,
                  simulate: bool = True) -> dict[str, float]:
    """How much better a candidate explains the residuals than its twin
    (:meth:`hdservo.discrepancy.effects.Effect.twin`: the look-alike without the effect's
    defining signature): ``twin_delta_bic`` = n_eff ln(RSS_twin / RSS) in the equation
    error, ``sim_twin_delta_bic`` likewise in the simulation error (reported; with
    ``simulate`` False not computed).  Empty for a candidate without a twin."""
    tw = c.effect.twin(state.design, c.variant)
    if tw is None:
        return {}
    try:
        ft = state.solve(tw)
    except np.linalg.LinAlgError:
        return {}
    eq = n_eff * np.log(max(ft.rss_w, 1e-300) / max(c.fit.rss_w, 1e-300))
    out = {"twin_delta_bic": float(eq), "twin_explained_fraction": float(1 - ft.rss_w / state.fit.rss_w)}
    if not simulate:
        return out
    e_t = state.simulate(ft, tw)
    sse_c = sse0 * (1.0 - c.evidence.get("sim_explained_fraction", np.nan))
    sse_t = _sse(e_t)
    sim = (n_sim * np.log(sse_t / sse_c) if np.isfinite(sse_t) and np.isfinite(sse_c) and sse_c > 0
           else (np.inf if not np.isfinite(sse_t) else -np.inf))
    return out | {"sim_twin_delta_bic": float(sim),
                  "twin_sim_explained_fraction": float(1 - sse_t / sse0) if sse0 > 0 else np.nan}


#: Halvings of the output-error level step when a named effect is re-fitted (2^(1/4),
#: 2^(1/8), 2^(1/16): levels to about 4 %).
REFIT_LEVEL_STEPS = 3

#: Integration sub-steps of the re-fit's simulations and of a banded effect's gap
#: (:func:`band_sim_figures`): twice :data:`simerr.SUBSTEPS`.  At 4 sub-steps the Karnopp
#: breakaway of the Stribeck hump is not converged: on csf17_50 closed loop s3 the plant's
#: own friction law simulates to 3.36e-5 rad over the band against 3.45e-5 for a fit far
#: from it; at 8 sub-steps to 1.83e-5 (docs/discrepancy.md).
FINE_SUBSTEPS = 8
#: Window of the re-fit's simulations, s: short segments (as in multiple shooting).
#: Through the Stribeck hump the replayed motor side is unstable (e-folding time about
#: 1.2 ms on csf17_50), so a breakaway instant that is off
#: grows over the window and a 50 ms window's SSE is rough in vs: csf17_50 closed s1 fitted
#: on 50 ms windows lands at vs 0.0115 rad/s, load Fs - Fc 0.40 N.m (plant 0.020, 0.204),
#: on 10 ms windows at 0.0183, 0.219.
REFIT_HORIZON_S = 0.01


def refit_named(state: State, c: Candidate, s: Settings | None = None) -> Candidate:
    """The named candidate re-fitted before it is added ("add it, re-fit").

    Ranking searches an output-error variant's levels on a sqrt(2) grid, its
    hyper-parameter on a coarse grid (Stribeck: vs about 2.4x apart), each judged by the
    joint score of both residuals among the admissible levels: enough to judge evidence,
    not to fit a breakaway.  Here the effect is fitted to the simulation error alone, on
    windows of :data:`REFIT_HORIZON_S` at :data:`FINE_SUBSTEPS` integration sub-steps:

    1. every hyper-parameter of the effect's grid (and the named one) is a start; each
       gets its levels by the lowest simulation SSE (:func:`oe_fit`, ``by_sim``, no
       admissibility rule: the equation error's friction columns see the breakaway
       through the filtered velocity and reject the plant's own levels, +1.7 % RSS on
       csf17_50 closed s3);
    2. the best start's levels are refined to about 4 % (``REFIT_LEVEL_STEPS``) and its
       hyper-parameter half and quarter grid steps either side (:meth:`Effect.refine_hyper`)
       is tried, the lowest simulation SSE kept.

    Evidence and naming are not changed; when no start can be fitted (or the effect finds
    every fit invalid) the candidate is left as it was.
    """
    if not c.variant.oe_levels:
        return c
    d = state.design
    fine = State(design=d, base_cols=state.base_cols, added=state.added, weights=state.weights,
                 fit=state.fit, substeps=FINE_SUBSTEPS, horizon_s=REFIT_HORIZON_S)
    assert fine.fit is not None
    fine.sim = fine.simulate(fine.fit)

    def fit_of(v: fx.Variant) -> tuple[fx.Variant, bl.Fit, float] | None:
        w = oe_fit(fine, v, s, refine=REFIT_LEVEL_STEPS, by_sim=True, admit=False)
        if w is None or w.oe_gain is None:
            return None
        try:
            f = fine.solve(w)
        except np.linalg.LinAlgError:
            return None
        if not c.effect.valid(f, w):
            return None
        e = fine.simulate(f, w)
        return (w, f, _sse(e)) if np.all(np.isfinite(e)) else None

    resid = next(iter(fine.fit.resid.values()))
    starts = [c.variant] + [v for v in c.effect.variants(d, resid) if v.hyper != c.variant.hyper]
    got = [g for g in (fit_of(v) for v in starts) if g is not None]
    if not got:
        return c
    best = min(got, key=lambda g: g[2])
    for frac in (0.5, 0.25):                 # half grid steps, then quarter steps
        for v in c.effect.refine_hyper(d, best[0], frac):
            g = fit_of(v)
            if g is not None and g[2] < best[2]:
                best = g
    return Candidate(c.effect, best[0], best[1], c.evidence)   # solve() is the same in `fine`


def eq_region(d: bl.Design, bands: dict[str, float] | None) -> np.ndarray:
    """Rows of the stacked equation error (every equation alike) where a side's measured
    speed is below its band (:meth:`Effect.region_bands`); all rows for None."""
    n = int(d.mask.sum())
    if bands is None:
        return np.ones(n * len(d.equations), dtype=bool)
    s = d.sig
    sel = np.zeros(n, dtype=bool)
    if "m" in bands:
        sel |= np.abs(d.dec("state:wm", s.w_m)[d.mask]) < bands["m"]
    if "l" in bands and s.w_l is not None:
        sel |= np.abs(d.dec("state:wl", s.w_l)[d.mask]) < bands["l"]
    return np.concatenate([sel for _ in d.equations])


def local_evidence(state: State, c: Candidate, e1: np.ndarray | None) -> dict[str, float]:
    """Explained fractions of a candidate over the region where it acts.

    The region comes from the data and the candidate's own fitted variant
    (:meth:`Effect.region_bands`, e.g. Stribeck: the speeds below 3 vs), identically for
    the current model and the candidate: in the simulation error the windows from the
    first sample where a side's measured speed is in the band
    (:func:`hdservo.discrepancy.simerr.region_mask`), in the equation error the used
    samples in the band.  An effect that acts over the whole record gets the whole
    record (the local figures equal the global ones).  ``region_share`` / ``sim_region_share``:
    the part of the samples in the region.  ``e1`` None: the equation error's figures only.
    """
    assert state.fit is not None and state.sim is not None
    d = state.design
    bands = c.effect.region_bands(d, c.variant)
    rs = region_mask(d, bands)
    out: dict[str, float] = {}
    if e1 is not None and len(rs) == len(state.sim) == len(e1) and rs.any():
        s0 = float(np.sum(state.sim[rs] ** 2))
        s1 = _sse(e1[rs])
        out["sim_explained_fraction_local"] = float(1 - s1 / s0) if s0 > 0 else np.nan
        out["sim_region_share"] = float(rs.mean())
    else:
        out["sim_explained_fraction_local"] = np.nan
        out["sim_region_share"] = 0.0
    rq = eq_region(d, bands)
    w = state.weights
    r0, r1 = _weighted(state.fit, w), _weighted(c.fit, w)
    out["explained_fraction_local"] = _explained(r0, r1, rq)
    # the same over the equations the candidate acts in only (rms_gap's choice of
    # residual; the size rule keeps the figure over every equation above)
    acting = set(_acting(c.variant, d))
    n = int(d.mask.sum())
    rows_act = np.concatenate([np.full(n, e in acting) for e in state.fit.resid])
    out["explained_fraction_local_acting"] = (_explained(r0, r1, rq & rows_act)
                                              if len(rows_act) == len(rq) else np.nan)
    out["region_share"] = float(rq.mean())
    return out


def _explained(r0: np.ndarray, r1: np.ndarray, rows: np.ndarray) -> float:
    """1 - sum(r1^2) / sum(r0^2) over the selected rows (NaN when none or r0 is 0)."""
    if not rows.any():
        return float("nan")
    q0 = float(np.sum(r0[rows] ** 2))
    return float(1 - np.sum(r1[rows] ** 2) / q0) if q0 > 0 else float("nan")


def score(e: dict[str, float]) -> float:
    """Ranking key: the Delta BIC of each residual per effective sample, summed.

    Delta BIC / n_eff = ln(RSS_0/RSS_1) - k ln(n_eff)/n_eff is the mean log-likelihood
    gain per independent sample (less the BIC penalty per sample).  The two residuals are
    two views of the *same* samples, not independent data, so their Delta BICs are not
    additive evidence: summed, the view with the whiter residual (larger n_eff, here the
    equation error with its differentiated noise) outweighs the other by its sample count
    alone.  Per effective sample both views count alike.
    """
    eq = e["delta_bic"] / max(e["n_eff"], 1.0)
    if "sim_n_eff" not in e:                      # ranked on the equation error alone
        return float(eq) if np.isfinite(eq) else -np.inf
    sim_n = e.get("sim_n_eff", np.nan)
    sim = e.get("sim_delta_bic", -np.inf) / max(sim_n, 1.0) if np.isfinite(sim_n) else -np.inf
    return float(eq + sim) if np.isfinite(eq + sim) else -np.inf


def worse(delta_bic_no_penalty: float, s: Settings) -> bool:
    """A residual is significantly worse when the current model beats the candidate's fit
    on it by more than ``bic_min`` in log-likelihood units (n_eff ln(RSS_1/RSS_0)), the
    same evidence threshold a candidate needs to be significant."""
    return -delta_bic_no_penalty > s.bic_min


def significant(c: Candidate, s: Settings, later: bool = False) -> bool:
    """Named only if (1) significant in the equation error or in the simulation error
    (Delta BIC > ``bic_min`` and F-test p < ``p_max`` in that residual), (2) the total
    Delta BIC exceeds ``bic_min``, (3) neither residual gets *significantly* worse
    (:func:`worse`: n_eff ln(RSS_1/RSS_0) > ``bic_min``; a coefficient fitted on one
    residual is not the least-squares optimum of the other, so an insignificant loss
    there is expected), and (4) large: it removes >= ``frac_min`` of the variance of the
    equation error or of the simulation error, judged over the region where the
    candidate acts (:func:`local_evidence`; the whole record for effects that act
    everywhere): an effect confined to the stops and reversals (Stribeck) is not diluted
    by the long stretches where it cannot act.

    A ``later`` name (the model holds a named effect already) that is significant in
    *both* residuals needs only ``frac_min_later``: its explained fraction is a share of
    the residual the earlier names left, part of which they took from it as look-alikes
    (an asymmetric friction from an unbalance, a Maxwell-slip fit from a stiffening
    spring), and the simulator confirms or drops every later name by the replay gap it
    closes (:func:`hdservo.discrepancy.closeloop.close`).  :func:`run` offers such a
    name only when no candidate of its round reaches ``frac_min``."""
    e = c.evidence
    sim_dbic = e.get("sim_delta_bic", -np.inf)
    sim_frac = e.get("sim_explained_fraction", -np.inf)
    eq_sig = e["delta_bic"] > s.bic_min and e["p_value"] < s.p_max
    sim_sig = sim_dbic > s.bic_min and e.get("sim_p_value", 1.0) < s.p_max
    large = size(e) >= s.frac_min or (later and eq_sig and sim_sig and size(e) >= s.frac_min_later)
    return bool((eq_sig or sim_sig) and e.get("total_delta_bic", -np.inf) > s.bic_min
                and admissible(e, s) and large and beats_twin(e, s))


def beats_twin(e: dict[str, float], s: Settings) -> bool:
    """A candidate with a twin (:func:`twin_evidence`) explains the equation error better
    than that look-alike by more than ``bic_min``, the evidence a candidate needs: a
    hysteresis shows its loop (its memoryless twin fits a lost-motion zone, a stiffening or
    a clean log's mismatch as well between reversals).  True for candidates without a
    twin."""
    if "twin_delta_bic" not in e:
        return True
    tb = e["twin_delta_bic"]
    return bool(tb is not None and np.isfinite(tb) and tb > s.bic_min)


def size(e: dict[str, float]) -> float:
    """Effect size: the largest explained fraction, whole record or the candidate's region,
    of the equation error and of the simulation error, and of the effect's own signature
    where it has one (:meth:`hdservo.discrepancy.effects.Effect.own_evidence`: the twist
    of a compliance); NaN entries ignored."""
    xs = [e.get(k, np.nan) for k in ("explained_fraction", "sim_explained_fraction",
                                      "explained_fraction_local", "sim_explained_fraction_local",
                                      "twist_fraction")]
    xs = [x for x in xs if x is not None and np.isfinite(x)]
    return float(max(xs)) if xs else -np.inf


def admissible(e: dict[str, float], s: Settings) -> bool:
    """Neither residual gets significantly worse (:func:`worse`) with the candidate."""
    sim_frac = e.get("sim_explained_fraction", -np.inf)
    sim_n = e.get("sim_n_eff", np.nan)
    eq_ll = e["n_eff"] * np.log(1.0 / max(1.0 - e["explained_fraction"], 1e-300))
    if "sim_n_eff" not in e:                      # ranked on the equation error alone
        return not worse(eq_ll, s)
    sim_ll = (sim_n * np.log(1.0 / max(1.0 - sim_frac, 1e-300))
              if np.isfinite(sim_frac) and np.isfinite(sim_n) else -np.inf)
    return not worse(eq_ll, s) and not worse(sim_ll, s)


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
    sim_rms_history: list[float] = field(default_factory=list)
    sims: list[np.ndarray] = field(default_factory=list)
    #: Sensor-noise floor of the baseline's equation error per equation, N.m (:func:`noise_images`).
    floor: dict[str, float] = field(default_factory=dict)
    #: Floor of the simulation error, rad at the output: ``noise`` (:func:`noise_images`),
    #: ``integration`` (:func:`integration_image`), ``total`` (both in quadrature).
    sim_floor: dict[str, float] = field(default_factory=dict)
    #: Remarks on the log and the run (e.g. a biased baseline), one line each.
    notes: list[str] = field(default_factory=list)
    #: The log's signal set (``both``, ``motor``, ``output``) and, per effect, whether it can
    #: show it (:func:`hdservo.discrepancy.identifiability`).
    angles: str = "both"
    identifiability: dict[str, str] = field(default_factory=dict)
    #: Parts of a ranked effect the baseline cannot tell from its own terms, effect -> part
    #: -> why (:func:`hdservo.discrepancy.not_identifiable_parts`: a Coulomb asymmetry next
    #: to a constant offset).
    not_identifiable_parts: dict[str, dict[str, str]] = field(default_factory=dict)
    #: Share of the baseline's weighted equation-error sum of squares that is its mean
    #: (:func:`hdservo.discrepancy.regression.constant_share`).
    base_constant_share: float = 0.0

    def named_by_size(self) -> list[str]:
        """The kept names, largest first by their share of the baseline's equation-error
        variance in the final model (``iterations[i].explained_share``,
        :func:`explained_shares`); the naming order breaks ties."""
        share = {it["named_effect"]: it.get("explained_share") or 0.0 for it in self.iterations}
        return sorted(self.named, key=lambda e: -share.get(e, 0.0))

    def to_json(self) -> dict[str, Any]:
        # JSON has no inf/NaN: a figure that does not exist (a biased baseline's simulation
        # error) is null
        return json_ready({"baseline": self.baseline, "baseline_relative_error_pct": self.base_rel_pct,
                "baseline_constant_share": self.base_constant_share, "iterations": self.iterations, "named_effects": self.named,
                "named_by_size": self.named_by_size(), "final_model": self.final_model, "residual_unit": "N.m at the motor (N for a linear axis)",
                "rms_history": self.rms_history, "sim_rms_history_rad": self.sim_rms_history,
                "sim_signal": SIM_TEXT, "first_ranking": self.ranking_first,
                "last_ranking": self.ranking_last,
                "final_whiteness": self.whiteness, "noise_floor": self.floor,
                "sim_floor_rad": self.sim_floor, "notes": list(self.notes),
                "signals": self.angles, "identifiability": dict(self.identifiability),
                "not_identifiable": [e for e, v in self.identifiability.items() if v != "identifiable"],
                "not_identifiable_parts": {e: dict(v) for e, v in self.not_identifiable_parts.items()}})


SIGNAL_TEXT = ("equation error of the measured motor torque (motor and rigid-body equations stacked), "
               "parallel low-pass filtered and decimated, moving samples only; RMS in N.m at the motor "
               "(N for a linear axis)")


#: Baseline parameters that must come out positive for the model to be a mechanical axis
#: (an inertia or a stiffness <= 0 is a log that does not excite what the model needs).
POSITIVE_PARAMS = ("J", "J_m_kgm2", "J_l_kgm2", "K_Nm_per_rad")


def unphysical(params: dict[str, float]) -> list[str]:
    """The inertias and stiffness fitted <= 0 (:data:`POSITIVE_PARAMS`), as "name = value"."""
    return [f"{k} = {params[k]:.3g}" for k in POSITIVE_PARAMS if k in params and not params[k] > 0]


def is_physical(params: dict[str, float]) -> bool:
    """Every inertia and the stiffness fitted > 0: a mechanical axis."""
    return not unphysical(params)


def check_physical(params: dict[str, float], d: bl.Design, library_tried: bool = False) -> None:
    """Refuse a baseline that is not a mechanical axis (one error line, what and why).

    Every residual, simulation and named effect afterwards would be measured against a
    model with a negative inertia or spring (its window simulation diverges), so there is
    nothing to report but that the log cannot identify the baseline.  :func:`run` calls
    it only when no single effect of the library makes the model a mechanical axis either
    (a missing effect can bias the baseline that far: see there).

    Raises
    ------
    UserError
        An inertia or the stiffness fitted <= 0.
    """
    bad = unphysical(params)
    if bad:
        from ..errors import UserError
        sig = d.sig
        why = " and no single effect of the library makes it one" if library_tried else ""
        raise UserError(f"{sig.source}: the baseline fit is not a mechanical axis ({', '.join(bad)}; expected > 0){why}: "
                        f"{int(d.mask.sum())} moving samples over {sig.t[-1] - sig.t[0]:.2f} s do not excite "
                        "it enough -- record a longer or richer motion (docs/discrepancy.md, Input)")


def encoder_zero_offset(d: bl.Design, cols: list[bl.Column]) -> float | None:
    """The twist offset of a two-encoder log whose encoders' zeros differ, rad at the output, or None.

    The twist phi = theta_m / N - theta_l is only measured up to the encoders' relative
    zero: a motor encoder offset of a fraction of a turn, or a recording that does not
    know the motor's whole turns, puts a constant phi0 into it (0.3 motor turn on N = 100:
    0.019 rad, forty times a real twist), and the baseline's spring K phi then fits
    nonsense (K = 44 instead of 3.1e4 N.m/rad).  The baseline is fitted once more with a
    constant in the spring's (motor) equation, K (phi - phi0) / N; phi0 is returned only
    when that constant torque, K |phi0| / N at the motor, exceeds every torque the motor
    applied in the log -- a spring preload no motion of the log could have put there, so
    not a twist.  A real preload (gravity, friction held in the gear) is bounded by the
    applied torque, so on logs whose encoders agree this returns None and nothing changes;
    a small zero offset (below that bound) is not detected (docs/discrepancy.md, Input).
    ``cols``: the baseline's columns of ``d``.
    """
    if d.sig.kind != "two_mass":
        return None
    c0 = bl.Column("twist_offset", np.ones_like(d.sig.tau), None)
    f = bl.solve(d, [*cols, c0], {})
    p = f.params()
    K, a = p.get("K_Nm_per_rad", 0.0), p["twist_offset"]
    if not K > 0 or abs(a) <= float(np.max(np.abs(d.sig.tau))):
        return None
    return float(-a * d.sig.ratio / K)


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
    s = (settings or Settings()).for_signals(sig.angles)
    lib = lib if lib is not None else fx.library()
    # never name what the log's signals cannot show (the identifiability table)
    ident = identifiability(sig.angles)
    lib = [e for e in lib if ident[e.name] == "identifiable"]
    sig, d, cols, zero_note = _prepare(sig, offset)
    st_ = State.start(d, cols)
    base_fit = st_.fit
    baseline = base_fit.params()
    # A missing effect can bias the baseline into a negative inertia or spring (held-out
    # CSF-14-30 axis, closed loop, fc_neg = 0.5 fc_pos: the unmodelled direction offset
    # drives J_m to -8e-8 kg.m^2; with the asymmetry's columns it is 1.7e-5, plant 1.5e-5).
    # Such a model cannot be simulated, so the first effect is then ranked and named on the
    # equation error alone, among the effects whose fit is a mechanical axis; only if none
    # is significant is the log refused (check_physical).
    biased = not is_physical(baseline)
    base_rel = relative_error_pct(st_)
    path = _name_effects(st_, lib, s)
    white = ljung_box(next(iter(st_.fit.resid.values())))
    floor, sim_floor, imgs_sim = _model_floors(st_, path)
    for k, it in enumerate(path.iterations):
        _gap_figures(st_, path, k, imgs_sim, floor)
    for it, share in zip(path.iterations, explained_shares(st_, base_fit)):
        it["explained_share"] = share
    notes = [zero_note] if zero_note else []
    const_share = bl.constant_share(base_fit, st_.weights)
    if const_share >= CONSTANT_NOTE_SHARE:
        held = "offset" in getattr(d, "_fixed_names", set())
        notes.append(f"the baseline's equation error is {100 * const_share:.0f} % a constant "
                     f"({bl.residual_mean(base_fit):.3g} {sig.units.get('torque', 'N.m')} at the motor"
                     + ("; the torque while moving differs from the offset held at the standstill torque" if held else "")
                     + "): an effect that cannot make up a constant (a gravity unbalance) is sized against it, and one "
                     "much smaller than that constant goes unnamed")
    if biased:
        notes.append(f"the baseline fit is not a mechanical axis ({', '.join(unphysical(baseline))}): it cannot be simulated, so "
                     f"{path.iterations[0]['named_effect']} was named on the equation error alone (its simulation-error "
                     "figures before are null)")
    final = {"structure": sig.kind, "params": st_.fit.params(),
             "relative_error_pct": relative_error_pct(st_),
             "effects": {it["named_effect"]: it["params"] for it in path.iterations}}
    return Result(baseline=baseline, iterations=path.iterations, named=[i["named_effect"] for i in path.iterations],
                  final_model=final, rms_history=path.rms, state=st_, base_fit=base_fit, snapshots=path.snapshots,
                  ranking_last=path.last_rank, whiteness=white, base_rel_pct=base_rel,
                  ranking_first=path.first_rank or [], sim_rms_history=path.sim_rms, sims=path.sims, floor=floor,
                  sim_floor=sim_floor, notes=notes, angles=sig.angles, identifiability=ident,
                  not_identifiable_parts=not_identifiable_parts(sig.kind, offset), base_constant_share=const_share)


def explained_shares(st_: State, base_fit: bl.Fit) -> list[float]:
    """Per added effect (in naming order), its share of the baseline's weighted
    equation-error variance in the final model: the rise of the weighted RSS when that
    effect alone is taken out of the final model (the rest re-fitted), over the
    baseline's weighted RSS.  A name's share in the model it was named in depends on what
    was named before it; this one does not, so two effects are ordered by it."""
    assert st_.fit is not None
    from dataclasses import replace
    out = []
    for i in range(len(st_.added)):
        without = replace(st_, added=st_.added[:i] + st_.added[i + 1:]).solve()
        out.append(max(0.0, (without.rss_w - st_.fit.rss_w) / max(base_fit.rss_w, 1e-300)))
    return out


def _prepare(sig: Signals, offset: bool | None) -> tuple[Signals, bl.Design, list[bl.Column], str | None]:
    """The regression design and baseline columns of a log, the encoders' zeros reconciled.

    Refuses a log with fewer than 50 moving samples.  When the encoders' zeros differ
    (:func:`encoder_zero_offset`) the twist offset is removed from the motor angle and
    the design rebuilt; the note says so (None otherwise).
    """
    d = bl.make_design(sig)
    if int(d.mask.sum()) < 50:
        from ..errors import UserError
        raise UserError(f"{sig.source}: fewer than 50 moving samples after filtering; the axis hardly moves")
    zero_note = None
    cols = bl.baseline_columns(d, offset)
    phi0 = encoder_zero_offset(d, cols)
    if phi0 is not None:
        from dataclasses import replace
        shift = sig.ratio * phi0
        sig = replace(sig, th_m=sig.th_m - shift, raw_th_m=sig.raw_th_m - shift)
        d = bl.make_design(sig)
        cols = bl.baseline_columns(d, offset)
        zero_note = (f"the encoders' zeros differ: the measured twist carries a constant {phi0:.4g} rad (output) that "
                     "no spring can (it would hold more torque than the motor ever applied); removed from the motor "
                     "angle before the fit")
    # the fitted baseline columns (a fixed standstill offset does not take up a Coulomb asymmetry)
    d._baseline_names = {c.name for c in cols if c.fixed is None}  # type: ignore[attr-defined]
    # and the ones held fixed (a rigid baseline's standstill offset)
    d._fixed_names = {c.name for c in cols if c.fixed is not None}  # type: ignore[attr-defined]
    return sig, d, cols, zero_note


#: Where a named effect acts: equation-error rows, simulation-error samples, its variant, speed bands.
Region = tuple[np.ndarray, np.ndarray, fx.Variant, "dict[str, float] | None"]


@dataclass
class _Path:
    """The models along the way: the baseline (index 0), then one per named effect."""

    snapshots: list[bl.Fit]
    rms: list[float]
    sim_rms: list[float]
    sims: list[np.ndarray]
    iterations: list[dict[str, Any]] = field(default_factory=list)
    regions: list[Region] = field(default_factory=list)
    first_rank: list[dict[str, Any]] | None = None
    last_rank: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def start(cls, st_: State) -> "_Path":
        assert st_.fit is not None
        return cls(snapshots=[st_.fit], rms=[st_.fit.rms], sim_rms=[_rms(st_.sim)], sims=[st_.sim])


def _ranking_json(ranked: list[Candidate], s: Settings, later: bool = False) -> list[dict[str, Any]]:
    """The ranking as reported (effect, evidence, hyper-parameters, significant)."""
    return [json_ready({"effect": c.effect.name, **c.evidence, "hyper": c.variant.hyper,
                        "significant": significant(c, s, later)}) for c in ranked]


def choose(ranked: list[Candidate], s: Settings, later: bool) -> Candidate | None:
    """The candidate a round names: the best-ranked one that passes :func:`significant` at
    ``s.frac_min``; for a ``later`` name, when none does, the best-ranked one significant in
    both residuals at ``s.frac_min_later``.  The larger effects are named first: a
    candidate at the later size never goes before one at ``frac_min`` (calibration seed
    163: a spurious current-loop lag at 28 % ahead of the hidden cogging at 76 % changes
    the cogging's fit, and the simulator drops both)."""
    top = next((c for c in ranked if significant(c, s)), None)
    if top is None and later:
        top = next((c for c in ranked if significant(c, s, later=True)), None)
    return top


def _name_effects(st_: State, lib: list[fx.Effect], s: Settings) -> _Path:
    """Rank the library, name the best significant effect, add it; repeat until none is
    significant, the residual is white or ``s.max_iter`` effects are named.  After the
    first name, a round in which no candidate reaches ``s.frac_min`` names the best one
    significant in both residuals at ``s.frac_min_later`` (:func:`significant`): the
    larger effects are named first.

    A model that is not a mechanical axis is ranked on the equation error alone; if then
    no effect is significant the log is refused (:func:`check_physical`).
    """
    path = _Path.start(st_)
    for _ in range(s.max_iter):
        eq_only = not is_physical(st_.fit.params())
        ranked = rank(st_, lib, s, simulate=not eq_only)
        later = bool(st_.added)
        path.last_rank = _ranking_json(ranked, s, later)
        if path.first_rank is None:
            path.first_rank = path.last_rank
        top = choose(ranked, s, later)
        if top is None:
            if eq_only:
                check_physical(st_.fit.params(), st_.design, library_tried=True)
            break
        runner = next((c for c in ranked if c is not top), None)
        it, region = _add_effect(st_, refit_named(st_, top, s), runner)
        path.iterations.append(it)
        path.regions.append(region)
        path.snapshots.append(st_.fit)
        path.rms.append(st_.fit.rms)
        path.sim_rms.append(_rms(st_.sim))
        path.sims.append(st_.sim)
        wm = ljung_box(next(iter(st_.fit.resid.values())))
        if wm["p_value"] > s.whiteness_p:
            break
    return path


def _add_effect(st_: State, top: Candidate, runner: Candidate | None) -> tuple[dict[str, Any], Region]:
    """Add the named effect to the model (re-fit, re-simulate); its iteration record (the
    figures before and after, overall and where it acts) and its region."""
    rms_before = st_.fit.rms
    rel_before = relative_error_pct(st_)
    sim_before = _rms(st_.sim)
    eq_before = _eq_rms(st_.fit, top.variant)
    bands = top.effect.region_bands(st_.design, top.variant)
    reg_eq = _eq_region_rows(st_.design, top.variant, bands)
    reg_sim = region_mask(st_.design, bands)
    loc_before = (_region_rms(st_.design, st_.fit, top.variant, reg_eq), _masked_rms(st_.sim, reg_sim))
    st_.added.append((top.effect, top.variant))
    st_.fit = st_.solve()
    st_.sim = st_.simulate(st_.fit)
    loc_after = (_region_rms(st_.design, st_.fit, top.variant, reg_eq), _masked_rms(st_.sim, reg_sim))
    it = {
        "named_effect": top.effect.name,
        "evidence": {**json_ready(top.evidence), "runner_up": runner.effect.name if runner else None,
                     "runner_up_delta_bic": runner.evidence["delta_bic"] if runner else None,
                     "runner_up_total_delta_bic": json_ready(runner.evidence.get("total_delta_bic")) if runner else None,
                     "runner_up_score": json_ready(runner.evidence.get("score")) if runner else None},
        "rms_before": rms_before, "rms_after": st_.fit.rms, "signal": SIGNAL_TEXT,
        "acting_equations": _acting(top.variant, st_.design),
        "rms_acting_before": eq_before, "rms_acting_after": _eq_rms(st_.fit, top.variant),
        "model_sim_rms_before_rad": sim_before, "model_sim_rms_after_rad": _rms(st_.sim),
        # the same figures over the region where the effect acts (local_evidence)
        "region": {"speed_bands": bands, "equation_share": float(reg_eq.mean()) if len(reg_eq) else 0.0,
                   "simulation_share": float(reg_sim.mean()) if len(reg_sim) else 0.0},
        "rms_region_before": loc_before[0], "rms_region_after": loc_after[0],
        "sim_rms_region_before_rad": loc_before[1], "sim_rms_region_after_rad": loc_after[1],
        "relative_error_pct_before": rel_before, "relative_error_pct_after": relative_error_pct(st_),
        "params": json_ready(top.effect.params(st_.fit, top.variant)),
        "signature": top.effect.signature, "coordinate": top.effect.coordinate,
    }
    return it, (reg_eq, reg_sim, top.variant, bands)


def _model_floors(st_: State, path: _Path) -> tuple[dict[str, float], dict[str, float],
                                                    list[tuple[np.ndarray, np.ndarray]]]:
    """The log's noise floors and every model's floor images.

    What no change of a model removes from its residuals (the sensor noise's image and,
    in the simulation error, the integration error) is a property of that model: an
    added effect can bring a noise source of its own (a rigid model's compliance column
    carries the load encoder's twice-differentiated noise). So every model along the
    way (baseline, then each added effect) gets its own floor, the before-figure of an
    iteration is judged against the model before it, the after-figure against the model after.

    Returns
    -------
    floor, sim_floor, images
        The equation error's floor per equation (N.m) and the simulation error's floor
        (``noise``, ``integration``, ``total``, rad) of the baseline, or of the first model
        that is a mechanical axis when the baseline is biased; per model, the equation
        error's floor image and the simulation error's (noise and integration in quadrature).
    """
    n_used = int(st_.design.mask.sum())
    imgs = [model_floor_images(st_, f, st_.added[:k], path.sims[k]) for k, f in enumerate(path.snapshots)]
    physical = [k for k, f in enumerate(path.snapshots) if is_physical(f.params())]
    k0 = physical[0] if physical else 0
    img_eq0, img_n0, img_i0 = imgs[k0]
    floor = {e: _rms(img_eq0[i * n_used:(i + 1) * n_used]) for i, e in enumerate(st_.design.equations)}
    sim_floor = {"noise": _rms(img_n0), "integration": _rms(img_i0), "total": _rms(np.sqrt(img_n0 ** 2 + img_i0 ** 2))}
    imgs_sim = [(e, np.sqrt(n ** 2 + i ** 2)) for e, n, i in imgs]
    return floor, sim_floor, imgs_sim


def _gap_figures(st_: State, path: _Path, k: int, imgs_sim: list[tuple[np.ndarray, np.ndarray]],
                 floor: dict[str, float]) -> None:
    """Iteration ``k``'s noise floors and systematic gaps before and after (overall, and
    where the effect acts in both residuals; a banded effect's simulation gap on short
    windows in its band, :func:`band_sim_figures`) and its :func:`rms_gap`, into its record."""
    it = path.iterations[k]
    reg_eq, reg_sim, v, bands = path.regions[k]
    n_used = int(st_.design.mask.sum())
    acting = set(_acting(v, st_.design))
    eqs = [e for e in it["acting_equations"] if e in floor] or list(floor)
    for when, (img_eq, img_sim), rms_act, rms_eq, rms_sim in (
            ("before", imgs_sim[k], it["rms_acting_before"], it["rms_region_before"], it["sim_rms_region_before_rad"]),
            ("after", imgs_sim[k + 1], it["rms_acting_after"], it["rms_region_after"], it["sim_rms_region_after_rad"])):
        per_eq = {e: _rms(img_eq[i * n_used:(i + 1) * n_used]) for i, e in enumerate(st_.design.equations)}
        fl = float(np.sqrt(np.mean([per_eq[e] ** 2 for e in eqs])))
        it[f"noise_floor_acting_{when}"] = fl
        it[f"gap_acting_{when}"] = systematic_gap(rms_act, fl)
        # the same over the region where the effect acts, both residuals (rms_gap)
        img_act = np.concatenate([img_eq[i * n_used:(i + 1) * n_used]
                                  for i, e in enumerate(st_.design.equations) if e in acting])
        fl_eq, fl_sim = _masked_rms(img_act, reg_eq), _masked_rms(img_sim, reg_sim)
        it[f"noise_floor_eq_region_{when}"] = fl_eq
        it[f"noise_floor_sim_region_{when}_rad"] = fl_sim
        it[f"gap_eq_{when}"] = systematic_gap(rms_eq, fl_eq)
        it[f"gap_sim_{when}"] = systematic_gap(rms_sim, fl_sim)
        it[f"sim_rms_gap_region_{when}_rad"] = rms_sim
    it["sim_gap_horizon_s"] = simerr.HORIZON_S
    if bands is not None:
        # a banded effect's simulation-error gap: short windows in its band (band_sim_figures)
        it["sim_gap_horizon_s"] = BAND_GAP_HORIZON_S
        for when, j in (("before", k), ("after", k + 1)):
            rms_b, fl_b = band_sim_figures(st_, path.snapshots[j], st_.added[:j], bands)
            it[f"sim_rms_gap_region_{when}_rad"] = rms_b
            it[f"noise_floor_sim_region_{when}_rad"] = fl_b
            it[f"gap_sim_{when}"] = systematic_gap(rms_b, fl_b)
    it["rms_gap"] = json_ready(rms_gap(it))


SIM_TEXT = ("simulation error: the model driven by the measured torque from the measured state over 50 ms "
            "windows, each side of a two-mass model with the other side's measured angle; RMS of the "
            "simulated minus measured angle, rad at the output (m for a linear axis)")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


def _acting(v: fx.Variant, d: bl.Design) -> list[str]:
    """Equations the variant's columns occupy (all of them for a torque replacement)."""
    if v.tau is not None or not v.columns:
        return list(d.equations)
    return [e for e in d.equations if any(getattr(c, e) is not None for c in v.columns)]


def _eq_region_rows(d: bl.Design, v: fx.Variant, bands: dict[str, float] | None) -> np.ndarray:
    """Rows of the equations the variant acts in, stacked, where the gap is measured.

    An effect with a speed band (Stribeck friction) is measured in its band
    (:func:`eq_region`), stops and reversals included: that is where it acts.  An effect
    that acts over the whole record is measured away from velocity reversals
    (:func:`hdservo.discrepancy.regression.away_from_reversals`): the static friction's
    stick transient there is outside the library and would be counted as a gap no such
    effect can close (all rows if none is away from a reversal)."""
    n = int(d.mask.sum())
    away = bl.away_from_reversals(d) if bands is None else None
    rows = np.tile(away, len(d.equations)) if away is not None and away.any() else eq_region(d, bands)
    acting = set(_acting(v, d))
    return np.concatenate([rows[i * n:(i + 1) * n] for i, e in enumerate(d.equations) if e in acting])


def _region_rms(d: bl.Design, fit: bl.Fit, v: fx.Variant, rows: np.ndarray) -> float:
    """RMS of the equation error over the acting equations' region rows, N.m at the motor."""
    acting = set(_acting(v, d))
    r = np.concatenate([fit.resid[e] for e in d.equations if e in acting])
    return _masked_rms(r, rows)


def _masked_rms(x: np.ndarray, m: np.ndarray) -> float:
    return _rms(x[m]) if len(m) == len(x) and m.any() else float("nan")


def _eq_rms(fit: bl.Fit, v: fx.Variant) -> float:
    """RMS of the equation error over the equations where an effect acts, N.m at the motor."""
    eqs = [e for e in fit.resid if e in {"M", "R"}]
    cols_eq = [e for e in eqs if v.tau is not None or not v.columns or any(getattr(c, e) is not None for c in v.columns)]
    return _rms(np.concatenate([fit.resid[e] for e in (cols_eq or eqs)]))


def _model_on(state: State, d: bl.Design | None, added: list[tuple[fx.Effect, fx.Variant]]
              ) -> tuple[list[bl.Column], np.ndarray | None, str]:
    """Columns and input torque of the model ``base + added``: the state's own (``d`` None,
    the log's signals) or built again from ``d``'s signals."""
    if d is None:
        base, vs = list(state.base_cols), [v for _, v in added]
    else:
        base = bl.baseline_columns(d, any(c.name.startswith("offset") for c in state.base_cols))
        vs = [e.rebuild(d, v) for e, v in added]
    tau, key = torque_of(vs)
    return base + [c for v in vs for c in v.columns], tau, key


def noise_images(state: State, fit: bl.Fit, seed: int = 0, added: list[tuple[fx.Effect, fx.Variant]] | None = None,
                 sim0: np.ndarray | None = None, simulate: bool = True, horizon_s: float = simerr.HORIZON_S,
                 substeps: int | None = None, phase: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Change of both residuals of one model that the sensor noise alone causes (noise injection).

    Each raw sensor signal (motor and load angle, torque) gets white noise of its own
    level (:func:`hdservo.discrepancy.signals.hf_noise_std`: the content above the
    angle cutoff and above fs/4, where the motion and the loops have none), the states
    and **every column of the model** (baseline and added effects, with the same
    hyper-parameters: :meth:`hdservo.discrepancy.effects.Effect.rebuild`) are rebuilt
    through the same filter/differentiation/decimation, and both residuals of ``fit``'s
    coefficients are recomputed.  For a pipeline linear in the noise (the inertia,
    spring, damping, viscous and torque terms; the sign columns are smoothed over the
    noise band) the RMS of the change equals the RMS the log's own noise adds.  The
    model matters: an added effect can carry a noise source of its own (the compliance
    column of a rigid model brings the load encoder's twice-differentiated noise; a
    current-loop lag filters the torque's).

    Parameters
    ----------
    state : State
    fit : Fit
        The model's fit (its coefficients, fixed ones included).
    seed : int
    added : list of (Effect, Variant), optional
        The model's added effects (default: none, the baseline).
    sim0 : numpy.ndarray, optional
        The model's simulation error on the log's own signals, if already computed.
    simulate : bool
        False: the equation error's image only (a model that is not a mechanical axis
        cannot be simulated); ``sim`` is then empty.
    horizon_s, substeps, phase : float, int, int
        The simulation error's windows, sub-steps and window phase (:func:`simulation_error`).

    Returns
    -------
    eq : numpy.ndarray
        Change of the stacked equation error (every equation, used rows), N.m at the motor.
    sim : numpy.ndarray
        Change of the simulation error (aligned with :func:`simulation_error`), rad at
        the output: the image of the noise at the window starts (the initial state) and
        of the torque noise integrated over the window.
    """
    d = state.design
    sig = d.sig
    added = added or []
    rng = np.random.default_rng(seed)
    noisy = sig_noisy(sig, rng)
    dn = bl.Design(sig=noisy, v_eps=d.v_eps, mask=d.mask, equations=d.equations)
    coef = dict(zip(fit.names, fit.theta))
    cols0, tau0, key0 = _model_on(state, None, added)
    colsn, taun, keyn = _model_on(state, dn, added)
    diff = dn.lhs(noisy.tau if taun is None else taun, keyn) - d.lhs(sig.tau if tau0 is None else tau0, key0)
    for c0, cn in zip(cols0, colsn):
        a = coef.get(c0.name, 0.0)
        diff = diff - a * (dn.stack(cn) - d.stack(c0))
    if not simulate:
        return diff, np.zeros(0)
    th = np.array([coef.get(c.name, 0.0) for c in cols0])
    e0 = simulation_error(d, cols0, th, tau0, key0, horizon_s, substeps, phase) if sim0 is None else sim0
    e1 = simulation_error(dn, colsn, th, taun, keyn, horizon_s, substeps, phase)
    sim = e1 - e0 if len(e1) == len(e0) else np.full(len(e0), np.nan)
    return diff, sim


def integration_image(state: State, fit: bl.Fit, added: list[tuple[fx.Effect, fx.Variant]] | None = None,
                      sim0: np.ndarray | None = None) -> np.ndarray:
    """The window simulation's own integration error for one model, rad at the output
    (aligned with :func:`simulation_error`).

    The Euler/Karnopp integration at :data:`simerr.SUBSTEPS` sub-steps is not converged
    (null logs: most of the baseline's simulation error is this error, docs/discrepancy.md);
    its error is estimated as the difference from an ``INTEGRATION_REF`` times
    finer integration of the model ``base + added`` with ``fit``'s coefficients (32
    sub-steps: within 5 % of 64 on the null logs).  Like the sensor noise it is not
    caused by the model mismatch and no effect removes it.  ``sim0``: the model's
    simulation error at the usual sub-steps, if already computed.
    """
    d = state.design
    coef = dict(zip(fit.names, fit.theta))
    cols, tau, key = _model_on(state, None, added or [])
    th = np.array([coef.get(c.name, 0.0) for c in cols])
    e_s = simulation_error(d, cols, th, tau, key) if sim0 is None else sim0
    e_f = simulation_error(d, cols, th, tau, key, substeps=INTEGRATION_REF * simerr.SUBSTEPS)
    if len(e_s) != len(e_f):
        return np.full(len(e_s), np.nan)
    with np.errstate(invalid="ignore"):                 # inf - inf of a diverging window: nan, judged later
        return e_s - e_f


#: Refinement factor of the reference integration of :func:`integration_image`.
INTEGRATION_REF = 8


def model_floor_images(state: State, fit: bl.Fit, added: list[tuple[fx.Effect, fx.Variant]],
                       sim0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What no change of one model removes from its residuals, per sample.

    Returns
    -------
    eq : numpy.ndarray
        The sensor noise's image in the stacked equation error, N.m at the motor.
    noise, integration : numpy.ndarray
        The sensor noise's image and the integration error in the simulation error
        (independent sources: they add in quadrature), rad at the output; NaN for a model
        that is not a mechanical axis (it cannot be simulated).
    """
    if not is_physical(fit.params()):
        img_eq, _ = noise_images(state, fit, added=added, simulate=False)
        nan = np.full(len(state.sim) if state.sim is not None else 0, np.nan)
        return img_eq, nan, nan
    img_eq, img_noise = noise_images(state, fit, added=added, sim0=sim0)
    return img_eq, img_noise, integration_image(state, fit, added, sim0)


#: Window of a banded effect's simulation-error gap (:func:`band_sim_figures`), s: about
#: the median dwell in a Stribeck band (0.3-14 ms on the logs measured).
BAND_GAP_HORIZON_S = 0.01
#: Window phases pooled by :func:`band_sim_figures` (starts 0, H/4, H/2, 3H/4).
BAND_GAP_PHASES = 4


def band_sim_figures(state: State, fit: bl.Fit, added: list[tuple[fx.Effect, fx.Variant]],
                     bands: dict[str, float]) -> tuple[float, float]:
    """RMS and floor of one model's simulation error where a banded effect acts, rad at the output.

    An effect with a speed band (Stribeck friction: below 3 vs) acts while a side dwells
    in the band, at stops and reversals: a few ms to a few tens of ms (csf17_50 closed
    loop s3: median 6 ms, upper quartile 31 ms).  A 50 ms window that starts there spends
    most of its length outside the band, where the simulated breakaway's timing (a
    chaotic stick-slip, docs/discrepancy.md) decides the error, not the
    friction law.  So its gap is measured on windows of ``BAND_GAP_HORIZON_S`` starting in
    the band (:func:`region_mask`), integrated at :data:`FINE_SUBSTEPS`, against the floor
    of the same windows: the sensor noise's image (:func:`noise_images`) and the
    integration error (difference from ``INTEGRATION_REF`` times finer integration), in
    quadrature.  The band holds a few stops (1.5 % of a closed-loop record), so one tiling
    of windows depends on where its edges fall relative to each breakaway (reference
    closed s3, one fit, one tiling: 4.8x at 10 ms, 2.4x at 20 ms, 4.0x at 50 ms): the squares of
    ``BAND_GAP_PHASES`` tilings shifted by H / phases are pooled (5.1x at 10 ms, 3.1x at
    20 ms).  NaN, NaN for a model that is not a mechanical axis.
    """
    if not is_physical(fit.params()):
        return float("nan"), float("nan")
    d, H, S = state.design, BAND_GAP_HORIZON_S, FINE_SUBSTEPS
    coef = dict(zip(fit.names, fit.theta))
    cols, tau, key = _model_on(state, None, added)
    th = np.array([coef.get(c.name, 0.0) for c in cols])
    n_h = simerr.window_samples(d, H)
    sq_e = sq_f = 0.0
    count = 0
    for ph in sorted({int(round(i * n_h / BAND_GAP_PHASES)) for i in range(BAND_GAP_PHASES)}):
        e = simulation_error(d, cols, th, tau, key, horizon_s=H, substeps=S, phase=ph)
        e_f = simulation_error(d, cols, th, tau, key, horizon_s=H, substeps=INTEGRATION_REF * S, phase=ph)
        _, img_n = noise_images(state, fit, added=added, sim0=e, horizon_s=H, substeps=S, phase=ph)
        reg = region_mask(d, bands, horizon_s=H, phase=ph)
        if not (len(e) == len(e_f) == len(img_n) == len(reg)):
            return float("nan"), float("nan")
        with np.errstate(invalid="ignore", over="ignore"):
            sq_e += float(np.sum(e[reg] ** 2))
            sq_f += float(np.sum((e - e_f)[reg] ** 2 + img_n[reg] ** 2))
        count += int(reg.sum())
    if count == 0:
        return float("nan"), float("nan")
    return float(np.sqrt(sq_e / count)), float(np.sqrt(sq_f / count))


def rms_gap(it: dict[str, Any]) -> dict[str, Any]:
    """The RMS gap of a named effect (the 3x rule), one definition for every effect.

    The gap is the part of the residual the model mismatch causes: the systematic gap
    sqrt(RMS^2 - floor^2) (:func:`systematic_gap`), the floor being what no model
    removes -- the sensor noise's image (:func:`noise_images`) and, in the simulation
    error, the integration error (:func:`integration_image`), each through the model
    whose residual it is (before: the model without the effect, after: with it) --
    over the region where
    the effect acts (its own speed band for Stribeck friction, the whole record
    otherwise -- in the equation error away from velocity reversals,
    :func:`_eq_region_rows`) and, in the equation error, the equations it acts in.  Both residuals
    see the same mismatch; the gap is measured in the one the effect was named for:
    the one of which it explains the larger part over its region (in the equation error
    over the equations it acts in, ``explained_fraction_local_acting``: a spring effect
    acts in the motor equation only, and the rigid-body equation would dilute it;
    Stribeck friction: the simulation error, which sees the stops;
    a stiffness nonlinearity: usually the equation error).  An effect with a speed band
    has its simulation-error gap on short windows in the band (:func:`band_sim_figures`,
    ``sim_gap_horizon_s``).  Reads the iteration's ``evidence``, ``gap_eq_*`` /
    ``gap_sim_*`` and ``sim_rms_gap_region_*`` fields.

    Returns
    -------
    dict
        ``residual`` ("equation" or "simulation"), ``before``, ``after``, ``floor_before``,
        ``floor_after`` (N.m at the motor or rad at the output; ``floor`` = ``floor_after``,
        what the final residual is judged against), ``shrink`` (before/after; inf when the
        after-gap is at the floor, then ``closed`` is true), ``raw_shrink`` (the RMS
        before/after in that view).
    """
    views = {"equation": ("explained_fraction_local_acting", "gap_eq_before", "gap_eq_after",
                          "noise_floor_eq_region_before", "noise_floor_eq_region_after",
                          "rms_region_before", "rms_region_after"),
             "simulation": ("sim_explained_fraction_local", "gap_sim_before", "gap_sim_after",
                            "noise_floor_sim_region_before_rad", "noise_floor_sim_region_after_rad",
                            "sim_rms_gap_region_before_rad", "sim_rms_gap_region_after_rad")}
    ev = it.get("evidence", {})

    def part(v: tuple[str, ...]) -> float:
        x = ev.get(v[0])
        return float(x) if x is not None and np.isfinite(x) else -np.inf
    name = max(views, key=lambda k: part(views[k]))
    gb, ga, fb, fa, rb, ra = (it.get(k, np.nan) for k in views[name][1:])
    shrink = gb / ga if ga > 0 else (np.inf if gb > 0 else np.nan)
    return {"residual": name, "before": gb, "after": ga, "floor_before": fb, "floor_after": fa, "floor": fa,
            "shrink": shrink,
            "closed": bool(ga == 0.0 and gb > 0.0), "raw_shrink": rb / ra if ra > 0 else np.nan}


def sig_noisy(sig: "Signals", rng: np.random.Generator) -> "Signals":
    """A copy of the signals rebuilt from the raw logs plus white noise of each sensor's level."""
    from dataclasses import replace
    from .signals import hf_noise_std, states_of
    fs = 1.0 / sig.dt

    def add(x: np.ndarray) -> np.ndarray:
        return x + hf_noise_std(x, sig.fc_Hz, fs) * rng.standard_normal(len(x))
    th_m, w_m, a_m = states_of(add(sig.raw_th_m), sig.fc_Hz, sig.dt)
    kw: dict[str, Any] = {"th_m": th_m, "w_m": w_m, "a_m": a_m, "tau": add(sig.tau)}
    if sig.raw_th_l is not None and sig.th_l is not None:
        kw["th_l"], kw["w_l"], kw["a_l"] = states_of(add(sig.raw_th_l), sig.fc_Hz, sig.dt)
    return replace(sig, **kw)


def systematic_gap(rms: float, floor: float) -> float:
    """RMS of the residual's systematic part: sqrt(max(rms^2 - floor^2, 0)), same unit."""
    return float(np.sqrt(max(rms * rms - floor * floor, 0.0)))


def relative_error_pct(state: State) -> float:
    """100 ||tau - tau_model|| / ||tau|| over the used samples (the EMPS figure of merit), %."""
    assert state.fit is not None
    tau, key = state.tau()
    y = state.design.lhs(state.design.sig.tau if tau is None else tau, key)
    r = np.concatenate(list(state.fit.resid.values()))
    return float(100.0 * np.linalg.norm(r) / max(np.linalg.norm(y), 1e-300))
