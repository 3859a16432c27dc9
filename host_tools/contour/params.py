"""Drive parameters in user units.

The protocol keeps SI integers (nm, nm/s, q32.32 gains ...; `unit` in
protocol/contour.toml). Each parameter also names the unit the host shows
(`display`) and how many raw units make one of it (`scale`), or an enum whose
value names it takes (`enum`). This module converts both ways:

* ``format_value(p, raw)`` -> ``"25 mm/s"``, ``"curvature"``;
* ``parse_value(p, text)`` -> raw integer. A bare number is in the display
  unit; a suffix picks another unit of the same kind: lengths ``nm um mm m
  in``, speeds ``mm/s mm/min m/s m/min um/s nm/s``, accelerations ``mm/s^2``
  (also ``mm/s2``, ``mm/s²``), jerks ``mm/s^3``, times ``ns us ms s``; the raw
  unit itself is accepted too (``250000000nm/s``). Enums take their value
  names (or the number); a parameter whose display unit is ``on/off`` takes
  on/off, true/false, yes/no, 1/0.
"""

from __future__ import annotations

import re
from fractions import Fraction

from contour import protocol_gen as pg
from contour.errors import UserError

# unit -> (kind, size in the kind's base unit: nm, nm/s, nm/s^2, nm/s^3, ns)
_UNITS: dict[str, tuple[str, Fraction]] = {}


def _add(kind: str, names: str, size) -> None:
    for n in names.split():
        _UNITS[n] = (kind, Fraction(size))


_add("length", "nm", 1)
_add("length", "um µm", 1000)
_add("length", "mm", 10**6)
_add("length", "m", 10**9)
_add("length", "in", 25_400_000)
_add("speed", "nm/s", 1)
_add("speed", "um/s µm/s", 1000)
_add("speed", "mm/s", 10**6)
_add("speed", "mm/min", Fraction(10**6, 60))
_add("speed", "m/s", 10**9)
_add("speed", "m/min", Fraction(10**9, 60))
for _sq in ("^2", "2", "²"):
    _add("accel", f"nm/s{_sq}", 1)
    _add("accel", f"um/s{_sq}", 1000)
    _add("accel", f"mm/s{_sq}", 10**6)
    _add("accel", f"m/s{_sq}", 10**9)
for _cu in ("^3", "3", "³"):
    _add("jerk", f"nm/s{_cu}", 1)
    _add("jerk", f"mm/s{_cu}", 10**6)
    _add("jerk", f"m/s{_cu}", 10**9)
_add("time", "ns", 1)
_add("time", "us µs", 1000)
_add("time", "ms", 10**6)
_add("time", "s", 10**9)

_NUM = re.compile(r"^\s*([-+]?(?:0x[0-9a-f]+|(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?))\s*(.*?)\s*$", re.I)
_TRUE = ("on", "true", "yes", "1")
_FALSE = ("off", "false", "no", "0")


def enum_names(p: pg.Param) -> dict[int, str]:
    """Value -> name of an enum parameter ({} for others)."""
    if not p.enum:
        return {}
    cls = getattr(pg, "".join(w.capitalize() for w in p.enum.split("_")))
    return {int(m): m.name.lower() for m in cls}


def display_unit(p: pg.Param) -> str:
    return "" if p.enum else (p.display or p.unit)


def user_value(p: pg.Param, raw: int):
    """The value in the display unit: an int when exact, else a float; the
    value name for an enum."""
    names = enum_names(p)
    if names:
        return names.get(raw, raw)
    if p.display == "on/off":
        return "on" if raw else "off"
    v = Fraction(raw) / Fraction(p.scale)
    return int(v) if v.denominator == 1 else float(v)


def format_value(p: pg.Param, raw: int) -> str:
    v = user_value(p, raw)
    if isinstance(v, float):
        v = f"{v:.12g}"
    unit = display_unit(p)
    return f"{v} {unit}" if unit and unit != "on/off" else str(v)


def _unit_size(p: pg.Param, unit: str) -> Fraction:
    """Raw units per one `unit` for parameter p."""
    if unit in ("", p.display):
        return Fraction(p.scale)
    if unit == p.unit:
        return Fraction(1)
    mine = _UNITS.get(p.unit)
    theirs = _UNITS.get(unit)
    if mine is None or theirs is None or mine[0] != theirs[0]:
        shown = p.display or p.unit
        raise UserError(f"{p.name}: unit {unit!r} does not fit a value in {shown}")
    return theirs[1] / mine[1]


def parse_value(p: pg.Param, text: str) -> int:
    """User text -> raw integer, range-checked against the protocol table."""
    t = text.strip()
    names = enum_names(p)
    if names:
        by_name = {n: v for v, n in names.items()}
        if t.lower() in by_name:
            raw = by_name[t.lower()]
        elif t.isdigit():
            raw = int(t)
        else:
            raise UserError(f"{p.name}: {text!r} is not one of {', '.join(by_name)}")
        if raw not in names:
            raise UserError(f"{p.name}: {raw} is not one of {', '.join(by_name)}")
        return raw
    if (p.display == "on/off" or p.type == "bool") and t.lower() in _TRUE + _FALSE:
        return int(t.lower() in _TRUE)
    m = _NUM.match(t.replace("_", ""))
    integer = p.scale == 1 and not p.display.startswith("2^")
    if m is None:
        kind = "an integer" if integer else "a number"
        raise UserError(f"{p.name}: {text!r} is not {kind} (unit optional: {_hint(p)})")
    num, unit = m.group(1), m.group(2)
    if num.lower().lstrip("+-").startswith("0x"):
        value = Fraction(int(num, 16))
    else:
        value = Fraction(num)
    raw_f = value * _unit_size(p, unit)
    raw = round(raw_f)  # finer than the drive's unit: rounded to it
    if raw_f != raw and integer and unit in ("", p.display):
        raise UserError(f"{p.name}: {text!r} is not an integer ({p.unit})")
    if not p.min <= raw <= p.max:
        raise UserError(f"{p.name}: {text.strip()} out of range {format_range(p, p.min, p.max)}")
    return raw


def _hint(p: pg.Param) -> str:
    mine = _UNITS.get(p.unit)
    if mine is None:
        return p.display or p.unit or "none"
    same = [u for u, (k, _) in _UNITS.items() if k == mine[0] and "²" not in u and "³" not in u]
    return ", ".join(same[:6])


def format_range(p: pg.Param, lo: int, hi: int) -> str:
    if enum_names(p):
        return f"[{format_value(p, lo)} .. {format_value(p, hi)}]"
    unit = display_unit(p)
    a, b = user_value(p, lo), user_value(p, hi)
    a = f"{a:.12g}" if isinstance(a, float) else a
    b = f"{b:.12g}" if isinstance(b, float) else b
    return f"[{a}, {b}] {unit}".rstrip()


def param_of_id(pid: int) -> tuple[pg.Param, int] | None:
    """(parameter, axis) of a wire id, None when unknown."""
    for p in pg.PARAMS:
        n = pg.MAX_AXES if p.per_axis else 1
        if p.id <= pid < p.id + n:
            return p, pid - p.id
    return None
