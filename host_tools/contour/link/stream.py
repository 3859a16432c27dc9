"""Stream motion blocks to the drive with flow control by planned time.

:func:`blocks_from_gcode` turns a G-code file into drive blocks (arcs split
by the reader within a chord tolerance, dwells as dwell blocks) with each
block's estimated time from the host build of the drive's planner
(:mod:`contour.planner`), falling back to length / feed when it is not
available. :class:`Streamer` keeps the drive's planned time queued between
``queue_s`` and ``queue_s / 2`` (and never sends into a full planner), polls
``status_get`` while waiting (which is also the keep-alive for the drive's
communication watchdog) and reports progress, live feed and ETA. On
KeyboardInterrupt it commands a controlled stop, waits for the axes to come
to rest and re-raises.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link.client import Client, DriveError

NM_PER_MM = 1_000_000
RAPID_MM_MIN = 30000.0  # for the estimate only; the drive caps rapids at its limits


@dataclass
class Block:
    kind: int  # pg.BlockKind
    target_nm: tuple  # 3 ints
    feed_nm_s: int  # line: nm/s; dwell: ms
    exact_stop: bool
    est_s: float
    line: int


def blocks_from_gcode(path: str, start_mm=(0.0, 0.0, 0.0), chord_mm: float = 0.001):
    from contour import gcode

    prog = gcode.read(path, start=list(start_mm) + [0.0, 0.0, 0.0])
    seg = gcode.segments(prog, chord_mm)
    n = len(seg)
    feed = np.where(seg.rapid, RAPID_MM_MIN, seg.feed)
    est = None
    try:
        from contour.planner import Planner, PlannerProfile

        res = Planner(PlannerProfile()).estimate(
            seg.end, feed, exact_stop=seg.exact_stop, start_mm=tuple(start_mm)
        )
        est = np.asarray(res.blocks["t_total_s"], dtype=float)
    except Exception:  # noqa: BLE001 - estimator unavailable: a plain estimate
        est = None
    if est is None or len(est) != n:
        with np.errstate(invalid="ignore", divide="ignore"):
            est = np.nan_to_num(seg.length / (feed / 60.0))
    blocks = []
    for i in range(n):
        target = tuple(int(round(v * NM_PER_MM)) for v in seg.end[i])
        if seg.rapid[i]:
            blocks.append(
                Block(
                    pg.BlockKind.RAPID,
                    target,
                    0,
                    bool(seg.exact_stop[i]),
                    float(est[i]),
                    int(seg.line[i]),
                )
            )
        else:
            f = feed[i]
            if not (math.isfinite(f) and f > 0):
                raise UserError(f"{path}:{int(seg.line[i])}: no feed for this move")
            blocks.append(
                Block(
                    pg.BlockKind.LINE,
                    target,
                    max(1, int(round(f * NM_PER_MM / 60.0))),
                    bool(seg.exact_stop[i]),
                    float(est[i]),
                    int(seg.line[i]),
                )
            )
        if seg.dwell_s[i] > 0:
            ms = int(round(seg.dwell_s[i] * 1000))
            blocks.append(
                Block(pg.BlockKind.DWELL, target, ms, False, ms / 1000.0, int(seg.line[i]))
            )
    return blocks


@dataclass
class Progress:
    sent: int
    done: int
    total: int
    elapsed_s: float
    est_done_s: float
    est_total_s: float
    feed_mm_min: float
    queued_s: float

    @property
    def eta_s(self) -> float:
        return max(0.0, self.est_total_s - self.est_done_s)


class Streamer:
    def __init__(
        self,
        client: Client,
        blocks: list,
        queue_s: float = 1.0,
        poll_s: float = 0.01,
        on_progress: Optional[Callable[[Progress], None]] = None,
        stall_s: float = 30.0,
    ) -> None:
        self.c = client
        self.blocks = blocks
        self.queue_us = int(queue_s * 1e6)
        self.poll_s = poll_s
        self.on_progress = on_progress
        self.stall_s = stall_s
        self.cum = np.cumsum([b.est_s for b in blocks]) if blocks else np.zeros(0)
        self.queue_full_replies = 0

    def _check(self, st: dict) -> None:
        if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
            names = [f.name.lower() for f in pg.Fault if st["faults"] & (1 << int(f))]
            raise UserError(
                f"drive stopped with fault(s): {', '.join(names) or 'unknown'} "
                f"(state {pg.State(st['state']).name.lower()})"
            )

    def _send(self, seq_no: int, b: Block) -> dict:
        return self.c.request(
            "queue_block",
            block_seq=seq_no & 0xFFFFFFFF,
            kind=int(b.kind),
            flags=(1 << pg.BlockFlag.EXACT_STOP) if b.exact_stop else 0,
            feed=b.feed_nm_s,
            target=list(b.target_nm) + [0] * (pg.MAX_AXES - len(b.target_nm)),
        ).fields

    def run(self) -> dict:
        try:
            return self._run()
        except KeyboardInterrupt:
            self.stop_and_wait()
            raise

    def stop_and_wait(self, timeout: float = 10.0) -> dict:
        self.c.request("stop")
        end = time.monotonic() + timeout
        st = self.c.status()
        while time.monotonic() < end and st["state"] in (pg.State.RUNNING, pg.State.STOPPING):
            time.sleep(0.02)
            st = self.c.status()
        return st

    def _run(self) -> dict:
        st = self.c.status()
        self._check(st)
        if st["state"] == pg.State.DISABLED:
            self.c.enable(True)
            st = self.c.status()
        done0 = st["blocks_done"]
        n = len(self.blocks)
        i = 0
        free = st["free_slots"]
        queued = st["queued_us"]
        t0 = time.monotonic()
        last_pos, last_t = st["pos"][:3], t0
        feed = 0.0
        last_change = t0
        done = 0
        while True:
            if i < n and free > 0 and (queued < self.queue_us or i == 0):
                try:
                    r = self._send(i, self.blocks[i])
                except DriveError as exc:
                    if exc.code != pg.ErrorCode.QUEUE_FULL:
                        raise
                    self.queue_full_replies += 1
                    free = 0
                    continue
                free, queued = r["free_slots"], r["queued_us"]
                i += 1
                continue
            st = self.c.status()
            self._check(st)
            free, queued = st["free_slots"], st["queued_us"]
            now = time.monotonic()
            new_done = (st["blocks_done"] - done0) & 0xFFFFFFFF
            if new_done != done:
                done, last_change = new_done, now
            if now - last_t >= 0.1:
                d = math.dist(st["pos"][:3], last_pos) / NM_PER_MM
                feed = d / (now - last_t) * 60.0
                last_pos, last_t = st["pos"][:3], now
            if self.on_progress is not None:
                k = min(done, n)
                self.on_progress(
                    Progress(
                        i,
                        k,
                        n,
                        now - t0,
                        float(self.cum[k - 1]) if k else 0.0,
                        float(self.cum[-1]) if n else 0.0,
                        feed,
                        queued / 1e6,
                    )
                )
            if i >= n and done >= n and st["state"] in (pg.State.READY, pg.State.DISABLED):
                break
            if now - last_change > self.stall_s + (self.blocks[min(done, n - 1)].est_s if n else 0):
                raise UserError(
                    f"drive made no progress for {self.stall_s:g} s "
                    f"({done} of {n} blocks done, state {pg.State(st['state']).name.lower()})"
                )
            if i >= n or free == 0 or queued >= self.queue_us // 2:
                time.sleep(self.poll_s)
        return {
            "blocks": n,
            "elapsed_s": time.monotonic() - t0,
            "estimated_s": float(self.cum[-1]) if n else 0.0,
            "position_nm": st["pos"][:3],
            "queue_full_replies": self.queue_full_replies,
            "retries": self.c.retried,
        }
