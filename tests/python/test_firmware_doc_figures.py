"""The instruction counts docs/firmware.md quotes are the ones ``make bench`` measures.

The claims (where docs/firmware.md quotes each figure and where ``build/bench/*.json`` has it)
and the check and fixer live in ``tools/firmware_doc_figures.py`` (``make docs-figures``
rewrites the figures after ``make bench``).  When the bench JSON is present and newer than the
firmware it measured, every quoted figure must equal the measured one within its claim's
tolerance.  Without the JSON (``make test`` does not run ``make bench``) the claims must still
each find their figures in the docs, so the check cannot go quiet when a sentence changes, and
the check and the fixer run on small synthetic docs.
"""
from __future__ import annotations

import importlib.util
import json
import os
import re
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).parents[2]
DOC = ROOT / "docs" / "firmware.md"


def _tool() -> ModuleType:
    name = "firmware_doc_figures"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    sys.modules[name] = m          # the dataclasses look their module up while it loads
    spec.loader.exec_module(m)
    return m


fdf = _tool()
CLAIMS = fdf.CLAIMS
BANK_BUDGET = fdf.BANK_BUDGET
mismatches = fdf.mismatches
profile_rows = fdf.profile_rows


# ------------------------------------------------------------------ tests

def test_every_claim_finds_its_figures_in_the_docs() -> None:
    text = DOC.read_text()
    for c in CLAIMS:
        assert c.doc(text), c.name
    assert len(CLAIMS[0].doc(text)) >= 14


def test_profile_rows_add_up_to_the_total_they_quote() -> None:
    rows, total = profile_rows(DOC.read_text())
    assert len(rows) >= 8
    assert sum(n for _, n in rows) == total


def test_the_check_flags_a_figure_a_few_instructions_off() -> None:
    text = ("### Totals\n\n| kernel | instructions | load at 10 kHz |\n|---|---:|---:|\n"
            "| `isr_worst_case` (worst) | 2,817 | 23.7 % |\n| `foc_step` | 240 | |\n\nnext\n")
    good = {"cm4_cost": {"kernels": {"isr_worst_case": {"instructions": 2817}, "foc_step": {"instructions": 240}}},
            "isr_load": {"modes": {"isr_worst_case": {"cpu_load": 0.2366}}}}
    claim = CLAIMS[0]
    assert claim.doc(text) == [2817.0, 23.7, 240.0]
    assert claim.bench(good, text) == pytest.approx([2817.0, 23.66, 240.0])
    assert mismatches(text, good, (claim,)) == []
    stale = json.loads(json.dumps(good))
    stale["cm4_cost"]["kernels"]["isr_worst_case"]["instructions"] = 2813
    msg = mismatches(text, stale, (claim,))
    assert len(msg) == 1 and "quoted 2817, make bench measured 2813" in msg[0]
    stale["isr_load"]["modes"]["isr_worst_case"]["cpu_load"] = 0.2355      # 23.6 %, quoted 23.7 %
    assert len(mismatches(text, stale, (claim,))) == 2


def test_docs_quote_what_make_bench_measured() -> None:
    b = fdf.bench_json()
    if b is None:
        pytest.skip("no build/bench JSON newer than the firmware (make bench)")
    bad = mismatches(DOC.read_text(), b)
    assert not bad, "docs/firmware.md is stale against make bench:\n" + "\n".join(bad)


