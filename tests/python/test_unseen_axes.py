"""Logic of tests/results/27_unseen_axes.py on a tiny case (no demo run)."""
from __future__ import annotations

import importlib.util
import tomllib
from pathlib import Path

import pytest

from hdservo import axisgen as ag

ROOT = Path(__file__).resolve().parents[2]


def _script():
    spec = importlib.util.spec_from_file_location("unseen_axes_results", ROOT / "tests" / "results" / "27_unseen_axes.py")
    assert spec is not None and spec.loader is not None
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def test_identification_errors_against_the_axis_file(tmp_path: Path) -> None:
    m = _script()
    path = ag.write_axes(tmp_path, 1, seed=4)[0]
    with open(path, "rb") as f:
        axis = tomllib.load(f)
    n = axis["gear"]["ratio"]
    fm, fl = axis["friction_motor"], axis["friction_load"]
    model = {"friction_total": {"fs_pos_Nm": 1.1 * (n * fm["fs_pos_Nm"] + fl["fs_pos_Nm"]),
                                "fc_pos_Nm": 0.5 * (n * fm["fc_pos_Nm"] + fl["fc_pos_Nm"]),
                                "vs_rad_s": fl["vs_rad_s"]},
             "stiffness": {"k1_Nm_per_rad": 0.97 * axis["stiffness"]["k1_Nm_per_rad"]},
             "transmission_error": {"wg1_order": 1, "wg1_amp_rad": 1.0, "wg2_order": 2,
                                    "wg2_amp_rad": 1.02 * axis["transmission_error"]["wg1_amp_rad"]},
             "motor": {"jm_kgm2": axis["motor"]["jm_kgm2"]}, "load": {"jl_kgm2": axis["load"]["jl_kgm2"]}}
    e = m.ident_errors(model, axis)
    assert e["friction_fs_pos_Nm"] == pytest.approx(0.1) and e["friction_fc_pos_Nm"] == pytest.approx(-0.5)
    assert e["friction_vs_rad_s"] == pytest.approx(0.0, abs=1e-12)
    assert e["stiffness_k1_Nm_per_rad"] == pytest.approx(-0.03)
    assert e["te_wg2_amp_rad"] == pytest.approx(0.02)          # the order-2 line, wherever it is listed
    assert e["j_total_kgm2"] == pytest.approx(0.0, abs=1e-12)
    assert e["friction_fs_neg_Nm"] is None and e["stiffness_t2_Nm"] is None    # not in the model


def test_headline_factors_and_relaxed_targets() -> None:
    m = _script()
    summ = {"positioning_accuracy_arcsec": {"pid": 4.0, "compensated": 1.0},
            "tracking_rms_0p01_arcsec": {"pid": 3.0, "compensated": 2.0},
            "bandwidth_hz": {"pid": 20.0, "compensated": 30.0},
            "reversal_peak_arcsec": {"pid": 10.0, "compensated": None},
            "conditions": {"pid": {}, "compensated": {}}}
    h = m.headline(summ)
    assert h["positioning_accuracy_arcsec"]["factor"] == 4.0
    assert h["bandwidth_hz"]["factor"] == 1.5                 # higher is better: compensated / pid
    assert h["reversal_peak_arcsec"]["factor"] is None and "conditions" not in h
    t = m.targets(h)
    assert t["positioning_accuracy_arcsec"] == {"required_factor": 5.0 / 1.5, "factor": 4.0, "met": True}
    assert t["tracking_rms_0p01_arcsec"]["met"] is False       # 1.5 < 3 / 1.5
    assert t["reversal_peak_arcsec"]["met"] is None and t["stabilisation_rms_arcsec"]["met"] is None
    assert m.verdict(t) is False and m.verdict({}) is None
    assert m.verdict({k: v for k, v in t.items() if k != "tracking_rms_0p01_arcsec"}) is True
    assert m.targets(h, factor=1.0)["positioning_accuracy_arcsec"]["met"] is False
    assert m.cycle_amplitude(48.0) == 63.0 and m.cycle_amplitude(10.0) == 13.0
