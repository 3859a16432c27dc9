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
    p.add_argument("--method", default="robust", choices=("robust", "zn", "simplex"))
    p.add_argument(
        "--friction-ff",
        choices=("auto", "on", "off"),
        default="auto",
        help="with --apply, the identified Coulomb friction as friction_ff_mv: on, off "
        "(parameters untouched) or auto (verified with and without, the better kept)",
    )
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
        "viscous_v_s_m": d["viscous_v_s_m"],
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


def _identify_and_tune(ax: str, rec, tick_hz: float, args, d_tau: float, friction=None):
    """identify and tune; `friction` (f, c, u0) from friction legs measured
    apart (the drive's), set on the identification before the tuning."""
    try:
        ident = identify.identify(rec)
        if friction is not None:
            ident.friction_v, ident.viscous_v_s_m, ident.load_v = friction
        return ident, tune.tune(ident, tick_hz, args.method, args.ms_target, d_tau)
    except (identify.IdentifyError, tune.TuneError) as e:
        raise UserError(f"axis {ax.upper()}: {e}") from e


def _cec(idents: dict, tuned: dict, tick_hz: float) -> tune.CecTuned | None:
    """CEC gains (tune.tune_cec) from the first two tuned axes, or None."""
    if len(idents) < 2:
        return None
    axes = {}
    for ax in list(idents)[:2]:
        loops = [tune.model_loop(idents[ax], tick_hz)]
        if idents[ax].fit.model == "two_inertia":
            loops.append(tune.model_loop(idents[ax], tick_hz, zeta=tune.worst_zeta(idents[ax])))
        axes[ax] = (loops, tuned[ax].gains)
    return tune.tune_cec(axes)


def _sim_circle(m, tuned: dict, cec: dict | None, controller: str) -> dict:
    """sim circle (R10 F6000, contour.sim.circle: its scoring) on machine
    `m` with the tuned PIDs and feed-forward of `tuned` (None: the
    machine's gains, no feed-forward) and the CEC gains `cec`."""
    import dataclasses

    from contour.sim import circle

    ff = "none"
    if tuned:
        gains = dict(m.gains)
        fwd = {}
        for ax, t in tuned.items():
            gains[ax] = {**m.gains[ax], **{k: float(t.gains[k]) for k in ("kp", "ki", "kd")}}
            fwd[f"kvff_{ax}"] = float(t.gains["velocity_feedforward"])
            fwd[f"kaff_{ax}"] = float(t.gains["acceleration_feedforward"])
        if cec is not None:
            gains["cec"] = {**m.gains["cec"], **cec}
        m = dataclasses.replace(m, gains=gains, feedforward=fwd)
        ff = "full"
    r = circle.run_circle(
        CIRCLE_R_MM, CIRCLE_F_MM_S * 60, controller=controller, feedforward=ff, mach=m
    ).result
    if r.faults:
        raise UserError(f"contour verification (sim circle) faulted: {', '.join(r.faults)}")
    return {
        "max_contour_error_um": round(r.max_contour_error_mm * 1e3, 2),
        "iae_um_s": round(r.iae_mm_s * 1e3, 3),
        "circular_deviation_um": round(r.circular_deviation_mm * 1e3, 2),
    }


CIRCLE_R_MM = 10.0
CIRCLE_F_MM_S = 100.0


def _contour_report(before: dict, after: dict, extra: dict) -> dict:
    out = dict(extra)
    for k in sorted(set(before) & set(after)):
        if k.endswith("_um") or k.endswith("_um_s"):
            out[f"{k}_before"] = before[k]
            out[f"{k}_after"] = after[k]
    return out


