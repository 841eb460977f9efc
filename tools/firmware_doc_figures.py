#!/usr/bin/env python3
"""The bench figures docs/firmware.md quotes, checked against ``make bench`` or rewritten from it.

Each claim below names a sentence or table of docs/firmware.md (where its figures are in the
text) and where the same figures are in ``build/bench/*.json`` (``cm4_cost.json``,
``phase_cost.json``, ``isr_load.json``, ``profile.json``).  Every quoted figure must equal the
measured one within the claim's tolerance: :data:`TOL_INSTRUCTIONS` for instruction and cycle
counts (QEMU counts repeat to the instruction), :data:`TOL_LOAD_PCT` for loads and
:data:`TOL_US` for times, which the docs round to one decimal.

Usage (from the checkout; ``make docs-figures`` runs ``--fix`` after ``make bench``)::

    tools/firmware_doc_figures.py [check] [--doc FILE] [--bench DIR]
    tools/firmware_doc_figures.py --fix  [--doc FILE] [--bench DIR]

``check`` (the default) prints one line per stale figure and exits 1 when there is one, 0 when
every figure agrees.  ``--fix`` rewrites every stale figure in place from the bench JSON, in
the docs' formatting (thousands with commas, loads and times with the quoted decimals), and
touches nothing else; the file is replaced atomically.  Bench JSON that is missing, older than
the firmware it measured or without a figure, and docs without a claim's sentence, are one
error line and exit 2 (the docs are left as they are).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

ROOT = Path(__file__).resolve().parents[1]
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
#: a figure's place in the docs: [start, end) character offsets
Span = tuple[int, int]

PHASE_NAMES = {"sensors": "sensors", "references": "references", "compensator bank": "comp_bank",
               "hunt breaker": "hunt_breaker", "loops": "loops", "limits and faults": "limits_faults",
               "command": "command", "telemetry": "telemetry"}
#: the compensator bank's phase budget, instructions per tick (docs/firmware.md, tests/bench/50_isr_load.py)
BANK_BUDGET = 850.0
TICK_ROWS = {"full closed": "control_step_full", "semi-closed": "control_step_semi",
             "semi-closed, `pr_t_src` 2": "isr_worst_case_semi_t2", "dual-loop": "control_step_dual"}

#: a figure as the docs write it: digits with thousands commas, optionally decimals
NUMBER = re.compile(r"\d{1,3}(?:,\d{3})+(?:\.\d+)?|\d+(?:\.\d+)?")


class FigureError(Exception):
    """Docs without a claim's sentence, or bench JSON without a claim's figure."""


def num(s: str) -> float:
    """A figure as the docs write it (thousands with commas)."""
    return float(s.replace(",", ""))


def fmt(value: float, quoted: str) -> str:
    """``value`` written like ``quoted``: its decimals, thousands with commas.

    Parameters
    ----------
    value : float
        The measured figure (instructions, cycles, percent or microseconds).
    quoted : str
        The figure the docs write now; its number of decimals is kept.

    Returns
    -------
    str
        ``value`` rounded to the quoted decimals, thousands separated by commas unless the
        quoted figure is 1,000 or more and written without them.
    """
    decimals = len(quoted.split(".")[1]) if "." in quoted else 0
    commas = "," in quoted or num(quoted) < 1000
    spec = f"{',' if commas else ''}.{decimals}f"
    return format(round(value, decimals) if decimals else round(value), spec)


# ------------------------------------------------------------------ where the bench keeps the figures

def kernel(b: Bench, name: str) -> float:
    """A kernel's instructions in ``cm4_cost.json`` (its worst tick for the scheduled ones)."""
    return float(b["cm4_cost"]["kernels"][name]["instructions"])


def bank(b: Bench, name: str) -> list[float]:
    """The compensator bank's phase per tick and its worst (phase_cost.json)."""
    t = [float(x) for x in b["phase_cost"]["kernels"][name]["ticks"]["comp_bank"]]
    return t + [max(t)]


def phases(b: Bench, name: str) -> Mapping[str, float]:
    """A kernel's phases in its worst tick (phase_cost.json), instructions."""
    return b["phase_cost"]["kernels"][name]["phases_instructions"]


