"""`contour stop`: controlled stop (decelerate on the path, flush the queue,
stay enabled); waits until the axes are at rest and prints where."""

from __future__ import annotations

import json

from contour.errors import UsageError
from contour.link.options import connect_from_args, link_options
from contour.operator import Operator


def run(args) -> int:
    if not 0 < args.wait_s <= 600:
        raise UsageError("--wait-s must be in (0, 600] s")
    with connect_from_args(args) as client:
        snap = Operator(client).stop(args.wait_s)
    if args.json:
        print(json.dumps(snap.as_dict()))
    else:
        print(f"stopped: state {snap.state}, at {snap.position_text()} mm")
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "stop", help="controlled stop, wait for the axes to rest", parents=[link_options()]
    )
    p.add_argument(
        "--wait-s", type=float, default=10.0, help="longest wait for rest, s (default 10)"
    )
    p.add_argument("--json", action="store_true", help="print the resulting status as JSON")
    p.set_defaults(func=run)
