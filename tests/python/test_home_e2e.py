"""End to end: `contour home` against the simulated drive (`sim serve`) over
the serial pseudo-terminal and over SLCAN.

The simulated machine's X axis has its home switch at table position
-21.3 mm (active below) and an encoder index every motor turn (5 mm), one at
table 0: the reference point is the index at -20 mm. The drive's position
frame starts as the table's, so a homing with --home-pos X=-20 moves the
frame by 0 and one with X=-21 by -1 mm; the drive reports the move of its
last homing per axis (drive_state.home_shift), which makes the table
position visible from the host.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest
from contour import protocol_gen as pg
from contour.link import connect
from contour.sim.serve import spawn
from linkhelp import link_args, run_cli, wait_state

TRANSPORTS = ["serial", "slcan"]
COUNT_NM = 1250  # one encoder count: 5 mm lead / 4000 counts
FAST = ["--search-feed", "1200", "--latch-feed", "300"]


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


def client_for(server, transport: str, **kw):
    if transport == "serial":
        return connect(port=server.serial, **kw)
    return connect(can=f"slcan:{server.slcan}@500000", node=1, **kw)


def fresh(c) -> dict:
    c.set_param("telem_period_ms", 0)
    c.set_param("comm_timeout_ms", 1000)
    st = c.status()
    if st["state"] in (pg.State.RUNNING, pg.State.STOPPING, pg.State.HOMING):
        c.request("stop")
        st = wait_state(c, (pg.State.READY, pg.State.DISABLED, pg.State.FAULT, pg.State.ESTOP))
    if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
        c.request("fault_reset")
    c.enable(True)
    return c.status()


def home(args, capsys, home_pos: str = "X=-20", extra=()) -> dict:
    argv = ["home", "--axes", "x", "--home-pos", home_pos, *FAST, "--json", *extra, *args]
    rc, out, err = run_cli(argv, capsys)
    assert rc == 0, err
    return json.loads(out)


def jog_to(args, capsys, mm: float) -> None:
    rc, _, err = run_cli(["jog", "x", "--to", str(mm), "--feed", "3000", *args], capsys)
    assert rc == 0, err


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_home_then_jog_lands_in_the_machine_frame(server, transport, capsys):
    args = link_args(server, transport)
    with client_for(server, transport) as c:
        fresh(c)
    home(args, capsys)  # frame = the table's, whatever it was before
    # repeatable from another start: the frame moves by less than a count
    jog_to(args, capsys, 12.0)
    res = home(args, capsys)
    assert res["homed_axes"] == ["x"] and res["state"] == "ready"
    assert abs(res["shift_um"]["x"]) <= COUNT_NM / 1000, res
    with client_for(server, transport) as c:
        st = c.status()
    assert st["homed"] & 1 and st["faults"] == 0
    # reference point at -21 mm: the frame moves by -1 mm exactly
    res = home(args, capsys, "X=-21")
    assert abs(res["shift_um"]["x"] + 1000.0) <= COUNT_NM / 1000, res
    # the homed position printed is the measured one, just past the index
    assert -21.0 - COUNT_NM / 1e6 <= res["position_mm"]["x"] < -20.9
    # a jog in that frame lands 1 mm higher on the table: homing in the
    # table's frame again (from there) moves the frame by +1 mm
    jog_to(args, capsys, -6.0)
    jog_to(args, capsys, 9.0)
    res = home(args, capsys)
    assert abs(res["shift_um"]["x"] - 1000.0) <= COUNT_NM / 1000, res
    rc, out, err = run_cli(["status", *args], capsys)
    assert rc == 0, err
    assert "homed     x" in out


def test_home_text_output_and_all_axes(server, capsys):
    args = link_args(server, "serial")
    with client_for(server, "serial") as c:
        fresh(c)
    rc, out, err = run_cli(["home", *FAST, "--home-pos", "-20", *args], capsys)
    assert rc == 0, err
    for name in ("x", "y", "z"):
        assert f"{name} homed at -20.0" in out
    with client_for(server, "serial") as c:
        st = c.status()
    assert st["homed"] == 0b111
    assert all(abs(p + 20_000_000) < 100_000 for p in st["pos"][:3])


def test_home_switch_not_found_is_a_named_fault(server, capsys):
    args = link_args(server, "serial")
    with client_for(server, "serial") as c:
        fresh(c)
    jog_to(args, capsys, 4.0)  # the switch is 25.3 mm away
    argv = ["home", "--axes", "x", *FAST, "--max-distance", "5", *args]
    rc, out, err = run_cli(argv, capsys)
    assert rc == 1, (out, err)
    assert "homing" in err and "contour reset" in err
    with client_for(server, "serial") as c:
        st = c.status()
        assert st["state"] == pg.State.FAULT
        assert st["faults"] & (1 << pg.Fault.HOMING)
        assert not st["homed"] & 1
        x = st["pos"][0]
        assert -2_000_000 < x < -500_000, x  # stopped after about 5 mm
    rc, out, err = run_cli(["reset", *args], capsys)
    assert rc == 0 and "homing" in out, (out, err)


def test_home_refused_while_disabled(server, capsys):
    args = link_args(server, "serial")
    with client_for(server, "serial") as c:
        fresh(c)
        c.enable(False)
        wait_state(c, (pg.State.DISABLED,))
    rc, out, err = run_cli(["home", *args], capsys)
    assert rc == 1 and "contour enable" in err, (out, err)


@pytest.mark.parametrize(
    "argv, text",
    [
        (["home", "--axes", "q"], "axis 'q'"),
        (["home", "--axes", "a"], "3 axes"),
        (["home", "--latch-feed", "2000", "--search-feed", "1000"], "--latch-feed"),
        (["home", "--max-distance", "0"], "--max-distance"),
        (["home", "--search-feed", "0"], "positive"),
        (["home", "--home-pos", "X=abc"], "--home-pos"),
    ],
)
def test_home_usage_errors(server, argv, text, capsys):
    rc, out, err = run_cli([*argv, *link_args(server, "serial")], capsys)
    assert rc == 2 and text in err, (out, err)


def test_ctrl_c_during_home_stops(server, monkeypatch, capsys):
    """Ctrl-C while `home` waits: controlled stop (homing aborted, axis not
    homed, no fault), exit 130."""
    from contour.operator import Operator

    args = link_args(server, "serial")
    with client_for(server, "serial") as c:
        fresh(c)
    jog_to(args, capsys, 10.0)
    real = Operator.snapshot
    fired = []

    def snapshot(self):
        s = real(self)
        if not fired and s.state == "homing" and s.position_nm[0] < 9_000_000:
            fired.append(s)
            raise KeyboardInterrupt
        return s

    monkeypatch.setattr(Operator, "snapshot", snapshot)
    rc, out, err = run_cli(["home", "--axes", "x", *FAST, *args], capsys)
    assert fired and rc == 130, err
    assert "homing stopped by Ctrl-C" in err
    monkeypatch.undo()
    with client_for(server, "serial") as c:
        st = c.status()
        assert st["state"] == pg.State.READY and st["faults"] == 0
        assert not st["homed"] & 1
        assert -21_300_000 < st["pos"][0] < 9_000_000


def test_first_home_finds_the_index_above_the_switch(capsys):
    """On a drive just started (its frame the table's), the reference point
    is the index at -20 mm: homing to -20 moves the frame by under a count
    (the switch edge, -21.3 mm, would move it by +1.3 mm)."""
    with spawn() as s:
        args = link_args(s, "slcan")
        with client_for(s, "slcan") as c:
            fresh(c)
        jog_to(args, capsys, 3.0)
        res = home(args, capsys)
        assert abs(res["shift_um"]["x"]) <= COUNT_NM / 1000, res
        # without the index, the switch edge is the reference
        res = home(args, capsys, "X=-21.3", extra=["--no-index"])
        assert abs(res["shift_um"]["x"]) <= 2 * COUNT_NM / 1000, res


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_kill_9_during_home_comm_timeout(server, transport, capsys):
    """A host killed while the drive homes: the communication watchdog stops
    the homing (fault comm_timeout, axis not homed), `reset`, `enable` and a
    new `home` go on."""
    other = "slcan" if transport == "serial" else "serial"
    oargs = link_args(server, other)
    with client_for(server, other) as c:
        fresh(c)
    jog_to(oargs, capsys, 10.0)
    with client_for(server, other) as c:
        c.set_param("comm_timeout_ms", 300)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (os.path.dirname(os.path.dirname(pg.__file__)), env.get("PYTHONPATH")) if p
    )
    argv = ["home", "--axes", "x", "--search-feed", "300", *link_args(server, transport)]
    p = subprocess.Popen(
        [sys.executable, "-m", "contour", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    try:
        with client_for(server, other) as c:
            wait_state(c, (pg.State.HOMING,))
            end = time.monotonic() + 10
            while c.status()["pos"][0] > 9_500_000 and time.monotonic() < end:
                time.sleep(0.02)
        p.kill()  # from here no host talks to the drive
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    time.sleep(1.5)  # 300 ms watchdog + the stop
    with client_for(server, other) as c:
        st = c.status()
        assert st["state"] == pg.State.FAULT, st
        assert st["faults"] == 1 << pg.Fault.COMM_TIMEOUT, st
        assert not st["homed"] & 1
        assert -21_300_000 < st["pos"][0] < 9_500_000  # stopped on the way
        c.set_param("comm_timeout_ms", 1000)
    rc, out, err = run_cli(["reset", *oargs], capsys)
    assert rc == 0 and "comm_timeout" in out, err
    rc, _, err = run_cli(["enable", *oargs], capsys)
    assert rc == 0, err
    assert home(oargs, capsys)["homed_axes"] == ["x"]
