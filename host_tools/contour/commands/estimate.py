"""`contour estimate`: how long a G-code job takes on a machine profile."""

from __future__ import annotations

import json
import math

from contour.errors import UsageError
from contour.estimation import DEFAULT_MODEL, MODELS, estimate_file, parse_options
from contour.estimation import profile as profiles


def register(sub) -> None:
    p = sub.add_parser(
        "estimate",
        help="estimate the run time of a G-code file",
        description=(
            "Estimate the run time of a G-code file on the machine a profile describes. "
            "Models: planner (the drive's own planner, default), camargo2017 (empirical, "
            "HERMLE/iTNC530), mrt (feed with a minimum block time), feed (distance/feed, "
            "what CAM systems print)."
        ),
    )
    p.add_argument("file", help="G-code file")
    p.add_argument("--profile", required=True, help="machine profile (TOML)")
    p.add_argument("--model", default=DEFAULT_MODEL, choices=list(MODELS), help="time model")
    p.add_argument(
        "--feed",
        type=float,
        metavar="F",
        help="default feed (mm/min) for feeds the file does not define (F=R0, no F)",
    )
    p.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="model option (camargo2017: see docs/estimation.md); repeatable",
    )
    p.add_argument(
        "--tool-table",
        metavar="FILE",
        help="LinuxCNC tool table for cutter compensation (G41/G42 with D)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--per-block", metavar="CSV", help="write the time of every segment to CSV")
    p.set_defaults(func=run)


def _fmt_s(t) -> str:
    if t is None:
        return "n/a"
    if t >= 3600:
        return f"{t:.1f} s ({int(t // 3600)} h {int(t % 3600 // 60)} min {t % 60:.0f} s)"
    if t >= 60:
        return f"{t:.2f} s ({int(t // 60)} min {t % 60:.1f} s)"
    return f"{t:.3f} s" if t >= 0.01 or t == 0 else f"{t * 1000:.3f} ms"


def run(args) -> int:
    if args.feed is not None and not (args.feed > 0 and math.isfinite(args.feed)):
        raise UsageError(f"--feed must be a positive number (mm/min), got {args.feed}")
    profile = profiles.load(args.profile)
    options = parse_options(args.model, args.option)
    summary, report = estimate_file(
        args.file,
        profile,
        args.model,
        options,
        default_feed=args.feed,
        per_block_csv=args.per_block,
        tool_table=args.tool_table,
    )
    skipped = report.as_dicts()
    if args.json:
        out = {
            "file": str(args.file),
            "profile": str(args.profile),
            **summary,
            "lines": report.lines_read,
            "program_blocks": summary["blocks"],
            "skipped": skipped,
        }
        print(json.dumps(out, allow_nan=False, default=float))
        return 0
    print(
        f"file:        {args.file} ({report.lines_read} lines, {summary['blocks']} motion blocks)"
    )
    print(f"profile:     {args.profile}" + (f" ({profile.name})" if profile.name else ""))
    print(f"model:       {summary['model']}")
    print(f"total time:  {_fmt_s(summary['total_s'])}")
    print(
        f"  acceleration {_fmt_s(summary['accel_s'])}, cruise {_fmt_s(summary['cruise_s'])}, "
        f"deceleration {_fmt_s(summary['decel_s'])}"
    )
    print(f"  at the minimum block time {_fmt_s(summary['min_block_time_s'])}")
    print(f"  rapids {_fmt_s(summary['rapid_s'])}, dwells {_fmt_s(summary['dwell_s'])}")
    print(f"blocks:      {summary['blocks']} ({summary['segments']} segments after arcs)")
    print(f"length:      {summary['length_mm']:.3f} mm ({summary['feed_length_mm']:.3f} at feed)")
    print(
        f"feed:        mean {summary['mean_feed_mm_min']:.0f} mm/min, "
        f"minimum {summary['min_feed_mm_min']:.0f} mm/min"
    )
    opts = {k: v for k, v in summary["options"].items()}
    if opts:
        print("options:     " + ", ".join(f"{k}={v}" for k, v in opts.items()))
    print("\n".join(report.text()))
    return 0
