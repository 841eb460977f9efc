"""Design report of the flow: JSON document, Markdown page and PNG plots (units on every axis)."""
from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

from ..fileio import files_into, json_ready, write_json_atomic, write_text_atomic
from ..plotting import pyplot
from ..report.builder import Document, readable
from . import influence
from .flow import Evaluated, FlowResult, headline, required_torques

DPI = 80


def _clean(x: Any) -> Any:
    """``x`` JSON-ready (:func:`hdservo.fileio.json_ready`) without the ``*_trace`` time series
    (they are drawn in the plots, not kept in the document)."""
    return json_ready(x, drop_suffix="_trace")


def candidate_doc(e: Evaluated) -> Dict[str, Any]:
    """JSON-able record of one candidate (parts, checks, figures, margins, gains)."""
    d: Dict[str, Any] = {"name": e.candidate.name, "parts": e.candidate.parts(), "cost_index": e.cost,
                         "feasible": e.feasible,
                         "checks": [{"name": c.name, "value": c.value, "limit": c.limit, "unit": c.unit,
                                     "margin": c.margin, "hard": c.hard, "ok": c.ok} for c in e.checks]}
    if e.sim:
        d["predicted"] = headline(e.sim)
        d["margins"] = e.margins
        d["figures"] = e.sim
        d["tuning"] = e.tuning
        d["controller"] = e.controller
        d["option"] = e.option
        d["options"] = e.options
        d["axis_file"] = Path(e.axis_path).name if e.axis_path else None
    return _clean(d)


def document(res: FlowResult) -> Dict[str, Any]:
    """The JSON report of a flow run."""
    spec = res.spec
    feas = [e for e in res.all_candidates if e.feasible]
    doc: Dict[str, Any] = {
        "format": "hdservo-design", "version": 1,
        "spec": spec.as_dict(),
        "enumerated": len(res.all_candidates), "feasible": len(feas),
        "rejected_by": _rejections(res.all_candidates),
        "feasible_list": [{"name": e.candidate.name, "cost_index": e.cost, "min_margin": e.min_margin}
                          for e in feas],
        "simulated": [candidate_doc(e) for e in res.simulated],
        "chosen": candidate_doc(res.chosen) if res.chosen else None,
    }
    if res.chosen:
        doc["chosen"]["required_torques_Nm"] = required_torques(spec, res.chosen.candidate)
        if res.chosen.margins:
            doc["chosen"]["influence"] = influence.requirement_influence(list(res.chosen.margins))
    return _clean(doc)


def _rejections(evals: List[Evaluated]) -> Dict[str, int]:
    out: Dict[str, int] = {}
    for e in evals:
        for c in e.checks:
            if c.hard and not c.ok:
                out[c.name] = out.get(c.name, 0) + 1
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


# ------------------------------------------------------------------ plots

