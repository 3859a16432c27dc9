"""RS-274/NGC real values and expressions, as LinuxCNC evaluates them.

A *real value* is a number (``-1.5``, ``.5``, ``1.``; spaces allowed inside,
``1 2`` is 12), a parameter (``#3``, ``##2``, ``#[1+2]``, ``#<name>``), an
expression in brackets, or a function (``SIN[30]``, ``ATAN[1]/[2]``,
``EXISTS[#<x>]``), optionally preceded by a sign.

Binary operators in groups of decreasing precedence, left to right inside a
group (so ``2**3**2`` is ``[2**3]**2`` = 64):

    **  |  * / MOD  |  + -  |  EQ NE GT GE LT LE  |  AND OR XOR

Comparisons give 1 or 0, values within 1e-6 compare equal (LinuxCNC's
TOLERANCE_EQUAL); logic takes non-zero as true; angles are degrees. A
result that is not a finite number (``SQRT[-1]``, ``[1/0]``, ``LN[0]``,
``EXP[1000]``) is an error naming the operation.

Text is upper-case with comments removed; :meth:`Evaluator.value` reads at
position ``i`` and returns ``(value, next position)``.
"""

from __future__ import annotations

import math
import re

_NUMBER = re.compile(r"[0-9][0-9 \t]*(?:\.[0-9 \t]*)?|\.[ \t]*[0-9][0-9 \t]*", re.ASCII)
_PLAIN_NUMBER = re.compile(r"[0-9]+(?:\.[0-9]*)?|\.[0-9]+", re.ASCII)
_WS = " \t"
TOLERANCE_EQUAL = 1e-6
MAX_DEPTH = 32  # brackets, indirections and signs nested in one value

# Operators by group, longest spelling first within the scan below.
_GROUP = {
    "**": 4,
    "*": 3,
    "/": 3,
    "MOD": 3,
    "+": 2,
    "-": 2,
    "EQ": 1,
    "NE": 1,
    "GT": 1,
    "GE": 1,
    "LT": 1,
    "LE": 1,
    "AND": 0,
    "OR": 0,
    "XOR": 0,
}
_OPERATOR = re.compile(r"\*\*|[*/+-]|MOD|EQ|NE|GT|GE|LT|LE|AND|OR|XOR")
FUNCTIONS = (
    "ABS",
    "ACOS",
    "ASIN",
    "ATAN",
    "COS",
    "EXISTS",
    "EXP",
    "FIX",
    "FUP",
    "LN",
    "ROUND",
    "SIN",
    "SQRT",
    "TAN",
)
_FUNC_AT = re.compile(r"(" + "|".join(sorted(FUNCTIONS, key=len, reverse=True)) + r")[ \t]*\[")
_NAME_END = re.compile(r"[^>]*>")


class ExprError(Exception):
    """Raised with a message; the caller adds ``file:line``."""


class TooLarge(ExprError):
    pass


class Malformed(ExprError):
    """A line that does not follow the syntax."""


def _round(v: float) -> float:
    # LinuxCNC rounds halves away from zero.
    return float(math.floor(abs(v) + 0.5)) * (1.0 if v >= 0 else -1.0)


def _check(v: float, what: str) -> float:
    if v != v or v in (math.inf, -math.inf):
        raise ExprError(f"{what} is not a finite number")
    return v


def _unary(name: str, a: float) -> float:
    if name == "ABS":
        return abs(a)
    if name == "ACOS" or name == "ASIN":
        if a < -1.0 or a > 1.0:
            raise ExprError(f"{name}[{a:g}]: argument outside -1..1")
        return math.degrees(math.acos(a) if name == "ACOS" else math.asin(a))
    if name == "ATAN":
        return math.degrees(math.atan(a))
    if name == "COS":
        return math.cos(math.radians(a))
    if name == "SIN":
        return math.sin(math.radians(a))
    if name == "TAN":
        return _check(math.tan(math.radians(a)), f"TAN[{a:g}]")
    if name == "EXP":
        try:
            return math.exp(a)
        except OverflowError:
            raise ExprError(f"EXP[{a:g}] is not a finite number") from None
    if name == "LN":
        if a <= 0.0:
            raise ExprError(f"LN[{a:g}]: argument must be positive")
        return math.log(a)
    if name == "SQRT":
        if a < 0.0:
            raise ExprError(f"SQRT[{a:g}]: negative argument")
        return math.sqrt(a)
    if name == "FIX":
        return float(math.floor(a))
    if name == "FUP":
        return float(math.ceil(a))
    return _round(a)  # ROUND


