"""G-code front end: text lines -> evaluated :class:`Block` s.

Interface (seam 1 of issue #17): :func:`blocks` reads lines lazily and yields
one :class:`Block` per line that carries words or messages; the interpreter
executes block k before block k+1 is evaluated. Errors are raised through
the :class:`Reporter` (``rep.error(line, message)``), reports of ignored
things through ``rep.skip(kind, line, note)``.

(First version: plain word lines, comments and messages.)
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Protocol

from contour.gcode.params import Params

LINE_CAP = 256 * 1024

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_SIMPLE_LINE = re.compile(r"(?:[A-NP-Z]\s*" + _NUM + r"\s*)+")
_SIMPLE_WORD = re.compile(r"([A-Z])\s*(" + _NUM + r")")


@dataclass
class Block:
    """One evaluated line.

    ``words``: ``(letter, value)`` in written order, ``letter`` 'A'..'Z' and
    ``value`` a finite float; Sinumerik forms as ``("=X", (value, func))``
    (func None/"DC"/"ACP"/"ACN"/"AC"/"IC"; value None when it cannot be
    evaluated, func then holds the source text), ``("CALL", name)`` for
    ``NAME(...)`` (its argument text in ``call_args[name]``) and
    ``("IDENT", name)`` for bare identifiers (``TRAORI``).
    ``messages``: texts of ``(MSG,...)``, ``(PRINT,...)``, ``(DEBUG,...)``.
    """

    line: int
    words: list
    messages: list = field(default_factory=list)
    call_args: dict = field(default_factory=dict)


class Reporter(Protocol):
    path: str

    def skip(self, kind: str, line: int, note: str = "") -> None: ...

    def error(self, line: int, message: str) -> Exception: ...


def blocks(lines: Iterable, params: Params, rep: Reporter) -> Iterator[Block]:
    """Evaluated blocks of ``lines`` (str, or bytes decoded as UTF-8)."""
    if params.rep is None:
        params.rep = rep
    simple = _SIMPLE_LINE.fullmatch
    findall = _SIMPLE_WORD.findall
    lineno = 0
    for raw in lines:
        lineno += 1
        if type(raw) is not str:
            raw = raw.decode("utf-8")
        text = raw.strip().upper()
        if not text:
            continue
        if simple(text):
            yield Block(lineno, [(a, float(b)) for a, b in findall(text)])
            continue
        words = []
        messages = []
        i = 0
        n = len(text)
        while i < n:
            c = text[i]
            if c in " \t":
                i += 1
            elif c == ";":
                break
            elif c == "(":
                j = text.find(")", i + 1)
                if j < 0:
                    raise rep.error(lineno, "unclosed comment '(' (no ')' on the line)")
                body = raw.strip()[i + 1 : j]
                head = body.lstrip()[:6].upper()
                if head.startswith(("MSG,", "PRINT,", "DEBUG,")):
                    messages.append(body.split(",", 1)[1].strip())
                i = j + 1
            else:
                m = _SIMPLE_WORD.match(text, i)
                if m is None:
                    raise rep.error(lineno, f"unexpected character '{c}'")
                words.append((m.group(1), float(m.group(2))))
                i = m.end()
        if words or messages:
            yield Block(lineno, words, messages)
