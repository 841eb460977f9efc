"""Identification and closed-loop procedures through CiA 402 standard objects only
(host/hdservo/ident/std_runner.py, host/hdservo/procedures/standard.py).

Against the virtual drive's generic profile (``hdservo-sim serve --profile generic``: only CiA
301/402 objects; every access to a vendor object is refused, logged on stderr and counted in the
exit statistics) in lock-step.  Every test checks both sides: the host's record of the SDO
requests on the bus (:class:`SdoGuard`) and the server's count.  The identified parameters must
be within 2x the tolerances of the hdservo-firmware path on the reference axis
(tests/python/test_ident_drive.py); the full table is tests/results/45_generic_drive.py.
"""
from __future__ import annotations

import json
import math
import os
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hdservo.cli import UserError
from hdservo.ident import experiments as ex
from hdservo.ident import friction as fr
from hdservo.ident import frf as frfm
from hdservo.ident import std_runner as sr
from hdservo.ident import te as tem
from hdservo.procedures import standard as sp

import ident_cache as cache
import ident_truth as truth

ROOT = Path(__file__).resolve().parents[2]
SIM = Path(os.environ.get("HDSERVO_SIM", ROOT / "build" / "bin" / "hdservo-sim"))
needs_sim = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")

#: gear ratio of the reference axis: catalogue data the user gives (the generic drive has no 0x6091)
RATIO = truth.axis("reference")["gear"]["ratio"]
#: 2x the tolerances of the hdservo path (test_ident_drive.py)
TOL_STRIBECK = {"fc_pos_Nm": 0.06, "fc_neg_Nm": 0.06, "fs_pos_Nm": 0.06, "fs_neg_Nm": 0.06,
                "viscous_Nms_per_rad": 0.10, "vs_rad_s": 0.20}
TOL_TE_AMP, TOL_TE_PHASE_DEG, TOL_FRF = 0.10, 10.0, 0.04


def server_stats(log: str) -> dict[str, Any]:
    """The JSON statistics line the virtual drive prints on exit."""
    line = next(ln for ln in reversed(log.splitlines()) if ln.startswith("{"))
    return json.loads(line)


def assert_no_vendor_access(session: sr.StdSession, runner: sr.StdRunner) -> None:
    assert runner.vendor_access == []
    assert runner.guard.accessed, "the guard saw no SDO request at all"
    st = server_stats(session.server_log)
    assert st["profile"] == "generic" and st["vendor_refused"] == 0, session.server_log[-400:]
    assert "vendor-object access" not in session.server_log


@lru_cache(maxsize=None)
def identified() -> tuple[dict[str, Any], sr.StdSession, sr.StdRunner]:
    """FRF, TE, gravity and friction of the reference axis on one generic-profile session."""
    s = sr.StdSession(axis="reference", seed=cache.CAN_SEEDS["reference"], gear_ratio=RATIO)
    out: dict[str, Any] = {}
    with s as r:
        d = r.run(cache.CAN_FRF)
        out["frf"] = frfm.fit_frf(d)
        out["frf_meta"] = d.meta
        out["te"] = tem.fit_te(r.run(cache.CAN_SHORT["te_rotation"]), f_antiresonance_Hz=out["frf"][-1].f_antiresonance_Hz)
        g = fr.fit_gravity(r.run(cache.CAN_SHORT["gravity_sine"]))
        out["gravity"] = g
        out["stribeck"] = fr.fit_stribeck(fr.sweep_points(r.run(cache.CAN_SHORT["friction_sweep"]), g))
    return out, s, r


