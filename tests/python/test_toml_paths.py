"""Paths with quotes and backslashes survive every TOML document the host generates.

An axis file named ``my "axis".toml`` or ``C:\\axes\\x.toml`` (both legal file names on
Linux) must reach the simulator unchanged: the virtual drive (``hdservo serve --axis``,
whose scenario text is built in C), the identification runner's scenario
(:class:`hdservo.ident.experiments.SimRunner`) and an identified model naming its Preisach
table file.
"""
from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

import pytest

from hdservo import sim
from hdservo.ident import experiments as ex
from hdservo.ident import model_reader, model_toml
from hdservo.tomltext import basic_string

from vdrive import SIM, Server  # tests/python/vdrive.py

ROOT = Path(__file__).resolve().parents[2]
NAMES = ['my "axis".toml', "C:\\axes\\x.toml", "tab\tand 'single' quote.toml"]


def _axis(tmp_path: Path, name: str) -> Path:
    p = tmp_path / name
    shutil.copy(ROOT / "sim" / "axes" / "csf17_50.toml", p)
    return p


@pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")
@pytest.mark.parametrize("name", NAMES)
def test_virtual_drive_takes_any_axis_path(tmp_path: Path, name: str) -> None:
    srv = Server("--pacing", "realtime", "-q", "--axis", str(_axis(tmp_path, name)))
    try:
        assert srv.port > 0
    finally:
        srv.stop()


@pytest.mark.parametrize("name", NAMES)
def test_identification_scenario_names_the_axis_exactly(tmp_path: Path, name: str) -> None:
    ax = _axis(tmp_path, name)
    r = ex.SimRunner(axis=str(ax), seed=1)
    sc = r._scenario(tmp_path, "probe", "position", {"type": "constant", "initial_rad": 0.0}, 0.01, 1)
    doc = tomllib.loads(sc.read_text())
    assert doc["scenario"]["axis"] == str(ax.resolve())
    # and the simulator's own TOML reader takes it: the axis is the CSF-17-50 (ratio 50)
    res = sim.run_scenario(sc, duration_s=0.002)
    assert res is not None
    assert sim.axis_param("gear.ratio", doc["scenario"]["axis"]) == 50.0


@pytest.mark.parametrize("name", NAMES)
def test_model_names_any_table_file(tmp_path: Path, name: str) -> None:
    m = tmp_path / "m.toml"
    model_toml.write_toml(m, {"gear": {"ratio": 100.0}, "identified": {"preisach_table": name}})
    assert model_reader.read_model(m)["identified"]["preisach_table"] == name


def test_control_characters_are_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match="U\\+0001"):
        basic_string("a\x01b")


def test_read_toml_file_one_line_errors(tmp_path: Path) -> None:
    """The design data files, the spec and the catalogue sources share one reader with one-line errors."""
    from hdservo.design.spec import SpecError, load_spec
    from hdservo.tomltext import read_toml_file
    good = tmp_path / "g.toml"
    good.write_text("[a]\nx = 1\n")
    assert read_toml_file(good) == {"a": {"x": 1}}
    bad = tmp_path / "b.toml"
    bad.write_text("[a]\nx = = 1\n")
    with pytest.raises(SpecError) as e:
        load_spec(bad)
    assert str(e.value).startswith(f"{bad}: not valid TOML:") and "line 2" in str(e.value)
    assert "\n" not in str(e.value)
    with pytest.raises(SpecError, match="cannot read"):
        load_spec(tmp_path / "missing.toml")