def test_bank_budget_is_the_bench_s() -> None:
    import importlib.util
    spec = importlib.util.spec_from_file_location("isr_load_bench", ROOT / "tests" / "bench" / "50_isr_load.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    assert float(m.COMP_BANK_BUDGET) == BANK_BUDGET
    assert "against its budget of 850 instructions" in DOC.read_text()


def test_profile_sums_instructions_per_function() -> None:
    """tools/cm4_profile.py on a three-function image: addresses inside a function count for it
    (Thumb bit dropped, clone suffix dropped, an address repeated by a retranslation added)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("cm4_profile", ROOT / "tools" / "cm4_profile.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    nm = ("00001000 00000010 T hd_app_step\n00001010 00000008 t map_recip.isra.0\n"
          "00001020 00000004 T hd_gv_cost_mark\n00002000 00000004 D some_data\n")
    pcs = "PC 0x1000 3\nPC 0x100e 2\nPC 0x1011 5\nPC 0x1010 1\nPC 0x1022 1\nPC 0x1018 4\n"
    assert m.profile(pcs, nm) == {"map_recip": 6, "hd_app_step": 5, "?": 4, "hd_gv_cost_mark": 1}


# ------------------------------------------------------------------ the fixer

SMALL_DOC = """# x

### Totals

| kernel | instructions | load at 10 kHz |
|---|---:|---:|
| `isr_worst_case` (worst) | 2,812 | 23.6 % |
| `control_step_semi` / `control_step_dual` (worst) | 999 / 2,248 | |
| `foc_step` | 240 | |

Slack of the worst period (`isr_worst_case`): 12,984 cycles (76.4 us) at
10 kHz; 4,968 cycles (29.2 us, load 41.6 %) at 20 kHz.  Worst 2,812 stays.
"""


def small_bench() -> dict[str, Any]:
    """Bench JSON for :data:`SMALL_DOC`: two instruction counts, a load and a slack time moved."""
    k = {"isr_worst_case": 2816, "control_step_semi": 1003, "control_step_dual": 2248, "foc_step": 240}
    return {"cm4_cost": {"kernels": {n: {"instructions": v} for n, v in k.items()}},
            "isr_load": {"modes": {"isr_worst_case": {"cpu_load": 0.2384}},
                         "slack": {"10kHz": {"slack_cycles": 12984, "slack_us": 76.44},
                                   "20kHz": {"slack_cycles": 4963, "slack_us": 29.19, "cpu_load": 0.4163}}}}


def small_claims() -> tuple[Any, ...]:
    return tuple(c for c in CLAIMS if c.name in ("Totals table", "slack of the worst period"))


def test_the_fixer_rewrites_exactly_the_stale_figures() -> None:
    new, stale = fdf.fixed(SMALL_DOC, small_bench(), small_claims())
    expected = (SMALL_DOC.replace("| 2,812 | 23.6 % |", "| 2,816 | 23.8 % |")
                .replace("999 / 2,248", "1,003 / 2,248")
                .replace("4,968 cycles", "4,963 cycles"))
    assert new == expected                      # 76.4 / 29.2 / 41.6 are within a tenth: kept
    assert [(s.quoted, s.measured) for s in stale] == [(2812.0, 2816.0), (23.6, pytest.approx(23.84)),
                                                       (999.0, 1003.0), (4968.0, 4963.0)]


def test_fix_then_check_is_clean_and_a_second_fix_changes_nothing() -> None:
    b = small_bench()
    assert len(mismatches(SMALL_DOC, b, small_claims())) == 4
    new, _ = fdf.fixed(SMALL_DOC, b, small_claims())
    assert mismatches(new, b, small_claims()) == []
    assert fdf.fixed(new, b, small_claims()) == (new, [])


def test_figures_keep_the_docs_format() -> None:
    assert fdf.fmt(1003.0, "999") == "1,003"
    assert fdf.fmt(998.0, "1,001") == "998"
    assert fdf.fmt(12345.0, "12345") == "12345"
    assert fdf.fmt(23.84, "23.6") == "23.8"
    assert fdf.fmt(3.0, "4") == "3"


def synthetic_bench(text: str, seed: int) -> dict[str, Any]:
    """Bench JSON with every figure the claims read from it, at random values (the bank over budget)."""
    rng = np.random.default_rng(seed)
    ints = lambda lo, hi, n=None: rng.integers(lo, hi, size=n).tolist()      # noqa: E731
    names = {n for row in fdf._table_rows(text, "### Totals")
             for n in re.findall(r"`([a-z0-9_<>]+)`", row[0][0].split("(")[0])}
    names |= {"control_step_baseline", "control_step_full", "isr_worst_case", "isr_worst_case_exc",
              "isr_worst_case_semi_t2", "control_step_entry", "control_step_semi", "control_step_dual"}
    kernels: dict[str, Any] = {n: {"instructions": ints(200, 5000)} for n in names}
    kernels["control_step_full"]["worst_slot"] = ints(0, 8)
    kernels["isr_worst_case_semi_t2"]["slots"] = ints(2500, 3000, 8)
    phase_keys = list(fdf.PHASE_NAMES.values())
    pk: dict[str, Any] = {}
    for k in fdf.TICK_ROWS.values():
        pk[k] = {"ticks": {"comp_bank": ints(700, 1000, 8)}, "phases_instructions": dict(zip(phase_keys, ints(10, 999, 8)))}
    for k in ("control_step_baseline", "control_step_full"):
        pk.setdefault(k, {})["phases_instructions"] = dict(zip(phase_keys, ints(10, 999, 8)))
    pk["control_step_full"]["ticks"]["comp_bank"][0] = 990          # the bank over budget in each mode
    for k in fdf.TICK_ROWS.values():
        pk[k]["ticks"]["comp_bank"][1] = 900
    worst = {k: {"worst_instructions": max(pk[k]["ticks"]["comp_bank"])} for k in fdf.TICK_ROWS.values()}
    by = {n: ints(10, 900) for names_, _ in fdf.profile_row_spans(text) for n in names_}
    return {"cm4_cost": {"kernels": kernels}, "phase_cost": {"kernels": pk},
            "isr_load": {"modes": {n: {"cpu_load": float(rng.uniform(0.1, 0.4))} for n in names},
                         "with_online_estimator": {"instructions": ints(2500, 3000), "cpu_load": 0.2468},
                         "with_online_estimator_modes": {
                             m: {"instructions": ints(2500, 3000), "cpu_load": float(rng.uniform(0.2, 0.3))}
                             for m in ("isr_worst_case", "isr_worst_case_exc", "isr_worst_case_semi_t2")},
                         "comp_bank_phase": worst,
                         "slack": {"10kHz": {"slack_cycles": ints(9000, 14000), "slack_us": float(rng.uniform(50, 90))},
                                   "20kHz": {"slack_cycles": ints(1000, 6000), "slack_us": float(rng.uniform(5, 35)),
                                             "cpu_load": float(rng.uniform(0.3, 0.6))}}},
            "profile": {"instructions": sum(by.values()) + ints(20, 60), "tick": ints(0, 8), "by_symbol": by}}


@pytest.mark.parametrize("seed", [1, 2])
def test_the_fixer_on_the_docs_changes_figures_only_and_leaves_nothing_stale(seed: int) -> None:
    text = DOC.read_text()
    b = synthetic_bench(text, seed)
    new, stale = fdf.fixed(text, b)
    assert len(stale) > 60
    assert mismatches(new, b) == []
    assert fdf.NUMBER.sub("#", new) == fdf.NUMBER.sub("#", text)       # only figures changed
    rows, total = profile_rows(new)
    assert sum(n for _, n in rows) == total


def _bench_dir(tmp: Path, b: dict[str, Any]) -> Path:
    d = tmp / "bench"
    d.mkdir()
    for f in fdf.FILES:
        (d / f"{f}.json").write_text(json.dumps(b.get(f, {})))
    return d


def test_command_line_check_fix_and_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = DOC.read_text()
    doc = tmp_path / "firmware.md"
    doc.write_text(text)
    bench = _bench_dir(tmp_path, synthetic_bench(text, 3))
    assert fdf.main(["--doc", str(doc), "--bench", str(bench)]) == 1
    assert "make bench measured" in capsys.readouterr().out
    assert fdf.main(["--fix", "--doc", str(doc), "--bench", str(bench)]) == 0
    assert doc.read_text() != text
    assert fdf.main(["check", "--doc", str(doc), "--bench", str(bench)]) == 0
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []      # no temporary left
    capsys.readouterr()
    fixed_text = doc.read_text()
    profile = (bench / "profile.json").read_text()
    (bench / "profile.json").unlink()
    assert fdf.main(["--fix", "--doc", str(doc), "--bench", str(bench)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "profile.json" in err and "Traceback" not in err
    assert doc.read_text() == fixed_text
    doc.write_text(text.replace("Slack of the worst period", "Slack of the period"))
    (bench / "profile.json").write_text(profile)
    assert fdf.main(["--fix", "--doc", str(doc), "--bench", str(bench)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Slack of the worst period" in err
    doc.write_text(fixed_text)
    for f in bench.iterdir():
        os.utime(f, (0, 0))                     # older than the firmware: stale, never used
    assert fdf.main(["--fix", "--doc", str(doc), "--bench", str(bench)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "older than the firmware" in err
    for f in bench.iterdir():
        os.utime(f)                             # fresh again
    (bench / "isr_load.json").write_text("{}")
    assert fdf.main(["check", "--doc", str(doc), "--bench", str(bench)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no figure for 'Totals table'" in err
