"""Straight segments of a program for the estimators (arcs split into chords)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contour.errors import UserError
from contour.gcode.arcs import ArcError, arc_points
from contour.gcode.moves import ARC_CCW, ARC_CW, RAPID
from contour.gcode.program import GcodeError, Program


@dataclass
class Segments:
    """Straight segments of a program (arcs split), in columns.

    ``start``/``end`` (n, 3) mm; ``rotary`` (n, 3) degrees moved on A B C;
    ``feed`` mm/min (NaN: rapid); ``rapid`` bool; ``exact_stop`` bool (the
    segment ends in a stop); ``dwell_s`` a dwell executed *after* the
    segment (a dwell row becomes a zero-length segment with ``dwell_s``);
    ``block`` the program row, ``line`` the source line.
    """

    start: np.ndarray
    end: np.ndarray
    rotary: np.ndarray
    feed: np.ndarray
    rapid: np.ndarray
    exact_stop: np.ndarray
    dwell_s: np.ndarray
    block: np.ndarray
    line: np.ndarray

    def __len__(self) -> int:
        return int(self.feed.shape[0])

    @property
    def delta(self) -> np.ndarray:
        return self.end - self.start

    @property
    def length(self) -> np.ndarray:
        return np.sqrt(np.einsum("ij,ij->i", self.delta, self.delta))


def segments(program: Program, chord_tolerance_mm: float = 0.001) -> Segments:
    """Straight segments of ``program``; arcs split so that no chord deviates
    from the arc by more than ``chord_tolerance_mm``. An arc that would need
    more than :data:`~contour.gcode.arcs.MAX_CHORDS` chords is a
    :class:`GcodeError` at its line."""
    if not chord_tolerance_mm > 0:
        raise UserError(f"chord tolerance must be positive, got {chord_tolerance_mm}")
    n = len(program)
    ends = program.end
    starts = np.empty_like(ends)
    if n:
        starts[0] = program.start
        starts[1:] = ends[:-1]
    arcs = np.nonzero((program.kind == ARC_CW) | (program.kind == ARC_CCW))[0]
    if arcs.size == 0:
        return Segments(
            start=np.ascontiguousarray(starts[:, :3]),
            end=np.ascontiguousarray(ends[:, :3]),
            rotary=ends[:, 3:] - starts[:, 3:],
            feed=program.feed,
            rapid=program.kind == RAPID,
            exact_stop=program.exact_stop,
            dwell_s=program.dwell_s,
            block=np.arange(n),
            line=program.line,
        )
    # Per row: how many pieces, then the arc points.
    pieces = np.ones(n, dtype=np.int64)
    arc_pts = {}
    for i in arcs:
        try:
            pts = arc_points(
                starts[i, :3],
                ends[i, :3],
                program.centre[i],
                int(program.plane[i]),
                program.kind[i] == ARC_CW,
                int(program.turns[i]),
                chord_tolerance_mm,
            )
        except ArcError as exc:
            raise GcodeError(program.path, int(program.line[i]), str(exc)) from None
        arc_pts[i] = pts
        pieces[i] = len(pts)
    total = int(pieces.sum())
    block = np.repeat(np.arange(n), pieces)
    seg_end = ends[block, :3].copy()
    first = np.cumsum(pieces) - pieces
    for i, pts in arc_pts.items():
        seg_end[first[i] : first[i] + len(pts)] = pts
    seg_start = np.empty_like(seg_end)
    if total:
        seg_start[0] = program.start[:3]
        seg_start[1:] = seg_end[:-1]
    rot = (ends[:, 3:] - starts[:, 3:]) / pieces[:, None]
    last = np.zeros(total, dtype=bool)
    last[first + pieces - 1] = True
    return Segments(
        start=seg_start,
        end=seg_end,
        rotary=rot[block],
        feed=program.feed[block],
        rapid=program.kind[block] == RAPID,
        exact_stop=program.exact_stop[block] & last,
        dwell_s=np.where(last, program.dwell_s[block], 0.0),
        block=block,
        line=program.line[block],
    )
