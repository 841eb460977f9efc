"""Random plausible harmonic-drive axes over catalogue ranges (axes no rule was tuned on).

:func:`random_axes` draws axes from a fixed seed: a gear size and a ratio of the
CSF catalogue grid (sizes 14-40, ratios 30-160), then every plant key of
docs/plant.md scaled from the reference axis (``sim/axes/reference.toml``) by the
size laws of the catalogue, times a random spread:

===========================  ==============================================================
plant keys                   drawn as (s = size / 25, U uniform, LU log-uniform)
===========================  ==============================================================
gear.ratio                   catalogue ratio of the size (30, 50, 80, 100, 120, 160)
stiffness k1                 3.1e4 s^3 LU(0.7, 1.4) N.m/rad (x 0.6 at N = 30, as the catalogue)
stiffness k2, k3             k1 U(1.3, 1.7), k2 U(1.05, 1.2)
stiffness t1, t2             14 s^3 U(0.8, 1.2) N.m, t1 U(3.0, 3.6)
motor.jm_kgm2                8e-5 s^2 LU(0.5, 2) (rotor + wave generator)
load.jl_kgm2                 0.5 s^3 LU(0.25, 4)
motor.kt_Nm_per_A            0.1 s^1.5 LU(0.7, 1.5), raised until the peak output torque
                             N kt i_peak covers 1.3 t2 and 4x (breakaway + unbalance)
friction_motor fs            0.1 s^2 LU(0.4, 2.5) N.m; fc = fs U(0.6, 0.8); neg = pos U(0.9, 1)
friction_load fs             0.6 s^3 LU(0.4, 2.5) N.m; same shape
Stribeck velocity            output-referred LU(0.005, 0.05) rad/s, shared by both sides
                             (motor side x N); delta U(1.5, 2.5) for both
viscous                      reference x s^2 (motor), x s^3 (load), each LU(0.5, 2)
LuGre sigma0 / sigma1        reference presliding distance kept (sigma0 ~ fs); motor sigma1
                             for damping ratio 0.5 (2 zeta sqrt(sigma0 jm)), load sigma1 ~ fs
hysteresis (Maxwell,         torque x t1 / 14 U(0.7, 1.4), twist x (t1 / k1) / (14 / 3.1e4)
Preisach)
transmission_error amps      reference x LU(0.5, 2)
cogging amps                 reference x kt / 0.1
gravity.mgl_Nm               t1 U(0.03, 0.2)
stiffness damping            reference gear damping ratio, 2 zeta sqrt(k1 jl)
===========================  ==============================================================

Encoders, gyro, current sensor, current loop and base motion stay the reference's.
An axis is redrawn when it is outside what the baseline design rule (velocity PI at
25 Hz, docs/control.md) is meant for: the coupled resonance of k1 below
:data:`MIN_RESONANCE_HZ` or a load-to-motor inertia ratio J_L / (N^2 J_m) outside
:data:`LOAD_RATIO_RANGE` -- such an axis needs a different loop structure, not
different compensation.  Nothing here reads the reference axis' compensator results.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Mapping

import numpy as np

from . import resources

#: the seed of the unseen axes of ``make results`` (fixed: every run checks the same axes)
DEFAULT_SEED = 20261127
#: catalogue ratios per size (CSF series, harmonic-drive catalogue grid)
CATALOGUE: Dict[int, tuple[int, ...]] = {
    14: (30, 50, 80, 100),
    17: (30, 50, 80, 100, 120),
    20: (30, 50, 80, 100, 120, 160),
    25: (30, 50, 80, 100, 120, 160),
    32: (30, 50, 80, 100, 120, 160),
    40: (50, 80, 100, 120, 160),
}
#: reference gear (sim/axes/reference.toml): size, K1 (N.m/rad), T1 (N.m)
REF_SIZE, REF_K1, REF_T1 = 25, 3.1e4, 14.0
#: lowest coupled resonance with K1 the 25 Hz velocity loop is designed for, Hz (reference: 50.5 Hz)
MIN_RESONANCE_HZ = 40.0
#: load-to-reflected-motor inertia ratios the design rule is meant for (reference 0.63, csf17_50 1.33)
LOAD_RATIO_RANGE = (0.2, 5.0)
#: attempts before giving up on one axis
MAX_DRAWS = 200


@dataclass(frozen=True)
class GeneratedAxis:
    """One drawn axis.

    Attributes
    ----------
    name : str
        ``unseen_<index>_csf<size>_<ratio>``.
    size, ratio : int
        Catalogue gear size and ratio.
    params : dict
        ``{section: {key: value}}`` (SI units in the key names, docs/plant.md).
    """

    name: str
    size: int
    ratio: int
    params: Dict[str, Dict[str, Any]]

    def summary(self) -> Dict[str, float]:
        """Headline quantities: ratio, inertias (kg.m^2), K1 (N.m/rad), output-referred friction (N.m, rad/s), f_res (Hz)."""
        p = self.params
        n = p["gear"]["ratio"]
        m, ld = p["friction_motor"], p["friction_load"]
        j1, j2 = n * n * p["motor"]["jm_kgm2"], p["load"]["jl_kgm2"]
        return {"ratio": float(n), "j_total_kgm2": j1 + j2, "jl_over_j1": j2 / j1,
                "k1_Nm_per_rad": p["stiffness"]["k1_Nm_per_rad"],
                "fs_total_Nm": n * m["fs_pos_Nm"] + ld["fs_pos_Nm"],
                "fc_total_Nm": n * m["fc_pos_Nm"] + ld["fc_pos_Nm"],
                "vs_out_rad_s": ld["vs_rad_s"], "f_res_k1_Hz": resonance_hz(p),
                "peak_torque_Nm": n * p["motor"]["kt_Nm_per_A"] * p["current_loop"]["peak_A"]}


def reference_params() -> Dict[str, Dict[str, Any]]:
    """The reference axis file as ``{section: {key: value}}``."""
    import tomllib
    with open(resources.axis_file("reference"), "rb") as f:
        return tomllib.load(f)


def resonance_hz(p: Mapping[str, Mapping[str, Any]]) -> float:
    """Coupled (locked-rotor-free) resonance of the two-mass model with K1, Hz."""
    n = p["gear"]["ratio"]
    j1, j2 = n * n * p["motor"]["jm_kgm2"], p["load"]["jl_kgm2"]
    return math.sqrt(p["stiffness"]["k1_Nm_per_rad"] * (j1 + j2) / (j1 * j2)) / (2 * math.pi)


def _lu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _draw(rng: np.random.Generator, base: Mapping[str, Mapping[str, Any]]) -> tuple[int, int, Dict[str, Dict[str, Any]]]:
    """One draw (not yet checked against the design-rule limits)."""
    p = {sec: dict(t) for sec, t in base.items()}
    pairs = [(sz, n) for sz, ns in CATALOGUE.items() for n in ns]
    size, ratio = pairs[int(rng.integers(len(pairs)))]
    s = size / REF_SIZE
    u = rng.uniform
    k1 = REF_K1 * s ** 3 * _lu(rng, 0.7, 1.4) * (0.6 if ratio == 30 else 1.0)
    k2 = k1 * u(1.3, 1.7)
    k3 = k2 * u(1.05, 1.2)
    t1 = REF_T1 * s ** 3 * u(0.8, 1.2)
    t2 = t1 * u(3.0, 3.6)
    jm = 8e-5 * s ** 2 * _lu(rng, 0.5, 2.0)
    jl = 0.5 * s ** 3 * _lu(rng, 0.25, 4.0)
    ref_st = base["stiffness"]
    zeta = ref_st["damping_Nms_per_rad"] / (2 * math.sqrt(ref_st["k1_Nm_per_rad"] * base["load"]["jl_kgm2"]))
    p["gear"]["ratio"] = ratio
    p["stiffness"].update(k1_Nm_per_rad=k1, k2_Nm_per_rad=k2, k3_Nm_per_rad=k3, t1_Nm=t1, t2_Nm=t2,
                          damping_Nms_per_rad=2 * zeta * math.sqrt(k1 * jl))
    p["stiffness_cubic"].update(k1_Nm_per_rad=k1, k3_Nm_per_rad3=base["stiffness_cubic"]["k3_Nm_per_rad3"]
                                * (k1 / base["stiffness_cubic"]["k1_Nm_per_rad"]) ** 3 / (t1 / REF_T1) ** 2)
    p["load"]["jl_kgm2"] = jl
    # friction: both sides share the output-referred Stribeck velocity and the exponent
    vs_out = round(_lu(rng, 0.005, 0.05), 6)     # 6 decimals: N x vs_out stays exact in the axis file's 10 digits
    delta = u(1.5, 2.5)
    sides = {"friction_motor": (0.1 * s ** 2, base["friction_motor"]["viscous_Nms_per_rad"] * s ** 2, vs_out * ratio),
             "friction_load": (0.6 * s ** 3, base["friction_load"]["viscous_Nms_per_rad"] * s ** 3, vs_out)}
    for sec, (fs0, fv0, vs) in sides.items():
        b = base[sec]
        fs = fs0 * _lu(rng, 0.4, 2.5)
        fc = fs * u(0.6, 0.8)
        neg = u(0.9, 1.0)
        fsc = fs / b["fs_pos_Nm"]
        p[sec].update(fs_pos_Nm=fs, fs_neg_Nm=fs * neg, fc_pos_Nm=fc, fc_neg_Nm=fc * neg, vs_rad_s=vs, delta=delta,
                      viscous_Nms_per_rad=fv0 * _lu(rng, 0.5, 2.0), sigma0_Nm_per_rad=b["sigma0_Nm_per_rad"] * fsc)
        if sec == "friction_motor":
            p[sec]["sigma1_Nms_per_rad"] = 2 * 0.5 * math.sqrt(p[sec]["sigma0_Nm_per_rad"] * jm)
        else:
            p[sec]["sigma1_Nms_per_rad"] = b["sigma1_Nms_per_rad"] * fsc
    # hysteresis: torque and twist scales of the gear
    tq = t1 / REF_T1 * u(0.7, 1.4)
    tw = (t1 / k1) / (REF_T1 / REF_K1)
    mx = p["hysteresis_maxwell"]
    for i in range(1, 9):
        mx[f"e{i}_k_Nm_per_rad"] = base["hysteresis_maxwell"][f"e{i}_k_Nm_per_rad"] * tq / tw
        mx[f"e{i}_w_Nm"] = base["hysteresis_maxwell"][f"e{i}_w_Nm"] * tq
    pz, bz = p["hysteresis_preisach"], base["hysteresis_preisach"]
    pz.update(u_max_rad=bz["u_max_rad"] * tw, t_sat_Nm=bz["t_sat_Nm"] * tq, r0_rad=bz["r0_rad"] * tw,
              s_rad=bz["s_rad"] * tw)
    te = p["transmission_error"]
    for k in list(te):
        if k.endswith("_amp_rad"):
            te[k] = base["transmission_error"][k] * _lu(rng, 0.5, 2.0)
    # motor: Kt from the size, raised until the drive can move the axis and cycle the gear
    kt = 0.1 * s ** 1.5 * _lu(rng, 0.7, 1.5)
    mgl = t1 * u(0.03, 0.2)
    ipk = float(base["current_loop"]["peak_A"])
    fs_tot = ratio * p["friction_motor"]["fs_pos_Nm"] + p["friction_load"]["fs_pos_Nm"]
    kt = max(kt, 1.3 * t2 / (ratio * ipk), 4.0 * (fs_tot + mgl) / (ratio * ipk))
    p["motor"].update(jm_kgm2=jm, kt_Nm_per_A=kt)
    p["gravity"]["mgl_Nm"] = mgl
    cg = p["cogging"]
    for k in list(cg):
        if k.endswith("_amp_Nm"):
            cg[k] = base["cogging"][k] * kt / base["motor"]["kt_Nm_per_A"]
    return size, ratio, p


def plausible(p: Mapping[str, Mapping[str, Any]]) -> bool:
    """True when the axis is inside the design rule's range (resonance, inertia ratio)."""
    n = p["gear"]["ratio"]
    r = p["load"]["jl_kgm2"] / (n * n * p["motor"]["jm_kgm2"])
    return resonance_hz(p) >= MIN_RESONANCE_HZ and LOAD_RATIO_RANGE[0] <= r <= LOAD_RATIO_RANGE[1]


