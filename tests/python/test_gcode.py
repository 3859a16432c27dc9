"""G-code reader: RS-274 subset, Sinumerik dialect words, errors, arcs."""

import math
from pathlib import Path

import numpy as np
import pytest
from contour import gcode
from contour.errors import UserError
from contour.gcode import ARC_CCW, ARC_CW, DWELL, LINEAR, RAPID, GcodeError

SHARED = Path(__file__).resolve().parents[2].parent / "shared"
ANTONIO = sorted((SHARED / "data" / "antonio2019").glob("*.mpf"))


def read(text, **kw):
    return gcode.read("t.nc", text=text, **kw)


def test_linear_moves_positions_feeds_and_lines():
    p = read("G21 G90\nG0 X10 Y5\n\nG1 Z-1 F300\nX20\nY15 F600\n")
    assert list(p.kind) == [RAPID, LINEAR, LINEAR, LINEAR]
    np.testing.assert_allclose(p.end[:, :3], [[10, 5, 0], [10, 5, -1], [20, 5, -1], [20, 15, -1]])
    assert math.isnan(p.feed[0])
    np.testing.assert_allclose(p.feed[1:], [300, 300, 600])
    assert list(p.line) == [2, 4, 5, 6]
    assert p.lines_read == 6


def test_incremental_and_inch():
    p = read("G20 G91 G1 X1 F10\nX1 Y-0.5\nG90 G21 X0 Y0\n")
    np.testing.assert_allclose(p.end[:, :2], [[25.4, 0], [50.8, -12.7], [0, 0]])
    np.testing.assert_allclose(p.feed, [254, 254, 254])


def test_sinumerik_metric_and_compact_words():
    p = read("G700 G1X1Y2F4\nG710 X3")
    np.testing.assert_allclose(p.end[:, :2], [[25.4, 50.8], [3, 50.8]])
    assert p.feed[0] == pytest.approx(101.6)


def test_fast_and_general_paths_agree():
    plain = read("G1 X1 Y2 Z3 F100\nX4.5 Y-.5\nN30 Z1.\n")
    noisy = read("G1 X1 Y2 Z3 F100 (comment)\nX4.5 Y-.5 ; tail\n N30 Z1. M8\n")
    np.testing.assert_array_equal(plain.end, noisy.end)
    np.testing.assert_array_equal(plain.feed, noisy.feed)
    assert "M8" in noisy.skipped


@pytest.mark.parametrize(
    "text,message",
    [
        ("G1 X1.2.3 F100", "malformed number in 'X1.2.3'"),
        ("G1 X- F100", "malformed number in 'X-'"),
        ("G1 X F100", "value expected at 'F100'"),
        ("G1 X12-3 F100", "malformed number in 'X12-3'"),
        ("G1 X1 E5 F100", "unknown address letter 'E'"),
        ("G1 U1 F100", "U axis is not supported"),
        ("G1 X1 @ F100", "polar coordinates (@ ^) are not supported"),
        ("G1 X1 (open comment", "unclosed comment"),
    ],
)
def test_bad_words_are_file_line_errors(text, message):
    with pytest.raises(GcodeError) as exc:
        read("G21\n; fine\n" + text)
    assert str(exc.value).startswith(f"t.nc:3: {message}")
    assert exc.value.line == 3


def test_unknown_letter_in_fast_path_line_is_an_error():
    # A line made only of letter+number words takes the fast path.
    with pytest.raises(GcodeError, match=r"t.nc:2: W axis is not supported"):
        read("G1 X0 F100\nX1 W2\n")


def test_feed_move_without_feed_needs_default():
    with pytest.raises(GcodeError, match=r"t.nc:1: feed move before any feed rate"):
        read("G1 X1")
    p = read("G1 X1", default_feed=700)
    assert p.feed[0] == 700
    assert p.skipped["missing F"].first_line == 1


