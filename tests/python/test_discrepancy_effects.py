"""One hidden effect per simulator log: the workflow names it and the RMS gap shrinks >= 3x
(fast subset; the full confusion table is tests/results/40_discrepancy.py)."""
from __future__ import annotations

from pathlib import Path

import pytest

from hdservo import logio
from hdservo.discrepancy import signals, workflow
from oracles import discrepancy_cases as cases


@pytest.mark.parametrize("effect,axis,loop,seed", [
    ("transmission_error", "reference", "closed", 1),
    ("gravity_unbalance", "csf17_50", "open", 1),
])
def test_hidden_effect_is_named_and_gap_shrinks(tmp_path: Path, effect: str, axis: str, loop: str,
                                                seed: int) -> None:
    c = cases.Case(effect, axis=axis, loop=loop, seed=seed, size=seed % 2)
    p = cases.make_log(c, tmp_path / "l.csv")
    r = workflow.run(signals.from_log(logio.read_log(p), c.structure))
    assert r.named and r.named[0] == effect
    assert r.rms_history[0] / r.rms_history[-1] >= 3.0
    ev = r.iterations[0]["evidence"]
    assert ev["delta_bic"] > 10 and ev["p_value"] < 1e-3
    # the RMS gap of the 3x rule (workflow.rms_gap): systematic gap over the region where
    # the effect acts (here the whole record), in one of the two residuals
    it = r.iterations[0]
    g = it["rms_gap"]
    assert g["residual"] in ("equation", "simulation")
    assert g["closed"] or g["shrink"] >= 3.0
    fl = g["floor_before"]
    assert 0.0 < fl < g["before"]


def test_noise_level_ignores_the_loops_content_below_fs_over_4() -> None:
    """The sensor's white-noise level comes from the upper half of the spectrum: real
    current that a closed loop makes between the angle cutoff and ~1 kHz does not count
    as noise (the round-4 estimate above the cutoff alone counted it)."""
    import numpy as np
    import scipy.signal as sps

    from hdservo.discrepancy.signals import hf_noise_std
    fs, n = 1e4, 100_000
    rng = np.random.default_rng(3)
    white = 0.01 * rng.standard_normal(n)
    loop = sps.sosfiltfilt(sps.butter(4, [300, 900], btype="band", fs=fs, output="sos"), rng.standard_normal(n))
    x = white + 0.05 * loop / np.std(loop)
    assert hf_noise_std(white, 200.0, fs) == pytest.approx(0.01, rel=0.03)
    assert hf_noise_std(x, 200.0, fs) == pytest.approx(0.01, rel=0.05)


@pytest.mark.parametrize("effect,axis,loop,seed", [
    # cubic stiffening, open loop: the equation error's spikes at fast motor reversals
    # (static friction's stick transient, the same before and after) held the gap to
    # 1.8x over the whole record (round 5b); away from the reversals it is ~4x
    ("nonlinear_stiffness", "csf17_50", "open", 3),
    # Maxwell-slip hysteresis in closed loop, where the twist span is about twice an
    # element's slip twist: the 6-threshold grid (2-64 %, 2x apart) left 1.4x, the
    # 12-threshold grid (2-90 %, sqrt 2 apart) reaches ~7x
    ("hysteresis", "reference", "closed", 2),
    # Stribeck friction Fs = 2.2 Fc in closed loop: the ranking's sqrt(2) level grid gave
    # 1.0 Fc for the plant's 1.2 Fc and a 1.3x gap; the re-fit of the named effect
    # (workflow.refit_named) reaches ~5x (session 12: 10 ms band windows, 4.9x)
    ("stribeck_friction", "csf17_50", "closed", 5),
])
def test_named_effect_gap_shrinks_3x_where_round5b_missed(tmp_path: Path, effect: str, axis: str, loop: str, seed: int) -> None:
    c = cases.Case(effect, axis=axis, loop=loop, seed=seed, size=seed % 2)
    p = cases.make_log(c, tmp_path / "l.csv")
    r = workflow.run(signals.from_log(logio.read_log(p), c.structure))
    assert r.named and r.named[0] == effect
    g = r.iterations[0]["rms_gap"]
    assert g["closed"] or g["shrink"] >= 3.0, g


def test_each_model_is_judged_against_its_own_noise_floor(tmp_path: Path, monkeypatch) -> None:
    # Held-out CSF-14-30 axis, closed loop, rigid baseline, compliance hidden. The rigid
    # model's acceleration column carries only the motor encoder's noise; the compliance
    # column it gains, J_l (a_l - a_m/N)/N, carries the load encoder's twice-differentiated
    # noise, which then dominates the rigid-body equation. Judged against the baseline's
    # floor (before session 10) the residual of the right model looked like a 2.3x gap.
    axis = cases.REPO_ROOT / "tests" / "results" / "axes" / "csf14_30.toml"
    monkeypatch.setitem(cases.AXES, "csf14_30", str(axis))
    c = cases.Case("unmodelled_compliance", axis="csf14_30", loop="closed", seed=2, size=0)
    p = cases.make_log(c, tmp_path / "l.csv")
    r = workflow.run(signals.from_log(logio.read_log(p), c.structure))
    assert r.named[:1] == ["unmodelled_compliance"]
    it = r.iterations[0]
    g = it["rms_gap"]
    assert g["residual"] == "equation"
    assert g["floor_after"] > 2.0 * g["floor_before"]
    # the model with the compliance column is the plant's rigid-body equation: what is
    # left is that model's noise image, to within the floor's accuracy
    assert 0.8 < it["rms_region_after"] / g["floor_after"] < 1.2
    assert g["closed"] or g["shrink"] >= 3.0, g
    # against the baseline's floor the same residual would still hold a gap > before / 3
    assert workflow.systematic_gap(it["rms_region_after"], g["floor_before"]) > g["before"] / 3.0