def _plot_feasibility(res: FlowResult) -> Any:
    """``feasibility.png``: smallest feasibility margin against cost of every gear x motor pair."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    feas = [e for e in res.all_candidates if e.feasible]
    bad = [e for e in res.all_candidates if not e.feasible]
    ax.scatter([e.cost for e in bad], [max(e.min_margin, -1.0) * 100 for e in bad], s=8, c="0.7",
               label="rejected")
    ax.scatter([e.cost for e in feas], [min(e.min_margin, 3.0) * 100 for e in feas], s=10, c="C0", label="feasible")
    for i, e in enumerate(res.simulated):
        ax.scatter([e.cost], [min(e.min_margin, 3.0) * 100], s=60, marker="*", c="C3" if i == 0 else "C1")
        ax.annotate(e.candidate.gear.name + " / " + e.candidate.motor.name, (e.cost, min(e.min_margin, 3.0) * 100),
                    fontsize=7, xytext=(4, 4 + 8 * i), textcoords="offset points")
    ax.axhline(res.spec.options.margin * 100, color="k", ls=":", lw=0.8)
    ax.set_xlabel("cost index (gear + motor mass, sensor grade) [kg-equivalent]")
    ax.set_ylabel("smallest feasibility margin [%] (clipped)")
    ax.set_title("gear x motor pairs (star: simulated, red: chosen)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _plot_margins(res: FlowResult) -> Any:
    """``margins.png``: each simulated candidate's margin against each requirement."""
    plt = pyplot()
    keys = list(res.simulated[0].margins)
    fig, ax = plt.subplots(figsize=(7, 3.6))
    w = 0.8 / len(res.simulated)
    for i, e in enumerate(res.simulated):
        ax.bar(np.arange(len(keys)) + i * w, [max(e.margins[k], -1.0) * 100 for k in keys], width=w,
               label=e.candidate.gear.name + " / " + e.candidate.motor.name)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(np.arange(len(keys)) + 0.4 - w / 2)
    ax.set_xticklabels([k.replace("_", "\n") for k in keys], fontsize=7)
    ax.set_ylabel("margin vs requirement [%] (clipped at -100)")
    ax.set_title("simulated margins (>= 0: requirement met)", fontsize=9)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def _panel_min_rate(a: Any, f: Dict[str, Any]) -> None:
    """Window rate over commanded rate per rung of the chosen design's prediction."""
    for rate, w in f["min_rate"]["series"].items():
        if w:
            a.plot(np.arange(len(w)) + 1, w, "o-", ms=3, label=f"{rate} deg/s")
    a.axhspan(1 - f["min_rate"]["bound"], 1 + f["min_rate"]["bound"], color="0.9")
    a.set_xlabel("fixed-angle window [-]")
    a.set_ylabel("window rate / commanded rate [-]")
    a.set_title("minimum smooth rate (band: +-10 %)", fontsize=9)
    a.legend(fontsize=7)
    a.grid(True, alpha=0.3)


def _panel_positioning(a: Any, f: Dict[str, Any]) -> None:
    """Positional deviation per target and approach direction of the chosen design's prediction."""
    p = f["positioning"]
    tg = np.asarray(p["targets_deg"])
    for j, (u, dn) in enumerate(zip(p["up_arcsec"], p["down_arcsec"])):
        a.plot(tg, u, "^-", color="C0", ms=3, lw=0.5, label="approach +" if j == 0 else None)
        a.plot(tg, dn, "v-", color="C1", ms=3, lw=0.5, label="approach -" if j == 0 else None)
    a.set_xlabel("target [deg]")
    a.set_ylabel("positional deviation [arcsec]")
    a.set_title(f"positioning: A = {p['A_arcsec']:.3g}\", R = {p['R_arcsec']:.3g}\" (encoder accuracy "
                "not included)", fontsize=9)
    a.legend(fontsize=7)
    a.grid(True, alpha=0.3)


def _panel_stabilisation(a: Any, f: Dict[str, Any]) -> None:
    """Inertial pointing error over time in STAB mode, with an ideal reference and the encoder hold."""
    s = f["stabilisation"]
    for tag, lab in (("stab", "STAB mode"), ("inertial", "ideal inertial reference"), ("hold", "encoder hold (/100)")):
        tr = s.get(f"{tag}_trace")
        if tr:
            scale = 0.01 if tag == "hold" else 1.0
            a.plot(tr["t_s"], np.asarray(tr["angle_arcsec"]) * scale, lw=0.7,
                   label=f"{lab}: {s[f'{tag}_rms_arcsec']:.3g}\" RMS")
    a.set_xlabel("time [s]")
    a.set_ylabel("inertial pointing error [arcsec]")
    a.set_title("stabilisation, base rocking (gyro integrated)", fontsize=9)
    a.legend(fontsize=7)
    a.grid(True, alpha=0.3)


