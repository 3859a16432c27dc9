"""Group 0 commands (G10, G28/G30, G92 family) and motion (G0-G3 with
G53, canned cycles) of one block: :class:`MotionExecutor`, mixed into
:class:`~contour.gcode.interp.Interpreter` with
:class:`~contour.gcode.execute.BlockExecutor`, which calls it in the order
of RS-274/NGC.
"""

from __future__ import annotations

import math

from contour.gcode.cycles import CYCLES, expand
from contour.gcode.moves import DWELL, LINEAR, RAPID

AXES = "XYZABC"
_NAN = math.nan


class MotionExecutor:
    """Mixin: needs the interpreter's state, ``emit``, ``arc``, ``skip``,
    ``error``, ``refuse``."""

    # ---- group 0 ----------------------------------------------------------------
    def axis_values(self, axes):
        """Axis words as mm/deg by axis index (absolute values, no offsets)."""
        out = {}
        for i, (v, _func) in axes.items():
            out[i] = v * self.scale if i < 3 else v
        return out

    def target_of(self, axes, machine=False):
        """Machine target of axis words (G90/G91, offsets, Sinumerik forms)."""
        target = list(self.pos)
        origin = [0.0] * 6 if machine else self.offsets.origin
        for i, (v, func) in axes.items():
            if i < 3:
                v *= self.scale
            if func in ("DC", "ACP", "ACN"):
                cur = self.pos[i] - origin[i]
                d = (v - cur) % 360.0
                if func == "DC" and d > 180.0 or func == "ACN" and d > 0:
                    d -= 360.0
                target[i] = self.pos[i] + d
            elif func == "IC" or (func is None and not self.absolute and not machine):
                target[i] = self.pos[i] + v
            else:
                target[i] = v + origin[i]
        return target

    def non_modal(self, line, k, w, axes, used, stop):
        if k == 100:
            self.g10(line, w, axes, used)
        elif k in (280, 300):
            if self.comp is not None and self.comp.active:
                raise self.error(line, f"G{k // 10} with cutter compensation on")
            which = k // 10
            inter = self.target_of(axes)
            if inter != self.pos:
                self.emit(RAPID, inter, _NAN, line, stop)
            home = self.offsets.home(which, line)
            target = list(self.pos)
            for i in axes if axes else range(6):
                target[i] = home[i]
            if not self.offsets.home_set[which]:
                first = 5161 if which == 28 else 5181
                self.skip(
                    f"G{which}",
                    line,
                    f"stored position not set by G{which}.1 in the "
                    f"program: #{first}-#{first + 5} used (zero unless assigned)",
                )
            self.emit(RAPID, target, _NAN, line, stop)
        elif k in (281, 301):
            self.offsets.store_home(k // 10, self.pos)
        elif k in (920, 921, 922, 923):
            self.no_comp(line, "change the G92 offsets")
        if k == 920:
            if not axes:
                raise self.error(line, "G92 without axis words")
            self.offsets.g92(self.axis_values(axes), self.pos, line)
        elif k == 921:
            self.offsets.g92_1()
        elif k == 922:
            self.offsets.g92_2()
        elif k == 923:
            self.offsets.g92_restore(line)

    def g10(self, line, w, axes, used):
        used.update("LPR")
        lv = w.get("L")
        if lv not in (2.0, 20.0):
            raise self.refuse(line, "G10" + ("" if lv is None else f" L{lv:g}"))
        p = w.get("P")
        if p is None or p != int(p) or not 0 <= p <= 9:
            raise self.error(line, "G10 L2/L20: P must be an integer 0 to 9 (0: the active system)")
        if w.get("R", 0.0) != 0.0:
            raise self.refuse(line, "coordinate system rotation (G10 L2 R)")
        values = self.axis_values(axes)
        if int(p) in (0, self.offsets.system):
            self.no_comp(line, "change the active coordinate system")
        if lv == 2.0:
            self.offsets.set_system(int(p), values, line)
        else:
            self.offsets.set_system_here(int(p), values, self.pos, line)

    # ---- motion -----------------------------------------------------------------
    def motion_block(self, line, bw, g53, stop, used):
        motion = self.motion
        w = bw.w
        if motion == 80:  # G80 modal
            raise self.error(
                line, "axis words without a motion mode (G0/G1/G2/G3 or a canned cycle)"
            )
        if g53:
            if motion not in (0, 1):
                raise self.error(line, "G53 needs G0 or G1")
            if not self.absolute:
                raise self.error(line, "G53 in incremental distance mode (G91)")
            if self.comp is not None and self.comp.active:
                raise self.error(line, "G53 with cutter compensation on")
        if motion in CYCLES:
            used.update("RQPL")
            self.canned_cycle(line, motion, bw, stop)
            return
        target = self.target_of(bw.axes, machine=g53)
        if motion == 0:
            self.emit(RAPID, target, _NAN, line, stop)
            return
        if self.feed != self.feed:
            if self.default_feed is None:
                raise self.error(line, "feed move before any feed rate (F); give --feed")
            self.feed = self.default_feed
            self.substituted += 1
            self.skip("missing F", line, f"default feed {self.default_feed:g} used")
        if motion == 1:
            self.emit(LINEAR, target, self.feed, line, stop)
            return
        ijk = {c: w[c] for c in "IJK" if c in w}
        used.update("IJKRP")
        self.arc(line, motion, target, ijk, w.get("R"), w.get("P"), stop)

    def canned_cycle(self, line, code, bw, stop):
        words = {AXES[i]: v for i, (v, _f) in bw.axes.items()}
        for c in "RQPL":
            if c in bw.w:
                words[c] = bw.w[c]
        if self.feed != self.feed and self.default_feed is not None:
            self.feed = self.default_feed
        origin = self.offsets.origin
        pos = [p - o for p, o in zip(self.pos, origin)]
        moves = expand(
            code,
            words,
            self.cycle,
            pos,
            self.plane,
            not self.absolute,
            line,
            self.error,
            unit_mm=self.scale,
            comp_on=self.comp is not None and self.comp.active,
        )
        for kind, target, dwell in moves:
            tgt = [t + o for t, o in zip(target, origin)]
            if kind == LINEAR and self.feed != self.feed:
                raise self.error(line, "feed move before any feed rate (F); give --feed")
            self.emit(
                kind,
                tgt,
                self.feed if kind == LINEAR else _NAN,
                line,
                stop if kind != DWELL else False,
                dwell=dwell,
            )
