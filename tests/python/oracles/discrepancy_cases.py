"""Synthetic test logs from the simulator, each with exactly one effect the baseline lacks.

Used by tests/python/test_discrepancy_*.py (a few cases) and tests/results/40_discrepancy.py
(the confusion table).  Every log comes from the plant (``hdservo.sim``: closed loop with
the drive firmware, or the plant alone open loop), with encoder quantisation and noise and
current-sensor noise on -- never from the model being fitted.

Experiments (the same for every hidden effect; the workflow is never told which one is
hidden): closed loop, the drive's position loop follows a slow large chirp whose end asks
for more than the drive's velocity limit (slow reversals and travel over many motor
revolutions first, then a triangle wave with current-limited reversals: torsion, torque
rate); open loop, the plant alone driven by :func:`open_loop_torque` (rigid-body
feed-forward of a slow sine plus a 2-45 Hz multisine).

What the baseline has is on in every case: linear stiffness (three-slope with
K1 = K2 = K3) with damping, static Coulomb + viscous friction on both sides (symmetric,
Fs = Fc, LuGre off), the current loop (2 kHz; invisible since the logged torque is
Kt times the measured current).  Off unless it is the hidden effect: cogging, TE,
stiffness nonlinearity, hysteresis, gravity, base motion.  The hidden effect maps onto
plant keys as follows (docs/discrepancy.md has the table):

stribeck_friction      friction_*.fs_* = r * fc (r = 1.5 / 2.2), vs from the axis file
asymmetric_friction    friction_*.fc_neg = (1 - a) fc_pos (a = 0.3 / 0.5)
transmission_error     transmission_error.enabled, the axis' harmonics x 1 / x 2
cogging_torque         cogging.enabled, the axis' harmonics x 3 / x 6
nonlinear_stiffness    size 0: the axis' three-slope K1 < K2 < K3; size 1: cubic k3 (three-slope off)
hysteresis             size 0: Maxwell-slip elements of the axis; size 1: Maxwell-slip + Preisach
backlash               emulated: three-slope with K1 = 2 % of K and a half-gap of 1.5e-4 / 3e-4 rad
gravity_unbalance      gravity.enabled, mgl = the axis' value x 1 / x 2, random offset
unmodelled_compliance  the usual two-mass plant, but the baseline given to the workflow is rigid
current_loop_lag       current_loop.bandwidth_Hz = 150 / 300 and the log's motor torque is the command
"""
from __future__ import annotations

import math
import tempfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hdservo import logio, sim
from hdservo.tomltext import basic_string

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[3]

AXES = {"reference": "reference", "csf17_50": str(REPO_ROOT / "sim" / "axes" / "csf17_50.toml")}


@dataclass(frozen=True)
class Case:
    """One synthetic log: hidden effect (None = nothing missing), axis, loop, seed, size index."""

    effect: str | None
    axis: str = "reference"
    loop: str = "closed"
    seed: int = 1
    size: int = 0
    duration_s: float = 10.0

    @property
    def structure(self) -> str:
        return "rigid" if self.effect == "unmodelled_compliance" else "two_mass"

    @property
    def label(self) -> str:
        return f"{self.effect or 'none'}-{self.axis}-{self.loop}-s{self.seed}-z{self.size}"


def _ax(case: Case, key: str) -> float:
    return sim.axis_param(key, AXES[case.axis])


