#!/usr/bin/env bash
# Sustained streaming rate of short motion blocks from the host tool to the
# real-time simulated drive (`sim serve`), over the serial pty and over SLCAN
# (python-can slcan + can-isotp). Blocks of 10 um along X at 6 m/min (0.1 ms
# of motion each): the link and the drive's block intake are the limit.
# Prints stream_blocks_per_second_serial / _slcan.
set -euo pipefail
cd "$(dirname "$0")/.."
N=${STREAM_BENCH_BLOCKS:-1500}
.venv/bin/python - "$N" <<'PY'
import sys
import time

from contour import protocol_gen as pg
from contour.link import connect
from contour.link.stream import Block, Streamer
from contour.sim.serve import spawn

n = int(sys.argv[1])


def measure(kind: str, server) -> float:
    if kind == "serial":
        c = connect(port=server.serial)
    else:
        c = connect(can=f"slcan:{server.slcan}@1000000", node=1)
    with c:
        st = c.status()
        if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
            c.request("fault_reset")
        c.enable(True)
        x0, y0, z0 = c.status()["pos"][:3]
        blocks = [
            Block(pg.BlockKind.LINE, (x0 + 10_000 * (i + 1), y0, z0), 100_000_000, False, 1e-4, i)
            for i in range(n)
        ]
        t0 = time.monotonic()
        res = Streamer(c, blocks, queue_s=0.05, poll_s=0.002).run()
        dt = time.monotonic() - t0
    return n / dt if res["blocks"] == n else 0.0


with spawn() as server:
    for kind in ("serial", "slcan"):
        rate = measure(kind, server)
        print(f"stream_blocks_per_second_{kind}: {rate:.0f} blocks/s", flush=True)
PY
