"""The wheel works outside the checkout: build it, install it into a fresh venv, run the CLI.

The wheel is built from host/ without build isolation (the project venv has setuptools) and
installed with ``--no-deps`` into a new venv in a temporary directory; the dependencies
(numpy, scipy, ...) come from the project venv through a ``.pth`` line, which adds that
directory to ``sys.path`` without running its ``.pth`` files, so the checkout's editable
install stays invisible.  Every command runs from a temporary working directory with a
cleared environment, and each test checks that it used the installed package.
"""
from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import sysconfig
import time
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _env(home: Path) -> dict[str, str]:
    """A clean environment: no PYTHONPATH, no simulator overrides, a private HOME and cache."""
    env = {"PATH": "/usr/bin:/bin", "HOME": str(home), "LANG": "C.UTF-8", "MPLBACKEND": "Agg",
           "MPLCONFIGDIR": str(home / "mpl"), "PIP_DISABLE_PIP_VERSION_CHECK": "1", "PIP_NO_INDEX": "1"}
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Build the wheel, create the venv, install the wheel; paths of the venv's programs."""
    tmp = tmp_path_factory.mktemp("wheel")
    home = tmp / "home"
    home.mkdir()
    dist = tmp / "dist"
    p = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(dist), str(ROOT / "host")], cwd=tmp, capture_output=True, text=True,
                       timeout=600, env={**os.environ, "PIP_NO_INDEX": "1"})
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    wheels = sorted(dist.glob("hdservo-*.whl"))
    assert len(wheels) == 1, wheels
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    py = venv / "bin" / "python"
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    deps = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (site / "_hdservo_test_deps.pth").write_text("".join(f"{d}\n" for d in sorted(deps)))
    # pip of the project venv installs into the new venv (--python needs pip >= 22.3)
    p = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--no-index", "-q",
                        str(wheels[0])], cwd=tmp, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    work = tmp / "work"
    work.mkdir()
    return {"wheel": wheels[0], "venv": venv, "python": py, "hdservo": venv / "bin" / "hdservo", "work": work,
            "home": home}


def _run(inst: dict[str, Path], *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(inst["hdservo"]), *args], cwd=inst["work"], capture_output=True, text=True,
                          timeout=timeout, env=_env(inst["home"]))


def test_wheel_carries_simulator_axes_eds_dbc_and_licence(installed: dict[str, Path]) -> None:
    names = set(zipfile.ZipFile(installed["wheel"]).namelist())
    for want in ("hdservo/_native/hdservo-sim", "hdservo/_native/libhdsim.so", "hdservo/data/hdservo.eds",
                 "hdservo/data/hdservo.dbc", "hdservo/data/axes/reference.toml", "hdservo/data/axes/csf17_50.toml",
                 "hdservo/data/scenarios/step.toml", "hdservo/data/examples/chirp_reference.csv",
                 "hdservo/data/examples/chirp_reference.json", "hdservo/resources.py"):
        assert want in names, want
    assert any(n.endswith("licenses/LICENSE") or n.endswith("/LICENSE") for n in names), sorted(names)[:20]
    meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
    text = zipfile.ZipFile(installed["wheel"]).read(meta).decode()
    assert "License-Expression: MIT" in text
    assert "Requires-Python: >=3.11" in text
    assert "Requires-Dist: numpy>=" in text
    # the wheel holds a native program: tagged for a platform, not "any"
    assert not installed["wheel"].name.endswith("-any.whl"), installed["wheel"].name


