"""Plots of the discrepancy workflow (PNG, units on every axis).

* ``residual_time.png``      equation error before (baseline) and after (final model) vs time;
* ``residual_<effect>.png``  per named effect, the residual before/after that iteration against
  the coordinate that reveals it (velocity, motor/WG angle mod one revolution, twist, load angle,
  twist acceleration, torque rate) and the order spectrum for angle-periodic effects;
* ``gap.png``                RMS of the equation error after each iteration;
* ``spectrum.png``           amplitude spectral density of the residual before/after.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .closeloop import Closed
    from .workflow import Result

from ..fileio import save_figure_atomic
from ..plotting import pyplot
from .residuals import order_spectrum, spectrum

plt = pyplot()


def _save(fig: "plt.Figure", path: Path) -> None:
    try:
        save_figure_atomic(fig, path, dpi=110)
    finally:
        plt.close(fig)


def _coord(res: "Result", effect: str) -> tuple[np.ndarray, str, bool]:
    """Coordinate (over the used decimated samples) that reveals an effect, its label, periodic?"""
    d = res.state.design
    s = d.sig
    u = s.units
    take = (lambda x: x[:: s.q][: len(d.mask)][d.mask]) if s.q > 1 else (lambda x: x[d.mask])
    if effect in ("stribeck_friction", "asymmetric_friction"):
        return take(s.v_out), f"output velocity ({u['velocity']})", False
    if effect in ("transmission_error", "cogging_torque"):
        return np.mod(take(s.raw_th_m), 2 * np.pi), "motor (wave-generator) angle mod 2π (rad)", True
    if effect in ("nonlinear_stiffness", "hysteresis", "backlash"):
        return take(s.phi), "twist θm/N − θl (rad)", False
    if effect == "gravity_unbalance":
        th = s.th_l if s.th_l is not None else s.th_m / s.ratio
        return take(th), "load angle (rad)", False
    if effect == "unmodelled_compliance":
        return take(s.ddphi), "twist acceleration (rad/s²)", False
    if effect == "current_loop_lag":
        return take(np.gradient(s.tau, s.dt)), f"logged torque rate ({u['torque']}/s)", False
    return take(s.t), "time (s)", False


def _time(res: "Result") -> np.ndarray:
    """Time (s) of the used decimated samples."""
    d = res.state.design
    s = d.sig
    return (s.t[:: s.q][: len(d.mask)] if s.q > 1 else s.t)[d.mask]


def _plot_residual_time(res: "Result") -> "plt.Figure":
    """``residual_time.png``: equation error of the baseline and the final model against time."""
    tu = res.state.design.sig.units["torque"]
    t = _time(res)
    fig, ax = plt.subplots(len(res.base_fit.resid), 1, figsize=(9, 3 + 2 * len(res.base_fit.resid)), squeeze=False)
    for i, e in enumerate(res.base_fit.resid):
        a = ax[i, 0]
        a.plot(t, res.base_fit.resid[e], lw=0.6, label="baseline")
        a.plot(t, res.snapshots[-1].resid[e], lw=0.6, label="final model")
        a.set_xlabel("time (s)")
        a.set_ylabel(f"residual, eq. {e} ({tu})")
        a.legend(loc="upper right")
        a.grid(alpha=0.3)
    ax[0, 0].set_title("equation error of the measured motor torque")
    return fig


def _plot_iteration(res: "Result", k: int) -> "plt.Figure":
    """``residual_<k+1>_<effect>.png``: the residual before/after iteration ``k`` against the
    coordinate that reveals its effect, with the order spectrum for angle-periodic effects."""
    d = res.state.design
    s = d.sig
    tu = s.units["torque"]
    name = res.iterations[k]["named_effect"]
    x, label, periodic = _coord(res, name)
    before, after = res.snapshots[k], res.snapshots[k + 1]
    eqs = list(before.resid)
    ncol = 2 if periodic else 1
    fig, ax = plt.subplots(len(eqs), ncol, figsize=(6 * ncol, 3 + 2 * len(eqs)), squeeze=False)
    for i, e in enumerate(eqs):
        a = ax[i, 0]
        a.plot(x, before.resid[e], ".", ms=1.5, alpha=0.5, label=f"before (iteration {k})")
        a.plot(x, after.resid[e], ".", ms=1.5, alpha=0.5, label=f"after adding {name}")
        a.set_xlabel(label)
        a.set_ylabel(f"residual, eq. {e} ({tu})")
        a.legend(loc="upper right", markerscale=6)
        a.grid(alpha=0.3)
        if periodic:
            b = ax[i, 1]
            for fit, lab in ((before, "before"), (after, "after")):
                o, amp = order_spectrum(d, fit.resid[e], s.raw_th_m, 120)
                b.semilogy(o, np.maximum(amp, 1e-12), lw=0.8, label=lab)
            b.set_xlabel("order (cycles per motor revolution)")
            b.set_ylabel(f"amplitude ({tu})")
            b.legend()
            b.grid(alpha=0.3)
    ax[0, 0].set_title(f"iteration {k + 1}: {name}")
    return fig


def _plot_gap(res: "Result") -> "plt.Figure":
    """``gap.png``: RMS equation error (and simulation error) after each iteration."""
    s = res.state.design.sig
    fig, ax = plt.subplots(figsize=(6, 4))
    labels = ["baseline"] + [it["named_effect"] for it in res.iterations]
    ax.semilogy(range(len(res.rms_history)), res.rms_history, "o-")
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=20, fontsize=8)
    ax.set_xlabel("iteration (effect added)")
    ax.set_ylabel(f"RMS equation error ({s.units['torque']})")
    ax.set_title("gap between model and measurement")
    ax.grid(alpha=0.3)
    if res.sim_rms_history:
        ax2 = ax.twinx()
        ax2.semilogy(range(len(res.sim_rms_history)), res.sim_rms_history, "s--", color="C1")
        ax2.set_ylabel(f"RMS simulation error ({s.units['angle']} at the output)", color="C1")
    return fig


def _plot_simulation_time(res: "Result") -> "plt.Figure":
    """``simulation_time.png``: simulated minus measured angle of the baseline and the final model."""
    s = res.state.design.sig
    fig, ax = plt.subplots(figsize=(9, 4))
    base_lab = "baseline" if np.all(np.isfinite(res.sims[0])) else "baseline (gaps: not simulable, inertia <= 0)"
    for e, lab in ((res.sims[0], base_lab), (res.sims[-1], "final model")):
        ax.plot(np.arange(len(e)) * s.dt * max(s.q, 1), e, lw=0.6, label=lab)
    ax.set_xlabel("time (s; two-mass: motor side, then load side)")
    ax.set_ylabel(f"simulated - measured ({s.units['angle']} at the output)")
    ax.set_title("simulation error over 50 ms windows from the measured state")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    return fig


def _plot_spectrum(res: "Result") -> "plt.Figure":
    """``spectrum.png``: amplitude spectral density of the first equation's residual before/after."""
    s = res.state.design.sig
    tu = s.units["torque"]
    eq0 = next(iter(res.base_fit.resid))
    fig, ax = plt.subplots(figsize=(7, 4))
    fs = 1.0 / (s.dt * s.q)
    for fit, lab in ((res.base_fit, "baseline"), (res.snapshots[-1], "final model")):
        f, a = spectrum(fit.resid[eq0], fs)
        ax.loglog(f[1:], a[1:], lw=0.8, label=lab)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"residual ASD, eq. {eq0} ({tu}/√Hz)")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    return fig


