"""Plain CAM lines in C: the G-code reader's fast path for the bulk of a file.

:class:`FastSource` reads the file in fixed-size pieces (no whole-file
buffer) and is the line iterator of the front end
(:class:`~contour.gcode.flow.Runner`). Where the front end streams plain
lines (top level, no loop or subroutine open), it hands it :data:`SCAN`
instead of a line; the runner passes that on as a block with the words
:data:`SCAN_WORDS`, and the interpreter, which has executed every line
before it, calls :meth:`FastSource.scan`. That runs ``gcode_scan`` of the
host library (``hil_sim/gcode_scan.h``) over the lines that follow: plain
``N.. G0/G1 X.. Y.. Z.. F..`` lines, the rows and state exactly as the
interpreter's plain-move path gives them, up to the first line it does not
take (any other word, comment, parameter, mode change, malformed number ...).
That line goes to the front end as usual, and the next one is offered to C
again.

The Python reader stays the reference: without the library (or with
``CONTOUR_GCODE_NATIVE=0``) the file is read line by line as before, and
``tests/python/test_gcode_fastscan.py`` compares both on generated files
bit for bit. docs/fast-paths.md lists this fast path.
"""

from __future__ import annotations

import ctypes
import os
import re
from array import array

from contour.gcode.lexer import LINE_CAP

PIECE = 1 << 20  # characters read from the file at a time
ROWS = 16384  # rows C writes before Python appends them to the columns
BACKOFF = 63  # most lines given to Python between two scans that take nothing
_NON_ASCII = re.compile(r"[^\x00-\x7f]")


class _Scan:
    """The sentinel in the line stream (not a line: ``isascii()`` is false
    and its length above the cap so that the runner's plain-line tests pass
    it by and it costs the plain loop nothing)."""

    __slots__ = ()

    def isascii(self) -> bool:
        return False

    def __len__(self) -> int:
        return LINE_CAP + 1  # not a plain line either way the runner tests it

    def __repr__(self) -> str:
        return "SCAN"


SCAN = _Scan()
SCAN_WORDS = [("SCAN", 0.0)]  # the words of the block that carries it


def library():
    """The host library when the fast path may be used, else None."""
    if os.environ.get("CONTOUR_GCODE_NATIVE", "1") == "0":
        return None
    from contour import native
    from contour.errors import UserError

    try:
        return native.load()
    except (UserError, OSError):
        return None


def source(fh, interp, rows=None):
    """A :class:`FastSource` over the text file ``fh``, or None without the
    library (the caller then reads lines as before)."""
    lib = library()
    if lib is None:
        return None
    return FastSource(fh, interp, lib, rows)


