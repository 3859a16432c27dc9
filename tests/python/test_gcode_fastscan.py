"""The C fast path of the G-code reader (contour.gcode.fastscan,
hil_sim/gcode_scan.c) against the pure Python reader, its reference: seeded
generated CAM-like files read both ways give the same Program, column by
column and bit by bit, the same report and lines read, the same chunks from
read_chunks, and the same error (message and line) for files with faults."""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest
from contour import gcode
from contour.gcode import fastscan

pytestmark = pytest.mark.skipif(
    fastscan.library() is None, reason="host library not built (make host)"
)

COLUMNS = (
    "start",
    "kind",
    "end",
    "feed",
    "centre",
    "plane",
    "turns",
    "exact_stop",
    "dwell_s",
    "line",
)


def _num(rng: random.Random, lo=-200.0, hi=200.0) -> str:
    """A number as CAM and hand-written files write them."""
    v = rng.uniform(lo, hi)
    form = rng.random()
    if form < 0.55:
        return f"{v:.{rng.choice((3, 3, 4, 1, 0))}f}"
    if form < 0.65:
        return f"{v:+.3f}"
    if form < 0.72:
        return f"{int(v)}."
    if form < 0.78:
        return "." + str(rng.randrange(1, 99999))
    if form < 0.82:
        return "-." + str(rng.randrange(0, 999))
    if form < 0.86:
        return "00" + f"{abs(v):.3f}"
    if form < 0.89:
        return rng.choice(("0", "-0", "-0.000", "+0.", "0.0000000"))
    if form < 0.93:
        return repr(v)  # 17 significant digits
    if form < 0.96:
        return f"{v:.12f}"  # more digits than double precision after the point
    return "0000" + str(rng.randrange(0, 10 ** rng.randrange(1, 4)))  # leading zeros


def _move(rng: random.Random, n: int) -> str:
    parts = []
    if rng.random() < 0.7:
        parts.append(f"N{n}")
    if rng.random() < 0.15:
        parts.append(rng.choice(("G0", "G1", "G01", "G00", "G1.0", "g1", "G1")))
    axes = [a for a in "XYZ" if rng.random() < 0.6] or ["X"]
    if rng.random() < 0.1:
        axes += rng.sample("ABC", rng.randrange(1, 4))  # rotary axes, degrees
    if rng.random() < 0.2:
        rng.shuffle(axes)
    for a in axes:
        parts.append((a.lower() if rng.random() < 0.05 else a) + _num(rng))
    if rng.random() < 0.12:
        parts.append(
            "F" + rng.choice(("{:.0f}", "{:.1f}", "{:.3f}", "{:.0f}.")).format(rng.uniform(1, 5000))
        )
    sep = rng.choice((" ", " ", " ", "  ", "\t"))
    return sep.join(parts)


def _arc(rng: random.Random, n: int) -> str:
    """An arc the fast path takes, then G1 or G0: a full circle (any
    distance mode, any plane), or quarter and half turns written
    incrementally."""
    rv = rng.choice((1.0, 2.5, 0.75, 10.0, 0.5))
    r = f"{rv:g}"
    d = rng.choice(("G2", "G3", "G02", "G03"))
    pre = f"N{n} " if rng.random() < 0.6 else ""
    back = rng.choice(("\nG1", "\nG0", "\nG01 X1", "\nN7 G1 F50"))
    form = rng.random()
    if form < 0.3:
        return pre + f"{d} I{r} J-{r}" + rng.choice(("", " F900", " Z-1", " A-45 B10")) + back
    if form < 0.45:
        plane, words = rng.choice((("G18", f"I{r} K{r}"), ("G19", f"J-{r} K{r}"), ("G18", f"K{r}")))
        return f"{plane}\n{pre}{d} {words}{back}\nG17"
    if form < 0.8:
        return f"G91\n{pre}{d} X{r} Y{r} I{r} J0 Z-0.1\nX{r} Y-{r} I0 J-{r}{back}\nG90"
    return f"G91\n{pre}{d} X-{2 * rv:g} I-{r} J0{back}\nG90"  # half turn