def test_f_equals_r_parameter():
    with pytest.raises(GcodeError) as exc:
        read("G90\nG1 X1 F=R0\n")
    assert str(exc.value).startswith("t.nc:2: cannot evaluate F=R0")
    assert "--feed" in str(exc.value)
    p = read("G90\nG1 X1 F=R0\nX2\n", default_feed=2500)
    np.testing.assert_allclose(p.feed, [2500, 2500])
    s = p.skipped["F=R0"]
    assert (s.first_line, s.count) == (2, 1)
    # An R parameter set to a constant in the file is understood.
    p = read("R0=1234.5\nG1 X1 F=R0\n")
    assert p.feed[0] == 1234.5 and set(p.skipped) == {"G20/G21"}
    # Set from an expression: unknown again.
    with pytest.raises(GcodeError, match="cannot evaluate F=R1"):
        read("R1=$A_HOUR\nG1 X1 F=R1\n")


def test_rotary_dc_takes_the_short_way():
    p = read("G0 C350\nG0 C=DC(10)\nG0 B=IC(-5) C=ACP(5)\nC=ACN(10)\n")
    np.testing.assert_allclose(p.end[:, 5], [350, 370, 725, 370])
    np.testing.assert_allclose(p.end[:, 4], [0, 0, -5, -5])


def test_skipped_words_reported_once_per_kind_with_first_line():
    text = (
        "N1 G40 G17 G710 G94 G90 G60 G601 FNORM\n"
        "N2 ;(*- comment -*)\n"
        'N3 T="BALL8" D1\n'
        'N4 CYCLE800(,"0",)\n'
        "N5 TRAORI\n"
        "N6 G54\n"
        "N7 G1 X1 F100 M8\n"
        "N8 X2 M8\n"
        "N9 CYCLE832(0.005,1,1)\n"
        "N10 M30\n"
        "N11 X5\n"
    )
    p = read(text)
    kinds = {s.kind: (s.first_line, s.count) for s in p.skipped_list()}
    assert kinds["T="] == (3, 1)
    assert kinds["D"] == (3, 1)
    assert kinds["CYCLE800"] == (4, 1)
    assert kinds["TRAORI"] == (5, 1)
    assert kinds["G54"] == (6, 1)
    assert kinds["M8"] == (7, 2)
    assert kinds["after M2/M30"] == (11, 1)
    assert "G17" not in kinds and "G60" not in kinds and "G601" not in kinds
    assert len(p) == 2  # nothing after M30


def test_exact_stop_modes():
    p = read("G1 F100 G61 X1\nG64 X2\nX3 G9\nG60 X4\n")
    assert list(p.exact_stop) == [True, False, True, True]


def test_cycle832_selects_continuous_path_until_deselected():
    p = read("G60 G1 X1 F100\nCYCLE832(0.005,1,1)\nX2\nCYCLE832()\nX3\n")
    assert list(p.exact_stop) == [True, False, True]
    assert "continuous path" in p.skipped["CYCLE832"].note


def test_dwell_forms():
    p = read("G1 X1 F500\nG4 P1.5\nG4 X0.25\nG4 F2\nX2\n")
    assert list(p.kind) == [LINEAR, DWELL, DWELL, DWELL, LINEAR]
    np.testing.assert_allclose(p.dwell_s[1:4], [1.5, 0.25, 2])
    assert p.feed[4] == 500  # Sinumerik G4 F<s> leaves the feed alone
    with pytest.raises(GcodeError, match="G4 dwell without a time"):
        read("G4\n")


def _chord_error(seg, centre, radius):
    mid = 0.5 * (seg.start + seg.end)
    d = np.linalg.norm(mid[:, :2] - centre, axis=1)
    return np.max(np.abs(d - radius))


def test_quarter_arc_ijk_is_split_within_chord_tolerance():
    p = read("G17 G90 G1 X10 Y0 F1000\nG3 X0 Y10 I-10 J0\n")
    assert p.kind[1] == ARC_CCW
    np.testing.assert_allclose(p.centre[1, :2], [0, 0])
    for tol in (0.01, 0.001):
        s = gcode.segments(p, tol)
        arc = s.block == 1
        assert (
            _chord_error(
                gcode.Segments(*(getattr(s, f)[arc] for f in s.__dataclass_fields__)), [0, 0], 10
            )
            <= tol * 1.0001
        )
        length = s.length[arc].sum()
        assert length == pytest.approx(math.pi * 5, rel=tol)
        np.testing.assert_allclose(s.end[arc][-1], [0, 10, 0], atol=1e-12)
        # counter-clockwise: every chord turns left around the centre
        a = np.arctan2(s.end[arc][:, 1], s.end[arc][:, 0])
        assert np.all(np.diff(a) > 0)


