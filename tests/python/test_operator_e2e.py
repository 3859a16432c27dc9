"""End to end: the operator commands (`enable`, `disable`, `reset`, `estop`,
`stop`, `jog`, `status`) against the simulated drive (`sim serve`) over the
serial pseudo-terminal and over SLCAN.

The simulated drive listens on both links at once (one drive): a test that
needs a second host while a command holds one link (e-stop during a jog,
watching a jog that is then killed) uses the other link.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from contour import protocol_gen as pg
from contour.sim.serve import spawn
from linkhelp import client_for, fresh, link_args, run_cli

TRANSPORTS = ["serial", "slcan"]
COUNT_NM = 1250  # one encoder count of the default machine: 5 mm lead / 4000 counts
OTHER = {"serial": "slcan", "slcan": "serial"}


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


def moving_from(c, axis: int, p0: int, timeout: float = 15.0, by: int = 200_000) -> int:
    """Poll until `axis` is more than `by` nm away from `p0`; its position."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        p = c.status()["pos"][axis]
        if abs(p - p0) > by:
            return p
        time.sleep(0.02)
    raise AssertionError(f"axis {axis} did not start moving from {p0} nm")


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_enable_disable_status(server, transport, capsys):
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        fresh(c)
    rc, out, err = run_cli(["disable", *args], capsys)
    assert rc == 0, err
    assert "state disabled" in out
    rc, out, _ = run_cli(["status", *args], capsys)
    assert rc == 0
    assert "state     disabled" in out and "faults    none" in out and " mm" in out
    rc, out, err = run_cli(["enable", "--json", *args], capsys)
    assert rc == 0, err
    assert json.loads(out)["state"] == "ready"
    assert json.loads(out)["enabled_axes"] == ["x", "y", "z"]
    with client_for(server, transport) as c:
        st = c.status()
    assert st["state"] == pg.State.READY
    rc, out, _ = run_cli(["status", "--json", *args], capsys)
    s = json.loads(out)
    assert rc == 0 and s["state"] == "ready" and s["faults"] == []
    assert s["position_mm"] == {a: st["pos"][i] / 1e6 for i, a in enumerate("xyz")}
    assert s["queue"]["free_slots"] == st["free_slots"]
    # a drive that switches its axes together refuses a part: said, exit 1
    rc, _, err = run_cli(["enable", "--axes", "x", *args], capsys)
    assert rc == 1 and "together" in err
    rc, _, err = run_cli(["enable", "--axes", "x,q", *args], capsys)
    assert rc == 2 and "axis 'q'" in err


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_status_watch_one_line_per_sample(server, transport, capsys):
    args = link_args(server, transport)
    rc, out, err = run_cli(
        ["status", "--watch", "--count", "3", "--period", "0.05", "--json", *args], capsys
    )
    assert rc == 0, err
    lines = out.strip().splitlines()
    assert len(lines) == 3
    objs = [json.loads(line) for line in lines]
    assert all("state" in o and "position_mm" in o for o in objs)
    assert objs[0]["t_s"] < objs[1]["t_s"] < objs[2]["t_s"]
    rc, out, err = run_cli(["status", "--watch", "--count", "2", "--period", "0.05", *args], capsys)
    assert rc == 0, err
    lines = out.splitlines()
    assert len(lines) == 2 and "\r" not in out and "\033" not in out  # not a TTY
    assert all(" mm" in line for line in lines)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_jog_incremental_and_absolute(server, transport, capsys):
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        st = fresh(c)
    y0 = st["pos"][1]
    rc, out, err = run_cli(["jog", "y", "2.5", "--feed", "1200", "--json", *args], capsys)
    assert rc == 0, err
    res = json.loads(out)
    with client_for(server, transport) as c:
        y1 = c.status()["pos"][1]
    assert abs(y1 - (y0 + 2_500_000)) <= 2 * COUNT_NM, (y0, y1)
    assert res["end_mm"] == y1 / 1e6  # the printed end is the measured position
    assert res["state"] == "ready"
    rc, out, err = run_cli(["jog", "y", "-1.25", "--feed", "600", *args], capsys)
    assert rc == 0, err
    with client_for(server, transport) as c:
        y2 = c.status()["pos"][1]
    assert abs(y2 - (y1 - 1_250_000)) <= 2 * COUNT_NM, (y1, y2)
    assert f"y at {y2 / 1e6:.4f} mm" in out
    # absolute: to a position, from wherever the axis is
    rc, out, err = run_cli(["jog", "x", "--to", "-3.75", "--feed", "3000", *args], capsys)
    assert rc == 0, err
    with client_for(server, transport) as c:
        x = c.status()["pos"][0]
    assert abs(x - (-3_750_000)) <= 2 * COUNT_NM, x
    rc, out, err = run_cli(["jog", "x", "--to", "7", "--feed", "6000", "--json", *args], capsys)
    assert rc == 0, err
    with client_for(server, transport) as c:
        x = c.status()["pos"][0]
    assert abs(x - 7_000_000) <= 2 * COUNT_NM, x
    assert abs(json.loads(out)["end_mm"] - 7.0) <= 2 * COUNT_NM / 1e6