# ------------------------------------------------------------------ where the docs quote them

def _table_rows(text: str, heading: str) -> list[list[tuple[str, int]]]:
    """The cells of each body row of the first table below ``heading``: (stripped text, offset)."""
    start = text.find(heading)
    if start < 0:
        raise FigureError(f"docs/firmware.md: no heading {heading!r}")
    rows: list[list[tuple[str, int]]] = []
    seen = False
    nl = text.find("\n", start)
    pos = len(text) if nl < 0 else nl + 1
    while pos < len(text):
        end = text.find("\n", pos)
        end = len(text) if end < 0 else end
        ln = text[pos:end]
        if ln.startswith("|"):
            seen = True
            cells: list[tuple[str, int]] = []
            for m in re.finditer(r"\|([^|\n]*)(?=\|)", ln):
                raw = m.group(1)
                lead = len(raw) - len(raw.lstrip())
                cells.append((raw.strip(), pos + m.start(1) + lead))
            first = cells[0][0] if cells else ""
            if cells and not (set(first) <= set("-: ") or first in ("kernel", "function", "tick")):
                rows.append(cells)
        elif seen:
            break
        pos = end + 1
    return rows


def _numbers(text: str, start: int, end: int) -> list[Span]:
    """The spans of the figures in text[start:end]."""
    return [m.span() for m in NUMBER.finditer(text, start, end)]


def pattern(rx: str) -> Callable[[str], list[Span]]:
    """The spans of the groups of the one match of ``rx`` in the docs, in order."""
    compiled = re.compile(rx, flags=re.S)

    def get(text: str) -> list[Span]:
        m = list(compiled.finditer(text))
        if len(m) != 1:
            raise FigureError(f"docs/firmware.md: expected one match of {rx!r}, found {len(m)}")
        return [m[0].span(i) for i in range(1, compiled.groups + 1)]
    return get


def totals_spans(text: str) -> list[Span]:
    """The Totals table: each row's instructions (split at '/') and its load when it has one."""
    out: list[Span] = []
    for row in _table_rows(text, "### Totals"):
        s, at = row[1]
        out += _numbers(text, at, at + len(s))
        if len(row) > 2 and row[2][0]:
            s, at = row[2]
            out += _numbers(text, at, at + len(s))
    return out


def totals_tolerances(text: str) -> tuple[float, ...]:
    """Per figure of the Totals table: exact instructions, the load within :data:`TOL_LOAD_PCT`."""
    tol: list[float] = []
    for row in _table_rows(text, "### Totals"):
        tol += [TOL_INSTRUCTIONS] * len(row[1][0].split("/"))
        if len(row) > 2 and row[2][0]:
            tol.append(TOL_LOAD_PCT)
    return tuple(tol)


def _with_estimator(b: Bench, name: str) -> dict[str, Any]:
    """A mode's worst period with the online estimator on (``<mode>_fe_<kind>`` in the table).

    Parameters
    ----------
    b : Bench
        The bench JSON.
    name : str
        The table's kernel name, ``<mode>_fe_<kind>``.

    Returns
    -------
    dict[str, Any]
        ``isr_load.json`` ``with_online_estimator_modes[<mode>]`` (``with_online_estimator``
        for the full-closed PTP period of a bench without the per-mode figures).
    """
    mode = name.split("_fe_<")[0]
    modes = b["isr_load"].get("with_online_estimator_modes")
    if modes is None and mode == "isr_worst_case":
        return b["isr_load"]["with_online_estimator"]
    if modes is None or modes.get(mode) is None:
        raise FigureError(f"isr_load.json: no figure with the online estimator for {mode}")
    return modes[mode]


def totals(b: Bench, text: str) -> list[float]:
    """The Totals table: per row, the kernels named in its first cell and their counts (and load)."""
    out: list[float] = []
    for row in _table_rows(text, "### Totals"):
        names = re.findall(r"`([a-z0-9_<>]+)`", row[0][0].split("(")[0])
        for name in names:
            if "_fe_<" in name:
                out.append(float(_with_estimator(b, name)["instructions"]))
            else:
                out.append(kernel(b, name))
        if len(row) > 2 and row[2][0]:
            name = names[0]
            load = (_with_estimator(b, name)["cpu_load"] if "_fe_<" in name
                    else b["isr_load"]["modes"][name]["cpu_load"])
            out.append(100.0 * float(load))
    return out


