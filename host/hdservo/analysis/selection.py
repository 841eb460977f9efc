"""Selection rules from measurements: Maxwell-slip vs Preisach, and which compensator for which need.

Two measured tables and the rules stated on them:

* :func:`hysteresis_table` -- the torque -> twist hysteresis of the locked-output gear of the
  simulated C plant (three-slope spring, Maxwell-slip elements *and* a Preisach density, noise,
  encoder quantisation, TE: more physics than either model) is identified with the project's
  own code, once as a Maxwell-slip model (:func:`hdservo.ident.stiffness.fit_stiffness` on
  +-A torque cycles) and once as a Preisach Everett table
  (:func:`hdservo.ident.hysteresis.everett_from_forcs` on reversal curves of the same range).
  Both then predict the twist of held-out runs of the same plant (another noise seed): the
  major loop +-A and minor loops of several widths about a bias.  Per amplitude the row holds
  the rms twist errors (arcsec), the identification effort (nominal experiment time, parameter
  count), the memory of the firmware image (bytes) and the Cortex-M4 cost per step (from
  ``build/bench/cm4_cost.json`` when ``make bench`` wrote it).
* :func:`needs_table` -- one row per need (pointing accuracy, low-speed smoothness,
  stabilisation, tracking, parameter drift) from an ablation document
  (:func:`hdservo.compare.ablation_doc` format, ``build/demo/ablation.json``): the single
  compensator with the largest gain on the need's figure, its gain (fair PID value / value),
  its CPU cost and the identification experiments it needs.

:data:`RULES` are functions of these tables; each returns a :class:`Rule` with ``holds`` and
the numbers behind it, so a test can recompute the tables and fail when a rule stops holding.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

#: rad -> arcsec
ARCSEC_PER_RAD = 180.0 / math.pi * 3600.0
#: Firmware words per Maxwell-slip element: stiffness k_i, slip limit d_i and the state s_i
#: (docs/compensators.md, section 3), 4 bytes each.
MAXWELL_BYTES_PER_ELEMENT = 3 * 4
#: Kernel names of the M4 cost bench (tests/golden/gv_comp.c) per model; a tuple is summed.  The
#: online-identified Stribeck feed-forward is the Stribeck step plus one estimator step with its bin
#: update (``fric_est_legs``; the estimator runs every ``fe_decim`` periods, so this is its worst period).
COST_KERNEL: dict[str, str | tuple[str, ...]] = {
    "maxwell": "comp_maxwell_step_n8", "preisach": "preisach_online_L32", "stribeck": "comp_stribeck_step",
    "lugre": "comp_lugre_step", "te": "comp_te_step_h4", "backstep": "comp_backstep_step",
    "stribeck_online": ("comp_stribeck_step", "fric_est_legs")}
#: Identification experiments each compensator needs (hdservo.ident.pipeline).
IDENT_EXPERIMENTS = {"stribeck": ["gravity_sine", "friction_sweep"],
                     "lugre": ["gravity_sine", "friction_sweep", "presliding_steps"],
                     "maxwell": ["locked_cycle"], "preisach": ["locked_cycle", "forc", "minor_loops"],
                     "te": ["te_rotation"], "backstep": ["gravity_sine", "friction_sweep", "frf"],
                     "compliance": ["locked_cycle"], "stribeck_online": []}
#: Controllers of the drift study (tests/results/58_drift_monte_carlo.py) -> compensator of the needs
#: table: the fixed-model Stribeck feed-forward, the same fed by the drive's online estimator
#: (identified during normal motion: no experiment), adaptive backstepping.
DRIFT_COMPENSATOR = {"fixed": "stribeck", "online": "stribeck_online", "backstep": "backstep"}
#: Needs -> (ablation figure, what it measures).  Every figure is "lower is better" except
#: those in :data:`HIGHER_IS_BETTER`.
NEEDS = {"pointing accuracy": "positioning_accuracy_arcsec",
         "low-speed smoothness": "tracking_peak_0p01_arcsec",
         "stabilisation": "stabilisation_rms_arcsec",
         "tracking": "tracking_rms_0p1_arcsec",
         "parameter drift": "drift"}
HIGHER_IS_BETTER = {"bandwidth_hz"}


# ----------------------------------------------------------------- hysteresis: Maxwell vs Preisach


@dataclass
class HysteresisRow:
    """One load amplitude of :func:`hysteresis_table` (twist errors in arcsec, rms, mean removed)."""

    axis: str
    amplitude_frac: float
    amplitude_Nm: float
    major_err_arcsec: dict[str, float]
    minor_err_arcsec: dict[str, dict[str, float]]
    loop_width_arcsec: float | None
    experiment_s: dict[str, float]
    parameters: dict[str, int]
    memory_bytes: dict[str, int]
    note: str = ""

    def minor_mean(self, model: str) -> float:
        """Mean over the loop widths of the minor-loop rms error of ``model`` (arcsec)."""
        v = list(self.minor_err_arcsec[model].values())
        return float(np.mean(v)) if v else math.nan

    def to_dict(self) -> dict[str, Any]:
        return {"axis": self.axis, "amplitude_frac": self.amplitude_frac, "amplitude_Nm": self.amplitude_Nm,
                "major_err_arcsec": self.major_err_arcsec, "minor_err_arcsec": self.minor_err_arcsec,
                "loop_width_arcsec": self.loop_width_arcsec, "experiment_s": self.experiment_s,
                "parameters": self.parameters, "memory_bytes": self.memory_bytes, "note": self.note}


def _measured(rows: Sequence["HysteresisRow"]) -> list["HysteresisRow"]:
    return [r for r in rows if not r.note]


@dataclass
class LockedPoints:
    """Locked-output torque run through given turning points (held-out validation loops)."""

    points_Nm: list[float]
    rate_Nm_s: float
    kind: str = "minor_loops"

    def plan(self, ratio: float) -> list[dict[str, Any]]:
        return [{"mode": "locked", "turning_points_Nm": list(self.points_Nm), "rate_Nm_s": self.rate_Nm_s}]


def _time_s(points: Sequence[float], rate_Nm_s: float, start: float = 0.0) -> float:
    """Nominal duration of a triangle torque profile through ``points`` (s)."""
    p = [start] + list(points)
    return float(sum(abs(b - a) for a, b in zip(p[:-1], p[1:])) / rate_Nm_s)


def rated_torque_Nm(axis: str | Path) -> float:
    """Rated torque of an axis: its spring's T2 (N.m), the end of the catalogue's second slope.

    Parameters
    ----------
    axis : str or Path
        "reference" or an axis TOML file.
    """
    from .. import sim
    return float(sim.axis_param("stiffness.t2_Nm", axis))


def maxwell_twist(st: Any, T: np.ndarray) -> np.ndarray:
    """Twist (rad) the identified Maxwell-slip model predicts for a torque history (N.m).

    The model is torque = three-slope spring(phi) + sum_j k_j s_j(phi) with stop operators s_j
    (relaxed at the start); it is monotone in phi for frozen element anchors, so each sample is
    solved by bisection and the anchors are then dragged as in
    :func:`hdservo.ident.hysteresis.stop_operators`.
    """
    k = np.asarray(st.maxwell.k_Nm_per_rad, dtype=float)
    d = np.asarray(st.maxwell.thresholds_rad, dtype=float)
    kmin = min(st.k1_Nm_per_rad, st.k2_Nm_per_rad, st.k3_Nm_per_rad)
    span = float(np.max(np.abs(T))) / max(kmin, 1.0) * 2.0 + 1e-6
    xi = np.zeros_like(k)
    out = np.empty(len(T))

    def torque(p: float) -> float:
        return float(st.three_slope(np.array([p]))[0] + np.sum(k * np.clip(p - xi, -d, d)))

    for i, t in enumerate(np.asarray(T, dtype=float)):
        lo, hi = -span, span
        for _ in range(48):
            mid = 0.5 * (lo + hi)
            if torque(mid) < t:
                lo = mid
            else:
                hi = mid
        p = 0.5 * (lo + hi)
        e = p - xi
        xi = np.where(e > d, p - d, np.where(e < -d, p + d, xi))
        out[i] = p
    return out


def _rms_centred(e: np.ndarray) -> float:
    e = e - np.mean(e)
    return float(np.sqrt(np.mean(e ** 2)))


def hysteresis_table(axis: str | Path = "reference", amplitudes: Sequence[float] = (0.1, 0.3, 1.0),
                     widths: Sequence[float] = (0.1, 0.3), levels: int = 16, seed: int = 11,
                     rate_per_s: float = 2.0, rated_Nm: float | None = None) -> list[HysteresisRow]:
    """Maxwell-slip vs Preisach on the simulated locked-output gear, one row per load amplitude.

    Parameters
    ----------
    axis : str or Path
        Simulated axis ("reference" or an axis TOML file).
    amplitudes : sequence of float
        Load amplitudes A as fractions of the rated torque (:func:`rated_torque_Nm`).
    widths : sequence of float
        Minor-loop widths as fractions of 2A: loops of that peak-to-peak torque about a bias of
        +A/3, reached from the major loop's bottom.
    levels : int
        Preisach table levels L (the grid spans +-A).
    seed : int
        Noise seed of the identification runs; the held-out runs use ``seed + 100``.
    rate_per_s : float
        Torque rate of every locked run in amplitudes per second (the rate is ``rate_per_s * A``
        N.m/s, so every amplitude has the same number of samples per loop).
    rated_Nm : float, optional
        Rated torque (N.m); default :func:`rated_torque_Nm` of the axis.

    Returns
    -------
    list of HysteresisRow
    """
    from ..ident import experiments as ex
    from ..ident import hysteresis as hy
    from ..ident import stiffness as stf
    from ..errors import UserError

    rated = rated_Nm if rated_Nm is not None else rated_torque_Nm(axis)
    rows = []
    keep = []
    for frac in amplitudes:
        A = float(frac) * rated
        rate_Nm_s = rate_per_s * A
        # fresh runners per amplitude: a runner calibrates the rig's input friction on its first
        # locked run at that run's amplitude, so every row is measured the same way whatever the grid
        # (kept alive: the calibration is keyed by the runner's id)
        fit_run = ex.SimRunner(axis=str(axis), seed=seed)
        val_run = ex.SimRunner(axis=str(axis), seed=seed + 100)
        keep += [fit_run, val_run]
        # Maxwell-slip: the catalogue +-A cycles and the +-4 % rated lost-motion cycles
        lc = ex.LockedCycle(torque_max_Nm=A, cycles=2, rate_Nm_s=rate_Nm_s)
        dl = fit_run.run(lc)
        try:
            st = stf.fit_stiffness(dl, None)
        except UserError as e:
            # the motor-side friction of the rig swallows a small commanded amplitude
            t = dl.segment(0)["load_torque_Nm"]
            rows.append(HysteresisRow(axis=str(axis), amplitude_frac=float(frac), amplitude_Nm=A,
                                      major_err_arcsec={}, minor_err_arcsec={"maxwell": {}, "preisach": {}},
                                      loop_width_arcsec=None, experiment_s={}, parameters={}, memory_bytes={},
                                      note=f"not measured: the locked rig reaches {float(np.min(t)):.2f} .. "
                                           f"{float(np.max(t)):.2f} N.m ({e})"))
            continue
        # Preisach: first-order reversal curves over the same +-A
        u0, step = hy.grid_for(A, levels)
        fs = ex.ForcSet(torque_range_Nm=-u0, levels=levels, rate_Nm_s=rate_Nm_s)
        df = fit_run.run(fs)
        s = df.segment(0)
        ev, _ = hy.everett_from_forcs(s["load_torque_Nm"], stf.twist_of(s, df.gear_ratio, None),
                                      s["torque_cmd_Nm"], levels, step, u0)
        tab = hy.quantise_table(ev)

        def errors(points: list[float]) -> tuple[dict[str, float], float]:
            d = val_run.run(LockedPoints(points, rate_Nm_s))
            v = d.segment(0)
            T, phi, cmd = v["load_torque_Nm"], stf.twist_of(v, d.gear_ratio, None), v["torque_cmd_Nm"]
            st_ = hy.split_reversals(cmd)
            k0 = st_[1][0] if len(st_) > 1 else 0           # after the first stretch (memory set)
            pp = ev.simulate(T)
            pm = maxwell_twist(st, T)
            w = hy.loop_width(T[k0:], phi[k0:], cmd[k0:])
            return ({"maxwell": _rms_centred(pm[k0:] - phi[k0:]) * ARCSEC_PER_RAD,
                     "preisach": _rms_centred(pp[k0:] - phi[k0:]) * ARCSEC_PER_RAD}, w * ARCSEC_PER_RAD)

        major, width = errors([-A, A, -A, A, -A])
        minor: dict[str, dict[str, float]] = {"maxwell": {}, "preisach": {}}
        bias = A / 3.0
        for w in widths:
            h = float(w) * A
            e, _ = errors([-A, A, -A, bias + h, bias - h, bias + h, bias - h, bias + h])
            for m in minor:
                minor[m][f"{w:g}"] = e[m]
        n_el = len(st.maxwell.k_Nm_per_rad)
        rows.append(HysteresisRow(
            axis=str(axis), amplitude_frac=float(frac), amplitude_Nm=A, major_err_arcsec=major,
            minor_err_arcsec=minor, loop_width_arcsec=width,
            experiment_s={"maxwell": _time_s(ex.cycle_points(A, lc.cycles), rate_Nm_s),
                          "preisach": _time_s(fs.plan(df.gear_ratio)[0]["turning_points_Nm"], rate_Nm_s)},
            parameters={"maxwell": 2 * n_el + 5, "preisach": levels * (levels - 1) // 2},
            memory_bytes={"maxwell": n_el * MAXWELL_BYTES_PER_ELEMENT, "preisach": len(tab.to_bytes())}))
    return rows


# ----------------------------------------------------------------- CPU cost and the needs table


def cpu_costs(bench_json: Path | None) -> dict[str, int | None]:
    """Cortex-M4 instructions per step per compensator from ``make bench``'s ``cm4_cost.json``.

    None for every compensator when the file is absent (not measured here).
    """
    kern: Mapping[str, Any] = {}
    if bench_json is not None and Path(bench_json).is_file():
        kern = json.loads(Path(bench_json).read_text()).get("kernels", {})
    out: dict[str, int | None] = {}
    for c, k in COST_KERNEL.items():
        names = (k,) if isinstance(k, str) else k
        out[c] = int(sum(int(kern[n]["instructions"]) for n in names)) if all(n in kern for n in names) else None
    return out


def drift_gains(doc: Mapping[str, Any] | None) -> dict[str, float]:
    """Gain each compensator keeps under parameter drift, from a drift study document.

    The document is ``build/results/drift_mc.json`` (tests/results/58_drift_monte_carlo.py).  The
    gain kept by a compensator is the smallest, over the drift scenarios (every scenario but
    ``nominal``) and the figures the compensation is for (``target.figures``: where the
    fixed-model compensation gains at least 1.5x on the nominal axis), of its median gain over
    the fair PID (median PID figure / median figure, dimensionless).  A compensator with a
    missing gain on one of them is left out.

    Parameters
    ----------
    doc : mapping or None
        The drift document; None or one without drift scenarios gives an empty mapping.

    Returns
    -------
    dict
        Compensator (:data:`DRIFT_COMPENSATOR` values) -> gain kept.
    """
    if not doc:
        return {}
    gain = doc.get("gain", {})
    figs = list(doc.get("target", {}).get("figures", []))
    drifts = [s for s in doc.get("scenarios", []) if s != "nominal" and s in gain]
    out: dict[str, float] = {}
    if not figs or not drifts:
        return out
    for ctl, comp in DRIFT_COMPENSATOR.items():
        vals = [gain[s].get(ctl, {}).get(f) for s in drifts for f in figs]
        if vals and all(v is not None and math.isfinite(float(v)) for v in vals):
            out[comp] = float(min(float(v) for v in vals))
    return out


def load_drift(path: Path | None) -> dict[str, Any] | None:
    """The drift study document at ``path`` (None when absent or unreadable: not measured here)."""
    if path is None or not Path(path).is_file():
        return None
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


@dataclass
class NeedRow:
    """Best single compensator for one need (gain = fair PID value / value on the need's figure)."""

    need: str
    figure: str
    feedback: str
    compensator: str | None
    gain: float | None
    cpu_instructions: int | None
    experiments: list[str] = field(default_factory=list)
    gains: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"need": self.need, "figure": self.figure, "feedback": self.feedback,
                "compensator": self.compensator, "gain": self.gain, "cpu_instructions": self.cpu_instructions,
                "experiments": self.experiments, "gains": self.gains}


