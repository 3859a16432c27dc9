"""`contour get PARAM` and `contour set PARAM VALUE`: drive parameters in user units.

Names come from the protocol definition (protocol/contour.toml); per-axis
parameters take the axis after a dot (``max_velocity.x``). Values are shown
and accepted in user units (lengths mm, speeds mm/s, accelerations mm/s^2,
gains in their SI unit, enums by name); a unit suffix picks another unit of
the same kind (``600mm/min``, ``2.5um``): see contour/params.py. The range is
checked here and again by the drive. ``--json`` gives, per parameter, the
value in its display unit, the unit, and the raw value in the protocol unit.
"""

from __future__ import annotations

import json

from contour import params as up
from contour import protocol_gen as pg
from contour.errors import UsageError, usage_errors
from contour.link.client import DriveError, parse_param
from contour.link.options import connect_from_args, link_options


def param_names(axes: int, writable_only: bool = False) -> list[str]:
    """Every parameter name (per-axis ones once per axis of the drive)."""
    out = []
    for p in pg.PARAMS:
        if writable_only and p.access != "rw":
            continue
        if p.per_axis:
            out += [f"{p.name}.{'xyza'[i]}" for i in range(axes)]
        else:
            out.append(p.name)
    return out


def _json_entry(p: pg.Param, raw: int) -> dict:
    return {
        "value": up.user_value(p, raw),
        "unit": up.display_unit(p),
        "raw": raw,
        "raw_unit": p.unit,
    }


def run_get(args) -> int:
    if not args.param and not args.all:
        raise UsageError("name a parameter (contour get max_velocity.x) or use --all")
    if args.param:
        with usage_errors():
            parse_param(args.param)  # a clear error before touching the link
    with connect_from_args(args) as client:
        names = param_names(client.identify()["axes"]) if args.all else [args.param]
        values = {}
        errors = {}
        for name in names:
            try:
                values[name] = client.get_param(name)
            except DriveError as exc:
                if not args.all:
                    raise
                errors[name] = str(exc)
    if args.json:
        out = {n: _json_entry(parse_param(n)[0], v) for n, v in values.items()}
        for n, e in errors.items():
            out[n] = {"error": e}
        print(json.dumps(out, indent=2))
    else:
        width = max(len(n) for n in names)
        for name in names:
            if name in values:
                text = up.format_value(parse_param(name)[0], values[name])
                print(f"{name:<{width}} = {text}" if args.all else f"{name} = {text}")
            else:
                print(f"{name}: {errors[name]}")
    return 0


def run_set(args) -> int:
    if args.value is None:  # NAME=VALUE: a negative value with a unit is no option
        if "=" not in args.param:
            raise UsageError("give a value: contour set NAME VALUE (or NAME=VALUE)")
        args.param, args.value = args.param.split("=", 1)
    with usage_errors():
        p, _ = parse_param(args.param)
        if p.access == "ro":
            raise UsageError(f"parameter {p.name} is read-only")
        value = up.parse_value(p, args.value)
    with connect_from_args(args) as client:
        applied = client.set_param(args.param, value)
    print(f"{args.param} = {up.format_value(p, applied)}")
    return 0


def register(sub) -> None:
    g = sub.add_parser(
        "get", help="read a drive parameter (in user units)", parents=[link_options()]
    )
    g.add_argument("param", nargs="?", help="parameter name (e.g. max_velocity.x, cec_mode)")
    g.add_argument("--all", action="store_true", help="read every parameter, with its unit")
    g.add_argument("--json", action="store_true", help="print JSON (value, unit, raw, raw_unit)")
    g.set_defaults(func=run_get)
    s = sub.add_parser(
        "set", help="write a drive parameter (user units, range-checked)", parents=[link_options()]
    )
    s.add_argument("param", help="parameter name, or NAME=VALUE (soft_limit_min.x=-10mm)")
    s.add_argument(
        "value",
        nargs="?",
        help="new value in the parameter's unit, or with a unit suffix (10mm/s, 600mm/min, "
        "2.5um), or an enum name (cec_mode curvature); a negative value with a unit: "
        "NAME=VALUE or after --",
    )
    s.set_defaults(func=run_set)
