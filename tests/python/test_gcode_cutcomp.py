"""Cutter radius compensation (gcode/cutcomp.py) on hand-computed paths."""

import math

import pytest
from contour.gcode.cutcomp import CutterComp
from contour.gcode.moves import ARC_CCW, ARC_CW, DWELL, LINEAR, RAPID, Move

NAN = math.nan


class Err(Exception):
    pass


def err(line, msg):
    return Err(f"t.ngc:{line}: {msg}")


def p6(x, y, z=0.0):
    return (float(x), float(y), float(z), 0.0, 0.0, 0.0)


class Prog:
    """Feed programmed moves (program order) through a CutterComp."""

    def __init__(self, x, y, z=0.0, plane=0):
        self.pos = p6(x, y, z)
        self.comp = CutterComp(err)
        self.out = []
        self.plane = plane
        self.line = 0

    def _push(self, m):
        self.out += self.comp.push(m)
        self.pos = m.end

    def g1(self, x=None, y=None, z=None, kind=LINEAR):
        self.line += 1
        end = list(self.pos)
        for i, v in enumerate((x, y, z)):
            if v is not None:
                end[i] = float(v)
        feed = NAN if kind == RAPID else 100.0
        self._push(Move(kind, self.pos, tuple(end), feed, self.line, plane=self.plane))

    def g0(self, **kw):
        self.g1(kind=RAPID, **kw)

    def arc(self, kind, x, y, cx, cy):
        self.line += 1
        end = (float(x), float(y)) + self.pos[2:]
        m = Move(kind, self.pos, end, 100.0, self.line, centre=(cx, cy, NAN), plane=self.plane)
        self._push(m)

    def dwell(self, s):
        self.line += 1
        self._push(Move(DWELL, self.pos, self.pos, NAN, self.line, dwell_s=s))

    def on(self, side, r):
        self.line += 1
        self.comp.on(side, r, self.plane, self.line)

    def off(self):
        self.line += 1
        self.comp.off(self.line)

    def done(self):
        self.out += self.comp.flush()
        return self.out


def simple(moves):
    """[(kind, (x0, y0), (x1, y1), centre or None)] rounded."""
    res = []
    for m in moves:
        c = None if m.centre is None else (round(m.centre[0], 6), round(m.centre[1], 6))
        res.append(
            (
                m.kind,
                (round(m.start[0], 6), round(m.start[1], 6)),
                (round(m.end[0], 6), round(m.end[1], 6)),
                c,
            )
        )
    return res


def length(moves, kinds=(LINEAR, ARC_CW, ARC_CCW)):
    total = 0.0
    for m in moves:
        if m.kind not in kinds:
            continue
        if m.kind in (ARC_CW, ARC_CCW):
            c = m.centre
            a0 = math.atan2(m.start[1] - c[1], m.start[0] - c[0])
            a1 = math.atan2(m.end[1] - c[1], m.end[0] - c[0])
            sweep = (a1 - a0) if m.kind == ARC_CCW else (a0 - a1)
            sweep %= 2 * math.pi
            total += sweep * math.hypot(m.start[0] - c[0], m.start[1] - c[1])
        else:
            total += math.dist(m.start[:3], m.end[:3])
    return total


def continuous(moves):
    for a, b in zip(moves, moves[1:]):
        assert a.end == b.start


def square_outside():
    # 20 mm square run clockwise with G41 and r = 3: the tool stays outside.
    p = Prog(0, -10)
    p.on("left", 3.0)
    p.g1(x=0, y=0)  # entry, going +Y: ends at (-3, 0)
    p.g1(y=20)
    p.g1(x=20)
    p.g1(y=0)
    p.g1(x=0)
    p.off()
    p.g1(x=-10, y=-10)  # exit
    return p.done()


