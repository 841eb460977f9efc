"""The package's layers (import-linter contracts in host/pyproject.toml) hold."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _lint_imports() -> str:
    exe = Path(sys.executable).with_name("lint-imports")
    return str(exe) if exe.exists() else (shutil.which("lint-imports") or "lint-imports")


def test_import_contracts_are_kept(tmp_path: Path) -> None:
    p = subprocess.run([_lint_imports(), "--no-cache", str(ROOT / "host" / "pyproject.toml")],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-2000:]
    assert "0 broken" in p.stdout


def test_a_library_import_of_the_cli_breaks_the_contract(tmp_path: Path) -> None:
    """The check can fail: a copy of the contracts run on a package whose library imports the CLI."""
    pkg = tmp_path / "hdservo"
    (pkg / "commands").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "cli.py").write_text("from . import commands\n")
    (pkg / "commands" / "__init__.py").write_text("")
    (pkg / "errors.py").write_text("")
    (pkg / "logio.py").write_text("from . import cli\n")
    cfg = tmp_path / "contracts.toml"
    cfg.write_text("[tool.importlinter]\nroot_package = \"hdservo\"\n\n"
                   "[[tool.importlinter.contracts]]\nname = \"library-not-cli\"\ntype = \"forbidden\"\n"
                   "source_modules = [\"hdservo.*\"]\nforbidden_modules = [\"hdservo.commands\", \"hdservo.cli\"]\n"
                   "ignore_imports = [\"hdservo.cli -> hdservo.commands\"]\n")
    p = subprocess.run([_lint_imports(), "--no-cache", str(cfg)], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300, env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"})
    assert p.returncode != 0
    assert "hdservo.logio" in p.stdout


def test_an_upward_import_breaks_the_layers(tmp_path: Path) -> None:
    """The check can fail: the package's own contracts on a copy whose simulator binding imports the CAN
    client (a layer above it) and whose report builder imports a drive."""
    pkg = tmp_path / "hdservo"
    shutil.copytree(ROOT / "host" / "hdservo", pkg, ignore=shutil.ignore_patterns("__pycache__", "data", "_native"))
    with open(pkg / "sim.py", "a", encoding="utf-8") as f:
        f.write("\nfrom . import driveconfig  # noqa: E402,F401\n")
    with open(pkg / "report" / "builder.py", "a", encoding="utf-8") as f:
        f.write("\nfrom .. import drive  # noqa: E402,F401\n")
    p = subprocess.run([_lint_imports(), "--no-cache", str(ROOT / "host" / "pyproject.toml")], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300,
                       env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"})
    assert p.returncode != 0
    assert "hdservo.sim -> hdservo.driveconfig" in p.stdout
    assert "hdservo.report.builder -> hdservo.drive" in p.stdout
