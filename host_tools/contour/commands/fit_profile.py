"""`contour fit-profile`: fit a machine profile to measured run times.

Reads the camargo2017 experiment tables as they are (each test program is
generated from its row) and plain ``program,time_s`` CSVs, fits the chosen
profile fields with the chosen model, reports the fitted values and the
errors per table (with and without suspect rows), and writes the profile
with the command that regenerates it. ``--no-fit`` only reports.
"""

from __future__ import annotations

import json
import math
import shlex
import sys
import time

import numpy as np

from contour.errors import UsageError, UserError
from contour.estimation import MODELS, estimate_program
from contour.estimation import experiments as xp
from contour.estimation import fit as fitting
from contour.estimation import profile as profiles
from contour.estimation.profile import AXIS_FIELDS, MOTION_FIELDS

# What each model can fit by default (X and Z tied: the thesis found them
# identical and most tests cannot tell them apart).
DEFAULT_FIT = {
    "planner": (
        "axes.XZ.corner_acceleration_mm_s2",
        "axes.Y.corner_acceleration_mm_s2",
        "axes.XZ.max_acceleration_mm_s2",
        "axes.Y.max_acceleration_mm_s2",
        "motion.min_block_time_s",
    ),
    "camargo2017": ("motion.min_block_time_s",),
    "mrt": ("motion.min_block_time_s",),
    "feed": (),
}


def register(sub) -> None:
    p = sub.add_parser(
        "fit-profile",
        help="fit a machine profile to measured run times",
        description=(
            "Fit profile parameters to measured run times: camargo2017 experiment tables "
            "(test programs generated from their rows) or program,time_s CSVs. Reports the "
            "fitted values and the errors per table; refuses parameters the data cannot "
            "identify."
        ),
    )
    p.add_argument(
        "--experiments", nargs="+", required=True, metavar="CSV", help="measured run times"
    )
    p.add_argument("--out", metavar="PROFILE.toml", help="write the fitted profile here")
    p.add_argument(
        "--base",
        metavar="PROFILE.toml",
        help="profile holding every value not fitted (default: built-in defaults)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="fix a profile value before fitting, e.g. motion.corner_rule=exact-stop "
        "or axes.XZ.max_jerk_mm_s3=1e6; repeatable",
    )
    p.add_argument("--name", help="name written into the fitted profile")
    p.add_argument("--description", help="description written into the fitted profile")
    p.add_argument("--model", default="planner", choices=list(MODELS), help="model to fit")
    p.add_argument(
        "--fit",
        nargs="*",
        metavar="PARAM",
        help="parameters: motion.<field> or axes.<AXES>.<field> (AXES tied, e.g. XZ), "
        "optionally =START and :LOW:HIGH (default depends on the model)",
    )
    p.add_argument(
        "--objective",
        default="mean-abs",
        choices=("mean-abs", "least-squares"),
        help="minimise the mean absolute relative error (default) or its squares",
    )
    p.add_argument(
        "--include-suspect",
        action="store_true",
        help="also fit on rows flagged suspect (E2Y75); they are always reported",
    )
    p.add_argument(
        "--compare",
        default="planner,camargo2017,mrt,feed",
        help="models to report after the fit (comma-separated)",
    )
    p.add_argument("--no-fit", action="store_true", help="only report the errors of --base")
    p.add_argument(
        "--full", action="store_true", help="time every test program whole (no extrapolation)"
    )
    p.add_argument("--per-test", metavar="CSV", help="write every test's predictions to CSV")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _parse_set(pairs, profile):
    """--set values as a dict of profile paths (AXES groups expanded)."""
    out = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip()
        if not sep:
            raise UsageError(f"--set '{pair}' is not FIELD=VALUE")
        parts = key.split(".")
        if len(parts) == 3 and parts[0] == "axes":
            if not parts[1] or any(a not in profiles.AXIS_NAMES for a in parts[1]):
                raise UsageError(f"--set {key}: '{parts[1]}' is not a set of axes")
            paths = [f"axes.{a}.{parts[2]}" for a in parts[1]]
            fields = {f.name: f for f in AXIS_FIELDS}
            name = parts[2]
        elif len(parts) == 2 and parts[0] in ("motion", "camargo2017"):
            paths = [key]
            from contour.estimation.profile import CAMARGO_FIELDS

            fields = {
                f.name: f for f in (MOTION_FIELDS if parts[0] == "motion" else CAMARGO_FIELDS)
            }
            name = parts[1]
        else:
            raise UsageError(
                f"--set {key}: use motion.<field>, axes.<AXES>.<field> or camargo2017.<option>"
            )
        f = fields.get(name)
        if f is None:
            raise UsageError(f"--set {key}: unknown field '{name}'")
        text = text.strip()
        if f.choices:
            value = text
        elif isinstance(f.default, bool):
            value = text.lower() == "true"
            if text.lower() not in ("true", "false"):
                raise UsageError(f"--set {key}: must be true or false")
        else:
            try:
                value = float(text)
            except ValueError:
                raise UsageError(f"--set {key}: '{text}' is not a number") from None
            if isinstance(f.default, int) and value == int(value):
                value = int(value)
        for path in paths:
            out[path] = value
    return profile.with_values(out) if out else profile


