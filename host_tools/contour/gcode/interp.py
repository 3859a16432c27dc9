"""The interpreter: evaluated blocks (:mod:`contour.gcode.lexer`) -> rows of
a :class:`~contour.gcode.program.Program`, with the modal state and the
execution order of RS-274/NGC as LinuxCNC defines them.

Per block, in this order: messages, F, S T D H (reported), M codes
(reported or refused), G4 dwell, plane, units, cutter compensation, tool
length, coordinate system, path control, distance modes, retract mode,
then G10 / G28 / G30 / G92 family, then motion (G53 applies to it), then
M0 M1 M2 M30. One G code per modal group and one M code per group per
line, at most one user of the axis words: otherwise an error, as in
LinuxCNC. See docs/gcode.md for the table of every word.

Positions are kept in machine coordinates (mm, degrees); program
coordinates are machine minus :attr:`Offsets.origin`, in program units.
Plain motion lines (``N.. G0/G1 X.. Y.. Z.. F..``) take a fast path.
"""

from __future__ import annotations

import math

from contour.gcode import arcs
from contour.gcode.cycles import CycleState
from contour.gcode.execute import BlockExecutor
from contour.gcode.fastscan import SCAN_WORDS
from contour.gcode.motion import MotionExecutor
from contour.gcode.moves import ARC_CCW, ARC_CW, PLANE_AXES
from contour.gcode.offsets import SYSTEM_KEYS, Offsets
from contour.gcode.params import Params
from contour.gcode.program import Columns, GcodeError, Skipped

INCH_MM = 25.4
AXES = "XYZABC"
_NAN = math.nan


class MachineParams(Params):
    """Parameters with #5420-#5428 (the current position in program
    coordinates and units) served by the interpreter; they are read-only."""

    position = None  # installed by the interpreter: callable(index) -> float

    def get(self, key, line):
        if type(key) is int and 5420 <= key <= 5428 and self.position is not None:
            return self.position(key - 5420)
        return super().get(key, line)

    def set(self, key, value, line=0):
        if type(key) is int and 5420 <= key <= 5428:
            raise self._error(line, f"#{key} (current position) is read-only")
        super().set(key, value, line)