def needs_table(ablation: Mapping[str, Any], costs: Mapping[str, int | None],
                feedback: str = "full-closed", drift: Mapping[str, float] | None = None) -> list[NeedRow]:
    """One row per need from an ablation document (:func:`hdservo.compare.ablation_doc`).

    Parameters
    ----------
    ablation : mapping
        ``{"rows": [{"name", "feedback", "kind", "components", "ratio_to_baseline"}]}``.
    costs : mapping
        Compensator -> M4 instructions per step (:func:`cpu_costs`).
    feedback : str
        Feedback configuration of the rows compared.
    drift : mapping, optional
        Compensator -> gain kept under parameter drift (from a drift study); without it the
        "parameter drift" row says not measured here (compensator None).
    """
    single = [r for r in ablation.get("rows", []) if r.get("feedback", "full-closed") == feedback
              and len(r.get("components", [])) == 1]
    out = []
    for need, fig in NEEDS.items():
        gains: dict[str, float] = {}
        if fig == "drift":
            gains = {k: float(v) for k, v in (drift or {}).items()}
        else:
            for r in single:
                q = (r.get("ratio_to_baseline") or {}).get(fig)
                if q is None or not q > 0:
                    continue
                gains[r["components"][0]] = float(q) if fig in HIGHER_IS_BETTER else 1.0 / float(q)
        best = max(gains, key=lambda c: gains[c]) if gains else None
        out.append(NeedRow(need=need, figure=fig, feedback=feedback, compensator=best,
                           gain=gains.get(best) if best else None,
                           cpu_instructions=costs.get(best) if best else None,
                           experiments=list(IDENT_EXPERIMENTS.get(best, [])) if best else [], gains=gains))
    return out


