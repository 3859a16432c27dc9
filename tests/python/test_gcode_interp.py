"""The interpreter (issue #17): offsets, units, dwell, policy, modal groups,
bounded resources. Expectations are computed by hand; the per-feature
programs of tests/gcode/programs run here through gcode.read alone."""

import math
from pathlib import Path

import numpy as np
import pytest
from contour import gcode
from contour.gcode import DWELL, LINEAR, RAPID, GcodeError

PROGRAMS = sorted((Path(__file__).resolve().parents[1] / "gcode" / "programs").glob("*.ngc"))


def read(text, **kw):
    return gcode.read("t.nc", text=text, **kw)


def lengths(p):
    s = gcode.segments(p, 1e-7)
    moving = ~np.isin(p.kind[s.block], [DWELL])
    feed = float(s.length[moving & ~s.rapid].sum())
    rapid = float(s.length[moving & s.rapid].sum())
    return feed, rapid


def test_g92_makes_the_current_point_x0_without_moving():
    p = read("G21 G90\nG1 X10 F100\nG92 X0\nG1 X10\n")
    assert list(p.kind) == [LINEAR, LINEAR]
    np.testing.assert_allclose(p.end[:, 0], [10, 20])
    assert lengths(p) == (pytest.approx(20.0), 0.0)


def test_g10_l2_moves_nothing_and_sets_the_g54_origin():
    p = read("G21 G90\nG10 L2 P1 X100 Y100\nG54 G0 X0\n")
    assert len(p) == 1
    np.testing.assert_allclose(p.end[0, :3], [100, 0, 0])
    # Set in the program: no 'zero offset' report for G54.
    assert "G54" not in p.skipped


def test_g54_selected_without_g10_reports_the_zero_offset():
    p = read("G21 G90 G54\nG0 X1\n")
    assert "zero unless set" in p.skipped["G54"].note


def test_g10_l2_p0_is_the_active_system_and_applies_at_once():
    p = read("G21 G90\nG10 L2 P2 X7\nG55\nG10 L2 P0 X3\nG0 X1\n")
    np.testing.assert_allclose(p.end[0, 0], 4)


def test_g53_in_a_g55_program_is_machine_coordinates_for_its_line_only():
    p = read("G21 G90\nG10 L2 P2 X50 Y20\nG55 G0 X0 Y0\nG53 G0 X10\nG1 X5 F100\n")
    np.testing.assert_allclose(p.end[:, :2], [[50, 20], [10, 20], [55, 20]])


def test_g53_needs_g0_or_g1_and_absolute_mode():
    with pytest.raises(GcodeError, match=r"t.nc:2: G53 needs G0 or G1"):
        read("G21 G1 X1 F10\nG2 G53 X0 Y1 I-1 J0\n")
    with pytest.raises(GcodeError, match=r"t.nc:2: G53 in incremental distance mode"):
        read("G21 G0 X1\nG91 G53 X0\n")


def test_g28_goes_through_the_intermediate_point_to_the_stored_position():
    p = read("G21 G90\nG0 X10 Y10 Z5\nG28.1\nG0 X50 Y40 Z20\nG28 Z30\n")
    np.testing.assert_allclose(p.end[2:, :3], [[50, 40, 30], [50, 40, 5]])
    assert list(p.kind[2:]) == [RAPID, RAPID]
    assert "G28" not in p.skipped


def test_g28_without_g28_1_uses_zero_and_says_so():
    p = read("G21 G90\nG0 X10 Y5\nG28 X20\n")
    np.testing.assert_allclose(p.end[:, :2], [[10, 5], [20, 5], [0, 5]])
    assert "G28.1" in p.skipped["G28"].note


def test_g28_intermediate_point_is_in_program_coordinates():
    p = read("G21 G90\nG10 L2 P1 Z100\nG30.1\nG0 X1\nG30 Z5\n")
    np.testing.assert_allclose(p.end[1:, 2], [105, 0])


