"""The simulator-speed bench's measurement (tests/bench/20_sim_speed.py): best of N
repetitions of the process's CPU time, on fake clocks and on a run that only waits."""
from __future__ import annotations

import importlib.util
import time
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "tests" / "bench" / "20_sim_speed.py"


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("sim_speed_bench", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_best_of_takes_the_least_cpu_and_its_result() -> None:
    m = _load()
    cpu_costs = iter([0.030, 0.021, 0.045, 0.024, 0.022])   # CPU s of each repetition
    wall_costs = iter([0.050, 0.090, 0.046, 0.060, 0.070])  # wall s (other jobs hold the core)
    clock = {"cpu": 0.0, "wall": 0.0}
    calls = []

    def run() -> int:
        clock["cpu"] += next(cpu_costs)
        clock["wall"] += next(wall_costs)
        calls.append(len(calls))
        return calls[-1]

    r = m.best_of(run, 5, cpu=lambda: clock["cpu"], wall=lambda: clock["wall"])
    assert r["cpu_s"] == pytest.approx([0.030, 0.021, 0.045, 0.024, 0.022])
    assert r["best_cpu_s"] == pytest.approx(0.021)
    assert r["result"] == 1                      # the repetition with the least CPU time
    assert r["median_cpu_s"] == pytest.approx(0.024)
    assert r["best_wall_s"] == pytest.approx(0.046)


def test_waiting_is_not_cpu_time() -> None:
    """A repetition that is kept off the core (here: sleeps) costs wall time, not CPU time."""
    m = _load()
    r = m.best_of(lambda: time.sleep(0.02), 3)
    assert r["best_wall_s"] >= 0.02
    assert r["best_cpu_s"] < 0.01
    assert len(r["cpu_s"]) == 3


def test_at_least_one_repetition() -> None:
    m = _load()
    with pytest.raises(ValueError, match="repeats"):
        m.best_of(lambda: None, 0)
