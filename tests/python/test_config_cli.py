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


def _read(port: int, where: dict) -> dict:
    """Raw values read from the drive: key -> (index, sub) in, key -> value out."""
    with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=port) as d:
        d.start()
        return {k: int(d.read(*at)) for k, at in where.items()}


def _raw_all(port: int) -> dict[str, int]:
    return _read(port, {n: (p.index, p.sub) for n, p in BY_NAME.items()})


def _dumped_drive(tmp_path: Path) -> tuple[Server, Path, Path]:
    """A virtual drive on its own NVM file, its configuration dumped: (drive, file, nvm)."""
    nvm, f = tmp_path / "nvm.bin", tmp_path / "drive.toml"
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        assert main(["config", "dump", "-o", str(f), *_bus(srv.port)]) == 0
    except BaseException:
        srv.stop()
        raise
    return srv, f, nvm


def test_dump_edit_restore_round_trip_and_save(tmp_path: Path, capsys) -> None:
    srv, f, nvm = _dumped_drive(tmp_path)
    try:
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


def _wear(out: str) -> tuple[int, int, int, int]:
    """(total erases, most erased page, credit, refused) from `config status` output."""
    m = re.search(r"NVM wear: (\d+) page erases, most erased page (\d+) of 10000 \([0-9.]+ %\); "
                  r"save credit (-?\d+) erases, (\d+) saves refused by the rate limit", out)
    assert m, out
    return int(m[1]), int(m[2]), int(m[3]), int(m[4])


def test_status_shows_flash_wear(tmp_path: Path, capsys) -> None:
    """`config status` shows the drive's 0x5102 wear figures: a changing save erases pages,
    an identical one none, and the count survives a restart on the same NVM file."""
    nvm = tmp_path / "nvm.bin"
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        assert main(["config", "status", *_bus(srv.port)]) == 0
        assert _wear(capsys.readouterr().out) == (0, 0, 160, 0)          # blank NVM, full credit
        assert main(["config", "set", "pos_kp=12.5", "--save", *_bus(srv.port)]) == 0
        capsys.readouterr()
        assert main(["config", "status", *_bus(srv.port)]) == 0
        total, top, credit, refused = _wear(capsys.readouterr().out)
        assert total >= 1 and 1 <= top <= total and credit == 160 - total and refused == 0
        with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=srv.port) as d:
            d.start()
            assert int(d.read(0x5102, 1)) == total
        assert main(["config", "save", *_bus(srv.port)]) == 0               # nothing changed
        capsys.readouterr()
        assert main(["config", "status", *_bus(srv.port)]) == 0
        assert _wear(capsys.readouterr().out)[0] == total                  # no erase
    finally:
        srv.stop()
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        assert main(["config", "status", *_bus(srv.port)]) == 0
        again = _wear(capsys.readouterr().out)
        assert again[:2] == (total, top)                                   # persisted (nvm.bin.wear)
        assert again[2] == 160                                             # credit: full after power-up
    finally:
        srv.stop()


@pytest.mark.parametrize("edit, msg", [
    (lambda t: t.replace("[meta]", "[meat]"), "expected the tables [meta] and [params]"),
    (lambda t: re.sub(r"param_layout_hash = 0x[0-9A-F]+", "param_layout_hash = 0x12345678", t),
     "is not the drive's"),
    (lambda t: re.sub(r"(?m)^pos_kp = .*$", "pos_kp = -5.0", t), "pos_kp = -5.0 outside"),
    (lambda t: re.sub(r"(?m)^pos_kp = .*$", 'pos_kp = "fast"', t), "expected a number"),
    (lambda t: t + "pos_kp = [\n", "not TOML"),
    (lambda t: re.sub(r'(?m)^"0x1017:0" = .*$', '"0x1017:0" = 70000', t), '"0x1017:0" = 70000 outside [0, 65535]'),
    (lambda t: re.sub(r'(?m)^"0x1800:1" = .*$', '"0x1800:1" = "$NODEID+x"', t), 'expected "$NODEID+" and an integer'),
    (lambda t: re.sub(r'(?m)^"0x6065:0" = .*$', '"0x6065:0" = "$NODEID+0x10"', t), "expected an integer"),
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


def _objects(port: int) -> dict[tuple[int, int], int]:
    return _read(port, {k: k for k in driveconfig.STORED_AT})


def test_canopen_settings_round_trip_remap_and_save(tmp_path: Path, capsys) -> None:
    srv, f, nvm = _dumped_drive(tmp_path)
    try:
        before = _objects(srv.port)
        text = f.read_text()
        assert driveconfig.parse(text).objects == before        # the file alone gives every setting back
        assert '"0x1800:1" = "$NODEID+0x180"' in text             # TPDO1 COB-ID follows the node
        # heartbeat, a TPDO's event timer and its mapping (one object instead of two): the
        # remap needs the CiA 301 order (PDO invalid, mapping cleared, entries, count, COB-ID)
        text = re.sub(r'(?m)^"0x1017:0" = .*$', '"0x1017:0" = 250', text)
        text = re.sub(r'(?m)^"0x1801:5" = .*$', '"0x1801:5" = 20', text)
        text = re.sub(r'(?m)^"0x1A01:0" = .*$', '"0x1A01:0" = 1', text)
        text = text.replace("[objects]\n", '[objects]\n"0x1234:9" = 1\n')
        f.write_text(text)
        capsys.readouterr()
        assert main(["config", "restore", str(f), "--save", *_bus(srv.port)]) == 0
        out = capsys.readouterr()
        assert "124 CANopen settings" in out.out and "saved to NVM" in out.out
        assert "0x1234:9" in out.err and "Mismatch" not in out.err
        after = _objects(srv.port)
        changed = {(0x1017, 0): 250, (0x1801, 5): 20, (0x1A01, 0): 1}
        assert {k: after[k] for k in changed} == changed != {k: before[k] for k in changed}
        assert {k: v for k, v in after.items() if k not in changed} == \
               {k: v for k, v in before.items() if k not in changed}
    finally:
        srv.stop()
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))   # restarted: the saved settings are in force
    try:
        assert _objects(srv.port) == after
        # a mapping the drive refuses: one line, exit 2
        bad = re.sub(r'(?m)^"0x1A01:1" = .*$', '"0x1A01:1" = 0x12345620', f.read_text())
        f.write_text(bad)
        capsys.readouterr()
        assert main(["config", "restore", str(f), *_bus(srv.port)]) == 2
        err = [x for x in capsys.readouterr().err.strip().splitlines() if "error" in x]
        assert len(err) == 1 and "0x1A01:1" in err[0] and "refused by the drive" in err[0], err
        assert "previous values are back" in err[0]
        assert _objects(srv.port) == after                  # nothing changed, the PDO is valid again
    finally:
        srv.stop()


