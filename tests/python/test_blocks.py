"""contour.link.blocks: the drive blocks of a program, checked as arrays
(the fast path) or one by one (the path that names a refused line) alike."""

from __future__ import annotations

import pytest
from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import blocks as bl
from contour.planner import CORNERS, SHAPES, BlockRefused, Planner, PlannerProfile
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


EST_JOB = "G21 G90 G64\nG0 X100\nG1 X150 Y20 F3000\nG4 P0.5\nG1 X0 Y0 F6000\n"


def _direct(profile) -> float:
    """The planner's time for EST_JOB, rapids at the feed the drive queues
    them at (PROTO_RAPID_FEED_NM_S in proto_dispatch.h)."""
    from pathlib import Path

    header = Path(__file__).parents[2] / "firmware/core/proto_dispatch.h"
    rapid = next(
        int(ln.split()[2].rstrip("u"))
        for ln in header.read_text().splitlines()
        if ln.startswith("#define PROTO_RAPID_FEED_NM_S ")
    )
    pts = [[100, 0, 0], [150, 20, 0], [150, 20, 0], [0, 0, 0]]
    feeds = [rapid * 60 / 1e6, 3000, 1, 6000]
    res = Planner(profile).estimate(pts, feeds, dwell_s=[0, 0, 0.5, 0])
    return res.total_s


def test_the_defaults_are_the_drives_generated_parameter_defaults():
    from contour.estimation import profile as mp

    # the enum values of the generated table name the host's shapes and rules
    assert SHAPES == {
        "s-curve": pg.VelocityProfile.SCURVE,
        "trapezoid": pg.VelocityProfile.TRAPEZOID,
        "s-curve-at-rest": pg.VelocityProfile.SCURVE_AT_REST,
        "s-curve-continuous": pg.VelocityProfile.SCURVE_CONTINUOUS,
    }
    assert CORNERS["smoothed-corner"] == pg.CornerRule.SMOOTHED
    defaults = PlannerProfile.from_params(lambda n: pg.PARAM_BY_NAME[n.split(".")[0]].default)
    assert PlannerProfile() == defaults
    assert defaults.shape == "s-curve-continuous"
    # `contour estimate` without a profile plans the drive's path rules
    motion = {f.name: f.default for f in mp.MOTION_FIELDS}
    assert motion["velocity_profile"] == defaults.shape
    assert motion["corner_rule"] == defaults.corner
    assert motion["junction_deviation_mm"] == defaults.junction_deviation_mm


def test_the_estimate_is_the_drive_profiles_plan(tmp_path):
    path = tmp_path / "job.ngc"
    path.write_text(EST_JOB)
    trap = PlannerProfile(shape="trapezoid", a_max_mm_s2=(500.0,) * 3, v_max_mm_s=(400.0,) * 3)
    for prof in (trap, None):
        limits = bl.DriveLimits(profile=prof)
        est = bl.check_gcode(str(path), limits=limits).est_s
        want = _direct(PlannerProfile() if prof is None else prof)
        assert est == pytest.approx(want, rel=1e-9)
    assert bl.check_gcode(str(path)).est_s == pytest.approx(_direct(PlannerProfile()), rel=1e-9)
    assert _direct(trap) != pytest.approx(_direct(PlannerProfile()), rel=1e-3)


def test_a_block_the_planner_refuses_is_refused_with_its_line(tmp_path, monkeypatch):
    path = tmp_path / "job.ngc"
    path.write_text(EST_JOB)

    def refuse(self, *a, **kw):
        raise BlockRefused(1, "planner ring full")

    monkeypatch.setattr(Planner, "estimate", refuse)
    with pytest.raises(UserError, match=r"job.ngc:3: the drive's planner refuses it: planner ring"):
        bl.check_gcode(str(path))
    # a line the checks refuse is still named by them
    path.write_text(EST_JOB.replace("F6000", "F300000"))
    with pytest.raises(UserError, match=r"job.ngc:5: feed F300000 mm/min does not fit"):
        bl.check_gcode(str(path))


def test_run_reads_the_profile_the_drive_runs():
    from contour.link import connect
    from contour.sim.serve import spawn

    with spawn() as s, connect(port=s.serial) as c:
        c.set_param("velocity_profile", int(pg.VelocityProfile.TRAPEZOID))
        c.set_param("max_acceleration.y", 1_234_000_000)
        c.set_param("min_block_time", 2_000_000)
        c.set_param("min_block_window", 8)
        got = bl.DriveLimits.read(c, axes=c.identify()["axes"]).profile
    assert got.shape == "trapezoid"
    assert tuple(got.a_max_mm_s2) == (10000.0, 1234.0, 10000.0)
    assert got.min_block_time_s == 0.002 and got.mbt_window == 8
    assert got.corner == "junction-deviation" and got.junction_deviation_mm == 0.01
