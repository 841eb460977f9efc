"""Lost-motion identification: Maxwell-slip elements on the output travel from the twist of a small
position sine, written to the model, read back and downloaded as the drive's ``mx_*`` elements."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hdservo import compsetup, sim
from hdservo import download as dl
from hdservo.errors import UserError
from hdservo.ident import experiments as ex
from hdservo.ident.lost_motion import LostMotionResult, fit_lost_motion
from hdservo.ident.model_reader import ModelError, check_model
from hdservo.ident.model_toml import format_toml, model_sections

#: the TE is hidden here (the pipeline removes the identified TE; tests/python/test_ident_any_axis covers it)
NO_TE = {"transmission_error": False}


def _run(effects: dict[str, bool], amplitude: float = 1e-3, seed: int = 1) -> ex.ExperimentData:
    return ex.SimRunner(axis="reference", effects={**NO_TE, **effects}, seed=seed).run(
        ex.LostMotionSine(amplitude_rad=amplitude, cycles=1.5))


def test_elements_follow_the_output_friction_turning_over() -> None:
    """On the reference axis (output friction Fs 0.6 / 0.552 N.m, gear K1 31000 N.m/rad) the
    reversal twist is the friction's change over the gear's small-torque stiffness: between
    (Fs+ + Fs-) / (3 K1) and (Fs+ + Fs-) / K1; without output friction there is none."""
    r = fit_lost_motion(_run({}))
    ax = {k: float(sim.axis_param(k, "reference")) for k in
          ("friction_load.fs_pos_Nm", "friction_load.fs_neg_Nm", "stiffness.k1_Nm_per_rad")}
    flip = (ax["friction_load.fs_pos_Nm"] + ax["friction_load.fs_neg_Nm"]) / ax["stiffness.k1_Nm_per_rad"]
    assert 1 <= len(r.gain) <= 8 and all(g > 0 for g in r.gain)
    assert flip / 3 < r.lost_motion_rad < flip
    # the elements turn over within the friction's presliding (a few x Fs / sigma0 = 2e-5 rad)
    assert max(d for g, d in zip(r.gain, r.d_rad) if g > 0.05 * max(r.gain)) < 1e-4
    assert r.rms_residual_rad < 0.1 * r.lost_motion_rad
    none = fit_lost_motion(_run({"friction_load": False}))
    assert none.lost_motion_rad < 0.05 * r.lost_motion_rad


def test_elements_predict_a_held_out_run() -> None:
    """Fitted on +-1e-3 rad, the elements predict the twist of a +-4e-4 rad run with another noise seed."""
    r = fit_lost_motion(_run({}))
    d = _run({}, amplitude=4e-4, seed=5)
    s = d.segment(0)
    x = np.asarray(s["load_angle_rad"])
    tw = np.asarray(s["motor_angle_rad"]) / d.gear_ratio - x
    k0 = int(np.argmax(np.abs(x - x[0])))
    pred = r.predict(x)[k0:]
    meas = tw[k0:]
    err = (meas - meas.mean()) - (pred - pred.mean())
    assert np.sqrt(np.mean(err ** 2)) < 0.25 * r.lost_motion_rad
    assert np.ptp(pred) > 0.8 * r.lost_motion_rad       # the smaller sine still turns the elements over


def test_model_roundtrip_and_download_gives_the_drive_elements(tmp_path: Path) -> None:
    """The model's [lost_motion] elements become mx_k = gain x mx_stiffness, mx_d = d (turn)."""
    lm = LostMotionResult(gain=[0.2, 0.3, 0.1], d_rad=[5e-6, 1e-5, 3e-5], lost_motion_rad=2 * (1e-6 + 3e-6 + 3e-6),
                          rms_residual_rad=1e-7, amplitude_rad=1e-3)
    text = format_toml(model_sections({"lost_motion": lm}, 100.0))
    import tomllib
    model = check_model(tomllib.loads(text), "m.toml")
    assert model["lost_motion"]["n_elements"] == 3 and model["lost_motion"]["e2_gain"] == 0.3
    over, _ = dl.model_overrides(model, lambda k: float(sim.axis_param(k, "reference")))
    cp = compsetup.compensator_params("reference", model={**over, "friction_load.enabled": 0.0})
    assert cp["mx_n"] == 3
    for i, (g, d) in enumerate(zip(lm.gain, lm.d_rad), start=1):
        assert cp[f"mx_k{i}"] == pytest.approx(g * cp["mx_stiffness"], rel=1e-12)
        assert cp[f"mx_d{i}"] == pytest.approx(d / (2 * math.pi), rel=1e-12)
    assert cp["mx_k4"] == 0.0 and cp["mx_d4"] == 0.0


def test_more_elements_than_the_drive_holds_are_merged() -> None:
    g = [0.05] * 12
    d = list(np.geomspace(1e-6, 1e-4, 12))
    model = {"lost_motion.n_elements": 12.0, "friction_load.enabled": 0.0}
    for i in range(12):
        model[f"lost_motion.e{i + 1}_gain"] = g[i]
        model[f"lost_motion.e{i + 1}_d_rad"] = d[i]
    cp = compsetup.compensator_params("reference", model=model)
    assert cp["mx_n"] == 8
    k = sum(cp[f"mx_k{i}"] for i in range(1, 9)) / cp["mx_stiffness"]
    reach = sum(cp[f"mx_k{i}"] * cp[f"mx_d{i}"] for i in range(1, 9)) * 2 * math.pi / cp["mx_stiffness"]
    assert k == pytest.approx(sum(g))                                      # the total gain is kept
    assert reach == pytest.approx(sum(a * b for a, b in zip(g, d)))        # and the lost motion


def test_bad_lost_motion_keys_are_one_line() -> None:
    with pytest.raises(ModelError, match=r"m.toml: key 'lost_motion.e1_gain': expected a finite number >= 0"):
        check_model({"gear": {"ratio": 50.0}, "lost_motion": {"n_elements": 1, "e1_gain": -0.1, "e1_d_rad": 1e-5}},
                    "m.toml")
    with pytest.raises(ModelError, match=r"key 'lost_motion.e2_d_rad': expected .* got nothing"):
        check_model({"gear": {"ratio": 50.0}, "lost_motion": {"n_elements": 2, "e1_gain": 0.1, "e1_d_rad": 1e-5,
                                                            "e2_gain": 0.1}}, "m.toml")


def test_wrong_data_is_refused() -> None:
    d = ex.ExperimentData("friction_sweep", {"t_s": np.zeros(3)}, {"gear_ratio": 100.0})
    with pytest.raises(UserError, match="expected lost_motion data"):
        fit_lost_motion(d)
