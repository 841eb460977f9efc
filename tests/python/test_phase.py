"""One unwrapping rule for the drive's wrapping phases and tick (hdservo.phase)."""
from __future__ import annotations

import numpy as np
import pytest

from hdservo.phase import unwrap_phase, unwrap_tick, unwrap_turns


def _wrapped(turns: np.ndarray) -> np.ndarray:
    return np.mod(np.round(turns * 2.0 ** 32).astype(np.int64), 2 ** 32)


def test_capture_and_stream_agree_across_many_wraps() -> None:
    rng = np.random.default_rng(11)
    true = np.cumsum(rng.uniform(-0.45, 0.45, 4000)) + 0.3          # steps under half a turn
    w = _wrapped(true)
    whole = unwrap_turns(w)
    prev = None
    stream = []
    for x in w:
        prev = unwrap_phase(prev, int(x))
        stream.append(prev)
    assert np.allclose(whole, true, atol=1e-9)
    assert np.allclose(np.asarray(stream), whole, atol=1e-9)


def test_first_sample_centred_or_not() -> None:
    w = np.array([3 * 2 ** 30, 3 * 2 ** 30 + 2 ** 29, 2 ** 28])   # 0.75, 0.875, then past the wrap to 1.0625
    assert unwrap_turns(w) == pytest.approx([-0.25, -0.125, 0.0625])
    assert unwrap_turns(w, centred=False) == pytest.approx([0.75, 0.875, 1.0625])
    assert unwrap_phase(None, 3 * 2 ** 30) == -0.25
    assert unwrap_turns(np.array([], dtype=np.int64)).size == 0


def test_tick_continues_over_its_wrap() -> None:
    ticks = [2 ** 32 - 2, 2 ** 32 - 1, 0, 1, 5]
    prev = None
    out = []
    for t in ticks:
        prev = unwrap_tick(prev, t)
        out.append(prev)
    assert out == [2 ** 32 - 2, 2 ** 32 - 1, 2 ** 32, 2 ** 32 + 1, 2 ** 32 + 5]
    assert unwrap_tick(10, 4) == 4                     # a frame a little older stays behind
