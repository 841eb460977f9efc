"""A later name's size rule: significant in both residuals, it needs only ``frac_min_later``.

The first name keeps the size threshold ``frac_min``; a name after it that is significant
in the equation error *and* in the simulation error is offered at ``frac_min_later``,
and the simulator's stop rule judges it (docs/discrepancy.md, "Later names").
Calibration logs only (never held-apart ones).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hdservo import logio
from hdservo.discrepancy import effects as fx
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_corpus as corpus

#: A calibration log (never a held-apart one): both encoders, a P-PI cascade, 1 kHz
#: logging, a 14-bit motor encoder; an unbalance at 1.50x and an asymmetric friction at
#: 0.84x their typical sizes.  The asymmetry is named first and takes part of what the
#: unbalance explains (both vary with the direction of a back-and-forth motion).
SEED = 187


def _candidate(size: float, eq_dbic: float, sim_dbic: float) -> workflow.Candidate:
    """A candidate with the evidence figures the rule reads (nothing else of it is used)."""
    ev = {"delta_bic": eq_dbic, "p_value": 1e-9 if eq_dbic > 10 else 0.5,
          "sim_delta_bic": sim_dbic, "sim_p_value": 1e-9 if sim_dbic > 10 else 0.5,
          "total_delta_bic": eq_dbic + sim_dbic, "n_eff": 4000.0, "sim_n_eff": 400.0,
          "explained_fraction": size, "sim_explained_fraction": size}
    return workflow.Candidate(effect=fx.Gravity(), variant=None, fit=None,  # type: ignore[arg-type]
                              evidence=ev)


def test_a_later_name_significant_in_both_residuals_needs_the_later_size() -> None:
    s = workflow.Settings(frac_min_by_signals={})
    assert s.frac_min_later < s.frac_min
    mid = 0.5 * (s.frac_min_later + s.frac_min)
    both = _candidate(mid, 100.0, 50.0)
    assert workflow.significant(both, s, later=True)
    # the first name keeps frac_min
    assert not workflow.significant(both, s, later=False)
    assert not workflow.significant(both, s)
    # significant in one residual only: frac_min for a later name too
    assert not workflow.significant(_candidate(mid, 100.0, 5.0), s, later=True)
    assert not workflow.significant(_candidate(mid, 5.0, 100.0), s, later=True)
    # below the later size: nothing
    assert not workflow.significant(_candidate(0.9 * s.frac_min_later, 100.0, 50.0), s, later=True)
    # at frac_min a candidate significant in one residual is named as before
    assert workflow.significant(_candidate(s.frac_min, 100.0, 5.0), s, later=True)


def test_a_candidate_at_frac_min_goes_before_one_at_the_later_size() -> None:
    s = workflow.Settings(frac_min_by_signals={})
    small = _candidate(0.5 * (s.frac_min_later + s.frac_min), 300.0, 50.0)    # ranked first
    large = _candidate(0.75, 200.0, 5.0)                                        # eq. error only
    assert workflow.choose([small, large], s, later=True) is large
    assert workflow.choose([small], s, later=True) is small
    # the first name: frac_min only
    assert workflow.choose([small], s, later=False) is None
    assert workflow.choose([small, large], s, later=False) is large


def test_the_unbalance_named_after_the_asymmetry_that_took_part_of_it(tmp_path: Path) -> None:
    case = corpus.draw(SEED)
    assert sorted(e for e, _ in case.hidden) == ["asymmetric_friction", "gravity_unbalance"]
    assert sorted(case.identifiable()) == ["asymmetric_friction", "gravity_unbalance"]
    sig = signals.from_log(logio.read_log(corpus.make_log(case, tmp_path / "l.csv"), require_tag=False),
                           case.structure)
    s = workflow.Settings(frac_min_by_signals={})
    res = workflow.run(sig, s)
    assert res.named[:2] == ["asymmetric_friction", "gravity_unbalance"]
    ev = res.iterations[1]["evidence"]
    # the unbalance is below frac_min against what the asymmetry left, above frac_min_later,
    # and significant in both residuals
    assert s.frac_min_later <= workflow.size(ev) < s.frac_min
    assert ev["delta_bic"] > s.bic_min and ev["sim_delta_bic"] > s.bic_min
    # so with one size threshold for every name it would stay unnamed; in the model it
    # lowers the equation error the asymmetry left
    assert not workflow.significant(workflow.Candidate(fx.Gravity(), None, None, ev), s)  # type: ignore[arg-type]
    assert np.isfinite(res.rms_history[2]) and res.rms_history[2] < res.rms_history[1]
