"""Catalogue data files and their loaders (hdservo.design.catalogue)."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from hdservo.cli import UserError
from hdservo.design import catalogue as cat


def test_sources_cover_every_kind():
    src = cat.load_sources()
    kinds = {s.kind for s in src.values()}
    assert {"catalogue", "derived", "estimated", "representative"} <= kinds


def test_gear_catalogue_ranges_and_reference_axis():
    rows = cat.load_gears()
    assert {g.size for g in rows} == {14, 17, 20, 25, 32, 40, 50}
    assert {g.ratio for g in rows} == {50, 80, 100, 120, 160}
    ref = cat.find_gear(25, 100, "CSF", rows)
    # DESIGN.md §2 reference gear: K1/K2/K3, T1/T2, rated ~67, momentary ~280
    assert (ref.k1_Nm_per_rad, ref.k2_Nm_per_rad, ref.k3_Nm_per_rad) == (3.1e4, 5.0e4, 5.7e4)
    assert (ref.t1_Nm, ref.t2_Nm) == (14.0, 48.0)
    assert ref.rated_torque_Nm == pytest.approx(67, abs=0.5)
    assert ref.momentary_peak_torque_Nm == pytest.approx(284, abs=1)
    assert ref.src_torque == "csf_from_csg"


def test_csf_is_csg_over_1p3_where_derived():
    rows = cat.load_gears()
    csg = {(g.size, g.ratio): g for g in rows if g.series == "CSG"}
    n = 0
    for g in rows:
        if g.series == "CSF" and g.src_torque == "csf_from_csg":
            c = csg[(g.size, g.ratio)]
            assert g.rated_torque_Nm == pytest.approx(c.rated_torque_Nm / 1.3, rel=1e-3, abs=0.06)
            assert g.momentary_peak_torque_Nm == pytest.approx(c.momentary_peak_torque_Nm / 1.3, rel=1e-3, abs=0.06)
            n += 1
    assert n >= 25
    src = cat.load_sources()
    assert src["csf_from_csg"].kind == "derived"
    assert src[cat.find_gear(50, 50, "CSG", rows).src_torque].kind == "estimated"


def test_stiffness_and_inertia_grow_with_size():
    rows = [g for g in cat.load_gears() if g.series == "CSF" and g.ratio == 100]
    rows.sort(key=lambda g: g.size)
    for a, b in zip(rows, rows[1:]):
        assert b.k1_Nm_per_rad > a.k1_Nm_per_rad
        assert b.input_inertia_kgm2 > a.input_inertia_kgm2
        assert b.max_input_speed_rpm < a.max_input_speed_rpm


def test_motor_and_sensor_catalogues():
    motors = cat.load_motors()
    assert len(motors) >= 4
    ref = [m for m in motors if m.kt_Nm_per_A == pytest.approx(0.1)]
    assert ref and ref[0].peak_current_A == 20.0          # DESIGN.md reference motor class
    src = cat.load_sources()
    assert all(src[m.source].kind == "representative" for m in motors)
    sensors = cat.load_sensors()
    bits = {s.kind: [x.bits_per_rev for x in sensors if x.kind == s.kind] for s in sensors}
    assert 17 in bits["motor_encoder"] and 23 in bits["motor_encoder"]
    assert {24, 25, 26} <= set(bits["output_encoder"])
    gyros = [s for s in sensors if s.kind == "rate_gyro"]
    assert any("fog" in g.name for g in gyros) and any("mems" in g.name for g in gyros)
    for g in gyros:
        assert g.noise_density_deg_s_rtHz > 0 and g.bandwidth_Hz > 0 and g.lsb_rad is None
    enc24 = next(s for s in sensors if s.bits_per_rev == 24)
    assert enc24.lsb_rad == pytest.approx(2 * math.pi / 2 ** 24)


def _copy_with(tmp_path: Path, name: str, old: str, new: str) -> Path:
    text = (cat.DATA_DIR / name).read_text()
    assert old in text
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1))
    return p


def test_bad_number_names_file_line_row_field(tmp_path):
    p = _copy_with(tmp_path, "harmonic_drives.csv", "CSG,25,100,87,", "CSG,25,100,eighty,")
    with pytest.raises(UserError) as e:
        cat.load_gears(p)
    msg = str(e.value)
    assert "\n" not in msg
    assert str(p) in msg and "row 'CSG-25-100'" in msg and "rated_torque_Nm" in msg
    line = next(i + 1 for i, ln in enumerate(p.read_text().splitlines()) if "eighty" in ln)
    assert f":{line}:" in msg


def test_bad_source_key_and_stiffness_order(tmp_path):
    p = _copy_with(tmp_path, "harmonic_drives.csv", "csg_2uh_ratings", "nowhere")
    with pytest.raises(UserError, match="src_torque.*sources.toml"):
        cat.load_gears(p)
    p2 = _copy_with(tmp_path, "harmonic_drives.csv", "14,48,31000,50000,57000", "14,48,31000,20000,57000")
    with pytest.raises(UserError, match="K1 <= K2 <= K3"):
        cat.load_gears(p2)


def test_bad_motor_and_sensor_rows(tmp_path):
    p = _copy_with(tmp_path, "motors.csv", "0.100,0.70,2.0,", "0.100,0.70,9.0,")
    with pytest.raises(UserError, match="fl-070-class.*peak_torque_Nm.*Kt x peak current"):
        cat.load_motors(p)
    p = _copy_with(tmp_path, "sensors.csv", "gyro-fog-tactical,rate_gyro,,", "gyro-fog-tactical,rate_gyro,20,")
    with pytest.raises(UserError, match="bits_per_rev.*empty cell"):
        cat.load_sensors(p)
    p = _copy_with(tmp_path, "motors.csv", "name,outer", "nom,outer")
    with pytest.raises(UserError, match="missing column"):
        cat.load_motors(p)


def test_missing_file_is_one_line(tmp_path):
    with pytest.raises(UserError, match="cannot read"):
        cat.load_gears(tmp_path / "none.csv")
    with pytest.raises(UserError, match="no harmonic drive CSF-14-160"):
        cat.find_gear(14, 160)