# ----------------------------------------------------------------- rules


@dataclass
class Rule:
    """A stated rule and whether the table it was checked on bears it out."""

    name: str
    text: str
    holds: bool
    evidence: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "text": self.text, "holds": self.holds, "evidence": self.evidence}


def _median(rows: Sequence[HysteresisRow], f: Callable[[HysteresisRow], float]) -> float:
    return float(np.median([f(r) for r in rows])) if rows else math.nan


#: Load amplitude (fraction of rated) from which the rules call the load "full" / below which "part".
FULL_LOAD_FRAC = 0.7
PART_LOAD_FRAC = 0.3


def _wins(rows: Sequence[HysteresisRow], win: str, lose: str) -> tuple[list[bool], str]:
    """Per row whether ``win`` has the smaller major- and minor-loop error than ``lose``, and the
    medians of both as text ('A" on the major loop and B" on minor loops' for each)."""
    ok = [r.major_err_arcsec[win] < r.major_err_arcsec[lose] and r.minor_mean(win) < r.minor_mean(lose)
          for r in rows]

    def errs(m: str) -> str:
        return (f"{_median(rows, lambda r: r.major_err_arcsec[m]):.2f}\" on the major loop and "
                f"{_median(rows, lambda r: r.minor_mean(m)):.2f}\" on minor loops")
    return ok, f"{errs(win)}, against {{}}'s {errs(lose).replace(' on the major loop', '').replace(' on minor loops', '')}"


