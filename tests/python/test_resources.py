"""hdservo.resources is the one way the package finds its files; nothing else points into the checkout."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hdservo import resources, sim
from hdservo.errors import UserError

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "host" / "hdservo"


def test_checkout_mode_finds_build_outputs_and_sim_files() -> None:
    assert resources.checkout_root() == ROOT
    assert resources.axis_file("reference") == ROOT / "sim" / "axes" / "reference.toml"
    assert resources.axis_file("csf17_50.toml") == ROOT / "sim" / "axes" / "csf17_50.toml"
    assert resources.scenario_file("step") == ROOT / "sim" / "scenarios" / "step.toml"
    assert resources.eds_path().is_file() and resources.dbc_path().is_file()
    assert resources.example_log().is_file()


def test_environment_overrides_the_native_files(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("HDSERVO_SIM", str(tmp_path / "my-sim"))
    monkeypatch.setenv("HDSERVO_SIMLIB", str(tmp_path / "my.so"))
    assert resources.sim_program() == tmp_path / "my-sim"
    assert resources.sim_library() == tmp_path / "my.so"


def test_unknown_axis_is_one_line_naming_the_shipped_ones() -> None:
    with pytest.raises(UserError) as e:
        resources.axis_file("csf99_1")
    msg = str(e.value)
    assert "\n" not in msg and "csf99_1" in msg and "reference" in msg and "csf17_50" in msg


def test_axis_arg_maps_names_and_keeps_paths(tmp_path: Path) -> None:
    assert resources.axis_arg("reference") == "reference"
    assert resources.axis_arg("minimal") == "minimal"
    assert resources.axis_arg("csf17_50") == str(ROOT / "sim" / "axes" / "csf17_50.toml")
    assert resources.axis_arg("some/dir/x.toml") == "some/dir/x.toml"
    assert resources.axis_arg("no_such_axis") == "no_such_axis"     # the simulator refuses it


def test_outside_a_checkout_a_missing_simulator_is_one_line(tmp_path: Path) -> None:
    """A copy of the package with no build outputs around it: the locator says what is missing
    and how to get it, and never runs make."""
    import shutil
    pkg = tmp_path / "site" / "hdservo"
    shutil.copytree(PKG, pkg, ignore=shutil.ignore_patterns("__pycache__", "emps"))
    code = ("import hdservo\nassert hdservo.__file__.startswith(%r), hdservo.__file__\n"
            "from hdservo import resources, sim\n"
            "for f in (resources.sim_program, resources.sim_library, sim.load_library):\n"
            "    try:\n        f(); print('found', f.__name__)\n"
            "    except resources.UserError as e:\n        print('error', str(e).count(chr(10)), e)\n"
            "print(resources.checkout_root())\n") % str(pkg)
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                       env={"PYTHONPATH": str(tmp_path / "site"), "PATH": "/usr/bin:/bin"})
    assert p.returncode == 0, p.stderr[-2000:]
    lines = p.stdout.strip().splitlines()
    assert len(lines) == 4, lines
    assert all(ln.startswith("error 0 ") for ln in lines[:3]), lines
    assert "hdservo-sim" in lines[0] and "HDSERVO_SIM" in lines[0]
    assert "libhdsim.so" in lines[1] and "make sim" in lines[1]
    assert lines[3] == "None"
    assert not (tmp_path / "build").exists()


def test_no_library_module_locates_files_by_itself() -> None:
    """Only hdservo/resources.py derives paths from the package location or the checkout."""
    bad = []
    pattern = re.compile(r"REPO_ROOT|parents\[\d\]|__file__|importlib\.resources|resources\.files\(")
    for path in sorted(PKG.rglob("*.py")):
        if path.name == "resources.py" and path.parent == PKG:
            continue
        tree = ast.parse(path.read_text(), str(path))
        doc_lines = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                doc_lines.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
        for i, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#", 1)[0]
            if i not in doc_lines and pattern.search(code):
                bad.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
            if i not in doc_lines and re.search(r"\[\s*\"make\"", code):
                bad.append(f"{path.relative_to(ROOT)}:{i}: runs make: {line.strip()}")
    assert not bad, "\n".join(bad)


def test_sim_library_comes_from_the_locator(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("HDSERVO_SIMLIB", str(tmp_path / "absent.so"))
    assert sim.library_path() == tmp_path / "absent.so"


def test_shipped_example_log_is_what_its_generator_writes(tmp_path: Path) -> None:
    """The example log comes from tools/make_example_log.py (same scenario, columns and rows);
    regenerate it with that tool when the simulated axis changes."""
    from hdservo import logio
    out = tmp_path / "ex.csv"
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "make_example_log.py"), "--out", str(out)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    new, shipped = logio.read_log(out), logio.read_log(resources.example_log())
    assert list(new.columns) == list(shipped.columns)
    for key in ("scenario", "scenario_name", "axis", "seed", "log_decimation", "duration_s", "gear_ratio"):
        assert new.meta[key] == shipped.meta[key], key
    import numpy as np
    for name in new.columns:
        a, b = np.asarray(new.columns[name]), np.asarray(shipped.columns[name])
        assert a.shape == b.shape, name
        scale = max(float(np.max(np.abs(b))), 1e-12)
        assert float(np.max(np.abs(a - b))) <= 1e-3 * scale, name


def test_sim_option_takes_a_shipped_axis_name(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import argparse
    from hdservo.drive import add_bus_arguments, choose_drive
    monkeypatch.setenv("HOME", str(tmp_path))
    for k in [k for k in __import__("os").environ if k.startswith("CAN_")]:
        monkeypatch.delenv(k)
    p = argparse.ArgumentParser()
    add_bus_arguments(p)
    c = choose_drive(p.parse_args(["--sim", "csf17_50"]))
    assert c.virtual and c.axis == str(resources.axis_file("csf17_50"))
    with pytest.raises(UserError, match="csf17_50") as e:
        choose_drive(p.parse_args(["--sim", "csf99_1"]))
    assert "\n" not in str(e.value)
