"""`contour monitor`: stream the drive's telemetry to a CSV file or a
python-can log (.asc, .blf; any extension can.Logger knows).

The drive sends one cycle every ``--period-ms`` (status, progress, path and
per axis pos/ferr, all with the same cycle seq). CSV gets one row per cycle;
a CAN log gets the cyclic frames exactly as they appear on the bus (on a
serial link they are rebuilt with the CAN identifiers of ``--node``), so
protocol/contour.dbc decodes them. Gaps in the cycle sequence are counted
and reported. Ctrl-C ends the recording (telemetry is switched off again).
"""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

from contour import protocol_gen as pg
from contour.errors import UsageError
from contour.link.options import connect_from_args, link_options
from contour.link.telemetry import Assembler

CAN_LOG_SUFFIXES = {".asc", ".blf", ".log", ".trc", ".mf4", ".csv.can"}


def _can_message(m, node: int, ts: float):
    import can

    from contour.link import codec

    msg = pg.MSG_BY_NAME[m.name]
    payload = codec.encode_payload(msg, m.fields)
    return can.Message(
        timestamp=ts,
        arbitration_id=pg.can_id(msg.can_func, node),
        is_extended_id=False,
        data=payload,
    )


def record(client, out: Path, period_ms: int, duration: float, node: int, quiet=False) -> dict:
    axes = client.identify()["axes"]
    asm = Assembler(axes)
    suffix = out.suffix.lower()
    logger = None
    writer = None
    fh = None
    if suffix in CAN_LOG_SUFFIXES and suffix != ".csv":
        import can

        logger = can.Logger(str(out))
    else:
        fh = open(out, "w", newline="")  # noqa: SIM115 - closed in finally
        writer = csv.DictWriter(fh, fieldnames=asm.columns(), extrasaction="ignore")
        writer.writeheader()
    rows = 0
    client.drain_unsolicited()
    client.set_param("telem_period_ms", period_ms)
    end = time.monotonic() + duration if duration > 0 else float("inf")
    last_ka = 0.0
    try:
        while time.monotonic() < end:
            item = client.unsolicited(timeout=0.05)
            now = time.monotonic()
            if now - last_ka > 0.2:  # keep-alive for the drive's watchdog
                client.status()
                last_ka = now
            if item is None:
                continue
            ts, m = item
            if m.name not in pg.MSG_BY_NAME or pg.MSG_BY_NAME[m.name].can_func is None:
                continue
            if logger is not None:
                if m.name != "heartbeat":
                    logger.on_message_received(_can_message(m, node, ts))
                    rows += 1
                asm.add(ts, m)
                continue
            done = asm.add(ts, m)
            if done is not None:
                writer.writerow(done)
                rows += 1
    except KeyboardInterrupt:
        pass
    finally:
        try:
            client.set_param("telem_period_ms", 0)
        finally:
            if writer is not None:
                last = asm.flush()
                if last is not None:
                    writer.writerow(last)
                    rows += 1
                fh.close()
            if logger is not None:
                logger.stop()
    summary = {"cycles": asm.cycles, "gaps": asm.gaps, "rows": rows, "file": str(out)}
    if not quiet:
        print(
            f"monitor: {asm.cycles} cycles, {asm.gaps} missing, {rows} "
            f"{'frames' if logger else 'rows'} written to {out}",
            file=sys.stderr,
        )
    return summary


def run(args) -> int:
    if not 1 <= args.period_ms <= 60000:
        raise UsageError("--period-ms must be 1..60000")
    if args.duration < 0:
        raise UsageError("--duration must be >= 0 (0: until Ctrl-C)")
    out = Path(args.out)
    if out.parent and not out.parent.exists():
        raise UsageError(f"{out.parent}: no such directory")
    with connect_from_args(args) as client:
        s = record(client, out, args.period_ms, args.duration, args.node)
    return 0 if s["gaps"] == 0 else 1


def register(sub) -> None:
    p = sub.add_parser(
        "monitor",
        help="record drive telemetry to CSV or a CAN log (ASC/BLF)",
        parents=[link_options()],
    )
    p.add_argument("--out", required=True, help="output file: .csv, .asc or .blf")
    p.add_argument("--period-ms", type=int, default=10, help="telemetry period (default 10 ms)")
    p.add_argument(
        "--duration", type=float, default=0.0, help="seconds to record (default: until Ctrl-C)"
    )
    p.set_defaults(func=run)
