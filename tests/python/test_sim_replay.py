"""``hdservo.sim.replay_windows``: the plant replayed over windows from given states."""
from __future__ import annotations

import numpy as np
import pytest

from hdservo import sim


def _open_loop(n: int, dt: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    t = np.arange(n) * dt
    u = 0.3 * np.sin(2 * np.pi * 2 * t) + 0.2
    return u, sim.simulate_open_loop(u, axis="minimal", dt_s=dt)


def test_windows_from_the_true_state_reproduce_the_run() -> None:
    n, dt = 6000, 1e-4
    u, o = _open_loop(n, dt)

    def at_rows(c: str) -> np.ndarray:          # open-loop row i is the state after input i
        return np.r_[0.0, o[c][:-1]]
    tm, tl = at_rows("motor_angle_true_rad"), at_rows("load_angle_true_rad")
    wm, wl = at_rows("motor_velocity_rad_s"), at_rows("load_velocity_rad_s")
    st = np.arange(0, n, 500)
    x0 = np.c_[tm[st], wm[st], tl[st], wl[st]]
    a, b = sim.replay_windows(u, st, x0, axis="minimal", dt_s=dt)
    assert np.array_equal(a, tm) and np.array_equal(b, tl)
    # a window started elsewhere follows its own start, and only that window changes
    x1 = x0.copy()
    x1[3, 0] += 0.5
    a1, _ = sim.replay_windows(u, st, x1, axis="minimal", dt_s=dt)
    w = slice(st[3], st[4])
    assert a1[st[3]] == tm[st[3]] + 0.5 and np.all(a1[w][1:] != tm[w][1:])
    assert np.array_equal(a1[: st[3]], tm[: st[3]]) and np.array_equal(a1[st[4]:], tm[st[4]:])
    # rows before the first window are NaN
    a2, _ = sim.replay_windows(u, st[1:], x0[1:], axis="minimal", dt_s=dt)
    assert np.all(np.isnan(a2[: st[1]])) and np.array_equal(a2[st[1]:], tm[st[1]:])


@pytest.mark.parametrize("starts, msg", [([0, 0], "increasing"), ([5, 100000], "increasing"), ([-1], "increasing")])
def test_bad_windows_are_refused(starts: list[int], msg: str) -> None:
    u = np.zeros(1000)
    with pytest.raises(sim.SimError, match=msg):
        sim.replay_windows(u, starts, np.zeros((len(starts), 4)), axis="minimal")
    with pytest.raises(sim.SimError, match="shape"):
        sim.replay_windows(u, [0], np.zeros((2, 4)), axis="minimal")


def test_plant_stepped_by_the_caller_matches_the_open_loop_run() -> None:
    n, dt = 3000, 1e-4
    u, o = _open_loop(n, dt)
    cols = sim.open_loop_columns()
    with sim.Plant("minimal") as p:
        rows = np.vstack([p.run(u[i:i + 7], dt) for i in range(0, n, 7)])      # any chunking
    for c in ("t_s", "motor_angle_true_rad", "load_angle_true_rad", "motor_velocity_rad_s"):
        assert np.allclose(rows[:, cols.index(c)], o[c], rtol=0, atol=1e-12), c
    with pytest.raises(sim.SimError, match="closed"):
        p.run(u[:3])


def test_windows_start_with_the_given_hysteresis_memory() -> None:
    """With Maxwell-slip elements, the windows replay the run exactly only when they start
    with the elements where the run left them; relaxed elements change the replay."""
    n, dt = 4000, 1e-4
    t = np.arange(n) * dt
    u = 0.5 * np.sin(2 * np.pi * 3 * t)
    eff = {"hysteresis_maxwell": True}
    o = sim.simulate_open_loop(u, axis="minimal", effects=eff, dt_s=dt)
    tm = np.r_[0.0, o["motor_angle_true_rad"][:-1]]
    tl = np.r_[0.0, o["load_angle_true_rad"][:-1]]
    wm = np.r_[0.0, o["motor_velocity_rad_s"][:-1]]
    wl = np.r_[0.0, o["load_velocity_rad_s"][:-1]]
    st = np.array([0, 2000])
    x0 = np.c_[tm[st], wm[st], tl[st], wl[st]]
    relaxed = sim.replay_windows(u, st, x0, axis="minimal", effects=eff, dt_s=dt)[1]
    from hdservo.discrepancy.effects import stop_operator
    N = sim.axis_param("gear.ratio", "minimal")
    phi = tm / N - tl
    xi = np.repeat(phi[st][:, None], sim.max_maxwell(), axis=1)
    for i in range(int(sim.axis_param("hysteresis_maxwell.n_elements", "minimal"))):
        k = sim.axis_param(f"hysteresis_maxwell.e{i + 1}_k_Nm_per_rad", "minimal")
        w = sim.axis_param(f"hysteresis_maxwell.e{i + 1}_w_Nm", "minimal")
        xi[:, i] = (phi - stop_operator(phi, w / k))[st]
    given = sim.replay_windows(u, st, x0, axis="minimal", effects=eff, dt_s=dt, maxwell_xi=xi)[1]
    e_rel, e_giv = np.abs(relaxed[2000:] - tl[2000:]).max(), np.abs(given[2000:] - tl[2000:]).max()
    assert e_rel > 0 and e_giv < 0.1 * e_rel, (e_rel, e_giv)
    with pytest.raises(sim.SimError, match="maxwell_xi"):
        sim.replay_windows(u, st, x0, axis="minimal", effects=eff, dt_s=dt, maxwell_xi=np.zeros((2, 3)))
    assert sim.max_maxwell() == 8