class _Evaluator:
    """Predicts every experiment with one model and a profile."""

    def __init__(self, experiments, full: bool):
        self.experiments = experiments
        self.full = full
        self.meas = np.array([e.time_s for e in experiments])

    def predict(self, profile, model: str) -> np.ndarray:
        def run(program):
            return estimate_program(program, profile, model).total_s

        return np.array(xp.predict(self.experiments, run, full=self.full))


def _stats(err: np.ndarray) -> dict:
    if err.size == 0:
        return {"n": 0, "mean_abs_pct": None, "max_abs_pct": None}
    a = np.abs(err) * 100.0
    return {"n": int(err.size), "mean_abs_pct": float(a.mean()), "max_abs_pct": float(a.max())}


def table_report(experiments, err: np.ndarray) -> dict:
    """Per table and overall, with and without suspect rows."""
    tables = []
    for e in experiments:
        if e.table not in tables:
            tables.append(e.table)
    ok = np.array([not e.suspect for e in experiments])
    out = {}
    for t in [*tables, "all"]:
        m = (
            np.ones(len(experiments), bool)
            if t == "all"
            else np.array([e.table == t for e in experiments])
        )
        entry = {"with_suspect": _stats(err[m])}
        if np.any(m & ~ok):
            entry["without_suspect"] = _stats(err[m & ok])
        out[t] = entry
    return out


def _fmt_pct(v) -> str:
    return "   -  " if v is None else f"{v:6.2f}"


def _print_tables(name: str, rep: dict) -> None:
    print(f"  {name}:")
    for t, entry in rep.items():
        w = entry["with_suspect"]
        line = (
            f"    {t:10s} n={w['n']:3d}  mean {_fmt_pct(w['mean_abs_pct'])} %"
            f"  max {_fmt_pct(w['max_abs_pct'])} %"
        )
        wo = entry.get("without_suspect")
        if wo:
            line += (
                f"   without suspect: mean {_fmt_pct(wo['mean_abs_pct'])} %"
                f"  max {_fmt_pct(wo['max_abs_pct'])} %"
            )
        print(line)