def rule_preisach_full_load(rows: Sequence[HysteresisRow]) -> Rule:
    """Preisach at full load: at >= FULL_LOAD_FRAC x rated its major- and minor-loop errors are below Maxwell's."""
    rows = [r for r in _measured(rows) if r.amplitude_frac >= FULL_LOAD_FRAC]
    ok, text = _wins(rows, "preisach", "maxwell")
    return Rule("preisach_full_load",
                f"Preisach when the gear is loaded to {FULL_LOAD_FRAC:g}-1 x rated torque and minor loops matter: "
                f"its twist error is {text.format('Maxwell-slip')} (medians)",
                bool(rows) and all(ok), {"amplitudes": [r.amplitude_frac for r in rows], "preisach_better": ok})


def rule_maxwell_part_load(rows: Sequence[HysteresisRow]) -> Rule:
    """Maxwell-slip at part load: at <= PART_LOAD_FRAC x rated its major- and minor-loop errors are below Preisach's."""
    rows = [r for r in _measured(rows) if r.amplitude_frac <= PART_LOAD_FRAC]
    ok, text = _wins(rows, "maxwell", "preisach")
    return Rule("maxwell_part_load",
                f"Maxwell-slip when the load stays within {PART_LOAD_FRAC:g} x rated torque: its twist error is "
                f"{text.format('the Preisach table')} (medians)",
                bool(rows) and all(ok), {"amplitudes": [r.amplitude_frac for r in rows], "maxwell_better": ok})


