"""One atomic writer and one JSON encoder (hdservo.fileio), and the writers that use them."""
from __future__ import annotations

import json
import math
import os
import stat
from pathlib import Path
from typing import Iterator

import numpy as np
import pytest

from hdservo import fileio, logio
from hdservo.ident import model_toml


@pytest.fixture
def umask_027() -> Iterator[None]:
    old = os.umask(0o027)
    try:
        yield
    finally:
        os.umask(old)


def _mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


def test_files_get_the_users_umask_not_0600(tmp_path: Path, umask_027: None) -> None:
    a = fileio.write_text_atomic(tmp_path / "a.txt", "x\n")
    b = fileio.write_json_atomic(tmp_path / "b.json", {"x": 1})
    c = fileio.write_bytes_atomic(tmp_path / "c.bin", b"\x00\x01")
    for p in (a, b, c):
        assert _mode(p) == 0o640, f"{p.name}: {oct(_mode(p))}"
    os.umask(0o002)
    assert _mode(fileio.write_text_atomic(tmp_path / "a.txt", "y\n")) == 0o664
    assert (tmp_path / "a.txt").read_text() == "y\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.json", "c.bin"]   # no temporary left


def test_encoder_numpy_and_non_finite_to_strict_json(tmp_path: Path) -> None:
    obj = {"f": np.float32(1.5), "i": np.int64(7), "b": np.bool_(True), "arr": np.array([1.0, np.nan, np.inf]),
           "t": (1, -math.inf), "nan": math.nan, "nested": [{"x": np.float64(2.25)}], np.int32(3): "key"}
    text = fileio.dumps_json(obj)
    assert text.endswith("\n") and "NaN" not in text and "Infinity" not in text
    back = json.loads(text)
    assert back == {"f": 1.5, "i": 7, "b": True, "arr": [1.0, None, None], "t": [1, None], "nan": None,
                    "nested": [{"x": 2.25}], "3": "key"}
    assert fileio.dumps_json({"a": 1}, indent=None) == '{"a": 1}\n'


def test_unencodable_object_leaves_the_old_file(tmp_path: Path) -> None:
    p = tmp_path / "r.json"
    fileio.write_json_atomic(p, {"v": 1})
    with pytest.raises(TypeError):
        fileio.write_json_atomic(p, {"v": object()})
    assert json.loads(p.read_text()) == {"v": 1}
    assert [q.name for q in tmp_path.iterdir()] == ["r.json"]
    # a default hook is encoded the same way
    assert json.loads(fileio.dumps_json({"p": Path("x")}, default=str)) == {"p": "x"}


def test_a_failing_figure_leaves_no_temporary(tmp_path: Path) -> None:
    class Broken:
        def savefig(self, *a: object, **k: object) -> None:
            raise RuntimeError("disk full")
    with pytest.raises(RuntimeError):
        fileio.save_figure_atomic(Broken(), tmp_path / "p.png")
    assert list(tmp_path.iterdir()) == []


def test_log_and_model_files_follow_the_umask(tmp_path: Path, umask_027: None) -> None:
    """The writers that used mkstemp directly created 0600 files."""
    log = tmp_path / "run.csv"
    logio.write_log(log, {"t_s": [0.0, 1e-4]}, {"gear_ratio": 100.0, "sample_period_s": 1e-4})
    model = tmp_path / "m.toml"
    model_toml.write_toml(model, {"gear": {"ratio": 100.0}})
    for p in (log, logio.sidecar_path(log), model):
        assert _mode(p) == 0o640, f"{p.name}: {oct(_mode(p))}"


def test_log_sidecar_is_strict_json(tmp_path: Path) -> None:
    log = tmp_path / "run.csv"
    logio.write_log(log, {"t_s": [0.0, 1e-4]}, {"gear_ratio": 100.0, "sample_period_s": 1e-4, "gain": np.float64(math.nan)})
    text = logio.sidecar_path(log).read_text()
    assert "NaN" not in text and json.loads(text)["gain"] is None


def test_json_ready_reads_as_json_reads_back() -> None:
    """Keys become strings as JSON writes them; ``drop_suffix`` leaves time series out at every depth."""
    obj = {1: "a", False: "b", None: "c", 2.5: [{"x_trace": [1, 2], "x": np.float64(3.0)}], "y_trace": np.ones(3)}
    ready = fileio.json_ready(obj)
    assert ready == json.loads(json.dumps(ready)) == json.loads(fileio.dumps_json(obj))
    assert set(ready) == {"1", "false", "null", "2.5", "y_trace"}
    assert fileio.json_ready(obj, drop_suffix="_trace") == {"1": "a", "false": "b", "null": "c", "2.5": [{"x": 3.0}]}


def test_files_into_publishes_all_or_nothing(tmp_path: Path, umask_027: None) -> None:
    out = tmp_path / "report"
    with fileio.files_into(out) as d:
        (d / "a.md").write_text("a\n")
        fileio.write_json_atomic(d / "b.json", {"v": 1})
        assert not out.exists()                               # nothing appears before the end
    assert sorted(p.name for p in out.iterdir()) == ["a.md", "b.json"]
    assert _mode(out / "a.md") == 0o640
    with pytest.raises(RuntimeError):
        with fileio.files_into(out) as d:
            (d / "a.md").write_text("half\n")
            raise RuntimeError("plot failed")
    assert (out / "a.md").read_text() == "a\n"                # the old report stays
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]   # no temporary directory left
