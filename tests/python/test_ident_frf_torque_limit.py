"""The frequency-response experiment over CAN on a gear whose friction nearly fills the drive's torque limit.

The CSF-40-120 drawn by ``hdservo.axisgen`` with seed 71 needs about 50 N.m output torque to hold
the FRF's 0.08 rad/s bias speed (sliding friction of both sides plus the unbalance) against the
drive's default ``torque_limit`` of 60 N.m; the multisine's torque peaks then clamp for long
enough that the drive trips on torque saturation (fault 1, 0x5F00:10).  The FRF runs with the
drive's limit raised to at least the gear's torque (``--torque-max``) and the drive's own limit
restored afterwards (docs/identification.md "Frequency response").
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hdservo import axisgen
from hdservo.cli import main
from hdservo.ident import experiments as ex
from hdservo.ident import pipeline as pl

#: the axisgen seed whose first axis tripped the drive in the FRF
SEED = 71


class _Recorder:
    """Runner stand-in: records the designs the pipeline asks for (no drive)."""

    def __init__(self) -> None:
        self.designs: list = []

    def run(self, design):  # noqa: ANN001, ANN201 - the pipeline stops at the first design
        self.designs.append(design)
        raise RuntimeError("recorded")


def test_frf_plan_asks_for_the_gear_torque_as_the_drive_limit() -> None:
    """The pipeline's FRF design carries --torque-max as the lowest torque limit, unless the user fixed the limit."""
    for fixed, want in (((), 199.0), (("torque_limit",), 0.0)):
        rec = _Recorder()
        p = pl.Pipeline(runner=rec, settings=pl.Settings(torque_max_Nm=199.0, tune_velocity_loop=False,
                                                         fixed_gains=fixed))
        with pytest.raises(RuntimeError, match="recorded"):
            p.frf()
        (design,) = rec.designs
        assert isinstance(design, ex.FRFExcitation)
        plan = design.plan(120.0)
        assert len(plan) == len(design.amplitudes_rad_s)
        assert all(seg["torque_limit_Nm"] == want for seg in plan)


def test_frf_over_can_runs_on_the_high_friction_unseen_axis(tmp_path: Path, capsys) -> None:
    """`identify frf --sim AXIS --torque-max 1.3 T2` on axisgen seed 71: no fault, unclamped torque, limit restored."""
    (axis,) = axisgen.write_axes(tmp_path / "axes", 1, SEED)
    gen = axisgen.random_axes(1, SEED)[0]
    summ = gen.summary()
    # the precondition of the case: friction + unbalance take most of the drive's default 60 N.m
    assert summ["fc_total_Nm"] + gen.params["gravity"]["mgl_Nm"] > 0.75 * 60.0
    tmax = 1.3 * gen.params["stiffness"]["t2_Nm"]
    js, data = tmp_path / "r.json", tmp_path / "data"
    rc = main(["identify", "frf", "--torque-max", repr(tmax), "--json", str(js), "--save-data", str(data), "-q",
               f"--sim={axis}"])
    err = capsys.readouterr().err
    assert rc == 0, err
    rep = json.loads(js.read_text())
    frf = rep["results"]["frf"]
    assert len(frf) == 2
    log = np.genfromtxt(data / "frf.csv", delimiter=",", names=True)
    peak = float(np.max(np.abs(log["torque_cmd_Nm"])))
    # the torque the multisine needed exceeds the drive's default limit, and never reached the raised one
    assert 60.0 < peak < tmax


def test_drive_runner_restores_the_drive_limit_after_the_frf(tmp_path: Path) -> None:
    """A short FRF through the runner: the raised limit holds during the experiment only."""
    from hdservo.ident import tuning as tun
    from hdservo.ident.drive_runner import DriveSession

    (axis,) = axisgen.write_axes(tmp_path / "axes", 1, SEED)
    tmax = 1.3 * axisgen.random_axes(1, SEED)[0].params["stiffness"]["t2_Nm"]
    with DriveSession(axis=str(axis), seed=1) as r:
        before = float(r.drive.get_param("torque_limit"))
        r.set_gains(tun.velocity_pi(r.commissioned_inertia_kgm2()))
        d = r.run(ex.FRFExcitation(amplitudes_rad_s=(0.02,), periods=2, torque_limit_Nm=tmax))
        after = float(r.drive.get_param("torque_limit"))
    assert before == pytest.approx(60.0)
    assert after == before
    assert float(np.max(np.abs(d.columns["torque_cmd_Nm"]))) > before + 3.0   # unclamped above the old limit
