"""The reader's results: :class:`GcodeError`, :class:`Skipped`, :class:`Program`,
and :class:`Columns`, the compact builder of a program's columns.

Columns grow in :mod:`array` buffers (8 bytes a coordinate, not a Python
float object each) and become NumPy arrays without a copy. Columns that
only arcs or dwells use are stored sparsely while reading and are dense in
the :class:`Program` only when the program has such rows; otherwise they
are read-only broadcast views of one value, which cost no memory.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field

import numpy as np

from contour.errors import FileLineError

# Beyond this a position is no machine's (and squares of it overflow).
MAX_COORDINATE = 1e12


class GcodeError(FileLineError):
    """A G-code error at ``file:line``; nothing is estimated or run."""


@dataclass
class Skipped:
    """One kind of word reported (not interpreted, or interpreted with an
    assumption the user should know)."""

    kind: str
    first_line: int
    count: int = 1
    note: str = ""

    def as_dict(self) -> dict:
        return {
            "kind": self.kind,
            "first_line": self.first_line,
            "count": self.count,
            "note": self.note,
        }


@dataclass
class Program:
    """Motion and dwell blocks of one G-code file, in columns.

    Row i is one block. ``end`` holds the end point in machine coordinates
    (X Y Z mm, A B C degrees, after units and offsets); the start of row i
    is the end of row i-1 (``start`` for row 0); ``feed`` is mm/min (NaN for
    rapids and dwells); ``centre`` the arc centre (mm, machine coordinates,
    NaN off arcs), ``plane`` 0/1/2 for G17/G18/G19, ``turns`` the extra full
    turns of an arc; ``exact_stop`` is true when the block ends in an exact
    stop (G60/G61 modal or G9); ``dwell_s`` the dwell of a G4 row; ``line``
    the 1-based source line. ``centre``, ``plane``, ``turns`` and
    ``dwell_s`` may be read-only views when the program has no arc or dwell.
    """

    path: str
    start: np.ndarray
    kind: np.ndarray
    end: np.ndarray
    feed: np.ndarray
    centre: np.ndarray
    plane: np.ndarray
    turns: np.ndarray
    exact_stop: np.ndarray
    dwell_s: np.ndarray
    line: np.ndarray
    lines_read: int
    skipped: dict = field(default_factory=dict)
    substituted_feeds: int = 0

    def __len__(self) -> int:
        return int(self.kind.shape[0])

    def skipped_list(self) -> list[Skipped]:
        return sorted(self.skipped.values(), key=lambda s: (s.first_line, s.kind))


class Columns:
    """Rows appended by the interpreter; ``program()`` hands them over."""

    def __init__(self):
        self.kind = array("b")
        self.end = array("d")
        self.feed = array("d")
        self.stop = array("b")
        self.line = array("i")
        self.arc_row = array("q")
        self.arc_centre = array("d")
        self.arc_plane = array("b")
        self.arc_turns = array("q")
        self.dwell_row = array("q")
        self.dwell = array("d")

    def __len__(self) -> int:
        return len(self.kind)

    def add(self, kind, target, feed, stop, line) -> None:
        self.kind.append(kind)
        self.end.extend(target)
        self.feed.append(feed)
        self.stop.append(stop)
        self.line.append(line)

    def add_arc(self, kind, target, feed, stop, line, centre, plane, turns) -> None:
        self.arc_row.append(len(self.kind))
        self.arc_centre.extend(centre)
        self.arc_plane.append(plane)
        self.arc_turns.append(turns)
        self.add(kind, target, feed, stop, line)

    def add_dwell(self, target, seconds, stop, line) -> None:
        self.dwell_row.append(len(self.kind))
        self.dwell.append(seconds)
        self.add(4, target, float("nan"), stop, line)

    def split(self, rows: int):
        """(the first ``rows`` rows, the rest) as two new builders."""
        head, tail = Columns(), Columns()
        for name, width in (("kind", 1), ("end", 6), ("feed", 1), ("stop", 1), ("line", 1)):
            col = getattr(self, name)
            getattr(head, name).extend(col[: rows * width])
            getattr(tail, name).extend(col[rows * width :])
        for part, keep in ((head, lambda r: r < rows), (tail, lambda r: r >= rows)):
            shift = 0 if part is head else rows
            for j, r in enumerate(self.arc_row):
                if keep(r):
                    part.arc_row.append(r - shift)
                    part.arc_centre.extend(self.arc_centre[3 * j : 3 * j + 3])
                    part.arc_plane.append(self.arc_plane[j])
                    part.arc_turns.append(self.arc_turns[j])
            for j, r in enumerate(self.dwell_row):
                if keep(r):
                    part.dwell_row.append(r - shift)
                    part.dwell.append(self.dwell[j])
        return head, tail

    def program(self, path, start, lines_read, skipped, substituted) -> Program:
        n = len(self.kind)
        end = np.frombuffer(self.end, dtype=float).reshape(n, 6) if n else np.zeros((0, 6))
        if n and not (end.min() > -MAX_COORDINATE and end.max() < MAX_COORDINATE):
            row = int(np.argmax(~(np.abs(end) < MAX_COORDINATE).all(axis=1)))
            raise GcodeError(
                path,
                int(self.line[row]),
                "coordinate out of range "
                f"(a machine position beyond {MAX_COORDINATE:g} mm or degrees)",
            )
        if self.arc_row:
            rows = np.frombuffer(self.arc_row, dtype=np.int64)
            centre = np.full((n, 3), np.nan)
            centre[rows] = np.frombuffer(self.arc_centre, dtype=float).reshape(-1, 3)
            plane = np.zeros(n, dtype=np.int8)
            plane[rows] = np.frombuffer(self.arc_plane, dtype=np.int8)
            turns = np.zeros(n, dtype=np.int32)
            turns[rows] = np.frombuffer(self.arc_turns, dtype=np.int64)
        else:
            centre = np.broadcast_to(np.full(3, np.nan), (n, 3))
            plane = np.broadcast_to(np.int8(0), (n,))
            turns = np.broadcast_to(np.int32(0), (n,))
        if self.dwell_row:
            rows = np.frombuffer(self.dwell_row, dtype=np.int64)
            dwell = np.zeros(n)
            dwell[rows] = np.frombuffer(self.dwell, dtype=float)
        else:
            dwell = np.broadcast_to(np.float64(0.0), (n,))
        return Program(
            path=path,
            start=np.array(start, dtype=float),
            kind=np.frombuffer(self.kind, dtype=np.int8) if n else np.zeros(0, np.int8),
            end=end,
            feed=np.frombuffer(self.feed, dtype=float) if n else np.zeros(0),
            centre=centre,
            plane=plane,
            turns=turns,
            exact_stop=np.frombuffer(self.stop, dtype=np.bool_) if n else np.zeros(0, bool),
            dwell_s=dwell,
            line=np.frombuffer(self.line, dtype=np.int32) if n else np.zeros(0, np.int32),
            lines_read=lines_read,
            skipped=skipped,
            substituted_feeds=substituted,
        )
