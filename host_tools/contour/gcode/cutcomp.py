"""Cutter radius compensation (G41 G42 G41.1 G42.1 G40) as LinuxCNC does it.

Interface (for the interpreter)::

    comp = CutterComp(error)              # error(line, message) -> exception to raise
    comp.on(side, radius_mm, plane, line) # G41/G41.1: side "left"; G42/G42.1: "right"
    comp.off(line)                        # G40
    comp.plane_change(plane, line)        # on G17/G18/G19 (an error while comp is on)
    out = comp.push(move)                 # every Move, in order -> the Moves to emit now
    out = comp.flush()                    # at the end of the program (and before M2/M30)

``push`` takes every canonical :class:`~contour.gcode.moves.Move` (rapids,
feeds, arcs, dwells), compensated or not, and returns the moves ready to
emit; it holds back the last in-plane move (with any out-of-plane moves
after it) until the next in-plane move decides the corner between them.
The moves returned are continuous (each starts where the one before ends)
and carry the line of the move they come from. ``Move.plane`` must be the
interpreter's current plane on every move (lines too): that is how a plane
change under compensation is caught. The attributes ``active`` (on),
``held`` (moves not yet released) and ``tool`` (the tool position, 6
floats, None before the first move) may be read. ``radius_mm`` is the tool
radius: half the diameter of the tool-table entry selected by ``D`` (or of
the current tool), or half of ``G41.1``/``G42.1``'s ``D``; a negative
radius swaps the side, as LinuxCNC does for a negative diameter.

The rules (``P`` the programmed corner, ``r`` the radius; the tool lies on
the left of the programmed path, looking along the motion, for G41):

- Planes: G17 (XY) and G18 (XZ, in the (Z, X) order of the arc sense, as
  LinuxCNC's lathe mode); G19 is refused. Changing plane while compensation
  is on is an error.
- Entry: the first in-plane move after G41/G42 must be straight (an arc is
  refused); it must be longer than ``r``; it ends at the programmed end
  moved by ``r`` perpendicular to the move, on the compensation side.
- Lines and arcs are offset by ``r`` on the compensation side; an arc is
  offset radially, its centre unchanged, so an arc with the tool inside
  (G41 with G3, G42 with G2) needs a radius larger than ``r``: "tool radius
  too big" otherwise.
- Corners, by the turn from the end tangent of one move to the start
  tangent of the next (tolerance 0.05 rad): a convex corner (turning away
  from the tool side, a reversal included) gets an arc of radius ``r``
  round ``P`` at the feed of the next move (a straight rapid when the next
  move is a rapid); a concave corner moves the end of the held move and
  the start of the next one to the intersection of the two offset paths
  (the one that shortens both); a reversal onto or off the outside of an
  arc counts as concave (the top of an "h"); a corner within the
  tolerance is joined straight.
- Gouging, as LinuxCNC checks it: when the end of the held move is set
  (at the next corner, at a convex corner before a line, and at G40), a
  line must not run against its programmed direction (the entry: against
  its offset direction) and an arc must not sweep more than programmed
  (+0.0254 rad); no intersection at a concave corner is an error too.
  Checked against LinuxCNC 2.9's rs274 (tests/gcode/lcnc_oracle.py) on
  2800 random programs: the same moves (to 3e-4 mm) or the same refusal,
  except exact tangencies that LinuxCNC's rounding refuses.
- Moves with no motion in the plane (Z only, dwells) keep the tool's
  in-plane position and pass through unchanged otherwise.
- Exit: after G40, the next move goes straight from the compensated
  position to its programmed end, in the plane too even if it is
  programmed along Z only; an arc there is refused.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Optional

from contour.gcode.moves import ARC_CCW, ARC_CW, DWELL, LINEAR, PLANE_AXES, RAPID, Move

SMALL = 0.05  # rad: LinuxCNC's TOLERANCE_CONCAVE_CORNER
_EPS = 1e-9  # mm: points closer than this are the same point
# rad: how much further than programmed a held arc may sweep once its end
# moves (LinuxCNC 2.9 as packaged in Debian 12, in mm mode; 0.001 in inch
# mode and in later versions).
ARC_SWEEP_SLACK = 0.0254
_PLANE_NAMES = ("G17 (XY)", "G18 (XZ)", "G19 (YZ)")


def _with(m: Move, start, end) -> Move:
    """m from start to end (dataclasses.replace, without its cost)."""
    return Move(
        m.kind, start, end, m.feed, m.line, m.centre, m.plane, m.turns, m.exact_stop, m.dwell_s
    )


def _perp(v):
    """v turned +90 degrees (to the left)."""
    return (-v[1], v[0])


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1])


def _add(a, b):
    return (a[0] + b[0], a[1] + b[1])


def _mul(a, k):
    return (a[0] * k, a[1] * k)


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1]


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _norm(a):
    return math.hypot(a[0], a[1])


def _unit(a):
    n = _norm(a)
    return (a[0] / n, a[1] / n)


def _sweep(centre, start, end, ccw: bool, turns: int) -> float:
    """Angle swept by an arc (radians, > 0)."""
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    d = (a1 - a0) if ccw else (a0 - a1)
    d %= 2.0 * math.pi
    if d <= 1e-12:
        d = 2.0 * math.pi
    return d + 2.0 * math.pi * turns


class _Geom:
    """The offset path of one held move, for the next corner."""

    def __init__(self, kind, start, end, tangent, centre=None, radius=0.0, ccw=False, turns=0):
        self.kind = kind  # "line" or "arc"
        self.start = start  # compensated start (plane coordinates)
        self.end = end  # compensated end
        self.tangent = tangent  # unit tangent of the programmed path at its end
        self.centre = centre
        self.radius = radius  # offset radius (arcs)
        self.ccw = ccw
        self.turns = turns
        # Lines: the direction the gouging test compares with (the programmed
        # one). Arcs: the programmed sweep (radians) it must not exceed.
        self.direction = tangent
        self.sweep0 = 0.0


class CutterComp:
    """Cutter radius compensation over a stream of canonical moves."""

    def __init__(self, error: Callable[[int, str], Exception]):
        self.error = error
        self.side = 0  # +1 left (G41), -1 right (G42), 0 off
        self.radius = 0.0
        self.plane = 0
        self.first = False  # on, and the entry move not made yet
        self.tool: Optional[tuple] = None  # tool position (6 floats)
        self.held: list[Move] = []
        self.geom: Optional[_Geom] = None
        self.corner = None  # programmed end of the held in-plane move
        self.exit_pending = False  # G40 given, no straight move since

    # ---- modal words --------------------------------------------------------
    @property
    def active(self) -> bool:
        return self.side != 0

    def on(self, side, radius_mm: float, plane: int, line: int) -> None:
        if self.side:
            raise self.error(line, "cutter compensation is already on (G40 first)")
        if side in ("left", 41, "G41"):
            s = 1
        elif side in ("right", 42, "G42"):
            s = -1
        else:
            raise self.error(line, f"cutter compensation side {side!r} (left or right)")
        r = float(radius_mm)
        if not math.isfinite(r):
            raise self.error(line, "cutter compensation radius is not a finite number")
        if plane not in (0, 1):
            name = _PLANE_NAMES[plane] if plane in (0, 1, 2) else str(plane)
            raise self.error(
                line, f"cutter compensation in the {name} plane is not supported (XY and XZ only)"
            )
        if r < 0.0:
            s, r = -s, -r
        self.side = s
        self.radius = r
        self.plane = plane
        self.first = True

    def off(self, line: int) -> None:
        if self.side and self.radius > 0.0:
            self.exit_pending = True
        if self.side and self.held and self.geom is not None:
            # As LinuxCNC: the held move, turned back by its corner, is a gouge.
            u, v = PLANE_AXES[self.plane]
            end = self.held[0].end
            self._check_gouge(self.geom, (end[u], end[v]), Move(0, end, end, 0.0, line))
        self.side = 0
        self.first = False
        # The held move ends where it is; the next in-plane move exits.
        self.geom = None

    def plane_change(self, plane: int, line: int) -> None:
        if self.side and plane != self.plane:
            raise self.error(line, "cannot change plane with cutter compensation on")

    # ---- moves --------------------------------------------------------------
    def flush(self) -> list:
        """Release the held moves. Called mid-program, it ends the corner
        look-ahead: the next in-plane move joins with a straight move."""
        out = self.held
        self.held = []
        self.geom = None
        return out

    def push(self, move: Move) -> list:
        out = self._push(move)
        for m in out + self.held:
            e = m.end
            if not (math.isfinite(e[0]) and math.isfinite(e[1]) and math.isfinite(e[2])):
                raise self.error(m.line, "cutter compensation: the offset path is out of range")
        return out

    def _push(self, move: Move) -> list:
        if self.tool is None:
            self.tool = tuple(move.start)
        if self.side and move.kind != DWELL and move.plane != self.plane:
            raise self.error(move.line, "cannot change plane with cutter compensation on")
        u, v = PLANE_AXES[self.plane] if self.side else PLANE_AXES[move.plane]
        if move.kind == DWELL:
            return self._passthrough(move, u, v)
        if not self.side or self.radius == 0.0:
            # After G40 every motion goes to its programmed end, a Z move
            # included: the tool leaves the offset path (as LinuxCNC).
            return self._uncompensated(move, u, v)
        if (
            move.kind not in (ARC_CW, ARC_CCW)
            and move.start[u] == move.end[u]
            and move.start[v] == move.end[v]
        ):
            return self._passthrough(move, u, v)
        if self.first:
            return self._entry(move, u, v)
        return self._corner(move, u, v)

    # ---- helpers ------------------------------------------------------------
    def _at(self, p, u, v, xy) -> tuple:
        q = list(p)
        q[u], q[v] = xy[0], xy[1]
        return tuple(q)

    def _release(self) -> list:
        out = self.held
        self.held = []
        return out

    def _passthrough(self, move: Move, u: int, v: int) -> list:
        tool = self.tool
        end = self._at(move.end, u, v, (tool[u], tool[v]))
        m = _with(move, tool, end)
        self.tool = end
        if self.held:
            self.held.append(m)
            return []
        return [m]

    def _uncompensated(self, move: Move, u: int, v: int) -> list:
        out = self._release()
        self.geom = None
        tool = self.tool
        if move.kind in (ARC_CW, ARC_CCW):
            if self.exit_pending:
                raise self.error(
                    move.line,
                    "the first move after G40 must be a straight line (it leaves the offset path)",
                )
        else:
            self.exit_pending = False
        m = _with(move, tool, move.end)
        self.tool = tuple(move.end)
        out.append(m)
        return out

    def _entry(self, move: Move, u: int, v: int) -> list:
        r = self.radius
        if move.kind in (ARC_CW, ARC_CCW):
            raise self.error(
                move.line,
                "an arc as the first move after G41/G42 is not supported; "
                "enter with a straight move",
            )
        out = self._release()
        c = (self.tool[u], self.tool[v])
        e = (move.end[u], move.end[v])
        d = _norm(_sub(e, c))
        if d <= r:
            raise self.error(
                move.line,
                f"cutter compensation entry move ({d:.4g} mm) is not longer than "
                f"the tool radius ({r:.4g} mm)",
            )
        t = _unit(_sub(e, c))
        n = _mul(_perp(t), self.side)
        tend = _add(e, _mul(n, r))
        m = _with(move, self.tool, self._at(move.end, u, v, tend))
        self.held = [m]
        self.geom = _Geom("line", c, tend, t)
        # LinuxCNC records the entry's direction as the offset normal, not the
        # motion; a concave corner right after the entry is checked with it.
        self.geom.direction = n
        self.corner = e
        self.first = False
        self.tool = m.end
        return out

    def _new_geom(self, move: Move, u: int, v: int):
        """Offset path of an incoming in-plane move: (geom, start tangent,
        offset start, tool inside an arc)."""
        r = self.radius
        s = self.side
        p = (move.start[u], move.start[v])
        e = (move.end[u], move.end[v])
        if move.kind in (ARC_CW, ARC_CCW):
            ccw = move.kind == ARC_CCW
            k = 1.0 if ccw else -1.0
            c = (move.centre[u], move.centre[v])
            r0 = _norm(_sub(e, c))
            rs = _norm(_sub(p, c))
            if r0 <= _EPS or rs <= _EPS:
                raise self.error(move.line, "arc of zero radius with cutter compensation")
            inside = s * k > 0
            if inside:
                if r0 <= r:
                    raise self.error(
                        move.line,
                        f"tool radius too big: the tool ({r:.4g} mm) does not fit inside "
                        f"the arc (radius {r0:.4g} mm)",
                    )
                rn = r0 - r
            else:
                rn = r0 + r
            ps = _unit(_sub(p, c))
            pe = _unit(_sub(e, c))
            start = _add(c, _mul(ps, rn))
            end = _add(c, _mul(pe, rn))
            t_start = _mul(_perp(ps), k)
            t_end = _mul(_perp(pe), k)
            g = _Geom("arc", start, end, t_end, c, rn, ccw, move.turns)
            g.sweep0 = _sweep(c, p, e, ccw, move.turns)
            return g, t_start, start, inside
        t = _unit(_sub(e, p))
        n = _mul(_perp(t), s)
        start = _add(p, _mul(n, r))
        end = _add(e, _mul(n, r))
        return _Geom("line", start, end, t), t, start, False

    def _corner(self, move: Move, u: int, v: int) -> list:
        s = self.side
        prev = self.geom
        p = (move.start[u], move.start[v])
        new, t2, s2, inside = self._new_geom(move, u, v)
        tool = self.tool
        tp = (tool[u], tool[v])
        out: list = []
        if prev is None:
            # After a flush: nothing held to adjust; join straight.
            out = self._release()
            if _norm(_sub(s2, tp)) > _EPS:
                join_end = self._at(tool, u, v, s2)
                kind = RAPID if move.kind == RAPID else LINEAR
                out.append(replace(move, kind=kind, start=tool, end=join_end, centre=None, turns=0))
                tool = join_end
            start = s2
        else:
            t1 = prev.tangent
            ang = math.atan2(_cross(t1, t2), _dot(t1, t2))  # turn, + = left
            beta = -s * ang  # + = away from the tool side (convex)
            if beta < -math.pi / 2:
                beta += 2.0 * math.pi
            if beta < -SMALL or beta > math.pi + SMALL:
                concave = True
            elif beta > math.pi - SMALL and (
                (new.kind == "arc" and not inside)
                or (new.kind == "line" and prev.kind == "arc" and s * (1 if prev.ccw else -1) < 0)
            ):
                # A reversal onto (or off) the outside of an arc, the top of
                # an "h" or "m": LinuxCNC stays on the near side.
                concave = True
            else:
                concave = False
            if concave:
                x = self._intersect(prev, new, p, move.line)
                self._check_gouge(prev, x, move)
                held0 = self.held[0]
                self.held[0] = _with(held0, held0.start, self._at(held0.end, u, v, x))
                for i in range(1, len(self.held)):
                    m = self.held[i]
                    self.held[i] = replace(
                        m, start=self._at(m.start, u, v, x), end=self._at(m.end, u, v, x)
                    )
                out = self._release()
                tool = self._at(tool, u, v, x)
                start = x
            elif beta > SMALL:
                if new.kind == "line":
                    # LinuxCNC checks the held move here too (it may have been
                    # turned back by the corner before it).
                    self._check_gouge(prev, tp, move)
                out = self._release()
                corner_end = tuple(
                    s2[0] if i == u else s2[1] if i == v else tool[i] if i < 3 else move.end[i]
                    for i in range(6)
                )
                if move.kind == RAPID:
                    cm = replace(move, start=tool, end=corner_end, exact_stop=False)
                else:
                    centre = [math.nan] * 3
                    centre[u], centre[v] = p
                    cm = Move(
                        kind=ARC_CW if s > 0 else ARC_CCW,
                        start=tool,
                        end=corner_end,
                        feed=move.feed,
                        line=move.line,
                        centre=tuple(centre),
                        plane=self.plane,
                    )
                out.append(cm)
                tool = corner_end
                start = s2
            else:
                out = self._release()
                start = tp
        new.start = start
        m = _with(move, tool, self._at(move.end, u, v, new.end))
        self.held = [m]
        self.geom = new
        self.corner = (move.end[u], move.end[v])
        self.tool = m.end
        return out

    def _intersect(self, a: _Geom, b: _Geom, p, line: int):
        """Intersection of the offset paths a (held) and b (next) nearest the
        programmed corner p."""
        if a.kind == "line" and b.kind == "line":
            den = _cross(a.tangent, b.tangent)
            if abs(den) < 1e-12:
                raise self._gouge(line)
            k = _cross(_sub(b.start, a.end), b.tangent) / den
            return _add(a.end, _mul(a.tangent, k))
        if a.kind == "line":
            pts = _line_circle(a.end, a.tangent, b.centre, b.radius)
        elif b.kind == "line":
            pts = _line_circle(b.start, b.tangent, a.centre, a.radius)
        else:
            pts = _circle_circle(a.centre, a.radius, b.centre, b.radius)
        if not pts:
            raise self._gouge(line)

        def key(q):
            # Prefer the point that shortens the held move and the next one
            # (a concave corner cuts both back), then the nearest to the corner.
            ok = _behind(a, q, a.end, True) and _behind(b, b.start, q, False)
            return (not ok, _norm(_sub(q, p)))

        return min(pts, key=key)

    def _check_gouge(self, a: _Geom, x, move: Move) -> None:
        """Moving the end of the held move to x must not turn it back (a
        line) or make it sweep further than programmed (an arc), as in
        LinuxCNC; the next move is checked when its own end moves."""
        if a.kind == "line":
            if _dot(_sub(x, a.start), a.direction) < 0.0:
                raise self._gouge(move.line)
        elif a.sweep0 > 0.0:
            cut = _sweep(a.centre, a.start, x, a.ccw, a.turns)
            if cut > a.sweep0 + ARC_SWEEP_SLACK:
                raise self._gouge(move.line)

    def _gouge(self, line: int) -> Exception:
        return self.error(
            line,
            f"cutter compensation: the tool (radius {self.radius:.4g} mm) cannot reach this "
            "concave corner without gouging the path",
        )


def _behind(g: _Geom, q0, q1, held: bool) -> bool:
    """q1 lies ahead of q0 along g (by less than half a turn on an arc)."""
    if g.kind == "line":
        return _dot(_sub(q1, q0), g.tangent) >= -1e-9
    if _norm(_sub(q1, q0)) <= 1e-9:
        return True
    return _sweep(g.centre, q0, q1, g.ccw, 0) < math.pi


def _line_circle(p, t, c, rad):
    """Points of the line p + k t (t unit) on the circle (c, rad)."""
    w = _sub(p, c)
    b = _dot(w, t)
    cc = _dot(w, w) - rad * rad
    disc = b * b - cc
    if disc < 0.0:
        if disc > -1e-12 * max(1.0, rad * rad):
            disc = 0.0
        else:
            return []
    sq = math.sqrt(disc)
    return [_add(p, _mul(t, -b - sq)), _add(p, _mul(t, -b + sq))]


def _circle_circle(c1, r1, c2, r2):
    d = _norm(_sub(c2, c1))
    if d < 1e-12:
        return []
    a = (r1 * r1 - r2 * r2 + d * d) / (2.0 * d)
    h2 = r1 * r1 - a * a
    if h2 < 0.0:
        if h2 > -1e-12 * max(1.0, r1 * r1):
            h2 = 0.0
        else:
            return []
    h = math.sqrt(h2)
    ex = _mul(_sub(c2, c1), 1.0 / d)
    m = _add(c1, _mul(ex, a))
    off = _mul(_perp(ex), h)
    return [_add(m, off), _sub(m, off)]
