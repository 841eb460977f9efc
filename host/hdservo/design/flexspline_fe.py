"""Finite-element model of a cup flexspline (scikit-fem, linear elasticity).

The cup is a solid of revolution: boss (bolted hub, rigid), diaphragm, cylinder
wall and the toothed rim at the open end as an equivalent ring band (wall plus
``tooth_rim_extra_m``).  Its meridian section (r, z) is meshed with 9-node
biquadratic quadrilaterals, and the displacement is expanded in circumferential
Fourier harmonics (the semi-analytical, "Fourier" axisymmetric solid):

* harmonic ``n >= 1``, family A: ``u_r = U_r cos n theta``, ``u_theta = U_theta sin n theta``,
  ``u_z = U_z cos n theta``; family B (``sin`` and ``cos`` swapped) is family A with ``n -> -n``;
* torsion (``n = 0``): ``u_theta = U_theta(r, z)`` alone.

On a body of revolution the harmonics decouple exactly in linear elasticity, so
each load harmonic is one 2-D solve.  This gives full 3-D solid elasticity (no
shell kinematics, no locking of the thin wall with quadratic elements) at the cost
of 2-D meshes.  Loads and results:

* :func:`torsional_stiffness`: the output torque enters over two tooth-engagement
  zones of the rim (around the ellipse's major axis, half-angle from the engaged
  tooth fraction) as a tangential traction, expanded in the harmonics 0, 2, 4, ...;
  the wave generator holds the rim bore radially (``u_r`` prescribed, the ellipse
  ``w0 cos 2 theta`` imposed); the boss is clamped.  Stiffness = torque / twist,
  the twist being the load-weighted mean rotation of the loaded zones.
* :func:`modes`: generalised eigenproblem ``K x = omega^2 M x`` with the load
  attached to the boss as a rigid body (rotation, or tilt plus lateral
  translation) carrying the load's inertia, the rim held; optionally the rim is
  held through a torsional spring (tooth mesh and wave-generator bearing).

All quantities SI (m, Pa, kg, N·m/rad, Hz).  docs/design-flow.md ("Flexspline
finite-element model") describes the model as a designer uses it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh, spsolve

from .structure import Structure

#: density of the flexspline steel, kg/m³
STEEL_DENSITY_KG_M3 = 7850.0
#: default mesh level of the design flow (elements per span x level)
DEFAULT_LEVEL = 2
#: default highest circumferential harmonic of the two-zone rim load
DEFAULT_HARMONICS = 24


# --------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class CupGeometry:
    """Meridian geometry of a cup flexspline, SI.

    z = 0 is the boss-side face of the diaphragm, z = ``length_m`` the open end.

    Attributes
    ----------
    boss_radius_m : float
        Outer radius a of the rigid boss (inner edge of the diaphragm), m.
    diaphragm_m : float
        Diaphragm thickness h, m.
    bore_radius_m : float
        Inner radius of the cylinder wall (wave-generator side), m.
    wall_m : float
        Wall thickness t of the smooth cylinder, m.
    length_m : float
        Cup length L from the diaphragm face to the open end, m.
    rim_width_m : float
        Axial width b of the toothed rim (tooth face width) at the open end, m.
    rim_extra_m : float
        Extra radial thickness of the toothed rim band over the wall, m.
    youngs_modulus_Pa, poisson_ratio : float
        Material.
    density_kg_m3 : float
        Material density, kg/m³.
    engaged_fraction : float
        Fraction of the circumference in tooth contact (both zones together), -.
    """

    boss_radius_m: float
    diaphragm_m: float
    bore_radius_m: float
    wall_m: float
    length_m: float
    rim_width_m: float
    rim_extra_m: float
    youngs_modulus_Pa: float
    poisson_ratio: float
    density_kg_m3: float = STEEL_DENSITY_KG_M3
    engaged_fraction: float = 0.30

    @property
    def outer_radius_m(self) -> float:
        """Outer radius of the smooth wall, m."""
        return self.bore_radius_m + self.wall_m

    @property
    def rim_radius_m(self) -> float:
        """Outer radius of the toothed rim band (where the tooth load acts), m."""
        return self.outer_radius_m + self.rim_extra_m

    @property
    def shear_modulus_Pa(self) -> float:
        """G = E / (2 (1 + nu)), Pa."""
        return self.youngs_modulus_Pa / (2.0 * (1.0 + self.poisson_ratio))


def cup_geometry(s: Structure, density_kg_m3: float = STEEL_DENSITY_KG_M3) -> CupGeometry:
    """Cup geometry of a catalogue :class:`~hdservo.design.structure.Structure`.

    The smooth wall's outer radius is d/2 (bore d/2 - t), the rim band is
    ``t + tooth_rim_extra_m`` thick over the face width, the diaphragm runs from
    the hub radius to the bore, and the tooth contact covers ``max_engaged_fraction``
    of the circumference.
    """
    return CupGeometry(
        boss_radius_m=s.hub_radius_m, diaphragm_m=s.diaphragm_m,
        bore_radius_m=0.5 * s.pitch_diameter_m - s.wall_m, wall_m=s.wall_m,
        length_m=s.cup_length_m, rim_width_m=s.face_width_m, rim_extra_m=s.tooth_rim_extra_m,
        youngs_modulus_Pa=s.youngs_modulus_Pa, poisson_ratio=s.poisson_ratio,
        density_kg_m3=density_kg_m3, engaged_fraction=s.max_engaged_fraction)


def validate(g: CupGeometry) -> None:
    """Refuse a geometry the mesh cannot represent: one line saying what was expected."""
    from ..errors import UserError
    for f in g.__dataclass_fields__:
        v = getattr(g, f)
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise UserError(f"flexspline FE geometry: {f}: expected a finite number, got {v!r}")
    checks = [
        (g.boss_radius_m > 0, f"boss_radius_m: expected > 0, got {g.boss_radius_m:g}"),
        (g.bore_radius_m > g.boss_radius_m,
         f"bore_radius_m: expected above the boss radius {g.boss_radius_m:g} m, got {g.bore_radius_m:g}"),
        (g.wall_m > 0, f"wall_m: expected > 0, got {g.wall_m:g}"),
        (g.diaphragm_m > 0, f"diaphragm_m: expected > 0, got {g.diaphragm_m:g}"),
        (g.rim_extra_m >= 0, f"rim_extra_m: expected >= 0, got {g.rim_extra_m:g}"),
        (0 < g.rim_width_m < g.length_m - g.diaphragm_m,
         f"rim_width_m: expected in (0, L - h = {g.length_m - g.diaphragm_m:g}) m, got {g.rim_width_m:g}"),
        (g.youngs_modulus_Pa > 0, f"youngs_modulus_Pa: expected > 0, got {g.youngs_modulus_Pa:g}"),
        (-1.0 < g.poisson_ratio < 0.5, f"poisson_ratio: expected in (-1, 0.5), got {g.poisson_ratio:g}"),
        (g.density_kg_m3 > 0, f"density_kg_m3: expected > 0, got {g.density_kg_m3:g}"),
        (0 < g.engaged_fraction <= 1, f"engaged_fraction: expected in (0, 1], got {g.engaged_fraction:g}"),
    ]
    for ok, msg in checks:
        if not ok:
            raise UserError(f"flexspline FE geometry: {msg}")


# --------------------------------------------------------------------------- meshing
Rect = Tuple[float, float, float, float]   # r0, r1, z0, z1


def section_mesh(rects: Sequence[Rect], r_spans: Sequence[Tuple[float, float, int]],
                 z_spans: Sequence[Tuple[float, float, int]], level: int = DEFAULT_LEVEL):
    """Structured quadrilateral mesh of a union of rectangles in the (r, z) plane.

    Parameters
    ----------
    rects : sequence of (r0, r1, z0, z1)
        Material rectangles, m.
    r_spans, z_spans : sequence of (start, end, cells)
        Tensor-grid spans (consecutive) and their cell counts at level 1, m.
    level : int
        Refinement level: every span gets ``cells x level`` cells.

    Returns
    -------
    skfem.MeshQuad1
        Cells of the tensor grid whose centre lies in a rectangle; unused nodes removed.
    """
    from skfem import MeshQuad
    if level < 1:
        raise ValueError("mesh level must be >= 1")

    def axis(spans: Sequence[Tuple[float, float, int]]) -> np.ndarray:
        pts = [np.linspace(a, b, max(1, int(n)) * level + 1)[:-1] for a, b, n in spans]
        return np.concatenate(pts + [np.array([spans[-1][1]])])

    r, z = axis(r_spans), axis(z_spans)
    m = MeshQuad.init_tensor(r, z)
    c = m.p[:, m.t].mean(axis=1)
    inside = np.zeros(m.t.shape[1], dtype=bool)
    for r0, r1, z0, z1 in rects:
        inside |= (c[0] > r0) & (c[0] < r1) & (c[1] > z0) & (c[1] < z1)
    return m.remove_elements(np.flatnonzero(~inside))


def cup_mesh(g: CupGeometry, level: int = DEFAULT_LEVEL):
    """Meridian mesh of the cup: diaphragm, wall and rim band (level-1 counts: 1 cell
    through each thickness, diaphragm 8 radial, free wall 14 axial, rim 4 axial)."""
    a, ri, ro, re = g.boss_radius_m, g.bore_radius_m, g.outer_radius_m, g.rim_radius_m
    h, L, b = g.diaphragm_m, g.length_m, g.rim_width_m
    rects: List[Rect] = [(a, ro, 0.0, h), (ri, ro, 0.0, L)]
    r_spans = [(a, ri, 8), (ri, ro, 1)]
    if g.rim_extra_m > 0:
        rects.append((ro, re, L - b, L))
        r_spans.append((ro, re, 1))
    z_spans = [(0.0, h, 1), (h, L - b, 14), (L - b, L, 4)]
    return section_mesh(rects, r_spans, z_spans, level)


# --------------------------------------------------------------------------- forms
def _lame(e: float, nu: float) -> Tuple[float, float]:
    return e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))


class AxiModel:
    """Fourier-harmonic axisymmetric solid on a meridian mesh (9-node quads).

    Parameters
    ----------
    mesh : skfem.MeshQuad1
        Meridian mesh, x = r (> 0 everywhere), y = z, m.
    youngs_modulus_Pa, poisson_ratio, density_kg_m3 : float
        Material.
    """

    def __init__(self, mesh, youngs_modulus_Pa: float, poisson_ratio: float, density_kg_m3: float) -> None:
        from skfem import Basis, ElementQuad2, ElementVector
        if float(np.min(mesh.p[0])) <= 0.0:
            raise ValueError("meridian mesh must lie at r > 0")
        self.mesh = mesh
        self.e, self.nu, self.rho = float(youngs_modulus_Pa), float(poisson_ratio), float(density_kg_m3)
        self.vec = Basis(mesh, ElementVector(ElementQuad2(), dim=3))
        self.sca = Basis(mesh, ElementQuad2())

    # ---- assembly
    def stiffness(self, n: int) -> sp.csr_matrix:
        """Stiffness matrix of harmonic ``n`` (signed, family A; ``n = 0`` gives torsion on the scalar
        basis).  Energy = 1/2 x^T K x for the true 3-D field."""
        from skfem import BilinearForm, asm
        lam, mu = _lame(self.e, self.nu)
        if n == 0:
            @BilinearForm
            def k0(u, v, w):
                r = w.x[0]
                return 2 * math.pi * r * mu * ((u.grad[0] - u / r) * (v.grad[0] - v / r) + u.grad[1] * v.grad[1])
            return asm(k0, self.sca).tocsr()

        def strains(u, r):
            ur, ut, uz = np.asarray(u)
            gr = u.grad
            return ((gr[0][0], (ur + n * ut) / r, gr[2][1]),
                    (gr[0][1] + gr[2][0], gr[1][0] - ut / r - n * ur / r, gr[1][1] - n * uz / r))

        @BilinearForm
        def kn(u, v, w):
            r = w.x[0]
            (nu_, su) = strains(u, r)
            (nv, sv) = strains(v, r)
            tr = (nu_[0] + nu_[1] + nu_[2]) * (nv[0] + nv[1] + nv[2])
            return math.pi * r * (lam * tr + 2 * mu * sum(a * b for a, b in zip(nu_, nv))
                                  + mu * sum(a * b for a, b in zip(su, sv)))
        return asm(kn, self.vec).tocsr()

    def mass(self, n: int) -> sp.csr_matrix:
        """Consistent mass matrix of harmonic ``n`` (kinetic energy = 1/2 v^T M v)."""
        from skfem import BilinearForm, asm
        rho = self.rho
        if n == 0:
            @BilinearForm
            def m0(u, v, w):
                return 2 * math.pi * rho * w.x[0] * u * v
            return asm(m0, self.sca).tocsr()

        @BilinearForm
        def mn(u, v, w):
            return math.pi * rho * w.x[0] * np.sum(np.asarray(u) * np.asarray(v), axis=0)
        return asm(mn, self.vec).tocsr()

    def traction(self, n: int, component: int, where: Callable[[np.ndarray], np.ndarray],
                 amplitude: float) -> np.ndarray:
        """Load vector of a surface traction ``amplitude x (cos|sin) n theta`` on the facets
        where ``where(x)`` holds (component 0 r, 1 theta, 2 z; ``n = 0``: theta only), N."""
        from skfem import ElementQuad2, ElementVector, FacetBasis, LinearForm, asm
        facets = self.mesh.facets_satisfying(where)
        if len(facets) == 0:
            raise ValueError("traction: no facet satisfies the location predicate")
        w_ang = 2 * math.pi if n == 0 else math.pi
        if n == 0:
            fb = FacetBasis(self.mesh, ElementQuad2(), facets=facets)

            @LinearForm
            def l0(v, w):
                return w_ang * amplitude * w.x[0] * v
            return asm(l0, fb)
        fb = FacetBasis(self.mesh, ElementVector(ElementQuad2(), dim=3), facets=facets)

        @LinearForm
        def ln(v, w):
            return w_ang * amplitude * w.x[0] * np.asarray(v)[component]
        return asm(ln, fb)

    # ---- degrees of freedom
    def dofs(self, where: Callable[[np.ndarray], np.ndarray], component: Optional[int] = None) -> np.ndarray:
        """DOFs on the facets where ``where(x)`` holds: scalar basis if ``component`` is None,
        else component 0 (r), 1 (theta), 2 (z) of the vector basis."""
        if component is None:
            return np.unique(self.sca.get_dofs(where).all())
        return np.unique(self.vec.get_dofs(where).all(f"u^{component + 1}"))

    def locs(self, dofs: np.ndarray, vector: bool = True) -> np.ndarray:
        """(r, z) of each DOF, shape (2, len(dofs)), m."""
        return (self.vec if vector else self.sca).doflocs[:, dofs]


def _solve(k: sp.csr_matrix, f: np.ndarray, fixed: np.ndarray, x_fixed: Optional[np.ndarray] = None) -> np.ndarray:
    """Solve K x = f with x[fixed] = x_fixed (default 0)."""
    n = k.shape[0]
    x = np.zeros(n)
    if x_fixed is not None:
        x[fixed] = x_fixed
    free = np.setdiff1d(np.arange(n), fixed)
    rhs = f[free] - k[free][:, fixed] @ x[fixed]
    x[free] = spsolve(k[free][:, free].tocsc(), rhs)
    return x


# --------------------------------------------------------------------------- cup model
class CupModel:
    """The FE model of one cup flexspline at one mesh level.

    Parameters
    ----------
    g : CupGeometry
    level : int
        Mesh level (1 coarse; :data:`DEFAULT_LEVEL` in the design flow).
    """

    def __init__(self, g: CupGeometry, level: int = DEFAULT_LEVEL) -> None:
        validate(g)
        self.g = g
        self.level = int(level)
        self.model = AxiModel(cup_mesh(g, level), g.youngs_modulus_Pa, g.poisson_ratio, g.density_kg_m3)
        tol = 1e-6 * g.bore_radius_m
        L, b = g.length_m, g.rim_width_m
        self.is_boss = lambda x: np.abs(x[0] - g.boss_radius_m) < tol
        self.is_bore_rim = lambda x: (np.abs(x[0] - g.bore_radius_m) < tol) & (x[1] > L - b - tol)
        self.is_rim_outer = lambda x: (np.abs(x[0] - g.rim_radius_m) < tol) & (x[1] > L - b - tol)
        self._k: Dict[int, sp.csr_matrix] = {}

    def k(self, n: int) -> sp.csr_matrix:
        if n not in self._k:
            self._k[n] = self.model.stiffness(n)
        return self._k[n]

    @property
    def dof_count(self) -> int:
        """Unknowns of one 3-component harmonic, -."""
        return int(self.model.vec.N)

    def mass_kg(self) -> float:
        """Mass of the meshed flexspline (boss excluded), kg."""
        from skfem import Functional, asm

        @Functional
        def vol(w):
            return 2 * math.pi * w.x[0]
        return float(self.g.density_kg_m3 * asm(vol, self.model.sca))

    # ---- static torsion, two-zone load, ellipse imposed
    def torsion(self, harmonics: int = DEFAULT_HARMONICS, ellipse_m: float = 0.0,
                zones: bool = True) -> Dict[str, float]:
        """Torsional stiffness for a unit output torque on the toothed rim.

        Parameters
        ----------
        harmonics : int
            Highest harmonic of the two-zone load expansion (even harmonics 2..harmonics).
        ellipse_m : float
            Radial amplitude w0 of the wave-generator ellipse imposed on the rim bore, m.
        zones : bool
            True: the torque enters over the two engagement zones; False: uniformly
            around the rim (the axisymmetric idealisation, harmonic 0 only).

        Returns
        -------
        dict
            ``stiffness_Nm_per_rad``; ``uniform_stiffness_Nm_per_rad`` (harmonic 0 alone);
            ``ring_stiffness_Nm_per_rad`` (the tooth surface turned as a rigid ring: the rim of
            the torsional modes); ``wg_force_N`` (diametral force pair equivalent
            to the bore pressure that holds the ellipse); ``dofs`` per harmonic.
        """
        g, mdl = self.g, self.model
        big_r, b = g.rim_radius_m, g.rim_width_m
        beta = 0.5 * math.pi * g.engaged_fraction          # half-angle of each zone
        a0 = 1.0 / (2 * math.pi * big_r ** 2 * b)          # mean traction of a unit torque, Pa
        q = a0 * math.pi / (2 * beta)                      # traction inside the zones, Pa
        # harmonic 0 (torsion), boss clamped; the bore constraint is radial only
        f0 = mdl.traction(0, 1, self.is_rim_outer, a0)
        x0 = _solve(self.k(0), f0, mdl.dofs(self.is_boss))
        w_uniform = float(f0 @ x0)
        work = w_uniform
        fixed = np.concatenate([mdl.dofs(self.is_boss, c) for c in range(3)] + [mdl.dofs(self.is_bore_rim, 0)])
        if zones:
            for n in range(2, int(harmonics) + 1, 2):
                an = q * 4.0 * math.sin(n * beta) / (n * math.pi)   # cos n theta coefficient
                # tangential traction an cos n theta pairs with family B (= family A with -n)
                fn = mdl.traction(-n, 1, self.is_rim_outer, an)
                xn = _solve(self.k(-n), fn, fixed)
                work += float(fn @ xn)
        # the rim's tooth surface turned as a rigid ring (the modal model's rim): U_theta = r
        rim = mdl.dofs(self.is_rim_outer)
        boss = mdl.dofs(self.is_boss)
        xr = _solve(self.k(0), np.zeros(self.k(0).shape[0]), np.concatenate([boss, rim]),
                    np.concatenate([np.zeros(len(boss)), mdl.locs(rim, vector=False)[0]]))
        out = {"stiffness_Nm_per_rad": 1.0 / work, "uniform_stiffness_Nm_per_rad": 1.0 / w_uniform,
               "ring_stiffness_Nm_per_rad": float(xr @ (self.k(0) @ xr)),
               "zone_half_angle_deg": math.degrees(beta), "harmonics": int(harmonics) if zones else 0,
               "dofs": self.dof_count}
        # the imposed ellipse: family A, n = 2, U_r = w0 on the rim bore
        bore_r = mdl.dofs(self.is_bore_rim, 0)
        fix2 = np.concatenate([mdl.dofs(self.is_boss, c) for c in range(3)] + [bore_r])
        vals = np.zeros(len(fix2))
        vals[len(fix2) - len(bore_r):] = ellipse_m
        xe = _solve(self.k(2), np.zeros(self.k(2).shape[0]), fix2, vals)
        reac = self.k(2) @ xe
        out["wg_force_N"] = float(np.sum(reac[bore_r]) / 2.0)
        out["ellipse_m"] = float(ellipse_m)
        return out

    # ---- modes with the load attached to the boss
    def torsional_modes(self, load_inertia_kgm2: float, count: int = 1,
                        rim_spring_Nm_per_rad: Optional[float] = None) -> Dict[str, object]:
        """Torsional modes: the load as a rigid inertia on the boss, the rim's tooth surface held
        (clamped, or a rigid ring on ``rim_spring_Nm_per_rad``: tooth mesh + WG bearing), see
        :func:`torsional_modes`."""
        return torsional_modes(self.model, self.is_boss, self.is_rim_outer, load_inertia_kgm2, count,
                               rim_spring_Nm_per_rad)

    def tilting_modes(self, tilt_inertia_kgm2: float, load_mass_kg: float = 0.0, count: int = 1,
                      load_offset_m: float = 0.0) -> Dict[str, object]:
        """Tilting modes: the load as a rigid body on the boss, the rim band clamped on its tooth
        surface and its bore, see :func:`tilting_modes`."""
        return tilting_modes(self.model, self.is_boss, [self.is_rim_outer, self.is_bore_rim], tilt_inertia_kgm2,
                             load_mass_kg, count, load_offset_m)


def _reduction(dof_sets: Sequence[np.ndarray], shapes: Sequence[np.ndarray], clamp: np.ndarray,
               ndof: int) -> sp.csr_matrix:
    """Map q = [free dofs, rigid dofs] -> full dofs; rigid dof j drives the rows ``dof_sets[i]``
    with the coefficients ``shapes[i][:, j]``; ``clamp`` rows are zero."""
    slaved = np.unique(np.concatenate(list(dof_sets)))
    free = np.setdiff1d(np.arange(ndof), np.union1d(slaved, clamp))
    nrig = shapes[0].shape[1]
    rows, cols, vals = list(free), list(range(len(free))), [1.0] * len(free)
    for dset, shp in zip(dof_sets, shapes):
        for j in range(nrig):
            rows += list(dset)
            cols += [len(free) + j] * len(dset)
            vals += list(shp[:, j])
    return sp.csr_matrix((vals, (rows, cols)), shape=(ndof, len(free) + nrig))


def torsional_modes(mdl: AxiModel, boss: Callable[[np.ndarray], np.ndarray], rim: Callable[[np.ndarray], np.ndarray],
                    load_inertia_kgm2: float, count: int = 1,
                    rim_spring_Nm_per_rad: Optional[float] = None) -> Dict[str, object]:
    """Torsional (harmonic 0) modes with a rigid load on the ``boss`` facets.

    Parameters
    ----------
    mdl : AxiModel
    boss, rim : callable
        Location predicates of the facets the load is attached to and of the held facets.
    load_inertia_kgm2 : float
        Load inertia about the axis, kg·m² (rigid body: U_theta = r phi on the boss).
    count : int
        Modes to return.
    rim_spring_Nm_per_rad : float, optional
        None: ``rim`` clamped.  Else ``rim`` is a rigid ring (U_theta = r phi_rim) on a torsional
        spring to the ground (tooth mesh and wave-generator bearing in series), N·m/rad.

    Returns
    -------
    dict
        ``frequencies_Hz``, ``load_energy_share`` (kinetic-energy fraction of the load per mode).
    """
    k, m = mdl.stiffness(0), mdl.mass(0)
    bd = mdl.dofs(boss)
    rd = mdl.dofs(rim)
    rb = mdl.locs(bd, vector=False)[0]
    if rim_spring_Nm_per_rad is None:
        p = _reduction([bd], [rb[:, None]], rd, k.shape[0])
        return _eig(p, k, m, [0.0], [load_inertia_kgm2], count, n_load=1)
    rr = mdl.locs(rd, vector=False)[0]
    p = _reduction([bd, rd], [np.column_stack([rb, 0 * rb]), np.column_stack([0 * rr, rr])],
                   np.array([], dtype=int), k.shape[0])
    return _eig(p, k, m, [0.0, float(rim_spring_Nm_per_rad)], [load_inertia_kgm2, 0.0], count, n_load=1)


def tilting_modes(mdl: AxiModel, boss: Callable[[np.ndarray], np.ndarray],
                  clamps: Sequence[Callable[[np.ndarray], np.ndarray]], tilt_inertia_kgm2: float,
                  load_mass_kg: float = 0.0, count: int = 1, load_offset_m: float = 0.0) -> Dict[str, object]:
    """Tilting (harmonic 1) modes with a rigid load on the ``boss`` facets.

    The load moves as a rigid body: lateral translation c and rotation psi about a diameter
    through z = 0 (u_x = c + psi z, u_z = -psi x, i.e. U_r = c + psi z, U_theta = -(c + psi z),
    U_z = -psi r).

    Parameters
    ----------
    mdl : AxiModel
    boss : callable
        Location predicate of the facets the load is attached to.
    clamps : sequence of callable
        Location predicates of the clamped facets (every component).
    tilt_inertia_kgm2 : float
        Load inertia about a diameter through its centre of mass, kg·m².
    load_mass_kg : float
        Load mass, kg (0: only the flexspline's own mass resists the translation).
    load_offset_m : float
        Axial distance of the load's centre of mass from z = 0, away from the cup (-z), m.
    """
    k, m = mdl.stiffness(1), mdl.mass(1)
    clamp = np.concatenate([mdl.dofs(c, i) for c in clamps for i in range(3)])
    sets, shapes = [], []
    for c in range(3):
        d = mdl.dofs(boss, c)
        r, z = mdl.locs(d)
        shp = {0: np.column_stack([np.ones_like(r), z]), 1: np.column_stack([-np.ones_like(r), -z]),
               2: np.column_stack([np.zeros_like(r), -r])}[c]
        sets.append(d)
        shapes.append(shp)
    p = _reduction(sets, shapes, clamp, k.shape[0])
    # the centre of mass at z = -offset moves with c - psi offset
    e = -load_offset_m
    m_rig = np.array([[load_mass_kg, load_mass_kg * e],
                      [load_mass_kg * e, load_mass_kg * e * e + tilt_inertia_kgm2]])
    return _eig(p, k, m, [0.0, 0.0], m_rig, count, n_load=2)


def _eig(p: sp.csr_matrix, k: sp.csr_matrix, m: sp.csr_matrix, extra_k: Sequence[float], extra_m,
         count: int, n_load: int) -> Dict[str, object]:
    """Lowest modes of the reduced system; the last rigid dofs get ``extra_k`` (diagonal) and
    ``extra_m`` (diagonal list or a full matrix over the first ``n_load`` rigid dofs)."""
    kr = (p.T @ k @ p).tolil()
    mr = (p.T @ m @ p).tolil()
    nr = len(extra_k)
    base = kr.shape[0] - nr
    for i, kv in enumerate(extra_k):
        kr[base + i, base + i] += kv
    em = np.asarray(extra_m, dtype=float)
    if em.ndim == 1:
        for i, mv in enumerate(em):
            mr[base + i, base + i] += mv
    else:
        for i in range(em.shape[0]):
            for j in range(em.shape[1]):
                mr[base + i, base + j] += em[i, j]
    kr, mr = kr.tocsc(), mr.tocsc()
    vals, vecs = eigsh(kr, k=count, M=mr, sigma=0.0, which="LM")
    order = np.argsort(vals)
    vals, vecs = vals[order], vecs[:, order]
    freqs = np.sqrt(np.maximum(vals, 0.0)) / (2 * math.pi)
    share = []
    for i in range(count):
        x = vecs[:, i]
        tot = float(x @ (mr @ x))
        xl = x[base:base + n_load]
        ml = np.diag(em) if em.ndim == 1 else em
        share.append(float(xl @ (ml[:n_load, :n_load] @ xl)) / tot)
    return {"frequencies_Hz": [float(f) for f in freqs], "load_energy_share": share, "vectors": vecs,
            "reduction": p}


# --------------------------------------------------------------------------- one-call analysis
@dataclass(frozen=True)
class FeResult:
    """FE figures of one flexspline with one load (:func:`analyse`).

    Attributes
    ----------
    stiffness_Nm_per_rad : float
        Flexspline torsional stiffness, two-zone tooth load, WG ellipse imposed, N·m/rad.
    uniform_stiffness_Nm_per_rad : float
        The same with the torque spread uniformly around the rim, N·m/rad.
    torsional_Hz : float
        First torsional mode, load on the boss, rim held by ``rim_spring`` (or clamped), Hz.
    tilting_Hz : float
        First tilting mode, load on the boss, rim band clamped, Hz.
    flexspline_mass_kg : float
        Mass of the meshed flexspline (boss excluded), kg.
    wg_force_N : float
        Diametral force pair that holds the imposed ellipse (bore pressure equivalent), N.
    level, dofs : int
        Mesh level and unknowns per 3-component harmonic.
    """

    stiffness_Nm_per_rad: float
    uniform_stiffness_Nm_per_rad: float
    torsional_Hz: float
    tilting_Hz: float
    flexspline_mass_kg: float
    wg_force_N: float
    level: int
    dofs: int


def analyse(g: CupGeometry, load_inertia_kgm2: float, *, tilt_inertia_kgm2: Optional[float] = None,
            load_mass_kg: float = 0.0, rim_spring_Nm_per_rad: Optional[float] = None,
            ellipse_m: float = 0.0, level: int = DEFAULT_LEVEL,
            harmonics: int = DEFAULT_HARMONICS) -> FeResult:
    """Static stiffness and first torsional and tilting modes of a cup flexspline with a load.

    Parameters
    ----------
    g : CupGeometry
    load_inertia_kgm2 : float
        Load inertia about the output axis, kg·m².
    tilt_inertia_kgm2 : float, optional
        Load inertia about a diameter, kg·m² (default J_L / 2: a thin disc).
    load_mass_kg : float
        Load mass for the tilting mode, kg.
    rim_spring_Nm_per_rad : float, optional
        Tooth mesh and wave-generator bearing in series between the rim and the ground
        for the torsional mode, N·m/rad (None: rim clamped, the flexspline alone).
    ellipse_m : float
        Imposed wave-generator radial deflection w0, m.
    level, harmonics : int
        Mesh level and highest load harmonic.
    """
    cm = CupModel(g, level)
    st = cm.torsion(harmonics, ellipse_m)
    tq = cm.torsional_modes(load_inertia_kgm2, 1, rim_spring_Nm_per_rad)
    jt = 0.5 * load_inertia_kgm2 if tilt_inertia_kgm2 is None else tilt_inertia_kgm2
    tl = cm.tilting_modes(jt, load_mass_kg, 1)
    return FeResult(st["stiffness_Nm_per_rad"], st["uniform_stiffness_Nm_per_rad"],
                    tq["frequencies_Hz"][0], tl["frequencies_Hz"][0], cm.mass_kg(), st["wg_force_N"],
                    cm.level, cm.dof_count)
