"""`contour calibrate`: measure an axis's encoder against a reference, write
the error map and compensation table, and apply it to the drive.

    contour calibrate --axis Y --from -75 --to 75 --step 15 --port /dev/pts/3 \\
        [--reference scale|FILE.csv] [--out TABLE.csv] [--comp-file F --comp-type 0|1]
        [--plot PNG] [--apply]
    contour calibrate --import READINGS.csv [--axis Y --apply --port ...] [--out ...]

The drive moves the axis through the targets (ISO 230-2 bidirectional cycle:
every target approached moving +x and moving -x, overrun at the ends), dwells
and samples its encoder and its reference scale; the host pulls the numbered,
CRC-checked samples (a lost or corrupt one is read again, a leg that cannot be
completed is measured again: never skipped), computes per point the mean
error per direction, systematic error, hysteresis and random error (95 %)
as defined in ../shared/data/README.md, and writes/plots them. --apply
uploads the table (stored in the drive's flash, previous table kept until
the new one is verified), then measures again on a grid of half the step
and reports the residual. docs/calibration.md has the details.

`--sim MACHINE` runs against the simulated drive inside this process (no
link; simulated time), e.g. hil_sim/machines/lacerda_y_calibration.toml.
`--inject-loss P` drops or corrupts that fraction of the frames in transit
(both directions) to show the run survives it.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from typing import Optional

from contour.calibration import analysis, faults, run, tables
from contour.errors import UsageError, UserError
from contour.progress import Bar

AXES = "XYZA"


def parse_axis(text: str) -> int:
    t = text.strip().upper()
    if t in AXES:
        return AXES.index(t)
    if t.isdigit() and int(t) < len(AXES):
        return int(t)
    raise UsageError(f"--axis {text!r}: expected X, Y, Z, A or 0..3")


def targets_mm(start: float, stop: float, step: float) -> list:
    for name, v in (("--from", start), ("--to", stop), ("--step", step)):
        if v is None:
            raise UsageError(f"{name} is required (or use --import FILE.csv)")
        if not math.isfinite(v):
            raise UsageError(f"{name} {v}: not a number")
    if step <= 0:
        raise UsageError(f"--step {step:g}: must be positive")
    lo, hi = min(start, stop), max(start, stop)
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    if n < 2:
        raise UsageError(
            f"--from {start:g} --to {stop:g} --step {step:g} gives fewer than 2 points"
        )
    if n > tables.POINTS_MAX:
        raise UsageError(
            f"{n} points: the drive's compensation table holds at most {tables.POINTS_MAX}; "
            "use a larger --step"
        )
    pts = [round(lo + i * step, 6) for i in range(n)]
    if hi - pts[-1] > 1e-6:
        pts.append(round(hi, 6))  # the end of the range is always measured
    return pts


def _print_map(em: analysis.ErrorMap, title: str, out=None) -> None:
    out = out if out is not None else sys.stdout
    print(title, file=out)
    print(
        f"{'position mm':>12} {'err +x um':>10} {'err -x um':>10} {'system. um':>10} "
        f"{'hyster. um':>10} {'random um':>10}",
        file=out,
    )
    for p in em.points:
        print(
            f"{p.position_mm:12.3f} {1000 * p.mean_err_pos_mm:10.2f}"
            f" {1000 * p.mean_err_neg_mm:10.2f} {1000 * p.systematic_mm:10.2f}"
            f" {1000 * p.hysteresis_mm:10.2f} {1000 * p.random_95_mm:10.2f}",
            file=out,
        )
    s = em.summary()
    print(
        f"max |systematic| {s['max_systematic_um']:.2f} um, max hysteresis "
        f"{s['max_hysteresis_um']:.2f} um, max random (95 %) {s['max_random_95_um']:.2f} um",
        file=out,
    )


class _Bar(Bar):
    """The calibrator's progress callback (legs done, legs in all)."""

    def __init__(self, enabled: bool, desc: str) -> None:
        super().__init__(total=0, unit="leg", desc=desc, enabled=enabled)

    def __call__(self, done: int, total: int) -> None:
        self.to(done, total)


