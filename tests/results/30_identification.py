#!/usr/bin/env python3
"""Identification accuracy on the simulator: relative error of every identified parameter per axis.

Every effect on, noise and quantisation on; two extra runs show the quantities
that need an effect hidden to be identifiable (docs/identification.md):
stiffness with the plant's Preisach term off, FRF with the hysteresis off.
Writes build/results/identification.json.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

import ident_cache as cache  # noqa: E402
import ident_truth as truth  # noqa: E402
from hdservo.ident import experiments as ex  # noqa: E402
from hdservo.ident import frf as frfm  # noqa: E402
from hdservo.ident import pipeline, stiffness as stf  # noqa: E402
from hdservo.ident.report import write_json  # noqa: E402


def rel(a: float, b: float) -> float:
    return a / b - 1.0


def one_axis(name: str) -> dict:
    a = truth.axis(name)
    r = cache.runner(name)
    pl = pipeline.Pipeline(runner=r, settings=pipeline.Settings(torque_max_Nm=truth.TORQUE_MAX[name]))
    pl.run("all")
    res = pl.results
    out: dict = {"timings_s": pl.timings}
    ft = truth.friction_total(a)
    sb = res["stribeck"]
    out["friction"] = {k: rel(getattr(sb, k), ft[k]) for k in ft}
    out["friction"]["delta"] = rel(sb.delta, a["friction_load"]["delta"])
    g = res["gravity"]
    out["gravity"] = {"mgl_Nm": rel(g.mgl_Nm, a["gravity"]["mgl_Nm"]),
                      "offset_rad_abs_error": g.offset_rad - a["gravity"]["offset_rad"]}
    o = dict(res["stribeck_online"])
    o.pop("max_rel_error_history", None)
    out["stribeck_online"] = o
    st = res["stiffness"]
    keys = ("k1_Nm_per_rad", "k2_Nm_per_rad", "k3_Nm_per_rad", "t1_Nm", "t2_Nm")
    out["stiffness_all_effects_on"] = {k: rel(getattr(st, k), a["stiffness"][k]) for k in keys}
    loss_true = truth.hysteresis_loss(a, truth.TORQUE_MAX[name])
    out["hysteresis_loss_all_effects_on"] = {"identified_arcmin": st.hysteresis_loss_rad / truth_arcmin(),
                                             "truth_arcmin": loss_true / truth_arcmin(),
                                             "rel_error": rel(st.hysteresis_loss_rad, loss_true),
                                             "lost_motion_arcmin": (st.lost_motion_rad or 0) / truth_arcmin()}
    hidden = stf.fit_stiffness(cache.locked(name, hide=True), res["te"])
    out["stiffness_preisach_hidden"] = {k: rel(getattr(hidden, k), a["stiffness"][k]) for k in keys}
    out["stiffness_preisach_hidden"]["hysteresis_loss"] = rel(
        hidden.hysteresis_loss_rad, truth.hysteresis_loss(a, truth.TORQUE_MAX[name], preisach=False))
    hm = a["hysteresis_maxwell"]
    wsum = sum(hm[f"e{i}_w_Nm"] for i in range(1, hm["n_elements"] + 1))
    out["stiffness_preisach_hidden"]["maxwell_sum_w"] = rel(sum(hidden.maxwell.w_Nm), wsum)
    out["stiffness_preisach_hidden"]["maxwell_elements"] = len(hidden.maxwell.w_Nm)
    te = res["te"]
    t = a["transmission_error"]
    out["te"] = {}
    for n, amp, ph in zip(te.wg_orders, te.wg_amp_rad, te.wg_phase_rad):
        k = next((i for i in range(1, 5) if t[f"wg{i}_order"] == n and t[f"wg{i}_amp_rad"] > 0), None)
        if k is None:
            out["te"][f"wg_order_{n}_amp_rad_spurious"] = amp
            continue
        d = (ph - t[f"wg{k}_phase_rad"] + math.pi) % (2 * math.pi) - math.pi
        out["te"][f"wg_order_{n}"] = {"amp_rel_error": rel(amp, t[f"wg{k}_amp_rad"]), "phase_error_deg": math.degrees(d)}
    fa, fr = truth.frf_truth(a)
    out["frf_all_effects_on"] = [{"amplitude_rad_s": f.amplitude_rad_s, "f_a_rel": rel(f.f_antiresonance_Hz, fa),
                                  "f_r_rel": rel(f.f_resonance_Hz, fr), "k_small_signal_over_k1":
                                  f.k_Nm_per_rad / a["stiffness"]["k1_Nm_per_rad"]} for f in res["frf"]]
    d = cache.runner(name, effects=cache.HIDE_FOR_FRF).run(ex.FRFExcitation())
    out["frf_hysteresis_hidden"] = []
    for f in frfm.fit_frf(d):
        out["frf_hysteresis_hidden"].append({
            "amplitude_rad_s": f.amplitude_rad_s, "f_a_rel": rel(f.f_antiresonance_Hz, fa),
            "f_r_rel": rel(f.f_resonance_Hz, fr), "k1_rel": rel(f.k_Nm_per_rad, a["stiffness"]["k1_Nm_per_rad"]),
            "j_load_rel": rel(f.j2_kgm2, a["load"]["jl_kgm2"]),
            "j_motor_rel": rel(f.j1_kgm2, a["motor"]["jm_kgm2"] * a["gear"]["ratio"] ** 2)})
    p = res["preisach"]
    out["preisach"] = {"minor_loop_rms_over_width": p["minor_loops"].rms_over_width,
                       "minor_loop_rms_over_width_quantised": p["minor_loops_quantised"].rms_over_width,
                       "loop_width_arcmin": p["minor_loops"].loop_width_rad / truth_arcmin(),
                       "levels": p["everett"].levels, "step_Nm": p["everett"].step_Nm, "crc": int(p["table"].crc)}
    if "presliding" in res:
        ps = res["presliding"]
        out["presliding_motor"] = {"sigma0_rel": rel(ps.sigma0_Nm_per_rad, a["friction_motor"]["sigma0_Nm_per_rad"]),
                                   "note": "not validated; see docs/identification.md"}
    return out


def truth_arcmin() -> float:
    return math.pi / 180 / 60


def main() -> int:
    out = {"note": "relative errors (identified/true - 1) unless named otherwise; simulator, noise on",
           "axes": {}}
    for name in truth.AXES:
        print(f"identification: {name} ...", flush=True)
        out["axes"][name] = one_axis(name)
    path = ROOT / "build" / "results" / "identification.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, out)
    for name, r in out["axes"].items():
        f = r["friction"]
        s = r["stiffness_preisach_hidden"]
        print(f"{name}: Fs+ {f['fs_pos_Nm']:+.2%} Fc+ {f['fc_pos_Nm']:+.2%} vs {f['vs_rad_s']:+.2%} "
              f"Fv {f['viscous_Nms_per_rad']:+.2%} | K1 {s['k1_Nm_per_rad']:+.2%} K2 {s['k2_Nm_per_rad']:+.2%} "
              f"K3 {s['k3_Nm_per_rad']:+.2%} T1 {s['t1_Nm']:+.2%} T2 {s['t2_Nm']:+.2%} | loss "
              f"{r['hysteresis_loss_all_effects_on']['rel_error']:+.2%} | Preisach "
              f"{r['preisach']['minor_loop_rms_over_width']:.2%} of width")
    print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