def _panel_bandwidth(a: Any, f: Dict[str, Any]) -> None:
    """Closed-loop position response magnitude against frequency, with the -3 dB line."""
    b = f["bandwidth"]
    a.semilogx(b["f_Hz"], b["magnitude_dB"], "o-", ms=3)
    a.axhline(-3, color="k", ls=":")
    a.set_xlabel("frequency [Hz]")
    a.set_ylabel("|theta_L / theta_ref| [dB]")
    a.set_title(f"position response, 60\" multisine: -3 dB at {_f(b['bandwidth_Hz'], 'Hz')}", fontsize=9)
    a.grid(True, which="both", alpha=0.3)


def _plot_chosen(res: FlowResult) -> Any:
    """``chosen_figures.png``: the chosen design's predicted min rate, positioning, stabilisation and bandwidth."""
    assert res.chosen is not None
    fig, axs = pyplot().subplots(2, 2, figsize=(9, 6.5))
    for a, panel in zip(axs.flat, (_panel_min_rate, _panel_positioning, _panel_stabilisation, _panel_bandwidth)):
        panel(a, res.chosen.sim)
    fig.suptitle(f"chosen: {res.chosen.candidate.name}", fontsize=9)
    return fig


def _plots(res: FlowResult, d: Path) -> List[str]:
    """Draw the report's plots into ``d``; returns their file names."""
    plt = pyplot()
    figures = [("feasibility.png", _plot_feasibility)]
    if res.simulated:
        figures.append(("margins.png", _plot_margins))
    if res.chosen and res.chosen.sim:
        figures.append(("chosen_figures.png", _plot_chosen))
    files: List[str] = []
    for name, draw in figures:
        fig = draw(res)
        fig.tight_layout()
        fig.savefig(d / name, dpi=DPI)
        plt.close(fig)
        files.append(name)
    return files


def _f(x: Any, unit: str = "", fmt: str = ".3g") -> str:
    if x is None:
        return "n/a"
    return f"{x:{fmt}} {unit}".strip()


# ------------------------------------------------------------------ markdown

REQ_ROWS = [
    ("min smooth rate", "min_smooth_rate_deg_s", "min_smooth_rate_deg_s", "deg/s", "<="),
    ("positioning accuracy A (incl. encoder)", "positioning_arcsec", "positioning_accuracy_with_encoder_arcsec",
     "arcsec", "<="),
    ("repeatability R", "repeatability_arcsec", "repeatability_arcsec", "arcsec", "<="),
    ("stabilisation (STAB mode, true inertial)", "stabilisation_arcsec_rms", "stabilisation_rms_arcsec",
     "arcsec RMS", "<="),
    ("peak output torque", "peak_torque_Nm", "peak_torque_Nm", "N·m", ">="),
    ("first resonance (locked motor)", "min_resonance_Hz", "resonance_Hz", "Hz", ">="),
]


def _fe_rows(r: Dict[str, Any]) -> List[str]:
    """Rows of the FE flexspline figures (docs/design-flow.md, "Flexspline finite-element model")."""
    fe = r.get("fe")
    if not fe:
        return []
    return [f"| FE flexspline (mesh level {fe['mesh_level']}): stiffness / share of catalogue K1 compliance | "
            f"{fe['flexspline_stiffness_Nm_per_rad']:.4g} N·m/rad / "
            f"{100 * fe['k1_catalogue_Nm_per_rad'] / fe['flexspline_stiffness_Nm_per_rad']:.0f} % |",
            f"| FE torsional mode (motor locked; the design figure is the lower of it and the two-mass) | "
            f"{fe['torsional_Hz']:.2f} Hz |",
            f"| FE tilting mode of the load on the flexspline alone (no output bearing) | {fe['tilting_Hz']:.1f} Hz |",
            f"| series rule K1 / K3 vs catalogue | {fe['k1_rule_Nm_per_rad']:.3g} / {fe['k3_rule_Nm_per_rad']:.3g} vs "
            f"{fe['k1_catalogue_Nm_per_rad']:.3g} / {fe['k3_catalogue_Nm_per_rad']:.3g} N·m/rad |"]


def _row(line: str) -> List[str]:
    """The cells of a Markdown table row ``| a | b |`` (no cell holds a ``|``)."""
    return [c.strip() for c in line.strip().strip("|").split(" | ")]


