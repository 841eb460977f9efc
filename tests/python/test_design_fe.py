"""FE flexspline model (scikit-fem): closed forms in limiting cases, mesh convergence, the series rule."""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Callable, Tuple

import numpy as np
import pytest

from hdservo.cli import UserError
from hdservo.design import catalogue as cat
from hdservo.design import fe_gear as fg
from hdservo.design import flexspline_fe as fe
from hdservo.design import structure as st

E, RHO = 206e9, 7850.0
R_IN, T = 0.03, 0.0006          # thin tube: t / r = 2 %


def _tube(length: float, nu: float, level: int, cells: int = 40,
          rho: float = RHO) -> Tuple[fe.AxiModel, Callable, Callable]:
    m = fe.section_mesh([(R_IN, R_IN + T, 0.0, length)], [(R_IN, R_IN + T, 1)], [(0.0, length, cells)], level)
    base = lambda x: x[1] < 1e-9                       # noqa: E731
    tip = lambda x: x[1] > length - 1e-9               # noqa: E731
    return fe.AxiModel(m, E, nu, rho), base, tip


def _thin_wall() -> Tuple[float, float, float]:
    rm = R_IN + T / 2
    return rm, 2 * math.pi * rm ** 3 * T, math.pi * rm ** 3 * T      # r_m, J, I (thin wall)


@pytest.mark.parametrize("level", [1, 2, 3])
def test_thin_tube_torsion_matches_gj_over_l(level: int) -> None:
    nu, length = 0.3, 0.3
    mdl, base, tip = _tube(length, nu, level)
    rm, j, _ = _thin_wall()
    # unit torque as a uniform shear traction on the end face
    f = mdl.traction(0, 1, tip, 1.0 / (2 * math.pi * rm ** 2 * T))
    x = fe._solve(mdl.stiffness(0), f, mdl.dofs(base))
    k_fe = 1.0 / float(f @ x)
    k_cf = E / (2 * (1 + nu)) * j / length
    assert k_fe == pytest.approx(k_cf, rel=0.02)


def test_tube_bending_matches_beam_theory() -> None:
    """Harmonic 1 (the tilting kinematics): a cantilever tube under an end moment, psi = M L / (E I)."""
    length = 0.6
    mdl, base, tip = _tube(length, 0.0, 2)
    rm, _, i = _thin_wall()
    f = mdl.traction(1, 2, tip, rm / i)                 # axial stress M r cos(theta) / I, M = 1
    fixed = np.concatenate([mdl.dofs(base, c) for c in range(3)])
    x = fe._solve(mdl.stiffness(1), f, fixed)
    assert 1.0 / float(f @ x) == pytest.approx(E * i / length, rel=0.02)


def test_ring_ovalisation_matches_curved_beam() -> None:
    """Harmonic 2 (the wave-generator ellipse): a free ring under q cos(2 theta), w = q R^4 / (9 E I)."""
    b, r = 0.006, 0.03
    m = fe.section_mesh([(r - T / 2, r + T / 2, 0.0, b)], [(r - T / 2, r + T / 2, 1)], [(0.0, b, 4)], 2)
    mdl = fe.AxiModel(m, E, 0.0, RHO)
    outer = lambda x: x[0] > r + T / 2 - 1e-9           # noqa: E731
    f = mdl.traction(2, 0, outer, 1.0)                  # 1 Pa on the outer face
    x = fe.spsolve(mdl.stiffness(2).tocsc(), f)
    w_fe = float(np.mean(x[mdl.dofs(outer, 0)]))
    q = b * (r + T / 2) / r                              # line load per unit mid-circumference, N/m
    assert w_fe == pytest.approx(q * r ** 4 / (9 * E * b * T ** 3 / 12), rel=0.02)