class Interpreter(BlockExecutor, MotionExecutor):
    """State of one read; also the :class:`~contour.gcode.lexer.Reporter`."""

    def __init__(self, path, default_feed, start, params=None, tool_table=None):
        self.path = path
        self.default_feed = default_feed
        self.skipped: dict[str, Skipped] = {}
        self.substituted = 0
        self.params = params if params is not None else MachineParams()
        self.params.system = self.system_param
        if isinstance(self.params, MachineParams):
            self.params.position = self.program_position
        self.params.rep = self
        self.offsets = Offsets(self.params)
        self.tools = tool_table or {}
        # Modal state (LinuxCNC start-up: G17 G21 (here) G40 G49 G54 G80 G90 G94 G64).
        self.motion = 80
        self.plane = 0
        self.scale = 1.0
        self.units_set = False
        self.absolute = True
        self.arc_absolute = False
        self.exact_stop_modal = False
        self.before_cycle832 = None
        self.feed = _NAN  # mm/min
        self.cycle = CycleState()
        self.comp = None  # cutter compensation, from G41/G42 until its exit move
        self.selected_tool = 0
        self.current_tool = 0
        pos = [0.0] * 6
        if start is not None:
            for i, v in enumerate(start):
                pos[i] = float(v)
        self.pos = pos
        self.start = list(pos)
        self.cols = Columns()
        self.ended = False
        self.lines_read = 0

    # ---- the Reporter of seam 1 ------------------------------------------------
    def skip(self, kind: str, line: int, note: str = "") -> None:
        s = self.skipped.get(kind)
        if s is None:
            self.skipped[kind] = Skipped(kind, line, 1, note)
        else:
            s.count += 1

    def error(self, line: int, message: str) -> GcodeError:
        return GcodeError(self.path, line, message)

    def refuse(self, line: int, feature: str) -> GcodeError:
        return GcodeError(self.path, line, f"{feature} is not supported")

    # ---- predefined parameters --------------------------------------------------
    def program_position(self, i: int) -> float:
        """Current position on axis i (0..8) in program coordinates and units."""
        if i > 5:
            return 0.0
        v = self.pos[i] - self.offsets.origin[i]
        return v / self.scale if i < 3 else v

    def system_param(self, name: str):
        if len(name) == 2 and name[1] in "xyzabc":
            return self.program_position(AXES.index(name[1].upper()))
        if name in ("_u", "_v", "_w"):
            return 0.0
        v = _SYSTEM_NAMES.get(name)
        return None if v is None else v(self)

    # ---- the main loop ------------------------------------------------------------
    def count_lines(self, lines):
        """Pass lines through, counting them (Program.lines_read)."""
        n = 0
        for n, text in enumerate(lines, 1):  # noqa: B007 - n is read after the loop
            self.lines_read = n
            yield text
        self.lines_read = n

    def run(self, blocks, rows=None):  # noqa: C901 - the hot loop, inlined on purpose
        """Execute ``blocks``; yields full columns each time ``rows`` rows are
        ready (never when ``rows`` is None), the caller takes them."""
        cols = self.cols
        limit = rows or 0
        fast, motion, feed, scale, absolute, origin, stop = self._modes()
        k_add, e_add, f_add, s_add, l_add = (
            cols.kind.append,
            cols.end.extend,
            cols.feed.append,
            cols.stop.append,
            cols.line.append,
        )
        for b in blocks:
            if limit and len(cols.kind) >= limit:
                while len(cols) >= limit:
                    head, cols = cols.split(limit)
                    yield head
                self.cols = cols
                k_add, e_add, f_add, s_add, l_add = (
                    cols.kind.append,
                    cols.end.extend,
                    cols.feed.append,
                    cols.stop.append,
                    cols.line.append,
                )
            words = b.words
            if fast and not b.messages:
                x = y = z = f = g = None
                for letter, value in words:
                    if letter == "X" and x is None:
                        x = value
                    elif letter == "Y" and y is None:
                        y = value
                    elif letter == "Z" and z is None:
                        z = value
                    elif letter == "F" and f is None:
                        f = value
                    elif letter == "G" and g is None:
                        g = value
                    elif letter != "N":
                        break
                else:
                    # Plain straight moves: the bulk of CAM output.
                    if g is not None and g != motion:
                        if g != 0 and g != 1:
                            self.block(b.line, words, b.messages, b.call_args)
                            fast, motion, feed, scale, absolute, origin, stop = self._modes()
                            continue
                        motion = self.motion = int(g)
                        self.cycle.cancel()
                    if f is not None:
                        if f <= 0:
                            raise self.error(b.line, f"feed must be positive, got F{f:g}")
                        feed = self.feed = f * scale
                    if motion == 0 or (motion == 1 and feed == feed):
                        if x is None and y is None and z is None:
                            continue
                        target = self.pos[:]
                        if absolute:
                            if x is not None:
                                target[0] = x * scale + origin[0]
                            if y is not None:
                                target[1] = y * scale + origin[1]
                            if z is not None:
                                target[2] = z * scale + origin[2]
                        else:
                            if x is not None:
                                target[0] += x * scale
                            if y is not None:
                                target[1] += y * scale
                            if z is not None:
                                target[2] += z * scale
                        if motion:
                            k_add(1)
                            f_add(feed)
                        else:
                            k_add(0)
                            f_add(_NAN)
                        e_add(target)
                        s_add(stop)
                        l_add(b.line)
                        self.pos = target
                        continue
                    # G1 without a feed, G80 ...: the general path says what is wrong.
            elif self.ended:
                if words is not SCAN_WORDS:
                    self.skip("after M2/M30", b.line, "lines after the end of program")
                continue
            if words is SCAN_WORDS:
                # The plain lines that follow, in C (fastscan); b.line
                # tells the front end how far it read.
                b.line = self.fast_source.scan(self, b.line)
                fast, motion, feed, scale, absolute, origin, stop = self._modes()
                continue
            self.block(b.line, words, b.messages, b.call_args)
            fast, motion, feed, scale, absolute, origin, stop = self._modes()

    def _modes(self):
        """The state the fast path keeps in locals, after a general block."""
        return (
            self.comp is None and self.units_set and not self.ended,
            self.motion,
            self.feed,
            self.scale,
            self.absolute,
            self.offsets.origin,
            self.exact_stop_modal,
        )

    # ---- emitting rows -----------------------------------------------------------
    def emit(self, kind, target, feed, line, stop, centre=None, turns=0, dwell=0.0):
        if self.comp is not None:
            for mv in self.comp.push(
                self.make_move(kind, target, feed, line, stop, centre, turns, dwell)
            ):
                self.add_move(mv)
        else:
            self.add_row(kind, target, feed, line, stop, centre, turns, dwell)
        self.pos = list(target)

    def add_row(self, kind, target, feed, line, stop, centre, turns, dwell):
        if kind == 4:
            self.cols.add_dwell(target, dwell, stop, line)
        elif centre is not None:
            self.cols.add_arc(kind, target, feed, stop, line, centre, self.plane, turns)
        else:
            self.cols.add(kind, target, feed, stop, line)

    def add_move(self, mv):
        if mv.kind == 4:
            self.cols.add_dwell(mv.end, mv.dwell_s, mv.exact_stop, mv.line)
        elif mv.centre is not None:
            self.cols.add_arc(
                mv.kind, mv.end, mv.feed, mv.exact_stop, mv.line, mv.centre, mv.plane, mv.turns
            )
        else:
            self.cols.add(mv.kind, mv.end, mv.feed, mv.exact_stop, mv.line)

    def make_move(self, kind, target, feed, line, stop, centre, turns, dwell):
        from contour.gcode.moves import Move

        return Move(
            kind,
            tuple(self.pos),
            tuple(target),
            feed,
            line,
            None if centre is None else tuple(centre),
            self.plane,
            turns,
            stop,
            dwell,
        )

    def finish(self):
        """End of input: flush cutter compensation, final reports."""
        if self.comp is not None:
            for mv in self.comp.flush():
                self.add_move(mv)
            self.comp = None

    # ---- arcs ---------------------------------------------------------------------
    def arc(self, line, motion, target, ijk, r_word, p_word, stop):
        u, v = PLANE_AXES[self.plane]
        su, sv = self.pos[u], self.pos[v]
        eu, ev = target[u], target[v]
        turns = 0
        if p_word is not None:
            if p_word < 1 or p_word != int(p_word):
                raise self.error(line, f"arc turns P must be a positive integer, got {p_word:g}")
            if p_word > arcs.MAX_TURNS:
                raise self.error(line, f"arc turns P{p_word:g} above the limit of {arcs.MAX_TURNS}")
            turns = int(p_word) - 1
        tol = 0.002 * self.scale + 1e-9
        try:
            if ijk:
                names = (("I", "J"), ("K", "I"), ("J", "K"))[self.plane]
                for k in ijk:
                    if k not in names:
                        raise arcs.ArcError(
                            f"{k} word in a {('G17', 'G18', 'G19')[self.plane]} "
                            "arc (not an offset in this plane)"
                        )
                if r_word is not None:
                    raise arcs.ArcError("arc with both a radius (R) and a centre (I J K)")
                ou = ijk.get(names[0], 0.0) * self.scale
                ov = ijk.get(names[1], 0.0) * self.scale
                if self.arc_absolute:
                    o = self.offsets.origin
                    ou += o[u]
                    ov += o[v]
                cu, cv = arcs.centre_ijk(su, sv, eu, ev, ou, ov, self.arc_absolute, tol)
            elif r_word is not None:
                cu, cv = arcs.centre_r(su, sv, eu, ev, r_word * self.scale, motion == 3, tol)
            else:
                raise arcs.ArcError("arc without centre (I/J/K) or radius (R)")
        except arcs.ArcError as exc:
            raise self.error(line, str(exc)) from None
        centre = [_NAN, _NAN, _NAN]
        centre[u] = cu
        centre[v] = cv
        self.emit(ARC_CW if motion == 2 else ARC_CCW, target, self.feed, line, stop, centre, turns)

    # ---- reports ---------------------------------------------------------------
    def units_used(self, line):
        """A length is read before any G20/G21: millimetres, reported once."""
        if not self.units_set:
            self.units_set = True
            self.skip("G20/G21", line, "the program sets neither G20 nor G21: millimetres assumed")


def _ccomp(comp) -> float:
    if comp is None or not comp.active:
        return 400.0
    return 410.0 if comp.side > 0 else 420.0


_SYSTEM_NAMES = {
    "_metric": lambda it: 1.0 if it.scale == 1.0 else 0.0,
    "_imperial": lambda it: 1.0 if it.scale != 1.0 else 0.0,
    "_absolute": lambda it: 1.0 if it.absolute else 0.0,
    "_incremental": lambda it: 0.0 if it.absolute else 1.0,
    "_coord_system": lambda it: SYSTEM_KEYS[it.offsets.system - 1],
    "_motion_mode": lambda it: it.motion * 10.0,
    "_plane": lambda it: (170.0, 180.0, 190.0)[it.plane],
    "_ccomp": lambda it: _ccomp(it.comp),
    "_current_tool": lambda it: float(it.current_tool),
    "_selected_tool": lambda it: float(it.selected_tool),
    "_feed": lambda it: 0.0 if it.feed != it.feed else it.feed / it.scale,
    "_retract_r": lambda it: 1.0 if it.cycle.retract == 99 else 0.0,
    "_retract_old_z": lambda it: 1.0 if it.cycle.retract == 98 else 0.0,
}
