"""The Stribeck feed-forward's steady-motion threshold (``str_steady_vs``) by the loop-damping rule.

In steady motion the feed-forward takes the reference velocity and leaves the plant's friction drop
to the velocity loop; where the drop is steeper than the loop's damping the axis stick-slips around
the reference.  ``compsetup.steady_motion_vs`` puts the threshold above the speeds where that is so.
The closed-loop check runs the comparison's Stribeck row on a CSF-40-100 of ``hdservo.axisgen`` (seed
29): with a fixed vs / 8 its 0.1 deg/s tracking sine stick-slips (peak error near the fair PID's).
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from hdservo import axisgen as ag
from hdservo import closedloop_cases as bl
from hdservo import compare as cp
from hdservo import compsetup as cs
from hdservo import download as dl
from hdservo.ident.model_toml import write_toml

#: The demo's slow tracking sine (``hdservo.procedures.tracking``): peak rate and period.
SINE_DEG_S = 0.1
SINE_PERIOD_S = 4.0


def _side(fc: float, fs: float, vs: float, delta: float = 2.0, fv: float = 0.0) -> dict[str, float]:
    return {"fc": fc, "fs": fs, "vs": vs, "delta": delta, "fv": fv}


def test_flat_drop_keeps_the_base_threshold() -> None:
    # peak drop of a delta-2 hump: 0.858 (Fs - Fc) / vs = 137 N.m.s/rad < vel_kp 204 (the reference axis)
    s = [_side(7.4, 10.6, 0.02)]
    assert cs.steady_motion_vs(s, 0.02, 204.0) == cs.STR_STEADY_VS
    assert cs.steady_motion_vs(s, 0.02, 0.0) > 1.0            # no damping: above the hump


def test_steep_drop_moves_the_threshold_above_the_hump() -> None:
    vs, kp = 0.005, 500.0
    s = [_side(33.0, 46.0, vs, 1.7, 20.0)]
    r = cs.steady_motion_vs(s, vs, kp)
    assert r > 1.0
    # the drop is below the loop's damping from the threshold on, and at or above it just below
    v = np.geomspace(r, 64.0, 500) * vs
    assert np.all(-cs.friction_slope(v, s) < kp)
    assert -cs.friction_slope(np.array([0.999 * r * vs]), s)[0] >= kp * 0.99
    # a stiffer loop needs a lower threshold
    assert cs.steady_motion_vs(s, vs, 2 * kp) < r


def test_negative_direction_is_checked() -> None:
    vs = 0.005
    s = [{**_side(33.0, 34.0, vs), "fcn": 33.0, "fsn": 46.0}]       # only the negative direction is steep
    assert cs.steady_motion_vs(s, vs, 500.0) > 1.0


def test_reference_and_csf17_keep_vs_over_8(repo_root: Path) -> None:
    for ax in ("reference", str(repo_root / "sim" / "axes" / "csf17_50.toml")):
        p = cs.compensator_params(ax, vel_kp=cp.design_gains(ax).get("vel_kp"))
        assert p["str_steady_vs"] == cs.STR_STEADY_VS, ax


def test_component_params_leave_the_threshold_to_the_model() -> None:
    # a fixed threshold in the row's gains would overwrite the model's after the download
    assert "str_steady_vs" not in cs.COMPONENT_PARAMS["stribeck"]
    assert "str_steady_vs" not in cs.BEST_GAINS


@pytest.fixture
def repo_root() -> Path:
    return Path(__file__).parents[2]


@pytest.fixture(scope="module")
def csf40(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = ag.write_axes(tmp_path_factory.mktemp("axes"), 1, 29)[0]
    with open(path, "rb") as f:
        assert int(tomllib.load(f)["gear"]["ratio"]) == 100
    return path


def test_identified_model_carries_its_shape_into_the_rule(csf40: Path, tmp_path: Path) -> None:
    # a model as `hdservo identify` fits it on this axis (its sweep's slow points stick-slip:
    # Fs low, vs high, the shape steep); the drive's map runs delta 2, the rule the fitted shape
    with open(csf40, "rb") as f:
        a = tomllib.load(f)
    model = {"gear": {"ratio": 100.0},
             "friction_total": {"fc_pos_Nm": 33.39, "fc_neg_Nm": 33.32, "fs_pos_Nm": 38.84, "fs_neg_Nm": 38.82,
                                "vs_rad_s": 0.01025, "delta": 5.0, "viscous_Nms_per_rad": 22.25},
             "load": {"jl_kgm2": a["load"]["jl_kgm2"]}, "motor": {"jm_kgm2": a["motor"]["jm_kgm2"]}}
    mp = tmp_path / "model.toml"
    write_toml(mp, model)
    kp = cp.design_gains(str(csf40))["vel_kp"]
    p = dl.plan_download(mp, str(csf40), vel_kp=kp)["params"]
    assert p["str_delta"] == 2
    threshold_deg_s = p["str_steady_vs"] * p["str_vs_pos"] * 360.0
    assert threshold_deg_s > SINE_DEG_S


def _sine_reversal_peak(axis: str, names: list[str], gains: dict[str, float]) -> float:
    """Peak |error| within a quarter period after each velocity reversal of the 0.1 deg/s sine, arcsec."""
    v = math.radians(SINE_DEG_S)
    w = 2 * math.pi / SINE_PERIOD_S
    t0 = 0.5
    case = bl.Case("sine_0p1", "reversal", {"type": "sine", "initial_rad": 0.0, "amplitude_rad": v / w,
                                            "frequency_Hz": 1 / SINE_PERIOD_S, "phase_rad": -math.pi / 2,
                                            "t0_s": t0}, duration_s=t0 + 2 * SINE_PERIOD_S, log_decimation=10)
    # the compliance's T1 of a CSF-40 is above the drive's default T2 (a write-order matter, not used here)
    params = {k: x for k, x in cs.compensator_params(axis, vel_kp=gains.get("vel_kp")).items()
              if not k.startswith("cp_")}
    r = bl.run_case(case, cs.controller(axis, names, extra_gains=gains, params=params), axis, 1)
    t, e = r["t_s"], bl.error_arcsec(r)
    revs = [t0 + SINE_PERIOD_S / 2 * k for k in (1, 2, 3)]
    return max(float(np.max(np.abs(e[(t >= tr) & (t <= tr + SINE_PERIOD_S / 4)]))) for tr in revs)


def test_stribeck_row_tracks_the_slow_sine_on_a_steep_drop(csf40: Path) -> None:
    axis = str(csf40)
    pid = cp.fair_row([], axis=axis)
    row = cp.fair_row(["stribeck"], axis=axis)
    base = _sine_reversal_peak(axis, [], pid.gains)
    comp = _sine_reversal_peak(axis, row.compensators, row.gains)
    # the unseen-axis target: the reversal peak 70 % lower, within 1.5 (2.22x)
    assert base / comp >= 1 / (0.3 * 1.5), (base, comp)
