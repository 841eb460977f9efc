"""One home per concept in the host package: the rules are read off the source (AST), so a
second atomic writer, backend switch, JSON cleaner or phase unwrapper is found where it is added."""
from __future__ import annotations

import ast
from pathlib import Path
from typing import Iterator

import pytest

PKG = Path(__file__).resolve().parents[2] / "host" / "hdservo"


def _modules() -> Iterator[tuple[str, ast.Module]]:
    for p in sorted(PKG.rglob("*.py")):
        yield str(p.relative_to(PKG.parent)), ast.parse(p.read_text(encoding="utf-8"), filename=str(p))


def _dotted(node: ast.AST) -> str:
    """``a.b.c`` of a Name/Attribute chain ('' for anything else)."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return ".".join(reversed(parts))
    return ""


def _calls(tree: ast.Module) -> Iterator[tuple[str, int]]:
    for n in ast.walk(tree):
        if isinstance(n, ast.Call):
            yield _dotted(n.func), n.lineno


def _offenders(home: str, names: set[str]) -> list[str]:
    return [f"{mod}:{line} {name}" for mod, tree in _modules() if mod != home
            for name, line in _calls(tree) if name in names]


def test_the_scan_sees_the_package() -> None:
    mods = dict(_modules())
    assert len(mods) > 50
    assert any(n == "json.dumps" for n, _ in _calls(mods["hdservo/fileio.py"]))
    assert any(n == "matplotlib.use" for n, _ in _calls(mods["hdservo/plotting.py"]))


def test_matplotlib_backend_is_chosen_only_in_plotting() -> None:
    assert _offenders("hdservo/plotting.py", {"matplotlib.use"}) == []


def test_files_are_replaced_atomically_only_in_fileio() -> None:
    """Temporary files and renames onto a result belong to hdservo.fileio (umask, cleanup)."""
    names = {"tempfile.mkstemp", "tempfile.mkdtemp", "os.replace", "os.rename", "json.dump"}
    assert _offenders("hdservo/fileio.py", names) == []


def test_json_text_is_not_written_by_hand() -> None:
    """``x.write_text(json.dumps(...))`` bypasses the strict encoder and the atomic rename."""
    bad = []
    for mod, tree in _modules():
        for n in ast.walk(tree):
            if (isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.func.attr in ("write_text", "write")
                    and any(_dotted(c.func) == "json.dumps" for a in n.args for c in ast.walk(a)
                            if isinstance(c, ast.Call))):
                bad.append(f"{mod}:{n.lineno}")
    assert bad == []


def _json_cleaner(fn: ast.FunctionDef) -> bool:
    """A recursive walk through dicts that turns non-finite floats into something else: a JSON cleaner."""
    recursive = any(isinstance(c, ast.Call) and _dotted(c.func) == fn.name for c in ast.walk(fn))
    src = ast.unparse(fn)
    return recursive and "isfinite" in src and "isinstance" in src and "dict" in src


@pytest.mark.parametrize("rule", ["json-cleaner", "unwrapper"])
def test_one_definition(rule: str) -> None:
    found = []
    for mod, tree in _modules():
        for n in ast.walk(tree):
            if not isinstance(n, ast.FunctionDef):
                continue
            if rule == "json-cleaner" and _json_cleaner(n):
                found.append(f"{mod}:{n.name}")
            if rule == "unwrapper" and "unwrap" in n.name.lower():
                found.append(f"{mod}:{n.name}")
    if rule == "json-cleaner":
        assert found == ["hdservo/fileio.py:json_ready"]
    else:
        assert sorted(found) == ["hdservo/phase.py:unwrap_count", "hdservo/phase.py:unwrap_pair", "hdservo/phase.py:unwrap_phase",
                                 "hdservo/phase.py:unwrap_tick", "hdservo/phase.py:unwrap_turns"]
