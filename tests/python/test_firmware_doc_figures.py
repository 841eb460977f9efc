"""The instruction counts docs/firmware.md quotes are the ones ``make bench`` measures.

Each claim below names a sentence or table of docs/firmware.md (a regular expression whose
groups are the quoted figures) and where the same figures are in ``build/bench/*.json``
(``cm4_cost.json``, ``phase_cost.json``, ``isr_load.json``, ``profile.json``).  When the bench
JSON is present and newer than the firmware it measured, every quoted figure must equal the
measured one within the claim's tolerance: :data:`TOL_INSTRUCTIONS` for instruction and cycle
counts (QEMU counts repeat to the instruction), :data:`TOL_LOAD_PCT` for loads and
:data:`TOL_US` for times, which the docs round to one decimal.  Without the JSON (``make test``
does not run ``make bench``) the same comparison runs on a small example, and the claims must
still each find their figures in the docs, so the check cannot go quiet when a sentence changes.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import pytest

ROOT = Path(__file__).parents[2]
DOC = ROOT / "docs" / "firmware.md"
BENCH = ROOT / "build" / "bench"
FILES = ("cm4_cost", "phase_cost", "isr_load", "profile")

#: instructions / cycles: exact (two QEMU runs agree to the instruction)
TOL_INSTRUCTIONS = 0.0
#: CPU load in percent: the docs give one decimal
TOL_LOAD_PCT = 0.05
#: times in microseconds: one decimal
TOL_US = 0.05

#: what the bench's numbers come from: newer than the JSON means the JSON is stale
SOURCES = ("firmware/core", "firmware/app", "firmware/canopen", "firmware/hal", "firmware/port/qemu-m4",
           "tests/golden", "tests/bench/phase")
IMAGES = ("build/golden/cost_m4.elf",)

Bench = Mapping[str, Any]
PHASE_NAMES = {"sensors": "sensors", "references": "references", "compensator bank": "comp_bank",
               "hunt breaker": "hunt_breaker", "loops": "loops", "limits and faults": "limits_faults",
               "command": "command", "telemetry": "telemetry"}
#: the compensator bank's phase budget, instructions per tick (docs/firmware.md, tests/bench/50_isr_load.py)
BANK_BUDGET = 850.0
TICK_ROWS = {"full closed": "control_step_full", "semi-closed": "control_step_semi",
             "semi-closed, `pr_t_src` 2": "isr_worst_case_semi_t2", "dual-loop": "control_step_dual"}


def num(s: str) -> float:
    """A figure as the docs write it (thousands with commas)."""
    return float(s.replace(",", ""))


def kernel(b: Bench, name: str) -> float:
    return float(b["cm4_cost"]["kernels"][name]["instructions"])


def bank(b: Bench, name: str) -> list[float]:
    """The compensator bank's phase per tick and its worst (phase_cost.json)."""
    t = [float(x) for x in b["phase_cost"]["kernels"][name]["ticks"]["comp_bank"]]
    return t + [max(t)]


def phases(b: Bench, name: str) -> Mapping[str, float]:
    return b["phase_cost"]["kernels"][name]["phases_instructions"]


def totals(b: Bench, text: str) -> list[float]:
    """The Totals table: per row, the kernels named in its first cell and their counts (and load)."""
    out: list[float] = []
    for row in _table_rows(text, "### Totals"):
        names = re.findall(r"`([a-z0-9_<>]+)`", row[0].split("(")[0])
        for name in names:
            if name.startswith("isr_worst_case_fe_<"):
                out.append(float(b["isr_load"]["with_online_estimator"]["instructions"]))
            else:
                out.append(kernel(b, name))
        if len(row) > 2 and row[2].strip():
            name = names[0]
            load = (b["isr_load"]["with_online_estimator"]["cpu_load"] if name.startswith("isr_worst_case_fe_<")
                    else b["isr_load"]["modes"][name]["cpu_load"])
            out.append(100.0 * float(load))
    return out


def _table_rows(text: str, heading: str) -> list[list[str]]:
    """The cells of each body row of the first table below ``heading``."""
    start = text.index(heading)
    lines = text[start:].splitlines()
    rows: list[list[str]] = []
    seen = False
    for ln in lines[1:]:
        if ln.startswith("|"):
            seen = True
            cells = [c.strip() for c in ln.strip().strip("|").split("|")]
            if set(cells[0]) <= set("-: ") or cells[0] in ("kernel", "function"):
                continue
            rows.append(cells)
        elif seen:
            break
    return rows


@dataclass(frozen=True)
class Claim:
    """Figures the docs quote (``doc``: the text -> figures) and the bench's (``bench``)."""

    name: str
    doc: Callable[[str], list[float]]
    bench: Callable[[Bench, str], list[float]]
    tol: float | tuple[float, ...] = TOL_INSTRUCTIONS


def pattern(rx: str) -> Callable[[str], list[float]]:
    """Figures of the one match of ``rx`` in the docs (its groups, in order)."""
    def get(text: str) -> list[float]:
        m = re.findall(rx, text, flags=re.S)
        if len(m) != 1:
            raise LookupError(f"docs/firmware.md: expected one match of {rx!r}, found {len(m)}")
        groups = m[0] if isinstance(m[0], tuple) else (m[0],)
        return [num(g) for g in groups]
    return get


