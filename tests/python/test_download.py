"""``hdservo download``: compensator parameters and tables from an identified model to the virtual drive,
verified by read-back; a corrupted table is refused (locally and by the drive) and the old one stays."""
from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path

import pytest

from hdservo import compsetup
from hdservo.cli import UserError, main
from hdservo import download as dl
from hdservo.drive import Drive
from hdservo.params_gen import BY_NAME as PARAMS

from vdrive import SIM, Server  # tests/python/vdrive.py

pytestmark = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")

MODEL = """[gear]
ratio = 100.0
[friction_total]
fc_pos_Nm = 7.4
fc_neg_Nm = 7.0
fs_pos_Nm = 10.5
fs_neg_Nm = 10.0
vs_rad_s = 0.02
delta = 2.0
viscous_Nms_per_rad = 5.3
[friction_motor]
sigma0_Nm_per_rad = 101.0
[stiffness]
k1_Nm_per_rad = 31000.0
k2_Nm_per_rad = 50000.0
k3_Nm_per_rad = 57000.0
t1_Nm = 14.0
t2_Nm = 48.0
[hysteresis_maxwell]
n_elements = 2
e1_k_Nm_per_rad = 10000.0
e1_w_Nm = 1.0
e2_k_Nm_per_rad = 5000.0
e2_w_Nm = 1.5
[transmission_error]
wg1_order = 1
wg1_amp_rad = 1.45e-5
wg1_phase_rad = -1.2
wg2_order = 2
wg2_amp_rad = 8.73e-5
wg2_phase_rad = 0.4
[identified]
preisach_table = "model.preisach.bin"
"""


@pytest.fixture
def server():
    srv = Server("--pacing", "realtime", "-q")
    try:
        yield srv.port
    finally:
        srv.stop()


def _model(tmp: Path, version: int = 1) -> tuple[Path, bytes]:
    m = tmp / "model.toml"
    m.write_text(MODEL)
    t = compsetup.preisach_table("reference", levels=16, version=version).to_bytes()
    (tmp / "model.preisach.bin").write_bytes(t)
    return m, t