def test_torsional_mode_with_load_inertia_matches_closed_form() -> None:
    length, nu, j_load = 0.3, 0.3, 2e-3
    mdl, base, tip = _tube(length, nu, 2, cells=20)
    rm, j, _ = _thin_wall()
    k = E / (2 * (1 + nu)) * j / length
    j_tube = RHO * 2 * math.pi * rm * T * length * rm ** 2
    res = fe.torsional_modes(mdl, tip, base, j_load, count=2)
    f_cf = math.sqrt(k / (j_load + j_tube / 3)) / (2 * math.pi)     # Rayleigh: a third of the shaft
    assert res["frequencies_Hz"][0] == pytest.approx(f_cf, rel=0.02)
    assert res["load_energy_share"][0] > 0.85
    # a rim spring in series lowers it as springs in series do
    soft = fe.torsional_modes(mdl, tip, base, j_load, 1, rim_spring_Nm_per_rad=k)
    assert soft["frequencies_Hz"][0] == pytest.approx(f_cf / math.sqrt(2), rel=0.02)


def test_tilting_mode_with_load_inertia_matches_closed_form() -> None:
    """A massless translation condenses the tip's (c, psi) stiffness to E I / L for the tilt
    (a near-massless tube, so its own lateral modes stay far above)."""
    length, j_t = 1.2, 0.05                           # L = 40 r: shear deflection < 0.5 %
    mdl, base, tip = _tube(length, 0.0, 1, cells=60, rho=1.0)
    _, _, i = _thin_wall()
    res = fe.tilting_modes(mdl, tip, [base], j_t, load_mass_kg=0.0, count=1)
    assert res["frequencies_Hz"][0] == pytest.approx(math.sqrt(E * i / length / j_t) / (2 * math.pi), rel=0.02)


@pytest.fixture(scope="module")
def cup25() -> fe.CupGeometry:
    return fe.cup_geometry(st.structure_for(25, 100))


@pytest.fixture(scope="module")
def levels(cup25: fe.CupGeometry):
    out = []
    for lv in (1, 2, 3):
        cm = fe.CupModel(cup25, lv)
        out.append((cm.torsion(16)["stiffness_Nm_per_rad"], cm.torsional_modes(0.5)["frequencies_Hz"][0],
                    cm.tilting_modes(0.25)["frequencies_Hz"][0], cm.dof_count))
    return out


def test_cup_converges_over_three_mesh_levels(levels) -> None:
    k = [r[0] for r in levels]
    # a conforming displacement model approaches from the stiff side, with shrinking steps
    assert k[0] > k[1] > k[2]
    assert abs(k[0] - k[1]) > abs(k[1] - k[2])
    assert abs(k[1] / k[2] - 1.0) < 2e-3
    for idx in (1, 2):
        f = [r[idx] for r in levels]
        assert f[0] >= f[1] >= f[2] and abs(f[1] / f[2] - 1.0) < 5e-3
    assert levels[0][3] < levels[1][3] < levels[2][3]


def test_cup_against_uniform_load_and_ellipse(cup25: fe.CupGeometry) -> None:
    cm = fe.CupModel(cup25, 1)
    r0 = cm.torsion(16)
    r1 = cm.torsion(16, ellipse_m=3e-4)
    # two engagement zones bend the rim locally: softer than the torque spread round the rim
    assert r0["stiffness_Nm_per_rad"] < r0["uniform_stiffness_Nm_per_rad"] < r0["ring_stiffness_Nm_per_rad"]
    # linear elasticity: the imposed ellipse (harmonic 2, the other family) leaves the stiffness alone
    assert r1["stiffness_Nm_per_rad"] == pytest.approx(r0["stiffness_Nm_per_rad"], rel=1e-9)
    assert r0["wg_force_N"] == 0.0 and r1["wg_force_N"] > 0.0
    # more harmonics: the expansion has converged
    assert cm.torsion(32)["stiffness_Nm_per_rad"] == pytest.approx(r0["stiffness_Nm_per_rad"], rel=1e-3)


