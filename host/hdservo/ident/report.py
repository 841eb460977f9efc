"""Plots (PNG, units on every axis, residual panels) and the JSON report of an identification."""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..fileio import save_figure_atomic
from ..plotting import pyplot

ARCMIN = math.pi / 180 / 60


def _fig(nrows: int = 2):
    plt = pyplot()
    fig, ax = plt.subplots(nrows, 1, figsize=(7, 2.6 * nrows + 0.6), squeeze=False,
                           gridspec_kw={"height_ratios": [2] + [1] * (nrows - 1)})
    return plt, fig, ax[:, 0]


def _save(plt: Any, fig: Any, path: Path) -> str:
    fig.tight_layout()
    try:
        save_figure_atomic(fig, path, dpi=110)
    finally:
        plt.close(fig)
    return str(path)


def _plot_stribeck(r: dict[str, Any]) -> tuple[Any, Any]:
    """Friction against velocity: the Stribeck fit per direction, and its residual."""
    s, sb = r["sweep"], r["stribeck"]
    plt, fig, ax = _fig()
    for sgn, mk in ((1, "o"), (-1, "s")):
        m = np.sign(s.v_rad_s) == sgn
        ax[0].semilogx(np.abs(s.v_rad_s[m]), np.abs(s.torque_Nm[m]), mk, label=f"measured, {'+' if sgn > 0 else '-'} direction")
        vv = sgn * np.geomspace(np.abs(s.v_rad_s).min(), np.abs(s.v_rad_s).max(), 200)
        ax[0].semilogx(np.abs(vv), np.abs(sb(vv)), "-")
        ax[1].semilogx(np.abs(s.v_rad_s[m]), s.torque_Nm[m] - sb(s.v_rad_s[m]), mk)
    ax[0].set_ylabel("friction torque |F| (N·m, output)")
    ax[0].legend()
    ax[0].set_title("Stribeck fit")
    ax[1].set_ylabel("residual (N·m)")
    ax[1].set_xlabel("|velocity| (rad/s, output)")
    return plt, fig


def _plot_stiffness(r: dict[str, Any]) -> tuple[Any, Any]:
    """Locked-output torque against twist: the three-slope fit, residuals of 3-slope and cubic (+ MS)."""
    st = r["stiffness"]
    pd = st.plot_data
    plt, fig, ax = _fig(3)
    ax[0].plot(pd["phi_rad"] / ARCMIN, pd["T_Nm"], ".", ms=1, label="measured")
    g = np.linspace(pd["phi_rad"].min(), pd["phi_rad"].max(), 300)
    ax[0].plot(g / ARCMIN, st.three_slope(g) + pd["offset_Nm"], "-", label="three-slope (elastic part)")
    ax[0].set_ylabel("torque (N·m)")
    ax[0].legend()
    ax[0].set_title("Locked-output torque-twist: three-slope + Maxwell-slip")
    ax[1].plot(pd["phi_rad"] / ARCMIN, pd["resid_Nm"], ".", ms=1)
    ax[1].set_ylabel("residual, 3-slope+MS (N·m)")
    ax[2].plot(pd["phi_rad"] / ARCMIN, pd["cubic_resid_Nm"], ".", ms=1)
    ax[2].set_ylabel("residual, cubic+MS (N·m)")
    ax[2].set_xlabel("twist (arcmin)")
    return plt, fig


def _plot_te(r: dict[str, Any]) -> tuple[Any, Any]:
    """Transmission error against wave-generator angle: the harmonic fit, and its residual."""
    te = r["te"]
    pd = te.plot_data
    plt, fig, ax = _fig()
    ax[0].plot(pd["wg_angle_rad"], pd["te_rad"] / ARCMIN, ".", ms=1, label="measured (drift removed)")
    g = np.linspace(0, 2 * math.pi, 400)
    ax[0].plot(g, (te.evaluate(g) - 0) / ARCMIN, "-", label="harmonic fit")
    ax[0].set_ylabel("TE (arcmin, output)")
    ax[0].legend()
    ax[0].set_title("Transmission error vs wave-generator angle")
    ax[1].plot(pd["wg_angle_rad"], pd["residual_rad"] / ARCMIN, ".", ms=1)
    ax[1].set_ylabel("residual (arcmin)")
    ax[1].set_xlabel("wave-generator angle mod 2π (rad)")
    return plt, fig