class Session:
    """A client plus the clock of the calibration (wall or simulated)."""

    def __init__(self, args) -> None:
        self.faults = (
            faults.FrameFaults(args.inject_loss, seed=args.seed) if args.inject_loss else None
        )
        self.drive = None
        if args.sim:
            from contour.calibration import inproc
            from contour.link.client import Client

            self.drive = inproc.SimDrive(machine=args.sim, feedforward=args.sim_feedforward)
            t = self.drive.transport(self.faults)
            self.client = Client(t, timeout=0.02, retries=args.retries)
            self.wait = t.wait
        else:
            from contour.link.client import Client
            from contour.link.options import transport_from_args

            t = transport_from_args(args)
            if self.faults is not None:
                faults.make_lossy(t, self.faults)
            self.client = Client(t, timeout=args.timeout, retries=args.retries)
            self.wait = time.sleep

    def close(self) -> None:
        self.client.close()


def _run_cfg(args, axis: int, pts_mm: list, host_ref: bool) -> run.RunConfig:
    return run.RunConfig(
        axis=axis,
        targets_nm=[round(p * 1e6) for p in pts_mm],
        cycles=args.cycles,
        samples=args.samples,
        sample_ticks=args.sample_ticks,
        dwell_ms=args.dwell_ms,
        overrun_nm=round(args.overrun * 1e6),
        feed_nm_s=round(args.feed / 60.0 * 1e6),
        host_reference=host_ref,
    )


def _check_numbers(args) -> None:
    if not 0 <= args.overrun <= 1000:
        raise UsageError(f"--overrun {args.overrun:g} mm: must be 0..1000")
    if not 0 < args.feed <= 240000:
        raise UsageError(f"--feed {args.feed:g} mm/min: must be in (0, 240000]")
    if not 0 <= args.dwell_ms <= 60000:
        raise UsageError(f"--dwell-ms {args.dwell_ms}: must be 0..60000")
    if not 1 <= args.sample_ticks <= 65535:
        raise UsageError(f"--sample-ticks {args.sample_ticks}: must be 1..65535")
    if not 0 <= args.ramp_ms <= 1000:
        raise UsageError(f"--ramp-ms {args.ramp_ms:g}: must be 0..1000")
    if args.comp_type is not None and args.comp_type not in (0, 1):
        raise UsageError(f"--comp-type {args.comp_type}: LinuxCNC knows types 0 and 1")
    # the drive-side limits of run.RunConfig, checked before anything moves
    if not 1 <= args.samples <= 512:
        raise UsageError(f"--samples {args.samples}: must be 1..512")
    if not 1 <= args.cycles <= 20:
        raise UsageError(f"--cycles {args.cycles}: must be 1..20")
    if not 0 < args.timeout <= 60:  # also refuses nan
        raise UsageError(f"--timeout {args.timeout:g} s: must be in (0, 60]")
    if not 0 <= args.retries <= 100:
        raise UsageError(f"--retries {args.retries}: must be 0..100")
    if not 0 < args.run_timeout <= 86400:
        raise UsageError(f"--run-timeout {args.run_timeout:g} s: must be in (0, 86400]")
    # outputs are written after a run that may take minutes: refuse a bad path now
    for opt, path in (("--out", args.out), ("--comp-file", args.comp_file), ("--plot", args.plot)):
        if path and not os.path.isdir(os.path.dirname(os.path.abspath(path))):
            raise UsageError(f"{opt} {path}: no such directory")


def _outputs(args, em: analysis.ErrorMap, residual: Optional[analysis.ErrorMap]) -> None:
    if args.out:
        tables.write_table_csv(args.out, em)
    if args.comp_file:
        tables.write_comp_file(args.comp_file, em, args.comp_type or 0)
    if args.plot:
        from contour.calibration.plot import plot_error_map

        plot_error_map(args.plot, em, residual, title=f"axis {em.axis}")


def _notify(msg: str) -> None:
    print(f"contour: {msg}", file=sys.stderr)


