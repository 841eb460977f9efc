#!/usr/bin/env python3
"""Online Stribeck identification in the drive (hd_fric_est) against the batch fit, over CAN.

Per axis (reference, csf17_50): the batch friction fit of ``hdservo identify friction``
on the virtual drive, then the drive's own estimator during 20 s of the normal motion
profile (:func:`hdservo.ident.stribeck_online.normal_profile`): the time after which
every level stays within 5 % and both Stribeck velocities within 15 % of the batch
fit, and the final errors.  Then the same with the plant's friction drifting +30 %
(a 10 s ramp from 25 s of plant time; 90 s of profile): the time after the end of the
ramp from which the estimate stays within those targets of the drifted batch values.
Writes build/results/online_stribeck.json.
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

from hdservo import closedloop_cases as bl  # noqa: E402
from hdservo.cli import main  # noqa: E402
from hdservo.fileio import write_json_atomic  # noqa: E402
from hdservo.ident import stribeck_online as so  # noqa: E402
from hdservo.ident.friction import StribeckResult  # noqa: E402
from hdservo.procedures.runner import Target  # noqa: E402

AXES = {"reference": "reference", "csf17_50": str(ROOT / "sim" / "axes" / "csf17_50.toml")}
ONLY = sys.argv[1:]          # axis names to run (default: all)
PROFILE_S = 20.0
DRIFT = {"t_start_s": 25.0, "ramp_s": 10.0, "scale": 1.3}
DRIFT_PROFILE_S = 90.0
KEYS = ("fc_pos_Nm", "fc_neg_Nm", "fs_pos_Nm", "fs_neg_Nm", "vs_rad_s", "delta", "viscous_Nms_per_rad")


def gains(name: str) -> dict[str, float]:
    """The axis's baseline drive gains (hdservo.closedloop_cases; the defaults are the reference axis's)."""
    g = bl.axis_controller(name)["gains"]
    return {} if g == "defaults" else {k: float(v) for k, v in g.items()}


def batch_fit(axis: str, g: dict[str, float]) -> StribeckResult:
    with tempfile.TemporaryDirectory() as d:
        js = Path(d) / "batch.json"
        opts = [x for k, v in g.items() for x in ("--gain", f"{k}={v!r}")]
        rc = main(["identify", "friction", "--sim", axis, "--json", str(js), "-q"] + opts)
        if rc != 0:
            raise SystemExit(f"batch identification of {axis} failed ({rc})")
        s = json.loads(js.read_text())["results"]["stribeck"]
    return StribeckResult(**{k: float(s[k]) for k in KEYS})


def summary(r: dict) -> dict:
    out = {k: r[k] for k in ("time_to_target_s", "final_rel_error", "profile", "targets") if k in r}
    if "tracked_s" in r:
        out["tracked_s"] = r["tracked_s"]
        out["drift"] = r["drift"]
    out["final"] = r["final"]
    out["history"] = r["history"]
    return out


def main_() -> int:
    res: dict = {"axes": {}}
    for name, axis in AXES.items():
        if ONLY and name not in ONLY:
            continue
        g = gains(name)
        batch = batch_fit(axis, g)
        nominal = so.online_identification(Target(axis=axis, params=dict(g)), batch, PROFILE_S)
        drift = so.online_identification(Target(axis=axis, params=dict(g)), batch, DRIFT_PROFILE_S, drift=DRIFT)
        res["axes"][name] = {"gains": g, "batch": batch.to_dict(), "nominal": summary(nominal), "drift": summary(drift)}
        print(f"{name}: target after {nominal['time_to_target_s']} s; final errors "
              + ", ".join(f"{k} {100 * v:+.1f} %" for k, v in nominal["final_rel_error"].items())
              + f"; drift tracked {drift['tracked_s']} s after the ramp; final errors "
              + ", ".join(f"{k} {100 * v:+.1f} %" for k, v in drift["final_rel_error"].items()), flush=True)
    out = ROOT / "build" / "results" / "online_stribeck.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out, res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
