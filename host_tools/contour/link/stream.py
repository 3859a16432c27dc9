"""Stream motion blocks to the drive: batches, windowed flow control.

The blocks come from :mod:`contour.link.blocks` (:func:`blocks_from_gcode`,
:class:`Block`, re-exported here). :class:`Streamer` sends them in
``queue_batch`` messages (:mod:`contour.link.batch`), several in flight,
within the window the drive's replies report (free bytes of its intake ring,
planned time queued), and reports progress, live feed and ETA. The batches
are the keep-alive for the drive's communication watchdog. On
KeyboardInterrupt it commands a controlled stop, waits for the axes to come
to rest and re-raises.
"""

from __future__ import annotations

import contextlib
import math
import random
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Callable, Optional

from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import batch as bt
from contour.link.blocks import (  # noqa: F401 - re-exported
    NM_PER_MM,
    RAPID_MM_MIN,
    Block,
    blocks_from_gcode,
)
from contour.link.client import Client, DriveError


@dataclass
class Progress:
    sent: int
    done: int
    total: Optional[int]  # None: a generator of unknown length
    elapsed_s: float
    est_done_s: float
    est_total_s: float  # NaN when the total is not known
    feed_mm_min: float
    queued_s: float

    @property
    def eta_s(self) -> float:
        if not math.isfinite(self.est_total_s):
            return float("nan")
        return max(0.0, self.est_total_s - self.est_done_s)


DEFAULT_IN_POSITION_NM = 5000  # when the drive has no in_position_window parameter
# Following-error samples during a job: a telemetry cycle is 2 + 2 x axes
# frames; on CAN every 10 ms would take most of a 500 kbit/s bus from the
# blocks, so there the job samples every 100 ms.
TELEM_PERIOD_MS = 10
TELEM_PERIOD_MS_CAN = 100
PROGRESS_PERIOD_S = 0.1  # on_progress at most this often while batches flow
# batches in flight: the drive's CAN link queues 4 replies (PROTO_LINK_REPLY_MAX)
INFLIGHT_SERIAL = 8
INFLIGHT_CAN = 3


