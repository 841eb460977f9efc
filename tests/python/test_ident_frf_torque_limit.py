"""Identification over CAN on a gear whose friction nearly fills the drive's torque limit.

The CSF-40-120 drawn by ``hdservo.axisgen`` with seed 71 needs about 50 N.m output torque to hold
the FRF's 0.08 rad/s bias speed (sliding friction of both sides plus the unbalance) against the
drive's default ``torque_limit`` of 60 N.m; the multisine's torque peaks then clamp for long
enough that the drive trips on torque saturation (fault 1, 0x5F00:10), and the TE rotation after
it does the same.  The identification runs with the drive's limit raised to at least the gear's
torque (``--torque-max``) and the drive's own limit restored when it ends
(docs/identification.md "The experiments' torque limit").
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pytest

from hdservo import axisgen
from hdservo.cli import main
from hdservo.ident import experiments as ex
from hdservo.ident import pipeline as pl
from hdservo.ident.drive_runner import DriveSession

#: the axisgen seed whose first axis tripped the drive in the FRF
SEED = 71


class _Recorder:
    """Runner stand-in with a settable torque limit: records the gains and designs (no drive)."""

    def __init__(self, limit_Nm: float) -> None:
        self.limit_Nm = limit_Nm
        self.gains: dict[str, float] = {}
        self.designs: list[Any] = []

    def torque_limit_Nm(self) -> float:
        return self.limit_Nm

    def set_gains(self, gains: Mapping[str, float]) -> None:
        self.gains.update(gains)

    def commissioned_inertia_kgm2(self) -> float:
        return 3.94

    def run(self, design: Any) -> Any:
        self.designs.append(design)
        raise RuntimeError("recorded")


@pytest.mark.parametrize("drive_limit, fixed, want", [(60.0, (), 199.0), (60.0, ("torque_limit",), None),
                                                      (250.0, (), None)])
def test_first_experiment_runs_with_the_gear_torque_as_the_limit(drive_limit: float, fixed: tuple[str, ...],
                                                                  want: float | None) -> None:
    """Before the first experiment the limit becomes --torque-max when higher, unless the user fixed it."""
    rec = _Recorder(drive_limit)
    p = pl.Pipeline(runner=rec, settings=pl.Settings(torque_max_Nm=199.0, fixed_gains=fixed))
    with pytest.raises(RuntimeError, match="recorded"):
        p.frf()
    assert isinstance(rec.designs[0], ex.FRFExcitation)
    assert rec.gains.get("torque_limit") == want
    assert "vel_kp" in rec.gains                     # the velocity loop is still tuned
    got = pl.summary(p.results)["experiment_torque_limit"]
    assert got["gear_torque_Nm"] == 199.0
    if "torque_limit" not in fixed:
        assert got["experiments_Nm"] == max(drive_limit, 199.0)


def test_frf_over_can_runs_on_the_high_friction_unseen_axis(tmp_path: Path, capsys) -> None:
    """`identify frf --sim AXIS --torque-max 1.3 T2` on axisgen seed 71: no fault, unclamped torque."""
    (axis,) = axisgen.write_axes(tmp_path / "axes", 1, SEED)
    gen = axisgen.random_axes(1, SEED)[0]
    # the precondition of the case: friction + unbalance take most of the drive's default 60 N.m
    assert gen.summary()["fc_total_Nm"] + gen.params["gravity"]["mgl_Nm"] > 0.75 * 60.0
    tmax = 1.3 * gen.params["stiffness"]["t2_Nm"]
    js, data = tmp_path / "r.json", tmp_path / "data"
    rc = main(["identify", "frf", "--torque-max", repr(tmax), "--json", str(js), "--save-data", str(data), "-q",
               f"--sim={axis}"])
    err = capsys.readouterr().err
    assert rc == 0, err
    rep = json.loads(js.read_text())
    assert len(rep["results"]["frf"]) == 2
    log = np.genfromtxt(data / "frf.csv", delimiter=",", names=True)
    peak = float(np.max(np.abs(log["torque_cmd_Nm"])))
    # the torque the multisine needed exceeds the drive's default limit, and never reached the raised one
    assert 60.0 < peak < tmax


def test_the_drive_limit_comes_back_when_the_runner_closes(tmp_path: Path) -> None:
    """The raised limit is the runner's: after close() the drive has its own 60 N.m again."""
    (axis,) = axisgen.write_axes(tmp_path / "axes", 1, SEED)
    with DriveSession(axis=str(axis), seed=1) as r:
        before = r.torque_limit_Nm()
        r.set_gains({"torque_limit": 199.0})
        assert r.torque_limit_Nm() == pytest.approx(199.0)
        r.close()
        after = r.torque_limit_Nm()
    assert before == pytest.approx(60.0)
    assert after == before
