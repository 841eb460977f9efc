"""A Coulomb asymmetry next to a constant torque offset: what the signals can show.

Friction whose Coulomb and static levels differ between directions is, in motion and at
standstill, symmetric friction at the mean level plus a constant torque of half the
difference.  A rigid baseline carries an unknown constant load (its offset), so it cannot
tell the two apart: the identifiability table lists the Coulomb part as not identifiable
there, the workflow says so, and the held-apart corpus (which hides a Coulomb-only
asymmetry) does not count such logs as hidden effects the signals can show.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hdservo import cli, sim
from hdservo.discrepancy import NOT_IDENTIFIABLE, not_identifiable_parts
from hdservo.discrepancy.closeloop import axis_text
from oracles import discrepancy_cases as cases
from oracles import discrepancy_corpus as corpus


def _motor_angle(axis: dict, torque: np.ndarray, tmp: Path, name: str) -> np.ndarray:
    f = tmp / f"{name}.toml"
    f.write_text(axis_text(axis, name))
    with sim.Plant(str(f), seed=1) as p:
        rows = p.run(torque, corpus.PLANT_DT)
    return rows[:, sim.open_loop_columns().index("motor_angle_rad")]


def test_coulomb_asymmetry_moves_the_plant_as_a_constant_load(tmp_path: Path) -> None:
    """The project's simulator, motor-side friction fc+ = 1, fc- = 0.6 (fs likewise), driven by
    a torque with reversals and holds, moves exactly as the same plant with symmetric
    friction 0.8 driven by that torque less 0.2 (a constant load), holds included; with
    the symmetric friction and the same torque it moves differently."""
    ax = corpus.draw(70).axis                  # a catalogue axis (its hidden asymmetry replaced below)
    ax = {k: dict(v) for k, v in ax.items()}
    for k in ("encoder_motor", "encoder_load"):
        ax[k]["noise_counts"] = 0.0
    ax["current_sensor"]["noise_A"] = 0.0
    N = ax["gear"]["ratio"]
    fl = ax["friction_load"]
    fl["fc_neg_Nm"] = fl["fs_neg_Nm"] = fl["fc_pos_Nm"]       # the load side symmetric
    fp = ax["friction_motor"]["fc_pos_Nm"]
    asym = {k: dict(v) for k, v in ax.items()}
    asym["friction_motor"].update(fc_pos_Nm=fp, fs_pos_Nm=fp, fc_neg_Nm=0.6 * fp, fs_neg_Nm=0.6 * fp)
    sym = {k: dict(v) for k, v in ax.items()}
    sym["friction_motor"].update(fc_pos_Nm=0.8 * fp, fs_pos_Nm=0.8 * fp, fc_neg_Nm=0.8 * fp, fs_neg_Nm=0.8 * fp)
    t = np.arange(int(2.0 / corpus.PLANT_DT)) * corpus.PLANT_DT
    # reversals through the static band and holds inside it
    tau = (fp + 0.4 * fl["fc_pos_Nm"] / N) * 1.6 * np.sin(2 * np.pi * 1.5 * t) * (np.sin(2 * np.pi * 0.5 * t) > -0.5)
    a = _motor_angle(asym, tau, tmp_path, "asym")
    b = _motor_angle(sym, tau - 0.2 * fp, tmp_path, "sym_load")
    c = _motor_angle(sym, tau, tmp_path, "sym")
    span = float(np.ptp(a))
    assert span > 1.0                          # it moves (motor rad) ...
    assert np.max(np.abs(a - b)) <= 1e-6 * span  # ... identically to symmetric friction + a constant load
    assert np.max(np.abs(a - c)) > 0.05 * span   # and the asymmetry is not nothing


def test_not_identifiable_parts_follow_the_offset() -> None:
    """The Coulomb part is not identifiable exactly when the baseline has a constant offset."""
    assert set(not_identifiable_parts("rigid")["asymmetric_friction"]) == {"coulomb"}
    assert set(not_identifiable_parts("rigid", True)["asymmetric_friction"]) == {"coulomb"}
    assert not_identifiable_parts("rigid", False) == {}
    assert not_identifiable_parts("two_mass") == {}
    assert set(not_identifiable_parts("two_mass", True)["asymmetric_friction"]) == {"coulomb"}


@pytest.mark.parametrize("seed, angles, shown", [(70, "motor", []), (233, "output", []),
                                                 (21, "both", ["asymmetric_friction"])])
def test_corpus_counts_a_coulomb_asymmetry_only_where_it_is_identifiable(seed: int, angles: str,
                                                                         shown: list[str]) -> None:
    """Calibration seeds with a Coulomb-only asymmetry: on a one-encoder log (rigid baseline
    with its offset) it is not a hidden effect the signals can show; on a two-encoder log
    (two-mass baseline, no offset) it is."""
    c = corpus.draw(seed)
    assert [e for e, _ in c.hidden] == ["asymmetric_friction"] and c.angles == angles
    fm = c.axis["friction_motor"]
    assert fm["fc_neg_Nm"] < fm["fc_pos_Nm"]   # the corpus' asymmetry: Coulomb (and static) only
    assert c.identifiable() == shown


@pytest.fixture(scope="module")
def motor_only_log(tmp_path_factory) -> Path:
    from hdservo import logio
    d = tmp_path_factory.mktemp("asym")
    src = cases.make_log(cases.Case("cogging_torque", seed=1, size=1, duration_s=4.0), d / "cog.csv")
    log = logio.read_log(src)
    p = d / "motor.csv"
    logio.write_log(p, {"t_s": log.t, "motor_angle_rad": log["motor_angle_rad"],
                        "motor_torque_Nm": log["motor_torque_Nm"]},
                    {"gear_ratio": log.meta["gear_ratio"], "sample_period_s": log.meta["sample_period_s"]})
    return p


def test_workflow_says_the_coulomb_part_is_not_identifiable(tmp_path: Path, motor_only_log: Path, capsys) -> None:
    """A motor-only log: the JSON's ``not_identifiable_parts`` and the terminal name the Coulomb
    part of the asymmetry; with ``offset = false`` (no constant load) they do not."""
    out = tmp_path / "o.json"
    capsys.readouterr()
    assert cli.main(["discrepancy", str(motor_only_log), "--json", str(out), "--no-simulator"]) == 0
    r = json.loads(out.read_text())
    assert r["identifiability"]["asymmetric_friction"] == "identifiable"     # its viscous part is ranked
    assert set(r["not_identifiable_parts"]["asymmetric_friction"]) == {"coulomb"}
    text = capsys.readouterr().out
    assert f"asymmetric_friction: its coulomb part is {NOT_IDENTIFIABLE}" in text
    m = tmp_path / "m.toml"
    m.write_text("[model]\noffset = false\n")
    assert cli.main(["discrepancy", str(motor_only_log), "--model", str(m), "--json", str(out),
                     "--no-simulator"]) == 0
    assert json.loads(out.read_text())["not_identifiable_parts"] == {}
    assert "coulomb part" not in capsys.readouterr().out
