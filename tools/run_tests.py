#!/usr/bin/env python3
"""Run every hdservo test suite and print one closing line ``N passed, N failed``.

Suites, in order (each one's own output is printed above the summary):

* ``c-unit``  -- every ``build/host/tests/test_*`` cmocka binary, run with TAP output.
* ``checks``  -- every ``tests/checks/*.sh`` script; each prints TAP lines
  (``ok - what`` / ``not ok - what``).
* ``pytest``  -- ``tests/python`` (and anything else pytest collects there).

A program that exits non-zero without reporting a failing case counts as one
failure, so a crash can never pass silently.  Environment: ``HD_TEST_ONLY`` (a
comma-separated list of suite names) restricts the run.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUILD = ROOT / "build"
TAP_OK = re.compile(r"^\s*ok\b")
TAP_NOT_OK = re.compile(r"^\s*not ok\b")


def _count_tap(text: str) -> tuple[int, int]:
    passed = sum(1 for line in text.splitlines() if TAP_OK.match(line))
    failed = sum(1 for line in text.splitlines() if TAP_NOT_OK.match(line))
    return passed, failed


def _run(cmd: list[str], env: dict[str, str] | None = None, timeout: float = 3600) -> tuple[int, str]:
    try:
        p = subprocess.run(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, timeout=timeout)
        return p.returncode, p.stdout
    except subprocess.TimeoutExpired as e:
        out = e.stdout if isinstance(e.stdout, str) else (e.stdout or b"").decode(errors="replace")
        return 124, out + f"\nTIMEOUT after {timeout:.0f} s: {' '.join(cmd)}\n"


def _tap_program(name: str, cmd: list[str], env: dict[str, str] | None = None,
                 timeout: float = 3600) -> tuple[int, int]:
    t0 = time.monotonic()
    rc, out = _run(cmd, env=env, timeout=timeout)
    sys.stdout.write(out)
    passed, failed = _count_tap(out)
    if rc != 0 and failed == 0:
        print(f"not ok - {name} exited with status {rc} without reporting a failing case")
        failed += 1
    if rc == 0 and passed == 0 and failed == 0:
        print(f"not ok - {name} ran no test case")
        failed += 1
    print(f"# {name}: {passed} passed, {failed} failed ({time.monotonic() - t0:.1f} s)")
    sys.stdout.flush()
    return passed, failed


def suite_c_unit() -> tuple[int, int]:
    env = dict(os.environ, CMOCKA_MESSAGE_OUTPUT="TAP",
               ASAN_OPTIONS="detect_leaks=1:abort_on_error=0",
               UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1")
    p = f = 0
    for binary in sorted((BUILD / "host" / "tests").glob("test_*")):
        if not os.access(binary, os.X_OK) or binary.suffix:
            continue
        a, b = _tap_program(binary.name, [str(binary)], env=env)
        p, f = p + a, f + b
    return p, f


def suite_checks() -> tuple[int, int]:
    p = f = 0
    for script in sorted((ROOT / "tests" / "checks").glob("*.sh")):
        a, b = _tap_program(script.name, ["bash", str(script)])
        p, f = p + a, f + b
    return p, f


def suite_pytest() -> tuple[int, int]:
    tests = ROOT / "tests" / "python"
    if not any(tests.rglob("test_*.py")):
        return 0, 0
    xml = BUILD / "test" / "pytest.xml"
    xml.parent.mkdir(parents=True, exist_ok=True)
    if xml.exists():
        xml.unlink()
    rc, out = _run([str(ROOT / ".venv" / "bin" / "python"), "-m", "pytest", "-q",
                    "-p", "no:cacheprovider", f"--junitxml={xml}", str(tests)])
    sys.stdout.write(out)
    if not xml.exists():
        print(f"not ok - pytest exited with status {rc} and wrote no report")
        return 0, 1
    root = ET.parse(xml).getroot()
    suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
    total = sum(int(s.get("tests", 0)) for s in suites)
    failed = sum(int(s.get("failures", 0)) + int(s.get("errors", 0)) for s in suites)
    skipped = sum(int(s.get("skipped", 0)) for s in suites)
    passed = total - failed - skipped
    if rc not in (0, 5) and failed == 0:
        failed = 1
    return passed, failed


SUITES = {"c-unit": suite_c_unit, "checks": suite_checks, "pytest": suite_pytest}


def main() -> int:
    only = [s for s in os.environ.get("HD_TEST_ONLY", "").split(",") if s]
    total_p = total_f = 0
    t0 = time.monotonic()
    for name, fn in SUITES.items():
        if only and name not in only:
            continue
        print(f"=== suite {name}")
        sys.stdout.flush()
        p, f = fn()
        print(f"=== suite {name}: {p} passed, {f} failed")
        total_p += p
        total_f += f
    print(f"# all suites took {time.monotonic() - t0:.0f} s")
    print(f"{total_p} passed, {total_f} failed")
    return 0 if total_f == 0 and total_p > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
