"""Block batches of ``queue_batch`` (protocol/README.md, "Block batches").

A batch is records: a head byte (bits 0..3 axis mask, bit 4 a feed
follows, bit 5 exact stop, bits 6..7 :class:`pg.BatchKind`), zigzag LEB128
deltas in nm from the stream's point for the masked axes, then an LEB128
feed (line nm/s, only when it changes; dwell ms). An origin record sets
the stream's point absolutely. The drive's decoder is
``firmware/core/proto_batch.c``; the constants come from the protocol
definition (:mod:`contour.protocol_gen`).
"""

from __future__ import annotations

from dataclasses import dataclass

from contour import protocol_gen as pg

HEAD_FEED = 1 << pg.BatchHead.FEED
HEAD_EXACT = 1 << pg.BatchHead.EXACT_STOP
KIND_SHIFT = int(pg.BatchHead.KIND)
AXIS_MASK = 0x0F
DATA_MAX = next(f.max for f in pg.MSG_BY_NAME["queue_batch"].fields if f.name == "data")
COUNT_MAX = 255  # queue_batch.count is a u8

_KIND_OF_BLOCK = {
    int(pg.BlockKind.LINE): int(pg.BatchKind.LINE),
    int(pg.BlockKind.RAPID): int(pg.BatchKind.RAPID),
    int(pg.BlockKind.DWELL): int(pg.BatchKind.DWELL),
}


class BatchError(ValueError):
    """A batch that does not decode."""


def _uvar(v: int, out: bytearray) -> None:
    while True:
        b = v & 0x7F
        v >>= 7
        if v:
            out.append(b | 0x80)
        else:
            out.append(b)
            return


def _zigzag(v: int) -> int:
    return (v << 1) if v >= 0 else ((-v << 1) - 1)


def encode_origin(point, out: bytearray) -> None:
    out.append((int(pg.BatchKind.ORIGIN) << KIND_SHIFT) | AXIS_MASK)
    for k in range(pg.MAX_AXES):
        _uvar(_zigzag(int(point[k]) if k < len(point) else 0), out)


def encode_block(kind: int, target, feed: int, exact: bool, point: list, state: dict) -> bytes:
    """The record of one block (pg.BlockKind, absolute target in nm, feed
    nm/s or dwell ms); `point` (the stream's point, 4 axes) and
    state["feed"] advance as the drive's decoder advances them."""
    bk = _KIND_OF_BLOCK[int(kind)]
    out = bytearray(1)
    head = bk << KIND_SHIFT
    if exact and bk != pg.BatchKind.DWELL:
        head |= HEAD_EXACT
    if bk != pg.BatchKind.DWELL:
        for k in range(pg.MAX_AXES):
            t = int(target[k]) if k < len(target) else 0
            if t != point[k]:
                head |= 1 << k
                _uvar(_zigzag(t - point[k]), out)
                point[k] = t
    if bk == pg.BatchKind.DWELL or (bk == pg.BatchKind.LINE and feed != state.get("feed")):
        head |= HEAD_FEED
        _uvar(int(feed), out)
        if bk == pg.BatchKind.LINE:
            state["feed"] = int(feed)
    out[0] = head
    return bytes(out)


@dataclass
class Record:
    kind: int  # pg.BatchKind (never ORIGIN: decode applies those)
    target: tuple
    feed: int
    exact: bool


def decode(data: bytes, point=(0, 0, 0, 0), feed: int = 0) -> list[Record]:
    """Records of a batch as the drive reads them (for tests)."""
    pt = list(point) + [0] * (pg.MAX_AXES - len(point))
    i = 0
    out = []

    def uvar() -> int:
        nonlocal i
        v = 0
        for k in range(10):
            if i >= len(data):
                raise BatchError("data ends inside an integer")
            c = data[i]
            i += 1
            v |= (c & 0x7F) << (7 * k)
            if not c & 0x80:
                if v >= 1 << 64:
                    raise BatchError("integer beyond 64 bits")
                return v
        raise BatchError("integer longer than 10 bytes")

    def svar() -> int:
        z = uvar()
        return (z >> 1) ^ -(z & 1)

    origin = False
    while i < len(data):
        head = data[i]
        i += 1
        kind = head >> KIND_SHIFT
        if kind == pg.BatchKind.ORIGIN:
            if origin or head & (HEAD_FEED | HEAD_EXACT):
                raise BatchError("two origins in a row, or an origin with feed or exact stop")
            origin = True
            pt = [svar() if head & (1 << k) else 0 for k in range(pg.MAX_AXES)]
            continue
        origin = False
        for k in range(pg.MAX_AXES):
            if head & (1 << k):
                pt[k] += svar()
        f = uvar() if head & HEAD_FEED else 0
        if kind == pg.BatchKind.LINE:
            if head & HEAD_FEED:
                feed = f
            if not feed:
                raise BatchError("line without a feed")
            f = feed
        elif kind == pg.BatchKind.RAPID and head & HEAD_FEED:
            raise BatchError("rapid with a feed")
        elif kind == pg.BatchKind.DWELL and (head & (HEAD_FEED | AXIS_MASK)) != HEAD_FEED:
            raise BatchError("dwell with deltas or without a duration")
        out.append(Record(kind, tuple(pt), f, bool(head & HEAD_EXACT)))
    return out
