"""model.toml says which Preisach operator is which: the host's torque -> twist model in
``[preisach_host_model]``, the drive's twist -> torque table (the downloaded image) in
``[preisach_drive_table]``; files that carry both in ``[identified]`` still read and download."""
from __future__ import annotations

import tomllib
from pathlib import Path
from types import SimpleNamespace

import pytest

from hdservo import compsetup
from hdservo import download as dl
from hdservo.errors import UserError
from hdservo.ident import model_reader as mr
from hdservo.ident import model_toml

ROOT = Path(__file__).parents[2]

FRICTION = {"fc_pos_Nm": 7.4, "fc_neg_Nm": 7.0, "fs_pos_Nm": 10.5, "fs_neg_Nm": 10.0, "vs_rad_s": 0.02,
            "delta": 2.0, "viscous_Nms_per_rad": 5.3}


def _preisach_result(crc: int) -> dict:
    """A fit result shaped like ``Pipeline.hysteresis``: the host's model and the drive's table differ in
    every grid figure, so a key written into the wrong section shows."""
    host = SimpleNamespace(u0_Nm=-31.0, step_Nm=2.0, levels=32, offset_rad=-2.1e-5)
    gear_ev = SimpleNamespace(u0_Nm=-2.9e-4, step_Nm=9.4e-6, levels=62)
    table = SimpleNamespace(crc=crc, sub_bits=4)
    gear = SimpleNamespace(everett=gear_ev, twist_offset_rad=3.0e-6)
    return {"everett": host, "table": table, "gear": gear, "file": "model.preisach.bin"}


def test_written_model_names_each_preisach_operator(tmp_path: Path) -> None:
    secs = model_toml.model_sections({"preisach": _preisach_result(0x9ABCDEF0)}, 100.0)
    path = tmp_path / "model.toml"
    model_toml.write_toml(path, secs)
    text = path.read_text()
    raw = tomllib.loads(text)
    # nothing Preisach left in [identified], where a reader could not tell the two apart
    assert not [k for k in raw.get("identified", {}) if k.startswith("preisach")]
    host, drive = raw["preisach_host_model"], raw["preisach_drive_table"]
    assert host == {"direction": "torque -> twist", "u0_Nm": -31.0, "step_Nm": 2.0, "levels": 32,
                    "offset_rad": -2.1e-5}
    assert drive == {"direction": "twist -> torque", "file": "model.preisach.bin", "crc": 0x9ABCDEF0, "levels": 62,
                     "u0_rad": -2.9e-4, "step_rad": 9.4e-6, "sub_bits": 4, "twist_offset_rad": 3.0e-6}
    # a comment line above each says which it is
    lines = text.splitlines()
    for sec, words in (("preisach_host_model", "torque (N.m) -> output twist"),
                       ("preisach_drive_table", "twist (rad) -> output torque")):
        i = lines.index(f"[{sec}]")
        assert lines[i - 1].startswith("# ") and words in lines[i - 1], lines[i - 1]
    m = mr.read_model(path)
    assert mr.preisach_table_file(m) == "model.preisach.bin"
    assert mr.preisach_table_crc(m) == 0x9ABCDEF0


def test_a_direction_other_than_its_section_is_refused(tmp_path: Path) -> None:
    for sec, bad in (("preisach_drive_table", "torque -> twist"), ("preisach_host_model", "twist -> torque")):
        p = tmp_path / "m.toml"
        p.write_text(f'[gear]\nratio = 100.0\n[{sec}]\ndirection = "{bad}"\n')
        with pytest.raises(mr.ModelError) as e:
            mr.read_model(p)
        msg = str(e.value)
        assert "\n" not in msg and f"'{sec}.direction'" in msg and str(p) in msg, msg


def test_earlier_layout_in_identified_still_reads() -> None:
    """The shipped example models carry both operators' keys in [identified]."""
    m = mr.read_model(ROOT / "examples" / "pitch_drive" / "verify" / "model.toml")
    assert mr.preisach_table_file(m) == "model.preisach.bin"
    assert mr.preisach_table_crc(m) == 2872428348
    assert m["identified"]["preisach_u0_Nm"] == -31.0 and m["identified"]["preisach_levels"] == 32
    bare = mr.parse_model(b"[gear]\nratio = 50.0\n", "m.toml")
    assert mr.preisach_table_file(bare) is None and mr.preisach_table_crc(bare) is None


@pytest.mark.parametrize("layout", ["drive_table", "identified"])
def test_download_plan_takes_the_drive_table_of_either_layout(tmp_path: Path, layout: str) -> None:
    table = compsetup.preisach_table("reference", levels=16).to_bytes()
    (tmp_path / "t.bin").write_bytes(table)
    sec = ('[preisach_drive_table]\ndirection = "twist -> torque"\nfile = "t.bin"\n' if layout == "drive_table"
           else '[identified]\npreisach_table = "t.bin"\n')
    body = "[gear]\nratio = 100.0\n[friction_total]\n" + "".join(f"{k} = {v}\n" for k, v in FRICTION.items())
    m = tmp_path / "model.toml"
    m.write_text(body + sec)
    plan = dl.plan_download(m)
    assert plan["preisach"] == table and Path(plan["preisach_file"]).name == "t.bin"
    # a named file that is missing: one line naming the key that named it
    (tmp_path / "t.bin").unlink()
    with pytest.raises(UserError) as e:
        dl.plan_download(m)
    want = "[preisach_drive_table] file" if layout == "drive_table" else "[identified] preisach_table"
    assert "\n" not in str(e.value) and want in str(e.value) and "not found" in str(e.value)
