"""The drift Monte Carlo study (tests/results/58_drift_monte_carlo.py) on a tiny grid."""
from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _script() -> Any:
    spec = importlib.util.spec_from_file_location("drift_mc", ROOT / "tests" / "results" / "58_drift_monte_carlo.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = m          # the worker processes find run_task by module name
    spec.loader.exec_module(m)
    return m


def _row(m: Any, scen: str, ctl: str, run: int, values: dict[str, float | None]) -> dict[str, Any]:
    return {"scenario": scen, "controller": ctl, "run": run, "factors": m.model_factors(run), "faults": 0,
            **{f: values.get(f) for f in m.FIGURES}}


def _figures(row: dict[str, Any]) -> dict[str, Any]:
    """A row without its run time."""
    return {k: v for k, v in row.items() if k != "run_time_s"}


def test_statistics_and_target_rule() -> None:
    m = _script()
    rng = np.random.default_rng(3)
    rows = []
    # pid 10x the nominal error of 'fixed'; under drift fixed falls to pid, the adaptive ones stay
    level = {("nominal", "pid"): 10.0, ("nominal", "fixed"): 1.0, ("nominal", "online"): 2.0,
             ("nominal", "backstep"): 2.5, ("inertia_x2", "pid"): 10.0, ("inertia_x2", "fixed"): 8.0,
             ("inertia_x2", "online"): 3.0, ("inertia_x2", "backstep"): 6.5}
    draws: dict[tuple[str, str], list[float]] = {}
    for (s, c), lv in level.items():
        draws[(s, c)] = list(lv * rng.uniform(0.8, 1.2, 7))
        for r, v in enumerate(draws[(s, c)]):
            rows.append(_row(m, s, c, r, {f: v for f in m.FIGURES}))
    rows.append(_row(m, "nominal", "pid", 7, {}))                       # a run without figures
    res = m.summarise(rows, m.CONTROLLERS, ("nominal", "inertia_x2"))
    st = res["stats"]["inertia_x2"]["online"][m.TARGET_FIGURE]
    assert st["median"] == pytest.approx(float(np.median(draws[("inertia_x2", "online")])))
    assert st["p95"] == pytest.approx(float(np.percentile(draws[("inertia_x2", "online")], 95)))
    assert st["n"] == 7 and st["missing"] == 0
    assert res["stats"]["nominal"]["pid"][m.TARGET_FIGURE]["missing"] == 1
    g = res["gain"]["inertia_x2"]["fixed"][m.TARGET_FIGURE]
    assert g == pytest.approx(np.median(draws[("inertia_x2", "pid")]) / np.median(draws[("inertia_x2", "fixed")]))
    r = res["retention"]["inertia_x2"]["fixed"][m.TARGET_FIGURE]
    assert r == pytest.approx(g / res["gain"]["nominal"]["fixed"][m.TARGET_FIGURE])
    t = res["target"]
    assert t["figures"] == list(m.FIGURES)                        # fixed gains ~10 on every figure
    e = t["per_scenario"]["inertia_x2"][m.TARGET_FIGURE]
    assert e["fixed_loses_gain"] and e["online_keeps_gain"] and not e["backstep_keeps_gain"]
    assert f"inertia_x2/{m.TARGET_FIGURE}" in t["where_fixed_loses"]
    assert t["met"] is False
    # with backstepping as good as the online FF the rule holds
    for row in rows:
        if row["scenario"] == "inertia_x2" and row["controller"] == "backstep":
            for f in m.FIGURES:
                row[f] = row[f] * 0.5
    assert m.summarise(rows, m.CONTROLLERS, ("nominal", "inertia_x2"))["target"]["met"] is True
    # a fixed-model compensation that keeps its gain: nothing to check, no verdict
    for row in rows:
        if row["scenario"] == "inertia_x2" and row["controller"] == "fixed":
            for f in m.FIGURES:
                row[f] = row[f] / 10.0
    res2 = m.summarise(rows, m.CONTROLLERS, ("nominal", "inertia_x2"))
    assert res2["target"]["where_fixed_loses"] == [] and res2["target"]["met"] is None

def test_scenarios_and_model() -> None:
    m = _script()
    c = m.cases(quick=True)[0]
    s, w = m._window(c)
    p = m.scenario_plant("friction_warm_cold", c, "reference")
    assert p["friction_drift.t_start_s"] >= s
    assert p["friction_drift.t_start_s"] + p["friction_drift.ramp_s"] + p["friction_drift.hold_s"] \
        + p["friction_drift.return_s"] <= s + w + 1e-9
    g = m.scenario_plant("gravity_appears", c, "reference")
    assert g["gravity_drift.mgl_Nm"] > 0.0
    assert m.scenario_plant("nominal", c, "reference") == {}
    with pytest.raises(ValueError, match="unknown scenario"):
        m.scenario_plant("nope", c, "reference")
    f = m.model_factors(4)
    assert f == m.model_factors(4) and f != m.model_factors(5)
    assert all(1 - m.MODEL_ERROR <= v <= 1 + m.MODEL_ERROR for v in f.values())
    true = m.perturbed_model("reference", {k: 1.0 for k in m.MODEL_GROUPS})
    pert = m.perturbed_model("reference", f)
    assert pert["load.jl_kgm2"] == pytest.approx(true["load.jl_kgm2"] * f["inertia"])
    t_fixed = m.controller_table("fixed", "reference", pert)
    t_true = m.controller_table("fixed", "reference", true)
    assert t_fixed["gains"]["str_fc_pos"] != t_true["gains"]["str_fc_pos"]
    assert m.controller_table("online", "reference", pert)["gains"]["fe_feed"] == 1.0
    assert m.controller_table("pid", "reference", pert)["compensators"] == []


def test_tiny_run_writes_json(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    m = _script()
    quick = m.cases(quick=True)
    # one short tracking case and one move: enough for two figures, seconds per run
    short = [c for c in quick if c.name == "tracking_0.01"] + [c for c in quick if c.kind == "ptp"][:1]
    monkeypatch.setattr(m, "cases", lambda quick=False: short)
    res = m.run("reference", runs=2, jobs=2, quick=True, controllers=("pid", "fixed"),
                scenarios=("nominal", "inertia_x2"), out=tmp_path, plots=True, run_in=False)
    data = json.loads((tmp_path / "drift_mc.json").read_text())
    assert data["format"] == m.FORMAT and data["runs_per_controller"] == 2
    assert (tmp_path / data["plots"][0]).is_file()
    assert len(data["runs"]) == 2 * 2 * 2
    for s in ("nominal", "inertia_x2"):
        for c in ("pid", "fixed"):
            st = data["stats"][s][c][m.TARGET_FIGURE]
            vals = [r[m.TARGET_FIGURE] for r in data["runs"] if r["scenario"] == s and r["controller"] == c]
            assert st["n"] == 2 and all(v is not None and math.isfinite(v) and v > 0 for v in vals)
            assert st["median"] == pytest.approx(float(np.median(vals)))
            assert min(vals) <= st["p95"] <= max(vals)
    # the drift changes the run: same seeds and model draws, different error
    nom = [r[m.TARGET_FIGURE] for r in data["runs"] if r["scenario"] == "nominal" and r["controller"] == "pid"]
    dr = [r[m.TARGET_FIGURE] for r in data["runs"] if r["scenario"] == "inertia_x2" and r["controller"] == "pid"]
    assert nom != dr
    assert set(data["target"]) == {"figures", "min_nominal_gain", "loss_retention", "gain_required",
                                   "per_scenario", "where_fixed_loses", "met"}
    assert "inertia_x2" in data["target"]["per_scenario"]


def test_backstepping_holds_an_appearing_unbalance() -> None:
    """Slow tracking (0.01 deg/s) while an unbalance of the axis' breakaway size appears, with a
    model whose friction is 10-20 % low: backstepping tracks without a drive fault.  Its friction
    regressor follows the cruising reference; on the noisy sign of the measured velocity the
    friction terms average out, the load term reaches its bound and the drive trips on torque
    saturation."""
    from hdservo import closedloop_cases as bl
    m = _script()
    case = next(c for c in m.cases(quick=False) if c.name == "tracking_0.01")
    factors = {g: 1.0 for g in m.MODEL_GROUPS}
    factors.update({"motor_levels": 0.9, "load_levels": 0.8, "inertia": 0.75})
    table = m.controller_table("backstep", "reference", m.perturbed_model("reference", factors))
    r = bl.run_case(case, table, "reference", 2, params=m.scenario_plant("gravity_appears", case, "reference"))
    a = bl.analyse(case, r)
    assert a.figures["fault_code"] == 0
    assert a.figures["rms_arcsec"] < 5.0


def test_checkpoint_resumes_without_running_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Finished runs go to the checkpoint as they end; a second study over the same tasks takes
    them from it (nothing runs again), a cut-off last line is run again, and other controllers
    of the same runs are added to the same file."""
    m = _script()
    calls: list[tuple[str, str, int]] = []

    def fake(task: tuple[Any, ...]) -> dict[str, Any]:
        axis, scen, ctl, run, seed, quick = task[:6]
        calls.append((scen, ctl, run))
        return _row(m, scen, ctl, run, {f: 1.0 + run + (ctl == "pid") for f in m.FIGURES})

    monkeypatch.setattr(m, "run_task", fake)
    ck = tmp_path / "ck.jsonl"
    tasks = [("reference", "nominal", c, r, 1, True) for c in ("pid", "fixed") for r in range(3)]
    rows = m.run_tasks(tasks, jobs=1, checkpoint=ck)
    assert len(calls) == 6 and len(ck.read_text().splitlines()) == 6
    assert [r["run"] for r in rows] == [0, 1, 2, 0, 1, 2]
    calls.clear()
    assert m.run_tasks(tasks, jobs=1, checkpoint=ck) == rows and calls == []
    # a run cut off while it was written is done again
    lines = ck.read_text().splitlines()
    ck.write_text("\n".join(lines[:-1] + [lines[-1][:20]]) + "\n")
    # (the row run again has its own run_time_s; the figures are the same)
    again = m.run_tasks(tasks, jobs=1, checkpoint=ck)
    assert [_figures(r) for r in again] == [_figures(r) for r in rows] and calls == [("nominal", "fixed", 2)]
    # another seed is another task
    calls.clear()
    m.run_tasks([("reference", "nominal", "pid", 0, 2, True)], jobs=1, checkpoint=ck)
    assert calls == [("nominal", "pid", 0)]
    # the study over both controllers from the file: pid 1 worse than fixed on every run
    calls.clear()
    res = m.run("reference", runs=3, jobs=1, quick=True, controllers=("pid", "fixed"), scenarios=("nominal",),
                out=tmp_path, plots=False, checkpoint=ck, run_in=False)
    assert calls == []
    # the same runs with the run-in are other tasks
    m.run_tasks([("reference", "nominal", "pid", 0, 1, True, True)], jobs=1, checkpoint=ck)
    assert calls == [("nominal", "pid", 0)]
    assert res["gain"]["nominal"]["fixed"][m.TARGET_FIGURE] == pytest.approx(3.0 / 2.0)


def test_command_line_refuses_unknown_names(capsys: pytest.CaptureFixture[str]) -> None:
    m = _script()
    assert m.main(["--controllers", "online,nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--controllers" in err[0] and "nope" in err[0] and "online" in err[0]
    assert m.main(["--scenarios", "cold"]) == 2


def test_online_feed_without_a_fit_is_the_model_given_to_the_drive() -> None:
    """In a case that gives the online estimator no accepted fit (the reversal sine is never
    steady) the online-identified feed-forward feeds the model written to the drive: the same
    error trace as the fixed-model feed-forward, bit for bit, with a model 25 % below the
    axis' friction.  Its figure differs from the feed-forward of the axis' true map, so an
    estimate that kept another map (e.g. the drive's start-up defaults, the reference axis'
    friction) would show."""
    from hdservo import closedloop_cases as bl
    m = _script()
    case = next(c for c in m.cases(quick=True) if c.kind == "reversal")
    factors = {g: 1.0 for g in m.MODEL_GROUPS}
    factors.update({"motor_levels": 0.75, "load_levels": 0.75})
    model = m.perturbed_model("reference", factors)
    true = m.perturbed_model("reference", {g: 1.0 for g in m.MODEL_GROUPS})

    def error(ctl: str, mdl: dict[str, float]) -> np.ndarray:
        return bl.error_arcsec(bl.run_case(case, m.controller_table(ctl, "reference", mdl), "reference", 3))

    online, fixed, fixed_true = error("online", model), error("fixed", model), error("fixed", true)
    assert np.array_equal(online, fixed)
    assert np.max(np.abs(online - fixed_true)) > 1.0


def test_run_time_is_the_sum_of_the_runs_not_the_merge(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``run_time_s`` is the sum of the runs' own times, carried through the checkpoint: a study merged
    from a finished checkpoint reports the runs' time, and its own (merge) time apart."""
    m = _script()
    now = [1000.0]

    def fake(task: tuple[Any, ...]) -> dict[str, Any]:
        axis, scen, ctl, run, seed, quick = task[:6]
        now[0] += 10.0 * (run + 1)          # run r takes 10 (r + 1) s on the study's clock
        return _row(m, scen, ctl, run, {f: 1.0 + run + (ctl == "pid") for f in m.FIGURES})

    monkeypatch.setattr(m, "run_task", fake)
    monkeypatch.setattr(m.time, "perf_counter", lambda: now[0])
    ck = tmp_path / "ck.jsonl"
    kw = dict(jobs=1, quick=True, controllers=("pid", "fixed"), scenarios=("nominal",), out=tmp_path, plots=False,
              checkpoint=ck, run_in=False)
    first = m.run("reference", runs=3, **kw)
    assert [r["run_time_s"] for r in first["runs"]] == [10.0, 20.0, 30.0] * 2
    assert first["run_time_s"] == 120.0 and first["runs_timed"] == 6 and first["runs_without_time"] == 0
    assert first["wall_time_s"] == 120.0 and first["merge_time_s"] == 0.0
    # the merge of the finished checkpoint: nothing runs, the study's time is still its runs' 120 s
    now[0] += 6.0
    merged = m.run("reference", runs=3, **kw)
    on_disk = json.loads((tmp_path / "drift_mc.json").read_text())
    assert merged["run_time_s"] == on_disk["run_time_s"] == 120.0
    assert merged["wall_time_s"] == merged["merge_time_s"] == 0.0
    # a checkpoint row written without its time is counted apart, not as 0 s silently
    old = _row(m, "nominal", "pid", 3, {f: 2.0 for f in m.FIGURES})
    with ck.open("a") as fh:
        fh.write(json.dumps({"key": m._task_key(("reference", "nominal", "pid", 3, 1, True)), "row": old}) + "\n")
    four = m.run("reference", runs=4, **kw)
    assert four["run_time_s"] == 120.0 + 40.0            # fixed run 3 ran now; pid run 3 came untimed
    assert four["runs_timed"] == 7 and four["runs_without_time"] == 1
    assert four["wall_time_s"] == 40.0 and four["merge_time_s"] == 0.0


def test_run_in_comes_before_the_case_and_the_drift_before_its_last_cycle() -> None:
    """With the run-in a case's setpoint starts after the run-in's moves (every controller the
    same), its measurement is as long as without, and each drift takes place at the start of
    the run-in's last cycle: after the drive has run the profile on the nominal axis, before
    the measurement (the warm-up's return to cold in the measurement window)."""
    m = _script()
    c0 = next(c for c in m.cases(quick=False) if c.kind == "reversal")
    c = m.with_run_in(c0, True)
    assert m.with_run_in(c0, False) == c0
    tg, sp, starts = m.run_in_legs(m.RUN_IN_CYCLES)
    assert len(starts) == m.RUN_IN_CYCLES + 1 and tg[-1] == 0.0 and len(tg) == len(sp)
    assert min(sp) == pytest.approx(math.radians(0.01)) and max(sp) == pytest.approx(math.radians(10.0))
    t_run = c.setpoint["run_in_t0_s"]
    assert c.setpoint["t0_s"] >= t_run + starts[-1] + m.RUN_IN_HOLD_S
    assert c.duration_s - c.setpoint["t0_s"] == pytest.approx(c0.duration_s - c0.setpoint["t0_s"])
    s, w = m._window(c)
    assert s == pytest.approx(c.setpoint["t0_s"] - 0.1 + c.skip_s)
    last = t_run + starts[-2]
    for name, key in (("inertia_x2", "inertia_drift"), ("gravity_appears", "gravity_drift"),
                      ("stiffness_m20", "stiffness_drift")):
        p = m.scenario_plant(name, c, "reference")
        assert last <= p[f"{key}.t_start_s"] and p[f"{key}.t_start_s"] + p[f"{key}.ramp_s"] < t_run + starts[-1]
    p = m.scenario_plant("friction_warm_cold", c, "reference")
    assert last <= p["friction_drift.t_start_s"]
    back = p["friction_drift.t_start_s"] + p["friction_drift.ramp_s"] + p["friction_drift.hold_s"]
    assert back == pytest.approx(s + 0.65 * w)
    assert back + p["friction_drift.return_s"] <= s + w + 1e-9
    # without the run-in the drifts stay in the measurement window
    s0, w0 = m._window(c0)
    assert m.scenario_plant("inertia_x2", c0, "reference")["inertia_drift.t_start_s"] == pytest.approx(s0 + 0.3 * w0)


def test_run_in_gives_the_online_feed_an_estimate_of_both_directions() -> None:
    """The run-in's normal motion lets the drive's estimator fit both directions before the
    measurement, so the online feed-forward measures its own estimate, not the model given to
    the drive: with a model 25 % low the fed levels move (above the model) and the reversal's
    error differs from the fixed-model feed-forward's; the row reports the fits and the change."""
    from hdservo import closedloop_cases as bl
    m = _script()
    case = m.with_run_in(next(c for c in m.cases(quick=True) if c.kind == "reversal"), True)
    factors = {g: 1.0 for g in m.MODEL_GROUPS}
    factors.update({"motor_levels": 0.75, "load_levels": 0.75})
    model = m.perturbed_model("reference", factors)
    r_on = bl.run_case(case, m.controller_table("online", "reference", model), "reference", 3)
    r_fix = bl.run_case(case, m.controller_table("fixed", "reference", model), "reference", 3)
    est = m.estimator_state(r_on.meta)
    assert est is not None and m.estimator_state(r_fix.meta) is None
    assert min(est["fits"]) > 0
    assert est["change"]["fc_pos"] > 0.1 and est["change"]["fs_neg"] > 0.0
    assert np.max(np.abs(bl.error_arcsec(r_on) - bl.error_arcsec(r_fix))) > 1.0
    summ = m.estimator_summary([{"scenario": "nominal", "controller": "online", "fric_est": est}], ["nominal"])
    assert summ["nominal"]["runs_fitted"] == 1
    assert summ["nominal"]["max_abs_change_median"] == pytest.approx(max(abs(v) for v in est["change"].values()))


def test_study_gives_every_friction_feed_forward_the_motor_share() -> None:
    """The model given to the drive carries the motor side's share of the friction, as
    ``hdservo download`` writes it: the Stribeck levels and the online feed relay that share."""
    from hdservo import compsetup as cs, sim
    m = _script()
    true = m.perturbed_model("reference", {g: 1.0 for g in m.MODEL_GROUPS})
    n = sim.axis_param("gear.ratio")
    fm = n * (sim.axis_param("friction_motor.fs_pos_Nm") + sim.axis_param("friction_motor.fs_neg_Nm"))
    fl = sim.axis_param("friction_load.fs_pos_Nm") + sim.axis_param("friction_load.fs_neg_Nm")
    share = true[cs.MOTOR_SHARE_KEY]
    assert 0.5 < share < 1.0 and share == pytest.approx(fm / (fm + fl))
    g = m.controller_table("online", "reference", true)["gains"]
    assert g["fe_share"] == pytest.approx(share)
    assert g["str_fs_pos"] == pytest.approx(share * (n * sim.axis_param("friction_motor.fs_pos_Nm")
                                                     + sim.axis_param("friction_load.fs_pos_Nm")))
    # a model with another motor/load split gives another share
    other = m.perturbed_model("reference", {**{g: 1.0 for g in m.MODEL_GROUPS}, "load_levels": 1.3})
    assert other[cs.MOTOR_SHARE_KEY] < share


def test_online_feed_does_not_keep_a_warm_level_while_the_axis_cools_and_only_reverses() -> None:
    """``friction_warm_cold`` with the run-in: the estimator learns the warm friction (x1.5) in the
    run-in, then the axis cools back during the reversal sine, which gives it no steady sample.
    A raised level no steady visit has confirmed for HD_FE_LEVEL_AGE steps fades back to the bins'
    level (hd_fric_est_fed_scale), so the online feed-forward's reversal peak stays below the fair
    PID's and near the fixed model's (a feed that kept the warm levels over-compensates: about
    1.6x the PID's peak for this model draw)."""
    from hdservo import closedloop_cases as bl
    m = _script()
    case = m.with_run_in(next(c for c in m.cases(quick=False) if c.kind == "reversal"), True)
    model = m.perturbed_model("reference", m.model_factors(0, 1))
    plant = m.scenario_plant("friction_warm_cold", case, "reference")

    def peak(ctl: str) -> float:
        r = bl.run_case(case, m.controller_table(ctl, "reference", model), "reference", 1, params=plant)
        v = m.figures_of(bl.collect([bl.analyse(case, r)]))["reversal_peak_arcsec"]
        assert v is not None
        return float(v)

    online, fixed, pid = peak("online"), peak("fixed"), peak("pid")
    assert online < 0.5 * pid
    assert online < 1.25 * fixed