def tick_spans(text: str) -> list[Span]:
    """The bank's phase per tick table: eight ticks and the worst per feedback configuration."""
    out: list[Span] = []
    for label in TICK_ROWS:
        m = re.search(r"^\| " + re.escape(label) + r" \|((?: [\d,]+ \|){9})$", text, flags=re.M)
        if m is None:
            raise FigureError(f"docs/firmware.md: no row '{label}' of the bank's phase per tick")
        out += _numbers(text, m.start(1), m.end(1))
    return out


def phase_sentence_spans(text: str) -> list[Span]:
    """The 'Per phase with every form' sentence: baseline / full per phase, then the four kernels."""
    m = re.search(r"Per phase with every form \(`phase_cost\.json`; baseline / the full\s+step's worst tick\): (.*?)"
                  r"; `control_step_baseline` ([\d,]+),\s+`control_step_full` ([\d,]+) \(worst tick (\d)[^)]*\),"
                  r"\s+`isr_worst_case` ([\d,]+)\.", text, flags=re.S)
    if m is None:
        raise FigureError("docs/firmware.md: no 'Per phase with every form' sentence")
    out: list[Span] = []
    for label in PHASE_NAMES:
        p = re.compile(re.escape(label) + r"\s+([\d,]+) / ([\d,]+)").search(text, m.start(1), m.end(1))
        if p is None:
            raise FigureError(f"docs/firmware.md: phase '{label}' missing from the 'Per phase' sentence")
        out += [p.span(1), p.span(2)]
    return out + [m.span(i) for i in (2, 3, 4, 5)]


def phase_sentence_bench(b: Bench, text: str) -> list[float]:
    """The bench's figures of the 'Per phase with every form' sentence."""
    base, full = phases(b, "control_step_baseline"), phases(b, "control_step_full")
    out: list[float] = []
    for key in PHASE_NAMES.values():
        out += [float(base[key]), float(full[key])]
    return out + [kernel(b, "control_step_baseline"), kernel(b, "control_step_full"),
                  float(b["cm4_cost"]["kernels"]["control_step_full"]["worst_slot"]), kernel(b, "isr_worst_case")]


PROFILE_TOTAL = r"their caller; ([\d,]+) in all\)"


def profile_row_spans(text: str) -> list[tuple[list[str], Span]]:
    """The per-function profile of the worst period: (backticked names, span of instructions) per row."""
    rows = []
    for row in _table_rows(text, "### Where the worst period goes"):
        s, at = row[1]
        rows.append((re.findall(r"`([A-Za-z0-9_]+)`", row[0][0]), (at, at + len(s))))
    return rows


def profile_rows(text: str) -> tuple[list[tuple[list[str], float]], float]:
    """The per-function profile of the worst period: (backticked names, instructions) per row, the total."""
    (s, e), = pattern(PROFILE_TOTAL)(text)
    rows = [(names, num(text[a:z])) for names, (a, z) in profile_row_spans(text)]
    return rows, num(text[s:e])


def profile_bench(b: Bench, text: str) -> list[float]:
    """Each profile row's functions summed from profile.json; a row without one is the rest."""
    by = b["profile"]["by_symbol"]
    rows = profile_row_spans(text)
    named = [float(sum(by.get(s, 0) for s in names)) if names else None for names, _ in rows]
    rest = float(b["profile"]["instructions"]) - sum(x for x in named if x is not None)
    return [rest if x is None else x for x in named]


def slack(b: Bench, text: str) -> list[float]:
    """Slack of the worst period at 10 and 20 kHz (cycles, us) and the load at 20 kHz (percent)."""
    s10, s20 = b["isr_load"]["slack"]["10kHz"], b["isr_load"]["slack"]["20kHz"]
    return [float(s10["slack_cycles"]), float(s10["slack_us"]), float(s20["slack_cycles"]), float(s20["slack_us"]),
            100.0 * float(s20["cpu_load"])]