def _special(rng: random.Random) -> str:
    """Lines the fast path leaves to Python (valid ones)."""
    return rng.choice(
        (
            "G91",
            "G90",
            "G20",
            "G21",
            "G0",
            "G1",
            "G1 F1500",
            "F800",
            "(a comment)",
            "; a comment",
            "G1 X5 (comment at the end)",
            "G1 X1 Y2 A30",
            "G0 Z5 B10 C-20",
            "G17 G2 I5 J0\nG1",
            "G17 G3 I-2 J1 F700\nG0",
            "G18\nG17",
            "G61",
            "G64",
            "G4 P0.25",
            "M3 S12000",
            "T1 M6",
            "M8",
            "G54",
            "G55",
            "G92 X10 Y-3",
            "G92.1",
            "G92 Z1",
            "G90 G53 G0 Z0",
            "G90.1\nG2 I5 J-2\nG91.1\nG1",
            "G90.1\nN3 G3 I0 J0 F100\nG91.1\nG0",
            "",
            "   ",
            "\t",
            "N5",
            "G1X3Y4",
            "n20 G1 X1",
            "/G1 X2",
            "#1 = 5",
            "G1 X#1",
            "G1 X[1 + 2]",
            "G9 G1 X3",
            "(caf\u00e9: non-ASCII comment)",
        )
    )


def _program(seed: int, lines: int = 1500) -> tuple[str, str]:
    rng = random.Random(seed)
    out = []
    head = rng.random()
    if head < 0.8:
        out.append(rng.choice(("G21 G90 G17 G64", "G20", "G21", "G21 G91")))
    if rng.random() < 0.5:
        out.append(f"G10 L2 P2 X{_num(rng)} Y{_num(rng)} Z{_num(rng, -5, 5)}")
        out.append("G55")
    if rng.random() < 0.3:
        out.append(f"G92 X{_num(rng)} Y{_num(rng)}")
    out.append(rng.choice(("G1 F3000", "G0 F200", "G1 F120.5", "F2500 G1")))
    n = 10
    for _ in range(lines):
        n += rng.choice((1, 5, 10))
        x = rng.random()
        line = _special(rng) if x < 0.06 else _arc(rng, n) if x < 0.12 else _move(rng, n)
        out.extend(line.split("\n"))
    if rng.random() < 0.3:
        out.append("M2")
        out.append("G1 X1")
    if rng.random() < 0.2:
        out = ["%"] + out + ["%", "G1 X99"]
    eol = "\r\n" if rng.random() < 0.2 else "\n"
    text = eol.join(out)
    if rng.random() < 0.8:
        text += eol
    return text, eol


MALFORMED = (
    "X1.2.3",
    "XNAN",
    "YINF",
    "X-",
    "X1e5",
    "XY5",
    "GOO",
    "X" + "9" * 400,
    "F0",
    "F-5",
    "X.",
    "X+-1",
    "N10.5.5 X1",
    "G1 X5*",
    "X1 N5",
    "G2 X5",
    "G7.5 X1",
    "X1 X2",
    "(open comment",
    "X1\x0bY2",
)


ARC_FAULTS = (
    "G2 X500 Y500 I1 J0",
    "G3 X500 Y500 I1 J0 F100",
    "G2 I0 J0",
    "G2 I2000000000 J0",
    "G17 G2 X1 K1",
    "G2 X1 Y2 K1",
    "G3 R5 X1",
    "G2 I1 J0\nX1 Y1",
    "G2 I1 J0\nI5 J0",
    "G2 I1 J0 P2",
    "G1 I5",
    "G0 X1 J2",
    "G2",
    "G18 G2 I1 J1",
    "G90.1 G2 I0.0000001 J0",
    "N" + "9" * 400 + " X1",  # a line number too large for a float
    "N" + "0" * 35 + "5 X1",
    "X" + "0" * 40 + "1.5",
    "X1" + " " * 300_000 + "Y2",  # beyond the line cap, plain words or not
)


def _read(monkeypatch, path, native: bool, rows=None):
    monkeypatch.setenv("CONTOUR_GCODE_NATIVE", "1" if native else "0")
    try:
        if rows is None:
            return [gcode.read(path)]
        return list(gcode.read_chunks(path, rows=rows))
    except gcode.GcodeError as exc:
        return ("error", str(exc), exc.line)


