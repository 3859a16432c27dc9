"""`contour tune`: identify an axis from an excitation experiment and
compute its gains (issue 23; contour.commission).

Today the experiment runs on the C simulator's drive configured with a
simulated machine (`--sim MACHINE`; the excitation enters through the
simulator's sim_inject): the drive-side excitation (and with it `--port`
and `--apply`) is not built yet, and both are refused with that reason.
"""

from __future__ import annotations

import json
import sys

from contour.commission import experiment, identify, tune
from contour.errors import UsageError, UserError
from contour.sim import machine as machines

AXES = ("x", "y", "z")


def register(sub) -> None:
    p = sub.add_parser(
        "tune",
        help="identify an axis and compute its gains",
        description=(
            "Excite the axis at rest (multisine on the command, constant-velocity legs), fit "
            "the two-inertia or rigid-body model, compute PID and feed-forward gains for a "
            "sensitivity-peak target, check the discretised closed loop, and compare the "
            "following error of a verification move before and after. Runs on the simulated "
            "drive of a machine (--sim); the drive-side experiment is not built yet."
        ),
    )
    p.add_argument("--axis", required=True, help="X, Y, Z or all")
    p.add_argument("--sim", metavar="MACHINE", help="simulated machine (name or TOML file)")
    p.add_argument("--port", metavar="PATH", help="drive port (not available yet)")
    p.add_argument("--apply", action="store_true", help="write the gains (not available yet)")
    p.add_argument("--json", action="store_true", help="JSON on stdout")
    p.add_argument("--method", default="robust", choices=("robust", "zn"))
    p.add_argument("--ms-target", type=float, default=1.6, help="sensitivity peak (1.1 .. 3)")
    p.add_argument("--amplitude", type=float, default=3.0, help="excitation rms, V")
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


def run(args) -> int:
    if args.port or args.apply:
        raise UserError(
            "tune against a drive (--port, --apply) is not available yet: the drive-side "
            "excitation experiment is not built (issue 23); use --sim MACHINE"
        )
    if not args.sim:
        raise UsageError("--sim MACHINE is required")
    if not 1.1 <= args.ms_target <= 3.0:
        raise UsageError(f"--ms-target {args.ms_target}: 1.1 .. 3")
    for name in ("amplitude", "travel_mm", "command_v", "velocity_mm_s"):
        v = getattr(args, name)
        if not v > 0:
            raise UsageError(f"--{name.replace('_', '-')} {v}: must be > 0")
    m = machines.load(args.sim)
    axes = _axes(args.axis, m.axis)
    limits = experiment.Limits(
        travel_m=args.travel_mm * 1e-3,
        command_v=args.command_v,
        velocity_m_s=args.velocity_mm_s * 1e-3,
    )
    plan = experiment.Plan(tick_hz=m.tick_hz, amplitude_v=args.amplitude)
    out = {"machine": m.name, "tick_hz": m.tick_hz, "axes": {}}
    for ax in axes:
        g0 = m.gains[ax]
        try:
            rec, stops = experiment.simulate_bounded(m, ax, plan, limits)
            ident = identify.identify(rec)
            t = tune.tune(ident, m.tick_hz, args.method, args.ms_target, g0.get("d_tau", 1e-3))
        except (experiment.ExperimentAborted, identify.IdentifyError, tune.TuneError) as e:
            raise UserError(f"axis {ax.upper()}: {e}") from e
        g = t.gains
        try:
            before = experiment.following_error(m, ax)
            after = experiment.following_error(m, ax, g)
        except experiment.ExperimentAborted as e:
            raise UserError(f"axis {ax.upper()}: {e}") from e
        d = ident.as_dict()
        td = t.as_dict()
        out["axes"][ax.upper()] = {
            "resonance_hz": d["resonance_hz"],
            "resonance_ci95_hz": d["resonance_ci95_hz"],
            "antiresonance_hz": d["antiresonance_hz"],
            "model": d["model"],
            "model_reason": d["reason"],
            "friction_v": d["friction_v"],
            "phase_margin_deg": td["phase_margin_deg"],
            "gain_margin_db": td["gain_margin_db"],
            "sensitivity_peak": td["sensitivity_peak"],
            "method": td["method"],
            "gains": {
                "pid_kp": td["gains"]["kp"],
                "pid_ki": td["gains"]["ki"],
                "pid_kd": td["gains"]["kd"],
                "velocity_feedforward": td["gains"]["velocity_feedforward"],
                "acceleration_feedforward": td["gains"]["acceleration_feedforward"],
            },
            "identified": {"params": d["params"], "ci95": d["ci95"], "rms_log": d["rms_log"]},
            "excitation_stops": stops,
            "verify": {
                "max_following_error_um_before": round(before * 1e6, 2),
                "max_following_error_um_after": round(after * 1e6, 2),
            },
        }
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
        print(f"  friction {r['friction_v']:.4f} V")
        print(
            f"  {r['method']}: Ms {r['sensitivity_peak']}, phase margin "
            f"{r['phase_margin_deg']} deg, gain margin {r['gain_margin_db']} dB"
        )
        print("  " + ", ".join(f"{k} {v:g}" for k, v in r["gains"].items()))
        v = r["verify"]
        print(
            f"  verification move: max following error {v['max_following_error_um_before']} um "
            f"(machine's gains) -> {v['max_following_error_um_after']} um"
        )
    return 0
