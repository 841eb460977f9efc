"""Hold vibration and positioning of the pitch-drive axis with a controller option (in-process).

Measures what the Stribeck feed-forward does at standstill (docs/compensators.md section 1,
"Standstill relay"): per sensor seed and direction, one drive PTP move of 1 deg onto +25 deg (the plant
shifted there: gravity, TE and cogging phases), then the hold; over 4-6 s the true output
angle gives the hold RMS about its mean, the RMS above 10 Hz (the relay chatter), the
peak-to-peak of its 0.1 s means (hunting), the dominant frequency and the mean deviation
from the target.  ``--positioning`` adds ``predict.positioning`` (scenario method, targets
-25/0/+25 deg, 2 runs).  ``--set NAME=VALUE`` overrides a drive parameter of the option (e.g.
``hold_ticks=0``: the best option without its standstill hunt breaker).  Uses ``build/lib/libhdsim.so`` (``$HDSERVO_SIMLIB`` overrides it, so
two firmware builds can be compared).

Usage (from the repository root)::

    .venv/bin/python examples/pitch_drive/hold_vibration.py [--option best] [--no-stribeck] [--positioning] [--set NAME=VALUE ...]
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "host"))

from hdservo.design import predict  # noqa: E402

ARCSEC = math.pi / 180.0 / 3600.0
DEG = math.pi / 180.0


def hold_figures(axis: str, ctl: dict[str, Any], seed: int, move_deg: float, at_deg: float = 25.0) -> dict[str, float]:
    """One move of ``move_deg`` ending at ``at_deg`` and its hold.

    Returns
    -------
    dict
        ``rms_arcsec`` (about the mean, 4-6 s), ``rms_hf_arcsec`` (above 10 Hz),
        ``pp_100ms_arcsec`` (peak-to-peak of 0.1 s means), ``f_peak_Hz``, ``dev_arcsec``
        (mean true angle minus target).
    """
    plant = predict.shifted_plant(axis, at_deg * DEG - move_deg * DEG)
    sp = {"type": "ptp", "initial_rad": 0.0, "target_rad": move_deg * DEG, "t0_s": 0.1}
    r = predict.run(axis, predict._mode(ctl, "position"), sp, 6.0, decimation=1, seed=seed, plant=plant)
    t = np.asarray(r["t_s"])
    y = np.asarray(r["load_angle_true_rad"])
    m = t >= 4.0
    dt = float(t[1] - t[0])
    yy = (y[m] - np.mean(y[m])) / ARCSEC
    n = int(round(0.1 / dt))
    blocks = yy[: (yy.size // n) * n].reshape(-1, n).mean(axis=1)
    f = np.fft.rfftfreq(yy.size, dt)
    spec = np.fft.rfft(yy)
    peak = float(f[int(np.argmax(np.abs(spec[1:]))) + 1])
    spec[f < 10.0] = 0.0
    hf = np.fft.irfft(spec, yy.size)
    return {"rms_arcsec": float(np.sqrt(np.mean(yy ** 2))), "rms_hf_arcsec": float(np.sqrt(np.mean(hf ** 2))),
            "pp_100ms_arcsec": float(np.ptp(blocks)), "f_peak_Hz": peak,
            "dev_arcsec": float((np.mean(y[m]) - move_deg * DEG) / ARCSEC)}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--option", default="best", help="controller option of the chosen design (default best)")
    p.add_argument("--no-stribeck", action="store_true", help="the option without its Stribeck feed-forward")
    p.add_argument("--seeds", default="1,2,3", help="sensor-noise seeds (default 1,2,3)")
    p.add_argument("--positioning", action="store_true", help="also the positioning scenarios (A/R)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a drive parameter on top of the option's gains (table unit), e.g. hold_ticks=0; repeatable")
    a = p.parse_args()
    design = json.loads((HERE / "design.json").read_text())
    opts = design["chosen"]["options"]
    if a.option not in opts:
        print(f"--option {a.option}: not an option of design.json; expected one of {', '.join(opts)}", file=sys.stderr)
        return 2
    ctl = dict(opts[a.option]["controller"])
    gains = dict(ctl.get("gains", {}))
    from hdservo.params_gen import BY_NAME as PARAMS
    for item in a.set:
        name, _, val = item.partition("=")
        try:
            if name not in PARAMS:
                raise ValueError
            gains[name] = float(val)
        except ValueError:
            print(f"--set {item!r}: expected NAME=VALUE with NAME a drive parameter and VALUE a number", file=sys.stderr)
            return 2
    ctl["gains"] = gains
    if a.no_stribeck:
        ctl["compensators"] = [c for c in ctl["compensators"] if c != "stribeck"]
    axis = str(HERE / "report" / "axis_csf-25-80_fl-050.toml")
    rows = []
    try:
        seeds = [int(s) for s in a.seeds.split(",")]
    except ValueError:
        print(f"--seeds {a.seeds!r}: expected comma-separated integers, e.g. 1,2,3", file=sys.stderr)
        return 2
    for seed in seeds:
        for move in (1.0, -1.0):
            h = hold_figures(axis, ctl, seed, move)
            rows.append(h)
            print(f"seed {seed} move {move:+.0f} deg: hold RMS {h['rms_arcsec']:.3f}\" (>10 Hz {h['rms_hf_arcsec']:.3f}\"), "
                  f"0.1 s means p-p {h['pp_100ms_arcsec']:.3f}\", peak {h['f_peak_Hz']:.1f} Hz, "
                  f"deviation {h['dev_arcsec']:+.3f}\"", flush=True)
    print(f"mean: hold RMS {np.mean([r['rms_arcsec'] for r in rows]):.3f}\", >10 Hz "
          f"{np.mean([r['rms_hf_arcsec'] for r in rows]):.3f}\", |deviation| "
          f"{np.mean([abs(r['dev_arcsec']) for r in rows]):.3f}\"")
    if a.positioning:
        r = predict.positioning(axis, ctl, [-25.0, 0.0, 25.0], runs=2, method="scenario")
        print(f"positioning (scenario, -25/0/+25 deg x 2 runs): A {r['A_arcsec']:.3f}\" R {r['R_arcsec']:.3f}\"")
    return 0


if __name__ == "__main__":
    sys.exit(main())
