"""Property-based tests (hypothesis) of the host's file readers.

For arbitrary bytes, arbitrary TOML / JSON structures and mutations of valid files, each
reader either returns a valid object or raises the package's UserError -- never another
exception (that would be a traceback on the command line).  A valid object written by
the package's own writer reads back equal.

Readers: identified model TOML (:mod:`hdservo.ident.model_reader`), logs (CSV and JSON
sidecar, :mod:`hdservo.logio`), drive configuration files (:mod:`hdservo.driveconfig`),
Preisach images (:class:`hdservo.preisach_table.PreisachTable`).  Example counts are
small so the file runs in seconds.
"""
from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from hdservo import driveconfig, logio
from hdservo.cli import UserError
from hdservo.ident import model_reader as mr
from hdservo.ident import model_toml
from hdservo.params_gen import BY_NAME, TABLE_HASH
from hdservo.preisach_table import PreisachTable, quantise_everett
from hdservo.tomltext import basic_string

#: modest example counts (the file runs in seconds); no example database written into the tree
FAST = settings(max_examples=60, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])

# ------------------------------------------------------------------ strategies

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
scalars = st.one_of(st.booleans(), st.integers(min_value=-2 ** 70, max_value=2 ** 70), st.floats(),
                    st.text(max_size=12))
toml_values = st.recursive(scalars, lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c,
                                                                                      max_size=3), max_leaves=8)
MODEL_KEYS = [f"{s}.{k}" for s, ks in mr.KEYS.items() for k in ks] + [
    "hysteresis_maxwell.e1_k_Nm_per_rad", "hysteresis_maxwell.e1_w_Nm", "transmission_error.wg1_order",
    "transmission_error.wg1_amp_rad", "transmission_error.wg1_phase_rad"]


def _toml_text(doc: dict[str, Any]) -> str:
    """TOML text of a two-level document of scalars (the writer under test covers the rest)."""
    out = []
    for sec, body in doc.items():
        if isinstance(body, dict):
            out.append(f"[{_tstr(sec)}]")
            for k, v in body.items():
                out.append(f"{_tstr(k)} = {_val(v)}")
        else:
            out.insert(0, f"{_tstr(sec)} = {_val(body)}")
    return "\n".join(out) + "\n"


def _tstr(s: str) -> str:
    """A TOML basic string of any text (control characters as \\uXXXX), for building test documents."""
    return '"' + "".join("\\\\" if c == "\\" else '\\"' if c == '"' else
                         f"\\u{ord(c):04X}" if ord(c) < 0x20 or ord(c) == 0x7F else c for c in s) + '"'