def cmd_calibrate(args) -> int:
    _check_numbers(args)
    if args.grid:
        from contour.commands.calibrate_grid import cmd_grid

        if args.axis or args.import_file or args.reference != "scale":
            raise UsageError("--grid measures X and Y itself: no --axis, --import or --reference")
        return cmd_grid(args)
    report: dict = {}
    if args.import_file:
        if args.reference != "scale":
            raise UsageError(
                "--import and --reference are exclusive (the import file is the reference)"
            )
        axis = parse_axis(args.axis) if args.axis else None
        em = tables.import_errmap(args.import_file, axis=AXES[axis] if axis is not None else "")
        report["source"] = args.import_file
        residual = None
        if args.apply:
            if axis is None:
                raise UsageError("--apply needs --axis")
            sess = Session(args)
            try:
                info = run.upload(
                    sess.client,
                    axis,
                    em,
                    ramp_us=round(args.ramp_ms * 1000),
                    wait=sess.wait,
                    notify=_notify,
                )
            finally:
                sess.close()
            report["applied"] = info
        _outputs(args, em, residual)
        return _report(args, em, None, report)

    if not args.axis:
        raise UsageError("--axis is required (X, Y, Z or A)")
    axis = parse_axis(args.axis)
    pts = targets_mm(args.from_mm, args.to_mm, args.step)
    host_ref = args.reference != "scale"
    ref_readings = tables.read_import_csv(args.reference) if host_ref else None
    # every file is checked before the axis moves
    sess = Session(args)
    try:
        client = sess.client
        ident = client.identify()
        if axis >= ident["axes"]:
            raise UserError(f"--axis {AXES[axis]}: the drive has {ident['axes']} axes")
        client.enable(True, axes=ident["axes"])
        cal = run.Calibrator(client, sess.wait, poll_s=0.02, timeout_s=args.run_timeout)
        bar = _Bar(not args.no_progress, f"calibrate {AXES[axis]}")
        cal.progress = bar
        try:
            res = cal.run(_run_cfg(args, axis, pts, host_ref))
        finally:
            bar.close()
        if host_ref:
            em = run.errmap_with_host_reference(res, ref_readings, axis=AXES[axis])
        else:
            em = run.errmap_from_run(res, "enc", axis=AXES[axis])
        report["measure"] = _run_report(res)
        residual = None
        if args.apply:
            info = run.upload(
                client, axis, em, ramp_us=round(args.ramp_ms * 1000), wait=sess.wait, notify=_notify
            )
            report["applied"] = info
            if host_ref:
                report["residual"] = "not measured: the reference is a file (no reference scale)"
            else:
                vstep = args.verify_step if args.verify_step else args.step / 2
                vpts = targets_mm(pts[0], pts[-1], vstep)
                bar = _Bar(not args.no_progress, f"verify {AXES[axis]}")
                cal.progress = bar
                try:
                    res2 = cal.run(_run_cfg(args, axis, vpts, False))
                finally:
                    bar.close()
                residual = run.errmap_from_run(res2, "comp", axis=AXES[axis])
                report["verify"] = _run_report(res2)
                report["residual"] = analysis.residual(residual)
        report["frames_repeated_total"] = getattr(client, "retried", 0)
        if sess.drive is not None:
            report["simulated_seconds"] = round(sess.drive.seconds, 3)
        if sess.faults is not None:
            report["injected"] = sess.faults.stats()
    finally:
        sess.close()
    _outputs(args, em, residual)
    return _report(args, em, residual, report)


def _run_report(res: run.RunResult) -> dict:
    n = sum(len(v) for v in res.legs.values())
    return {
        "samples": n,
        "frames_repeated": res.frames_repeated,
        "reads_repeated": res.reads_repeated,
        "points_repeated": res.points_repeated,
        "samples_lost": res.samples_lost,
        "wall_seconds": round(res.seconds, 3),
    }


def _report(args, em, residual, report: dict) -> int:
    if args.json:
        out = {
            "axis": em.axis,
            "points": [p.as_dict() for p in em.points],
            "summary": em.summary(),
            **report,
        }
        if residual is not None:
            out["residual_points"] = [p.as_dict() for p in residual.points]
        print(json.dumps(out, indent=2, default=str))
        return 0
    _print_map(em, f"axis {em.axis or '?'}: error = encoder - reference ({em.source})")
    for key in ("measure", "verify"):
        r = report.get(key)
        if r:
            print(
                f"{key}: {r['samples']} samples; repeated: {r['frames_repeated']} frames "
                f"(lost or corrupt in transit), {r['reads_repeated']} batches re-read, "
                f"{r['points_repeated']} points re-measured"
            )
    if "applied" in report:
        a = report["applied"]
        print(f"applied: {a['n']} points, version {a['version']}, flash slot {a['slot']}")
    if residual is not None:
        _print_map(residual, "after compensation (re-measured):")
        res_um = report["residual"]["residual_systematic_um"]
        print(f"residual systematic error: {res_um:.2f} um (max)")
    elif isinstance(report.get("residual"), str):
        print(f"residual: {report['residual']}")
    if "injected" in report:
        i = report["injected"]
        print(
            f"injected: {i['dropped']} frames dropped, {i['corrupted']} corrupted of {i['frames']}"
        )
    return 0


