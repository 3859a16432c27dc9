"""G-code reader: RS-274/NGC as LinuxCNC defines it, plus the Sinumerik words
of real CAM files. The policy and the table of every word: docs/gcode.md.

Every word is executed, reported once per kind (``Program.skipped``: words
that change nothing for a drive, or assumptions such as a work offset the
program does not set), or the program is refused before any motion with
``file:line: <feature> is not supported``. Malformed input is a
:class:`GcodeError` naming ``file:line``; nothing is skipped silently.

Pieces: :mod:`~contour.gcode.lexer` (text -> evaluated blocks, parameters,
expressions, O-words), :mod:`~contour.gcode.interp` and
:mod:`~contour.gcode.execute` (modal state, execution order),
:mod:`~contour.gcode.offsets` (coordinate systems in LinuxCNC's numbered
parameters), :mod:`~contour.gcode.cycles` (canned cycles),
:mod:`~contour.gcode.arcs` (arc geometry, chord bounds),
:mod:`~contour.gcode.segments` (straight segments for the estimators).

The result is a :class:`Program`: one row per motion or dwell, in compact
columns, positions in machine coordinates (mm, degrees). :func:`read_chunks`
yields a long program in pieces of bounded size.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Optional

from contour.errors import UserError
from contour.gcode.moves import (  # noqa: F401 - re-exported
    ARC_CCW,
    ARC_CW,
    DWELL,
    KIND_NAMES,
    LINEAR,
    RAPID,
)
from contour.gcode.program import GcodeError, Program, Skipped  # noqa: F401 - re-exported
from contour.gcode.segments import Segments, segments  # noqa: F401 - re-exported

INCH_MM = 25.4


def _chunks(path, default_feed, start, text, tool_table, rows) -> Iterator[Program]:
    from contour.gcode import fastscan, lexer
    from contour.gcode.interp import Interpreter

    if default_feed is not None and not (default_feed > 0 and math.isfinite(default_feed)):
        raise UserError(f"default feed must be a positive number, got {default_feed}")
    name = str(path)
    tools = None
    if tool_table is not None:
        from contour.gcode import tooltable

        tools = tooltable.load(tool_table)
    it = Interpreter(name, default_feed, start, tool_table=tools)
    start_pos = list(it.pos)

    def piece(cols, skipped) -> Program:
        nonlocal start_pos
        prog = cols.program(name, start_pos, it.lines_read, skipped, it.substituted)
        if len(prog):
            start_pos = [float(v) for v in prog.end[-1]]
        return prog

    def drain(lines, counted=False):
        src = lines if counted else it.count_lines(lines)
        for cols in it.run(lexer.blocks(src, it.params, it), rows):
            yield piece(cols, dict(it.skipped))
        it.finish()
        cols = it.cols
        while rows is not None and len(cols) > rows:
            head, cols = cols.split(rows)
            yield piece(head, dict(it.skipped))
        yield piece(cols, it.skipped)

    if text is not None:
        yield from drain(text.splitlines())
        return
    try:
        # Text with undecodable bytes kept as surrogates (the front end
        # refuses them with the line); lines cut at the front end's cap + 1
        # so that memory stays bounded whatever the file holds.
        fh = open(Path(path), encoding="utf-8", errors="surrogateescape")  # noqa: SIM115
    except OSError as exc:
        raise UserError(f"cannot read {name}: {exc.strerror}") from exc
    with fh:
        try:
            # Plain CAM lines in C when the host library is there (fastscan).
            fast = fastscan.source(fh, it, rows)
            if fast is not None:
                yield from drain(fast, counted=True)
                return
            yield from drain(iter(functools.partial(fh.readline, lexer.LINE_CAP + 1), ""))
        except OSError as exc:
            raise UserError(f"cannot read {name}: {exc.strerror}") from exc


def read(
    path,
    default_feed: Optional[float] = None,
    start=None,
    text: Optional[str] = None,
    tool_table=None,
) -> Program:
    """Read a G-code file (or ``text``, named ``path`` in messages).

    ``default_feed`` (mm/min) replaces feeds the reader cannot evaluate and
    is used before the first F word; without it those are errors. ``start``
    is the machine position before the program (X Y Z mm, A B C deg; the
    origin by default). ``tool_table``: a LinuxCNC tool table file (for
    ``G41``/``G42`` with ``D``).
    """
    (prog,) = _chunks(path, default_feed, start, text, tool_table, None)
    return prog


def read_chunks(
    path,
    rows: int = 65536,
    default_feed: Optional[float] = None,
    start=None,
    text: Optional[str] = None,
    tool_table=None,
) -> Iterator[Program]:
    """The program of ``path`` in pieces of at most ``rows`` rows; each
    piece's ``start`` is the end of the one before. The last piece's
    ``skipped`` is the report of the whole file; ``lines_read`` counts the
    lines read so far. A file with an error raises it when the reading gets
    there, after the pieces before it were yielded."""
    if not (isinstance(rows, int) and rows > 0):
        raise UserError(f"rows must be a positive integer, got {rows}")
    return _chunks(path, default_feed, start, text, tool_table, rows)
