"""A wide corpus of synthetic logs for the held-apart validation of the discrepancy workflow.

Every log comes from the project's C simulator (never from the model being fitted), with
everything drawn from the case's seed:

* an axis drawn over catalogue ranges (:func:`draw_axis`): gear ratio 30-160, inertias,
  stiffness (three slopes), friction levels and Stribeck velocities between a CSF-14 and a
  CSF-32 class axis, each jittered x0.7-1.4;
* a controller (:func:`draw_controller`): the drive's own firmware in one of its feedback
  configurations (full closed, semi-closed, dual loop; velocity gains scaled to the axis'
  inertia), or a plain P-PI cascade written here (:func:`run_ppi`) at 1 or 2 kHz with its
  own gains (velocity bandwidth 10-35 Hz, position bandwidth a fifth of it);
* logging at 1, 2 or 10 kHz;
* a motor encoder of 14-20 bits and an output encoder of 18-24 bits, or one of them absent
  (a log with the motor encoder alone or the output encoder alone);
* closed-loop motion: the drive follows a sine or a chirp; the cascade a random sequence
  of moves, holds, sinusoids and reversals (:func:`draw_motion`);
* none, one or two hidden effects (:data:`EFFECTS`), each at 0.5-1.5x a typical size
  (:func:`effect_overrides`).

What the baseline model has is on in the plant (linear spring with damping, Coulomb +
viscous friction both sides with Fs = Fc, the current loop at 2 kHz, which is invisible in
``Kt x measured current``); LuGre, base motion and every hidden-effect section are off
unless hidden.  ``unmodelled_compliance`` is the usual two-mass plant analysed with a rigid
baseline (only on logs with both encoders).  ``current_loop_lag`` logs the torque command
with the current loop at 150-450 Hz.

The split (:data:`CALIBRATION_SEEDS`, :data:`HELD_APART_SEEDS`) is fixed: thresholds are
tuned only on the first, the second is reported (tests/results/47_discrepancy_heldout.py).
"""
from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hdservo import logio, sim
from hdservo.discrepancy import EFFECT_NAMES, IDENTIFIABLE, not_identifiable_parts
from hdservo.discrepancy.closeloop import axis_text
from hdservo.tomltext import basic_string

#: Effects that can be hidden (every name of the workflow's library).
EFFECTS: tuple[str, ...] = EFFECT_NAMES
#: The part of an effect the corpus hides where the workflow's identifiability table tells
#: parts apart (:func:`hdservo.discrepancy.not_identifiable_parts`): the asymmetry is
#: Coulomb only (fc and fs of one direction scaled, the viscous friction symmetric).
HIDDEN_PART: dict[str, str] = {"asymmetric_friction": "coulomb"}
#: Pairs not hidden together: both act through the same plant section (the spring).
EXCLUSIVE = {frozenset({"nonlinear_stiffness", "backlash"})}
#: The fixed split: seeds 1-1000 are calibration, 100001-101000 held apart.
CALIBRATION_SEEDS = range(1, 1001)
HELD_APART_SEEDS = range(100001, 101001)
#: Log length, s.
DURATION_S = 8.0
#: Plant period, s (the simulator's own).
PLANT_DT = 1e-4


