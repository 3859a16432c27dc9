"""Canned cycles (gcode/cycles.py): every move of hand-computed cycles."""

import pytest
from contour.gcode.cycles import CycleState, expand
from contour.gcode.moves import DWELL, LINEAR, RAPID


class Err(Exception):
    pass


def err(line, msg):
    return Err(f"t.ngc:{line}: {msg}")


def run(blocks, pos=(0, 0, 10, 0, 0, 0), retract=98, incremental=False, plane=0, state=None):
    """Expand a list of (code, words) blocks; return [(kind, (x, y, z), dwell)]."""
    st = state or CycleState()
    st.retract = retract
    out = []
    cur = tuple(float(v) for v in pos)
    for i, (code, words) in enumerate(blocks, 1):
        for kind, target, dwell in expand(code, words, st, cur, plane, incremental, i, err):
            out.append((kind, tuple(round(v, 9) for v in target[:3]), dwell))
            cur = target
    return out


def R(x, y, z):
    return (RAPID, (x, y, z), 0.0)


def F(x, y, z):
    return (LINEAR, (x, y, z), 0.0)


def D(x, y, z, s):
    return (DWELL, (x, y, z), s)


def test_g81_two_holes_g98_returns_to_the_initial_level():
    moves = run([(81, {"X": 10, "Y": 5, "Z": -3, "R": 2}), (81, {"X": 20})], retract=98)
    assert moves == [
        R(10, 5, 10),  # to the hole at the initial level
        R(10, 5, 2),  # down to R
        F(10, 5, -3),  # drill
        R(10, 5, 10),  # back to the initial level
        R(20, 5, 10),  # next hole (R and Z sticky)
        R(20, 5, 2),
        F(20, 5, -3),
        R(20, 5, 10),
    ]


def test_g81_two_holes_g99_returns_to_r():
    moves = run([(81, {"X": 10, "Y": 5, "Z": -3, "R": 2}), (81, {"X": 20})], retract=99)
    assert moves == [
        R(10, 5, 10),
        R(10, 5, 2),
        F(10, 5, -3),
        R(10, 5, 2),  # G99: back to R only
        R(20, 5, 2),  # next hole at R
        F(20, 5, -3),
        R(20, 5, 2),
    ]


def test_start_below_r_rises_first_and_g98_clears_at_r():
    moves = run([(81, {"X": 10, "Y": 0, "Z": -3, "R": 2})], pos=(0, 0, 0, 0, 0, 0))
    assert moves == [R(0, 0, 2), R(10, 0, 2), F(10, 0, -3), R(10, 0, 2)]


def test_incremental_g81_l3():
    # G91 G81 X10 Z-5 R-8 L3 from (0, 0, 10): R = 10 - 8 = 2, Z = 2 - 5 = -3,
    # holes at X10, X20, X30.
    moves = run([(81, {"X": 10, "Z": -5, "R": -8, "L": 3})], incremental=True)
    assert moves == [
        R(10, 0, 10),
        R(10, 0, 2),
        F(10, 0, -3),
        R(10, 0, 10),
        R(20, 0, 10),
        R(20, 0, 2),
        F(20, 0, -3),
        R(20, 0, 10),
        R(30, 0, 10),
        R(30, 0, 2),
        F(30, 0, -3),
        R(30, 0, 10),
    ]


def test_incremental_r_is_from_the_initial_level_across_blocks():
    # G99: after the first hole the tool waits at R (2), but the second
    # block's R-8 is still taken from the initial level 10.
    moves = run(
        [(81, {"X": 10, "Z": -5, "R": -8}), (81, {"X": 10})],
        incremental=True,
        retract=99,
    )
    assert moves[-3:] == [R(20, 0, 2), F(20, 0, -3), R(20, 0, 2)]


def test_g83_pecks_at_exact_depths():
    # R2 Z-7 Q3: pecks to -1, -4, then the bottom -7; out to R after each peck
    # and back to 0.254 above the depth reached.
    moves = run([(83, {"X": 0, "Y": 0, "Z": -7, "R": 2, "Q": 3})])
    assert moves == [
        R(0, 0, 2),
        F(0, 0, -1),
        R(0, 0, 2),
        R(0, 0, -0.746),
        F(0, 0, -4),
        R(0, 0, 2),
        R(0, 0, -3.746),
        F(0, 0, -7),
        R(0, 0, 10),
    ]


def test_g83_exact_multiple_of_q_ends_with_the_bottom_peck():
    # R0 Z-6 Q3: depths -3 then the bottom -6 (no zero-length peck at -6).
    moves = run([(83, {"X": 0, "Y": 0, "Z": -6, "R": 0, "Q": 3})], pos=(0, 0, 0, 0, 0, 0))
    feeds = [m[1][2] for m in moves if m[0] == LINEAR]
    assert feeds == [-3, -6]


def test_g73_chip_break_retracts_0254():
    moves = run([(73, {"X": 0, "Y": 0, "Z": -5, "R": 1, "Q": 2})])
    assert moves == [
        R(0, 0, 1),
        F(0, 0, -1),
        R(0, 0, -0.746),
        F(0, 0, -3),
        R(0, 0, -2.746),
        F(0, 0, -5),
        R(0, 0, 10),
    ]


def test_g82_dwells_at_the_bottom_and_p_is_sticky():
    moves = run([(82, {"X": 5, "Y": 0, "Z": -2, "R": 1, "P": 0.5}), (82, {"X": 6})], retract=99)
    assert moves == [
        R(5, 0, 10),
        R(5, 0, 1),
        F(5, 0, -2),
        D(5, 0, -2, 0.5),
        R(5, 0, 1),
        R(6, 0, 1),
        F(6, 0, -2),
        D(6, 0, -2, 0.5),
        R(6, 0, 1),
    ]


