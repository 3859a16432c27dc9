"""Canned cycles G73 G81 G82 G83 G85 G89 expanded into straight moves, as
LinuxCNC's RS-274/NGC interpreter defines them.

Interface (for the interpreter)::

    state = CycleState()                 # one per program
    state.retract = 98 | 99              # set on G98 / G99 (before expand on the same line)
    state.cancel()                       # on G80 and on any non-cycle motion (G0 G1 G2 G3 ...)
    moves = expand(code, words, state, pos, plane, incremental, line, error,
                   unit_mm=1.0, comp_on=False, inverse_time=False)

- ``code``: 73, 81, 82, 83, 85 or 89 (the cycle of this block: written on
  the line, or the modal one when the line has axis words only).
- ``words``: mapping letter -> value of the block's words (``X Y Z A B C R Q
  P L``; other letters are ignored), in program units; ``unit_mm`` converts
  lengths to mm (25.4 under G20). ``P`` is seconds, ``L`` a count.
- ``pos``: the current position, 6 floats (X Y Z mm, A B C deg), in program
  coordinates (units converted, before work offsets), which is also the
  coordinate system of the targets returned.
- ``plane``: 0 G17 (Z drills), 1 G18 (Y drills, ZX plane), 2 G19 (X drills,
  YZ plane).
- ``incremental``: G91 is in effect.
- ``error(line, message)`` returns the exception to raise.

Returns a list of ``(kind, target, dwell_s)``: ``kind`` is ``moves.RAPID``,
``moves.LINEAR`` (at the current feed) or ``moves.DWELL`` (target is the
position, ``dwell_s`` the time); ``target`` a 6-tuple. The interpreter's
position after the block is the target of the last entry. The state keeps
the sticky words, so call ``expand`` only for a block that executes a cycle:
one with a cycle G code, or one with axis words while a cycle is modal (a
block without axis words and without a cycle code, ``F100`` or ``M8``, does
not drill).

Rules (XY plane; the other planes are analogous with the drill axis their
normal):

- ``R`` (retract plane), ``Z`` (bottom) are required on the first block of a
  cycle and sticky while the same cycle stays modal; ``Q`` (peck, G73/G83)
  and ``P`` (dwell, G82/G89) likewise. ``L`` (repeats, default 1) is not.
- Absolute: X Y are the hole, R and Z levels. Incremental: R is relative to
  the initial level, Z relative to R; X Y are increments applied before each
  of the L repeats (holes along a line).
- Initial level: the drill-axis position when the first cycle block after a
  non-cycle motion began; kept through the following cycle blocks. G98
  retracts to it (to R if it lies below R), G99 to R.
- Preliminary motion: if the initial level is below R, rapid along the drill
  axis to R. Then on the first repeat, if the drill axis is above R, a rapid
  to the hole at that height and a rapid down to R; otherwise (and on every
  further repeat) a rapid to the hole at the clear level, then down to R
  when the clear level is above it.
- G81: feed to Z, rapid to the clear level. G82: G81 with a dwell P at Z.
  G85: feed to Z, feed out to R, rapid to the clear level. G89: G85 with a
  dwell P at Z, fed out straight to the clear level. G73: feed down by Q (or
  to Z when less deep), rapid back up 0.254 mm (0.010 in), again until Z,
  then rapid to the clear level. G83: feed down by Q (or to Z), rapid out to
  R, rapid back to 0.254 mm above the depth reached, again until Z, then
  rapid to the clear level.
- Errors: R or Z missing on the first block of a cycle, R below Z, L not a
  positive integer, a block without any X Y Z word, Q missing or <= 0
  (G73/G83), P missing or negative (G82/G89), a rotary axis that would move,
  cutter compensation on, inverse-time feed, more than MAX_MOVES moves.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from contour.gcode.moves import DWELL, LINEAR, RAPID

CYCLES = (73, 81, 82, 83, 85, 89)

# Back-off of G73's chip-break retract and G83's rapid re-entry above the
# depth already drilled: LinuxCNC uses 0.010 in (in mm: 0.254).
PECK_CLEARANCE_MM = 0.254

# Bound on the moves of one block (a tiny Q or a huge L would otherwise
# allocate without limit).
MAX_MOVES = 100_000

# (first in-plane axis, second in-plane axis, drill axis) per plane.
_PLANE_AXES = ((0, 1, 2), (2, 0, 1), (1, 2, 0))
_LETTERS = "XYZABC"
_PLANE_NAMES = ("G17 (XY)", "G18 (ZX)", "G19 (YZ)")


class CycleState:
    """Modal state of the canned cycles across blocks."""

    def __init__(self) -> None:
        # 98: back to the initial level, 99: to R. G98 until told: the usual
        # startup code, and the higher (safer) retract.
        self.retract = 98
        self.cancel()

    def cancel(self) -> None:
        """G80, or any motion that is not a canned cycle: the next cycle block
        needs its R and Z (and Q/P) again and takes a new initial level."""
        self.code: int | None = None  # cycle modal since the last cancel
        self.r: float = math.nan  # mm, as written (absolute or incremental)
        self.depth: float = math.nan  # mm, the Z word (absolute or incremental)
        self.q: float = math.nan  # mm
        self.p: float = math.nan  # s
        self.initial: float | None = None  # drill-axis level, program coordinates


def _err(error: Callable, line: int, code: int, msg: str) -> Exception:
    return error(line, f"G{code}: {msg}")


def expand(
    code: int,
    words: Mapping[str, float],
    state: CycleState,
    pos,
    plane: int,
    incremental: bool,
    line: int,
    error: Callable[[int, str], Exception],
    *,
    unit_mm: float = 1.0,
    comp_on: bool = False,
    inverse_time: bool = False,
) -> list:
    """The moves of one canned-cycle block; see the module docstring."""
    if code not in CYCLES:
        raise error(line, f"G{code} canned cycle is not supported")
    if plane not in (0, 1, 2):
        raise error(line, f"G{code}: canned cycles in this plane are not supported")
    if comp_on:
        raise _err(error, line, code, "canned cycles cannot be used with cutter compensation on")
    if inverse_time:
        raise _err(error, line, code, "canned cycles cannot be used with inverse time feed (G93)")
    ia, ib, ic = _PLANE_AXES[plane]
    la, lb, lc = _LETTERS[ia], _LETTERS[ib], _LETTERS[ic]
    same = state.code == code
    pos = [float(v) for v in pos[:6]] + [0.0] * (6 - len(pos[:6]))

    if not any(k in words for k in (la, lb, lc)):
        raise _err(error, line, code, "no X, Y or Z word in a canned-cycle block")
    for k in (3, 4, 5):
        letter = _LETTERS[k]
        if letter in words:
            v = float(words[letter])
            moves = v != 0.0 if incremental else v != pos[k]
            if moves:
                raise _err(error, line, code, f"{letter} cannot move during a canned cycle")

    # Sticky words.
    if "R" in words:
        r_word = float(words["R"]) * unit_mm
    elif same:
        r_word = state.r
    else:
        raise _err(error, line, code, "R (retract plane) is missing")
    if lc in words:
        z_word = float(words[lc]) * unit_mm
    elif same:
        z_word = state.depth
    else:
        raise _err(error, line, code, f"{lc} (bottom of the hole) is missing")
    repeats = 1
    if "L" in words:
        lv = float(words["L"])
        if lv != math.floor(lv) or lv < 1:
            raise _err(error, line, code, f"L{lv:g}: the repeat count must be a positive integer")
        repeats = int(lv)
    q = math.nan
    if code in (73, 83):
        if "Q" in words:
            q = float(words["Q"]) * unit_mm
        elif same:
            q = state.q
        else:
            raise _err(error, line, code, "Q (peck depth) is missing")
        if not q > 0.0:
            raise _err(error, line, code, f"Q must be positive (Q{q / unit_mm:g})")
    dwell = 0.0
    if code in (82, 89):
        if "P" in words:
            dwell = float(words["P"])
        elif same:
            dwell = state.p
        else:
            raise _err(error, line, code, "P (dwell at the bottom, seconds) is missing")
        if math.isnan(dwell):
            raise _err(error, line, code, "P (dwell at the bottom, seconds) is missing")
        if dwell < 0.0:
            raise _err(error, line, code, f"P must not be negative (P{dwell:g})")

    # Levels along the drill axis.
    initial = pos[ic] if state.initial is None else state.initial
    if incremental:
        r = initial + r_word
        bottom = r + z_word
        inc_a = float(words.get(la, 0.0)) * unit_mm
        inc_b = float(words.get(lb, 0.0)) * unit_mm
        a, b = pos[ia], pos[ib]
    else:
        r = r_word
        bottom = z_word
        inc_a = inc_b = 0.0
        a = float(words[la]) * unit_mm if la in words else pos[ia]
        b = float(words[lb]) * unit_mm if lb in words else pos[ib]
    if not all(math.isfinite(x) for x in (r, bottom, a, b, inc_a, inc_b)):
        raise _err(error, line, code, "a cycle position is out of range")
    if r < bottom:
        raise _err(
            error,
            line,
            code,
            f"R{r_word / unit_mm:g} is below the bottom {lc}{z_word / unit_mm:g} of the hole",
        )

    # Bound the work before producing it.
    per_hole = 5
    if code in (73, 83):
        pecks = (r - bottom) / q
        per_hole += (3 if code == 83 else 2) * min(pecks + 1.0, float(MAX_MOVES))
    if per_hole * repeats > MAX_MOVES:
        raise _err(
            error,
            line,
            code,
            f"the cycle would make more than {MAX_MOVES} moves (Q too small or L too large)",
        )

    out: list = []
    cur = list(pos)

    def go(kind: int, aa: float, bb: float, cc: float) -> None:
        cur[ia], cur[ib], cur[ic] = aa, bb, cc
        out.append((kind, tuple(cur), 0.0))

    level = initial
    here = pos[ic]
    if level < r:
        # Below the retract plane: straight up to R first.
        go(RAPID, pos[ia], pos[ib], r)
        level = r
        here = r
    clear = r if state.retract == 99 else level

    for rep in range(repeats):
        a += inc_a
        b += inc_b
        if rep == 0 and here > r:
            go(RAPID, a, b, here)
            go(RAPID, a, b, r)
        else:
            go(RAPID, a, b, clear)
            if clear > r:
                go(RAPID, a, b, r)
        if code in (73, 83):
            k = 1
            depth = r - q
            while depth > bottom:
                go(LINEAR, a, b, depth)
                if code == 73:
                    go(RAPID, a, b, depth + PECK_CLEARANCE_MM)
                else:
                    go(RAPID, a, b, r)
                    go(RAPID, a, b, depth + PECK_CLEARANCE_MM)
                k += 1
                depth = r - k * q
        go(LINEAR, a, b, bottom)
        if code in (82, 89):
            out.append((DWELL, tuple(cur), dwell))
        if code == 85:
            go(LINEAR, a, b, r)
            go(RAPID, a, b, clear)
        elif code == 89:
            go(LINEAR, a, b, clear)
        else:
            go(RAPID, a, b, clear)

    # Remember what stays modal.
    state.code = code
    state.r = r_word
    state.depth = z_word
    if code in (73, 83):
        state.q = q
    if code in (82, 89):
        state.p = dwell
    state.initial = initial
    # Drop the zero-length moves (a rapid to where the tool already is).
    return _drop_null(out, pos)


def _drop_null(out: list, pos) -> list:
    kept = []
    prev = tuple(pos)
    for kind, target, dwell in out:
        if kind != DWELL and target == prev:
            continue
        kept.append((kind, target, dwell))
        prev = target
    return kept