class FastSource:
    """Lines of a text file (as ``readline(LINE_CAP + 1)`` gives them) with
    :data:`SCAN` offered before each line; counts ``interp.lines_read``."""

    def __init__(self, fh, interp, lib, rows=None):
        from contour.native import GcodeScan

        self.read = fh.read
        self.interp = interp
        interp.fast_source = self
        self.lib = lib
        self.limit = rows or 0
        self.buf = ""
        self.bbuf = b""  # buf[boff:boff + len(bbuf)], all ASCII, encoded
        self.boff = 0
        self.pos = 0
        self.eof = False
        self.armed = True
        self.count = 0
        # Lines to give Python before SCAN is offered again: a file whose
        # lines C does not take (parameters, comments on every line) pays
        # for one scan every BACKOFF lines, not for one each line.
        self.wait = 0
        self.backoff = 0
        st = GcodeScan()
        self.st = st
        self.kind = array("b", bytes(ROWS))
        self.end = array("d", bytes(ROWS * 48))
        self.feeds = array("d", bytes(ROWS * 8))
        self.stops = array("b", bytes(ROWS))
        self.lines = array("i", bytes(ROWS * 4))
        self.arc_row = array("q", bytes(ROWS * 8))
        self.arc_centre = array("d", bytes(ROWS * 24))
        st.kind = self.kind.buffer_info()[0]
        st.end = self.end.buffer_info()[0]
        st.feeds = self.feeds.buffer_info()[0]
        st.stops = self.stops.buffer_info()[0]
        st.lines = self.lines.buffer_info()[0]
        st.arc_row = self.arc_row.buffer_info()[0]
        st.arc_centre = self.arc_centre.buffer_info()[0]
        self.st_ref = ctypes.byref(st)
        self.kind_b = memoryview(self.kind).cast("B")
        self.end_b = memoryview(self.end).cast("B")
        self.feeds_b = memoryview(self.feeds).cast("B")
        self.stops_b = memoryview(self.stops).cast("B")
        self.lines_b = memoryview(self.lines).cast("B")
        self.arc_row_b = memoryview(self.arc_row).cast("B")
        self.arc_centre_b = memoryview(self.arc_centre).cast("B")
        self.lines_taken = 0  # by C, for the profile in docs/fast-paths.md

    def __iter__(self):
        return self

    def _fill(self) -> bool:
        """Read the next piece; False at the end of the file."""
        if self.eof:
            return False
        more = self.read(PIECE)
        if not more:
            self.eof = True
            return False
        self.buf = self.buf[self.pos :] + more
        self.pos = 0
        self._segment()
        return True

    def _segment(self) -> None:
        """bbuf: the ASCII run of buf from pos (C reads only ASCII; a line
        with other characters goes to Python)."""
        buf = self.buf
        pos = self.pos
        if buf.isascii():  # O(1): CPython knows it
            self.bbuf = (buf[pos:] if pos else buf).encode("ascii")
        else:
            m = _NON_ASCII.search(buf, pos)
            end = len(buf) if m is None else m.start()
            self.bbuf = buf[pos:end].encode("ascii")
        self.boff = pos

    def __next__(self):
        if self.armed:
            self.armed = False
            it = self.interp
            if self.wait:
                self.wait -= 1  # backing off after scans that took nothing
            elif (
                it.comp is None
                and it.units_set
                and not it.ended
                and 0 <= it.motion <= 3
                and not (self.limit and len(it.cols) >= self.limit)
            ):
                return SCAN
        while True:
            buf = self.buf
            pos = self.pos
            nl = buf.find("\n", pos)
            if nl >= 0 or len(buf) - pos > LINE_CAP or not self._fill():
                break
        if nl < 0:
            if pos >= len(buf):
                raise StopIteration
            nl = len(buf) - 1
        stop = min(nl + 1, pos + LINE_CAP + 1)  # readline(LINE_CAP + 1)
        self.pos = stop
        self.count += 1
        self.interp.lines_read = self.count
        self.armed = True
        return buf[pos:stop]

    def scan(self, it, lineno: int) -> int:
        """Take the plain lines after ``lineno`` in C; the number of the
        last line taken. ``it``: the interpreter, in its plain-move state."""
        if not (it.comp is None and it.units_set and not it.ended and 0 <= it.motion <= 3):
            return lineno
        st = self.st
        cols = it.cols
        pos = it.pos
        origin = it.offsets.origin
        for i in range(6):
            st.pos[i] = pos[i]
            st.origin[i] = origin[i]
        st.scale = it.scale
        st.feed = it.feed
        st.motion = it.motion
        st.absolute = 1 if it.absolute else 0
        st.arc_abs = 1 if it.arc_absolute else 0
        st.plane = it.plane
        st.tol = 0.002 * it.scale + 1e-9  # Interpreter.arc
        st.gseen = 0
        st.stop = 1 if it.exact_stop_modal else 0
        st.line = lineno
        gcode_scan = self.lib.gcode_scan
        ref = self.st_ref
        limit = self.limit
        while True:
            cap = ROWS
            if limit:
                cap = min(cap, limit - len(cols))
                if cap <= 0:
                    break  # the interpreter splits the chunk at the next block
            st.rows = 0
            st.arcs = 0
            st.cap = cap
            st.row_base = len(cols)
            if self.pos >= self.boff + len(self.bbuf):
                self._segment()
            bbuf = self.bbuf
            boff = self.boff
            n = len(bbuf)
            self.pos = boff + gcode_scan(bbuf, n, self.pos - boff, ref)
            rows = st.rows
            if rows:
                cols.kind.frombytes(self.kind_b[:rows])
                cols.end.frombytes(self.end_b[: rows * 48])
                cols.feed.frombytes(self.feeds_b[: rows * 8])
                cols.stop.frombytes(self.stops_b[:rows])
                cols.line.frombytes(self.lines_b[: rows * 4])
                arcs = st.arcs
                if arcs:
                    cols.arc_row.frombytes(self.arc_row_b[: arcs * 8])
                    cols.arc_centre.frombytes(self.arc_centre_b[: arcs * 24])
                    cols.arc_plane.frombytes(bytes((st.plane,)) * arcs)
                    cols.arc_turns.frombytes(bytes(arcs * 8))
            if rows == cap:
                continue  # the row arrays were full
            # Stopped at a line it does not take (Python's), or at the end
            # of what is read so far (read on, unless the rest is not ASCII).
            if (
                bbuf.find(b"\n", self.pos - boff) >= 0
                or boff + n < len(self.buf)
                or not self._fill()
            ):
                break
        taken = st.line - lineno
        if taken:
            self.backoff = 0
        else:
            self.backoff = min(2 * self.backoff + 1, BACKOFF)
            self.wait = self.backoff
        self.lines_taken += taken
        self.count += taken
        it.lines_read = self.count
        it.pos = list(st.pos)
        it.feed = st.feed
        if st.gseen:
            it.motion = st.motion
            it.cycle.cancel()  # as every G0-G3 line does (idempotent here)
        return st.line