def _val(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return _tstr(v)
    if isinstance(v, list):
        return "[" + ", ".join(_val(x) for x in v) + "]"
    return "{" + ", ".join(f"{_tstr(k)} = {_val(x)}" for k, x in v.items()) + "}"


GOOD_MODEL = {
    "gear": {"ratio": 100.0},
    "stiffness": {"k1_Nm_per_rad": 31000.0, "k2_Nm_per_rad": 5.0e4, "t1_Nm": 14.0},
    "hysteresis_maxwell": {"n_elements": 1, "e1_k_Nm_per_rad": 1.0e4, "e1_w_Nm": 1.0},
    "transmission_error": {"wg1_order": 2, "wg1_amp_rad": 8.7e-5, "wg1_phase_rad": 0.4},
    "friction_total": {"fc_pos_Nm": 7.4, "fc_neg_Nm": 7.0, "fs_pos_Nm": 10.5, "fs_neg_Nm": 10.0,
                       "vs_rad_s": 0.02, "delta": 2.0, "viscous_Nms_per_rad": 5.3},
    "identified": {"preisach_table": "m.preisach.bin", "preisach_crc": 12345},
}


# ------------------------------------------------------------------ identified model TOML

@FAST
@given(st.binary(max_size=400))
def test_model_arbitrary_bytes(raw: bytes) -> None:
    try:
        m = mr.parse_model(raw, "m.toml")
    except UserError as e:
        assert "\n" not in str(e) and str(e).startswith("m.toml")
        return
    assert m["gear"]["ratio"] > 0


@FAST
@given(st.dictionaries(st.sampled_from(list(mr.KEYS) + ["other"]),
                       st.dictionaries(st.sampled_from([k.split(".")[1] for k in MODEL_KEYS]), scalars, max_size=6)
                       | scalars, max_size=5))
def test_model_arbitrary_structure(doc: dict[str, Any]) -> None:
    try:
        m = mr.parse_model(_toml_text(doc).encode(), "m.toml")
    except UserError:
        return
    _assert_valid_model(m)


@FAST
@given(st.sampled_from(MODEL_KEYS), toml_values | st.none())
def test_model_mutated(key: str, v: Any) -> None:
    """One key of a valid model replaced by anything (None: removed)."""
    sec, k = key.split(".")
    doc = json.loads(json.dumps(GOOD_MODEL))
    doc.setdefault(sec, {})
    if v is None:
        doc[sec].pop(k, None)
    else:
        doc[sec][k] = v
    try:
        m = mr.parse_model(_toml_text(doc).encode(), "m.toml")
    except UserError as e:
        assert key in str(e) or sec in str(e), str(e)
        return
    _assert_valid_model(m)


def _assert_valid_model(m: mr.Model) -> None:
    """What the consumers rely on after a successful read."""
    assert isinstance(m["gear"]["ratio"], float) and m["gear"]["ratio"] > 0
    for sec, kinds in mr.KEYS.items():
        for k, kind in kinds.items():
            v = m.get(sec, {}).get(k)
            if v is None:
                continue
            if kind == "str":
                assert isinstance(v, str)
            elif kind == "int":
                assert isinstance(v, int) and not isinstance(v, bool) and v >= 0
            else:
                assert isinstance(v, float) and math.isfinite(v)
    hm = m.get("hysteresis_maxwell", {})
    for i in range(1, hm.get("n_elements", 0) + 1):
        assert isinstance(hm[f"e{i}_k_Nm_per_rad"], float) and isinstance(hm[f"e{i}_w_Nm"], float)
    te = m.get("transmission_error", {})
    i = 1
    while f"wg{i}_order" in te:
        assert isinstance(te[f"wg{i}_amp_rad"], float) and isinstance(te[f"wg{i}_phase_rad"], float)
        i += 1


@FAST
@given(st.fixed_dictionaries({
    "gear": st.fixed_dictionaries({"ratio": st.floats(1e-3, 1e4)}),
    "friction_total": st.fixed_dictionaries({k: finite for k in ("fc_pos_Nm", "fc_neg_Nm", "fs_pos_Nm", "fs_neg_Nm",
                                                                 "viscous_Nms_per_rad")}
                                            | {"vs_rad_s": st.floats(1e-6, 10.0)}),
    "identified": st.fixed_dictionaries({"preisach_table": st.text(alphabet=st.characters(min_codepoint=0x20,
                                                                                          exclude_characters="\x7f"),
                                                                   max_size=20),
                                         "preisach_levels": st.integers(0, 2 ** 62)}),
}))
def test_model_round_trip(sections: dict[str, dict[str, Any]]) -> None:
    """A model written by model_toml reads back equal (strings with quotes and backslashes too)."""
    text = model_toml.format_toml(sections, header="round trip")
    assert mr.parse_model(text.encode(), "m.toml") == sections


# ------------------------------------------------------------------ logs: CSV + JSON sidecar

@FAST
@given(st.binary(max_size=400))
def test_log_csv_arbitrary_bytes(tmp_path_factory: pytest.TempPathFactory, raw: bytes) -> None:
    p = tmp_path_factory.mktemp("csv") / "l.csv"
    p.write_bytes(raw)
    try:
        cols = logio.read_csv(p)
    except UserError as e:
        assert "\n" not in str(e)
        return
    assert list(cols)[0] == "t_s" and all(np.all(np.isfinite(v)) for v in cols.values())


@FAST
@given(st.lists(st.lists(st.sampled_from(["0", "1", "-2.5", "1e3", "nan", "x", "", " 3", "1_0", "0x1", "inf"]),
                         min_size=1, max_size=4), min_size=0, max_size=6),
       st.lists(st.sampled_from(["t_s", "motor_angle_rad", "load_angle_deg", "x", "", "t_s", "gyro_rate_rad_s"]),
                min_size=1, max_size=4))
def test_log_csv_mutated(tmp_path_factory: pytest.TempPathFactory, rows: list[list[str]], header: list[str]) -> None:
    p = tmp_path_factory.mktemp("csv") / "l.csv"
    p.write_text(",".join(header) + "\n" + "".join(",".join(r) + "\n" for r in rows))
    try:
        cols = logio.read_csv(p)
    except UserError:
        return
    assert list(cols) == header and all(len(v) == len(rows) for v in cols.values())
    assert np.all(np.diff(cols["t_s"]) > 0)


json_values = st.recursive(st.none() | st.booleans() | st.integers(min_value=-2 ** 1100, max_value=2 ** 1100)
                           | st.sampled_from([10 ** 400, -(10 ** 309), 2 ** 63, 0, -1])
                           | st.floats() | st.text(max_size=8),
                           lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=8), c, max_size=3),
                           max_leaves=10)


