"""Chunked transfers over the request/reply link, the host side of
firmware/core/sample_pull.h: one piece of code for the calibration
(calib_read, comp_write), the 2-D map (comp2d_write) and the excitation
(excite_read).

:class:`SamplePull` pulls numbered samples: a read names from_seq and max,
releases everything before from_seq on the drive and is answered with
``from_seq, count, <next number>, crc, data`` (calib_samples,
excite_samples). A reply is taken only when it continues from from_seq,
holds ``count`` whole samples (at most max) and its data has the CRC-32
``crc``; otherwise the same from_seq is read again (the drive's read is
idempotent), and after more than ``give_up`` failures in a row the pull
gives up. A reply that never arrives is the client's to retry (same
sequence number, counted in ``client.retried``).

:func:`write_record` sends a record in chunks at offset (comp_write,
comp2d_write) and checks each echo; the commit that follows names the
record's length and CRC-32.
"""

from __future__ import annotations

import zlib
from typing import Any, Callable, Optional

from contour.errors import UserError

# (request name, **fields) -> the reply's fields
Request = Callable[..., dict]


class SamplePull:
    """Reads chunks of samples of ``size`` bytes with ``name`` (from_seq,
    max), at most ``max_count`` per reply. ``repeated`` counts the chunks
    read again."""

    def __init__(
        self,
        request: Request,
        name: str,
        size: int,
        max_count: int,
        too_noisy: Callable[[], Exception],
        give_up: int = 20,
    ) -> None:
        self.request = request
        self.name = name
        self.size = size
        self.max_count = max_count
        self.too_noisy = too_noisy
        self.give_up = give_up
        self.repeated = 0

    def intact(self, r: dict, from_seq: int) -> bool:
        """The reply continues from from_seq, its count and length agree
        and its data has its CRC-32."""
        n, data = r["count"], r["data"]
        return (
            r["from_seq"] == from_seq
            and n <= self.max_count
            and len(data) == self.size * n
            and zlib.crc32(data) == r["crc"]
        )

    def read(self, from_seq: int, parse: Optional[Callable[[dict], Any]] = None) -> Any:
        """One intact chunk from from_seq: its fields, or what ``parse``
        makes of them (None from parse: the chunk fails the caller's own
        checks and is read again too). A refusal of the read (DriveError)
        is the caller's."""
        bad = 0
        while True:
            r = self.request(self.name, from_seq=from_seq, max=self.max_count)
            if self.intact(r, from_seq):
                got = r if parse is None else parse(r)
                if got is not None:
                    return got
            self.repeated += 1
            bad += 1
            if bad > self.give_up:
                raise self.too_noisy()

    def release(self, seq: int) -> None:
        """Free every sample before seq on the drive (a read of one)."""
        self.request(self.name, from_seq=seq, max=1)


def write_record(request: Request, name: str, record: bytes, chunk: int, **key) -> None:
    """``record`` in chunks of ``chunk`` bytes at their offsets with
    ``name`` (plus ``key``, e.g. axis); each echo (offset, len) is checked."""
    for off in range(0, len(record), chunk):
        part = record[off : off + chunk]
        w = request(name, offset=off, data=part, **key)
        if w["offset"] != off or w["len"] != len(part):
            raise UserError(
                f"drive staged {w['len']} bytes at {w['offset']}, sent {len(part)} at {off}"
            )
