"""LinuxCNC tool tables (``--tool-table``): ``load(path) -> dict[int, Tool]``.

One tool per line, words separated by blanks, a ``;`` starts a comment that
runs to the end of the line (the tool's description)::

    T1 P1 D6.0 Z+35.2 ;6 mm end mill
    T2 P2 X0 Z41.05 D3.175 I0 J0 Q0 ;1/8 in drill

Words (letter case does not matter): ``T`` tool number (required, integer
>= 0, once per table), ``P`` pocket (integer >= 0), ``D`` diameter (>= 0),
``X Y Z A B C U V W`` offsets, ``I`` front angle, ``J`` back angle, ``Q``
orientation (integer 0..9, lathe tools). Blank lines and comment-only lines
are skipped.

Units: LinuxCNC keeps the table in the machine's units and says nothing in
the file. Here lengths are mm unless the file says otherwise in a comment
line before the first tool, ``;units: inch`` (or ``;units: mm``), or the
caller passes ``unit_mm=25.4``. :class:`Tool` holds mm and degrees.

Every malformed line is a :class:`ToolTableError` naming ``file:line``: an
unknown letter, a word without a number or with a malformed one, a
non-finite value, a repeated word, a line without ``T``, a tool number
listed twice, a negative diameter, a non-integer ``T``/``P``/``Q``, the
pre-2.4 column format (``POC FMS LEN DIAM``), a line longer than
:data:`MAX_LINE`, text that is not UTF-8.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from contour.errors import FileLineError, UserError

MAX_LINE = 4096
MAX_TOOLS = 100_000

_LETTERS = "TPDXYZABCUVWIJQ"
_OFFSET_LETTERS = "XYZABCUVW"
_ROTARY = "ABC"
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_UNITS = re.compile(r"^\s*;\s*units\s*[:=]?\s*(\w+)\s*$", re.IGNORECASE)


class ToolTableError(FileLineError):
    """A tool table line that cannot be used, at ``file:line``."""


@dataclass
class Tool:
    number: int
    pocket: Optional[int] = None
    diameter: float = 0.0  # mm
    # X Y Z U V W in mm, A B C in degrees; only the words written.
    offsets: dict = field(default_factory=dict)
    front_angle: float = 0.0  # I, degrees
    back_angle: float = 0.0  # J, degrees
    orientation: int = 0  # Q
    comment: str = ""
    line: int = 0  # line of the table

    @property
    def radius(self) -> float:
        return self.diameter / 2.0


def load(path, unit_mm: Optional[float] = None) -> dict[int, Tool]:
    """Read a LinuxCNC tool table; ``unit_mm`` (mm per file unit) overrides
    the file's ``;units:`` line."""
    name = str(path)
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise UserError(f"{name}: cannot read the tool table: {e.strerror or e}") from None
    return parse(data, name, unit_mm)


def parse(data, name: str = "<tool table>", unit_mm: Optional[float] = None) -> dict[int, Tool]:
    """:func:`load` on the bytes (or text) of a table."""
    if isinstance(data, bytes):
        if b"\0" in data:
            raise ToolTableError(name, 1, "binary file, not a tool table")
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as e:
            lineno = data[: e.start].count(b"\n") + 1
            raise ToolTableError(name, lineno, "not UTF-8 text, not a tool table") from None
    else:
        text = data
    scale = unit_mm
    tools: dict[int, Tool] = {}
    for lineno, raw in enumerate(text.splitlines(), 1):
        if len(raw) > MAX_LINE:
            raise ToolTableError(name, lineno, f"line longer than {MAX_LINE} characters")
        body, sep, comment = raw.partition(";")
        if not body.strip():
            m = _UNITS.match(raw)
            if m:
                if tools:
                    raise ToolTableError(name, lineno, "the units line must come before the tools")
                unit = m.group(1).lower()
                file_scale = {"mm": 1.0, "metric": 1.0, "inch": 25.4, "in": 25.4}.get(unit)
                if file_scale is None:
                    raise ToolTableError(name, lineno, f"unknown units {m.group(1)!r} (mm or inch)")
                if unit_mm is None:
                    scale = file_scale
            continue
        tool = _parse_line(body, name, lineno, 1.0 if scale is None else scale)
        tool.comment = comment.strip() if sep else ""
        if tool.number in tools:
            first = tools[tool.number].line
            raise ToolTableError(
                name, lineno, f"T{tool.number} is listed twice (first on line {first})"
            )
        if len(tools) >= MAX_TOOLS:
            raise ToolTableError(name, lineno, f"more than {MAX_TOOLS} tools")
        tools[tool.number] = tool
    return tools


def _parse_line(body: str, name: str, lineno: int, scale: float) -> Tool:
    words: dict[str, float] = {}
    tokens = body.split()
    if tokens and (tokens[0][0].isdigit() or tokens[0][0] in "+-."):
        raise ToolTableError(
            name,
            lineno,
            "old column format (POC FMS LEN DIAM) is not supported; "
            "write T<n> P<pocket> D<diameter> Z<offset>",
        )
    for tok in tokens:
        letter = tok[0].upper()
        if letter not in _LETTERS:
            raise ToolTableError(name, lineno, f"unknown word {tok!r} in a tool table")
        text = tok[1:]
        if not text:
            raise ToolTableError(name, lineno, f"{letter} without a value")
        if not _NUMBER.match(text):
            raise ToolTableError(name, lineno, f"malformed number in {tok!r}")
        value = float(text)
        if not math.isfinite(value):
            raise ToolTableError(name, lineno, f"{tok!r} is out of range")
        if letter in words:
            raise ToolTableError(name, lineno, f"{letter} given twice")
        words[letter] = value
    if "T" not in words:
        raise ToolTableError(name, lineno, "tool line without a T word")
    number = _integer(words, "T", name, lineno)
    tool = Tool(number=number, line=lineno)
    if "P" in words:
        tool.pocket = _integer(words, "P", name, lineno)
    if "D" in words:
        d = words["D"] * scale
        if d < 0.0:
            raise ToolTableError(name, lineno, f"T{number}: negative diameter D{words['D']:g}")
        tool.diameter = d
    for letter in _OFFSET_LETTERS:
        if letter in words:
            tool.offsets[letter] = words[letter] * (1.0 if letter in _ROTARY else scale)
    tool.front_angle = words.get("I", 0.0)
    tool.back_angle = words.get("J", 0.0)
    if "Q" in words:
        q = _integer(words, "Q", name, lineno)
        if q > 9:
            raise ToolTableError(name, lineno, f"T{number}: orientation Q{q} (0..9)")
        tool.orientation = q
    return tool


def _integer(words: dict, letter: str, name: str, lineno: int) -> int:
    v = words[letter]
    if v != math.floor(v) or v < 0 or v > 2**31 - 1:
        raise ToolTableError(
            name, lineno, f"{letter}{v:g}: {letter} must be a non-negative integer"
        )
    return int(v)
