"""An independent time-domain simulation of the cascaded loop (to check DF predictions).

Not the C simulator: a small sampled-data model written directly from the
equations, sharing no code with :mod:`.loop` (which is continuous and uses a
Pade delay).  The firmware side is discrete at the loop period T (type-2
tracking velocity observer on the motor encoder, position PI, velocity PI,
the two torque biquads, the command applied one period after the samples it
was computed from); the linear two-mass plant with the current loop is
advanced exactly (matrix exponential, zero-order hold).  Lost motion sits in
the position feedback: the position loop sees ``play_b[theta_L]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy.linalg import expm


@dataclass
class Oscillation:
    """Measured steady oscillation of a signal.

    Attributes
    ----------
    amplitude : float
        Half the peak-to-peak value over the analysis window (signal units).
    frequency_Hz : float
        From the mean period between upward mean crossings (Hz).
    cycles : int
        Number of full periods in the window.
    """

    amplitude: float
    frequency_Hz: float
    cycles: int


def measure_oscillation(t: np.ndarray, x: np.ndarray) -> Oscillation:
    """Amplitude and frequency of a periodic signal (s, any unit)."""
    y = x - 0.5 * (x.max() + x.min())
    up = np.where((y[:-1] < 0) & (y[1:] >= 0))[0]
    if up.size < 3:
        return Oscillation(0.5 * float(x.max() - x.min()), 0.0, 0)
    tc = t[up] - y[up] * (t[up + 1] - t[up]) / (y[up + 1] - y[up])
    a = tc[0] <= t
    b = t <= tc[-1]
    seg = x[a & b]
    return Oscillation(0.5 * float(seg.max() - seg.min()), float((up.size - 1) / (tc[-1] - tc[0])), int(up.size - 1))


def simulate_lost_motion_loop(axis: Mapping[str, float], gains: Mapping[str, float], b_rad: float,
                              duration_s: float = 2.0, r_rad: float = 0.0,
                              theta0_rad: float = 0.0) -> dict:
    """Simulate the position loop with lost motion in the position feedback.

    Parameters
    ----------
    axis, gains : mapping
        As for :class:`hdservo.analysis.loop.LoopModel` (linear parts only:
        friction and stiffness nonlinearities are not simulated here).
    b_rad : float
        Total lost motion (rad).
    duration_s : float
        Simulated time (s).
    r_rad : float
        Constant position reference (rad).
    theta0_rad : float
        Initial angle of both masses (rad): the initial position error.

    Returns
    -------
    dict
        ``t_s``, ``theta_L_rad``, ``theta_fb_rad``, ``torque_Nm`` arrays (one per period).
    """
    T = float(gains.get("loop_period_s", 1e-4))
    N = float(axis["gear.ratio"])
    Jm = N * N * float(axis["motor.jm_kgm2"])
    JL = float(axis["load.jl_kgm2"])
    K = float(axis["stiffness.k1_Nm_per_rad"])
    c = float(axis["stiffness.damping_Nms_per_rad"])
    cm = N * N * float(axis.get("friction_motor.viscous_Nms_per_rad", 0.0)) * float(axis.get("friction_motor.enabled", 1.0))
    cl = float(axis.get("friction_load.viscous_Nms_per_rad", 0.0)) * float(axis.get("friction_load.enabled", 1.0))
    use_il = bool(float(axis.get("current_loop.enabled", 1.0)))
    wi = 2 * math.pi * float(axis["current_loop.bandwidth_Hz"])
    # x = [theta_m', omega_m', theta_L, omega_L, tau]; input u (torque command, output-referred)
    A = np.zeros((5, 5))
    A[0, 1] = 1
    A[1] = [-K / Jm, -(cm + c) / Jm, K / Jm, c / Jm, 1 / Jm]
    A[2, 3] = 1
    A[3] = [K / JL, c / JL, -K / JL, -(cl + c) / JL, 0]
    Bc = np.zeros(5)
    if use_il:
        A[4, 4] = -wi
        Bc[4] = wi
    else:  # torque follows the command at once: fold into the motor equation
        A[1, 4] = 0
        Bc[1] = 1 / Jm
    M = np.zeros((6, 6))
    M[:5, :5] = A * T
    M[:5, 5] = Bc * T
    E = expm(M)
    Ad, Bd = E[:5, :5], E[:5, 5]

    kp, ki = float(gains["pos_kp"]), float(gains["pos_ki"])
    vkp, vki, vkd = float(gains["vel_kp"]), float(gains["vel_ki"]), float(gains["vel_kd"])
    wd = 2 * math.pi * float(gains.get("vel_d_fc", 500.0))
    src = int(gains.get("vel_fb_src", 0))
    wo = 2 * math.pi * float(gains["obs_out_bw"] if src else gains["obs_mot_bw"])
    zeta = float(gains.get("obs_zeta", 1.0))
    okp, oki = 2 * zeta * wo * T, wo * wo * T
    fe = int(gains.get("filt_enable", 0))
    bq = []
    for i in (1, 2):
        if fe & (1 << (i - 1)):
            bq.append([gains[f"f{i}_b0"], gains[f"f{i}_b1"], gains[f"f{i}_b2"], gains[f"f{i}_a1"], gains[f"f{i}_a2"]])
    bq_state = [[0.0, 0.0] for _ in bq]  # transposed direct form II

    n = int(round(duration_s / T))
    x = np.array([theta0_rad, 0.0, theta0_rad, 0.0, 0.0])
    th_hat, w_hat = (theta0_rad if not src else theta0_rad), 0.0
    ipos = ivel = 0.0
    dfilt = 0.0
    a_d = math.exp(-wd * T)
    play_c = theta0_rad
    u_applied = 0.0
    t = np.arange(1, n + 1) * T
    th_L = np.empty(n)
    th_fb = np.empty(n)
    tq = np.empty(n)
    for k in range(n):
        # --- samples at t_k
        meas_v = x[0] if not src else x[2]
        thL = x[2]
        if thL - play_c > b_rad / 2:
            play_c = thL - b_rad / 2
        elif thL - play_c < -b_rad / 2:
            play_c = thL + b_rad / 2
        e_o = meas_v - th_hat
        w_hat += oki * e_o
        th_hat += T * w_hat + okp * e_o
        e_pos = r_rad - play_c
        ipos += ki * T * e_pos
        w_ref = kp * e_pos + ipos
        e_vel = w_ref - w_hat
        ivel += vki * T * e_vel
        dprev = dfilt
        dfilt = a_d * dfilt + (1 - a_d) * w_hat
        u = vkp * e_vel + ivel - vkd * (dfilt - dprev) / T
        for (b0, b1, b2, a1, a2), st in zip(bq, bq_state):
            y = b0 * u + st[0]
            st[0] = b1 * u - a1 * y + st[1]
            st[1] = b2 * u - a2 * y
            u = y
        # --- plant over [t_k, t_k+1) with the command computed one period earlier
        x = Ad @ x + Bd * u_applied
        u_applied = u
        th_L[k] = x[2]
        th_fb[k] = play_c
        tq[k] = x[4] if use_il else u_applied
    return {"t_s": t, "theta_L_rad": th_L, "theta_fb_rad": th_fb, "torque_Nm": tq}
