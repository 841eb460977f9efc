"""Studies of the FE flexspline model for ``make results`` (tests/results/50_flexspline_fe.py).

* :func:`closed_forms`: the FE in limiting cases with closed forms (thin tube in torsion,
  tube in bending, ring ovalisation) over the mesh levels;
* :func:`convergence`: a catalogue cup over the mesh levels (stiffness, modes, unknowns, time);
* :func:`sensitivity`: elasticities ``d ln y / d ln p`` of the flexspline stiffness, the first
  torsional mode (flexspline + the tooth-mesh/WG-bearing spring of the series rule, held
  fixed) and the first tilting mode, to wall thickness, diaphragm thickness, boss radius,
  cup length, diameter, rim width and rim thickening;
* :func:`sweep`: the same figures over a range of one parameter (plots);
* :func:`held_out`: the series rule's leave-one-size-out errors against the catalogue.

Every function takes its grid as arguments so a test can run it small.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, Callable, Dict, List, Optional, Sequence

import numpy as np

from . import fe_gear as fg
from . import flexspline_fe as fe
from . import structure as st

#: structural parameters of the sensitivity study: name -> (label, geometry change for a factor)
PARAMETERS: Dict[str, tuple] = {
    "wall": ("wall thickness t", lambda g, k: replace(g, wall_m=g.wall_m * k, bore_radius_m=g.bore_radius_m
                                                      + g.wall_m * (1 - k))),
    "diaphragm": ("diaphragm thickness h", lambda g, k: replace(g, diaphragm_m=g.diaphragm_m * k)),
    "boss": ("boss (hub) radius a", lambda g, k: replace(g, boss_radius_m=g.boss_radius_m * k)),
    "length": ("cup length L", lambda g, k: replace(g, length_m=g.length_m * k)),
    "diameter": ("diameter d (radii, same t)", lambda g, k: replace(
        g, bore_radius_m=(g.outer_radius_m) * k - g.wall_m, boss_radius_m=g.boss_radius_m * k)),
    "rim_width": ("face width b", lambda g, k: replace(g, rim_width_m=g.rim_width_m * k)),
    "rim_extra": ("rim thickening", lambda g, k: replace(g, rim_extra_m=g.rim_extra_m * k)),
}


def figures(g: fe.CupGeometry, load_inertia_kgm2: float, rim_spring: Optional[float], *,
            level: int, harmonics: int) -> Dict[str, float]:
    """Stiffness (two-zone), torsional mode (rim spring ``rim_spring``; None = clamped) and
    tilting mode (tilt inertia J_L/2) of one geometry."""
    cm = fe.CupModel(g, level)
    k = cm.torsion(harmonics)
    spring = None
    if rim_spring is not None:   # the two-zone contact compliance into the rigid-ring rim's spring
        spring = 1.0 / (1.0 / rim_spring + 1.0 / k["stiffness_Nm_per_rad"] - 1.0 / k["ring_stiffness_Nm_per_rad"])
    return {"stiffness_Nm_per_rad": k["stiffness_Nm_per_rad"],
            "torsional_Hz": cm.torsional_modes(load_inertia_kgm2, 1, spring)["frequencies_Hz"][0],
            "tilting_Hz": cm.tilting_modes(0.5 * load_inertia_kgm2)["frequencies_Hz"][0]}


def closed_forms(levels: Sequence[int] = (1, 2, 3), nu: float = 0.3) -> List[Dict[str, float]]:
    """FE vs closed forms: thin tube (t/r = 2 %, L = 10 r) in torsion (G J / L, J = 2 pi r³ t),
    in bending (E I / L, I = pi r³ t; nu = 0), and a free ring under q cos 2 theta
    (w = q R⁴ / 9 E I; nu = 0), per mesh level.  Errors relative, FE / closed form - 1."""
    e, rho, ri, t = 206e9, 7850.0, 0.03, 0.0006
    rm = ri + t / 2
    length = 10 * ri
    out = []
    for lv in levels:
        rec: Dict[str, float] = {"level": lv}
        for kind, n, nu_k in (("torsion", 0, nu), ("bending", 1, 0.0)):
            m = fe.section_mesh([(ri, ri + t, 0.0, length)], [(ri, ri + t, 1)], [(0.0, length, 40)], lv)
            mdl = fe.AxiModel(m, e, nu_k, rho)
            base = lambda x: x[1] < 1e-9                         # noqa: E731
            tip = lambda x, L=length: x[1] > L - 1e-9            # noqa: E731
            if n == 0:
                f = mdl.traction(0, 1, tip, 1.0 / (2 * math.pi * rm ** 2 * t))
                x = fe._solve(mdl.stiffness(0), f, mdl.dofs(base))
                ref = e / (2 * (1 + nu_k)) * 2 * math.pi * rm ** 3 * t / length
            else:
                i = math.pi * rm ** 3 * t
                f = mdl.traction(1, 2, tip, rm / i)
                x = fe._solve(mdl.stiffness(1), f, np.concatenate([mdl.dofs(base, c) for c in range(3)]))
                ref = e * i / length
            rec[f"{kind}_fe"], rec[f"{kind}_closed"] = 1.0 / float(f @ x), ref
            rec[f"{kind}_err"] = rec[f"{kind}_fe"] / ref - 1.0
        b = 0.006
        m = fe.section_mesh([(rm - t / 2, rm + t / 2, 0.0, b)], [(rm - t / 2, rm + t / 2, 1)], [(0.0, b, 4)], lv)
        mdl = fe.AxiModel(m, e, 0.0, rho)
        outer = lambda x: x[0] > rm + t / 2 - 1e-9               # noqa: E731
        x = fe.spsolve(mdl.stiffness(2).tocsc(), mdl.traction(2, 0, outer, 1.0))
        w = float(np.mean(x[mdl.dofs(outer, 0)]))
        q = b * (rm + t / 2) / rm
        ref = q * rm ** 4 / (9 * e * b * t ** 3 / 12)
        rec.update({"ring_fe": w, "ring_closed": ref, "ring_err": w / ref - 1.0})
        out.append(rec)
    return out


def convergence(s: st.Structure, load_inertia_kgm2: float, levels: Sequence[int] = (1, 2, 3),
                harmonics: int = fe.DEFAULT_HARMONICS) -> List[Dict[str, float]]:
    """Stiffness, torsional mode (rim clamped) and tilting mode of a catalogue cup per mesh level,
    with the unknowns per harmonic and the wall time of the whole evaluation (s)."""
    out = []
    for lv in levels:
        t0 = time.perf_counter()
        cm = fe.CupModel(fe.cup_geometry(s), lv)
        k = cm.torsion(harmonics, ellipse_m=s.module_m)
        tq = cm.torsional_modes(load_inertia_kgm2)["frequencies_Hz"][0]
        tl = cm.tilting_modes(0.5 * load_inertia_kgm2)["frequencies_Hz"][0]
        out.append({"level": lv, "dofs": cm.dof_count, "elements": int(cm.model.mesh.t.shape[1]),
                    "stiffness_Nm_per_rad": k["stiffness_Nm_per_rad"],
                    "uniform_stiffness_Nm_per_rad": k["uniform_stiffness_Nm_per_rad"],
                    "torsional_clamped_Hz": tq, "tilting_Hz": tl, "wg_force_N": k["wg_force_N"],
                    "seconds": time.perf_counter() - t0})
    return out


def sensitivity(s: st.Structure, load_inertia_kgm2: float, rim_spring: Optional[float],
                names: Sequence[str] = tuple(PARAMETERS), step: float = 0.05, level: int = fe.DEFAULT_LEVEL,
                harmonics: int = 16) -> Dict[str, Dict[str, float]]:
    """Elasticities d ln y / d ln p by central differences (factors 1 ± ``step``) for each
    parameter of :data:`PARAMETERS` in ``names``; y = stiffness, torsional mode, tilting mode."""
    g0 = fe.cup_geometry(s)
    out: Dict[str, Dict[str, float]] = {}
    for name in names:
        change: Callable = PARAMETERS[name][1]
        hi = figures(change(g0, 1 + step), load_inertia_kgm2, rim_spring, level=level, harmonics=harmonics)
        lo = figures(change(g0, 1 - step), load_inertia_kgm2, rim_spring, level=level, harmonics=harmonics)
        d = math.log((1 + step) / (1 - step))
        out[name] = {k: math.log(hi[k] / lo[k]) / d for k in hi}
        out[name]["label"] = PARAMETERS[name][0]
    return out


def sweep(s: st.Structure, load_inertia_kgm2: float, rim_spring: Optional[float], name: str,
          factors: Sequence[float], level: int = fe.DEFAULT_LEVEL, harmonics: int = 16) -> List[Dict[str, float]]:
    """Figures of :func:`figures` over ``factors`` of one parameter."""
    g0 = fe.cup_geometry(s)
    change = PARAMETERS[name][1]
    return [{"factor": float(k), **figures(change(g0, k), load_inertia_kgm2, rim_spring, level=level,
                                           harmonics=harmonics)} for k in factors]


def held_out(cases: Optional[Sequence[fg.Case]] = None) -> Dict[str, Any]:
    """Leave-one-size-out errors of the series rule (rows and a per-size / overall summary)."""
    rows = fg.cross_validate(cases)
    summ: Dict[str, Any] = {}
    for lv in fg.LEVELS:
        e = np.array([r[f"{lv}_err"] for r in rows])
        summ[lv] = {"max_abs": float(np.max(np.abs(e))), "rms": float(np.sqrt(np.mean(e ** 2))),
                    "per_size_max_abs": {int(sz): float(max(abs(r[f"{lv}_err"]) for r in rows if r["size"] == sz))
                                         for sz in sorted({r["size"] for r in rows})}}
    return {"rows": rows, "summary": summ}


def plot(doc: Dict[str, Any], out_dir: Any) -> List[str]:
    """Convergence, sensitivity bars and frequency-vs-parameter plots (PNG) into ``out_dir``."""
    from pathlib import Path

    from ..fileio import save_figure_atomic
    from ..plotting import pyplot
    plt = pyplot()
    out = Path(out_dir)
    files = []
    conv = doc["convergence"]
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.5))
    dofs = [c["dofs"] for c in conv]
    for a, key, lab in zip(ax, ("stiffness_Nm_per_rad", "torsional_clamped_Hz", "tilting_Hz"),
                           ("stiffness, N·m/rad", "torsional mode (rim clamped), Hz", "tilting mode, Hz")):
        a.semilogx(dofs, [c[key] for c in conv], "o-")
        a.set_xlabel("unknowns per harmonic")
        a.set_title(lab, fontsize=9)
        a.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"FE convergence, {doc['gear']}")
    fig.tight_layout()
    save_figure_atomic(fig, out / "flexspline_fe_convergence.png", dpi=110)
    plt.close(fig)
    files.append("flexspline_fe_convergence.png")
    sens = doc["sensitivity"]
    names = list(sens)
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.8), sharey=True)
    for a, key, lab in zip(ax, ("stiffness_Nm_per_rad", "torsional_Hz", "tilting_Hz"),
                           ("flexspline stiffness", "torsional mode (gear)", "tilting mode")):
        a.barh([sens[n]["label"] for n in names], [sens[n][key] for n in names])
        a.axvline(0, color="k", lw=0.8)
        a.set_title(f"d ln({lab}) / d ln(p)", fontsize=9)
        a.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    save_figure_atomic(fig, out / "flexspline_fe_sensitivity.png", dpi=110)
    plt.close(fig)
    files.append("flexspline_fe_sensitivity.png")
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
    for name, rows in doc["sweeps"].items():
        k = [r["factor"] for r in rows]
        ax[0].plot(k, [r["torsional_Hz"] for r in rows], "o-", label=PARAMETERS[name][0])
        ax[1].plot(k, [r["tilting_Hz"] for r in rows], "o-", label=PARAMETERS[name][0])
    ax[0].set_title("first torsional mode (gear), Hz", fontsize=9)
    ax[1].set_title("first tilting mode (flexspline alone), Hz", fontsize=9)
    for a in ax:
        a.set_xlabel("parameter / nominal")
        a.grid(True, alpha=0.3)
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    save_figure_atomic(fig, out / "flexspline_fe_modes.png", dpi=110)
    plt.close(fig)
    files.append("flexspline_fe_modes.png")
    return files