@dataclass
class CorpusCase:
    """One drawn case (everything follows from ``seed``)."""

    seed: int
    axis: dict[str, dict[str, Any]] = field(default_factory=dict)
    controller: dict[str, Any] = field(default_factory=dict)
    log_rate_Hz: float = 2000.0
    motor_bits: int | None = 17
    load_bits: int | None = 24
    motion: dict[str, Any] = field(default_factory=dict)
    hidden: list[tuple[str, float]] = field(default_factory=list)   # (effect, size factor)

    @property
    def angles(self) -> str:
        """Signal set of the log (``both``, ``motor``, ``output``)."""
        return "both" if self.motor_bits and self.load_bits else "motor" if self.motor_bits else "output"

    @property
    def structure(self) -> str:
        return "rigid" if any(e == "unmodelled_compliance" for e, _ in self.hidden) or self.angles != "both" \
            else "two_mass"

    @property
    def label(self) -> str:
        h = "+".join(e for e, _ in self.hidden) or "none"
        return f"s{self.seed}-{h}-{self.controller.get('kind')}-{self.log_rate_Hz / 1000:g}k-{self.angles}"

    def identifiable(self) -> list[str]:
        """The hidden effects the log's signals can show (the identifiability table; the
        workflow's default offset for the log's baseline structure): a Coulomb-only
        asymmetry on a rigid baseline with its constant offset is not one of them."""
        parts = not_identifiable_parts(self.structure)
        return [e for e, _ in self.hidden if e in IDENTIFIABLE[self.angles]
                and HIDDEN_PART.get(e) not in parts.get(e, {})]


def _lerp_log(a: float, b: float, u: float) -> float:
    return float(math.exp(math.log(a) + u * (math.log(b) - math.log(a))))


def draw_axis(rng: np.random.Generator) -> dict[str, dict[str, Any]]:
    """Plant sections of a random axis over catalogue ranges (CSF-14 to CSF-32 class)."""
    u = float(rng.uniform(0, 1))

    def j() -> float:
        return float(rng.uniform(0.7, 1.4))
    N = float(rng.choice([30, 50, 80, 100, 120, 160]))
    K = _lerp_log(1.9e3, 6.7e4, u) * j()
    T1 = _lerp_log(2.0, 29.0, u) * j()
    jm, jl = _lerp_log(1.5e-5, 1.1e-4, u) * j(), _lerp_log(0.02, 2.0, u) * j()
    kt = float(rng.uniform(0.04, 0.1))
    fscale = _lerp_log(0.3, 4.0, u)
    fcm, fcl = 0.07 * fscale * j() * (1e-4 / 8e-5) ** 0, 0.4 * fscale * j()
    # damping of the torsional mode: ratio 5-20 %
    jeq = jl * N * N * jm / (jl + N * N * jm)
    c = 2 * float(rng.uniform(0.05, 0.2)) * math.sqrt(K * jeq)
    return {
        "axis": {"defaults": "minimal"},
        "gear": {"ratio": N}, "motor": {"jm_kgm2": jm, "kt_Nm_per_A": kt}, "load": {"jl_kgm2": jl},
        "current_loop": {"enabled": True, "bandwidth_Hz": 2000.0, "peak_A": 1e3},
        "stiffness": {"enabled": True, "k1_Nm_per_rad": K, "k2_Nm_per_rad": K, "k3_Nm_per_rad": K,
                      "t1_Nm": T1, "t2_Nm": 3.5 * T1, "damping_Nms_per_rad": c},
        "friction_motor": {"enabled": True, "fc_pos_Nm": fcm, "fc_neg_Nm": fcm, "fs_pos_Nm": fcm, "fs_neg_Nm": fcm,
                           "vs_rad_s": 2.0 * float(rng.uniform(0.5, 2.0)), "delta": 2.0,
                           "viscous_Nms_per_rad": 5e-4 * fscale * j(), "lugre_enabled": False},
        "friction_load": {"enabled": True, "fc_pos_Nm": fcl, "fc_neg_Nm": fcl, "fs_pos_Nm": fcl, "fs_neg_Nm": fcl,
                          "vs_rad_s": 0.02 * float(rng.uniform(0.5, 2.0)), "delta": 2.0,
                          "viscous_Nms_per_rad": 0.3 * fscale * j(), "lugre_enabled": False},
        "encoder_motor": {"enabled": True, "bits": 17, "noise_counts": 0.2},
        "encoder_load": {"enabled": True, "bits": 24, "noise_counts": 1.0},
        "current_sensor": {"enabled": True, "noise_A": 0.01},
    }


