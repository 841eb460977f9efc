"""The download plan of a model identified on any catalogue axis (hdservo.axisgen, ratios 30-160) fits
the drive's parameter ranges: every compensator parameter, the Stribeck motor share and the
identified lost-motion elements included (the identification -> download -> compare chain)."""
from __future__ import annotations

from pathlib import Path

import pytest

import ident_truth as truth
from hdservo import axisgen as ag
from hdservo import download as dl
from hdservo.ident.model_toml import write_toml
from hdservo.params_gen import BY_NAME as PARAMS


def _true_model(a: dict) -> dict:
    """A model with every section identification writes, from the axis file's true values."""
    n = a["gear"]["ratio"]
    m, st = a["friction_motor"], a["stiffness"]
    ft = truth.friction_total(a)
    tm = {"gear": {"ratio": float(n)},
          "friction_total": {**ft, "delta": 2.0},
          "friction_motor": {"sigma0_Nm_per_rad": m["sigma0_Nm_per_rad"],
                             "presliding_breakaway_pos_Nm": m["fs_pos_Nm"],
                             "presliding_breakaway_neg_Nm": m["fs_neg_Nm"]},
          "stiffness": {k: st[k] for k in ("k1_Nm_per_rad", "k2_Nm_per_rad", "k3_Nm_per_rad", "t1_Nm", "t2_Nm")},
          "load": {"jl_kgm2": a["load"]["jl_kgm2"]}, "motor": {"jm_kgm2": a["motor"]["jm_kgm2"]},
          "gravity": {"mgl_Nm": a["gravity"]["mgl_Nm"], "offset_rad": 0.0}}
    hm = a["hysteresis_maxwell"]
    tm["hysteresis_maxwell"] = {"n_elements": int(hm["n_elements"])}
    for i in range(1, int(hm["n_elements"]) + 1):
        tm["hysteresis_maxwell"][f"e{i}_k_Nm_per_rad"] = hm[f"e{i}_k_Nm_per_rad"]
        tm["hysteresis_maxwell"][f"e{i}_w_Nm"] = hm[f"e{i}_w_Nm"]
    te = a["transmission_error"]
    tm["transmission_error"] = {}
    for i in range(1, 5):
        for k in ("order", "amp_rad", "phase_rad"):
            v = te[f"wg{i}_{k}"]
            tm["transmission_error"][f"wg{i}_{k}"] = int(v) if k == "order" else float(v)
    # the output-side lines, numbered from 1 without gaps as `hdservo identify` writes them
    n_out = 0
    for i in range(1, 5):
        if int(te.get(f"out{i}_order", 0)) > 0 and float(te.get(f"out{i}_amp_rad", 0.0)) != 0.0:
            n_out += 1
            for k in ("order", "amp_rad", "phase_rad"):
                v = te[f"out{i}_{k}"]
                tm["transmission_error"][f"out{n_out}_{k}"] = int(v) if k == "order" else float(v)
    # lost motion: the output friction turned over in its presliding distance, through K1
    fl = a["friction_load"]
    z = fl["fs_pos_Nm"] / fl["sigma0_Nm_per_rad"]
    lost = (fl["fs_pos_Nm"] + fl["fs_neg_Nm"]) / st["k1_Nm_per_rad"]
    tm["lost_motion"] = {"n_elements": 3}
    for i, f in enumerate((0.5, 1.0, 2.0), start=1):
        tm["lost_motion"][f"e{i}_d_rad"] = f * z
        tm["lost_motion"][f"e{i}_gain"] = lost / (3 * 2 * f * z)
    return tm


@pytest.mark.parametrize("seed", [3, 101])
def test_download_plan_fits_the_drive_on_catalogue_axes(tmp_path: Path, seed: int) -> None:
    ratios = set()
    for path in ag.write_axes(tmp_path / "axes", 12, seed):
        import tomllib
        with open(path, "rb") as f:
            a = tomllib.load(f)
        ratios.add(int(a["gear"]["ratio"]))
        mp = tmp_path / f"{path.stem}.model.toml"
        write_toml(mp, _true_model(a))
        plan = dl.plan_download(mp, axis=str(path))          # a value outside a range is a UserError
        p = plan["params"]
        for name, v in p.items():
            assert PARAMS[name].min <= v <= PARAMS[name].max, (path.stem, name, v)
        assert p["mx_n"] == 3 and p["mx_k1"] > 0
        assert 0 < p["str_fs_pos"] <= truth.friction_total(a)["fs_pos_Nm"] * (1 + 1e-12)
    assert min(ratios) <= 50 and max(ratios) >= 100          # the catalogue's range is covered


