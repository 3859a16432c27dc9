"""One block through the interpreter (:class:`BlockExecutor`, mixed into
:class:`~contour.gcode.interp.Interpreter`): the words sorted by modal group
with the one-per-group checks, then executed in the order of RS-274/NGC.
"""

from __future__ import annotations

import math

from contour.gcode import policy
from contour.gcode.cutcomp import CutterComp
from contour.gcode.cycles import CYCLES
from contour.gcode.moves import DWELL

INCH_MM = 25.4
AXES = "XYZABC"
_NAN = math.nan
# Letters that are only parameters of some command: an error when nothing on
# the line uses them (LinuxCNC: "I word with no G2 or G3 ... to use it").
_PARAM_LETTERS = "IJKLPQR"
_SYSTEM_OF_KEY = {k: n for n, k in enumerate((540, 550, 560, 570, 580, 590, 591, 592, 593), 1)}


class Words:
    """The words of one block, sorted."""

    __slots__ = ("g", "m", "w", "axes", "feed_text", "calls")

    def __init__(self):
        self.g = {}  # modal group -> code key
        self.m = {}  # M group -> M number
        self.w = {}  # letter -> value (not G, M, axes)
        self.axes = {}  # axis index -> (value, func)
        self.feed_text = None  # F=<text> that could not be evaluated
        self.calls = []