def _md_requirements(d: Document, spec: Any) -> None:
    d.heading("Requirements")
    d.table(["requirement", "value"], [[readable(k), f"{v:g}"] for k, v in spec.as_dict().items()
                                       if k not in ("options", "source", "name")])


def _md_feasibility(d: Document, doc: Dict[str, Any], plots: List[str]) -> None:
    d.heading(f"Feasibility: {doc['feasible']} of {doc['enumerated']} gear x motor pairs pass")
    if doc["rejected_by"]:
        d.table(["hard check", "pairs rejected by it"], [[k, str(v)] for k, v in doc["rejected_by"].items()])
    if "feasibility.png" in plots:
        d.figure("feasibility.png", "Smallest feasibility margin against the cost index of every gear x motor "
                 "pair (grey: rejected; stars: simulated, red: chosen; dotted: the required margin)")


def _md_candidates(d: Document, res: FlowResult, spec: Any, plots: List[str]) -> None:
    s = spec.as_dict()
    d.heading("Simulated candidates (ranked)")
    L: List[str] = []
    for i, e in enumerate(res.simulated):
        h = headline(e.sim)
        cells = []
        for r in REQ_ROWS:
            m = e.margins.get({"min_smooth_rate_deg_s": "min_smooth_rate",
                               "positioning_arcsec": "positioning_accuracy", "repeatability_arcsec": "repeatability",
                               "stabilisation_arcsec_rms": "stabilisation", "peak_torque_Nm": "peak_torque",
                               "min_resonance_Hz": "resonance"}[r[1]])
            mark = "" if m is None else (" ok" if m >= 0 else " **FAIL**")
            cells.append(f"{_f(h[r[2]])} ({_f(None if m is None else 100 * m, '%', '+.0f')}){mark}")
        L.append(f"| {i + 1} | {e.candidate.name} | {e.cost:.2f} | " + " | ".join(cells) + " |")
    d.table(["rank", "candidate", "cost index"] + [r[0] for r in REQ_ROWS],
            [["", "requirement", ""] + [f"{r[4]} {_f(s[r[1]])} {r[3]}" for r in REQ_ROWS]] + [_row(x) for x in L])
    d.para("Margins in brackets: relative to the requirement (min smooth rate: 1 - max(stability, accuracy)/0.1 "
           "at the required rate, -100 % when that rung goes back or stops).")
    if any(e.options for e in res.simulated):
        d.heading("Controller options per candidate", level=3)
        d.para("Every candidate is simulated with each controller option (`flow.controller_options`: the flow's own "
               "compensators and the demo's best combination read from `hdservo.compsetup`); it keeps the option "
               "with the better margins (all met first, then the larger smallest margin).")
        L = []
        for e in res.simulated:
            for name, o in e.options.items():
                m = o["margins"]
                k = min(m, key=lambda x: m[x])
                h = o["predicted"]
                extra = ", ".join(f"{a} = {b:g}" for a, b in o["option"].get("extra_gains", {}).items()) or "-"
                L.append(f"| {e.candidate.gear.name} | {name} | {', '.join(o['option']['compensators']) or '-'} | "
                         f"{extra} | {100 * m[k]:+.0f} % ({k}) | {_f(h['positioning_accuracy_arcsec'])} / "
                         f"{_f(h['repeatability_arcsec'])}\" | {_f(h['min_smooth_rate_deg_s'], 'deg/s')} | "
                         f"{_f(h['stabilisation_rms_arcsec'])}\" | {'**yes**' if name == e.option else ''} |")
        d.table(["candidate", "option", "compensators", "extra drive parameters", "smallest margin", "A / R",
                 "min rate", "stabilisation", "kept"], [_row(x) for x in L])
    if "margins.png" in plots:
        d.figure("margins.png", "Margin of each simulated candidate against each requirement, % (>= 0: met; "
                 "clipped at -100 %)")


