"""G-code reader: RS-274 / ISO 6983 subset plus the dialect words of real files.

Understood (they change the path or its timing):

- motion ``G0 G1 G2 G3`` (arcs in the ``I J K`` form, incremental centre unless
  ``G90.1``, and in the ``R`` form, negative ``R`` for more than half a turn,
  ``P`` extra turns), dwell ``G4`` (``P`` or ``X`` in seconds, Sinumerik ``F``
  seconds), planes ``G17 G18 G19``, units ``G20 G21`` (and Sinumerik ``G70 G71
  G700 G710``), distance ``G90 G91`` (and ``G90.1 G91.1`` for arc centres),
  exact stop ``G60 G61`` (modal), ``G9`` (this block), continuous path ``G64``,
  Sinumerik exact-stop windows ``G601 G602 G603``, ``F`` (feed in mm/min, or
  in/min under G20), ``N`` and ``O`` numbers, ``(...)`` and ``;`` comments,
  blank lines, ``%`` tape marks, ``M2``/``M30`` (end of program).
- axes ``X Y Z`` (mm) and rotary ``A B C`` (degrees), absolute or incremental,
  and the Sinumerik forms ``C=DC(v)`` (shortest way), ``=ACP(v)``, ``=ACN(v)``,
  ``=AC(v)``, ``=IC(v)``.
- Sinumerik R parameters assigned a constant (``R0=2500``) and used as a feed
  (``F=R0``).

Everything else that is well formed (M, S, T, D, H words, ``G54``,
``CYCLE832(...)``, ``TRAORI``, ``$A_...`` ...) is *skipped*: the reader records
it once per kind with its first line and a count (:attr:`Program.skipped`).

Errors (:class:`GcodeError`, a :class:`~contour.errors.UserError`) name
``file:line`` and stop the read: a malformed number (``X1.2.3``, ``X-``), an
address letter the reader does not know (``E U V W`` or any other
character), a feed it cannot evaluate (``F=R0`` with R0 unknown) or a feed
move with no feed at all, unless a default feed was given, and impossible
arcs.

The result is a :class:`Program`: one row per motion or dwell block, in
columns (NumPy arrays), so that a million-line file stays compact. Positions
are in mm and degrees in the program's coordinate system; the start point is
the origin (or ``start=``). :func:`segments` turns the program into straight
segments (arcs split within a chord tolerance) for the estimators.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from contour.errors import UserError
from contour.gcode.moves import (  # noqa: F401 - re-exported
    ARC_CCW,
    ARC_CW,
    DWELL,
    KIND_NAMES,
    LINEAR,
    RAPID,
)

INCH_MM = 25.4

# A line of plain address words only (the bulk of CAM output): one regex
# decides it, a second splits it.
_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_SIMPLE_LINE = re.compile(r"(?:[A-Z]\s*" + _NUM + r"\s*)+")
_SIMPLE_WORD = re.compile(r"([A-Z])\s*(" + _NUM + r")")

# The commonest block of all: optional N, optional G0/G1, X Y Z in order, F.
_FAST_LINE = re.compile(
    r"(?:N\d+\s*)?(?:G0?([01])(?![\d.])\s*)?(?:X\s*("
    + _NUM
    + r")\s*)?(?:Y\s*("
    + _NUM
    + r")\s*)?(?:Z\s*("
    + _NUM
    + r")\s*)?(?:F\s*("
    + _NUM
    + r")\s*)?"
)

# Pieces used by the general tokenizer.
_WORD_AT = re.compile(r"([A-Z])\s*(" + _NUM + r")")
_IDENT_AT = re.compile(r"[A-Z_$][A-Z0-9_$]*")
_BAD_TAIL = re.compile(r"[-+0-9.]")
_JUNK_AT = re.compile(r"[^\s;(]*")
_NUMBER_FULL = re.compile(_NUM)

# Address letters with a meaning here. Others are an error.
_KNOWN_LETTERS = set("ABCDFGHIJKLMNOPQRSTXYZ")
_AXES = "XYZABC"
_ROTARY_FUNCS = {"DC", "ACP", "ACN", "AC", "IC"}

# Short notes for skipped kinds a user may wonder about.
_NOTES = {
    "G40": "cutter compensation off (no effect on the path)",
    "G41": "cutter compensation not applied",
    "G42": "cutter compensation not applied",
    "G43": "tool length offset not applied",
    "G49": "tool length offset cancel",
    "G53": "machine-coordinate move not timed (work offset unknown)",
    "G54": "work offset unknown: zero assumed",
    "G93": "inverse-time feed not supported: F read as mm/min",
    "G95": "feed per revolution not supported: F read as mm/min",
    "S": "spindle speed",
    "T": "tool select",
    "D": "tool offset number",
    "H": "tool length offset number",
    "T=": "tool select by name",
    "TRAORI": "5-axis transform: X Y Z read as the tool-tip path",
    "TRAFOOF": "transform off",
    "CYCLE800": "swivel cycle (orientation), not timed",
    "CYCLE832": "high-speed settings: read as continuous path (G64) until CYCLE832(); "
    "its tolerance and compressor are the profile's business",
    "TRAF00F": "unknown word (TRAFOOF, transform off, written with zeros?)",
    "FNORM": "feed normal (the default)",
    "M6": "tool change not timed",
    "M0": "program stop: the wait is not timed",
    "M1": "optional stop: the wait is not timed",
}


_M_NOTE = "machine function, not timed"


class GcodeError(UserError):
    """A G-code error at ``file:line``; no estimate is made."""

    def __init__(self, path: str, line: int, message: str):
        super().__init__(f"{path}:{line}: {message}")
        self.path = path
        self.line = line
        self.message = message


@dataclass
class Skipped:
    """One kind of word the reader did not interpret."""

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

    Row i is one block. ``end`` holds the end point (X Y Z mm, A B C degrees),
    the start of row i is the end of row i-1 (``start`` for row 0); ``feed``
    is mm/min (NaN for rapids and dwells); ``centre`` is the arc centre (mm,
    NaN off arcs), ``plane`` 0/1/2 for G17/G18/G19, ``turns`` the extra full
    turns of an arc; ``exact_stop`` is true when the block ends in an exact
    stop (G60/G61 modal or G9); ``dwell_s`` the dwell of a G4 row; ``line`` the
    1-based source line.
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


class _Reader:
    """State of one read. The hot loop lives in :meth:`run`."""

    def __init__(self, path: str, default_feed: Optional[float], start):
        self.path = path
        self.default_feed = default_feed
        self.skipped: dict[str, Skipped] = {}
        self.rparams: dict[int, float] = {}
        self.substituted = 0
        # Modal state.
        self.motion = None  # None until a motion G word
        self.plane = 0
        self.scale = 1.0  # mm per program unit
        self.absolute = True
        self.arc_absolute = False
        self.exact_stop_modal = False
        self.before_cycle832 = None
        self.feed = math.nan  # mm/min
        self.pos = (
            [0.0] * 6 if start is None else [float(v) for v in start] + [0.0] * (6 - len(start))
        )
        self.start = list(self.pos)
        # Output columns.
        self.o_kind: list[int] = []
        self.o_end: list[float] = []
        self.o_feed: list[float] = []
        self.o_arc: dict[int, tuple] = {}
        self.o_stop: list[bool] = []
        self.o_dwell: dict[int, float] = {}
        self.o_line: list[int] = []

    # ---- reporting --------------------------------------------------------
    def skip(self, kind: str, lineno: int, note: str = "") -> None:
        s = self.skipped.get(kind)
        if s is None:
            if not note:
                note = _NOTES.get(kind, "")
                if not note and kind in ("G55", "G56", "G57", "G58", "G59"):
                    note = _NOTES["G54"]
            self.skipped[kind] = Skipped(kind, lineno, 1, note)
        else:
            s.count += 1

    def error(self, lineno: int, message: str) -> GcodeError:
        return GcodeError(self.path, lineno, message)

    # ---- tokenizer for lines that are not plain words ---------------------
    def tokenize(self, text: str, lineno: int) -> list:
        """Split one upper-cased line into ``(letter, value)`` words.

        Returns address words as ``(letter, float)`` and Sinumerik specials
        as ``("=" + letter, payload)`` tuples. Comments and skipped words are
        consumed here.
        """
        words = []
        i = 0
        n = len(text)
        while i < n:
            c = text[i]
            if c == " " or c == "\t" or c == "\r":
                i += 1
                continue
            if c == ";":
                break
            if c == "(":
                j = text.find(")", i + 1)
                if j < 0:
                    raise self.error(lineno, "unclosed comment '(' (no ')' on the line)")
                i = j + 1
                continue
            if c == "%" and not words and text[i:].strip() == "%":
                break
            if c == "/" and i == 0:
                # Block delete: the switch is taken as off (the block runs).
                self.skip("/ (block delete)", lineno, "block delete switch off: block executed")
                i += 1
                continue
            if "A" <= c <= "Z" or c == "_" or c == "$":
                nxt = text[i + 1] if i + 1 < n else ""
                if c == "$" or c == "_" or "A" <= nxt <= "Z" or nxt == "_" or nxt == "$":
                    i = self._identifier(text, i, lineno, words)
                    continue
                j = i + 1
                while j < n and text[j] in " \t":
                    j += 1
                if j < n and text[j] == "=":
                    i = self._assignment(text, c, j + 1, lineno, words)
                    continue
                if c not in _KNOWN_LETTERS:
                    raise self.error(lineno, f"unknown address letter '{c}'")
                m = _WORD_AT.match(text, i)
                if m is None:
                    bad = _JUNK_AT.match(text, i).group(0)
                    raise self.error(lineno, f"malformed number in '{bad}'")
                end = m.end()
                if end < n and _BAD_TAIL.match(text, end):
                    bad = _JUNK_AT.match(text, i).group(0)
                    raise self.error(lineno, f"malformed number in '{bad}'")
                if c == "R":
                    k = end
                    while k < n and text[k] in " \t":
                        k += 1
                    if k < n and text[k] == "=":
                        i = self._assign_r(text, m.group(2), k + 1, lineno)
                        continue
                words.append((c, float(m.group(2))))
                i = end
                continue
            raise self.error(lineno, f"unexpected character '{c}'")
        return words

    def _balanced(self, text: str, i: int, lineno: int) -> int:
        """Index just after the ')' matching the '(' at text[i]."""
        depth = 0
        n = len(text)
        quoted = False
        while i < n:
            c = text[i]
            if c == '"':
                quoted = not quoted
            elif not quoted:
                if c == "(":
                    depth += 1
                elif c == ")":
                    depth -= 1
                    if depth == 0:
                        return i + 1
            i += 1
        raise self.error(lineno, "unbalanced parentheses")

    def _identifier(self, text: str, i: int, lineno: int, words: list) -> int:
        m = _IDENT_AT.match(text, i)
        name = m.group(0)
        j = m.end()
        n = len(text)
        if j < n and text[j] == "(":
            k = self._balanced(text, j, lineno)
            if name == "CYCLE832":
                self._cycle832(text[j + 1 : k - 1].strip())
            j = k
        elif j < n and text[j] == "=":
            j = self._expression_end(text, j + 1, lineno)
            self.skip(name + "=", lineno)
            return j
        self.skip(name, lineno)
        return j

    def _cycle832(self, args: str) -> None:
        """Sinumerik high-speed cycle: with a tolerance it selects continuous
        path (G642); empty, it deselects and the previous mode returns."""
        if args.strip(", "):
            if self.before_cycle832 is None:
                self.before_cycle832 = self.exact_stop_modal
            self.exact_stop_modal = False
        elif self.before_cycle832 is not None:
            self.exact_stop_modal = self.before_cycle832
            self.before_cycle832 = None

    def _expression_end(self, text: str, j: int, lineno: int) -> int:
        n = len(text)
        while j < n and text[j] in " \t":
            j += 1
        while j < n and text[j] not in " \t;":
            if text[j] == "(":
                j = self._balanced(text, j, lineno)
                continue
            if text[j] == '"':
                k = text.find('"', j + 1)
                if k < 0:
                    raise self.error(lineno, "unclosed string")
                j = k + 1
                continue
            j += 1
        return j

    def _assign_r(self, text: str, index: str, j: int, lineno: int) -> int:
        """``R<n>=value``: a constant is remembered, anything else forgotten."""
        end = self._expression_end(text, j, lineno)
        expr = text[j:end].strip()
        if not index.isdigit():
            raise self.error(lineno, f"malformed R parameter number 'R{index}'")
        if _NUMBER_FULL.fullmatch(expr):
            self.rparams[int(index)] = float(expr)
        else:
            self.rparams.pop(int(index), None)
            self.skip("R= expression", lineno, "R parameter set from an expression: left unknown")
        return end

    def _assignment(self, text: str, letter: str, j: int, lineno: int, words: list) -> int:
        """``X=...`` forms. R parameters are words ``R<n>``, handled here too."""
        end = self._expression_end(text, j, lineno)
        expr = text[j:end].strip()
        words.append(("=" + letter, expr))
        return end

    # ---- evaluation of Sinumerik values -----------------------------------
    def evaluate(self, expr: str):
        """Number, known R parameter or ``NAME(number)``; None if unknown."""
        if _NUMBER_FULL.fullmatch(expr):
            return float(expr), None
        m = re.fullmatch(r"R(\d+)\.?", expr)
        if m:
            v = self.rparams.get(int(m.group(1)))
            return v, None
        m = re.fullmatch(r"([A-Z]+)\((" + _NUM + r")\)", expr)
        if m and m.group(1) in _ROTARY_FUNCS:
            return float(m.group(2)), m.group(1)
        return None, None

    # ---- the main loop ----------------------------------------------------
    def run(self, lines: Iterable[str]) -> int:
        simple_line = _SIMPLE_LINE.fullmatch
        simple_words = _SIMPLE_WORD.findall
        fast_line = _FAST_LINE.fullmatch
        o_kind = self.o_kind
        o_end = self.o_end
        o_feed = self.o_feed
        o_stop = self.o_stop
        o_line = self.o_line
        lineno = 0
        ended = False
        for raw in lines:
            lineno += 1
            text = raw.strip().upper()
            if not text:
                continue
            if ended:
                self.skip("after M2/M30", lineno, "lines after the end of program")
                continue
            m = fast_line(text)
            if m is not None:
                # Straight moves with X Y Z (and F): the bulk of CAM output.
                g, xs, ys, zs, fs = m.groups()
                motion = self.motion if g is None else int(g)
                if motion == 0 or (motion == 1 and (fs is not None or self.feed == self.feed)):
                    self.motion = motion
                    if fs is not None:
                        f = float(fs)
                        if f <= 0:
                            raise self.error(lineno, f"feed must be positive, got F{f:g}")
                        self.feed = f * self.scale
                    if xs is None and ys is None and zs is None:
                        continue
                    pos = self.pos
                    target = pos[:]
                    sc = self.scale
                    if self.absolute:
                        if xs is not None:
                            target[0] = float(xs) * sc
                        if ys is not None:
                            target[1] = float(ys) * sc
                        if zs is not None:
                            target[2] = float(zs) * sc
                    else:
                        if xs is not None:
                            target[0] += float(xs) * sc
                        if ys is not None:
                            target[1] += float(ys) * sc
                        if zs is not None:
                            target[2] += float(zs) * sc
                    o_kind.append(motion)
                    o_end.extend(target)
                    o_feed.append(self.feed if motion else math.nan)
                    o_stop.append(self.exact_stop_modal)
                    o_line.append(lineno)
                    self.pos = target
                    continue
            if simple_line(text):
                words = [(a, float(b)) for a, b in simple_words(text)]
            else:
                words = self.tokenize(text, lineno)
                if not words:
                    continue
            ended = self.block(words, lineno)
        return lineno

    def block(self, words: list, lineno: int) -> bool:  # noqa: C901 - one dispatch
        """Interpret one block; returns True at end of program."""
        axes = None  # dict axis index -> (value, func)
        ijk = None
        r_word = None
        p_word = None
        g_motion = None
        g4 = False
        g53 = False
        g9 = False
        f_word = None
        f_unknown = None
        ended = False
        for letter, value in words:
            if letter in "XYZABC" and len(letter) == 1:
                if axes is None:
                    axes = {}
                axes["XYZABC".index(letter)] = (value, None)
            elif letter == "G":
                g = value
                if g == 0 or g == 1 or g == 2 or g == 3:
                    g_motion = int(g)
                elif g == 4:
                    g4 = True
                elif g == 17:
                    self.plane = 0
                elif g == 18:
                    self.plane = 1
                elif g == 19:
                    self.plane = 2
                elif g in (20, 70, 700):
                    self.scale = INCH_MM
                elif g in (21, 71, 710):
                    self.scale = 1.0
                elif g == 90:
                    self.absolute = True
                elif g == 91:
                    self.absolute = False
                elif g == 90.1:
                    self.arc_absolute = True
                elif g == 91.1:
                    self.arc_absolute = False
                elif g in (60, 61):
                    self.exact_stop_modal = True
                elif g in (64, 641, 642, 643, 644, 645):
                    self.exact_stop_modal = False
                elif g == 9:
                    g9 = True
                elif g in (601, 602, 603, 94, 80):
                    pass  # exact-stop window, feed per minute, canned cycle off
                elif g == 53:
                    g53 = True
                    self.skip("G53", lineno)
                else:
                    self.skip("G" + _fmt_code(g), lineno)
            elif letter == "F":
                f_word = value
            elif letter in "IJK" and len(letter) == 1:
                if ijk is None:
                    ijk = [None, None, None]
                ijk["IJK".index(letter)] = value
            elif letter == "R":
                r_word = value
            elif letter == "P":
                p_word = value
            elif letter == "N" or letter == "O":
                pass
            elif letter == "M":
                m = value
                if m == 2 or m == 30:
                    ended = True
                else:
                    self.skip("M" + _fmt_code(m), lineno, _NOTES.get("M" + _fmt_code(m), _M_NOTE))
            elif letter in ("S", "T", "D", "H", "L", "Q"):
                self.skip(letter, lineno)
            elif letter[0] == "=":
                a = letter[1]
                if a == "F":
                    v, _ = self.evaluate(value)
                    if v is None:
                        f_unknown = value
                    else:
                        f_word = v
                elif a in _AXES:
                    v, func = self.evaluate(value)
                    if v is None:
                        raise self.error(lineno, f"cannot evaluate {a}={value}")
                    if axes is None:
                        axes = {}
                    axes[_AXES.index(a)] = (v, func)
                elif a == "R":
                    raise self.error(lineno, f"malformed R parameter assignment 'R={value}'")
                else:
                    self.skip(a + "=", lineno)
            else:
                raise self.error(lineno, f"unknown address letter '{letter}'")
        return self._execute(
            lineno, axes, ijk, r_word, p_word, g_motion, g4, g53, g9, f_word, f_unknown, ended
        )

    def _execute(
        self, lineno, axes, ijk, r_word, p_word, g_motion, g4, g53, g9, f_word, f_unknown, ended
    ) -> bool:
        scale = self.scale
        if g4:
            if p_word is not None:
                t = p_word
            elif axes is not None and 0 in axes:
                t = axes[0][0]
            elif f_word is not None:
                t = f_word  # Sinumerik: G4 F<seconds>, the feed is unchanged
            else:
                raise self.error(lineno, "G4 dwell without a time (P or X, seconds)")
            if t < 0:
                raise self.error(lineno, f"negative dwell time {t:g}")
            self._emit(DWELL, list(self.pos), math.nan, None, 0, t, lineno, False)
            return ended
        if f_word is not None:
            if f_word <= 0:
                raise self.error(lineno, f"feed must be positive, got F{f_word:g}")
            self.feed = f_word * scale
        elif f_unknown is not None:
            if self.default_feed is None:
                raise self.error(
                    lineno,
                    f"cannot evaluate F={f_unknown} (its value is set outside the file); "
                    "give a default feed with --feed",
                )
            self.feed = self.default_feed
            self.substituted += 1
            note = f"replaced by the default feed {self.default_feed:g}"
            self.skip(f"F={f_unknown}", lineno, note)
        if g_motion is not None:
            self.motion = g_motion
        if axes is None:
            if g_motion in (2, 3) and ijk is None and r_word is None:
                raise self.error(lineno, "arc without end point or centre")
            return ended
        if g53:
            return ended  # motion in machine coordinates: skipped (reported)
        if self.motion is None:
            raise self.error(lineno, "axis words before any motion mode (G0/G1/G2/G3)")
        target = list(self.pos)
        for idx, (v, func) in axes.items():
            if idx < 3:
                v *= scale
                target[idx] = (
                    v if (self.absolute and func != "IC") or func == "AC" else (self.pos[idx] + v)
                )
            else:
                target[idx] = self._rotary(self.pos[idx], v, func)
        motion = self.motion
        if motion == 0:
            self._emit(RAPID, target, math.nan, None, 0, 0.0, lineno, g9)
            return ended
        feed = self.feed
        if feed != feed:  # NaN: no feed yet
            if self.default_feed is None:
                raise self.error(lineno, "feed move before any feed rate (F); give --feed")
            feed = self.feed = self.default_feed
            self.substituted += 1
            self.skip("missing F", lineno, f"default feed {self.default_feed:g} used")
        if motion == 1:
            self._emit(LINEAR, target, feed, None, 0, 0.0, lineno, g9)
            return ended
        centre, turns = self._arc_centre(lineno, target, ijk, r_word, p_word, motion)
        self._emit(ARC_CW if motion == 2 else ARC_CCW, target, feed, centre, turns, 0.0, lineno, g9)
        return ended

    def _rotary(self, current: float, v: float, func) -> float:
        if func is None:
            return v if self.absolute else current + v
        if func == "IC":
            return current + v
        if func == "AC":
            return v
        # DC, ACP, ACN: the target angle modulo 360 reached the short,
        # positive or negative way.
        d = (v - current) % 360.0
        if func == "DC":
            if d > 180.0:
                d -= 360.0
        elif func == "ACN" and d > 0:
            d -= 360.0
        return current + d

    def _arc_centre(self, lineno, target, ijk, r_word, p_word, motion):
        u, v = ((0, 1), (2, 0), (1, 2))[self.plane]
        su, sv = self.pos[u], self.pos[v]
        eu, ev = target[u], target[v]
        turns = 0
        if p_word is not None:
            if p_word < 1 or p_word != int(p_word):
                raise self.error(lineno, f"arc turns P must be a positive integer, got {p_word:g}")
            turns = int(p_word) - 1
        tol = 0.002 * self.scale + 1e-9
        if ijk is not None:
            names = (("I", "J"), ("K", "I"), ("J", "K"))[self.plane]
            ou = ijk["IJK".index(names[0])] or 0.0
            ov = ijk["IJK".index(names[1])] or 0.0
            if self.arc_absolute:
                cu, cv = ou * self.scale, ov * self.scale
            else:
                cu, cv = su + ou * self.scale, sv + ov * self.scale
            r0 = math.hypot(su - cu, sv - cv)
            r1 = math.hypot(eu - cu, ev - cv)
            if r0 < 1e-9:
                raise self.error(lineno, "arc of zero radius (centre on the start point)")
            if abs(r0 - r1) > max(tol, 1e-3 * r0):
                raise self.error(
                    lineno,
                    f"arc end point is not on the circle: radius {r0:.4f} at the start, "
                    f"{r1:.4f} at the end",
                )
        elif r_word is not None:
            r = abs(r_word) * self.scale
            du, dv = eu - su, ev - sv
            d = math.hypot(du, dv)
            if d < 1e-9:
                raise self.error(lineno, "R-form arc with identical start and end points")
            if d > 2 * r + tol:
                raise self.error(lineno, f"arc radius {r:.4f} too small for a chord of {d:.4f}")
            h = math.sqrt(max(r * r - d * d / 4.0, 0.0))
            # Centre to the left of the chord for CCW short arcs.
            left = (motion == 3) == (r_word > 0)
            s = 1.0 if left else -1.0
            cu = su + du / 2 - s * h * dv / d
            cv = sv + dv / 2 + s * h * du / d
        else:
            raise self.error(lineno, "arc without centre (I/J/K) or radius (R)")
        centre = [math.nan, math.nan, math.nan]
        centre[u] = cu
        centre[v] = cv
        return centre, turns

    def _emit(self, kind, target, feed, centre, turns, dwell, lineno, g9):
        row = len(self.o_kind)
        self.o_kind.append(kind)
        self.o_end.extend(target)
        self.o_feed.append(feed)
        if centre is not None:
            self.o_arc[row] = (centre, self.plane, turns)
        if dwell:
            self.o_dwell[row] = dwell
        self.o_stop.append(self.exact_stop_modal or g9)
        self.o_line.append(lineno)
        self.pos = target

    def program(self, lines_read: int) -> Program:
        n = len(self.o_kind)
        centre = np.full((n, 3), np.nan)
        plane = np.zeros(n, dtype=np.int8)
        turns = np.zeros(n, dtype=np.int32)
        for row, (c, pl, t) in self.o_arc.items():
            centre[row] = c
            plane[row] = pl
            turns[row] = t
        dwell = np.zeros(n)
        for row, t in self.o_dwell.items():
            dwell[row] = t
        return Program(
            path=self.path,
            start=np.array(self.start, dtype=float),
            kind=np.array(self.o_kind, dtype=np.int8),
            end=np.array(self.o_end, dtype=float).reshape(n, 6),
            feed=np.array(self.o_feed, dtype=float),
            centre=centre,
            plane=plane,
            turns=turns,
            exact_stop=np.array(self.o_stop, dtype=bool),
            dwell_s=dwell,
            line=np.array(self.o_line, dtype=np.int64),
            lines_read=lines_read,
            skipped=self.skipped,
            substituted_feeds=self.substituted,
        )


def _fmt_code(v: float) -> str:
    return str(int(v)) if v == int(v) else f"{v:g}"


def read(
    path,
    default_feed: Optional[float] = None,
    start=None,
    text: Optional[str] = None,
) -> Program:
    """Read a G-code file (or ``text``, named ``path`` in messages).

    ``default_feed`` (mm/min) replaces feeds the reader cannot evaluate and
    is used before the first F word; without it those are errors.
    """
    if default_feed is not None and not (default_feed > 0 and math.isfinite(default_feed)):
        raise UserError(f"default feed must be a positive number, got {default_feed}")
    name = str(path)
    reader = _Reader(name, default_feed, start)
    if text is not None:
        lines_read = reader.run(text.splitlines())
    else:
        try:
            with open(Path(path), encoding="utf-8", errors="replace") as fh:
                lines_read = reader.run(fh)
        except OSError as exc:
            raise UserError(f"cannot read {name}: {exc.strerror}") from exc
    return reader.program(lines_read)


# ---- straight segments for the estimators -----------------------------------


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
    from the arc by more than ``chord_tolerance_mm``."""
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
            start=starts[:, :3].copy(),
            end=ends[:, :3].copy(),
            rotary=ends[:, 3:] - starts[:, 3:],
            feed=program.feed.copy(),
            rapid=program.kind == RAPID,
            exact_stop=program.exact_stop.copy(),
            dwell_s=program.dwell_s.copy(),
            block=np.arange(n),
            line=program.line.copy(),
        )
    # Per row: how many pieces, then the arc points.
    pieces = np.ones(n, dtype=np.int64)
    arc_pts = {}
    for i in arcs:
        pts = _arc_points(
            starts[i, :3],
            ends[i, :3],
            program.centre[i],
            int(program.plane[i]),
            program.kind[i] == ARC_CW,
            int(program.turns[i]),
            chord_tolerance_mm,
        )
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


