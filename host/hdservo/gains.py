"""Baseline cascade gains from the two-mass model of a harmonic-drive axis.

Model (output-referred, SI): motor side J1 = N^2 J_m, load J2 = J_L, gear
stiffness K1 (the soft first slope of the three-slope curve, where a pointing
axis lives), torque applied on the motor side.  Velocity feedback is colocated
(motor encoder / N), the position loop closes on the output encoder.

Design rules (docs/control.md):
* velocity PI: kp = J_tot * 2 pi f_v, ki = kp * 2 pi f_v / 4
* position P:  kp_pos = 2 pi f_p
* torque filters: notch at the coupled resonance, 2nd-order low-pass 1 kHz
* loop delay: 1.5 periods (sample + ZOH), Pade(2)
* gear damping: equivalent viscous, zeta 0.05 of the load-side mode

``python -m hdservo.gains [--json PATH]`` prints the gains, crossovers and
margins of the reference axis and the CSF-17-50 class second axis.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass

import control as ct
import numpy as np

from hdservo import filters
from hdservo.fileio import write_json_atomic

T_S = 1e-4


@dataclass(frozen=True)
class Axis:
    """Axis data, SI units."""

    name: str
    n: float
    j_m_kgm2: float
    j_l_kgm2: float
    k1_Nm_per_rad: float
    kt_Nm_per_A: float


REFERENCE = Axis("CSF-25-100 reference pitch axis", 100, 8e-5, 0.5, 3.1e4, 0.1)
SECOND = Axis("CSF-17-50 class axis", 50, 3e-5, 0.1, 0.81e4, 0.05)


@dataclass(frozen=True)
class Design:
    """Gains (parameter-table units) and achieved loop figures."""

    axis: str
    j_total_kgm2: float
    f_res_hz: float
    f_antires_hz: float
    vel_kp_Nms_per_rad: float
    vel_ki_Nm_per_rad: float
    pos_kp_per_s: float
    notch_hz: float
    vel_crossover_hz: float
    vel_phase_margin_deg: float
    vel_gain_margin_db: float
    pos_crossover_hz: float
    pos_phase_margin_deg: float
    pos_gain_margin_db: float
    pos_bandwidth_hz: float


def _tf_biquad(bq: filters.Biquad) -> ct.TransferFunction:
    b, a = bq.tf()
    return ct.tf(b, a, T_S)


def design(ax: Axis, f_v_hz: float = 25.0, f_p_hz: float = 6.0, notch_width_hz: float = 40.0,
           zeta_gear: float = 0.05) -> Design:
    """Gains and margins for ``ax`` (velocity-loop target f_v, position-loop f_p)."""
    j1 = ax.n ** 2 * ax.j_m_kgm2
    j2 = ax.j_l_kgm2
    k = ax.k1_Nm_per_rad
    jt = j1 + j2
    w_res = math.sqrt(k * jt / (j1 * j2))
    w_ar = math.sqrt(k / j2)
    s = ct.tf("s")
    # motor velocity / torque and load velocity / motor velocity
    c = 2 * zeta_gear * math.sqrt(k * j2)                     # gear damping (hysteresis, equivalent viscous)
    p_vm = (j2 * s ** 2 + c * s + k) / (s * (j1 * j2 * s ** 2 + c * jt * s + k * jt))
    g_lm = (c * s + k) / (j2 * s ** 2 + c * s + k)
    num, den = ct.pade(1.5 * T_S, 2)
    delay = ct.tf(num, den)
    kp = jt * 2 * math.pi * f_v_hz
    ki = kp * 2 * math.pi * f_v_hz / 4
    f_notch = w_res / (2 * math.pi)
    filt = ct.d2c(_tf_biquad(filters.notch(f_notch, notch_width_hz, -20)) * _tf_biquad(filters.lowpass(1000.0)),
                  method="bilinear") if hasattr(ct, "d2c") else None
    if filt is None:
        filt_c = _filters_continuous(f_notch, notch_width_hz)
    else:
        filt_c = filt
    c_v = kp + ki / s
    l_v = c_v * filt_c * delay * p_vm
    gm_v, pm_v, _, wc_v = ct.margin(l_v)
    t_v = ct.feedback(c_v * filt_c * delay, p_vm)          # torque ... closed loop velocity
    cl_v = ct.feedback(l_v, 1)
    kpp = 2 * math.pi * f_p_hz
    l_p = kpp * cl_v * g_lm / s
    gm_p, pm_p, _, wc_p = ct.margin(l_p)
    cl_p = ct.feedback(l_p, 1)
    bw_p = ct.bandwidth(cl_p)
    del t_v
    return Design(ax.name, jt, w_res / (2 * math.pi), w_ar / (2 * math.pi), kp, ki, kpp, f_notch,
                  wc_v / (2 * math.pi), float(pm_v), float(20 * np.log10(gm_v)) if np.isfinite(gm_v) else float("inf"),
                  wc_p / (2 * math.pi), float(pm_p), float(20 * np.log10(gm_p)) if np.isfinite(gm_p) else float("inf"),
                  float(bw_p) / (2 * math.pi))


def _filters_continuous(f_notch: float, width: float) -> ct.TransferFunction:
    s = ct.tf("s")
    w = 2 * math.pi * f_notch
    z2 = width / (2 * f_notch)
    z1 = z2 * 0.1
    wl = 2 * math.pi * 1000.0
    return (s ** 2 + 2 * z1 * w * s + w ** 2) / (s ** 2 + 2 * z2 * w * s + w ** 2) * wl ** 2 / (
        s ** 2 + 2 * 0.7071 * wl * s + wl ** 2)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="baseline cascade gains and margins")
    ap.add_argument("--json", help="write the designs as JSON to this path")
    a = ap.parse_args(argv)
    res = [design(REFERENCE), design(SECOND)]
    for d in res:
        print(f"{d.axis}: J_tot {d.j_total_kgm2:.3g} kg m^2, resonance {d.f_res_hz:.1f} Hz "
              f"(anti {d.f_antires_hz:.1f} Hz)")
        print(f"  vel kp {d.vel_kp_Nms_per_rad:.1f} N m s/rad, ki {d.vel_ki_Nm_per_rad:.0f} N m/rad: "
              f"crossover {d.vel_crossover_hz:.1f} Hz, PM {d.vel_phase_margin_deg:.1f} deg, "
              f"GM {d.vel_gain_margin_db:.1f} dB")
        print(f"  pos kp {d.pos_kp_per_s:.1f} 1/s: crossover {d.pos_crossover_hz:.1f} Hz, "
              f"PM {d.pos_phase_margin_deg:.1f} deg, GM {d.pos_gain_margin_db:.1f} dB, "
              f"closed-loop -3 dB {d.pos_bandwidth_hz:.1f} Hz")
    if a.json:
        write_json_atomic(a.json, [asdict(d) for d in res])
    return 0


if __name__ == "__main__":
    sys.exit(main())
