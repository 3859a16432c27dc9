"""`contour calibrate --grid X:FROM:TO:STEP,Y:FROM:TO:STEP`: the 2-D
calibration of an X-Y table against a 2-D reference (issue 22,
docs/calibration.md "Calibration over the field").

Rows and columns of the grid are run in both directions of approach
(contour.calibration.grid); the report gives per node both coordinates'
errors (systematic, hysteresis, random 95 %) and per line ISO 230-2's E,
B, R, A, M and the straightness. --map-out writes the 2-D map (CSV),
--apply uploads it (comp2d_write / comp2d_commit: flash, versioned),
measures the nodes again with it in use and adds their residual
(--passes 2, the default; grid.py says why), then measures at the points
between the grid lines (--verify-grid, default the cell centres), where
the map interpolates: the residual systematic error there is the figure of
merit.
"""

from __future__ import annotations

import csv
import json
import sys
import time

from contour.calibration import grid, map2d, run
from contour.errors import UsageError, UserError


def _bar(args, desc: str):
    from contour.commands.calibrate import _Bar

    return _Bar(not args.no_progress, desc)


def _measure(args, runner, g, column: str, desc: str):
    bar = _bar(args, desc)
    runner.progress = lambda k, n: bar(k, n)
    try:
        return runner.measure(g, column)
    finally:
        bar.close()


def _write_nodes(path: str, stats: list) -> None:
    try:
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(stats[0].keys()))
            w.writeheader()
            for r in stats:
                w.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in r.items()})
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None


def _meas_report(m: grid.GridMeasurement) -> dict:
    return {
        "lines": m.runs,
        "samples": m.samples,
        "frames_repeated": m.frames_repeated,
        "reads_repeated": m.reads_repeated,
        "points_repeated": m.points_repeated,
        "simulated_seconds": round(m.simulated_s, 3),
    }


def _upload(client, sess, m2) -> dict:
    from contour.commands.calibrate import _notify

    cm = map2d.to_c(m2)
    span = 1e6  # mm; the drive checks its own field (soft limits) on commit
    map2d.check(cm, (-span, -span), (span, span))
    return grid.upload_map(client, map2d.encode_record(cm), sess.wait, notify=_notify)