def worst_banks(b: Bench, text: str) -> list[float]:
    """The bank's phase in its worst tick: full closed, semi-closed, dual-loop (isr_load.json)."""
    c = b["isr_load"]["comp_bank_phase"]
    return [float(c[k]["worst_instructions"]) for k in ("control_step_full", "control_step_semi", "control_step_dual")]


def over_budget(b: Bench) -> list[float]:
    """How far each feedback configuration's worst tick is over :data:`BANK_BUDGET`."""
    return [bank(b, k)[-1] - BANK_BUDGET for k in TICK_ROWS.values()]


@dataclass(frozen=True)
class Claim:
    """Figures the docs quote (``spans``: where in the text) and the bench's (``bench``).

    ``tol`` is one tolerance for every figure, one per figure, or a function of the docs'
    text giving one per figure.
    """

    name: str
    spans: Callable[[str], list[Span]]
    bench: Callable[[Bench, str], list[float]]
    tol: float | tuple[float, ...] | Callable[[str], tuple[float, ...]] = TOL_INSTRUCTIONS

    def figures(self, text: str) -> list[Span]:
        """Where the figures are in the docs, each exactly one figure (a pattern's group may take
        the comma after it, as in '53 / 922, hunt breaker')."""
        out: list[Span] = []
        for s, e in self.spans(text):
            m = NUMBER.fullmatch(text, s, e) or NUMBER.fullmatch(text, s, e - 1)
            if m is None or text[s:e].startswith(","):
                raise FigureError(f"docs/firmware.md: {self.name}: {text[s:e]!r} is not a figure")
            out.append(m.span())
        return out

    def doc(self, text: str) -> list[float]:
        """The figures the docs quote, in order."""
        return [num(text[s:e]) for s, e in self.figures(text)]

    def tolerances(self, text: str, n: int) -> tuple[float, ...]:
        """One tolerance per figure (``n`` figures)."""
        if callable(self.tol):
            return self.tol(text)
        return self.tol if isinstance(self.tol, tuple) else (self.tol,) * n


CLAIMS: tuple[Claim, ...] = (
    Claim("Totals table", totals_spans, totals, tol=totals_tolerances),
    Claim("profile of the worst period: total", pattern(PROFILE_TOTAL),
          lambda b, t: [float(b["profile"]["instructions"])]),
    Claim("profile of the worst period: its tick", pattern(r"`isr_worst_case` in its worst tick\s+\((\d),"),
          lambda b, t: [float(b["profile"]["tick"])]),
    Claim("bank's phase per tick", tick_spans,
          lambda b, t: [x for k in TICK_ROWS.values() for x in bank(b, k)]),
    Claim("targets: the bank's worst ticks",
          pattern(r"it\s+takes ([\d,]+) / ([\d,]+) / ([\d,]+) instructions \(full-closed / semi-closed / dual-loop; "
                  r"([\d,]+)\s+semi-closed with `pr_t_src` 2\)"),
          lambda b, t: worst_banks(b, t) + [bank(b, "isr_worst_case_semi_t2")[-1]]),
    Claim("what the targets need: the bank's worst ticks",
          pattern(r"Left to do: the bank's phase <= 850 in every tick \(([\d,]+) / ([\d,]+) / ([\d,]+); ([\d,]+) with"),
          lambda b, t: worst_banks(b, t) + [bank(b, "isr_worst_case_semi_t2")[-1]]),
    Claim("what the targets need: the bank in the worst tick",
          pattern(r"in the worst tick: ([\d,]+) \+ ~300\)"),
          lambda b, t: [bank(b, "control_step_full")[-1]]),
    Claim("the bank's worst ticks over the budget",
          pattern(r"the worst tick is ([\d,]+) \(full closed\),\s+([\d,]+) \(semi-closed\), ([\d,]+) \(semi-closed, "
                  r"`pr_t_src` 2\) and ([\d,]+) \(dual-loop\)\s+instructions over it"),
          lambda b, t: over_budget(b)),
    Claim("targets: how far the bank is over its budget", pattern(r"\), ([\d,]+) to ([\d,]+) over the budget"),
          lambda b, t: [min(over_budget(b)), max(over_budget(b))]),
    Claim("profile of the worst period: per function", lambda t: [sp for _, sp in profile_row_spans(t)],
          profile_bench),
    Claim("per phase, baseline / full worst tick", phase_sentence_spans, phase_sentence_bench),
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
    Claim("targets: the baseline within its 1,000",
          pattern(r"`control_step_baseline` \(([\d,]+)\)\s+within 1,000"),
          lambda b, t: [kernel(b, "control_step_baseline")]),
    Claim("what the targets need: the baseline within its 1,000",
          pattern(r"`control_step_baseline` \(([\d,]+)\) is within its 1,000"),
          lambda b, t: [kernel(b, "control_step_baseline")]),
    Claim("what the targets need: where the baseline goes",
          pattern(r"`control_step_baseline` \(([\d,]+)\) holds about"),
          lambda b, t: [kernel(b, "control_step_baseline")]),
    Claim("first period after a start", pattern(r"`control_step_entry`, ([\d,]+) instructions, once per\s+start"),
          lambda b, t: [kernel(b, "control_step_entry")]),
)


