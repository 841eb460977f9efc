#!/usr/bin/env python3
"""Minimum smooth rate below the ladder (issue 8): do the PID and the best combination tie?

Both are smooth on the whole min-rate ladder (down to 0.0001 deg/s), so the figure is "same".
This runs the PID and the best combination (hdservo.compsetup) on the virtual reference axis at
0.0001, 5e-5, 2e-5 and 1e-5 deg/s, each rung from rest on a fresh virtual drive exactly like a
ladder rung (profile move at ``traj_vmax`` = rate, settling >= 4 windows, 10 fixed-angle windows
of 3.6 arcsec), and records beside the output encoder the rig's true output angle, the drive's
reference and torque command and the true gear torque (load cell).  Per rung: rate stability and
accuracy from the encoder (what the procedure judges) and from the true angle (no encoder noise),
the true angle's window rates in 0.36 arcsec windows (min / max over the command), the reference's
rate error, and the torque command's mean, standard deviation and peak-to-peak.  The encoder
figure is compared with the measurement's own floor: a perfect ramp with the encoder's noise
(24 bits, 1 count RMS) and quantisation through the same fixed-angle timing.

Writes build/results/min_rate_below_ladder.json and build/results/min_rate_below_ladder.png.
About 4-6 min wall on the 2 loaded cores (8 rungs, two at a time).

Usage: tests/results/35_min_rate_below_ladder.py [--rates 1e-4,5e-5,2e-5,1e-5] [--out DIR]
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo import compsetup as cs  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402
from hdservo.procedures import closedloop as cl  # noqa: E402
from hdservo.procedures import metrics as mt  # noqa: E402
from hdservo.procedures.runner import DT, Bench, Target, open_bench  # noqa: E402
from hdservo.phase import unwrap_turns  # noqa: E402

TURN = 2 * math.pi
#: output encoder of the reference axis (sim/axes/reference.toml): bits, noise in counts RMS
ENC_BITS, ENC_NOISE_COUNTS = 24, 1.0
FINE_HDR = '0.36" min/max'


def target(ctrl: str) -> Target:
    """The PID baseline or the best combination (model of the reference axis, best gains)."""
    if ctrl == "pid":
        return Target(compensators=[])
    params = dict(cs.compensator_params("reference"))
    params.update(cs.best_gains("reference"))
    return Target(compensators=list(cs.BEST_NAMES), params=params)


def rung(ctrl: str, rate_deg_s: float) -> dict[str, Any]:
    """One rung from rest on a fresh virtual drive; figures and the traces (s, rad, N.m)."""
    rate = math.radians(rate_deg_s)
    settle = cl.rung_settle_s(rate_deg_s)
    win = cl.rate_window_rad(rate_deg_s)
    dur = (10 + cl.RECORD_MARGIN_WINDOWS) * win / rate
    decim = max(1, int(math.ceil(dur / 2000 / DT)))
    frames = int(math.ceil(dur / (decim * DT)))
    with open_bench(target(ctrl), cl.AXIS_SETUP) as b:
        b.rig.brake(False)
        b.enable("PROFILED POSITION")
        b.wait(0.5)
        with b.params({"traj_vmax": rate / TURN}):
            far = b.load_angle_rad() + rate * (settle + dur) * cl.RATE_REACH + math.radians(0.001)
            cl.pp_move_start(b, far)
            b.wait(settle)
            with b.rig.record(decim) as rec:
                cap = b.capture(["tick", "pos_out_lo", "pos_ref_lo", "torque_cmd"], frames, decim)
    tick = cap["tick"].astype(float)
    t = (tick - tick[0]) * DT
    enc = unwrap_turns(cap["pos_out_lo"], centred=False) * TURN
    ref = unwrap_turns(cap["pos_ref_lo"], centred=False) * TURN
    true = np.interp(tick, rec["tick"], rec["load_angle_true_rad"])
    gear = np.interp(tick, rec["tick"], rec["gear_torque_Nm"])
    tq = cap["torque_cmd"].astype(float) / 2 ** 16
    se = mt.rate_stability(t, enc, rate, win)
    st = mt.rate_stability(t, true, rate, win)
    fine = mt.fixed_angle_rates(t, true, win / 10) / rate
    return {"controller": ctrl, "rate_deg_s": rate_deg_s, "settle_s": settle, "window_s": win / rate,
            "reference_moved_throughout": cl.reference_moved_throughout(cap["pos_ref_lo"]),
            "reference_rate_error": float(np.polyfit(t, ref, 1)[0] / rate - 1),
            "encoder": {"windows": se["windows"], "stability": se["stability"], "accuracy": se["accuracy"],
                        "monotone": se["monotone"]},
            "true": {"stability": st["stability"], "accuracy": st["accuracy"], "monotone": st["monotone"],
                     "back_arcsec": st["max_backlash_rad"] / mt.ARCSEC,
                     "rate_min_max_0p36_arcsec": [float(fine.min()), float(fine.max())]},
            "torque_cmd_Nm": {"mean": float(tq.mean()), "std": float(tq.std()), "p2p": float(np.ptp(tq))},
            "gear_torque_Nm": {"mean": float(gear.mean()), "std": float(gear.std())},
            "_trace": {"t_s": t, "torque_Nm": tq, "true_err_arcsec": (true - true[0] - rate * t) / mt.ARCSEC}}


def encoder_floor(rate_deg_s: float, runs: int = 200, seed: int = 1) -> dict[str, float]:
    """Rate stability of a perfect ramp seen through the output encoder (noise + quantisation)."""
    rng = np.random.default_rng(seed)
    rate = math.radians(rate_deg_s)
    win = cl.rate_window_rad(rate_deg_s)
    t = np.linspace(0.0, (10 + cl.RECORD_MARGIN_WINDOWS) * win / rate, 2000)
    cnt = TURN / 2 ** ENC_BITS
    s = []
    for _ in range(runs):
        a = rate * t + rng.normal(0.0, ENC_NOISE_COUNTS * cnt, t.size) + rng.uniform(0.0, cnt)
        s.append(mt.rate_stability(t, np.floor(a / cnt) * cnt, rate, win)["stability"])
    return {"median": float(np.median(s)), "p95": float(np.percentile(s, 95))}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", default="1e-4,5e-5,2e-5,1e-5", help="rungs, deg/s, comma-separated")
    ap.add_argument("--out", type=Path, default=ROOT / "build" / "results", help="output directory")
    a = ap.parse_args()
    try:
        rates = [float(x) for x in a.rates.split(",")]
    except ValueError:
        print(f"--rates: expected numbers in deg/s separated by commas, got '{a.rates}'", file=sys.stderr)
        return 2
    if not rates or min(rates) <= 0:
        print(f"--rates: expected rates > 0 deg/s, got '{a.rates}'", file=sys.stderr)
        return 2
    jobs = [(c, r) for r in rates for c in ("pid", "best")]
    with cf.ThreadPoolExecutor(max_workers=2) as ex:
        res = list(ex.map(lambda j: rung(*j), jobs))
    floor = {f"{r:g}": encoder_floor(r) for r in rates}
    a.out.mkdir(parents=True, exist_ok=True)
    from hdservo.plotting import pyplot
    plt = pyplot()
    fig, ax = plt.subplots(2, len(rates), figsize=(4 * len(rates), 6), squeeze=False)
    for k, r in enumerate(rates):
        for x in res:
            if x["rate_deg_s"] != r:
                continue
            tr = x["_trace"]
            ax[0][k].plot(tr["t_s"], tr["torque_Nm"], lw=0.6, label=x["controller"])
            ax[1][k].plot(tr["t_s"], tr["true_err_arcsec"], lw=0.6, label=x["controller"])
        ax[0][k].set_title(f"{r:g} deg/s")
        ax[0][k].set_ylabel("torque command (N.m)")
        ax[1][k].set_ylabel("true output - ramp (arcsec)")
        ax[1][k].set_xlabel("time in the record (s)")
        for row in ax:
            row[k].grid(True)
            row[k].legend()
    fig.tight_layout()
    fig.savefig(a.out / "min_rate_below_ladder.png", dpi=90)
    for x in res:
        del x["_trace"]
    doc = {"axis": "reference", "seed": 1, "rungs": res, "encoder_floor_stability": floor}
    write_json_atomic(a.out / "min_rate_below_ladder.json", doc, indent=1)
    print(f"{'rate deg/s':>10} {'ctrl':>5} {'enc stab':>9} {'floor p95':>9} {'true stab':>9} {'enc acc':>8} "
          f"{'ref err':>8} {FINE_HDR:>14} {'torque mean/std N.m':>20}")
    for x in res:
        f = floor[f"{x['rate_deg_s']:g}"]
        print(f"{x['rate_deg_s']:>10g} {x['controller']:>5} {x['encoder']['stability']:9.4f} {f['p95']:9.4f} "
              f"{x['true']['stability']:9.4f} {x['encoder']['accuracy']:8.4f} {x['reference_rate_error']:+8.4f} "
              f"{x['true']['rate_min_max_0p36_arcsec'][0]:6.2f}/{x['true']['rate_min_max_0p36_arcsec'][1]:<6.2f} "
              f"{x['torque_cmd_Nm']['mean']:9.2f} / {x['torque_cmd_Nm']['std']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