def run_sim(args) -> dict:
    m = machines.load(args.sim)
    axes = _axes(args.axis, m.axis)
    limits = _limits(args)
    plan = experiment.Plan(tick_hz=m.tick_hz, amplitude_v=args.amplitude)
    out = {"machine": m.name, "tick_hz": m.tick_hz, "axes": {}}
    idents, tuned = {}, {}
    for ax in axes:
        try:
            rec, stops = experiment.simulate_bounded(m, ax, plan, limits)
        except experiment.ExperimentAborted as e:
            raise UserError(f"axis {ax.upper()}: {e}") from e
        ident, t = _identify_and_tune(ax, rec, m.tick_hz, args, m.gains[ax].get("d_tau", 1e-3))
        idents[ax], tuned[ax] = ident, t
        try:
            before = experiment.following_error(m, ax)
            after = experiment.following_error(m, ax, t.gains)
        except experiment.ExperimentAborted as e:
            raise UserError(f"axis {ax.upper()}: {e}") from e
        out["axes"][ax.upper()] = _result(ident, t, stops, before, after)
    cec = _cec(idents, tuned, m.tick_hz)
    if cec is not None and axes[:2] == ["x", "y"]:
        out["cec"] = cec.as_dict()
        before = _sim_circle(m, {}, None, "pid")
        after = _sim_circle(m, {a: tuned[a] for a in axes[:2]}, None, "pid")
        with_cec = _sim_circle(m, {a: tuned[a] for a in axes[:2]}, cec.gains, "cec-tangent")
        rep = _contour_report(
            before,
            after,
            {"path": "circle", "plane": "xy", "radius_mm": CIRCLE_R_MM, "feed_mm_s": CIRCLE_F_MM_S},
        )
        rep.update({f"{k}_after_cec": v for k, v in with_cec.items()})
        out["contour_verify"] = rep
    return out


def _try_contour(client, pair) -> dict:
    """verify_contour, or {"error": why} when its telemetry cannot score it
    (e.g. on CAN, 100 ms cycles): the gains are written either way."""
    try:
        return drive_experiment.verify_contour(client, pair)
    except UserError as e:
        if "telemetry" not in str(e):
            raise
        return {"error": str(e)}


def _score(after: dict, c_after: dict | None) -> tuple:
    """What the friction decision compares (lower is better): the square's
    rms and max contour error when it was scored, else the sum of the
    lines' max following errors."""
    if c_after is not None and "error" not in c_after:
        return (c_after["rms_contour_error_um"], c_after["max_contour_error_um"])
    return (sum(a["max_following_error_um"] for a in after.values()),)


