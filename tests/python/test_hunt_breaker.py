"""The drive's standstill hunt breaker (``hold_*``, issue 10; docs/compensators.md section 1).

On the pitch-drive axis (``examples/pitch_drive``, option ``best``: Stribeck feed-forward on the
measured velocity) the relay at standstill usually dithers the axis at ~107 Hz (+-1-3"), but after
some stops it falls into a ~13 Hz cycle of +-10-20" (2 to 3 % of the in-process holds, 6 of 200 at
+25 deg).  With the breaker (``hold_ticks`` 2000) the same stops hold like the others.  In-process
holds after a 1 deg drive PTP move onto +25 deg (the plant shifted there), true output angle over
4-6 s, the seeds where the relay alone hunts.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from hdservo import compsetup
from hdservo.design import predict

EX = Path(__file__).resolve().parents[2] / "examples" / "pitch_drive"
AXIS = str(EX / "report" / "axis_csf-25-80_fl-050.toml")
ARCSEC = math.pi / 180.0 / 3600.0
DEG = math.pi / 180.0
#: sensor seeds whose hold after a -1 deg move onto +25 deg hunts with the relay alone: the
#: first four from seed 0 up (p-p of the 0.1 s means and RMS above 10 Hz both > 5"); which
#: stops hunt is chaotic, so the list follows the drive's arithmetic (the rate does not:
#: 2-6 % of the stops in each run of 120 seeds)
HUNT_SEEDS = (14, 69, 112, 140)


def _hold(ctl: dict[str, Any], seed: int) -> tuple[float, float]:
    """(peak-to-peak of the 0.1 s means, RMS above 10 Hz), arcsec, of the hold 4-6 s after the move."""
    plant = predict.shifted_plant(AXIS, 26.0 * DEG)
    sp = {"type": "ptp", "initial_rad": 0.0, "target_rad": -DEG, "t0_s": 0.1}
    r = predict.run(AXIS, predict._mode(ctl, "position"), sp, 6.0, decimation=1, seed=seed, plant=plant)
    t = np.asarray(r["t_s"])
    y = np.asarray(r["load_angle_true_rad"])[t >= 4.0] / ARCSEC
    y = y - y.mean()
    blocks = y[: y.size // 1000 * 1000].reshape(-1, 1000).mean(axis=1)
    spec = np.fft.rfft(y)
    spec[np.fft.rfftfreq(y.size, float(t[1] - t[0])) < 10.0] = 0.0
    return float(np.ptp(blocks)), float(np.sqrt(np.mean(np.fft.irfft(spec, y.size) ** 2)))


def _controller(hold_ticks: float) -> dict[str, Any]:
    ctl = dict(json.loads((EX / "design.json").read_text())["chosen"]["options"]["best"]["controller"])
    ctl["gains"] = dict(ctl["gains"], hold_ticks=hold_ticks)
    return ctl


def test_best_option_sets_the_breaker() -> None:
    assert compsetup.BEST_GAINS["hold_ticks"] == 2000.0


def test_breaker_ends_the_standstill_hunt() -> None:
    off = [_hold(_controller(0.0), s) for s in HUNT_SEEDS]
    on = [_hold(_controller(2000.0), s) for s in HUNT_SEEDS]
    print("relay alone (p-p 0.1 s means, RMS > 10 Hz):", [f"{a:.1f}/{b:.1f}" for a, b in off])
    print("with the breaker:", [f"{a:.1f}/{b:.1f}" for a, b in on])
    # the relay alone hunts after at least half of these stops (all four with the present arithmetic)
    assert sum(pp > 5.0 and hf > 5.0 for pp, hf in off) >= len(HUNT_SEEDS) // 2
    # with the breaker every one holds like an ordinary stop: the ~107 Hz dither only (p-p 1.6-3.0", 1.07" RMS)
    assert all(pp < 3.5 and hf < 1.5 for pp, hf in on)
