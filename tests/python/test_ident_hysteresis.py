"""Preisach Everett from reversal curves, held-out minor loops, firmware table; stop operators."""
from __future__ import annotations

import numpy as np
import pytest

import ident_cache as cache
from hdservo import preisach_table as pt
from hdservo.ident import experiments as ex
from hdservo.ident import hysteresis as hy
from hdservo.ident import stiffness as stf

AXES = ["reference", "csf17_50"]


@pytest.mark.parametrize("name", AXES)
def test_preisach_predicts_held_out_minor_loops(name: str) -> None:
    r = cache.runner(name)
    te = cache.te(name)
    L = 32
    # the FORC range comes from the identified T1 (the stiffness fit, every effect on)
    u0, step = hy.grid_for(2 * cache.stiffness(name).t1_Nm, L)
    d = r.run(ex.ForcSet(torque_range_Nm=-u0, levels=L))
    s = d.segment(0)
    ev, info = hy.everett_from_forcs(s["load_torque_Nm"], stf.twist_of(s, d.gear_ratio, te), s["torque_cmd_Nm"],
                                     L, step, u0)
    assert info["forcs"] == L - 1
    # Everett of a non-negative density: positive, rising in alpha, falling in beta
    E = ev.table
    lo = np.tril(np.ones_like(E), -1) > 0
    assert np.all(E[lo] >= 0)
    assert np.all(np.diff(E, axis=0)[np.tril(np.ones((L - 1, L)), 0) > 0] >= -1e-15)
    m = r.run(ex.MinorLoops(torque_range_Nm=-u0))
    ms = m.segment(0)
    phi = stf.twist_of(ms, m.gear_ratio, te)
    chk = hy.check_minor_loops(ev, ms["load_torque_Nm"], phi, ms["torque_cmd_Nm"])
    assert chk.loop_width_rad > 0
    assert chk.rms_over_width <= 0.05
    tab = hy.quantise_table(ev, version=7)
    back = pt.PreisachTable.from_bytes(tab.to_bytes())
    assert back.crc == tab.crc and back.unit == pt.UNIT_TORQUE_TWIST
    q = hy.check_minor_loops(hy.dequantise_table(back, ev.offset_rad), ms["load_torque_Nm"], phi,
                             ms["torque_cmd_Nm"])
    assert q.rms_over_width <= 0.05


def test_identified_table_resolves_torque_inside_a_grid_cell() -> None:
    """The drive's twist from the identified torque -> twist image follows the torque between grid levels.

    A linear gear spring (K = 31000 N.m/rad) on the identification's grid (32 levels of 2 N.m from
    -31 N.m): on the ascending branch from negative saturation the firmware output is
    -E(P, 0) + 2 E(p, 0) at the lattice index p of the torque (rounded as hd_preisach_quantise), so
    holding 1.3 and 1.9 N.m must predict twists 0.6 N.m / K apart.
    """
    from oracles.compref import everett_lattice
    k, levels, step, u0 = 31000.0, 32, 2.0, -31.0
    grid = u0 + step * np.arange(levels)
    ev = hy.Everett(u0_Nm=u0, step_Nm=step, table=np.tril(np.subtract.outer(grid, grid)) / (2.0 * k))
    tab = hy.quantise_table(ev)
    g = tab.grid()
    p_top = (levels - 1) << tab.sub_bits

    def twist(t_nm: float) -> float:
        p = min(max(int(np.floor((round(t_nm * 65536) - tab.u0) / 2 ** tab.in_shift + 0.5)), 0), p_top)
        y = -everett_lattice(g, tab.sub_bits, p_top, 0) + 2.0 * everett_lattice(g, tab.sub_bits, p, 0)
        return y * hy.TWIST_LSB_RAD
    d = twist(1.9) - twist(1.3)
    assert d == pytest.approx(0.6 / k, rel=0.15)
    assert twist(1.3) == pytest.approx(1.3 / k, abs=0.0625 / k + 1e-9)


def test_stop_operator_and_masing_loop() -> None:
    phi = np.concatenate([np.linspace(0, 1, 50), np.linspace(1, -1, 100), np.linspace(-1, 1, 100)])
    s = hy.stop_operators(phi, np.array([0.25]))[:, 0]
    assert np.max(np.abs(s)) == pytest.approx(0.25)
    # after the first reversal from +1 the element follows phi - (1 - 0.25) until it saturates at -0.25
    k = 50 + 10
    assert s[k] == pytest.approx(phi[k] - 0.75)


def test_everett_memory_wipes_out() -> None:
    L = 9
    E = np.zeros((L, L))
    for i in range(L):
        for j in range(i):
            E[i, j] = 0.5 * (i - j) ** 2 / L ** 2
    ev = hy.Everett(u0_Nm=-4.0, step_Nm=1.0, table=E)
    seq = [-4, 3, -1, 2, -0.5, 3.5, 3]      # 3.5 wipes the (2, -0.5) loop and the (3, -1) loop
    y = ev.simulate(seq)
    y2 = ev.simulate([-4, 3.5, 3])
    assert y[-1] == pytest.approx(y2[-1], abs=1e-15)