# ------------------------------------------------------------------ check and fix

@dataclass(frozen=True)
class Stale:
    """One quoted figure that differs from the bench's by more than its tolerance."""

    claim: str
    index: int
    span: Span
    quoted: float
    measured: float
    tol: float

    def line(self) -> str:
        """The figure as one report line."""
        return (f"{self.claim}: figure {self.index + 1} quoted {self.quoted:g}, make bench measured "
                f"{self.measured:g} (tolerance {self.tol:g})")


def _measured(c: Claim, text: str, b: Bench) -> list[float]:
    try:
        return c.bench(b, text)
    except (KeyError, IndexError, TypeError, ValueError) as e:
        raise FigureError(f"the bench JSON has no figure for '{c.name}' ({type(e).__name__}: {e}); "
                          "expected the files of make bench") from None


def stale_figures(text: str, b: Bench, claims: Iterable[Claim] | None = None) -> list[Stale]:
    """Every quoted figure that differs from the bench's by more than its tolerance.

    Parameters
    ----------
    text : str
        The docs (docs/firmware.md).
    b : Mapping
        The bench JSON by file stem (``cm4_cost``, ``phase_cost``, ``isr_load``, ``profile``).
    claims : iterable of Claim, optional
        Default :data:`CLAIMS`.

    Returns
    -------
    list of Stale
        In the claims' order.

    Raises
    ------
    FigureError
        A claim that does not find its figures in the docs or the bench, or finds a different
        number of them.
    """
    out: list[Stale] = []
    for c in CLAIMS if claims is None else claims:
        spans = c.figures(text)
        quoted = [num(text[s:e]) for s, e in spans]
        measured = _measured(c, text, b)
        tols = c.tolerances(text, len(quoted))
        if len(measured) != len(quoted) or len(tols) != len(quoted):
            raise FigureError(f"{c.name}: the docs quote {len(quoted)} figures, the bench gives {len(measured)}")
        for i, (sp, q, m, t) in enumerate(zip(spans, quoted, measured, tols)):
            if abs(q - m) > t + 1e-9:
                out.append(Stale(c.name, i, sp, q, m, t))
    return out


def mismatches(text: str, b: Bench, claims: Iterable[Claim] | None = None) -> list[str]:
    """Every quoted figure that differs from the bench's by more than its tolerance, one line each
    (``claims``: default :data:`CLAIMS`)."""
    try:
        return [s.line() for s in stale_figures(text, b, claims)]
    except FigureError as e:
        return [str(e)]


def fixed(text: str, b: Bench, claims: Iterable[Claim] | None = None) -> tuple[str, list[Stale]]:
    """The docs with every stale figure rewritten from the bench, and the figures rewritten.

    Only the stale figures' characters change; each new figure keeps the quoted one's format
    (:func:`fmt`).  A figure quoted by two claims must be given the same value by both.

    Raises
    ------
    FigureError
        As :func:`stale_figures`, or two claims that want different values in one place.
    """
    stale = stale_figures(text, b, claims)
    new: dict[Span, str] = {}
    for s in stale:
        if s.measured < 0:
            raise FigureError(f"{s.claim}: figure {s.index + 1} is negative in the bench ({s.measured:g}); "
                              "the sentence needs rewording, not a new figure")
        value = fmt(s.measured, text[s.span[0]:s.span[1]])
        if new.setdefault(s.span, value) != value:
            raise FigureError(f"{s.claim}: figure {s.index + 1} is also quoted by another claim with "
                              f"{new[s.span]}, the bench gives {value}")
    out = text
    for (a, z), value in sorted(new.items(), reverse=True):
        out = out[:a] + value + out[z:]
    return out, stale


