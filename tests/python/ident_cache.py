"""Shared, cached simulator experiments for the identification tests (short runs, decimated logs)."""
from __future__ import annotations

from functools import lru_cache

from hdservo.ident import experiments as ex
from hdservo.ident import friction as fr
from hdservo.ident import stiffness as stf
from hdservo.ident import te as tem

import ident_truth as truth



def gains(name: str) -> dict[str, float]:
    """Velocity-loop gains for the axis: the drive defaults (tuned for the reference axis, total
    inertia 1.3 kg.m^2) scaled by the commissioned total inertia -- drive tuning, not identification."""
    a = truth.axis(name)
    j = a["load"]["jl_kgm2"] + a["gear"]["ratio"] ** 2 * a["motor"]["jm_kgm2"]
    sc = j / 1.3
    return {} if abs(sc - 1) < 1e-9 else {"vel_kp": 204.2 * sc, "vel_ki": 8019.0 * sc}


def runner(name: str, seed: int = 11, effects: dict | None = None) -> ex.SimRunner:
    return ex.SimRunner(axis=str(truth.AXES[name]), seed=seed, effects=effects or {}, gains=gains(name))


@lru_cache(maxsize=None)
def te(name: str) -> tem.TEResult:
    return tem.fit_te(runner(name).run(ex.TERotation()))


@lru_cache(maxsize=None)
def friction(name: str):
    r = runner(name)
    g = fr.fit_gravity(r.run(ex.GravitySine()))
    pts = fr.sweep_points(r.run(ex.FrictionSweep()), g)
    return g, pts, fr.fit_stribeck(pts)


@lru_cache(maxsize=None)
def locked(name: str):
    """Locked-output torque cycles, every effect on (Preisach, Maxwell-slip, TE, noise, quantisation)."""
    return runner(name).run(ex.LockedCycle(torque_max_Nm=truth.TORQUE_MAX[name]))


@lru_cache(maxsize=None)
def stiffness(name: str) -> stf.StiffnessResult:
    """Stiffness fit of :func:`locked` with the identified TE removed."""
    return stf.fit_stiffness(locked(name), te(name))