def _binary(op: str, a: float, b: float) -> float:
    if op == "+":
        return _check(a + b, f"{a:g} + {b:g}")
    if op == "-":
        return _check(a - b, f"{a:g} - {b:g}")
    if op == "*":
        return _check(a * b, f"{a:g} * {b:g}")
    if op == "/":
        if b == 0.0:
            raise ExprError(f"division by zero ({a:g} / 0)")
        return _check(a / b, f"{a:g} / {b:g}")
    if op == "MOD":
        if b == 0.0:
            raise ExprError(f"{a:g} MOD 0: division by zero")
        r = math.fmod(a, b)
        if r < 0.0:
            r += abs(b)  # LinuxCNC: the result lies in [0, |b|)
        return r
    if op == "**":
        if a < 0.0 and b != math.floor(b):
            raise ExprError(f"{a:g} ** {b:g}: negative number to a non-integer power")
        if a == 0.0 and b < 0.0:
            raise ExprError(f"0 ** {b:g}: zero to a negative power")
        try:
            return _check(math.pow(a, b), f"{a:g} ** {b:g}")
        except OverflowError:
            raise ExprError(f"{a:g} ** {b:g} is not a finite number") from None
    if op == "EQ":
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL else 0.0
    if op == "NE":
        return 0.0 if abs(a - b) < TOLERANCE_EQUAL else 1.0
    if op == "GT":
        return 1.0 if a > b else 0.0
    if op == "GE":
        return 1.0 if a >= b else 0.0
    if op == "LT":
        return 1.0 if a < b else 0.0
    if op == "LE":
        return 1.0 if a <= b else 0.0
    if op == "AND":
        return 1.0 if (a != 0.0 and b != 0.0) else 0.0
    if op == "OR":
        return 1.0 if (a != 0.0 or b != 0.0) else 0.0
    return 1.0 if ((a != 0.0) != (b != 0.0)) else 0.0  # XOR


def _skip(s: str, i: int) -> int:
    n = len(s)
    while i < n and (s[i] == " " or s[i] == "\t"):
        i += 1
    return i


def number_at(s: str, i: int):
    """Unsigned number at ``s[i]`` (spaces inside allowed): (value, end) or None."""
    m = _PLAIN_NUMBER.match(s, i)
    if m is not None:
        end = m.end()
        if end >= len(s) or s[end] not in _WS:
            v = float(m.group(0))
            if v == math.inf:
                raise TooLarge(f"number too large: {m.group(0)[:20]}...")
            return v, end
    m = _NUMBER.match(s, i)
    if m is None:
        return None
    text = m.group(0)
    # Trailing blanks belong to the gap, not to the number.
    end = m.start() + len(text.rstrip(_WS))
    v = float(text.replace(" ", "").replace("\t", ""))
    if v == math.inf:
        raise TooLarge(f"number too large: {text[:20].strip()}...")
    return v, end


def name_at(s: str, i: int):
    """``<name>`` at ``s[i]``: (key, end) with spaces removed and lower-cased."""
    m = _NAME_END.match(s, i + 1)
    if m is None:
        raise ExprError("unclosed parameter name '<' (no '>')")
    key = s[i + 1 : m.end() - 1].replace(" ", "").replace("\t", "").lower()
    if not key:
        raise ExprError("empty parameter name #<>")
    return key, m.end()