def write_text_atomic(path: Path, text: str) -> None:
    """``text`` to ``path`` through a temporary file in its directory and a rename (keeps the mode)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.write(text)
        if path.exists():
            os.chmod(tmp, path.stat().st_mode & 0o7777)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def bench_json(bench: Path = BENCH, root: Path = ROOT) -> dict[str, Any] | None:
    """The bench's JSON when every file is there and newer than what it measured, else None."""
    paths = [bench / f"{f}.json" for f in FILES]
    if not all(p.is_file() for p in paths):
        return None
    made = min(p.stat().st_mtime for p in paths)
    inputs = [root / i for i in IMAGES if (root / i).is_file()]
    for d in SOURCES:
        inputs += [p for p in (root / d).rglob("*") if p.suffix in (".c", ".h", ".S", ".ld")]
    if any(p.stat().st_mtime > made for p in inputs):
        return None
    return {f: json.loads((bench / f"{f}.json").read_text()) for f in FILES}


def _shown(path: Path) -> str:
    """``path`` relative to the working directory when it is below it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _load_bench(bench: Path) -> dict[str, Any]:
    missing = [f"{f}.json" for f in FILES if not (bench / f"{f}.json").is_file()]
    if missing:
        raise FigureError(f"{_shown(bench)}: no {', '.join(missing)}; expected the JSON of make bench (run make bench)")
    try:
        b = bench_json(bench)
    except json.JSONDecodeError as e:
        raise FigureError(f"{_shown(bench)}: a bench file is not JSON ({e}); expected the JSON of make bench") from None
    if b is None:
        raise FigureError(f"{_shown(bench)}: the bench JSON is older than the firmware it measured; "
                          "expected a fresh make bench (run make bench)")
    return b


def main(argv: Sequence[str] | None = None) -> int:
    """The command line: ``check`` (default) or ``--fix``; 0 clean / fixed, 1 stale, 2 bad input."""
    ap = argparse.ArgumentParser(description="Check docs/firmware.md's bench figures against make bench, "
                                             "or rewrite them from it (--fix).")
    ap.add_argument("action", nargs="?", choices=("check",), default="check",
                    help="compare every quoted figure with the bench JSON (default)")
    ap.add_argument("--fix", action="store_true", help="rewrite every stale figure in place from the bench JSON")
    ap.add_argument("--doc", type=Path, default=DOC, help="the docs to check (default docs/firmware.md)")
    ap.add_argument("--bench", type=Path, default=BENCH, help="the bench JSON directory (default build/bench)")
    args = ap.parse_args(argv)
    try:
        try:
            text = args.doc.read_text(encoding="utf-8")
        except OSError as e:
            raise FigureError(f"{_shown(args.doc)}: cannot read the docs ({e.strerror})") from None
        b = _load_bench(args.bench)
        if args.fix:
            new, stale = fixed(text, b)
            left = stale_figures(new, b)
            if left:
                raise FigureError(f"{_shown(args.doc)}: {left[0].line()} after the rewrite; "
                                  "expected the claims to read back what they wrote (left as it was)")
            if stale:
                write_text_atomic(args.doc, new)
            print(f"{_shown(args.doc)}: {len(stale)} stale figure(s) rewritten from {_shown(args.bench)}")
            return 0
        stale = stale_figures(text, b)
    except FigureError as e:
        print(f"firmware_doc_figures: error: {e}", file=sys.stderr)
        return 2
    for s in stale:
        print(f"{_shown(args.doc)}: {s.line()}")
    n = sum(len(c.figures(text)) for c in CLAIMS)
    print(f"{_shown(args.doc)}: {n - len(stale)} of {n} figures agree with {_shown(args.bench)}"
          + ("; run tools/firmware_doc_figures.py --fix (make docs-figures)" if stale else ""))
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