def _apply_friction_and_verify(client, args, axes, pair, tuned, noise, out):
    """After the gains: the friction feed-forward as --friction-ff says
    (on: the identified Coulomb term as friction_ff_mv and the band;
    off: the drive's friction parameters untouched; auto: both on and 0,
    each verified, and the better kept (_score): the drive's friction
    feed-forward follows the reference velocity, so it drops out as the
    reference stops while the axis still moves, and the axis stops
    F / Kp short until the integral takes over) and the verification jobs
    after: (lines {axis: report}, square report or None)."""

    def verify_all():
        a = {ax: drive_experiment.verify(client, AXES.index(ax)) for ax in axes}
        return a, (_try_contour(client, pair) if pair is not None else None)

    if args.friction_ff == "off":
        return verify_all()
    fr = {AXES.index(a): tuned[a].gains.get("friction_ff_v") for a in axes}
    known = [v for v in noise.values() if v is not None]
    band = drive_experiment.friction_band(
        max(known) if known else None, drive_experiment.FRICTION_SPEEDS_MM_S[0] * 1e-3
    )
    rep = {
        "mode": args.friction_ff,
        "identified_v": {a.upper(): tuned[a].gains.get("friction_ff_v") for a in axes},
        "band_mm_s": round(band * 1e3, 3),
        "vel_noise_mm_s": {
            a.upper(): None if v is None else round(v * 1e3, 3) for a, v in noise.items()
        },
    }
    out["friction_ff"] = rep
    rep["written"] = drive_experiment.apply_friction(client, fr, band)
    on = verify_all()
    if args.friction_ff == "on" or rep["written"] is None:
        rep["kept"] = rep["written"] is not None
        return on
    drive_experiment.apply_friction(client, {i: 0.0 for i in fr}, band)
    off = verify_all()
    rep["score_on"], rep["score_off"] = _score(*on), _score(*off)
    rep["kept"] = rep["score_on"] <= rep["score_off"]
    if rep["kept"]:
        rep["written"] = drive_experiment.apply_friction(client, fr, band)
        return on
    rep["written"] = drive_experiment.apply_friction(client, {i: 0.0 for i in fr}, band)
    return off


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
        idents, tuned, stops, noise = {}, {}, {}, {}
        for ax in axes:
            i = AXES.index(ax)
            try:
                rec, stops[ax] = drive_experiment.run_bounded(client, i, plan, limits)
            except experiment.ExperimentAborted as e:
                raise UserError(f"axis {ax.upper()}: {e}") from e
            st = {}
            legs = drive_experiment.friction_legs(client, i, travel_mm=args.travel_mm, stats=st)
            noise[ax] = st.get("vel_noise_m_s")
            friction = identify.friction_fit(legs)
            idents[ax], tuned[ax] = _identify_and_tune(
                ax, rec, plan.tick_hz, args, args.d_tau, friction
            )
        cec = _cec(idents, tuned, plan.tick_hz)
        if cec is not None:
            out["cec"] = cec.as_dict()
        pair = tuple(AXES.index(a) for a in axes[:2]) if len(axes) >= 2 else None
        before, after, r = {}, {}, {}
        c_before = c_after = None
        if args.apply:
            for ax in axes:
                before[ax] = drive_experiment.verify(client, AXES.index(ax))
            if pair is not None:
                c_before = _try_contour(client, pair)
            for ax in axes:
                i = AXES.index(ax)
                r[ax] = {"gains_before": drive_experiment.read_gains(client, i)}
                r[ax]["gains_written"] = drive_experiment.apply_gains(client, i, tuned[ax].gains)
            if cec is not None:
                out["cec"]["written"] = drive_experiment.apply_cec_gains(client, cec)
            after, c_after = _apply_friction_and_verify(client, args, axes, pair, tuned, noise, out)
            if pair is not None:
                if "error" in c_before or "error" in c_after:
                    out["contour_verify"] = {"error": c_before.get("error") or c_after["error"]}
                else:
                    extra = {k: c_after[k] for k in ("path", "plane", "side_mm", "feed_mm_s")}
                    extra["cec_mode"] = drive_experiment.cec_mode(client)
                    out["contour_verify"] = _contour_report(c_before, c_after, extra)
        for ax in axes:
            res = _result(
                idents[ax],
                tuned[ax],
                stops[ax],
                before[ax]["max_following_error_um"] * 1e-6 if ax in before else 0.0,
                after[ax]["max_following_error_um"] * 1e-6 if ax in after else None,
            )
            if ax in before:
                res["applied"] = r[ax]
            else:
                res["verify"] = None
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
            print(f"  friction {r['friction_v']:.4f} V Coulomb, {r['viscous_v_s_m']:.2f} V/(m/s)")
        else:
            print("  friction not measured (no constant-velocity legs passed)")
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
    c = out.get("cec")
    if c is not None:
        g = c["gains"]
        print(
            f"CEC: kp {g['kp']:g}, ki {g['ki']:g}, kd {g['kd']:g} ({c['alpha']:g} x the "
            f"{c['slower_axis']} axis's Kp), Ms {c['sensitivity_peak']}, coupled loop "
            f"{'stable' if c['stable'] else 'UNSTABLE'}"
            + ("" if not c["reason"] else f" ({c['reason']})")
        )
    v = out.get("contour_verify")
    if v is not None and "error" in v:
        print(f"contour verification not scored: {v['error']}")
    elif v is not None:
        size = f"R{v['radius_mm']:g}" if v["path"] == "circle" else f"{v['side_mm']:g} mm"
        print(
            f"contour verification: {v['path']} {size} at {v['feed_mm_s']:g} mm/s "
            f"in {v['plane'].upper()}: max contour error {v['max_contour_error_um_before']} -> "
            f"{v['max_contour_error_um_after']} um"
            + (
                f", rms {v['rms_contour_error_um_before']} -> {v['rms_contour_error_um_after']} um"
                if "rms_contour_error_um_before" in v
                else ""
            )
            + (
                f", with the CEC {v['max_contour_error_um_after_cec']} um"
                if "max_contour_error_um_after_cec" in v
                else ""
            )
            + (
                f", max following error {v['max_following_error_um_before']} -> "
                f"{v['max_following_error_um_after']} um"
                if "max_following_error_um_before" in v
                else ""
            )
        )
    return 0