def test_square_outside_g41_cw_gets_corner_arcs_of_radius_3():
    moves = square_outside()
    continuous(moves)
    assert simple(moves) == [
        (LINEAR, (0, -10), (-3, 0), None),  # entry
        (LINEAR, (-3, 0), (-3, 20), None),  # tangent: no corner
        (ARC_CW, (-3, 20), (0, 23), (0, 20)),  # convex corner: arc r=3 round the corner
        (LINEAR, (0, 23), (20, 23), None),
        (ARC_CW, (20, 23), (23, 20), (20, 20)),
        (LINEAR, (23, 20), (23, 0), None),
        (ARC_CW, (23, 0), (20, -3), (20, 0)),
        (LINEAR, (20, -3), (0, -3), None),
        (LINEAR, (0, -3), (-10, -10), None),  # exit after G40
    ]
    # entry sqrt(109) + 4 sides' offsets 20 each + 3 quarter circles of r 3 + exit sqrt(149)
    expect = math.sqrt(109) + 80 + 3 * (math.pi / 2 * 3) + math.sqrt(149)
    assert length(moves) == pytest.approx(expect, abs=1e-9)
    for m in moves:
        if m.kind == ARC_CW:
            assert math.dist(m.start[:2], m.centre[:2]) == pytest.approx(3.0)
            assert math.dist(m.end[:2], m.centre[:2]) == pytest.approx(3.0)


def test_g42_mirrors_g41():
    # The square counter-clockwise with G42: outside again, arcs counter-clockwise.
    p = Prog(-10, 0)
    p.on("right", 3.0)
    p.g1(x=0, y=0)  # entry going +X: ends at (0, -3)
    p.g1(x=20)
    p.g1(y=20)
    moves = p.done()
    assert simple(moves) == [
        (LINEAR, (-10, 0), (0, -3), None),
        (LINEAR, (0, -3), (20, -3), None),
        (ARC_CCW, (20, -3), (23, 0), (20, 0)),
        (LINEAR, (23, 0), (23, 20), None),
    ]


def test_concave_entry_corner_pulls_the_entry_back():
    # G42 entry going +Y then a right turn: concave, the entry ends on both offsets.
    p = Prog(0, -10)
    p.on("right", 3.0)
    p.g1(x=0, y=0)
    p.g1(x=20)
    assert simple(p.done()) == [
        (LINEAR, (0, -10), (3, -3), None),
        (LINEAR, (3, -3), (20, -3), None),
    ]


def test_pocket_inside_corners_are_intersections_and_z_moves_follow():
    # The square counter-clockwise with G41: the tool inside, every corner concave.
    p = Prog(10, 10)
    p.on("left", 3.0)
    p.g1(x=10, y=0)  # entry going -Y: offset (13, 0), then pulled back to (13, 3)
    p.g1(z=-1)  # plunge: keeps the tool's XY, and follows the corner
    p.g1(x=20)
    p.g1(y=20)
    p.g1(x=0)
    p.g1(y=0)
    p.g1(x=10)
    p.off()
    p.g1(y=10)
    moves = p.done()
    continuous(moves)
    assert simple(moves) == [
        (LINEAR, (10, 10), (13, 3), None),
        (LINEAR, (13, 3), (13, 3), None),  # the plunge, moved with the corner
        (LINEAR, (13, 3), (17, 3), None),
        (LINEAR, (17, 3), (17, 17), None),
        (LINEAR, (17, 17), (3, 17), None),
        (LINEAR, (3, 17), (3, 3), None),
        (LINEAR, (3, 3), (10, 3), None),
        (LINEAR, (10, 3), (10, 10), None),
    ]
    assert moves[1].start[2] == 0 and moves[1].end[2] == -1
    expect = math.sqrt(58) + 1 + 4 + 14 * 3 + 7 + 7
    assert length(moves) == pytest.approx(expect, abs=1e-9)


def test_arc_offset_outside_and_inside():
    # Upper half circle R10 round (10, 0), clockwise from (0, 0) to (20, 0).
    p = Prog(0, -10)
    p.on("left", 3.0)  # tool outside a clockwise arc: R 13
    p.g1(x=0, y=0)
    p.arc(ARC_CW, 20, 0, 10, 0)
    out = simple(p.done())
    assert out == [(LINEAR, (0, -10), (-3, 0), None), (ARC_CW, (-3, 0), (23, 0), (10, 0))]

    p = Prog(0, -10)
    p.on("right", 3.0)  # tool inside: R 7
    p.g1(x=0, y=0)
    p.arc(ARC_CW, 20, 0, 10, 0)
    moves = p.done()
    assert simple(moves) == [(LINEAR, (0, -10), (3, 0), None), (ARC_CW, (3, 0), (17, 0), (10, 0))]
    assert length(moves) == pytest.approx(math.sqrt(109) + 7 * math.pi)


