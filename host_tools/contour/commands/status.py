"""`contour status`: the drive's state, faults, position per axis (mm) and
queue, once or with `--watch` until Ctrl-C.

`--watch` redraws one line in place on a terminal and prints one line per
sample otherwise; with `--json` one object (per sample with `--watch`, one
per line). Polling is the drive's communication keep-alive, as any request.
"""

from __future__ import annotations

import json
import shutil
import sys
from time import monotonic, sleep

from contour.errors import Terminated, UsageError
from contour.link.options import connect_from_args, link_options
from contour.operator import Operator
from contour.progress import is_terminal


def _watch(op: Operator, args) -> int:
    tty = is_terminal(sys.stdout) and not args.json
    t0 = monotonic()
    n = 0
    try:
        while args.count == 0 or n < args.count:
            snap = op.snapshot()
            t = monotonic() - t0
            if args.json:
                print(json.dumps({"t_s": round(t, 3), **snap.as_dict()}), flush=True)
            elif tty:
                width = shutil.get_terminal_size().columns - 1  # a wrapped line is not redrawn
                sys.stdout.write(f"\r\033[K{t:7.1f} s  {snap.line()}"[: width + 4])
                sys.stdout.flush()
            else:
                print(f"{t:7.1f} s  {snap.line()}", flush=True)
            n += 1
            if args.count == 0 or n < args.count:
                sleep(max(0.0, t0 + n * args.period - monotonic()))
    except Terminated:
        if tty:
            print()
        raise
    except KeyboardInterrupt:
        pass  # Ctrl-C: the normal end of watching
    if tty:
        print()
    return 0


def run(args) -> int:
    if not 0.02 <= args.period <= 3600:
        raise UsageError("--period must be 0.02..3600 s")
    if args.count < 0:
        raise UsageError("--count must be >= 0 (0: until Ctrl-C)")
    with connect_from_args(args) as client:
        op = Operator(client)
        if args.watch:
            return _watch(op, args)
        snap = op.snapshot()
    if args.json:
        print(json.dumps(snap.as_dict()))
    else:
        print(snap.text())
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "status", help="state, faults, position and queue of the drive", parents=[link_options()]
    )
    p.add_argument("--watch", action="store_true", help="refresh until Ctrl-C")
    p.add_argument(
        "--period", type=float, default=0.5, metavar="S", help="--watch period, s (default 0.5)"
    )
    p.add_argument(
        "--count",
        type=int,
        default=0,
        metavar="N",
        help="--watch: stop after N samples (default 0: until Ctrl-C)",
    )
    p.add_argument("--json", action="store_true", help="JSON: one object (per line with --watch)")
    p.set_defaults(func=run)
