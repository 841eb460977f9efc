"""Closed-loop baseline figures (hdservo.closedloop_cases): figure arithmetic on known
signals, the case definitions, and short closed-loop runs that show the figures
respond to the plant effects they are meant to expose."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hdservo import closedloop_cases as bl

ALL_OFF = {e: False for e in ("cogging", "transmission_error", "hysteresis_maxwell", "hysteresis_preisach",
                              "friction_motor", "friction_load", "gravity", "base", "encoder_load",
                              "encoder_motor", "current_sensor", "gyro")}
FRICTION_ONLY = {**ALL_OFF, "friction_motor": True, "friction_load": True}


def _quick(name: str) -> bl.Case:
    return {c.name: c for c in bl.quick_cases()}[name]


# ------------------------------------------------------------------ arithmetic on synthetic signals

def test_rms_max_of_a_sine_and_a_constant() -> None:
    t = np.arange(0, 10.0, 1e-3)                       # 10 whole periods of 1 Hz
    f = bl.rms_max(3.0 * np.sin(2 * np.pi * t))
    assert f["rms"] == pytest.approx(3.0 / math.sqrt(2), rel=1e-9)
    assert f["max"] == pytest.approx(3.0, rel=1e-6)
    assert f["mean"] == pytest.approx(0.0, abs=1e-9)
    g = bl.rms_max(np.full(7, -2.5))
    assert (g["rms"], g["max"], g["mean"]) == (2.5, 2.5, -2.5)
    with pytest.raises(ValueError):
        bl.rms_max(np.array([]))


def test_tracking_figures_skip_the_transient_and_measure_the_rate() -> None:
    t = np.arange(0, 20.0, 1e-3)
    v_ref = 1e-3                                        # rad/s
    e = np.where(t < 5.0, 100.0, 0.5 * np.sin(2 * np.pi * 2.0 * t))   # transient then 0.5" at 2 Hz
    y = v_ref * t - e / bl.ARCSEC_PER_RAD
    v = np.gradient(y, t)
    f = bl.tracking_figures(t, e, v, 5.5, v_ref, y)
    assert f["rms_arcsec"] == pytest.approx(0.5 / math.sqrt(2), rel=1e-3)
    assert f["max_arcsec"] == pytest.approx(0.5, rel=1e-3)
    assert f["window_s"][0] == pytest.approx(5.5)
    assert f["rate_mean_deg_s"] == pytest.approx(v_ref / bl.RAD_PER_DEG, rel=1e-3)
    # rate ripple: d/dt of 0.5" sin(2 pi 2 t) -> amplitude 2 pi 2 0.5" /s
    amp = 2 * np.pi * 2.0 * 0.5 / 3600.0                # deg/s
    assert f["rate_rms_dev_deg_s"] == pytest.approx(amp / math.sqrt(2), rel=1e-2)
    assert f["travel_arcsec"] == pytest.approx(v_ref * 14.5 * bl.ARCSEC_PER_RAD, rel=1e-3)


def test_step_figures_of_a_first_order_response() -> None:
    tau, t0, amp = 0.02, 0.1, 100.0 / bl.ARCSEC_PER_RAD
    t = np.arange(0, 3.0, 1e-4)                        # final error: mean over the last 1 s
    sp = np.where(t >= t0, amp, 0.0)
    y = np.where(t >= t0, amp * (1 - np.exp(-(t - t0) / tau)), 0.0)
    f = bl.step_figures(t, sp, y, t0)
    assert f["amplitude_arcsec"] == pytest.approx(100.0)
    assert f["rise_time_s"] == pytest.approx(tau * math.log(9), abs=2e-4)
    assert f["overshoot_pct"] == 0.0
    assert f["settling_time_s_2arcsec"] == pytest.approx(tau * math.log(100 / 2), abs=2e-4)
    assert f["settling_time_s_10arcsec"] == pytest.approx(tau * math.log(100 / 10), abs=2e-4)
    assert abs(f["final_error_arcsec"]) < 1e-9
    # 20 % overshoot, never settling inside 2": reported as None
    # underdamped: 1 - exp(-a t) cos(w t), a = 20/s, w = 40 rad/s, peaks where tan(w t) = -a/w; ends 3" beyond
    y2 = np.where(t >= t0, amp * (1 - np.exp(-(t - t0) / 0.05) * np.cos(40 * (t - t0))) + 3 / bl.ARCSEC_PER_RAD,
                  0.0)
    f2 = bl.step_figures(t, sp, y2, t0)
    tp = (math.pi - math.atan(20.0 / 40.0)) / 40.0
    assert f2["overshoot_pct"] == pytest.approx(-100 * math.exp(-20 * tp) * math.cos(40 * tp) + 3.0, abs=0.01)
    assert f2["settling_time_s_2arcsec"] is None
    assert f2["final_error_arcsec"] == pytest.approx(-3.0, abs=1e-6)


def test_reversal_figures_find_each_peak() -> None:
    t = np.arange(0, 22.0, 1e-3)
    e = 0.1 * np.sin(2 * np.pi * 3 * t)
    for tr, peak in ((5.0, 40.0), (10.0, -55.0), (15.0, 30.0), (20.0, -20.0)):
        e = e + peak * np.exp(-(((t - tr - 0.2) / 0.05) ** 2))
    f = bl.reversal_figures(t, e, [5.0, 10.0, 15.0, 20.0, 25.0], half_window_s=1.0)
    assert f["t_reversal_s"] == [5.0, 10.0, 15.0, 20.0]      # 25 s is outside the run
    assert f["per_reversal_arcsec"] == pytest.approx([40.0, 55.0, 30.0, 20.0], abs=0.11)
    assert f["peak_arcsec"] == pytest.approx(55.0, abs=0.11)
    assert f["mean_peak_arcsec"] == pytest.approx(36.25, abs=0.11)


def test_ptp_final_and_move_end() -> None:
    t = np.arange(0, 4.0, 1e-3)
    sp = np.clip(t - 1.0, 0.0, 1.0)                     # moves from 1 s to 2 s
    assert bl.move_end_s(t, sp) == pytest.approx(2.0, abs=1e-3)
    e = np.where(t < 2.0, 50.0, 1.5 + 40.0 * np.exp(-(t - 2.0) / 0.1))
    f = bl.ptp_final(t, e, 2.0, window_s=1.0)
    assert f["final_error_arcsec"] == pytest.approx(1.5, abs=1e-3)
    assert f["settling_time_s"] == pytest.approx(0.1 * math.log(40 / 8.5), abs=2e-3)


def test_improvement_ratios() -> None:
    base = {"tracking": {"0.01": {"rms_arcsec": 1.0}}, "reversal": {"peak_arcsec": 50.0}}
    comp = {"tracking": {"0.01": {"rms_arcsec": 0.2}}, "reversal": {"peak_arcsec": 10.0}}
    imp = bl.improvement(base, comp)
    assert imp["rms_ratio"] == pytest.approx(5.0)
    assert imp["reversal_peak_reduction_pct"] == pytest.approx(80.0)


# ------------------------------------------------------------------ case definitions

def test_standard_cases_cover_the_brief() -> None:
    cases = bl.standard_cases()
    names = {c.name for c in cases}
    assert {"step_100arcsec", "step_1deg", "ramp_1degps", "reversal"} <= names
    trk = {c.name: c for c in cases if c.name.startswith("tracking_")}
    assert set(trk) == {f"tracking_{bl.speed_key(v)}" for v in (0.001, 0.01, 0.1)}
    for c in trk.values():
        v_deg_s = c.setpoint["rate_rad_s"] / bl.RAD_PER_DEG
        window = c.duration_s - c.setpoint["t0_s"] - c.skip_s
        # long enough: >= several hundred arcsec of travel or >= 20 s, after the transient
        assert v_deg_s * 3600 * window >= 500 or window >= 20.0
    assert len([c for c in cases if c.kind == "ptp"]) == 12
    rev = {c.name: c for c in cases}["reversal"].setpoint
    assert rev["amplitude_rad"] == pytest.approx(bl.RAD_PER_DEG) and rev["frequency_Hz"] == 0.1


def test_axis_controller_applies_the_design_rules_to_each_axis() -> None:
    assert bl.axis_controller("reference")["gains"] == "defaults"
    g = bl.axis_controller("csf17_50")["gains"]
    # docs/control.md table: vel kp 27.5 N m s/rad, ki 1079 N m/rad
    assert g["vel_kp"] == pytest.approx(27.5, abs=0.05)
    assert g["vel_ki"] == pytest.approx(1079, abs=1)
    # notch coefficients are exact Q2.30 words; the notch is at ~69 Hz
    for k in ("f1_b0", "f1_b1", "f1_b2", "f1_a1", "f1_a2"):
        assert (g[k] * 2 ** 30) == int(g[k] * 2 ** 30)
    b = np.array([g["f1_b0"], g["f1_b1"], g["f1_b2"]])
    a = np.array([1.0, g["f1_a1"], g["f1_a2"]])
    z = np.exp(1j * 2 * np.pi * np.array([69.2, 5.0]) / 1e4)
    h = np.abs(np.polyval(b[::-1], 1 / z) / np.polyval(a[::-1], 1 / z))
    assert 20 * np.log10(h[0]) == pytest.approx(-20.0, abs=0.5)
    assert h[1] == pytest.approx(1.0, abs=0.01)


def test_scenario_text_carries_the_controller_table() -> None:
    ctl = {"gains": {"vel_kp": 100.0}, "compensators": ["lugre"], "lugre": {"sigma0": 3.0, "on": True}}
    txt = bl.scenario_text(_quick("step_100arcsec"), ctl, "reference", seed=5)
    assert 'mode = "position"' in txt and "seed = 5" in txt
    assert "[controller.gains]\nvel_kp = 100.0" in txt
    assert 'compensators = ["lugre"]' in txt
    assert "[controller.lugre]\nsigma0 = 3.0\non = true" in txt
    with pytest.raises(ValueError):
        bl.scenario_text(_quick("step_100arcsec"), {"mode": "velocity"})


# ------------------------------------------------------------------ closed loop (short runs)

def test_tracking_error_small_without_effects_and_grows_with_friction() -> None:
    c = _quick("tracking_0.01")
    ctl = bl.axis_controller()
    clean = bl.analyse(c, bl.run_case(c, ctl, effects=ALL_OFF)).figures
    fric = bl.analyse(c, bl.run_case(c, ctl, effects=FRICTION_ONLY)).figures
    # linear axis, velocity feed-forward: sub-encoder-count error after the start
    assert clean["rms_arcsec"] < 0.1 and clean["start_peak_arcsec"] < 1.0
    assert clean["rate_mean_deg_s"] == pytest.approx(0.01, rel=0.02)
    # friction: breakaway at the start costs arcsec of error
    assert fric["start_peak_arcsec"] > 5.0
    assert fric["start_peak_arcsec"] > 10 * clean["start_peak_arcsec"]
    assert clean["fault_code"] == 0 and fric["fault_code"] == 0


def test_reversal_peak_comes_from_friction() -> None:
    c = _quick("reversal")
    ctl = bl.axis_controller()
    clean = bl.analyse(c, bl.run_case(c, ctl, effects=ALL_OFF)).figures
    fric = bl.analyse(c, bl.run_case(c, ctl, effects=FRICTION_ONLY)).figures
    assert clean["t_reversal_s"] == pytest.approx([5.1])
    assert clean["peak_arcsec"] < 1.0
    assert fric["peak_arcsec"] > 10.0
    assert fric["peak_arcsec"] > 20 * clean["peak_arcsec"]


def test_run_cases_json_layout(tmp_path: Path) -> None:
    figs, runs = bl.run_cases(axis="reference", cases=bl.quick_cases())
    for v in ("0.001", "0.01", "0.1"):
        t = figs["tracking"][v]
        assert t["rms_arcsec"] >= 0 and t["max_arcsec"] >= t["rms_arcsec"]
        assert math.isfinite(t["rms_arcsec"])
    for k in ("rise_time_s", "overshoot_pct", "settling_time_s_2arcsec", "settling_time_s_10arcsec",
              "final_error_arcsec"):
        assert k in figs["step_100arcsec"] and k in figs["step_1deg"]
    assert figs["step_1deg"]["amplitude_arcsec"] == pytest.approx(3600.0)
    assert {"rms_arcsec", "max_arcsec"} <= set(figs["ramp_1degps"])
    assert figs["reversal"]["peak_arcsec"] > 0
    p = figs["ptp_12"]
    assert len(p["final_error_arcsec"]) == len(p["targets_deg"]) == 2
    assert figs["faults"] == 0
    assert figs["controller"]["gains"] == "defaults"
    files = bl.plot_axis("quick", runs, tmp_path)
    assert {f.name for f in files} == {"baseline_quick_steps.png", "baseline_quick_tracking.png",
                                       "baseline_quick_reversal.png", "baseline_quick_ptp.png"}
    assert all(f.stat().st_size > 10_000 for f in files)