def register(sub) -> None:
    from contour.link.options import link_options

    p = sub.add_parser(
        "calibrate",
        parents=[link_options()],
        help="measure an axis against a reference, write and apply its compensation table",
        description=__doc__.split("\n\n")[0],
    )
    p.add_argument("--axis", help="axis to calibrate: X, Y, Z or A")
    p.add_argument(
        "--grid",
        metavar="X:FROM:TO:STEP,Y:FROM:TO:STEP",
        help="2-D calibration of X and Y over a grid of lines (mm), e.g. X:-60:60:15,Y:-60:60:15",
    )
    p.add_argument(
        "--verify-grid",
        metavar="SPEC",
        help="--grid --apply: where to re-measure (default: the cell centres)",
    )
    p.add_argument("--map-out", metavar="MAP.csv", help="--grid: write the 2-D map (CSV)")
    p.add_argument(
        "--passes",
        type=int,
        default=2,
        help="--grid --apply: measurements of the nodes, the later ones with the map on (2)",
    )
    p.add_argument("--from", dest="from_mm", type=float, metavar="MM", help="first target, mm")
    p.add_argument("--to", dest="to_mm", type=float, metavar="MM", help="last target, mm")
    p.add_argument("--step", type=float, metavar="MM", help="target spacing, mm")
    p.add_argument(
        "--reference",
        default="scale",
        metavar="scale|FILE.csv",
        help="the drive's reference scale (default) or readings of an external instrument "
        "(CSV position_mm,reading_mm,direction; see docs/calibration.md)",
    )
    p.add_argument(
        "--import",
        dest="import_file",
        metavar="FILE.csv",
        help="analyse readings taken by a separate instrument instead of running a measurement",
    )
    p.add_argument("--out", metavar="TABLE.csv", help="write the error map and corrections (CSV)")
    p.add_argument("--comp-file", metavar="FILE", help="also write a LinuxCNC COMP_FILE")
    p.add_argument("--comp-type", type=int, default=None, help="COMP_FILE_TYPE 0 (default) or 1")
    p.add_argument("--plot", metavar="PNG", help="plot the error map")
    p.add_argument(
        "--apply",
        action="store_true",
        help="upload and activate the table, then re-measure and report the residual",
    )
    p.add_argument(
        "--verify-step", type=float, metavar="MM", help="re-measure grid (default step/2)"
    )
    p.add_argument("--samples", type=int, default=200, help="samples per point and direction (200)")
    p.add_argument("--cycles", type=int, default=1, help="bidirectional passes (1)")
    p.add_argument("--sample-ticks", type=int, default=2, help="control ticks between samples (2)")
    p.add_argument("--dwell-ms", type=int, default=400, help="settling time at each stop, ms (400)")
    p.add_argument(
        "--overrun", type=float, default=1.0, metavar="MM", help="overrun at the ends (1)"
    )
    p.add_argument(
        "--feed", type=float, default=3000.0, metavar="MM_PER_MIN", help="move speed (3000)"
    )
    p.add_argument(
        "--ramp-ms", type=float, default=20.0, help="reversal ramp of the table, ms (20)"
    )
    p.add_argument("--retries", type=int, default=8, help="resends of a request without reply (8)")
    p.add_argument(
        "--run-timeout", type=float, default=900.0, help="give up a run after this long, s (900)"
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument(
        "--no-progress", action="store_true", help="no progress bar (none unless stderr is a TTY)"
    )
    g = p.add_argument_group("testing")
    g.add_argument(
        "--sim",
        metavar="MACHINE",
        help="calibrate the simulated drive in this process (machine name or TOML file)",
    )
    g.add_argument(
        "--sim-feedforward",
        default="full",
        choices=("none", "velocity", "full"),
        help="axis feed-forward of --sim (full)",
    )
    g.add_argument(
        "--inject-loss",
        type=float,
        default=0.0,
        metavar="P",
        help="drop or corrupt this fraction of the frames in transit (both directions)",
    )
    g.add_argument("--seed", type=int, default=1, help="seed of --inject-loss (1)")
    p.set_defaults(func=cmd_calibrate)