def draw_controller(rng: np.random.Generator, angles: str) -> dict[str, Any]:
    """The drive's firmware in a feedback configuration the encoders allow, or a P-PI cascade."""
    if rng.uniform() < 0.5 and angles == "both":
        return {"kind": "drive", "fb_config": int(rng.integers(0, 3)), "vel_bw_scale": float(rng.uniform(0.6, 1.2))}
    return {"kind": "ppi", "rate_Hz": float(rng.choice([1000.0, 2000.0])), "vel_bw_Hz": float(rng.uniform(10, 35)),
            "vel_filter_Hz": float(rng.uniform(150, 400))}


def draw_motion(rng: np.random.Generator, kind: str) -> dict[str, Any]:
    """Reference motion: the drive follows a sine or chirp; the cascade a random sequence of
    moves, holds, sinusoids and reversals (output rad)."""
    if kind == "drive":
        if rng.uniform() < 0.5:
            A = float(rng.uniform(0.3, 1.0))
            return {"type": "sine", "amplitude_rad": A, "frequency_Hz": float(rng.uniform(0.3, 1.5)) / (2 * math.pi * A)}
        A = float(rng.uniform(0.5, 1.0))
        return {"type": "chirp", "amplitude_rad": A, "f0_Hz": float(rng.uniform(0.03, 0.06)),
                "f1_Hz": float(rng.uniform(0.8, 1.6)) / (2 * math.pi * A)}
    segs: list[tuple[str, float, float, float]] = []
    t = 0.3
    while t < DURATION_S:
        k = str(rng.choice(["move", "hold", "sine", "reversals"], p=[0.35, 0.15, 0.25, 0.25]))
        d = float(rng.uniform(0.6, 2.0)) if k != "hold" else float(rng.uniform(0.2, 0.6))
        segs.append((k, d, float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.3, 1.5))))
        t += d
    return {"type": "sequence", "segments": segs}


def reference(motion: dict[str, Any], t: np.ndarray) -> np.ndarray:
    """Position reference of a ``sequence`` motion at times ``t`` (output rad, smooth)."""
    r = np.zeros_like(t)
    pos, t0 = 0.0, 0.3
    for k, d, a, v in motion["segments"]:
        m = (t >= t0) & (t < t0 + d)
        tau = (t[m] - t0) / d
        if k == "move":
            tgt = float(np.clip(pos + math.copysign(a, 0.5 - (pos > 0)), -1.2, 1.2))
            r[m] = pos + (tgt - pos) * (10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5)      # min-jerk
            pos_end = tgt
        elif k == "hold":
            r[m] = pos
            pos_end = pos
        elif k == "sine":
            n = max(1, round(d * v / (2 * math.pi * a) * 2 * math.pi)) if a > 0 else 1
            r[m] = pos + a * np.sin(2 * np.pi * n * tau) * np.sin(np.pi * tau) ** 2
            pos_end = pos
        else:                              # reversals: a smoothed triangle about pos
            n = max(1, int(d * v / (4 * a)))
            tri = 2 * np.abs(2 * ((n * tau + 0.25) % 1.0) - 1.0) - 1.0
            r[m] = pos + a * tri * np.sin(np.pi * tau) ** 2
            pos_end = pos
        r[t >= t0 + d] = pos_end
        pos, t0 = pos_end, t0 + d
    # smooth the joins (reversal corners) over 20 ms
    w = max(1, int(0.02 / max(float(t[1] - t[0]), 1e-6)))
    return np.convolve(np.pad(r, (w, w), mode="edge"), np.ones(2 * w + 1) / (2 * w + 1), mode="same")[w:-w]


def peak_torque_estimate(axis: dict[str, dict[str, Any]]) -> float:
    """Rough peak transmitted torque of the motions drawn here, N.m at the output (sizes effects)."""
    N = axis["gear"]["ratio"]
    jl = axis["load"]["jl_kgm2"]
    return float(jl * 8.0 + axis["friction_load"]["fc_pos_Nm"] + axis["friction_load"]["viscous_Nms_per_rad"] * 1.0
                 + 0.0 * N)


