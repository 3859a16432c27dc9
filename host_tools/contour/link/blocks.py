"""G-code to drive blocks, checked against what the drive and its protocol take.

:func:`blocks_from_gcode` yields the drive blocks of a G-code file in order
(arcs split by the reader within a chord tolerance, dwells as dwell blocks),
reading the file chunk by chunk (:func:`contour.program.chunks`), each block
with its estimated time from the host build of the drive's planner
(:mod:`contour.planner`) with the drive's profile (:attr:`DriveLimits.profile`:
the planner parameters read from the drive; the drive's defaults, the
continuous S-curve, where none is given). The estimate is what ``contour run``
shows (progress bar, ETA, "estimated" in its report) and what its stall check
allows a queued block. A block the planner refuses is refused with its line,
never estimated another way. Without the host library (the reader runs
without it too) the estimate is length / feed, rapids at the profile's
lowest axis limit, and the report says so.

Every block is checked as it is built, so that one pass over the file
(:func:`check_gcode`) finds everything the drive would refuse before the
first block is sent, and a second pass streams (``contour run``, ``contour
sim run``). Refused with ``file:line``:

- a value that does not fit the protocol: a target beyond +-2^40 nm (the
  soft-limit parameters' range, 1099 m), a block longer than 2^40 nm, a feed
  outside 1000..2^32-1 nm/s (0.06..257698 mm/min), a dwell over 3600 s;
- a target outside the drive's soft limits (:class:`DriveLimits`) on an
  axis the block moves (an arc: each of its chords, so its bulge too);
- motion of a rotary axis (A B C): the drive has linear axes only.

A feed above the drive's velocity limits along the block's direction is not
refused (the drive caps it, as a control does); the report says so once.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Optional

import numpy as np

from contour import protocol_gen as pg
from contour.errors import UserError
from contour.planner import BlockRefused, Planner, PlannerProfile
from contour.program import Report, chunks

NM_PER_MM = 1_000_000
# PROTO_RAPID_FEED_NM_S (proto_dispatch.h): the feed the drive queues a rapid
# at; its planner holds each axis to its velocity limit
RAPID_FEED_NM_S = 4_000_000_000
RAPID_MM_MIN = RAPID_FEED_NM_S * 60 / NM_PER_MM

POS_MAX_NM = 1 << 40  # soft_limit_min/max range, and SC_LEN_MAX for one block
FEED_MIN_NM_S = 1000  # the planner's lowest feed
FEED_MAX_NM_S = (1 << 32) - 1  # u32 feed field (and SC_V_LIMIT)
DWELL_MAX_MS = 3_600_000  # PROTO_DWELL_MAX_MS


@dataclass
class Block:
    kind: int  # pg.BlockKind
    target_nm: tuple  # 3 ints
    feed_nm_s: int  # line: nm/s; dwell: ms
    exact_stop: bool
    est_s: float
    line: int


@dataclass
class DriveLimits:
    """What a drive takes beyond the protocol: per axis soft limits (nm,
    None where off) and velocity limits (nm/s); and the profile its planner
    runs, for the time estimate (None: the drive's defaults)."""

    soft_min_nm: tuple = (None, None, None)
    soft_max_nm: tuple = (None, None, None)
    max_velocity_nm_s: tuple = (None, None, None)
    profile: Optional[PlannerProfile] = None

    @classmethod
    def read(cls, client, axes: int = 3) -> DriveLimits:
        """The limits and planner profile of a connected drive (its
        parameters)."""
        lo, hi, vmax = [], [], []
        for a in range(3):
            if a >= axes:
                lo.append(None)
                hi.append(None)
                vmax.append(None)
                continue
            ax = "xyza"[a]
            mn = client.get_param(f"soft_limit_min.{ax}")
            mx = client.get_param(f"soft_limit_max.{ax}")
            on = mn < mx  # off while min >= max
            lo.append(mn if on else None)
            hi.append(mx if on else None)
            vmax.append(client.get_param(f"max_velocity.{ax}"))
        profile = PlannerProfile.from_params(client.get_param, axes=max(1, min(axes, 3)))
        return cls(tuple(lo), tuple(hi), tuple(vmax), profile)


@dataclass
class Checked:
    """What the first pass found: blocks, estimated time, the report."""

    blocks: int
    est_s: float
    dwell_s: float
    end_nm: tuple
    report: Report


def _mm(nm: int) -> str:
    return f"{nm / NM_PER_MM:.6g}"


def check_position(where: str, axis: int, v_mm: float) -> None:
    """Refuse a target beyond the drive's position range (``estimate``
    refuses the same)."""
    nm = v_mm * NM_PER_MM
    if not (math.isfinite(nm) and abs(nm) <= POS_MAX_NM):
        raise UserError(
            f"{where}: {'XYZ'[axis]} target {v_mm:g} mm is out of range "
            f"(|position| <= {POS_MAX_NM / NM_PER_MM:.6f} mm)"
        )


def _estimate(planner, seg, feed, dwell, start_mm) -> tuple:
    """Planned time of each segment and None; or (None, (i, reason)) when
    the planner refuses segment i (the caller refuses its line; i None when
    the planner names no block). `planner` (float, no host library): the
    plain estimate, length / feed with rapids at that speed (mm/s)."""
    if not isinstance(planner, Planner):
        f = np.where(seg.rapid, planner * 60.0, feed)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.nan_to_num(seg.length / (f / 60.0)) + dwell, None
    try:
        res = planner.estimate(
            seg.end,
            np.where(dwell > 0, 1.0, feed),
            exact_stop=seg.exact_stop,
            dwell_s=dwell,
            start_mm=tuple(start_mm),
        )
    except BlockRefused as exc:
        return None, ((exc.index if exc.index < len(seg) else None), exc.reason)
    except UserError as exc:
        return None, (None, str(exc))
    return np.asarray(res.blocks["t_total_s"], dtype=float), None


NO_LIBRARY = "plain time estimate"


def _planner(limits: Optional[DriveLimits], report: Optional[Report] = None):
    """The planner of the drive's profile; without the host library (the
    reader runs without it too: docs/fast-paths.md) the speed rapids are
    estimated at (the profile's lowest axis limit, mm/s) and a note."""
    from contour import native

    profile = limits.profile if limits is not None and limits.profile is not None else None
    profile = PlannerProfile() if profile is None else profile
    try:
        native.load()
    except (UserError, OSError) as exc:
        if report is not None:
            report.note(NO_LIBRARY, 0, f"length / feed, no planner: {exc}")
        return float(min(profile.v_max_mm_s))
    try:
        return Planner(profile)
    except UserError as exc:
        raise UserError(f"job time estimate: {exc}") from None


def blocks_from_gcode(
    path: str,
    start_mm=(0.0, 0.0, 0.0),
    chord_mm: float = 0.001,
    default_feed: Optional[float] = None,
    limits: Optional[DriveLimits] = None,
    report: Optional[Report] = None,
    tool_table=None,
) -> Iterator[Block]:
    """Drive blocks of `path`, checked one by one (see the module doc);
    `report` (if given) collects the reader's report and the notes."""
    from contour import gcode

    planner = _planner(limits, report)
    start = [float(v) for v in start_mm][:3]
    prev = tuple(int(round(v * NM_PER_MM)) for v in start)
    vmax = None
    if limits is not None and all(v is not None for v in limits.max_velocity_nm_s):
        vmax = np.array(limits.max_velocity_nm_s, dtype=float)
    for prog in chunks(
        path, default_feed=default_feed, start=start + [0.0, 0.0, 0.0], tool_table=tool_table
    ):
        if report is not None:
            report.take(prog)
        seg = gcode.segments(prog, chord_mm)
        n = len(seg)
        if n == 0:
            continue
        is_dwell = prog.kind[seg.block] == gcode.DWELL
        feed = np.where(seg.rapid, RAPID_MM_MIN, seg.feed)
        dwell = np.where(is_dwell, seg.dwell_s, 0.0)
        est, refused = _estimate(planner, seg, feed, dwell, seg.start[0])
        moved_rot = np.any(np.abs(seg.rotary) > 1e-9, axis=1)
        fast = None
        if refused is None:
            fast = _fast(path, seg, is_dwell, feed, est, moved_rot, prev, limits, vmax, report)
        if fast is None:  # something to refuse in this chunk: block by block, in order
            if refused is not None:  # the checks name the line if they refuse it too
                est = np.full(n, np.nan)
            prev = yield from _one_by_one(
                path, seg, is_dwell, feed, est, moved_rot, prev, limits, vmax, report
            )
            if refused is not None:
                i, reason = refused
                where = path if i is None else f"{path}:{int(seg.line[i])}"
                raise UserError(f"{where}: the drive's planner refuses it: {reason}")
            continue
        yield from fast
        if fast:
            prev = fast[-1].target_nm
        del fast


def _fast(path, seg, is_dwell, feed, est, moved_rot, prev, limits, vmax, report):
    """The blocks of one chunk of segments, checked as arrays; None if a
    segment must be refused (then :func:`_one_by_one` says which and why)."""
    n = len(seg)
    moves = ~is_dwell
    with np.errstate(invalid="ignore", over="ignore"):
        end_nm = seg.end * NM_PER_MM
        bad = moves & ~np.all(np.abs(end_nm) <= POS_MAX_NM, axis=1)
        bad |= moves & moved_rot
        if np.any(bad):
            return None
        tgt = np.rint(end_nm)
        d = tgt - np.vstack([np.array(prev, dtype=float)[None, :], tgt[:-1]])
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        bad |= moves & (length > POS_MAX_NM)
        if limits is not None:
            for a in range(3):
                lo, hi = limits.soft_min_nm[a], limits.soft_max_nm[a]
                if lo is not None:
                    bad |= moves & (d[:, a] != 0) & ((tgt[:, a] < lo) | (tgt[:, a] > hi))
        lin = moves & ~seg.rapid
        f_nm = feed * (NM_PER_MM / 60.0)
        bad |= lin & ~((f_nm >= FEED_MIN_NM_S) & (f_nm <= FEED_MAX_NM_S))
        ms = np.rint(seg.dwell_s * 1000.0)
        bad |= is_dwell & (ms > DWELL_MAX_MS)
    if np.any(bad):
        return None
    if vmax is not None and report is not None:
        sel = lin & (length > 0)
        if np.any(sel):
            u = np.abs(d[sel]) / length[sel, None]
            with np.errstate(divide="ignore"):
                cap = np.min(np.where(u > 0, vmax / u, np.inf), axis=1)
            over = f_nm[sel] > cap * (1 + 1e-9)
            if np.any(over):
                k = int(np.argmax(over))
                line = int(seg.line[np.nonzero(sel)[0][k]])
                report.note(
                    "feed capped",
                    line,
                    "feed above the drive's axis velocity limits on this path: "
                    f"runs at {cap[k] * 60 / NM_PER_MM:.0f} mm/min here",
                )
                report.items["feed capped"].count += int(np.count_nonzero(over)) - 1
    ti = tgt.astype(np.int64).tolist()
    lines = seg.line.tolist()
    stops = seg.exact_stop.tolist()
    ests = est.tolist()
    dw = is_dwell.tolist()
    rapid = seg.rapid.tolist()
    fi = np.maximum(1, np.rint(np.nan_to_num(f_nm))).astype(np.int64).tolist()
    msl = ms.astype(np.int64).tolist()
    out = []
    cur = tuple(prev)
    dwell_kind, rapid_kind, line_kind = pg.BlockKind.DWELL, pg.BlockKind.RAPID, pg.BlockKind.LINE
    for i in range(n):
        if dw[i]:
            if msl[i] > 0:
                out.append(Block(dwell_kind, cur, msl[i], False, ests[i], lines[i]))
            continue
        cur = tuple(ti[i])
        if rapid[i]:
            out.append(Block(rapid_kind, cur, 0, stops[i], ests[i], lines[i]))
        else:
            out.append(Block(line_kind, cur, fi[i], stops[i], ests[i], lines[i]))
    return out


def _one_by_one(path, seg, is_dwell, feed, est, moved_rot, prev, limits, vmax, report):
    """The blocks of one chunk checked one at a time: raises at the first
    segment the drive would refuse, with its line and reason; returns the
    last target."""
    n = len(seg)
    for i in range(n):
        line = int(seg.line[i])
        where = f"{path}:{line}"
        if is_dwell[i]:
            ms = int(round(float(seg.dwell_s[i]) * 1000))
            if ms > DWELL_MAX_MS:
                raise UserError(
                    f"{where}: dwell of {seg.dwell_s[i]:g} s does not fit the drive "
                    f"(at most {DWELL_MAX_MS // 1000} s per G4)"
                )
            if ms > 0:
                yield Block(pg.BlockKind.DWELL, prev, ms, False, float(est[i]), line)
            continue
        if moved_rot[i]:
            axes = "".join("ABC"[k] for k in range(3) if abs(float(seg.rotary[i, k])) > 1e-9)
            raise UserError(
                f"{where}: rotary axis motion ({' '.join(axes)}) is not supported by the "
                "drive (linear axes X Y Z only)"
            )
        target = []
        for a in range(3):
            v = float(seg.end[i, a])
            check_position(where, a, v)
            target.append(int(round(v * NM_PER_MM)))
        target = tuple(target)
        d = [t - p for t, p in zip(target, prev)]
        if math.sqrt(sum(float(x) * x for x in d)) > POS_MAX_NM:
            raise UserError(
                f"{where}: a move of {math.dist(target, prev) / NM_PER_MM:g} mm is longer "
                f"than one drive block may be ({_mm(POS_MAX_NM)} mm)"
            )
        if limits is not None:
            for a in range(3):
                lo, hi = limits.soft_min_nm[a], limits.soft_max_nm[a]
                if lo is None or d[a] == 0:
                    continue
                if not lo <= target[a] <= hi:
                    raise UserError(
                        f"{where}: {'XYZ'[a]} {_mm(target[a])} mm is outside the drive's "
                        f"soft limits {_mm(lo)}..{_mm(hi)} mm"
                    )
        if seg.rapid[i]:
            yield Block(
                pg.BlockKind.RAPID,
                target,
                0,
                bool(seg.exact_stop[i]),
                float(est[i]),
                line,
            )
        else:
            f = float(feed[i])
            if not (math.isfinite(f) and f > 0):
                raise UserError(f"{where}: no feed for this move")
            f_nm = f * NM_PER_MM / 60.0
            if not FEED_MIN_NM_S <= f_nm <= FEED_MAX_NM_S:
                raise UserError(
                    f"{where}: feed F{f:g} mm/min does not fit the drive "
                    f"({FEED_MIN_NM_S * 60 / NM_PER_MM:g}..{FEED_MAX_NM_S * 60 // NM_PER_MM} "
                    "mm/min)"
                )
            if vmax is not None and any(d):
                u = np.abs(np.array(d, dtype=float)) / math.sqrt(sum(float(x) * x for x in d))
                with np.errstate(divide="ignore"):
                    cap = float(np.min(np.where(u > 0, vmax / u, np.inf)))
                if f_nm > cap * (1 + 1e-9) and report is not None:
                    report.note(
                        "feed capped",
                        line,
                        "feed above the drive's axis velocity limits on this path: "
                        f"runs at {cap * 60 / NM_PER_MM:.0f} mm/min here",
                    )
            yield Block(
                pg.BlockKind.LINE,
                target,
                max(1, int(round(f_nm))),
                bool(seg.exact_stop[i]),
                float(est[i]),
                line,
            )
        prev = target
    return prev


def check_gcode(
    path: str,
    start_mm=(0.0, 0.0, 0.0),
    chord_mm: float = 0.001,
    default_feed: Optional[float] = None,
    limits: Optional[DriveLimits] = None,
    tool_table=None,
) -> Checked:
    """The first pass: every block built and checked, none kept."""
    report = Report()
    n = 0
    t = 0.0
    dw = 0.0
    end = tuple(int(round(v * NM_PER_MM)) for v in start_mm)
    for b in blocks_from_gcode(
        path, start_mm, chord_mm, default_feed, limits, report, tool_table=tool_table
    ):
        n += 1
        t += b.est_s
        if b.kind == pg.BlockKind.DWELL:
            dw += b.feed_nm_s / 1000.0
        end = b.target_nm
    return Checked(n, t, dw, end, report)
