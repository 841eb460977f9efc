"""Influence laws (hdservo.design.influence): elasticity logic and a 2-parameter x 1-figure sweep."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from hdservo.cli import UserError
from hdservo.design import influence as inf

ROOT = Path(__file__).resolve().parents[2]
AXIS = str(ROOT / "sim" / "axes" / "reference.toml")


@pytest.mark.parametrize("a", [-1.5, -0.3, 0.0, 0.5, 2.0])
def test_elasticity_of_a_power_law_is_its_exponent(a):
    c, h = 3.7, 0.2
    y = lambda p: c * p ** a  # noqa: E731
    assert inf.elasticity(y(1 - h), y(1 + h), h) == pytest.approx(a, abs=1e-12)


def test_elasticity_refuses_what_has_no_log():
    assert inf.elasticity(0.0, 1.0) is None
    assert inf.elasticity(None, 1.0) is None  # type: ignore[arg-type]
    assert inf.elasticity(1.0, math.inf) is None
    with pytest.raises(UserError, match="expected 0 < h < 1"):
        inf.elasticity(1.0, 2.0, 1.0)


def test_scaled_touches_only_the_parameter_keys():
    vals = inf.parameter_values(AXIS)
    s = inf.scaled(vals, "coulomb", 1.2)
    assert set(s) == set(inf.PARAMETERS["coulomb"][0])
    for k, v in s.items():
        assert v == pytest.approx(1.2 * vals[k])
    with pytest.raises(UserError, match="influence parameter 'mass'"):
        inf.scaled(vals, "mass", 1.2)


def test_mini_sweep_resonance_follows_k1_not_te():
    """Two parameters, one figure: the first resonance of a two-mass axis goes as sqrt(K1)
    (elasticity 1/2) and does not depend on the TE amplitude; the describing function says
    the same."""
    res = inf.sweep(AXIS, parameters=("k1", "te_amplitude"), figures=("first_resonance_Hz",), workers=2)
    e = res["elasticity"]
    assert set(e) == {"k1", "te_amplitude"}
    # two-mass theory: f ~ sqrt(K) -> 0.5 with K1 alone; the Maxwell-slip elements, while they
    # stick, add 11.7e3 N m/rad in parallel that K1 does not scale -> 0.5 x 31/42.7 = 0.36
    assert 0.3 <= e["k1"]["first_resonance_Hz"]["sim"] <= 0.6
    assert e["k1"]["first_resonance_Hz"]["df"] == pytest.approx(0.5, abs=0.05)
    assert abs(e["te_amplitude"]["first_resonance_Hz"]["sim"]) < 0.05
    assert e["te_amplitude"]["first_resonance_Hz"]["df"] is None  # TE is no DF element
    # the elasticity is formed from the stored plus/minus figures
    pts = res["points"]["k1"]
    assert e["k1"]["first_resonance_Hz"]["sim"] == pytest.approx(
        inf.elasticity(pts["minus"]["first_resonance_Hz"], pts["plus"]["first_resonance_Hz"], 0.2))
    assert 30.0 < res["nominal"]["first_resonance_Hz"] < 100.0
    # the stored table (design report) is this code's output on the same axis and seed: fresh
    tab = inf.load_table()
    assert tab["axis"] == Path(AXIS).name and tab["seed"] == res["seed"]
    for p in ("k1", "te_amplitude"):
        for src in ("sim", "df"):
            stored = tab["elasticity"][p]["first_resonance_Hz"][src]
            now = e[p]["first_resonance_Hz"][src]
            assert (stored is None and now is None) or stored == pytest.approx(now, abs=1e-9), (p, src)


def test_requirement_influence_ranks_by_magnitude():
    table = {"parameters": {"a": "A", "b": "B", "c": "C"},
             "elasticity": {"a": {"bandwidth_Hz": {"sim": 0.1, "df": 0.2}},
                            "b": {"bandwidth_Hz": {"sim": -0.9, "df": None}},
                            "c": {"bandwidth_Hz": {"sim": None, "df": 1.0}}}}
    out = inf.requirement_influence(["bandwidth", "unknown"], table, top=3)
    assert list(out) == ["bandwidth"]
    assert [r["parameter"] for r in out["bandwidth"]] == ["b", "a"]
    assert out["bandwidth"][0]["elasticity_sim"] == -0.9 and out["bandwidth"][0]["meaning"] == "B"


def test_stored_table_is_complete():
    tab = inf.load_table()
    assert set(tab["elasticity"]) == set(inf.PARAMETERS)
    for p, row in tab["elasticity"].items():
        assert set(row) == set(inf.SIM_FIGURES), p


def test_bad_table_is_refused(tmp_path):
    bad = tmp_path / "t.json"
    bad.write_text("{")
    with pytest.raises(UserError, match="not valid JSON"):
        inf.load_table(bad)
    bad.write_text(json.dumps({"x": 1}))
    with pytest.raises(UserError, match="'elasticity'"):
        inf.load_table(bad)


def test_agreement_rule():
    assert inf.agreement(1.0, 1.3) == "agrees"          # 0.3 <= 0.1 + 0.25
    assert inf.agreement(1.0, 1.4) == "differs"
    assert inf.agreement(0.0, 0.09) == "agrees"
    assert inf.agreement(0.0, -0.2) == "differs"
    assert inf.agreement(0.5, None) == "no DF"
    assert inf.agreement(None, 0.5) == "no sim"


def test_report_section_names_each_requirements_binding_parameter():
    tab = inf.load_table()
    margins = {"min_smooth_rate": 0.4, "positioning_accuracy": -0.1, "stabilisation": 0.2,
               "peak_torque": 0.3, "resonance": 0.13}
    lines = inf.markdown_section(margins, tab)
    text = "\n".join(lines)
    assert lines[0] == "## Influence of the binding parameters"
    for req in ("min_smooth_rate", "positioning_accuracy", "stabilisation", "resonance"):
        fig = inf.REQUIREMENT_FIGURE[req]
        best = max((p for p in tab["elasticity"] if tab["elasticity"][p][fig]["sim"] is not None),
                   key=lambda p: abs(tab["elasticity"][p][fig]["sim"]))
        row = next(ln for ln in lines if ln.startswith(f"| {req} |"))
        assert f"| {best} |" in row and f"{100 * margins[req]:+.0f} %" in row
    assert "| peak_torque |" not in text  # no nonlinearity lever for the torque rating


def test_improving_direction_follows_the_figure_sense():
    assert inf.improving_direction("first_resonance_Hz", 0.5) == "raise"      # stiffer -> higher
    assert inf.improving_direction("positioning_arcsec", -0.8) == "raise"     # more -> smaller error
    assert inf.improving_direction("min_smooth_rate_deg_s", 0.6) == "lower"
    assert inf.improving_direction("bandwidth_Hz", -1.9) == "lower"
    assert set(inf.FIGURE_BETTER) == set(inf.SIM_FIGURES)