class Streamer:
    """Streams `blocks` (any iterable of Block: a list or a generator; `total`
    its length when it has none) and returns when the last one is done AND
    every axis is within its in-position window of the program's end point
    (the drive's `in_position_window` parameter, else DEFAULT_IN_POSITION_NM;
    `settle_s` at most). Reports the measured end position, the largest
    following error the drive's telemetry showed, and the smallest planned
    time the drive had queued between the first and the last block sent
    (`min_queued_s`). A fault, or a block the drive refuses, raises UserError
    naming the program line (`source`).

    Flow control: blocks go in queue_batch messages of up to `batch_max`
    blocks (at most the free slots the drive reported), block numbers
    counting from 0; the drive accepts a prefix and says which block it
    expects next, so a batch it could not take whole is sent again from
    there (with an origin record), and a retried batch (lost reply) is
    answered from the drive's replay cache, never queued twice. Only the
    blocks sent and not yet done are held here (a generator is read as the
    window opens)."""

    def __init__(
        self,
        client: Client,
        blocks: Iterable,
        queue_s: float = 1.0,
        poll_s: float = 0.01,
        on_progress: Optional[Callable[[Progress], None]] = None,
        stall_s: float = 30.0,
        source: str = "program",
        in_position_nm: Optional[int] = None,
        settle_s: float = 10.0,
        telem_period_ms: Optional[int] = None,
        on_telemetry: Optional[Callable] = None,
        total: Optional[int] = None,
        est_total_s: Optional[float] = None,
        batch_max: int = bt.COUNT_MAX,
        inflight_max: Optional[int] = None,
    ) -> None:
        self.c = client
        self.blocks = blocks
        if total is None and hasattr(blocks, "__len__"):
            total = len(blocks)
        self.total = total
        if est_total_s is None and isinstance(blocks, (list, tuple)):
            est_total_s = float(sum(b.est_s for b in blocks))
        self.est_total_s = float("nan") if est_total_s is None else est_total_s
        self.queue_us = int(queue_s * 1e6)
        self.poll_s = poll_s
        self.on_progress = on_progress
        self.stall_s = stall_s
        self.source = source
        self.in_position_nm = in_position_nm
        self.settle_s = settle_s
        if telem_period_ms is None:
            from contour.link.transport import CanTransport

            on_can = isinstance(getattr(client, "t", None), CanTransport)
            telem_period_ms = TELEM_PERIOD_MS_CAN if on_can else TELEM_PERIOD_MS
        self.telem_period_ms = telem_period_ms
        self.on_telemetry = on_telemetry
        self.batch_max = max(1, min(int(batch_max), bt.COUNT_MAX))
        self.inflight_max = inflight_max
        self.queue_full_replies = 0
        self.batches = 0
        self.resent_blocks = 0
        self.min_queued_us: Optional[int] = None
        self.ferr_max_nm = [0, 0, 0, 0]
        self.ferr_samples = 0
        self._done = 0
        # blocks taken from the iterator and not yet done: (seq, block, cum_est)
        self._held: deque = deque()
        self._last: Optional[Block] = None

    def _where_seq(self, seq: int) -> str:
        items = list(self._held) + list(getattr(self, "_retake", []))
        items += list(getattr(self, "_unsent", []))
        for _, _, batch_items, _ in getattr(self, "_inflight", []):
            items += batch_items
        for s, b, _ in items:
            if s == seq:
                return f"{self.source}:{b.line}"
        if self._last is not None:
            return f"{self.source}:{self._last.line}"
        return self.source

    def _where(self, index: int) -> str:
        return self._where_seq(index)

    def _check(self, st: dict) -> None:
        if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
            names = [f.name.lower() for f in pg.Fault if st["faults"] & (1 << int(f))]
            raise UserError(
                f"{self._where(self._done)}: drive stopped with fault(s): "
                f"{', '.join(names) or 'unknown'} (state {pg.State(st['state']).name.lower()}); "
                "`contour reset` clears it"
            )

    def _telemetry(self) -> None:
        """Fold the following-error frames received so far into the maxima."""
        while True:
            item = self.c.unsolicited()
            if item is None:
                return
            m = item[1]
            if self.on_telemetry is not None:
                self.on_telemetry(m)
            if m.name.startswith("ferr_"):
                k = int(m.name[5:])
                self.ferr_max_nm[k] = max(self.ferr_max_nm[k], abs(m.fields["ferr"]))
                self.ferr_samples += 1

    def _windows(self, axes: int) -> list:
        if self.in_position_nm is not None:
            return [self.in_position_nm] * axes
        out = []
        for a in range(axes):
            try:
                out.append(self.c.get_param(f"in_position_window.{'xyza'[a]}"))
            except UserError:  # firmware without the parameter
                out.append(DEFAULT_IN_POSITION_NM)
        return out

    def _settle(self, axes: int) -> dict:
        """Wait until every axis is within its window of the end point (two
        status readings in a row)."""
        target = list(self._end_target)[:axes] if self._end_target is not None else None
        win = self._windows(axes)
        end = time.monotonic() + self.settle_s
        inside = 0
        while True:
            st = self.c.status()
            self._check(st)
            self._telemetry()
            if target is None:
                return st
            off = [abs(st["pos"][a] - target[a]) for a in range(axes)]
            inside = inside + 1 if all(o <= w for o, w in zip(off, win)) else 0
            if inside >= 2:
                return st
            if time.monotonic() > end:
                worst = max(range(axes), key=lambda a: off[a] - win[a])
                where = f"{self.source}:{self._last.line}" if self._last else self.source
                raise UserError(
                    f"{where}: the axes did not reach the end point "
                    f"within {self.settle_s:g} s: axis {'XYZA'[worst]} is "
                    f"{off[worst] / 1000:.1f} um off (window {win[worst] / 1000:.1f} um)"
                )
            time.sleep(self.poll_s)

    def run(self) -> dict:
        self.c.require_protocol("streaming a job (queue_batch)", version=2)
        previous = None
        try:
            previous = self.c.get_param("telem_period_ms")
            self.c.set_param("telem_period_ms", self.telem_period_ms)
            return self._run()
        except KeyboardInterrupt:
            for item in getattr(self, "_inflight", ()):
                item[0].cancel()
            self.stop_and_wait()
            raise
        finally:
            if previous is not None:  # the drive is not left streaming
                with contextlib.suppress(UserError, KeyboardInterrupt):
                    self.c.set_param("telem_period_ms", previous)

    def stop_and_wait(self, timeout: float = 10.0) -> dict:
        self.c.request("stop")
        end = time.monotonic() + timeout
        st = self.c.status()
        while time.monotonic() < end and st["state"] in (pg.State.RUNNING, pg.State.STOPPING):
            time.sleep(0.02)
            st = self.c.status()
        return st

    # ---- batches -------------------------------------------------------------
    #
    # Up to `inflight_max` batches are in flight: the window is the ring's
    # free bytes of the last reply less the bytes sent since. Replies are
    # handled in order. A batch the drive could not take whole makes every
    # later batch in flight fail its sequence check (nothing of them is
    # taken); once they are answered the blocks not taken are sent again
    # from the block the drive expects, after an origin record. A retried
    # batch (lost reply) that the replay cache no longer holds is refused
    # as out of sequence: its next_seq then says how much of it was taken.

    def _encode(self, room: int) -> tuple[bytes, list, list, Optional[int]]:
        """Records of as many unsent blocks as fit `room` bytes, from the
        encoder's point and feed (after the last block sent)."""
        point = list(self._enc_point)
        state = {"feed": self._enc_feed}
        out = bytearray()
        if self._need_origin:
            bt.encode_origin(point, out)
        items = []
        for item in self._unsent:
            if len(items) >= self.batch_max:
                break
            b = item[1]
            before = (list(point), state["feed"])
            rec = bt.encode_block(b.kind, b.target_nm, b.feed_nm_s, b.exact_stop, point, state)
            if len(out) + len(rec) > room:
                point, state["feed"] = before  # not sent: the stream stays before it
                break
            out += rec
            items.append(item)
        return bytes(out), items, point, state["feed"]

    def _send(self, room: int) -> bool:
        """Send one batch into `room` bytes; False when nothing fits."""
        data, items, point, feed = self._encode(min(room, bt.DATA_MAX))
        if not items:
            return False
        first = items[0][0]
        flags = (1 << pg.BatchFlag.START) if self._start else 0
        p = self.c.submit(
            "queue_batch",
            first_seq=(self._base + first) & 0xFFFFFFFF,
            count=len(items),
            flags=flags,
            data=data,
        )
        for _ in items:
            self._unsent.popleft()
        self._inflight.append((p, first, items, len(data)))
        self._inflight_bytes += len(data)
        self._enc_point, self._enc_feed = point, feed
        self._need_origin = False
        self._start = False
        self.batches += 1
        return True

    def _poll(self) -> dict:
        """An empty batch: only the window."""
        return self.c.request(
            "queue_batch",
            first_seq=(self._base + self._acc_next) & 0xFFFFFFFF,
            count=0,
            flags=0,
            data=b"",
        ).fields

    def _collect(self) -> dict:
        """The reply of the oldest batch in flight, accounted."""
        p, first, items, nbytes = self._inflight.popleft()
        self._inflight_bytes -= nbytes
        try:
            r = p.result().fields
        except DriveError as exc:  # a malformed batch: a bug here, not in the program
            raise UserError(f"{self._where_seq(first)}: {exc}") from None
        k = len(items)
        status = r["status"]
        nseq = (r["next_seq"] - self._base) & 0xFFFFFFFF  # as a block index of this job
        if status == pg.ErrorCode.SEQUENCE:
            taken = min(nseq - first, k) if first <= nseq < first + (1 << 31) else 0
            if taken == 0 and not self._resync and nseq != first:
                raise UserError(
                    f"{self._where_seq(first)}: the drive expected block {nseq}, "
                    f"not {first} (another host streamed to it?)"
                )
        else:
            taken = r["accepted"]
        for item in items[:taken]:
            self._held.append(item)
            b = item[1]
            if b.kind != pg.BlockKind.DWELL:
                t = list(b.target_nm)
                self._acc_point = t + [0] * (pg.MAX_AXES - len(t))
            if b.kind == pg.BlockKind.LINE:
                self._acc_feed = b.feed_nm_s
        self._acc_next = first + taken
        if taken < k:
            self._resync = True
            self._retake.extend(items[taken:])
            self.resent_blocks += k - taken
        if status == pg.ErrorCode.QUEUE_FULL:
            self.queue_full_replies += 1
        elif status not in (pg.ErrorCode.NONE, pg.ErrorCode.SEQUENCE):
            seq = nseq
            if status == pg.ErrorCode.FAULTED or r["state"] in (pg.State.FAULT, pg.State.ESTOP):
                st = self.c.status()
                self._done = (st["blocks_done"] - self._done0) & 0xFFFFFFFF
                self._check(st)
            if status == pg.ErrorCode.BUSY and first == 0 and taken == 0:
                # the start batch: nothing of this job is on the drive
                raise UserError(
                    f"{self._where_seq(first)}: the drive is busy with motion it already "
                    f"has (state {pg.State(r['state']).name.lower()}: another job, a jog "
                    "or homing); nothing of this program was queued"
                )
            if status == pg.ErrorCode.OUT_OF_RANGE:
                text = (
                    f"drive refused the block: axis {'XYZA'[r['arg'] & 3]} out of range "
                    "(soft travel limits, or a dwell/feed outside what the drive takes)"
                )
            else:
                from contour.link.client import describe_error

                fields = {"code": status, "arg": r["arg"], "lo": 0, "hi": 0, "req": 0}
                text = describe_error("queue_batch", fields)
            raise UserError(f"{self._where_seq(seq)}: {text}")
        if self._resync and not self._inflight:
            # every batch sent is answered: the rest again, from what was taken
            self._unsent.extendleft(reversed(self._retake))
            self._retake = []
            self._resync = False
            self._need_origin = True
            self._enc_point, self._enc_feed = list(self._acc_point), self._acc_feed
        return r

    def _run(self) -> dict:
        st = self.c.status()
        self._check(st)
        if st["state"] == pg.State.DISABLED:
            self.c.enable(True)
            st = self.c.status()
        self._done0 = done0 = st["blocks_done"]
        it = iter(self.blocks)
        self._unsent: deque = deque()  # (seq, block, cum_est) read, not yet sent
        self._inflight: deque = deque()  # (pending, first, items, bytes)
        self._inflight_bytes = 0
        self._retake: list = []
        self._resync = False
        self._acc_point = [0] * pg.MAX_AXES
        self._acc_feed: Optional[int] = None
        self._acc_next = 0
        self._enc_point = list(self._acc_point)
        self._enc_feed: Optional[int] = None
        self._need_origin = True
        self._start = True
        # each job starts at a new block number: a late retry of its start
        # batch is then never taken for the start of another stream
        self._base = random.getrandbits(32)
        self._end_target = None
        on_can = type(getattr(self.c, "t", None)).__name__ == "CanTransport"
        inflight_max = self.inflight_max or (INFLIGHT_CAN if on_can else INFLIGHT_SERIAL)
        taken = 0
        cum = 0.0
        exhausted = False
        r = self._poll()  # the window before any block is sent
        free = r["free_bytes"]  # the ring's free bytes in the last reply
        queued = st["queued_us"]
        state = st["state"]
        t0 = time.monotonic()
        last_pos, last_t = st["pos"][:3], t0
        feed = 0.0
        last_change = t0
        last_report = 0.0
        done = 0
        done_est = 0.0
        while True:
            # read the iterator only as far as the window needs
            while not exhausted and len(self._unsent) < self.batch_max:
                try:
                    b = next(it)
                except StopIteration:
                    exhausted = True
                    break
                cum += b.est_s
                self._unsent.append((taken, b, cum))
                self._last = b
                if b.kind != pg.BlockKind.DWELL:
                    self._end_target = b.target_nm
                taken += 1
            # send while the window is open
            sent = False
            if (
                not self._resync
                and self._unsent
                and len(self._inflight) < inflight_max
                and (queued < self.queue_us or not self._held)
            ):
                room = free - self._inflight_bytes
                if room >= min(bt.DATA_MAX, 64) or (not self._inflight and room > 0):
                    sent = self._send(room)
            if sent and len(self._inflight) < inflight_max and self._unsent:
                continue  # fill the pipe first
            r = self._collect() if self._inflight else self._poll()
            now = time.monotonic()
            free, queued, state = r["free_bytes"], r["queued_us"], r["state"]
            new_done = (r["blocks_done"] - done0) & 0xFFFFFFFF
            if now - last_t >= 0.1:  # live feed, telemetry, faults
                st = self.c.status()
                self._check(st)
                self._telemetry()
                d = math.dist(st["pos"][:3], last_pos) / NM_PER_MM
                feed = d / (now - last_t) * 60.0
                last_pos, last_t = st["pos"][:3], now
            sent_all = exhausted and not self._unsent and not self._inflight and not self._resync
            self._done = new_done
            # mid-job: after the first block is done, before the last is sent
            if (
                new_done > 0
                and not sent_all
                and (self.min_queued_us is None or queued < self.min_queued_us)
            ):
                self.min_queued_us = queued
            while self._held and self._held[0][0] < new_done:
                done_est = self._held.popleft()[2]
            if new_done != done:
                done, last_change = new_done, now
            if self.on_progress is not None and (now - last_report >= PROGRESS_PERIOD_S):
                last_report = now
                self.on_progress(
                    Progress(
                        self._acc_next,
                        min(done, taken),
                        self.total,
                        now - t0,
                        done_est,
                        self.est_total_s,
                        feed,
                        queued / 1e6,
                    )
                )
            if state in (pg.State.FAULT, pg.State.ESTOP):
                self._check(self.c.status())
            if sent_all and done >= taken and state in (pg.State.READY, pg.State.DISABLED):
                break
            if now - last_change > self.stall_s + (self._held[0][1].est_s if self._held else 0):
                raise UserError(
                    f"drive made no progress for {self.stall_s:g} s "
                    f"({done} of {taken} blocks done, state {pg.State(state).name.lower()})"
                )
            if self._inflight:
                continue
            if sent_all or queued >= self.queue_us // 2:
                time.sleep(self.poll_s)
            elif free < min(bt.DATA_MAX, 64):
                time.sleep(min(self.poll_s, 0.0005))
        motion_s = time.monotonic() - t0
        st = self._settle(3)
        n = taken
        return {
            "blocks": n,
            "blocks_done": (st["blocks_done"] - done0) & 0xFFFFFFFF,
            "elapsed_s": time.monotonic() - t0,
            "motion_s": motion_s,
            "estimated_s": cum,
            "position_nm": st["pos"][:3],
            "max_following_error_um": max(self.ferr_max_nm) / 1000.0,
            "following_error_samples": self.ferr_samples,
            "queue_full_replies": self.queue_full_replies,
            "batches": self.batches,
            "resent_blocks": self.resent_blocks,
            "min_queued_s": None if self.min_queued_us is None else self.min_queued_us / 1e6,
            "first_block_tag": self._base,
            "retries": self.c.retried,
        }