def test_g20_program_is_read_in_inches():
    p = read("G20 G90\nG1 X1 Y1 F10\nG91 X1\n")
    np.testing.assert_allclose(p.end[:, :2], [[25.4, 25.4], [50.8, 25.4]])
    np.testing.assert_allclose(p.feed, [254, 254])
    assert "G20/G21" not in p.skipped


def test_program_without_units_reports_millimetres():
    p = read("G90\nG1 X10 F100\n")
    s = p.skipped["G20/G21"]
    assert s.first_line == 2 and "millimetres" in s.note
    assert p.end[0, 0] == 10


def test_dwell_is_a_row_in_seconds():
    p = read("G21\nG4 P0.5\nG1 X1 F60\nG4 P1.5\n")
    assert list(p.kind) == [DWELL, LINEAR, DWELL]
    np.testing.assert_allclose(p.dwell_s, [0.5, 0, 1.5])
    with pytest.raises(GcodeError, match="t.nc:2: dwell time -1 s out of range"):
        read("G21\nG4 P-1\n")


@pytest.mark.parametrize(
    "code,feature",
    [
        ("G93 G1 X10 F2", "G93 inverse time feed"),
        ("G95 G1 X10 F1", "G95 feed per revolution"),
        ("G5.2 X0 Y0 P1 L3", "G5.2 NURBS"),
        ("G33 Z-1 K1", "G33 spindle-synchronized motion"),
        ("G76 P1 Z-1 I-1 J1 K1", "G76 threading cycle"),
        ("G38.2 Z-10 F50", "G38.2 probing"),
        ("G43 H1", "G43 tool length offset"),
        ("G17.1", "G17.1 UV plane"),
        ("G52 X1", "G52 local coordinate offset"),
        ("G10 L1 P1 R2", "G10 L1"),
        ("G10 L2 P1 R30", "coordinate system rotation (G10 L2 R)"),
        ("M66 P0 L3 Q5", "M66 wait on input"),
        ("M72", "M72 restore modal state"),
        ("M101", "M101 (user-defined M code)"),
        ("G1 W1 F100", "W axis"),
        ("G12 X1", "G12"),
        ("G70 Q100 X15 Z4 D1 P1", "G70 lathe finishing cycle"),
        ("G71 Q100 X-5 Z-14 D0.5 I1 R0.3", "G71 lathe roughing cycle"),
        ("G72 Q100 X-5 Z-14", "G72"),
    ],
)
def test_refusals_name_the_feature_and_the_line(code, feature):
    with pytest.raises(GcodeError) as exc:
        read(f"G21\nG0 X5\n{code}\n")
    assert str(exc.value) == f"t.nc:3: {feature} is not supported"


@pytest.mark.parametrize(
    "code,message",
    [
        ("G0 G1 X10 F100", "G0 and G1 on one line: two G codes of the same modal group"),
        ("G20 G21", "G20 and G21 on one line"),
        ("G1 G92 X10 F100", "G1 and G92 both use the axis words"),
        ("G10 L2 P1 G28 X1", "G10 and G28 on one line"),
        ("G80 X1", "axis words with G80"),
        ("M3 M4", "M3 and M4 on one line"),
        ("M8 M9", "M8 and M9 on one line"),
        ("M7 M8", "M7 and M8 on one line"),
        ("M0 M1", "M0 and M1 on one line"),
        ("G1 X1 X2 F10", "two X words on one line"),
        ("G1 X1 I5 F10", "I word with nothing on the line to use it"),
        ("G1 X1 F10 R1", "R word with nothing on the line to use it"),
        ("G92", "G92 without axis words"),
        ("G10 L2 P10 X1", "G10 L2/L20: P must be an integer 0 to 9"),
    ],
)
def test_modal_group_and_word_conflicts_are_errors(code, message):
    with pytest.raises(GcodeError) as exc:
        read(f"G21\n{code}\n")
    assert str(exc.value).startswith(f"t.nc:2: {message}")


