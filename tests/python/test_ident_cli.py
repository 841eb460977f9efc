"""`hdservo identify`: bad input gives one line and no output; --data round trip."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from hdservo import logio
from hdservo.cli import main

import ident_cache as cache
from hdservo.ident import experiments as ex

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[2]


def test_missing_log_is_one_line(tmp_path: Path, capsys) -> None:
    out = tmp_path / "m.toml"
    rc = main(["identify", "te", "--data", str(tmp_path / "nope.csv"), "-o", str(out), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "nope.csv" in err[0]
    assert not out.exists()


def test_log_without_experiment_key(tmp_path: Path, capsys) -> None:
    p = tmp_path / "x.csv"
    logio.write_log(p, {"t_s": np.arange(3) * 1e-3, "motor_angle_rad": np.zeros(3)},
                    {"gear_ratio": 100.0, "sample_period_s": 1e-3})
    rc = main(["identify", "te", "--data", str(p), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "experiment" in err[0] and "x.json" in err[0]


def test_te_from_saved_log(tmp_path: Path, capsys) -> None:
    d = cache.runner("reference").run(ex.TERotation(wg_revs=2, output_span_rad=0.0))
    log = tmp_path / "te.csv"
    d.save(log)
    out, js = tmp_path / "model.toml", tmp_path / "r.json"
    rc = main(["identify", "te", "--data", str(log), "-o", str(out), "--json", str(js), "-q",
               "--plots", str(tmp_path / "plots")])
    assert rc == 0
    text = out.read_text()
    assert "[transmission_error]" in text and "wg2_amp_rad" in text
    rep = json.loads(js.read_text())
    assert rep["results"]["te"]["wg_orders"][1] == 2
    # the TE fit's plot (and only it: no other experiment ran) is drawn and listed
    assert [p.name for p in (tmp_path / "plots").iterdir()] == ["te.png"]
    assert (tmp_path / "plots" / "te.png").stat().st_size > 5000


def test_sources_exclude_each_other(tmp_path: Path, capsys) -> None:
    log = tmp_path / "te.csv"
    for argv, words in ((["--offline", "reference", "--sim"], "--sim: drive options do not go with --offline"),
                        (["--data", str(log), "-i", "socketcand"], "--interface: drive options do not go with --data"),
                        (["--offline", "reference", "--data", str(log)], "two sources"),
                        (["--data", str(log), "--seed", "2"], "--seed"),
                        (["--offline", "nosuch/axis.toml"], "nosuch/axis.toml"),
                        (["--sim", "nosuch/axis.toml"], "no such axis file"),
                        (["--no-rig", "-i", "socketcand", "--port", "1"], "--no-rig")):
        rc = main(["identify", "te", "-q", *argv])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and words in err[0], (argv, err)
