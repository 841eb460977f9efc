"""Shared, cached simulator experiments for the identification tests (short runs, decimated logs)."""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

from hdservo.ident import drive_runner as dr
from hdservo.ident import experiments as ex
from hdservo.ident import pipeline as pl
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


# ---- over CAN (virtual drive, lock-step) ----------------------------------------------------

#: the virtual drive binary (DriveSession starts it)
SIM_BIN = Path(os.environ.get("HDSERVO_SIM", truth.ROOT / "build" / "bin" / "hdservo-sim"))

CAN_SHORT = {
    "te_rotation": ex.TERotation(wg_revs=2, output_span_rad=0.0, settle_s=0.5),
    "gravity_sine": ex.GravitySine(amplitudes_rad=(0.8, 0.4), frequencies_Hz=(0.2, 0.4)),
    "friction_sweep": ex.FrictionSweep(v_min_rad_s=1e-3, v_max_rad_s=0.3, points=8, settle_s=0.3,
                                       min_window_s=0.2, max_window_s=1.0),
}
#: csf17_50: the gravity sine at half the frequency (the short one trips the drive's overspeed on the
#: light load) and the full friction sweep (the short one misses its Stribeck knee: Fs -8.7 %)
#: FRF over CAN: small signal (elements stick: the linearised gear) and 0.04 rad/s (partly slipping)
CAN_FRF = ex.FRFExcitation(amplitudes_rad_s=(0.005, 0.04))
CAN_DESIGNS = {"reference": {**CAN_SHORT, "frf": CAN_FRF},
               "csf17_50": {"te_rotation": CAN_SHORT["te_rotation"], "frf": CAN_FRF,
                            "gravity_sine": ex.GravitySine(amplitudes_rad=(0.8, 0.4), frequencies_Hz=(0.1, 0.2))}}
CAN_SEEDS = {"reference": 11, "csf17_50": 3}


@lru_cache(maxsize=None)
def over_can(name: str) -> pl.Pipeline:
    """TE, friction, the locked-output stiffness cycles and the FRF over CAN on one virtual drive session
    of the axis (the locked output through the virtual rig); every effect on, the fitter given only data."""
    axis = "reference" if name == "reference" else str(truth.AXES[name])
    with dr.DriveSession(axis=axis, seed=CAN_SEEDS[name], gains=gains(name)) as runner:
        p = pl.Pipeline(runner=runner, designs=CAN_DESIGNS[name],
                        settings=pl.Settings(torque_max_Nm=truth.TORQUE_MAX[name]))
        p.run("frf")            # first, as in `identify all` (fresh gear state; the TE fit uses its f_a)
        p.run("te")
        p.run("friction")
        p.run("stiffness")
        if runner.notes:
            raise RuntimeError(f"over CAN ({name}): {runner.notes}")
    return p
