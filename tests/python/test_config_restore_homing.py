"""`config restore` on a drive that is homing, against `sim serve`: refused
by the restore's own check (the drive is moving), nothing written, and the
message says so instead of blaming another session."""

from __future__ import annotations

from contour import protocol_gen as pg
from contour.link import connect
from contour.sim.serve import spawn
from linkhelp import run_cli, wait_state


def test_a_restore_while_homing_is_refused_by_its_check(capsys, tmp_path):
    backup = tmp_path / "b.toml"
    with spawn() as s:
        port = ["--port", s.serial]
        rc, _, err = run_cli(["config", "backup", str(backup), *port], capsys)
        assert rc == 0, err
        text = backup.read_text()
        backup.write_text(text.replace("velocity_profile = ", "velocity_profile = 'trapezoid' #"))
        with connect(port=s.serial) as c:
            c.request("enable", axis_mask=7, on=1)
            assert wait_state(c, (pg.State.READY,))["state"] == pg.State.READY
            # X toward its switch at -21.3 mm at 5 mm/s: homing for seconds
            c.request(
                "home",
                axis_mask=1,
                negative_mask=1,
                index_mask=1,
                search_feed=5_000_000,
                latch_feed=1_000_000,
                max_distance=100_000_000,
                home_pos=[0, 0, 0, 0],
            )
            assert c.status()["state"] == pg.State.HOMING
            before = c.get_param("velocity_profile")
        rc, _, err = run_cli(["config", "restore", str(backup), *port], capsys)
        assert rc == 1
        assert "the drive is moving (homing): nothing written" in err
        assert "another session" not in err
        with connect(port=s.serial) as c:
            assert c.get_param("velocity_profile") == before
            c.request("stop")
