"""The Preisach table ``hdservo identify`` downloads has the gear's minor loops.

The identification (``Pipeline.hysteresis``) runs the ``forc`` experiment on the simulated rig (every
effect on: friction, TE, noise, quantisation) and fits the table the drive gets.  The drive runs it the
way its unit says: a torque -> twist image forward at the transmitted torque (``hd_preisach_step_p``),
a twist -> torque image through its inverse (``hd_preisach_inv_step_p``), both the firmware kernels
through ``build/lib/libhdcomp.so``.  Reference: the simulated plant itself, loaded quasi-statically
(``test_preisach_axis_table.plant_twist``).  Checked on the reference axis and on the heavy CSF-40-120
of ``hdservo.axisgen`` seed 55, where the semi-closed stops depend on these loops
(docs/compensators.md section 13): the width of the minor loop at a small held torque after swings
of 0.5, 1 and 1.5 T1 is within 15 % (plus one twist lattice step) of the gear's.
"""
from __future__ import annotations

import ctypes as C
import math
from types import SimpleNamespace

import numpy as np
import pytest

from hdservo import sim
from hdservo.ident import experiments as ex
from hdservo.ident import pipeline as pl
from hdservo.preisach_table import UNIT_GENERIC, UNIT_TORQUE_TWIST, PreisachTable

from test_preisach_axis_table import ARCSEC, TURN_LSB_RAD, _histories, _profile, heavy_axis, lib, plant_twist  # noqa: F401

__all__ = ["heavy_axis", "lib"]


def identified_table(axis: str) -> PreisachTable:
    """The table of ``Pipeline.hysteresis`` on the simulated rig; the torque range from the axis' T1
    (the stiffness fit's job, tested elsewhere)."""
    p = pl.Pipeline(ex.SimRunner(axis=axis, seed=11), pl.Settings(tune_velocity_loop=False))
    p.results["stiffness"] = SimpleNamespace(t1_Nm=sim.axis_param("stiffness.t1_Nm", axis))
    return p.hysteresis()["table"]


def drive_twist(lib: C.CDLL, table: PreisachTable, levels: list[float]) -> np.ndarray:
    """The drive's twist prediction (rad) at the end of each held torque of ``levels`` (N.m)."""
    torque, ends = _profile(levels, 60, 1)
    q = np.round(torque * 65536.0)
    w = table.words()
    if table.unit == UNIT_GENERIC:                   # twist -> torque: the inverse at the torque
        yd = np.ascontiguousarray(q, dtype=np.int64)
        p = np.zeros(len(yd), dtype=np.int32)
        y = np.zeros(len(yd), dtype=np.int64)
        assert lib.comp_preisach_inv_run(w, len(w), 0, yd, p, y, len(yd)) == 0
        return (table.u0 + p[ends].astype(float) * 2.0 ** table.in_shift) * TURN_LSB_RAD
    assert table.unit == UNIT_TORQUE_TWIST            # torque -> twist: forward at the torque
    p = np.ascontiguousarray([lib.comp_preisach_quantise(w, len(w), int(v)) for v in q], dtype=np.int32)
    y = np.zeros(len(p), dtype=np.int64)
    assert lib.comp_preisach_run(w, len(w), 0, 0, p, y, len(p)) == 0
    return y[ends].astype(float) * TURN_LSB_RAD


@pytest.mark.parametrize("which", ["reference", "heavy"])
def test_identified_table_has_the_gears_loop_width(lib: C.CDLL, heavy_axis: str, which: str) -> None:
    lib.comp_preisach_quantise.argtypes = [np.ctypeslib.ndpointer(np.uint32, flags="C"), C.c_uint32, C.c_int32]
    lib.comp_preisach_quantise.restype = C.c_int32
    lib.comp_preisach_run.argtypes = [np.ctypeslib.ndpointer(np.uint32, flags="C"), C.c_uint32, C.c_uint32,
                                      C.c_uint32, np.ctypeslib.ndpointer(np.int32, flags="C"),
                                      np.ctypeslib.ndpointer(np.int64, flags="C"), C.c_uint32]
    lib.comp_preisach_run.restype = C.c_int32
    axis = {"reference": "reference", "heavy": heavy_axis}[which]
    t1 = sim.axis_param("stiffness.t1_Nm", axis)
    table = identified_table(axis)
    # the twist resolution of the prediction: the inverse's twist lattice, or the forward output's LSB
    lattice = (2.0 ** table.in_shift if table.unit == UNIT_GENERIC else 1.0) * TURN_LSB_RAD * ARCSEC
    hs = _histories(t1)
    ends = [(plant_twist(axis, h)[-1] * ARCSEC, drive_twist(lib, table, h)[-1] * ARCSEC) for h in hs]
    for k in range(0, len(ends), 2):
        w_plant = ends[k][0] - ends[k + 1][0]
        w_drive = ends[k][1] - ends[k + 1][1]
        print(f"# {which}: loop width after +-{0.5 * (k // 2 + 1):.1f} T1: plant {w_plant:.2f}\", "
              f"identified table {w_drive:.2f}\"")
        assert w_plant > 0.0
        assert abs(w_drive - w_plant) <= 0.15 * w_plant + lattice, (which, k, w_plant, w_drive)


def test_twist_grid_rule() -> None:
    """Lattice step 2^10, at most 64 levels, every level inside the measured range; a range of less
    than one grid cell is refused."""
    from hdservo.errors import UserError
    from hdservo.ident import hysteresis as hy
    for rng in (1e-4, 5.8e-4, 7.4e-4, 2.5e-3, 2e-2):
        levels, sub, shift, u0 = hy.twist_grid(rng)
        cell = (1 << shift) << sub
        assert 2 <= levels <= hy.TWIST_LEVELS_MAX
        assert shift >= 10 and (shift == 10 or sub == 8)
        assert -u0 * hy.TWIST_LSB_RAD <= rng + 1e-15                 # inside the data
        assert (-u0 + cell / 2) * hy.TWIST_LSB_RAD > rng or levels == hy.TWIST_LEVELS_MAX  # as many as fit
        # the fewest sub-steps: with half the grid step the range needs more than 64 levels
        assert sub == 0 or 2 * rng / ((cell / 2) * hy.TWIST_LSB_RAD) > hy.TWIST_LEVELS_MAX - 1 - 1e-9
    with pytest.raises(UserError, match="twist range"):
        hy.twist_grid(0.0)
    with pytest.raises(UserError, match="grid level"):
        hy.twist_grid(1e-9)
