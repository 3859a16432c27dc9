"""Measured run times to fit and check profiles against.

Two kinds of CSV are read:

- The four experiment tables of Camargo (2017) in
  ``../shared/data/camargo2017/``, as they are. Each row describes a test
  program; :func:`camargo_program` writes it as G-code (F15000, incremental
  G01 from X0 Y0 Z0, ``lines`` blocks) and the program is read back with the
  normal G-code reader.

  - exp1 (``seg1_dx_mm ... seg2_dz_mm, lines``): the two-block pattern
    (seg1, seg2) repeated; an empty cell omits the axis word.
  - exp2 (``limiting_axis, enl1_mm, enl2_mm, s1_mm, s2_mm, lines``): every
    block moves all three axes; the other two axes (XYZ order) step by
    enl1/enl2, the limiting axis alternates s1, s2 (first block s1).
  - exp3 (``axis, s_mm, lines``): +s then -s on one axis, repeated.

- A plain ``program,time_s`` CSV: each program is a G-code file, its path
  relative to the CSV's directory.

The row named ``E2Y75`` is flagged suspect (``../shared/data/README.md``):
results are reported with and without it.

Long periodic test programs (up to 400 000 blocks) are timed by
extrapolation: the program is estimated at three shorter lengths n, 2n, 3n
(whole periods of the pattern); when the two increments agree (the middle of
the program has reached its periodic steady state and the start-up and
run-out are the same), ``T(N) = T(3n) + (N - 3n) * (T(3n) - T(2n)) / n``;
otherwise n is doubled, up to timing the whole program. ``full=True`` times
every program whole; the tests check that both agree.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

from contour import gcode
from contour.errors import UserError

SUSPECT = frozenset({"E2Y75"})
CAMARGO_FEED_MM_MIN = 15000.0

EXP1_COLUMNS = (
    "test",
    "seg1_dx_mm",
    "seg1_dy_mm",
    "seg1_dz_mm",
    "seg2_dx_mm",
    "seg2_dy_mm",
    "seg2_dz_mm",
    "lines",
    "time_s",
)
EXP2_COLUMNS = ("test", "limiting_axis", "enl1_mm", "enl2_mm", "s1_mm", "s2_mm", "lines", "time_s")
EXP3_COLUMNS = ("test", "axis", "s_mm", "lines", "time_s")
PLAIN_COLUMNS = ("program", "time_s")


@dataclass
class Experiment:
    """One measured program.

    ``pattern`` (periodic tests) is the list of blocks (G-code text lines)
    repeated to make ``lines`` blocks after ``header``; ``path`` (plain CSV)
    names a G-code file instead.
    """

    name: str
    table: str
    time_s: float
    lines: int = 0
    header: tuple = ()
    pattern: tuple = ()
    path: Optional[str] = None
    source: str = ""

    @property
    def suspect(self) -> bool:
        return self.name in SUSPECT

    @property
    def periodic(self) -> bool:
        return bool(self.pattern)

    def text(self, blocks: Optional[int] = None) -> str:
        """G-code of the test program (``blocks`` blocks, default all)."""
        n = self.lines if blocks is None else blocks
        p = len(self.pattern)
        body = [self.pattern[i % p] for i in range(n)]
        return "\n".join((*self.header, *body, "M30")) + "\n"

    def program(self, blocks: Optional[int] = None) -> gcode.Program:
        """The test program (cached: fits time the same programs many times)."""
        key = blocks if blocks is not None else self.lines
        cache = self.__dict__.setdefault("_programs", {})
        prog = cache.get(key)
        if prog is None:
            if self.path is not None:
                prog = gcode.read(self.path)
            else:
                prog = gcode.read(f"{self.source}[{self.name}]", text=self.text(blocks))
            if len(cache) >= 8:
                cache.clear()
            cache[key] = prog
        return prog


def _num(cell: str, where: str) -> Optional[float]:
    cell = cell.strip()
    if cell == "":
        return None
    try:
        v = float(cell)
    except ValueError:
        raise UserError(f"{where}: '{cell}' is not a number") from None
    if not math.isfinite(v):
        raise UserError(f"{where}: '{cell}' is not a finite number")
    return v


def _header(name: str, feed: float) -> tuple:
    return (
        f"; {name}: generated from its row (camargo2017 test program)",
        f"G21 G17 G64 G91 G1 F{feed:g}",
    )


def _word(letter: str, v: Optional[float]) -> str:
    return "" if v is None else f"{letter}{v:.4f}".rstrip("0").rstrip(".") + " "


def _block(dx, dy, dz) -> str:
    return (_word("X", dx) + _word("Y", dy) + _word("Z", dz)).strip()


def _exp1(row: dict, where: str, source: str) -> Experiment:
    v = [_num(row[c], f"{where} {c}") for c in EXP1_COLUMNS[1:7]]
    if all(x is None or x == 0 for x in v[:3]) or all(x is None or x == 0 for x in v[3:]):
        raise UserError(f"{where}: a segment of the pattern does not move")
    return Experiment(
        name=row["test"].strip(),
        table="exp1",
        time_s=_time(row, where),
        lines=_lines(row, where),
        header=_header(row["test"].strip(), CAMARGO_FEED_MM_MIN),
        pattern=(_block(*v[:3]), _block(*v[3:])),
        source=source,
    )


def _exp2(row: dict, where: str, source: str) -> Experiment:
    axis = row["limiting_axis"].strip().upper()
    if axis not in ("X", "Y", "Z"):
        raise UserError(f"{where}: limiting_axis must be X, Y or Z, got '{axis}'")
    enl1, enl2, s1, s2 = (_num(row[c], f"{where} {c}") for c in EXP2_COLUMNS[2:6])
    if None in (enl1, enl2, s1, s2) or min(enl1, enl2, s1, s2) <= 0:
        raise UserError(f"{where}: enl1_mm, enl2_mm, s1_mm, s2_mm must be positive")
    others = [a for a in "XYZ" if a != axis]
    blocks = []
    for s in (s1, s2):
        d = {others[0]: enl1, others[1]: enl2, axis: s}
        blocks.append(_block(d["X"], d["Y"], d["Z"]))
    return Experiment(
        name=row["test"].strip(),
        table="exp2_" + axis.lower(),
        time_s=_time(row, where),
        lines=_lines(row, where),
        header=_header(row["test"].strip(), CAMARGO_FEED_MM_MIN),
        pattern=tuple(blocks),
        source=source,
    )


def _exp3(row: dict, where: str, source: str) -> Experiment:
    axis = row["axis"].strip().upper()
    if axis not in ("X", "Y", "Z"):
        raise UserError(f"{where}: axis must be X, Y or Z, got '{axis}'")
    s = _num(row["s_mm"], f"{where} s_mm")
    if s is None or s <= 0:
        raise UserError(f"{where}: s_mm must be positive")
    d = {"X": None, "Y": None, "Z": None}
    plus = dict(d, **{axis: s})
    minus = dict(d, **{axis: -s})
    return Experiment(
        name=row["test"].strip(),
        table="exp3",
        time_s=_time(row, where),
        lines=_lines(row, where),
        header=_header(row["test"].strip(), CAMARGO_FEED_MM_MIN),
        pattern=(
            _block(plus["X"], plus["Y"], plus["Z"]),
            _block(minus["X"], minus["Y"], minus["Z"]),
        ),
        source=source,
    )


def _time(row: dict, where: str) -> float:
    t = _num(row["time_s"], f"{where} time_s")
    if t is None or t <= 0:
        raise UserError(f"{where}: time_s must be a positive number")
    return t


def _lines(row: dict, where: str) -> int:
    n = _num(row["lines"], f"{where} lines")
    if n is None or n < 2 or n != int(n):
        raise UserError(f"{where}: lines must be a whole number >= 2")
    return int(n)


def _kind(columns) -> Optional[tuple]:
    cols = set(columns)
    for need, fn in (
        (EXP1_COLUMNS, _exp1),
        (EXP2_COLUMNS, _exp2),
        (EXP3_COLUMNS, _exp3),
    ):
        if set(need) <= cols:
            return fn, need
    if set(PLAIN_COLUMNS) <= cols:
        return None, PLAIN_COLUMNS
    return None


def read_csv(path) -> list[Experiment]:
    """Experiments of one CSV file (a Camargo table or ``program,time_s``)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise UserError(f"cannot read {p}: {exc.strerror}") from exc
    reader = csv.DictReader(text.splitlines())
    if not reader.fieldnames:
        raise UserError(f"{p}: empty file")
    kind = _kind([c.strip() for c in reader.fieldnames])
    if kind is None:
        raise UserError(
            f"{p}: unknown experiment table (columns {', '.join(reader.fieldnames)}); expected "
            "a camargo2017 table or 'program,time_s'"
        )
    fn, _ = kind
    out = []
    names = set()
    for lineno, row in enumerate(reader, start=2):
        row = {k.strip(): (v or "") for k, v in row.items() if k is not None}
        where = f"{p}:{lineno}"
        if fn is None:
            prog = row["program"].strip()
            if not prog:
                raise UserError(f"{where}: empty program name")
            e = Experiment(
                name=prog,
                table=p.stem,
                time_s=_time(row, where),
                path=str(p.parent / prog),
                source=str(p),
            )
        else:
            e = fn(row, where, p.name)
        if e.name in names:
            raise UserError(f"{where}: test '{e.name}' appears twice")
        names.add(e.name)
        out.append(e)
    if not out:
        raise UserError(f"{p}: no rows")
    return out


