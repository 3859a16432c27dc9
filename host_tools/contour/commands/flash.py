"""`contour flash IMAGE`: update a drive's firmware so that the worst case is "try again".

The image file is checked first (refused here, before any link is opened),
then every option; the procedure itself is the boot client,
contour.link.boot (docs/bootloader.md). Also `contour image build|info`
(contour.image).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

from contour import image as img
from contour.errors import UsageError
from contour.link.boot import BootClient, Link, TransportLink, flash
from contour.link.options import (
    check_timeout,
    link_options,
    target_from_args,
    transport_from_args,
)


def open_link(args) -> Link:
    if args.sim_flash is not None:
        from contour.sim.bootsim import SimDriveLink

        return SimDriveLink(args.sim_flash)
    return TransportLink(transport_from_args(args))


def cmd_flash(args) -> int:
    image = img.load(args.image)  # refused here, before any link is opened
    if not 1 <= args.attempts <= 100:
        raise UsageError(f"--attempts must be 1..100, got {args.attempts}")
    check_timeout(args)
    if args.sim_flash is None:
        target_from_args(args)  # every link option checked before the image is sent
    link = open_link(args)
    client = BootClient(link, timeout=args.timeout)
    try:
        result = flash(
            client,
            image,
            verify_only=args.verify_only,
            attempts=args.attempts,
            progress=not args.no_progress and not args.json,
            log=(lambda s: None) if args.json else _log,
        )
    finally:
        close = getattr(link, "close", None)
        if close is not None:
            close()
    if args.json:
        stats = result.pop("stats", None)
        if stats is not None:
            result["link"] = dataclasses.asdict(stats)
        print(json.dumps(result, indent=2))
    return 0


def _log(text: str) -> None:
    print(text, file=sys.stderr)


def register(sub) -> None:
    p = sub.add_parser(
        "flash",
        help="flash a firmware image over serial or CAN (never bricks)",
        parents=[link_options()],
    )
    p.add_argument("image", help="image file built by `contour image build` (or make firmware)")
    p.add_argument("--sim-flash", help=argparse.SUPPRESS, default=None)  # tests: in-process
    p.add_argument("--verify-only", action="store_true", help="compare, do not write")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--attempts", type=int, default=3, help="whole-session attempts (default 3)")
    p.add_argument(
        "--no-progress", action="store_true", help="no progress bar (none unless stderr is a TTY)"
    )
    p.set_defaults(func=cmd_flash)

    i = sub.add_parser("image", help="build or inspect firmware images")
    img.add_parsers(i.add_subparsers(dest="image_cmd", required=True))
