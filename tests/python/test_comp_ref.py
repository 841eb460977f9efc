"""Fixed-point compensators (firmware/core) vs the double references (hdservo.compref).

The C code is reached through ctypes on build/lib/libhdcomp.so (mk/comp.mk, built
by ``make test`` before pytest).  Tolerances are in LSB of the firmware output
format and are quoted in docs/compensators.md.
"""
from __future__ import annotations

import ctypes as C
from pathlib import Path

import numpy as np
import pytest

from oracles import compref

ROOT = Path(__file__).resolve().parents[2]
LIB = ROOT / "build" / "lib" / "libhdcomp.so"

i32p = np.ctypeslib.ndpointer(np.int32, flags="C")
i64p = np.ctypeslib.ndpointer(np.int64, flags="C")
u32p = np.ctypeslib.ndpointer(np.uint32, flags="C")


@pytest.fixture(scope="module")
def lib() -> C.CDLL:
    if not LIB.exists():
        pytest.fail(f"{LIB} missing: run `make build/lib/libhdcomp.so`")
    so = C.CDLL(str(LIB))
    so.comp_stribeck_run.argtypes = [i32p, i32p, i32p, i32p, C.c_uint32]
    so.comp_lugre_run.argtypes = [i32p, i32p, i64p, i32p, i64p, C.c_uint32]
    so.comp_maxwell_run.argtypes = [C.c_uint32, i32p, i32p, C.c_int32, C.c_int32, i64p, i32p,
                                    i64p, C.c_uint32]
    so.comp_te_run.argtypes = [C.c_uint32, u32p, i32p, u32p, C.c_int32, C.c_int32, i64p, i64p,
                               i32p, C.c_uint32]
    so.comp_backstep_run.argtypes = [i32p, i32p, i64p, i64p, i32p, i32p, i32p, i32p, i64p,
                                     C.c_uint32]
    return so


def a32(x) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(x), dtype=np.int32)


def a64(x) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(x), dtype=np.int64)


# reference-axis scale helpers
DEG_S = 2.0**32 / 360.0            # 2^-32 turn/s per deg/s
NM = 2.0**16                       # Q16 per N.m


def stribeck_params(rng: np.random.Generator) -> tuple[list[int], list[int]]:
    def one() -> list[int]:
        fc = rng.uniform(2.0, 12.0)
        fs = fc * rng.uniform(1.0, 2.0)
        vs = rng.uniform(0.2, 2.0) * DEG_S
        fv = rng.uniform(0.0, 300.0)             # N.m/(turn/s)
        return [int(fc * NM), int(fs * NM), int(vs), int(fv * NM)]
    return one(), one()


@pytest.mark.parametrize("delta", [1, 2])
def test_stribeck_matches_reference(lib: C.CDLL, delta: int) -> None:
    rng = np.random.default_rng(10 + delta)
    worst = 0.0
    for _ in range(20):
        pos, neg = stribeck_params(rng)
        eps = int(rng.uniform(0.0, 0.01) * DEG_S)
        tmax = int(200 * NM)
        v = np.concatenate([rng.uniform(-60, 60, 500), rng.uniform(-2, 2, 500),
                            rng.uniform(-0.02, 0.02, 200)]) * DEG_S
        v = a32(np.round(v))
        cfg = a32(pos + neg + [delta, eps, 1 << 30, tmax, 0])
        out = np.zeros(len(v), np.int32)
        lib.comp_stribeck_run(cfg, v, a32(np.zeros(len(v))), out, len(v))
        ref = compref.stribeck_map(v, pos, neg, delta, eps, tmax)
        # tolerance: 2 LSB rounding + exp input quantised to 2^-16 (slope <= (fs-fc))
        tol = 2.0 + np.where(v >= 0, abs(pos[1] - pos[0]), abs(neg[1] - neg[0])) * 2.0**-15
        err = np.abs(out - ref)
        assert np.all(err <= tol), f"max err {err.max():.2f} LSB"
        worst = max(worst, float(err.max()))
    print(f"# stribeck delta={delta}: max |err| = {worst:.2f} LSB (Q16 N.m)")


