"""Parameters a machinist can use, against `sim serve`: values in user units
with unit suffixes and enum names, `get --all` with units, servo and travel
parameters, soft limits refusing a jog before it moves, `config backup` /
`config restore` (whole file checked before anything is written; written and
read back), and `config save` surviving a restart of the drive on the same
flash file (`--flash`)."""

from __future__ import annotations

import json
import random
import time
from pathlib import Path

import pytest
from contour import image as img
from contour import protocol_gen as pg
from contour.link import DriveError, codec, connect
from contour.sim.serve import spawn
from linkhelp import run_cli, wait_state

LOAD_ADDR = 0x08010200  # the simulated drive's application slot (test_flash_e2e.py)


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


def test_values_in_user_units(server, capsys):
    port = ["--port", server.serial]
    rc, out, err = run_cli(["set", "max_velocity.x", "600mm/min", *port], capsys)
    assert rc == 0, err
    assert out.strip() == "max_velocity.x = 10 mm/s"
    rc, out, _ = run_cli(["get", "max_velocity.x", *port], capsys)
    assert out.strip() == "max_velocity.x = 10 mm/s"
    rc, out, _ = run_cli(["set", "max_velocity.x", "250", *port], capsys)
    assert rc == 0 and out.strip() == "max_velocity.x = 250 mm/s"
    rc, out, err = run_cli(["set", "cec_mode", "curvature", *port], capsys)
    assert rc == 0, err
    assert out.strip() == "cec_mode = curvature"
    rc, out, _ = run_cli(["set", "cec_mode", "off", *port], capsys)
    assert rc == 0
    rc, out, _ = run_cli(["set", "arc_chord_tolerance", "0.5um", *port], capsys)
    assert rc == 0 and out.strip() == "arc_chord_tolerance = 0.5 um"
    # wrong unit kind, unknown enum name: usage errors, nothing sent
    rc, _, err = run_cli(["set", "max_velocity.x", "10mm", *port], capsys)
    assert rc == 2 and "does not fit" in err
    rc, _, err = run_cli(["set", "cec_mode", "curly", *port], capsys)
    assert rc == 2 and "curvature" in err
    # the drive's out_of_range in user units
    with connect(port=server.serial) as c:
        with pytest.raises(DriveError, match=r"max_velocity.x out of range \[0.001, ") as e:
            c.request("param_set", param=pg.PARAM_BY_NAME["max_velocity"].id, value=1)
        assert e.value.code == pg.ErrorCode.OUT_OF_RANGE
    rc, out, _ = run_cli(["get", "--all", *port], capsys)
    assert rc == 0
    lines = {ln.split("=")[0].strip(): ln.split("=", 1)[1].strip() for ln in out.splitlines()}
    assert lines["in_position_window.x"] == "0.005 mm"
    assert lines["pid_kp.y"].endswith(" V/m") and float(lines["pid_kp.y"].split()[0]) > 0
    assert lines["following_error_limit.z"].endswith(" mm")
    assert lines["soft_limit_max.x"] == "0 mm"
    assert lines["cec_mode"] == "off"
    assert lines["param_store_status"] == "none"
    rc, out, _ = run_cli(["get", "max_acceleration.y", "--json", *port], capsys)
    j = json.loads(out)["max_acceleration.y"]
    assert j["unit"] == "mm/s^2" and j["raw_unit"] == "nm/s^2" and j["raw"] == j["value"] * 10**6


def test_soft_limits_refuse_a_jog_before_it_moves(server, capsys):
    port = ["--port", server.serial]
    with connect(port=server.serial) as c:
        if c.status()["state"] in (pg.State.FAULT, pg.State.ESTOP):
            c.request("fault_reset")
        x0 = c.status()["pos"][0]
    lo, hi = (x0 - 1_000_000) / 1e6, (x0 + 2_000_000) / 1e6
    assert run_cli(["set", f"soft_limit_min.x={lo}mm", *port], capsys)[0] == 0
    assert run_cli(["set", "soft_limit_max.x", f"{hi}mm", *port], capsys)[0] == 0
    with connect(port=server.serial) as c:
        c.enable(True)
        wait_state(c, (pg.State.READY,))
        with pytest.raises(DriveError, match="out of range") as e:
            c.request("jog", axis=0, feed=20_000_000, distance=3_000_000)
        assert e.value.fields["hi"] == round(hi * 1e6)
        time.sleep(0.2)
        st = c.status()
        assert st["state"] == pg.State.READY and abs(st["pos"][0] - x0) < 20_000
        c.request("jog", axis=0, feed=20_000_000, distance=1_000_000)  # inside
        wait_state(c, (pg.State.READY,))
        c.enable(False)
        wait_state(c, (pg.State.DISABLED,))
    assert run_cli(["set", "soft_limit_max.x", "0", *port], capsys)[0] == 0
    assert run_cli(["set", "soft_limit_min.x", "0", *port], capsys)[0] == 0


