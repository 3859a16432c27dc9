"""Bits of CAN frames on the wire (contour.link.canbits), standard and
extended (our protocol's 29-bit ids, docs/canopen.md)."""

from __future__ import annotations

import random

from contour import protocol_gen as pg
from contour.link.canbits import frame_bits, worst_frame_bits


def test_known_frames_and_bounds():
    # 34 dominant bits (id 0, DLC 0, CRC 0): a stuff bit after every 5
    assert frame_bits(0, b"") == 47 + 6
    assert worst_frame_bits(8) == 135
    assert worst_frame_bits(8, extended=True) == 160
    rng = random.Random(1)
    for _ in range(300):
        n = rng.randrange(9)
        data = bytes(rng.randrange(256) for _ in range(n))
        std = frame_bits(rng.randrange(0x800), data)
        ext = frame_bits(pg.can_id(rng.randrange(2, 32), rng.randrange(1, 128)), data, True)
        assert 47 + 8 * n <= std <= worst_frame_bits(n)
        assert 67 + 8 * n <= ext <= worst_frame_bits(n, extended=True)


def test_extended_frame_is_longer_than_the_same_standard_one():
    # the same data under an 11-bit and a 29-bit id: 20 more bits unstuffed
    data = bytes(range(8))
    assert frame_bits(0x2AA, data, True) - frame_bits(0x2AA, data) >= 20 - 5
    assert frame_bits(pg.can_id(4, 1), data, True) > frame_bits(0x201, data)
