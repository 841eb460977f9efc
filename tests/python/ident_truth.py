"""Truth of the identification tests, computed from an axis file (tests only).

The identification code never sees these numbers.  Formulas follow
docs/plant.md (three-slope spring, Maxwell-slip elements, the plant's
Preisach Everett table: 32 x 32 midpoint rule, bilinear interpolation).
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

ROOT = Path(__file__).resolve().parents[2]
AXES = {"reference": ROOT / "sim" / "axes" / "reference.toml", "csf17_50": ROOT / "sim" / "axes" / "csf17_50.toml"}
#: Stiffness-cycle amplitude per axis (catalogue: >= 1.3 T2 of the size), N.m.
TORQUE_MAX = {"reference": 67.0, "csf17_50": 24.0}


def axis(name: str) -> dict:
    with open(AXES[name], "rb") as f:
        return tomllib.load(f)


def friction_total(a: dict) -> dict[str, float]:
    """Output-referred total friction N F_m(N v) + F_l(v) (both sides share vs at the output)."""
    N = a["gear"]["ratio"]
    m, l = a["friction_motor"], a["friction_load"]
    assert abs(m["vs_rad_s"] / N - l["vs_rad_s"]) < 1e-12, "test assumes equal output-referred vs"
    return {"fs_pos_Nm": N * m["fs_pos_Nm"] + l["fs_pos_Nm"], "fs_neg_Nm": N * m["fs_neg_Nm"] + l["fs_neg_Nm"],
            "fc_pos_Nm": N * m["fc_pos_Nm"] + l["fc_pos_Nm"], "fc_neg_Nm": N * m["fc_neg_Nm"] + l["fc_neg_Nm"],
            "vs_rad_s": l["vs_rad_s"], "viscous_Nms_per_rad": N * N * m["viscous_Nms_per_rad"]
            + l["viscous_Nms_per_rad"]}


def three_slope(a: dict, phi: float) -> float:
    s = a["stiffness"]
    k1, k2, k3, t1, t2 = s["k1_Nm_per_rad"], s["k2_Nm_per_rad"], s["k3_Nm_per_rad"], s["t1_Nm"], s["t2_Nm"]
    p1 = t1 / k1
    p2 = p1 + (t2 - t1) / k2
    sat = lambda x, d: max(-d, min(d, x))  # noqa: E731
    return k3 * phi + (k1 - k2) * sat(phi, p1) + (k2 - k3) * sat(phi, p2)


class PlantEverett:
    """The plant's Everett table (hd_plant_preisach.c) in N.m."""

    L = 32

    def __init__(self, h: dict) -> None:
        self.u = h["u_max_rad"]
        L, W = self.L, self.L + 1
        du = 2 * self.u / L
        r0, s = h["r0_rad"], h["s_rad"]
        dens = lambda a, b: math.exp(-0.5 * (a - b) / r0) * math.exp(-(0.5 * (a + b)) ** 2 / (2 * s * s))  # noqa
        E = np.zeros((W, W))
        for j in range(L):
            acc = 0.0
            for ai in range(j, L):
                ua = -self.u + ai * du
                row = sum(dens(ua + 0.5 * du, -self.u + b * du + 0.5 * du) * du * du for b in range(j, ai))
                row += dens(ua + 2 * du / 3, ua + du / 3) * 0.5 * du * du
                acc += row
                E[ai + 1, j] = acc
        E *= h["t_sat_Nm"] / E[L, 0]
        self.E, self.du = E, du

    def __call__(self, alpha: float, beta: float) -> float:
        if alpha <= beta:
            return 0.0
        L, E = self.L, self.E
        xa = min(max((alpha + self.u) / self.du, 0.0), L)
        xb = min(max((beta + self.u) / self.du, 0.0), L)
        ia, ib = min(int(xa), L - 1), min(int(xb), L - 1)
        fa, fb = xa - ia, xb - ib
        if ia < ib:
            return 0.0
        if ia == ib:
            return E[ia + 1, ia] * (fa - fb) if fa > fb else 0.0
        return ((1 - fa) * (1 - fb) * E[ia, ib] + fa * (1 - fb) * E[ia + 1, ib] + (1 - fa) * fb * E[ia, ib + 1]
                + fa * fb * E[ia + 1, ib + 1])