def test_download_reads_back_and_corrupted_table_is_refused(tmp_path: Path, server: int, capsys) -> None:
    model, table = _model(tmp_path)
    # --skip-missing: the virtual drive binary may predate parameters just added to params.toml
    bus = ["-i", "socketcand", "--host", "127.0.0.1", "--port", str(server), "-q", "--skip-missing"]
    rc = main(["download", str(model), *bus, "--json", str(tmp_path / "d.json")])
    assert rc == 0, capsys.readouterr().err
    plan = dl.plan_download(model)
    with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=server) as d:
        d.start()
        # parameters by SDO
        for name in ("mx_k1", "mx_d2", "mx_stiffness", "pr_motor_share", "bs_j"):
            p = PARAMS[name]
            assert d.read(p.index, p.sub) == dl.raw_of(name, plan["params"][name])
        # tables in force = what the model gave (payload + CRC-32 trailer)
        assert d.read_domain(0x5100, 1) == table + struct.pack("<I", zlib.crc32(table))
        g2 = d.read_domain(0x5100, 2)
        vals = struct.unpack_from(f"<{len(plan['groups'][2])}i", g2, 16)
        assert list(vals) == list(plan["groups"][2].values())
        # the identified friction, lumped: Stribeck Fs+ = 10.5 N.m, LuGre sigma0 = N^2 sigma0_m per turn
        assert abs(vals[1] / 65536 - 10.5) < 1e-4
        assert abs(plan["params"]["lug_sigma0"] - 101.0 * 100 ** 2 * 2 * 3.141592653589793) < 1.0
        te = struct.unpack_from(f"<{len(plan['groups'][3])}i", d.read_domain(0x5100, 3), 16)
        assert te[0] == 2 and te[3] == 2          # two harmonics, the larger (order 2) first

        # a corrupted image: refused locally, one line, the drive untouched
        bad = bytearray(table)
        bad[60] ^= 0x40
        (tmp_path / "bad.bin").write_bytes(bytes(bad))
        capsys.readouterr()
        rc = main(["download", str(model), *bus, "--preisach", str(tmp_path / "bad.bin")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "CRC" in err[0]
        assert d.read_domain(0x5100, 1) == table + struct.pack("<I", zlib.crc32(table))
        # ... and by the drive: a transfer whose CRC-32 trailer does not match is refused (abort
        # 0x08000020) and the table in force stays
        from hdservo.drive import DriveError
        with pytest.raises(DriveError, match="0x08000020"):
            d.write_domain(0x5100, 1, bytes(bad) + struct.pack("<I", zlib.crc32(table)))
        assert d.read_domain(0x5100, 1) == table + struct.pack("<I", zlib.crc32(table))
        # a refusal inside a download is one UserError naming the drive
        forced = {**plan, "sdo": {"mx_k1": 8.3e6}, "groups": {}, "preisach": None}
        with pytest.raises(UserError, match="refused by the drive"):
            dl.write_verified(d, forced)


def test_bad_model_is_one_line(tmp_path: Path, capsys) -> None:
    p = tmp_path / "m.toml"
    p.write_text("[gear]\nratio = 100.0\n[friction_total]\nfc_pos_Nm = 1.0\n")
    rc = main(["download", str(p), "-q", "-i", "socketcand", "--port", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "friction_total" in err[0]
    rc = main(["download", str(tmp_path / "none.toml"), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "not found" in err[0]


def test_download_save_survives_a_restart(tmp_path: Path, capsys) -> None:
    """``--save`` stores parameters, groups and the Preisach table; a drive restarted on the same NVM
    file boots with all of them, and reports the table loaded and saved (0x5101)."""
    model, table = _model(tmp_path, version=9)
    nvm = tmp_path / "nvm.bin"
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        bus = ["-i", "socketcand", "--host", "127.0.0.1", "--port", str(srv.port), "-q", "--skip-missing"]
        with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=srv.port) as d:
            d.write(0x6065, 0, 5000)          # CiA 402 settings a master makes, saved with the rest
            d.write(0x6067, 0, 40)
        capsys.readouterr()
        rc = main(["download", str(model), *bus, "--save"])
        out = capsys.readouterr()
        assert rc == 0, out.err
        assert "saved to NVM" in out.out
    finally:
        srv.stop()
    plan = dl.plan_download(model)
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=srv.port) as d:
            d.start()
            assert d.store_status() == {"params": "loaded", "table": "loaded", "objects": "loaded", "table_saved": True}
            assert d.read(0x6065, 0) == 5000 and d.read(0x6067, 0) == 40
            assert d.read_domain(0x5100, 1) == table + struct.pack("<I", zlib.crc32(table))
            from hdservo.drive import group_payload
            for sub in (2, 3):           # the groups with their version (a parameter, saved)
                g = group_payload(sub, plan["groups"][sub], 1)
                assert d.read_domain(0x5100, sub) == g + struct.pack("<I", zlib.crc32(g))
            for name in ("pr_motor_share", "mx_stiffness", "bs_j"):
                p = PARAMS[name]
                assert d.read(p.index, p.sub) == dl.raw_of(name, plan["params"][name])
            # a restore of the defaults drops the table at once; saved, the next boot has none
            d.write(0x1011, 1, 0x64616F6C)
            assert d.read_domain(0x5100, 1) == b""
            assert d.store_status()["table_saved"] is False
            d.save()
    finally:
        srv.stop()
    srv = Server("--pacing", "realtime", "-q", "--nvm", str(nvm))
    try:
        with Drive.connect(1, interface="socketcand", channel="can0", host="127.0.0.1", port=srv.port) as d:
            d.start()
            assert d.store_status() == {"params": "loaded", "table": "saved as none", "objects": "loaded",
                                        "table_saved": True}
            assert d.read(0x6065, 0) == 0xFFFFFFFF and d.read(0x6067, 0) == 256     # restored defaults
            assert d.read_domain(0x5100, 1) == b""
            for name in ("pr_motor_share", "mx_stiffness"):          # downloaded != default
                p = PARAMS[name]
                assert dl.raw_of(name, plan["params"][name]) != p.raw_default
                assert d.read(p.index, p.sub) == p.raw_default       # the restored default, saved
    finally:
        srv.stop()


def test_plan_carries_unbalance_output_te_and_three_slope(tmp_path: Path) -> None:
    """The identified unbalance, output-side TE lines and three-slope curve reach the drive parameters
    (the twist estimate's pr_mgl / pr_g_off, te_out_*, cp_*), not the axis file's values."""
    from hdservo.download import plan_download
    m, _ = _model(tmp_path)
    text = MODEL.replace("[identified]", "out1_order = 1\nout1_amp_rad = 3.0e-5\nout1_phase_rad = 0.7\n"
                                          "[gravity]\nmgl_Nm = 1.5\noffset_rad = -0.2\n[identified]")
    text = text.replace("k2_Nm_per_rad = 50000.0", "k2_Nm_per_rad = 45000.0")
    m.write_text(text)
    p = plan_download(m, "reference")["params"]
    assert p["pr_mgl"] == pytest.approx(1.5) and p["pr_g_off"] == pytest.approx(-0.2 / (2 * math.pi))
    assert p["te_out_order1"] == 1 and p["te_out_amp1"] == pytest.approx(3.0e-5 / (2 * math.pi))
    assert p["te_out_phase1"] == pytest.approx(0.7 / (2 * math.pi)) and p["te_out_amp2"] == 0.0
    assert p["cp_k2"] == pytest.approx(45000.0 * 2 * math.pi)
    # a model without output-side lines: none (the axis file's line is not the model's)
    m.write_text(MODEL)
    assert plan_download(m, "reference")["params"]["te_out_amp1"] == 0.0
