"""The ISR-load bench's arithmetic (tests/bench/50_isr_load.py) on a small example."""
from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "tests" / "bench" / "50_isr_load.py"


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("isr_load_bench", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_slack_at_10_and_20_khz() -> None:
    m = _load()
    # step 1000, one FOC period 500, decode 100 instructions
    s10 = m.slack(1000, 500.0, 100, 10e3)
    s20 = m.slack(1000, 500.0, 100, 20e3)
    assert s10["foc_periods"] == 2 and s20["foc_periods"] == 1
    assert s10["instructions"] == 2100 and s20["instructions"] == 1600
    # 10 kHz: the three allowances (360 cycles); 20 kHz: one ADC interrupt and one port access less
    assert s10["cycles"] == round(2100 * 1.3 + 360)
    assert s20["cycles"] == round(1600 * 1.3 + 360 - 90)
    assert s10["cycles_available"] == 17000 and s20["cycles_available"] == 8500
    assert s10["slack_cycles"] == 17000 - s10["cycles"]
    assert s20["slack_us"] == pytest.approx((8500 - s20["cycles"]) / 170.0, abs=0.01)
    assert s20["cpu_load"] == pytest.approx(s20["cycles"] / 8500, abs=1e-4)


def test_the_25_percent_target_in_instructions() -> None:
    m = _load()
    # 2,992 instructions of isr_worst_case is the most within 25 % at 10 kHz (docs/firmware.md)
    assert 2992 * m.CPI + sum(m.ALLOW_CYCLES.values()) <= m.TARGET * m.F_CPU_HZ / m.F_CTRL_HZ
    assert 2993 * m.CPI + sum(m.ALLOW_CYCLES.values()) > m.TARGET * m.F_CPU_HZ / m.F_CTRL_HZ


def test_the_worst_period_with_the_online_estimator() -> None:
    m = _load()
    assert m.with_online_estimator({"isr_worst_case": {"instructions": 2000}}) is None
    k = {"isr_worst_case_fe_observe": {"instructions": 2500}, "isr_worst_case_fe_finish": {"instructions": 2992}}
    fe = m.with_online_estimator(k)
    assert fe is not None
    assert fe["instructions"] == 2992 and fe["worst_part"] == "finish"
    assert fe["parts_instructions"] == {"observe": 2500, "finish": 2992}
    assert fe["cpu_load"] == round((2992 * 1.3 + 360) / 17000, 4) and fe["within_target"] is True
    k["isr_worst_case_fe_sse"] = {"instructions": 2993}
    assert m.with_online_estimator(k)["within_target"] is False


def test_every_mode_against_the_target() -> None:
    m = _load()
    kernels = {
        "isr_worst_case": {"instructions": 2992, "worst_slot": 1, "slots": [2900, 2992]},
        "isr_worst_case_semi_t2": {"instructions": 2993, "worst_slot": 0, "slots": [2993, 2800]},
        "control_step_baseline": {"instructions": 999},
    }
    out = m.modes(kernels)
    assert set(out) == {"isr_worst_case", "isr_worst_case_semi_t2"}
    assert out["isr_worst_case"]["within_target"] is True
    assert out["isr_worst_case_semi_t2"]["within_target"] is False
    assert out["isr_worst_case_semi_t2"]["worst_tick"] == 0
    assert out["isr_worst_case"]["cycles"] == round(2992 * m.CPI + sum(m.ALLOW_CYCLES.values()))
    assert out["isr_worst_case"]["cpu_load"] == pytest.approx(out["isr_worst_case"]["cycles"] / 17000, abs=1e-4)


def test_the_estimator_check_fails_above_the_target() -> None:
    m = _load()
    k = {"isr_worst_case_fe_sample": {"instructions": 2992},
         "isr_worst_case_exc_fe_observe": {"instructions": 2950},
         "isr_worst_case_exc_fe_observe.s3": {"instructions": 2950},
         "isr_worst_case_semi_t2_fe_feed": {"instructions": 2900}}
    fe = m.estimator_modes(k)
    assert fe["isr_worst_case_exc"]["parts_instructions"] == {"observe": 2950}     # ticks folded, not parts
    ok, line = m.estimator_check(fe)
    assert ok is True and "within" in line
    # one mode over the target fails the check, named
    k["isr_worst_case_semi_t2_fe_observe"] = {"instructions": 2993}
    ok, line = m.estimator_check(m.estimator_modes(k))
    assert ok is False and "FAILED (isr_worst_case_semi_t2)" in line and "observe" in line
    # a mode not measured fails
    del k["isr_worst_case_exc_fe_observe"], k["isr_worst_case_exc_fe_observe.s3"]
    k["isr_worst_case_semi_t2_fe_observe"] = {"instructions": 2000}
    ok, line = m.estimator_check(m.estimator_modes(k))
    assert ok is False and "no isr_worst_case_exc_fe_*" in line
    ok, line = m.estimator_check(m.estimator_modes({}))
    assert ok is False and "no isr_worst_case_fe_*" in line


def test_the_background_load() -> None:
    m = _load()
    assert m.background({}) is None
    bg = m.background({"fe_background_step": {"instructions": 6500}}, fe_decim=10)
    assert bg is not None and bg["step_instructions"] == 6500
    assert bg["cpu_load"] == round(6500 * 1.3 / 170000, 4)
    assert bg["fits_beside_isr"] is True
    assert m.background({"fe_background_step": {"instructions": 6500}}, fe_decim=1)["fits_beside_isr"] is True
    assert m.background({"fe_background_step": {"instructions": 200000}}, fe_decim=1)["fits_beside_isr"] is False