def effect_overrides(axis: dict[str, dict[str, Any]], eff: str, g: float,
                     rng: np.random.Generator) -> dict[str, dict[str, Any]]:
    """Plant sections that hide ``eff`` at ``g`` x its typical size on ``axis``."""
    N = axis["gear"]["ratio"]
    K = axis["stiffness"]["k1_Nm_per_rad"]
    Tp = peak_torque_estimate(axis)
    fm, fl = dict(axis["friction_motor"]), dict(axis["friction_load"])
    if eff == "stribeck_friction":
        for f in (fm, fl):
            f["fs_pos_Nm"] = f["fc_pos_Nm"] * (1 + 0.8 * g)
            f["fs_neg_Nm"] = f["fc_neg_Nm"] * (1 + 0.8 * g)
        return {"friction_motor": fm, "friction_load": fl}
    if eff == "asymmetric_friction":
        for f in (fm, fl):
            f["fc_neg_Nm"] = f["fc_pos_Nm"] * (1 - 0.4 * g)
            f["fs_neg_Nm"] = f["fs_pos_Nm"] * (1 - 0.4 * g)
        return {"friction_motor": fm, "friction_load": fl}
    if eff == "transmission_error":
        te: dict[str, Any] = {"enabled": True}
        for i, (o, a) in enumerate(((2, 8.7e-5), (1, 1.45e-5), (4, 1.16e-5)), start=1):
            te.update({f"wg{i}_order": float(o), f"wg{i}_amp_rad": 1.5 * g * a,
                       f"wg{i}_phase_rad": float(rng.uniform(-math.pi, math.pi))})
        te.update({"out1_order": 1.0, "out1_amp_rad": 1.5 * g * 2.9e-5, "out1_phase_rad": float(rng.uniform(-3, 3))})
        return {"transmission_error": te}
    if eff == "cogging_torque":
        p = float(rng.choice([24, 36, 48, 72]))
        a = 0.025 * g * 3.5 * axis["stiffness"]["t1_Nm"] / N
        return {"cogging": {"enabled": True, "h1_order": p, "h1_amp_Nm": a, "h1_phase_rad": float(rng.uniform(-3, 3)),
                            "h2_order": 2 * p, "h2_amp_Nm": a / 4, "h2_phase_rad": float(rng.uniform(-3, 3))}}
    if eff == "nonlinear_stiffness":
        t1 = float(rng.uniform(0.25, 0.45)) * Tp
        return {"stiffness": {"k2_Nm_per_rad": K * (1 + 0.4 * g), "k3_Nm_per_rad": K * (1 + 0.7 * g),
                              "t1_Nm": t1, "t2_Nm": 2.5 * t1}}
    if eff == "hysteresis":
        h: dict[str, Any] = {"enabled": True, "n_elements": 4}
        for i in range(1, 5):
            h[f"e{i}_k_Nm_per_rad"] = 0.18 * K / i
            h[f"e{i}_w_Nm"] = 0.04 * g * Tp
        return {"hysteresis_maxwell": h}
    if eff == "backlash":
        b = 0.15 * g * Tp / K
        k1 = 0.02 * K
        return {"stiffness": {"k1_Nm_per_rad": k1, "t1_Nm": k1 * b, "t2_Nm": k1 * b + 0.2 * Tp,
                              "k2_Nm_per_rad": K, "k3_Nm_per_rad": K}}
    if eff == "gravity_unbalance":
        # the reference axis' unbalance is 0.14 T1; the tuned cases use 1x and 2x of it
        T1 = axis["stiffness"]["t1_Nm"]
        return {"gravity": {"enabled": True, "mgl_Nm": 0.21 * g * T1, "offset_rad": float(rng.uniform(-math.pi, math.pi))}}
    if eff == "current_loop_lag":
        return {"current_loop": {"bandwidth_Hz": 225.0 / g}}
    if eff == "unmodelled_compliance":
        return {}
    raise ValueError(f"unknown effect {eff}")