def cmd_grid(args) -> int:
    from contour.commands.calibrate import Session

    g = grid.parse_grid(args.grid)
    if not 1 <= args.passes <= 4:
        raise UsageError(f"--passes {args.passes}: must be 1..4")
    vg = grid.parse_grid(args.verify_grid) if args.verify_grid else grid.midpoints(g)
    for opt, path in (("--out", args.out), ("--map-out", args.map_out), ("--plot", args.plot)):
        if path:
            import os

            if not os.path.isdir(os.path.dirname(os.path.abspath(path))):
                raise UserError(f"{opt} {path}: no such directory")
    sess = Session(args)
    report: dict = {"grid": {"x_mm": g.xs, "y_mm": g.ys}}
    residual_stats = None
    try:
        client = sess.client
        ident = client.identify()
        if ident["axes"] < 2:
            raise UserError(f"--grid needs X and Y: the drive has {ident['axes']} axis")
        client.enable(True, axes=ident["axes"])

        def clock():
            return sess.drive.seconds if sess.drive is not None else time.monotonic()

        cfg = run.RunConfig(
            axis=0,
            targets_nm=[0],
            cycles=args.cycles,
            samples=args.samples,
            sample_ticks=args.sample_ticks,
            dwell_ms=args.dwell_ms,
            overrun_nm=round(args.overrun * 1e6),
            feed_nm_s=round(args.feed / 60 * 1e6),
        )
        runner = grid.GridRunner(client, sess.wait, cfg, clock=clock)
        meas = _measure(args, runner, g, "enc", "grid")
        stats = grid.node_stats(meas)
        report["measure"] = _meas_report(meas)
        report["nodes"] = stats
        report["lines"] = grid.line_figures(meas, stats)
        report["cross_check"] = grid.cross_check(meas)
        report["before_um"] = grid.worst(stats, "systematic_um")
        corr = grid.corrections(meas)
        m2 = grid.build_map(g, corr)
        if args.out:
            _write_nodes(args.out, stats)
        if args.apply:
            info = _upload(client, sess, m2)
            # the nodes again with the map on: its residual is added (grid.py)
            passes = []
            for k in range(1, args.passes):
                again = _measure(args, runner, g, "comp", f"pass {k + 1}")
                again_stats = grid.node_stats(again)
                passes.append(
                    {
                        **_meas_report(again),
                        "residual_at_nodes_um": grid.worst(again_stats, "systematic_um"),
                    }
                )
                corr = corr + grid.corrections(again)
                m2 = grid.build_map(g, corr)
                info = _upload(client, sess, m2)
            report["passes"] = passes
            report["applied"] = info
            ver = _measure(args, runner, vg, "comp", "verify")
            residual_stats = grid.node_stats(ver)
            report["verify"] = _meas_report(ver)
            report["verify_grid"] = {"x_mm": vg.xs, "y_mm": vg.ys}
            report["residual_nodes"] = residual_stats
            report["residual_um"] = grid.worst(residual_stats, "systematic_um")
            # the same coordinates read across the crossing lines (held axis)
            report["residual_cross_um"] = grid.worst(residual_stats, "cross_systematic_um")
        if args.map_out:
            map2d.write_csv(m2, args.map_out)
        report["frames_repeated_total"] = getattr(client, "retried", 0)
        if sess.drive is not None:
            report["simulated_seconds"] = round(sess.drive.seconds, 3)
        if sess.faults is not None:
            report["injected"] = sess.faults.stats()
    finally:
        sess.close()
    if args.plot:
        from contour.calibration.plot import plot_field

        plot_field(args.plot, stats, residual_stats)
    if args.json:
        print(json.dumps(report, indent=2, default=str))
        return 0
    _print(report)
    return 0


def _print(report: dict, out=None) -> None:
    out = out if out is not None else sys.stdout
    print("2-D calibration: error = encoder - reference, um", file=out)
    print(
        f"{'x mm':>8} {'y mm':>8} | {'X sys':>7} {'X hys':>6} {'X r95':>6} |"
        f" {'Y sys':>7} {'Y hys':>6} {'Y r95':>6}",
        file=out,
    )
    for r in report["nodes"]:
        print(
            f"{r['x_mm']:8.2f} {r['y_mm']:8.2f} | {r['x_systematic_um']:7.2f}"
            f" {r['x_hysteresis_um']:6.2f} {r['x_random_95_um']:6.2f} |"
            f" {r['y_systematic_um']:7.2f} {r['y_hysteresis_um']:6.2f} {r['y_random_95_um']:6.2f}",
            file=out,
        )
    print("ISO 230-2 per line (um): E B R A M, straightness", file=out)
    for ln in report["lines"]:
        print(
            f"  {ln['line']:<18} E {ln['E_um']:7.2f}  B {ln['B_um']:6.2f}  R {ln['R_um']:6.2f}"
            f"  A {ln['A_um']:7.2f}  M {ln['M_um']:7.2f}"
            f"  straightness {ln['straightness_um']:7.2f}"
            f" (crossing lines {ln['straightness_crossing_um']:.2f})",
            file=out,
        )
    cc = report["cross_check"]
    print(
        "cross coordinate measured at the stop - crossing line's reading (um):"
        f" X max {cc['x_max_um']:.2f} rms {cc['x_rms_um']:.2f},"
        f" Y max {cc['y_max_um']:.2f} rms {cc['y_rms_um']:.2f}",
        file=out,
    )
    print(f"largest systematic error before: {report['before_um']:.2f} um", file=out)
    if "residual_um" in report:
        a = report["applied"]
        print(
            f"applied: {a['nx']} x {a['ny']} nodes, version {a['version']}, flash bank {a['slot']}",
            file=out,
        )
        print(
            f"residual systematic error between the grid lines: {report['residual_um']:.2f} um"
            " (max, both coordinates)",
            file=out,
        )
