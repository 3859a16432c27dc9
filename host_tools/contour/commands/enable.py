"""`contour enable` / `contour disable`: switch the drive's axes on or off.

Reports the resulting state. Enabling a drive with a fault latched fails
(exit code 1) naming the faults; `contour reset` clears them.
"""

from __future__ import annotations

import json

from contour.link.options import connect_from_args, link_options
from contour.operator import Operator, parse_axes


def _run(args, on: bool) -> int:
    mask = parse_axes(args.axes) if args.axes else None
    with connect_from_args(args) as client:
        snap = Operator(client).enable(on, mask)
    if args.json:
        print(json.dumps(snap.as_dict()))
    else:
        print(
            f"{'enabled' if on else 'disabled'}: state {snap.state}, "
            f"axes on: {' '.join(snap.enabled) or 'none'}"
        )
    return 0


def register(sub) -> None:
    for name, on, text in (
        ("enable", True, "switch the axes on (refused while a fault is latched)"),
        ("disable", False, "switch the axes off"),
    ):
        p = sub.add_parser(name, help=text, description=text, parents=[link_options()])
        p.add_argument(
            "--axes",
            metavar="X,Y",
            help="the axes to switch (default all; a drive may only switch all together)",
        )
        p.add_argument("--json", action="store_true", help="print the resulting status as JSON")
        p.set_defaults(func=lambda args, on=on: _run(args, on))