class Evaluator:
    """Evaluates values against ``params`` (reads only; the caller applies
    a line's assignments after the whole line is read)."""

    def __init__(self, params):
        self.params = params
        self.line = 0
        self.depth = 0

    def _enter(self):
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise ExprError(f"expression nested deeper than {MAX_DEPTH} levels")

    # ---- parameters -----------------------------------------------------
    def param_key(self, s: str, i: int):
        """Key of the parameter whose ``#`` is at ``s[i]``: (key, end)."""
        i = _skip(s, i + 1)
        if i < len(s) and s[i] == "<":
            return name_at(s, i)
        v, i = self.value(s, i)
        return self.params.index(v, self.line), i

    # ---- values -----------------------------------------------------------
    def value(self, s: str, i: int):
        self._enter()
        try:
            return self._value(s, i)
        finally:
            self.depth -= 1

    def _value(self, s: str, i: int):
        i = _skip(s, i)
        n = len(s)
        if i >= n:
            raise ExprError("value missing at the end of the line")
        c = s[i]
        if c == "[":
            return self.bracket(s, i)
        if c == "#":
            key, i = self.param_key(s, i)
            return self.params.get(key, self.line), i
        if c == "-" or c == "+":
            v, i = self.value(s, i + 1)
            return (-v if c == "-" else v), i
        if "0" <= c <= "9" or c == ".":
            r = number_at(s, i)
            if r is None:
                raise ExprError(f"malformed number at '{_show(s, i)}'")
            return r
        if "A" <= c <= "Z":
            m = _FUNC_AT.match(s, i)
            if m is not None:
                return self.function(m.group(1), s, m.end() - 1)
        raise ExprError(f"value expected at '{_show(s, i)}'")

    def function(self, name: str, s: str, i: int):
        """``NAME[...]`` with ``s[i]`` the '['."""
        if name == "EXISTS":
            j = _skip(s, i + 1)
            if j >= len(s) or s[j] != "#" or _skip(s, j + 1) >= len(s):
                raise ExprError("EXISTS takes one named parameter: EXISTS[#<name>]")
            j = _skip(s, j + 1)
            if s[j] != "<":
                raise ExprError("EXISTS takes one named parameter: EXISTS[#<name>]")
            key, j = name_at(s, j)
            j = _skip(s, j)
            if j >= len(s) or s[j] != "]":
                raise ExprError("EXISTS takes one named parameter: EXISTS[#<name>]")
            return (1.0 if self.params.exists(key) else 0.0), j + 1
        a, i = self.bracket(s, i)
        if name == "ATAN":
            j = _skip(s, i)
            if j >= len(s) or s[j] != "/":
                # LinuxCNC requires the two-argument form.
                raise ExprError("ATAN needs two arguments: ATAN[y]/[x]")
            j = _skip(s, j + 1)
            if j >= len(s) or s[j] != "[":
                raise ExprError("ATAN needs two arguments: ATAN[y]/[x]")
            b, i = self.bracket(s, j)
            return math.degrees(math.atan2(a, b)), i
        return _unary(name, a), i

    def bracket(self, s: str, i: int):
        """Expression ``[ ... ]`` with ``s[i]`` the '['."""
        self._enter()
        try:
            v, i = self._binary(s, i + 1)
        finally:
            self.depth -= 1
        i = _skip(s, i)
        if i >= len(s):
            raise ExprError("unclosed expression '[' (no ']')")
        if s[i] != "]":
            raise ExprError(f"operator or ']' expected at '{_show(s, i)}'")
        return v, i + 1

    def _binary(self, s: str, i: int):
        """Operands and binary operators up to the closing ']': operator
        precedence with a stack, left to right within a group."""
        values = []
        ops = []
        v, i = self.value(s, i)
        n = len(s)
        while True:
            while i < n and (s[i] == " " or s[i] == "\t"):
                i += 1
            m = _OPERATOR.match(s, i)
            if m is None:
                break
            op = m.group(0)
            g = _GROUP[op]
            while ops and _GROUP[ops[-1]] >= g:
                v = _binary(ops.pop(), values.pop(), v)
            values.append(v)
            ops.append(op)
            v, i = self.value(s, m.end())
        while ops:
            v = _binary(ops.pop(), values.pop(), v)
        return v, i


def _show(s: str, i: int) -> str:
    t = s[i : i + 12].strip()
    return t if t else "end of line"