def run(args) -> int:
    experiments = xp.read_all(args.experiments)
    base = profiles.load(args.base) if args.base else profiles.default()
    base = _parse_set(args.set, base)
    for key in ("name", "description"):
        if getattr(args, key):
            base = base.with_values({key: getattr(args, key)})
    compare = [m.strip() for m in args.compare.split(",") if m.strip()]
    for m in compare:
        if m not in MODELS:
            raise UsageError(f"--compare: unknown model '{m}' (models: {', '.join(MODELS)})")
    ev = _Evaluator(experiments, args.full)
    fit_mask = np.array([args.include_suspect or not e.suspect for e in experiments])
    log = (lambda s: print(s, file=sys.stderr)) if args.json else print
    result = None
    profile = base
    t0 = time.perf_counter()
    if not args.no_fit:
        specs = DEFAULT_FIT[args.model] if args.fit is None else tuple(args.fit)
        if not specs:
            raise UsageError(f"nothing to fit: model {args.model} has no parameters; use --fit")
        params = [fitting.parse_param(s, base) for s in specs]
        log(
            f"fitting {len(params)} parameter(s) of model {args.model} on "
            f"{int(fit_mask.sum())} of {len(experiments)} measurements"
        )

        def residuals(values):
            prof = base.with_values(values)
            return (ev.predict(prof, args.model) / ev.meas - 1.0)[fit_mask]

        result = fitting.fit(params, residuals, args.objective, log=log)
        values = {}
        for p in params:
            for path in p.paths:
                values[path] = result.values[p.name]
        profile = base.with_values(values)
    elapsed = time.perf_counter() - t0
    reports = {}
    preds = {}
    for m in compare:
        pred = ev.predict(profile, m)
        preds[m] = pred
        reports[m] = table_report(experiments, pred / ev.meas - 1.0)
    if args.per_test:
        _write_per_test(args.per_test, experiments, ev.meas, preds)
    if args.out:
        if result is None:
            raise UsageError("--out needs a fit (drop --no-fit)")
        header = _header(args, result, reports.get(args.model))
        profiles.save(profile, args.out, header)
    out = {
        "model": args.model,
        "measurements": len(experiments),
        "fitted": None
        if result is None
        else {p: {"value": v, "rel_std": result.rel_std.get(p)} for p, v in result.values.items()},
        "evaluations": None if result is None else result.evaluations,
        "fit_seconds": elapsed,
        "errors": reports,
    }
    if args.json:
        print(json.dumps(out, default=_json_default))
        return 0
    if result is not None:
        n_eval = result.evaluations
        print(f"fitted ({n_eval} evaluations, {elapsed:.0f} s, objective {result.objective}):")
        for p, v in result.values.items():
            rs = result.rel_std.get(p)
            unc = "" if rs is None or not math.isfinite(rs) else f"  (+/- {rs * 100:.1f} %)"
            print(f"  {p} = {v:.6g}{unc}")
    print("absolute relative error of each model per table:")
    for m, rep in reports.items():
        _print_tables(m, rep)
    if args.out:
        print(f"wrote {args.out}")
    return 0


def _json_default(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return float(o)


def _write_per_test(path, experiments, meas, preds) -> None:
    import csv

    try:
        with open(path, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(["table", "test", "suspect", "measured_s", *[f"{m}_s" for m in preds]])
            for i, e in enumerate(experiments):
                w.writerow(
                    [e.table, e.name, int(e.suspect), f"{meas[i]:g}"]
                    + [f"{preds[m][i]:.6g}" for m in preds]
                )
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from exc


def command_line(args) -> str:
    """The `contour fit-profile` command that reproduces this fit."""
    q = shlex.quote
    parts = ["contour", "fit-profile", "--experiments", *[q(e) for e in args.experiments]]
    if args.base:
        parts += ["--base", q(args.base)]
    for s in args.set:
        parts += ["--set", q(s)]
    for key in ("name", "description"):
        if getattr(args, key):
            parts += [f"--{key}", q(getattr(args, key))]
    parts += ["--model", args.model]
    if args.fit is not None:
        parts += ["--fit", *[q(f) for f in args.fit]]
    if args.objective != "mean-abs":
        parts += ["--objective", args.objective]
    if args.include_suspect:
        parts.append("--include-suspect")
    if args.full:
        parts.append("--full")
    if args.out:
        parts += ["--out", q(args.out)]
    return " ".join(parts)


def _header(args, result, rep) -> str:
    lines = [
        "Fitted by `contour fit-profile`; regenerate (from the repository root) with:",
        "  " + command_line(args),
        f"Model {args.model}, objective {result.objective}; fitted values:",
    ]
    for p, v in result.values.items():
        lines.append(f"  {p} = {v:.6g}")
    if rep:
        for t, entry in rep.items():
            w = entry["with_suspect"]
            line = f"  {t}: mean abs error {w['mean_abs_pct']:.2f} % (max {w['max_abs_pct']:.1f} %)"
            wo = entry.get("without_suspect")
            if wo:
                line += f", without suspect rows {wo['mean_abs_pct']:.2f} %"
            lines.append(line)
    return "\n".join(lines)
