"""Run the identification experiments and fits in order, with timings.

Order (each step uses what the earlier ones found, never the truth):
te -> (frf) -> friction (gravity sine, sweep, Stribeck, online RLS) ->
lost motion (small position sine, TE removed) -> stiffness (locked cycles, TE removed) -> presliding (locked, small torque
steps, motor-side LuGre sigma0/sigma1) -> hysteresis
(FORCs on a grid chosen from the identified T1, Preisach table, held-out
minor loops).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..errors import UserError
from ..params_gen import BY_NAME
from . import experiments as ex
from . import friction as fr
from . import frf as frfm
from . import hysteresis as hy
from . import lost_motion as lm
from . import stiffness as stf
from . import stribeck_online as so
from . import te as tem
from . import tuning as tun

TARGETS = ("friction", "stiffness", "hysteresis", "te", "frf", "presliding", "lost_motion", "all")


@dataclass
class Settings:
    """Experiment settings a user may change (catalogue data, not the truth)."""

    torque_max_Nm: float = 67.0          # cycle amplitude of the stiffness test (>= 1.3 T2 to see K3)
    rated_torque_Nm: float | None = None  # for lost motion (+-4 %); default torque_max
    preisach_levels: int = 32
    maxwell_elements: int = 8
    #: set the velocity PI from the axis' inertia before the closed-loop experiments (ident/tuning.py)
    tune_velocity_loop: bool = True
    #: gain names the user fixed (``--gain``): never retuned
    fixed_gains: tuple[str, ...] = ()


@dataclass
class Pipeline:
    """Runs experiments through a runner (or takes recorded data) and collects results."""

    runner: Any | None
    settings: Settings = field(default_factory=Settings)
    progress: Callable[[str], None] = lambda m: None
    results: dict[str, Any] = field(default_factory=dict)
    data: dict[str, ex.ExperimentData] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    #: experiment designs replacing the defaults, by kind (shorter runs in tests, other speeds)
    designs: dict[str, Any] = field(default_factory=dict)

    def _design(self, default: Any) -> Any:
        return self.designs.get(default.kind, default)

    def _get(self, design: Any) -> ex.ExperimentData:
        design = self._design(design)
        if design.kind in self.data:
            return self.data[design.kind]
        if self.runner is None:
            raise UserError(f"no '{design.kind}' data given and no simulator/drive to run the experiment")
        if "tuning" not in self.results:
            self._torque_limit_for_experiments()
            self._tune_commissioned()
        t0 = time.perf_counter()
        d = self.runner.run(design)
        self.timings[f"run_{design.kind}_s"] = time.perf_counter() - t0
        self.data[design.kind] = d
        return d

    def _timed(self, name: str, fn: Callable[[], Any]) -> Any:
        t0 = time.perf_counter()
        out = fn()
        self.timings[f"fit_{name}_s"] = time.perf_counter() - t0
        return out

    def _tune(self, j_kgm2: float, source: str) -> None:
        """Velocity PI of the design rule for the inertia ``j_kgm2`` (user-fixed gains kept), recorded."""
        g = tun.without(tun.velocity_pi(j_kgm2), self.settings.fixed_gains)
        if g:
            self.runner.set_gains(g)
            self.progress(f"velocity loop for J = {j_kgm2:.4g} kg.m^2 ({source}): "
                          + ", ".join(f"{k} {v:.4g}" for k, v in g.items()))
        self.results.setdefault("tuning", []).append({"j_total_kgm2": j_kgm2, "source": source, "gains": g})

    def _torque_limit_for_experiments(self) -> None:
        """Before the first experiment: the drive's torque limit at least the gear's torque (``torque_max_Nm``).

        The moving experiments hold the axis at speed against the sliding friction of both sides
        plus the unbalance, and the FRF adds its multisine on top.  A drive commissioned with a
        torque limit below what the gear needs (the default 60 N.m on a large gear with high
        friction) clamps, and after ``torque_sat_time`` saturated periods trips on torque
        saturation (fault 1).  The gear's torque the user gives (``--torque-max``, also the
        stiffness cycle's amplitude) is the limit the identification runs with; the drive's own
        limit comes back when the runner closes (:meth:`DriveRunner.close`).  A limit the user
        fixes (``--set torque_limit=...``) stays; a runner that cannot read its limit (the
        standard-objects path) keeps it.
        """
        rec: dict[str, Any] = {"gear_torque_Nm": float(self.settings.torque_max_Nm)}
        self.results["torque_limit"] = rec
        if "torque_limit" in self.settings.fixed_gains or not hasattr(self.runner, "torque_limit_Nm"):
            rec["source"] = "the drive's own (fixed by the user or not settable)"
            return
        old = float(self.runner.torque_limit_Nm())
        new = min(BY_NAME["torque_limit"].max, float(self.settings.torque_max_Nm))   # the parameter's range
        rec["drive_Nm"] = old
        rec["experiments_Nm"] = max(old, new)
        if new > old:
            self.runner.set_gains({"torque_limit": new})
            rec["source"] = "raised to the gear's torque (--torque-max)"
            self.progress(f"torque limit for the experiments: {new:.4g} N.m (the gear's torque, --torque-max; "
                          f"the drive's own {old:.4g} N.m comes back at the end)")
        else:
            rec["source"] = "the drive's own (covers the gear's torque)"

    def _tune_commissioned(self) -> None:
        """Before the first experiment: the loop for the inertia the drive is commissioned with."""
        if not self.settings.tune_velocity_loop or not hasattr(self.runner, "set_gains"):
            self.results["tuning"] = []
            return
        self._tune(float(self.runner.commissioned_inertia_kgm2()), "commissioned j_total")

    def _retune_from_frf(self) -> None:
        """After the FRF: the loop for the identified J1 + J2 when it differs from the one in use."""
        done = self.results.get("tuning") or []
        if self.runner is None or not done:
            return
        j = tun.frf_inertia(self.results.get("frf"))
        if j is not None and tun.needs_retune(done[-1]["j_total_kgm2"], j):
            self._tune(j, "identified by the FRF")

    def te(self) -> tem.TEResult:
        if "te" not in self.results:
            d = self._get(ex.TERotation())
            fa = self.results["frf"][-1].f_antiresonance_Hz if self.results.get("frf") else None
            self.progress("fit: transmission error")
            self.results["te"] = self._timed("te", lambda: tem.fit_te(d, f_antiresonance_Hz=fa))
        return self.results["te"]

    def te_output(self) -> tem.TEResult:
        """The TE fitted again with the twist of the unbalance added back (output-side lines).

        Over an output revolution the gear twists with the unbalance it holds, mgl cos(theta + off),
        once per output revolution: the first fit takes that for output-side TE.  With the unbalance
        (gravity sine) and the hysteresis model (reversal curves) known, their twist is predicted
        along each window and added back.  Without output-side lines, or without those models,
        the first fit stands.
        """
        te = self.te()
        grav, pz = self.results.get("gravity"), self.results.get("preisach")
        if not te.out_orders or grav is None or pz is None or "te_rotation" not in self.data:
            return te
        ev = pz["everett"]
        d = self.data["te_rotation"]
        segs = [int(sg["index"]) for sg in d.segments]
        angles = [np.asarray(d.segment(i)["load_angle_rad"], dtype=float) for i in segs]

        def model(th_l: np.ndarray) -> np.ndarray:
            k = max(1, len(th_l) // 8000)              # the torque changes slowly: every k-th sample
            idx = np.arange(0, len(th_l), k)
            return np.interp(np.arange(len(th_l)), idx, ev.simulate(grav.holding_torque(th_l[idx])))
        # the hysteresis memory runs through the whole experiment on a drive (one motion); the
        # simulator binding starts every segment on a fresh plant
        if d.meta.get("source") == "simulator":
            tw = {i: model(a) for i, a in zip(segs, angles)}
        else:
            whole = model(np.concatenate(angles))
            cut = np.cumsum([0] + [len(a) for a in angles])
            tw = {i: whole[cut[j]:cut[j + 1]] for j, i in enumerate(segs)}

        def twist(index: int) -> np.ndarray:
            return tw[int(index)]
        fa = self.results["frf"][-1].f_antiresonance_Hz if self.results.get("frf") else None
        self.progress("fit: transmission error, output-side lines without the unbalance's twist")
        self.results["te"] = self._timed("te_output", lambda: tem.fit_te(self.data["te_rotation"],
                                                                        f_antiresonance_Hz=fa, twist_model=twist))
        return self.results["te"]

    def frf(self) -> list[frfm.FRFResult]:
        if "frf" not in self.results:
            d = self._get(ex.FRFExcitation())
            self.progress("fit: frequency response")
            self.results["frf"] = self._timed("frf", lambda: frfm.fit_frf(d))
            self._retune_from_frf()
        return self.results["frf"]

    def friction(self) -> fr.StribeckResult:
        if "stribeck" not in self.results:
            g = self._get(ex.GravitySine())
            self.progress("fit: unbalance and inertia")
            grav = self._timed("gravity", lambda: fr.fit_gravity(g))
            self.results["gravity"] = grav
            d = self._get(ex.FrictionSweep())
            self.progress("fit: Stribeck")
            pts = fr.sweep_points(d, grav)
            self.results["sweep"] = pts
            self.results["stribeck"] = self._timed("stribeck", lambda: fr.fit_stribeck(pts))
            if pts.samples:
                self.progress("online Stribeck (RLS over a vs grid)")
                self.results["stribeck_online"] = self._timed(
                    "stribeck_online", lambda: so.convergence(pts.samples, self.results["stribeck"]))
        return self.results["stribeck"]

    def stiffness(self) -> stf.StiffnessResult:
        if "stiffness" not in self.results:
            te = self.te() if (self.runner is not None or "te_rotation" in self.data) else None
            st = self.settings
            d = self._get(ex.LockedCycle(torque_max_Nm=st.torque_max_Nm, rated_torque_Nm=st.rated_torque_Nm))
            self.progress("fit: stiffness (three-slope + Maxwell-slip, cubic), hysteresis loss, lost motion")
            self.results["stiffness"] = self._timed(
                "stiffness", lambda: stf.fit_stiffness(d, te, max_elements=st.maxwell_elements))
        return self.results["stiffness"]

    def presliding(self) -> fr.PreslidingResult:
        """LuGre sigma0 (and sigma1 when the ring-down allows) of the motor-side friction, output locked."""
        if "presliding" not in self.results:
            sb = self.results.get("stribeck")
            if sb is not None:      # reversal sizes from the identified breakaway (total, output-referred)
                bk = 0.5 * (sb.fs_pos_Nm + sb.fs_neg_Nm)
                design = ex.PreslidingSteps(breakaway_Nm=bk,
                                            preload_Nm=max(2.0 * bk, 0.3 * self.settings.torque_max_Nm))
            else:
                design = ex.PreslidingSteps()
            d = self._get(design)
            jm = None
            if self.results.get("frf"):
                jm = self.results["frf"][-1].j1_kgm2 / d.gear_ratio ** 2
            self.progress("fit: LuGre presliding (sigma0, sigma1)")
            self.results["presliding"] = self._timed("presliding", lambda: fr.fit_presliding(d, jm_kgm2=jm))
        return self.results["presliding"]

    def lost_motion(self) -> lm.LostMotionResult:
        """Maxwell-slip lost-motion elements on the output travel (small position sine, TE removed)."""
        if "lost_motion" not in self.results:
            te = self.te() if (self.runner is not None or "te_rotation" in self.data) else None
            d = self._get(ex.LostMotionSine())
            self.progress("fit: lost motion (Maxwell-slip elements on the output travel)")
            self.results["lost_motion"] = self._timed(
                "lost_motion", lambda: lm.fit_lost_motion(d, te, max_elements=self.settings.maxwell_elements))
        return self.results["lost_motion"]

    def hysteresis(self) -> dict[str, Any]:
        if "preisach" not in self.results:
            st = self.stiffness()
            te = self.results.get("te")
            L = self.settings.preisach_levels
            # grid: the hysteresis lives below ~T1 (beyond, only the spring): +-max(2 T1, 0.3 T_max),
            # power-of-two step (firmware lattice)
            u0, step = hy.grid_for(max(2.0 * abs(st.t1_Nm), 0.3 * self.settings.torque_max_Nm), L)
            rng = -u0
            d = self._get(ex.ForcSet(torque_range_Nm=rng, levels=L))
            s = d.segment(0)
            phi = stf.twist_of(s, d.gear_ratio, te)
            self.progress("fit: Preisach Everett function from reversal curves")
            ev, info = self._timed("preisach", lambda: hy.everett_from_forcs(
                s["load_torque_Nm"], phi, s["torque_cmd_Nm"], L, step, u0))
            # the drive's table: the gear's own direction, twist -> torque, run through the inverse
            # (the torque -> twist model `ev` stays for the predictions on the host)
            gear = self._timed("preisach_gear", lambda: hy.gear_table_from_forcs(
                s["load_torque_Nm"], phi, s["torque_cmd_Nm"]))
            out: dict[str, Any] = {"everett": ev, "table": gear.table, "gear": gear, "info": info}
            m = self._get(ex.MinorLoops(torque_range_Nm=rng))
            ms = m.segment(0)
            mphi = stf.twist_of(ms, m.gear_ratio, te)
            out["minor_loops"] = hy.check_minor_loops(ev, ms["load_torque_Nm"], mphi, ms["torque_cmd_Nm"])
            # the downloaded image, quantised: torque predicted from the twist of the held-out loops
            out["minor_loops_quantised"] = hy.check_minor_loops(hy.dequantise_gear_table(gear.table),
                                                                mphi - gear.twist_offset_rad,
                                                                ms["load_torque_Nm"], ms["torque_cmd_Nm"])
            self.results["preisach"] = out
        return self.results["preisach"]

    def run(self, target: str) -> None:
        if target not in TARGETS:
            raise UserError(f"identify: unknown target '{target}' (expected one of {', '.join(TARGETS)})")
        steps = {"te": [self.te], "frf": [self.frf], "friction": [self.friction],
                 "stiffness": [self.stiffness], "hysteresis": [self.stiffness, self.hysteresis],
                 "presliding": [self.presliding], "lost_motion": [self.lost_motion],
                 "all": [self.frf, self.te, self.friction, self.lost_motion, self.stiffness, self.presliding,
                         self.hysteresis, self.te_output]}[target]
        t0 = time.perf_counter()
        for s in steps:
            s()
        self.timings["total_s"] = time.perf_counter() - t0


def summary(results: dict[str, Any]) -> dict[str, Any]:
    """JSON-ready view of every result."""
    out: dict[str, Any] = {}
    if results.get("tuning"):
        out["velocity_loop_tuning"] = list(results["tuning"])
    if results.get("torque_limit"):
        out["experiment_torque_limit"] = dict(results["torque_limit"])
    for k in ("te", "gravity", "stribeck", "stiffness", "presliding", "lost_motion"):
        if k in results:
            out[k] = results[k].to_dict()
    if "frf" in results:
        out["frf"] = [f.to_dict() for f in results["frf"]]
    if "stribeck_online" in results:
        o = dict(results["stribeck_online"])
        o.pop("max_rel_error_history", None)
        out["stribeck_online"] = o
    if "preisach" in results:
        p = results["preisach"]
        out["preisach"] = {**p["everett"].to_dict(), **p["info"], "crc": int(p["table"].crc),
                           "minor_loops": p["minor_loops"].to_dict(),
                           "minor_loops_quantised": p["minor_loops_quantised"].to_dict()}
        if "gear" in p:
            out["preisach"]["gear_table"] = p["gear"].to_dict()
    if "sweep" in results:
        s = results["sweep"]
        out["friction_sweep_points"] = {"v_rad_s": s.v_rad_s.tolist(), "torque_Nm": s.torque_Nm.tolist(),
                                        "rejected": s.rejected}
    return out


def arcmin(rad: float) -> float:
    return rad / (math.pi / 180 / 60)