def _arc_points(start, end, centre, plane, clockwise, turns, tol):
    u, v = ((0, 1), (2, 0), (1, 2))[plane]
    w = 3 - u - v
    cu, cv = centre[u], centre[v]
    a0 = math.atan2(start[v] - cv, start[u] - cu)
    a1 = math.atan2(end[v] - cv, end[u] - cu)
    r = math.hypot(start[u] - cu, start[v] - cv)
    if clockwise:
        sweep = a0 - a1
    else:
        sweep = a1 - a0
    sweep %= 2 * math.pi
    if sweep < 1e-12:
        sweep = 2 * math.pi
    sweep += 2 * math.pi * turns
    if tol >= r:
        k = max(1, int(math.ceil(sweep / (2 * math.pi / 3))))
    else:
        step = 2 * math.acos(1 - tol / r)
        k = max(1, int(math.ceil(sweep / step)))
    sgn = -1.0 if clockwise else 1.0
    t = np.arange(1, k + 1) / k
    ang = a0 + sgn * sweep * t
    pts = np.empty((k, 3))
    pts[:, u] = cu + r * np.cos(ang)
    pts[:, v] = cv + r * np.sin(ang)
    pts[:, w] = start[w] + (end[w] - start[w]) * t
    pts[-1] = end  # exact end point
    return pts