def _md_chosen(d: Document, res: FlowResult, plots: List[str]) -> None:
    spec = res.spec
    ch = res.chosen
    assert ch is not None
    f = ch.sim
    t = ch.tuning
    d.heading("Chosen design")
    d.para(f"**{ch.candidate.name}** — axis file `{Path(ch.axis_path or '').name}` "
           "(serve it with `hdservo serve --axis` or `build/bin/hdservo-sim serve --axis`), drive parameters "
           "in the JSON report (`chosen.controller.gains`).")
    tq = required_torques(spec, ch.candidate)
    L = [
        f"| output inertia J_L + N² J_in | {tq['j_total_kgm2']:.3g} kg·m² |",
        f"| torque demand: acceleration / unbalance / friction / base | {tq['accel']:.3g} / "
        f"{spec.unbalance_Nm:.3g} / {tq['friction']:.3g} / {tq['base']:.3g} N·m |",
        f"| drive torque limit | {t['torque_limit_Nm']:.3g} N·m |",
        f"| resonance: locked motor / coupled (two-mass, K1) | {f['resonance']['locked_motor_Hz']:.1f} / "
        f"{f['resonance']['coupled_Hz']:.1f} Hz |",
        *_fe_rows(f["resonance"]),
        f"| velocity PI: kp, ki | {t['vel_kp_Nms_per_rad']:.4g} N·m·s/rad, {t['vel_ki_Nm_per_rad']:.4g} N·m/rad "
        f"(crossover {t['vel_crossover_hz']:.1f} Hz, PM {t['vel_phase_margin_deg']:.0f}°, "
        f"GM {t['vel_gain_margin_db']:.1f} dB) |",
        f"| position P: kp | {t['pos_kp_per_s']:.3g} 1/s (crossover {t['pos_crossover_hz']:.1f} Hz, PM "
        f"{t['pos_phase_margin_deg']:.0f}°, GM {t['pos_gain_margin_db']:.1f} dB, analytic -3 dB "
        f"{t['pos_bandwidth_hz']:.1f} Hz) |",
        f"| notch | {t['notch_hz']:.1f} Hz |",
        f"| controller option | {ch.option or 'flow'} ({t.get('option', {}).get('source', '')}) |",
        f"| compensators | {', '.join(t['compensators'])} (parameters: hdservo.compsetup"
        + (("; then " + ", ".join(f"{k} = {v:g}" for k, v in t['option']['extra_gains'].items()))
           if t.get("option", {}).get("extra_gains") else "") + ") |",
        f"| position P applied | {t.get('pos_kp_applied_per_s', t['pos_kp_per_s']):.3g} 1/s |",
        f"| simulated position bandwidth (60\" multisine) | {_f(f['bandwidth']['bandwidth_Hz'], 'Hz')} |",
        f"| stabilisation, drive holding its encoder position | {f['stabilisation']['hold_rms_arcsec']:.4g}\" RMS "
        f"(base {f['stabilisation']['base_rms_arcsec']:.4g}\" RMS) |",
        f"| stabilisation, STAB mode: true inertial / integrated gyro | "
        f"{f['stabilisation'].get('stab_true_rms_arcsec', float('nan')):.3g} / "
        f"{f['stabilisation'].get('stab_rms_arcsec', float('nan')):.3g}\" RMS |",
        f"| stabilisation, ideal inertial reference / gyro-noise term | {f['stabilisation']['inertial_rms_arcsec']:.3g}"
        f" / {f['stabilisation']['gyro_noise_rms_arcsec']:.3g}\" RMS |",
        f"| positioning A without / with encoder installed accuracy | {f['positioning']['A_arcsec']:.3g} / "
        f"{f['positioning']['A_with_encoder_arcsec']:.3g}\" (reversal B {f['positioning']['B_arcsec']:.3g}\") |",
    ]
    d.table(["quantity", "value"], [_row(x) for x in L])
    d.para("Feasibility checks of the chosen design:")
    d.table(["check", "value", "limit", "margin", "hard"],
            [[c.name, f"{c.value:.4g} {c.unit}", f"{c.limit:.4g} {c.unit}", f"{100 * c.margin:+.0f} %",
              "yes" if c.hard else "no"] for c in ch.checks])
    if "chosen_figures.png" in plots:
        d.figure("chosen_figures.png", "Predicted figures of the chosen design: window rates of the minimum smooth "
                 "rate ladder, positional deviation per target, stabilisation error over time and the closed-loop "
                 "position response")
    inf = influence.markdown_section(ch.margins)
    d.heading(inf[0].lstrip("# ").strip())
    d.para(inf[2])
    d.table(_row(inf[4]), [_row(x) for x in inf[6:] if x.startswith("|")])


