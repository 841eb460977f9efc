"""Preisach table format (host <-> firmware) and the fixed-point model vs the double reference."""
from __future__ import annotations

import ctypes as C
from pathlib import Path

import numpy as np
import pytest

from oracles import compref
from hdservo.preisach import everett_from_density
from hdservo.preisach_table import PreisachTable, quantise_everett

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
    so.comp_preisach_load.argtypes = [u32p, C.c_uint32]
    so.comp_preisach_load.restype = C.c_int32
    so.comp_preisach_run.argtypes = [u32p, C.c_uint32, C.c_uint32, C.c_uint32, i32p, i64p,
                                     C.c_uint32]
    so.comp_preisach_run.restype = C.c_int32
    so.comp_preisach_inv_run.argtypes = [u32p, C.c_uint32, C.c_uint32, i64p, i32p, i64p,
                                         C.c_uint32]
    so.comp_preisach_inv_run.restype = C.c_int32
    so.comp_preisach_quantise.argtypes = [u32p, C.c_uint32, C.c_int32]
    so.comp_preisach_quantise.restype = C.c_int32
    return so


def make_table(levels: int, sub_bits: int, version: int = 7) -> PreisachTable:
    """Twist hysteresis (~1 arcmin loop) over +-20 N.m torque, mu = 1 + 0.4 (a - b)."""
    u = np.linspace(-20.0, 20.0, levels)
    mu = lambda a, b: 1.0 + 0.4 * (a - b) / 40.0        # noqa: E731
    e = everett_from_density(mu, u, n_sub=4)
    e *= (2.909e-4 / 2) / e[-1, 0]                       # E(P, 0) = half the loop height, rad
    step_q16 = 40.0 / (levels - 1) / (1 << sub_bits) * 65536.0
    in_shift = int(np.floor(np.log2(step_q16)))
    return quantise_everett(e, 2.0**32 / (2 * np.pi), sub_bits=sub_bits, in_shift=in_shift,
                            u0=int(-20 * 65536), unit=1, version=version)


def walk(rng: np.random.Generator, ptop: int, n: int) -> np.ndarray:
    p = np.clip(np.cumsum(rng.integers(-6, 7, n)) + ptop // 2, 0, ptop)
    return np.ascontiguousarray(p, dtype=np.int32)


def test_image_roundtrip_and_refusal(lib: C.CDLL) -> None:
    t = make_table(32, 0)
    w = t.words()
    assert lib.comp_preisach_load(w, len(w)) == 0
    t2 = PreisachTable.from_bytes(t.to_bytes())
    assert t2.version == 7 and t2.crc == t.crc and np.array_equal(t2.entries, t.entries)
    bad = w.copy()
    bad[10 + 40] ^= 1                                    # one flipped bit in an entry
    assert lib.comp_preisach_load(bad, len(bad)) == -5
    with pytest.raises(ValueError, match="CRC"):
        PreisachTable.from_bytes(bad.astype("<u4").tobytes())
    bad = w.copy()
    bad[0] = 0
    assert lib.comp_preisach_load(bad, len(bad)) == -1
    t3 = make_table(8, 0)
    t3.entries[0] = 5                                    # E[0][0] != 0, CRC resealed
    t3.seal()
    w3 = t3.words()
    assert lib.comp_preisach_load(w3, len(w3)) == -4
    bad = w.copy()
    bad[2] += 1                                          # version is covered by the CRC
    assert lib.comp_preisach_load(bad, len(bad)) == -5


@pytest.mark.parametrize("levels,sub_bits", [(32, 0), (16, 2)])
def test_online_equals_bruteforce_and_double(lib: C.CDLL, levels: int, sub_bits: int) -> None:
    t = make_table(levels, sub_bits)
    w = t.words()
    rng = np.random.default_rng(levels + sub_bits)
    p = walk(rng, t.p_top, 1500)
    y_on = np.zeros(len(p), np.int64)
    y_bf = np.zeros(len(p), np.int64)
    assert lib.comp_preisach_run(w, len(w), 1, 0, p, y_on, len(p)) == 0
    assert lib.comp_preisach_run(w, len(w), 1, 1, p, y_bf, len(p)) == 0
    assert np.array_equal(y_on, y_bf)                    # exact, same integers
    ref = compref.preisach_bruteforce(t.grid(), sub_bits, p, deadband=1)
    err = np.abs(y_on - ref).max()
    print(f"# preisach L={levels} sub={sub_bits}: online == brute force; max |C - double| = {err:.2f} LSB")
    if sub_bits == 0:
        assert err == 0.0
    else:
        assert err <= 6.0


def test_quantise_matches_host(lib: C.CDLL) -> None:
    t = make_table(32, 1)
    w = t.words()
    for u in (-2**31, -20 * 65536 - 5, -20 * 65536, 0, 12345678, 2**31 - 1):
        d = (u - t.u0) / 2.0**t.in_shift
        exp = int(min(max(np.sign(d) * np.floor(abs(d) + 0.5), 0), t.p_top))
        assert lib.comp_preisach_quantise(w, len(w), u) == exp


def test_inverse_round_trip(lib: C.CDLL) -> None:
    t = make_table(32, 2)
    w = t.words()
    rng = np.random.default_rng(1)
    ymax = t.entries[-1 - 0] if False else t.grid()[-1, 0]
    yd = np.clip(np.cumsum(rng.normal(0, ymax / 40, 2000)), -0.95 * ymax, 0.95 * ymax)
    yd = np.ascontiguousarray(np.round(yd), dtype=np.int64)
    p = np.zeros(len(yd), np.int32)
    y = np.zeros(len(yd), np.int64)
    assert lib.comp_preisach_inv_run(w, len(w), 0, yd, p, y, len(yd)) == 0
    # resolution: the largest output change of one lattice step anywhere
    g = t.grid().astype(float)
    step = 2 * np.max(np.abs(np.diff(g, axis=0))) / (1 << t.sub_bits)
    err = np.abs(y - yd)
    print(f"# preisach inverse: max |y - y_d| = {err.max()} LSB, lattice step <= {step:.0f} LSB")
    assert err.max() <= step / 2 + 1