@FAST
@given(st.dictionaries(st.sampled_from(["format", "version", "gear_ratio", "sample_period_s", "columns", "seed",
                                        "effects", "source", "x"]), json_values, max_size=6)
       | json_values, st.booleans())
def test_log_sidecar_arbitrary(tmp_path_factory: pytest.TempPathFactory, meta: Any, base: bool) -> None:
    p = tmp_path_factory.mktemp("meta") / "l.json"
    if base and isinstance(meta, dict):
        meta = {"format": logio.FORMAT, "version": logio.FORMAT_VERSION, "gear_ratio": 100,
                "sample_period_s": 0.001, **meta}
    p.write_text(json.dumps(meta))          # NaN / Infinity and huge integers included
    try:
        m = logio.read_meta(p)
    except UserError as e:
        assert "\n" not in str(e)
        return
    assert m["format"] == logio.FORMAT and m["sample_period_s"] > 0 and m["gear_ratio"] != 0


@FAST
@given(st.integers(1, 30), st.lists(st.sampled_from(["motor_angle_rad", "load_torque_Nm", "gyro_rate_rad_s",
                                                     "fault_code", "motor_current_A"]), unique=True, max_size=4),
       st.data())
def test_log_round_trip(tmp_path_factory: pytest.TempPathFactory, n: int, names: list[str], data: st.DataObject) -> None:
    t = np.cumsum(data.draw(st.lists(st.floats(1e-6, 1e3), min_size=n, max_size=n)))
    assume(np.all(np.diff(t) > 0))
    cols = {"t_s": t, **{c: np.array(data.draw(st.lists(finite, min_size=n, max_size=n))) for c in names}}
    meta = {"gear_ratio": data.draw(st.floats(0.01, 1e4)), "sample_period_s": 0.001, "seed": 3}
    p = tmp_path_factory.mktemp("rt") / "run.csv"
    logio.write_log(p, cols, meta)
    log = logio.read_log(p)
    assert list(log.columns) == list(cols)
    for k, v in cols.items():
        assert np.array_equal(log.columns[k], v)
    assert log.meta["gear_ratio"] == meta["gear_ratio"]


# ------------------------------------------------------------------ drive configuration files

CONFIG_KEYS = ["pos_kp", "vel_kp", "traj_vmax", "cb_enable", "nonexistent"]


@FAST
@given(st.binary(max_size=300))
def test_config_arbitrary_bytes(raw: bytes) -> None:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return
    try:
        parsed = driveconfig.parse(text, where="c.toml")
    except UserError as e:
        assert "\n" not in str(e)
        return
    _assert_valid_config(parsed)


@FAST
@given(st.dictionaries(st.sampled_from(["meta", "params", "objects", "x"]),
                       st.dictionaries(st.sampled_from(["format", "param_layout_hash", *CONFIG_KEYS, "0x1017:0",
                                                        "0x1800:1", "0x1A00:0", "0xZZ:1", "0x1017"]),
                                       scalars | st.sampled_from(["$NODEID+0x180", "$NODEID+x", "$nodeid+1"]),
                                       max_size=6) | scalars, max_size=4),
       st.booleans())
def test_config_arbitrary_structure(doc: dict[str, Any], signed: bool) -> None:
    if signed and isinstance(doc.get("meta"), dict):
        doc["meta"].update({"format": 2, "param_layout_hash": TABLE_HASH})
    try:
        parsed = driveconfig.parse(_toml_text(doc), where="c.toml", node_id=3)
    except UserError as e:
        assert "\n" not in str(e)
        return
    _assert_valid_config(parsed)