def plant_overrides(case: Case, rng: np.random.Generator) -> tuple[dict[str, float], dict[str, bool]]:
    """Plant parameters and effect switches of a case."""
    K = _ax(case, "stiffness.k1_Nm_per_rad")
    p: dict[str, float] = {"stiffness.k2_Nm_per_rad": K, "stiffness.k3_Nm_per_rad": K}
    for side in ("friction_motor", "friction_load"):
        fc = _ax(case, f"{side}.fc_pos_Nm")
        for d in ("pos", "neg"):
            p[f"{side}.fc_{d}_Nm"] = fc
            p[f"{side}.fs_{d}_Nm"] = fc
    e: dict[str, bool] = {"friction_motor.lugre": False, "friction_load.lugre": False, "cogging": False,
                          "transmission_error": False, "stiffness_cubic": False, "hysteresis_maxwell": False,
                          "hysteresis_preisach": False, "gravity": False, "base": False}
    z = case.size
    eff = case.effect
    if eff == "stribeck_friction":
        r = (1.5, 2.2)[z]
        for side in ("friction_motor", "friction_load"):
            fc = _ax(case, f"{side}.fc_pos_Nm")
            p[f"{side}.fs_pos_Nm"] = p[f"{side}.fs_neg_Nm"] = r * fc
    elif eff == "asymmetric_friction":
        a = (0.3, 0.5)[z]
        for side in ("friction_motor", "friction_load"):
            fc = _ax(case, f"{side}.fc_pos_Nm")
            p[f"{side}.fc_neg_Nm"] = p[f"{side}.fs_neg_Nm"] = (1 - a) * fc
    elif eff == "transmission_error":
        e["transmission_error"] = True
        g = (1.0, 2.0)[z]
        for k in range(1, 5):
            for pre in ("wg", "out"):
                key = f"transmission_error.{pre}{k}_amp_rad"
                p[key] = g * _ax(case, key)
    elif eff == "cogging_torque":
        e["cogging"] = True
        g = (3.0, 6.0)[z]
        for k in range(1, 5):
            key = f"cogging.h{k}_amp_Nm"
            p[key] = g * _ax(case, key)
    elif eff == "nonlinear_stiffness":
        if z == 0:
            for k in ("k2_Nm_per_rad", "k3_Nm_per_rad"):
                p[f"stiffness.{k}"] = _ax(case, f"stiffness.{k}")
        else:
            e["stiffness"] = False
            e["stiffness_cubic"] = True
            p["stiffness_cubic.k1_Nm_per_rad"] = K
            p["stiffness_cubic.k3_Nm_per_rad3"] = 2.0 * _ax(case, "stiffness_cubic.k3_Nm_per_rad3")
    elif eff == "hysteresis":
        e["hysteresis_maxwell"] = True
        e["hysteresis_preisach"] = z == 1
    elif eff == "backlash":
        b = (1.5e-4, 3e-4)[z]
        k1 = 0.02 * K
        p.update({"stiffness.k1_Nm_per_rad": k1, "stiffness.t1_Nm": k1 * b,
                  "stiffness.t2_Nm": k1 * b + 1.0, "stiffness.k2_Nm_per_rad": K, "stiffness.k3_Nm_per_rad": K})
    elif eff == "gravity_unbalance":
        e["gravity"] = True
        p["gravity.mgl_Nm"] = (1.0, 2.0)[z] * _ax(case, "gravity.mgl_Nm")
        p["gravity.offset_rad"] = float(rng.uniform(-math.pi, math.pi))
    elif eff == "current_loop_lag":
        p["current_loop.bandwidth_Hz"] = (150.0, 300.0)[z]
    elif eff in (None, "unmodelled_compliance"):
        pass
    else:
        raise ValueError(f"unknown effect {eff}")
    return p, e


#: Peak output speed of the closed-loop chirp's end (rad/s) and the drive's velocity limit
#: (rad/s): past the frequency where the chirp asks for more than the limit the axis
#: follows a triangle wave with current-limited reversals (large torsion and torque rate).
V_PEAK = 2.5
V_LIM = 0.5

#: Velocity-loop gains of the drive defaults (N.m.s/rad, N.m/rad at the output), tuned for
#: the reference axis' total inertia; other axes get them scaled by their inertia (same
#: bandwidth), else the smaller axis' loop limit-cycles at the current limit.
_VEL_KP_REF, _VEL_KI_REF = 204.2, 8019.0


def _total_inertia(case: Case) -> float:
    N = _ax(case, "gear.ratio")
    return _ax(case, "load.jl_kgm2") + N ** 2 * _ax(case, "motor.jm_kgm2")


def _scenario_text(case: Case, amp: float, f0: float, f1: float) -> str:
    axis = case.axis if case.axis == "reference" else AXES[case.axis]
    ref = Case(None)
    g = _total_inertia(case) / _total_inertia(ref)
    return f"""[scenario]
axis = {basic_string(str(axis))}
duration_s = {case.duration_s}
seed = {case.seed}
[controller]
mode = "position"
[controller.gains]
follow_err_max = 0.2
vel_trip = 0.48
pos_vlim = {V_LIM / (2 * math.pi):.6g}
vel_kp = {_VEL_KP_REF * g:.6g}
vel_ki = {_VEL_KI_REF * g:.6g}
[setpoint]
type = "chirp"
amplitude_rad = {amp}
f0_Hz = {f0}
f1_Hz = {f1}
t0_s = 0.05
t1_s = {case.duration_s}
"""