def draw(seed: int) -> CorpusCase:
    """The case of ``seed`` (axis, encoders, controller, rate, motion, hidden effects)."""
    rng = np.random.default_rng([seed, 30])
    axis = draw_axis(rng)
    mb: int | None = int(rng.integers(14, 21))
    lb: int | None = int(rng.integers(18, 25))
    x = rng.uniform()
    if x < 0.15:
        lb = None
    elif x < 0.25:
        mb = None
    ctl = draw_controller(rng, "both" if mb and lb else "one")
    rate = float(rng.choice([1000.0, 2000.0, 10000.0]))
    k = int(rng.choice([0, 1, 2], p=[0.2, 0.55, 0.25]))
    pool = [e for e in EFFECTS if e != "unmodelled_compliance" or (mb and lb)]
    hidden: list[tuple[str, float]] = []
    while len(hidden) < k:
        e = str(rng.choice(pool))
        if e in [h for h, _ in hidden] or any(frozenset({e, h}) in EXCLUSIVE for h, _ in hidden):
            continue
        if k == 2 and e == "unmodelled_compliance":
            continue
        hidden.append((e, float(rng.uniform(0.5, 1.5))))
    for e, g in hidden:
        for sec, kv in effect_overrides(axis, e, g, rng).items():
            axis.setdefault(sec, {}).update(kv)
    axis["encoder_motor"]["bits"] = mb or 17
    axis["encoder_load"]["bits"] = lb or 24
    return CorpusCase(seed=seed, axis=axis, controller=ctl, log_rate_Hz=rate, motor_bits=mb, load_bits=lb,
                      motion=draw_motion(rng, ctl["kind"]), hidden=hidden)


def _total_inertia(axis: dict[str, dict[str, Any]]) -> float:
    N = axis["gear"]["ratio"]
    return axis["load"]["jl_kgm2"] + N * N * axis["motor"]["jm_kgm2"]


def run_ppi(case: CorpusCase, axis_file: Path) -> dict[str, np.ndarray]:
    """Closed loop with a plain P-PI cascade at ``rate_Hz`` (velocity from the motor encoder,
    position from the output encoder when there is one, else the motor's / N); the plant
    at 10 kHz.  Returns the plant's rows at 10 kHz plus the torque command per row."""
    c = case.controller
    ax = case.axis
    N = ax["gear"]["ratio"]
    kt = ax["motor"]["kt_Nm_per_A"]
    J = _total_inertia(ax)
    wv = 2 * math.pi * c["vel_bw_Hz"]
    kv, ki, kp = wv * J, wv * J * wv / 5.0, wv / 5.0
    Tc = 1.0 / c["rate_Hz"]
    m = int(round(Tc / PLANT_DT))
    n_ctl = int(DURATION_S / Tc)
    t = np.arange(n_ctl) * Tc
    r = reference(case.motion, t)
    v_ff = np.gradient(r, Tc)
    a_fv = math.exp(-2 * math.pi * c["vel_filter_Hz"] * Tc)
    cols = sim.open_loop_columns()
    im, il = cols.index("motor_angle_rad"), cols.index("load_angle_rad")
    rows, cmds = [], []
    integ, v_f, th_prev = 0.0, 0.0, 0.0
    # torque limit: the spring's range, and at least 4x the breakaway friction seen at the motor
    # (a large axis with Stribeck friction must not stay stuck)
    fr = ax["friction_motor"]["fs_pos_Nm"] + ax["friction_load"]["fs_pos_Nm"] / N
    u_max = max(3.5 * ax["stiffness"]["t1_Nm"] / N * 3, 4.0 * fr)
    with sim.Plant(str(axis_file), seed=case.seed) as p:
        last = None
        for i in range(n_ctl):
            if last is None:
                th_m, th_l = 0.0, 0.0
            else:
                th_m, th_l = float(last[-1, im]), float(last[-1, il])
            pos = th_l if case.load_bits else th_m / N
            v_raw = (th_m - th_prev) / Tc / N if i else 0.0
            th_prev = th_m
            v_f = a_fv * v_f + (1 - a_fv) * v_raw
            v_cmd = kp * (r[i] - pos) + v_ff[i]
            e = v_cmd - v_f
            u = (kv * e + integ) / N
            if abs(u) < u_max:
                integ += ki * e * Tc
            u = float(np.clip(u, -u_max, u_max))
            last = p.run(np.full(m, u), PLANT_DT)
            rows.append(last)
            cmds.append(np.full(m, u))
            if not np.all(np.isfinite(last)) or abs(r[i] - pos) > 1.0:
                raise RuntimeError("unstable cascade")
    out = np.vstack(rows)
    res = {name: out[:, j] for j, name in enumerate(cols)}
    res["torque_cmd_Nm"] = np.concatenate(cmds)
    return res


