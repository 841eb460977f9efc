"""The Preisach table built from an axis file (``compsetup.preisach_table``) predicts the gear's twist.

The drive inverts the twist -> torque table at the transmitted torque (``hd_preisach_inv_step_p``,
the firmware kernel through ``build/lib/libhdcomp.so``).  Reference: the simulated plant itself,
loaded quasi-statically (motor torque T / N and load torque -T ramped slowly, friction, gravity,
TE, cogging and base motion off), its twist read at the end of each hold.  Checked on the two axis
files and on a heavy, stiff catalogue axis (``hdservo.axisgen`` seed 55, a CSF-40-120):

* the twist at every held torque, and
* the width of the minor loop at a small held torque after swings of 0.5, 1 and 1.5 T1 (twist
  after the last swing from above minus after the last swing from below), the quantity the
  semi-closed stops depend on (docs/compensators.md section 13).
"""
from __future__ import annotations

import ctypes as C
import math
from pathlib import Path

import numpy as np
import pytest

from hdservo import axisgen, sim
from hdservo import compsetup as cs
from hdservo.preisach_table import PreisachTable

ROOT = Path(__file__).resolve().parents[2]
LIB = ROOT / "build" / "lib" / "libhdcomp.so"
ARCSEC = 180.0 * 3600.0 / math.pi
TURN_LSB_RAD = 2.0 * math.pi / 2.0 ** 32
#: effects that are not the gear's spring and hysteresis
OFF = {e: False for e in ("friction_motor", "friction_load", "gravity", "transmission_error", "cogging", "base")}


@pytest.fixture(scope="module")
def lib() -> C.CDLL:
    if not LIB.exists():
        pytest.fail(f"{LIB} missing: run `make build/lib/libhdcomp.so`")
    so = C.CDLL(str(LIB))
    so.comp_preisach_inv_run.argtypes = [np.ctypeslib.ndpointer(np.uint32, flags="C"), C.c_uint32, C.c_uint32,
                                         np.ctypeslib.ndpointer(np.int64, flags="C"),
                                         np.ctypeslib.ndpointer(np.int32, flags="C"),
                                         np.ctypeslib.ndpointer(np.int64, flags="C"), C.c_uint32]
    so.comp_preisach_inv_run.restype = C.c_int32
    return so


@pytest.fixture(scope="module")
def heavy_axis(tmp_path_factory: pytest.TempPathFactory) -> str:
    return str(axisgen.write_axes(tmp_path_factory.mktemp("axes"), 1, 55)[0])


def _profile(levels: list[float], ramp: int, hold: int) -> tuple[np.ndarray, np.ndarray]:
    """Torque per period (N.m): from 0, ramps of ``ramp`` periods to each level, held ``hold``; the
    index of the last period of each hold."""
    t = [0.0]
    ends = []
    for lv in levels:
        t += list(np.linspace(t[-1], lv, ramp)[1:]) + [lv] * hold
        ends.append(len(t) - 2)                      # row i is the state after input i (t[0] is input 0)
    return np.array(t), np.array(ends)


def plant_twist(axis: str, levels: list[float]) -> np.ndarray:
    """The plant's twist (rad) at the end of each held transmitted torque of ``levels`` (N.m)."""
    n = sim.axis_param("gear.ratio", axis)
    torque, ends = _profile(levels, 3000, 2000)       # 0.3 s ramps, 0.2 s holds at 10 kHz
    r = sim.simulate_open_loop(torque / n, load_torque_Nm=-torque, axis=axis, effects=OFF)
    assert np.allclose(r["transmitted_torque_Nm"][ends], levels, atol=0.02 * max(map(abs, levels)))
    return r["torsion_rad"][ends]


def table_twist(lib: C.CDLL, table: PreisachTable, levels: list[float]) -> np.ndarray:
    """The drive's twist prediction (rad): the firmware inverse of ``table`` along the same torques."""
    torque, ends = _profile(levels, 60, 1)
    yd = np.ascontiguousarray(np.round(torque * 65536.0), dtype=np.int64)
    p = np.zeros(len(yd), dtype=np.int32)
    y = np.zeros(len(yd), dtype=np.int64)
    w = table.words()
    assert lib.comp_preisach_inv_run(w, len(w), 0, yd, p, y, len(yd)) == 0
    return (table.u0 + p[ends].astype(float) * 2.0 ** table.in_shift) * TURN_LSB_RAD


def _histories(t1: float) -> list[list[float]]:
    """From beyond the hysteresis' saturation (-2.5 T1), minor loops about T_f = 0.1 T1 of amplitude
    a: pairs ending from above (... +a, -a, +a, T_f) and from below (... +a, -a, T_f)."""
    tf = 0.1 * t1
    out = []
    for a in (0.5 * t1, 1.0 * t1, 1.5 * t1):
        out.append([-2.5 * t1, tf + a, tf - a, tf + a, tf])
        out.append([-2.5 * t1, tf + a, tf - a, tf])
    return out


@pytest.mark.parametrize("which", ["reference", "csf17_50", "heavy"])
def test_axis_table_predicts_the_plant_twist_and_loop_width(lib: C.CDLL, heavy_axis: str, which: str) -> None:
    axis = {"reference": "reference", "csf17_50": str(ROOT / "sim" / "axes" / "csf17_50.toml"),
            "heavy": heavy_axis}[which]
    t1 = sim.axis_param("stiffness.t1_Nm", axis)
    table = cs.preisach_table(axis)
    lattice = 2.0 ** table.in_shift * TURN_LSB_RAD * ARCSEC
    widths = []
    for h in _histories(t1):
        ph = plant_twist(axis, h) * ARCSEC
        pt_ = table_twist(lib, table, h) * ARCSEC
        for lv, a, b in zip(h[1:], ph[1:], pt_[1:]):   # the first level only saturates both
            assert abs(b - a) <= 0.1 * abs(a) + 1.0 + lattice, (which, h, lv, a, b)
        widths.append((ph[-1], pt_[-1]))
    for k in range(0, len(widths), 2):
        w_plant = widths[k][0] - widths[k + 1][0]
        w_table = widths[k][1] - widths[k + 1][1]
        print(f"# {which}: loop width after +-{0.5 * (k // 2 + 1):.1f} T1: plant {w_plant:.2f}\", table {w_table:.2f}\"")
        assert w_plant > 0.0
        assert abs(w_table - w_plant) <= 0.15 * w_plant + lattice, (which, k, w_plant, w_table)


def test_axis_table_covers_twice_t1(heavy_axis: str) -> None:
    """The lattice spans the elastic twist at +-2 T1 (the identification's torque range) and keeps its
    step at TABLE_LATTICE_LSB; the table's torque at its top end is above 2 T1."""
    for axis in ("reference", heavy_axis):
        t1 = sim.axis_param("stiffness.t1_Nm", axis)
        t = cs.preisach_table(axis)
        top_rad = (-t.u0) * TURN_LSB_RAD
        assert top_rad >= cs.table_range_rad(cs._reader(axis))
        assert 2 ** t.in_shift == cs.TABLE_LATTICE_LSB
        assert t.grid()[-1, 0] / 65536.0 > 2.0 * t1      # E(top, bottom): the output at saturation
