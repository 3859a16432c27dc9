"""LinuxCNC tool tables (gcode/tooltable.py)."""

import pytest
from contour.errors import UserError
from contour.gcode import tooltable
from contour.gcode.tooltable import ToolTableError


def test_load_reads_tools_offsets_and_comments(tmp_path):
    f = tmp_path / "tool.tbl"
    f.write_text(
        "; shop table\n"
        "T1 P1 D6.0 Z+35.2 ;6 mm end mill\n"
        "\n"
        "t2 p2 x0.5 z41.05 d3.175 i10 j80 q2 ; 1/8 drill\n"
        "T10 P3 D10 A1.5\n"
    )
    tools = tooltable.load(f)
    assert sorted(tools) == [1, 2, 10]
    t1 = tools[1]
    assert (t1.pocket, t1.diameter, t1.radius) == (1, 6.0, 3.0)
    assert t1.offsets == {"Z": 35.2}
    assert t1.comment == "6 mm end mill"
    assert t1.line == 2
    t2 = tools[2]
    assert t2.offsets == {"X": 0.5, "Z": 41.05}
    assert (t2.diameter, t2.front_angle, t2.back_angle, t2.orientation) == (3.175, 10, 80, 2)
    assert tools[10].offsets == {"A": 1.5}
    assert tools[10].comment == ""


def test_units_line_and_override():
    text = ";units: inch\nT1 P1 D0.25 Z1 A2\n"
    t = tooltable.parse(text, "t.tbl")[1]
    assert t.diameter == pytest.approx(6.35)
    assert t.offsets == {"Z": 25.4, "A": 2.0}  # angles are not scaled
    t = tooltable.parse(text, "t.tbl", unit_mm=1.0)[1]
    assert t.diameter == 0.25
    assert tooltable.parse(";UNITS=mm\nT1 D4\n")[1].diameter == 4.0


@pytest.mark.parametrize(
    "text, line, message",
    [
        ("T1 P1 D6\nT2 P2 E5\n", 2, "unknown word 'E5'"),
        ("T1 D\n", 1, "D without a value"),
        ("T1 D6.0.1\n", 1, "malformed number in 'D6.0.1'"),
        ("T1 Dnan\n", 1, "malformed number"),
        ("T1 D1e999\n", 1, "out of range"),
        ("T1 D6 D7\n", 1, "D given twice"),
        ("P1 D6 ;no tool\n", 1, "tool line without a T word"),
        ("T1 D6\nT1 D8\n", 2, "T1 is listed twice (first on line 1)"),
        ("T1 D-6\n", 1, "negative diameter"),
        ("T1.5 D6\n", 1, "T must be a non-negative integer"),
        ("T-1 D6\n", 1, "T must be a non-negative integer"),
        ("T1 P2.5\n", 1, "P must be a non-negative integer"),
        ("T1 Q12\n", 1, "orientation Q12"),
        ("1 1 0.5 0.25 ;old\n", 1, "old column format"),
        ("T1 D1\n;units: inch\n", 2, "units line must come before the tools"),
        (";units: furlong\n", 1, "unknown units"),
        ("T1 D1 ;" + "x" * 5000 + "\n", 1, "line longer than 4096"),
    ],
)
def test_malformed_lines_are_file_line_errors(text, line, message):
    with pytest.raises(ToolTableError) as e:
        tooltable.parse(text, "shop.tbl")
    assert str(e.value).startswith(f"shop.tbl:{line}: ")
    assert message in str(e.value)
    assert isinstance(e.value, UserError)


def test_binary_and_undecodable_files(tmp_path):
    f = tmp_path / "b.tbl"
    f.write_bytes(b"T1 D1\n\x00\x01\x02")
    with pytest.raises(ToolTableError, match="b.tbl:1: binary file"):
        tooltable.load(f)
    f.write_bytes(b"T1 D1\nT2 D\xff\n")
    with pytest.raises(ToolTableError, match="b.tbl:2: not UTF-8"):
        tooltable.load(f)


def test_missing_file_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="cannot read the tool table"):
        tooltable.load(tmp_path / "nope.tbl")


def test_bom_and_crlf():
    tools = tooltable.parse("\ufeffT3 P3 D2\r\nT4 D4\r\n".encode())
    assert sorted(tools) == [3, 4]
