"""One unwrapping rule for the drive's wrapping phases and tick (hdservo.phase)."""
from __future__ import annotations

import numpy as np
import pytest

from hdservo.phase import unwrap_count, unwrap_pair, unwrap_phase, unwrap_tick, unwrap_turns


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


def test_signed_count_continues_across_the_int32_wrap() -> None:
    """The drive's signed 32-bit position count (CiA 402 0x6064) runs past 2^31 - 1 into -2^31."""
    true = np.array([2 ** 31 - 3, 2 ** 31 - 1, 2 ** 31 + 4, 2 ** 31 + 100, 2 ** 31 - 50], dtype=np.int64)
    signed = ((true + 2 ** 31) % 2 ** 32) - 2 ** 31                   # as the int32 field reads
    assert signed[2] < 0
    assert unwrap_count(signed).tolist() == true.astype(float).tolist()
    assert unwrap_count(signed.astype(float)).tolist() == true.astype(float).tolist()
    neg = np.array([-7, -2 ** 31, 2 ** 31 - 1], dtype=np.int64)      # down through -2^31
    assert unwrap_count(neg).tolist() == [-7.0, -2.0 ** 31, -2.0 ** 31 - 1]
    assert unwrap_count(np.array([], dtype=np.int64)).size == 0


def test_signed_and_unsigned_views_of_a_word_agree() -> None:
    rng = np.random.default_rng(3)
    true = np.cumsum(rng.integers(-2 ** 30, 2 ** 30, 500))
    unsigned = np.mod(true, 2 ** 32)
    signed = ((true + 2 ** 31) % 2 ** 32) - 2 ** 31
    assert np.array_equal(unwrap_count(unsigned), unwrap_count(signed))
    assert np.array_equal(unwrap_turns(unsigned), unwrap_count(signed) / 2.0 ** 32)


def test_unwrap_pair_keeps_the_output_next_to_its_reference() -> None:
    # reference 2^-30 turn above the wrap and rising, output 2^-30 behind it: across the wrap
    ref = np.array([2 ** 2, 2 ** 2 + 8, 2 ** 2 + 16], dtype=np.int64)
    out = (ref - 2 ** 3) % 2 ** 32
    r, o = unwrap_pair(ref, out, centred=False)
    assert r == pytest.approx(ref / 2 ** 32)
    assert o - r == pytest.approx(np.full(3, -(2 ** 3) / 2 ** 32), abs=1e-18)
    # separately unwrapped, the output lands a whole turn away from the reference
    assert unwrap_turns(out, centred=False)[0] - unwrap_turns(ref, centred=False)[0] == pytest.approx(1.0, abs=1e-8)
    with pytest.raises(ValueError, match="same number"):
        unwrap_pair(ref, out[:2])
