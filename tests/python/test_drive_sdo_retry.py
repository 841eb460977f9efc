"""The CAN client repeats an expedited SDO exchange that got a stale (late, duplicated) response."""
from __future__ import annotations

from typing import Any

import canopen
import pytest

from hdservo import drive as dv

STALE = "Node returned a value for 0x2800:04 instead, maybe there is another SDO client"


class _Var:
    """Stands in for a canopen variable whose first ``fails`` accesses get the given error."""

    def __init__(self, fails: int, err: Exception) -> None:
        self.fails, self.err, self.calls, self.written = fails, err, 0, []

    def _hit(self) -> None:
        self.calls += 1
        if self.calls <= self.fails:
            raise self.err

    @property
    def raw(self) -> int:
        self._hit()
        return 42

    @raw.setter
    def raw(self, value: Any) -> None:
        self._hit()
        self.written.append(value)


def _drive(var: _Var, monkeypatch: pytest.MonkeyPatch) -> dv.Drive:
    d = dv.Drive(canopen.Network(), 1)
    monkeypatch.setattr(d, "_var", lambda index, sub=0: var)
    d.node.sdo.RESPONSE_TIMEOUT = 0.001
    return d


@pytest.mark.parametrize("msg", [STALE, "Unexpected response 0x4B"])
def test_stale_response_is_retried(msg: str, monkeypatch: pytest.MonkeyPatch) -> None:
    v = _Var(1, canopen.SdoCommunicationError(msg))
    d = _drive(v, monkeypatch)
    assert d.read(0x2800, 1) == 42 and v.calls == 2
    v2 = _Var(1, canopen.SdoCommunicationError(msg))
    d2 = _drive(v2, monkeypatch)
    d2.write(0x2800, 1, 7)
    assert v2.written == [7] and v2.calls == 2


def test_gives_up_after_the_attempts(monkeypatch: pytest.MonkeyPatch) -> None:
    v = _Var(dv.SDO_ATTEMPTS, canopen.SdoCommunicationError(STALE))
    with pytest.raises(dv.DriveError, match=r"read 0x2800:1: Node returned"):
        _drive(v, monkeypatch).read(0x2800, 1)
    assert v.calls == dv.SDO_ATTEMPTS


@pytest.mark.parametrize("err", [canopen.SdoAbortedError(0x06020000), canopen.SdoCommunicationError("No SDO response received")])
def test_aborts_and_timeouts_are_not_repeated_here(err: Exception, monkeypatch: pytest.MonkeyPatch) -> None:
    """An abort is the drive's answer; a time-out was already retried by python canopen (MAX_RETRIES)."""
    v = _Var(1, err)
    with pytest.raises(dv.DriveError):
        _drive(v, monkeypatch).read(0x2800, 1)
    assert v.calls == 1


@pytest.mark.parametrize("err, calls", [(canopen.SdoAbortedError(0x05040001), 2),
                                        (canopen.SdoCommunicationError("No SDO response received"), 2),
                                        (canopen.SdoAbortedError(0x06090030), 1)])
def test_table_download_repeats_a_broken_transfer_only(err: Exception, calls: int,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A table block download broken at the protocol level (a loaded host missed the drive's SDO
    time-out) is repeated; a refusal of the content (value range 0x06090030) is not."""
    d = dv.Drive(canopen.Network(), 1)
    sent: list[bytes] = []

    def write_domain(index: int, sub: int, blob: bytes) -> None:
        sent.append(blob)
        if len(sent) == 1:
            raise dv.DriveError(f"download 0x{index:04X}:{sub}: {err}")
    monkeypatch.setattr(d, "write_domain", write_domain)
    monkeypatch.setattr(d, "read_domain", lambda index, sub: sent[-1])
    if calls == 1:
        with pytest.raises(dv.DriveError, match="0x06090030"):
            d.download_table(2, b"abcd")
    else:
        d.download_table(2, b"abcd")
    assert len(sent) == calls and all(b == sent[0] for b in sent)