def _same(a, b):
    if isinstance(a, tuple) or isinstance(b, tuple):
        assert a == b
        return
    assert len(a) == len(b)
    for pa, pb in zip(a, b):
        for name in COLUMNS:
            ca, cb = (
                np.ascontiguousarray(getattr(pa, name)),
                np.ascontiguousarray(getattr(pb, name)),
            )
            assert ca.dtype == cb.dtype and ca.shape == cb.shape, name
            assert ca.tobytes() == cb.tobytes(), name  # bit for bit, NaN and -0.0 included
        assert pa.lines_read == pb.lines_read
        assert pa.substituted_feeds == pb.substituted_feeds
        assert {k: v.as_dict() for k, v in pa.skipped.items()} == {
            k: v.as_dict() for k, v in pb.skipped.items()
        }


@pytest.fixture
def taken(monkeypatch):
    """Lines the C scanner took, over every FastSource made in the test."""
    made = []
    real = fastscan.FastSource.__init__

    def init(self, *a, **k):
        real(self, *a, **k)
        made.append(self)

    monkeypatch.setattr(fastscan.FastSource, "__init__", init)
    return lambda: sum(s.lines_taken for s in made)


@pytest.mark.parametrize("seed", range(24))
def test_generated_files_read_the_same(tmp_path, monkeypatch, taken, seed):
    text, _ = _program(seed)
    path = tmp_path / f"cam{seed}.ngc"
    path.write_bytes(text.encode("utf-8"))
    slow = _read(monkeypatch, path, False)
    fast = _read(monkeypatch, path, True)
    _same(fast, slow)
    if not isinstance(fast, tuple):
        assert taken() > 0.5 * fast[0].lines_read  # the fast path did the bulk
        assert (fast[0].kind >= 2).sum() > 20
    rows = 1 + seed * 7
    _same(_read(monkeypatch, path, True, rows), _read(monkeypatch, path, False, rows))


@pytest.mark.parametrize("seed", range(40))
def test_malformed_words_give_the_same_error(tmp_path, monkeypatch, seed):
    text, eol = _program(1000 + seed, 400)
    rng = random.Random(seed)
    lines = text.split(eol)
    k = rng.randrange(5, len(lines) - 3)
    lines.insert(k, f"N{k} G1 " + MALFORMED[seed % len(MALFORMED)])
    path = tmp_path / f"bad{seed}.ngc"
    path.write_bytes(eol.join(lines).encode("utf-8"))
    slow = _read(monkeypatch, path, False)
    fast = _read(monkeypatch, path, True)
    _same(fast, slow)


@pytest.mark.parametrize("seed", range(60))
def test_mutated_characters_give_the_same_result(tmp_path, monkeypatch, seed):
    """Fuzz: a few characters of a generated file replaced, inserted or
    deleted (signs, points, exponents, letters, blanks, control bytes); both
    readers give the same program or the same error."""
    rng = random.Random(seed)
    text, _ = _program(3000 + seed, 200)
    chars = list(text)
    for _ in range(rng.randrange(1, 6)):
        k = rng.randrange(len(chars))
        c = rng.choice("0123456789.-+eEXYZIJKFGNn ;(\t\x0b\x00\u00e9#[")
        op = rng.random()
        if op < 0.4:
            chars[k] = c
        elif op < 0.8:
            chars.insert(k, c)
        else:
            del chars[k]
    path = tmp_path / f"mut{seed}.ngc"
    path.write_bytes("".join(chars).encode("utf-8"))
    _same(_read(monkeypatch, path, True), _read(monkeypatch, path, False))


@pytest.mark.parametrize("seed", range(len(ARC_FAULTS)))
def test_arc_faults_give_the_same_error_or_rows(tmp_path, monkeypatch, seed):
    text, eol = _program(2000 + seed, 300)
    lines = text.split(eol)
    k = random.Random(seed).randrange(5, len(lines) - 3)
    lines[k:k] = ARC_FAULTS[seed].split("\n")
    path = tmp_path / f"arc{seed}.ngc"
    path.write_bytes(eol.join(lines).encode("utf-8"))
    _same(_read(monkeypatch, path, True), _read(monkeypatch, path, False))