class BlockExecutor:
    """Mixin: needs the interpreter's state, ``emit``, ``arc``, ``skip``,
    ``error``, ``refuse``, ``units_used``."""

    # ---- sorting --------------------------------------------------------------
    def sort_words(self, line, words):  # noqa: C901 - one dispatch over the letters
        bw = Words()
        m_count = 0
        for letter, value in words:
            if len(letter) == 1:
                if letter == "G":
                    k = policy.code_key(value)
                    grp = policy.G_GROUP.get(k)
                    name = policy.code_name("G", value)
                    if grp is None:
                        raise self.refuse(line, name)
                    if k in policy.G_REFUSED:
                        raise self.refuse(line, policy.G_REFUSED[k])
                    if grp in bw.g:
                        other = policy.code_name("G", bw.g[grp] / 10)
                        raise self.error(
                            line,
                            f"{other} and {name} on one line: two G codes of the same modal group",
                        )
                    bw.g[grp] = k
                elif letter == "M":
                    self.sort_m(line, value, bw)
                    m_count += 1
                    if m_count > 4:
                        raise self.error(line, "more than four M codes on one line")
                elif letter in AXES:
                    i = AXES.index(letter)
                    if i in bw.axes:
                        raise self.error(line, f"two {letter} words on one line")
                    bw.axes[i] = (value, None)
                elif letter in "UVW":
                    raise self.refuse(line, f"{letter} axis")
                elif letter == "E":
                    raise self.error(line, "unknown address letter 'E'")
                else:
                    if letter in bw.w:
                        raise self.error(line, f"two {letter} words on one line")
                    bw.w[letter] = value
            elif letter[0] == "=":
                self.sort_assignment(line, letter[1], value, bw)
            elif letter == "CALL":
                bw.calls.append(value)
            elif letter == "IDENT":
                self.skip(value, line, policy.IDENT_NOTES.get(value, policy.IDENT_NOTE))
            else:
                raise self.error(line, f"unexpected word {letter}")
        return bw

    def sort_m(self, line, value, bw):
        if value != int(value) or value < 0:
            raise self.refuse(line, policy.code_name("M", value))
        m = int(value)
        grp = policy.M_GROUP.get(m, 1000 + m)
        if grp in bw.m:
            raise self.error(
                line, f"M{bw.m[grp]} and M{m} on one line: two M codes of the same modal group"
            )
        if m in policy.M_REFUSED:
            raise self.refuse(line, policy.M_REFUSED[m])
        if m in policy.M_USER:
            raise self.refuse(line, f"M{m} (user-defined M code)")
        bw.m[grp] = m

    def sort_assignment(self, line, a, payload, bw):
        value, func = payload
        if a in AXES:
            i = AXES.index(a)
            if i in bw.axes:
                raise self.error(line, f"two {a} words on one line")
            if value is None:
                raise self.error(line, f"cannot evaluate {a}={func}")
            bw.axes[i] = (value, func)
        elif a == "F":
            if "F" in bw.w:
                raise self.error(line, "two F words on one line")
            if value is None:
                bw.feed_text = func
            else:
                bw.w["F"] = value
        else:
            self.skip(a + "=", line, policy.WORD_NOTES.get(a + "=", ""))

    # ---- execution --------------------------------------------------------------
    def block(self, line, words, messages=(), call_args=None):  # noqa: C901
        for text in messages:
            self.skip("(MSG)", line, f"message: {text}")
        bw = self.sort_words(line, words)
        g = bw.g
        w = bw.w
        used = set()
        for name in bw.calls:
            self.call(line, name, (call_args or {}).get(name, ""))
        # Reported codes and words.
        for k in g.values():
            if k in policy.G_REPORTED:
                note = policy.G_REPORTED[k]
                if note:
                    self.skip(policy.code_name("G", k / 10), line, note)
        comp_d = g.get(7) in (410, 420, 411, 421)
        for letter in "STDH":
            if letter in w and not (letter == "D" and comp_d):
                used.add(letter)
                self.skip(letter, line, policy.WORD_NOTES[letter])
        self.tool_words(line, w, bw.m.values(), used)
        for m in bw.m.values():
            if m not in (2, 30):
                self.skip(f"M{m}", line, policy.M_REPORTED.get(m, policy.M_NOTE))
            if m in (50, 51, 52, 53, 62, 63, 64, 65, 67, 68, 19):
                used.update("PQR")
        # Units first: F and every length on the line are in the line's units.
        u = g.get(6)
        if u in (700, 710) and "Q" in w:
            # G70/G71 with a Q profile are LinuxCNC's lathe cycles, not the
            # Sinumerik inch/metric codes.
            name = "G70 lathe finishing cycle" if u == 700 else "G71 lathe roughing cycle"
            raise self.refuse(line, name)
        if u is not None:
            self.scale = INCH_MM if u in (200, 700, 7000) else 1.0
            self.units_set = True
        has_length = bw.axes or "F" in w or bw.feed_text is not None
        if has_length or any(c in w for c in "IJKR") or 0 in g:
            self.units_used(line)
        g0 = g.get(0)
        # Feed (G4 F<s> is the Sinumerik dwell: the feed stays).
        if g0 != 40:
            self.set_feed(line, w, bw.feed_text)
        # Plane, cutter comp, tool length, coordinate system, path, distance.
        if 2 in g:
            self.plane = (170, 180, 190).index(g[2])
            if self.comp is not None:
                self.comp.plane_change(self.plane, line)
        if 7 in g:
            self.cutter_comp(line, g[7], w, used)
        if 12 in g:
            n = _SYSTEM_OF_KEY[g[12]]
            if n != self.offsets.system:  # LinuxCNC: the active one is not reloaded
                self.no_comp(line, "change the coordinate system")
                self.offsets.select(n, line)
            if n not in self.offsets.set_in_program:
                self.skip(
                    policy.code_name("G", g[12] / 10),
                    line,
                    "work offset: zero unless set by G10 L2/L20 in the program",
                )
        p13 = g.get(13)
        if p13 is not None:
            self.exact_stop_modal = p13 in (600, 610, 611)
            if p13 == 640 and ("P" in w or "Q" in w):
                used.update("PQ")
                self.skip("G64 P", line, "path tolerance: the profile's business")
        if 3 in g:
            self.absolute = g[3] == 900
        if 4 in g:
            self.arc_absolute = g[4] == 901
        if 10 in g:
            self.cycle.retract = 98 if g[10] == 980 else 99
        # Dwell (LinuxCNC runs it before the modal settings; nothing above moves).
        if g0 == 40:
            self.dwell(line, w, bw.axes, used)
            bw.axes = {}
        g9 = g.get(100) == 90
        stop = self.exact_stop_modal or g9
        motion_g = g.get(1)
        axis_user = g0 in policy.G_AXIS_USERS
        if bw.axes and axis_user and motion_g is not None and motion_g != 800:
            raise self.error(
                line,
                f"{policy.code_name('G', motion_g / 10)} and "
                f"{policy.code_name('G', g0 / 10)} both use the axis words",
            )
        if g0 is not None and g0 != 40 and g0 != 530:
            self.non_modal(line, g0, w, bw.axes, used, stop)
        if motion_g is not None:
            if motion_g == 800 and bw.axes and not axis_user:
                raise self.error(line, "axis words with G80 (canned cycle off)")
            self.motion = motion_g // 10
            if self.motion not in CYCLES:
                self.cycle.cancel()
        if bw.axes and not axis_user and g0 != 40:
            self.motion_block(line, bw, g0 == 530, stop, used)
        elif motion_g in (20, 30):
            if not any(c in w for c in "IJK"):
                raise self.error(line, "arc without end point (no axis word)")
            # LinuxCNC: G2/G3 with a centre and no axis word is a full circle.
            self.motion_block(line, bw, False, stop, used)
        elif motion_g is not None and motion_g // 10 in CYCLES:
            self.motion_block(line, bw, False, stop, used)
        for letter in _PARAM_LETTERS:
            if letter in w and letter not in used:
                raise self.error(line, f"{letter} word with nothing on the line to use it")
        if 4 in bw.m and bw.m[4] in (2, 30):
            self.ended = True
            self.finish()
        elif (
            self.comp is not None
            and not self.comp.active
            and not self.comp.held
            and (self.comp.tool is None or list(self.comp.tool) == self.pos)
        ):
            self.comp = None  # back on the plain path: the fast path again

    def no_comp(self, line, what):
        """LinuxCNC refuses offset changes while cutter compensation is on."""
        if self.comp is not None and self.comp.active:
            raise self.error(line, f"cannot {what} with cutter compensation on (G40 first)")

    def set_feed(self, line, w, feed_text):
        f = w.get("F")
        if f is not None:
            if f <= 0:
                raise self.error(line, f"feed must be positive, got F{f:g}")
            self.feed = f * self.scale
        elif feed_text is not None:
            if self.default_feed is None:
                raise self.error(
                    line,
                    f"cannot evaluate F={feed_text} (its value is set outside "
                    "the file); give a default feed with --feed",
                )
            self.feed = self.default_feed
            self.substituted += 1
            self.skip(f"F={feed_text}", line, f"replaced by the default feed {self.default_feed:g}")

    def dwell(self, line, w, axes, used):
        if "P" in w:
            t = w["P"]
            used.add("P")
        elif 0 in axes:
            t = axes[0][0]  # Fanuc/Sinumerik G4 X<s>
        elif "F" in w:
            t = w["F"]  # Sinumerik G4 F<s>
        else:
            raise self.error(line, "G4 dwell without a time (P or X, seconds)")
        if not 0 <= t < 1e7:
            raise self.error(line, f"dwell time {t:g} s out of range")
        self.emit(DWELL, self.pos, _NAN, line, False, dwell=t)

    def cutter_comp(self, line, k, w, used):
        if k == 400:
            if self.comp is not None:
                self.comp.off(line)
            return
        name = policy.code_name("G", k / 10)
        d = w.get("D")
        if k in (410, 420):
            if d is None:
                n = self.current_tool
            else:
                used.add("D")
                if d != int(d) or d < 0:
                    raise self.error(line, f"{name} D{d:g}: a tool number must be an integer >= 0")
                n = int(d)
            tool = self.tools.get(n)
            if tool is None:
                hint = "" if self.tools else " (give one with --tool-table, or use G41.1/G42.1 D)"
                raise self.error(line, f"{name}: tool {n} is not in the tool table{hint}")
            radius = tool.radius
        else:
            if d is None:
                raise self.error(line, f"{name} without D (the tool diameter)")
            used.add("D")
            radius = d * self.scale / 2.0
        if self.comp is None:
            self.comp = CutterComp(self.error)
        self.comp.on("left" if k in (410, 411) else "right", radius, self.plane, line)

    def tool_words(self, line, w, m_codes, used):
        """T selects, M6 makes the selected tool current, M61 Q sets it."""
        t = w.get("T")
        if t is not None:
            if t != int(t) or t < 0:
                raise self.error(line, f"T{t:g}: a tool number must be an integer >= 0")
            self.selected_tool = int(t)
        if 6 in m_codes:
            self.current_tool = self.selected_tool
        if 61 in m_codes:
            q = w.get("Q")
            if q is None or q != int(q) or q < 0:
                raise self.error(line, "M61 needs Q, the tool number (an integer >= 0)")
            used.add("Q")
            self.current_tool = int(q)

    def call(self, line, name, args):
        if name == "CYCLE832":
            # Sinumerik high-speed cycle: with a tolerance it selects continuous
            # path (G642); empty, the previous mode returns.
            if args.strip(", "):
                if self.before_cycle832 is None:
                    self.before_cycle832 = self.exact_stop_modal
                self.exact_stop_modal = False
            elif self.before_cycle832 is not None:
                self.exact_stop_modal = self.before_cycle832
                self.before_cycle832 = None
        self.skip(name, line, policy.IDENT_NOTES.get(name, policy.IDENT_NOTE))
