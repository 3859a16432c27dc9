"""Block batches and the windowed Streamer (issue 20, "Streaming").

Without a drive: the batch records round-trip through the Python codec and
the drive's C decoder (the golden vector is test_proto_batch.c's), a drive
whose window stays shut stalls the host (no block sent), a lost reply is
retried without a block queued twice, and protocol versions are refused
both ways with a message that says what to do. Against the simulated drive
(`sim serve`): jobs over the serial pty and SLCAN end with every block done
once, in order, at the program's end point; a job of 0.05 mm chords at
10 m/min runs at its programmed feed with the queue never empty."""

from __future__ import annotations

import ctypes
import random
import threading

import pytest
from contour import native
from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import batch as bt
from contour.link import codec
from contour.link.client import Client, DriveError
from contour.link.stream import Block, Streamer
from contour.link.transport import CanBus
from contour.sim import stream_bench as sb
from contour.sim.serve import spawn

GOLDEN = bytes.fromhex(
    "CF80897AFF91F401000011A09C0180C2D72F01A09C0166A09C01904E90FA0117BFB8029F9C018F4E80E1EB17"
)
GOLDEN_BLOCKS = [
    (pg.BlockKind.LINE, (1010000, -2000000, 0), 100000000, False),
    (pg.BlockKind.LINE, (1020000, -2000000, 0), 100000000, False),
    (pg.BlockKind.RAPID, (1020000, -1990000, 5000), 0, True),
    (pg.BlockKind.DWELL, (0, 0, 0), 250, False),
    (pg.BlockKind.LINE, (1000000, -2000000, 0), 50000000, False),
]


def _encode(blocks, origin) -> bytes:
    pt = list(origin) + [0] * (pg.MAX_AXES - len(origin))
    state: dict = {"feed": None}
    out = bytearray()
    bt.encode_origin(pt, out)
    for kind, target, feed, exact in blocks:
        out += bt.encode_block(kind, target, feed, exact, pt, state)
    return bytes(out)


def test_golden_batch_is_the_drive_s():
    assert _encode(GOLDEN_BLOCKS, (1000000, -2000000)) == GOLDEN
    recs = bt.decode(GOLDEN)
    assert [(r.kind, r.target[:3], r.feed, r.exact) for r in recs] == [
        (pg.BatchKind.LINE, (1010000, -2000000, 0), 100000000, False),
        (pg.BatchKind.LINE, (1020000, -2000000, 0), 100000000, False),
        (pg.BatchKind.RAPID, (1020000, -1990000, 5000), 0, True),
        (pg.BatchKind.DWELL, (1020000, -1990000, 5000), 250, False),
        (pg.BatchKind.LINE, (1000000, -2000000, 0), 50000000, False),
    ]


def test_a_short_block_at_the_same_feed_takes_four_bytes():
    pt = [0, 0, 0, 0]
    state = {"feed": 100_000_000}
    rec = bt.encode_block(pg.BlockKind.LINE, (10_000, 0, 0), 100_000_000, False, pt, state)
    assert len(rec) == 4  # head + zigzag(10 000) in three bytes; no feed


class _Block(ctypes.Structure):  # proto_batch_block_t
    _fields_ = [
        ("kind", ctypes.c_uint8),
        ("exact_stop", ctypes.c_bool),
        ("frm", ctypes.c_int64 * 4),
        ("target", ctypes.c_int64 * 4),
        ("feed", ctypes.c_uint64),
    ]


class _Reader(ctypes.Structure):  # proto_batch_rd_t
    _fields_ = [
        ("p", ctypes.c_void_p),
        ("left", ctypes.c_size_t),
        ("pt", ctypes.c_int64 * 4),
        ("feed", ctypes.c_uint64),
        ("record", ctypes.c_uint16),
    ]


def _c_decode(data: bytes) -> list:
    lib = ctypes.CDLL(str(native.library_path()))
    buf = ctypes.create_string_buffer(data, len(data))
    rd, b = _Reader(), _Block()
    zero = (ctypes.c_int64 * 4)()
    lib.proto_batch_rd_init(ctypes.byref(rd), buf, ctypes.c_size_t(len(data)), zero, 0)
    out = []
    while True:
        k = lib.proto_batch_rd_next(ctypes.byref(rd), ctypes.byref(b))
        if k != 1:
            assert k == 0, "the C decoder refused what Python encoded"
            return out
        out.append(
            (b.kind, tuple(b.target), b.feed if b.kind != pg.BatchKind.RAPID else 0, b.exact_stop)
        )


