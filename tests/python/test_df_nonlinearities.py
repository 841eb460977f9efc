"""Describing functions of hdservo.analysis against python-control's numerical DF and known values."""
from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

from hdservo.analysis.friction import CoulombFriction, FrictionOnPosition, StribeckFriction
from hdservo.analysis.catalogue import build
from hdservo.analysis.hysteresis import LostMotion, MaxwellSlip, PreisachHysteresis
from hdservo.preisach import (EverettTable, PreisachModel, everett_table_from_density,
                              everett_table_plant, preisach_exponential_gaussian_density)
from hdservo.analysis.stiffness import CubicStiffness, ThreeSlopeStiffness


def numerical(factory, A, n=4000):
    """python-control's numerical DF of a fresh object per amplitude (warm-up at that amplitude)."""
    return complex(ct.describing_function(factory(), [A], num_points=n, try_method=False)[0])


def test_jenkins_known_value():
    # harmonic-drive.md section 7: k = 2, Delta = 1, A = 1.5 -> 1.4164 + 0.5659j
    n = MaxwellSlip([2.0], [2.0]).describing_function(1.5)
    assert n == pytest.approx(1.4164 + 0.5659j, abs=1e-4)
    assert MaxwellSlip([2.0], [2.0]).describing_function(0.9) == pytest.approx(2.0)


@pytest.mark.parametrize("A", [0.3, 1.0, 1.5, 4.0])
def test_maxwell_slip_against_numerical(A):
    f = lambda: MaxwellSlip([2.0, 1.0, 0.5], [0.6, 1.2, 1.0], k_parallel=3.0)  # noqa: E731
    assert f().describing_function(A) == pytest.approx(numerical(f, A), rel=2e-4, abs=2e-4)


@pytest.mark.parametrize("A", [0.6, 1.5, 10.0])
def test_lost_motion_against_python_control(A):
    ours = LostMotion(1.0).describing_function(A)
    theirs = complex(ct.describing_function(ct.friction_backlash_nonlinearity(1.0), [A])[0])
    assert ours == pytest.approx(theirs, abs=1e-12)
    assert ours == pytest.approx(numerical(lambda: LostMotion(1.0), A), abs=2e-3)
    assert LostMotion(1.0).describing_function(0.4) == 0


@pytest.mark.parametrize("A", [1e-3, 0.02, 0.1, 2.0])
def test_coulomb_against_numerical(A):
    f = CoulombFriction(0.1, 5e-4)
    assert f.describing_function(A) == pytest.approx(4 * 0.1 / (math.pi * A) + 5e-4)
    # python-control's sampling puts a sample at v = 0 (sign 0): real part matches to O(1/n)
    assert f.describing_function(A).real == pytest.approx(numerical(lambda: f, A, 20000).real, rel=1e-4)


@pytest.mark.parametrize("delta", [2.0, 1.0, 0.7])
@pytest.mark.parametrize("A", [0.05, 0.5, 2.0, 20.0])
def test_stribeck_against_numerical(delta, A):
    f = StribeckFriction(0.07, 0.1, 2.0, delta, 5e-4)
    assert f.describing_function(A).real == pytest.approx(numerical(lambda: f, A, 20000).real, rel=2e-4)


def test_stribeck_limits():
    f = StribeckFriction(0.07, 0.1, 2.0, 2.0)
    assert f.describing_function(1e-6) == pytest.approx(4 * 0.1 / (math.pi * 1e-6), rel=1e-6)
    assert f.describing_function(1e4) == pytest.approx(4 * 0.07 / (math.pi * 1e4), rel=1e-5)


@pytest.mark.parametrize("A", [1e-3, 0.01, 0.3])
def test_friction_on_position(A):
    w = 30.0
    p = FrictionOnPosition(StribeckFriction(0.07, 0.1, 2.0, 2.0), w)
    n = p.describing_function(A)
    assert n.real == 0
    num = p.numerical_df(A, 20000)  # samples hit v = 0 exactly: tiny spurious real part
    assert n.imag == pytest.approx(num.imag, rel=2e-4)
    assert abs(num.real) < 1e-3 * abs(n)
    c = FrictionOnPosition(CoulombFriction(0.1), w).describing_function(A)
    assert c == pytest.approx(4j * 0.1 / (math.pi * A))


