#!/usr/bin/env python3
"""Static analysis of firmware/: cppcheck with the MISRA C:2012 addon and clang-tidy.

Usage (from anywhere; paths are relative to the repository root):
    python3 tools/lint/lint.py [--strict DIR ...] [--json PATH] [DIR ...]

* DIRs to analyse (default: firmware/core firmware/app firmware/canopen).
* --strict DIRs (default: firmware/core firmware/app): any finding there that
  is not covered by a deviation in docs/misra-deviations.md makes the exit
  status 1.  Findings elsewhere are counted and reported only.
* Every finding is printed as ``file:line: tool rule [Dnn|UNDOCUMENTED]``;
  then counts per rule (total / documented / undocumented) and the closing
  line ``lint: N findings, N documented, N undocumented (N in strict dirs)``.
* JSON (default build/lint/lint.json): counts per rule and tool, every
  finding with its deviation id.

Deviations (docs/misra-deviations.md) are table rows
``| Dnn | rule id | path glob | `regex` or blank | why |``: a finding is
covered when its rule matches, its path matches the glob, and (if a regex is
given) the regex matches the source line of the finding.  cppcheck 2.10's
MISRA addon has no rule texts (licensed), so rules are named by number only.

Results are cached under build/lint/cache, keyed by the content of every
analysed file and header and of this script's tool settings, so an unchanged
tree is re-linted in well under a second.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import fnmatch
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DEV_DOC = ROOT / "docs" / "misra-deviations.md"
CACHE = ROOT / "build" / "lint" / "cache"
INCLUDES = ["firmware/core", "firmware/app", "firmware/canopen", "firmware/hal"]
CPPCHECK_ARGS = ["--addon=misra", "--std=c99", "--enable=warning,style,portability,performance",
                 "--inline-suppr", "--quiet", "--platform=unix64",
                 "--template={file}:{line}:{column}: {severity} {id} {message}"]
TIDY_CHECKS = ("-*,clang-analyzer-*,bugprone-*,cert-*,misc-redundant-expression,"
               "readability-misleading-indentation,-bugprone-easily-swappable-parameters")
TIDY_ARGS = ["-std=c99", "-D__STDC_NO_THREADS__"] + [f"-I{d}" for d in INCLUDES]
LINE_RE = re.compile(r"^(?P<file>[^:\s]+):(?P<line>\d+):(?P<col>\d+): (?P<sev>\w+) (?P<id>[\w.\-]+) ?(?P<msg>.*)$")
TIDY_RE = re.compile(r"^(?P<file>[^:\s]+):(?P<line>\d+):(?P<col>\d+): (?:warning|error): (?P<msg>.*) \[(?P<id>[\w.,\-]+)\]$")


def sha(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p)
        h.update(b"\0")
    return h.hexdigest()[:24]


def headers() -> list[Path]:
    return sorted(p for d in INCLUDES for p in (ROOT / d).glob("*.h"))


def load_deviations() -> list[dict]:
    devs = []
    if not DEV_DOC.exists():
        return devs
    for line in DEV_DOC.read_text().splitlines():
        # cells split on unescaped pipes; "\|" inside a cell is a literal "|"
        body = line.strip()[1:-1] if line.startswith("| D") and line.strip().endswith("|") else ""
        cells = [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", body)] if body else []
        if len(cells) >= 5 and re.fullmatch(r"D\d+", cells[0]):
            rx = cells[3].strip("`") if cells[3] not in ("", "-", "—") else None
            devs.append({"id": cells[0], "rule": cells[1].strip("`"), "glob": cells[2].strip("`"),
                         "regex": re.compile(rx) if rx else None, "why": cells[4]})
    return devs


def source_line(path: str, line: int, cache: dict[str, list[str]]) -> str:
    if path not in cache:
        try:
            cache[path] = (ROOT / path).read_text(errors="replace").splitlines()
        except OSError:
            cache[path] = []
    lines = cache[path]
    return lines[line - 1] if 0 < line <= len(lines) else ""


def run_cppcheck(files: list[Path]) -> list[dict]:
    key = sha(b"cppcheck", " ".join(CPPCHECK_ARGS).encode(), subprocess.run(
        ["cppcheck", "--version"], capture_output=True).stdout,
        *[p.relative_to(ROOT).as_posix().encode() + p.read_bytes() for p in files + headers()])
    cf_path = CACHE / f"cppcheck-{key}.json"
    if cf_path.exists():
        return json.loads(cf_path.read_text())
    cmd = ["cppcheck", *CPPCHECK_ARGS, f"-j{min(2, os.cpu_count() or 1)}"] + \
          [f"-I{d}" for d in INCLUDES] + [p.relative_to(ROOT).as_posix() for p in files]
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    out = []
    for ln in (p.stderr + p.stdout).splitlines():
        m = LINE_RE.match(ln)
        if m and m["id"] not in ("missingIncludeSystem", "checkersReport", "unmatchedSuppression"):
            out.append({"tool": "cppcheck", "file": m["file"], "line": int(m["line"]),
                        "rule": m["id"], "msg": m["msg"]})
    if p.returncode not in (0, 1):
        raise SystemExit(f"lint: cppcheck failed ({p.returncode}): {p.stderr.strip()[:400]}")
    CACHE.mkdir(parents=True, exist_ok=True)
    cf_path.write_text(json.dumps(out))
    return out


def tidy_one(f: Path, hkey: str) -> list[dict]:
    rel = f.relative_to(ROOT).as_posix()
    key = sha(b"tidy", TIDY_CHECKS.encode(), " ".join(TIDY_ARGS).encode(), hkey.encode(), rel.encode(), f.read_bytes())
    cp = CACHE / f"tidy-{key}.json"
    if cp.exists():
        return json.loads(cp.read_text())
    p = subprocess.run(["clang-tidy", "--quiet", f"-checks={TIDY_CHECKS}", rel, "--", *TIDY_ARGS],
                       cwd=ROOT, capture_output=True, text=True)
    out = []
    for ln in p.stdout.splitlines():
        m = TIDY_RE.match(ln)
        if m:
            path = os.path.relpath(m["file"], ROOT) if os.path.isabs(m["file"]) else m["file"]
            for rid in m["id"].split(","):
                out.append({"tool": "clang-tidy", "file": path, "line": int(m["line"]), "rule": rid, "msg": m["msg"]})
    CACHE.mkdir(parents=True, exist_ok=True)
    cp.write_text(json.dumps(out))
    return out


def run_tidy(files: list[Path]) -> list[dict]:
    hkey = sha(*[p.read_bytes() for p in headers()])
    res: list[dict] = []
    with cf.ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as ex:
        for r in ex.map(lambda f: tidy_one(f, hkey), files):
            res.extend(r)
    # a header finding is reported once per including file: keep one
    seen, uniq = set(), []
    for r in res:
        k = (r["file"], r["line"], r["rule"])
        if k not in seen:
            seen.add(k)
            uniq.append(r)
    return uniq


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="*", default=["firmware/core", "firmware/app", "firmware/canopen"])
    ap.add_argument("--strict", nargs="*", default=["firmware/core", "firmware/app"])
    ap.add_argument("--json", default="build/lint/lint.json")
    ap.add_argument("--quiet", action="store_true", help="print only undocumented findings and the counts")
    a = ap.parse_args()
    for tool in ("cppcheck", "clang-tidy"):
        if shutil.which(tool) is None:
            print(f"lint: {tool} not found (make setup installs it)", file=sys.stderr)
            return 2
    files = sorted(p for d in a.dirs for p in (ROOT / d).glob("*.c"))
    if not files:
        print(f"lint: no C files under {' '.join(a.dirs)}", file=sys.stderr)
        return 2
    findings = run_cppcheck(files) + run_tidy(files)
    devs = load_deviations()
    lines: dict[str, list[str]] = {}
    strict = [d.rstrip("/") + "/" for d in a.strict]
    for f in findings:
        src = source_line(f["file"], f["line"], lines)
        f["deviation"] = None
        for d in devs:
            if d["rule"] == f["rule"] and fnmatch.fnmatch(f["file"], d["glob"]) and \
                    (d["regex"] is None or d["regex"].search(src)):
                f["deviation"] = d["id"]
                break
        f["strict"] = any(f["file"].startswith(s) for s in strict)
    findings.sort(key=lambda f: (f["file"], f["line"], f["rule"]))
    counts: dict[str, dict[str, int]] = {}
    for f in findings:
        c = counts.setdefault(f["rule"], {"tool": f["tool"], "total": 0, "documented": 0, "undocumented": 0})
        c["total"] += 1
        c["documented" if f["deviation"] else "undocumented"] += 1
        if not a.quiet or (f["deviation"] is None and f["strict"]):
            print(f"{f['file']}:{f['line']}: {f['tool']} {f['rule']} "
                  f"[{f['deviation'] or 'UNDOCUMENTED'}] {f['msg']}")
    print(f"{'rule':45s} {'total':>6s} {'documented':>10s} {'undoc':>6s}")
    for rule in sorted(counts, key=lambda r: (-counts[r]["total"], r)):
        c = counts[rule]
        print(f"{rule:45s} {c['total']:6d} {c['documented']:10d} {c['undocumented']:6d}")
    no_reason = [d["id"] for d in devs if len(d["why"]) < 20]
    if no_reason:
        print(f"lint: deviations without a reason: {' '.join(no_reason)}")
    print(f"lint: {len(devs)} deviations in {DEV_DOC.relative_to(ROOT)}, "
          f"{len(devs) - len(no_reason)} with a reason")
    n = len(findings)
    nd = sum(1 for f in findings if f["deviation"])
    nu_strict = sum(1 for f in findings if not f["deviation"] and f["strict"])
    per_dir: dict[str, dict[str, int]] = {}
    for f in findings:
        d = per_dir.setdefault(str(Path(f["file"]).parent), {"total": 0, "undocumented": 0})
        d["total"] += 1
        d["undocumented"] += 0 if f["deviation"] else 1
    out = ROOT / a.json
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps({"dirs": a.dirs, "strict": a.strict, "files": len(files), "findings": n,
                               "documented": nd, "undocumented": n - nd, "undocumented_strict": nu_strict,
                               "per_dir": per_dir, "per_rule": counts, "deviations": [d["id"] for d in devs],
                               "list": findings}, indent=1))
    tmp.replace(out)
    print(f"lint: {len(files)} files, {n} findings, {nd} documented, {n - nd} undocumented "
          f"({nu_strict} in {' '.join(a.strict)})")
    return 1 if nu_strict or no_reason else 0


if __name__ == "__main__":
    sys.exit(main())