def test_the_drive_s_decoder_reads_what_the_host_encodes():
    rng = random.Random(20)
    for _ in range(300):
        origin = [rng.choice([0, rng.randrange(-(2**40), 2**40)]) for _ in range(3)]
        pt = list(origin)
        blocks = []
        feed = rng.randrange(1, 2**32)
        for _ in range(rng.randrange(1, 30)):
            kind = rng.choice([pg.BlockKind.LINE, pg.BlockKind.RAPID, pg.BlockKind.DWELL])
            if kind == pg.BlockKind.DWELL:
                blocks.append((kind, tuple(pt), rng.randrange(1, 3_600_000), False))
                continue
            pt = [p + rng.choice([0, rng.randrange(-(2**30), 2**30)]) for p in pt]
            if rng.random() < 0.3:
                feed = rng.randrange(1, 2**32)
            blocks.append(
                (kind, tuple(pt), feed if kind == pg.BlockKind.LINE else 0, rng.random() < 0.5)
            )
        data = _encode(blocks, origin)
        want = []
        last = list(origin) + [0]
        for kind, target, f, exact in blocks:
            if kind != pg.BlockKind.DWELL:
                last = list(target) + [0]
            want.append(
                (
                    int({0: 0, 1: 1, 2: 2}[int(kind)]),
                    tuple(last),
                    f,
                    exact and kind != pg.BlockKind.DWELL,
                )
            )
        assert _c_decode(data) == want
        assert [(r.kind, r.target, r.feed, r.exact) for r in bt.decode(data)] == want


# ---- a drive made of Python (no simulator): window and retries ---------------


class FakeDrive:
    """Speaks the protocol like a drive: sessions, a one-entry replay cache,
    queue_batch into a ring of `ring` bytes that drains `drain` bytes per
    request. `drop_batch`: drop the reply of that many-th batch (once);
    `version`: the drive's protocol version (1: no version in session_open
    or session_reply)."""

    def __init__(self, ring: int = 4096, drain: int = 10**9, drop_batch: int = 0, version=None):
        self.ring, self.drain = ring, drain
        self.used = 0
        self.drop_batch = drop_batch
        self.version = pg.PROTOCOL_VERSION if version is None else version
        self.batches = 0
        self.taken: list = []  # block numbers queued, in order
        self.next = 0
        self.stream_start = None
        self.pt, self.feed = [0] * 4, 0
        self.cache = (None, None)
        self.on = None
        self.lock = threading.Lock()

    def start(self, on):
        self.on = on

    def send(self, data: bytes) -> None:
        with self.lock:
            self._send(data)

    def _send(self, data: bytes) -> None:
        if data[0] == pg.MSG_BY_NAME["session_open"].id:
            return self._session(data)
        if self.cache[0] == data:
            return self.on(self.cache[1], 0.0)
        req = codec.decode(data)
        f = req.fields
        if req.name == "queue_batch":
            reply = self._batch(req.seq, f)
        elif req.name == "status_get":
            reply = codec.encode("drive_state", req.seq, state=int(pg.State.READY))
        elif req.name in ("param_get", "param_set"):
            reply = codec.encode("param_value", req.seq, param=f["param"], value=0)
        elif req.name == "stop":
            reply = codec.encode("ack", req.seq, req=req.id)
        else:
            reply = codec.encode("ack", req.seq, req=req.id)
        self.cache = (data, reply)
        if req.name == "queue_batch" and f["count"]:
            self.batches += 1
            if self.batches == self.drop_batch:
                return  # lost on the way back
        self.on(reply, 0.0)

    def _session(self, data: bytes) -> None:
        seq, payload = data[1], data[2:]
        nonce = int.from_bytes(payload[:4], "little")
        if self.version == 1:
            if len(payload) != 4:
                reply = codec.encode(
                    "error", seq, req=data[0], code=2, arg=len(payload), lo=4, hi=4
                )
            else:
                reply = bytes([pg.MSG_BY_NAME["session_reply"].id, seq]) + payload[:4] + b"\x01\x00"
        elif int.from_bytes(payload[4:6], "little") != self.version:
            reply = codec.encode(
                "error",
                seq,
                req=data[0],
                code=int(pg.ErrorCode.NOT_SUPPORTED),
                arg=self.version,
                lo=self.version,
                hi=self.version,
            )
        else:
            reply = codec.encode(
                "session_reply", seq, nonce=nonce, sessions=1, protocol_version=self.version
            )
        self.on(reply, 0.0)

    def _batch(self, seq: int, f: dict) -> bytes:
        self.used = max(0, self.used - self.drain)
        status, accepted = 0, 0
        start = f["flags"] & 1
        fresh = start and self.stream_start != f["first_seq"]
        pt, feed = ([0] * 4, 0) if fresh else (self.pt, self.feed)
        recs = bt.decode(f["data"], pt, feed)
        assert len(recs) == f["count"]
        if f["count"]:
            if start and self.stream_start == f["first_seq"]:
                status = int(pg.ErrorCode.SEQUENCE)
            elif start:
                self.stream_start = self.next = f["first_seq"]
            elif f["first_seq"] != self.next:
                status = int(pg.ErrorCode.SEQUENCE)
            if status == 0:
                if len(f["data"]) > self.ring - self.used:
                    status = int(pg.ErrorCode.QUEUE_FULL)
                else:
                    self.used += len(f["data"])
                    accepted = len(recs)
                    self.pt = list(recs[-1].target)
                    lines = [r.feed for r in recs if r.kind == pg.BatchKind.LINE]
                    self.feed = lines[-1] if lines else feed
                    self.taken += list(range(self.next, self.next + accepted))
                    self.next += accepted
        return codec.encode(
            "batch_reply",
            seq,
            first_seq=f["first_seq"],
            accepted=accepted,
            status=status,
            next_seq=self.next,
            free_bytes=self.ring - self.used,
            queued_us=0,
            blocks_done=len(self.taken) if self.drain else 0,
            state=int(pg.State.RUNNING if not self.drain else pg.State.READY),
        )


