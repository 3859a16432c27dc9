"""Planner parameters and the enable-then-queue batch over the serial link of
the simulated drive (`sim serve`): typed get/set of the drive's planner
limits, the drive's own (profile-wide) range check, busy while moving and
nothing half applied; a block queued right after the enable request, with no
pause between them, runs to its end point; queued time is reported."""

from __future__ import annotations

import time

import pytest
from contour import cli
from contour import protocol_gen as pg
from contour.link import DriveError, connect
from contour.sim.serve import spawn
from linkhelp import wait_state


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


def test_planner_parameters_over_the_link(server, capsys):
    with connect(port=server.serial) as c:
        vy0 = c.get_param("max_velocity.y")  # the machine's (hil_sim/machines/tuned.toml)
    rc = cli.main(["set", "max_velocity.y", "250", "--port", server.serial])
    assert rc == 0 and "max_velocity.y = 250 mm/s" in capsys.readouterr().out
    with connect(port=server.serial) as c:
        assert c.get_param("max_velocity.y") == 250000000
        assert c.get_param("max_velocity.x") != 250000000
        # the table's range (checked by the drive too, bypassing the host)
        with pytest.raises(DriveError) as e:
            c.request("param_set", param=pg.PARAM_BY_NAME["corner_rule"].id, value=4)
        assert e.value.code == pg.ErrorCode.OUT_OF_RANGE
        # the drive's range: max_jerk must keep max_acceleration / max_jerk <= 3 s
        a = c.get_param("max_acceleration.z")
        with pytest.raises(DriveError, match="out of range") as e:
            c.set_param("max_jerk.z", 1000)
        assert e.value.code == pg.ErrorCode.OUT_OF_RANGE
        assert e.value.fields["lo"] == -(-a // 3)
        # the smoothed corner: refused with the default continuous S-curve
        # (its cap would cut a run under way), taken with the per-block one
        assert c.get_param("velocity_profile") == pg.VelocityProfile.SCURVE_CONTINUOUS
        with pytest.raises(DriveError) as e:
            c.set_param("corner_rule", 2)
        assert e.value.code == pg.ErrorCode.BAD_VALUE
        c.set_param("velocity_profile", pg.VelocityProfile.SCURVE)
        c.set_param("corner_rule", 2)
        assert c.get_param("corner_rule") == 2
        c.set_param("corner_rule", 0)
        c.set_param("velocity_profile", pg.VelocityProfile.SCURVE_CONTINUOUS)
        c.set_param("max_velocity.y", vy0)


def test_feedforward_corrections_over_the_link(server, capsys):
    """ff_advance_ns, qg_comp, ffl_rate, friction_ff_mv, friction_ff_band
    (drive_ff.h, servo.h): set and read by name, the table's range checked by
    the drive too (bypassing the host), busy while moving."""
    port = ["--port", server.serial]
    for argv, shown in (
        (["ff_advance_ns", "1500"], "ff_advance_ns = 1500 ns"),
        (["qg_comp", "1"], "qg_comp = 1"),
        (["ffl_rate", "100"], "ffl_rate = 100 1/s"),
        (["friction_ff_mv.y", "45"], "friction_ff_mv.y = 45 mV"),
        (["friction_ff_band", "0.5"], "friction_ff_band = 0.5 mm/s"),
    ):
        assert cli.main(["set", *argv, *port]) == 0, argv
        assert capsys.readouterr().out.strip() == shown
    with connect(port=server.serial) as c:
        assert c.get_param("ff_advance_ns") == 1500
        assert c.get_param("qg_comp") == 1
        assert c.get_param("ffl_rate") == 100
        assert c.get_param("friction_ff_mv.y") == 45
        assert c.get_param("friction_ff_mv.x") == 0
        assert c.get_param("friction_ff_band") == 500_000
        for name, bad, lo, hi in (
            ("ff_advance_ns", 10_000_001, 0, 10_000_000),
            ("qg_comp", 2, 0, 1),
            ("ffl_rate", 1001, 0, 1000),
            ("friction_ff_band", 0, 1, 4294967295),
        ):
            with pytest.raises(DriveError) as e:
                c.request("param_set", param=pg.PARAM_BY_NAME[name].id, value=bad)
            assert e.value.code == pg.ErrorCode.OUT_OF_RANGE, name
            assert (e.value.fields["lo"], e.value.fields["hi"]) == (lo, hi), name
        assert c.get_param("ff_advance_ns") == 1500  # nothing changed
        for name, v in (
            ("ff_advance_ns", 0),
            ("qg_comp", 0),
            ("ffl_rate", 0),
            ("friction_ff_mv.y", 0),
            ("friction_ff_band", 1_000_000),
        ):
            c.set_param(name, v)
            assert c.get_param(name) == v


def test_enable_and_queue_in_one_batch(server):
    with connect(port=server.serial) as c:
        c.set_param("comm_timeout_ms", 1000)
        st = c.status()
        if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
            c.request("fault_reset")
            wait_state(c, (pg.State.DISABLED,))
        c.enable(False)
        wait_state(c, (pg.State.DISABLED,))
        st = c.status()
        x0, done0 = st["pos"][0], st["blocks_done"]
        vx0 = c.get_param("max_velocity.x")
        target = [round(x0 / 1000) * 1000 + 2_000_000, st["pos"][1], st["pos"][2], 0]
        c.enable(True)
        r = c.request(
            "queue_block",
            block_seq=77,
            kind=pg.BlockKind.LINE,
            flags=0,
            feed=20_000_000,
            target=target,
        ).fields
        assert r["queued_us"] > 50_000  # 2 mm at 20 mm/s: about 0.1 s planned
        with pytest.raises(DriveError) as e:
            c.set_param("max_velocity.x", 5_000_000)
        assert e.value.code == pg.ErrorCode.BUSY
        for name in ("ff_advance_ns", "ffl_rate"):  # drive_ff / servo: busy too
            with pytest.raises(DriveError) as e:
                c.set_param(name, 1)
            assert e.value.code == pg.ErrorCode.BUSY, name
        st = wait_state(c, (pg.State.READY,))
        assert st["state"] == pg.State.READY
        assert st["blocks_done"] == done0 + 1 and st["last_block_seq"] == 77
        end = time.monotonic() + 3.0  # the axis settles after the reference
        while abs(st["pos"][0] - target[0]) >= 10_000 and time.monotonic() < end:
            time.sleep(0.02)
            st = c.status()
        assert abs(st["pos"][0] - target[0]) < 10_000
        assert st["queued_us"] == 0
        assert c.get_param("max_velocity.x") == vx0  # the busy set never landed