def test_backing_off_changes_nothing_but_the_cost(tmp_path, monkeypatch, taken):
    """Lines C does not take, then plain ones: C resumes within BACKOFF lines."""
    out = ["G21 G90", "G1 F100"] + ["G1 X[1 + 1] (param)"] * 500 + ["X1 Y2", "Y3"] * 200
    path = tmp_path / "backoff.ngc"
    path.write_text("\n".join(out) + "\n")
    fast = _read(monkeypatch, path, True)
    _same(fast, _read(monkeypatch, path, False))
    assert taken() >= 400 - fastscan.BACKOFF


def test_piece_boundaries_and_long_files(tmp_path, monkeypatch, taken):
    """Lines that straddle the read pieces, a last line without newline,
    more rows than the scanner's arrays."""
    monkeypatch.setattr(fastscan, "PIECE", 97)
    monkeypatch.setattr(fastscan, "ROWS", 13)
    text, _ = _program(7, 3000)
    path = tmp_path / "pieces.ngc"
    path.write_bytes(text.rstrip("\r\n").encode("utf-8"))
    _same(_read(monkeypatch, path, True), _read(monkeypatch, path, False))
    _same(_read(monkeypatch, path, True, 50), _read(monkeypatch, path, False, 50))
    assert taken() > 1000


def test_numbers_convert_as_python_float(tmp_path, monkeypatch, taken):
    """The decimal conversion in C against float() on awkward values: up to
    19 significant digits and 22 after the point (C), more (Python)."""
    monkeypatch.setattr(fastscan, "BACKOFF", 0)  # every line offered to C
    rng = random.Random(5)
    vals = [
        "0.1",
        "0.3",
        "2.675",
        "1.005",
        "9007199.254740993",
        "900719925474.0992",
        "0.000000000000000000001",
        "-0",
        "+.5",
        "5.",
        "1.0000000000000000000000001",
    ]
    vals += [f"{rng.uniform(-1e6, 1e6):.{rng.randrange(0, 16)}f}" for _ in range(3000)]
    for _ in range(1000):
        d = str(rng.randrange(10**15, 10 ** rng.randrange(16, 21)))
        k = rng.randrange(1, 9)
        vals.append(rng.choice(("", "-")) + d[:k] + "." + d[k:])
    text = "G21 G90\nG1 F100\n" + "".join(f"X{v}\n" for v in vals)
    path = tmp_path / "nums.ngc"
    path.write_text(text)
    (prog,) = _read(monkeypatch, path, True)
    want = np.array([float(v) * 1.0 + 0.0 for v in vals])  # X * scale + origin
    assert prog.end[:, 0].tobytes() == want.tobytes()
    _same([prog], _read(monkeypatch, path, False))
    assert taken() > 2000  # the others have more digits than C converts


def test_arcs_of_every_plane_are_taken(tmp_path, monkeypatch, taken):
    """I J K of G17 G18 G19, G90.1 centres, G20: taken by C, as Python reads them."""
    monkeypatch.setattr(fastscan, "BACKOFF", 0)  # every line offered to C
    out = ["G20 G90 G17", "G1 F10", "G10 L2 P1 X3 Y4 Z5"]
    for mode in ("G91.1", "G90.1"):
        for plane, words, w in (
            ("G17", "I2 J-1", "Z"),
            ("G18", "K2 I-1", "Y"),
            ("G19", "J2 K-1", "X"),
        ):
            out += [mode, plane]
            for k in range(50):
                out += [f"N{k} G2 {words}", f"G3 {words} {w}{k}", "G1 X0.5 Y0.25 Z0.125", "G0 Z1"]
    path = tmp_path / "planes.ngc"
    path.write_text("\n".join(out) + "\n")
    fast = _read(monkeypatch, path, True)
    _same(fast, _read(monkeypatch, path, False))
    assert (fast[0].kind >= 2).sum() == 600
    assert set(fast[0].plane[fast[0].kind >= 2]) == {0, 1, 2}
    assert taken() == fast[0].lines_read - 15  # all but the mode lines


PROGRAMS = sorted((Path(__file__).resolve().parents[1] / "gcode" / "programs").glob("*.ngc"))


@pytest.mark.parametrize("path", PROGRAMS, ids=[p.name for p in PROGRAMS])
def test_the_test_programs_read_the_same(monkeypatch, path):
    """Every hand-written program of tests/gcode/programs, both ways."""
    _same(_read(monkeypatch, path, True), _read(monkeypatch, path, False))
    _same(_read(monkeypatch, path, True, 3), _read(monkeypatch, path, False, 3))
