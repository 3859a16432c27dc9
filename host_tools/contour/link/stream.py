"""Stream motion blocks to the drive with flow control by planned time.

The blocks come from :mod:`contour.link.blocks` (:func:`blocks_from_gcode`,
:class:`Block`, re-exported here). :class:`Streamer` keeps the drive's planned time queued between
``queue_s`` and ``queue_s / 2`` (and never sends into a full planner), polls
``status_get`` while waiting (which is also the keep-alive for the drive's
communication watchdog) and reports progress, live feed and ETA. On
KeyboardInterrupt it commands a controlled stop, waits for the axes to come
to rest and re-raises.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from contour import protocol_gen as pg
from contour.errors import UserError
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
    total: int
    elapsed_s: float
    est_done_s: float
    est_total_s: float
    feed_mm_min: float
    queued_s: float

    @property
    def eta_s(self) -> float:
        return max(0.0, self.est_total_s - self.est_done_s)


DEFAULT_IN_POSITION_NM = 5000  # when the drive has no in_position_window parameter
# Following-error samples during a job: a telemetry cycle is 2 + 2 x axes
# frames; on CAN every 10 ms would take most of a 500 kbit/s bus from the
# blocks, so there the job samples every 100 ms.
TELEM_PERIOD_MS = 10
TELEM_PERIOD_MS_CAN = 100


class Streamer:
    """Streams `blocks` and returns when the last one is done AND every axis
    is within its in-position window of the program's end point (the drive's
    `in_position_window` parameter, else DEFAULT_IN_POSITION_NM; `settle_s`
    at most). Reports the measured end position and the largest following
    error the drive's telemetry showed during the job. A fault, or a block the
    drive refuses, raises UserError naming the program line (`source`)."""

    def __init__(
        self,
        client: Client,
        blocks: list,
        queue_s: float = 1.0,
        poll_s: float = 0.01,
        on_progress: Optional[Callable[[Progress], None]] = None,
        stall_s: float = 30.0,
        source: str = "program",
        in_position_nm: Optional[int] = None,
        settle_s: float = 10.0,
        telem_period_ms: Optional[int] = None,
        on_telemetry: Optional[Callable] = None,
    ) -> None:
        self.c = client
        self.blocks = blocks
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
        self.cum = np.cumsum([b.est_s for b in blocks]) if blocks else np.zeros(0)
        self.queue_full_replies = 0
        self.ferr_max_nm = [0, 0, 0, 0]
        self.ferr_samples = 0
        self._done = 0

    def _where(self, index: int) -> str:
        if not self.blocks:
            return self.source
        b = self.blocks[min(max(index, 0), len(self.blocks) - 1)]
        return f"{self.source}:{b.line}"

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
        target = list(self.blocks[-1].target_nm)[:axes] if self.blocks else None
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
                raise UserError(
                    f"{self._where(len(self.blocks) - 1)}: the axes did not reach the end point "
                    f"within {self.settle_s:g} s: axis {'XYZA'[worst]} is "
                    f"{off[worst] / 1000:.1f} um off (window {win[worst] / 1000:.1f} um)"
                )
            time.sleep(self.poll_s)

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
        previous = None
        try:
            previous = self.c.get_param("telem_period_ms")
            self.c.set_param("telem_period_ms", self.telem_period_ms)
            return self._run()
        except KeyboardInterrupt:
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
                    if exc.code == pg.ErrorCode.FAULTED:  # faulted meanwhile: say where it ran
                        st = self.c.status()
                        self._done = (st["blocks_done"] - done0) & 0xFFFFFFFF
                        self._check(st)
                    if exc.code != pg.ErrorCode.QUEUE_FULL:
                        raise UserError(f"{self._where(i)}: {exc}") from None
                    self.queue_full_replies += 1
                    free = 0
                    continue
                free, queued = r["free_slots"], r["queued_us"]
                i += 1
                continue
            st = self.c.status()
            now = time.monotonic()
            new_done = (st["blocks_done"] - done0) & 0xFFFFFFFF
            self._done = new_done
            self._check(st)
            self._telemetry()
            free, queued = st["free_slots"], st["queued_us"]
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
        motion_s = time.monotonic() - t0
        st = self._settle(3)
        return {
            "blocks": n,
            "elapsed_s": time.monotonic() - t0,
            "motion_s": motion_s,
            "estimated_s": float(self.cum[-1]) if n else 0.0,
            "position_nm": st["pos"][:3],
            "max_following_error_um": max(self.ferr_max_nm) / 1000.0,
            "following_error_samples": self.ferr_samples,
            "queue_full_replies": self.queue_full_replies,
            "retries": self.c.retried,
        }