def totals_figures(text: str) -> list[float]:
    out: list[float] = []
    for row in _table_rows(text, "### Totals"):
        out += [num(x.strip()) for x in row[1].split("/")]
        if len(row) > 2 and row[2].strip():
            out.append(num(row[2].replace("%", "").strip()))
    return out


def totals_tolerances(text: str) -> tuple[float, ...]:
    tol: list[float] = []
    for row in _table_rows(text, "### Totals"):
        tol += [TOL_INSTRUCTIONS] * len(row[1].split("/"))
        if len(row) > 2 and row[2].strip():
            tol.append(TOL_LOAD_PCT)
    return tuple(tol)


def tick_rows(text: str) -> list[float]:
    out: list[float] = []
    for label in TICK_ROWS:
        m = re.search(r"^\| " + re.escape(label) + r" \|((?: [\d,]+ \|){9})$", text, flags=re.M)
        if m is None:
            raise LookupError(f"docs/firmware.md: no row '{label}' of the bank's phase per tick")
        out += [num(x) for x in m.group(1).split("|") if x.strip()]
    return out


def phase_sentence(text: str) -> list[float]:
    m = re.search(r"Per phase with every form \(`phase_cost\.json`; baseline / the full\s+step's worst tick\): (.*?)"
                  r"; `control_step_baseline` ([\d,]+),\s+`control_step_full` ([\d,]+) \(worst tick (\d)[^)]*\),"
                  r"\s+`isr_worst_case` ([\d,]+)\.", text, flags=re.S)
    if m is None:
        raise LookupError("docs/firmware.md: no 'Per phase with every form' sentence")
    out: list[float] = []
    for label, key in PHASE_NAMES.items():
        p = re.search(re.escape(label) + r"\s+([\d,]+) / ([\d,]+)", m.group(1))
        if p is None:
            raise LookupError(f"docs/firmware.md: phase '{label}' missing from the 'Per phase' sentence")
        out += [num(p.group(1)), num(p.group(2))]
    return out + [num(m.group(i)) for i in (2, 3, 4, 5)]


def phase_sentence_bench(b: Bench, text: str) -> list[float]:
    base, full = phases(b, "control_step_baseline"), phases(b, "control_step_full")
    out: list[float] = []
    for key in PHASE_NAMES.values():
        out += [float(base[key]), float(full[key])]
    return out + [kernel(b, "control_step_baseline"), kernel(b, "control_step_full"),
                  float(b["cm4_cost"]["kernels"]["control_step_full"]["worst_slot"]), kernel(b, "isr_worst_case")]


def profile_bench(b: Bench, text: str) -> list[float]:
    """Each profile row's functions summed from profile.json; a row without one is the rest."""
    by = b["profile"]["by_symbol"]
    rows, _ = profile_rows(text)
    named = [float(sum(by.get(s, 0) for s in names)) if names else None for names, _ in rows]
    rest = float(b["profile"]["instructions"]) - sum(x for x in named if x is not None)
    return [rest if x is None else x for x in named]


def slack(b: Bench, text: str) -> list[float]:
    s10, s20 = b["isr_load"]["slack"]["10kHz"], b["isr_load"]["slack"]["20kHz"]
    return [float(s10["slack_cycles"]), float(s10["slack_us"]), float(s20["slack_cycles"]), float(s20["slack_us"]),
            100.0 * float(s20["cpu_load"])]


def worst_banks(b: Bench, text: str) -> list[float]:
    c = b["isr_load"]["comp_bank_phase"]
    return [float(c[k]["worst_instructions"]) for k in ("control_step_full", "control_step_semi", "control_step_dual")]


def profile_rows(text: str) -> tuple[list[tuple[list[str], float]], float]:
    """The per-function profile of the worst period: (backticked names, instructions) per row, the total."""
    total = pattern(r"their caller; ([\d,]+) in all\)")(text)[0]
    rows = []
    for row in _table_rows(text, "### Where the worst period goes"):
        if row[0] == "function":
            continue
        rows.append((re.findall(r"`([A-Za-z0-9_]+)`", row[0]), num(row[1])))
    return rows, total