def test_g2_with_a_centre_and_no_axis_word_is_a_full_circle():
    # As LinuxCNC's rs274 reads its own 3dtest.ngc.
    p = read("G20 F30\nG0 X1 Y1\nG17 G2 I.5 J.5\n")
    assert p.kind[1] == gcode.ARC_CW
    np.testing.assert_allclose(p.end[1, :2], [25.4, 25.4])
    np.testing.assert_allclose(p.centre[1, :2], [38.1, 38.1])
    s = gcode.segments(p, 1e-6)
    assert s.length[s.block == 1].sum() == pytest.approx(2 * math.pi * 25.4 / math.sqrt(2))
    with pytest.raises(GcodeError, match="t.nc:3: arc without end point"):
        read("G21\nG1 X1 F10\nG2\n")


def test_axis_words_before_a_motion_mode_are_an_error():
    with pytest.raises(GcodeError, match="t.nc:2: axis words without a motion mode"):
        read("G21\nX10\n")


def test_words_that_change_nothing_are_reported_once_per_kind():
    p = read("G21\nT1 M6\nS1000 M3\nG1 X1 F10 M8\nX2 M8\nM5 M9\n")
    kinds = {s.kind: (s.first_line, s.count) for s in p.skipped_list()}
    assert kinds["T"] == (2, 1) and kinds["M6"] == (2, 1) and kinds["S"] == (3, 1)
    assert kinds["M8"] == (4, 2) and kinds["M5"] == (6, 1) and kinds["M9"] == (6, 1)


def test_arc_turns_are_capped_and_huge_arcs_are_errors_not_tracebacks():
    with pytest.raises(GcodeError, match=r"t.nc:3: arc turns P3e\+06 above the limit"):
        read("G21\nG1 X10 F100\nG2 X10 Y0 I-10 J0 P3000000\n")
    for arc in ("G2 X2 Y0 I1000000000000000", "G2 X2 Y0 R" + "9" * 300, "G2 X2 Y0 R0.0000001"):
        with pytest.raises(GcodeError, match="t.nc:3: arc"):
            read(f"G21\nG1 X1 F100\n{arc}\n")


def test_segments_caps_the_chords_of_one_arc():
    p = read("G21\nG1 X500 F100\nG2 X500 Y0 I-500 J0 P1000\n")
    with pytest.raises(GcodeError, match=r"t.nc:3: arc needs more than 1000000 chords"):
        gcode.segments(p, 1e-6)
    assert len(gcode.segments(p, 0.01)) < 1_000_000


def test_coordinates_beyond_any_machine_are_errors():
    with pytest.raises(GcodeError, match="t.nc:3: coordinate out of range"):
        read("G20\nG0 X1\nG0 X" + "9" * 15 + "\n")


def test_program_columns_are_compact_arrays():
    p = read("G21\nG1 X1 F10\nX2\n")
    assert p.end.dtype == np.float64 and p.end.base is not None  # a view on the array buffer
    assert p.line.dtype == np.int32 and p.kind.dtype == np.int8
    assert p.centre.strides == (0, 8)  # no arcs: a broadcast view, no memory


def test_read_chunks_yields_bounded_pieces_that_join_up():
    text = "G21 G91\n" + "G1 X1 F100\n" * 10 + "G4 P1\n" + "G2 X2 Y0 I1 J0\n" * 3 + "M3\n"
    whole = read(text)
    pieces = list(gcode.read_chunks("t.nc", rows=4, text=text))
    assert [len(p) for p in pieces] == [4, 4, 4, 2]
    np.testing.assert_array_equal(np.concatenate([p.end for p in pieces]), whole.end)
    np.testing.assert_array_equal(np.concatenate([p.dwell_s for p in pieces]), whole.dwell_s)
    np.testing.assert_array_equal(np.concatenate([p.centre for p in pieces]), whole.centre)
    for a, b in zip(pieces, pieces[1:]):
        np.testing.assert_array_equal(b.start, a.end[-1])
    assert "M3" in pieces[-1].skipped and "M3" not in pieces[0].skipped


