"""`contour tune`: identify an axis from an excitation experiment and
compute its gains (issue 23; contour.commission).

Two sources of the experiment, one identification and tuning: a drive over
the link (`--port` / CAN options: the drive's own PRBS experiment,
drive_experiment.py; `--apply` writes the gains as drive parameters, saves
them to flash and runs the verification job before and after), or the C
simulator's drive configured with a machine file (`--sim MACHINE`: a
multisine through sim_inject, experiment.py).
"""

from __future__ import annotations

import json
import sys

from contour.commission import drive_experiment, experiment, identify, tune
from contour.errors import UsageError, UserError
from contour.link.options import connect_from_args, link_options
from contour.sim import machine as machines

AXES = ("x", "y", "z")


def register(sub) -> None:
    p = sub.add_parser(
        "tune",
        parents=[link_options()],
        help="identify an axis and compute its gains",
        description=(
            "Excite the axis at rest (multisine on the command, constant-velocity legs), fit "
            "the two-inertia or rigid-body model, compute PID and feed-forward gains for a "
            "sensitivity-peak target, check the discretised closed loop, and compare the "
            "following error of a verification move before and after. On a drive (--port or "
            "CAN options: its own PRBS experiment within the limits given; --apply writes and "
            "saves the gains) or on the simulated drive of a machine file (--sim)."
        ),
    )
    p.add_argument("--axis", required=True, help="X, Y, Z or all")
    p.add_argument("--sim", metavar="MACHINE", help="simulated machine (name or TOML file)")
    p.add_argument(
        "--apply", action="store_true", help="write the gains to the drive and save them (--port)"
    )
    p.add_argument(
        "--d-tau", type=float, default=1e-3, help="the drive's derivative filter, s (--port)"
    )
    p.add_argument("--windows", type=int, default=16, help="PRBS periods recorded (--port)")
    p.add_argument("--json", action="store_true", help="JSON on stdout")
    p.add_argument("--method", default="robust", choices=("robust", "zn"))
    p.add_argument("--ms-target", type=float, default=1.6, help="sensitivity peak (1.1 .. 3)")
    p.add_argument(
        "--amplitude",
        type=float,
        default=None,
        help="excitation rms, V (default 3 for --sim's multisine, 6 for the drive's PRBS: "
        "at 3 V Coulomb friction biased the low-frequency gain by 8 %%)",
    )
    p.add_argument("--travel-mm", type=float, default=10.0, help="travel either side, mm")
    p.add_argument("--command-v", type=float, default=20.0, help="command limit, V")
    p.add_argument("--velocity-mm-s", type=float, default=200.0, help="velocity limit, mm/s")
    p.set_defaults(func=run)


def _axes(arg: str, have) -> list[str]:
    a = arg.lower()
    if a == "all":
        return [x for x in AXES if x in have]
    if a not in AXES:
        raise UsageError(f"--axis {arg!r}: X, Y, Z or all")
    if a not in have:
        raise UsageError(f"--axis {arg}: the machine has no axis {a.upper()}")
    return [a]


def _check_args(args) -> None:
    if args.amplitude is None:
        args.amplitude = 3.0 if args.sim else 6.0
    if not 1.1 <= args.ms_target <= 3.0:
        raise UsageError(f"--ms-target {args.ms_target}: 1.1 .. 3")
    for name in ("amplitude", "travel_mm", "command_v", "velocity_mm_s", "d_tau"):
        v = getattr(args, name)
        if not v > 0:
            raise UsageError(f"--{name.replace('_', '-')} {v}: must be > 0")
    if not 2 <= args.windows <= 200:
        raise UsageError(f"--windows {args.windows}: 2 .. 200")
    if args.sim and (args.port or getattr(args, "can", None) or getattr(args, "interface", None)):
        raise UsageError("--sim MACHINE or a drive (--port, CAN), not both")
    if args.apply and args.sim:
        raise UsageError("--apply writes to a drive: with --port (or CAN), not --sim")


def _limits(args) -> experiment.Limits:
    return experiment.Limits(
        travel_m=args.travel_mm * 1e-3,
        command_v=args.command_v,
        velocity_m_s=args.velocity_mm_s * 1e-3,
    )


def _result(ident, t, stops, before: float, after: float | None) -> dict:
    d = ident.as_dict()
    td = t.as_dict()
    return {
        "resonance_hz": d["resonance_hz"],
        "resonance_ci95_hz": d["resonance_ci95_hz"],
        "antiresonance_hz": d["antiresonance_hz"],
        "model": d["model"],
        "model_reason": d["reason"],
        "friction_v": d["friction_v"],
        "phase_margin_deg": td["phase_margin_deg"],
        "gain_margin_db": td["gain_margin_db"],
        "sensitivity_peak": td["sensitivity_peak"],
        "stable": td["stable"],
        "method": td["method"],
        "gains": {p: td["gains"][k] for p, k in drive_experiment.GAIN_PARAMS.items()},
        "identified": {"params": d["params"], "ci95": d["ci95"], "rms_log": d["rms_log"]},
        "excitation_stops": stops,
        "verify": {
            "max_following_error_um_before": round(before * 1e6, 2),
            "max_following_error_um_after": None if after is None else round(after * 1e6, 2),
        },
    }