def _assert_valid_config(parsed: driveconfig.Parsed) -> None:
    for name, r in parsed.raw.items():
        p = BY_NAME[name]
        assert isinstance(r, int) and p.raw_min <= r <= p.raw_max
    for key, v in parsed.objects.items():
        e = driveconfig.STORED_AT[key]
        assert isinstance(v, int) and e.min <= v <= e.max


@FAST
@given(st.data(), st.integers(1, 127))
def test_config_round_trip(data: st.DataObject, node_id: int) -> None:
    """dump (to_toml) -> parse gives the same raw words and objects, for any node ID."""
    names = data.draw(st.lists(st.sampled_from(sorted(BY_NAME)), unique=True, min_size=1, max_size=12))
    raw = {}
    for n in names:
        p = BY_NAME[n]
        lo = max(p.raw_min, math.ceil(p.min * 2 ** p.frac))
        hi = min(p.raw_max, math.floor(p.max * 2 ** p.frac))
        raw[n] = data.draw(st.integers(lo, hi))
    keys = data.draw(st.lists(st.sampled_from(sorted(driveconfig.STORED_AT)), unique=True, max_size=8))
    objects = {}
    for k in keys:
        e = driveconfig.STORED_AT[k]
        objects[k] = data.draw(st.integers(e.min, e.max))
    text = driveconfig.to_toml(raw, TABLE_HASH, "round trip", objects, node_id)
    parsed = driveconfig.parse(text, node_id=node_id)
    assert parsed.raw == raw and parsed.objects == objects and parsed.unknown == []


# ------------------------------------------------------------------ Preisach images

def _table(levels: int, seed: int) -> PreisachTable:
    rng = np.random.default_rng(seed)
    e = np.tril(rng.normal(size=(levels, levels)))
    return quantise_everett(e, 1000.0, sub_bits=2, in_shift=3, u0=-100, unit=0, version=seed % 7 + 1)


@FAST
@given(st.binary(max_size=200) | st.binary(min_size=40, max_size=80).map(
    lambda b: b"HDPT" + b"\x01\x00\x00\x00" + b[8:]))
def test_preisach_arbitrary_bytes(raw: bytes) -> None:
    try:
        t = PreisachTable.from_bytes(raw)
    except UserError as e:
        assert "\n" not in str(e)
        return
    assert t.to_bytes() == raw


@FAST
@given(st.integers(2, 12), st.integers(0, 1000), st.data())
def test_preisach_mutated_and_round_trip(levels: int, seed: int, data: st.DataObject) -> None:
    good = _table(levels, seed).to_bytes()
    assert PreisachTable.from_bytes(good).to_bytes() == good            # round trip
    i = data.draw(st.integers(0, len(good) - 1))
    bad = bytearray(good)
    bad[i] ^= data.draw(st.integers(1, 255))
    cut = data.draw(st.sampled_from([len(good), len(good) - 4, len(good) - 1, 40, 0]))
    blob = bytes(bad[:cut])
    try:
        t = PreisachTable.from_bytes(blob)
    except UserError as e:
        assert "\n" not in str(e)
        return
    assert t.to_bytes() == blob      # a flipped byte that still checks: it must be self-consistent


def test_preisach_read_names_the_file(tmp_path: Path) -> None:
    p = tmp_path / "t.bin"
    p.write_bytes(b"\x00" * 44)
    with pytest.raises(UserError, match=r"t\.bin: Preisach image: magic"):
        PreisachTable.read(p)
    with pytest.raises(UserError, match="cannot read"):
        PreisachTable.read(tmp_path / "none.bin")


# ------------------------------------------------------------------ TOML strings

@FAST
@given(st.text(alphabet=st.characters(exclude_categories=["Cs"]), max_size=40))
def test_basic_string_round_trips_or_refuses(s: str) -> None:
    try:
        q = basic_string(s)
    except ValueError:
        assert any(ord(c) < 0x20 and c not in "\t\n\r" or ord(c) == 0x7F for c in s)
        return
    assert tomllib.loads(f"k = {q}\n")["k"] == s