def _scenario_text(case: CorpusCase, axis_file: Path) -> str:
    c, mo = case.controller, case.motion
    g = _total_inertia(case.axis) / (0.5 + 100 ** 2 * 8e-5) * c["vel_bw_scale"]
    keys = "\n".join(f"{k} = {v!r}" for k, v in mo.items() if k != "type")
    return f"""[scenario]
axis = {basic_string(str(axis_file))}
duration_s = {DURATION_S}
seed = {case.seed}
[controller]
mode = "position"
[controller.gains]
follow_err_max = 0.2
vel_trip = 0.48
fb_config = {c['fb_config']}
pos_vlim = {2.5 / (2 * math.pi):.6g}
vel_kp = {min(4999.0, 204.2 * g):.6g}
vel_ki = {min(31999.0, 8019.0 * g):.6g}
[setpoint]
type = "{mo['type']}"
{keys}
t0_s = 0.3
"""


def make_log(case: CorpusCase, out_csv: Path) -> Path:
    """Simulate a case and write its log (CSV + minimal sidecar, no format tag: a user's log)."""
    lag = any(e == "current_loop_lag" for e, _ in case.hidden)
    with tempfile.TemporaryDirectory() as td:
        axis_file = Path(td) / "axis.toml"
        axis_file.write_text(axis_text(case.axis, f"corpus case {case.label}"))
        if case.controller["kind"] == "drive":
            sc = Path(td) / "case.toml"
            sc.write_text(_scenario_text(case, axis_file))
            r = sim.run_scenario(sc, seed=case.seed)
            cols = dict(r.columns)
            cols["torque_cmd_Nm"] = cols["torque_cmd_Nm"]
        else:
            cols = run_ppi(case, axis_file)
    kt = case.axis["motor"]["kt_Nm_per_A"]
    k = max(1, int(round(1.0 / (case.log_rate_Hz * PLANT_DT))))
    tau = cols["torque_cmd_Nm"] if lag else kt * cols["motor_current_A"]
    n = len(tau)
    idx = np.arange(0, n, k)
    out: dict[str, np.ndarray] = {"t_s": np.arange(len(idx)) * k * PLANT_DT}
    if case.motor_bits:
        out["motor_angle_rad"] = cols["motor_angle_rad"][idx]
    if case.load_bits:
        out["load_angle_rad"] = cols["load_angle_rad"][idx]
    out["motor_torque_Nm"] = tau[idx]
    out_csv = Path(out_csv)
    out_csv.parent.mkdir(parents=True, exist_ok=True)
    meta = {"gear_ratio": float(case.axis["gear"]["ratio"]), "sample_period_s": k * PLANT_DT}
    logio.write_log(out_csv, out, meta)
    # a user's sidecar: what write_log adds beyond the two required keys is taken out again
    import json
    out_csv.with_suffix(".json").write_text(json.dumps(meta))
    return out_csv


def split_is_disjoint() -> bool:
    """The calibration and held-apart seed ranges share no seed."""
    return not set(CALIBRATION_SEEDS) & set(HELD_APART_SEEDS)
