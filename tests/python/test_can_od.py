"""The generated object dictionary outputs (EDS, DBC, Python constants) and the transports' error paths."""
from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import cantools
import canopen
import pytest

ROOT = Path(__file__).resolve().parents[2]
EDS = ROOT / "host" / "hdservo" / "data" / "hdservo.eds"
DBC = ROOT / "host" / "hdservo" / "data" / "hdservo.dbc"
SIM = ROOT / "build" / "bin" / "hdservo-sim"
sys.path.insert(0, str(ROOT / "host"))

from hdservo import od_gen, params_gen  # noqa: E402


def test_eds_loads_without_warnings(caplog: pytest.LogCaptureFixture) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        od = canopen.import_od(str(EDS), node_id=3)
    assert not [r for r in caplog.records if r.levelname in ("WARNING", "ERROR")]
    assert od[0x1800][1].default == 0x183                     # $NODEID resolved
    assert od["drive_status"]["loop_tick"].pdo_mappable
    # every drive parameter of params.toml is in the EDS with its scale
    for p in params_gen.PARAMS:
        v = od[p.index][p.sub]
        assert v.name == p.name
        assert v.factor == pytest.approx(2.0 ** -p.frac)
        if v.min is None:                                      # full type range: no limits written
            assert (p.raw_min, p.raw_max) == (-2 ** 31, 2 ** 31 - 1)
        else:
            assert v.min == p.raw_min and v.max == p.raw_max


def test_dbc_loads_and_decodes() -> None:
    db = cantools.database.load_file(str(DBC))
    tp2 = db.get_message_by_name("TPDO2")
    assert tp2.frame_id == 0x281
    d = db.decode_message(0x281, bytes([1, 0, 0, 0, 0, 0, 0, 0x80]))
    assert d["loop_tick"] == 1 and d["load_phase"] == 0x80000000
    assert {s.name for s in db.get_message_by_name("TPDO1").signals} >= {"statusword", "loop_tick"}


def test_python_constants_match_eds() -> None:
    od = canopen.import_od(str(EDS))
    for e in od_gen.ENTRIES:
        obj = od[e.index]
        var = obj if isinstance(obj, canopen.objectdictionary.ODVariable) else obj[e.sub]
        assert var.name == e.name


def test_generator_bad_input_one_line_no_output(tmp_path: Path) -> None:
    bad = tmp_path / "canopen.toml"
    text = (ROOT / "firmware" / "params" / "canopen.toml").read_text()
    bad.write_text(text.replace('name = "controlword"\ntype = "u16"', 'name = "controlword"\ntype = "u17"'))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "gen_od.py"), "--canopen", str(bad),
                        "--out-dir", str(out)], capture_output=True, text=True)
    assert r.returncode == 1
    assert len(r.stderr.strip().splitlines()) == 1
    assert "canopen.toml" in r.stderr and "controlword" in r.stderr
    assert not out.exists()


def test_tpdo1_has_an_inhibit_time_and_a_bad_one_is_refused(tmp_path: Path) -> None:
    """TPDO1 (change of state) carries its canopen.toml inhibit time into the EDS, so a
    chattering statusword cannot fill the bus; an inhibit outside 0..65535 is one error line."""
    od = canopen.import_od(str(EDS))
    assert od[0x1800][3].default >= 10                         # >= 1 ms (100 us units)
    text = (ROOT / "firmware" / "params" / "canopen.toml").read_text()
    assert "inhibit = 100" in text
    bad = tmp_path / "canopen.toml"
    bad.write_text(text.replace("inhibit = 100", "inhibit = 70000", 1))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "gen_od.py"), "--canopen", str(bad),
                        "--out-dir", str(out)], capture_output=True, text=True)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "tpdo 1" in lines[0] and "inhibit" in lines[0]
    assert not out.exists()


@pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built")
def test_socketcan_without_kernel_can_says_so() -> None:
    r = subprocess.run([str(SIM), "serve", "--transport", "socketcan", "--channel", "hdnosuch0"],
                       capture_output=True, text=True, timeout=20)
    assert r.returncode != 0
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "socketcand" in lines[0]


@pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built")
def test_serve_bad_options() -> None:
    for args in (["--node-id", "0"], ["--pacing", "slow"], ["--axis", "no/such/axis.toml"], ["--bogus"]):
        r = subprocess.run([str(SIM), "serve", *args], capture_output=True, text=True, timeout=20)
        assert r.returncode != 0, args
        assert len(r.stderr.strip().splitlines()) == 1, (args, r.stderr)


@pytest.mark.parametrize("change, words", [
    ('kind = "param:traj_vmax"', 'kind = "param:no_such_param"'),
    ('kind = "param:traj_vmax"', 'kind = "param:traj_vmax"\ndefault = 5'),
    ('name = "profile_velocity"\ntype = "u32"', 'name = "profile_velocity"\ntype = "u8"'),
])
def test_generator_param_alias_bad_input(tmp_path: Path, change: str, words: str) -> None:
    """An object that is a drive parameter (kind param:NAME) must name one, take its limits
    and default from it, and have a type that holds its range: else one error line."""
    text = (ROOT / "firmware" / "params" / "canopen.toml").read_text()
    assert change in text
    bad = tmp_path / "canopen.toml"
    bad.write_text(text.replace(change, words, 1))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "gen_od.py"), "--canopen", str(bad),
                        "--out-dir", str(out)], capture_output=True, text=True)
    assert r.returncode == 1
    assert len(r.stderr.strip().splitlines()) == 1
    assert "profile_velocity" in r.stderr
    assert not out.exists()


def test_profile_objects_are_the_trajectory_parameters() -> None:
    """0x6081/0x6083 carry traj_vmax/traj_amax's default and limits (EDS and constants)."""
    import canopen
    from hdservo import params_gen
    od = canopen.import_od(str(ROOT / "host" / "hdservo" / "data" / "hdservo.eds"))
    for index, name in ((0x6081, "traj_vmax"), (0x6083, "traj_amax")):
        p = next(q for q in params_gen.PARAMS if q.name == name)
        v = od[index]
        assert (v.default, v.min, v.max) == (p.raw_default, p.raw_min, p.raw_max)