def test_cutter_comp_g41_1_offsets_the_path():
    # Tool radius 1 on the left of a +X move: the path runs at Y+1.
    p = read("G21 G90\nG0 X0 Y0\nG41.1 D2\nG1 X10 Y0 F100\nX20\nG40\nG0 X30 Y5\n")
    np.testing.assert_allclose(p.end[1:3, :2], [[10, 1], [20, 1]], atol=1e-9)
    np.testing.assert_allclose(p.end[-1, :2], [30, 5])


@pytest.mark.parametrize("path", PROGRAMS, ids=[p.stem for p in PROGRAMS])
def test_feature_program(path):
    expect = {}
    for text in path.read_text().splitlines():
        if text.startswith("; expect "):
            key, _, value = text[len("; expect ") :].partition(":")
            expect[key.strip()] = value.strip()
    if "refused" in expect:
        # Refused by the reader, or else by the drive-range checks every
        # command runs on the reader's blocks (link/blocks.py).
        from contour.errors import UserError
        from contour.link.blocks import check_gcode

        try:
            gcode.read(path)
        except GcodeError as e:
            assert expect["refused"] in str(e)
            return
        with pytest.raises(UserError) as exc:
            check_gcode(str(path))
        assert expect["refused"] in str(exc.value)
        return
    p = gcode.read(path)
    feed, rapid = lengths(p)
    if "end" in expect:
        want = {w[0]: float(w[1:]) for w in expect["end"].split()}
        for axis, v in want.items():
            assert p.end[-1, "XYZABC".index(axis)] == pytest.approx(v, abs=1e-6), axis
    if "feed_mm" in expect:
        assert feed == pytest.approx(float(expect["feed_mm"]), abs=1e-5)
    if "rapid_mm" in expect:
        assert rapid == pytest.approx(float(expect["rapid_mm"]), abs=1e-5)
    if "dwell_s" in expect:
        assert float(p.dwell_s.sum()) == pytest.approx(float(expect["dwell_s"]))
    # notes the commands add about their machine are checked by the harness
    command_notes = {"rotary+linear", "rotary only", "feed capped"}
    for kind in expect.get("reported", "").split():
        if kind not in command_notes:
            assert kind in p.skipped, kind
    assert math.isfinite(float(np.abs(p.end).sum()))


def _interpreter(lines):
    from contour.gcode.interp import Interpreter
    from contour.gcode.lexer import Block

    it = Interpreter("t.nc", None, None)
    blocks = [Block(i, words) for i, words in enumerate(lines, 1)]
    for _ in it.run(iter(blocks)):
        pass
    return it


def test_offsets_live_in_linuxcnc_parameters():
    it = _interpreter(
        [
            [("G", 21.0), ("G", 90.0)],
            [("G", 10.0), ("L", 2.0), ("P", 2.0), ("X", 100.0), ("Z", -5.0)],
            [("G", 55.0), ("G", 0.0), ("X", 1.0), ("Y", 2.0)],
            [("G", 92.0), ("X", 0.0)],
            [("G", 28.1)],
            [("G", 20.0)],
        ]
    )
    get = it.params.get
    assert (get(5241, 0), get(5243, 0)) == (100.0, -5.0)  # G55 X, Z
    assert get(5220, 0) == 2.0  # G55 selected
    assert (get(5210, 0), get(5211, 0)) == (1.0, 1.0)  # G92 on, X offset 1 mm
    assert (get(5161, 0), get(5162, 0), get(5163, 0)) == (101.0, 2.0, 0.0)  # machine
    # Current position in program coordinates and units (G20 now): X0, Y 2 mm, Z +5 mm.
    assert get(5420, 0) == 0.0
    assert get(5421, 0) == pytest.approx(2 / 25.4)
    assert get(5422, 0) == pytest.approx(5 / 25.4)
    assert it.params.system("_x") == 0.0 and it.params.system("_metric") == 0.0
    assert it.params.system("_coord_system") == 550
    with pytest.raises(GcodeError, match="read-only"):
        it.params.set(5420, 1.0, 7)


