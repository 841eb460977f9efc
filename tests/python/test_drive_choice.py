"""Which drive a command talks to: python-can's configuration, a simulated drive only when asked.

* no bus options and no python-can configuration: every drive command refuses in one line
  (exit 2) and starts no simulator;
* ``--sim [AXIS]`` or the interface name ``virtual-drive`` (``-i`` or ``CAN_INTERFACE``):
  the simulated drive, said on stderr in one line;
* a python-can config file that names socketcand on the port of a running virtual drive:
  the command talks to that drive (python-can's configuration is what is used);
* ``hdservo demo``, simulated by design, says so first.

The commands run as subprocesses with ``HOME`` in a temporary directory and no ``CAN_*``
variables, so no configuration of the machine leaks in.  ``HDSERVO_SIM`` points at a stand-in
program that only leaves a mark, so a simulator start is seen without running one.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hdservo.cli import UserError
from hdservo.drive import Drive, add_bus_arguments, choose_drive

from vdrive import SIM, Server  # tests/python/vdrive.py

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "examples" / "pitch_drive" / "verify" / "model.toml"
NOTICE = "using a simulated drive (virtual drive, axis"

#: the drive commands, each with valid arguments apart from the choice of drive
COMMANDS = {
    "config get": ["config", "get", "pos_kp"],
    "config set": ["config", "set", "pos_kp=30"],
    "download --save": ["download", str(MODEL), "-q", "--save"],
    "test": ["test", "peak-torque", "-q"],
    "compare": ["compare", "-q", "--procedures", "peak-torque"],
    "identify": ["identify", "friction", "-q"],
    "record": ["record", "--duration", "0.5"],
    "drive info": ["drive", "info"],
}


def _env(home: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
    env.update(HOME=str(home), PYTHONPATH=str(ROOT / "host"), **extra)
    return env


def _fake_sim(tmp_path: Path) -> tuple[Path, Path]:
    """A stand-in ``hdservo-sim`` that records that it was started and exits at once; (program, mark)."""
    mark = tmp_path / "sim-started"
    prog = tmp_path / "fake-hdservo-sim"
    prog.write_text(f"#!/bin/sh\necho \"$@\" >> '{mark}'\necho 'fake simulator' >&2\nexit 1\n")
    prog.chmod(0o755)
    return prog, mark


def _run(argv: list[str], cwd: Path, env: dict[str, str], timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hdservo.cli", *argv], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def _argv(name: str, tmp_path: Path) -> list[str]:
    argv = list(COMMANDS[name])
    if name == "compare":
        argv += ["--out-dir", str(tmp_path / "cmp")]
    if name == "record":
        argv += ["-o", str(tmp_path / "rec.csv")]
    return argv


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_no_bus_and_no_python_can_config_refuses_without_a_simulator(tmp_path: Path, name: str) -> None:
    if not MODEL.is_file():
        pytest.skip("examples/pitch_drive/verify/model.toml not present")
    prog, mark = _fake_sim(tmp_path)
    home = tmp_path / "home"
    home.mkdir()
    p = _run(_argv(name, tmp_path), tmp_path, _env(home, HDSERVO_SIM=str(prog)))
    err = p.stderr.strip().splitlines()
    assert p.returncode == 2, (name, p.stderr)
    assert len(err) == 1, (name, err)
    assert "no CAN interface chosen" in err[0] and "python-can" in err[0] and "--sim" in err[0], err
    assert "Traceback" not in p.stderr and NOTICE not in p.stderr
    assert not mark.exists(), f"{name} started a simulator: {mark.read_text()}"
    assert p.stdout == ""
    assert not (tmp_path / "cmp").exists() and not (tmp_path / "rec.csv").exists()


#: every command with --sim; the other spellings of the choice on two of them
ASKED = ([(name, "--sim") for name in sorted(COMMANDS)]
         + [(name, how) for name in ("config get", "identify") for how in ("-i virtual-drive", "CAN_INTERFACE", "can.conf")])


@pytest.mark.parametrize("name, how", ASKED)
def test_simulated_drive_only_when_asked_and_said(tmp_path: Path, name: str, how: str) -> None:
    if not MODEL.is_file():
        pytest.skip("examples/pitch_drive/verify/model.toml not present")
    prog, mark = _fake_sim(tmp_path)
    home = tmp_path / "home"
    home.mkdir()
    argv = _argv(name, tmp_path)
    extra = {"HDSERVO_SIM": str(prog)}
    if how == "--sim":
        argv.append("--sim")
    elif how == "-i virtual-drive":
        argv += ["-i", "virtual-drive"]
    elif how == "CAN_INTERFACE":
        extra["CAN_INTERFACE"] = "virtual-drive"
    else:
        (home / "can.conf").write_text("[default]\ninterface = virtual-drive\n")
    p = _run(argv, tmp_path, _env(home, **extra))
    notices = [ln for ln in p.stderr.splitlines() if NOTICE in ln]
    assert len(notices) == 1, (name, how, p.stderr)
    assert notices[0].startswith(f"hdservo {name.split()[0]}: ") and "axis reference" in notices[0]
    assert "your real drive is not touched" in notices[0]
    assert mark.exists(), (name, how, p.stderr)      # the simulator was started ...
    assert p.returncode == 2 and "Traceback" not in p.stderr     # ... the stand-in exits: one error line


def _vdrive_args(**kw: object) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    add_bus_arguments(p)
    p.add_argument("--seed", type=int, default=None)
    argv: list[str] = []
    for k, v in kw.items():
        argv += [f"--{k.replace('_', '-')}"] + ([] if v is True else [str(v)])
    return p.parse_args(argv)


def test_sim_axis_and_conflicts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("HOME", str(tmp_path))
    for k in [k for k in os.environ if k.startswith("CAN_")]:
        monkeypatch.delenv(k)
    axis = ROOT / "sim" / "axes" / "csf17_50.toml"
    c = choose_drive(_vdrive_args(sim=str(axis)))
    assert c.virtual and c.axis == str(axis.resolve()) and c.axis_name == "csf17_50.toml"
    assert choose_drive(_vdrive_args(sim="minimal")).axis == "minimal"
    with pytest.raises(UserError, match="no such axis file"):
        choose_drive(_vdrive_args(sim=str(tmp_path / "none.toml")))
    with pytest.raises(UserError, match="--channel.*do not go with a simulated drive"):
        choose_drive(_vdrive_args(sim=True, channel="can0"))
    with pytest.raises(UserError, match="--port.*do not go with a simulated drive"):
        choose_drive(_vdrive_args(interface="virtual-drive", port=5))
    with pytest.raises(UserError, match="--seed is an option of the simulated drive"):
        choose_drive(_vdrive_args(interface="socketcand", seed=3), sim_only=("seed",))
    assert choose_drive(_vdrive_args(sim=True, seed=3), sim_only=("seed",)).virtual
    # explicit options come first, the rest from python-can's configuration
    monkeypatch.setenv("CAN_INTERFACE", "virtual-drive")
    c = choose_drive(_vdrive_args(interface="socketcand", port=1234))
    assert not c.virtual and c.bus == {"interface": "socketcand", "port": 1234, "channel": "can0",
                                       "host": "127.0.0.1"}
    monkeypatch.setenv("CAN_INTERFACE", "nosuchbus")
    with pytest.raises(UserError, match="python-can configuration \\(CAN_INTERFACE\\).*nosuchbus"):
        choose_drive(_vdrive_args())


@pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")
def test_python_can_config_file_names_the_drive(tmp_path: Path) -> None:
    home = tmp_path / "home"
    home.mkdir()
    srv = Server("--pacing", "realtime", "-q")
    try:
        (home / "can.conf").write_text(f"[default]\ninterface = socketcand\nchannel = can0\nhost = 127.0.0.1\n"
                                       f"port = {srv.port}\n")
        env = _env(home, HDSERVO_SIM=str(tmp_path / "no-simulator-here"))
        p = _run(["config", "set", "pos_kp=33.5"], tmp_path, env)
        assert p.returncode == 0, p.stderr
        assert NOTICE not in p.stderr
        with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=srv.port) as d:
            d.start()
            assert d.get_param("pos_kp") == pytest.approx(33.5)       # the running drive has it
            d.set_param("pos_kp", 21.25)
        q = _run(["config", "get", "pos_kp"], tmp_path, env)
        assert q.returncode == 0, q.stderr
        assert q.stdout.split("=")[1].split("#")[0].strip() == "21.25"
        # the same through python-can's environment variables (CAN_CONFIG carries host and port)
        (home / "can.conf").unlink()
        env2 = _env(home, HDSERVO_SIM=str(tmp_path / "no-simulator-here"), CAN_INTERFACE="socketcand",
                    CAN_CHANNEL="can0", CAN_CONFIG=f'{{"host": "127.0.0.1", "port": {srv.port}}}')
        r = _run(["record", "--duration", "0.5", "--rate", "1000", "-o", str(tmp_path / "rec.csv")], tmp_path, env2)
        assert r.returncode in (0, 1), r.stderr            # 1: lost ticks on a loaded machine, still written
        assert (tmp_path / "rec.csv").is_file() and NOTICE not in r.stderr
    finally:
        srv.stop()


@pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")
def test_sim_starts_a_real_virtual_drive(tmp_path: Path) -> None:
    home = tmp_path / "home"
    home.mkdir()
    p = _run(["config", "get", "pos_kp", "--sim"], tmp_path, _env(home))
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("pos_kp = ")
    assert sum(NOTICE in ln for ln in p.stderr.splitlines()) == 1


def test_demo_says_it_is_simulated(tmp_path: Path) -> None:
    prog, mark = _fake_sim(tmp_path)
    home = tmp_path / "home"
    home.mkdir()
    p = _run(["demo", "--out-dir", str(tmp_path / "demo"), "--quick", "--controllers", "pid", "--procedures", "peak-torque"],
             tmp_path, _env(home, HDSERVO_SIM=str(prog)))
    err = p.stderr.splitlines()
    assert err and err[0] == ("hdservo demo: using a simulated drive (virtual drive, axis reference); "
                              "your real drive is not touched"), p.stderr
    assert mark.exists() and p.returncode == 2 and "Traceback" not in p.stderr    # the stand-in did not start
