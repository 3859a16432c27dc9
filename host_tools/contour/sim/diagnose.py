"""What a circle's contour error is made of, term by term (issue 21;
docs/simulator.md "Realistic machine: what the contour error is made of"
"The 3 ms tick: where the CEC loses" and "Why no change of the CEC removes
it").

    .venv/bin/python -m contour.sim.diagnose [OUT_DIR]

prints the tables of that section and, with OUT_DIR, writes its figures.
Each row switches one term of the machine file off (or the drive's answer
to it on) and runs the circle again; the radial deviation of the true table
over the scored revolution is split into harmonics of the path angle:
h0 the mean radius error, h2 the ellipse (per-axis gain differences), h4
the quadrant glitches (friction at the reversals), and what is left above
the 8th harmonic (count noise, alias).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from contour.sim import circle, machine, tuning

R_MM, FEED = 20.0, 10000.0


def radial(tr: np.ndarray, r_mm: float) -> tuple:
    """(angle rad, radial deviation um) of a scored trace (rows t, x, y)."""
    x, y = tr[:, 1], tr[:, 2]
    return np.arctan2(y, x), (np.hypot(x, y) - r_mm * 1e-3) * 1e6


def harmonics(tr: np.ndarray, r_mm: float, kmax: int = 8) -> tuple:
    """Amplitudes (um) of harmonics 0..4 and the peak-to-peak of what is
    left above kmax."""
    ang, rad = radial(tr, r_mm)
    cols = [np.ones_like(ang)]
    for k in range(1, kmax + 1):
        cols += [np.cos(k * ang), np.sin(k * ang)]
    m = np.column_stack(cols)
    c, *_ = np.linalg.lstsq(m, rad, rcond=None)
    amp = [abs(c[0])] + [math.hypot(c[2 * k - 1], c[2 * k]) for k in range(1, 5)]
    return amp, float(np.ptp(rad - m @ c))


def run(
    name: str,
    ctl: str,
    mod=None,
    r_mm=R_MM,
    feed=FEED,
    tick=None,
    d="ccw",
    settle=0.5,
    table_mean=False,
):
    m = machine.load(name)
    if mod:
        mod(m)
    return circle.run_circle(
        r_mm,
        feed,
        d,
        controller=ctl,
        feedforward="full",
        mach=m,
        tick_hz=tick,
        allow_limited=True,
        settle_s=settle,
        table_mean=table_mean,
    )


def dev_um(cr, score: str = "instrument") -> float:
    """Circular deviation (um) of a run as scored ("instrument": the table at
    the plant's substeps, as `make run` scores) or from one sample per tick
    ("tick": the diagnostic; the score of the 3 ms analyses below, which
    were made with it)."""
    if score == "tick":
        return cr.result.tick_scores.get("circular_deviation_mm", float("nan")) * 1e3
    return cr.result.circular_deviation_mm * 1e3


def _no_coulomb(m):
    for a in m.axis.values():
        a.update(coulomb_motor=0.0, coulomb_table=0.0)


def _exact_ff(m):
    m.feedforward.update(scale_x=1.0, scale_y=1.0)


def _before(m):
    m.feedforward.update(quadrant_comp=0, learn_rate=0.0)


def _both(*fs):
    def f(m):
        for g in fs:
            g(m)

    return f


REALISTIC_ROWS = [
    ("without the drive's compensations", _before),
    ("  without Coulomb friction", _both(_before, _no_coulomb)),
    ("  feed-forward gains exact", _both(_before, _exact_ff)),
    ("  friction fed forward 100 %", _both(_before, lambda m: m.feedforward.update(friction=1.0))),
    ("  neither friction nor gain error", _both(_before, _no_coulomb, _exact_ff)),
    ("+ quadrant-glitch compensation", lambda m: m.feedforward.update(learn_rate=0.0)),
    ("+ feed-forward learning (shipped)", None),
]


def realistic_table(log=print) -> dict:
    log(f"Realistic machine, R {R_MM:g} mm, {FEED:g} mm/min, ccw; um")
    log("| case | pid dev | pid h2 | pid h4 | cec dev | cec h2 | cec h4 |")
    log("|---|---:|---:|---:|---:|---:|---:|")
    traces = {}
    for lab, mod in REALISTIC_ROWS:
        cells = []
        for ctl in ("pid", "cec-curvature"):
            cr = run("realistic", ctl, mod)
            h, _ = harmonics(cr.trace, R_MM)
            cells += [cr.result.circular_deviation_mm * 1e3, h[2], h[4]]
            traces[(lab, ctl)] = cr.trace
        log(f"| {lab.strip()} | " + " | ".join(f"{v:.2f}" for v in cells) + " |")
    return traces


C3_CASES = [(10, 10000), (10, 20000), (20, 10000), (20, 20000), (20, 30000), (50, 10000)]
C3_ROWS = [
    ("thesis.toml as shipped", None),
    (
        "encoder 1e5 lines (no count)",
        lambda m: [a.update(encoder_lines=100000) for a in m.axis.values()],
    ),
    ("X table as Y (I2 3.5e-6)", lambda m: m.axis["x"].update(I2=3.5e-6)),
]


def c3_table(log=print) -> None:
    log(
        "\n3 ms tick (thesis.toml), full feed-forward, circular deviation pid / cec-curvature,"
        " um, one sample per tick"
    )
    log("| case | " + " | ".join(f"R {r} {f // 1000} m/min" for r, f in C3_CASES) + " |")
    log("|---|" + "---:|" * len(C3_CASES))
    for lab, mod in C3_ROWS:
        cells = []
        for r, f in C3_CASES:
            a = dev_um(run("thesis", "pid", mod, r, f), "tick")
            b = dev_um(run("thesis", "cec-curvature", mod, r, f), "tick")
            cells.append(f"{a:.2f} / {b:.2f}")
        log(f"| {lab} | " + " | ".join(cells) + " |")


NINE = [(r, f) for r in (10, 20, 50) for f in (10000, 20000, 30000)]


def _cec_scale(k: float):
    def f(m):
        for key in ("kp", "ki", "kd"):
            m.gains["cec"][key] *= k

    return f


def _ideal_measure(m):
    m.axis["x"].update(I2=m.axis["y"]["I2"])
    for a in m.axis.values():
        a.update(encoder_lines=1e6)


WHY_ROWS = [  # label, machine change, CEC gain scale (for Ms), settle s
    ("CEC gains x 0.1", _cec_scale(0.1), 0.1, 0.5),
    ("CEC gains x 0.3", _cec_scale(0.3), 0.3, 0.5),
    ("shipped (x 1)", None, 1.0, 0.5),
    ("X table as Y, 1e6 lines", _ideal_measure, None, 0.5),
    ("the same, 3 s before the scored revolution", _ideal_measure, None, 3.0),
]


def why_table(log=print, rows=WHY_ROWS, cases=NINE) -> list:
    """C3 with the CEC's gains scaled and with the measurement made ideal:
    circular deviation pid / cec-curvature (um, one sample per tick), the
    number of cases the CEC is worse in, and the sampled loop's Ms along the
    normal (X / Y). Returns per row the (pid, cec) pairs."""
    m0 = machine.load("thesis")
    loops = {ax: tuning.Loop(m0.axis[ax], m0.tick_hz) for ax in ("x", "y")}
    ms0 = [loops[ax].margins(m0.gains[ax]).ms for ax in ("x", "y")]
    log(
        "\nC3, why the CEC loses: pid / cec-curvature, um, one sample per tick "
        f"(Ms of the PIDs alone {ms0[0]:.2f} / {ms0[1]:.2f})"
    )
    log("| case | Ms X / Y | " + " | ".join(f"R{r} {f // 1000}" for r, f in cases) + " | worse |")
    log("|---|---|" + "---:|" * (len(cases) + 1))
    out = []
    for lab, mod, k, settle in rows:
        ms = ""
        if k is not None:
            g = {
                key: v * (k if key in ("kp", "ki", "kd") else 1)
                for key, v in m0.gains["cec"].items()
            }
            ms = " / ".join(f"{loops[ax].margins(m0.gains[ax], g).ms:.2f}" for ax in ("x", "y"))
        cells, pairs, worse = [], [], 0
        for r, f in cases:
            a = dev_um(run("thesis", "pid", mod, r, f, settle=settle), "tick")
            b = dev_um(run("thesis", "cec-curvature", mod, r, f, settle=settle), "tick")
            worse += b > a
            pairs.append((a, b))
            cells.append(f"{a:.2f} / {b:.2f}")
        out.append(pairs)
        log(f"| {lab} | {ms} | " + " | ".join(cells) + f" | {worse} |")
    return out


MEAN_ROWS = [  # label, machine, settle s, table's tick mean in the trace, score
    ("thesis.toml (one sample per tick)", "thesis", 0.5, False, "tick"),
    ("  scored on the table's mean over the tick", "thesis", 0.5, True, "tick"),
    ("  scored on the instrument (>= 10 kHz)", "thesis", 0.5, False, "instrument"),
    ("thesis_mean.toml (mean measurement), one sample per tick", "thesis_mean", 0.5, False, "tick"),
    ("  3 s before the scored revolution", "thesis_mean", 3.0, False, "tick"),
    ("  scored on the table's mean over the tick", "thesis_mean", 0.5, True, "tick"),
    ("  scored on the instrument (>= 10 kHz: make run)", "thesis_mean", 0.5, False, "instrument"),
]


def mean_table(log=print, rows=MEAN_ROWS, cases=NINE) -> list:
    """C3 with the mean measurement (drive.h enc_mean): circular deviation
    pid / cec-curvature (um) and the number of cases the CEC is worse in,
    scored on one sample of the table per tick, on the table's mean over
    the tick (sim_trace_table_mean: the X table's 662.6 Hz mode, which no
    loop at 333 Hz can act on, averaged out) and on the instrument (the
    table at the plant's substeps, its vibration whole: `make run`).
    Returns per row the (pid, cec) pairs."""
    log("\nC3, the mean measurement: pid / cec-curvature circular deviation, um")
    log("| case | " + " | ".join(f"R{r} {f // 1000}" for r, f in cases) + " | worse |")
    log("|---|" + "---:|" * (len(cases) + 1))
    out = []
    for lab, name, settle, tm, score in rows:
        cells, pairs, worse = [], [], 0
        for r, f in cases:
            a, b = (
                dev_um(run(name, c, None, r, f, settle=settle, table_mean=tm), score)
                for c in ("pid", "cec-curvature")
            )
            worse += b > a
            pairs.append((a, b))
            cells.append(f"{a:.2f} / {b:.2f}")
        out.append(pairs)
        log(f"| {lab.strip()} | " + " | ".join(cells) + f" | {worse} |")
    return out


def alias_table(log=print) -> dict:
    """Motor encoder minus true table position on X, R 20 mm at 20 m/min,
    PIDs: its fit on the reference velocity, per tick rate."""
    log("\nX motor encoder - table, R 20 mm 20 m/min, PIDs: um per m/s of X velocity, std um")
    log("| tick | X per m/s | X std | Y per m/s | Y std |")
    log("|---|---:|---:|---:|---:|")
    out = {}
    for hz in (333, 300, 400):
        cr = run("thesis", "pid", None, 20, 20000, hz)
        t0, t1 = cr.trace[0, 0], cr.trace[-1, 0]
        f = cr.full[(cr.full[:, 0] >= t0) & (cr.full[:, 0] <= t1)]
        cells = []
        for ir, it, im in ((4, 5, 6), (8, 9, 10)):
            d = (f[:, im] - f[:, it]) * 1e6
            v = np.gradient(f[:, ir], f[:, 0])
            a = np.column_stack([np.ones_like(v), v])
            c, *_ = np.linalg.lstsq(a, d, rcond=None)
            cells += [c[1], d.std()]
        out[hz] = f
        log(f"| {hz} Hz | " + " | ".join(f"{v:.2f}" for v in cells) + " |")
    return out


def figures(out: Path, traces: dict, alias: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4))
    for (lab, ctl), style in (
        ((REALISTIC_ROWS[0][0], "pid"), "C0-"),
        ((REALISTIC_ROWS[0][0], "cec-curvature"), "C1-"),
        ((REALISTIC_ROWS[-2][0], "pid"), "C0:"),
        ((REALISTIC_ROWS[-1][0], "cec-curvature"), "C2-"),
    ):
        ang, rad = radial(traces[(lab, ctl)], R_MM)
        o = np.argsort(np.degrees(ang) % 360)
        ax.plot((np.degrees(ang) % 360)[o], rad[o], style, label=f"{ctl}: {lab.strip()}", lw=1)
    ax.set_xlabel("path angle (deg, ccw from +X)")
    ax.set_ylabel("radial deviation of the table (um)")
    ax.set_title(f"realistic.toml, R {R_MM:g} mm, {FEED:g} mm/min, 10 kHz, full feed-forward")
    ax.set_xticks(range(0, 361, 45))
    ax.grid(True)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "realistic_radial.png", dpi=80)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(9, 3.5))
    for hz, f in alias.items():
        ax.plot(f[:, 0] - f[0, 0], (f[:, 6] - f[:, 5]) * 1e6, lw=1, label=f"{hz} Hz")
    ax.set_xlabel("time in the scored revolution (s)")
    ax.set_ylabel("X encoder - X table (um)")
    ax.set_title("thesis.toml, PIDs, R 20 mm, 20 m/min: X table mode 662.6 Hz vs 2 x tick")
    ax.grid(True)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "c3_alias.png", dpi=80)
    plt.close(fig)


# The sweep of "CEC never worse than the PIDs" (docs/simulator.md, "Outside
# the tables: the sweep"): id -> machine file, feed-forward (make run's
# set-ups, demo.SETUPS, and F).
SWEEP_SETUPS = {
    "A": ("default", "none"),
    "B": ("thesis", "none"),
    "C10": ("default_mean", "full"),
    "C3": ("thesis_mean", "full"),
    "F": ("realistic", "full"),
}
SWEEP_RADII = (5, 7.5, 10, 15, 20, 25, 30, 40, 50, 75, 100)
SWEEP_FEEDS = (2, 3, 5, 7.5, 10, 15, 20, 25, 30)
SWEEP_CTL = ("pid", "cec-curvature", "cec-exact")


def sweep(
    setups=tuple(SWEEP_SETUPS),
    radii=SWEEP_RADII,
    feeds=SWEEP_FEEDS,
    dirs=("ccw", "cw"),
    log=print,
) -> list:
    """Every controller of SWEEP_CTL on a grid of circles (R mm, feed m/min)
    at the stated feed (the ones the planner limits are left out), scored as
    `make run` scores them; rows of dicts (circular deviation and max error
    in um)."""
    rows = []
    for sid in setups:
        name, ff = SWEEP_SETUPS[sid]
        m = machine.load(name)
        for r in radii:
            for f in feeds:
                if circle.limits(r, f * 1000, m.planner):
                    continue
                for d in dirs:
                    for ctl in SWEEP_CTL:
                        x = circle.run_circle(
                            r, f * 1000, d, controller=ctl, feedforward=ff, mach=m
                        )
                        rows.append(
                            {
                                "setup": sid,
                                "radius_mm": r,
                                "feed_m_min": f,
                                "direction": d,
                                "controller": ctl,
                                "circular_deviation_um": x.result.circular_deviation_mm * 1e3,
                                "max_contour_error_um": x.result.max_contour_error_mm * 1e3,
                                "mean_radial_error_um": x.result.mean_radial_error_mm * 1e3,
                            }
                        )
            log(f"{sid}: {sum(x['setup'] == sid for x in rows)} runs")
    return rows


def sweep_worse(rows: list, tol: float = 0.01) -> list:
    """(setup, R, feed, direction, controller, score, pid, cec) for every CEC
    row worse than the PIDs alone by more than tol in circular deviation
    ("cd") or max error ("max")."""
    pid = {
        (x["setup"], x["radius_mm"], x["feed_m_min"], x["direction"]): x
        for x in rows
        if x["controller"] == "pid"
    }
    out = []
    for x in rows:
        p = pid.get((x["setup"], x["radius_mm"], x["feed_m_min"], x["direction"]))
        if x["controller"] == "pid" or p is None:
            continue
        for lab, k in (("cd", "circular_deviation_um"), ("max", "max_contour_error_um")):
            if x[k] > (1 + tol) * p[k]:
                key = (x["setup"], x["radius_mm"], x["feed_m_min"], x["direction"])
                out.append((*key, x["controller"], lab, p[k], x[k]))
    return out


def sweep_main(argv: list) -> int:
    """`python -m contour.sim.diagnose sweep [SETUPS]`: the sweep and its
    worse rows (SETUPS: comma-separated ids, any case, default all). An
    unknown id is refused before any circle runs (not after the ids before
    it have run)."""
    setups = [s.strip().upper() for s in argv[0].split(",")] if argv else list(SWEEP_SETUPS)
    bad = [s for s in setups if s not in SWEEP_SETUPS]
    if bad:
        print(
            f"sweep: unknown set-up {', '.join(bad)} (known: {', '.join(SWEEP_SETUPS)})",
            file=sys.stderr,
        )
        return 2
    rows = sweep(setups)
    worse = sweep_worse(rows)
    for sid in setups:
        n = sum(x["setup"] == sid and x["controller"] != "pid" for x in rows)
        w = {w[:5] for w in worse if w[0] == sid}
        print(f"{sid}: {len(w)} of {n} CEC rows worse than the PIDs by > 1 %")
    for w in worse:
        sid, r, f, d, ctl, score, p, c = w
        print(f"  {sid} R {r:g} mm {f:g} m/min {d} {ctl} {score}: pid {p:.3f}, cec {c:.3f} um")
    return 0


def main(argv: list) -> int:
    if argv and argv[0] == "sweep":
        return sweep_main(argv[1:])
    traces = realistic_table()
    c3_table()
    why_table()
    mean_table()
    alias = alias_table()
    if argv:
        out = Path(argv[0])
        out.mkdir(parents=True, exist_ok=True)
        figures(out, traces, alias)
        print(f"\nwritten: {out}/realistic_radial.png, {out}/c3_alias.png")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
