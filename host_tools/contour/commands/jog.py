"""`contour jog AXIS DIST_MM --feed MM_MIN` (incremental) and
`contour jog AXIS --to POS_MM --feed MM_MIN` (absolute, from the measured
position).

Axis, distance and feed are checked before anything moves (exit code 2).
Waits until the jog is done and the axis is at rest, then prints the
measured end position. A fault before or during the jog: exit code 1 naming
it. Ctrl-C or SIGTERM: controlled stop, then exit code 130 / 143.
"""

from __future__ import annotations

import json

from contour.commands import interrupted
from contour.errors import UsageError
from contour.link.options import connect_from_args, link_options
from contour.operator import Operator, feed_to_nm_s, mm_to_nm, parse_axis


def run(args) -> int:
    axis = parse_axis(args.axis)
    if args.distance is not None and args.to is not None:
        raise UsageError("give a distance or --to POS_MM, not both")
    if args.distance is None and args.to is None:
        raise UsageError("give a distance (contour jog x 5 --feed 600) or --to POS_MM")
    dist = mm_to_nm(args.distance, "distance") if args.distance is not None else None
    if dist == 0:
        raise UsageError("distance must not be 0")
    to = mm_to_nm(args.to, "--to") if args.to is not None else None
    feed = feed_to_nm_s(args.feed)
    with connect_from_args(args) as client:
        op = Operator(client)
        try:
            res = op.jog(axis, feed, distance_nm=dist, to_nm=to)
        except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (Terminated): stopped already
            return interrupted.report(op, exc, "jog", "stopped", args.json)
    if args.json:
        print(json.dumps(res))
    else:
        print(
            f"{res['axis']} at {res['end_mm']:.4f} mm (target {res['target_mm']:.4f}, "
            f"error {res['error_um']:+.2f} um) in {res['elapsed_s']:.2f} s"
        )
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "jog",
        help="move one axis by a distance or to a position",
        description="Move one axis by DIST_MM, or to --to POS_MM, at --feed; waits for rest.",
        parents=[link_options()],
    )
    p.add_argument("axis", metavar="AXIS", help="x, y, z or a")
    p.add_argument(
        "distance", metavar="DIST_MM", type=float, nargs="?", help="distance, mm (incremental)"
    )
    p.add_argument("--to", metavar="POS_MM", type=float, help="end position, mm (absolute)")
    p.add_argument("--feed", metavar="MM_MIN", type=float, required=True, help="feed, mm/min")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)