def rule_maxwell_memory(rows: Sequence[HysteresisRow]) -> Rule:
    """Maxwell-slip where memory and identification time are tight: both are smaller at every amplitude."""
    rows = _measured(rows)
    holds = bool(rows) and all(r.memory_bytes["maxwell"] < r.memory_bytes["preisach"]
                               and r.experiment_s["maxwell"] < r.experiment_s["preisach"] for r in rows)
    return Rule("maxwell_memory",
                f"Maxwell-slip where memory and identification time are tight: "
                f"{_median(rows, lambda r: r.memory_bytes['maxwell']):.0f} B and "
                f"{_median(rows, lambda r: r.experiment_s['maxwell']):.0f} s of experiment against the "
                f"Preisach table's {_median(rows, lambda r: r.memory_bytes['preisach']):.0f} B and "
                f"{_median(rows, lambda r: r.experiment_s['preisach']):.0f} s",
                holds, {"memory_bytes": [r.memory_bytes for r in rows],
                        "experiment_s": [r.experiment_s for r in rows]})


def rule_need_friction_ff(needs: Sequence[NeedRow]) -> Rule:
    """A friction feed-forward is the best single compensator for pointing, stabilisation and tracking."""
    want = ("pointing accuracy", "stabilisation", "tracking")
    rows = {n.need: n for n in needs}
    got = {w: (rows[w].compensator, rows[w].gain) for w in want if w in rows}
    holds = all(got.get(w, (None, None))[0] in ("stribeck", "lugre") and (got[w][1] or 0.0) >= 2.0 for w in want)
    txt = "; ".join(f"{w}: {c} {g:.1f}x" if g else f"{w}: not measured here" for w, (c, g) in got.items())
    return Rule("need_friction_ff", "a friction feed-forward (Stribeck or LuGre) is the compensator for "
                f"pointing, stabilisation and tracking, each at least 2x better than the fair PID ({txt})",
                holds, {w: list(v) for w, v in got.items()})


