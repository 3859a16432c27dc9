"""`contour monitor`: stream the drive's telemetry to a CSV file or a
python-can log (.asc, .blf, .log, .trc, .db).

The drive sends one cycle every ``--period-ms`` (status, progress, path and
per axis pos/ferr, all with the same cycle seq). CSV gets one row per cycle;
a CAN log gets the cyclic frames exactly as they appear on the bus (on a
serial link they are rebuilt with the CAN identifiers of ``--node``), so
protocol/contour.dbc decodes them. Gaps in the cycle sequence are counted
and reported (exit code 1 when there are any).

Ctrl-C ends the recording. On every way out (Ctrl-C, SIGTERM, a write
error, a link error) the drive's telemetry period is set back to what it
was before. An output extension it does not write is refused before the
drive is touched; a port another process holds is reported as busy.
"""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path

from contour import protocol_gen as pg
from contour.errors import Terminated, UsageError, UserError
from contour.link.options import connect_from_args, link_options
from contour.link.telemetry import Assembler

# python-can's writers (can.Logger) that need nothing beyond python-can;
# .csv is this command's own one-row-per-cycle table.
CAN_LOG_SUFFIXES = (".asc", ".blf", ".log", ".trc", ".db")
SUFFIXES = (".csv", *CAN_LOG_SUFFIXES)


def check_output(out: Path) -> str:
    """The output's kind ("csv" or "can"); UsageError for anything else."""
    suffix = out.suffix.lower()
    if suffix == ".csv":
        return "csv"
    if suffix in CAN_LOG_SUFFIXES:
        return "can"
    raise UsageError(
        f"--out {out}: monitor writes {', '.join(SUFFIXES)} "
        f"(CSV table, or python-can logs), not {suffix or 'a file without extension'}"
    )


def _can_message(m, node: int, ts: float):
    import can

    from contour.link import codec

    msg = pg.MSG_BY_NAME[m.name]
    payload = codec.encode_payload(msg, m.fields)
    return can.Message(
        timestamp=ts,
        arbitration_id=pg.can_id(msg.can_func, node),
        is_extended_id=True,
        data=payload,
    )


class _Output:
    """The CSV table or the python-can log; write errors become one
    UserError naming the file."""

    def __init__(self, out: Path, kind: str, columns: list) -> None:
        self.out = out
        self.logger = None
        self.fh = None
        self.writer = None
        try:
            if kind == "can":
                import can

                self.logger = can.Logger(str(out))
            else:
                self.fh = open(out, "w", newline="")  # noqa: SIM115 - closed in close()
                self.writer = csv.DictWriter(self.fh, fieldnames=columns, extrasaction="ignore")
                self.writer.writeheader()
        except OSError as exc:
            raise UserError(f"{out}: cannot write: {exc.strerror or exc}") from None

    def row(self, row: dict) -> None:
        try:
            self.writer.writerow(row)
        except OSError as exc:
            raise UserError(f"{self.out}: cannot write: {exc.strerror or exc}") from None

    def frame(self, msg) -> None:
        try:
            self.logger.on_message_received(msg)
        except OSError as exc:
            raise UserError(f"{self.out}: cannot write: {exc.strerror or exc}") from None

    def close(self) -> None:
        try:
            if self.fh is not None:
                fh, self.fh = self.fh, None
                fh.close()
            if self.logger is not None:
                logger, self.logger = self.logger, None
                logger.stop()
        except OSError as exc:
            raise UserError(f"{self.out}: cannot write: {exc.strerror or exc}") from None


def _first_identify(client, where: str) -> dict:
    """identify, with a clear word when another process answers on the port."""
    from contour.link import codec

    try:
        return client.identify()
    except codec.ProtocolError as exc:
        raise UserError(
            f"{where}: the drive's replies go to someone else ({exc}): is another "
            "process using the port?"
        ) from None


def record(
    client,
    out: Path,
    period_ms: int,
    duration: float,
    node: int,
    quiet: bool = False,
    where: str = "",
) -> dict:
    kind = check_output(out)
    axes = _first_identify(client, where or str(out))["axes"]
    asm = Assembler(axes)
    sink = _Output(out, kind, asm.columns())
    rows = 0
    stopped = None
    previous = None
    try:
        previous = client.get_param("telem_period_ms")
        client.drain_unsolicited()
        client.set_param("telem_period_ms", period_ms)
        end = time.monotonic() + duration if duration > 0 else float("inf")
        last_ka = 0.0
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
            if kind == "can":
                if m.name != "heartbeat":
                    sink.frame(_can_message(m, node, ts))
                    rows += 1
                asm.add(ts, m)
                continue
            done = asm.add(ts, m)
            if done is not None:
                sink.row(done)
                rows += 1
        if kind == "csv":
            last = asm.flush()
            if last is not None:
                sink.row(last)
                rows += 1
    except Terminated as exc:
        stopped = exc  # after the clean-up below: exit code 128 + signal
    except KeyboardInterrupt:
        pass  # Ctrl-C: the normal end of an open-ended recording
    finally:
        try:
            if previous is not None:
                _restore(client, previous)
        finally:
            sink.close()
    summary = {"cycles": asm.cycles, "gaps": asm.gaps, "rows": rows, "file": str(out)}
    if not quiet:
        print(
            f"monitor: {asm.cycles} cycles, {asm.gaps} missing, {rows} "
            f"{'frames' if kind == 'can' else 'rows'} written to {out}",
            file=sys.stderr,
        )
    if stopped is not None:
        raise stopped
    return summary


def _restore(client, previous: int) -> None:
    """Set the telemetry period back; a second Ctrl-C or SIGTERM meanwhile
    does not stop it (the drive must not be left streaming)."""
    for _ in range(3):
        try:
            client.set_param("telem_period_ms", previous)
            return
        except KeyboardInterrupt:
            continue


def run(args) -> int:
    if not 1 <= args.period_ms <= 60000:
        raise UsageError("--period-ms must be 1..60000")
    if args.duration < 0:
        raise UsageError("--duration must be >= 0 (0: until Ctrl-C)")
    out = Path(args.out)
    check_output(out)
    if out.parent and not out.parent.exists():
        raise UsageError(f"{out.parent}: no such directory")
    with connect_from_args(args) as client:
        where = args.port or "the CAN bus"
        s = record(
            client, out, args.period_ms, args.duration, args.node, quiet=args.json, where=where
        )
    if args.json:
        print(json.dumps(s, indent=2))
    return 0 if s["gaps"] == 0 else 1


def register(sub) -> None:
    p = sub.add_parser(
        "monitor",
        help="record drive telemetry to CSV or a CAN log (ASC/BLF)",
        parents=[link_options()],
    )
    p.add_argument(
        "--out", required=True, help=f"output file: {', '.join(SUFFIXES)} (by its extension)"
    )
    p.add_argument("--period-ms", type=int, default=10, help="telemetry period (default 10 ms)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument(
        "--duration", type=float, default=0.0, help="seconds to record (default: until Ctrl-C)"
    )
    p.set_defaults(func=run)