def test_parameter_assignment_takes_effect_when_the_system_is_selected_again():
    it = _interpreter([[("G", 21.0)], [("G", 54.0)], [("G", 0.0), ("X", 0.0)]])
    it.params.set(5221, 7.0)
    # G54 while G54 is active: LinuxCNC does not reload ("continuing to use
    # same coordinate system"), checked against its rs274.
    it.block(4, [("G", 54.0), ("G", 0.0), ("X", 1.0)])
    assert it.pos[0] == 1.0
    it.block(5, [("G", 55.0)])
    it.block(6, [("G", 54.0), ("G", 0.0), ("X", 1.0)])
    assert it.pos[0] == 8.0


def test_g41_takes_the_radius_from_the_tool_table(tmp_path):
    table = tmp_path / "tools.tbl"
    table.write_text("T1 P1 D4.0 ;4 mm end mill\nT2 P2 D10\n")
    text = "G21 G90\nG0 X0 Y0\nG41 D1\nG1 X10 Y0 F100\nX20\nG40\nG0 X30 Y5\n"
    p = read(text, tool_table=table)
    np.testing.assert_allclose(p.end[1:3, :2], [[10, 2], [20, 2]], atol=1e-9)
    # Without D: the current tool (T2 M6), radius 5, on the right for G42.
    p = read(text.replace("G41 D1", "T2 M6\nG42"), tool_table=table)
    np.testing.assert_allclose(p.end[1:3, :2], [[10, -5], [20, -5]], atol=1e-9)
    assert "D" not in p.skipped  # D of G41/G42 is used, not reported
    with pytest.raises(GcodeError, match="t.nc:3: G41: tool 7 is not in the tool table"):
        read(text.replace("D1", "D7"), tool_table=table)


def test_any_arc_is_read_or_a_gcode_error():
    rng = np.random.default_rng(17)
    values = ["0", "0.0000001", "1", "-1", "2.5", "-400", "1000000", "99999999999", "1" + "0" * 40]
    errors = 0
    for _ in range(400):
        w = {c: rng.choice(values) for c in "XYIJR"}
        form = f"I{w['I']} J{w['J']}" if rng.random() < 0.5 else f"R{w['R']}"
        turns = f" P{rng.integers(1, 4)}" if rng.random() < 0.2 else ""
        plane = rng.choice(["G17", "G18", "G19"])
        letters = {"G17": "XY", "G18": "ZX", "G19": "YZ"}[plane]
        form = form.replace("I", {"G17": "I", "G18": "K", "G19": "J"}[plane] + "@", 1)
        form = form.replace("J", {"G17": "J", "G18": "I", "G19": "K"}[plane], 1).replace("@", "")
        text = (
            f"G21 {plane}\nG1 X1 Y1 Z1 F100\n"
            f"{rng.choice(['G2', 'G3'])} {letters[0]}{w['X']} {letters[1]}{w['Y']} {form}{turns}\n"
        )
        try:
            gcode.segments(read(text), 0.01)
        except GcodeError as exc:
            assert exc.line == 3, text
            errors += 1
    assert 0 < errors < 400


@pytest.mark.parametrize(
    "code,message",
    [
        ("G55", "cannot change the coordinate system with cutter compensation on"),
        ("G92 X0", "cannot change the G92 offsets with cutter compensation on"),
        ("G10 L2 P1 X5", "cannot change the active coordinate system with cutter compensation"),
        ("G28", "G28 with cutter compensation on"),
        ("G53 G0 X0", "G53 with cutter compensation on"),
        ("G81 X1 Y1 Z-1 R1", "canned cycles cannot be used with cutter compensation on"),
    ],
)
def test_offsets_cannot_change_under_cutter_compensation(code, message):
    with pytest.raises(GcodeError) as exc:
        read(f"G21 G90\nG0 X0 Y0\nG41.1 D2\nG1 X10 F100\n{code}\n")
    assert str(exc.value).startswith("t.nc:5: ") and message in str(exc.value)
    # After G40 the same line is fine (G10 L2 P2 for another system always is).
    read(f"G21 G90\nG0 X0 Y0\nG41.1 D2\nG1 X10 F100\nG10 L2 P2 X5\nG40\nG0 X20\n{code}\n")