def write_plots(res: "Result", out_dir: str | Path) -> list[Path]:
    """Write every plot of a result into ``out_dir`` (created); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = [("residual_time.png", lambda: _plot_residual_time(res))]
    figures += [(f"residual_{k + 1}_{it['named_effect']}.png", lambda k=k: _plot_iteration(res, k))
                for k, it in enumerate(res.iterations)]
    figures.append(("gap.png", lambda: _plot_gap(res)))
    if len(res.sims) >= 1:
        figures.append(("simulation_time.png", lambda: _plot_simulation_time(res)))
    figures.append(("spectrum.png", lambda: _plot_spectrum(res)))
    paths: list[Path] = []
    for name, draw in figures:
        fig = draw()
        fig.tight_layout()
        p = out / name
        _save(fig, p)
        paths.append(p)
    return paths


#: Length of the span the simulator overlay shows, s.
OVERLAY_SPAN_S = 0.5


def write_simulator_overlay(res: "Result", cl: "Closed", out_dir: str | Path) -> list[Path]:
    """``simulator_<k>_<effect>.png`` per kept named effect: the measured output angle and the
    C simulator's replay of the axis before and after the effect (top), and their errors
    (bottom), over the :data:`OVERLAY_SPAN_S` span where the effect acts and the replay
    changes most (a speed-banded effect: only rows inside its band count)."""
    from .simerr import region_mask
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    s = res.state.design.sig
    t = s.t
    meas = s.th_l if (s.kind == "two_mass" and s.th_l is not None) else s.th_m / s.ratio
    paths: list[Path] = []
    for k, (it, (rb, ra)) in enumerate(zip(cl.iterations, cl.pairs)):
        if rb is None or ra is None:
            continue
        sim_b = rb.load if s.kind == "two_mass" else rb.motor / s.ratio
        sim_a = ra.load if s.kind == "two_mass" else ra.motor / s.ratio
        gain = np.nan_to_num((sim_b - meas) ** 2 - (sim_a - meas) ** 2)
        # the workflow's record of this name (the kept names' order can differ from the
        # naming order when a name is judged again)
        wf = next((x for x in res.iterations if x["named_effect"] == it["named_effect"]), {})
        bands = (wf.get("region") or {}).get("speed_bands")
        if bands:
            m = region_mask(res.state.design, bands)
            idx = np.minimum((np.arange(len(t)) // max(1, s.q)), len(m) - 1)
            gain = gain * m[idx]
        w = max(2, int(OVERLAY_SPAN_S / s.dt))
        c = np.convolve(gain, np.ones(w), mode="valid") if len(gain) > w else gain
        a = int(np.argmax(c)) if len(gain) > w else 0
        sl = slice(a, min(len(t), a + w))
        fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        ax[0].plot(t[sl], meas[sl], "k", lw=1.2, label="measured")
        ax[0].plot(t[sl], sim_b[sl], "C3", lw=0.8, label="simulator before")
        ax[0].plot(t[sl], sim_a[sl], "C2", lw=0.8, label=f"simulator with {it['named_effect']}")
        ax[0].set_ylabel(f"output angle [{s.units['angle']}]")
        ax[0].legend(loc="best", fontsize=8)
        ax[0].set_title(f"C simulator replay, {cl.iterations[k]['horizon_s'] * 1000:g} ms windows from the "
                        f"measured state: RMS {rb.rms_rad:.3g} -> {ra.rms_rad:.3g} {s.units['angle']}", fontsize=9)
        ax[1].plot(t[sl], 1e6 * (sim_b[sl] - meas[sl]), "C3", lw=0.8, label="before - measured")
        ax[1].plot(t[sl], 1e6 * (sim_a[sl] - meas[sl]), "C2", lw=0.8, label="after - measured")
        ax[1].set_ylabel(f"error [µ{s.units['angle']}]")
        ax[1].set_xlabel("time [s]")
        ax[1].legend(loc="best", fontsize=8)
        p = out / f"simulator_{k + 1}_{it['named_effect']}.png"
        _save(fig, p)
        paths.append(p)
    return paths