def _plot_frf(r: dict[str, Any]) -> tuple[Any, Any]:
    """Motor torque to motor angle: measured FRF and two-mass fit (magnitude, phase, log error)."""
    plt, fig, ax = _fig(3)
    for f in r["frf"]:
        ax[0].loglog(f.f_Hz, np.abs(f.G), ".", ms=3, label=f"measured, {f.amplitude_rad_s:g} rad/s")
        ax[0].loglog(f.f_Hz, np.abs(f.model(f.f_Hz)), "-", label="two-mass fit")
        ax[1].semilogx(f.f_Hz, np.degrees(np.angle(f.G)), ".", ms=3)
        ax[1].semilogx(f.f_Hz, np.degrees(np.angle(f.model(f.f_Hz))), "-")
        ax[2].semilogx(f.f_Hz, np.abs(np.log(f.G / f.model(f.f_Hz))), ".", ms=3)
    ax[0].set_ylabel("|θ_m/τ| (rad/(N·m), output)")
    ax[0].legend(fontsize=7)
    ax[0].set_title("FRF motor torque -> motor angle")
    ax[1].set_ylabel("phase (deg)")
    ax[2].set_ylabel("|log error| (-)")
    ax[2].set_xlabel("frequency (Hz)")
    return plt, fig


def _plot_preisach(r: dict[str, Any]) -> tuple[Any, Any]:
    """Held-out minor loops against the Preisach prediction, and the error."""
    p = r["preisach"]
    pd = p["minor_loops"].plot_data
    plt, fig, ax = _fig()
    ax[0].plot(pd["T_Nm"], pd["phi_rad"] / ARCMIN, "-", lw=0.8, label="measured (held out)")
    ax[0].plot(pd["T_Nm"], pd["pred_rad"] / ARCMIN, "--", lw=0.8, label="Preisach prediction")
    ax[0].set_ylabel("twist (arcmin)")
    ax[0].legend()
    ax[0].set_title("Preisach (Everett from FORCs): minor loops not used in fitting")
    ax[1].plot(pd["T_Nm"], (pd["pred_rad"] - pd["phi_rad"]) / ARCMIN, ".", ms=1)
    ax[1].set_ylabel("error (arcmin)")
    ax[1].set_xlabel("torque (N·m)")
    return plt, fig


def _plot_presliding(r: dict[str, Any]) -> tuple[Any, Any]:
    """Input friction against motor angle: the LuGre presliding fit, and its residual."""
    pr = r["presliding"]
    pd = pr.plot_data
    plt, fig, ax = _fig()
    ax[0].plot(pd["theta_rad"] * 1e3, pd["f_Nm"], ".", ms=1, label="measured τ_m − T/N")
    ax[0].plot(pd["theta_rad"] * 1e3, pd["fit_Nm"], ".", ms=1, label="LuGre presliding fit")
    ax[0].set_ylabel("input friction (N·m, motor)")
    ax[0].legend()
    ax[1].plot(pd["theta_rad"] * 1e3, pd["f_Nm"] - pd["fit_Nm"], ".", ms=1)
    ax[1].set_ylabel("residual (N·m)")
    ax[1].set_xlabel("motor angle (mrad)")
    return plt, fig


#: (file name, whether the results hold what it needs, drawing) in the order of the report.
_PLOTS: tuple[tuple[str, Callable[[dict[str, Any]], bool], Callable[[dict[str, Any]], tuple[Any, Any]]], ...] = (
    ("friction_stribeck.png", lambda r: "stribeck" in r and "sweep" in r, _plot_stribeck),
    ("stiffness.png", lambda r: "stiffness" in r, _plot_stiffness),
    ("te.png", lambda r: "te" in r, _plot_te),
    ("frf.png", lambda r: bool(r.get("frf")), _plot_frf),
    ("preisach_minor_loops.png", lambda r: "preisach" in r, _plot_preisach),
    ("presliding.png", lambda r: "presliding" in r, _plot_presliding),
)


def plot_all(results: dict[str, Any], outdir: str | os.PathLike[str]) -> list[str]:
    """One PNG per fit with its residual; returns the file names."""
    d = Path(outdir)
    d.mkdir(parents=True, exist_ok=True)
    files = []
    for name, wanted, draw in _PLOTS:
        if wanted(results):
            plt, fig = draw(results)
            files.append(_save(plt, fig, d / name))
    return files
