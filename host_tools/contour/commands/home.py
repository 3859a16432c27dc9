"""`contour home [--axes X,Y,Z|all]`: reference the axes the way machine tools
do (docs/operating.md, Homing).

Each axis moves toward its home switch at --search-feed until it triggers,
backs off at --latch-feed until it releases, goes on to the next encoder
index (the switch edge with --no-index) and stops; the position there
becomes --home-pos. Waits until every axis is homed and at rest, then prints
each axis's position. A fault before or during homing (e.g. homing: switch
not found within --max-distance): exit code 1 naming it. Ctrl-C or SIGTERM:
controlled stop (homing aborted), exit code 130 / 143.
"""

from __future__ import annotations

import json

from contour.commands import interrupted
from contour.errors import UsageError
from contour.link.client import AXIS_NAMES
from contour.link.options import connect_from_args, link_options
from contour.operator import HomeParams, Operator, feed_to_nm_s, mm_to_nm, parse_axes


def parse_home_pos(text: str) -> tuple:
    """``-21`` (every axis) or ``X=-21,Y=0`` -> nm per axis (0 for axes not named)."""
    pos = [0, 0, 0, 0]
    if "=" not in text:
        nm = mm_to_nm(_float(text, "--home-pos"), "--home-pos")
        return (nm, nm, nm, nm)
    for part in text.split(","):
        name, _, value = part.partition("=")
        axis = parse_axes(name)
        i = axis.bit_length() - 1
        pos[i] = mm_to_nm(_float(value, f"--home-pos {name}"), f"--home-pos {name}")
    return tuple(pos)


def _float(text: str, what: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise UsageError(f"{what} {text!r}: a number of mm") from None


def run(args) -> int:
    search = feed_to_nm_s(args.search_feed)
    latch = feed_to_nm_s(args.latch_feed)
    if latch > search:
        raise UsageError("--latch-feed must not exceed --search-feed")
    dist = mm_to_nm(args.max_distance, "--max-distance")
    if not 0 < dist <= 0xFFFFFFFF:
        raise UsageError("--max-distance must be above 0 and at most 4294 mm")
    params = HomeParams(
        search_nm_s=search,
        latch_nm_s=latch,
        max_distance_nm=dist,
        negative=args.direction == "-",
        index=not args.no_index,
        home_pos_nm=parse_home_pos(args.home_pos),
    )
    axes_text = args.axes.strip().lower()
    with connect_from_args(args) as client:
        op = Operator(client)
        mask = (1 << op.axes) - 1 if axes_text == "all" else parse_axes(args.axes)
        try:
            res = op.home(mask, params)
        except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (Terminated): stopped already
            return interrupted.report(op, exc, "home", "homing stopped", args.json)
    if args.json:
        print(json.dumps(res))
    else:
        for name in res["homed_axes"]:
            print(
                f"{name} homed at {res['position_mm'][name]:.4f} mm "
                f"(frame moved {res['shift_um'][name]:+.2f} um)"
            )
        print(f"in {res['elapsed_s']:.2f} s")
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "home",
        help="reference the axes on their home switches and encoder index",
        description=(
            "Home the axes: toward the switch at --search-feed, back off at --latch-feed "
            "to its edge, on to the next encoder index; that point becomes --home-pos. "
            "Waits until done and prints each axis's position."
        ),
        parents=[link_options()],
    )
    p.add_argument(
        "--axes",
        metavar="X,Y,Z|all",
        default="all",
        help=f"axes to home (default all; names {', '.join(AXIS_NAMES)})",
    )
    p.add_argument(
        "--search-feed", metavar="MM_MIN", type=float, default=600.0, help="default 600 mm/min"
    )
    p.add_argument(
        "--latch-feed", metavar="MM_MIN", type=float, default=60.0, help="default 60 mm/min"
    )
    p.add_argument(
        "--max-distance",
        metavar="MM",
        type=float,
        default=1000.0,
        help="travel allowed to find the switch (and again its edge and index); default 1000",
    )
    p.add_argument(
        "--direction",
        choices=("-", "+"),
        default="-",
        help="side of the home switches (default -: toward negative positions)",
    )
    p.add_argument(
        "--home-pos",
        metavar="MM|X=MM,...",
        default="0",
        help="position at the reference point, every axis or per axis (default 0)",
    )
    p.add_argument(
        "--no-index", action="store_true", help="reference on the switch edge, not the index"
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)