@pytest.mark.parametrize("A", [1e-4, 4.5e-4, 1e-3, 3e-3, 1e-2])
def test_three_slope_against_numerical(A):
    f = lambda: ThreeSlopeStiffness(3.1e4, 5.0e4, 5.7e4, 14.0, 48.0)  # noqa: E731
    assert f().describing_function(A) == pytest.approx(numerical(f, A), rel=1e-5)


def test_three_slope_limits():
    t = ThreeSlopeStiffness(3.1e4, 5.0e4, 5.7e4, 14.0, 48.0)
    assert t.describing_function(t.phi1 * 0.99) == pytest.approx(3.1e4)
    assert t.describing_function(1.0).real == pytest.approx(5.7e4, rel=2e-3)
    assert t(t.phi1) == pytest.approx(14.0) and t(t.phi2) == pytest.approx(48.0)


@pytest.mark.parametrize("A", [1e-4, 1e-3, 3e-3])
def test_cubic_against_numerical(A):
    f = lambda: CubicStiffness(3.49e4, 5.5e9)  # noqa: E731
    assert f().describing_function(A) == pytest.approx(3.49e4 + 0.75 * 5.5e9 * A * A)
    assert f().describing_function(A) == pytest.approx(numerical(f, A), rel=1e-9)


# ---------------------------------------------------------------- Preisach

def brute_force_relays(alpha, beta, weight, u):
    """Sum of weighted relays, all starting at -1 (negative saturation)."""
    state = -np.ones_like(alpha)
    out = []
    for x in u:
        state = np.where(x >= alpha, 1.0, np.where(x <= beta, -1.0, state))
        out.append(float(weight @ state))
    return np.array(out)


def test_preisach_recursion_matches_relays():
    rng = np.random.default_rng(1)
    n = 300
    a = rng.uniform(-1, 1, n)
    b = rng.uniform(-1, 1, n)
    alpha, beta = np.maximum(a, b), np.minimum(a, b)
    wgt = rng.uniform(0.1, 1.0, n)

    def E(x, y):  # Everett of the discrete relay set: the weight inside T(x, y)
        if x <= y:
            return 0.0
        return float(wgt[(beta >= y) & (alpha <= x)].sum())

    u = np.clip(np.cumsum(rng.normal(0, 0.15, 1500)), -1.2, 1.2)
    model = PreisachModel(E, 1.0)
    ours = np.array([model(x) for x in u])
    ref = brute_force_relays(alpha, beta, wgt, np.clip(u, -1, 1))
    assert np.max(np.abs(ours - ref)) < 1e-9


@pytest.mark.parametrize("A", [0.3, 0.8, 1.6, 3.0])
def test_preisach_of_jenkins_everett_equals_maxwell_slip(A):
    k, w = np.array([2.0, 4.0]), np.array([2.0, 2.0])
    d = w / k
    E = lambda x, y: float(sum(ki * min(x - y, 2 * di) / 2 for ki, di in zip(k, d))) if x > y else 0.0  # noqa: E731
    p = PreisachHysteresis(PreisachModel(E, 5.0), num_points=4096, orientation="operator")
    assert p.describing_function(A) == pytest.approx(MaxwellSlip(k, w).describing_function(A), rel=1e-4, abs=1e-5)