def open_loop_torque(case: Case, rng: np.random.Generator, dt: float, n: int) -> np.ndarray:
    """Designed open-loop motor torque of a case, N.m at the motor.

    Sum of (1) the nominal rigid-body feed-forward (inertia, viscous and Coulomb friction
    of the axis file) of a slow output sine -- amplitude 0.6-0.9 rad, peak speed
    0.4-0.6 rad/s, so the axis travels over many motor revolutions and passes slowly
    through low speeds in both directions -- and (2) a random-phase multisine, flat over
    2-45 Hz, sized so that its transmitted torque reaches about 1.5x the first knee
    torque T1 of the axis (torsion for stiffness/hysteresis, torque rate for the
    current loop, the torsional mode for compliance).  No feedback: the axis drifts
    a little, which is what an open-loop test does.
    """
    N = _ax(case, "gear.ratio")
    jm, jl = _ax(case, "motor.jm_kgm2"), _ax(case, "load.jl_kgm2")
    J = jm + jl / N ** 2
    fv = _ax(case, "friction_motor.viscous_Nms_per_rad") + _ax(case, "friction_load.viscous_Nms_per_rad") / N ** 2
    fc = _ax(case, "friction_motor.fc_pos_Nm") + _ax(case, "friction_load.fc_pos_Nm") / N
    t = np.arange(n) * dt
    A = float(rng.uniform(0.6, 0.9))
    vpk = float(rng.uniform(0.4, 0.6))
    w = vpk / A
    ramp = np.minimum(1.0, t / 0.3)
    v = vpk * np.sin(w * t) * ramp                     # output velocity, rad/s
    a = np.gradient(v, dt)
    u_ff = J * N * a + fv * N * v + fc * np.tanh(v / 0.01)
    # multisine: transmitted torque ~ N*u*jl/(jl + N^2 jm) below the mode
    T1 = _ax(case, "stiffness.t1_Nm")
    share = jl / (jl + N ** 2 * jm)
    lines = np.arange(2.0, 45.0, 0.5)
    ph = rng.uniform(0, 2 * np.pi, len(lines))
    ms = np.sin(2 * np.pi * lines[:, None] * t[None, :] + ph[:, None]).sum(axis=0)
    ms /= np.max(np.abs(ms))
    u_ms = 1.5 * T1 / (N * share) * ms * ramp
    return u_ff + u_ms


def make_log(case: Case, out_csv: str | Path) -> Path:
    """Simulate one case and write its log (CSV + sidecar) atomically.

    Closed loop: the drive's position loop follows a slow chirp (0.03-0.05 Hz up to
    2.5 rad/s, amplitude 0.8-1.1 rad) with the drive's velocity limit at 0.5 rad/s:
    large travel, slow reversals first, then a triangle wave with current-limited
    reversals.  Open loop: the plant alone driven by :func:`open_loop_torque`.
    The log holds ``t_s``, ``motor_angle_rad``, ``load_angle_rad`` (encoder readings)
    and ``motor_torque_Nm`` = Kt x measured current (the torque command for
    ``current_loop_lag`` cases).  The sidecar records the case under ``"case"``.
    """
    rng = np.random.default_rng(1000 * case.seed + 17 * case.size + zlib.crc32((case.effect or "none").encode()) % 997
                                + 7 * (case.loop == "open") + 3 * (case.axis != "reference"))
    params, effects = plant_overrides(case, rng)
    kt = _ax(case, "motor.kt_Nm_per_A")
    N = _ax(case, "gear.ratio")
    out_csv = Path(out_csv)
    if case.loop == "closed":
        amp = float(rng.uniform(0.8, 1.1))
        f0 = float(rng.uniform(0.03, 0.05))
        f1 = float(rng.uniform(0.9, 1.1)) * V_PEAK / (2 * math.pi * amp)
        with tempfile.TemporaryDirectory() as td:
            sc = Path(td) / "case.toml"
            sc.write_text(_scenario_text(case, amp, f0, f1))
            r = sim.run_scenario(sc, params=params, effects=effects, seed=case.seed)
        cols = r.columns
        meta = dict(r.meta)
        meta.pop("columns", None)
        meta["scenario"] = case.label
        tq = cols["torque_cmd_Nm"] if case.effect == "current_loop_lag" else kt * cols["motor_current_A"]
        t = cols["t_s"]
    else:
        dt = 1e-4
        n = int(case.duration_s / dt)
        t = np.arange(1, n + 1) * dt
        u = open_loop_torque(case, rng, dt, n)
        o = sim.simulate_open_loop(u, params=params, effects=effects, axis=AXES[case.axis], dt_s=dt,
                                   seed=case.seed)
        cols = o
        tq = u if case.effect == "current_loop_lag" else kt * o["motor_current_A"]
        meta = {"source": "hdservo.sim.simulate_open_loop", "axis": case.axis, "gear_ratio": float(N),
                "sample_period_s": dt, "seed": case.seed,
                "motor_encoder_counts_per_rev": int(2 ** _ax(case, "encoder_motor.bits")),
                "load_encoder_counts_per_rev": int(2 ** _ax(case, "encoder_load.bits"))}
    meta["gear_ratio"] = float(meta["gear_ratio"])
    meta["case"] = {"effect": case.effect, "axis": case.axis, "loop": case.loop, "seed": case.seed,
                    "size": case.size, "plant_overrides": params,
                    "effects_switched": {k: bool(v) for k, v in effects.items()},
                    "motor_torque_is": "command" if case.effect == "current_loop_lag" else "Kt x measured current"}
    logio.write_log(out_csv, {"t_s": t, "motor_angle_rad": cols["motor_angle_rad"],
                              "load_angle_rad": cols["load_angle_rad"], "motor_torque_Nm": tq}, meta)
    return out_csv


def model_for(case: Case) -> dict[str, Any]:
    """The ``--model`` content a case is analysed with (rigid for unmodelled_compliance)."""
    return {"structure": case.structure}
