"""The drive's own excitation generator over CAN (0x5010, firmware/canopen/hd_app_co.c) on the
virtual drive: SDO refusals, the captured excitation against the commanded multisine / chirp,
and the FRF resonance of the reference axis measured with the drive's multisine.

The drive runs in lock-step with SYNC (``--pacing sync`` through
hdservo.procedures.runner.open_bench, which always stops it): every check is on loop ticks
and values, no wall-clock limit is asserted.
"""
from __future__ import annotations

import math
from pathlib import Path

import canopen
import numpy as np
import pytest

from hdservo.drive import EXC_SUB, SIGNALS
from hdservo.procedures import closedloop as cl
from hdservo.procedures import frequency as fq
from hdservo.procedures.runner import DT, Target, open_bench

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "build" / "bin" / "hdservo-sim"
pytestmark = pytest.mark.skipif(not SIM.exists(), reason="build/bin/hdservo-sim not built (make sim)")

LINEAR = {f"{k}.enabled": False for k in ("friction_motor", "friction_load", "hysteresis_maxwell",
                                            "hysteresis_preisach", "cogging", "transmission_error")}
AB_STATE, AB_VALUE, AB_HIGH = 0x08000022, 0x06090030, 0x06090031


def _abort(fn) -> int:
    with pytest.raises(canopen.SdoAbortedError) as e:
        fn()
    return e.value.code


def _run_capture(b, signals: list[str], frames: int, start) -> np.ndarray:
    """Arm, start the excitation (which triggers the capture), run drive time, upload."""
    d = b.drive
    d.arm_capture([SIGNALS[s] for s in signals], frames, 1)
    start()
    fq._wait_capture(b, frames)
    return fq._upload(b, len(signals))


def test_excitation_refusals_multisine_and_chirp_shapes() -> None:
    with open_bench(Target(plant=LINEAR), cl.AXIS_SETUP, lockstep=True) as b:
        d = b.drive
        assert d.has_excitation()
        sdo = d.node.sdo[0x5010]
        # out of range: standard aborts from the OD limits
        assert _abort(lambda: setattr(sdo[EXC_SUB["type"]], "raw", 7)) == AB_HIGH
        assert _abort(lambda: setattr(sdo[EXC_SUB["injection"]], "raw", 4)) == AB_HIGH
        # start with the power stage off: state refused
        d.excite("multisine", 0.5, lines=5, period_s=0.1, start=False)
        assert _abort(lambda: setattr(sdo[1], "raw", 1)) == AB_STATE
        assert d.excitation_state() == "idle"

        b.enable("CYCLIC SYNCHRONOUS POSITION")
        b.wait(0.05)
        # inconsistent configuration (PRBS order 8 has no LFSR): refused at start, nothing runs
        d.excite("prbs", 0.5, order=8, start=False)
        assert _abort(lambda: setattr(sdo[1], "raw", 1)) == AB_VALUE
        assert d.excitation_state() == "idle"

        # multisine: 5 lines of 0.5 N.m at k * 10 Hz (period 1000 loop periods), torque feed-forward
        amp, n, P = 0.5, 5, 1000
        w = _run_capture(b, ["exc", "tick"], 3 * P,
                         lambda: d.excite("multisine", amp, lines=n, period_s=P * DT))
        assert d.excitation_state() == "running"
        assert np.all(np.diff(w[:, 1]) == 1)                        # one frame per loop period
        x = w[:, 0] / 2 ** 16
        t = np.arange(x.size)
        model = sum(amp * np.sin(2 * np.pi * (i * t / P - i * (i - 1) / (2 * n))) for i in range(1, n + 1))
        assert np.max(np.abs(x - model)) < 1e-3 * amp                # sample by sample, from the first period
        X = np.abs(np.fft.rfft(x)) * 2 / x.size
        lines = 3 * np.arange(1, n + 1)                              # three periods: line k at bin 3k
        assert X[lines] == pytest.approx(np.full(n, amp), rel=1e-3)
        others = np.delete(X, lines)
        assert np.max(others) < 1e-3 * amp
        assert np.sqrt(np.mean(x ** 2)) == pytest.approx(amp * math.sqrt(n / 2), rel=1e-3)
        d.stop_excitation()
        b.sync()
        assert d.excitation_state() == "idle"
        assert b.fault() == 0

        # chirp 5 -> 100 Hz over 0.2 s, 1 N.m; then the offset (0) and state done
        L, f0, f1 = 2000, 5.0, 100.0
        w = _run_capture(b, ["exc", "tick"], L + 500,
                         lambda: d.excite("chirp", 1.0, f0_Hz=f0, f1_Hz=f1, duration_s=L * DT))
        assert np.all(np.diff(w[:, 1]) == 1)
        x = w[:, 0] / 2 ** 16
        k = np.arange(L)
        ph = f0 * DT * k + (f1 - f0) * DT / L * k * (k - 1) / 2    # turns: sum of the linearly growing increment
        assert np.max(np.abs(x[:L] - np.sin(2 * np.pi * ph))) < 2e-3
        assert np.all(x[L:] == 0.0)
        assert d.excitation_state() == "done"
        # frequency law from the zero crossings: half a cycle between two crossings
        zc = np.where(np.diff(np.signbit(x[:L])))[0]
        tz = (zc + x[zc] / (x[zc] - x[zc + 1])) * DT                 # linear interpolation
        f_meas = 0.5 / np.diff(tz)
        f_law = f0 + (f1 - f0) * (0.5 * (tz[1:] + tz[:-1])) / (L * DT)
        assert zc.size >= 18
        assert np.max(np.abs(f_meas / f_law - 1)) < 0.03
        d.stop_excitation()
        b.sync()
        assert d.excitation_state() == "idle"
        assert b.fault() == 0


def test_frf_resonance_with_the_drive_multisine() -> None:
    with open_bench(Target(plant=LINEAR), cl.AXIS_SETUP, lockstep=True) as b:
        r = fq.resonance(b, blocks=2)
        assert "drive multisine" in r.conditions["excitation"]
    # docs/plant.md: two-mass resonance 50.52 Hz, anti-resonance 39.63 Hz; lines every 1.25 Hz
    assert r.headline["resonance_hz"] == pytest.approx(50.52, rel=0.03)
    assert r.headline["anti_resonance_hz"] == pytest.approx(39.63, rel=0.05)
    assert r.figures["mean_coherence_load"] > 0.9