CAVEATS = (
    "Stabilisation: the design figure is the drive's gyro stabilisation mode (STAB, CiA 402 mode -1, "
    "default stab_* gains) with the option's compensators, true inertial angle (line removed); holding the "
    "encoder position the payload follows the base.",
    "Positioning moves are the drive's own PTP trajectory; with `approach` the drive's one-direction final "
    "approach ends every move (appr_* parameters, table defaults).",
    "Min smooth rate: the prediction ramps through the simulator's set-point (exact rate); the test "
    "procedure uses the drive's profile generator, whose cruise rate is quantised 2-19 % slow at "
    "0.1-0.001 deg/s (docs/procedures.md): the measured rate accuracy is worse than predicted.",
    "Encoder installed accuracy is not modelled by the simulator; it is added to A (2 x +-accuracy).",
    "Catalogue motors and sensors are representative classes; friction and hysteresis come from the "
    "structure relations scaled from the reference axis (docs/design-structure.md).",
)


def markdown(res: FlowResult, doc: Dict[str, Any], plots: List[str]) -> str:
    """The Markdown report (:class:`hdservo.report.builder.Document`: contents, anchors, captions)."""
    spec = res.spec
    d = Document(f"Design report: {spec.name}")
    _md_requirements(d, spec)
    _md_feasibility(d, doc, plots)
    _md_candidates(d, res, spec, plots)
    if res.chosen:
        _md_chosen(d, res, plots)
    d.heading("Caveats")
    for c in CAVEATS:
        d.para(f"* {c}")
    return d.markdown(intro=[f"Generated by `hdservo design` from `{Path(spec.source).name}`. Figures are simulator "
                             "predictions (firmware + plant, every effect on) unless marked analytic. "
                             "Method: `docs/design-flow.md`."])


def write_report(res: FlowResult, json_path: "str | os.PathLike[str] | None",
                 report_dir: "str | os.PathLike[str] | None", axis_files: Dict[str, Path]) -> Dict[str, Any]:
    """Write the JSON report, the Markdown report with plots and the chosen axis TOML.

    Everything is first written to a temporary directory beside the targets
    and moved in place at the end, so a failure leaves no half-written output.

    Parameters
    ----------
    res : FlowResult
    json_path : path-like or None
    report_dir : path-like or None
        Receives ``report.md``, the PNG plots, ``axis_chosen.toml`` and the
        simulated candidates' axis files.
    axis_files : dict
        Candidate slug -> axis TOML written by the flow (copied into the report).

    Returns
    -------
    dict
        The JSON document.
    """
    doc = document(res)
    if report_dir is not None:
        with files_into(report_dir) as tmp:
            plots = _plots(res, tmp)
            write_text_atomic(tmp / "report.md", markdown(res, doc, plots))
            for slug, p in axis_files.items():
                shutil.copy(p, tmp / Path(p).name)
            if res.chosen and res.chosen.axis_path:
                shutil.copy(res.chosen.axis_path, tmp / "axis_chosen.toml")
                write_json_atomic(tmp / "drive_params.json", _clean(res.chosen.controller), indent=1)
    if json_path is not None:
        write_json_atomic(json_path, doc, indent=1)
    return doc


__all__ = ["candidate_doc", "document", "markdown", "write_report"]
