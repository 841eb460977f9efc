"""``hdservo discrepancy``: bad input gives one line and no output; JSON shape and plots."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from hdservo import cli
from hdservo.discrepancy import EFFECT_NAMES
from oracles import discrepancy_cases as cases


@pytest.fixture(scope="module")
def cog_log(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("dq")
    return cases.make_log(cases.Case("cogging_torque", seed=1, size=1, duration_s=4.0), d / "cog.csv")


def test_bad_model_file_one_line_no_output(tmp_path: Path, cog_log: Path, capsys) -> None:
    m = tmp_path / "m.toml"
    m.write_text('[model]\nstructure = "three_mass"\n')
    out = tmp_path / "o.json"
    assert cli.main(["discrepancy", str(cog_log), "--model", str(m), "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "structure" in err[0] and str(m) in err[0]
    assert not out.exists()


def test_missing_torque_column(tmp_path: Path, capsys) -> None:
    p = tmp_path / "l.csv"
    p.write_text("t_s,motor_angle_rad\n" + "".join(f"{i * 1e-3},{i * 1e-3}\n" for i in range(500)))
    p.with_suffix(".json").write_text(json.dumps({"format": "hdservo-log", "version": 1, "gear_ratio": 100.0,
                                                  "sample_period_s": 1e-3}))
    out = tmp_path / "o.json"
    assert cli.main(["discrepancy", str(p), "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "motor_torque_Nm" in err[0]
    assert not out.exists()


def test_log_that_cannot_identify_the_baseline(tmp_path: Path, capsys) -> None:
    # a 0.5 s position step (sim/scenarios/step.toml): 197 moving samples, the two-mass fit
    # comes out with a negative load inertia and spring -- refused, not analysed against it
    log = tmp_path / "step.csv"
    assert cli.main(["sim", str(cases.REPO_ROOT / "sim" / "scenarios" / "step.toml"), "-o", str(log)]) == 0
    out = tmp_path / "o.json"
    capsys.readouterr()
    assert cli.main(["discrepancy", str(log), "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(log) in err[0] and "not a mechanical axis" in err[0] and "expected > 0" in err[0], err
    assert not out.exists()
    # an axis at rest
    rest = tmp_path / "rest.csv"
    rest.write_text("t_s,motor_angle_rad,load_angle_rad,motor_torque_Nm\n"
                    + "".join(f"{i * 1e-3},0.5,0.005,0.01\n" for i in range(2000)))
    rest.with_suffix(".json").write_text(json.dumps({"format": "hdservo-log", "version": 1, "gear_ratio": 100.0,
                                                     "sample_period_s": 1e-3}))
    assert cli.main(["discrepancy", str(rest), "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(rest) in err[0] and "hardly moves" in err[0], err
    assert not out.exists()


def test_lost_samples_and_wrong_period_are_refused(tmp_path: Path, cog_log: Path, capsys) -> None:
    from hdservo import logio
    log = logio.read_log(cog_log)
    n = len(log.t)
    keep = [i for i in range(n) if not 20000 <= i < 20007]            # a logger that lost 7 samples
    gap = tmp_path / "gap.csv"
    logio.write_log(gap, {k: v[keep] for k, v in log.columns.items()}, log.meta)
    wrong = tmp_path / "wrong.csv"                                     # sidecar says 2x the real period
    logio.write_log(wrong, log.columns, {**log.meta, "sample_period_s": 2 * log.meta["sample_period_s"]})
    out = tmp_path / "o.json"
    for p, msg in ((gap, "at row 20001"), (wrong, "sample_period_s is 0.0002 s")):
        capsys.readouterr()
        assert cli.main(["discrepancy", str(p), "--json", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(p) in err[0] and msg in err[0], err
        assert not out.exists()


def test_low_log_rate_gets_a_note(tmp_path: Path, cog_log: Path, capsys) -> None:
    """1 kHz is inside the validated range (no warning); 500 Hz is outside (one warning line)."""
    from hdservo import logio
    log = logio.read_log(cog_log)
    out = tmp_path / "o.json"
    for k, hz in ((10, 1000), (20, 500)):
        slow = tmp_path / f"slow{hz}.csv"                  # every k-th sample: a slower logger
        logio.write_log(slow, {c: v[::k] for c, v in log.columns.items()},
                        {**log.meta, "sample_period_s": log.meta["sample_period_s"] * k})
        capsys.readouterr()
        assert cli.main(["discrepancy", str(slow), "--json", str(out), "--no-simulator"]) == 0
        err = [ln for ln in capsys.readouterr().err.splitlines() if "validated" in ln]
        notes = [n for n in json.loads(out.read_text())["notes"] if "validated" in n]
        if hz == 1000:
            assert err == [] and notes == []
        else:
            assert len(err) == 1 and f"sampled at {hz} Hz" in err[0] and f"sampled at {hz} Hz" in notes[0]


def test_cogging_case_json_and_plots(tmp_path: Path, cog_log: Path) -> None:
    out = tmp_path / "o.json"
    assert cli.main(["discrepancy", str(cog_log), "--json", str(out), "--out-dir", str(tmp_path / "p")]) == 0
    res = json.loads(out.read_text())
    assert set(res) >= {"baseline", "iterations", "named_effects", "final_model"}
    assert res["named_effects"] and res["named_effects"][0] == "cogging_torque"
    assert all(n in EFFECT_NAMES for n in res["named_effects"])
    it = res["iterations"][0]
    assert it["params"]["order_per_motor_rev"] in (36, 72)       # the plant's cogging orders
    assert it["rms_before"] / it["rms_after"] >= 2.0
    # final model (baseline re-fitted with the cogging term): the reference axis' load
    # inertia and stiffness (the baseline alone is biased by the missing effect)
    f = res["final_model"]["params"]
    assert f["J_l_kgm2"] == pytest.approx(0.5, rel=0.1)
    assert f["K_Nm_per_rad"] == pytest.approx(3.1e4, rel=0.1)
    names = {p.name for p in (tmp_path / "p").iterdir()}
    assert {"residual_time.png", "gap.png", "spectrum.png", "simulation_time.png",
            "residual_1_cogging_torque.png"} <= names
    # the simulation error is reported and used as evidence
    assert len(res["sim_rms_history_rad"]) == len(res["rms_history"])
    assert it["model_sim_rms_after_rad"] < it["model_sim_rms_before_rad"]
    assert {"sim_delta_bic", "sim_explained_fraction", "total_delta_bic"} <= set(it["evidence"])


def test_baseline_biased_by_the_missing_effect(tmp_path: Path, monkeypatch, capsys) -> None:
    # CSF-14-30 (held-out axis), closed loop, friction half as large in the negative
    # direction: the two-mass baseline, which lacks that offset, comes out with J_m < 0.
    # Not a log that cannot identify the axis: the effect is named on the equation error
    # alone and the model with it is a mechanical axis again (plant J_m 1.5e-5, K 1900).
    axis = cases.REPO_ROOT / "tests" / "results" / "axes" / "csf14_30.toml"
    monkeypatch.setitem(cases.AXES, "csf14_30", str(axis))
    log = cases.make_log(cases.Case("asymmetric_friction", axis="csf14_30", loop="closed", seed=1, size=1),
                         tmp_path / "asym.csv")
    out = tmp_path / "o.json"
    assert cli.main(["discrepancy", str(log), "--json", str(out)]) == 0
    text = out.read_text()
    assert "Infinity" not in text and "NaN" not in text
    res = json.loads(text)
    assert res["baseline"]["J_m_kgm2"] <= 0.0
    assert res["named_effects"][:1] == ["asymmetric_friction"]
    assert res["sim_rms_history_rad"][0] is None and res["iterations"][0]["model_sim_rms_before_rad"] is None
    assert res["iterations"][0]["rms_gap"]["residual"] == "equation"
    assert res["iterations"][0]["rms_gap"]["shrink"] >= 3.0
    fin = res["final_model"]["params"]
    assert 1.0e-5 < fin["J_m_kgm2"] < 2.0e-5 and 1500.0 < fin["K_Nm_per_rad"] < 2300.0
    assert any("not a mechanical axis" in n for n in res["notes"])
    assert "not a mechanical axis" in capsys.readouterr().err


def test_encoder_zeros_that_differ(tmp_path: Path, cog_log: Path, capsys) -> None:
    # the same log with the motor encoder's zero 0.3 turn off (0.019 rad of twist at the
    # output, forty times a real one): without the correction K came out 44 N.m/rad and
    # the first name was asymmetric friction
    from hdservo import logio
    log = logio.read_log(cog_log)
    cols = dict(log.columns)
    cols["motor_angle_rad"] = cols["motor_angle_rad"] + 0.3 * 2 * 3.141592653589793
    shifted = tmp_path / "shifted.csv"
    logio.write_log(shifted, cols, {k: v for k, v in log.meta.items() if k not in ("format", "version", "columns")})
    out, ref = tmp_path / "o.json", tmp_path / "ref.json"
    assert cli.main(["discrepancy", str(shifted), "--json", str(out)]) == 0
    assert "zeros differ" in capsys.readouterr().err
    assert cli.main(["discrepancy", str(cog_log), "--json", str(ref)]) == 0
    res, want = json.loads(out.read_text()), json.loads(ref.read_text())
    assert want["notes"] == []                                        # encoders that agree: untouched
    assert res["named_effects"] == want["named_effects"] and res["named_effects"][:1] == ["cogging_torque"]
    assert abs(res["baseline"]["K_Nm_per_rad"] / want["baseline"]["K_Nm_per_rad"] - 1) < 0.02
    assert any("zeros differ" in n and "0.0188" in n for n in res["notes"]), res["notes"]


def test_users_log_with_minimal_sidecar_and_coarse_encoder(tmp_path: Path, cog_log: Path, capsys) -> None:
    """A user's log: the documented columns, a sidecar with only gear_ratio and sample_period_s
    (no format tag), a 13-bit motor encoder: analysed, with one warning line on the range."""
    import numpy as np
    from hdservo import logio
    log = logio.read_log(cog_log)
    q = 2 * np.pi / 2 ** 13
    cols = {"t_s": log.t, "motor_angle_rad": np.round(log["motor_angle_rad"] / q) * q,
            "load_angle_rad": log["load_angle_rad"], "motor_torque_Nm": log["motor_torque_Nm"]}
    p = tmp_path / "user.csv"
    p.write_text(logio.format_csv(cols))
    p.with_suffix(".json").write_text(json.dumps({"gear_ratio": log.meta["gear_ratio"],
                                                  "sample_period_s": log.meta["sample_period_s"]}))
    out = tmp_path / "o.json"
    capsys.readouterr()
    assert cli.main(["discrepancy", str(p), "--json", str(out)]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert len(err) == 1 and str(p) in err[0] and "motor encoder 13.0 bits" in err[0], err
    r = json.loads(out.read_text())
    vr = r["validated_range"]
    assert vr["inside"] is False and abs(vr["log"]["motor_encoder_bits"] - 13.0) < 1e-6
    assert any("motor encoder 13.0 bits" in n for n in r["notes"])
    from hdservo.discrepancy import validity
    lr = vr["log"]
    assert lr["twist_resolution_rad"] == validity.twist_resolution(
        validity.LogRange(lr["rate_Hz"], lr["motor_encoder_bits"], lr["output_encoder_bits"]), log.meta["gear_ratio"])
    # a sidecar whose tag names another format is still refused (one line, no output)
    out.unlink()
    p.with_suffix(".json").write_text(json.dumps({"format": "other", "gear_ratio": 100.0, "sample_period_s": 1e-4}))
    assert cli.main(["discrepancy", str(p), "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and '"format"' in err[0] and not out.exists()


def test_validated_range_checks() -> None:
    import numpy as np
    from hdservo.discrepancy import validity as v
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(0, 1e-3, 5000))
    for bits in (14, 17, 20):
        q = 2 * np.pi / 2 ** bits
        assert abs(v.quantum_bits(np.round(x / q) * q) - bits) < 1e-6
    assert v.quantum_bits(x) is None                        # not on a grid: resolution unknown
    inside = v.LogRange(rate_Hz=2000.0, motor_bits=17.0, load_bits=None)
    assert v.outside(inside) == [] and v.warning("l.csv", inside) is None
    assert v.outside(v.LogRange(500.0, 17.0, 24.0)) == ["sampled at 500 Hz"]
    assert v.outside(v.LogRange(20000.0, 17.0, 24.0)) == ["sampled at 20000 Hz"]
    assert v.outside(v.LogRange(1000.0, 30.0, 16.0)) == ["output encoder 16.0 bits"]
    w = v.warning("l.csv", v.LogRange(500.0, 12.0, 24.0))
    assert w is not None and "\n" not in w and w.startswith("l.csv: sampled at 500 Hz, motor encoder 12.0 bits")
    assert v.log_range({"motor_encoder_counts_per_rev": 2 ** 16}, 1e-3, x, None).motor_bits == 16.0


@pytest.mark.parametrize("keep, angles", [("motor_angle_rad", "motor"), ("load_angle_rad", "output")])
def test_one_encoder_names_only_what_it_can_show(tmp_path: Path, cog_log: Path, capsys, keep: str,
                                                  angles: str) -> None:
    """A log with one encoder never names an effect outside its row of the identifiability
    table and lists the rest as not identifiable from these signals (cogging is hidden in
    the log: the motor encoder shows it, the output encoder alone cannot)."""
    from hdservo import logio
    from hdservo.discrepancy import IDENTIFIABLE, NOT_IDENTIFIABLE
    log = logio.read_log(cog_log)
    p = tmp_path / f"{angles}.csv"
    logio.write_log(p, {"t_s": log.t, keep: log[keep], "motor_torque_Nm": log["motor_torque_Nm"]},
                    {"gear_ratio": log.meta["gear_ratio"], "sample_period_s": log.meta["sample_period_s"]})
    out = tmp_path / "o.json"
    capsys.readouterr()
    assert cli.main(["discrepancy", str(p), "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["signals"] == angles
    assert set(r["named_effects"]) <= set(IDENTIFIABLE[angles])
    assert {e for e, v in r["identifiability"].items() if v == NOT_IDENTIFIABLE} == \
        set(EFFECT_NAMES) - set(IDENTIFIABLE[angles]) == set(r["not_identifiable"])
    assert "cogging_torque" in r["not_identifiable"] if angles == "output" else "cogging_torque" in r["named_effects"]
    ranked = {c["effect"] for c in r["first_ranking"]}
    assert not ranked & set(r["not_identifiable"])
    assert NOT_IDENTIFIABLE in capsys.readouterr().out


def test_output_encoder_alone_never_names_cogging(tmp_path: Path, capsys) -> None:
    """A rigid log with the output encoder alone whose torque carries a ripple at 40 lines per
    output revolution: the motor angle it would need to be cogging is not measured, so the
    workflow does not name cogging_torque (it reports it as not identifiable)."""
    import numpy as np
    from hdservo import logio
    from hdservo.discrepancy import NOT_IDENTIFIABLE
    dt, N = 5e-4, 50.0
    t = np.arange(int(8.0 / dt)) * dt
    th = 0.8 * np.sin(2 * np.pi * 0.25 * t) + 0.02 * np.sin(2 * np.pi * 3.1 * t)
    v, a = np.gradient(th, dt), np.gradient(np.gradient(th, dt), dt)
    J, Fv, Fc = 0.02, 0.01, 0.05                            # at the motor, per output rad/s x N
    tau = J * N * a + Fv * N * v + Fc * np.tanh(v / 0.01) + 0.4 * Fc * np.cos(40 * th + 0.3)
    rng = np.random.default_rng(5)
    q = 2 * np.pi / 2 ** 22
    p = tmp_path / "out_only.csv"
    logio.write_log(p, {"t_s": t, "load_angle_rad": np.round(th / q) * q,
                        "motor_torque_Nm": tau + rng.normal(0, 1e-4, t.size)},
                    {"gear_ratio": N, "sample_period_s": dt})
    out = tmp_path / "o.json"
    assert cli.main(["discrepancy", str(p), "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["signals"] == "output" and r["identifiability"]["cogging_torque"] == NOT_IDENTIFIABLE
    assert "cogging_torque" not in r["named_effects"]
    assert "cogging_torque" not in {c["effect"] for c in r["first_ranking"]}


def test_named_effect_goes_into_an_axis_file_the_simulator_confirms(tmp_path: Path, cog_log: Path) -> None:
    """The named effect is written into AXIS.updated.toml (the identified baseline with the
    effect's section on), the C simulator replays the log's torque through the axis before
    and after, and the gap shrinks; with the user's own axis file the effect goes into a copy
    of it and the rest of the file is kept."""
    import tomllib
    from hdservo import sim
    out = tmp_path / "o.json"
    assert cli.main(["discrepancy", str(cog_log), "--json", str(out), "--out-dir", str(tmp_path / "p")]) == 0
    r = json.loads(out.read_text())
    it = r["iterations"][0]
    assert it["named_effect"] == "cogging_torque"
    assert it["sim_rms_after_rad"] < 0.7 * it["sim_rms_before_rad"] and it["simulator_confirmed"] is True
    assert it["model_sim_rms_after_rad"] < it["model_sim_rms_before_rad"]
    upd = Path(r["simulator"]["updated_axis"])
    assert upd == tmp_path / "cog.updated.toml" and Path(it["axis_before"]) == tmp_path / "cog.baseline.toml"
    ax = tomllib.loads(upd.read_text())
    assert ax["cogging"]["enabled"] is True and ax["cogging"]["h1_order"] == 36.0
    # the plant's 3 x 0.004 N.m at phase 0.3 rad (discrepancy_cases, size 1 is 6x)
    assert ax["cogging"]["h1_amp_Nm"] == pytest.approx(6 * 0.004, rel=0.25)
    assert abs((ax["cogging"]["h1_phase_rad"] - 0.3 + 3.1416) % 6.2832 - 3.1416) < 0.3
    assert sim.axis_param("cogging.h1_amp_Nm", str(upd)) == ax["cogging"]["h1_amp_Nm"]   # a valid axis file
    assert (tmp_path / "p" / "simulator_1_cogging_torque.png").stat().st_size > 0
    # the user's axis file: the effect's section goes into a copy, the user's keys stay
    mine = tmp_path / "mine.toml"
    mine.write_text((tmp_path / "cog.baseline.toml").read_text().replace('name = "cog identified baseline"',
                                                                         'name = "my axis"'))
    out2 = tmp_path / "o2.json"
    assert cli.main(["discrepancy", str(cog_log), "--json", str(out2), "--axis", str(mine),
                     "--axis-out", str(tmp_path / "ax")]) == 0
    r2 = json.loads(out2.read_text())
    it2 = r2["iterations"][0]
    # (the user's file keeps its own inertias and spring: here the baseline's, which the missing
    # cogging biased, so the gap shrinks less than with the re-fitted baseline above)
    assert it2["axis_before"] == str(mine) and it2["sim_rms_after_rad"] < it2["sim_rms_before_rad"]
    ax2 = tomllib.loads((tmp_path / "ax" / "mine.updated.toml").read_text())
    assert ax2["axis"]["name"] == "my axis" and ax2["cogging"]["enabled"] is True


def test_bad_axis_file_is_one_line(tmp_path: Path, cog_log: Path, capsys) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[stiffness]\nk9_Nm_per_rad = 3\n")
    out = tmp_path / "o.json"
    capsys.readouterr()
    assert cli.main(["discrepancy", str(cog_log), "--json", str(out), "--axis", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "k9_Nm_per_rad" in err[0] and not out.exists()


def test_stop_rule_keeps_a_later_effect_only_when_the_simulator_confirms_it() -> None:
    from hdservo.discrepancy import closeloop as c
    assert c.confirm(1.0, 0.85) and not c.confirm(1.0, 0.95) and not c.confirm(float("nan"), 0.1)
    assert not c.confirm(1.0, float("nan"))


def test_effect_parameters_written_are_fitted_on_the_simulators_replay(tmp_path: Path, cog_log: Path) -> None:
    """The axis file gets the effect's parameters that make the C simulator's replay agree
    best, not the regression's coefficients as they come: a regression that got the size
    wrong (as the hysteresis and compliance fits do on closed-loop logs) is corrected by the
    replay fit, and the gap after is smaller than with the regression's parameters."""
    import tomllib
    from hdservo import logio
    from hdservo.discrepancy import closeloop, signals, workflow
    sig = signals.from_log(logio.read_log(cog_log, require_tag=False), "two_mass")
    res = workflow.run(sig)
    assert res.named[:1] == ["cogging_torque"]
    p = res.iterations[0]["params"]
    amps = [k for k in p if k.endswith("_amp_Nm")]
    assert amps
    for k in amps:
        p[k] *= 0.3
    c = closeloop.close(res, tmp_path, "cog")
    ax = tomllib.loads((tmp_path / "cog.updated.toml").read_text())
    # the plant's 6 x 0.004 N.m (discrepancy_cases, size 1), not 0.3 x the regression's
    assert ax["cogging"]["h1_amp_Nm"] == pytest.approx(6 * 0.004, rel=0.3)
    rec = c.iterations[0]
    assert rec["sim_rms_after_rad"] < 0.8 * rec["replay_fit"]["sim_rms_regression_rad"]
    assert rec["sim_gap_after_rad"] < rec["sim_gap_before_rad"] and rec["sim_floor_rad"] > 0
    # a first name the simulator cannot confirm (a slow current loop this log does not have:
    # the replay fit can only bring its bandwidth up to 10x, still a lag the plant lacks) is
    # dropped by the stop rule, like a later one
    res.iterations[0].update({"named_effect": "current_loop_lag", "params": {"bandwidth_Hz": 20.0}})
    c2 = closeloop.close(res, tmp_path / "wrong", "cog")
    assert [d["named_effect"] for d in c2.dropped] == ["current_loop_lag"] and c2.iterations == []
    assert c2.updated is None
    closeloop.apply(res, c2)
    assert res.named == [] and any("current_loop_lag is not kept" in n for n in res.notes)