@pytest.mark.parametrize(
    "argv, text",
    [
        (["jog", "q", "1", "--feed", "600"], "axis 'q'"),
        (["jog", "a", "1", "--feed", "600"], "3 axes"),  # the drive has x, y, z
        (["jog", "x", "0", "--feed", "600"], "not be 0"),
        (["jog", "x", "nan", "--feed", "600"], "finite"),
        (["jog", "x", "--feed", "600"], "distance"),
        (["jog", "x", "1", "--to", "2", "--feed", "600"], "not both"),
        (["jog", "x", "1", "--feed", "0"], "positive"),
        (["jog", "x", "1", "--feed", "-5"], "positive"),
        (["jog", "x", "1"], "--feed"),
        (["jog", "x", "1", "--feed", "90000"], "limit"),  # above max_velocity.x
        (["status", "--watch", "--period", "0"], "--period"),
    ],
)
def test_jog_usage_errors_move_nothing(server, argv, text, capsys):
    args = link_args(server, "serial")
    with client_for(server, "serial") as c:
        p0 = fresh(c)["pos"]
    rc, _, err = run_cli([*argv, *args], capsys)
    assert rc == 2 and text in err, err
    with client_for(server, "serial") as c:
        st = c.status()
    assert st["pos"] == p0 and st["state"] == pg.State.READY


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_estop_then_reset_enable_and_go_on(server, transport, tmp_path, capsys):
    """The fault scenario: a latched e-stop is reported, refuses motion by
    name, is cleared by `reset` (named), and after `enable` a jog works."""
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        fresh(c)
    rc, out, err = run_cli(["estop", *args], capsys)
    assert rc == 0, err
    assert "state estop" in out and "contour reset" in out
    rc, out, _ = run_cli(["status", "--json", *args], capsys)
    s = json.loads(out)
    assert s["state"] == "estop" and s["faults"] == ["estop"]
    assert s["enabled_axes"] == []
    job = tmp_path / "j.nc"
    job.write_text("G21 G91\nG1 X1 F600\n")
    rc, _, err = run_cli(["run", str(job), "--quiet", *args], capsys)
    assert rc == 1 and "estop" in err
    rc, _, err = run_cli(["jog", "x", "1", "--feed", "600", *args], capsys)
    assert rc == 1 and "estop" in err and "contour reset" in err
    rc, _, err = run_cli(["enable", *args], capsys)
    assert rc == 1 and "estop" in err and "contour reset" in err
    rc, out, err = run_cli(["reset", *args], capsys)
    assert rc == 0, err
    assert "cleared: estop" in out
    rc, out, _ = run_cli(["reset", "--json", *args], capsys)
    assert rc == 0 and json.loads(out)["cleared"] == []
    rc, out, _ = run_cli(["reset", *args], capsys)
    assert rc == 0 and "no fault latched" in out
    rc, out, err = run_cli(["jog", "x", "1", "--feed", "600", *args], capsys)
    assert rc == 1 and "disabled" in err and "contour enable" in err
    rc, _, err = run_cli(["enable", *args], capsys)
    assert rc == 0, err
    with client_for(server, transport) as c:
        x0 = c.status()["pos"][0]
    rc, out, err = run_cli(["jog", "x", "1", "--feed", "600", *args], capsys)
    assert rc == 0, err
    with client_for(server, transport) as c:
        assert abs(c.status()["pos"][0] - (x0 + 1_000_000)) <= 2 * COUNT_NM


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_stop_waits_for_rest(server, transport, capsys):
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        st = fresh(c)
        x0 = st["pos"][0]
        c.request("jog", axis=0, feed=2_000_000, distance=30_000_000)
        moving_from(c, 0, x0)
    rc, out, err = run_cli(["stop", "--json", *args], capsys)
    assert rc == 0, err
    s = json.loads(out)
    assert s["state"] == "ready" and s["faults"] == []
    with client_for(server, transport) as c:
        time.sleep(0.1)
        x = c.status()["pos"][0]
    assert abs(x - s["position_mm"]["x"] * 1e6) <= COUNT_NM  # it was at rest
    assert x0 + 200_000 < x < x0 + 29_000_000  # stopped on the way


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_fault_during_jog_is_named(server, transport, capsys):
    """Another host e-stops the drive while `jog` runs: exit 1, fault named."""
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        x0 = fresh(c)["pos"][0]

    def estop_when_moving() -> None:
        with client_for(server, OTHER[transport]) as other:
            moving_from(other, 0, x0)
            other.request("estop")

    t = threading.Thread(target=estop_when_moving)
    t.start()
    try:
        rc, _, err = run_cli(["jog", "x", "20", "--feed", "1200", *args], capsys)
    finally:
        t.join(20)
    assert rc == 1 and "stopped by a fault: estop" in err, err
    with client_for(server, transport) as c:
        st = c.status()
        assert st["state"] == pg.State.ESTOP
        assert x0 + 200_000 < st["pos"][0] < x0 + 19_000_000
        c.request("fault_reset")