def test_installed_package_finds_its_files_inside_itself(installed: dict[str, Path]) -> None:
    code = ("import json, hdservo; from hdservo import resources as r; print(json.dumps({"
            "'pkg': hdservo.__file__, 'checkout': str(r.checkout_root()), 'prog': str(r.sim_program()),"
            "'lib': str(r.sim_library()), 'axis': str(r.axis_file('csf17_50')), 'eds': str(r.eds_path()),"
            "'dbc': str(r.dbc_path()), 'axes': r.axis_names()}))")
    p = subprocess.run([str(installed["python"]), "-c", code], cwd=installed["work"], capture_output=True,
                       text=True, timeout=120, env=_env(installed["home"]))
    assert p.returncode == 0, p.stderr[-2000:]
    got = json.loads(p.stdout)
    venv = str(installed["venv"].resolve())
    assert got["checkout"] == "None"
    for key in ("pkg", "prog", "lib", "axis", "eds", "dbc"):
        assert got[key].startswith(venv), (key, got[key])
        assert not got[key].startswith(str(ROOT)), (key, got[key])
    assert {"reference", "csf17_50"} <= set(got["axes"])


def test_help_runs(installed: dict[str, Path]) -> None:
    p = _run(installed, "--help", timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    for cmd in ("sim", "serve", "discrepancy"):
        assert cmd in p.stdout


def test_sim_runs_a_shipped_scenario(installed: dict[str, Path]) -> None:
    p = _run(installed, "sim", "step", "--duration", "0.1", "-o", "x.csv")
    assert p.returncode == 0, p.stderr[-2000:]
    log = installed["work"] / "x.csv"
    rows = log.read_text().splitlines()
    assert rows[0].startswith("t_s,")
    assert len(rows) == 1 + 1000                      # 0.1 s at the 10 kHz loop, one row per period
    meta = json.loads(log.with_suffix(".json").read_text())
    assert meta["scenario_name"] == "step"
    # an unknown name is one line naming what is shipped
    p = _run(installed, "sim", "no_such_scenario", "-o", "y.csv")
    assert p.returncode == 2
    assert len(p.stderr.strip().splitlines()) == 1 and "step" in p.stderr, p.stderr
    assert not (installed["work"] / "y.csv").exists()


def _children(pid: int) -> list[int]:
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            kids.append(int(stat.parent.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_serve_starts_listens_and_stops_on_sigterm(installed: dict[str, Path]) -> None:
    proc = subprocess.Popen([str(installed["hdservo"]), "serve", "--port", "0", "--axis", "csf17_50"],
                            cwd=installed["work"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env(installed["home"]), start_new_session=True)
    try:
        line = ""
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not line:
            ready, _, _ = select.select([proc.stdout], [], [], 1.0)
            if ready:
                line = proc.stdout.readline()
                if not line:
                    break
        assert line.startswith("listening on 127.0.0.1:"), (line, proc.poll())
        assert int(line.strip().rsplit(":", 1)[1]) > 0
        sims = _children(proc.pid)
        assert len(sims) == 1, sims                      # hdservo-sim, started by the command
        proc.send_signal(signal.SIGTERM)                  # to the command only, as a service manager does
        proc.wait(timeout=20)
        deadline = time.monotonic() + 10
        while _alive(sims[0]) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(sims[0]), "hdservo-sim still serves after hdservo serve got SIGTERM"
        assert proc.returncode in (0, 128 + signal.SIGTERM), proc.returncode
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)           # whatever is left of the command's session
        proc.wait(timeout=20)


def test_discrepancy_on_the_shipped_example_log(installed: dict[str, Path]) -> None:
    p = subprocess.run([str(installed["python"]), "-c", "from hdservo import resources; print(resources.example_log())"],
                       cwd=installed["work"], capture_output=True, text=True, timeout=120, env=_env(installed["home"]))
    assert p.returncode == 0, p.stderr
    log = Path(p.stdout.strip())
    assert log.is_file() and log.with_suffix(".json").is_file()
    assert log.stat().st_size + log.with_suffix(".json").stat().st_size < 200_000
    p = _run(installed, "discrepancy", str(log), "--json", "d.json", timeout=900)
    assert p.returncode == 0, p.stderr[-2000:]
    out = json.loads((installed["work"] / "d.json").read_text())
    assert out["log"] == str(log)
    assert out["structure"] == "two_mass"
    assert out["iterations"], out.keys()