def test_stribeck_zero_crossing_and_source(lib: C.CDLL) -> None:
    pos = [int(5 * NM), int(8 * NM), int(DEG_S), int(100 * NM)]
    neg = [int(6 * NM), int(10 * NM), int(DEG_S), int(120 * NM)]
    eps = int(0.001 * DEG_S)
    v = a32(np.arange(-100, 101) * (eps // 50))
    cfg = a32(pos + neg + [2, eps, 1 << 30, int(100 * NM), 0])
    out = np.zeros(len(v), np.int32)
    lib.comp_stribeck_run(cfg, v, a32(np.zeros(len(v))), out, len(v))
    assert out[v == 0][0] == 0
    assert np.all(np.diff(out) >= 0)                      # monotone through zero
    assert np.max(np.abs(np.diff(out))) < 0.05 * 10 * NM  # no jump (C1 smooth sign)
    # source selection: w_ref = 0 uses the estimate only
    cfg0 = a32(pos + neg + [2, eps, 0, int(100 * NM), 0])
    vr = a32(np.full(10, 5 * DEG_S))
    ve = a32(np.full(10, -5 * DEG_S))
    o1 = np.zeros(10, np.int32)
    lib.comp_stribeck_run(cfg0, vr, ve, o1, 10)
    assert np.all(o1 < 0)


def test_stribeck_cruise_source(lib: C.CDLL) -> None:
    """str_cruise_ticks: the reference velocity once v_ref has been constant that long, else w_ref."""
    pos = [int(5 * NM), int(8 * NM), int(DEG_S), int(100 * NM)]
    eps = int(0.001 * DEG_S)
    cfg = a32(pos + pos + [2, eps, 0, int(100 * NM), 5])       # w_ref 0 (estimate), cruise after 5 periods
    # v_ref: 0 (rest), then +0.001 deg/s (+-1 LSB jitter: still cruising), then a ramp, then 0
    slow = int(0.001 * DEG_S)
    vr = a32([0] * 4 + [slow, slow + 1, slow, slow - 1, slow, slow, slow, slow] + [slow + 1000 * k for k in range(1, 7)]
             + [0] * 4)
    ve = a32(np.full(len(vr), -5 * DEG_S))                     # estimate of the opposite sign
    out = np.zeros(len(vr), np.int32)
    lib.comp_stribeck_run(cfg, vr, ve, out, len(vr))
    src_ref = out > 0
    # rest: estimate; constant v_ref: the estimate for the first 5 periods of the run (the first
    # constant period is the one after the step from 0), then the reference; ramp and rest: estimate
    assert list(src_ref[:4]) == [False] * 4
    assert list(src_ref[4:12]) == [False] * 5 + [True] * 3
    assert not src_ref[12:].any()
    # off (cruise_ticks 0): the estimate throughout
    cfg[12] = 0
    lib.comp_stribeck_run(cfg, vr, ve, out, len(vr))
    assert np.all(out < 0)


def test_lugre_matches_reference(lib: C.CDLL) -> None:
    fc, fs, vs = int(8 * NM), int(12 * NM), int(1.0 * DEG_S)
    sigma0 = int(1.9e5 * 256)            # N.m/turn (3e4 N.m/rad) in Q8
    sigma1 = int(600 * NM)
    sigma2 = int(150 * NM)
    n = 20000
    t = np.arange(n) * compref.TS
    v = a32(np.round(3.0 * np.sin(2 * np.pi * 1.0 * t) * DEG_S))
    e = a64(np.round(1e-4 * np.sin(2 * np.pi * 3.0 * t) * 2**32))
    for k_obs in (0, int(50 * NM)):
        cfg = a32([fc, fs, vs, 2, sigma0, sigma1, sigma2, k_obs, int(200 * NM)])
        tau = np.zeros(n, np.int32)
        z = np.zeros(n, np.int64)
        lib.comp_lugre_run(cfg, v, e, tau, z, n)
        rt, rz = compref.lugre_run(v, e, fc, fs, vs, 2, sigma0, sigma1, sigma2, k_obs,
                                   int(200 * NM))
        err = np.abs(tau - rt)
        zerr = np.abs(z - rz) / max(1.0, np.abs(rz).max())
        print(f"# lugre k_obs={k_obs}: max |tau err| = {err.max():.2f} LSB, "
              f"max z rel err = {zerr.max():.2e}")
        assert err.max() <= 4.0
        assert zerr.max() < 2e-6
        # steady state: the Stribeck curve at constant velocity
    vc = a32(np.full(2000, int(5 * DEG_S)))
    cfg = a32([fc, fs, vs, 2, sigma0, 0, 0, 0, int(200 * NM)])
    tau = np.zeros(2000, np.int32)
    z = np.zeros(2000, np.int64)
    lib.comp_lugre_run(cfg, vc, a64(np.zeros(2000)), tau, z, 2000)
    g = compref.stribeck_g(np.array(5 * DEG_S), fc, fs, vs, 2)
    assert abs(tau[-1] - float(g)) <= 2.0


def test_maxwell_matches_reference_and_masing(lib: C.CDLL) -> None:
    rng = np.random.default_rng(3)
    nel = 8
    arcsec = 2.0**32 / 1296000.0
    d = a32(np.round(np.linspace(2, 60, nel) * arcsec))
    k = a32(np.round(rng.uniform(0.5e4, 3e4, nel) * 256))
    comp = int(1.0 / (3.1e4 * 2 * np.pi) * 2**44)   # 1/K1 in 2^-44 turn / N.m
    x = a64(np.cumsum(np.round(rng.normal(0, 3 * arcsec, 5000))))
    tau = np.zeros(len(x), np.int32)
    dth = np.zeros(len(x), np.int64)
    lib.comp_maxwell_run(nel, k, d, comp, int(500 * NM), x, tau, dth, len(x))
    rt, rd = compref.maxwell_run(x, k, d, comp, int(500 * NM))
    assert np.abs(tau - rt).max() <= 0.5 + 1e-9
    assert np.abs(dth - rd).max() <= 1.0
    print(f"# maxwell: max |tau err| = {np.abs(tau - rt).max():.3f} LSB, "
          f"max |dth err| = {np.abs(dth - rd).max():.3f} LSB")
    # Masing: from positive saturation, the reversal curve is the virgin curve x2
    amp = int(200 * arcsec)
    up = np.arange(0, amp + 1, int(arcsec))
    down = amp - np.arange(0, 2 * amp + 1, int(arcsec))
    xs = a64(np.concatenate([up, down]))
    t2 = np.zeros(len(xs), np.int32)
    d2 = np.zeros(len(xs), np.int64)
    lib.comp_maxwell_run(nel, k, d, comp, int(500 * NM), xs, t2, d2, len(xs))
    virgin = t2[:len(up)].astype(float)
    rev = t2[len(up):].astype(float)
    # T(x) on the reversal = T_r - 2 T_v((x_r - x)/2) for every even step
    for j in range(0, len(up) - 1, 2):
        assert abs(rev[j] - (virgin[-1] - 2 * virgin[j // 2])) <= 2.0


def test_te_matches_reference(lib: C.CDLL) -> None:
    rng = np.random.default_rng(5)
    order = np.array([1, 2, 4, 2, 6], np.uint32)
    arcsec = 2.0**32 / 1296000.0
    amp = a32(np.round(rng.uniform(-20, 20, len(order)) * arcsec))
    phase = rng.integers(0, 2**32, len(order), dtype=np.uint64).astype(np.uint32)
    k1 = int(3.1e4 * 2 * np.pi * 256)
    th = a64(rng.integers(-2**40, 2**40, 5000))
    dth = np.zeros(len(th), np.int64)
    tau = np.zeros(len(th), np.int32)
    lib.comp_te_run(len(order), order, amp, phase, k1, int(50 * NM), th, dth, tau, len(th))
    rd, rt = compref.te_run(th, order, amp, phase, k1, int(50 * NM))
    ed, et = np.abs(dth - rd).max(), np.abs(tau - rt).max()
    print(f"# te: max |dth err| = {ed:.3f} LSB (2^-32 turn), max |tau err| = {et:.3f} LSB")
    assert ed <= 1.0 + 1e-6 * np.abs(amp).sum()
    assert et <= 2.0


@pytest.mark.parametrize("lag_turn", [0.0, 6e-4])
def test_backstep_matches_reference(lib: C.CDLL, lag_turn: float) -> None:
    """The kernel against the double reference; with a held lag (lag_turn behind the reference)
    T_load winds past its configured box into the box widened by the friction bounds."""
    rng = np.random.default_rng(9)
    n = 5000
    J = 1.3 * 2 * np.pi
    c1 = c2 = 2 * np.pi * 8
    cfg = [int(c1 * NM), int(c2 * NM), int(J * NM), int(J * c1 * c2 / 4 * 256),
           int(0.01 * DEG_S), int(1.0 * DEG_S), int(2**32 / 360), int(150 * NM),
           int(2e3 * compref.TS * 2**24), int(2e3 * compref.TS * 2**24),
           int(5e2 * compref.TS * 2**24), int(2e3 * compref.TS * 2**24),
           0, 0, 0, int(-20 * NM), int(30 * NM), int(30 * NM), int(500 * NM), int(20 * NM)]
    th0 = a32([int(2 * NM), int(1 * NM), int(10 * NM), 0])
    t = np.arange(n) * compref.TS
    thd = np.round(0.01 * np.sin(2 * np.pi * 0.5 * t) * 2**32)
    wd = np.round(0.01 * 2 * np.pi * 0.5 * np.cos(2 * np.pi * 0.5 * t) * 2**32)
    ad = np.round(-0.01 * (2 * np.pi * 0.5)**2 * np.sin(2 * np.pi * 0.5 * t) * 2**24)
    theta = thd + np.round(rng.normal(0, 2e-6, n) * 2**32) - round(lag_turn * 2**32)
    omega = wd + np.round(rng.normal(0, 1e-4, n) * 2**32)
    u = np.zeros(n, np.int32)
    th = np.zeros(n * 4, np.int64)
    lib.comp_backstep_run(a32(cfg), th0, a64(theta), a64(thd), a32(omega), a32(wd), a32(ad),
                          u, th, n)
    ru, rth = compref.backstep_run(cfg, th0, theta, thd, omega, wd, ad)
    eu = np.abs(u - ru).max()
    eth = (np.abs(th.reshape(n, 4) - rth).max(axis=0) / 2.0**32)   # in Q16 LSB
    print(f"# backstep: max |u err| = {eu:.2f} LSB, max |theta_hat err| = {eth.max():.3f} Q16 LSB")
    assert eu <= 6.0
    assert eth.max() <= 2.0
    # the projection holds
    th4 = th.reshape(n, 4)
    for i in range(3):
        assert th4[:, i].min() >= cfg[12 + i] * 2**32 and th4[:, i].max() <= cfg[16 + i] * 2**32
    # T_load: the configured box widened by the friction bounds while the reference moves slowly
    widen = (cfg[16] + cfg[17]) * 2**32
    assert th4[:, 3].min() >= cfg[15] * 2**32 - widen and th4[:, 3].max() <= cfg[19] * 2**32 + widen
    if lag_turn > 0:
        assert th4[:, 3].max() > cfg[19] * 2**32       # the lag winds T_load past the load box
