"""Figure-of-merit calculators of hdservo.procedures.metrics on synthetic signals with known answers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hdservo.procedures import metrics as mt


def test_iso230_2_known_figures() -> None:
    targets = np.array([0.0, 10.0, 20.0])
    # deviations: up runs +1 +-0.5, down runs -1 +-0.5 (two runs: s = 0.5*sqrt(2))
    up = targets + np.array([[1.5, 1.5, 1.5], [0.5, 0.5, 0.5]])
    down = targets + np.array([[-0.5, -0.5, -0.5], [-1.5, -1.5, -1.5]])
    r = mt.iso230_2(targets, up, down)
    s = 0.5 * math.sqrt(2.0)
    assert r["B"] == pytest.approx(2.0)
    assert r["R_up"] == pytest.approx(4 * s)
    assert r["R"] == pytest.approx(max(2 * s + 2 * s + 2.0, 4 * s))
    assert r["A"] == pytest.approx((1 + 2 * s) - (-1 - 2 * s))
    assert r["E"] == pytest.approx(2.0)
    assert r["M"] == pytest.approx(0.0)


def test_iso230_2_systematic_error() -> None:
    targets = np.linspace(0, 110, 12)
    dev = 0.1 * targets                       # a scale error, perfectly repeatable, no reversal
    up = np.tile(targets + dev, (5, 1))
    r = mt.iso230_2(targets, up, up.copy())
    assert r["R"] == pytest.approx(0.0, abs=1e-9)
    assert r["B"] == pytest.approx(0.0, abs=1e-9)
    assert r["A"] == pytest.approx(11.0)
    assert r["E"] == pytest.approx(11.0)


def test_iso230_2_refuses_one_run() -> None:
    with pytest.raises(ValueError):
        mt.iso230_2(np.zeros(3), np.zeros((1, 3)), np.zeros((1, 3)))


def test_fixed_angle_rates_constant_and_ripple() -> None:
    t = np.linspace(0, 10, 100001)
    w = 1e-3
    a = w * t
    r = mt.fixed_angle_rates(t, a, w * 1.0)
    assert r.size == 9
    assert np.allclose(r, w, rtol=1e-6)
    # +-20 % rate ripple at 0.3 Hz, windows of 1 s: the window means keep part of it
    a2 = w * t + 0.2 * w / (2 * math.pi * 0.3) * np.sin(2 * math.pi * 0.3 * t)
    st = mt.rate_stability(t, a2, w, w * 1.0)
    assert st["monotone"]
    assert 0.05 < st["stability"] < 0.2
    assert st["accuracy"] < 0.03


def test_rate_stability_detects_stick_slip_and_reversal() -> None:
    t = np.linspace(0, 10, 10001)
    a = 1e-3 * np.floor(t / 2.0) * 2.0          # staircase: stops for 2 s, jumps
    st = mt.rate_stability(t, a, 1e-3, 1e-3 * 0.5)
    assert st["stability"] > 0.5 or not st["monotone"]
    back = 1e-3 * t - 5e-3 * np.sin(2 * math.pi * t)   # goes back by more than a window
    st2 = mt.rate_stability(t, back, 1e-3, 1e-3)
    assert not st2["monotone"]


def test_min_smooth_rate_ladder() -> None:
    lad = [{"rate_deg_s": 1.0, "stability": 0.01, "accuracy": 0.0, "monotone": True},
           {"rate_deg_s": 0.1, "stability": 0.02, "accuracy": 0.0, "monotone": True},
           {"rate_deg_s": 0.01, "stability": 0.5, "accuracy": 0.0, "monotone": True},
           {"rate_deg_s": 0.001, "stability": 0.01, "accuracy": 0.0, "monotone": True}]
    assert mt.min_smooth_rate(lad, 0.1) == 0.1       # the ladder stops at the first failing rung
    assert mt.min_smooth_rate(lad[:1], 0.001) is None


def _three_slope(t: np.ndarray, k1: float, k2: float, k3: float, t1: float, t2: float) -> np.ndarray:
    a, s = np.abs(t), np.sign(t)
    return s * (np.minimum(a, t1) / k1 + np.clip(a - t1, 0, t2 - t1) / k2 + np.clip(a - t2, 0, None) / k3)


def test_three_slope_fit_recovers_catalogue_curve() -> None:
    t = np.linspace(-67, 67, 401)
    p = _three_slope(t, 3.1e4, 5.0e4, 5.7e4, 14.0, 48.0)
    f = mt.three_slope_fit(t, p)
    assert f["k1_Nm_per_rad"] == pytest.approx(3.1e4, rel=0.02)
    assert f["k2_Nm_per_rad"] == pytest.approx(5.0e4, rel=0.05)
    assert f["t1_Nm"] == pytest.approx(14.0, abs=1.5)


def test_hysteresis_loss_and_lost_motion_of_a_parallelogram() -> None:
    # loop: twist = T/K +- h/2 (sign of dT/dt), cycles 0 -> +T -> 0 -> -T -> 0
    k, h, top = 3.1e4, 2.9e-4, 67.0
    seg = np.linspace(0, 1, 200)
    cyc = np.concatenate([top * seg, top * (1 - seg), -top * seg, -top * (1 - seg)])
    t = np.tile(cyc, 3)
    d = np.sign(np.gradient(t))
    p = t / k + 0.5 * h * -d                  # loading branch lags (less twist)
    hl = mt.hysteresis_loss(t, p, ref_Nm=t)
    assert hl["loss_rad"] == pytest.approx(h, rel=1e-6)
    lm = mt.lost_motion(t, p, top, ref_Nm=t)
    assert lm["lost_motion_rad"] == pytest.approx(2 * top / k, rel=0.01)


def test_hysteresis_loss_ignores_the_virgin_branch() -> None:
    """A short record (virgin 0 -> +T, one unloading branch each way): the virgin curve crosses zero
    torque in the middle of the loop and must not be paired (it would give half the loss)."""
    k, h, top = 3.1e4, 2.9e-4, 67.0
    seg = np.linspace(0, 1, 200)
    t = np.concatenate([-0.01 + (top + 0.01) * seg, top - 2 * top * seg[1:], -top + 2 * top * seg[1:]])
    d = np.sign(np.gradient(t))
    p = t / k + 0.5 * h * -d
    p[:200] = t[:200] / k                     # virgin branch through the loop's centre
    hl = mt.hysteresis_loss(t, p, ref_Nm=t)
    assert hl["loss_rad"] == pytest.approx(h, rel=1e-6)
    assert len(hl["per_cycle_rad"]) == 1


def test_transmission_accuracy_recovers_lines() -> None:
    n = 100.0
    lo = np.linspace(0, 2 * math.pi, 20001)
    mo = n * lo
    e = 8.7e-5 * np.sin(2 * mo + 0.4) + 2.9e-5 * np.sin(lo + 0.7)
    ta = mt.transmission_accuracy(mo, lo + e, n)
    lines = {(x["kind"], x["order"]): x for x in ta["lines"]}
    assert lines[("wg", 2)]["amplitude_rad"] == pytest.approx(8.7e-5, rel=1e-3)
    assert lines[("wg", 2)]["phase_rad"] == pytest.approx(0.4, abs=1e-3)
    assert lines[("out", 1)]["amplitude_rad"] == pytest.approx(2.9e-5, rel=1e-3)
    assert ta["accuracy_rad"] == pytest.approx(np.ptp(e), rel=1e-9)


def test_welch_frf_first_order_and_bandwidth() -> None:
    fs, tau = 2000.0, 1.0 / (2 * math.pi * 20.0)
    rng = np.random.default_rng(0)
    u = rng.standard_normal(40000)
    a = math.exp(-1 / (fs * tau))
    y = np.zeros_like(u)
    for i in range(1, u.size):
        y[i] = a * y[i - 1] + (1 - a) * u[i - 1]
    h = mt.welch_frf(u, y, fs, 1024)
    f = h["f_Hz"]
    k = np.searchsorted(f, 20.0)
    assert abs(h["H"][k]) == pytest.approx(1 / math.sqrt(2), rel=0.05)
    assert np.min(h["coherence"][1:200]) > 0.95
    bw = mt.bandwidth_3db(f[1:200], h["H"][1:200])
    assert bw == pytest.approx(20.0, rel=0.06)


def test_multisine_line_response_is_exact() -> None:
    n, lines = 2048, [3, 10, 40]
    r = mt.schroeder_multisine(n, lines)
    assert np.max(np.abs(r)) == pytest.approx(1.0)
    y = 0.5 * np.roll(r, 4)                   # gain 0.5, 4-sample delay
    h = mt.line_response(r, y, lines)
    assert np.allclose(np.abs(h), 0.5)
    assert np.allclose(np.angle(h), -2 * np.pi * np.array(lines) * 4 / n)


def test_gyro_integration_and_pointing_error() -> None:
    t = np.linspace(0, 5, 5001)
    amp = 10 * mt.ARCSEC
    rate = amp * 2 * math.pi * np.cos(2 * math.pi * t) + 2.4e-6     # 1 Hz motion + gyro bias
    ang = mt.inertial_angle_from_gyro(t, rate)
    pe = mt.pointing_error(ang)
    assert pe["rms_arcsec"] == pytest.approx(10 / math.sqrt(2), rel=0.02)
    assert pe["peak_arcsec"] == pytest.approx(10, rel=0.15)   # the straight-line removal tilts the sine


def _stops(twist_up: np.ndarray, twist_dn: np.ndarray, motor: float = 2.0, te: tuple = (-3.0, 1.0)) -> dict:
    """Synthetic rig stops (runs x 2 targets): a constant motor deviation, a TE per target, the twists given."""
    def side(tw: np.ndarray) -> dict:
        te_a = np.broadcast_to(np.asarray(te), tw.shape)
        return {"motor_dev_arcsec": np.full(tw.shape, motor).tolist(), "te_arcsec": te_a.tolist(),
                "twist_arcsec": tw.tolist(), "gear_torque_Nm": np.full(tw.shape, 6.0).tolist(),
                "out_dev_arcsec": (motor + te_a - tw).tolist()}
    return {"up": side(twist_up), "down": side(twist_dn)}


def test_stop_error_parts_splits_the_output_deviation() -> None:
    # twist 10" at the first target and 12" at the second; 1" more after an approach from below;
    # the later runs repeat to 0.2" (run-to-run s = 0.2), the first run's upward stops 2" off
    base = np.array([10.0, 12.0])
    jit = np.array([0.0, 0.2, -0.2, 0.0])[:, None]
    up = base + 1.0 + jit
    up[0] -= 2.0
    dn = base + jit
    r = mt.stop_error_parts(_stops(up, dn))
    assert r["sum_check_arcsec"] < 1e-12
    tw = r["parts"]["minus_twist_arcsec"]
    assert tw["direction"] == pytest.approx(abs(up.mean(0) - dn.mean(0)).max())
    assert tw["first_run"] == pytest.approx(2.0)
    assert tw["systematic"] == pytest.approx(max(up.mean(0).max(), dn.mean(0).max())
                                             - min(up.mean(0).min(), dn.mean(0).min()))
    assert tw["scatter"] == pytest.approx(np.std(up[:, 0], ddof=1))
    # TE differs between the targets only: systematic, never direction, scatter or first run
    te = r["parts"]["te_arcsec"]
    assert te["systematic"] == pytest.approx(4.0) and te["direction"] == 0.0 and te["scatter"] == 0.0
    assert r["parts"]["motor_dev_arcsec"]["systematic"] == 0.0
    # the output is the sum: its ISO A with and without the first run (which holds the outlier)
    out = r["output"]
    o_up, o_dn = 2.0 + np.array([-3.0, 1.0]) - up, 2.0 + np.array([-3.0, 1.0]) - dn
    assert out["A"] == pytest.approx(mt.iso230_2(np.zeros(2), o_up, o_dn)["A"])
    assert out["A_after_first_run"] == pytest.approx(mt.iso230_2(np.zeros(2), o_up[1:], o_dn[1:])["A"])
    assert out["A_after_first_run"] < out["A"]
