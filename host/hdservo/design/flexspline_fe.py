"""1-D finite-element model of the flexspline's torsional stiffness.

The cup and its diaphragm are meshed as a chain of torsion elements:

* diaphragm: annular-plate rings between radii rho_j < rho_{j+1}, thickness
  h(rho) tapering linearly from ``h (1 + taper)`` at the hub to ``h`` at the cup;
  ring stiffness ``k = 4 pi G h_e / (1/rho_j^2 - 1/rho_{j+1}^2)`` (exact for a
  uniform ring, h_e at the element centre);
* cup: tube elements of length dx with the exact annulus polar moment
  ``J = pi/2 (r_o^4 - r_i^4)``: bore r_i constant, wall t in the smooth part
  and ``t + tooth_rim_extra`` in the toothed rim (last face width b);
  ``k = G J / dx``.

The hub node is fixed; the output torque is applied as equal nodal loads over
the toothed rim (the mesh reacts it over the face width).  The stiffness is the
torque divided by the load-weighted mean twist of the rim.  Units SI.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_banded

from .structure import Structure


@dataclass(frozen=True)
class FeResult:
    """Result of :func:`solve`.

    Attributes
    ----------
    stiffness_Nm_per_rad : float
        Torque / mean twist of the toothed rim, N·m/rad.
    x_m : numpy.ndarray
        Node coordinate along the load path (diaphragm radius then cup length), m.
    twist_rad : numpy.ndarray
        Nodal twist for 1 N·m, rad.
    """

    stiffness_Nm_per_rad: float
    x_m: np.ndarray
    twist_rad: np.ndarray


def element_stiffnesses(s: Structure, n_diaphragm: int = 40, n_cup: int = 120,
                        taper: float = 0.3, tooth_rim: bool = True) -> tuple[np.ndarray, np.ndarray, int]:
    """Series element stiffnesses along the load path.

    Returns
    -------
    k : numpy.ndarray
        Element stiffnesses, N·m/rad (diaphragm rings first, then cup tubes).
    x : numpy.ndarray
        Node coordinates, m (len(k) + 1).
    first_rim_node : int
        Index of the first node of the toothed rim.
    """
    if n_diaphragm < 1 or n_cup < 2:
        raise ValueError("need at least 1 diaphragm and 2 cup elements")
    g = s.shear_modulus_Pa
    r_i = 0.5 * s.pitch_diameter_m - s.wall_m          # bore (wave-generator side)
    r_m = s.mid_radius_m
    rho = np.linspace(s.hub_radius_m, r_m, n_diaphragm + 1)
    rc = 0.5 * (rho[:-1] + rho[1:])
    h = s.diaphragm_m * (1.0 + taper * (r_m - rc) / (r_m - s.hub_radius_m))
    k_dia = 4.0 * math.pi * g * h / (1.0 / rho[:-1] ** 2 - 1.0 / rho[1:] ** 2)
    # cup: nodes so that the rim start falls on a node
    l_free = s.cup_length_m - s.face_width_m
    n_rim = max(2, int(round(n_cup * s.face_width_m / s.cup_length_m)))
    n_free = max(1, n_cup - n_rim)
    xs = np.concatenate([np.linspace(0.0, l_free, n_free + 1),
                         np.linspace(l_free, s.cup_length_m, n_rim + 1)[1:]])
    dx = np.diff(xs)
    xc = 0.5 * (xs[:-1] + xs[1:])
    t = np.where((xc > l_free) & tooth_rim, s.wall_m + s.tooth_rim_extra_m, s.wall_m)
    j = 0.5 * math.pi * ((r_i + t) ** 4 - r_i ** 4)
    k_cup = g * j / dx
    x = np.concatenate([rho - s.hub_radius_m, (r_m - s.hub_radius_m) + xs[1:]])
    return np.concatenate([k_dia, k_cup]), x, n_diaphragm + n_free


def solve(s: Structure, n_diaphragm: int = 40, n_cup: int = 120, taper: float = 0.3,
          tooth_rim: bool = True) -> FeResult:
    """Assemble and solve the chain for a unit torque on the toothed rim.

    Parameters
    ----------
    s : Structure
        Flexspline geometry and material.
    n_diaphragm, n_cup : int
        Number of diaphragm and cup elements.
    taper : float
        Relative extra diaphragm thickness at the hub, -.
    tooth_rim : bool
        Thicken the toothed rim by ``s.tooth_rim_extra_m``.
    """
    k, x, rim0 = element_stiffnesses(s, n_diaphragm, n_cup, taper, tooth_rim)
    n = len(k)                      # free nodes 1..n (node 0 = hub, fixed)
    main = np.zeros(n)
    main[:-1] = k[:-1] + k[1:]
    main[-1] = k[-1]
    off = -k[1:]
    ab = np.zeros((3, n))
    ab[0, 1:] = off
    ab[1, :] = main
    ab[2, :-1] = off
    f = np.zeros(n)
    rim_nodes = np.arange(rim0, n + 1)        # global node indices of the rim
    f[rim_nodes - 1] = 1.0 / len(rim_nodes)   # unit torque shared equally
    u = solve_banded((1, 1), ab, f)
    mean_twist = float(np.dot(f, u))          # load-weighted mean twist for 1 N·m
    return FeResult(1.0 / mean_twist, x, np.concatenate([[0.0], u]))
