"""Drive mode STAB (inertial stabilisation on the payload gyro) in the simulator.

Reference axis, every plant effect on, base rocking 0.5 deg at 1 Hz
(sim/scenarios/stabilise.toml).  The true inertial pointing angle is
load_angle_true_rad + base_angle_true_rad; the error is its deviation from the
value at mode entry (t = 0), analysed after 2 s.  DESIGN.md section 2 requires
<= 20 arcsec RMS.  docs/control.md "Stabilisation" has the figures.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from hdservo import sim

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[2]

SCEN = REPO_ROOT / "sim" / "scenarios" / "stabilise.toml"
ARCSEC = math.pi / 180 / 3600


def _run(tmp_path: Path, compensators: str, duration_s: float = 6.0, base: bool = True) -> dict:
    txt = SCEN.read_text()
    txt = re.sub(r"compensators = \[.*?\]", f"compensators = {compensators}", txt, count=1)
    txt = txt.replace("duration_s = 12.0", f"duration_s = {duration_s}")
    if not base:
        txt = txt.replace("base_amp_rad = 8.726646259971648e-3", "base_amp_rad = 0.0")
    p = tmp_path / "stab.toml"
    p.write_text(txt)
    r = sim.run_scenario(p)
    t = np.asarray(r["t_s"])
    th = np.asarray(r["load_angle_true_rad"]) + np.asarray(r["base_angle_true_rad"])
    e = (th - th[0])[t >= 2.0] / ARCSEC
    rel = np.asarray(r["load_angle_true_rad"])[t >= 2.0] / ARCSEC
    return {"rms": float(np.sqrt(np.mean(e ** 2))), "peak": float(np.max(np.abs(e))),
            "rel_pp": float(np.ptp(rel)), "fault": int(np.max(r["fault_code"])),
            "base_pp": float(np.ptp(np.asarray(r["base_angle_true_rad"]))) / ARCSEC}


def test_stabilise_meets_20_arcsec_rms(tmp_path: Path) -> None:
    r = _run(tmp_path, '["stribeck"]')
    print(f"# STAB + Stribeck FF, base 0.5 deg 1 Hz: inertial error {r['rms']:.2f} arcsec RMS, "
          f"peak {r['peak']:.1f}")
    assert r["fault"] == 0
    assert r["base_pp"] > 3500.0                      # the base really rocks +-0.5 deg
    assert r["rel_pp"] > 0.95 * r["base_pp"]          # the axis moves against it (not an encoder hold)
    assert r["rms"] <= 20.0                           # requirement (measured 11.2-11.5)
    assert r["peak"] <= 60.0                          # measured 40-41


def test_stabilise_pid_only_and_still_base(tmp_path: Path) -> None:
    pid = _run(tmp_path, "[]", duration_s=4.0)
    still = _run(tmp_path, '["stribeck"]', duration_s=4.0, base=False)
    print(f"# STAB without friction FF: {pid['rms']:.1f} arcsec RMS; base at rest: {still['rms']:.2f} RMS, "
          f"peak {still['peak']:.2f}")
    assert pid["fault"] == 0 and still["fault"] == 0
    # the gyro loop alone isolates by > 20x (base 1273 arcsec RMS); friction reversals dominate
    assert pid["rms"] < 1273.0 / 20
    # base at rest: no chatter of the friction feed-forward (dead band), only gyro drift/noise
    assert still["peak"] < 15.0