def random_axes(count: int, seed: int = DEFAULT_SEED) -> list[GeneratedAxis]:
    """``count`` plausible axes drawn from ``seed`` (the same axes for the same seed).

    Parameters
    ----------
    count : int
        Number of axes (>= 0).
    seed : int
        Seed of :func:`numpy.random.default_rng`.

    Returns
    -------
    list of GeneratedAxis

    Raises
    ------
    ValueError
        A negative count, or no plausible axis in :data:`MAX_DRAWS` draws.
    """
    if count < 0:
        raise ValueError(f"count {count}: expected >= 0")
    rng = np.random.default_rng(seed)
    base = reference_params()
    out = []
    for i in range(count):
        for _ in range(MAX_DRAWS):
            size, ratio, p = _draw(rng, base)
            if plausible(p):
                break
        else:
            raise ValueError(f"no plausible axis in {MAX_DRAWS} draws (seed {seed}, axis {i})")
        out.append(GeneratedAxis(f"unseen_{i}_csf{size}_{ratio}", size, ratio, p))
    return out


def axis_text(ax: GeneratedAxis, seed: int) -> str:
    """TOML text of a drawn axis (readable by ``hdservo-sim``, ``hdservo demo --axis``)."""
    from .design.axis_builder import axis_toml
    head = (f"Random plausible axis {ax.name} (CSF-{ax.size}-{ax.ratio} class), drawn by hdservo.axisgen "
            f"with seed {seed}.\nEvery key is 'section.key' of docs/plant.md, SI units in the key names; "
            "never used to choose a rule or a constant.")
    return axis_toml(ax.params, head)


def write_axes(directory: "str | os.PathLike[str]", count: int, seed: int = DEFAULT_SEED) -> list[Path]:
    """Write ``count`` drawn axes as ``DIRECTORY/<name>.toml`` (temporary file + rename); returns the paths."""
    from .design.axis_builder import write_text_atomic
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    return [write_text_atomic(d / f"{a.name}.toml", axis_text(a, seed)) for a in random_axes(count, seed)]


__all__ = ["CATALOGUE", "DEFAULT_SEED", "GeneratedAxis", "LOAD_RATIO_RANGE", "MIN_RESONANCE_HZ", "axis_text",
           "plausible", "random_axes", "reference_params", "resonance_hz", "write_axes"]