def test_node_relative_cob_ids_and_pdo_write_order() -> None:
    objs = {(e.index, e.sub): e.default + (1 if e.nodeid else 0) for e in driveconfig.STORED}
    objs[(0x1801, 1)] = 0x2A1                           # not relative to the node: kept absolute
    text = driveconfig.to_toml({}, TABLE_HASH, "", objs, node_id=1)
    got = driveconfig.parse(text, node_id=5).objects
    assert got[(0x1800, 1)] == 0x185 and got[(0x1400, 1)] == 0x205 and got[(0x1801, 1)] == 0x2A1
    assert got[(0x1403, 1)] == 0x80000505                 # an invalid PDO's COB-ID moves with the node too
    w = driveconfig.restore_writes(got)
    assert sorted({(i, s) for i, s, _ in w}) == sorted(got)
    pos = {k: [n for n, (i, s, _) in enumerate(w) if (i, s) == k] for k in got}
    for c in (0x1400, 0x1401, 0x1800, 0x1803):
        m = c + 0x200
        first_cob, last_cob = pos[(c, 1)][0], pos[(c, 1)][-1]
        assert w[first_cob][2] & 0x80000000                                        # PDO invalid first
        assert first_cob < pos[(m, 0)][0] < pos[(m, 1)][0] < pos[(m, 0)][-1] < last_cob
        assert w[pos[(m, 0)][0]][2] == 0 and w[last_cob][2] == got[(c, 1)]          # cleared, final COB-ID last
        assert all(pos[(c, s)][0] < last_cob for s in (2, 3, 5))
    assert max(pos[(0x1017, 0)]) < min(pos[(0x1400, 1)])                           # the rest before the PDOs


def test_format_1_files_are_still_read() -> None:
    text = driveconfig.to_toml({"pos_kp": 40 << 16}, TABLE_HASH).replace("format = 2", "format = 1")
    p = driveconfig.parse(text)
    assert p.raw == {"pos_kp": 40 << 16} and p.objects == {}


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


def test_get_and_status_write_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``config get`` / ``config status`` take ``--json PATH`` like every command with a result."""
    import json
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(tmp_path / "nvm.bin"))
    try:
        g, s = tmp_path / "get.json", tmp_path / "status.json"
        assert main(["config", "get", "pos_kp", "vel_kp", "--json", str(g), *_bus(srv.port)]) == 0
        printed = capsys.readouterr().out
        doc = json.loads(g.read_text())
        assert doc["action"] == "get" and set(doc["params"]) == {"pos_kp", "vel_kp"}
        for n, v in doc["params"].items():
            assert f"{n} = {v['value']!r}" in printed and v["unit"] == BY_NAME[n].unit
        assert main(["config", "status", "--json", str(s), *_bus(srv.port)]) == 0
        st = json.loads(s.read_text())
        from hdservo.drive import PARAM_STORE_STATUS
        assert st["store"]["params"] in PARAM_STORE_STATUS.values() and isinstance(st["store"]["table_saved"], bool)
        assert set(st["nvm_wear"]) == {"erases_total", "erases_max_page", "saves_refused", "save_credit"}
        assert "NVM wear:" in capsys.readouterr().out
        assert main(["config", "get", "pos_kp", "--json", str(tmp_path / "no" / "x.json"), *_bus(srv.port)]) == 2
        assert "--json" in capsys.readouterr().err
    finally:
        srv.stop()
