"""`contour estop`: emergency stop now (fastest stop, then the axes off).

Latched until `contour reset`; reports the latched state and where the axes
came to rest.
"""

from __future__ import annotations

import json

from contour.link.options import connect_from_args, link_options
from contour.operator import Operator


def run(args) -> int:
    with connect_from_args(args) as client:
        snap = Operator(client).estop()
    if args.json:
        print(json.dumps(snap.as_dict()))
    else:
        print(
            f"emergency stop: state {snap.state}, faults {', '.join(snap.faults) or 'none'}, "
            f"at {snap.position_text()} mm; `contour reset` clears it"
        )
    return 0


def register(sub) -> None:
    p = sub.add_parser("estop", help="emergency stop now (latched)", parents=[link_options()])
    p.add_argument("--json", action="store_true", help="print the resulting status as JSON")
    p.set_defaults(func=run)
