"""Link throughput jobs for `bench/bench-stream.sh` and the end-to-end tests.

Two jobs on the real-time simulated drive (`sim serve`):

- :func:`short_blocks`: N blocks of 10 um along Y at 15 m/min (25 000
  blocks/s of motion), so that the link, not the motion, is the limit. The
  drive runs them with ``velocity_profile = scurve_at_rest`` and 50 m/s^2 on
  every axis (:data:`SHORT_BLOCK_PARAMS`): its look-ahead of 64 planner
  blocks is 0.64 mm of 10 um blocks, and the distance to stop from 15 m/min
  must fit it (at the tuned machine's 10 m/s^2 the planner alone caps
  10 um blocks at about 11 000 blocks/s, and the per-block S-curve at
  about 1 700, whatever the link: protocol/README.md, "Throughput and bus capacity").
- :func:`cam_circle`: a circle of 0.05 mm chords at 10 m/min (3333
  blocks/s), the shape of CAM output, with the drive's own limits and
  ``scurve_at_rest``.

Both jobs run again with ``velocity_profile = scurve_continuous`` (jerk
limited, the acceleration continuous across blocks; :data:`CAM_PARAMS_CONTINUOUS`,
:data:`SHORT_BLOCK_PARAMS_CONTINUOUS`). Its stop from the feed is jerk-limited
too, so 10 um blocks at 50 m/s^2 and the tuned machine's 1000 m/s^3 run at
the speed from which the drive stops within its 0.64 mm of look-ahead (about
4.5 m/min, some 7 000 blocks/s), not at 15 m/min.

:func:`run` streams a job and checks that nothing was lost, duplicated or
reordered: the drive's blocks done equal the program's blocks, the last
block done is the program's last (block numbers are the tags the drive
reports), and the axes end within the in-position window of the program's
end point.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Optional

from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link.stream import Block, Streamer

SHORT_BLOCK_NM = 10_000
SHORT_BLOCK_FEED = 250_000_000  # nm/s = 15 m/min
SHORT_BLOCK_PARAMS = {
    "velocity_profile": 2,  # scurve_at_rest
    "max_acceleration.x": 50_000_000_000,
    "max_acceleration.y": 50_000_000_000,
    "max_acceleration.z": 50_000_000_000,
}
CAM_SEG_NM = 50_000
CAM_FEED = round(10_000 / 60 * 1e6)  # 10 m/min in nm/s
CAM_RADIUS_NM = 20_000_000
CAM_PARAMS = {"velocity_profile": 2}
CAM_PARAMS_CONTINUOUS = {"velocity_profile": 3}  # scurve_continuous
SHORT_BLOCK_PARAMS_CONTINUOUS = dict(SHORT_BLOCK_PARAMS, velocity_profile=3)


def short_blocks(start, n: int):
    """Generator of n 10 um lines along Y from `start` (nm)."""
    x0, y0, z0 = start[:3]
    for i in range(n):
        yield Block(
            pg.BlockKind.LINE,
            (x0, y0 + SHORT_BLOCK_NM * (i + 1), z0),
            SHORT_BLOCK_FEED,
            False,
            SHORT_BLOCK_NM / SHORT_BLOCK_FEED,
            i + 1,
        )


def cam_circle(start, revs: float = 1.0):
    """(generator, count) of 0.05 mm chords of a circle through `start`
    (centre at -radius along X) at 10 m/min."""
    x0, y0, z0 = start[:3]
    r = CAM_RADIUS_NM
    n = int(revs * 2 * math.pi * r / CAM_SEG_NM)

    def gen():
        for i in range(n):
            a = 2 * math.pi * (i + 1) * CAM_SEG_NM / (2 * math.pi * r)
            yield Block(
                pg.BlockKind.LINE,
                (x0 + round(r * math.cos(a)) - r, y0 + round(r * math.sin(a)), z0),
                CAM_FEED,
                False,
                CAM_SEG_NM / CAM_FEED,
                i + 1,
            )

    return gen(), n


@dataclass
class JobResult:
    blocks: int
    seconds: float  # first send to the last block done
    blocks_per_second: float
    blocks_done: int
    last_block_seq: int  # as a block index of the job (tags start at a random base)
    end_error_nm: int
    min_queued_s: Optional[float]
    feed_mm_min: Optional[float]  # median path speed the drive reported while moving
    stream: dict = field(default_factory=dict)
    bus_frames: int = 0  # CAN frames of this node, both ways (0: serial)

    def check(self) -> None:
        """UserError unless the drive did exactly the program."""
        if self.blocks_done != self.blocks:
            raise UserError(f"the drive did {self.blocks_done} blocks of {self.blocks}")
        if self.last_block_seq != self.blocks - 1:
            raise UserError(
                f"the last block done is block {self.last_block_seq}, not {self.blocks - 1}"
            )


def run(c, params: dict, make_blocks, total: int, end_window_nm: int = 5000) -> JobResult:
    """Stream `make_blocks(start)` (total blocks) to the enabled drive of
    client `c` with `params` set; the checks of the module docstring."""
    st = c.status()
    if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
        c.request("fault_reset")
    for k, v in params.items():
        c.set_param(k, v)
    c.enable(True)
    st = c.status()
    start = st["pos"][:3]
    done0 = st["blocks_done"]
    marks: list = []
    end_target: list = []

    def blocks():
        for b in make_blocks(start):
            end_target[:] = list(b.target_nm)
            yield b

    feeds: list = []

    def progress(p) -> None:
        marks.append((time.monotonic(), p.done))

    def telemetry(m) -> None:
        if m.name == "path":
            feeds.append(m.fields["feed"])

    s = Streamer(
        c,
        blocks(),
        total=total,
        queue_s=1.0,
        poll_s=0.002,
        on_progress=progress,
        in_position_nm=end_window_nm,
        on_telemetry=telemetry,
    )
    res = s.run()
    dt = res["motion_s"]
    st = c.status()
    # where the streamer found the axes settled (two readings in a row
    # within the window); a later reading may show the servo still ringing
    err = max(abs(res["position_nm"][a] - end_target[a]) for a in range(3))
    # the path speed the drive reported (telemetry, on its own clock: a host
    # or simulator lagging behind the wall clock does not show here)
    moving = sorted(f for f in feeds if f > 0)
    feed_mm_min = moving[len(moving) // 2] if moving else None
    t = getattr(c, "t", None)
    frames = getattr(t, "bus_tx_frames", 0) + getattr(t, "bus_rx_frames", 0)
    return JobResult(
        blocks=total,
        seconds=dt,
        blocks_per_second=total / dt if dt > 0 else 0.0,
        blocks_done=(st["blocks_done"] - done0) & 0xFFFFFFFF,
        last_block_seq=(st["last_block_seq"] - res["first_block_tag"]) & 0xFFFFFFFF,
        end_error_nm=err,
        min_queued_s=res["min_queued_s"],
        feed_mm_min=feed_mm_min,
        stream=res,
        bus_frames=frames,
    )
