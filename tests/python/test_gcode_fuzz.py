"""Fuzz of the G-code front end: any input gives blocks or a GcodeError,
never another exception (fixed seeds, so a failure reproduces)."""

import random

import pytest
from contour.gcode import GcodeError, flow
from contour.gcode.lexer import blocks
from contour.gcode.params import Params

TOKENS = [
    "G1", "g0", "X1.5", "Y-2", "Z.5", "F100", "N10", "M3", "S1000", "T1", "R5", "P2",
    "X", "Y", "-", "+", ".", "1", "2.", "..", "e5", "X1.2.3", "XNAN", "GOO", "XY5",
    "#1", "#2=3", "#<a>", "#<a>=1", "#<_g>=2", "##1", "#[1+1]", "=", "#", "<", ">",
    "[", "]", "[1+2]", "[#1*2]", "[1/0]", "SQRT[-1]", "ATAN[1]/[2]", "SIN[30]",
    "EXISTS[#<a>]", "MOD", "AND", "**", "EQ", "(", ")", "(c)", "(MSG,hi)", "(DEBUG,#1)",
    ";", "; x", "/", "%", "o1", "O<s>", "sub", "endsub", "call", "return", "if", "else",
    "elseif", "endif", "while", "endwhile", "do", "repeat", "endrepeat", "break",
    "continue", "[0]", "[1]", "[3]", "R1=5", "F=R1", "X=IC(5)", "C=DC(90)",
    "CYCLE832(0.1)", "TRAORI", "GOTOF", "IF", "BEGIN PGM", "FMAX", "L", "\t", " ",
    "\ufeff", "\x00", "é", "@", "^", "$A", "_", "\"", "'",
]  # fmt: skip


class Rep:
    path = "f.ngc"

    def skip(self, kind, line, note=""):
        pass

    def error(self, line, message):
        return GcodeError(self.path, line, message)


def consume(lines):
    try:
        for b in blocks(lines, Params(), Rep()):
            assert isinstance(b.line, int) and b.line >= 1
            for w in b.words:
                assert isinstance(w, tuple) and len(w) == 2
                if len(w[0]) == 1:
                    v = w[1]
                    assert isinstance(v, float) and v == v and abs(v) != float("inf")
    except GcodeError:
        pass


@pytest.fixture(autouse=True)
def small_cap(monkeypatch):
    monkeypatch.setattr(flow, "ITERATION_CAP", 2000)


def test_random_bytes():
    rng = random.Random(17)
    for _ in range(1500):
        lines = [bytes(rng.randrange(256) for _ in range(rng.randrange(40))) for _ in range(4)]
        consume(lines)
        consume([b.decode("latin-1") for b in lines])


def test_random_token_soups():
    rng = random.Random(1717)
    for _ in range(3000):
        lines = []
        for _ in range(rng.randrange(1, 8)):
            k = rng.randrange(1, 9)
            sep = rng.choice(["", " ", " "])
            lines.append(sep.join(rng.choice(TOKENS) for _ in range(k)))
        consume(lines)


def test_random_control_flow_programs():
    rng = random.Random(4242)
    heads = ["sub", "endsub", "call", "return", "if [#1 LT 2]", "elseif [1]", "else",
             "endif", "while [#1 LT 3]", "endwhile", "do", "while [0]", "repeat [2]",
             "endrepeat", "break", "continue", "return [1]", "call [1] [2]"]  # fmt: skip
    for _ in range(2000):
        lines = []
        for _ in range(rng.randrange(2, 12)):
            r = rng.random()
            if r < 0.5:
                lines.append(f"o{rng.choice(['1', '2', '<s>'])} {rng.choice(heads)}")
            elif r < 0.7:
                lines.append("#1=[#1+1]")
            else:
                lines.append(f"G1 X#1 Y{rng.randrange(9)}")
        consume(lines)


def test_fast_path_reads_plain_lines_as_the_general_path_does():
    # A trailing comment sends a line through the general tokenizer; both
    # must give the same words, or the same refusal.
    rng = random.Random(99)
    parts = ["G", "X", "Y", "Z", "F", "M", "e", "x", "N", "O", "E", "1", "-", "+", ".", "5"]
    parts += [
        "07",
        " ",
        "  ",
        "\t",
        "G1",
        "X-1.5",
        "Y.5",
        "Z1.",
        "F100",
        "M30",
        "N10",
        "X1E5",
        "E-2",
    ]
    for _ in range(3000):
        line = "".join(rng.choice(parts) for _ in range(rng.randrange(1, 9)))

        def read(text):
            try:
                # Line 2: after the first line the streaming fast path runs.
                return [b.words for b in blocks(["G21", text], Params(), Rep())]
            except GcodeError as exc:
                return exc.message

        fast, general = read(line), read(line + " (c)")
        if isinstance(fast, str):
            assert isinstance(general, str), (line, fast, general)
        else:
            assert fast == general, (line, fast, general)