def _identify_and_tune(ax: str, rec, tick_hz: float, args, d_tau: float):
    try:
        ident = identify.identify(rec)
        return ident, tune.tune(ident, tick_hz, args.method, args.ms_target, d_tau)
    except (identify.IdentifyError, tune.TuneError) as e:
        raise UserError(f"axis {ax.upper()}: {e}") from e


def run_sim(args) -> dict:
    m = machines.load(args.sim)
    axes = _axes(args.axis, m.axis)
    limits = _limits(args)
    plan = experiment.Plan(tick_hz=m.tick_hz, amplitude_v=args.amplitude)
    out = {"machine": m.name, "tick_hz": m.tick_hz, "axes": {}}
    for ax in axes:
        try:
            rec, stops = experiment.simulate_bounded(m, ax, plan, limits)
        except experiment.ExperimentAborted as e:
            raise UserError(f"axis {ax.upper()}: {e}") from e
        ident, t = _identify_and_tune(ax, rec, m.tick_hz, args, m.gains[ax].get("d_tau", 1e-3))
        try:
            before = experiment.following_error(m, ax)
            after = experiment.following_error(m, ax, t.gains)
        except experiment.ExperimentAborted as e:
            raise UserError(f"axis {ax.upper()}: {e}") from e
        out["axes"][ax.upper()] = _result(ident, t, stops, before, after)
    return out


def run_port(args) -> dict:
    limits = _limits(args)
    with connect_from_args(args) as client:
        info = client.identify()
        have = AXES[: info["axes"]]
        axes = _axes(args.axis, have)
        out = {"drive": {"tick_hz": info["tick_hz"], "axes": info["axes"]}, "axes": {}}
        plan = drive_experiment.PrbsPlan(
            tick_hz=float(info["tick_hz"]), amplitude_v=args.amplitude, windows=args.windows
        )
        for ax in axes:
            i = AXES.index(ax)
            try:
                rec, stops = drive_experiment.run_bounded(client, i, plan, limits)
            except experiment.ExperimentAborted as e:
                raise UserError(f"axis {ax.upper()}: {e}") from e
            ident, t = _identify_and_tune(ax, rec, plan.tick_hz, args, args.d_tau)
            before = after = None
            r = None
            if args.apply:
                before = drive_experiment.verify(client, i)
                r = {"gains_before": drive_experiment.read_gains(client, i)}
                r["gains_written"] = drive_experiment.apply_gains(client, i, t.gains)
                after = drive_experiment.verify(client, i)
            res = _result(
                ident,
                t,
                stops,
                0.0 if before is None else before["max_following_error_um"] * 1e-6,
                None if after is None else after["max_following_error_um"] * 1e-6,
            )
            if before is None:
                res["verify"] = None
            else:
                res["applied"] = r
            out["axes"][ax.upper()] = res
    return out


def run(args) -> int:
    _check_args(args)
    if args.sim:
        out = run_sim(args)
    elif args.port or getattr(args, "interface", None) or getattr(args, "can", None):
        out = run_port(args)
    else:
        raise UsageError("give the drive (--port or CAN options) or --sim MACHINE")
    if args.json:
        json.dump(out, sys.stdout, indent=1)
        sys.stdout.write("\n")
        return 0
    for ax, r in out["axes"].items():
        res = "-" if r["resonance_hz"] is None else f"{r['resonance_hz']:.1f} Hz"
        print(f"axis {ax}: {r['model']} model, resonance {res}", end="")
        if r["resonance_ci95_hz"] is not None:
            print(f" +-{r['resonance_ci95_hz']:.1f}, anti-resonance {r['antiresonance_hz']:.1f} Hz")
        else:
            print(f" ({r['model_reason']})")
        if r["friction_v"] is not None:
            print(f"  friction {r['friction_v']:.4f} V")
        else:
            print("  friction not measured (the drive's experiment has no constant-velocity legs)")
        print(
            f"  {r['method']}: Ms {r['sensitivity_peak']}, phase margin "
            f"{r['phase_margin_deg']} deg, gain margin {r['gain_margin_db']} dB"
        )
        print("  " + ", ".join(f"{k} {v:g}" for k, v in r["gains"].items()))
        v = r["verify"]
        if v is None:
            print("  gains not written (--apply writes them and verifies)")
            continue
        print(
            f"  verification move: max following error {v['max_following_error_um_before']} um "
            f"(gains before) -> {v['max_following_error_um_after']} um"
        )
    return 0