CLAIMS: tuple[Claim, ...] = (
    Claim("Totals table", totals_figures, totals, tol=()),      # tolerances per cell: totals_tolerances
    Claim("profile of the worst period: total", pattern(r"their caller; ([\d,]+) in all\)"),
          lambda b, t: [float(b["profile"]["instructions"])]),
    Claim("profile of the worst period: its tick", pattern(r"`isr_worst_case` in its worst tick\s+\((\d),"),
          lambda b, t: [float(b["profile"]["tick"])]),
    Claim("bank's phase per tick", tick_rows,
          lambda b, t: [x for k in TICK_ROWS.values() for x in bank(b, k)]),
    Claim("targets: the bank's worst ticks",
          pattern(r"it\s+takes ([\d,]+) / ([\d,]+) / ([\d,]+) instructions \(full-closed / semi-closed / dual-loop; "
                  r"([\d,]+)\s+semi-closed with `pr_t_src` 2\)"),
          lambda b, t: worst_banks(b, t) + [bank(b, "isr_worst_case_semi_t2")[-1]]),
    Claim("what the targets need: the bank's worst ticks",
          pattern(r"Left to do: the bank's phase <= 850 in every tick \(([\d,]+) / ([\d,]+) / ([\d,]+); ([\d,]+) with"),
          lambda b, t: worst_banks(b, t) + [bank(b, "isr_worst_case_semi_t2")[-1]]),
    Claim("the bank's worst ticks over the budget",
          pattern(r"the worst tick is ([\d,]+) \(full closed\),\s+([\d,]+) \(semi-closed\), ([\d,]+) \(semi-closed, "
                  r"`pr_t_src` 2\) and ([\d,]+) \(dual-loop\)\s+instructions over it"),
          lambda b, t: [bank(b, k)[-1] - BANK_BUDGET for k in ("control_step_full", "control_step_semi",
                                                               "isr_worst_case_semi_t2", "control_step_dual")]),
    Claim("targets: how far the bank is over its budget", pattern(r"\), ([\d,]+) to ([\d,]+) over the budget"),
          lambda b, t: [min(over := [bank(b, k)[-1] - BANK_BUDGET for k in (*TICK_ROWS.values(),)]), max(over)]),
    Claim("profile of the worst period: per function", lambda t: [n for _, n in profile_rows(t)[0]],
          lambda b, t: profile_bench(b, t)),
    Claim("per phase, baseline / full worst tick", phase_sentence, phase_sentence_bench),
    Claim("slack of the worst period",
          pattern(r"Slack of the worst period \(`isr_worst_case`\): ([\d,]+) cycles \(([\d.]+) us\) at\s+10 kHz; "
                  r"([\d,]+) cycles \(([\d.]+) us, load ([\d.]+) %\) at 20 kHz"),
          slack, tol=(TOL_INSTRUCTIONS, TOL_US, TOL_INSTRUCTIONS, TOL_US, TOL_LOAD_PCT)),
    Claim("semi-closed pr_t_src 2: every tick",
          pattern(r"\(ticks\s+([\d,]+), ([\d,]+), ([\d,]+), ([\d,]+), ([\d,]+), ([\d,]+), ([\d,]+), ([\d,]+)\)"),
          lambda b, t: [float(x) for x in b["cm4_cost"]["kernels"]["isr_worst_case_semi_t2"]["slots"]]),
    Claim("targets: excitation and semi-closed pr_t_src 2 periods",
          pattern(r"the excitation mode \(([\d,]+)\) and the semi-closed period\s+with `pr_t_src` 2 \(([\d,]+)\)"),
          lambda b, t: [kernel(b, "isr_worst_case_exc"), kernel(b, "isr_worst_case_semi_t2")]),
    Claim("first period after a start", pattern(r"`control_step_entry`, ([\d,]+) instructions, once per\s+start"),
          lambda b, t: [kernel(b, "control_step_entry")]),
)


def mismatches(text: str, b: Bench, claims: tuple[Claim, ...] | None = None) -> list[str]:
    """Every quoted figure that differs from the bench's by more than its tolerance, one line each
    (``claims``: default :data:`CLAIMS`)."""
    out: list[str] = []
    for c in CLAIMS if claims is None else claims:
        quoted, measured = c.doc(text), c.bench(b, text)
        tol = totals_tolerances(text) if c.name == "Totals table" else c.tol
        tols = tol if isinstance(tol, tuple) else (tol,) * len(quoted)
        if len(measured) != len(quoted) or len(tols) != len(quoted):
            out.append(f"{c.name}: the docs quote {len(quoted)} figures, the bench gives {len(measured)}")
            continue
        for i, (q, m, t) in enumerate(zip(quoted, measured, tols)):
            if abs(q - m) > t + 1e-9:
                out.append(f"{c.name}: figure {i + 1} quoted {q:g}, make bench measured {m:g} (tolerance {t:g})")
    return out


def bench_json() -> dict[str, Any] | None:
    """The bench's JSON when every file is there and newer than what it measured, else None."""
    paths = [BENCH / f"{f}.json" for f in FILES]
    if not all(p.is_file() for p in paths):
        return None
    made = min(p.stat().st_mtime for p in paths)
    inputs = [ROOT / i for i in IMAGES if (ROOT / i).is_file()]
    for d in SOURCES:
        inputs += [p for p in (ROOT / d).rglob("*") if p.suffix in (".c", ".h", ".S", ".ld")]
    if any(p.stat().st_mtime > made for p in inputs):
        return None
    return {f: json.loads((BENCH / f"{f}.json").read_text()) for f in FILES}


# ------------------------------------------------------------------ tests

def test_every_claim_finds_its_figures_in_the_docs() -> None:
    text = DOC.read_text()
    for c in CLAIMS:
        assert c.doc(text), c.name
    assert len(totals_figures(text)) >= 14


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
    b = bench_json()
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