def test_line_to_arc_concave_corner_is_on_the_offset_circle():
    # G41 r 2: +X along Y=0, then a counter-clockwise quarter R10 round
    # (10, 10) (tangent, tool inside: R 8), then a line back along Y=10
    # going -X: a left turn at (20, 10), concave. The offset line is Y = 8;
    # it meets the offset circle where (x - 10)^2 + 2^2 = 64.
    p = Prog(0, -10)
    p.on("left", 2.0)
    p.g1(x=0, y=0)
    p.g1(x=10)
    p.arc(ARC_CCW, 20, 10, 10, 10)
    p.g1(x=0)
    moves = p.done()
    continuous(moves)
    x = round(10 + math.sqrt(60), 6)
    assert simple(moves) == [
        (LINEAR, (0, -10), (-2, 0), None),
        (ARC_CW, (-2, 0), (0, 2), (0, 0)),  # convex corner at the origin
        (LINEAR, (0, 2), (10, 2), None),  # tangent into the arc
        (ARC_CCW, (10, 2), (x, 8), (10, 10)),  # the arc, cut short at the corner
        (LINEAR, (x, 8), (0, 8), None),
    ]


def test_gouge_slot_narrower_than_the_tool_is_refused():
    p = Prog(0, -10)
    p.on("left", 3.0)
    p.g1(x=0, y=0)
    p.g1(x=10)
    with pytest.raises(Err) as e:
        p.g1(y=2)  # a 2 mm step then back: the r 3 tool cannot get into it
        p.g1(x=0)
    # Found, as LinuxCNC does, when the next corner moves the end of the step
    # back past its start: on line 5.
    assert "t.ngc:5:" in str(e.value)
    assert "without gouging" in str(e.value)


def test_tool_too_big_for_a_concave_arc():
    p = Prog(0, -30)
    p.on("right", 10.0)  # G42 on a clockwise arc: the tool inside an R10 arc
    p.g1(x=0, y=0)
    with pytest.raises(Err, match="t.ngc:3: tool radius too big"):
        p.arc(ARC_CW, 20, 0, 10, 0)


def test_entry_rules():
    p = Prog(0, 0)
    p.on("left", 3.0)
    with pytest.raises(Err, match="entry move .2 mm. is not longer than the tool radius"):
        p.g1(x=2)
    p = Prog(0, 0)
    p.on("left", 3.0)
    with pytest.raises(Err, match="arc as the first move after G41/G42"):
        p.arc(ARC_CW, 20, 0, 10, 0)


def test_z_only_and_dwell_before_the_entry_pass_unchanged():
    p = Prog(0, -10, 5)
    p.on("left", 3.0)
    p.g1(z=-1)
    p.dwell(0.5)
    p.g1(x=0, y=0)
    moves = p.done()
    assert [(m.kind, m.start[:3], m.end[:3]) for m in moves] == [
        (LINEAR, (0, -10, 5), (0, -10, -1)),
        (DWELL, (0, -10, -1), (0, -10, -1)),
        (LINEAR, (0, -10, -1), (-3, 0, -1)),
    ]


def test_rapid_round_a_convex_corner_is_straight():
    p = Prog(0, -10)
    p.on("left", 3.0)
    p.g1(x=0, y=0)
    p.g1(y=20)
    p.g0(x=20)
    moves = p.done()
    assert simple(moves)[2:] == [
        (RAPID, (-3, 20), (0, 23), None),
        (RAPID, (0, 23), (20, 23), None),
    ]