@needs_sim
def test_identification_through_standard_objects_within_twice_the_hdservo_tolerances() -> None:
    out, s, r = identified()
    assert_no_vendor_access(s, r)
    a = truth.axis("reference")
    ft = truth.friction_total(a)
    f = out["stribeck"]
    for key, tol in TOL_STRIBECK.items():
        assert abs(getattr(f, key) / ft[key] - 1) < tol, (key, getattr(f, key), ft[key])
    g = a["gravity"]
    assert abs(out["gravity"].mgl_Nm / g["mgl_Nm"] - 1) < 0.10
    t = a["transmission_error"]
    k = next(i for i in range(1, 5) if t[f"wg{i}_order"] == 2)
    amp, ph = out["te"].line(2)
    assert abs(amp / t[f"wg{k}_amp_rad"] - 1) < TOL_TE_AMP
    assert abs(math.degrees((ph - t[f"wg{k}_phase_rad"] + math.pi) % (2 * math.pi) - math.pi)) < TOL_TE_PHASE_DEG
    small = out["frf"][0]
    fa, fres = truth.frf_small_signal_truth(a)
    assert small.f_antiresonance_Hz == pytest.approx(fa, rel=TOL_FRF)
    assert small.f_resonance_Hz == pytest.approx(fres, rel=TOL_FRF)


@needs_sim
def test_experiment_metadata_states_bus_load_and_host_sync_timing() -> None:
    out, _, _ = identified()
    m = out["frf_meta"]
    assert m["source"] == "CiA 402 standard objects" and m["encoder2"] is True
    # CSV: SYNC + TPDO1 (6 B) + TPDO2 (8 B) + TPDO3 (4 B) + RPDO2 (8 B) at 1 kHz on 1 Mbit/s
    assert m["bus_load"] == pytest.approx((55 + 115 + 135 + 95 + 135) * 1000 / 1e6)
    st = m["sync_stats"]
    assert st["lockstep"] is True and st["nominal_period_s"] == pytest.approx(1e-3)
    n = sum(int(round(seg["duration_s"] / 1e-3)) for seg in m["segments"])
    assert st["period"]["count"] > n
    assert 0 < st["period"]["min_s"] <= st["period"]["mean_s"] <= st["period"]["max_s"]
    assert 0 < st["round_trip"]["median_s"] <= st["round_trip"]["max_s"]


@needs_sim
def test_peak_torque_into_the_locked_output_on_the_generic_profile() -> None:
    """The bench locks the output (its brake, not a drive object); a CST staircase on 0x6071 up to
    40 N.m is delivered as 0x6077 reports it, and no vendor object is touched."""
    s = sr.StdSession(axis="reference", seed=5, gear_ratio=RATIO, output_locked=True)
    with s as r:
        res = sp.peak_torque(r, 40.0, output_locked=True)
    assert_no_vendor_access(s, r)
    cmd, got = res.figures["commanded_Nm"], res.figures["delivered_Nm"]
    assert len(cmd) == len(got) == 6
    for c, g in zip(cmd, got):
        assert abs(g - c) < 0.1 * c, (c, g)          # below the limit the drive delivers the request
    assert res.headline["peak_torque_Nm"] == pytest.approx(40.0, rel=0.1)


@needs_sim
def test_closed_loop_procedures_on_the_generic_profile() -> None:
    s = sr.StdSession(axis="reference", seed=5, gear_ratio=RATIO)
    with s as r:
        bw = sp.bandwidth(r, amplitude_arcsec=1800.0)
        pos = sp.positioning(r, targets_deg=[-5.0, 5.0], runs=2, dwell_s=0.5)
        mr = sp.min_rate(r, rates_deg_s=(1.0, 0.1), windows=4, settle_s=1.0)
        with pytest.raises(UserError, match="needs the output locked"):
            sp.peak_torque(r, 50.0)
    assert_no_vendor_access(s, r)
    mag = np.asarray(bw.figures["magnitude_dB"])
    assert abs(mag[0]) < 1.0                     # the loop follows the slowest line
    assert bw.headline["bandwidth_hz"] is not None and 1.0 < bw.headline["bandwidth_hz"] < 80.0
    assert mag[-1] < -3.0
    iso = pos.figures["iso230_2_arcsec"]
    assert 0 < pos.headline["repeatability_arcsec"] < 60 and abs(iso["B"]) < 60
    assert mr.headline["min_smooth_rate_deg_s"] == 0.1
    assert [x["rate_deg_s"] for x in mr.figures["ladder"]] == [1.0, 0.1]


