#!/usr/bin/env python3
"""How much the velocity loop rings the gear in a move, against load resonance / loop crossover.

The twist predictions (Preisach, compliance) need the torque the gear transmits.  The model
estimate (``pr_t_src`` 1) takes it as J_L a_ref plus friction and unbalance; the gear's hysteresis
branch at a stop is set by the last large swing of the real gear torque.  When the velocity loop
excites the load's resonance against the motor, the swings are several times J_L a_ref and the
model estimate misses them (docs/compensators.md section 13, "Download rule").

For each axis drawn by :func:`hdservo.axisgen.random_axes` (``--seeds``, seeds no rule was set on)
and each velocity-loop crossover of ``--bandwidths`` (the design rule's PI,
:func:`hdservo.closedloop_cases.velocity_pi`, at that crossover; position P and notch of the
axis' design), one 30 deg move of the positioning procedure's profile (100 deg/s^2) runs
semi-closed (``fb_config`` 1) with the fair PID on the axis' true model, and :func:`swing_ratio`
gives the gear's dynamic torque swing over J_L a_ref.  The ratio f_load / f_v with f_load =
sqrt(K1 / J_L) / 2 pi and f_v the configured crossover (vel_kp / (2 pi J_tot)) is the abscissa.

Writes ``build/results/twist_ringing.json``: one row per (axis, crossover).
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo import axisgen, compsetup, sim  # noqa: E402
from hdservo import closedloop_cases as cl  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402

#: Seeds of the axes (none of them was used to set a rule)
DEFAULT_SEEDS = (35, 42, 43, 46)
#: Velocity-loop crossovers, Hz (the design rule's 25 Hz and one below / above)
DEFAULT_BANDWIDTHS = (15.0, 25.0, 40.0)
#: The move: 30 deg at the positioning procedure's 30 deg/s and 100 deg/s^2
MOVE_DEG, VMAX_DEG_S, AMAX_DEG_S2 = 30.0, 30.0, 100.0
#: Swing (x J_L a_ref) taken as "several times what the model estimate predicts" by :func:`edge_ratio`
SWING_LIMIT = 2.0


def swing_ratio(t_s: np.ndarray, v_load_rad_s: np.ndarray, a_ref_rad_s2: float, after_s: float = -math.inf) -> float:
    """Peak-to-peak load acceleration of a move over twice the reference acceleration.

    J_L a_L is the gear torque less friction and unbalance, so the ratio is the gear's dynamic
    torque swing over the swing J_L a_ref the model estimate predicts (1 for a load that follows
    the reference rigidly).

    Parameters
    ----------
    t_s : ndarray
        Sample times, s (uniform).
    v_load_rad_s : ndarray
        Output (load) velocity, rad/s.
    a_ref_rad_s2 : float
        Reference acceleration of the move's profile, rad/s^2 (> 0).
    after_s : float
        Only samples from this time on, s (the end of the move: the ringing left at the stop).

    Returns
    -------
    float
        (max a_L - min a_L) / (2 a_ref) over the samples.
    """
    if not a_ref_rad_s2 > 0:
        raise ValueError(f"reference acceleration {a_ref_rad_s2!r} rad/s^2: expected > 0")
    t = np.asarray(t_s, dtype=float)
    a = np.gradient(np.asarray(v_load_rad_s, dtype=float), t)[t >= after_s]
    if a.size == 0:
        raise ValueError(f"no sample at or after {after_s!r} s")
    return float((np.max(a) - np.min(a)) / (2.0 * a_ref_rad_s2))


def run_one(axis: Path, f_v_hz: float, seed: int = 1) -> dict[str, Any]:
    """One semi-closed move of ``axis`` with the velocity loop at ``f_v_hz``; returns the row."""
    g = lambda k: float(sim.axis_param(k, str(axis)))  # noqa: E731
    n, jl, jm, k1 = g("gear.ratio"), g("load.jl_kgm2"), g("motor.jm_kgm2"), g("stiffness.k1_Nm_per_rad")
    jt = jl + n * n * jm
    ctl = cl.axis_controller(str(axis))
    gains = dict(ctl["gains"])
    gains.update(cl.velocity_pi(jt, f_v_hz))
    gains.update(compsetup.FAIR_GAINS)
    gains["fb_config"] = 1.0
    ctl["gains"] = gains
    amax = AMAX_DEG_S2 * math.pi / 180.0
    case = cl.Case("ring", "ptp", {"type": "move", "initial_rad": 0.0, "target_rad": math.radians(MOVE_DEG),
                                   "max_velocity_rad_s": math.radians(VMAX_DEG_S), "max_accel_rad_s2": amax,
                                   "t0_s": 0.2}, duration_s=2.2, log_decimation=1)
    r = cl.run_case(case, ctl, str(axis), seed=seed)
    vmax = math.radians(VMAX_DEG_S)
    t_end = 0.2 + math.radians(MOVE_DEG) / vmax + vmax / amax       # trapezoid (the move reaches vmax)
    f_v = compsetup.velocity_loop_hz(gains["vel_kp"], jt)
    f_load = compsetup.load_resonance_hz(k1, jl)
    return {"axis": axis.stem, "jl_kgm2": jl, "j_total_kgm2": jt, "f_load_hz": f_load, "f_v_hz": f_v,
            "resonance_over_loop": f_load / f_v,
            "swing_ratio": swing_ratio(r["t_s"], r["load_velocity_rad_s"], amax),
            "stop_swing_ratio": swing_ratio(r["t_s"], r["load_velocity_rad_s"], amax, after_s=t_end)}


def study(seeds: Sequence[int], bandwidths: Sequence[float], directory: Path) -> list[dict[str, Any]]:
    """Rows of :func:`run_one` for the first axis of every seed at every crossover."""
    rows = []
    for s in seeds:
        ax = axisgen.write_axes(directory / f"seed{s}", 1, seed=s)[0]
        for f in bandwidths:
            row = run_one(ax, f)
            row["seed"] = s
            print(f"seed {s} {ax.stem}: f_load {row['f_load_hz']:.1f} Hz, f_v {row['f_v_hz']:.1f} Hz, "
                  f"ratio {row['resonance_over_loop']:.2f}: swing {row['swing_ratio']:.2f} x J_L a_ref, "
                  f"after the move {row['stop_swing_ratio']:.3f}", flush=True)
            rows.append(row)
    return rows


def edge_ratio(rows: Sequence[Mapping[str, Any]], swing_limit: float) -> float | None:
    """Largest f_load / f_v at which a row's swing still exceeds ``swing_limit`` (None: no row does)."""
    hit = [float(r["resonance_over_loop"]) for r in rows if float(r["swing_ratio"]) > swing_limit]
    return max(hit) if hit else None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(DEFAULT_SEEDS), help="axisgen seeds")
    ap.add_argument("--bandwidths", type=float, nargs="+", default=list(DEFAULT_BANDWIDTHS),
                    help="velocity-loop crossovers, Hz")
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "build" / "results")
    a = ap.parse_args(argv)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as d:
        rows = study(a.seeds, a.bandwidths, Path(d))
    doc = {"rows": rows, "swing_limit": SWING_LIMIT, "edge_ratio": edge_ratio(rows, SWING_LIMIT),
           "rule_ratio": compsetup.RESONANCE_LOOP_RATIO, "run_time_s": time.monotonic() - t0}
    a.out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(a.out / "twist_ringing.json", doc)
    print(f"largest f_load / f_v with a swing > {SWING_LIMIT:g}: {doc['edge_ratio']}; "
          f"rule {compsetup.RESONANCE_LOOP_RATIO:g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
