"""The circle test of Lacerda (1998): one revolution scored after a lead-in
and settling, run through the drive's own planner, interpolator and loops.

Path (XY plane, circle centre at the origin of the path frame, machine
coordinates shifted so that the axes start at 0):

1. a positioning move from the start to the lead-in point with an exact
   stop, then a dwell of 0.2 s;
2. a tangential lead-in line of length ``max(5 mm, 2 v^2 / a_max)`` ending on
   the circle at angle 0, in the direction of travel;
3. ``settle + 1`` full-circle arc blocks (the drive cuts them into chords and
   interpolates the exact arc), or with ``chords = N`` the same revolutions
   as N G1 lines each, as a CAM system writes a circle (the firmware then
   sees straight lines only: no arc geometry reaches the CEC);
   ``settle`` = the revolutions needed for at least ``settle_s`` seconds
   (at least one);
4. a tangential lead-out line at least 1.5 times the planner's stopping
   distance from the feed (``stop_distance``), so that the final
   deceleration is off the circle.

Honest conditions: before anything runs, ``limits`` checks the stated feed
against the machine description's planner limits on the circle (v_max,
centripetal acceleration v^2/R <= a_max, jerk v^3/R^2 <= j_max, per axis).
A circle the planner cannot run at the stated feed is refused (UserError
naming the limit) unless ``allow_limited`` is given; then it runs and the
result's ``limited_by`` names the limit. Either way the result reports the
reference's measured path speed over the scored revolution
(``min_feed_mm_min``, ``mean_feed_mm_min``); a revolution whose minimum is
below 99 % of the stated feed is always flagged in ``limited_by``.

Scoring, over the last full revolution of the reference (the interval in
which the unwrapped reference angle sweeps its last 2 pi before the
lead-out): contour error ``e = |P - C| - R`` of the true table position P
(positive outside), sampled by the simulator's instrument at the plant's
substeps, at least ``SCORE_HZ`` whatever the tick (``sim_table_record``:
the path the table really traces, as a ballbar sees it; a table mode above
half the tick rate is scored whole, not aliased), ``score_hz`` the rate;
``tick_scores`` has the same scores from one sample per tick (the drive's
own trace rows: a diagnostic; at 10 kHz on a machine without friction the
two are the same samples), ``iae_mm_s`` = integral of |e| dt (mm s),
``max_contour_error_mm`` = max |e| (with chords, e includes the chords'
sagitta R (1 - cos(pi / N)), the path as programmed),
``circular_deviation_mm`` = max e - min e
(ISO 230-4 circular deviation about the nominal centre: the thesis's
"circularity error", which it does not define).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from contour.errors import UserError
from contour.sim import core, machine

# cec-curvature: r from the arc geometry on arcs, from the reference history
# on lines; cec-calcr: from the history always (the thesis's calcr block);
# cec-koren: Koren's straight line through the segment start; cec-chuang-liu:
# tangent + |E|^2 / (2 r) (r as cec-curvature)
CONTROLLERS = (
    "pid",
    "cec-tangent",
    "cec-curvature",
    "cec-exact",
    "cec-calcr",
    "cec-koren",
    "cec-chuang-liu",
)
FEEDFORWARD = ("none", "velocity", "full")
# the instrument's minimum sample rate (Hz): well above the table modes of
# the machine files (X 662.6 Hz, Y 948 Hz: >= 10 samples per period)
SCORE_HZ = 10000.0
# chunks of the run loop in one simulator call once every block is queued
STRETCH_CHUNKS = 100
SCORE_KEYS = ("iae_mm_s", "max_contour_error_mm", "circular_deviation_mm", "mean_radial_error_mm")


@dataclass
class CircleResult:
    radius_mm: float
    feed_mm_min: float
    direction: str
    controller: str
    feedforward: str
    machine: str
    tick_hz: float
    iae_mm_s: float
    max_contour_error_mm: float
    circular_deviation_mm: float
    mean_radial_error_mm: float
    revolution_s: float
    simulated_s: float
    edges: int
    edge_mismatch_ticks: int
    faults: list
    min_feed_mm_min: float = 0.0
    mean_feed_mm_min: float = 0.0
    limited_by: str = ""  # empty: the scored revolution ran at the stated feed
    chords: int = 0  # 0: arc blocks; N: the circle as N G1 chords
    disturbance: dict = field(default_factory=dict)  # the machine's [disturbance] (N, N/mm)
    score_hz: float = 0.0  # the instrument's sample rate of the scores above
    # the same scores from one sample per tick (diagnostic: what the drive's trace sees)
    tick_scores: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """JSON fields (docs/conventions.md: errors in um as in `sim run`; the
        `_mm` error fields are kept for readers of earlier output)."""
        d = {
            k: (None if isinstance(v, float) and math.isnan(v) else v)
            for k, v in asdict(self).items()
        }
        for k in ("iae", "max_contour_error", "circular_deviation", "mean_radial_error"):
            v = getattr(self, k + ("_mm_s" if k == "iae" else "_mm")) * 1e3
            d[k + ("_um_s" if k == "iae" else "_um")] = None if math.isnan(v) else v
        return d


@dataclass
class CircleRun:
    result: CircleResult
    trace: np.ndarray  # instrument rows of the scored revolution: t, x, y (table), ex (m)
    full: np.ndarray  # every tick of the run (sim trace rows)


def check_args(
    radius_mm: float, feed_mm_min: float, direction: str, controller: str, feedforward: str
) -> None:
    """The circle test's own limits (UserError), before anything runs."""
    if not (radius_mm > 0 and math.isfinite(radius_mm)) or radius_mm > 1000:
        raise UserError(f"radius must be in (0, 1000] mm, got {radius_mm}")
    if not (feed_mm_min > 0 and math.isfinite(feed_mm_min)) or feed_mm_min > 60000:
        raise UserError(f"feed must be in (0, 60000] mm/min, got {feed_mm_min}")
    if direction not in ("cw", "ccw"):
        raise UserError(f"direction must be cw or ccw, got {direction!r}")
    if controller not in CONTROLLERS:
        raise UserError(f"controller must be one of {', '.join(CONTROLLERS)}")
    if feedforward not in FEEDFORWARD:
        raise UserError(f"feedforward must be one of {', '.join(FEEDFORWARD)}")


