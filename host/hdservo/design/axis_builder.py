"""Axis model (simulator axis TOML) of a design candidate, and its controller.

:func:`build_axis` turns a :class:`Candidate` (gear x motor x encoders x gyro
from the catalogues) and the :class:`~hdservo.design.spec.Spec` into every
plant key of ``docs/plant.md`` (``section.key``, SI units), starting from the
reference axis file (``sim/axes/reference.toml``) and replacing what the
candidate and the requirements determine:

==========================  ============================================================
plant keys                  from
==========================  ============================================================
gear.ratio                  catalogue N
motor.jm_kgm2               motor rotor + wave-generator inertia (catalogue)
motor.kt_Nm_per_A           motor Kt
current_loop.*              spec ``current_loop_bandwidth_Hz``, motor peak current
cogging.*                   reference harmonics scaled by motor peak torque (0.2 %)
transmission_error.*        reference harmonics scaled by catalogue transmission accuracy
stiffness.*                 catalogue K1-K3, T1, T2; damping for zeta = 0.024 (reference)
hysteresis_maxwell/preisach reference elements scaled: torque by T1 x (structure hysteresis
                            loss / reference), twist by T1/K1
friction_motor.*            starting torque (catalogue, else structure relation) as
                            breakaway; reference shape (Fc = 0.7 Fs, -5 % asymmetry)
friction_load.*             reference output-bearing friction scaled by (size/25)^3
load.jl_kgm2, gravity.mgl   spec load inertia and unbalance
base.*                      spec base rocking
encoder_motor/load.*        sensor bits; noise counts = catalogue noise / LSB
gyro.*                      noise density, bandwidth, bias instability (catalogue)
current_sensor.noise_A      0.05 % of the peak current (reference: 0.01 A at 20 A)
==========================  ============================================================

Scaling the reference's shapes (rather than inventing new ones) keeps the
candidate axes comparable with the reference axis, whose values are the
reference-axis figures (docs/reference-axis.md).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Mapping, Optional

from .. import resources
from ..fileio import write_text_atomic
from . import structure as st
from .catalogue import GearRow, MotorRow, SensorRow
from .spec import Spec

import tomllib

from ..units import DEG  # noqa: E402
#: reference gear and motor (the values of reference.toml were made for these)
REF_SIZE, REF_RATIO, REF_T1_Nm, REF_K1, REF_TA_arcmin = 25, 100, 14.0, 3.1e4, 1.0
REF_MOTOR_PEAK_Nm = 2.0
#: gear damping ratio of the reference axis: 6 / (2 sqrt(3.1e4 * 0.5))
ZETA_GEAR = 6.0 / (2.0 * math.sqrt(3.1e4 * 0.5))


@dataclass(frozen=True)
class Candidate:
    """One combination of catalogue parts.

    Attributes
    ----------
    gear : GearRow
    motor : MotorRow
    motor_encoder, output_encoder, gyro : SensorRow
    """

    gear: GearRow
    motor: MotorRow
    motor_encoder: SensorRow
    output_encoder: SensorRow
    gyro: SensorRow

    @property
    def name(self) -> str:
        """``GEAR + MOTOR + ENC/ENC/GYRO``."""
        return (f"{self.gear.name} + {self.motor.name} + {self.motor_encoder.name} / "
                f"{self.output_encoder.name} / {self.gyro.name}")

    @property
    def slug(self) -> str:
        """File-name friendly short name, e.g. ``csf-25-100_fl-070``."""
        return f"{self.gear.name.lower()}_{self.motor.name.replace('-class', '')}"

    @property
    def input_inertia_kgm2(self) -> float:
        """Motor rotor + wave generator, kg·m² (input side)."""
        return self.motor.rotor_inertia_kgm2 + self.gear.input_inertia_kgm2

    def parts(self) -> Dict[str, str]:
        """Part names by role."""
        return {"gear": self.gear.name, "motor": self.motor.name, "motor_encoder": self.motor_encoder.name,
                "output_encoder": self.output_encoder.name, "gyro": self.gyro.name}


def reference_params(path: Optional[Path] = None) -> Dict[str, Dict[str, Any]]:
    """The reference axis file every candidate starts from, as ``{section: {key: value}}``.

    Parameters
    ----------
    path : pathlib.Path, optional
        Axis file to read instead of the shipped ``reference`` axis
        (:func:`hdservo.resources.axis_file`).
    """
    with open(path if path is not None else resources.axis_file("reference"), "rb") as f:
        return tomllib.load(f)


def gear_friction(gear: GearRow) -> st.Friction:
    """No-load friction of a gear: the catalogue starting torque if published, else
    the structure relation (:func:`hdservo.design.structure.friction`)."""
    cal = st.load_calibration()
    rel = st.friction(st.structure_for(gear.size, gear.ratio), cal)
    if gear.starting_torque_input_Nm is None:
        return rel
    ts = gear.starting_torque_input_Nm
    back = st.BACKDRIVE_FACTOR * gear.ratio * ts
    return st.Friction(ts, back, back / st.STATIC_OVER_COULOMB)


def hysteresis_scale(gear: GearRow) -> float:
    """Hysteresis loss at rated torque of the gear relative to the reference gear
    (structure relation, :func:`hdservo.design.structure.hysteresis_loss`)."""
    cal = st.load_calibration()
    h = st.hysteresis_loss(st.structure_for(gear.size, gear.ratio), cal, gear.rated_torque_Nm)
    from .catalogue import find_gear
    ref = find_gear(REF_SIZE, REF_RATIO, "CSF")
    h0 = st.hysteresis_loss(st.structure_for(REF_SIZE, REF_RATIO), cal, ref.rated_torque_Nm)
    return h / h0


def build_axis(c: Candidate, spec: Spec, base: Optional[Mapping[str, Mapping[str, Any]]] = None
               ) -> Dict[str, Dict[str, Any]]:
    """Every plant parameter of the candidate's axis.

    Parameters
    ----------
    c : Candidate
    spec : Spec
    base : mapping, optional
        Template ``{section: {key: value}}``; default the reference axis file.

    Returns
    -------
    dict
        ``{section: {key: value}}`` with SI values (see the module docstring).
    """
    p: Dict[str, Dict[str, Any]] = {s: dict(v) for s, v in (base or reference_params()).items()}
    g, m = c.gear, c.motor
    n = float(g.ratio)
    p["gear"]["ratio"] = int(g.ratio)
    p["motor"]["jm_kgm2"] = c.input_inertia_kgm2
    p["motor"]["kt_Nm_per_A"] = m.kt_Nm_per_A
    p["current_loop"].update(enabled=True, bandwidth_Hz=spec.options.current_loop_bandwidth_Hz,
                             peak_A=m.peak_current_A)
    cs = m.peak_torque_Nm / REF_MOTOR_PEAK_Nm
    for i in range(1, 5):
        p["cogging"][f"h{i}_amp_Nm"] = float(p["cogging"][f"h{i}_amp_Nm"]) * cs
    ts = g.transmission_accuracy_max_arcmin / REF_TA_arcmin
    for pre in ("wg", "out"):
        for i in range(1, 5):
            p["transmission_error"][f"{pre}{i}_amp_rad"] = float(p["transmission_error"][f"{pre}{i}_amp_rad"]) * ts
    p["stiffness"].update(enabled=True, k1_Nm_per_rad=g.k1_Nm_per_rad, k2_Nm_per_rad=g.k2_Nm_per_rad,
                          k3_Nm_per_rad=g.k3_Nm_per_rad, t1_Nm=g.t1_Nm, t2_Nm=g.t2_Nm,
                          damping_Nms_per_rad=2.0 * ZETA_GEAR * math.sqrt(g.k1_Nm_per_rad * spec.load_inertia_kgm2))
    p["stiffness_cubic"]["enabled"] = False
    torque_s = g.t1_Nm / REF_T1_Nm * hysteresis_scale(g)    # hysteresis torque scale
    twist_s = (g.t1_Nm / g.k1_Nm_per_rad) / (REF_T1_Nm / REF_K1)
    hm = p["hysteresis_maxwell"]
    for i in range(1, 9):
        hm[f"e{i}_w_Nm"] = float(hm[f"e{i}_w_Nm"]) * torque_s
        hm[f"e{i}_k_Nm_per_rad"] = float(hm[f"e{i}_k_Nm_per_rad"]) * torque_s / twist_s
    hp = p["hysteresis_preisach"]
    hp["t_sat_Nm"] = float(hp["t_sat_Nm"]) * torque_s
    for k in ("u_max_rad", "r0_rad", "s_rad"):
        hp[k] = float(hp[k]) * twist_s
    fr = gear_friction(g)
    fm = p["friction_motor"]
    f_ref = float(fm["fs_pos_Nm"])
    sc = fr.starting_input_Nm / f_ref
    for k in ("fc_pos_Nm", "fc_neg_Nm", "fs_pos_Nm", "fs_neg_Nm", "viscous_Nms_per_rad", "sigma0_Nm_per_rad",
              "sigma1_Nms_per_rad"):
        fm[k] = float(fm[k]) * sc
    fl = p["friction_load"]
    sl = (g.size / REF_SIZE) ** 3
    for k in ("fc_pos_Nm", "fc_neg_Nm", "fs_pos_Nm", "fs_neg_Nm", "viscous_Nms_per_rad", "sigma0_Nm_per_rad",
              "sigma1_Nms_per_rad"):
        fl[k] = float(fl[k]) * sl
    p["load"]["jl_kgm2"] = spec.load_inertia_kgm2
    p["gravity"].update(enabled=spec.unbalance_Nm > 0, mgl_Nm=spec.unbalance_Nm)
    p["base"].update(enabled=spec.base_amplitude_deg > 0, amplitude_rad=spec.base_amplitude_deg * DEG,
                     frequency_Hz=spec.base_frequency_Hz)
    for sec, enc in (("encoder_motor", c.motor_encoder), ("encoder_load", c.output_encoder)):
        lsb_arcsec = 360.0 * 3600.0 / 2 ** int(enc.bits_per_rev or 0)
        p[sec].update(enabled=True, bits=int(enc.bits_per_rev or 0),
                      noise_counts=float(enc.noise_arcsec_rms or 0.0) / lsb_arcsec)
    gy = c.gyro
    p["gyro"].update(enabled=True, noise_rad_s_per_rtHz=float(gy.noise_density_deg_s_rtHz or 0.0) * DEG,
                     bandwidth_Hz=float(gy.bandwidth_Hz or 500.0),
                     bias_rad_s=float(gy.bias_instability_deg_h or 0.0) * DEG / 3600.0)
    p["current_sensor"]["noise_A"] = 5e-4 * m.peak_current_A
    p.setdefault("integrator", {})["substeps"] = 1
    return p


def flat(p: Mapping[str, Mapping[str, Any]]) -> Dict[str, Any]:
    """``{section: {key: v}}`` -> ``{"section.key": v}``."""
    return {f"{s}.{k}": v for s, t in p.items() for k, v in t.items()}


def _val(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    x = float(v)
    if not math.isfinite(x):
        raise ValueError(f"non-finite plant value {x!r}")
    return f"{x:.10g}"


def axis_toml(p: Mapping[str, Mapping[str, Any]], header: str = "") -> str:
    """TOML text of an axis (``section.key`` tables, SI units in the key names)."""
    lines = [f"# {ln}" if ln else "#" for ln in header.splitlines()] if header else []
    for sec, table in p.items():
        if lines:
            lines.append("")
        lines.append(f"[{sec}]")
        lines += [f"{k} = {_val(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def write_axis(c: Candidate, spec: Spec, path: "str | os.PathLike[str]") -> Path:
    """Write the candidate's axis TOML (usable by ``hdservo serve --axis`` and scenarios)."""
    head = (f"Axis of the design candidate {c.name}\n"
            f"Generated by `hdservo design` from {Path(spec.source).name or 'SPEC.toml'} ({spec.name}).\n"
            "Every key is 'section.key' of docs/plant.md, SI units in the key names; the values and their\n"
            "derivation rules are in host/hdservo/design/axis_builder.py and docs/design-flow.md.")
    return write_text_atomic(path, axis_toml(build_axis(c, spec), head))


__all__ = ["Candidate", "axis_toml", "build_axis", "flat", "gear_friction", "hysteresis_scale",
           "reference_params", "write_axis"]