def rule_need_hysteresis_alone(needs: Sequence[NeedRow]) -> Rule:
    """In full closed neither hysteresis model alone buys 2x on any need (the output encoder sees the twist)."""
    g = {n.need: max([n.gains.get(c, 0.0) for c in ("maxwell", "preisach")]) for n in needs if n.gains}
    top = max(g.values()) if g else math.nan
    return Rule("need_hysteresis_alone", "in full closed Maxwell-slip or Preisach alone is no answer to any need: "
                f"their best gain is {top:.2f}x (the output encoder already measures the twist)",
                bool(g) and top < 2.0, {"best_gain": g})


#: Least gain over the fair PID a compensator keeps in the worst drift scenario for the drift rule.
DRIFT_MIN_GAIN = 1.5


def rule_need_drift(needs: Sequence[NeedRow]) -> Rule:
    """Parameter drift: a Stribeck feed-forward (fixed-model or online-identified) keeps at least
    DRIFT_MIN_GAIN over the fair PID in every drift scenario, and more than adaptive backstepping."""
    row = next((n for n in needs if n.figure == "drift"), None)
    g = dict(row.gains) if row is not None else {}
    ff = {c: g[c] for c in ("stribeck", "stribeck_online") if c in g}
    best = max(ff, key=lambda c: ff[c]) if ff else None
    bs = g.get("backstep")
    holds = best is not None and ff[best] >= DRIFT_MIN_GAIN and (bs is None or bs < ff[best])
    names = {"stribeck": "the fixed-model Stribeck feed-forward", "stribeck_online": "the online-identified one",
             "backstep": "adaptive backstepping"}
    txt = ", ".join(f"{names[c]} {v:.2f}x" for c, v in g.items() if c in names)
    return Rule("need_drift", f"for parameter drift a Stribeck feed-forward is the compensator: on the reversal "
                f"peak and positioning, in the worst drift scenario, {txt} over the fair PID "
                f"(at least {DRIFT_MIN_GAIN:g}x, and more than backstepping)", holds, {"gain_kept": g})