def test_scale_and_parameter_directions(cup25: fe.CupGeometry) -> None:
    k0 = fe.CupModel(cup25, 1).torsion(8)["stiffness_Nm_per_rad"]
    # linear elasticity is scale-free: lengths x 2 -> stiffness x 8
    k2 = fe.CupModel(fg.scaled(cup25, 2.0), 1).torsion(8)["stiffness_Nm_per_rad"]
    assert k2 == pytest.approx(8.0 * k0, rel=1e-6)

    def k(**kw: float) -> float:
        return fe.CupModel(replace(cup25, **kw), 1).torsion(8)["stiffness_Nm_per_rad"]
    g = cup25
    assert k(wall_m=1.2 * g.wall_m) > k0
    assert k(diaphragm_m=1.2 * g.diaphragm_m) > k0
    assert k(boss_radius_m=1.2 * g.boss_radius_m) > k0
    assert k(length_m=1.2 * g.length_m) < k0


def test_bad_geometry_is_refused_in_one_line(cup25: fe.CupGeometry) -> None:
    with pytest.raises(UserError) as e:
        fe.CupModel(replace(cup25, boss_radius_m=cup25.bore_radius_m * 1.1), 1)
    assert "bore_radius_m: expected above the boss radius" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(UserError, match="wall_m: expected > 0"):
        fe.CupModel(replace(cup25, wall_m=-1e-3), 1)
    with pytest.raises(UserError, match="length_m: expected a finite number"):
        fe.CupModel(replace(cup25, length_m=float("nan")), 1)


def test_rule_file_errors(tmp_path: Path) -> None:
    p = tmp_path / "rule.toml"
    p.write_text("[mesh_rule]\nk1_mesh_N_per_m2 = 'stiff'\n")
    with pytest.raises(UserError, match=r"k1_mesh_N_per_m2: expected a finite number"):
        fg.load_rule(p)
    p.write_text("x = 1\n")
    with pytest.raises(UserError, match=r"missing table \[mesh_rule\]"):
        fg.load_rule(p)


@pytest.fixture(scope="module")
def cases():
    return fg.cases()


def test_stored_rule_is_the_fit(cases) -> None:
    fit, stored = fg.fit_rule(cases), fg.load_rule()
    for name in fit.__dataclass_fields__:
        assert getattr(fit, name) == pytest.approx(getattr(stored, name), rel=1e-4), name


def test_flexspline_stiffness_uses_similarity_exactly() -> None:
    s = st.structure_for(32, 80)
    direct = fe.CupModel(fe.cup_geometry(s)).torsion()["stiffness_Nm_per_rad"]
    assert fg.flexspline_stiffness(s) == pytest.approx(direct, rel=1e-6)


def test_held_out_sizes(cases) -> None:
    cv = fg.cross_validate(cases)
    assert {r["size"] for r in cv} == {c.row.size for c in cases} and len(cv) == len(cases)
    inner = [r for r in cv if r["size"] != min(r["size"] for r in cv)]
    # sizes inside the catalogue's range, predicted without their own rows
    assert max(abs(r["k3_err"]) for r in inner) < 0.20
    assert max(abs(r["k1_err"]) for r in inner) < 0.20
    # the flexspline is the smaller part of the gear's compliance: 20-50 % at both levels
    assert all(0.15 < r["k1_fe_share"] < r["k3_fe_share"] < 0.55 for r in cv)


def test_candidate_figures_keep_catalogue_k1() -> None:
    g = cat.find_gear(25, 100)
    fig = fg.candidate_figures(g, 0.5, level=1)
    f_two_mass = math.sqrt(g.k1_Nm_per_rad / 0.5) / (2 * math.pi)
    # the modal model's static stiffness is K1; the flexspline's own inertia lowers the mode a little
    assert fig["torsional_Hz"] < f_two_mass
    assert fig["torsional_Hz"] == pytest.approx(f_two_mass, rel=2e-3)
    assert fig["rim_spring_source"].startswith("catalogue")
    assert 0.0 < fig["tilting_Hz"] < fig["torsional_Hz"]


