#!/usr/bin/env python3
"""Identification accuracy on the simulator: relative error of every identified parameter per axis.

Every effect on, noise and quantisation on, the fitter given only the data: the
simulator binding (full designs) and, when hdservo-sim is built, the virtual drive
over CAN (TE, friction, locked-output stiffness through its rig).  The FRF runs at
several amplitudes against the linearised (small-signal) gear and the K1 values.
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
from hdservo.fileio import write_json_atomic as write_json  # noqa: E402


def rel(a: float, b: float) -> float:
    return a / b - 1.0


STIFF_KEYS = ("k1_Nm_per_rad", "k2_Nm_per_rad", "k3_Nm_per_rad", "t1_Nm", "t2_Nm")
#: FRF amplitudes (rad/s) of the amplitude-dependence run: small signal (elements stick) .. slipping
FRF_AMPLITUDES = (0.005, 0.01, 0.02, 0.04, 0.16)
#: Cortex-M4 estimate for the online Stribeck RLS on the drive: one sample per 50 ms block, FPU at
#: ~2 cycles per operation (multiply-add/compare/load-store mix), 170 MHz (STM32G474)
M4_HZ, M4_CYCLES_PER_OP, BLOCK_S = 170e6, 2.0, 0.05


def stiffness_errors(a: dict, st: stf.StiffnessResult, name: str) -> dict:
    out = {k: rel(getattr(st, k), a["stiffness"][k]) for k in STIFF_KEYS}
    loss_true = truth.hysteresis_loss(a, truth.TORQUE_MAX[name])
    out["hysteresis_loss"] = rel(st.hysteresis_loss_rad, loss_true)
    out["hysteresis_loss_identified_arcmin"] = st.hysteresis_loss_rad / truth_arcmin()
    out["hysteresis_loss_truth_arcmin"] = loss_true / truth_arcmin()
    out["lost_motion_arcmin"] = (st.lost_motion_rad or 0) / truth_arcmin()
    hm = a["hysteresis_maxwell"]
    out["maxwell_sum_w"] = rel(sum(st.maxwell.w_Nm), sum(hm[f"e{i}_w_Nm"] for i in range(1, hm["n_elements"] + 1)))
    out["maxwell_elements"] = len(st.maxwell.w_Nm)
    out["odd_band_rad"] = st.odd_band_rad
    return out


def friction_errors(a: dict, sb) -> dict:
    ft = truth.friction_total(a)
    out = {k: rel(getattr(sb, k), ft[k]) for k in ft}
    out["delta"] = rel(sb.delta, a["friction_load"]["delta"])
    return out


def te_errors(a: dict, te) -> dict:
    t = a["transmission_error"]
    out: dict = {}
    for n, amp, ph in zip(te.wg_orders, te.wg_amp_rad, te.wg_phase_rad):
        k = next((i for i in range(1, 5) if t[f"wg{i}_order"] == n and t[f"wg{i}_amp_rad"] > 0), None)
        if k is None:
            out[f"wg_order_{n}_amp_rad_spurious"] = amp
            continue
        d = (ph - t[f"wg{k}_phase_rad"] + math.pi) % (2 * math.pi) - math.pi
        out[f"wg_order_{n}"] = {"amp_rel_error": rel(amp, t[f"wg{k}_amp_rad"]), "phase_error_deg": math.degrees(d)}
    return out


def one_axis(name: str) -> dict:
    a = truth.axis(name)
    r = cache.runner(name)
    pl = pipeline.Pipeline(runner=r, settings=pipeline.Settings(torque_max_Nm=truth.TORQUE_MAX[name]))
    pl.run("all")
    res = pl.results
    out: dict = {"timings_s": pl.timings}
    out["friction"] = friction_errors(a, res["stribeck"])
    g = res["gravity"]
    out["gravity"] = {"mgl_Nm": rel(g.mgl_Nm, a["gravity"]["mgl_Nm"]),
                      "offset_rad_abs_error": g.offset_rad - a["gravity"]["offset_rad"]}
    o = dict(res["stribeck_online"])
    o.pop("max_rel_error_history", None)
    ops_s = o["ops_per_sample"] / BLOCK_S
    o["on_drive_estimate"] = {"block_s": BLOCK_S, "ops_per_s": ops_s,
                              "m4_load_fraction": ops_s * M4_CYCLES_PER_OP / M4_HZ,
                              "state_bytes": 4 * o["memory_words"],
                              "note": "float32 on the M4 FPU; the firmware's integer rule needs an int64 / "
                                      "Q-scaled covariance update, or the drive streams block means to the host"}
    out["stribeck_online"] = o
    out["stiffness"] = stiffness_errors(a, res["stiffness"], name)
    out["te"] = te_errors(a, res["te"])
    # FRF: truth = two-mass model with the linearised gear stiffness (K1 + sticking Maxwell-slip k +
    # Preisach small-signal slope, ident_truth.frf_small_signal_truth); K1 values for reference
    fa, fr = truth.frf_small_signal_truth(a)
    fa1, fr1 = truth.frf_truth(a)
    k_lin = truth.small_signal_stiffness(a)
    out["frf_truth"] = {"f_a_small_signal_Hz": fa, "f_r_small_signal_Hz": fr, "f_a_k1_Hz": fa1, "f_r_k1_Hz": fr1,
                        "k_small_signal_over_k1": k_lin / a["stiffness"]["k1_Nm_per_rad"]}
    d = r.run(ex.FRFExcitation(amplitudes_rad_s=FRF_AMPLITUDES))
    out["frf"] = [{"amplitude_rad_s": f.amplitude_rad_s, "f_a_rel": rel(f.f_antiresonance_Hz, fa),
                   "f_r_rel": rel(f.f_resonance_Hz, fr), "f_a_rel_to_k1_value": rel(f.f_antiresonance_Hz, fa1),
                   "f_r_rel_to_k1_value": rel(f.f_resonance_Hz, fr1),
                   "k_fit_over_k1": f.k_Nm_per_rad / a["stiffness"]["k1_Nm_per_rad"],
                   "j_load_rel": rel(f.j2_kgm2, a["load"]["jl_kgm2"]),
                   "j_motor_rel": rel(f.j1_kgm2, a["motor"]["jm_kgm2"] * a["gear"]["ratio"] ** 2)}
                  for f in frfm.fit_frf(d)]
    p = res["preisach"]
    out["preisach"] = {"minor_loop_rms_over_width": p["minor_loops"].rms_over_width,
                       "minor_loop_rms_over_width_quantised": p["minor_loops_quantised"].rms_over_width,
                       "loop_width_arcmin": p["minor_loops"].loop_width_rad / truth_arcmin(),
                       "levels": p["everett"].levels, "step_Nm": p["everett"].step_Nm, "crc": int(p["table"].crc)}
    if "presliding" in res:
        ps = res["presliding"]
        out["presliding_motor"] = {"sigma0_rel": rel(ps.sigma0_Nm_per_rad, a["friction_motor"]["sigma0_Nm_per_rad"]),
                                   "breakaway_pos_rel": rel(ps.breakaway_pos_Nm, a["friction_motor"]["fs_pos_Nm"]),
                                   "breakaway_neg_rel": rel(ps.breakaway_neg_Nm, a["friction_motor"]["fs_neg_Nm"])}
    # over CAN: the virtual drive (lock-step), locked output through its rig
    if cache.SIM_BIN.exists():
        pc = cache.over_can(name)
        out["over_can"] = {"source": "virtual drive over CAN", "friction": friction_errors(a, pc.results["stribeck"]),
                           "stiffness": stiffness_errors(a, pc.results["stiffness"], name),
                           "te": te_errors(a, pc.results["te"]), "timings_s": pc.timings,
                           "frf": [{"amplitude_rad_s": f.amplitude_rad_s, "f_a_rel": rel(f.f_antiresonance_Hz, fa),
                                    "f_r_rel": rel(f.f_resonance_Hz, fr),
                                    "f_a_rel_to_k1_value": rel(f.f_antiresonance_Hz, fa1),
                                    "f_r_rel_to_k1_value": rel(f.f_resonance_Hz, fr1)} for f in pc.results["frf"]]}
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
        s = r["stiffness"]
        f0 = r["frf"][0]
        print(f"{name}: Fs+ {f['fs_pos_Nm']:+.2%} Fc+ {f['fc_pos_Nm']:+.2%} vs {f['vs_rad_s']:+.2%} "
              f"Fv {f['viscous_Nms_per_rad']:+.2%} | K1 {s['k1_Nm_per_rad']:+.2%} K2 {s['k2_Nm_per_rad']:+.2%} "
              f"K3 {s['k3_Nm_per_rad']:+.2%} T1 {s['t1_Nm']:+.2%} T2 {s['t2_Nm']:+.2%} | loss "
              f"{s['hysteresis_loss']:+.2%} | Preisach {r['preisach']['minor_loop_rms_over_width']:.2%} of width | "
              f"f_a/f_r at {f0['amplitude_rad_s']} rad/s {f0['f_a_rel']:+.2%}/{f0['f_r_rel']:+.2%}")
        if "over_can" in r:
            c, cs = r["over_can"]["friction"], r["over_can"]["stiffness"]
            print(f"  over CAN: Fs+ {c['fs_pos_Nm']:+.2%} Fc+ {c['fc_pos_Nm']:+.2%} | K1 {cs['k1_Nm_per_rad']:+.2%} "
                  f"K2 {cs['k2_Nm_per_rad']:+.2%} K3 {cs['k3_Nm_per_rad']:+.2%} T1 {cs['t1_Nm']:+.2%} "
                  f"T2 {cs['t2_Nm']:+.2%} | loss {cs['hysteresis_loss']:+.2%}")
    print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
