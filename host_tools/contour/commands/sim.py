"""`contour sim ...`: the hardware-in-the-loop simulator.

contour sim circle --radius MM --feed MM_PER_MIN [--direction cw|ccw]
    [--cutting-force F_AT,F_W] [--spring N_PER_MM]
    --controller pid|cec-tangent|cec-curvature|cec-exact
    [--feedforward none|velocity|full] [--machine FILE.toml] [--tick-hz N]
    [--encoder-model fast|edges] [--json] [--plot PNG] [--trace CSV]
contour sim run FILE.nc [--machine ...] [--controller ...] [--json]
contour sim demo --out DIR        (what `make run` runs)
contour sim serve                 (the simulated drive on pseudo-terminals)
"""

from __future__ import annotations

import argparse
import json
import sys

from contour.errors import UserError, usage_errors


def _common(p: argparse.ArgumentParser, controller_required: bool = False) -> None:
    from contour.sim import machine
    from contour.sim.circle import CONTROLLERS, FEEDFORWARD

    p.add_argument(
        "--controller",
        choices=CONTROLLERS,
        required=controller_required,
        default=None if controller_required else "cec-exact",
        help="axis PIDs alone, or with the contour-error controller and its estimate",
    )
    p.add_argument(
        "--feedforward",
        choices=FEEDFORWARD,
        default="none",
        help="feed-forward of the axis loops (default none: the thesis's set-up)",
    )
    p.add_argument(
        "--machine",
        metavar="FILE.toml",
        default=None,
        help="machine description (default hil_sim/machines/default.toml; a bare name "
        "looks in hil_sim/machines/)",
    )
    p.add_argument("--tick-hz", type=float, default=None, metavar="N", help="control tick rate, Hz")
    machine.add_encoder_model_argument(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")


def register(sub) -> None:
    p = sub.add_parser("sim", help="hardware-in-the-loop simulator: circle tests, jobs, demo")
    ss = p.add_subparsers(dest="sim_command", metavar="SIM_COMMAND")
    p.set_defaults(func=lambda a: (p.print_help(), 2)[1])

    c = ss.add_parser("circle", help="circle test scored as in Lacerda (1998)")
    c.add_argument("--radius", type=float, required=True, metavar="MM")
    c.add_argument("--feed", type=float, required=True, metavar="MM_PER_MIN")
    c.add_argument("--direction", choices=("cw", "ccw"), default="ccw")
    _common(c, controller_required=True)
    c.add_argument(
        "--allow-limited",
        action="store_true",
        help="run a circle the planner limits cannot run at the stated feed (flagged in "
        "limited_by) instead of refusing it",
    )
    c.add_argument(
        "--chords",
        type=int,
        default=0,
        metavar="N",
        help="run the circle as N G1 chords (as CAM writes it) instead of arc blocks",
    )
    c.add_argument(
        "--cutting-force",
        metavar="F_AT,F_W",
        help="the thesis's cutting/friction disturbance (eq. 4.3), N: F_at sgn(v) per axis "
        "and the cutting force F_w at phi 45 deg (replaces the machine's [disturbance])",
    )
    c.add_argument(
        "--spring",
        type=float,
        default=None,
        metavar="N_PER_MM",
        help="a spring on the X and on the Y table, relaxed at the machine origin (the "
        "lead-in's start; replaces the machine's spring_x, spring_y)",
    )
    c.add_argument(
        "--plot",
        metavar="PNG",
        help="ballbar plot (ISO 230-4): both directions overlaid (runs the other one too)",
    )
    c.add_argument(
        "--scale",
        type=float,
        default=None,
        metavar="UM_PER_DIV",
        help="ballbar plot scale, um per division (default: 1-2-5 ladder from the largest error)",
    )
    c.add_argument("--trace", metavar="CSV", help="scored revolution: t, x, y, contour error")
    c.set_defaults(func=cmd_circle)

    r = ss.add_parser("run", help="run a G-code job on the simulated drive")
    r.add_argument("file", metavar="FILE.nc")
    _common(r)
    r.add_argument("--feed", type=float, default=None, help="default feed, mm/min")
    r.add_argument(
        "--tool-table",
        metavar="FILE",
        help="LinuxCNC tool table for cutter compensation (G41/G42 with D)",
    )
    r.set_defaults(func=cmd_run)

    d = ss.add_parser("demo", help="the thesis's nine circle cases beside its numbers")
    d.add_argument("--out", default="out/demo", metavar="DIR", help="folder for plots and tables")
    d.add_argument("--quick", action="store_true", help="one case per table (smoke test)")
    d.set_defaults(func=cmd_demo)

    s = ss.add_parser("serve", help="the simulated drive in real time on pseudo-terminals")
    try:
        from contour.sim import serve as simserve

        simserve.add_arguments(s)
    except ImportError:
        pass
    s.set_defaults(func=cmd_serve)


def disturbed_machine(args):
    """The machine with --cutting-force / --spring in its [disturbance]
    (None when neither is given: run_circle loads --machine itself)."""
    from contour.sim import machine

    if args.cutting_force is None and args.spring is None:
        return None
    m = machine.load(args.machine)
    d = dict(m.disturbance)
    if args.cutting_force is not None:
        try:
            f_at, f_w = (float(v) for v in args.cutting_force.split(","))
        except ValueError:
            msg = f"--cutting-force wants F_AT,F_W in N, got {args.cutting_force!r}"
            raise UserError(msg) from None
        for k in ("f_w", "k_s", "feed_per_tooth_mm", "depth_mm"):
            d.pop(k, None)
        d.update(f_at=f_at, f_w=f_w)
    if args.spring is not None:
        d.update(spring_x=args.spring, spring_y=args.spring)
    # the same checks as a [disturbance] section in the file
    m.disturbance = machine.from_dict({"disturbance": d}, "command line").disturbance
    return m


def cmd_circle(args) -> int:
    from contour.sim import circle, plots

    with usage_errors():  # --radius, --feed ... out of the test's range
        circle.check_args(args.radius, args.feed, args.direction, args.controller, args.feedforward)
        mach = disturbed_machine(args)
    run = circle.run_circle(
        args.radius,
        args.feed,
        direction=args.direction,
        controller=args.controller,
        feedforward=args.feedforward,
        machine_file=args.machine,
        tick_hz=args.tick_hz,
        encoder_model=args.encoder_model,
        allow_limited=args.allow_limited,
        chords=args.chords,
        mach=mach,
    )
    res = run.result
    if args.trace:
        plots.write_trace(args.trace, run.trace)
    if args.plot:  # both directions overlaid, as a ballbar report shows them
        other = circle.run_circle(
            args.radius,
            args.feed,
            direction="cw" if args.direction == "ccw" else "ccw",
            controller=args.controller,
            feedforward=args.feedforward,
            machine_file=args.machine,
            tick_hz=args.tick_hz,
            allow_limited=args.allow_limited,
            chords=args.chords,
            mach=mach,
        )
        plots.ballbar(args.plot, [(run.trace, res), (other.trace, other.result)], args.scale)
    if args.json:
        print(json.dumps(res.as_dict()))
    else:
        print(
            f"circle R {res.radius_mm:g} mm at {res.feed_mm_min:g} mm/min {res.direction}, "
            f"{res.controller}, feed-forward {res.feedforward}, {res.machine} at "
            f"{res.tick_hz:g} Hz"
        )
        print(f"  iae                 {res.iae_mm_s:.6f} mm s")
        print(f"  max contour error   {res.max_contour_error_mm * 1e3:.3f} um")
        print(f"  circular deviation  {res.circular_deviation_mm * 1e3:.3f} um (ISO 230-4)")
        print(f"  mean radial error   {res.mean_radial_error_mm * 1e3:+.3f} um")
        print(
            f"  feed (measured)     min {res.min_feed_mm_min:.0f}, mean "
            f"{res.mean_feed_mm_min:.0f} mm/min"
        )
        if res.limited_by:
            print(f"  NOT AT STATED FEED  {res.limited_by}")
        if res.faults:
            print(f"  faults              {', '.join(res.faults)}")
    return 1 if res.faults else 0


def cmd_run(args) -> int:
    from contour.program import report_text
    from contour.sim import job

    rep = job.run_job(
        args.file,
        controller=args.controller,
        feedforward=args.feedforward,
        machine_file=args.machine,
        tick_hz=args.tick_hz,
        default_feed=args.feed,
        encoder_model=args.encoder_model,
        tool_table=args.tool_table,
    )
    if args.json:
        print(json.dumps(rep))
    else:
        print(f"{args.file}: {rep['blocks']} blocks, executed in {rep['executed_s']:.4f} s")
        print(
            f"  contour error: max {rep['max_contour_error_um']:.3f} um, "
            f"rms {rep['rms_contour_error_um']:.3f} um"
        )
        print(f"  following error: max {rep['max_following_error_um']:.3f} um")
        print(f"  faults: {', '.join(rep['faults']) or 'none'}")
        print("\n".join(report_text(rep["skipped"])))
    return 1 if rep["faults"] else 0


def cmd_demo(args) -> int:
    from contour.sim import demo

    return demo.main(args.out, quick=args.quick)


def cmd_serve(args) -> int:
    try:
        from contour.sim import serve as simserve
    except ImportError as exc:
        raise UserError(
            f"`contour sim serve` is not available in this build (contour.sim.serve: {exc})"
        ) from exc
    return int(simserve.main(args) or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(2)
