"""One reader and one report for the commands that time or run a program.

``contour estimate``, ``contour run`` and ``contour sim run`` read a G-code
file only through :func:`chunks` (the reader's chunks in order, so that no
command holds a whole program) and print what was not executed, not
modelled, or adjusted through :class:`Report` (one text, one JSON form).

The report holds the reader's skipped words (:attr:`contour.gcode.Program.skipped`
of the last chunk: the full report) and the commands' own notes (a feed the
drive caps, rotary motion the estimate times with machine-axis kinematics),
each kind once with its first line and a count.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Optional

from contour import gcode
from contour.gcode import Skipped

CHUNK_ROWS = 65536


def chunks(
    path,
    default_feed: Optional[float] = None,
    start=None,
    rows: Optional[int] = None,
    tool_table=None,
) -> Iterator[gcode.Program]:
    """The program of `path` in chunks of at most `rows` blocks; each
    chunk's ``start`` is the previous chunk's end, the last chunk's
    ``skipped`` is the report of the whole file. `tool_table`: a LinuxCNC
    tool table file (``--tool-table``)."""
    rows = CHUNK_ROWS if rows is None else rows
    read_chunks = getattr(gcode, "read_chunks", None)
    if read_chunks is None:  # before the reader streams: one chunk
        yield gcode.read(path, default_feed=default_feed, start=start)
        return
    yield from read_chunks(
        path, rows=rows, default_feed=default_feed, start=start, tool_table=tool_table
    )


class Report:
    """Words reported once per kind: the reader's and the commands' own."""

    def __init__(self) -> None:
        self.items: dict[str, Skipped] = {}
        self.lines_read = 0

    def note(self, kind: str, line: int, note: str = "") -> None:
        s = self.items.get(kind)
        if s is None:
            self.items[kind] = Skipped(kind, int(line), 1, note)
        else:
            s.count += 1

    def take(self, program: gcode.Program) -> None:
        """Fold in a chunk's reader report (the last chunk's is complete)."""
        for kind, s in program.skipped.items():
            self.items[kind] = Skipped(s.kind, s.first_line, s.count, s.note)
        self.lines_read = max(self.lines_read, int(program.lines_read))

    def sorted(self) -> list[Skipped]:
        return sorted(self.items.values(), key=lambda s: (s.first_line, s.kind))

    def as_dicts(self) -> list[dict]:
        return [s.as_dict() for s in self.sorted()]

    def kinds(self) -> set:
        return set(self.items)

    def text(self) -> list[str]:
        """The report as printed by every command."""
        return report_text(self.as_dicts())


def report_text(items: list) -> list[str]:
    """Printed lines of a report given as :meth:`Report.as_dicts`."""
    if not items:
        return ["reported:    nothing"]
    out = ["reported (not executed, not modelled or adjusted), first line and count:"]
    for s in items:
        note = f"  ({s['note']})" if s["note"] else ""
        out.append(f"  {s['kind']:<16} line {s['first_line']:<6} x{s['count']}{note}")
    return out
