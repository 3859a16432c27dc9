"""`contour reset`: clear the latched faults (and a latched e-stop).

Says which faults were cleared. A fault whose cause is still present stays
latched: exit code 1 naming it. Nothing latched: says so, exit code 0.
After a reset the drive is disabled: `contour enable` switches it on.
"""

from __future__ import annotations

import json

from contour.link.options import connect_from_args, link_options
from contour.operator import Operator


def run(args) -> int:
    with connect_from_args(args) as client:
        cleared, snap = Operator(client).reset()
    if args.json:
        print(json.dumps({"cleared": cleared, **snap.as_dict()}))
    elif cleared:
        print(f"cleared: {', '.join(cleared)}; state {snap.state}")
    else:
        print(f"no fault latched; state {snap.state}")
    return 0


def register(sub) -> None:
    p = sub.add_parser("reset", help="clear latched faults, saying which", parents=[link_options()])
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)