def test_everett_table_converges_to_callable_and_loop_area():
    mu = preisach_exponential_gaussian_density(0.2, 0.4)
    fine = everett_table_from_density(mu, 1.0, 64, y_sat=1.0)
    coarse = everett_table_from_density(mu, 1.0, 16, y_sat=1.0)
    assert fine(1.0, -1.0) == pytest.approx(1.0) and fine(0.2, 0.2) == 0.0
    for A in (0.3, 0.7):
        nf = PreisachHysteresis(PreisachModel(fine, 1.0), orientation="operator").describing_function(A)
        nc = PreisachHysteresis(PreisachModel(coarse, 1.0), orientation="operator").describing_function(A)
        assert nc == pytest.approx(nf, rel=0.05)
        # |Im N| = W / (pi A^2): loop area from the steady cycle
        m = PreisachModel(fine, 1.0)
        th = np.linspace(0, 4 * np.pi, 8001)
        x = A * np.sin(th)
        y = np.array([m(v) for v in x])
        h = slice(4000, 8001)
        area = float(np.sum(0.5 * (y[h][1:] + y[h][:-1]) * np.diff(x[h])))
        assert abs(nf.imag) == pytest.approx(abs(area) / (math.pi * A * A), rel=1e-2)
        # relays with positive density lag: P alone is traversed against dissipation
        assert nf.imag < 0 and area < 0
        # the plant's torque P_mean - P: same loop, opposite orientation (dissipative), the
        # single-valued P_mean only adds to the real part
        npl = PreisachHysteresis(PreisachModel(fine, 1.0)).describing_function(A)
        assert npl.imag == pytest.approx(-nf.imag, rel=1e-9)
        assert npl.imag > 0


def _plant_twist_and_hysteresis(n: int = 12000):
    """C plant (Preisach only, output held by a huge load inertia): motor torque sine,
    first beyond the Preisach range, then inside it; returns twist (rad), hysteresis torque (N m)."""
    sim = pytest.importorskip("hdservo.sim")
    t = np.arange(n) * 1e-4
    amp = np.where(t < 0.6, 0.25, 0.09)  # N m at the motor: +-25 N m, then +-9 N m at the output
    tau = amp * np.sin(2 * np.pi * 5.0 * t)
    off = {e: False for e in ("friction_motor", "friction_load", "hysteresis_maxwell", "transmission_error",
                              "cogging", "gravity", "base", "encoder_motor", "encoder_load", "gyro",
                              "current_sensor")}
    out = sim.simulate_open_loop(tau, effects=dict(off, hysteresis_preisach=True),
                                 params={"load.jl_kgm2": 1e4})
    return t, out["torsion_rad"], out["hysteresis_torque_Nm"]


def test_preisach_torque_matches_the_simulated_plant():
    """The DF module's Preisach torque is the plant's: same Everett table, P_mean - P,
    the plant's demagnetised initial state; sample by sample on the plant's own twist."""
    from hdservo.analysis.axis import load_axis
    ax, _ = load_axis(None)
    u = ax["hysteresis_preisach.u_max_rad"]
    table = everett_table_plant(u, ax["hysteresis_preisach.t_sat_Nm"], ax["hysteresis_preisach.r0_rad"],
                                ax["hysteresis_preisach.s_rad"])
    t, phi, th = _plant_twist_and_hysteresis()
    assert np.max(np.abs(phi)) > u  # the first part wipes the memory out
    model = PreisachModel(table, u)
    model.demagnetise()
    el = PreisachHysteresis(model)
    ours = np.array([el(float(x)) for x in phi])
    assert np.max(np.abs(ours - th)) < 1e-6 * ax["hysteresis_preisach.t_sat_Nm"]
    # dissipative: energy absorbed over the last (minor-loop) cycles, oint T dphi > 0
    k = t >= 1.0
    assert float(np.sum(0.5 * (th[k][1:] + th[k][:-1]) * np.diff(phi[k]))) > 0
    # the catalogue element (K1 + Preisach) has Im N > 0 and its loop area matches
    nl = build("preisach", ax).nl
    A = 0.5 * u
    N = nl.describing_function(A)
    m = PreisachModel(table, u)
    x = A * np.sin(np.linspace(0, 4 * np.pi, 8001))
    y = np.array([m.mean(v) - m(v) for v in x])
    area = float(np.sum(0.5 * (y[4000:][1:] + y[4000:][:-1]) * np.diff(x[4000:])))
    assert area > 0 and N.imag == pytest.approx(area / (math.pi * A * A), rel=1e-2)


def test_everett_table_rejects_bad_shape():
    with pytest.raises(ValueError):
        EverettTable(np.zeros((3, 4)), 1.0)