def _refused_before_any_write(server, path, capsys, before: dict) -> str:
    """`config restore PATH` refused over encoder_mean with nothing written
    (the parameters in `before` read as before); then the drive disabled.
    Returns the error message."""
    try:
        argv = ["config", "restore", str(path), "--json", "--port", server.serial]
        rc, out, _ = run_cli(argv, capsys)
        assert rc == 1
        msg = json.loads(out)["error"]["message"]
        assert "encoder_mean" in msg and "nothing written" in msg, msg
        with connect(port=server.serial) as c:
            assert {n: c.get_param(n) for n in before} == before
        return msg
    finally:
        with connect(port=server.serial) as c:
            c.enable(False)


def test_backup_and_restore(server, capsys, tmp_path):
    port = ["--port", server.serial]
    f = tmp_path / "drive.toml"
    rc, out, err = run_cli(["config", "backup", str(f), *port], capsys)
    assert rc == 0, err
    text = f.read_text()
    assert "[drive]" in text and "axes = 3" in text and "board_id = " in text
    assert 'firmware_version = "' in text
    assert "\nposition = " not in text and "\nparam_store_status" not in text  # read-only
    with connect(port=server.serial) as c:
        before = {n: c.get_param(n) for n in ("max_velocity.y", "pid_kd.x", "corner_rule")}
    # edit: other values, in other units of the same kind
    edited = text.replace(
        text.split("max_velocity = ")[1].split("\n")[0],
        '{ x = "250 mm/s", y = "6000 mm/min", z = "0.2 m/s" }',
    ).replace('corner_rule = "junction_deviation"', 'corner_rule = "smoothed"')
    # the smoothed corner needs a per-block profile (the default continuous
    # S-curve refuses it): the restore writes it after velocity_profile
    assert 'velocity_profile = "scurve_continuous"' in text
    edited = edited.replace('velocity_profile = "scurve_continuous"', 'velocity_profile = "scurve"')
    g = tmp_path / "edited.toml"
    g.write_text(edited)
    # broken variants: each refused as a whole, nothing written
    bad = {
        "unknown": edited + 'no_such_param = "1 mm"\n',
        "range": edited.replace('y = "6000 mm/min"', 'y = "-5 mm/s"'),
        "axes": edited.replace("axes = 3", "axes = 2"),
        "missing axis": edited.replace(', z = "0.2 m/s"', ""),
    }
    for what, body in bad.items():
        b = tmp_path / "bad.toml"
        b.write_text(body)
        rc, out, _ = run_cli(["config", "restore", str(b), "--json", *port], capsys)
        assert rc == 1, what
        assert "nothing written" in json.loads(out)["error"]["message"], (what, out)
        with connect(port=server.serial) as c:
            assert c.get_param("max_velocity.y") == before["max_velocity.y"], what
            assert c.get_param("corner_rule") == before["corner_rule"], what
    # encoder_mean changes only with the drive disabled: an enabled drive is
    # refused before the first write, not stopped halfway (max_velocity comes
    # first in table order)
    m = tmp_path / "mean.toml"
    m.write_text(edited.replace('encoder_mean = "0"', 'encoder_mean = "1"'))
    assert 'encoder_mean = "0"' in edited
    with connect(port=server.serial) as c:
        c.enable(True)
    _refused_before_any_write(server, m, capsys, before)
    rc, out, err = run_cli(["config", "restore", str(g), "--dry-run", "--json", *port], capsys)
    assert rc == 0 and json.loads(out)["written"] is False, err
    with connect(port=server.serial) as c:
        assert c.get_param("corner_rule") == before["corner_rule"]
    rc, out, err = run_cli(["config", "restore", str(g), *port], capsys)
    assert rc == 0, err
    assert "read back" in out
    with connect(port=server.serial) as c:
        assert c.get_param("max_velocity.x") == 250_000_000
        assert c.get_param("max_velocity.y") == 100_000_000
        assert c.get_param("max_velocity.z") == 200_000_000
        assert c.get_param("corner_rule") == 2
        assert c.get_param("pid_kd.x") == before["pid_kd.x"]
    # and back to the first backup
    rc, _, err = run_cli(["config", "restore", str(f), *port], capsys)
    assert rc == 0, err
    with connect(port=server.serial) as c:
        assert {n: c.get_param(n) for n in before} == before


