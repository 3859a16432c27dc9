"""`contour get PARAM` and `contour set PARAM VALUE`: typed drive parameters.

Names come from the protocol definition (protocol/contour.toml); per-axis
parameters take the axis after a dot (``position.x``). Values are integers in
the parameter's unit; the range is checked here and again by the drive.
"""

from __future__ import annotations

import json

from contour import protocol_gen as pg
from contour.errors import UsageError, usage_errors
from contour.link.client import DriveError, parse_param
from contour.link.options import connect_from_args, link_options


def _names(axes: int) -> list[str]:
    out = []
    for p in pg.PARAMS:
        if p.per_axis:
            out += [f"{p.name}.{'xyza'[i]}" for i in range(axes)]
        else:
            out.append(p.name)
    return out


def run_get(args) -> int:
    if not args.param and not args.all:
        raise UsageError("name a parameter (contour get comm_timeout_ms) or use --all")
    if args.param:
        with usage_errors():
            parse_param(args.param)  # a clear error before touching the link
    with connect_from_args(args) as client:
        names = _names(client.identify()["axes"]) if args.all else [args.param]
        values = {}
        for name in names:
            try:
                values[name] = client.get_param(name)
            except DriveError as exc:
                if not args.all:
                    raise
                values[name] = None
                print(f"{name}: {exc}")
    if args.json:
        print(json.dumps(values, indent=2))
    else:
        for name, v in values.items():
            if v is not None:
                unit = parse_param(name)[0].unit
                print(f"{name} = {v} {unit}".rstrip())
    return 0


def run_set(args) -> int:
    from contour.link.client import parse_value

    with usage_errors():
        p, _ = parse_param(args.param)
        if p.access == "ro":
            raise UsageError(f"parameter {p.name} is read-only")
        value = parse_value(p, args.value)
    with connect_from_args(args) as client:
        applied = client.set_param(args.param, value)
    print(f"{args.param} = {applied} {p.unit}".rstrip())
    return 0


def register(sub) -> None:
    g = sub.add_parser("get", help="read a drive parameter", parents=[link_options()])
    g.add_argument("param", nargs="?", help="parameter name (e.g. comm_timeout_ms, position.x)")
    g.add_argument("--all", action="store_true", help="read every parameter")
    g.add_argument("--json", action="store_true", help="print JSON")
    g.set_defaults(func=run_get)
    s = sub.add_parser(
        "set", help="write a drive parameter (range-checked)", parents=[link_options()]
    )
    s.add_argument("param", help="parameter name")
    s.add_argument("value", help="new value (integer in the parameter's unit)")
    s.set_defaults(func=run_set)
