"""`contour run`'s check without the host library (build/host/libcontour.so):
the G-code reader runs without it (docs/fast-paths.md), and so does the job:
its time estimate is length / feed (rapids at the profile's lowest axis
limit), with a note in the report, instead of refusing the job."""

from __future__ import annotations

from pathlib import Path

import pytest
from contour import native
from contour.link import blocks as bl
from contour.planner import PlannerProfile


@pytest.fixture
def no_library(monkeypatch):
    native._load.cache_clear()
    monkeypatch.setattr(native, "library_path", lambda: Path("/nonexistent/libcontour.so"))
    yield
    native._load.cache_clear()


def test_check_without_the_host_library_estimates_length_over_feed(no_library, tmp_path):
    path = tmp_path / "job.ngc"
    path.write_text("G21 G90\nG0 X10\nG1 X40 F600\nG4 P0.5\n")
    prof = PlannerProfile(v_max_mm_s=(250.0, 100.0, 50.0))
    checked = bl.check_gcode(str(path), limits=bl.DriveLimits(profile=prof))
    assert checked.blocks == 3
    # rapid 10 mm at 50 mm/s, 30 mm at 10 mm/s, dwell 0.5 s
    assert checked.est_s == pytest.approx(10 / 50 + 30 / 10 + 0.5, rel=1e-9)
    note = checked.report.items[bl.NO_LIBRARY].note
    assert "no planner" in note and "libcontour.so not found" in note
