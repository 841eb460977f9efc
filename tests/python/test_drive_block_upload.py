"""A response time-out at the end of a block upload is an SDO time-out, not a crash."""
from __future__ import annotations

import canopen
import pytest
from canopen.sdo.client import BlockUploadStream

import hdservo.drive  # noqa: F401  (installs the fix)


class _LateClient:
    """An SDO client whose server never answers the end of the upload."""

    def __init__(self) -> None:
        self.aborts: list[int] = []

    def read_response(self) -> bytes:
        raise canopen.SdoCommunicationError("No SDO response received")

    def abort(self, code: int) -> None:
        self.aborts.append(code)


def test_end_of_upload_time_out_aborts_and_raises_the_sdo_error() -> None:
    stream = BlockUploadStream.__new__(BlockUploadStream)
    stream.sdo_client = _LateClient()
    with pytest.raises(canopen.SdoCommunicationError):
        stream._end_upload()
    assert stream.sdo_client.aborts == [0x05040000]      # SDO protocol timed out, sent to the drive
