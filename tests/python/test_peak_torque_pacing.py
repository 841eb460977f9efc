"""Peak torque into a locked output does not depend on the host's speed (virtual drive).

The saturated last step of the staircase is held for its drive time.  With fast pacing a host
that answered the capture upload late let the drive run on at the torque limit past
``torque_sat_time``: a TORQUE_SAT fault, and the headline fell back to the 50 N.m step
(42.1 instead of ~60.7 N.m; the LuGre row of a loaded comparison run).  The procedure runs
lock-step on the virtual drive, so a late host changes nothing.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from hdservo.cli import main
from hdservo.procedures import runner

ROOT = Path(__file__).parents[2]
SIM = ROOT / "build" / "bin" / "hdservo-sim"
needs_sim = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")


@needs_sim
def test_peak_torque_with_a_late_host(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    orig = runner.Bench.capture

    def late(self: runner.Bench, *a: object, **k: object) -> object:
        out = orig(self, *a, **k)
        time.sleep(1.0)                  # a loaded host: the upload's answer comes 1 s late
        return out
    monkeypatch.setattr(runner.Bench, "capture", late)
    js = tmp_path / "pk.json"
    assert main(["test", "peak-torque", "--sim", "-q", "--json", str(js)]) == 0
    r = json.loads(js.read_text())["results"]["peak-torque"]
    limit = r["conditions"]["torque_limit_Nm"]
    assert r["figures"]["fault_code"] == 0
    assert len(r["figures"]["delivered_Nm"]) == 6
    # the saturated step delivers the limit (within the gear's friction in the locked output)
    assert r["headline"]["peak_torque_Nm"] == pytest.approx(limit, rel=0.05)
