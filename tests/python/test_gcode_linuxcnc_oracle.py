"""The canned-cycle and cutter-compensation test programs agree with LinuxCNC.

Runs only when LinuxCNC's rs274 has been fetched into .cache/linuxcnc
(``.venv/bin/python tests/gcode/linuxcnc_oracle.py --fetch``); skipped
otherwise, so the suite needs no download.
"""

import sys
from pathlib import Path

import pytest

GCODE = Path(__file__).resolve().parents[1] / "gcode"
sys.path.insert(0, str(GCODE))
import linuxcnc_oracle as oracle  # noqa: E402

PROGRAMS = sorted(GCODE.glob("programs/cycle_*.ngc")) + sorted(GCODE.glob("programs/cutcomp_*.ngc"))


@pytest.mark.skipif(not oracle.available(), reason="LinuxCNC rs274 not fetched")
@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.stem)
def test_program_expectations_hold_for_linuxcnc(path):
    res = oracle.run(path)
    assert oracle.agrees(path, res), res


def test_the_oracle_parser_sums_moves_and_arcs():
    # rs274's output format, as printed by LinuxCNC 2.9: a 10 mm feed, a
    # quarter circle of radius 10, a dwell and a rapid back.
    text = "\n".join(
        [
            "executing",
            "   7 N..... SELECT_PLANE(CANON_PLANE_XY)",
            "   9 N..... STRAIGHT_FEED(10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
            "  10 N..... ARC_FEED(0.0000, 10.0000, 0.0000, 0.0000, 1, 0.0000, 0, 0, 0)",
            "  11 N..... DWELL(0.5000)",
            "  12 N..... STRAIGHT_TRAVERSE(0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
        ]
    )
    res = oracle.parse(text)
    assert res.feed_mm == pytest.approx(10 + 5 * 3.141592653589793)
    assert res.rapid_mm == pytest.approx(10)
    assert res.dwell_s == 0.5
    assert res.end == (0, 0, 0)
    assert res.error == ""
    assert oracle.parse("executing\nR less than z in cycle in xy plane\n").error