@needs_sim
def test_host_friction_and_gravity_feedforward_in_the_torque_offset() -> None:
    """PID alone vs PID + the identified friction/gravity in 0x60B2, same CSP reference."""
    out, _, _ = identified()
    ff = sr.friction_gravity_feedforward(out["stribeck"], out["gravity"])
    t = np.arange(4000) * 1e-3
    ref = 0.05 * (1 - np.cos(2 * math.pi * 0.5 * t))
    s = sr.StdSession(axis="reference", seed=7, gear_ratio=RATIO)
    with s as r:
        pid = r.track(ref)
        both = r.track(ref, ff)
    assert_no_vendor_access(s, r)
    assert both["rms_error_rad"] < 0.6 * pid["rms_error_rad"], (both["rms_error_rad"], pid["rms_error_rad"])
    assert both["max_error_rad"] < pid["max_error_rad"]


@needs_sim
def test_pdo_configuration_is_restored_and_guard_sees_vendor_access() -> None:
    """On the hdservo profile (vendor objects present): the drive's own PDO set-up comes back after
    the session; a vendor read is caught by the guard (the guard can fail)."""
    s = sr.StdSession(axis="reference", profile="hdservo", gear_ratio=RATIO)
    with s as r:
        saved = {k: dict(v) for k, v in r._saved.items()}
        assert any(e[0] == 0x5F00 for e in saved["tpdo"][2].entries)      # the default stream
        assert [(v.index, v.subindex) for v in r.node.tpdo[1].map] == [(0x6041, 0), (0x6064, 0)]
        assert r.vendor_access == [] and r.guard.accessed
        r.node.sdo.upload(0x5F00, 1)
        assert r.vendor_access == [(0x5F00, 1)]
        r.close()
        r.node.tpdo.read()
        r.node.rpdo.read()
        for kind, maps in (("tpdo", r.node.tpdo), ("rpdo", r.node.rpdo)):
            for n, snap in saved[kind].items():
                back = sr.PdoSnapshot.of(maps[n])
                assert (back.enabled, back.cob_id, back.trans_type, back.entries) == \
                    (snap.enabled, snap.cob_id, snap.trans_type, snap.entries), (kind, n)


def test_sdo_guard_decodes_initiate_frames_only() -> None:
    g = sr.SdoGuard(1)
    g.note(bytes([0x40, 0x00, 0x50, 0x07, 0, 0, 0, 0]))     # upload initiate 0x5000:7
    g.note(bytes([0x23, 0x40, 0x60, 0x00, 0x0F, 0, 0, 0]))  # expedited download 0x6040
    g.note(bytes([0xC6, 0x00, 0x51, 0x01, 0, 0, 1, 0]))     # block download initiate 0x5100:1
    g.note(bytes([0xA0, 0x10, 0x50, 0x03, 0x7F, 0, 0, 0]))  # block upload initiate 0x5010:3
    g.note(bytes([0x00, 0x00, 0x50, 0x01, 0, 0, 0, 0]))     # download segment: data, not an index
    g.note(bytes([0x60, 0x00, 0x50, 0x01, 0, 0, 0, 0]))     # upload segment request
    g.note(bytes([0xA3, 0x00, 0x50, 0x01, 0, 0, 0, 0]))     # block upload start
    assert g.accessed == [(0x5000, 7), (0x6040, 0), (0x5100, 1), (0x5010, 3)]
    assert g.vendor() == [(0x5000, 7), (0x5100, 1), (0x5010, 3)]