def read_all(paths) -> list[Experiment]:
    out = []
    seen = set()
    for path in paths:
        for e in read_csv(path):
            key = (e.table, e.name)
            if key in seen:
                raise UserError(f"{path}: test '{e.name}' of table {e.table} given twice")
            seen.add(key)
            out.append(e)
    return out


# ---- timing experiments with a model ----------------------------------------


def predict(
    experiments,
    run: Callable[[gcode.Program], float],
    warmup: int = 128,
    full: bool = False,
    rtol: float = 1e-9,
) -> list[float]:
    """Predicted time of every experiment; ``run`` times one program.

    Periodic programs are timed at three lengths n, 2n, 3n (whole periods,
    n >= ``warmup``); when the two increments agree within ``rtol`` the time
    is extrapolated linearly to the full length, otherwise n is doubled, up
    to timing the whole program.
    """
    return [predict_one(e, run, warmup, full, rtol) for e in experiments]


def predict_one(e: Experiment, run, warmup: int = 128, full: bool = False, rtol: float = 1e-9):
    if not e.periodic or full:
        return run(e.program())
    p = len(e.pattern)
    base = -(-max(warmup, 1) // p) * p
    while 3 * base + p < e.lines:
        t1, t2, t3 = (run(e.program(k * base)) for k in (1, 2, 3))
        d1, d2 = t2 - t1, t3 - t2
        if abs(d2 - d1) <= rtol * max(abs(d2), 1e-12):
            return t3 + (e.lines - 3 * base) * d2 / base
        base *= 2
    return run(e.program())