def _line_blocks(n: int):
    for i in range(n):
        yield Block(pg.BlockKind.LINE, (10_000 * (i + 1), 0, 0), 100_000_000, False, 1e-4, i + 1)


def test_a_shut_window_stalls_the_host_without_sending_a_block():
    drive = FakeDrive(ring=0, drain=0)
    c = Client(drive, timeout=0.2)
    s = Streamer(c, _line_blocks(100), total=100, stall_s=0.3, poll_s=0.01, in_position_nm=10**9)
    with pytest.raises(UserError, match="no progress"):
        s.run()
    assert drive.batches == 0 and drive.taken == []


def test_a_lost_reply_is_retried_and_no_block_is_queued_twice():
    drive = FakeDrive(drop_batch=2)
    c = Client(drive, timeout=0.1)
    res = Streamer(c, _line_blocks(2000), total=2000, poll_s=0.001, in_position_nm=10**9).run()
    assert c.retried >= 1
    first = res["first_block_tag"]
    assert drive.taken == [(first + i) & 0xFFFFFFFF for i in range(2000)]
    assert res["blocks"] == 2000


def test_an_old_drive_is_refused_for_streaming_with_what_to_do():
    c = Client(FakeDrive(version=1), timeout=0.2)
    c.status()  # the session opens (the old way) for what does not need version 2
    assert c.drive_protocol == 1
    with pytest.raises(UserError, match="protocol version 2.*speaks version 1.*contour flash"):
        Streamer(c, _line_blocks(3), total=3).run()


def test_a_newer_drive_refuses_this_host_clearly():
    c = Client(FakeDrive(version=pg.PROTOCOL_VERSION + 1), timeout=0.2)
    with pytest.raises(DriveError, match=f"speaks protocol version {pg.PROTOCOL_VERSION + 1}"):
        c.status()


# ---- against the simulated drive ------------------------------------------------


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


@pytest.mark.parametrize("old", [1, 2])
def test_an_old_host_is_refused_by_the_drive(server, old):
    """A host of protocol 1 sends session_open without a version; one of
    protocol 2 (11-bit CAN ids) with its version."""
    from contour.link.transport import SerialTransport

    t = SerialTransport(server.serial)
    got: list = []
    ev = threading.Event()
    t.start(lambda m, ts: (got.append(codec.decode(m)), ev.set()))
    try:
        msg = codec.encode("session_open", 9, nonce=1234, protocol_version=old)
        t.send(msg[:-2] if old == 1 else msg)
        assert ev.wait(2.0)
    finally:
        t.close()
    err = [m for m in got if m.name == "error"][0]
    assert err.fields["code"] == pg.ErrorCode.NOT_SUPPORTED
    assert err.fields["arg"] == pg.PROTOCOL_VERSION


@pytest.mark.parametrize("transport", ["serial", "slcan"])
def test_a_job_of_short_blocks_runs_every_block_once_in_order(server, transport):
    from contour.link import connect

    n = 3000
    if transport == "serial":
        c = connect(port=server.serial)
    else:
        c = connect(can=CanBus("slcan", server.slcan, 1_000_000), node=1)
    with c:
        r = sb.run(c, sb.SHORT_BLOCK_PARAMS, lambda s: sb.short_blocks(s, n), n)
    r.check()
    assert r.end_error_nm <= 5000
    assert r.blocks_done == n and r.last_block_seq == n - 1


def test_cam_chords_run_at_the_programmed_feed_and_the_queue_never_empties(server):
    from contour.link import connect

    with connect(port=server.serial) as c:
        gen, total = sb.cam_circle((0, 0, 0), revs=1.0)
        r = sb.run(c, sb.CAM_PARAMS, lambda s: sb.cam_circle(s, revs=1.0)[0], total)
    r.check()
    assert r.feed_mm_min >= 0.95 * 10_000, r.feed_mm_min  # the drive's own path speed
    assert r.min_queued_s is not None and r.min_queued_s >= 0.005, r.min_queued_s
