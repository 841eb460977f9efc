"""Identified axis/model TOML: SI units in every key, the plant's keys where they overlap.

Sections written (only those identified):

* ``[gear]`` ratio; ``[stiffness]`` k1/k2/k3_Nm_per_rad, t1_Nm, t2_Nm,
  damping_Nms_per_rad (FRF); ``[stiffness_cubic]`` k1_Nm_per_rad, k3_Nm_per_rad3;
* ``[hysteresis_maxwell]`` n_elements, eK_k_Nm_per_rad, eK_w_Nm;
* ``[lost_motion]`` n_elements, eK_gain (rad/rad), eK_d_rad -- Maxwell-slip elements of the twist
  on the output travel (:mod:`.lost_motion`);
* ``[transmission_error]`` wgK_order/_amp_rad/_phase_rad, outK_...;
* ``[load]`` jl_kgm2 and ``[motor]`` jm_kgm2 (FRF: J2, J1/N^2);
  ``[gravity]`` mgl_Nm, offset_rad;
* ``[friction_total]`` -- output-referred total friction of the axis
  (motor side x N plus load side), keys as the plant's friction sections:
  fc_pos_Nm, fc_neg_Nm, fs_pos_Nm, fs_neg_Nm, vs_rad_s, delta,
  viscous_Nms_per_rad; ``[friction_motor]`` sigma0_Nm_per_rad (+ sigma1)
  from the locked-output presliding (motor units);
* ``[identified]`` hysteresis_loss_rad, lost_motion_rad,
  f_antiresonance_Hz, f_resonance_Hz;
* ``[preisach_host_model]`` -- the host's Preisach model, input torque -> output twist
  (the host's twist predictions; never downloaded): direction, u0_Nm, step_Nm, levels,
  offset_rad;
* ``[preisach_drive_table]`` -- the drive's table, input twist -> output torque, the image
  downloaded to 0x5100:1: direction, file (the ``.preisach.bin`` beside the model), crc,
  levels, u0_rad, step_rad, sub_bits, twist_offset_rad.

Each of the two Preisach sections carries a comment line saying which it is
(:data:`SECTION_NOTES`).  Written atomically (temp file + rename).
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Mapping

from ..fileio import write_text_atomic
from ..tomltext import basic_string


def _fmt(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"non-finite value {v}")
        return repr(float(v))
    if isinstance(v, str):
        return basic_string(v)
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


#: Direction of each Preisach operator (the ``direction`` key of its section).
HOST_MODEL_DIRECTION = "torque -> twist"
DRIVE_TABLE_DIRECTION = "twist -> torque"

#: Comment line written above a section: what a reader cannot tell from the keys alone.
SECTION_NOTES: dict[str, str] = {
    "preisach_host_model": "The host's Preisach model, input torque (N.m) -> output twist (rad): the host's "
                           "twist predictions. Not downloaded.",
    "preisach_drive_table": "The drive's Preisach table, input twist (rad) -> output torque (N.m): the image "
                            "`file` that hdservo download writes to 0x5100:1 (its CRC-32 `crc`).",
}


def format_toml(sections: Mapping[str, Mapping[str, Any]], header: str = "",
                notes: Mapping[str, str] | None = None) -> str:
    """TOML text of ``{section: {key: value}}`` (numbers, bools, strings).

    Parameters
    ----------
    sections : mapping
        Section name -> key -> value.
    header : str
        Comment lines at the top of the file.
    notes : mapping, optional
        Section name -> a comment line written above that section (default :data:`SECTION_NOTES`).
    """
    notes = SECTION_NOTES if notes is None else notes
    out = [f"# {line}" for line in header.splitlines()]
    for name, kv in sections.items():
        if not kv:
            continue
        out.append("")
        if name in notes:
            out.append(f"# {notes[name]}")
        out.append(f"[{name}]")
        for k, v in kv.items():
            if v is None:
                continue
            out.append(f"{k} = {_fmt(v)}")
    return "\n".join(out) + "\n"


def write_toml(path: str | os.PathLike[str], sections: Mapping[str, Mapping[str, Any]], header: str = "") -> None:
    """Write atomically."""
    p = Path(path)
    write_text_atomic(p, format_toml(sections, header))


def model_sections(results: Mapping[str, Any], ratio: float) -> dict[str, dict[str, Any]]:
    """Map fit results (objects from the ident modules) to TOML sections."""
    s: dict[str, dict[str, Any]] = {"gear": {"ratio": float(ratio)}}
    ident: dict[str, Any] = {}
    st = results.get("stiffness")
    if st is not None:
        s["stiffness"] = {"k1_Nm_per_rad": st.k1_Nm_per_rad, "k2_Nm_per_rad": st.k2_Nm_per_rad,
                          "k3_Nm_per_rad": st.k3_Nm_per_rad, "t1_Nm": st.t1_Nm, "t2_Nm": st.t2_Nm}
        s["stiffness_cubic"] = {"k1_Nm_per_rad": st.cubic_k1_Nm_per_rad, "k3_Nm_per_rad3": st.cubic_k3_Nm_per_rad3}
        mw = st.maxwell
        hm: dict[str, Any] = {"n_elements": len(mw.k_Nm_per_rad)}
        for i, (k, w) in enumerate(zip(mw.k_Nm_per_rad, mw.w_Nm), start=1):
            hm[f"e{i}_k_Nm_per_rad"] = k
            hm[f"e{i}_w_Nm"] = w
        s["hysteresis_maxwell"] = hm
        ident["hysteresis_loss_rad"] = st.hysteresis_loss_rad
        ident["lost_motion_rad"] = st.lost_motion_rad
    te = results.get("te")
    if te is not None:
        t: dict[str, Any] = {}
        for i, (n, a, p) in enumerate(zip(te.wg_orders, te.wg_amp_rad, te.wg_phase_rad), start=1):
            t[f"wg{i}_order"], t[f"wg{i}_amp_rad"], t[f"wg{i}_phase_rad"] = int(n), a, p
        for i, (n, a, p) in enumerate(zip(te.out_orders, te.out_amp_rad, te.out_phase_rad), start=1):
            t[f"out{i}_order"], t[f"out{i}_amp_rad"], t[f"out{i}_phase_rad"] = int(n), a, p
        s["transmission_error"] = t
    fr = results.get("frf")
    if fr:
        f = fr[-1]
        s.setdefault("stiffness", {})["damping_Nms_per_rad"] = f.c_Nms_per_rad
        s["load"] = {"jl_kgm2": f.j2_kgm2}
        s["motor"] = {"jm_kgm2": f.j1_kgm2 / ratio ** 2}
        ident["f_antiresonance_Hz"] = f.f_antiresonance_Hz
        ident["f_resonance_Hz"] = f.f_resonance_Hz
        ident["frf_small_signal_k_Nm_per_rad"] = f.k_Nm_per_rad
    g = results.get("gravity")
    if g is not None:
        s["gravity"] = {"mgl_Nm": g.mgl_Nm, "offset_rad": g.offset_rad}
    sb = results.get("stribeck")
    if sb is not None:
        s["friction_total"] = {"fc_pos_Nm": sb.fc_pos_Nm, "fc_neg_Nm": sb.fc_neg_Nm, "fs_pos_Nm": sb.fs_pos_Nm,
                               "fs_neg_Nm": sb.fs_neg_Nm, "vs_rad_s": sb.vs_rad_s, "delta": sb.delta,
                               "viscous_Nms_per_rad": sb.viscous_Nms_per_rad}
    ps = results.get("presliding")
    if ps is not None:
        fm = {"sigma0_Nm_per_rad": ps.sigma0_Nm_per_rad, "presliding_breakaway_pos_Nm": ps.breakaway_pos_Nm,
              "presliding_breakaway_neg_Nm": ps.breakaway_neg_Nm}
        if ps.sigma1_Nms_per_rad is not None:
            fm["sigma1_Nms_per_rad"] = ps.sigma1_Nms_per_rad     # rule sqrt(sigma0 J_m), see the report
        s["friction_motor"] = fm
    lmr = results.get("lost_motion")
    if lmr is not None:
        lt: dict[str, Any] = {"n_elements": len(lmr.gain)}
        for i, (g, d) in enumerate(zip(lmr.gain, lmr.d_rad), start=1):
            lt[f"e{i}_gain"] = g
            lt[f"e{i}_d_rad"] = d
        s["lost_motion"] = lt
        ident["lost_motion_reversal_rad"] = lmr.lost_motion_rad
    s["identified"] = ident
    pz = results.get("preisach")
    if pz is not None:
        ev = pz["everett"]
        s["preisach_host_model"] = {"direction": HOST_MODEL_DIRECTION, "u0_Nm": ev.u0_Nm, "step_Nm": ev.step_Nm,
                                    "levels": ev.levels, "offset_rad": ev.offset_rad}
        tab = pz["table"]
        dt: dict[str, Any] = {"direction": DRIVE_TABLE_DIRECTION}
        if pz.get("file"):
            dt["file"] = str(pz["file"])
        dt["crc"] = int(tab.crc)
        gear = pz.get("gear")
        if gear is not None:        # the twist grid in rad (the Everett's u0_Nm / step_Nm hold rad here)
            dt.update({"levels": gear.everett.levels, "u0_rad": gear.everett.u0_Nm, "step_rad": gear.everett.step_Nm,
                       "sub_bits": int(tab.sub_bits), "twist_offset_rad": gear.twist_offset_rad})
        s["preisach_drive_table"] = dt
    return s
