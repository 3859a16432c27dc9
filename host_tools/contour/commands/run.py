"""`contour run FILE.nc`: stream a G-code job to the drive.

Progress bar over the job's estimated time (the drive's own planner, host
build), live feed and ETA; flow control by the planned time queued in the
drive. "Done" means the last block is done and every axis is within its
in-position window of the program's end point; the measured end position and
the largest following error of the job are reported. A fault or a refused
block names the program line (exit 1). Ctrl-C brings the axes to a
controlled stop before exiting.

Two passes over the file: the first builds and checks every block against
the protocol and the drive's soft and velocity limits (read from the drive)
and prints the report (:mod:`contour.program`); only a program that passes
is streamed, by the second pass. Nothing moves for a program refused
anywhere in it.
"""

from __future__ import annotations

import json
import math
import sys

from contour.errors import Terminated, UsageError, UserError
from contour.link.blocks import DriveLimits, blocks_from_gcode, check_gcode
from contour.link.options import connect_from_args, link_options
from contour.link.stream import Streamer
from contour.progress import Bar


def run(args) -> int:
    if not 0.05 <= args.queue_s <= 60:
        raise UsageError("--queue-s must be 0.05..60 s")
    if args.in_position_um is not None and not 0.001 <= args.in_position_um <= 10000:
        raise UsageError("--in-position-um must be 0.001..10000")
    if args.feed is not None and not (args.feed > 0 and math.isfinite(args.feed)):
        raise UsageError(f"--feed must be a positive number (mm/min), got {args.feed}")
    if not (args.chord_mm > 0 and math.isfinite(args.chord_mm)):
        raise UsageError(f"--chord-mm must be a positive number, got {args.chord_mm}")
    with connect_from_args(args) as client:
        st = client.status()
        start = [p / 1e6 for p in st["pos"][:3]]
        limits = DriveLimits.read(client, axes=client.identify()["axes"])
        checked = check_gcode(
            args.file, start, args.chord_mm, args.feed, limits, tool_table=args.tool_table
        )
        if not checked.blocks:
            raise UserError(f"{args.file}: no motion blocks")
        if not args.json:
            print("\n".join(checked.report.text()), flush=True)
        blocks = blocks_from_gcode(
            args.file, start, args.chord_mm, args.feed, limits, tool_table=args.tool_table
        )
        extra = {"total": checked.blocks, "est_total_s": checked.est_s}
        total = checked.est_s
        bar = Bar(
            total=round(total, 2),
            unit="s",
            desc="job",
            enabled=not args.json and not args.quiet,
            bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s est {postfix}",
        )

        def progress(p) -> None:
            bar.note(
                f"feed {p.feed_mm_min:7.0f} mm/min  ETA {p.eta_s:6.1f} s  blocks {p.done}/{p.total}"
            )
            bar.to(round(p.est_done_s, 2))

        streamer = Streamer(
            client,
            blocks,
            **extra,
            queue_s=args.queue_s,
            on_progress=progress,
            source=args.file,
            in_position_nm=None
            if args.in_position_um is None
            else round(args.in_position_um * 1000),
        )
        try:
            result = streamer.run()
        except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (Terminated)
            bar.close()
            st = client.status()
            what = f"signal {exc.signum}" if isinstance(exc, Terminated) else "Ctrl-C"
            print(
                f"contour run: stopped by {what} at {[p / 1e6 for p in st['pos'][:3]]} mm",
                file=sys.stderr,
            )
            return 128 + exc.signum if isinstance(exc, Terminated) else 130
        finally:
            bar.close()
    result["position_mm"] = [p / 1e6 for p in result.pop("position_nm")]
    result["dwell_s"] = checked.dwell_s
    result["skipped"] = checked.report.as_dicts()
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(
            f"job done: {result['blocks']} blocks in {result['elapsed_s']:.2f} s "
            f"(estimated {result['estimated_s']:.2f} s), axes in position at "
            + ", ".join(f"{v:.4f}" for v in result["position_mm"])
            + f" mm, max following error {result['max_following_error_um']:.1f} um"
        )
    return 0


def register(sub) -> None:
    p = sub.add_parser("run", help="stream a G-code job to the drive", parents=[link_options()])
    p.add_argument("file", help="G-code file (.nc)")
    p.add_argument(
        "--queue-s",
        type=float,
        default=1.0,
        help="planned time to keep queued in the drive, s (default 1)",
    )
    p.add_argument(
        "--chord-mm", type=float, default=0.001, help="arc chord tolerance, mm (default 0.001)"
    )
    p.add_argument(
        "--feed",
        type=float,
        default=None,
        metavar="F",
        help="default feed (mm/min) for feeds the file does not define (F=R0, no F)",
    )
    p.add_argument(
        "--tool-table",
        metavar="FILE",
        help="LinuxCNC tool table for cutter compensation (G41/G42 with D)",
    )
    p.add_argument(
        "--in-position-um",
        type=float,
        default=None,
        help="done when every axis is this close to the end point, um "
        "(default: the drive's in_position_window parameter, else 5)",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument(
        "--quiet", action="store_true", help="no progress bar (none unless stderr is a TTY)"
    )
    p.set_defaults(func=run)