# --------------------------------------------------------------------------- make results study, tiny grid
def test_results_study_logic_on_a_tiny_grid(tmp_path: Path, cases) -> None:
    from hdservo.design import fe_study as fs
    s = st.structure_for(25, 100)
    cf = fs.closed_forms(levels=(1,))
    assert all(abs(cf[0][f"{k}_err"]) < 0.02 for k in ("torsion", "bending", "ring"))
    conv = fs.convergence(s, 0.5, levels=(1, 2), harmonics=4)
    assert conv[0]["dofs"] < conv[1]["dofs"] and conv[0]["stiffness_Nm_per_rad"] > conv[1]["stiffness_Nm_per_rad"]
    sens = fs.sensitivity(s, 0.5, 5e4, names=("length", "wall"), step=0.1, level=1, harmonics=4)
    sw = fs.sweep(s, 0.5, 5e4, "length", [0.9, 1.0, 1.1], level=1, harmonics=4)
    # the elasticity is the log slope between the sweep's end points
    slope = math.log(sw[2]["stiffness_Nm_per_rad"] / sw[0]["stiffness_Nm_per_rad"]) / math.log(1.1 / 0.9)
    assert sens["length"]["stiffness_Nm_per_rad"] == pytest.approx(slope, rel=1e-9)
    assert sens["length"]["stiffness_Nm_per_rad"] < 0 < sens["wall"]["stiffness_Nm_per_rad"]
    # with a mesh spring in series the flexspline moves the mode less than it moves its own stiffness
    assert 0 < sens["wall"]["torsional_Hz"] < 0.5 * sens["wall"]["stiffness_Nm_per_rad"]
    small = [c for c in cases if c.row.ratio == 100 and c.row.size in (20, 25, 32)]
    ho = fs.held_out(small)
    assert len(ho["rows"]) == 3
    for lv in fg.LEVELS:
        errs = [abs(r[f"{lv}_err"]) for r in ho["rows"]]
        assert ho["summary"][lv]["max_abs"] == pytest.approx(max(errs))
        assert ho["summary"][lv]["per_size_max_abs"][25] == pytest.approx(errs[1])
    doc = {"gear": "CSF-25-100", "convergence": conv, "sensitivity": sens, "sweeps": {"length": sw}}
    files = fs.plot(doc, tmp_path)
    assert all((tmp_path / f).stat().st_size > 1000 for f in files) and len(files) == 3


def test_flow_ranks_the_lower_of_two_mass_and_fe_resonance() -> None:
    from hdservo.design import axis_builder as ab
    from hdservo.design import flow as fl
    from hdservo.design import spec as sp
    spec = sp.load_spec(Path(__file__).resolve().parents[2] / "examples" / "pitch_drive" / "SPEC.toml")
    sens = {x.name: x for x in cat.load_sensors()}
    mot = {m.name: m for m in cat.load_motors()}
    c = ab.Candidate(cat.find_gear(25, 80), mot["fl-050-class"], sens["enc-motor-17bit"],
                     sens["ring-output-25bit"], sens["gyro-mems-industrial"])
    fem = fl.fe_resonance(spec, c, level=1)
    assert fl.fe_resonance(spec, c, level=1) == fem                     # cached, a copy each time
    fa, _ = fl.resonance(spec, c)
    assert fem["torsional_Hz"] < fa and fem["tilting_Hz"] > 0
    # headline(): the ranked resonance is the design figure when present, else the two-mass value
    figs = {"min_rate": {"min_smooth_rate_deg_s": 0.001, "ladder": [{"rate_deg_s": 0.001, "stability": 0.01}]},
            "positioning": {"A_arcsec": 1.0, "A_with_encoder_arcsec": 7.0, "R_arcsec": 1.0},
            "stabilisation": {"predicted_rms_arcsec": 7.0, "hold_rms_arcsec": 1000.0},
            "peak_torque": {"peak_torque_Nm": 60.0}, "bandwidth": {"bandwidth_Hz": 20.0},
            "resonance": {"locked_motor_Hz": fa, "design_Hz": min(fa, fem["torsional_Hz"])}}
    assert fl.headline(figs)["resonance_Hz"] == fem["torsional_Hz"]
    del figs["resonance"]["design_Hz"]
    assert fl.headline(figs)["resonance_Hz"] == fa
