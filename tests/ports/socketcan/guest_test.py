"""Checks run inside the SocketCAN guest against the Linux port on vcan.

The host tool's own code paths: python-can's `socketcan` interface, ISO-TP
requests (can-isotp) through contour.link.client, and `contour info --can`.
Prints one line per check and "SOCKETCAN: PASS" when all passed.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import can
from contour import protocol_gen as pg
from contour.link.client import DriveError, connect


def main() -> int:
    iface, node = sys.argv[1], int(sys.argv[2])
    spec = f"socketcan:{iface}"
    failures = []

    def check(name: str, ok: bool, detail: str = "") -> None:
        print(f"  {'ok  ' if ok else 'FAIL'} {name} {detail}".rstrip(), flush=True)
        if not ok:
            failures.append(name)

    # raw frames: the drive's heartbeat on its node id (python-can socketcan)
    with can.Bus(interface="socketcan", channel=iface) as bus:
        hb = pg.can_id(pg.CAN_FUNC["heartbeat"], node)
        end = time.monotonic() + 5
        seen = None
        while time.monotonic() < end and seen is None:
            m = bus.recv(timeout=0.5)
            if m is not None and m.is_extended_id and m.arbitration_id == hb:
                seen = m
        check("heartbeat frame", seen is not None, f"id 0x{hb:08X} (29-bit)")

    with connect(can=spec, node=node, timeout=1.0) as c:
        ident = c.identify()  # multi-frame ISO-TP reply
        check("identify over ISO-TP", ident["board_id"] == 4 and ident["axes"] == 3, str(ident))
        st = c.status()
        check("status", st["state"] == pg.State.DISABLED, f"state {st['state']}")
        old = c.get_param("status_period_ms")
        c.set_param("status_period_ms", 50)
        check("param set/get", c.get_param("status_period_ms") == 50, f"was {old}")
        try:
            c.set_param("status_period_ms", 10**9)
            check("out-of-range param refused", False)
        except DriveError as exc:
            check("out-of-range param refused", "out of range" in str(exc), str(exc))
        c.enable(True)
        check("enable", c.status()["state"] == pg.State.READY, str(c.status()["state"]))
        c.enable(False)
        check("disable", c.status()["state"] == pg.State.DISABLED)

    r = subprocess.run(
        [sys.executable, "-m", "contour", "info", "--can", spec, "--node", str(node), "--json"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    info = json.loads(r.stdout) if r.returncode == 0 else {}
    ok = info.get("board_id") == 4
    check("contour info --can", ok, "" if ok else f"rc {r.returncode} {r.stderr.strip()[-300:]}")
    # a wrong node gets no answer: a clear error, not a hang
    r = subprocess.run(
        [sys.executable, "-m", "contour", "info", "--can", spec, "--node", str(node + 1),
         "--timeout", "0.2"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    check(
        "silent node reported",
        r.returncode == 1 and "no reply" in r.stderr,  # a link failure: exit code 1
        r.stderr.strip()[-200:],
    )
    print("SOCKETCAN: PASS" if not failures else f"SOCKETCAN: FAIL {failures}", flush=True)
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