def test_errors_on_planes_and_modes():
    c = CutterComp(err)
    with pytest.raises(Err, match="t.ngc:5: cutter compensation in the G19 .YZ. plane"):
        c.on("left", 3, 2, 5)
    c.on("left", 3, 0, 6)
    with pytest.raises(Err, match="t.ngc:7: cutter compensation is already on"):
        c.on("right", 3, 0, 7)
    with pytest.raises(Err, match="t.ngc:8: cannot change plane"):
        c.plane_change(1, 8)
    c.plane_change(0, 9)  # the same plane is fine
    with pytest.raises(Err, match="t.ngc:4: cannot change plane"):
        c.push(Move(LINEAR, p6(0, 0), p6(10, 0), 100.0, 4, plane=1))


def test_negative_radius_swaps_the_side():
    p = Prog(0, -10)
    p.on("left", -3.0)
    p.g1(x=0, y=0)
    assert simple(p.done())[0][2] == (3, 0)


def test_xz_plane_offsets_in_z_x_order():
    # G18: the plane's axes in arc-sense order are (Z, X); the left of a
    # move going +Z is +X.
    p = Prog(0, 0, 0, plane=1)
    p.on("left", 2.0)
    p.g1(z=10)  # in-plane move (Z), entry
    moves = p.done()
    assert moves[0].end[:3] == pytest.approx((2.0, 0.0, 10.0))


def test_zero_radius_is_the_programmed_path():
    p = Prog(0, -10)
    p.on("left", 0.0)
    p.g1(x=0, y=0)
    p.g1(x=10)
    assert [m.end[:2] for m in p.done()] == [(0, 0), (10, 0)]


def test_acute_inside_corner_is_an_intersection():
    # G41 r 1: +X along Y=0, then a 135 degree left turn towards (0, 10).
    # Offsets: Y = 1 and X + Y = 10 - sqrt(2); they meet at X = 9 - sqrt(2).
    p = Prog(0, -10)
    p.on("left", 1.0)
    p.g1(x=0, y=0)
    p.g1(x=10)
    p.g1(x=0, y=10)
    moves = p.done()
    x = round(9 - math.sqrt(2), 6)
    h = round(math.sqrt(0.5), 6)
    assert simple(moves) == [
        (LINEAR, (0, -10), (-1, 0), None),
        (ARC_CW, (-1, 0), (0, 1), (0, 0)),
        (LINEAR, (0, 1), (x, 1), None),
        (LINEAR, (x, 1), (-h, round(10 - math.sqrt(0.5), 6)), None),
    ]


def test_overflowing_offsets_are_an_error():
    p = Prog(-1e308, 0)
    p.on("left", 3.0)
    with pytest.raises(Err, match="t.ngc:2: cutter compensation: the offset path is out of range"):
        p.g1(x=1e308, y=0)


def test_random_programs_give_continuous_moves_or_a_clear_error():
    # Seeded random lines, arcs, Z moves, dwells, G41/G42/G40: every outcome is
    # a continuous path or an Err naming a line; never another exception.
    import random

    rnd = random.Random(17)
    for _ in range(3000):
        c = CutterComp(err)
        pos = p6(0, 0)
        out = []
        try:
            for i in range(1, rnd.randint(2, 12)):
                r = rnd.random()
                if r < 0.1:
                    if c.active:
                        c.off(i)
                    else:
                        c.on(rnd.choice(["left", "right"]), rnd.choice([0, 0.5, 1, 3, 10]), 0, i)
                    continue
                kind = rnd.choice([LINEAR, LINEAR, RAPID, ARC_CW, ARC_CCW, DWELL])
                if kind == DWELL:
                    m = Move(DWELL, pos, pos, NAN, i, dwell_s=1.0)
                elif kind in (LINEAR, RAPID):
                    end = list(pos)
                    if rnd.random() < 0.2:
                        end[2] += rnd.uniform(-5, 5)
                    else:
                        end[0] = rnd.choice([0, 10, 20, pos[0] + rnd.uniform(-20, 20)])
                        end[1] = rnd.choice([0, 10, 20, pos[1] + rnd.uniform(-20, 20)])
                    m = Move(kind, pos, tuple(end), 100.0, i)
                else:
                    cen = (pos[0] + rnd.uniform(-10, 10), pos[1] + rnd.uniform(-10, 10))
                    rad = math.hypot(pos[0] - cen[0], pos[1] - cen[1])
                    a = rnd.uniform(0, 2 * math.pi)
                    end = (cen[0] + rad * math.cos(a), cen[1] + rad * math.sin(a)) + pos[2:]
                    m = Move(kind, pos, end, 100.0, i, centre=cen + (NAN,))
                out += c.push(m)
                pos = m.end
            out += c.flush()
        except Err as e:
            assert str(e).startswith("t.ngc:")
            continue
        if not out:
            continue
        assert out[0].start == p6(0, 0)
        continuous(out)
        for m in out:
            if m.kind in (ARC_CW, ARC_CCW):
                r0 = math.dist(m.start[:2], m.centre[:2])
                r1 = math.dist(m.end[:2], m.centre[:2])
                # A corner within the tolerance joins without an arc: the
                # start may then be off the radius by up to r * 0.05.
                assert abs(r0 - r1) <= 0.05 * 5 + 1e-9


