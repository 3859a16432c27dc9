"""The circle test of Lacerda (1998): one revolution scored after a lead-in
and settling, run through the drive's own planner, interpolator and loops.

Path (XY plane, circle centre at the origin of the path frame, machine
coordinates shifted so that the axes start at 0):

1. a positioning move from the start to the lead-in point with an exact
   stop, then a dwell of 0.2 s;
2. a tangential lead-in line of length ``max(5 mm, 2 v^2 / a_max)`` ending on
   the circle at angle 0, in the direction of travel;
3. ``settle + 1`` full-circle arc blocks (the drive cuts them into chords and
   interpolates the exact arc); ``settle`` = the revolutions needed for at
   least ``settle_s`` seconds (at least one);
4. a short tangential lead-out line so that the final deceleration is off
   the circle.

Scoring, over the last full revolution of the reference (the interval in
which the unwrapped reference angle sweeps its last 2 pi before the
lead-out): contour error ``e = |P - C| - R`` of the true table position P
(positive outside), ``iae_mm_s`` = integral of |e| dt (mm s),
``max_contour_error_mm`` = max |e|, ``circular_deviation_mm`` = max e - min e
(ISO 230-4 circular deviation about the nominal centre: the thesis's
"circularity error", which it does not define).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from contour.errors import UserError
from contour.sim import core, machine

CONTROLLERS = ("pid", "cec-tangent", "cec-curvature", "cec-exact")
FEEDFORWARD = ("none", "velocity", "full")


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

    def as_dict(self) -> dict:
        """JSON fields (docs/conventions.md: errors in um as in `sim run`; the
        `_mm` error fields are kept for readers of earlier output)."""
        d = asdict(self)
        d["iae_um_s"] = self.iae_mm_s * 1e3
        d["max_contour_error_um"] = self.max_contour_error_mm * 1e3
        d["circular_deviation_um"] = self.circular_deviation_mm * 1e3
        d["mean_radial_error_um"] = self.mean_radial_error_mm * 1e3
        return d


@dataclass
class CircleRun:
    result: CircleResult
    trace: np.ndarray  # rows of the scored revolution: t, x, y (table), ex (m)
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
) -> CircleRun:
    check_args(radius_mm, feed_mm_min, direction, controller, feedforward)
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
    hz = so.sim_tick_hz()
    r = radius_mm * 1e-3
    v = feed_mm_min / 60000.0
    if v > m.planner["v_max"]:
        raise UserError(f"feed {feed_mm_min} mm/min exceeds the planner's v_max")
    sense = 1 if direction == "ccw" else -1
    t_rev = 2 * math.pi * r / v
    settle = max(1, math.ceil(settle_s / t_rev))
    lead = max(5e-3, 2 * v * v / m.planner["a_max"])
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
        pending.append(("arc", on_circle, 0, False))
    out_y = on_circle[1] + int(round(sense * 2e-3 * nm))
    pending.append(("line", (0, out_y, 0), 0, True))

    rows = []
    tag = 1
    max_ticks = int((t_rev * (settle + 1) + 4 * lead / v + 10.0) * hz)
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
        chunk = core.run(max(1, hz // 20))
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
    res = score(full, cx, cy, r, sense, settle)
    st = core.status()
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
        **res["scores"],
    )
    return CircleRun(result=result, trace=res["trace"], full=full)


def score(full: np.ndarray, cx: float, cy: float, r: float, sense: int, settle: int) -> dict:
    """Scores of the last full revolution of the reference (see module doc)."""
    t = full[:, 0]
    rx, ry = full[:, 4] - cx, full[:, 8] - cy
    px, py = full[:, 5] - cx, full[:, 9] - cy
    on = np.abs(np.hypot(rx, ry) - r) < 1e-6 * max(r, 1e-3) + 2e-9
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
    scores = {
        "iae_mm_s": float(np.abs(es).sum() * dt * 1e3),
        "max_contour_error_mm": float(np.abs(es).max() * 1e3),
        "circular_deviation_mm": float((es.max() - es.min()) * 1e3),
        "mean_radial_error_mm": float(es.mean() * 1e3),
    }
    trace = np.column_stack([t[sel], px[sel], py[sel], es])
    return {"scores": scores, "trace": trace}
