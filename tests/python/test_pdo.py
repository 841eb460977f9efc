"""The PDO codec (hdservo.pdo): the EDS's maps read by canopen agree with the DBC read by cantools.

The EDS and the DBC are generated from the same ``firmware/params/canopen.toml``; canopen
(EDS) and cantools (DBC) are two independent readers, so frames decoded / encoded by
:class:`hdservo.pdo.PdoDecoder` are checked against cantools on random payloads.
"""
from __future__ import annotations

import random
import re
from pathlib import Path

import cantools
import pytest

from hdservo import resources
from hdservo.pdo import STATUS_PDO, STREAM_PDOS, PdoDecoder

ROOT = Path(__file__).parents[2]


@pytest.fixture(scope="module")
def dbc() -> cantools.database.can.Database:
    return cantools.database.load_file(str(resources.dbc_path()))


def test_tpdo_cob_ids_follow_the_node() -> None:
    for node in (1, 5, 127):
        d = PdoDecoder(node)
        assert [d.cob_id(n) for n in (1, 2, 3, 4)] == [0x180 + node, 0x280 + node, 0x380 + node, 0x480 + node]
        assert d.pdo_of(0x280 + node) == 2 and d.pdo_of(0x80) is None


def test_stream_and_status_pdos_carry_what_their_users_need() -> None:
    d = PdoDecoder(1)
    streamed = {name for n in STREAM_PDOS for name in d.names(n)}
    assert {"loop_tick", "load_phase", "motor_phase", "motor_torque"} <= streamed
    assert all("loop_tick" in d.names(n) for n in (*STREAM_PDOS, STATUS_PDO))
    assert d.names(STATUS_PDO)[0] == "statusword"


@pytest.mark.parametrize("seed", range(5))
def test_tpdo_decoding_agrees_with_the_dbc(dbc: cantools.database.can.Database, seed: int) -> None:
    """Every TPDO, random payloads: canopen's map (EDS) and cantools' message (DBC) give the same raw values."""
    rng = random.Random(seed)
    d = PdoDecoder(1)
    for n in (1, 2, 3, 4):
        msg = dbc.get_message_by_frame_id(d.cob_id(n))
        for _ in range(50):
            data = bytes(rng.randrange(256) for _ in range(msg.length))
            fr = d.decode(d.cob_id(n), data)
            assert fr is not None and fr.pdo == n
            ref = msg.decode(data, decode_choices=False, scaling=False)
            assert fr.values == {k: int(v) for k, v in ref.items()}, f"TPDO{n} {data.hex()}"


def test_rpdo_encoding_agrees_with_the_dbc(dbc: cantools.database.can.Database) -> None:
    rng = random.Random(3)
    d = PdoDecoder(1)
    for n in (1, 2, 3):
        cob, _ = d.encode(n)
        msg = dbc.get_message_by_frame_id(cob)
        for _ in range(50):
            values = {}
            for s in msg.signals:
                lo = -(1 << (s.length - 1)) if s.is_signed else 0
                values[s.name] = rng.randrange(lo, lo + (1 << s.length))
            cob2, data = d.encode(n, **values)
            assert cob2 == cob and data == msg.encode(values, scaling=False)


def test_short_and_foreign_frames_are_not_decoded() -> None:
    d = PdoDecoder(1)
    assert d.decode(0x281, b"\x00" * 7) is None            # TPDO2 maps 8 bytes
    assert d.decode(0x282, b"\x00" * 8) is None            # another node's TPDO2
    assert d.decode(0x701, b"\x05") is None                # heartbeat
    with pytest.raises(KeyError):
        d.encode(3, no_such_object=1)
    with pytest.raises(KeyError):
        d.encode(4)                                        # RPDO4 is not enabled


def test_decoding_falls_back_to_canopen_for_bit_fields() -> None:
    """A map that is not byte aligned is decoded by canopen's PdoVariable; the result is the same."""
    d = PdoDecoder(1)
    data = bytes(range(8))
    fast = d.decode(0x481, data)
    d._fast = {k: None for k in d._fast}       # force canopen's own decoding path
    assert d.decode(0x481, data) == fast


def test_no_pdo_cob_id_or_byte_offset_by_hand() -> None:
    """PDO COB-IDs (0x180/0x280/.. + node id) and PDO byte offsets live only in the EDS."""
    pat = re.compile(r"0x[1-5][08]0\s*\+\s*(self\.|drive\.|self\.drive\.)?node_id|unpack_from\(\"<I+\", m\.data")
    hits = []
    for f in sorted((ROOT / "host" / "hdservo").rglob("*.py")):
        for i, line in enumerate(f.read_text().splitlines(), 1):
            if pat.search(line):
                hits.append(f"{f.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not hits, "\n".join(hits)