def test_g85_feeds_out_to_r_and_g89_dwells_and_feeds_out():
    assert run([(85, {"X": 0, "Y": 0, "Z": -2, "R": 1})]) == [
        R(0, 0, 1),
        F(0, 0, -2),
        F(0, 0, 1),
        R(0, 0, 10),
    ]
    assert run([(89, {"X": 0, "Y": 0, "Z": -2, "R": 1, "P": 1.5})]) == [
        R(0, 0, 1),
        F(0, 0, -2),
        D(0, 0, -2, 1.5),
        F(0, 0, 10),
    ]


def test_inch_units_scale_words_not_the_peck_clearance():
    # in mm: R 2.54, Z -5.08, Q 5.08 -> pecks at -2.54, then the bottom.
    st = CycleState()
    moves = expand(
        83, {"X": 0, "Y": 0, "Z": -0.2, "R": 0.1, "Q": 0.2}, st, (0, 0, 10, 0, 0, 0), 0, False, 1,
        err, unit_mm=25.4,
    )  # fmt: skip
    zs = [round(t[2], 6) for _, t, _ in moves]
    assert zs == [2.54, -2.54, 2.54, -2.286, -5.08, 10]


def test_g18_drills_along_y():
    # G18: the plane is ZX, Y the drill axis; the Y word is the bottom.
    moves = run([(81, {"X": 3, "Z": 4, "Y": -2, "R": 1})], pos=(0, 5, 0, 0, 0, 0), plane=1)
    assert moves == [R(3, 5, 4), R(3, 1, 4), F(3, -2, 4), R(3, 5, 4)]


@pytest.mark.parametrize(
    "code, words, kw, message",
    [
        (81, {"X": 1, "Z": -1}, {}, "R (retract plane) is missing"),
        (81, {"X": 1, "R": 1}, {}, "Z (bottom of the hole) is missing"),
        (81, {"X": 1, "Z": 2, "R": 1}, {}, "R1 is below the bottom Z2"),
        (81, {"R": 1, "F": 100}, {}, "no X, Y or Z word"),
        (81, {"X": 1, "Z": -1, "R": 1, "L": 0}, {}, "positive integer"),
        (81, {"X": 1, "Z": -1, "R": 1, "L": 1.5}, {}, "positive integer"),
        (83, {"X": 1, "Z": -1, "R": 1}, {}, "Q (peck depth) is missing"),
        (83, {"X": 1, "Z": -1, "R": 1, "Q": 0}, {}, "Q must be positive"),
        (73, {"X": 1, "Z": -1, "R": 1, "Q": -1}, {}, "Q must be positive"),
        (82, {"X": 1, "Z": -1, "R": 1}, {}, "P (dwell"),
        (89, {"X": 1, "Z": -1, "R": 1, "P": -1}, {}, "P must not be negative"),
        (81, {"X": 1, "Z": -1, "R": 1, "A": 5}, {}, "A cannot move"),
        (81, {"X": 1, "Z": -1, "R": 1}, {"comp_on": True}, "cutter compensation"),
        (81, {"X": 1, "Z": -1, "R": 1}, {"inverse_time": True}, "inverse time"),
        (84, {"X": 1, "Z": -1, "R": 1}, {}, "G84 canned cycle is not supported"),
        (83, {"X": 1, "Z": -1e6, "R": 1, "Q": 1e-3}, {}, "more than 100000 moves"),
        (81, {"X": 1, "Z": -1, "R": 1, "L": 1e9}, {}, "more than 100000 moves"),
    ],
)
def test_errors_name_the_line_and_the_cycle(code, words, kw, message):
    with pytest.raises(Err) as e:
        expand(code, words, CycleState(), (0, 0, 10, 0, 0, 0), 0, False, 7, err, **kw)
    assert str(e.value).startswith("t.ngc:7: ")
    assert message in str(e.value)


def test_sticky_words_are_dropped_by_cancel_and_by_another_cycle():
    st = CycleState()
    expand(81, {"X": 1, "Z": -1, "R": 1}, st, (0, 0, 10, 0, 0, 0), 0, False, 1, err)
    st.cancel()
    with pytest.raises(Err, match="R .retract plane. is missing"):
        expand(81, {"X": 2}, st, (1, 0, 10, 0, 0, 0), 0, False, 3, err)
    st = CycleState()
    expand(82, {"X": 1, "Z": -1, "R": 1, "P": 1}, st, (0, 0, 10, 0, 0, 0), 0, False, 1, err)
    with pytest.raises(Err, match="P .dwell"):
        expand(89, {"X": 2, "Z": -1, "R": 1}, st, (1, 0, 10, 0, 0, 0), 0, False, 2, err)


def test_initial_level_survives_a_switch_to_g99_and_back():
    # G98 hole, then G99 hole (stays at R), then G98 again: back to the
    # initial level 10, not to R where the tool waits.
    st = CycleState()
    moves = run([(81, {"X": 1, "Y": 0, "Z": -1, "R": 2})], state=st, retract=98)
    cur = (1, 0, 10, 0, 0, 0)
    st.retract = 99
    m2 = expand(81, {"X": 2}, st, cur, 0, False, 2, err)
    assert m2[-1][1][2] == 2
    st.retract = 98
    m3 = expand(81, {"X": 3}, st, m2[-1][1], 0, False, 3, err)
    assert m3[-1][1][2] == 10
    assert moves[0] == R(1, 0, 10)


def test_overflowing_positions_are_an_error():
    with pytest.raises(Err, match="t.ngc:2: G81: a cycle position is out of range"):
        expand(81, {"X": 1e308, "Z": -1, "R": 1}, CycleState(), (0,) * 6, 0, False, 2, err,
               unit_mm=25.4)  # fmt: skip
