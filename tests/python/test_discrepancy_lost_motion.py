"""The lost-motion test of a backlash: the motor's travel through the zone at every reversal
of the transmitted torque, resolved by the motor encoder where the zone spans a few counts
of the output encoder (:func:`hdservo.discrepancy.residuals.lost_motion`).

Synthetic two-mass logs: a motor following a prescribed motion drives a load through a
spring with (or without) a dead zone; the output encoder is 18-bit and the zone 3 of its
counts across; the reflected motor inertia is ten times the load's, so the transmitted
torque is a small difference of motor-side terms.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hdservo import logio
from hdservo.discrepancy import effects as fx
from hdservo.discrepancy import regression as bl
from hdservo.discrepancy import residuals, signals

N = 50.0
K = 2000.0              # N.m/rad at the output
C = 2.0                 # spring damping, N.m.s/rad
J_M, J_L = 2e-4, 0.05   # kg.m^2
FC_M, FV_L = 0.02, 0.5  # motor Coulomb N.m, load viscous N.m.s/rad
FS = 2000.0
Q_OUT = 2 * math.pi / 2 ** 18
Q_MOT = 2 * math.pi / 2 ** 20
#: Half gap: the whole zone is 3 counts of the 18-bit output encoder.
HALF_GAP = 1.5 * Q_OUT


def _log(tmp_path: Path, half_gap: float, name: str, load: bool = True) -> signals.Signals:
    """Simulate 30 s (20 sub-steps per sample) and write the quantised log."""
    sub = 20
    h = 1.0 / FS / sub
    n = int(30.0 * FS)
    tt = np.arange(n * sub) * h
    # motor motion (output radians): two sines, so the reversals fall at varied torques
    xo = 0.3 * np.sin(2 * np.pi * 0.9 * tt) + 0.05 * np.sin(2 * np.pi * 2.3 * tt + 0.4)
    vo = np.gradient(xo, h)
    ao = np.gradient(vo, h)
    thl, wl = 0.0, float(vo[0])
    th_l = np.empty(n * sub)
    ts = np.empty(n * sub)
    for i in range(n * sub):
        phi = xo[i] - thl
        z = phi - np.clip(phi, -half_gap, half_gap)
        t_s = K * z + (C * (vo[i] - wl) if z != 0.0 else 0.0)
        wl += h * (t_s - FV_L * wl) / J_L
        thl += h * wl
        th_l[i], ts[i] = thl, t_s
    k = slice(None, None, sub)
    wm = vo[k] * N
    tau = J_M * ao[k] * N + FC_M * np.sign(wm) + ts[k] / N
    cols = {"t_s": np.arange(n) / FS, "motor_angle_rad": np.round(xo[k] * N / Q_MOT) * Q_MOT,
            "motor_torque_Nm": tau}
    if load:
        cols["load_angle_rad"] = np.round(th_l[k] / Q_OUT) * Q_OUT
    p = tmp_path / f"{name}.csv"
    logio.write_log(p, cols, {"gear_ratio": N, "sample_period_s": 1.0 / FS})
    return signals.from_log(logio.read_log(p, require_tag=False))


def _test(sig: signals.Signals) -> dict[str, float]:
    d = bl.make_design(sig)
    fit = bl.solve(d, bl.baseline_columns(d), {e: 1.0 for e in d.equations})
    return residuals.lost_motion(d, fit.params())


def test_a_zone_of_three_output_counts_is_found_by_the_motor_travel(tmp_path: Path) -> None:
    lm = _test(_log(tmp_path, HALF_GAP, "gap"))
    assert lm["lost_motion_events"] >= residuals.LOST_MOTION_MIN_EVENTS
    assert lm["lost_motion_p_value"] < 1e-3
    # the band's edges cut into the zone's impacts: about 60 % of the gap is seen
    assert 0.4 < lm["lost_motion_half_gap_rad"] / HALF_GAP < 1.2
    assert 1.0 < lm["lost_motion_counts"] < 4.0


def test_a_spring_without_a_zone_shows_no_lost_motion(tmp_path: Path) -> None:
    lm = _test(_log(tmp_path, 0.0, "clean"))
    assert lm["lost_motion_events"] >= residuals.LOST_MOTION_MIN_EVENTS
    assert lm["lost_motion_p_value"] > 0.01
    assert abs(lm["lost_motion_counts"]) < 1.0


def test_the_backlash_candidate_reports_the_lost_motion(tmp_path: Path) -> None:
    sig = _log(tmp_path, HALF_GAP, "gap")
    d = bl.make_design(sig)
    fit = bl.solve(d, bl.baseline_columns(d), {e: 1.0 for e in d.equations})
    ev = fx.Backlash().own_evidence(d, fit, fx.Backlash.variant_at(d, HALF_GAP))
    assert ev == residuals.lost_motion(d, fit.params())
    assert ev["lost_motion_events"] >= residuals.LOST_MOTION_MIN_EVENTS
    # reported only: the size rule does not count it
    assert "twist_fraction" not in ev


def test_a_motor_only_log_has_no_lost_motion_test(tmp_path: Path) -> None:
    sig = _log(tmp_path, HALF_GAP, "motor", load=False)
    assert _test(sig) == {}
