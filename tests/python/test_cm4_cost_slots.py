"""The bench measures every tick of the compensator bank's schedule and reports the worst.

``tools/cm4_cost.py`` folds the per-tick kernels ``<name>.s<k>`` into ``<name>``
(the worst tick) and refuses a kernel with a tick missing; the golden cost
images register one kernel per tick of ``HD_SCHED_CYCLE`` for every control-period
kernel with the bank on that the bench reports (tests/golden/gv_*.c).
"""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "tools" / "cm4_cost.py"
SCHEDULED = ("isr_worst_case", "isr_worst_case_pid", "control_step_full", "control_step_semi", "control_step_dual")


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("cm4_cost_tool", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_fold_takes_the_worst_tick() -> None:
    m = _load()
    k = m.fold_slots({"foo.s0": 10, "foo.s1": 30, "foo.s2": 20, "foo.s3": 5, "bar": 7}, 4)
    assert k["foo"] == {"instructions": 30, "worst_slot": 1, "slots": [10, 30, 20, 5]}
    assert k["bar"] == {"instructions": 7}
    assert k["foo.s3"] == {"instructions": 5}


@pytest.mark.parametrize("ticks", [{"foo.s0": 1, "foo.s1": 2, "foo.s3": 3},          # a tick missing
                                   {"foo.s0": 1, "foo.s1": 2, "foo.s2": 3},          # the last one missing
                                   {"foo.s0": 1, "foo.s1": 2, "foo.s2": 3, "foo.s3": 4, "foo.s4": 5}])
def test_fold_refuses_an_incomplete_or_foreign_cycle(ticks: dict[str, int]) -> None:
    m = _load()
    with pytest.raises(m.CostError, match="foo: slots"):
        m.fold_slots(ticks, 4)


def test_cycle_is_read_from_the_schedule_header(tmp_path: Path) -> None:
    m = _load()
    h = tmp_path / "hd_sched.h"
    h.write_text("#define HD_SCHED_CYCLE     16u\n")
    assert m.sched_cycle(h) == 16
    h.write_text("/* nothing */\n")
    with pytest.raises(m.CostError):
        m.sched_cycle(h)


def test_golden_images_register_every_tick_of_the_cycle() -> None:
    m = _load()
    cycle = m.sched_cycle()
    names: dict[str, set[int]] = {}
    for src in (ROOT / "tests" / "golden").glob("gv_*.c"):
        for base, k in re.findall(r'\{"(\w+)\.s(\d+)",', src.read_text()):
            names.setdefault(base, set()).add(int(k))
    for base in SCHEDULED:
        assert names.get(base) == set(range(cycle)), f"{base}: ticks {sorted(names.get(base, ()))}"


def _load_script(path: Path, name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_phase_probe_folds_the_worst_tick() -> None:
    m = _load_script(ROOT / "tests" / "bench" / "phase" / "phase_cost.py", "phase_cost_tool")
    ph = lambda cb, lp: {"sensors": 400, "comp_bank": cb, "loops": lp}          # noqa: E731
    res = {f"k.s{t}": {"phases_instructions": ph(cb, lp), "sum": 400 + cb + lp, "kernel_instructions": None}
           for t, (cb, lp) in enumerate([(700, 600), (900, 500), (800, 650), (600, 600)])}
    f = m.fold_ticks(res)["k"]
    assert f["worst_tick"] == 2                                   # the largest period, not the largest bank
    assert f["ticks"]["comp_bank"] == [700, 900, 800, 600]
    assert f["worst_instructions"]["comp_bank"] == 900            # the bank's own worst over the ticks
    assert f["worst_instructions"]["loops"] == 650


def test_isr_load_reports_the_bank_phase_per_configuration() -> None:
    m = _load_script(ROOT / "tests" / "bench" / "50_isr_load.py", "isr_load_tool")
    k = {"control_step_full": {"ticks": {"comp_bank": [800, 850, 700]}},
         "control_step_dual": {"ticks": {"comp_bank": [800, 851, 700]}},
         "control_step_baseline": {"phases_instructions": {"comp_bank": 200}}}
    out = m.comp_bank_phase(k)
    assert out["control_step_full"] == {"worst_instructions": 850, "tick_instructions": [800, 850, 700],
                                        "within_budget": True}
    assert out["control_step_dual"]["within_budget"] is False
    assert "control_step_semi" not in out and "control_step_baseline" not in out
