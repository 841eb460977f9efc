"""One command-line convention across every ``hdservo`` subcommand, progress bars, file modes.

The convention (docs/cli.md): ``--node-id N``; ``-o FILE`` is always a file and
``--out-dir DIR`` a directory; overrides are ``--set NAME=VALUE`` (repeatable); ``-q`` /
``-v`` are logging levels and ``-q`` turns progress off; ``--version`` prints the version
on every command; results are written with the user's umask.
"""
from __future__ import annotations

import argparse
import io
import json
import logging
import os
import stat
from pathlib import Path
from typing import Iterator

import pytest

from hdservo import __version__, cli, progress


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _all_parsers() -> Iterator[tuple[str, argparse.ArgumentParser]]:
    """Every subcommand parser, and the sub-subcommands (``config dump``, ``emps export`` ...)."""
    for name, p in _subparsers().items():
        yield name, p
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for sname, sp in a.choices.items():
                    yield f"{name} {sname}", sp


def _option(p: argparse.ArgumentParser, flag: str) -> argparse.Action | None:
    return p._option_string_actions.get(flag)


COMMANDS = sorted(_subparsers())


def test_every_command_is_checked() -> None:
    assert {"compare", "demo", "download", "identify", "record", "test", "sim", "df", "design"} <= set(COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_common_options_on_every_command(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    """-q, -v and --version on every subcommand; ``--version`` prints the version and exits 0."""
    p = _subparsers()[command]
    for flag in ("-q", "--quiet", "-v", "--verbose", "--version"):
        assert _option(p, flag) is not None, f"hdservo {command}: no {flag}"
    with pytest.raises(SystemExit) as e:
        cli.main([command, "--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"hdservo {__version__}"


def test_download_version_takes_no_argument(capsys: pytest.CaptureFixture[str]) -> None:
    """``download --version`` prints the version; the table version is ``--table-version``."""
    with pytest.raises(SystemExit) as e:
        cli.main(["download", "model.toml", "--version"])
    assert e.value.code == 0
    assert __version__ in capsys.readouterr().out
    ns = cli.build_parser().parse_args(["download", "model.toml", "--table-version", "7"])
    assert ns.table_version == 7


def test_download_table_version_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    m = tmp_path / "model.toml"
    m.write_text("[model]\n")
    assert cli.main(["download", str(m), "--table-version", "0", "--sim"]) == 2
    err = capsys.readouterr().err
    assert "--table-version 0: expected 1..2147483647" in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("name,parser", list(_all_parsers()), ids=[n for n, _ in _all_parsers()])
def test_o_is_a_file_and_out_dir_a_directory(name: str, parser: argparse.ArgumentParser) -> None:
    """``-o`` is ``--output`` (a file) wherever it exists; a directory is ``--out-dir``."""
    o = _option(parser, "-o")
    if o is not None:
        assert "--output" in o.option_strings, f"{name}: -o is {o.option_strings}"
        assert (o.metavar or "").upper() not in ("DIR", "DIRECTORY"), f"{name}: -o is a directory"
        assert "director" not in (o.help or ""), f"{name}: -o is a directory"
    d = _option(parser, "--out-dir")
    if d is not None:
        assert d.dest == "out_dir" and d.metavar == "DIR"
    for a in parser._actions:
        if a.help == argparse.SUPPRESS:
            continue
        shown = [s for s in a.option_strings if s.startswith("--")]
        assert not any(s in ("--out", "--plots", "--report", "--gain", "--gains-set", "--params", "--node")
                       for s in shown), f"{name}: old spelling {shown} still shown"


def test_directory_outputs_are_out_dir() -> None:
    sp = _subparsers()
    for command in ("compare", "demo", "design", "test", "identify", "discrepancy", "df"):
        assert _option(sp[command], "--out-dir") is not None, command
    assert _option(sp["compare"], "-o") is None
    assert _option(sp["demo"], "-o") is None
    p = cli.build_parser()
    assert p.parse_args(["compare", "--out-dir", "x"]).out_dir == Path("x")
    # the older spellings still parse, hidden, into the same place
    assert p.parse_args(["design", "s.toml", "--report", "r"]).out_dir == Path("r")
    assert p.parse_args(["test", "bandwidth", "--plots", "p"]).out_dir == Path("p")
    assert p.parse_args(["identify", "all", "--plots", "p"]).out_dir == Path("p")
    assert p.parse_args(["discrepancy", "l.csv", "--json", "j", "--plots", "p"]).out_dir == Path("p")
    assert p.parse_args(["record", "-o", "r.csv"]).output == "r.csv"
    assert p.parse_args(["emps", "export", "-o", "e.csv"]).output == "e.csv"
    assert p.parse_args(["config", "dump", "-o", "c.toml"]).output == Path("c.toml")


def test_overrides_are_set() -> None:
    """``--set NAME=VALUE`` (repeatable) is the override on identify, test, df and sim; the older
    spellings parse into the same list, in order."""
    p = cli.build_parser()
    assert p.parse_args(["identify", "all", "--set", "vel_kp=2", "--gain", "vel_ki=3"]).set == ["vel_kp=2", "vel_ki=3"]
    assert p.parse_args(["identify", "all"]).set == []
    assert p.parse_args(["test", "bandwidth", "--set", "vel_kp=200", "--params", "pos_kp=30"]).params == [
        ("vel_kp", 200.0), ("pos_kp", 30.0)]
    assert p.parse_args(["df", "--set", "pos_ki=2000", "--set", "vel_kp=1"]).set == ["pos_ki=2000", "vel_kp=1"]
    assert p.parse_args(["sim", "step", "-o", "x.csv", "--set", "plant.a=1"]).set


def test_set_names_the_option_in_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["identify", "friction", "--offline", "reference", "--set", "vel_kp"]) == 2
    assert "--set vel_kp: expected NAME=NUMBER" in capsys.readouterr().err
    assert cli.main(["df", "--set", "no_such_gain=1", "--nonlinearity", "cubic"]) == 2
    assert "--set no_such_gain=1: unknown gain" in capsys.readouterr().err


def test_node_id_everywhere() -> None:
    """Every command that talks to a drive spells the node ``--node-id``; ``--node`` is a hidden alias."""
    p = cli.build_parser()
    for command, sp in _subparsers().items():
        if _option(sp, "-i") is not None or command == "serve":
            assert _option(sp, "--node-id") is not None, command
    assert p.parse_args(["identify", "all", "--node-id", "5"]).node_id == 5
    assert p.parse_args(["identify", "all", "--node", "4"]).node_id == 4
    assert p.parse_args(["identify", "all"]).node_id == 1


@pytest.mark.parametrize("argv,level", [([], logging.INFO), (["-q"], logging.WARNING), (["-v"], logging.DEBUG),
                                        (["-vv"], logging.DEBUG)])
def test_quiet_verbose_are_logging_levels(argv: list[str], level: int, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["df", "--nonlinearity", "nonsense", *argv]) == 2
    assert logging.getLogger("hdservo").level == level
    # before the command too
    assert cli.main([*argv, "df", "--nonlinearity", "nonsense"]) == 2
    assert logging.getLogger("hdservo").level == level
    capsys.readouterr()


def test_quiet_silences_progress_lines(capsys: pytest.CaptureFixture[str]) -> None:
    """The command's progress lines go through logging: shown by default, none under -q."""
    assert cli.main(["df", "--nonlinearity", "cubic"]) == 0
    loud = capsys.readouterr()
    assert "[df] [1/1] cubic" in loud.err
    assert cli.main(["df", "--nonlinearity", "cubic", "-q"]) == 0
    quiet = capsys.readouterr()
    assert "[df]" not in quiet.err
    assert quiet.out == loud.out            # the results are the same


# ---- progress ---------------------------------------------------------------------------

class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_bar_draws_tqdm_on_a_terminal() -> None:
    s = _Tty()
    bar = progress.Bar("compare", 4, stream=s)
    bar.show("pid / stabilisation ...")
    bar.step("one")
    bar.step("two")
    bar.close()
    text = s.getvalue()
    assert "\r" in text and "compare" in text and "2/4" in text


def test_bar_logs_lines_off_a_terminal(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="hdservo.progress")
    s = io.StringIO()
    bar = progress.Bar("compare", 3, stream=s)
    bar.step("pid done")
    bar.total = 5
    bar.step("lugre done")
    assert s.getvalue() == ""
    lines = [r.getMessage() for r in caplog.records if r.name == "hdservo.progress"]
    assert lines == ["[compare] 1/3 pid done", "[compare] 2/5 lugre done"]


def test_fraction_logs_every_tenth_off_a_terminal(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="hdservo.progress")
    f = progress.Fraction("min-rate", stream=io.StringIO())
    for k in range(1, 101):
        f(k / 100, f"rung {k}")
    lines = [r.getMessage() for r in caplog.records if r.name == "hdservo.progress"]
    assert 9 <= len(lines) <= 11
    assert lines[-1].startswith("[min-rate] 100.0%")


def test_fraction_bar_on_a_terminal() -> None:
    s = _Tty()
    f = progress.Fraction("positioning", stream=s)
    f(0.25, "run 1")
    f(1.0, "done")
    text = s.getvalue()
    assert "\r" in text and "positioning" in text and "100.0%" in text


def test_disabled_progress_says_nothing(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG)
    for stream in (_Tty(), io.StringIO()):
        b = progress.Bar("x", 2, enabled=False, stream=stream)
        b.show("a")
        b.step("b")
        progress.Fraction("y", enabled=False, stream=stream)(1.0, "c")
        assert stream.getvalue() == ""
    assert not [r for r in caplog.records if r.name == "hdservo.progress"]


def test_identification_segments_draw_a_bar_or_log_lines(monkeypatch: pytest.MonkeyPatch) -> None:
    """A segment of a drive experiment: ``label: N %`` lines off a terminal (the command's progress
    callback, as before), a tqdm bar on one, off when the progress logger is above INFO (-q)."""
    from hdservo.ident.drive_runner import DriveRunner
    r = DriveRunner.__new__(DriveRunner)
    said: list[str] = []
    r.progress = said.append
    monkeypatch.setattr(progress, "on_terminal", lambda stream=None: False)
    bar = r._segment_progress("frf: segment 1/2")
    for k in range(1, 10):
        bar((100 * k // 10) / 100.0)
    r._segment_done(bar)
    assert said == [f"frf: segment 1/2: {10 * k} %" for k in range(1, 10)]
    monkeypatch.setattr(progress, "on_terminal", lambda stream=None: True)
    old = progress.LOG.level
    try:
        for level, shown in ((logging.INFO, True), (logging.WARNING, False)):
            progress.LOG.setLevel(level)
            bar = r._segment_progress("frf")
            assert isinstance(bar, progress.Fraction) and bar.enabled is shown
    finally:
        progress.LOG.setLevel(old)
    r.progress = None
    r._segment_progress("x")(0.5)          # no callback: nothing at all
    assert len(said) == 9


def test_procedure_and_compare_progress_are_tqdm_based() -> None:
    from hdservo import compare
    from hdservo.procedures import runner
    assert runner.Progress is progress.Fraction
    assert compare.StageBar is progress.Bar


# ---- file modes ---------------------------------------------------------------------------

@pytest.fixture
def umask027() -> Iterator[None]:
    old = os.umask(0o027)
    try:
        yield
    finally:
        os.umask(old)


def _mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


def test_result_writers_honour_the_umask(tmp_path: Path, umask027: None) -> None:
    """Every result writer gives 0666 & ~umask (0640 here), not tempfile's 0600 or a fixed 0644."""
    from hdservo import compare, fileio
    from hdservo.procedures import results
    compare._write_json_atomic(tmp_path / "compare.json", {"a": 1})
    results.write_json(tmp_path / "test.json", [results.Result("x")], {"target": "t"})
    fileio.write_json_atomic(tmp_path / "plain.json", {"b": 2})
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    pngs = results.save_figure(fig, tmp_path / "plots", "curve")
    for p in [tmp_path / "compare.json", tmp_path / "test.json", tmp_path / "plain.json", *pngs]:
        assert _mode(p) == 0o640, f"{p.name}: {oct(_mode(p))}"
    assert json.loads((tmp_path / "compare.json").read_text()) == {"a": 1}
    assert not [q for q in tmp_path.rglob(".*") if q.is_file()]      # no temporary left behind


def test_report_page_honours_the_umask(tmp_path: Path, umask027: None) -> None:
    from hdservo.procedures import results
    from hdservo.report import build_report
    tj = results.write_json(tmp_path / "t.json", [results.Result("stiffness")], {"target": "virtual drive"})
    out = tmp_path / "report.html"
    build_report(out, tests=[tj])
    assert out.read_text().startswith("<!DOCTYPE html>")
    assert _mode(out) == 0o640