def test_bus_load_arithmetic_and_refusal() -> None:
    assert sr.frame_bits(0) == 55 and sr.frame_bits(8) == 135 and sr.frame_bits(4) == 95
    with pytest.raises(ValueError):
        sr.frame_bits(9)
    assert sr.bus_load([8, 8], 1000.0, 1e6) == pytest.approx(0.325)
    assert sr.check_bus_load([8, 8], 1000.0, 1e6) == pytest.approx(0.325)
    with pytest.raises(UserError) as e:
        sr.check_bus_load([8, 8, 8, 8], 1000.0, 500e3)
    msg = str(e.value)
    assert "\n" not in msg and "bus load 119 %" in msg and "above 70 %" in msg
    st = sr.period_stats([0.0, 0.001, 0.003, 0.004])
    assert st["count"] == 3 and st["max_s"] == pytest.approx(0.002) and st["min_s"] == pytest.approx(0.001)


@needs_sim
def test_experiment_refused_before_it_starts_when_the_bus_is_too_slow() -> None:
    s = sr.StdSession(axis="reference", gear_ratio=RATIO, bitrate=250e3)
    with s as r:
        with pytest.raises(UserError, match="bus load .* above 70 %"):
            r.run(cache.CAN_SHORT["gravity_sine"])
        assert r._syncs == 0                     # refused before any SYNC: the drive never moved
        # without a second encoder TE and the FRF are refused with one line; here it has one
        assert r.has_encoder2
    assert_no_vendor_access(s, r)


