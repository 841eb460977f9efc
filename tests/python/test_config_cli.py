"""``hdservo config`` on the virtual drive: dump -> edit -> restore round trips bit for bit, a saved
configuration survives a restart, and bad files are one error line with nothing written."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from hdservo import driveconfig
from hdservo.cli import main
from hdservo.drive import Drive
from hdservo.params_gen import BY_NAME, TABLE_HASH

from vdrive import SIM, Server  # tests/python/vdrive.py

pytestmark = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")


def _bus(port: int) -> list[str]:
    return ["-i", "socketcand", "--host", "127.0.0.1", "--port", str(port)]


def _raw_all(port: int) -> dict[str, int]:
    with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=port) as d:
        d.start()
        return {n: int(d.read(p.index, p.sub)) for n, p in BY_NAME.items()}


def test_dump_edit_restore_round_trip_and_save(tmp_path: Path, capsys) -> None:
    nvm = tmp_path / "nvm.bin"
    f = tmp_path / "drive.toml"
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        assert main(["config", "dump", "-o", str(f), *_bus(srv.port)]) == 0
        before = _raw_all(srv.port)
        text = f.read_text()
        assert f"param_layout_hash = 0x{TABLE_HASH:08X}" in text
        # the file alone gives back every raw word (SI values exact in binary floating point)
        assert driveconfig.parse(text).raw == before
        # edit two values, add a name this drive does not have
        kp = BY_NAME["pos_kp"]
        new_kp = driveconfig.si_of(kp, before["pos_kp"]) * 0.75
        text = re.sub(r"(?m)^pos_kp = .*$", f"pos_kp = {new_kp!r}", text)
        text = re.sub(r"(?m)^traj_vmax = .*$", "traj_vmax = 0.05", text)
        text = text.replace("[params]\n", "[params]\nfuture_param = 3.0\n")
        f.write_text(text)
        capsys.readouterr()
        assert main(["config", "restore", str(f), "--save", *_bus(srv.port)]) == 0
        out = capsys.readouterr()
        assert "restored" in out.out and "saved to NVM" in out.out
        assert "future_param" in out.err                      # listed, not fatal
        after = _raw_all(srv.port)
        assert after["pos_kp"] == driveconfig.raw_of(kp, new_kp) != before["pos_kp"]
        assert after["traj_vmax"] == driveconfig.raw_of(BY_NAME["traj_vmax"], 0.05)
        assert {n: v for n, v in after.items() if n not in ("pos_kp", "traj_vmax")} == \
               {n: v for n, v in before.items() if n not in ("pos_kp", "traj_vmax")}
    finally:
        srv.stop()
    # restarted on the same NVM: the restored configuration is the boot configuration
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        assert _raw_all(srv.port) == after
        capsys.readouterr()
        assert main(["config", "get", "pos_kp", "traj_vmax", *_bus(srv.port)]) == 0
        got = capsys.readouterr().out
        vm = BY_NAME["traj_vmax"]
        assert f"pos_kp = {driveconfig.si_of(kp, driveconfig.raw_of(kp, new_kp))!r}" in got       # as stored
        assert f"traj_vmax = {driveconfig.si_of(vm, driveconfig.raw_of(vm, 0.05))!r}" in got
        assert main(["config", "status", *_bus(srv.port)]) == 0
        assert "parameters: loaded" in capsys.readouterr().out
        # set + read back, one parameter
        assert main(["config", "set", "pos_kp=12.5", *_bus(srv.port)]) == 0
        assert _raw_all(srv.port)["pos_kp"] == driveconfig.raw_of(kp, 12.5)
    finally:
        srv.stop()


@pytest.mark.parametrize("edit, msg", [
    (lambda t: t.replace("[meta]", "[meat]"), "expected the tables [meta] and [params]"),
    (lambda t: re.sub(r"param_layout_hash = 0x[0-9A-F]+", "param_layout_hash = 0x12345678", t),
     "is not the drive's"),
    (lambda t: re.sub(r"(?m)^pos_kp = .*$", "pos_kp = -5.0", t), "pos_kp = -5.0 outside"),
    (lambda t: re.sub(r"(?m)^pos_kp = .*$", 'pos_kp = "fast"', t), "expected a number"),
    (lambda t: t + "pos_kp = [\n", "not TOML"),
])
def test_bad_file_is_one_line_and_nothing_written(tmp_path: Path, capsys, edit, msg) -> None:
    srv = Server("--pacing", "realtime", "-q")
    try:
        f = tmp_path / "drive.toml"
        assert main(["config", "dump", "-o", str(f), *_bus(srv.port)]) == 0
        before = _raw_all(srv.port)
        text = re.sub(r"(?m)^traj_vmax = .*$", "traj_vmax = 0.05", f.read_text())   # a change that must not land
        f.write_text(edit(text))
        capsys.readouterr()
        assert main(["config", "restore", str(f), *_bus(srv.port)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and msg in err[0] and str(f) in err[0], err
        assert _raw_all(srv.port) == before
    finally:
        srv.stop()


def test_force_matches_another_layout_by_name(tmp_path: Path) -> None:
    text = driveconfig.to_toml({"pos_kp": 40 << 16}, 0x12345678)
    with pytest.raises(ValueError, match="not the drive's"):
        driveconfig.parse(text)
    assert driveconfig.parse(text, force=True).raw == {"pos_kp": 40 << 16}


def test_bad_arguments_are_one_line(tmp_path: Path, capsys) -> None:
    for argv, msg in ((["config", "get", "no_such_param", "--port", "1", "-i", "socketcand"], "not drive parameters"),
                      (["config", "set", "pos_kp", "--port", "1", "-i", "socketcand"], "expected NAME=VALUE"),
                      (["config", "set", "pos_kp=-1", "--port", "1", "-i", "socketcand"], "outside"),
                      (["config", "dump", "-o", str(tmp_path / "no" / "x.toml"), "--port", "1", "-i", "socketcand"],
                       "does not exist")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and msg in err[0], err
