"""contour.link.chunks: the host side of the chunked transfers
(firmware/core/sample_pull.h). A chunk that lost samples or fails its CRC
is read again from the same from_seq, never taken; a link that keeps
garbling gives up; a record is written in chunks with each echo checked."""

import struct
import zlib

import pytest
from contour.errors import UserError
from contour.link.chunks import SamplePull, write_record

SAMPLE = struct.Struct("<ii")


class Noisy(Exception):
    pass


def _samples(first: int, n: int) -> bytes:
    return b"".join(SAMPLE.pack(1000 + i, -i) for i in range(first, first + n))


def _reply(first: int, n: int, written: int = 100) -> dict:
    data = _samples(first, n)
    return {
        "from_seq": first,
        "count": n,
        "written": written,
        "crc": zlib.crc32(data),
        "data": data,
    }


class Drive:
    """Answers reads from a script of damage, one entry a read (None: intact)."""

    def __init__(self, damage=()):
        self.damage = list(damage)
        self.reads = []

    def request(self, name, **f):
        assert name == "excite_read"
        self.reads.append((f["from_seq"], f["max"]))
        r = _reply(f["from_seq"], min(f["max"], 100 - f["from_seq"]))
        how = self.damage.pop(0) if self.damage else None
        if how == "lost":  # a sample lost on the way, count and CRC of what is left
            r["data"] = r["data"][SAMPLE.size :]
            r["crc"] = zlib.crc32(r["data"])
        elif how == "crc":  # a bit flipped in the data
            d = bytearray(r["data"])
            d[3] ^= 0x10
            r["data"] = bytes(d)
        elif how == "shifted":  # intact, but not from the from_seq asked
            r = _reply(f["from_seq"] + 1, r["count"])
        return r


def _pull(drive, give_up=20):
    return SamplePull(drive.request, "excite_read", SAMPLE.size, 29, Noisy, give_up=give_up)


def test_intact_chunk_is_taken_at_once():
    d = Drive()
    p = _pull(d)
    r = p.read(10)
    assert r["data"] == _samples(10, 29) and d.reads == [(10, 29)] and p.repeated == 0


@pytest.mark.parametrize("how", ["lost", "crc", "shifted"])
def test_damaged_chunk_is_read_again_from_the_same_seq(how):
    d = Drive([how])
    p = _pull(d)
    r = p.read(40)
    assert r["from_seq"] == 40 and r["data"] == _samples(40, 29)
    assert d.reads == [(40, 29), (40, 29)]
    assert p.repeated == 1


def test_bad_crc_is_never_accepted():
    d = Drive(["crc"] * 100)
    p = _pull(d, give_up=5)
    with pytest.raises(Noisy):
        p.read(0)
    assert len(d.reads) == 6 and p.repeated == 6


def test_callers_check_failing_reads_again():
    d = Drive()
    p = _pull(d)
    seen = []

    def parse(r):
        seen.append(r["from_seq"])
        return None if len(seen) == 1 else len(r["data"])

    assert p.read(5, parse) == 29 * SAMPLE.size
    assert seen == [5, 5] and p.repeated == 1


def test_release_reads_one():
    d = Drive()
    _pull(d).release(77)
    assert d.reads == [(77, 1)]


def test_write_record_in_chunks_with_echo_checked():
    sent = []

    def request(name, **f):
        sent.append((name, f["offset"], bytes(f["data"]), f.get("axis")))
        return {"offset": f["offset"], "len": len(f["data"])}

    record = bytes(range(250)) * 2
    write_record(request, "comp_write", record, 224, axis=2)
    assert [s[1] for s in sent] == [0, 224, 448]
    assert b"".join(s[2] for s in sent) == record and {s[3] for s in sent} == {2}

    def short(name, **f):
        return {"offset": f["offset"], "len": len(f["data"]) - 1}

    with pytest.raises(UserError, match="drive staged 223 bytes at 0, sent 224 at 0"):
        write_record(short, "comp2d_write", record, 224)