def _spawn_jog(server, transport: str, argv: list[str]) -> subprocess.Popen:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (os.path.dirname(os.path.dirname(pg.__file__)), env.get("PYTHONPATH")) if p
    )
    return subprocess.Popen(
        [sys.executable, "-m", "contour", "jog", *argv, *link_args(server, transport)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_sigterm_during_jog_is_a_controlled_stop(server, transport):
    with client_for(server, OTHER[transport]) as c:
        x0 = fresh(c)["pos"][0]
    p = _spawn_jog(server, transport, ["x", "30", "--feed", "1200"])
    try:
        with client_for(server, OTHER[transport]) as c:
            moving_from(c, 0, x0)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=20)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 128 + signal.SIGTERM, err
    assert "stopped by signal 15" in err
    with client_for(server, OTHER[transport]) as c:
        st = c.status()
        assert st["state"] == pg.State.READY and st["faults"] == 0  # a stop, no fault
        assert x0 + 200_000 < st["pos"][0] < x0 + 29_000_000
        time.sleep(0.1)
        assert abs(c.status()["pos"][0] - st["pos"][0]) <= 2 * COUNT_NM  # at rest


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_kill_9_during_jog_comm_timeout_then_reset(server, transport, capsys):
    """A host killed mid-jog: the drive stops by its communication watchdog,
    `status` reports comm_timeout, `reset` clears it (named), and after
    `enable` a jog works again."""
    other = link_args(server, OTHER[transport])
    with client_for(server, OTHER[transport]) as c:
        x0 = fresh(c)["pos"][0]
        c.set_param("comm_timeout_ms", 300)
    p = _spawn_jog(server, transport, ["x", "40", "--feed", "1200"])
    try:
        with client_for(server, OTHER[transport]) as c:
            moving_from(c, 0, x0)
        # from here no host talks to the drive
        p.kill()
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    time.sleep(1.5)  # 300 ms watchdog + the stop
    rc, out, _ = run_cli(["status", "--json", *other], capsys)
    s = json.loads(out)
    assert rc == 0 and s["state"] == "fault" and s["faults"] == ["comm_timeout"], s
    x1 = s["position_mm"]["x"] * 1e6
    assert x0 + 200_000 < x1 < x0 + 39_000_000  # stopped on the way
    with client_for(server, OTHER[transport]) as c:
        assert abs(c.status()["pos"][0] - x1) <= 2 * COUNT_NM  # at rest
        c.set_param("comm_timeout_ms", 1000)
    rc, _, err = run_cli(["jog", "x", "1", "--feed", "600", *other], capsys)
    assert rc == 1 and "comm_timeout" in err
    rc, out, err = run_cli(["reset", *other], capsys)
    assert rc == 0 and "cleared: comm_timeout" in out, err
    rc, _, err = run_cli(["enable", *other], capsys)
    assert rc == 0, err
    rc, out, err = run_cli(["jog", "x", "-1", "--feed", "600", "--json", *other], capsys)
    assert rc == 0, err
    assert abs(json.loads(out)["end_mm"] * 1e6 - (x1 - 1_000_000)) <= 2 * COUNT_NM


@pytest.mark.parametrize("as_json", [False, True])
def test_ctrl_c_during_jog_is_a_controlled_stop(server, as_json, monkeypatch, capsys):
    """Ctrl-C while `jog` waits: controlled stop, exit 130, no fault; with
    --json the report is a JSON error object with where the axes stopped."""
    from contour.operator import Operator

    with client_for(server, "serial") as c:
        x0 = fresh(c)["pos"][0]
    real = Operator.snapshot
    fired = []

    def snapshot(self):
        s = real(self)
        if not fired and s.state == "running" and s.position_nm[0] - x0 > 200_000:
            fired.append(s)
            raise KeyboardInterrupt
        return s

    monkeypatch.setattr(Operator, "snapshot", snapshot)
    argv = ["jog", "x", "30", "--feed", "1200", *link_args(server, "serial")]
    rc, out, err = run_cli(argv + ["--json"] * as_json, capsys)
    assert fired and rc == 130, err
    if as_json:
        res = json.loads(out)
        assert err == "" and res["error"]["kind"] == "interrupted"
        assert res["error"]["exit_code"] == 130 and res["state"] == "ready"
        assert "stopped by Ctrl-C" in res["error"]["message"]
    else:
        assert "stopped by Ctrl-C" in err
    monkeypatch.undo()
    with client_for(server, "serial") as c:
        st = c.status()
        assert st["state"] == pg.State.READY and st["faults"] == 0
        assert x0 + 200_000 < st["pos"][0] < x0 + 29_000_000
        time.sleep(0.1)
        assert abs(c.status()["pos"][0] - st["pos"][0]) <= 2 * COUNT_NM  # at rest


def test_status_watch_redraws_in_place_on_a_terminal(server, monkeypatch, capsys):
    import contour.commands.status as status_cmd

    monkeypatch.setattr(status_cmd, "is_terminal", lambda stream: True)
    argv = ["status", "--watch", "--count", "3", "--period", "0.05"]
    rc, out, err = run_cli([*argv, *link_args(server, "serial")], capsys)
    assert rc == 0, err
    assert out.count("\r\033[K") == 3 and out.count("\n") == 1  # one line, redrawn


def test_watch_ends_on_ctrl_c_with_exit_0(server, monkeypatch, capsys):
    """Ctrl-C is how `status --watch` is meant to end: no error."""
    import contour.commands.status as status_cmd

    calls = []

    def sleep(s):
        calls.append(s)
        if len(calls) == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(status_cmd, "sleep", sleep)
    rc, out, err = run_cli(
        ["status", "--watch", "--json", "--period", "0.05", *link_args(server, "serial")], capsys
    )
    assert rc == 0 and err == ""
    assert len(out.strip().splitlines()) == 2


class FakeClient:
    """Just enough of a Client for Operator.reset: a fault whose cause stays."""

    def __init__(self, faults: int, state: int, refuse=None) -> None:
        self.st = {
            "state": state,
            "enabled": 0,
            "faults": faults,
            "free_slots": 16,
            "queued_us": 0,
            "blocks_done": 0,
            "last_block_seq": 0,
            "pos": [0, 0, 0, 0],
        }
        self.refuse = refuse
        self.sent = []

    def identify(self):
        return {"axes": 3}

    def status(self):
        return dict(self.st)

    def request(self, name, **fields):
        from contour.link.client import DriveError, describe_error

        self.sent.append(name)
        if self.refuse is not None:
            f = {"req": 9, "code": int(self.refuse), "arg": 0, "lo": 0, "hi": 0}
            raise DriveError(name, f, describe_error(name, f))
        self.st.update(faults=0, state=pg.State.DISABLED)


def test_reset_names_a_fault_whose_cause_is_present():
    from contour.operator import FaultError, Operator

    bits = 1 << pg.Fault.AMP_FAULT
    c = FakeClient(bits, pg.State.FAULT, refuse=pg.ErrorCode.CAUSE_PRESENT)
    with pytest.raises(FaultError, match=r"cannot clear amp_fault: its cause is still present"):
        Operator(c).reset()
    assert c.sent == ["fault_reset"]
    c = FakeClient(bits | 1, pg.State.FAULT)
    cleared, snap = Operator(c).reset()
    assert cleared == ["comm_timeout", "amp_fault"] and snap.state == "disabled"
    c = FakeClient(0, pg.State.READY)
    assert Operator(c).reset()[0] == [] and c.sent == []  # nothing latched: nothing sent


LINK_OPTIONS = {"--port", "--can", "--interface", "--channel", "--bitrate", "--node", "--timeout"}
OPERATOR_COMMANDS = ("enable", "disable", "reset", "estop", "stop", "jog", "status")


def test_operator_commands_follow_the_conventions():
    """Same link options and --json on every operator command; the commands
    only parse and print (the procedures are in contour.operator)."""
    import argparse
    import ast

    from contour import cli, operator

    parser = cli.build_parser()
    cmds = {}
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            cmds.update(a.choices)
    for name in OPERATOR_COMMANDS:
        opts = {o for a in cmds[name]._actions for o in a.option_strings}
        assert opts >= LINK_OPTIONS | {"--json"}, (name, LINK_OPTIONS - opts)
    tree = ast.parse(Path(operator.__file__).read_text())
    imported = {
        n.module if isinstance(n, ast.ImportFrom) else a.name
        for n in ast.walk(tree)
        if isinstance(n, (ast.Import, ast.ImportFrom))
        for a in n.names
    }
    assert not {m for m in imported if m == "argparse" or m.startswith("contour.commands")}


def test_reset_cause_present_is_exit_1_on_the_command_line(monkeypatch, capsys):
    import contour.commands.reset as reset_cmd

    fake = FakeClient(1 << pg.Fault.AMP_FAULT, pg.State.FAULT, refuse=pg.ErrorCode.CAUSE_PRESENT)

    class Ctx:
        def __enter__(self):
            return fake

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(reset_cmd, "connect_from_args", lambda args: Ctx())
    rc, out, _ = run_cli(["reset", "--json", "--port", "/nonexistent"], capsys)
    err = json.loads(out)["error"]
    assert rc == 1 and err["kind"] == "fault" and "amp_fault" in err["message"]


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_fault_during_run_names_the_program_line(server, transport, tmp_path, capsys):
    """Another host e-stops the drive during `contour run`: exit 1 and the
    message names the line of the block that was executing."""
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        x0 = fresh(c)["pos"][0]
    job = tmp_path / "long.nc"
    job.write_text("G21 G91\nG1 X0.5 F600\nG1 X20 F1200\nG1 X-20.5\n")

    def estop_when_moving() -> None:
        with client_for(server, OTHER[transport]) as other:
            moving_from(other, 0, x0, by=1_000_000)
            other.request("estop")

    t = threading.Thread(target=estop_when_moving)
    t.start()
    try:
        rc, _, err = run_cli(["run", str(job), "--quiet", *args], capsys)
    finally:
        t.join(20)
    assert rc == 1 and f"{job}:3: drive stopped with fault(s): estop" in err, err
    with client_for(server, transport) as c:
        c.request("fault_reset")


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_refused_block_names_the_program_line(server, transport, tmp_path, capsys):
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        fresh(c)
    job = tmp_path / "far.nc"
    job.write_text(
        "G21 G91\nG1 X0.1 F600\nG1 X10000000000\n"
    )  # 10 000 km: beyond the drive's range
    rc, _, err = run_cli(["run", str(job), "--quiet", *args], capsys)
    # refused by run's first pass, before any block is sent (issue 17)
    assert rc == 1 and f"{job}:3: X target 1e+10 mm is out of range" in err, err