FEED_TOLERANCE = 0.99  # min feed over the scored revolution / stated feed


def stop_distance(v: float, a: float, j: float) -> float:
    """Distance (m) of a jerk-limited stop from speed v (m/s) with limits a, j."""
    if v * j >= a * a:  # reaches a
        return 0.5 * v * (v / a + a / j)
    return v * math.sqrt(v / j)


def limits(radius_mm: float, feed_mm_min: float, planner: dict) -> list[str]:
    """The planner limits (machine description) that a circle of this radius
    at this feed exceeds; empty if it can run at the stated feed."""
    r = radius_mm * 1e-3
    v = feed_mm_min / 60000.0
    out = []
    if v > planner["v_max"]:
        out.append(f"v_max {planner['v_max']:g} m/s < feed {v:g} m/s")
    if v * v / r > planner["a_max"]:
        out.append(
            f"a_max {planner['a_max']:g} m/s^2 < centripetal v^2/R = {v * v / r:.4g} m/s^2 "
            f"(max feed on R {radius_mm:g} mm: "
            f"{math.sqrt(planner['a_max'] * r) * 60000:.0f} mm/min)"
        )
    if v**3 / (r * r) > planner["j_max"]:
        out.append(f"j_max {planner['j_max']:g} m/s^3 < v^3/R^2 = {v**3 / r**2:.4g} m/s^3")
    return out


