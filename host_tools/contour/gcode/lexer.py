"""G-code front end: text lines -> evaluated :class:`Block` s (RS-274/NGC as
LinuxCNC reads it, plus the Sinumerik words the reader has always taken).

Interface (seam 1 of issue #17)::

    blocks(lines, params, rep) -> Iterator[Block]

``lines`` yields ``str`` or ``bytes`` (decoded as UTF-8; :func:`file_lines`
reads a file that way with the line-length cap). The generator is lazy: the
interpreter executes block k before block k+1 is evaluated, so ``#5420`` or
``#<_x>`` read on a line see the state after the blocks before it. A block is
yielded for every line that has words or messages; parameter assignments,
O-word control flow and comments are handled here.

Errors go through ``rep.error(line, message)`` (the reporter returns the
exception to raise); things read and deliberately ignored (block delete
switch, LinuxCNC log comments, program numbers) through ``rep.skip``.

Line rules: spaces are allowed anywhere outside comments (``G0X +0. 12 34Y
7`` is ``G0 X0.1234 Y7``); case is folded outside comments; ``( )`` comments
may not nest and must close on their line; ``;`` comments the rest; of
several comments on a line only the last is active (``(MSG,..)``,
``(DEBUG,..)``, ``(PRINT,..)``, the last two with ``#`` substitution);
``/`` first on a line is block delete (the switch is off: the block runs,
reported once); a word is a letter and a real value (number, ``#n``,
``#<name>``, ``[expr]`` or a function); ``#..=value`` sets a parameter after
the whole line is read.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from typing import Protocol

from contour.gcode import dialect
from contour.gcode.comments import OKEYS, active, balanced, split
from contour.gcode.expr import FUNCTIONS, Evaluator, ExprError, Malformed, TooLarge, number_at
from contour.gcode.params import Params

LINE_CAP = 256 * 1024  # characters (bytes for bytes input) in one line

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
# Fast path: a line of blank-separated plain words, an N number first
# perhaps; O (control flow) is not a plain word; at most 30 digits a side
# so that every number is finite.
_PLAIN_NUM = r"[+-]?(?:\d{1,30}(?:\.\d{0,30})?|\.\d{1,30})"
PLAIN_LINE = re.compile(
    r"\s*(?:N\d{1,30}\s*)?((?:[A-MP-Z]" + _PLAIN_NUM + r"\s+)*[A-MP-Z]" + _PLAIN_NUM + r")\s*",
    re.ASCII,
)

_IDENT_AT = re.compile(r"[A-Z_$][A-Z0-9_$]*")
_KEYWORD = re.compile(r"[A-Z]+")
_FUNC_NAME = re.compile(
    "(?:" + "|".join(sorted(FUNCTIONS, key=len, reverse=True)) + r")(?=[ \t]*\[)"
)
_GAP = " \t\x01"  # \x01 stands for a comment: it separates words


class Block:
    """One evaluated line.

    ``words``: ``(letter, value)`` in written order, ``letter`` 'A'..'Z' and
    ``value`` a finite float (``N`` line numbers are not words and are left
    out, as RS-274/NGC says); Sinumerik forms as ``("=X", (value, func))``
    (func None/"DC"/"ACP"/"ACN"/"AC"/"IC"; value None when it cannot be
    evaluated here, func then holds the source text, e.g. ``F=R7`` with R7
    unknown), ``("CALL", name)`` for ``NAME(...)`` (argument text in
    ``call_args[name]``), ``("IDENT", name)`` for a bare Sinumerik word
    (``TRAORI``) and ``("IDENT", name + "=")`` for ``NAME=...``.
    ``messages``: texts of ``(MSG,...)``, ``(PRINT,...)``, ``(DEBUG,...)``
    (an empty tuple when there are none: blocks share it, do not append).
    """

    __slots__ = ("line", "words", "messages", "call_args")

    def __init__(self, line: int, words: list, messages=(), call_args=None):
        self.line = line
        self.words = words
        self.messages = messages
        self.call_args = _NO_ARGS if call_args is None else call_args

    def __eq__(self, other):
        return isinstance(other, Block) and (
            self.line,
            self.words,
            list(self.messages),
            self.call_args,
        ) == (other.line, other.words, list(other.messages), other.call_args)

    def __repr__(self):
        return f"Block(line={self.line}, words={self.words!r}, messages={list(self.messages)!r}" + (
            f", call_args={self.call_args!r})" if self.call_args else ")"
        )


_NO_ARGS: dict = {}
ENDS = (("M", 2.0), ("M", 30.0))


def plain_words(raw: str):
    """Words of a line made only of blank-separated plain words (after an
    optional ``N`` number), or None: the fast path for CAM output. One
    regex decides; the tokens are then split on blanks."""
    m = PLAIN_LINE.fullmatch(raw)
    if m is None:
        u = raw.upper()
        if u == raw:
            return None
        m = PLAIN_LINE.fullmatch(u)
        if m is None:
            return None
    return [(t[0], float(t[1:])) for t in m.group(1).split()]


class Reporter(Protocol):
    path: str

    def skip(self, kind: str, line: int, note: str = "") -> None: ...

    def error(self, line: int, message: str) -> Exception: ...


def blocks(lines: Iterable, params: Params, rep: Reporter) -> Iterator[Block]:
    """Evaluated blocks of ``lines`` (str, or bytes decoded as UTF-8)."""
    from contour.gcode.flow import Runner  # flow builds on this module

    if params.rep is None:
        params.rep = rep
    return Runner(lines, params, rep).run()


def file_lines(fh, cap: int = LINE_CAP) -> Iterator[bytes]:
    """Lines of a binary file object, each at most ``cap + 2`` bytes: a longer
    line is cut there (and :func:`blocks` refuses it), so memory stays
    bounded whatever the file holds."""
    readline = fh.readline
    limit = cap + 2  # the line and its CR LF
    while True:
        line = readline(limit)
        if not line:
            return
        yield line
        if len(line) == limit and not line.endswith(b"\n"):
            return  # blocks() stops at this line


class Line:
    """What one line says, evaluated. ``oword``: None or ``(label, keyword,
    values)`` with label ``"100"`` or ``"<name>"``."""

    __slots__ = ("words", "messages", "assigns", "oword", "call_args")

    def __init__(self):
        self.words = []
        self.messages = []
        self.assigns = []
        self.oword = None
        self.call_args = {}


def _skip(s: str, i: int) -> int:
    n = len(s)
    while i < n and s[i] in _GAP:
        i += 1
    return i


def _token(s: str, i: int) -> str:
    """The text from s[i] to the next blank, for messages (cut at 40)."""
    j = i
    n = min(len(s), i + 40)
    while j < n and s[j] not in _GAP and s[j] != ";":
        j += 1
    t = s[i:j] if j > i else s[i : i + 1]
    return t + "..." if j == i + 40 else t


class Tokenizer:
    """Reads one line into a :class:`Line`."""

    def __init__(self, params: Params, rep: Reporter):
        self.params = params
        self.rep = rep
        self.ev = Evaluator(params)
        self.ended = False  # an M2 or M30 was read

    def parse(self, text: str, lineno: int) -> Line:
        """``text``: one stripped line (original case)."""
        try:
            return self._parse(text, lineno)
        except ExprError as exc:
            hint = dialect.hint(text)
            raise self.rep.error(lineno, hint or str(exc)) from None

    def _parse(self, text: str, lineno: int) -> Line:
        self.ev.line = lineno
        line = Line()
        code, comments = split(text)
        if not code.isascii():
            c = next(c for c in code if not c.isascii())
            raise Malformed(f"unexpected character '{c}' (U+{ord(c):04X})")
        if comments:
            active(comments[-1], line.messages, lineno, self.params, self.rep)
        s = code.upper()
        n = len(s)
        i = _skip(s, 0)
        if i < n and s[i] == "/":
            self.rep.skip("/ (block delete)", lineno, "block delete switch off: block executed")
            i = _skip(s, i + 1)
        if i < n and s[i] == "N":
            # Line number: N, an unsigned integer, optionally .digits.
            r = number_at(s, _skip(s, i + 1))
            if r is None:
                raise Malformed(f"malformed line number '{_token(s, i)}'")
            i = _skip(s, r[1])
        if i < n and s[i] == "O":
            self._oword(s, i, line, lineno)
            return line
        while True:
            i = _skip(s, i)
            if i >= n:
                return line
            c = s[i]
            if c == "#":
                key, j = self.ev.param_key(s, i)
                j = _skip(s, j)
                if j >= n or s[j] != "=":
                    raise Malformed(f"'=' expected after parameter '{_token(s, i)}'")
                v, i = self.ev.value(s, j + 1)
                line.assigns.append((key, v))
            elif "A" <= c <= "Z":
                nxt = s[i + 1] if i + 1 < n else ""
                if "A" <= nxt <= "Z" or nxt == "_" or nxt == "$":
                    m = _FUNC_NAME.match(s, i + 1)
                    if m is not None and c != "O":
                        v, i = self.ev.function(m.group(0), s, _skip(s, m.end()))
                        line.words.append((c, v))
                    else:
                        i = self._identifier(s, i, line, lineno)
                else:
                    i = self._word(s, c, i, line)
            elif c == "_" or c == "$":
                i = self._identifier(s, i, line, lineno)
            elif c == "@" or c == "^":
                raise Malformed("polar coordinates (@ ^) are not supported")
            elif c < " " or c == "\x7f":
                raise Malformed(f"control character 0x{ord(c):02x} in the line (binary file?)")
            else:
                raise Malformed(f"unexpected character '{c}'")

    # ---- words ------------------------------------------------------------
    def _word(self, s: str, c: str, i: int, line: Line) -> int:
        n = len(s)
        j = i + 1
        while j < n and (s[j] == " " or s[j] == "\t"):
            j += 1  # a comment may not stand between a letter and its value
        if j < n and s[j] == "=":
            return dialect.sinumerik_assign(s, c, j + 1, line.words, self.params)
        if c == "O":
            raise Malformed("an O-word must begin its line (O-words are control flow)")
        if c == "N":
            raise Malformed(f"line number '{_token(s, i)}' must begin the line")
        k = j
        if k < n and s[k] in "+-":
            k = _skip(s, k + 1)
        if k == j and k < n and "A" <= s[k] <= "Z" and not _FUNC_NAME.match(s, k):
            raise Malformed(f"value expected at '{_token(s, k)}' after {c}")
        if k >= n or s[k] in ".0123456789" or (s[k] not in "[#" and not _FUNC_NAME.match(s, k)):
            # A number (or nothing usable): one message for its faults.
            try:
                v, j = self.ev.value(s, j)
            except TooLarge:
                raise
            except ExprError:
                raise Malformed(f"malformed number in '{_token(s, i)}'") from None
            if j < n and s[j] in "-+.0123456789":
                raise Malformed(f"malformed number in '{_token(s, i)}'")
        else:
            v, j = self.ev.value(s, j)
        if c == "R":
            k = _skip(s, j)
            if k < n and s[k] == "=":
                return dialect.r_assign(v, s, k + 1, self.params, self.rep, self.ev.line)
        if c == "M" and (v == 2.0 or v == 30.0):
            self.ended = True
        line.words.append((c, v))
        return j

    def _identifier(self, s: str, i: int, line: Line, lineno: int) -> int:
        m = _IDENT_AT.match(s, i)
        name = m.group(0)
        j = m.end()
        n = len(s)
        why = dialect.identifier(name, s[j : j + 1])
        if why:
            raise Malformed(why)
        if j < n and s[j] == "(":
            k = balanced(s, j)
            line.words.append(("CALL", name))
            line.call_args[name] = s[j + 1 : k - 1].strip()
            return k
        k = _skip(s, j)
        if k < n and s[k] == "=":
            line.words.append(("IDENT", name + "="))
            return dialect.value_end(s, k + 1)
        if name in dialect.SINUMERIK_WORDS or (name[0] in "_$" and len(name) > 1):
            line.words.append(("IDENT", name))
            return j
        raise Malformed(_bad_word(name))

    # ---- O-words ------------------------------------------------------------
    def _oword(self, s: str, i: int, line: Line, lineno: int) -> None:
        n = len(s)
        j = _skip(s, i + 1)
        if j < n and s[j] == "<":
            k = s.find(">", j)
            if k < 0:
                raise Malformed("unclosed O-word name 'O<' (no '>')")
            label = "<" + s[j + 1 : k].replace(" ", "").replace("\t", "").lower() + ">"
            if label == "<>":
                raise Malformed("empty O-word name O<>")
            j = k + 1
        elif j < n and s[j] == "[":
            v, j = self.ev.bracket(s, j)
            label = str(self.params.index(v, lineno))
        else:
            r = number_at(s, j)
            if r is None or r[0] != int(r[0]):
                raise Malformed(f"malformed O-word '{_token(s, i)}'")
            label = str(int(r[0]))
            j = r[1]
        j = _skip(s, j)
        m = _KEYWORD.match(s, j)
        if m is None:
            if j >= n and not line.words:
                # A program number (O1000 at the top of CAM output).
                self.rep.skip("O (program number)", lineno, "program number, no effect")
                return
            raise Malformed(f"O{label} without a keyword (sub, call, if, while ...)")
        key = m.group(0)
        if key not in OKEYS:
            raise Malformed(f"unknown O-word keyword '{key.lower()}'")
        values = []
        j = _skip(s, m.end())
        while j < n:
            if s[j] != "[":
                raise Malformed(
                    f"O{label} {key.lower()}: unexpected '{_token(s, j)}' "
                    "(other words are not allowed on an O-word line; arguments go in [ ])"
                )
            v, j = self.ev.bracket(s, j)
            values.append(v)
            j = _skip(s, j)
        need = {"IF": 1, "ELSEIF": 1, "WHILE": 1, "REPEAT": 1}.get(key)
        most = 30 if key == "CALL" else (1 if key in ("RETURN", "ENDSUB") else (need or 0))
        if need and len(values) != need:
            raise Malformed(f"O{label} {key.lower()} needs a condition [..]")
        if len(values) > most:
            raise Malformed(f"O{label} {key.lower()}: too many values in [ ]")
        line.oword = (label, key, values)


def _bad_word(name: str) -> str:
    if len(name) < 2 or not ("A" <= name[0] <= "Z"):
        return f"unknown word '{name}'"
    note = f"{name[0]} has no value"
    if name[1] == "O" and len(name) > 2 and name[2] in "O0123456789":
        note += " (letter O written for zero?)"
    return f"malformed word '{name}': {note}"