def test_true_model_downloads_the_output_side_te(tmp_path: Path) -> None:
    """The true model of an axis (the studies' stand-in for an identified one) carries the axis' largest
    output-side TE line into the download, as an identified model does: without it a semi-closed
    study leaves that line (a few arcsec per output revolution) uncompensated."""
    import math
    import tomllib
    path = ag.write_axes(tmp_path / "axes", 1, 55)[0]
    with open(path, "rb") as f:
        a = tomllib.load(f)
    te = a["transmission_error"]
    lines = [(abs(te[f"out{i}_amp_rad"]), int(te[f"out{i}_order"])) for i in range(1, 5)
             if int(te[f"out{i}_order"]) > 0 and te[f"out{i}_amp_rad"] != 0.0]
    assert lines, "the drawn axis has an output-side TE line"
    amp, order = max(lines)
    mp = tmp_path / "true.model.toml"
    write_toml(mp, _true_model(a))
    p = dl.plan_download(mp, axis=str(path))["params"]
    assert p["te_out_order1"] == order
    assert p["te_out_amp1"] * 2 * math.pi == pytest.approx(amp, rel=1e-9)


def test_velocity_loop_of_the_design_rule_fits_the_drive_on_heavy_axes(tmp_path: Path) -> None:
    """A CSF-40 axis with J = 6.5 kg.m^2 (axisgen seed 7): ki of the 25 Hz rule (40000 N.m/rad) is beyond
    the drive's Q15.16 vel_ki; the identification's loop and the comparison's fair PID stay inside it,
    with the crossover's kp and a lower PI zero."""
    import math
    from hdservo import closedloop_cases as bl
    from hdservo.ident import tuning
    path = ag.write_axes(tmp_path, 1, seed=7)[0]
    j = ag.random_axes(1, seed=7)[0].summary()["j_total_kgm2"]
    assert j > 5.3
    for g in (tuning.velocity_pi(j), bl.axis_controller(str(path))["gains"]):
        assert g["vel_ki"] == PARAMS["vel_ki"].max
        assert g["vel_kp"] == pytest.approx(j * 2 * math.pi * 25.0)
        assert PARAMS["vel_kp"].min <= g["vel_kp"] <= PARAMS["vel_kp"].max
    light = tuning.velocity_pi(1.3)
    assert light["vel_ki"] == pytest.approx(1.3 * (2 * math.pi * 25.0) ** 2 / 4)      # the rule itself


class _CrossCheckDrive:
    """A drive whose compliance check refuses cp_t1 above the cp_t2 in force (as hd_compliance_design)."""

    def __init__(self) -> None:
        from hdservo.download import raw_of
        self.values = {(PARAMS[n].index, PARAMS[n].sub): raw_of(n, v) for n, v in (("cp_t1", 14.0), ("cp_t2", 48.0))}
        self.t1, self.t2 = (PARAMS["cp_t1"].index, PARAMS["cp_t1"].sub), (PARAMS["cp_t2"].index, PARAMS["cp_t2"].sub)

    def state(self) -> str:
        return "SWITCH ON DISABLED"

    def write(self, index: int, sub: int, raw: int) -> None:
        from hdservo.drive import DriveError
        new = {**self.values, (index, sub): raw}
        if new.get(self.t1, 0) > new.get(self.t2, 0):
            raise DriveError(f"write 0x{index:04X}:{sub} = {raw}: Code 0x06090030, Value range of parameter exceeded")
        self.values = new

    def read(self, index: int, sub: int) -> int:
        return self.values[(index, sub)]


def test_download_orders_writes_across_a_cross_check() -> None:
    """A CSF-40 gear's T1 (52.8 N.m) above the drive's default T2 (48 N.m): cp_t1 is refused until
    cp_t2 is written; the download writes it again after the others (it ended the demo before)."""
    from hdservo.download import raw_of, write_verified
    d = _CrossCheckDrive()
    plan = {"sdo": {"cp_t1": 52.8, "cp_t2": 185.7}, "groups": {}, "preisach": None, "version": 1}
    done = write_verified(d, plan, tables=False)
    assert done["params"] == 2
    assert d.values[d.t1] == raw_of("cp_t1", 52.8) and d.values[d.t2] == raw_of("cp_t2", 185.7)
    # a value the drive refuses on its own stays a refusal (one line)
    from hdservo.errors import UserError
    d2 = _CrossCheckDrive()
    with pytest.raises(UserError, match="refused by the drive.*0x06090030"):
        write_verified(d2, {"sdo": {"cp_t1": 60.0, "cp_t2": 50.0}, "groups": {}, "preisach": None,
                            "version": 1}, tables=False)
