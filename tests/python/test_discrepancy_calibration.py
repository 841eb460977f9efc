"""Logic of the calibration run (tests/results/48_discrepancy_calibration.py) on tiny records,
and the simulator-closed loop's replay fit and quantisation floor
(hdservo.discrepancy.closeloop); the calibration set itself runs in `make results`."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from hdservo.discrepancy import closeloop as cl

REPO = Path(__file__).parents[2]


def _script():
    spec = importlib.util.spec_from_file_location("calib48", REPO / "tests" / "results" / "48_discrepancy_calibration.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def _rank(effect: str, size: float, significant: bool, dbic: float = 50.0) -> dict:
    return {"effect": effect, "size": size, "significant": significant, "total_delta_bic": dbic}


RECORDS = [
    {"hidden": ["cogging_torque"], "identifiable": ["cogging_torque"], "named": ["cogging_torque"], "angles": "both",
     "ranking_first": [_rank("cogging_torque", 0.8, True), _rank("hysteresis", 0.35, True)]},
    {"hidden": ["cogging_torque"], "identifiable": ["cogging_torque"], "named": [], "angles": "both",
     "ranking_first": [_rank("cogging_torque", 0.1, False)]},
    {"hidden": ["backlash"], "identifiable": ["backlash"], "named": ["hysteresis"], "angles": "both",
     "ranking_first": [_rank("hysteresis", 0.5, True), _rank("backlash", 0.4, True)]},
    {"hidden": [], "identifiable": [], "named": [], "angles": "both",
     "ranking_first": [_rank("hysteresis", 0.2, False)]},
    {"hidden": [], "identifiable": [], "named": ["current_loop_lag"], "angles": "output",
     "ranking_first": [_rank("current_loop_lag", 0.45, True)]},
    {"hidden": [], "identifiable": [], "named": [], "angles": "output", "ranking_first": []},
    {"hidden": ["hysteresis"], "identifiable": [], "named": [], "angles": "motor", "ranking_first": []},
    {"hidden": ["cogging_torque"], "identifiable": ["cogging_torque"], "named": [], "angles": "both",
     "error": "UserError: x", "ranking_first": []},
]


def test_confusion_counts_named_first_missed_and_wrong() -> None:
    c = _script().confusion(RECORDS)
    assert c == {"backlash": {"named_first": 0, "missed": 0, "wrong": 1, "n": 1},
                 "cogging_torque": {"named_first": 1, "missed": 1, "wrong": 0, "n": 2}}


def test_threshold_rule_is_the_false_alarm_quantile_per_signal_set() -> None:
    m = _script()
    # clean logs: both -> nothing significant (0); output -> 0.45 (significant) and 0
    got = m.choose_frac_min(RECORDS, default=0.3, q=1.0, min_logs=0)
    assert got == {"both": 0.3, "motor": 0.3, "output": pytest.approx(0.45 + m.MARGIN)}
    assert m.choose_frac_min(RECORDS, default=0.3, q=0.5, min_logs=0)["output"] == 0.3    # median 0.225 < default
    assert m.choose_frac_min(RECORDS, default=0.1, q=0.5, min_logs=0)["output"] == pytest.approx(0.225 + m.MARGIN)
    # two clean logs are fewer than the 20 a 95 % quantile needs: the default stays
    assert m.MIN_CLEAN_LOGS == 20
    assert m.choose_frac_min(RECORDS, default=0.3, q=1.0) == {"both": 0.3, "motor": 0.3, "output": 0.3}
    ev = m.evidence_stats(RECORDS)
    assert ev["hysteresis"]["n_hidden"] == 0 and ev["hysteresis"]["n_not_hidden"] == 3
    assert ev["hysteresis"]["significant_not_hidden"] == 2
    assert ev["cogging_torque"]["size_q05_q50_q95_hidden"][1] == pytest.approx(0.45)


def test_scaled_sections_multiply_the_effect_and_keep_the_rest() -> None:
    secs = {"gear": {"ratio": 50.0}, "motor": {"jm_kgm2": 1e-3}, "load": {"jl_kgm2": 0.5},
            "stiffness": {"enabled": True, "k1_Nm_per_rad": 1e4, "k2_Nm_per_rad": 1e4, "k3_Nm_per_rad": 1e4,
                          "damping_Nms_per_rad": 5.0},
            "cogging": {"enabled": True, "h1_order": 36.0, "h1_amp_Nm": 0.02, "h1_phase_rad": 0.3},
            "hysteresis_maxwell": {"enabled": True, "n_elements": 1, "e1_k_Nm_per_rad": 2e3, "e1_w_Nm": 1.0},
            "friction_motor": {"enabled": True, "fc_pos_Nm": 0.12, "fc_neg_Nm": 0.08, "fs_pos_Nm": 0.12,
                               "fs_neg_Nm": 0.08, "vs_rad_s": 2.0}}
    for name in ("cogging_torque", "hysteresis", "asymmetric_friction", "unmodelled_compliance"):
        assert cl.scaled_sections(name, secs, (1.0,) * cl.tune_dims(name)) == secs
    c = cl.scaled_sections("cogging_torque", secs, (2.0,))
    assert c["cogging"]["h1_amp_Nm"] == pytest.approx(0.04) and c["cogging"]["h1_phase_rad"] == 0.3
    h = cl.scaled_sections("hysteresis", secs, (2.0, 4.0))["hysteresis_maxwell"]
    assert h["e1_w_Nm"] == pytest.approx(2.0) and h["e1_k_Nm_per_rad"] == pytest.approx(1e3)   # slip twist x4
    f = cl.scaled_sections("asymmetric_friction", secs, (0.5,))["friction_motor"]
    assert f["fc_pos_Nm"] == pytest.approx(0.11) and f["fc_neg_Nm"] == pytest.approx(0.09)
    t = cl.scaled_sections("unmodelled_compliance", secs, (2.0, 3.0))
    J = 1e-3 + 0.5 / 50 ** 2
    assert t["load"]["jl_kgm2"] == pytest.approx(1.0) and t["motor"]["jm_kgm2"] + 1.0 / 2500 == pytest.approx(J)
    assert t["stiffness"]["k1_Nm_per_rad"] == pytest.approx(3e4)
    assert secs["cogging"]["h1_amp_Nm"] == 0.02                                               # not modified


@pytest.mark.parametrize("name,best", [("cogging_torque", (2.5,)), ("hysteresis", (0.4, 3.0))])
def test_fit_on_replay_finds_the_factors_and_is_never_worse(name: str, best: tuple) -> None:
    secs = {"cogging": {"enabled": True, "h1_amp_Nm": 0.02},
            "hysteresis_maxwell": {"enabled": True, "e1_k_Nm_per_rad": 2e3, "e1_w_Nm": 1.0}}

    def factors(s: dict) -> tuple:
        if name == "cogging_torque":
            return (s["cogging"]["h1_amp_Nm"] / 0.02,)
        h = s["hysteresis_maxwell"]
        a = h["e1_w_Nm"] / 1.0
        return (a, a / (h["e1_k_Nm_per_rad"] / 2e3))

    def cost(s: dict) -> float:
        return 1e-6 * (1.0 + sum(math.log(x / b) ** 2 for x, b in zip(factors(s), best)))
    out, info = cl.fit_on_replay(name, secs, cost)
    assert np.allclose(factors(out), best, rtol=0.15)
    assert info["sim_rms_fitted_rad"] <= info["sim_rms_regression_rad"]
    assert info["evaluations"] <= max(cl.TUNE_EVALS_1D, cl.TUNE_EVALS_2D) + 3
    # a cost the regression's parameters already minimise: they are kept
    out, info = cl.fit_on_replay(name, secs, lambda s: 1e-6 * (1 + sum(math.log(x) ** 2 for x in factors(s))))
    assert np.allclose(factors(out), 1.0, rtol=0.05)


def test_quantisation_floor_and_gap_above_it() -> None:
    from hdservo.discrepancy.signals import Signals
    q = 2 * math.pi / 2 ** 18
    th_l = np.round(np.linspace(0, 0.002, 4000) / q) * q
    N = 100.0
    qm = 2 * math.pi / 2 ** 16
    th_m = np.round(N * np.linspace(0, 0.002, 4000) / qm) * qm
    sig = Signals.__new__(Signals)
    sig.units, sig.meta, sig.dt, sig.ratio, sig.angles = {"angle": "rad"}, {}, 1e-3, N, "both"
    sig.raw_th_m, sig.raw_th_l = th_m, th_l
    both = cl.quantisation_floor(sig, count_load=True)
    assert both == pytest.approx(math.sqrt(((qm / N) ** 2 + q ** 2) / 24), rel=0.05)
    assert cl.quantisation_floor(sig, count_load=False) == pytest.approx(qm / N / math.sqrt(12), rel=0.05)
    sig.units = {"angle": "m"}
    assert cl.quantisation_floor(sig, count_load=True) == 0.0
    assert cl.gap_above_floor(5.0, 3.0) == pytest.approx(4.0)
    assert cl.gap_above_floor(3.0, 3.0) == pytest.approx(cl.FLOOR_RESOLUTION * 3.0)
    assert math.isnan(cl.gap_above_floor(float("nan"), 1.0))


def test_first_names_under_thresholds_replays_the_rankings() -> None:
    m = _script()
    low = m.first_names_under(RECORDS, {"both": 0.3, "motor": 0.3, "output": 0.3})
    assert low["named_first"]["cogging_torque"] == {"k": 1, "n": 2} and low["named_first"]["backlash"]["k"] == 0
    assert low["false_alarm"] == {"k": 1, "n": 3}
    high = m.first_names_under(RECORDS, {"both": 0.45, "motor": 0.3, "output": 0.5})
    assert high["false_alarm"] == {"k": 0, "n": 3}
    assert high["named_first"]["backlash"]["k"] == 0            # hysteresis (0.5) is still first
    assert high["named_first_total"] == {"k": 1, "n": 3}


def test_threshold_inputs_and_census_records(tmp_path: Path) -> None:
    m = _script()
    recs = [dict(r, seed=i + 1) for i, r in enumerate(RECORDS)]
    recs.append({"seed": 9, "hidden": [], "identifiable": [], "named": [], "angles": "motor", "census": True,
                 "ranking_first": [_rank("asymmetric_friction", 0.6, True), _rank("gravity_unbalance", 0.2, True)]})
    doc = m.threshold_inputs(recs, 0.3, 12.0)
    # one input per clean log (errors left out), the largest significant size, 0 when none
    assert doc["clean_seeds"] == {"both": [4], "motor": [9], "output": [5, 6]}
    assert doc["largest_sizes"] == {"both": [0.0], "motor": [0.6], "output": [0.45, 0.0]}
    assert doc["seeds_analysed"] == [1, 8] and doc["census_seeds"] == [9]
    assert doc["errors"] == [8] and doc["wall_s"] == 12.0
    from hdservo.discrepancy import thresholds
    assert thresholds.from_inputs(doc) == m.choose_frac_min(recs, 0.3) == {"both": 0.3, "motor": 0.3, "output": 0.3}
    assert doc["min_logs"] == m.MIN_CLEAN_LOGS
    assert thresholds.from_inputs(dict(doc, min_logs=0))["motor"] == pytest.approx(0.6 + m.MARGIN)
    # the census' extra clean logs enter the rule, not the report's figures
    assert len(m.sample(recs)) == len(RECORDS)
    # the census is the corpus' own draw: clean logs of the asked signal sets only
    from oracles import discrepancy_corpus as corpus
    got = m.census_seeds(["motor", "output"], range(1, 200))
    assert got and all(not corpus.draw(s).hidden and corpus.draw(s).angles in ("motor", "output") for s in got)
    assert set(got) == {s for s in range(1, 200) if not corpus.draw(s).hidden and corpus.draw(s).angles != "both"}
    # runs merged by seed: the first file's case wins, run times add up
    import json
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"cases": recs[:2], "wall_s": 5.0}))
    b.write_text(json.dumps({"cases": [dict(recs[1], named=["x"]), recs[2]], "wall_s": 7.0}))
    got_recs, wall = m.merged([str(a), str(b)])
    assert [r["seed"] for r in got_recs] == [1, 2, 3] and got_recs[1]["named"] == recs[1]["named"] and wall == 12.0


def test_refresh_applies_the_current_identifiability_table() -> None:
    m = _script()
    from hdservo.discrepancy import IDENTIFIABLE
    from oracles import discrepancy_corpus as corpus
    seed = next(s for s in range(1, 400) if corpus.draw(s).angles == "output" and not corpus.draw(s).hidden)
    rec = {"seed": seed, "hidden": [], "identifiable": ["x"], "angles": "output",
           "named": ["cogging_torque", "gravity_unbalance"],
           "ranking_first": [_rank("cogging_torque", 0.5, True), _rank("gravity_unbalance", 0.4, True)]}
    (r,) = m.refresh([rec])
    assert "cogging_torque" not in IDENTIFIABLE["output"]
    assert r["named"] == ["gravity_unbalance"] and [c["effect"] for c in r["ranking_first"]] == ["gravity_unbalance"]
    assert r["refreshed"] == ["cogging_torque"] and r["identifiable"] == []
    assert rec["named"] == ["cogging_torque", "gravity_unbalance"]            # the input is not modified


def _two(seed: int, hidden: list[str], named: list[str], workflow: list[str], ident: int = 2) -> dict:
    return {"seed": seed, "hidden": hidden, "identifiable": hidden[:ident], "named": named,
            "named_workflow": workflow, "angles": "both", "ranking_first": []}


def test_two_effect_census_sorts_logs_by_where_the_second_name_is_lost() -> None:
    m = _script()
    recs = [_two(1, ["a", "b"], ["b", "a"], ["b", "a", "c"]),        # both kept, a third dropped
            _two(2, ["a", "b"], ["a"], ["a", "b"]),                  # the simulator drops b
            _two(3, ["a", "b"], ["a", "c"], ["a", "c"]),             # the workflow names c, not b
            _two(4, ["a", "b"], [], []),
            _two(5, ["a", "b"], ["a"], ["a"], ident=1),              # b not identifiable: not counted
            _two(6, ["a"], ["a"], ["a"]),
            {**_two(7, ["a", "b"], [], []), "error": "UserError: x"}]
    t = m.two_effects(recs)
    assert t["logs"] == [1, 2, 3, 4]
    assert t["both_named"] == [1] and t["both_by_workflow"] == [1, 2] and t["lost_by_simulator"] == [2]
    assert t["one_missed"] == [3, 4] and t["spurious"] == [3]
    assert t["both_named_fraction"]["k"] == 1 and t["both_named_fraction"]["n"] == 4


def test_two_effect_census_counts_both_named_as_the_held_apart_score() -> None:
    """The calibration's two-effect figure and the held-apart one count the same logs and the
    same hits (two hidden effects the signals can show, both among the simulator's kept names)."""
    m = _script()
    recs = [_two(1, ["a", "b"], ["b", "a"], ["b", "a", "c"]), _two(2, ["a", "b"], ["a"], ["a", "b"]),
            _two(3, ["a", "b"], ["a", "c", "b"], ["a", "c", "b"]), _two(4, ["a", "b"], [], []),
            _two(5, ["a", "b"], ["a", "b"], ["a", "b"], ident=1), _two(6, ["a"], ["a"], ["a"]),
            {**_two(7, ["a", "b"], ["a", "b"], ["a", "b"]), "error": "UserError: x"}]
    calib = m.two_effects(recs)["both_named_fraction"]
    held = m._heldout().score(recs)["two_both_named"]
    assert (calib["k"], calib["n"]) == (held["k"], held["n"]) == (2, 4)


def test_two_effect_seeds_are_calibration_seeds_with_two_identifiable_effects() -> None:
    from oracles import discrepancy_corpus as corpus
    seeds = _script().two_effect_seeds(corpus.CALIBRATION_SEEDS, 3)
    assert seeds == [1, 7, 10]
    for s in seeds:
        c = corpus.draw(s)
        assert len(c.hidden) == 2 and len(c.identifiable()) == 2
    assert all(s not in corpus.HELD_APART_SEEDS for s in seeds)