def test_arc_r_form_short_and_long_and_clockwise():
    short = read("G1 X10 Y0 F100\nG2 X0 Y-10 R10\n")
    np.testing.assert_allclose(short.centre[1, :2], [0, 0], atol=1e-9)
    long = read("G1 X10 Y0 F100\nG2 X0 Y-10 R-10\n")
    np.testing.assert_allclose(long.centre[1, :2], [10, -10], atol=1e-9)
    s_short = gcode.segments(short, 0.001)
    s_long = gcode.segments(long, 0.001)
    assert s_short.length[s_short.block == 1].sum() == pytest.approx(5 * math.pi, rel=1e-3)
    assert s_long.length[s_long.block == 1].sum() == pytest.approx(15 * math.pi, rel=1e-3)
    assert short.kind[1] == ARC_CW


def test_full_circle_helix_in_g18():
    p = read("G18 G1 X5 Y0 Z0 F100\nG2 X5 Z0 Y3 I-5 K0\n")
    s = gcode.segments(p, 0.001)
    arc = s.block == 1
    assert s.length[arc].sum() == pytest.approx(math.hypot(2 * math.pi * 5, 3), rel=1e-3)
    assert s.end[arc][-1] == pytest.approx([5, 3, 0])
    assert np.all(np.diff(s.end[arc][:, 1]) > 0)  # helix climbs along Y


def test_impossible_arcs_are_errors():
    with pytest.raises(GcodeError, match=r"t.nc:2: arc end point is not on the circle"):
        read("G1 X10 Y0 F100\nG3 X0 Y12 I-10 J0\n")
    with pytest.raises(GcodeError, match=r"t.nc:2: arc radius 1.0000 too small"):
        read("G1 X10 Y0 F100\nG3 X0 Y10 R1\n")
    with pytest.raises(GcodeError, match="identical start and end"):
        read("G1 X10 Y0 F100\nG3 X10 Y0 R5\n")


def test_unreadable_file_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="cannot read"):
        gcode.read(tmp_path / "missing.nc")


def test_all_nine_siemens_programs_load_and_report_what_they_skipped():
    assert len(ANTONIO) == 9
    for path in ANTONIO:
        p = gcode.read(path, default_feed=2500)
        assert len(p) > 200, path.name
        kinds = {s.kind for s in p.skipped_list()}
        # G53 is executed now (machine coordinates); G54's offset is assumed zero.
        assert {"CYCLE800", "G54", "T=", "M6"} <= kinds, path.name
        assert "G53" not in kinds
        # F=R0 or no F at all: the default feed stands in (one file has F2500.).
        if p.substituted_feeds:
            assert kinds & {"F=R0", "F=R0.", "missing F"}, path.name
        else:
            assert path.name == "cycle832_5axis_x25.mpf"
        assert np.all(np.isfinite(p.end))
        feeds = p.feed[p.kind == LINEAR]
        assert np.all((feeds == 2500) | (feeds > 0))


def test_siemens_program_without_default_feed_names_the_line():
    path = next(p for p in ANTONIO if p.name == "linear_3p2_x5.mpf")
    with pytest.raises(GcodeError) as exc:
        gcode.read(path)
    assert str(exc.value).startswith(f"{path}:22: cannot evaluate F=R0")


def test_five_axis_program_reads_rotary_moves():
    path = next(p for p in ANTONIO if p.name == "cycle832_5axis_x5.mpf")
    p = gcode.read(path, default_feed=2500)
    b = p.end[:, 4]
    assert b.min() < 30 < 50 < b.max()  # B swings from ~51 deg down along the pass
    assert "TRAORI" in p.skipped