def hysteresis_loss(a: dict, t_max: float, maxwell: bool = True, preisach: bool = True) -> float:
    """Catalogue hysteresis loss (rad) of the +-t_max cycle: 2 x twist at T = 0 on the descending branch."""
    hm = a["hysteresis_maxwell"]
    els = [(hm[f"e{i}_k_Nm_per_rad"], hm[f"e{i}_w_Nm"]) for i in range(1, hm["n_elements"] + 1)] \
        if maxwell and hm["enabled"] else []
    hp = a["hysteresis_preisach"]
    pz = PlantEverett(hp) if preisach and hp["enabled"] else None
    wsum = sum(w for _, w in els)
    top = brentq(lambda p: three_slope(a, p) + wsum - t_max, 0.0, 1.0)   # Preisach closed above u_max

    def t_desc(p: float) -> float:
        t = three_slope(a, p) + sum(max(-w, w - k * (top - p)) for k, w in els)
        if pz is not None:
            # plant: T_h = P_mean(u) - P[u], P_mean(u) = E(u, -M) - E(M, u); descending
            # branch from positive saturation P = t_sat - 2 E(M, u)
            u = max(-pz.u, min(pz.u, p))
            t += pz(u, -pz.u) - pz(pz.u, u) - (hp["t_sat_Nm"] - 2.0 * pz(pz.u, u))
        return t

    pb = brentq(t_desc, -top, top)
    return 2.0 * pb


def frf_truth(a: dict) -> tuple[float, float]:
    """(anti-resonance, resonance) in Hz of the two-mass model with K1."""
    N = a["gear"]["ratio"]
    k = a["stiffness"]["k1_Nm_per_rad"]
    jl, jm = a["load"]["jl_kgm2"], a["motor"]["jm_kgm2"] * N * N
    return math.sqrt(k / jl) / (2 * math.pi), math.sqrt(k * (1 / jl + 1 / jm)) / (2 * math.pi)


def preisach_small_signal_stiffness(a: dict, u0: float = 0.0, amp: float = 1e-7) -> float:
    """Incremental stiffness (N.m/rad) of the plant's Preisach torque P_mean(u) - P[u] for a small
    oscillation +-amp around the twist u0 (the plant's Everett table and interpolation).

    After a reversal P changes by 2 E(u0 + amp, u0 - amp); P_mean is a function of u alone.
    """
    hp = a["hysteresis_preisach"]
    if not hp["enabled"]:
        return 0.0
    pz = PlantEverett(hp)
    m = pz.u

    def p_mean(u: float) -> float:
        u = max(-m, min(m, u))
        return pz(u, -m) - pz(m, u)

    return (p_mean(u0 + amp) - p_mean(u0 - amp) - 2.0 * pz(u0 + amp, u0 - amp)) / (2.0 * amp)


def small_signal_stiffness(a: dict, u0: float = 0.0) -> float:
    """Linearised gear stiffness (N.m/rad) at the twist u0 with every hysteresis element sticking:
    the spring's local slope + every Maxwell-slip element's k + the Preisach small-signal slope.

    This is the stiffness an FRF sees when its twist oscillation stays well inside the smallest
    element's slip travel 2 w/k (reference: 2e-4 rad) and no reversal crosses the Preisach cells.
    """
    s = a["stiffness"]
    h = 1e-9
    k = (three_slope(a, u0 + h) - three_slope(a, u0 - h)) / (2 * h)
    hm = a["hysteresis_maxwell"]
    if hm["enabled"]:
        k += sum(hm[f"e{i}_k_Nm_per_rad"] for i in range(1, hm["n_elements"] + 1))
    assert s["enabled"]
    return k + preisach_small_signal_stiffness(a, u0)


def frf_small_signal_truth(a: dict) -> tuple[float, float]:
    """(anti-resonance, resonance) in Hz of the two-mass model with the linearised stiffness at
    zero twist (:func:`small_signal_stiffness`).  The FRF's operating twist (load friction at the
    bias speed + gravity, <= 3 N.m / 6e4 N.m/rad = 5e-5 rad) moves it by < 0.5 %."""
    N = a["gear"]["ratio"]
    k = small_signal_stiffness(a, 0.0)
    jl, jm = a["load"]["jl_kgm2"], a["motor"]["jm_kgm2"] * N * N
    return math.sqrt(k / jl) / (2 * math.pi), math.sqrt(k * (1 / jl + 1 / jm)) / (2 * math.pi)