HYSTERESIS_RULES: list[Callable[[Sequence[HysteresisRow]], Rule]] = [
    rule_preisach_full_load, rule_maxwell_part_load, rule_maxwell_memory]
NEED_RULES: list[Callable[[Sequence[NeedRow]], Rule]] = [rule_need_friction_ff, rule_need_hysteresis_alone]


def check_rules(hyst: Sequence[HysteresisRow] | None, needs: Sequence[NeedRow] | None) -> list[Rule]:
    """Every rule on the tables given (a missing table skips its rules)."""
    out = [r(hyst) for r in HYSTERESIS_RULES] if hyst else []
    out += [r(needs) for r in NEED_RULES] if needs else []
    # the drift rule is checked where a drift study measured the row
    if needs and any(n.figure == "drift" and n.gains for n in needs):
        out.append(rule_need_drift(needs))
    return out


def rules_from_doc(doc: Mapping[str, Any]) -> list[Rule]:
    """Rules checked on a stored selection document (:func:`selection_doc`)."""
    hyst = [HysteresisRow(**r) for r in doc.get("hysteresis", [])]
    needs = [NeedRow(**r) for r in doc.get("needs", [])]
    return check_rules(hyst or None, needs or None)


def closed_loop_benefit(ablation: Mapping[str, Any], feedback: str = "semi-closed",
                        figure: str = "positioning_accuracy_arcsec") -> dict[str, Any]:
    """Positioning gain (fair PID value / value) of Maxwell-slip and Preisach rows in ``feedback``.

    Alone and, when the ablation has them, on top of TE (``te+maxwell``, ``te+preisach``); a
    model without a row is "not measured here".
    """
    out: dict[str, Any] = {}
    rows = [r for r in ablation.get("rows", []) if r.get("feedback", "full-closed") == feedback]
    for m in ("maxwell", "preisach"):
        for parts in ([m], ["te", m]):
            key = "+".join(parts)
            q = next(((r.get("ratio_to_baseline") or {}).get(figure) for r in rows
                      if sorted(r.get("components", [])) == sorted(parts)), None)
            out[key] = 1.0 / float(q) if q else "not measured here"
    return out


