"""Compensator parameters of an axis, in the firmware's parameter-table units.

:func:`compensator_params` turns an axis model (for now the axis TOML's true
values, read through :func:`hdservo.sim.axis_param`; later the identified
model, which has the same keys) into the drive parameters of the compensator
bank (``firmware/app/hd_comp_bank.h``, parameter table entries ``cb_*`` /
``str_*`` / ``lug_*`` / ``mx_*`` / ``pr_*`` / ``te_*`` / ``bs_*`` in
``firmware/params/params.toml``), each value in its table unit (the unit of
``docs/parameters.md``; the harness and CANopen turn it into the raw word), and
:func:`preisach_table` builds the quantised Everett table (``preisach_table.py``
image) of the gear's twist -> torque hysteresis.

Models (output-referred; docs/compensators.md section 8):

* friction (Stribeck feed-forward, LuGre): the motor-side friction times N
  (torque) and N^2 (viscous, sigma1, sigma0) plus the load-side friction, on
  the output velocity; the Stribeck velocities of both sides agree on both
  axis files (motor vs / N = load vs), otherwise the torque-weighted mean;
* Maxwell-slip (lost motion at reversal): the identified lost-motion elements
  (``lost_motion.eK_gain`` / ``eK_d_rad``, twist per output travel, :mod:`hdservo.ident.lost_motion`)
  when the model has them; otherwise the load-side presliding friction
  ``F(x) = Fs (1 - exp(-sigma0_l x / Fs))`` fitted by ``n`` stop elements,
  turned into twist by the tangent stiffness of the gear (K1 + hysteresis
  elements);
* Preisach: the gear's static twist -> transmitted-torque operator of the plant
  (its three-slope or cubic spring, its Maxwell-slip elements, its Preisach part
  about the part's centre line), Everett function in closed form plus the
  plant's own Everett table, over the twist at +-2 T1, quantised;
* TE: the wave-generator harmonics (per motor revolution) and the two largest
  output-side harmonics (per output revolution, evaluated at the loop's output position);
* backstepping: the gains of docs/compensators.md section 6, scaled by J.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from . import preisach, preisach_table as pt
from . import sim
from .fileio import write_bytes_atomic
from .params_gen import BY_NAME as PARAM_DEFS

TWO_PI = 2.0 * math.pi
#: Smallest Maxwell-slip stiffness the firmware format holds, N.m/turn (above 2^52 / 2^31 / 2^8 = 2^13,
#: i.e. 1.3e3 N.m/rad: the compliance is 2^-44 turn/N.m in int32).
MX_STIFFNESS_MIN = 8200.0

#: Model key (``{"section.key": value}`` of :func:`compensator_params`) of the motor side's share of the
#: identified total friction, 0..1; set by :func:`hdservo.download.model_overrides`.
MOTOR_SHARE_KEY = "friction_total.motor_share"
#: Model key of the identified Stribeck shape exponent delta of the total friction (the drive's
#: feed-forward runs delta 2; the steady-motion rule, :func:`steady_motion_vs`, takes the plant's
#: friction drop in the shape the identification fitted); set by :func:`hdservo.download.model_overrides`.
FRICTION_DELTA_KEY = "friction_total.delta"

#: Velocity-loop crossover of the PID design rule, Hz (:func:`hdservo.closedloop_cases.velocity_pi`); the
#: crossover the drive runs is vel_kp / (2 pi J_tot) (:func:`velocity_loop_hz`), lower where vel_kp
#: reaches the drive's maximum or the gains are set otherwise (design flow, ``--gain``).
VEL_LOOP_HZ = 25.0
#: The twist torque estimate takes the motor side while the motor slides (``pr_t_src`` 2) when the load's
#: resonance against the held motor, sqrt(K1 / J_L) / 2 pi, is below this multiple of the crossover of the
#: velocity loop the drive runs (:func:`velocity_loop_hz`).  Measured by
#: tests/results/27_twist_source_edge.py on axes no rule was set on (docs/compensators.md section 13): the
#: motor side pays on seven of eight rows at ratios up to 1.27 (1.06-2.75x; one axis at 0.93 loses) and
#: costs on five of seven from 1.59 on (1.6-3.8x), also on axes with their loop moved from 40 to 15 Hz;
#: every factor between 1.28 and 1.58 makes the same choices there.
RESONANCE_LOOP_RATIO = 1.5
#: Reference-speed schedule of the scheduled position integral (cb_pki_vlo / cb_pki_vhi), deg/s.
PKI_V_LO_DEG_S = 0.002
PKI_V_HI_DEG_S = 0.005
#: Backstepping: corner of the integral action of the T_load adaptation, Hz.
BS_F_INT_HZ = 25.0
#: Smallest output clamp of the friction feed-forwards (``str_tau_max``, ``lug_tau_max``), N.m: the
#: parameters' default.  An axis whose fed-forward friction is larger gets a clamp from its levels
#: (:func:`feedforward_clamp`, :func:`friction_clamp`).
FF_TAU_MAX_MIN = float(PARAM_DEFS["str_tau_max"].default)


def feedforward_clamp(levels_Nm: "list[float] | tuple[float, ...]") -> float:
    """Output clamp of a friction feed-forward that does not cut its map: the largest level it carries.

    The largest static level of the feed-forward (either direction, output-referred), and at least
    :data:`FF_TAU_MAX_MIN`.  A clamp below the static level turns the map into a relay of the clamp
    at every reversal and leaves the rest of the friction to the velocity loop (docs/compensators.md
    section 1, "The feed-forward's clamp"); :func:`friction_clamp` cuts it only where the friction
    drop beats the loop.

    Parameters
    ----------
    levels_Nm : sequence of float
        The feed-forward's levels (Fs and Fc of each direction), N.m, output-referred.

    Returns
    -------
    float
        Clamp, N.m.
    """
    top = max((abs(float(v)) for v in levels_Nm if math.isfinite(float(v))), default=0.0)
    return max(FF_TAU_MAX_MIN, top)


def friction_clamp(directions: "list[tuple[float, float]]", steady_vs: float) -> float:
    """``str_tau_max`` by the documented rule: the fed-forward level, cut where the friction drop beats
    the loop.

    Near rest the Stribeck map runs on the measured velocity and relays its level.  Where the
    model's friction drop stays within the velocity loop's damping (the steady-motion threshold of
    :func:`steady_motion_vs` is its base value :data:`STR_STEADY_VS`), the clamp is the map's static
    level (:func:`feedforward_clamp`).  Where the drop beats the loop below a speed v* (the
    threshold > :data:`STR_STEADY_VS`), the clamp is the map's level at v*: below v* the map is flat
    (a relay of the sliding level the loop can hold), above it the map is the model's.  With the
    drive's delta-2 map that level is ``Fc + (Fs - Fc) exp(-(v*/vs)^2)`` per direction; one clamp
    holds both directions (the lower); never below :data:`FF_TAU_MAX_MIN`.

    Parameters
    ----------
    directions : list of (float, float)
        (Fs, Fc) of each direction as fed forward, N.m (output-referred).
    steady_vs : float
        The steady-motion threshold ``str_steady_vs`` of the model, in Stribeck velocities of the map.

    Returns
    -------
    float
        Clamp, N.m.
    """
    levels = [max(abs(float(fs)), abs(float(fc))) for fs, fc in directions]
    if not steady_vs > STR_STEADY_VS:
        return feedforward_clamp(levels)
    w = math.exp(-float(steady_vs) ** 2)
    return feedforward_clamp([min(abs(float(fc)) + (abs(float(fs)) - abs(float(fc))) * w for fs, fc in directions)])

ENABLE_BITS: dict[str, int] = {"stribeck": 1, "lugre": 2, "maxwell": 4, "preisach": 8, "te": 16, "backstep": 32,
                               "dob": 64, "approach": 128, "compliance": 256}
# "approach" is not a bank compensator: the drive's one-direction final approach of PTP
# moves (parameters appr_*, firmware/core/hd_trajectory.h, docs/control.md "Repeatability").


#: Stribeck feed-forward's steady-motion threshold (``str_steady_vs``), in Stribeck velocities of the
#: model, where the friction drop is no threat to the velocity loop: once the axis follows a reference
#: moving at |v_ref| >= vs / 8, the map takes the reference velocity until the reference falls below
#: that speed or reverses; near rest, at reversals and in the final arrival it takes the measured
#: velocity.  On the measured velocity a moving reference that never cruises (a sine) drives a
#: stick-slip oscillation of the feed-forward.  vs / 8 is the lowest threshold above the peak rate of
#: the slow tracking sine on the reference axis (0.1 deg/s = 0.087 vs): lower thresholds (vs / 16,
#: vs / 32) lower the reversal peak of the faster sine but raise the slow sine's tracking peak 4-6x
#: (docs/compensators.md section 11).  Where the friction drop is steeper than the velocity loop's
#: damping the threshold is higher (:func:`steady_motion_vs`).
STR_STEADY_VS = 1.0 / 8.0
#: Largest ``str_steady_vs`` the drive takes (its parameter range).
STR_STEADY_VS_MAX = 64.0


def friction_slope(v_rad_s: np.ndarray, sides: "list[dict[str, float]]") -> np.ndarray:
    """Slope dF/dv of the static friction map at v > 0, N.m.s/rad (output-referred).

    ``F(v) = sum over sides [Fc + (Fs - Fc) exp(-(v/vs)^delta)] + Fv v`` (positive direction); in the
    Stribeck hump the slope is negative: the friction drops as the speed rises.

    Parameters
    ----------
    v_rad_s : ndarray
        Speeds > 0, rad/s (output).
    sides : list of dict
        Per side ``fc``, ``fs`` (N.m), ``vs`` (rad/s), ``delta``, ``fv`` (N.m.s/rad), output-referred.

    Returns
    -------
    ndarray
        dF/dv at each speed, N.m.s/rad.
    """
    v = np.asarray(v_rad_s, dtype=float)
    out = np.zeros_like(v)
    for sd in sides:
        vs, d = float(sd["vs"]), float(sd["delta"])
        out += sd["fv"]
        if vs > 0.0 and d > 0.0 and sd["fs"] != sd["fc"]:
            r = v / vs
            out -= (sd["fs"] - sd["fc"]) * d * r ** (d - 1.0) / vs * np.exp(-r ** d)
    return out


def steady_motion_vs(sides: "list[dict[str, float]]", vs_rad_s: float, vel_kp_Nms_per_rad: float) -> float:
    """``str_steady_vs`` by the documented rule: the reference velocity only where the loop can hold steady sliding.

    In steady motion the map takes the reference velocity, so its torque no longer falls with the
    measured speed and the plant's own friction slope dF/dv acts on the velocity loop uncompensated.
    Sliding at v is then stable only while the loop's damping ``vel_kp`` exceeds the drop,
    ``-dF/dv < vel_kp``; below that the axis stick-slips around the reference (on the measured velocity
    the map cancels the drop).  The threshold is :data:`STR_STEADY_VS` where the whole map's drop stays
    below ``vel_kp``, else the speed above the Stribeck hump from which on it does.

    Parameters
    ----------
    sides : list of dict
        The friction sides (:func:`friction_slope`), output-referred; both directions are checked
        (keys ``fc``/``fs`` of the positive, ``fcn``/``fsn`` of the negative direction when present).
    vs_rad_s : float
        Stribeck velocity of the feed-forward (the unit of ``str_steady_vs``), rad/s.
    vel_kp_Nms_per_rad : float
        Velocity-loop gain the drive runs, N.m.s/rad.

    Returns
    -------
    float
        Threshold in units of ``vs_rad_s``, within [:data:`STR_STEADY_VS`, :data:`STR_STEADY_VS_MAX`].
    """
    if not (vs_rad_s > 0.0) or not sides:
        return STR_STEADY_VS
    kp = max(float(vel_kp_Nms_per_rad), 0.0)
    dirs = [list(sides), [{**sd, "fc": sd.get("fcn", sd["fc"]), "fs": sd.get("fsn", sd["fs"])} for sd in sides]]
    r = np.geomspace(1e-4, STR_STEADY_VS_MAX, 4000)            # speeds in units of vs
    unstable = np.zeros(r.size, dtype=bool)
    for sd in dirs:
        unstable |= -friction_slope(r * vs_rad_s, sd) >= kp
    if not unstable.any():
        return STR_STEADY_VS
    i = int(np.flatnonzero(unstable)[-1])
    if i + 1 >= r.size:
        return STR_STEADY_VS_MAX
    # the drop falls through vel_kp between r[i] and r[i + 1]: bisect there
    lo, hi = float(r[i]), float(r[i + 1])
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if any(-float(friction_slope(np.array([mid * vs_rad_s]), sd)[0]) >= kp for sd in dirs):
            lo = mid
        else:
            hi = mid
    return float(min(max(STR_STEADY_VS, hi), STR_STEADY_VS_MAX))

#: The best combination of the comparison (``hdservo compare`` / ``make demo``; docs/demo.md): one drive
#: configuration for every procedure.  Stribeck friction feed-forward on the *measured* velocity
#: (``str_w_ref`` 0: with the reference velocity the feed-forward differs between the fast and the
#: slow final arrivals, ISO R 3.7 arcsec) except in steady motion above the threshold of
#: :func:`steady_motion_vs` (from the model's parameters) and while
#: the reference cruises at a constant rate
#: (``str_cruise_ticks`` 200 = 20 ms of constant reference velocity: then the reference velocity; on
#: the measured velocity the map is a relay in the velocity loop, a ~95 Hz +-12 N.m limit cycle that
#: makes 0.001 deg/s jerky; docs/compensators.md), the one-direction final approach of PTP moves,
#: position P 60 1/s.  No scheduled position integral (``cb_pki`` 0): it turns the 0.01 deg/s rung into a
#: stick-slip limit cycle.  The drive's standstill hunt breaker (``hold_ticks`` 2000 = 0.2 s at rest, then an
#: error above ``hold_hunt_win`` 6" fades the Stribeck feed-forward to its mean over ``hold_fade_ticks`` 300
#: and back): the relay at rest sometimes falls into a ~13 Hz +-10-20" cycle instead of its ~107 Hz dither
#: (docs/compensators.md).  The stabilisation procedure runs in the drive's STAB mode (gyro).
BEST_NAMES: tuple[str, ...] = ("stribeck", "approach")
#: Procedure options of the best combination: the stabilisation test in the drive's STAB mode (gyro).
BEST_PROC_ARGS: dict[str, list[str]] = {"stabilisation": ["--stab-mode", "stab"]}
#: Retuned drive parameters of the best combination (table units), on top of the model's compensator parameters.
BEST_GAINS: dict[str, float] = {"pos_kp": 60.0, "str_w_ref": 0.0, "str_cruise_ticks": 200.0,
                                "hold_ticks": 2000.0}


#: Fair-comparison rule (docs/compensators.md, "Fair baselines"): every row of a comparison -- the PID
#: baseline, each compensator, the best combination, the leave-one-out rows -- runs with the loop gains
#: of the compensated set: the velocity PI and filters of the axis' PID design (velocity loop at 25 Hz on
#: every axis, :func:`hdservo.closedloop_cases.axis_controller`) and this position P, 60 1/s = 2 pi 25 Hz / 2.6
#: (the position loop a factor 2.6 below the velocity loop), scaled down on an axis whose load resonance is
#: below 1.5 x the velocity loop (:func:`fair_gains`).
FAIR_GAINS: dict[str, float] = {"pos_kp": 60.0}


def position_gain_scale(axis: str = "reference") -> float:
    """Factor on the position P for the bandwidth the load follows (:func:`fair_gains`).

    Parameters
    ----------
    axis : str
        "reference", "minimal", a shipped axis name or an axis TOML path (its K1 and J_L).

    Returns
    -------
    float
        min(1, f_load / (``RESONANCE_LOOP_RATIO`` x :data:`VEL_LOOP_HZ`)), f_load = sqrt(K1 / J_L) / 2 pi
        (:func:`load_resonance_hz`); 1 for an axis whose K1 or J_L cannot be read.
    """
    from .closedloop_cases import _axis_spec
    try:
        get = _reader(_axis_spec(axis))
        f_load = load_resonance_hz(get("stiffness.k1_Nm_per_rad"), get("load.jl_kgm2"))
    except (KeyError, ValueError, OSError, sim.SimError):
        return 1.0
    return min(1.0, f_load / (RESONANCE_LOOP_RATIO * VEL_LOOP_HZ))


def fair_gains(axis: str = "reference") -> dict[str, float]:
    """The fair loop gains of an axis (table units): :data:`FAIR_GAINS` with the position P the load follows.

    The position P is 2.6 times below the velocity loop the *load* follows.  The load follows the
    motor's velocity loop only below its own resonance on the gear: from
    ``RESONANCE_LOOP_RATIO`` x the velocity loop (:data:`VEL_LOOP_HZ`) down, the crossover the load
    sees is the load resonance over that ratio (the same boundary as the twist torque rule,
    :func:`twist_torque_source`), and the position P scales with it::

        pos_kp = 60 min(1, f_load / (RESONANCE_LOOP_RATIO VEL_LOOP_HZ)),   f_load = sqrt(K1 / J_L) / 2 pi

    With the full P on such an axis, a friction feed-forward that removes the friction's damping leaves
    the position loop on a load that rocks on the gear (docs/compensators.md section 13: stops hunting at ~12 Hz).

    Parameters
    ----------
    axis : str
        "reference", "minimal", a shipped axis name or an axis TOML path (its K1 and J_L).

    Returns
    -------
    dict
        ``{"pos_kp": 1/s}`` (:func:`position_gain_scale` x :data:`FAIR_GAINS`).
    """
    return {k: (float(v) * position_gain_scale(axis) if k == "pos_kp" else float(v)) for k, v in FAIR_GAINS.items()}


#: Every row runs each procedure in the same drive mode: the stabilisation test in the gyro mode (STAB).
FAIR_PROC_ARGS: dict[str, list[str]] = {"stabilisation": ["--stab-mode", "stab"]}
#: Settings a compensator carries when it is on (its configuration, the same on every axis): the
#: Stribeck feed-forward on the measured velocity, on the reference velocity while the reference
#: cruises at a constant rate or the axis follows it above the steady-motion threshold (docs/compensators.md
#: section 1).  The threshold ``str_steady_vs`` is not here: it depends on the axis' friction and velocity
#: loop and comes with the model's parameters (:func:`compensator_params`, :func:`steady_motion_vs`).
COMPONENT_PARAMS: dict[str, dict[str, float]] = {"stribeck": {"str_w_ref": 0.0, "str_cruise_ticks": 200.0}}
#: Motion strategies, reported as their own rows: name -> (cb_enable names, drive parameters).
#: ``hold``: the standstill hunt breaker (fades the friction feed-forward at rest); ``approach``: the
#: one-direction final approach of PTP moves.
STRATEGIES: dict[str, tuple[tuple[str, ...], dict[str, float]]] = {
    "hold": ((), {"hold_ticks": 2000.0}), "approach": (("approach",), {})}
#: Compensators that act on the same effect: the best combination takes at most one of each group.
GROUPS: dict[str, tuple[str, ...]] = {"friction": ("stribeck", "lugre", "backstep"),
                                      "lost motion / hysteresis": ("maxwell", "preisach"),
                                      "transmission error": ("te", "te+maxwell", "te+preisach", "te+compliance"),
                                      "compliance": ("compliance",)}
#: Semi-closed and dual-loop: TE, lost motion / hysteresis and compliance each predict one part of the
#: same quantity, the output's offset from the motor angle / N, and the loop holds their sum.  One part
#: alone moves that offset at a start position as much as it removes elsewhere (TE without the twist
#: leaves the twist, which the TE partly cancelled), so these pairs are measured as rows of their own
#: and compete with TE alone in its group.
MOTOR_SIDE_PAIRS: tuple[tuple[str, str], ...] = (("te", "maxwell"), ("te", "preisach"), ("te", "compliance"))
#: Compensators that predict the same part of the output error although they may be chosen in
#: different groups (a measured pair of :data:`MOTOR_SIDE_PAIRS` sits in the TE group): the Preisach
#: operator is the gear's whole torque -> twist curve, its elastic twist and its lost motion included,
#: so it is combined with neither the compliance twist nor the Maxwell-slip lost motion (of two chosen
#: candidates the one with the larger factor is left out, and the next one of its group without the
#: conflicting part takes its place).
EXCLUSIVE: tuple[tuple[str, str], ...] = (("preisach", "compliance"), ("preisach", "maxwell"))
#: Best combination when no measurements choose one (``--controllers best``): the compensators of
#: :data:`BEST_NAMES` without the motion strategies.
DEFAULT_BEST: tuple[str, ...] = ("stribeck",)


def best_gains(axis: str = "reference") -> dict[str, float]:
    """Drive parameters the best combination sets after the model download (table units): :data:`BEST_GAINS`,
    its position P times :func:`position_gain_scale` (the same factor as the fair gains, :func:`fair_gains`)."""
    g = {k: float(v) for k, v in BEST_GAINS.items()}
    if "pos_kp" in g:
        g["pos_kp"] *= position_gain_scale(axis)
    return g


def _reader(axis: str) -> Callable[[str], float]:
    def get(key: str) -> float:
        return float(sim.axis_param(key, axis))
    return get


def _has(get: Callable[[str], float], key: str) -> bool:
    """Whether ``get`` knows ``key`` (an axis file or model without it raises KeyError / ValueError)."""
    try:
        get(key)
    except (KeyError, ValueError):
        return False
    return True


def _maxwell_fit(fs: float, x0: float, n: int) -> tuple[list[float], list[float]]:
    """Stop elements (k_i N.m/rad, d_i rad) fitting F(x) = fs (1 - exp(-x/x0)) on [0, 5 x0].

    The breakpoints are geometric (x0/4 ... 4 x0); the element stiffnesses are the
    slope drops of the piecewise-linear interpolant through the breakpoints.
    """
    xs = x0 * np.geomspace(0.25, 4.0, n)
    fx = fs * (1.0 - np.exp(-xs / x0))
    slopes = np.diff(np.concatenate([[0.0], fx])) / np.diff(np.concatenate([[0.0], xs]))
    k = [float(slopes[i] - (slopes[i + 1] if i + 1 < n else 0.0)) for i in range(n)]
    return k, [float(x) for x in xs]


def _lost_motion_elements(model: Mapping[str, float] | None, k_nm_per_rad: float
                          ) -> tuple[list[float], list[float]] | None:
    """Identified lost-motion elements as Maxwell-slip stop elements (k_i N.m/rad, d_i rad), or None.

    The drive's element i adds ``k_i s_i / mx_stiffness`` of twist; an identified element of twist
    gain g_i (rad per rad of output travel) therefore gets ``k_i = g_i x mx_stiffness``.  More than
    the drive's 8 elements are merged (neighbours with the smallest gains).
    """
    # only an identified model has them (an axis file describes the plant's friction instead)
    if model is None or "lost_motion.n_elements" not in model:
        return None
    n = int(model["lost_motion.n_elements"])
    g = [float(model[f"lost_motion.e{i}_gain"]) for i in range(1, n + 1)]
    d = [float(model[f"lost_motion.e{i}_d_rad"]) for i in range(1, n + 1)]
    while len(g) > 8:          # merge the neighbour pair of smallest gain (gain-weighted threshold)
        j = int(np.argmin([g[i] + g[i + 1] for i in range(len(g) - 1)]))
        gg = g[j] + g[j + 1]
        dd = (g[j] * d[j] + g[j + 1] * d[j + 1]) / gg if gg > 0 else d[j]
        g[j:j + 2], d[j:j + 2] = [gg], [dd]
    return [gi * k_nm_per_rad for gi in g], d


#: The axis-file Preisach table covers the gear's twist at +-TABLE_TORQUE_T1 x T1 of its elastic curve:
#: the torque range of the reversal curves ``hdservo identify`` fits its own table on (the gear's
#: hysteresis lives below about T1, beyond it only the spring stiffens).  A table that ends inside the
#: torque swings of a move saturates there: its memory is wiped out and every later stop is predicted on
#: the major loop's branch, a wider loop than the gear shows.
TABLE_TORQUE_T1 = 2.0
#: Twist lattice step of the axis-file table, in 2^-32 turn (2^10: 1.46 urad, 0.30"): the inverse
#: rounds the predicted twist to half of it.  The sub-steps per grid level follow from the range.
TABLE_LATTICE_LSB = 2 ** 10
#: Twist range of a table whose gear has no usable stiffness (rad).
TABLE_RANGE_FALLBACK_RAD = 2.5e-4


def elastic_torque(get: Callable[[str], float], u: np.ndarray) -> np.ndarray:
    """Single-valued torque of the gear at twist ``u`` (rad), N.m: the stiffness curve of the plant
    (three-slope, or cubic) plus the centre line of its Preisach part (docs/plant.md).

    Parameters
    ----------
    get : callable
        Model reader, ``"section.key"`` -> value.
    u : numpy.ndarray
        Twist, rad (output-referred).

    Returns
    -------
    numpy.ndarray
        Torque, N.m; odd and non-decreasing in ``u``.
    """
    x = np.asarray(u, dtype=float)
    t = np.zeros_like(x)
    if get("stiffness.enabled"):
        k1, k2, k3 = (get(f"stiffness.k{i}_Nm_per_rad") for i in (1, 2, 3))
        t1 = get("stiffness.t1_Nm")
        t2 = max(get("stiffness.t2_Nm"), t1)
        p1 = t1 / k1 if k1 > 0 else 0.0
        p2 = p1 + ((t2 - t1) / k2 if k2 > 0 else 0.0)
        t += k3 * x + (k1 - k2) * np.clip(x, -p1, p1) + (k2 - k3) * np.clip(x, -p2, p2)
    if _has(get, "stiffness_cubic.enabled") and get("stiffness_cubic.enabled"):
        t += get("stiffness_cubic.k1_Nm_per_rad") * x + get("stiffness_cubic.k3_Nm_per_rad3") * x ** 3
    if get("hysteresis_preisach.enabled"):
        et, m = _plant_preisach(get)
        xc = np.clip(x, -m, m)
        t += np.array([et(v, -m) - et(m, v) for v in xc.ravel()]).reshape(x.shape)
    return t


def _plant_preisach(get: Callable[[str], float]) -> tuple[preisach.EverettTable, float]:
    """The plant's Preisach part: its Everett table (the plant's own grid and interpolation) and u_max, rad."""
    m = get("hysteresis_preisach.u_max_rad")
    return preisach.everett_table_plant(m, get("hysteresis_preisach.t_sat_Nm"), get("hysteresis_preisach.r0_rad"),
                                        get("hysteresis_preisach.s_rad")), m


def gear_everett(get: Callable[[str], float], u_grid: np.ndarray) -> np.ndarray:
    """Everett grid (N.m) of the gear's twist -> torque operator on ``u_grid`` (rad).

    The plant's gear torque is ``S(phi) + sum_i sat(k_i (phi - xi_i), w_i) + P_mean(phi) - P[phi]``
    (spring ``S``, Maxwell-slip elements, the Preisach part ``P`` about its centre line ``P_mean``), so

    E(a, b) = (F(a) - F(b))/2 + sum_i min(k_i (a - b), 2 w_i)/2 - E_P(a, b),

    with the single-valued ``F = S + P_mean`` (:func:`elastic_torque`) and E_P the plant's own Everett
    table of the Preisach part (inputs held at its u_max, as the plant holds them).
    """
    u = np.asarray(u_grid, dtype=float)
    a, b = np.meshgrid(u, u, indexing="ij")
    d = np.clip(a - b, 0.0, None)
    f = elastic_torque(get, u)
    e = 0.5 * (f[:, None] - f[None, :])
    if get("hysteresis_preisach.enabled"):
        et, m = _plant_preisach(get)
        uc = np.clip(u, -m, m)
        e -= np.array([[et(uc[i], uc[j]) if j < i else 0.0 for j in range(len(u))] for i in range(len(u))])
    if get("hysteresis_maxwell.enabled"):
        for i in range(1, int(get("hysteresis_maxwell.n_elements")) + 1):
            k, w = get(f"hysteresis_maxwell.e{i}_k_Nm_per_rad"), get(f"hysteresis_maxwell.e{i}_w_Nm")
            e += np.minimum(k * d, 2 * w) / 2
    return np.tril(e, -1)


def table_range_rad(get: Callable[[str], float]) -> float:
    """Twist half-range of the axis-file Preisach table, rad: the elastic curve's twist at
    ``TABLE_TORQUE_T1`` x T1 (:func:`elastic_torque`; the fallback without a stiffness)."""
    t1 = get("stiffness.t1_Nm") if _has(get, "stiffness.t1_Nm") else 0.0
    target = TABLE_TORQUE_T1 * abs(t1)
    hi = 1e-2
    if not target > 0.0 or not float(elastic_torque(get, np.array([hi]))[0]) > target:
        return TABLE_RANGE_FALLBACK_RAD
    lo = 0.0
    for _ in range(60):                       # the elastic curve is monotone: bisection
        mid = 0.5 * (lo + hi)
        if float(elastic_torque(get, np.array([mid]))[0]) < target:
            lo = mid
        else:
            hi = mid
    return hi


def preisach_table(axis: str = "reference", levels: int = 64, sub_bits: int | None = None,
                   range_rad: float | None = None, version: int = 1) -> pt.PreisachTable:
    """Quantised Everett table of the gear twist (input, 2^-32 turn) -> torque (Q15.16 N.m).

    Parameters
    ----------
    axis : str
        "reference", "minimal" or an axis TOML path.
    levels : int
        Grid levels L.
    sub_bits : int, optional
        Lattice steps per grid cell = 2**sub_bits; default the fewest that keep the lattice step at
        ``TABLE_LATTICE_LSB`` over the range.
    range_rad : float, optional
        Twist range +-range_rad (output rad) covered by the lattice; default :func:`table_range_rad`.
    version : int
        Table version.

    Returns
    -------
    PreisachTable
        Unit HD_PREISACH_UNIT_GENERIC (twist -> torque), sealed.
    """
    get = _reader(axis)
    lsb_turn = 2.0 ** -32
    rng = table_range_rad(get) if range_rad is None else float(range_rad)
    span = 2 * rng / TWO_PI / lsb_turn               # lattice span in 2^-32 turn
    if sub_bits is None:
        need = span / ((levels - 1) * TABLE_LATTICE_LSB)
        sub_bits = min(max(0, math.ceil(math.log2(need))), pt.SUB_MAX) if need > 1 else 0
    p_top = (levels - 1) << sub_bits
    in_shift = max(0, math.ceil(math.log2(span / p_top)))
    step = 2 ** in_shift
    half = p_top * step // 2
    u0 = -half
    grid_turn = (u0 + np.arange(levels) * (step << sub_bits)) * lsb_turn
    e = gear_everett(get, grid_turn * TWO_PI)
    return pt.quantise_everett(e, 65536.0, sub_bits=sub_bits, in_shift=in_shift, u0=int(u0),
                               unit=pt.UNIT_GENERIC, version=version)


def _friction_sides(get: Callable[[str], float], n: float) -> tuple[dict[str, float], dict[str, float], bool, bool]:
    """Motor-side (scaled to the output by N) and load-side friction of the model:
    (motor, load, motor enabled, load enabled); a disabled side is all zero."""
    fm, fl = bool(get("friction_motor.enabled")), bool(get("friction_load.enabled"))

    def side(sec: str, scale_t: float, scale_v: float, on: bool) -> dict[str, float]:
        if not on:
            return {"fcp": 0.0, "fcn": 0.0, "fsp": 0.0, "fsn": 0.0, "vs": 1.0, "fv": 0.0, "s0": 0.0, "s1": 0.0,
                    "delta": 2.0}
        return {"fcp": get(f"{sec}.fc_pos_Nm") * scale_t, "fcn": get(f"{sec}.fc_neg_Nm") * scale_t,
                "fsp": get(f"{sec}.fs_pos_Nm") * scale_t, "fsn": get(f"{sec}.fs_neg_Nm") * scale_t,
                "vs": get(f"{sec}.vs_rad_s") / scale_v, "fv": get(f"{sec}.viscous_Nms_per_rad") * scale_t * scale_v,
                "s0": (get(f"{sec}.sigma0_Nm_per_rad") * scale_t * scale_v) if get(f"{sec}.lugre_enabled") else 0.0,
                "s1": get(f"{sec}.sigma1_Nms_per_rad") * scale_t * scale_v, "delta": get(f"{sec}.delta")}
    return side("friction_motor", n, n, fm), side("friction_load", 1.0, 1.0, fl), fm, fl


def _stribeck_params(m: dict[str, float], ld: dict[str, float], fm: bool, fl: bool,
                     eps_rad: float, share: float = 1.0) -> tuple[dict[str, float], float, float]:
    """The Stribeck feed-forward (both sides summed, the levels times ``share``): (parameters, vs turn/s,
    viscous N.m/(turn/s))."""
    # Stribeck velocity: the mean of both sides weighted by their Stribeck hump Fs - Fc; a hump
    # that is not there (an identified Fs <= Fc) weighs nothing, and with no hump on either
    # side the enabled sides count equally (a negative weight sum made vs meaningless)
    ws = (max(m["fsp"] - m["fcp"], 0.0) if fm else 0.0, max(ld["fsp"] - ld["fcp"], 0.0) if fl else 0.0)
    if ws[0] + ws[1] <= 0.0:
        ws = (1.0 if fm else 0.0, 1.0 if fl else 0.0)
    vs = (m["vs"] * ws[0] + ld["vs"] * ws[1]) / max(ws[0] + ws[1], 1e-12)      # rad/s, output
    vs_turn = vs / TWO_PI
    fv = (m["fv"] + ld["fv"]) * TWO_PI                                            # N.m/(turn/s)
    return ({"str_fc_pos": share * (m["fcp"] + ld["fcp"]), "str_fs_pos": share * (m["fsp"] + ld["fsp"]),
             "str_vs_pos": vs_turn, "str_fv_pos": fv, "str_fc_neg": share * (m["fcn"] + ld["fcn"]),
             "str_fs_neg": share * (m["fsn"] + ld["fsn"]),
             "str_vs_neg": vs_turn, "str_fv_neg": fv, "str_delta": 2, "str_eps_v": eps_rad / TWO_PI,
             "str_w_ref": 1.0,
             # the clamp follows the levels and the velocity loop (compensator_params, friction_clamp)
             "str_tau_max": feedforward_clamp([share * (m["fsp"] + ld["fsp"]), share * (m["fsn"] + ld["fsn"]),
                                               share * (m["fcp"] + ld["fcp"]), share * (m["fcn"] + ld["fcn"])])},
            vs_turn, fv)


def _lugre_params(m: dict[str, float], ld: dict[str, float], vs_turn: float, fv: float) -> tuple[dict[str, float], float]:
    """LuGre with one bristle state for both sides (sigma0 from the torque-weighted presliding
    distance): (parameters, the load side's presliding distance rad, 0 without one)."""
    g_s = m["fsp"] + ld["fsp"]
    z_m = m["fsp"] / m["s0"] if m["s0"] > 0 else 0.0
    z_l = ld["fsp"] / ld["s0"] if ld["s0"] > 0 else 0.0
    zbar = (m["fsp"] * z_m + ld["fsp"] * z_l) / max(g_s, 1e-12)
    sigma0 = g_s / zbar if zbar > 0 else 1e6
    # sigma1 carries the motor's bristle damping times N^2: at N = 160 an identified model can
    # exceed the drive's range, and the bank is held inside it (as sigma0 above) so that the
    # download is accepted whether or not LuGre is enabled.
    return ({"lug_fc": 0.5 * (m["fcp"] + m["fcn"] + ld["fcp"] + ld["fcn"]),
             "lug_fs": 0.5 * (m["fsp"] + m["fsn"] + ld["fsp"] + ld["fsn"]), "lug_vs": vs_turn, "lug_delta": 2,
             "lug_sigma0": min(sigma0 * TWO_PI, 8.0e6),
             "lug_sigma1": min((m["s1"] + ld["s1"]) * TWO_PI, PARAM_DEFS["lug_sigma1"].max),
             "lug_sigma2": fv, "lug_k_obs": 0.0,
             # the clamp follows the levels and the velocity loop (compensator_params, friction_clamp)
             "lug_tau_max": FF_TAU_MAX_MIN, "lug_v_src": 0}, z_l)


def _tangent_stiffness(get: Callable[[str], float]) -> float:
    """Tangent stiffness of the gear after a reversal (K1 + hysteresis elements), N.m/rad."""
    k_tan = get("stiffness.k1_Nm_per_rad")
    if get("hysteresis_maxwell.enabled"):
        k_tan += sum(get(f"hysteresis_maxwell.e{i}_k_Nm_per_rad")
                     for i in range(1, int(get("hysteresis_maxwell.n_elements")) + 1))
    if get("hysteresis_preisach.enabled"):
        k_tan += get("hysteresis_preisach.t_sat_Nm") / get("hysteresis_preisach.u_max_rad")
    return k_tan


def _compliance_params(get: Callable[[str], float]) -> dict[str, float]:
    """Compliance (cb_enable 256): the three-slope stiffness of the axis, N.m/turn and N.m (the cubic
    form is not in the firmware: its linear term stands in for K1)."""
    k1 = get("stiffness.k1_Nm_per_rad") if get("stiffness.enabled") else get("stiffness_cubic.k1_Nm_per_rad")
    k2 = get("stiffness.k2_Nm_per_rad") if get("stiffness.enabled") else k1
    k3 = get("stiffness.k3_Nm_per_rad") if get("stiffness.enabled") else k1
    return {"cp_k1": max(k1 * TWO_PI, MX_STIFFNESS_MIN), "cp_k2": max(k2 * TWO_PI, MX_STIFFNESS_MIN),
            "cp_k3": max(k3 * TWO_PI, MX_STIFFNESS_MIN), "cp_t1": get("stiffness.t1_Nm"),
            "cp_t2": max(get("stiffness.t2_Nm"), get("stiffness.t1_Nm"))}


def _te_params(get: Callable[[str], float]) -> dict[str, float]:
    """TE: wave-generator harmonics (plant: a sin(n theta_m + p), theta_m rad) -> amp turn, phase turn."""
    te = []
    if get("transmission_error.enabled"):
        for i in range(1, 5):
            o, a, p = (get(f"transmission_error.wg{i}_order"), get(f"transmission_error.wg{i}_amp_rad"),
                       get(f"transmission_error.wg{i}_phase_rad"))
            if o > 0 and a != 0.0:
                te.append((o, a / TWO_PI, ((p / TWO_PI + 0.5) % 1.0) - 0.5))
    out: dict[str, float] = {"te_n": len(te), "te_k1": 0.0, "te_tau_max": 10.0}
    for i in range(4):
        o, a, p = te[i] if i < len(te) else (0, 0.0, 0.0)
        out[f"te_order{i + 1}"], out[f"te_amp{i + 1}"], out[f"te_phase{i + 1}"] = o, a, p
    out.update(_te_output_lines(get))
    return out


def _te_output_lines(get: Callable[[str], float]) -> dict[str, float]:
    """The two largest output-side TE lines (per output revolution): functions of the output angle,
    which a motor-encoder loop knows as motor / N; amp turn, phase turn."""
    te_o = []
    if get("transmission_error.enabled"):
        for i in range(1, 5):
            if not _has(get, f"transmission_error.out{i}_order"):
                break
            o, a, p = (get(f"transmission_error.out{i}_order"), get(f"transmission_error.out{i}_amp_rad"),
                       get(f"transmission_error.out{i}_phase_rad"))
            if o > 0 and a != 0.0:
                te_o.append((abs(a), int(o), a / TWO_PI, ((p / TWO_PI + 0.5) % 1.0) - 0.5))
    te_o.sort(reverse=True)
    out: dict[str, float] = {}
    for i in range(2):
        _, o, a, p = te_o[i] if i < len(te_o) else (0.0, 0, 0.0, 0.0)
        out[f"te_out_order{i + 1}"], out[f"te_out_amp{i + 1}"], out[f"te_out_phase{i + 1}"] = o, a, p
    return out


def _unbalance_params(get: Callable[[str], float]) -> dict[str, float]:
    """The unbalance the gear holds, mgl cos(theta + offset) (identified: [gravity]): at rest it is the
    whole transmitted torque, so the twist of a position hold (Preisach, compliance) needs it."""
    grav = bool(get("gravity.enabled")) if _has(get, "gravity.enabled") else True
    has_mgl = _has(get, "gravity.mgl_Nm")
    off = get("gravity.offset_rad") if _has(get, "gravity.offset_rad") else 0.0
    if grav and has_mgl and get("gravity.mgl_Nm") < 0:
        off += math.pi                                     # -m cos(x) = m cos(x + pi)
    return {"pr_mgl": abs(get("gravity.mgl_Nm")) if grav and has_mgl else 0.0,
            "pr_g_off": ((off / TWO_PI + 0.5) % 1.0) - 0.5}


def _backstepping_params(get: Callable[[str], float], n: float, vs_turn: float, fv: float, eps_rad: float,
                         str_fc: float, str_fs: float, torque_limit_Nm: float) -> dict[str, float]:
    """Backstepping (docs/compensators.md 6): c = 2 pi f_bs, f_bs = f_a / 5, ke = J c1 c2 / 4, the
    adaptation gains and bounds, and the law's torque clamp ``bs_u_max`` = the drive's ``torque_limit``."""
    jl, jm = get("load.jl_kgm2"), get("motor.jm_kgm2")
    jt = jl + n * n * jm
    f_a = math.sqrt(get("stiffness.k1_Nm_per_rad") / jl) / TWO_PI
    c = TWO_PI * min(8.0, f_a / 5.0)
    j_turn = TWO_PI * jt
    scale = jt / 1.3
    out = {"bs_c1": c, "bs_c2": c, "bs_j": j_turn, "bs_ke": j_turn * c * c / 4, "bs_eps_w": eps_rad / TWO_PI,
           "bs_w_s": vs_turn, "bs_e1_max": 0.01,
           # the law's clamp is the torque the drive applies: a lower one stops the law short of the
           # friction and load of a heavy axis (a following-error fault), and its anti-windup (the
           # adaptation frozen while clamped) then acts where the drive is not limited at all
           "bs_u_max": float(torque_limit_Nm)}
    # T_load adaptation is the law's integral action on e2: Gamma_4 = J (2 pi f_i)^2 with f_i = 25 Hz,
    # the velocity-loop bandwidth of the PID design (baseline.axis_controller); the slower
    # friction adaptations keep the section 6 values.  Gamma T in Q7.24 (Gamma_4 T = 20.2 here).
    # A heavy load (J_L of several kg m^2) asks for more than the drive's Q7.24 range holds: the
    # gain is held at the table maximum (slower integral action) so that the parameter set of the
    # whole bank stays one the drive accepts, whether or not backstepping is enabled.
    g4 = min(j_turn * (TWO_PI * BS_F_INT_HZ) ** 2 / 10000.0, PARAM_DEFS["bs_gamma4"].max)
    gam = (0.5 * scale, 0.5 * scale, 0.25 * scale, g4)
    fmax = max(str_fs, 1e-3)
    lo = (0.0, 0.0, 0.0, -20.0 * min(1.0, fmax / 10.6))
    hi = (3.0 * fmax, 3.0 * fmax, 15.0 * max(fv, 1.0), 20.0 * min(1.0, fmax / 10.6))
    th0 = (str_fc, str_fs - str_fc, fv, 0.0)
    for i in range(4):
        out[f"bs_gamma{i + 1}"] = gam[i]
        out[f"bs_min{i + 1}"] = lo[i]
        out[f"bs_max{i + 1}"] = hi[i]
        out[f"bs_th0_{i + 1}"] = min(max(th0[i], lo[i]), hi[i])
    return out


def load_resonance_hz(k1_Nm_per_rad: float, jl_kgm2: float) -> float:
    """Resonance of the load on the gear's first stiffness against a held motor.

    Parameters
    ----------
    k1_Nm_per_rad : float
        First slope K1 of the gear's stiffness, N.m/rad.
    jl_kgm2 : float
        Load inertia J_L, kg m^2.

    Returns
    -------
    float
        sqrt(K1 / J_L) / (2 pi), Hz (inf without a load inertia).
    """
    if jl_kgm2 <= 0.0:
        return math.inf
    return math.sqrt(max(k1_Nm_per_rad, 0.0) / jl_kgm2) / (2.0 * math.pi)


def velocity_loop_hz(vel_kp_Nms_per_rad: float, j_total_kgm2: float) -> float:
    """Crossover of the drive's velocity loop on the rigid axis, Hz.

    Parameters
    ----------
    vel_kp_Nms_per_rad : float
        Velocity-loop proportional gain the drive runs (``vel_kp``), N.m.s/rad.
    j_total_kgm2 : float
        Total inertia referred to the output, J_L + N^2 J_m, kg m^2.

    Returns
    -------
    float
        vel_kp / (2 pi J_tot), Hz (inf without an inertia).
    """
    if j_total_kgm2 <= 0.0:
        return math.inf
    return max(vel_kp_Nms_per_rad, 0.0) / (2.0 * math.pi * j_total_kgm2)


def design_vel_kp(j_total_kgm2: float) -> float:
    """``vel_kp`` the design rule configures for a total inertia, N.m.s/rad (25 Hz within the drive's range)."""
    from .closedloop_cases import velocity_pi
    return float(velocity_pi(j_total_kgm2, VEL_LOOP_HZ)["vel_kp"])


def twist_torque_source(k1_Nm_per_rad: float, jl_kgm2: float, vel_loop_hz: float) -> int:
    """``pr_t_src`` of the twist predictions (Preisach, compliance) by the documented rule.

    Parameters
    ----------
    k1_Nm_per_rad : float
        First slope K1 of the gear's stiffness, N.m/rad.
    jl_kgm2 : float
        Load inertia J_L, kg m^2.
    vel_loop_hz : float
        Crossover of the velocity loop the drive runs (:func:`velocity_loop_hz`), Hz.

    Returns
    -------
    int
        2 (the motor side while the motor slides, the model near standstill) when the load resonance
        :func:`load_resonance_hz` is below ``RESONANCE_LOOP_RATIO`` x ``vel_loop_hz``; else 1 (the model).
    """
    return 2 if load_resonance_hz(k1_Nm_per_rad, jl_kgm2) < RESONANCE_LOOP_RATIO * vel_loop_hz else 1


def compensator_params(axis: str = "reference", *, n_maxwell: int = 4,
                       model: Mapping[str, float] | None = None,
                       vel_kp: float | None = None, torque_limit: float | None = None) -> dict[str, float]:
    """Compensator-bank parameters of an axis (table units; docs/parameters.md).

    Parameters
    ----------
    axis : str
        "reference", "minimal" or an axis TOML path (its true values are the model).
    n_maxwell : int
        Maxwell-slip elements (<= 8).
    model : mapping, optional
        ``{"section.key": value}`` overriding the axis values (an identified model).
    vel_kp : float, optional
        Velocity-loop gain the drive runs, N.m.s/rad (default: the design rule's for the model's
        J_tot, :func:`design_vel_kp`); with the model's J_tot it gives the crossover of the
        twist torque rule (:func:`twist_torque_source`).
    torque_limit : float, optional
        Output torque limit the drive runs (``torque_limit``), N.m (default: the parameter's default,
        60 N.m); the backstepping law's clamp ``bs_u_max``.

    Returns
    -------
    dict
        Parameter name -> value in the table unit.  ``cb_enable`` is 0 (every
        compensator off); the caller sets the bits of the ones it wants.
    """
    base = _reader(axis)

    def get(key: str) -> float:
        if model is not None and key in model:
            return float(model[key])
        return base(key)

    n = get("gear.ratio")
    out: dict[str, float] = {"cb_enable": 0, "cb_ramp_ticks": 2000, "cb_dpos_fc": 50.0}
    # scheduled position integral (off here; the best combination sets cb_pki): full weight above
    # 0.005 deg/s, none below 0.002 deg/s and at standstill, where the friction side of the gear
    # is in presliding and an extra integrator makes the loop hunt (docs/compensators.md 8)
    out.update({"cb_pki": 0.0, "cb_pki_vlo": PKI_V_LO_DEG_S / 360.0, "cb_pki_vhi": PKI_V_HI_DEG_S / 360.0,
                "cb_pki_leak": 2.0, "cb_pki_max": 1.0 / 360.0})
    m, ld, fm, fl = _friction_sides(get, n)
    eps_rad = 1e-5                                                                # smooth-sign half width, rad/s
    # Stribeck levels of an identified model: the motor side's share of the total (download.model_overrides,
    # from the presliding breakaway).  On the measured velocity the feed-forward is a relay at rest; the
    # motor torque meets the motor-side friction directly, while the output-side friction sits behind the
    # gear's spring: relaying its level too winds the spring back and forth and scatters the stops
    share = float(model[MOTOR_SHARE_KEY]) if model is not None and MOTOR_SHARE_KEY in model else 1.0
    stribeck, vs_turn, fv = _stribeck_params(m, ld, fm, fl, eps_rad, share)
    out.update(stribeck)
    # the velocity loop the drive runs: the twist torque rule's crossover and the steady-motion threshold
    jt = get("load.jl_kgm2") + n * n * get("motor.jm_kgm2")
    kp_run = (design_vel_kp(jt) if jt > 0.0 else 0.0) if vel_kp is None else float(vel_kp)
    # steady-motion threshold from the plant's friction drop (the whole levels, not the fed-forward
    # share: the reference velocity leaves all of it to the loop) in the shape the identification fitted
    d_id = float(model[FRICTION_DELTA_KEY]) if model is not None and FRICTION_DELTA_KEY in model else None
    sides = [{"fc": sd["fcp"], "fs": sd["fsp"], "fcn": sd["fcn"], "fsn": sd["fsn"], "vs": sd["vs"],
              "delta": d_id if d_id is not None else sd["delta"], "fv": sd["fv"]}
             for sd, on in ((m, fm), (ld, fl)) if on]
    out["str_steady_vs"] = steady_motion_vs(sides, vs_turn * TWO_PI, kp_run)
    # the map's clamp: its static level, or its level at the threshold where the drop beats the loop
    out["str_tau_max"] = friction_clamp([(out["str_fs_pos"], out["str_fc_pos"]), (out["str_fs_neg"], out["str_fc_neg"])],
                                        out["str_steady_vs"])
    # the online estimator measures the total steady friction: its feed relays the same share
    out["fe_share"] = share
    lugre, z_l = _lugre_params(m, ld, vs_turn, fv)
    out.update(lugre)
    # LuGre's clamp: its static level where the friction drop is no threat to the loop; where it is,
    # the map on the reference velocity has no level the loop holds beyond the Coulomb one (a clamp
    # above it tracks 7x worse on the CSF-40-100 of docs/compensators.md section 1): the default
    lug_levels = [m["fsp"] + ld["fsp"], m["fcp"] + ld["fcp"], m["fsn"] + ld["fsn"], m["fcn"] + ld["fcn"]]
    out["lug_tau_max"] = (feedforward_clamp(lug_levels) if not out["str_steady_vs"] > STR_STEADY_VS
                          else FF_TAU_MAX_MIN)
    out["mx_n"] = n_maxwell
    # the firmware compliance (2^-44 turn/N.m, int32) needs K > 2^13 N.m/turn (1.3e3 N.m/rad)
    out["mx_stiffness"] = min(max(_tangent_stiffness(get) * TWO_PI, MX_STIFFNESS_MIN),
                              PARAM_DEFS["mx_stiffness"].max)                       # N.m/turn
    out["mx_tau_max"] = 30.0
    out.update(_compliance_params(get))
    lm = _lost_motion_elements(model, out["mx_stiffness"] / TWO_PI)
    if lm is not None:
        k_el, d_el = lm
        n_maxwell = len(k_el)
        out["mx_n"] = n_maxwell
    else:
        k_el, d_el = _maxwell_fit(ld["fsp"], z_l if z_l > 0 else 1e-5, n_maxwell) if fl else ([0.0] * n_maxwell,
                                                                                             [0.0] * n_maxwell)
    for i in range(8):
        out[f"mx_k{i + 1}"] = k_el[i] * TWO_PI if i < n_maxwell else 0.0      # N.m/turn
        out[f"mx_d{i + 1}"] = d_el[i] / TWO_PI if i < n_maxwell else 0.0      # turn
    # Preisach: torque estimate from the model (pr_t_src 1): the load-side share of the friction
    # model on the reference velocity plus J_L a_ref, i.e. what the gear has to transmit
    out["pr_deadband"] = 1
    out["pr_fc"] = 20.0
    out["pr_motor_share"] = (m["fcp"] / max(m["fcp"] + ld["fcp"], 1e-12)) if fm else 0.0
    out["pr_jl"] = get("load.jl_kgm2")
    out["pr_jm"] = n * n * get("motor.jm_kgm2")
    # the rule's crossover: the velocity-loop gain the drive runs over the model's total inertia
    f_v = math.inf if jt <= 0.0 else velocity_loop_hz(kp_run, jt)
    out["pr_t_src"] = twist_torque_source(get("stiffness.k1_Nm_per_rad"), out["pr_jl"], f_v)
    out.update(_unbalance_params(get))
    out.update(_te_params(get))
    t_lim = float(PARAM_DEFS["torque_limit"].default) if torque_limit is None else float(torque_limit)
    out.update(_backstepping_params(get, n, vs_turn, fv, eps_rad, m["fcp"] + ld["fcp"], m["fsp"] + ld["fsp"], t_lim))
    # disturbance observer: Q-filter bandwidth (Hz) and nominal inertia
    out["dob_fc"] = 10.0
    out["dob_j"] = get("load.jl_kgm2") + n * n * get("motor.jm_kgm2")
    return out


def enable_mask(names: list[str] | tuple[str, ...]) -> int:
    """``cb_enable`` bits of compensator names (``ENABLE_BITS``); ValueError for an unknown name."""
    m = 0
    for nm in names:
        if nm not in ENABLE_BITS:
            raise ValueError(f"unknown compensator {nm!r}; expected one of {sorted(ENABLE_BITS)}")
        m |= ENABLE_BITS[nm]
    return m


def write_preisach_table(axis: str, path: "str | os.PathLike[str]") -> Path:
    """Write the axis' Preisach table image (:func:`preisach_table`) to ``path``; returns the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return write_bytes_atomic(p, preisach_table(axis).to_bytes())


def controller(axis: str, names: "list[str] | tuple[str, ...]", base: Mapping[str, Any] | None = None,
               table_dir: "str | os.PathLike[str] | None" = None,
               extra_gains: Mapping[str, float] | None = None,
               params: Mapping[str, float] | None = None) -> dict[str, Any]:
    """A scenario ``[controller]`` table: the baseline of the axis plus compensators.

    Parameters
    ----------
    axis : str
        Axis spec (as :func:`hdservo.closedloop_cases.axis_controller` takes it).
    names : sequence of str
        Compensators to switch on (keys of :data:`ENABLE_BITS`).
    base : mapping, optional
        The baseline controller table (default ``baseline.axis_controller(axis)``).
    table_dir : path-like, optional
        Where the Preisach table file goes (needed when "preisach" is in names).
    extra_gains : mapping, optional
        Further drive parameters (retuned gains, compensator options), table units.
    params : mapping, optional
        Compensator parameters (default :func:`compensator_params` of the axis).

    Returns
    -------
    dict
        ``mode``, ``gains`` (the baseline's plus every compensator parameter),
        ``compensators``, and ``preisach_table`` when needed.
    """
    from . import closedloop_cases as bl
    ctl = dict(bl.axis_controller(axis) if base is None else base)
    spec = bl._axis_spec(axis)
    gains: dict[str, float] = {} if ctl.get("gains", "defaults") == "defaults" else dict(ctl["gains"])
    cp = compensator_params(spec) if params is None else dict(params)
    cp.pop("cb_enable", None)
    gains.update(cp)
    if extra_gains:
        gains.update(extra_gains)
    ctl["gains"] = gains
    ctl["compensators"] = list(names)
    if "preisach" in names:
        if table_dir is None:
            raise ValueError("controller(): the Preisach compensator needs table_dir for its table file")
        tag = Path(spec).stem if spec not in ("reference", "minimal") else spec
        ctl["preisach_table"] = str(write_preisach_table(spec, Path(table_dir) / f"preisach_{tag}.bin").resolve())
    return ctl


__all__ = ["FF_TAU_MAX_MIN", "feedforward_clamp", "friction_clamp",
           "FRICTION_DELTA_KEY", "MOTOR_SHARE_KEY", "STR_STEADY_VS", "STR_STEADY_VS_MAX", "friction_slope",
           "steady_motion_vs", "RESONANCE_LOOP_RATIO", "VEL_LOOP_HZ", "design_vel_kp", "load_resonance_hz",
           "twist_torque_source", "velocity_loop_hz", "BEST_GAINS", "BEST_NAMES", "BEST_PROC_ARGS", "COMPONENT_PARAMS", "DEFAULT_BEST", "ENABLE_BITS", "EXCLUSIVE", "MOTOR_SIDE_PAIRS",
           "FAIR_GAINS", "FAIR_PROC_ARGS", "fair_gains", "position_gain_scale", "GROUPS", "STRATEGIES", "TABLE_LATTICE_LSB", "TABLE_TORQUE_T1", "best_gains",
           "compensator_params", "controller", "elastic_torque", "enable_mask", "gear_everett", "preisach_table",
           "table_range_rad",
           "write_preisach_table"]