def test_a_second_session_enabling_mid_restore_leaves_nothing_half_written(
    server, capsys, tmp_path, monkeypatch
):
    """encoder_mean changes only while disabled: the restore checks that up
    front, but a second session (slcan) may enable the drive between that
    check and the transaction. The drive refuses the commit over
    encoder_mean, and nothing of the file is written."""
    from contour.commands import config as cfg
    from linkhelp import client_for

    port = ["--port", server.serial]
    f = tmp_path / "drive.toml"
    rc, _, err = run_cli(["config", "backup", str(f), *port], capsys)
    assert rc == 0, err
    text = f.read_text()
    edited = text.replace(
        text.split("max_velocity = ")[1].split("\n")[0],
        '{ x = "250 mm/s", y = "6000 mm/min", z = "0.2 m/s" }',
    ).replace('encoder_mean = "0"', 'encoder_mean = "1"')
    assert edited.index("max_velocity = ") < edited.index("encoder_mean = ")
    g = tmp_path / "mean.toml"
    g.write_text(edited)
    with connect(port=server.serial) as c:
        c.enable(False)
        wait_state(c, (pg.State.DISABLED,))
        before = {n: c.get_param(n) for n in ("max_velocity.y", "encoder_mean")}
    write_all = cfg.write_all

    def enable_then_write(client, values):
        with client_for(server, "slcan") as other:  # the second session
            other.enable(True)
            assert wait_state(other, (pg.State.READY,))["state"] == pg.State.READY
        write_all(client, values)

    monkeypatch.setattr(cfg, "write_all", enable_then_write)
    msg = _refused_before_any_write(server, g, capsys, before)
    assert "encoder_mean cannot change now: the drive is ready" in msg, msg
    assert "another session" in msg, msg


def _app_image() -> img.Image:
    payload = random.Random(7).randbytes(4096)
    return img.build(
        payload, board_id=1, fw_version=img.parse_version("1.2.3"), load_addr=LOAD_ADDR
    )