def run_circle(
    radius_mm: float,
    feed_mm_min: float,
    direction: str = "ccw",
    controller: str = "pid",
    feedforward: str = "none",
    machine_file: str | None = None,
    tick_hz: float | None = None,
    settle_s: float = 0.5,
    mach: machine.Machine | None = None,
    encoder_model: str | None = None,
    allow_limited: bool = False,
    chords: int = 0,
    table_mean: bool = False,
) -> CircleRun:
    check_args(radius_mm, feed_mm_min, direction, controller, feedforward)
    if chords and not 8 <= chords <= 100000:
        raise UserError(f"chords must be 0 (arcs) or in [8, 100000], got {chords}")
    m = mach if mach is not None else machine.load(machine_file)
    if m.axes < 2:
        raise UserError(f"{m.path}: the circle test needs 2 axes")
    machine.apply(
        m,
        tick_hz=tick_hz,
        feedforward=feedforward,
        controller=controller,
        encoder_model=encoder_model,
    )
    so = core.lib()
    # diagnostic: score each table's mean over the tick (sim_trace_table_mean;
    # the mean of a circle lies r (w T / 2)^2 / 6 inside it: compare
    # circular deviations)
    core.check(so.sim_trace_table_mean(1 if table_mean else 0), "table mean")
    hz = so.sim_tick_hz()
    r = radius_mm * 1e-3
    v = feed_mm_min / 60000.0
    over = limits(radius_mm, feed_mm_min, m.planner)
    if over and not allow_limited:
        raise UserError(
            f"R {radius_mm:g} mm at {feed_mm_min:g} mm/min cannot run at the stated feed on "
            f"{m.name}: " + "; ".join(over)
        )
    sense = 1 if direction == "ccw" else -1
    t_rev = 2 * math.pi * r / v
    settle = max(1, math.ceil(settle_s / t_rev))
    a_max, j_max = m.planner["a_max"], m.planner["j_max"]
    d_stop = stop_distance(v, a_max, j_max)
    lead = max(5e-3, 2 * v * v / a_max, 1.5 * d_stop)
    lead_out = max(2e-3, 1.5 * d_stop)
    # path frame: centre (0, 0), circle start (r, 0), travel +y (ccw) / -y (cw)
    # machine frame: the start of the lead-in is the machine origin
    cx, cy = -r, sense * lead  # centre in machine coordinates
    nm = 1e9
    feed = int(round(v * nm))
    start = (0, 0, 0)
    on_circle = (0, int(round(sense * lead * nm)), 0)

    if so.sim_enable(1) != 0:
        raise UserError("simulator: the drive refused to enable")
    core.run(2, trace=False)
    pending = [("line", start, 0, True)]
    pending.append(("dwell", None, 0, False))
    pending.append(("line", on_circle, 0, False))
    for _ in range(settle + 1):
        if chords:
            for k in range(1, chords + 1):
                th = sense * 2 * math.pi * k / chords
                p = (cx + r * math.cos(th), cy + r * math.sin(th))
                pending.append(
                    ("line", (int(round(p[0] * nm)), int(round(p[1] * nm)), 0), 0, False)
                )
        else:
            pending.append(("arc", on_circle, 0, False))
    out_y = on_circle[1] + int(round(sense * lead_out * nm))
    pending.append(("line", (0, out_y, 0), 0, True))

    rows = []
    # the instrument: table positions at >= SCORE_HZ, recorded per chunk
    # (t, x, y kept: 24 bytes a sample)
    chunk_ticks = max(1, hz // 1000)
    # with every block queued, up to STRETCH_CHUNKS chunks in one call that
    # stops where this loop would (core.run_until_idle: the same ticks)
    rec = np.zeros(
        (STRETCH_CHUNKS * chunk_ticks * so.sim_substeps() + 2, rec_cols(so)), dtype=np.float64
    )
    dense = []
    tag = 1
    max_ticks = int((t_rev * (settle + 1) + 4 * (lead + lead_out) / v + 10.0) * hz)
    ticks = 0
    while True:
        while pending:
            kind, tgt, _, stop = pending[0]
            if kind == "line":
                res = core.queue_line(tgt, feed, tag, stop)
            elif kind == "dwell":
                res = core.queue_dwell(200, tag)
            else:
                res = core.queue_arc(
                    tgt, feed, 0, int(round(cx * nm)), int(round(cy * nm)), sense, tag
                )
            if res == 1:  # queue full
                break
            if res != 0:
                raise UserError(f"simulator: block refused: {core.DRIVE_RESULT.get(res, res)}")
            pending.pop(0)
            tag += 1
        core.check(so.sim_table_record(rec.ctypes.data, rec.shape[0], SCORE_HZ), "record")
        try:
            if pending:
                chunk = core.run(chunk_ticks)  # keep the host queue fed (short G1 chords)
            else:  # up to the chunk that passes max_ticks, as chunk by chunk
                n_chunks = min(STRETCH_CHUNKS, (max_ticks - ticks) // chunk_ticks + 1)
                chunk = core.run_until_idle(n_chunks * chunk_ticks, chunk_ticks)
            n = so.sim_table_recorded()
            score_hz = so.sim_table_record_hz()
        finally:
            so.sim_table_record(None, 0, 0.0)
        if n > rec.shape[0]:
            raise UserError("simulator: instrument buffer overrun")
        dense.append(rec[:n, :3].copy())
        rows.append(chunk)
        ticks += chunk.shape[0]
        st = core.status()
        if st.faults:
            break
        if not pending and st.state == 1:  # idle: done
            break
        if ticks > max_ticks:
            raise UserError("simulator: the circle did not finish in time")
    full = np.vstack(rows)
    dense_rows = np.vstack(dense)
    # a chord's reference lies inside the circle by up to its sagitta
    sag = r * (1 - math.cos(math.pi / chords)) if chords else 0.0
    st = core.status()
    try:
        res = score(full, cx, cy, r, sense, settle, sag, dense=dense_rows)
    except UserError:
        if not st.faults:
            raise
        # faulted before the scored revolution ended (e.g. a limit cycle,
        # fault "oscillation"): no scores, the faults say why
        nan = float("nan")
        res = {
            "scores": {
                k: nan
                for k in (
                    "iae_mm_s",
                    "max_contour_error_mm",
                    "circular_deviation_mm",
                    "mean_radial_error_mm",
                    "min_feed_mm_min",
                    "mean_feed_mm_min",
                )
            },
            "trace": np.zeros((0, 4)),
            "tick_scores": {},
        }
    result = CircleResult(
        radius_mm=radius_mm,
        feed_mm_min=feed_mm_min,
        direction=direction,
        controller=controller,
        feedforward=feedforward,
        machine=m.name,
        tick_hz=float(hz),
        revolution_s=t_rev,
        simulated_s=float(so.sim_time_s()),
        edges=int(so.sim_edges()),
        edge_mismatch_ticks=int(so.sim_edge_mismatches()),
        faults=core.fault_names(st.faults),
        chords=chords,
        disturbance={**m.disturbance, "f_w": m.cutting_f_w()} if m.disturbance else {},
        score_hz=float(score_hz),
        tick_scores=res["tick_scores"],
        **res["scores"],
    )
    flags = list(over)
    if math.isnan(result.min_feed_mm_min):
        flags.append("no scored revolution: faulted (" + ", ".join(result.faults) + ")")
    elif result.min_feed_mm_min < FEED_TOLERANCE * feed_mm_min:
        flags.append(
            f"measured min feed {result.min_feed_mm_min:.0f} mm/min < "
            f"{FEED_TOLERANCE:.0%} of {feed_mm_min:g}"
        )
    result.limited_by = "; ".join(flags)
    return CircleRun(result=result, trace=res["trace"], full=full)


def rec_cols(so) -> int:
    """Columns of an instrument row (sim.h SIM_REC_COLS = 1 + SIM_AXES)."""
    return 1 + (so.sim_trace_cols() - 4) // 4


def radial_scores(t: np.ndarray, e: np.ndarray, dt: float) -> dict:
    """iae, max |e|, max - min, mean of radial deviations e (m) -> mm."""
    return {
        "iae_mm_s": float(np.abs(e).sum() * dt * 1e3),
        "max_contour_error_mm": float(np.abs(e).max() * 1e3),
        "circular_deviation_mm": float((e.max() - e.min()) * 1e3),
        "mean_radial_error_mm": float(e.mean() * 1e3),
    }


def score(
    full: np.ndarray,
    cx: float,
    cy: float,
    r: float,
    sense: int,
    settle: int,
    sag: float = 0.0,
    dense: np.ndarray | None = None,
) -> dict:
    """Scores of the last full revolution of the reference (see module doc):
    the revolution is found on the trace rows (one per tick, the reference);
    the table is scored from ``dense`` (instrument rows t, x, y, at least
    10 samples) between the first and last tick of the revolution, or from
    the trace rows without it. ``tick_scores``: from the trace rows."""
    t = full[:, 0]
    rx, ry = full[:, 4] - cx, full[:, 8] - cy
    px, py = full[:, 5] - cx, full[:, 9] - cy
    on = np.abs(np.hypot(rx, ry) - r + sag / 2) < sag / 2 + 1e-6 * max(r, 1e-3) + 2e-9
    ang = np.unwrap(np.arctan2(ry, rx)) * sense
    idx = np.nonzero(on)[0]
    if idx.size < 10:
        raise UserError("simulator: the reference never reached the circle")
    a0 = ang[idx[0]]
    a_end = a0 + 2 * math.pi * (settle + 1)
    lo = a_end - 2 * math.pi
    sel = on & (ang >= lo - 1e-12) & (ang <= a_end + 1e-12)
    if np.count_nonzero(sel) < 10:
        raise UserError("simulator: the scored revolution is empty")
    e = np.hypot(px, py) - r
    es = e[sel]
    dt = np.diff(t).mean() if t.size > 1 else 0.0
    # path speed of the reference between consecutive ticks of the revolution
    isel = np.nonzero(sel)[0]
    i0, i1 = isel[0], isel[-1]
    seg = np.hypot(np.diff(rx[i0 : i1 + 1]), np.diff(ry[i0 : i1 + 1])) / np.diff(t[i0 : i1 + 1])
    tick = radial_scores(t[sel], es, dt)
    feeds = {
        "min_feed_mm_min": float(seg.min() * 60000),
        "mean_feed_mm_min": float(seg.mean() * 60000),
    }
    trace = np.column_stack([t[sel], px[sel], py[sel], es])
    if dense is None:
        return {"scores": {**tick, **feeds}, "trace": trace, "tick_scores": tick}
    # the instrument's samples from the revolution's first to last tick
    # (a sample at a tick's end is that tick's row exactly: same time)
    td = dense[:, 0]
    dsel = (td >= t[i0] - 5e-10) & (td <= t[i1] + 5e-10)
    if np.count_nonzero(dsel) < 10:
        raise UserError("simulator: the instrument recorded too few samples")
    qx, qy = dense[dsel, 1] - cx, dense[dsel, 2] - cy
    ed = np.hypot(qx, qy) - r
    ddt = np.diff(td[dsel]).mean()
    scores = radial_scores(td[dsel], ed, ddt)
    return {
        "scores": {**scores, **feeds},
        "trace": np.column_stack([td[dsel], qx, qy, ed]),
        "tick_scores": tick,
    }
