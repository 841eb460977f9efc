"""The simulator's confirmation of a one-sided effect: a cogging torque moves the motor
angle and leaves the load angle to the rest of the model, so its first name is also
confirmed on the motor angle's replay gap alone (``closeloop.ONE_SIDED``).

Calibration seed 56 of the corpus (never a held-apart seed): the drive in feedback
configuration 1 with a hidden cogging torque (1.24x), logged at 1 kHz with a 16-bit motor
and a 19-bit output encoder.  The workflow names the cogging (68-70 % of both residuals);
its axis file cuts the replay's stacked gap by about 6 % (the load angle's error, which
cogging does not touch, is the larger part) and the motor angle's by about 30 %.
"""
from __future__ import annotations

from pathlib import Path

from hdservo import logio
from hdservo.discrepancy import closeloop, signals, workflow
from oracles import discrepancy_corpus as corpus

SEED = 56


def test_cogging_first_name_is_confirmed_on_the_motor_angle(tmp_path: Path) -> None:
    case = corpus.draw(SEED)
    assert [e for e, _ in case.hidden] == ["cogging_torque"] and case.angles == "both"
    log = corpus.make_log(case, tmp_path / "l.csv")
    res = workflow.run(signals.from_log(logio.read_log(log, require_tag=False), case.structure))
    assert res.named[:1] == ["cogging_torque"]
    cl = closeloop.close(res, tmp_path / "axes", "l")
    # the cogging is kept; a later look-alike the workflow offers at the later size rule
    # (an asymmetric friction) is the simulator's to drop
    assert "cogging_torque" not in [d["named_effect"] for d in cl.dropped]
    assert [x["named_effect"] for x in cl.iterations] == ["cogging_torque"]
    (it,) = [x for x in cl.iterations if x["named_effect"] == "cogging_torque"]
    # the stack alone would not confirm it ...
    assert not closeloop.confirm(it["sim_rms_before_rad"], it["sim_rms_after_rad"])
    # ... its own side's angle does
    side = it["sim_side"]
    assert side["side"] == "motor"
    assert closeloop.confirm(side["before_rad"], side["after_rad"])
    assert it["confirmed"] is True
    assert cl.updated is not None and "[cogging]" in cl.updated.read_text()
