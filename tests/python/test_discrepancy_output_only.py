"""Output-encoder-only logs: a current-loop lag is not identifiable there.

The output angle sees the motor torque through the gear's spring; below the torsional
mode (30-70 Hz on the catalogue axes) the spring passes the torque like a second-order
low-pass whose phase is that of a delay of about 2 zeta / omega_0, 0.5-1.5 ms: the phase
of a 100-300 Hz current loop.  So on a clean output-only log the rigid model's lag
candidate fits a lag the current loop does not have.
"""
from __future__ import annotations

import math
from pathlib import Path

from hdservo import logio
from hdservo.discrepancy import IDENTIFIABLE, NOT_IDENTIFIABLE, effects, signals, workflow
from oracles import discrepancy_corpus as corpus

#: A calibration log (never a held-apart one): output encoder only (23 bits), plain P-PI
#: cascade at 1 kHz logged at 1 kHz, nothing hidden (the current loop at 2 kHz, T = 80 us).
SEED = 279


def _signals(tmp_path: Path) -> tuple[corpus.CorpusCase, signals.Signals]:
    case = corpus.draw(SEED)
    assert case.angles == "output" and case.hidden == []
    p = corpus.make_log(case, tmp_path / "l.csv")
    return case, signals.from_log(logio.read_log(p, require_tag=False), case.structure)


def test_clean_output_only_log_shows_the_springs_delay_as_a_lag(tmp_path: Path, monkeypatch) -> None:
    case, sig = _signals(tmp_path)
    res = workflow.run(sig, lib=[effects.CurrentLag()])
    # whatever the table says, the lag is not ranked on an output-only log ...
    assert res.ranking_first == []
    assert res.identifiability["current_loop_lag"] == NOT_IDENTIFIABLE
    assert "current_loop_lag" in res.to_json()["not_identifiable"]
    assert res.named == []
    # ... because its candidate, ranked on the same log, takes up the spring's phase: a lag
    # ten times the current loop's, with strong evidence, on a log without any
    monkeypatch.setitem(IDENTIFIABLE, "output", IDENTIFIABLE["output"] + ("current_loop_lag",))
    r = workflow.run(sig, lib=[effects.CurrentLag()])
    c = r.ranking_first[0]
    T_loop = 1.0 / (2 * math.pi * case.axis["current_loop"]["bandwidth_Hz"])
    assert c["effect"] == "current_loop_lag" and c["delta_bic"] > 50.0
    assert c["hyper"]["time_constant_s"] > 5 * T_loop


def test_identifiability_table_keeps_the_lag_where_the_motor_angle_is_logged() -> None:
    assert "current_loop_lag" not in IDENTIFIABLE["output"]
    assert "current_loop_lag" in IDENTIFIABLE["motor"] and "current_loop_lag" in IDENTIFIABLE["both"]