def selection_doc(hyst: Sequence[HysteresisRow], needs: Sequence[NeedRow], costs: Mapping[str, int | None],
                  meta: Mapping[str, Any] | None = None,
                  closed_loop: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """JSON-ready document of both tables, the CPU costs and the rules with their verdicts."""
    return {"hysteresis": [r.to_dict() for r in hyst], "needs": [n.to_dict() for n in needs],
            "closed_loop_semi_positioning_gain": dict(closed_loop or {}),
            "cpu_instructions": dict(costs), "rules": [r.to_dict() for r in check_rules(hyst, needs)],
            "meta": dict(meta or {})}


def summary_lines(ablation: Mapping[str, Any], costs: Mapping[str, int | None],
                  selection: Mapping[str, Any] | None = None,
                  drift: Mapping[str, Any] | None = None) -> list[str]:
    """Lines for the end of ``hdservo compare``: the need rows and the rules that hold.

    Parameters
    ----------
    ablation : mapping
        The run's ablation document (:func:`hdservo.compare.ablation_doc`).
    costs : mapping
        Compensator -> M4 instructions per step (:func:`cpu_costs`).
    selection : mapping, optional
        A stored selection document (``build/results/selection_rules.json``) for the hysteresis
        rules.
    drift : mapping, optional
        A drift study document (``build/results/drift_mc.json``) for the parameter-drift row
        (full-closed); without it that row says not measured here.
    """
    lines = []
    fbs = []
    for r in ablation.get("rows", []):
        if r.get("feedback", "full-closed") not in fbs:
            fbs.append(r.get("feedback", "full-closed"))
    needs_all: list[NeedRow] = []
    for fb in fbs:
        needs = needs_table(ablation, costs, fb, drift=drift_gains(drift) if fb == "full-closed" else None)
        needs_all += needs if fb == "full-closed" else []
        for n in needs:
            if n.compensator is None:
                lines.append(f"need {n.need} ({fb}): not measured here")
                continue
            cpu = f"{n.cpu_instructions} M4 instructions/step" if n.cpu_instructions is not None else \
                "CPU not measured here"
            what = "kept under drift (worst drift scenario)" if n.figure == "drift" else "better than the fair PID"
            lines.append(f"need {n.need} ({fb}): {n.compensator}, {n.gain:.2g}x {what}; {cpu}; "
                         f"identification: {', '.join(n.experiments) or 'none'}")
    hyst = [HysteresisRow(**r) for r in (selection or {}).get("hysteresis", [])]
    for r in check_rules(hyst or None, needs_all or None):
        if r.holds:
            lines.append(f"rule: {r.text}")
    return lines


def compare_lines(doc: Mapping[str, Any]) -> list[str]:
    """Selection lines for the end of ``hdservo compare`` from its document (empty without ablation rows).

    The CPU costs come from ``build/bench/cm4_cost.json`` and the hysteresis rules from
    ``build/results/selection_rules.json`` when a checkout has them (:func:`hdservo.resources.build_output`).
    """
    from .. import resources
    from ..compare import ablation_doc
    if not doc.get("ablation"):
        return []
    abl = ablation_doc(doc)
    costs = cpu_costs(resources.build_output("bench", "cm4_cost.json"))
    sp = resources.build_output("results", "selection_rules.json")
    selection = None
    if sp is not None:
        try:
            selection = json.loads(sp.read_text())
        except (OSError, ValueError):
            selection = None
    drift = load_drift(resources.build_output("results", "drift_mc.json"))
    return summary_lines(abl, costs, selection, drift)
