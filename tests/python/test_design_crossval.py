"""Leave-one-group-out cross-validation of the structure relations (hdservo.design.crossval)."""
from __future__ import annotations

from dataclasses import replace
from typing import Dict, List, Sequence

import pytest

from hdservo.cli import UserError
from hdservo.design import catalogue as cat
from hdservo.design import crossval as cv
from hdservo.design import structure as st

ROWS = cat.load_gears()
CSF = [g for g in ROWS if g.series == "CSF"]

#: a calibration unlike the stored one, so an exact held-out prediction cannot come from defaults
TRUE = replace(st.load_calibration(), mesh_stiffness_per_width_N_per_m2=2.1e8,
               zero_torque_engaged_fraction=0.07, clearance_spread_m=2.5e-5,
               mesh_module_exponent=0.4, t1_coefficient_N_per_m2=3.1e5,
               t2_coefficient_N_per_m2=1.2e6)


def synthetic_stiffness_rows(cal: st.Calibration, sizes: Sequence[int]) -> List[cat.GearRow]:
    """CSF rows of the given sizes whose T1, T2, K1-K3 follow the structure relation exactly."""
    out = []
    for g in CSF:
        if g.size not in sizes:
            continue
        s = st.structure_for(g.size, g.ratio)
        t1, t2 = st.breakpoints(s, cal)
        ts = st.three_slope(s, cal, (t1, t2))
        out.append(replace(g, t1_Nm=t1, t2_Nm=t2, k1_Nm_per_rad=ts.k1_Nm_per_rad,
                           k2_Nm_per_rad=ts.k2_Nm_per_rad, k3_Nm_per_rad=ts.k3_Nm_per_rad))
    return out


def test_exact_stiffness_relation_gives_zero_held_out_error():
    rows = synthetic_stiffness_rows(TRUE, (14, 25, 40, 50))
    pts = cv.leave_one_group_out(rows, cv.STIFFNESS, "size")
    assert {p.fold for p in pts} == {"size 14", "size 25", "size 40", "size 50"}
    assert len(pts) == 5 * len(rows)
    for p in pts:
        assert abs(p.error) < 1e-4, p
    # the same rows against the stored calibration are far off, so ~0 is the fit's doing
    far = [abs(cv.predict_stiffness(st.load_calibration(), g)["k1"] / g.k1_Nm_per_rad - 1)
           for g in rows]
    assert max(far) > 0.1


def test_exact_friction_scaling_gives_zero_held_out_error():
    c, q, kb = 0.09, 0.6, 1.05
    picks = {(17, 100), (25, 50), (32, 80), (40, 120)}
    rows = []
    for g in CSF:
        if (g.size, g.ratio) in picks:
            d = g.size * 2.54e-3
            ts = c * (d / cv.D25_M) ** 3 * (100.0 / g.ratio) ** q
            rows.append(replace(g, starting_torque_input_Nm=ts,
                                backdriving_torque_output_Nm=kb * g.ratio * ts, src_starting="x"))
    pts = cv.leave_one_group_out(rows, cv.FRICTION, "size")
    assert len(pts) == 8
    assert max(abs(p.error) for p in pts) < 1e-9


def test_unidentified_ratio_exponent_falls_back():
    g1 = next(g for g in CSF if g.starting_torque_input_Nm is not None)
    f = cv.fit_friction([g1])
    assert not f.q_identified and f.ratio_exponent == cv.UNIDENTIFIED_RATIO_EXPONENT
    assert cv.predict_friction(f, g1)["starting_torque"] == pytest.approx(g1.starting_torque_input_Nm)
    with pytest.raises(UserError, match="no training row"):
        cv.fit_friction([g for g in CSF if g.starting_torque_input_Nm is None][:3])


class _Memory:
    """A relation that knows exactly the rows it was fitted on: a held-out row that leaked
    into its fit would be predicted exactly (error 0)."""

    def __init__(self) -> None:
        self.seen: List[List[str]] = []

    def fit(self, train: Sequence[cat.GearRow]) -> Dict[str, float]:
        self.seen.append([g.name for g in train])
        return {g.name: g.k1_Nm_per_rad for g in train}

    @staticmethod
    def predict(model: Dict[str, float], g: cat.GearRow) -> Dict[str, float]:
        if g.name in model:
            return {"k1": model[g.name]}
        return {"k1": sum(model.values()) / len(model)}


@pytest.mark.parametrize("grouping", ["size", "ratio"])
def test_held_out_rows_never_enter_their_own_fit(grouping):
    mem = _Memory()
    rel = cv.Relation("memory", mem.fit, mem.predict, lambda g: {"k1": g.k1_Nm_per_rad},
                      lambda g: g.series == "CSF")
    pts = cv.leave_one_group_out(ROWS, rel, grouping)
    assert len(pts) == len(CSF)
    # a leak would make every prediction exact
    assert all(abs(p.error) > 1e-6 for p in pts)
    key = cv.GROUPINGS[grouping]
    by_name = {g.name: g for g in CSF}
    for names in mem.seen:
        assert len({key(by_name[n]) for n in names}) == len({key(g) for g in CSF}) - 1


def test_summary_statistics():
    pts = [cv.HeldOut("r", "size", "size 14", "A", "k1", 1.1, 1.0),
           cv.HeldOut("r", "size", "size 17", "B", "k1", 0.7, 1.0),
           cv.HeldOut("r", "size", "size 17", "B", "k3", 1.05, 1.0)]
    s = cv.summary(pts)
    assert s["k1"]["n"] == 2
    assert s["k1"]["max_abs"] == pytest.approx(0.3)
    assert s["k1"]["worst_row"] == "B" and s["k1"]["worst_error"] == pytest.approx(-0.3)
    assert s["k1"]["rms"] == pytest.approx(((0.01 + 0.09) / 2) ** 0.5)
    assert s["k1"]["within"] == pytest.approx(0.5) and s["k1"]["meets"] is False
    assert s["k3"]["meets"] is True


def test_bad_grouping_is_refused():
    with pytest.raises(UserError, match="grouping 'colour'"):
        cv.leave_one_group_out(ROWS, cv.STIFFNESS, "colour")


def test_stored_calibration_is_the_full_data_fit_of_the_cv_fits():
    """The CV refits use the same fit functions as the stored calibration."""
    cal = cv.fit_stiffness(CSF)
    stored = st.load_calibration()
    assert cal.mesh_stiffness_per_width_N_per_m2 == pytest.approx(
        stored.mesh_stiffness_per_width_N_per_m2, rel=1e-4)
    assert cal.t1_coefficient_N_per_m2 == pytest.approx(stored.t1_coefficient_N_per_m2, rel=1e-4)


def test_held_out_stiffness_on_the_catalogue_meets_the_k3_target():
    """Leave-one-size-out on the shipped catalogue: K3 within the 20 % target on every held-out
    row, K1 on at least 90 % of them (docs/design-structure.md section 4 lists the rest)."""
    pts = cv.leave_one_group_out(ROWS, cv.STIFFNESS, "size")
    s = cv.summary(pts)
    assert s["k3"]["n"] == len(CSF) and s["k3"]["meets"]
    assert s["k1"]["within"] >= 0.9
