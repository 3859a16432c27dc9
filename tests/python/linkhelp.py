"""Helpers shared by the end-to-end tests that talk to a simulated drive
(`contour sim serve`) through the command line or a `contour.link` client."""

from __future__ import annotations

import time

from contour import cli


def link_args(server, transport: str) -> list[str]:
    """Command-line options that reach `server` over "serial" or "slcan" (node 1)."""
    if transport == "serial":
        return ["--port", server.serial]
    return ["--can", f"slcan:{server.slcan}", "--bitrate", "500000", "--node", "1"]


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    """Run `contour ARGV` in process: (exit code, stdout, stderr)."""
    rc = cli.main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


def wait_state(c, states, timeout: float = 5.0) -> dict:
    """Poll the drive's status until its state is one of `states` (or timeout);
    returns the last status."""
    end = time.monotonic() + timeout
    st = c.status()
    while time.monotonic() < end and st["state"] not in states:
        time.sleep(0.02)
        st = c.status()
    return st


def client_for(server, transport: str, **kw):
    """A `contour.link` client of `server` over "serial" or "slcan" (node 1)."""
    from contour.link import connect

    if transport == "serial":
        return connect(port=server.serial, **kw)
    return connect(can=f"slcan:{server.slcan}@500000", node=1, **kw)


def fresh(c) -> dict:
    """Drive back to a known state: link defaults, no fault, enabled, at rest.
    Returns the status after it."""
    from contour import protocol_gen as pg

    c.set_param("telem_period_ms", 0)
    c.set_param("comm_timeout_ms", 1000)
    st = c.status()
    if st["state"] in (pg.State.RUNNING, pg.State.STOPPING):
        c.request("stop")
        st = wait_state(c, (pg.State.READY, pg.State.DISABLED, pg.State.FAULT, pg.State.ESTOP))
    if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
        c.request("fault_reset")
    c.enable(True)
    return c.status()
