"""Fast pacing bounds the drive's lead over its client: a master that streams three TPDOs every
period gets its SDO answers behind a bounded number of PDO frames, and the stream stays lossless.

The virtual drive in fast pacing runs as fast as its client reads.  What it may hold for a slow
client is its own output buffer (4 KiB) and the socket's send buffer (8 KiB, doubled by Linux):
about 500 frames of some 40 bytes.  The client's own socket holds what it has not read yet (its
receive buffer: 128 KiB to start with on Linux, about 3,300 frames, which the kernel's receive
autotuning may grow on a loaded machine: measured up to 5,600 frames ahead).  An SDO answer queued
by the drive waits behind those frames at most, the way a CAN interface's bounded receive FIFO
bounds it; without the bound it waited behind 100,000-140,000.  Counted in frames, not timed."""
from __future__ import annotations

import threading
import time

import can
import pytest

from hdservo.drive import Drive
from hdservo.pdo import STREAM_PDOS

from vdrive import NODE, SIM, Server  # tests/python/vdrive.py

pytestmark = pytest.mark.skipif(not SIM.exists(), reason="hdservo-sim not built (make sim)")

#: frames an SDO answer may wait behind: the drive's ~500 and the client socket's ~3,300 at the
#: start, with room for the kernel's autotuning of the client's receive buffer (see above); an
#: order of magnitude below the unbounded backlog
MAX_FRAMES_AHEAD = 12_000


class _Stream(can.Listener):
    """Counts every frame; keeps the loop ticks of one streamed TPDO (python-can's reader thread)."""

    def __init__(self, cob_id: int) -> None:
        self.n = 0
        self.cob_id = cob_id
        self.ticks: list[int] = []
        self.lock = threading.Lock()

    def on_message_received(self, msg: can.Message) -> None:
        with self.lock:
            self.n += 1
            if msg.arbitration_id == self.cob_id and len(self.ticks) < 200_000:
                self.ticks.append(int.from_bytes(bytes(msg.data[:4]), "little"))


def test_sdo_answers_behind_a_bounded_number_of_pdo_frames() -> None:
    srv = Server("--pacing", "fast", "-q")
    try:
        with Drive.connect(NODE, interface="socketcand", channel="can0", host="127.0.0.1", port=srv.port) as d:
            d.node.sdo.RESPONSE_TIMEOUT = 30.0      # the old unbounded backlog took seconds: count, do not time out
            first = STREAM_PDOS[0]
            st = _Stream(0x180 + 0x100 * (first - 1) + NODE)
            d.network.notifier.add_listener(st)
            d.configure_stream(1)                   # TPDO2..4 every period: ~3 frames per 100 us of drive time
            d.start()
            time.sleep(1.0)                         # a client slower than the drive: the backlog forms
            ahead = []
            for _ in range(8):
                n0 = st.n
                assert d.read(0x1000, 0) is not None
                ahead.append(st.n - n0)
                time.sleep(0.05)
            d.network.notifier.remove_listener(st)
            with st.lock:
                ticks = list(st.ticks)
    finally:
        srv.stop()
    assert min(ahead) > 0, ahead                    # the stream did run ahead of the answers
    assert max(ahead) <= MAX_FRAMES_AHEAD, f"PDO frames ahead of each SDO answer: {ahead}"
    # bounded by waiting for the client, not by dropping: one frame of the TPDO per period, no gap
    assert len(ticks) > 1000
    steps = {b - a for a, b in zip(ticks, ticks[1:])}
    assert steps == {1}, sorted(steps)[:10]
