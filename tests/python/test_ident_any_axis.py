"""Identification on an axis the drive's default gains were not made for (csf17_50).

The drive's velocity-loop defaults suit the reference axis (1.3 kg.m^2); on the
CSF-17-50 class axis (0.175 kg.m^2) they limit-cycle and the friction sweep is
noise.  `hdservo identify` sets the velocity PI from the axis' inertia
(hdservo.ident.tuning) before the closed-loop experiments, with no gain given
by the user.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from hdservo import closedloop_cases as bl
from hdservo.cli import main
from hdservo.ident import pipeline as pl
from hdservo.ident import tuning as tun

import ident_truth as truth

#: Tolerances of the friction identified over CAN, relative to the axis file's truth
#: (as docs/identification.md: Fc/Fs 3 %, viscous 5 %, vs 10 %).
TOL = {"fs_pos_Nm": 0.03, "fs_neg_Nm": 0.03, "fc_pos_Nm": 0.03, "fc_neg_Nm": 0.03,
       "viscous_Nms_per_rad": 0.05, "vs_rad_s": 0.10}


def test_friction_over_can_on_csf17_50_without_given_gains(tmp_path: Path, capsys) -> None:
    """`identify friction --sim csf17_50` as the demo runs it (no --gain): within TOL of the truth."""
    js = tmp_path / "r.json"
    rc = main(["identify", "friction", f"--sim={truth.AXES['csf17_50']}", "--seed", "3", "--json", str(js), "-q"])
    capsys.readouterr()
    assert rc == 0
    rep = json.loads(js.read_text())
    got = rep["results"]["stribeck"]
    want = truth.friction_total(truth.axis("csf17_50"))
    err = {k: got[k] / want[k] - 1 for k in TOL}
    assert all(abs(err[k]) <= TOL[k] for k in TOL), err
    tuning = rep["results"]["velocity_loop_tuning"]
    a = truth.axis("csf17_50")
    j = a["load"]["jl_kgm2"] + a["gear"]["ratio"] ** 2 * a["motor"]["jm_kgm2"]
    assert tuning[0]["source"] == "commissioned j_total"
    assert tuning[0]["j_total_kgm2"] == pytest.approx(j, rel=1e-3)   # the drive's j_total (Q16.16)


def test_velocity_pi_is_the_baseline_design_rule() -> None:
    """The identification's loop is the PID baseline's velocity PI for the same inertia."""
    a = truth.axis("csf17_50")
    j = a["load"]["jl_kgm2"] + a["gear"]["ratio"] ** 2 * a["motor"]["jm_kgm2"]
    base = bl.axis_controller(str(truth.AXES["csf17_50"]))["gains"]
    g = tun.velocity_pi(j)
    assert g["vel_kp"] == pytest.approx(base["vel_kp"], rel=1e-12)
    assert g["vel_ki"] == pytest.approx(base["vel_ki"], rel=1e-12)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            tun.velocity_pi(bad)


@dataclass
class _Runner:
    """A runner that records the gains it is given (no experiment is run)."""

    j: float
    set: list = field(default_factory=list)

    def commissioned_inertia_kgm2(self) -> float:
        return self.j

    def set_gains(self, gains: dict) -> None:
        self.set.append(dict(gains))


@dataclass
class _FRF:
    amplitude_rad_s: float
    j1_kgm2: float
    j2_kgm2: float


def test_frf_inertia_replaces_a_wrong_commissioned_one() -> None:
    """Commissioned 1.3 kg.m^2 on a 0.175 kg.m^2 axis: after the FRF the loop follows the identified J."""
    r = _Runner(1.3)
    p = pl.Pipeline(runner=r)
    p._tune_commissioned()
    assert r.set[-1]["vel_kp"] == pytest.approx(tun.velocity_pi(1.3)["vel_kp"])
    p.results["frf"] = [_FRF(0.04, 0.08, 0.1), _FRF(0.02, 0.075, 0.1)]      # smallest amplitude used
    p._retune_from_frf()
    assert len(r.set) == 2 and r.set[-1]["vel_kp"] == pytest.approx(tun.velocity_pi(0.175)["vel_kp"])
    assert p.results["tuning"][-1]["source"] == "identified by the FRF"
    # within the tolerance: no second retune
    p.results["frf"] = [_FRF(0.02, 0.08, 0.1)]
    p._retune_from_frf()
    assert len(r.set) == 2


def test_user_gains_are_kept_and_tuning_can_be_off() -> None:
    r = _Runner(0.175)
    p = pl.Pipeline(runner=r, settings=pl.Settings(fixed_gains=("vel_kp",)))
    p._tune_commissioned()
    assert r.set == [{"vel_ki": tun.velocity_pi(0.175)["vel_ki"]}]
    r2 = _Runner(0.175)
    p2 = pl.Pipeline(runner=r2, settings=pl.Settings(tune_velocity_loop=False))
    p2._tune_commissioned()
    assert r2.set == [] and p2.results["tuning"] == []
    p2._retune_from_frf()
    assert r2.set == []


def test_unusable_frf_inertia_is_ignored() -> None:
    assert tun.frf_inertia([]) is None
    assert tun.frf_inertia([_FRF(0.02, -0.1, 0.3)]) is None
    assert tun.frf_inertia([_FRF(0.02, float("nan"), 0.3)]) is None
    assert tun.frf_inertia([_FRF(0.02, 0.1, 0.3)]) == pytest.approx(0.4)


def test_locked_setpoints_reverse_only_at_the_turning_points() -> None:
    """Turning points half a CAN step off the grid (a median of an even number of samples): the
    set-points the drive receives (rounded to 1/1000 of rated, as RPDO3) reverse only at the
    turning points, so the stretch through T = 0 stays one stretch for the hysteresis-loss fit."""
    import numpy as np

    from hdservo.ident import drive_runner as dr
    from hdservo.ident.hysteresis import split_reversals
    lsb = 67.0 / 1000.0
    for k in range(-40, 40):
        for a in (68.407, 68.4, 30.1234):
            pts = [a, (k + 0.5) * lsb, -a, (k + 0.5) * lsb]
            prof = dr.locked_setpoints(pts, 60.0, 0.002, lsb)
            sent = np.array([round(x / lsb) for x in prof], dtype=float) * lsb     # as DriveRunner._rpdo3
            # 0 -> a up, a -> b -> -a down (one stretch through T = 0), -a -> b up: three stretches
            assert len(split_reversals(sent)) == 3, (a, k)