@pytest.mark.parametrize("argv,msg", [
    (("identify", "stiffness", "--sim", "--standard-objects", "--gear-ratio", "100"),
     "identify stiffness: needs the output locked and a torque sensor (a test rig); --standard-objects identifies "
     "friction, te, frf"),
    (("identify", "friction", "--sim", "--gear-ratio", "100"), "--gear-ratio: options of --standard-objects"),
    (("identify", "friction", "--sim", "--standard-objects"),
     "--standard-objects: the generic virtual drive has no 0x6091: give --gear-ratio"),
    (("identify", "friction", "--sim", "--standard-objects", "--gear-ratio", "-3"),
     "--gear-ratio -3.0: expected a positive number"),
    (("identify", "friction", "--sim", "--standard-objects", "--gear-ratio", "100", "--sync-period", "0.00015"),
     "--sync-period 0.00015: the virtual drive needs a multiple of 0.0001 s"),
])
def test_identify_standard_objects_bad_arguments_one_line(argv: tuple[str, ...], msg: str,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    from hdservo.cli import main
    assert main(list(argv)) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert err == [f"hdservo identify: error: {msg}"]


def _results_script() -> Any:
    import importlib.util
    spec = importlib.util.spec_from_file_location("generic_drive_results", ROOT / "tests" / "results" / "45_generic_drive.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_results_tolerance_table_and_bus_table_logic() -> None:
    """The make-results script's table logic on a tiny input (its full run is tests/results/45_generic_drive.py)."""
    m = _results_script()
    rows = m.tolerance_rows({"a": 0.05, "b": -0.09, "c": 0.5}, {"a": 0.01}, tol={"a": 0.03, "b": 0.05, "c": 0.1,
                                                                                  "d": 0.1}, factor=2.0)
    got = {r["parameter"]: (r["pass"], r["generic_tolerance"]) for r in rows}
    assert got == {"a": (True, 0.06), "b": (True, 0.1), "c": (False, 0.2), "d": (False, 0.2)}
    assert rows[0]["hdservo_error"] == 0.01 and rows[1]["hdservo_error"] is None
    bt = m.bus_table(bitrates=(1e6,), sync_hz=1000.0)
    csv = next(r for r in bt if r["mode"] == "CSV" and not r["encoder2"])
    assert csv["bits_per_sync"] == 55 + 115 + 135 + 135
    assert csv["load_at_sync_hz"] == pytest.approx(0.44)
    assert csv["max_sync_hz"] == pytest.approx(0.7 * 1e6 / 440)
    csp2 = next(r for r in bt if r["mode"] == "CSP" and r["encoder2"])
    assert csp2["bits_per_sync"] == 55 + 115 + 135 + 95 + 135 + 135
    # the same arithmetic as the runner's own check
    assert csp2["load_at_sync_hz"] == pytest.approx(sr.bus_load([6, 8, 4, 8, 8], 1000.0, 1e6))
    a = truth.axis("reference")
    class _S:  # noqa: E306 - a Stribeck result with the truth: zero error
        pass
    s = _S()
    for k, v in truth.friction_total(a).items():
        setattr(s, k, v)
    e = m.errors({"stribeck": s}, a)
    assert all(abs(v) < 1e-12 for v in e.values()) and len(e) == 6


@needs_sim
def test_identify_cli_on_the_generic_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`identify frf --sim generic --standard-objects`: the FRF through standard objects, in the JSON report;
    without --standard-objects the generic drive is refused in one line that names the option."""
    from hdservo.cli import main
    js = tmp_path / "frf.json"
    assert main(["identify", "frf", "--sim", "generic", "--standard-objects", "--gear-ratio", str(RATIO),
                 "--json", str(js), "-q"]) == 0
    rep = json.loads(js.read_text())
    assert rep["source"].endswith("standard objects")
    assert rep["experiment_sources"] == {"frf": "CiA 402 standard objects"}
    frf = rep["results"]["frf"]
    assert len(frf) == 2
    a = truth.axis("reference")
    fa1, fr1 = truth.frf_truth(a)
    fa, fres = truth.frf_small_signal_truth(a)
    for f in frf:
        assert fa1 < f["f_antiresonance_Hz"] < 1.02 * fa and fr1 < f["f_resonance_Hz"] < 1.02 * fres
    capsys.readouterr()
    assert main(["identify", "friction", "--sim", "generic", "-q"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert len(err) == 1 and err[0].endswith("--standard-objects identifies friction through the CiA 402 "
                                             "standard objects")


@needs_sim
def test_test_cli_bandwidth_on_the_generic_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`hdservo test bandwidth --sim generic --standard-objects`: the JSON names the path and the figure."""
    from hdservo.cli import main
    js = tmp_path / "bw.json"
    assert main(["test", "bandwidth", "--sim", "generic", "--standard-objects", "--gear-ratio", str(RATIO),
                 "--amplitude-arcsec", "1800", "--json", str(js), "-q"]) == 0
    rep = json.loads(js.read_text())
    assert rep["target"].endswith("standard objects")
    assert "standard objects" in rep["results"]["bandwidth"]["conditions"]["path"]
    bw = rep["headline"]["bandwidth_hz"]
    assert 1.0 < bw < 80.0 and rep["results"]["bandwidth"]["figures"]["magnitude_dB"][0] > -1.0


@pytest.mark.parametrize("argv,msg", [
    (("test", "stiffness", "--sim", "generic", "--standard-objects", "--gear-ratio", "100"),
     "test stiffness: not on the standard-objects path (needs hdservo's capture or a test rig); --standard-objects "
     "runs bandwidth, min-rate, peak-torque, positioning"),
    (("test", "peak-torque", "--sim", "generic", "--standard-objects", "--gear-ratio", "100"),
     "peak-torque --standard-objects: needs --peak-request N.m and --output-locked (the operator locks the output; "
     "the standard objects have no brake)"),
    (("test", "bandwidth", "--sim", "--gear-ratio", "100"), "--gear-ratio: options of --standard-objects"),
    (("test", "bandwidth", "--sim", "generic", "--standard-objects", "--set", "vel_kp=200", "--gear-ratio", "100"),
     "--set: hdservo drive parameters, not on the standard-objects path"),
])
def test_test_standard_objects_bad_arguments_one_line(argv: tuple[str, ...], msg: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    from hdservo.cli import main
    assert main(list(argv)) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert err == [f"hdservo test: error: {msg}"]
