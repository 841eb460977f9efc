"""Two hidden effects: the workflow names one, refits with it in the model, looks again, and
orders the names by their share of the equation-error variance in the final model."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from hdservo import logio
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_corpus as corpus

#: A calibration log (never a held-apart one): both encoders, the drive's firmware at 1 kHz,
#: asymmetric friction at 1.13x and nonlinear stiffness at 0.77x their typical sizes.
SEED = 1


def test_two_effects_named_and_ordered_by_explained_variance(tmp_path: Path) -> None:
    case = corpus.draw(SEED)
    hidden = sorted(case.hidden, key=lambda eg: -eg[1])
    assert [e for e, _ in hidden] == ["asymmetric_friction", "nonlinear_stiffness"]
    p = corpus.make_log(case, tmp_path / "l.csv")
    res = workflow.run(signals.from_log(logio.read_log(p, require_tag=False), case.structure))
    assert set(res.named) == {"asymmetric_friction", "nonlinear_stiffness"}
    shares = {it["named_effect"]: it["explained_share"] for it in res.iterations}
    assert all(v > 0 for v in shares.values())
    # the larger hidden effect explains more and comes first
    assert res.named_by_size() == ["asymmetric_friction", "nonlinear_stiffness"]
    assert res.to_json()["named_by_size"] == res.named_by_size()
    # a share is the rise of the weighted residual when that effect alone is taken out
    st_ = res.state
    i = [e.name for e, _ in st_.added].index("nonlinear_stiffness")
    without = replace(st_, added=st_.added[:i] + st_.added[i + 1:]).solve()
    assert shares["nonlinear_stiffness"] == (without.rss_w - st_.fit.rss_w) / res.base_fit.rss_w
    # the second name is judged against what the first left: its explained fractions are
    # taken on the residuals of the model that already holds the first name, not on the
    # baseline's (where the first effect would make up most of the drop)
    ev = res.iterations[1]["evidence"]
    before, after = res.snapshots[1], res.snapshots[2]
    assert abs(ev["explained_fraction"] - (1 - after.rss_w / before.rss_w)) < 1e-9
    assert ev["explained_fraction"] < 1 - after.rss_w / res.base_fit.rss_w - 0.05
    sse = [float((s ** 2).sum()) for s in res.sims]
    assert abs(ev["sim_explained_fraction"] - (1 - sse[2] / sse[1])) < 1e-9