# Regression cases found by running random programs through LinuxCNC 2.9's
# own interpreter (rs274 of the Debian 12 package) next to this module; the
# expected points are what rs274 printed (4 decimals).


def points(moves):
    """[(kind, (x, y, z), centre xy or None)] without zero-length straight moves."""
    out = []
    for m in moves:
        if m.kind in (LINEAR, RAPID) and m.start == m.end:
            continue
        c = None if m.centre is None else tuple(m.centre[:2])
        out.append((m.kind, tuple(m.end[:3]), c))
    return out


def assert_points(moves, expect):
    got = points(moves)
    assert [g[0] for g in got] == [e[0] for e in expect], got
    for g, e in zip(got, expect):
        assert g[1] == pytest.approx(e[1], abs=1e-4), (got, expect)
        if e[2] is not None:
            assert g[2] == pytest.approx(e[2], abs=1e-4)


def test_a_turn_within_005_rad_is_joined_straight():
    p = Prog(36, 5)
    p.on("right", 1.0)
    p.g1(x=36, y=15)
    p.g1(x=35, y=29)
    p.g1(x=33, y=46)  # a 0.046 rad turn: no corner arc
    p.off()
    p.g1(x=14, y=56)
    assert_points(
        p.done(),
        [
            (LINEAR, (37, 15, 0), None),
            (ARC_CCW, (36.9975, 15.0712, 0), (36, 15)),
            (LINEAR, (35.9975, 29.0712, 0), None),
            (LINEAR, (33.9932, 46.1168, 0), None),
            (LINEAR, (14, 56, 0), None),
        ],
    )


def test_g40_checks_the_held_move_for_gouging():
    p = Prog(-2, 2)
    p.on("left", 3.0)
    p.g1(x=3, y=6)
    p.g1(z=-1)
    p.g1(x=-8, y=2)  # pulls the entry back past its start
    with pytest.raises(Err, match="t.ngc:5: .*without gouging"):
        p.off()


def test_a_convex_corner_checks_the_held_line():
    p = Prog(-27, -15)
    p.on("right", 0.5)
    p.g1(x=-43, y=-33)
    p.g1(x=-37, y=-25)  # nearly reversed: its offset runs backwards
    with pytest.raises(Err, match="t.ngc:4: .*without gouging"):
        p.g1(x=-28, y=-7)


def test_entry_followed_by_a_sharp_concave_corner():
    p = Prog(-10, -17)
    p.on("right", 1.0)
    p.g1(x=-18, y=-11)
    p.g1(x=-1, y=-20)  # a 171 degree turn back
    p.g1(x=19, y=-33)
    p.off()
    p.g1(x=1, y=-44)
    assert_points(
        p.done(),
        [
            (LINEAR, (-7.2039, -17.8471, 0), None),
            (LINEAR, (-1.5075, -20.8628, 0), None),
            (LINEAR, (18.4550, -33.8384, 0), None),
            (LINEAR, (1, -44, 0), None),
        ],
    )


