#!/usr/bin/env bash
# Sustained streaming rate of short motion blocks from the host tool to the
# real-time simulated drive (`sim serve`), over the serial pty and over SLCAN
# at 1 Mbit/s (python-can slcan + can-isotp): queue_batch messages of many
# blocks, windowed by the drive's intake ring. A job of STREAM_BENCH_BLOCKS
# (default 20 000) blocks of 10 um along Y at 15 m/min, the drive executing
# them (contour.sim.stream_bench: its settings and why); the job must end
# with every block done once, in order, at the program's end point, else
# the figure is 0 and the bench fails. Then a CAM-like job over serial: a
# circle of 0.05 mm chords at 10 m/min, with the smallest planned time the
# drive had queued mid-job and the median path speed its telemetry reported
# while moving, of the programmed feed.
# The simulated CAN bus carries each frame in its exact bit time at the
# bitrate (1 Mbit/s here; contour.sim.serve); the SLCAN job's frames are
# counted by the host, and their load on the bus is given with worst-case
# stuffing (stream_slcan_bus_load_1mbit, and the same frames on a 500 kbit/s
# bus). Prints stream_blocks_per_second_serial / _slcan,
# stream_slcan_bits_per_block, stream_slcan_bus_load_1mbit and
# stream_cam_min_queued_ms / stream_cam_feed_percent. Then the CAM job and
# the 10 um job over serial again with velocity_profile = scurve_continuous
# (acceleration continuous across blocks): stream_cam_min_queued_ms_continuous,
# stream_cam_feed_percent_continuous, stream_blocks_per_second_serial_continuous
# (10 um blocks: the jerk-limited stop within the 0.64 mm of look-ahead is the
# limit there, not the link).
set -euo pipefail
cd "$(dirname "$0")/.."
N=${STREAM_BENCH_BLOCKS:-20000}
.venv/bin/python - "$N" <<'PY'
import sys

from contour.link import connect
from contour.link.canbits import worst_frame_bits
from contour.link.transport import CanBus
from contour.sim import stream_bench as sb
from contour.sim.serve import spawn

n = int(sys.argv[1])
failed = False
with spawn() as server:
    for kind in ("serial", "slcan"):
        if kind == "serial":
            c = connect(port=server.serial)
        else:
            c = connect(can=CanBus("slcan", server.slcan, 1_000_000), node=1)
        with c:
            r = sb.run(c, sb.SHORT_BLOCK_PARAMS, lambda s: sb.short_blocks(s, n), n)
        try:
            r.check()
            rate = r.blocks_per_second
        except Exception as exc:  # noqa: BLE001 - reported, the figure is 0
            print(f"bench-stream: {kind}: {exc}", file=sys.stderr)
            rate, failed = 0.0, True
        print(f"stream_blocks_per_second_{kind}: {rate:.0f} blocks/s", flush=True)
        if kind == "slcan" and r.bus_frames:
            # every frame as a full extended one (our 29-bit ids): an upper bound
            bits = r.bus_frames * worst_frame_bits(8, extended=True)
            load = bits / r.seconds / 1_000_000 * 100
            print(f"stream_slcan_bits_per_block: {bits / n:.0f} bits", flush=True)
            print(f"stream_slcan_bus_load_1mbit: {load:.0f} %", flush=True)
    c = connect(port=server.serial)
    with c:
        gen, total = sb.cam_circle((0, 0, 0), revs=1.0)
        r = sb.run(c, sb.CAM_PARAMS, lambda s: sb.cam_circle(s, revs=1.0)[0], total)
    try:
        r.check()
    except Exception as exc:  # noqa: BLE001
        print(f"bench-stream: cam job: {exc}", file=sys.stderr)
        failed = True
    print(f"stream_cam_min_queued_ms: {r.min_queued_s * 1000:.1f} ms", flush=True)
    feed = (r.feed_mm_min or 0.0) / (sb.CAM_FEED * 60 / 1e6) * 100
    print(f"stream_cam_feed_percent: {feed:.1f} %", flush=True)
    c = connect(port=server.serial)
    with c:
        gen, total = sb.cam_circle((0, 0, 0), revs=1.0)
        r = sb.run(c, sb.CAM_PARAMS_CONTINUOUS, lambda s: sb.cam_circle(s, revs=1.0)[0], total)
        try:
            r.check()
        except Exception as exc:  # noqa: BLE001
            print(f"bench-stream: cam job (continuous): {exc}", file=sys.stderr)
            failed = True
        print(f"stream_cam_min_queued_ms_continuous: {r.min_queued_s * 1000:.1f} ms", flush=True)
        feed = (r.feed_mm_min or 0.0) / (sb.CAM_FEED * 60 / 1e6) * 100
        print(f"stream_cam_feed_percent_continuous: {feed:.1f} %", flush=True)
        r = sb.run(c, sb.SHORT_BLOCK_PARAMS_CONTINUOUS, lambda s: sb.short_blocks(s, n), n)
        try:
            r.check()
            rate = r.blocks_per_second
        except Exception as exc:  # noqa: BLE001
            print(f"bench-stream: serial (continuous): {exc}", file=sys.stderr)
            rate, failed = 0.0, True
        print(f"stream_blocks_per_second_serial_continuous: {rate:.0f} blocks/s", flush=True)
sys.exit(1 if failed else 0)
PY