def _wait_app(server, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while True:
        try:
            with connect(port=server.serial) as c:
                if c.identify()["axes"] > 0:
                    return
        except Exception:  # noqa: BLE001 - a drive that just reset: ask again
            pass
        if time.monotonic() > end:
            raise AssertionError("the application did not start")
        time.sleep(0.05)


def test_save_survives_a_restart(capsys, tmp_path):
    flash = tmp_path / "drive.flash"
    image = tmp_path / "app.img"
    image.write_bytes(_app_image().to_bytes())
    with spawn(["--flash", str(flash), "--boot-window-ms", "200"]) as s:
        rc, _, err = run_cli(["flash", str(image), "--port", s.serial, "--no-progress"], capsys)
        assert rc == 0, err
        _wait_app(s)
        port = ["--port", s.serial]
        for argv in (
            ["set", "max_velocity.y", "123mm/s"],
            ["set", "pid_kp.x", "2500"],
            ["set", "following_error_limit.z", "0.75"],
            ["set", "soft_limit_max.x", "300"],
            ["set", "in_position_window.y", "2um"],
            ["set", "ff_advance_ns", "1500"],
            ["set", "qg_comp", "1"],
            ["set", "ffl_rate", "50"],
            ["set", "friction_ff_mv.x", "30"],
        ):
            assert run_cli([*argv, *port], capsys)[0] == 0, argv
        # refused while enabled
        with connect(port=s.serial) as c:
            c.enable(True)
            wait_state(c, (pg.State.READY,))
        rc, _, err = run_cli(["config", "save", *port], capsys)
        assert rc == 1 and "disable" in err
        with connect(port=s.serial) as c:
            c.enable(False)
            wait_state(c, (pg.State.DISABLED,))
        rc, out, err = run_cli(["config", "save", *port], capsys)
        assert rc == 0, err
        # changed after the save: not kept
        assert run_cli(["set", "max_velocity.y", "77", *port], capsys)[0] == 0
    # power cycle: a new server process on the same flash file
    with spawn(["--flash", str(flash), "--boot-window-ms", "0"]) as s:
        _wait_app(s)
        with connect(port=s.serial) as c:
            assert c.get_param("param_store_status") == 1  # loaded
            assert c.get_param("max_velocity.y") == 123_000_000
            assert c.get_param("pid_kp.x") == 2500 << 32
            assert c.get_param("following_error_limit.z") == 750_000
            assert c.get_param("soft_limit_max.x") == 300_000_000
            assert c.get_param("in_position_window.y") == 2000
            assert c.get_param("in_position_window.x") == 5000
            assert c.get_param("ff_advance_ns") == 1500
            assert c.get_param("qg_comp") == 1
            assert c.get_param("ffl_rate") == 50
            assert c.get_param("friction_ff_mv.x") == 30
            assert c.get_param("friction_ff_mv.y") == 0
    # an erased flash of the same drive: the machine's values, status none
    with spawn(["--flash", str(Path(tmp_path / "other.flash")), "--boot-window-ms", "200"]) as s:
        assert run_cli(["flash", str(image), "--port", s.serial, "--no-progress"], capsys)[0] == 0
        _wait_app(s)
        with connect(port=s.serial) as c:
            assert c.get_param("param_store_status") == 0
            assert c.get_param("max_velocity.y") != 123_000_000


def test_a_drive_without_transactions_is_refused_with_nothing_written():
    """An older drive answers param_begin with unknown_message: the restore
    is refused before any value is written (no one-at-a-time fallback that
    could stop halfway)."""
    from contour.commands import config as cfg
    from contour.errors import UserError

    class OldDrive:
        def __init__(self):
            self.sent = []

        def request(self, name, **fields):
            self.sent.append(name)
            if name.startswith("param_") and name not in ("param_get", "param_set"):
                raise DriveError(name, {"code": pg.ErrorCode.UNKNOWN_MESSAGE}, "unknown")
            raise AssertionError(f"{name} sent")

        def set_param(self, name, value):
            raise AssertionError(f"set_param {name} sent")

    d = OldDrive()
    values = {"max_velocity.x": 1, "max_velocity.y": 2, "encoder_mean": 0}
    with pytest.raises(UserError, match=r"nothing written: the drive's firmware has no parameter "):
        cfg.write_all(d, values)
    assert d.sent == ["param_begin"]


class _BeforeCommit:
    """A client whose param_commit runs `hook` first (between the last
    param_stage and the commit)."""

    def __init__(self, client, hook):
        self.c, self.hook, self.staged = client, hook, 0

    def request(self, name, **fields):
        if name == "param_stage":
            self.staged += 1
        if name == "param_commit":
            assert self.staged >= 2  # the whole file was staged, over several frames
            self.hook()
        return self.c.request(name, **fields)

    def __getattr__(self, name):
        return getattr(self.c, name)


def _edited_backup(server, capsys, tmp_path) -> Path:
    f = tmp_path / "drive.toml"
    rc, _, err = run_cli(["config", "backup", str(f), "--port", server.serial], capsys)
    assert rc == 0, err
    text = f.read_text()
    g = tmp_path / "edited.toml"
    g.write_text(
        text.replace(
            text.split("max_velocity = ")[1].split("\n")[0],
            '{ x = "321 mm/s", y = "6000 mm/min", z = "0.2 m/s" }',
        ).replace("comm_timeout_ms = ", "comm_timeout_ms = 900 #")
    )
    return g


def _restore_refused(server, capsys, path) -> str:
    argv = ["config", "restore", str(path), "--json", "--port", server.serial]
    rc, out, _ = run_cli(argv, capsys)
    assert rc == 1, out
    msg = json.loads(out)["error"]["message"]
    assert "nothing written" in msg, msg
    return msg


WATCH = ("max_velocity.x", "max_velocity.y", "max_velocity.z", "comm_timeout_ms")


def test_a_second_session_moving_between_stage_and_commit_leaves_nothing_written(
    server, capsys, tmp_path, monkeypatch
):
    """A second session (slcan, open before the restore began) enables the
    drive and starts a jog after the restore staged the whole file: the
    drive refuses the commit, naming the first parameter it cannot change
    while moving, and applies none of the file (not even comm_timeout_ms,
    which it could)."""
    from contour.commands import config as cfg
    from linkhelp import client_for

    g = _edited_backup(server, capsys, tmp_path)
    with connect(port=server.serial) as c:
        if c.status()["state"] in (pg.State.FAULT, pg.State.ESTOP):
            c.request("fault_reset")
        c.enable(False)
        wait_state(c, (pg.State.DISABLED,))
        before = {n: c.get_param(n) for n in WATCH}
    assert before["max_velocity.x"] != 321_000_000 and before["comm_timeout_ms"] != 900
    write_all = cfg.write_all
    with client_for(server, "slcan") as other:  # the second session, opened first
        other.status()  # its session_open goes out with its first request

        def move():
            other.enable(True)
            assert wait_state(other, (pg.State.READY,))["state"] == pg.State.READY
            other.request("jog", axis=1, feed=5_000_000, distance=5_000_000)  # 1 s

        monkeypatch.setattr(cfg, "write_all", lambda c, v: write_all(_BeforeCommit(c, move), v))
        try:
            msg = _restore_refused(server, capsys, g)
        finally:
            other.request("stop")
            wait_state(other, (pg.State.READY,))
            other.enable(False)
    # the first drive parameter of the file (table order)
    assert "cec_mode cannot change now: the drive is running" in msg, msg
    assert "another session" in msg, msg
    with connect(port=server.serial) as c:
        assert {n: c.get_param(n) for n in WATCH} == before


def test_a_session_opened_between_stage_and_commit_loses_the_transaction(
    server, capsys, tmp_path, monkeypatch
):
    """A second host connecting (session_open) after the restore staged the
    file aborts the transaction: the restore's commit is refused as lost,
    nothing written."""
    from contour.commands import config as cfg
    from linkhelp import client_for

    g = _edited_backup(server, capsys, tmp_path)
    with connect(port=server.serial) as c:
        before = {n: c.get_param(n) for n in WATCH}

    def connect_other():
        with client_for(server, "slcan") as other:
            other.status()

    write_all = cfg.write_all
    monkeypatch.setattr(
        cfg, "write_all", lambda c, v: write_all(_BeforeCommit(c, connect_other), v)
    )
    msg = _restore_refused(server, capsys, g)
    assert "lost: another session opened" in msg, msg
    with connect(port=server.serial) as c:
        assert {n: c.get_param(n) for n in WATCH} == before


class _CommitReplyFaults:
    """A transport that, from the first param_commit sent on, drops every
    reply (`reply_drop`) or every param_commit sent (`commit_drop`) for the
    first `tries` param_commit sends (None: for good)."""

    def __init__(self, inner, tries, drop_commits: bool = False):
        self.t, self.tries, self.drop_commits = inner, tries, drop_commits
        self.commits = 0

    def _dead(self) -> bool:
        return self.commits > 0 and (self.tries is None or self.commits <= self.tries)

    def send(self, data: bytes) -> None:
        if data[0] == pg.MSG_BY_NAME["param_commit"].id:
            self.commits += 1
            if self.drop_commits and self._dead():
                return
        self.t.send(data)

    def start(self, on_message) -> None:
        def on(data: bytes, ts: float) -> None:
            if self.drop_commits or not self._dead():
                on_message(data, ts)

        self.t.start(on)

    def __getattr__(self, name):
        return getattr(self.t, name)


def _faulty_client(server, tries, drop_commits=False):
    from contour.link.client import Client
    from contour.link.transport import open_transport

    t = _CommitReplyFaults(open_transport(port=server.serial), tries, drop_commits)
    return Client(t, timeout=0.1, retries=3), t


def _disabled_watch(server) -> dict:
    with connect(port=server.serial) as c:
        if c.status()["state"] in (pg.State.FAULT, pg.State.ESTOP):
            c.request("fault_reset")
        c.enable(False)
        wait_state(c, (pg.State.DISABLED,))
        return {n: c.get_param(n) for n in WATCH}


def test_a_commit_whose_replies_are_all_lost_is_settled_as_applied(server, monkeypatch):
    """The drive applies the commit, but its reply is lost on every try of
    the client (4): the restore asks again (same transaction, a new
    request) once the link answers, and the drive says committed without
    applying twice; the values are read back."""
    from contour.commands import config as cfg

    monkeypatch.setattr(cfg, "COMMIT_ASK_PAUSE_S", 0.05)
    before = _disabled_watch(server)
    values = {"max_velocity.x": before["max_velocity.x"] + 1_000, "max_velocity.y": 7_000_000}
    c, t = _faulty_client(server, tries=4)
    with c:
        cfg.write_all(c, values)
        assert t.commits == 5  # the first request's 4 tries, then one that was answered
        assert {n: c.get_param(n) for n in values} == values
        c.set_param("max_velocity.x", before["max_velocity.x"])
        c.set_param("max_velocity.y", before["max_velocity.y"])


def test_a_commit_never_answered_says_the_outcome_is_unknown(server, monkeypatch):
    """The link stays dead after the commit went out: the error says plainly
    that the outcome is unknown and how to check, not just 'no reply'."""
    from contour.commands import config as cfg
    from contour.errors import UserError

    monkeypatch.setattr(cfg, "COMMIT_ASK_PAUSE_S", 0.05)
    before = _disabled_watch(server)
    values = {"max_velocity.x": before["max_velocity.x"] + 2_000}
    c, t = _faulty_client(server, tries=None)
    with c:
        with pytest.raises(UserError, match="restore outcome unknown") as e:
            cfg.write_all(c, values)
        assert t.commits == 4 * (1 + cfg.COMMIT_ASK_ROUNDS)
    msg = str(e.value)
    assert "config backup" in msg and "restore again" in msg, msg
    with connect(port=server.serial) as c:  # (it was applied: the requests got through)
        assert c.get_param("max_velocity.x") == values["max_velocity.x"]
        c.set_param("max_velocity.x", before["max_velocity.x"])


def test_a_commit_lost_on_the_way_is_settled_as_not_applied(server, monkeypatch):
    """The commit requests themselves are lost for longer than the drive's
    comm_timeout_ms: the drive dropped the transaction (link_timeout), and
    the commit asked again says so: nothing written, definitely."""
    from contour.commands import config as cfg
    from contour.errors import UserError

    monkeypatch.setattr(cfg, "COMMIT_ASK_PAUSE_S", 0.05)
    before = _disabled_watch(server)
    values = {"max_velocity.x": before["max_velocity.x"] + 3_000}
    c, t = _faulty_client(server, tries=4, drop_commits=True)
    with c:
        c.set_param("comm_timeout_ms", 200)  # < the 4 tries of 0.1 s
        try:
            with pytest.raises(UserError, match="nothing written") as e:
                cfg.write_all(c, values)
        finally:
            c.set_param("comm_timeout_ms", before["comm_timeout_ms"])
        assert "lost: link timeout" in str(e.value), str(e.value)
        assert c.get_param("max_velocity.x") == before["max_velocity.x"]


@pytest.mark.parametrize("holds", [True, False])
def test_a_commit_the_drive_no_longer_knows_is_settled_by_reading_back(holds, monkeypatch):
    """No try of the commit answered, and when asked again the drive no
    longer knows the transaction (not_open: another session's transaction
    came since): the values read back say whether the drive holds the file."""
    from contour.commands import config as cfg
    from contour.errors import UserError
    from contour.link.transport import LinkError

    monkeypatch.setattr(cfg, "COMMIT_ASK_PAUSE_S", 0.0)
    values = {"max_velocity.x": 5, "max_velocity.y": 6}

    class Drive:
        commits = 0

        def request(self, name, **fields):
            if name == "param_begin":
                return codec.Decoded("param_txn", 0, 0, {"txn": 7})
            if name == "param_commit":
                self.commits += 1
                if self.commits == 1:
                    raise LinkError("no reply")
                f = {"code": pg.ErrorCode.TXN, "arg": pg.TxnStatus.NOT_OPEN, "lo": 7, "hi": 0}
                raise DriveError(name, f, "not open")
            return codec.Decoded("ack", 0, 0, {})

        def get_param(self, name):
            return values[name] if holds or name.endswith(".x") else 0

    if holds:
        cfg.write_all(Drive(), values)
    else:
        with pytest.raises(UserError, match=r"restore not completed: .*\(max_velocity.y\)"):
            cfg.write_all(Drive(), values)
