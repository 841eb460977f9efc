"""Firmware controllers (ctypes, build/lib/libhdcontrol.so) against the
double-precision references in host/hdservo/refmodels, same inputs.

Tolerances (docs/control.md, "Quantisation tolerances"):
* PID: |fixed - real| <= 1 LSB per term (P, I, D, rounding of the sum) -> 3 LSB.
* observer: velocity within 2 LSB of 2^-32 turn/s + 1e-6 relative (the T constant
  in Q44 and the 2^-48 turn angle state), on an unquantised input.
* biquad chain: within 4 LSB of the signal (the output rounding of each section;
  the full-precision feedback keeps the notch's near-unit-circle poles from
  amplifying it, measured < 2).
* trajectory rate: bit-exact against the exact rational reference.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from hdservo import filters
from oracles.refmodels import biquad as ref_bq
from oracles.refmodels import trajectory as ref_traj
from oracles.refmodels.observer import ObserverRef
from oracles.refmodels.pid import PidRef

from control_lib import BqCoef, BqState, Obs, ObsCfg, Pid, PidCfg, Traj, TrajCfg, load


@pytest.fixture(scope="module")
def lib():
    return load()


def test_pid_matches_reference(lib) -> None:
    shift = 32
    cfg = PidCfg(100904141, 475648, 2000000, 289000000, shift, -(60 << 16), 60 << 16)
    ref = PidRef(cfg.kp / 2 ** shift, cfg.ki_dt / 2 ** shift, cfg.kd_fs / 2 ** shift, cfg.d_alpha / 2 ** 30,
                 cfg.out_min, cfg.out_max)
    s = Pid()
    lib.hd_pid_reset(s)
    rng = np.random.default_rng(1)
    worst = 0.0
    n_sat = 0
    for k in range(20000):
        r = int(2e8 * math.sin(2 * math.pi * k / 3000))
        m = int(2e8 * math.sin(2 * math.pi * (k - 700) / 3000) + rng.normal(0, 2e5))
        ff = int(rng.integers(-1000, 1000))
        y = lib.hd_pid_step(s, cfg, r, m, ff)
        yr = ref.step(r, m, ff)
        worst = max(worst, abs(y - yr))
        n_sat += int(s.saturated)
    assert worst <= 3.0, worst
    assert n_sat > 100          # the run exercised the limits and anti-windup


def test_observer_matches_reference(lib) -> None:
    cfg = ObsCfg()
    bw, zeta = 30.0, 1.0
    lib.hd_velobs_design(cfg, round(2 * math.pi * bw * 65536), round(zeta * 65536))
    s = Obs()
    lib.hd_velobs_reset(s, 0)
    ref = ObserverRef(bw, zeta, kp_dt=cfg.kp_dt / 65536, ki_dt=cfg.ki_dt / 65536)
    worst = 0.0
    for k in range(30000):
        th = 0.01 * math.sin(2 * math.pi * 0.7 * k * 1e-4) + 1e-6 * k      # turn
        raw = round(th * 2 ** 32)
        lib.hd_velobs_step(s, cfg, raw)
        v = lib.hd_velobs_vel_out(s) / 2 ** 32
        vr = ref.step(raw / 2 ** 32)
        worst = max(worst, abs(v - vr) * 2 ** 32)
    # the gains are quantised to Q16 (kp_dt, ki_dt): allow that relative error too
    kp_rel = abs(cfg.kp_dt / 65536 - 2 * zeta * 2 * math.pi * bw * 1e-4) / (2 * zeta * 2 * math.pi * bw * 1e-4)
    ki_rel = abs(cfg.ki_dt / 65536 - (2 * math.pi * bw) ** 2 * 1e-4) / ((2 * math.pi * bw) ** 2 * 1e-4)
    assert kp_rel < 1e-3 and ki_rel < 1e-3
    assert worst <= 2.0, worst


def test_observer_quantisation_noise_documented() -> None:
    """docs/control.md: 24-bit encoder at 10 kHz, observer 30 Hz -> velocity noise."""
    q = 2.0 ** -24                                     # turn
    g = ObserverRef(30.0, 1.0).noise_gain()
    sigma_deg_s = g * q / math.sqrt(12) * 360
    assert 1e-5 < sigma_deg_s < 5e-4


def test_biquad_chain_matches_reference(lib) -> None:
    secs = [filters.notch(50, 40, -20), filters.lowpass(1000)]
    raws = [filters.quantise(b) for b in secs]
    exact = [filters.dequantise(r) for r in raws]
    rng = np.random.default_rng(2)
    x = np.round(1e6 * np.sin(2 * np.pi * 45 * np.arange(20000) * 1e-4) + rng.normal(0, 1e4, 20000)).astype(int)
    states = [BqState() for _ in raws]
    coefs = [BqCoef(*r) for r in raws]
    y = np.empty(len(x))
    for k, xi in enumerate(x):
        v = int(xi)
        for st, c in zip(states, coefs):
            v = lib.hd_biquad_step(st, c, v)
        y[k] = v
    yr = ref_bq.chain(exact, x)
    err = np.max(np.abs(y - yr))
    assert err <= 4.0, err


def test_trajectory_rate_is_exact(lib) -> None:
    cfg = TrajCfg(round(60 / 360 * 2 ** 32), 1 << 30, round(1000 / 360 * 2 ** 16))
    s = Traj()
    for v in (1193, -1193, 11930, 119305, 987654):
        lib.hd_traj_reset(s, 0)
        lib.hd_traj_rate(s, cfg, v)
        for k in range(1, 5001):
            lib.hd_traj_step(s, cfg)
        assert s.p48 == ref_traj.rate_position_p48(5000, v)


def test_trajectory_sine_matches_reference(lib) -> None:
    cfg = TrajCfg(round(60 / 360 * 2 ** 32), round(100 / 360 * 2 ** 24), round(1000 / 360 * 2 ** 16))
    s = Traj()
    lib.hd_traj_reset(s, 0)
    amp, f = 1 << 22, 2.5
    assert lib.hd_traj_sine(s, 0, amp, round(f * 65536)) == 0
    worst = 0.0
    for k in range(1, 20001):
        lib.hd_traj_step(s, cfg)
        worst = max(worst, abs(s.pos - ref_traj.sine_position(k, 0.0, amp, f)))
    assert worst <= 4.0, worst          # sin in Q30 (~1 LSB) times amp/2^30, rounding
