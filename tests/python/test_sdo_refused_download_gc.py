"""A segmented SDO download the drive refuses at its start sends nothing more when collected.

python canopen's ``WritableStream`` sends its initiate in ``__init__``; a refused initiate left
the stream open, and its ``close()`` from the garbage collector sent an end segment, which hangs
the host when the collector runs inside another send (the network's send lock is held).
"""
from __future__ import annotations

import gc

import pytest
from canopen.sdo.client import WritableStream
from canopen.sdo.exceptions import SdoAbortedError

import hdservo.drive  # noqa: F401  (installs the wrapped __init__)


class _RefusingClient:
    """An SDO client whose drive aborts every request; counts the requests sent."""

    def __init__(self) -> None:
        self.requests = 0

    def request_response(self, request: bytes) -> bytes:
        self.requests += 1
        raise SdoAbortedError(0x06010002)

    def abort(self, code: int) -> None:  # pragma: no cover - not reached
        self.requests += 1


def test_refused_initiate_leaves_the_stream_closed_and_silent() -> None:
    client = _RefusingClient()
    stream = WritableStream.__new__(WritableStream)
    with pytest.raises(SdoAbortedError):
        WritableStream.__init__(stream, client, 0x5100, 1, size=100)
    assert stream.closed
    del stream
    gc.collect()
    assert client.requests == 1
