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
