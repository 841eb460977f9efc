"""`hdservo demo --seeds`: medians over sensor-noise seeds, per-seed values kept; bad input."""
from __future__ import annotations

from pathlib import Path

import pytest

from hdservo import seeds as sd
from hdservo.cli import main
from hdservo.commands.demo import median_table


def _summary(a: float | None, pid: float, comp_parts: list[str]) -> dict:
    return {"positioning_accuracy_arcsec": {"pid": pid, "compensated": a},
            "bandwidth_hz": {"pid": 20.0, "compensated": 25.0},
            "conditions": {"pid": {"feedback": "full-closed"},
                           "compensated": {"feedback": "full-closed", "components": comp_parts}}}


def test_summary_medians_keep_every_seed() -> None:
    s = sd.merge_summaries([_summary(1.0, 4.0, ["lugre"]), _summary(3.0, 6.0, ["stribeck"]),
                            _summary(2.0, 5.0, ["lugre"])], [1, 2, 3])
    a = s["positioning_accuracy_arcsec"]
    assert (a["pid"], a["compensated"]) == (5.0, 2.0)
    assert a["per_seed"] == {"pid": [4.0, 6.0, 5.0], "compensated": [1.0, 3.0, 2.0]}
    assert s["seeds"] == [1, 2, 3] and s["statistic"] == "median"
    assert [c["compensated"]["components"] for c in s["conditions"]["per_seed"]] == [["lugre"], ["stribeck"], ["lugre"]]
    # a failed seed (None) is kept per seed and left out of the median; no value at all -> None
    s2 = sd.merge_summaries([_summary(None, 4.0, []), _summary(3.0, 6.0, [])], [1, 2])
    assert s2["positioning_accuracy_arcsec"]["compensated"] == 3.0
    assert s2["positioning_accuracy_arcsec"]["per_seed"]["compensated"] == [None, 3.0]
    assert sd.median([None, None]) is None
    table = median_table(s)
    assert "positioning_accuracy_arcsec" in table and "0.4" in table and "[4 / 1, 6 / 3, 5 / 2]" in table


def _ablation(pid_a: float, best_a: float, best_parts: list[str]) -> dict:
    return {"baseline": "pid", "rule": "r", "best": {"full-closed": best_parts},
            "feedbacks": {"full-closed": {"best": best_parts, "rule": "r", "steps": [f"seed: {best_parts[0]}"],
                                          "leave_one_out": {}}}, "rows": [
        {"name": "pid", "feedback": "full-closed", "kind": "baseline", "components": [], "baseline_row": "pid",
         "figures": {"a": pid_a}, "ratio_to_baseline": {"a": 1.0}},
        {"name": "best", "feedback": "full-closed", "kind": "best", "components": best_parts, "baseline_row": "pid",
         "figures": {"a": best_a}, "ratio_to_baseline": {"a": best_a / pid_a}}]}


def test_ablation_medians_and_ratio_of_medians() -> None:
    d = sd.merge_ablations([_ablation(4.0, 1.0, ["lugre"]), _ablation(8.0, 4.0, ["te"]),
                            _ablation(6.0, 1.5, ["lugre"])], [1, 2, 3])
    rows = {r["name"]: r for r in d["rows"]}
    assert rows["pid"]["figures"]["a"] == 6.0 and rows["best"]["figures"]["a"] == 1.5
    assert rows["best"]["ratio_to_baseline"]["a"] == pytest.approx(0.25)          # median / median
    assert rows["best"]["per_seed"]["ratio_to_baseline"]["a"] == [0.25, 0.5, 0.25]
    assert rows["best"]["per_seed"]["components"] == [["lugre"], ["te"], ["lugre"]]
    assert d["best"] == {"full-closed": [["lugre"], ["te"], ["lugre"]]} and d["seeds"] == [1, 2, 3]
    # the rule's text once, and every seed's selection steps (what each seed chose and why)
    f = d["feedbacks"]["full-closed"]
    assert f["rule"] == "r" and f["best"] == [["lugre"], ["te"], ["lugre"]]
    assert f["steps"] == [["seed: lugre"], ["seed: te"], ["seed: lugre"]]


def test_parse_seeds() -> None:
    assert sd.parse_seeds("1,2,3") == [1, 2, 3] and sd.parse_seeds(" 7 ") == [7]
    for bad, word in (("1,x", "'x'"), ("1,1", "twice"), ("-1", "negative"), ("", "not an integer")):
        with pytest.raises(ValueError, match=word):
            sd.parse_seeds(bad)


def test_demo_seed_options_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "d"
    for argv, word in ((["--seeds", "1,a"], "'a' is not an integer"), (["--seeds", "2,2"], "twice"),
                       (["--seed", "1", "--seeds", "1,2"], "--seed and --seeds"),
                       (["--torque-max", "-1"], "--torque-max -1.0: expected a positive number")):
        assert main(["demo", "--out-dir", str(out), *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0] and not out.exists(), err
