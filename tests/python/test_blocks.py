"""contour.link.blocks: the drive blocks of a program, checked as arrays
(the fast path) or one by one (the path that names a refused line) alike."""

from __future__ import annotations

import pytest
from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import blocks as bl
from contour.program import Report

JOB = """G21 G90 G17
G0 X1 Y1
G1 X5 F1200
G2 X7 Y3 I0 J2
G4 P0.25
G1 Z-1 F300000
G9 G1 X0 Y0 Z0 F600
G4 P1
"""
LIMITS = bl.DriveLimits((None,) * 3, (None,) * 3, (50_000_000,) * 3)


def _blocks(path, monkeypatch, one_by_one: bool):
    if one_by_one:
        monkeypatch.setattr(bl, "_fast", lambda *a: None)
    rep = Report()
    out = list(bl.blocks_from_gcode(str(path), limits=LIMITS, report=rep))
    monkeypatch.undo()
    return out, rep.as_dicts()


def test_array_checks_give_the_blocks_of_the_one_by_one_path(tmp_path, monkeypatch):
    path = tmp_path / "job.ngc"
    path.write_text(JOB.replace("F300000", "F3000"))
    fast, rep_fast = _blocks(path, monkeypatch, False)
    slow, rep_slow = _blocks(path, monkeypatch, True)
    assert fast == slow
    assert rep_fast == rep_slow
    kinds = [b.kind for b in fast]
    assert kinds.count(pg.BlockKind.DWELL) == 2 and kinds[0] == pg.BlockKind.RAPID
    assert [b.feed_nm_s for b in fast if b.kind == pg.BlockKind.DWELL] == [250, 1000]
    # 50 mm/s on each axis: F3000 on Z is 50 mm/s, not capped; nothing else is above
    assert not any(r["kind"] == "feed capped" for r in rep_fast)
    assert fast[-1].target_nm == (0, 0, 0) and fast[-2].exact_stop


def test_a_feed_the_drive_caps_is_reported_with_its_count(tmp_path, monkeypatch):
    path = tmp_path / "job.ngc"
    path.write_text("G21 G90\nG1 X10 F6000\nG1 X20 Y10\nG1 X30 F600\n")
    for one_by_one in (False, True):
        _, rep = _blocks(path, monkeypatch, one_by_one)
        capped = [r for r in rep if r["kind"] == "feed capped"]
        assert capped and capped[0]["first_line"] == 2 and capped[0]["count"] == 2
        assert "3000 mm/min" in capped[0]["note"]


def test_the_first_refused_line_is_named(tmp_path):
    path = tmp_path / "job.ngc"
    path.write_text(JOB)
    with pytest.raises(UserError, match=r"job.ngc:6: feed F300000 mm/min does not fit"):
        bl.check_gcode(str(path), limits=LIMITS)
