"""Selection rules (hdservo.analysis.selection): recomputed on a tiny grid, and able to fail.

The hysteresis table is measured here on the simulated reference axis (one part-load and the
rated amplitude, one minor-loop width); every stated hysteresis rule must hold on it.  The
needs rules are checked on ``build/demo/ablation.json`` when ``make demo`` has written it.
Each rule is also shown to fail on a table where the measured ordering is reversed.
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from hdservo.analysis import selection as sel

ROOT = Path(__file__).parents[2]
ABLATION = ROOT / "build" / "demo" / "ablation.json"


@pytest.fixture(scope="module")
def hyst() -> list[sel.HysteresisRow]:
    return sel.hysteresis_table("reference", amplitudes=(0.3, 1.0), widths=(0.3,), levels=16, seed=11)


def test_hysteresis_rules_hold_on_a_tiny_grid(hyst: list[sel.HysteresisRow]) -> None:
    assert [r.note for r in hyst] == ["", ""]
    rules = sel.check_rules(hyst, None)
    assert len(rules) == len(sel.HYSTERESIS_RULES)
    for r in rules:
        assert r.holds, r.text


def test_hysteresis_table_is_consistent(hyst: list[sel.HysteresisRow]) -> None:
    for r in hyst:
        # the Preisach table image: header + CRC + L(L+1)/2 int32 entries
        assert r.memory_bytes["preisach"] >= 4 * 16 * 17 // 2
        assert r.parameters["preisach"] == 16 * 15 // 2
        assert r.experiment_s["preisach"] > 0 and r.experiment_s["maxwell"] > 0
        assert r.loop_width_arcsec is not None and r.loop_width_arcsec > 0
        # both models predict the twist far better than the loop is wide
        for m in ("maxwell", "preisach"):
            assert 0 < r.major_err_arcsec[m] < r.loop_width_arcsec


def _swap_models(rows: list[sel.HysteresisRow]) -> list[sel.HysteresisRow]:
    out = copy.deepcopy(rows)
    for r in out:
        for d in (r.major_err_arcsec, r.minor_err_arcsec, r.memory_bytes, r.experiment_s):
            d["maxwell"], d["preisach"] = d["preisach"], d["maxwell"]
    return out


def test_every_hysteresis_rule_fails_when_the_models_swap(hyst: list[sel.HysteresisRow]) -> None:
    for r in sel.check_rules(_swap_models(hyst), None):
        assert not r.holds, r.text


def test_rules_survive_the_json_document(hyst: list[sel.HysteresisRow]) -> None:
    doc = json.loads(json.dumps(sel.selection_doc(hyst, [], sel.cpu_costs(None))))
    assert [r.holds for r in sel.rules_from_doc(doc)] == [r["holds"] for r in doc["rules"]]
    assert all(v is None for v in doc["cpu_instructions"].values())


def _ablation_rows(gains: dict[str, float]) -> dict:
    """Ablation rows where compensator c divides every figure by gains[c] (for the failing case)."""
    figs = [f for f in sel.NEEDS.values() if f != "drift"]
    rows = [{"name": "pid", "feedback": "full-closed", "components": [], "ratio_to_baseline": {f: 1.0 for f in figs}}]
    rows += [{"name": c, "feedback": "full-closed", "components": [c],
              "ratio_to_baseline": {f: 1.0 / g for f in figs}} for c, g in gains.items()]
    return {"rows": rows}


def test_needs_rules_fail_when_hysteresis_models_win() -> None:
    needs = sel.needs_table(_ablation_rows({"stribeck": 1.1, "preisach": 3.0}), sel.cpu_costs(None))
    assert {n.need: n.compensator for n in needs if n.figure != "drift"} == {
        "pointing accuracy": "preisach", "low-speed smoothness": "preisach", "stabilisation": "preisach",
        "tracking": "preisach"}
    for r in sel.check_rules(None, needs):
        assert not r.holds, r.text


@pytest.mark.skipif(not ABLATION.is_file(), reason="build/demo/ablation.json: run make demo")
def test_needs_rules_hold_on_the_demo_ablation() -> None:
    needs = sel.needs_table(json.loads(ABLATION.read_text()), sel.cpu_costs(None))
    assert [n.need for n in needs] == list(sel.NEEDS)
    for r in sel.check_rules(None, needs):
        assert r.holds, r.text


def test_compare_summary_names_the_best_compensator_and_only_rules_that_hold() -> None:
    abl = _ablation_rows({"stribeck": 20.0, "lugre": 4.0, "preisach": 1.2})
    lines = sel.summary_lines(abl, {"stribeck": 301})
    assert "need pointing accuracy (full-closed): stribeck, 20x better than the fair PID; " \
           "301 M4 instructions/step; identification: gravity_sine, friction_sweep" in lines
    assert "need parameter drift (full-closed): not measured here" in lines
    rules = [ln for ln in lines if ln.startswith("rule: ")]
    assert len(rules) == 2 and all(r.holds for r in sel.check_rules(None, sel.needs_table(abl, {})))
    # a table on which the friction rule fails: the rule is not printed
    bad = sel.summary_lines(_ablation_rows({"stribeck": 1.5, "preisach": 1.2}), {})
    assert not any("friction feed-forward" in ln for ln in bad)
    assert sel.compare_lines({"controllers": {}}) == []


def _drift_doc(gains: dict[str, dict[str, float]]) -> dict:
    """A drift study document (58_drift_monte_carlo.py format) with the median gains given per
    scenario and controller on two figures (the second 10 % higher)."""
    figs = ["reversal_peak_arcsec", "positioning_A_arcsec"]
    return {"scenarios": ["nominal", *gains], "target": {"figures": figs},
            "gain": {"nominal": {c: {f: 5.0 for f in figs} for c in ("pid", "fixed", "online", "backstep")},
                     **{s: {c: {figs[0]: g, figs[1]: 1.1 * g} for c, g in row.items()}
                        for s, row in gains.items()}}}


def test_drift_row_comes_from_the_drift_study(tmp_path: Path) -> None:
    doc = _drift_doc({"friction_warm_cold": {"pid": 1.0, "fixed": 1.2, "online": 3.0, "backstep": 2.5},
                      "gravity_appears": {"pid": 1.0, "fixed": 4.0, "online": 2.2, "backstep": 0.5}})
    kept = sel.drift_gains(doc)
    # the worst drift scenario and figure of each compensator
    assert kept == pytest.approx({"stribeck": 1.2, "stribeck_online": 2.2, "backstep": 0.5})
    abl = _ablation_rows({"stribeck": 20.0})
    row = {n.need: n for n in sel.needs_table(abl, {"stribeck_online": 350}, drift=kept)}["parameter drift"]
    assert (row.compensator, row.gain, row.cpu_instructions, row.experiments) == ("stribeck_online", 2.2, 350, [])
    # one drift on which the online FF falls behind: backstepping becomes the row's answer
    doc["gain"]["gravity_appears"]["online"] = {f: 0.4 for f in doc["target"]["figures"]}
    doc["gain"]["gravity_appears"]["backstep"] = {f: 2.0 for f in doc["target"]["figures"]}
    row = {n.need: n for n in sel.needs_table(abl, {}, drift=sel.drift_gains(doc))}["parameter drift"]
    assert (row.compensator, row.gain) == ("backstep", 2.0)
    # the compare summary prints the measured row; without a study it says not measured here
    lines = sel.summary_lines(abl, {}, None, doc)
    assert any(ln.startswith("need parameter drift (full-closed): backstep, 2x kept under drift") for ln in lines)
    assert "need parameter drift (full-closed): not measured here" in sel.summary_lines(abl, {}, None, None)
    # the stored document round trip, and a missing or broken file
    p = tmp_path / "drift_mc.json"
    p.write_text(json.dumps(doc))
    assert sel.drift_gains(sel.load_drift(p)) == sel.drift_gains(doc)
    assert sel.load_drift(tmp_path / "none.json") is None
    (tmp_path / "bad.json").write_text("{")
    assert sel.load_drift(tmp_path / "bad.json") is None and sel.drift_gains(None) == {}


def test_cpu_cost_of_the_online_feed_forward_sums_its_kernels(tmp_path: Path) -> None:
    p = tmp_path / "cm4_cost.json"
    p.write_text(json.dumps({"kernels": {"comp_stribeck_step": {"instructions": 300},
                                         "fric_est_legs": {"instructions": 120}}}))
    c = sel.cpu_costs(p)
    assert c["stribeck"] == 300 and c["stribeck_online"] == 420 and c["lugre"] is None


def test_drift_rule_is_checked_on_the_measured_row_and_can_fail() -> None:
    abl = _ablation_rows({"stribeck": 20.0, "lugre": 4.0})
    good = _drift_doc({"gravity_appears": {"pid": 1.0, "fixed": 1.6, "online": 1.8, "backstep": 0.4}})
    rules = {r.name: r for r in sel.check_rules(None, sel.needs_table(abl, {}, drift=sel.drift_gains(good)))}
    assert rules["need_drift"].holds, rules["need_drift"].text
    assert "the online-identified one 1.80x" in rules["need_drift"].text
    # backstepping ahead of both feed-forwards, or the feed-forwards below 1.5x: the rule fails
    for row in ({"pid": 1.0, "fixed": 1.6, "online": 1.8, "backstep": 2.5},
                {"pid": 1.0, "fixed": 1.2, "online": 1.4, "backstep": 0.4}):
        bad = sel.needs_table(abl, {}, drift=sel.drift_gains(_drift_doc({"gravity_appears": row})))
        assert not {r.name: r for r in sel.check_rules(None, bad)}["need_drift"].holds
    # no drift study: the rule is not stated
    assert "need_drift" not in {r.name for r in sel.check_rules(None, sel.needs_table(abl, {}))}
