"""The reference axis's linear loop and where each nonlinearity enters it.

Model (all output-referred, SI): two-mass axis::

    J_m' w_m' = tau - N f_m - c_m w_m' - K phi - c phi' - T_x
    J_L  w_L' = K phi + c phi' + T_x - f_L - c_L w_L,     phi = theta_m/N - theta_L

with ``J_m' = N^2 J_m``; actuator ``u_c -> torque filters (biquads f1, f2,
mapped to continuous time by the inverse Tustin transform) -> delay
``delay_periods`` T (Pade 1/1; default 1.5 T = one period of computation + the
zero-order hold's T/2 on the drive; 0.5 T in the lock-step simulator, where the
sample taken at the start of a period drives the command held over it) ->
current loop 1/(s/w_i + 1) -> tau``; cascaded
PID: ``w_ref = (pos_kp + pos_ki/s)(r - theta_fb)``,
``u_c = (vel_kp + vel_ki/s)(w_ref - w_fb) - vel_kd s/(1 + s/w_d) w_fb``
with ``w_fb`` the type-2 tracking observer ``(2 z w_o s + w_o^2)/(s^2 + 2 z w_o s + w_o^2)``
of the motor velocity / N (``vel_fb_src = 0``) or of the load velocity.

Insertion points (the nonlinearity's input ``z`` and output ``w``):

=================  =========================================  ===========================================
name               z (input)                                  w (output) and where it acts
=================  =========================================  ===========================================
motor_friction     motor velocity, rad/s at the motor          friction torque at the motor, N m (opposes)
load_friction      load velocity, rad/s                        friction torque on the load, N m (opposes)
torsion            twist phi, rad                              whole torsion torque, N m (linear spring removed)
position_feedback  load angle theta_L, rad                     angle the position loop sees, rad (lost motion)
=================  =========================================  ===========================================

With the loop closed, the linear part seen by the nonlinearity is
``P_zw(s)``; a limit cycle needs ``1 - P_zw N = 0``, i.e. ``H N = -1`` with
``H = -P_zw`` (python-control's convention).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, Mapping, Tuple

import control as ct
import numpy as np

INSERTIONS = ("motor_friction", "load_friction", "torsion", "position_feedback")


def _biquad_continuous(b: Tuple[float, float, float], a: Tuple[float, float], T: float) -> ct.TransferFunction:
    """Continuous equivalent of ``(b0 + b1 z^-1 + b2 z^-2)/(1 + a1 z^-1 + a2 z^-2)`` (inverse Tustin)."""
    p = np.poly1d([T / 2, 1.0])   # 1 + sT/2
    m = np.poly1d([-T / 2, 1.0])  # 1 - sT/2
    num = b[0] * p * p + b[1] * m * p + b[2] * m * m
    den = 1.0 * p * p + a[0] * m * p + a[1] * m * m
    return ct.tf(num.coeffs, den.coeffs)


@dataclass
class LoopModel:
    """The linear cascaded loop of one axis, ready for describing-function analysis.

    Parameters
    ----------
    axis : mapping
        ``"section.key"`` -> value (see :mod:`hdservo.analysis.axis`).
    gains : mapping
        Drive gains (see :mod:`hdservo.analysis.axis`).
    """

    axis: Mapping[str, float]
    gains: Mapping[str, float]

    # ---------------------------------------------------------------- pieces
    @property
    def ratio(self) -> float:
        """Gear ratio N."""
        return float(self.axis["gear.ratio"])

    @property
    def j_motor_out(self) -> float:
        """Motor inertia referred to the output, N^2 J_m (kg m^2)."""
        return self.ratio ** 2 * float(self.axis["motor.jm_kgm2"])

    @property
    def j_load(self) -> float:
        """Load inertia J_L (kg m^2)."""
        return float(self.axis["load.jl_kgm2"])

    @property
    def k_lin(self) -> float:
        """Small-signal torsional stiffness used in the linear part (N m/rad)."""
        return float(self.axis["stiffness.k1_Nm_per_rad"])

    def plant(self, insertion: str) -> ct.StateSpace:
        """Two-mass plant with the extra input ``w`` and output ``z`` of one insertion point.

        Inputs ``tau`` (N m, output-referred), ``w``; outputs ``theta_L`` (rad),
        ``theta_fb`` (rad, what the position loop sees), ``omega_m`` (motor
        velocity / N, rad/s), ``omega_L`` (rad/s), ``z``.
        """
        if insertion not in INSERTIONS:
            raise ValueError(f"unknown insertion point '{insertion}' (expected one of {', '.join(INSERTIONS)})")
        N = self.ratio
        Jm, JL = self.j_motor_out, self.j_load
        K = 0.0 if insertion == "torsion" else self.k_lin
        c = float(self.axis["stiffness.damping_Nms_per_rad"])
        cm = 0.0 if insertion == "motor_friction" else N * N * float(self.axis.get("friction_motor.viscous_Nms_per_rad", 0.0)) * float(self.axis.get("friction_motor.enabled", 1.0))
        cl = 0.0 if insertion == "load_friction" else float(self.axis.get("friction_load.viscous_Nms_per_rad", 0.0)) * float(self.axis.get("friction_load.enabled", 1.0))
        # x = [theta_m', omega_m', theta_L, omega_L]
        A = np.array([[0, 1, 0, 0],
                      [-K / Jm, -(cm + c) / Jm, K / Jm, c / Jm],
                      [0, 0, 0, 1],
                      [K / JL, c / JL, -K / JL, -(cl + c) / JL]])
        # inputs [tau, w]
        bw = {"motor_friction": (-N / Jm, 0.0), "load_friction": (0.0, -1.0 / JL),
              "torsion": (-1.0 / Jm, 1.0 / JL), "position_feedback": (0.0, 0.0)}[insertion]
        B = np.array([[0, 0], [1 / Jm, bw[0]], [0, 0], [0, bw[1]]])
        C = [[0, 0, 1, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1]]
        D = [[0, 0], [0, 0], [0, 0], [0, 0]]
        zrow = {"motor_friction": [0, N, 0, 0], "load_friction": [0, 0, 0, 1],
                "torsion": [1, 0, -1, 0], "position_feedback": [0, 0, 1, 0]}[insertion]
        C.append(zrow)
        D.append([0, 0])
        C, D = np.array(C, float), np.array(D, float)
        if insertion == "position_feedback":
            C[1] = 0.0
            D[1] = [0.0, 1.0]  # theta_fb = w
        return ct.ss(A, B, C, D, inputs=["tau", "w"],
                     outputs=["theta_L", "theta_fb", "omega_m", "omega_L", "z"], name="plant")

    def actuator(self) -> ct.StateSpace:
        """Torque filters, computation delay and current loop: ``u_in -> tau``."""
        g = self.gains
        T = float(g.get("loop_period_s", 1e-4))
        sys = ct.tf([1.0], [1.0])
        fe = int(g.get("filt_enable", 0))
        if fe & 1:
            sys = sys * _biquad_continuous((g["f1_b0"], g["f1_b1"], g["f1_b2"]), (g["f1_a1"], g["f1_a2"]), T)
        if fe & 2:
            sys = sys * _biquad_continuous((g["f2_b0"], g["f2_b1"], g["f2_b2"]), (g["f2_a1"], g["f2_a2"]), T)
        num, den = ct.pade(float(g.get("delay_periods", 1.5)) * T, 1)
        sys = sys * ct.tf(num, den)
        if float(self.axis.get("current_loop.enabled", 1.0)):
            wi = 2 * math.pi * float(self.axis["current_loop.bandwidth_Hz"])
            sys = sys * ct.tf([wi], [1.0, wi])
        return ct.ss(sys, inputs="u_in", outputs="tau", name="actuator")

    def observer(self) -> ct.StateSpace:
        """Velocity feedback path: tracking observer on the chosen encoder."""
        g = self.gains
        src = int(g.get("vel_fb_src", 0))
        w = 2 * math.pi * float(g["obs_out_bw"] if src else g["obs_mot_bw"])
        z = float(g.get("obs_zeta", 1.0))
        tf = ct.tf([2 * z * w, w * w], [1.0, 2 * z * w, w * w])
        return ct.ss(tf, inputs="omega_L" if src else "omega_m", outputs="omega_fb", name="observer")

    def controller(self) -> Tuple[ct.StateSpace, ct.StateSpace]:
        """Position PI (``e_pos -> omega_ref``) and velocity PID (``[omega_ref, omega_fb] -> u_c``)."""
        g = self.gains
        kp, ki = float(g["pos_kp"]), float(g["pos_ki"])
        cpos = ct.tf([kp, ki], [1.0, 0.0]) if ki > 0 else ct.tf([kp], [1.0])
        pos = ct.ss(cpos, inputs="e_pos", outputs="omega_ref", name="pos_ctrl")
        vkp, vki, vkd = float(g["vel_kp"]), float(g["vel_ki"]), float(g["vel_kd"])
        cpi = ct.tf([vkp, vki], [1.0, 0.0]) if vki > 0 else ct.tf([vkp], [1.0])
        wd = 2 * math.pi * float(g.get("vel_d_fc", 500.0))
        cd = ct.tf([vkd * wd, 0.0], [1.0, wd])
        vel = ct.ss(ct.append(ct.ss(cpi), ct.ss(cd)), inputs=["e_vel", "omega_fb_d"],
                    outputs=["u_pi", "u_d"], name="vel_ctrl")
        return pos, vel

    def _blocks(self, insertion: str) -> list:
        pos, vel = self.controller()
        sums = [
            ct.summing_junction(inputs=["r", "-theta_fb"], output="e_pos", name="sum_pos"),
            ct.summing_junction(inputs=["omega_ref", "-omega_fb"], output="e_vel", name="sum_vel"),
            ct.summing_junction(inputs=["u_pi", "-u_d"], output="u_c", name="sum_u"),
            ct.ss([], [], [], [[1.0]], inputs="omega_fb", outputs="omega_fb_d", name="fb_copy"),
        ]
        return [self.plant(insertion), self.actuator(), self.observer(), pos, vel] + sums

    def open_system(self, insertion: str) -> ct.StateSpace:
        """Loop broken at the torque command and at the nonlinearity.

        Inputs ``[r, w, u_in]`` (reference rad, nonlinearity output, torque
        command into the actuator N m); outputs ``[z, u_c, theta_L]``
        (nonlinearity input, controller torque command N m, load angle rad).
        """
        return ct.interconnect(self._blocks(insertion), inputs=["r", "w", "u_in"],
                               outputs=["z", "u_c", "theta_L"], check_unused=False, name="open")

    def closed_system(self, insertion: str) -> ct.StateSpace:
        """Torque loop closed: inputs ``[r, w]``, outputs ``[z, theta_L]``."""
        blocks = self._blocks(insertion)
        conn = ct.ss([], [], [], [[1.0]], inputs="u_c", outputs="u_in", name="close")
        return ct.interconnect(blocks + [conn], inputs=["r", "w"], outputs=["z", "theta_L"],
                               check_unused=False, name="closed")

    def H(self, insertion: str) -> ct.StateSpace:
        """Linear part seen by the nonlinearity, ``H = -P_zw`` (z units per w unit)."""
        cl = self.closed_system(insertion)
        return ct.ss(cl.A, cl.B[:, [1]], -cl.C[[0], :], -cl.D[[0]][:, [1]])

    def cycle_amplitude(self, insertion: str, output: str, A: float, omega: float) -> float:
        """Amplitude of a loop signal in a predicted limit cycle.

        In the cycle the nonlinearity's input is ``z = A sin(w t)`` and every
        other signal is the linear response to the first harmonic of its output
        ``w``; so ``|y| = A |G_yw(jw) / G_zw(jw)|`` (closed loop, ``r`` constant).

        Parameters
        ----------
        insertion : str
            Insertion point of the nonlinearity.
        output : str
            ``"theta_L"`` (load angle, rad; also the position error for a
            constant reference) or ``"z"``.
        A : float
            Cycle amplitude at the nonlinearity's input (its unit).
        omega : float
            Cycle angular frequency (rad/s).

        Returns
        -------
        float
            Amplitude of ``output`` (rad for ``theta_L``).
        """
        cl = self.closed_system(insertion)
        G = freqresp(cl, np.array([float(omega)]))[:, 1, 0]  # column of input w
        idx = {"z": 0, "theta_L": 1}[output]
        return float(A * abs(G[idx] / G[0]))

    def linear_gain(self, insertion: str) -> complex:
        """The gain the linear model uses in place of the nonlinearity (for the nominal loop)."""
        return {"motor_friction": 0j, "load_friction": 0j, "torsion": complex(self.k_lin),
                "position_feedback": 1 + 0j}[insertion]


def freqresp(sys: ct.StateSpace, omega: np.ndarray) -> np.ndarray:
    """Complex frequency response ``C (j w I - A)^-1 B + D``, shape (n_out, n_in, n_omega)."""
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    n = A.shape[0]
    out = np.empty((C.shape[0], B.shape[1], omega.size), dtype=complex)
    I = np.eye(n)
    for k, w in enumerate(omega):
        if n:
            X = np.linalg.solve(1j * w * I - A, B)
            out[:, :, k] = C @ X + D
        else:
            out[:, :, k] = D
    return out


def equivalent_loop(O: np.ndarray, N: complex) -> Dict[str, np.ndarray]:
    """Close the nonlinearity with its equivalent gain and return loop quantities.

    Parameters
    ----------
    O : numpy.ndarray
        Frequency response of :meth:`LoopModel.open_system`, shape (3, 3, n).
    N : complex
        Equivalent gain of the nonlinearity (w units per z unit).

    Returns
    -------
    dict
        ``L`` loop gain at the torque command (dimensionless), ``T`` closed-loop
        ``theta_L / r`` (dimensionless), each shape (n,).
    """
    iz, ic, iy = 0, 1, 2
    ir, iw, iu = 0, 1, 2
    den = 1.0 - N * O[iz, iw]

    def m(o: int, i: int) -> np.ndarray:
        return O[o, i] + O[o, iw] * N * O[iz, i] / den

    Mcu, Mcr, Myr, Myu = m(ic, iu), m(ic, ir), m(iy, ir), m(iy, iu)
    L = -Mcu
    c = Mcr / (1.0 - Mcu)
    T = Myr + Myu * c
    return {"L": L, "T": T}