def test_reversal_between_arcs_of_one_centre_goes_round_the_corner():
    p = Prog(28, -13)
    p.on("left", 0.5)
    p.g1(x=46, y=-14)
    p.arc(ARC_CW, 48, -18, 51, -14)
    p.arc(ARC_CCW, 47, -11, 51, -14)
    p.off()
    p.g1(x=28, y=6)
    assert_points(
        p.done(),
        [
            (LINEAR, (45.5253, -13.4729, 0), None),
            (ARC_CW, (47.7, -18.4, 0), (51, -14)),
            (ARC_CW, (48.3, -17.6, 0), (48, -18)),
            (ARC_CCW, (47.4, -11.3, 0), (51, -14)),
            (LINEAR, (28, 6, 0), None),
        ],
    )


def test_concave_line_to_arc_takes_the_point_that_shortens_the_line():
    p = Prog(16, -22)
    p.on("right", 0.5)
    p.g1(x=22, y=-20)
    p.g1(x=25, y=-3)
    p.g1(x=12, y=14)
    p.arc(ARC_CCW, 16, 22, 16, 17)  # nearly reverses onto the arc's outside
    p.off()
    p.g1(x=0, y=15)
    assert_points(
        p.done(),
        [
            (LINEAR, (22.1581, -20.4743, 0), None),
            (ARC_CCW, (22.4924, -20.0869, 0), (22, -20)),
            (LINEAR, (25.4924, -3.0869, 0), None),
            (ARC_CCW, (25.3972, -2.6963, 0), (25, -3)),
            (LINEAR, (14.3467, 11.7544, 0), None),
            (ARC_CCW, (16, 22.5, 0), (16, 17)),
            (LINEAR, (0, 15, 0), None),
        ],
    )


def test_an_arc_joined_straight_may_sweep_a_little_more_than_programmed():
    # The entry ends 0.031 rad off the arc's tangent: joined without a corner,
    # the offset arc sweeps 0.009 rad more than programmed, within LinuxCNC's slack.
    p = Prog(3, 15)
    p.on("left", 2.0)
    p.g1(x=-9, y=30)
    p.arc(ARC_CW, -9, 36, -5, 33)
    p.off()
    p.g1(x=-10, y=47)
    assert_points(
        p.done(),
        [
            (LINEAR, (-10.5617, 28.7506, 0), None),
            (ARC_CW, (-10.6, 37.2, 0), (-5, 33)),
            (LINEAR, (-10, 47, 0), None),
        ],
    )


def test_after_g40_a_z_move_returns_to_the_programmed_xy_and_an_arc_is_refused():
    p = Prog(21, -27)
    p.on("left", 3.0)
    p.g1(x=4, y=-16)
    p.g1(x=-4, y=-32)
    p.off()
    p.g1(z=-2)
    assert_points(
        p.done(),
        [
            (LINEAR, (5.1843, -20.3396, 0), None),
            (LINEAR, (-1.3167, -33.3416, 0), None),
            (LINEAR, (-4, -32, -2), None),
        ],
    )
    p = Prog(0, -10)
    p.on("left", 3.0)
    p.g1(x=0, y=0)
    p.off()
    with pytest.raises(Err, match="t.ngc:4: the first move after G40 must be a straight line"):
        p.arc(ARC_CW, 20, 0, 10, 0)


def test_h_shape_reversal_off_the_outside_of_an_arc_stays_on_the_near_side():
    # G42 over the top of a half circle, then straight back up beside it: the
    # 180 degree turn is taken as concave (the arc is cut where X = 1 meets R 6).
    p = Prog(10, -10)
    p.on("right", 1.0)
    p.g1(x=10, y=0)
    p.arc(ARC_CCW, 0, 0, 5, 0)
    p.g1(x=0, y=10)
    p.off()
    p.g1(x=-5, y=15)
    assert_points(
        p.done(),
        [
            (LINEAR, (11, 0, 0), None),
            (ARC_CCW, (1, math.sqrt(20), 0), (5, 0)),
            (LINEAR, (1, 10, 0), None),
            (LINEAR, (-5, 15, 0), None),
        ],
    )
