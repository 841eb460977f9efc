"""Loop model, limit-cycle prediction against an independent time-domain simulation, and the CLI."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hdservo.analysis.axis import REFERENCE_AXIS, REFERENCE_GAINS
from hdservo.analysis.catalogue import build
from hdservo.analysis.limitcycle import find_limit_cycles, loop_metrics
from hdservo.analysis.loop import LoopModel, equivalent_loop, freqresp
from oracles.timesim import measure_oscillation, simulate_lost_motion_loop
from hdservo.cli import main

OMEGA = 2 * math.pi * np.logspace(-2, 3.5, 1500)


def test_equivalent_linearisation_is_consistent_across_insertions():
    """Torsion path closed with N = K1 gives the same loop as the linear spring model."""
    m = LoopModel(REFERENCE_AXIS, REFERENCE_GAINS)
    w = 2 * math.pi * np.logspace(0, 3, 200)
    a = equivalent_loop(freqresp(m.open_system("torsion"), w), m.k_lin)
    b = equivalent_loop(freqresp(m.open_system("position_feedback"), w), 1.0)
    assert np.allclose(a["L"], b["L"], rtol=1e-6)
    assert np.allclose(a["T"], b["T"], rtol=1e-6)
    # a stiffer spring moves the crossover up a little, a softer down
    met = [loop_metrics(freqresp(m.open_system("torsion"), OMEGA), OMEGA, k) for k in (2e4, 3.1e4, 5.7e4)]
    assert all(x["phase_margin_deg"] is not None for x in met)


@pytest.mark.parametrize("pos_ki", [2000.0, 3000.0])
def test_lost_motion_limit_cycle_matches_time_simulation(pos_ki):
    """Acceptance (issue 8): detuned position loop (integral action) + 1' lost motion in the
    position feedback; DF amplitude within 30 % and frequency within 15 % of the simulated cycle."""
    gains = dict(REFERENCE_GAINS, pos_ki=pos_ki)
    entry = build("lost_motion", REFERENCE_AXIS)
    b = entry.nl.b
    H = LoopModel(REFERENCE_AXIS, gains).H("position_feedback")
    cycles = find_limit_cycles(H, entry.nl, entry.amplitudes, OMEGA)
    stable = [c for c in cycles if c.stable]
    assert len(stable) == 1
    lc = stable[0]
    assert lc.residual < 1e-8
    sim = simulate_lost_motion_loop(REFERENCE_AXIS, gains, b, duration_s=3.0, theta0_rad=5 * b)
    keep = sim["t_s"] > 1.5
    osc = measure_oscillation(sim["t_s"][keep], sim["theta_L_rad"][keep])
    assert osc.cycles >= 5
    assert abs(lc.amplitude - osc.amplitude) / osc.amplitude < 0.30
    assert abs(lc.frequency_Hz - osc.frequency_Hz) / osc.frequency_Hz < 0.15


def test_no_limit_cycle_without_integral_action():
    entry = build("lost_motion", REFERENCE_AXIS)
    H = LoopModel(REFERENCE_AXIS, dict(REFERENCE_GAINS, pos_ki=0.0)).H("position_feedback")
    assert find_limit_cycles(H, entry.nl, entry.amplitudes, OMEGA) == []
    sim = simulate_lost_motion_loop(REFERENCE_AXIS, dict(REFERENCE_GAINS, pos_ki=0.0), entry.nl.b,
                                    duration_s=1.5, theta0_rad=5 * entry.nl.b)
    tail = sim["theta_L_rad"][sim["t_s"] > 1.0]
    assert np.ptp(tail) < 1e-3 * entry.nl.b  # settles inside the gap


def test_cli_writes_json_and_plots(tmp_path, capsys):
    out = tmp_path / "df.json"
    rc = main(["df", "--nonlinearity", "cubic", "lost_motion", "--set", "pos_ki=2000",
               "--json", str(out), "--out-dir", str(tmp_path / "plots"), "--quiet"])
    assert rc == 0
    data = json.loads(out.read_text())
    r = data["results"]
    assert set(r) == {"cubic", "lost_motion"}
    assert r["cubic"]["df"][0]["amplitude"] > 0 and r["cubic"]["limit_cycles"] == []
    lcs = r["lost_motion"]["limit_cycles"]
    assert any(c["stable"] for c in lcs)
    assert len(r["lost_motion"]["margins_vs_amplitude"]) == len(r["lost_motion"]["df"])
    for name in ("cubic", "lost_motion"):
        for kind in ("nyquist", "df", "margins"):
            assert (tmp_path / "plots" / f"{name}_{kind}.png").stat().st_size > 1000


def test_cli_bad_input_one_line_no_output(tmp_path, capsys):
    bad = tmp_path / "axis.toml"
    bad.write_text("[load]\njl_kgm2 = \"heavy\"\n")
    out = tmp_path / "df.json"
    rc = main(["df", "--axis", str(bad), "--nonlinearity", "cubic", "--json", str(out), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "axis.toml" in err[0] and "load.jl_kgm2" in err[0]
    assert not out.exists()
    rc = main(["df", "--nonlinearity", "nonsense", "--quiet"])
    assert rc == 2
    bad.write_text("[load\n")
    assert main(["df", "--axis", str(bad), "--quiet"]) == 2
    assert list(tmp_path.iterdir()) == [bad]
