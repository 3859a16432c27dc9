"""What the person at the machine does: enable, disable, reset, stop, e-stop,
jog, home and look at the drive's status (library of the `contour enable`,
`disable`, `reset`, `stop`, `estop`, `jog`, `home` and `status` commands).

Everything here works in the drive's units (nm, nm/s) on a connected
:class:`contour.link.client.Client`; the commands convert from and to mm and
mm/min. A latched fault is reported as a :class:`FaultError` (exit code 1)
that names the faults and says that ``contour reset`` clears them.

"At rest" is decided on the host: the drive's state is ready (or disabled,
fault, estop) and the measured position of every axis changes by at most
one encoder count between polls over ``REST_S``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Optional

from contour import protocol_gen as pg
from contour.errors import UsageError, UserError
from contour.link.client import AXIS_NAMES, Client, DriveError

NM_PER_MM = 1_000_000
POS_LIMIT_NM = 10**15  # PROTO_POS_LIMIT_NM (firmware/core/proto_dispatch.h)
REST_NM = 1250  # one encoder count of the default machine (5 mm lead, 4000 counts/rev)
REST_S = 0.1  # the position holds within REST_NM this long: at rest
POLL_S = 0.02
MOVING = (pg.State.RUNNING, pg.State.STOPPING, pg.State.HOMING)
MOVING_NAMES = ("running", "stopping", "homing")
LATCHED = (pg.State.FAULT, pg.State.ESTOP)


class FaultError(UserError):
    """The drive has a fault latched (or latched one during a command)."""

    kind = "fault"

    def __init__(self, text: str, faults: list[str]) -> None:
        super().__init__(text)
        self.faults = faults


def fault_names(bits: int) -> list[str]:
    """Names of the fault bits set in ``bits`` (unknown bits as ``bitN``)."""
    known = {int(f): f.name.lower() for f in pg.Fault}
    return [known.get(b, f"bit{b}") for b in range(16) if bits & (1 << b)]


def state_name(state: int) -> str:
    try:
        return pg.State(state).name.lower()
    except ValueError:
        return f"state {state}"


def parse_axis(text: str) -> int:
    """``x``/``y``/``z``/``a`` (any case) or ``0``..``3`` -> axis index; UsageError otherwise."""
    t = text.strip().lower()
    if t.isdigit() and int(t) < pg.MAX_AXES:
        return int(t)
    if len(t) == 1 and t in AXIS_NAMES:
        return AXIS_NAMES.index(t)
    raise UsageError(f"axis {text!r}: one of x, y, z, a (or 0..3)")


def parse_axes(text: str) -> int:
    """``X,Y`` -> axis mask; UsageError for an unknown or repeated axis."""
    mask = 0
    for part in text.split(","):
        a = parse_axis(part)
        if mask & (1 << a):
            raise UsageError(f"--axes {text}: axis {AXIS_NAMES[a]} named twice")
        mask |= 1 << a
    return mask


def mm_to_nm(mm: float, what: str) -> int:
    if not math.isfinite(mm):
        raise UsageError(f"{what} must be a finite number of mm")
    nm = int(round(mm * NM_PER_MM))
    if abs(nm) >= POS_LIMIT_NM:
        raise UsageError(f"{what} {mm:g} mm is beyond the drive's +-{POS_LIMIT_NM // 10**6} mm")
    return nm


def feed_to_nm_s(mm_min: float) -> int:
    if not (math.isfinite(mm_min) and mm_min > 0):
        raise UsageError(f"--feed {mm_min:g}: must be a positive number of mm/min")
    nm_s = int(round(mm_min * NM_PER_MM / 60.0))
    if not 1 <= nm_s <= 0xFFFFFFFF:
        raise UsageError(f"--feed {mm_min:g} mm/min is outside what the drive takes")
    return nm_s


@dataclass
class Snapshot:
    """One status of the drive, decoded."""

    state: str
    enabled: list  # axis names
    faults: list  # fault names
    position_nm: list  # per axis of the drive
    free_slots: int
    queued_us: int
    blocks_done: int
    last_block_seq: int
    homed: list = None  # axis names homed since the drive started

    @property
    def latched(self) -> bool:
        return self.state in ("fault", "estop") or bool(self.faults)

    def as_dict(self) -> dict:
        """JSON form (units in the field names, mm and s)."""
        return {
            "state": self.state,
            "enabled_axes": self.enabled,
            "faults": self.faults,
            "homed_axes": self.homed or [],
            "position_mm": {AXIS_NAMES[i]: p / NM_PER_MM for i, p in enumerate(self.position_nm)},
            "queue": {
                "free_slots": self.free_slots,
                "queued_s": self.queued_us / 1e6,
                "blocks_done": self.blocks_done,
                "last_block_seq": self.last_block_seq,
            },
        }

    def position_text(self) -> str:
        return "  ".join(
            f"{AXIS_NAMES[i]} {p / NM_PER_MM:10.4f}" for i, p in enumerate(self.position_nm)
        )

    def line(self) -> str:
        """One line: what `status --watch` prints per sample."""
        return (
            f"{self.state:9s} faults {','.join(self.faults) or 'none':16s} "
            f"{self.position_text()} mm  queue {self.free_slots} free "
            f"{self.queued_us / 1e6:.3f} s"
        )

    def text(self) -> str:
        """Several lines: what `status` prints."""
        enabled = " ".join(self.enabled) or "none"
        return (
            f"state     {self.state} (enabled: {enabled})\n"
            f"faults    {', '.join(self.faults) or 'none'}\n"
            f"position  {self.position_text()} mm\n"
            f"homed     {' '.join(self.homed or []) or 'none'}\n"
            f"queue     {self.free_slots} slots free, {self.queued_us / 1e6:.3f} s planned, "
            f"{self.blocks_done} blocks done"
        )


def latched_text(snap: Snapshot) -> str:
    names = ", ".join(snap.faults) or snap.state
    return f"fault latched: {names} (state {snap.state}); `contour reset` clears it"


class Operator:
    """The operator's requests on one connected client."""

    def __init__(self, client: Client) -> None:
        self.c = client
        self._axes: Optional[int] = None

    @property
    def axes(self) -> int:
        if self._axes is None:
            self._axes = int(self.c.identify()["axes"])
        return self._axes

    def snapshot(self) -> Snapshot:
        st = self.c.status()
        return Snapshot(
            state=state_name(st["state"]),
            enabled=[AXIS_NAMES[i] for i in range(self.axes) if st["enabled"] & (1 << i)],
            faults=fault_names(st["faults"]),
            position_nm=list(st["pos"][: self.axes]),
            free_slots=st["free_slots"],
            queued_us=st["queued_us"],
            blocks_done=st["blocks_done"],
            last_block_seq=st["last_block_seq"],
            homed=[AXIS_NAMES[i] for i in range(self.axes) if st.get("homed", 0) & (1 << i)],
        )

    def check_axes(self, mask: int) -> None:
        bad = [AXIS_NAMES[a] for a in range(pg.MAX_AXES) if mask & (1 << a) and a >= self.axes]
        if bad:
            raise UsageError(f"axis {', '.join(bad)}: this drive has {self.axes} axes")

    def ready_to_move(self) -> Snapshot:
        """The status, if the drive can take a motion command now: no fault
        latched (FaultError), enabled and at rest (UserError otherwise)."""
        snap = self.snapshot()
        self.refuse_if_latched(snap)
        if snap.state == "disabled":
            raise UserError("the drive is disabled: `contour enable` first")
        if snap.state in MOVING_NAMES:
            raise UserError(f"the drive is moving (state {snap.state}): `contour stop` first")
        return snap

    def refuse_if_latched(self, snap: Snapshot) -> None:
        if snap.latched:
            raise FaultError(latched_text(snap), snap.faults)

    # ---- enable / disable / reset / stop / estop ---------------------------------

    def enable(self, on: bool, mask: Optional[int] = None) -> Snapshot:
        """Switch the axes on or off; a latched fault refuses enabling."""
        full = (1 << self.axes) - 1
        if mask is None:
            mask = full
        self.check_axes(mask)
        if on:
            self.refuse_if_latched(self.snapshot())
        try:
            self.c.request("enable", axis_mask=mask, on=int(on))
        except DriveError as exc:
            if exc.code == pg.ErrorCode.NOT_SUPPORTED and mask != full:
                raise UserError("this drive switches its axes together: leave out --axes") from None
            if exc.code == pg.ErrorCode.FAULTED:
                snap = self.snapshot()
                raise FaultError(latched_text(snap), snap.faults) from None
            raise
        return self.snapshot()

    def reset(self) -> tuple[list, Snapshot]:
        """fault_reset: (the faults it cleared, the status after). Nothing
        latched: ([], status) without a request. The cause still present:
        FaultError naming what stays latched."""
        before = self.snapshot()
        if not before.latched:
            return [], before
        try:
            self.c.request("fault_reset")
        except DriveError as exc:
            if exc.code != pg.ErrorCode.CAUSE_PRESENT:
                raise
            after = self.snapshot()
            still = after.faults or before.faults
            raise FaultError(
                f"cannot clear {', '.join(still)}: its cause is still present (cause_present)",
                still,
            ) from None
        # the tick applies the reset: wait for it to show (briefly)
        end = time.monotonic() + 1.0
        after = self.snapshot()
        while after.latched and time.monotonic() < end:
            time.sleep(0.01)
            after = self.snapshot()
        return [f for f in before.faults if f not in after.faults], after

    def stop(self, timeout: float = 10.0) -> Snapshot:
        """Controlled stop (decelerate on the path, flush the queue), then wait for rest."""
        self.c.request("stop")
        return self.wait_rest(timeout)

    def estop(self) -> Snapshot:
        """Emergency stop now; returns the latched state once the axes are at rest."""
        self.c.request("estop")
        return self.wait_rest(5.0)

    # ---- motion -------------------------------------------------------------------

    def wait_rest(
        self, timeout: float = 10.0, on_sample: Optional[Callable[[Snapshot], None]] = None
    ) -> Snapshot:
        """Poll until not moving and every axis holds within REST_NM over REST_S.
        Polling is also the keep-alive of the drive's communication watchdog."""
        end = time.monotonic() + timeout
        snap = self.snapshot()
        held_since = None
        ref = snap.position_nm
        while True:
            if on_sample is not None:
                on_sample(snap)
            now = time.monotonic()
            if snap.state in MOVING_NAMES:
                held_since, ref = None, snap.position_nm
            elif max(abs(a - b) for a, b in zip(snap.position_nm, ref)) > REST_NM:
                held_since, ref = now, snap.position_nm
            elif held_since is None:
                held_since = now
            elif now - held_since >= REST_S:
                return snap
            if now > end:
                raise UserError(
                    f"the axes did not come to rest within {timeout:g} s (state {snap.state})"
                )
            time.sleep(POLL_S)
            snap = self.snapshot()

    def max_feed_nm_s(self, axis: int) -> int:
        return int(self.c.get_param(f"max_velocity.{AXIS_NAMES[axis]}"))

    def jog(
        self,
        axis: int,
        feed_nm_s: int,
        distance_nm: Optional[int] = None,
        to_nm: Optional[int] = None,
        timeout: Optional[float] = None,
    ) -> dict:
        """Move one axis by ``distance_nm`` or to ``to_nm`` (measured position,
        absolute) at ``feed_nm_s``, wait until the jog is done and the axis
        is at rest. Checks the axis and feed against the drive before moving
        (UsageError); a latched fault before or during the jog is a
        FaultError. On KeyboardInterrupt: controlled stop, wait for rest,
        re-raise."""
        self.check_axes(1 << axis)
        vmax = self.max_feed_nm_s(axis)
        if feed_nm_s > vmax:
            raise UsageError(
                f"--feed {feed_nm_s * 60 / NM_PER_MM:g} mm/min is above axis "
                f"{AXIS_NAMES[axis]}'s limit {vmax * 60 / NM_PER_MM:g} mm/min"
            )
        snap = self.ready_to_move()
        start = snap.position_nm[axis]
        if distance_nm is None:
            distance_nm = to_nm - start
        target = start + distance_nm
        if abs(target) >= POS_LIMIT_NM:
            raise UsageError(f"the jog would end beyond the drive's +-{POS_LIMIT_NM // 10**6} mm")
        t0 = time.monotonic()
        result = {
            "axis": AXIS_NAMES[axis],
            "start_mm": start / NM_PER_MM,
            "target_mm": target / NM_PER_MM,
            "feed_mm_min": feed_nm_s * 60 / NM_PER_MM,
        }
        if distance_nm != 0:
            if timeout is None:
                timeout = 10.0 + 3.0 * abs(distance_nm) / feed_nm_s
            done0 = snap.blocks_done
            try:
                self.c.request("jog", axis=axis, feed=feed_nm_s, distance=distance_nm)
                snap = self._wait_jog(done0, t0 + timeout)
            except KeyboardInterrupt:
                self.stop()
                raise
        end = snap.position_nm[axis]
        result.update(
            {
                "end_mm": end / NM_PER_MM,
                "error_um": (end - target) / 1000,
                "elapsed_s": time.monotonic() - t0,
                "position_mm": {
                    AXIS_NAMES[i]: p / NM_PER_MM for i, p in enumerate(snap.position_nm)
                },
                "state": snap.state,
            }
        )
        return result

    def _wait_jog(self, done0: int, deadline: float) -> Snapshot:
        def check(s: Snapshot) -> None:
            if s.latched:
                raise FaultError(
                    f"jog stopped by a fault: {', '.join(s.faults) or s.state} at "
                    f"{s.position_text()} mm; `contour reset` clears it",
                    s.faults,
                )

        sent = time.monotonic()
        snap = self.snapshot()
        # the queued jog makes the drive "running" at once; the grace covers a
        # drive that reports it a poll late
        while snap.state in ("running", "stopping") or (
            snap.blocks_done == done0 and time.monotonic() - sent < 0.2
        ):
            check(snap)
            if time.monotonic() > deadline:
                self.stop()
                raise UserError(f"the jog did not finish in time (state {snap.state}): stopped")
            time.sleep(POLL_S)
            snap = self.snapshot()
        return self.wait_rest(max(1.0, deadline - time.monotonic()), on_sample=check)

    # ---- homing -------------------------------------------------------------------

    def home(self, mask: int, params: HomeParams, timeout: Optional[float] = None) -> dict:
        """Home the axes of ``mask`` (the drive's sequence: switch, back-off,
        index; docs/operating.md, Homing), wait until the drive is ready and
        at rest, return the homed axes and their positions. A fault before or
        during homing: FaultError naming it; the drive refusing (moving,
        disabled): UserError. On KeyboardInterrupt: controlled stop (aborts
        homing), wait for rest, re-raise."""
        self.check_axes(mask)
        for a in range(self.axes):
            if mask & (1 << a) and params.search_nm_s > self.max_feed_nm_s(a):
                limit = self.max_feed_nm_s(a) * 60 / NM_PER_MM
                raise UsageError(
                    f"--search-feed {params.search_nm_s * 60 / NM_PER_MM:g} mm/min is above "
                    f"axis {AXIS_NAMES[a]}'s limit {limit:g} mm/min"
                )
        snap = self.ready_to_move()
        if timeout is None:
            # search, back-off and index phases at their feeds, plus ramps and margin
            timeout = (
                15.0
                + params.max_distance_nm / params.search_nm_s
                + 2.0 * params.max_distance_nm / params.latch_nm_s
            )
        t0 = time.monotonic()
        home_pos = [params.home_pos_nm[i] if i < len(params.home_pos_nm) else 0 for i in range(4)]
        try:
            self.c.request(
                "home",
                axis_mask=mask,
                negative_mask=mask if params.negative else 0,
                index_mask=mask if params.index else 0,
                search_feed=params.search_nm_s,
                latch_feed=params.latch_nm_s,
                max_distance=params.max_distance_nm,
                home_pos=home_pos,
            )
        except DriveError as exc:
            if exc.code == pg.ErrorCode.FAULTED:
                s2 = self.snapshot()
                raise FaultError(latched_text(s2), s2.faults) from None
            if exc.code in (pg.ErrorCode.BUSY, pg.ErrorCode.DISABLED):
                raise UserError(f"the drive refused homing: {exc}") from None
            raise
        try:
            snap = self._wait_home(t0 + timeout)
        except KeyboardInterrupt:
            self.stop()
            raise
        names = [AXIS_NAMES[a] for a in range(self.axes) if mask & (1 << a)]
        shift = self.c.status()["home_shift"]
        missing = [n for n in names if n not in (snap.homed or [])]
        if missing:
            raise UserError(
                f"homing ended without homing {', '.join(missing)} (state {snap.state})"
            )
        return {
            "homed_axes": names,
            "position_mm": {AXIS_NAMES[i]: p / NM_PER_MM for i, p in enumerate(snap.position_nm)},
            "shift_um": {
                AXIS_NAMES[a]: shift[a] / 1000 for a in range(self.axes) if mask & (1 << a)
            },
            "elapsed_s": time.monotonic() - t0,
            "state": snap.state,
        }

    def _wait_home(self, deadline: float) -> Snapshot:
        def check(s: Snapshot) -> None:
            if s.latched:
                raise FaultError(
                    f"homing stopped by a fault: {', '.join(s.faults) or s.state} at "
                    f"{s.position_text()} mm; `contour reset` clears it",
                    s.faults,
                )

        snap = self.snapshot()
        while snap.state in MOVING_NAMES:
            check(snap)
            if time.monotonic() > deadline:
                self.stop()
                raise UserError(f"homing did not finish in time (state {snap.state}): stopped")
            time.sleep(POLL_S)
            snap = self.snapshot()
        check(snap)
        return self.wait_rest(max(1.0, deadline - time.monotonic()), on_sample=check)


@dataclass
class HomeParams:
    """The homing request's parameters, drive units (see the `home` message)."""

    search_nm_s: int
    latch_nm_s: int
    max_distance_nm: int
    negative: bool = True  # the switches are toward negative positions
    index: bool = True  # reference on the encoder index after the switch edge
    home_pos_nm: tuple = (0, 0, 0, 0)  # position at the reference point, per axis
