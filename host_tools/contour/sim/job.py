"""`contour sim run FILE.nc`: a G-code job through the drive's planner and
loops on the simulated machine.

The file is read through :func:`contour.program.chunks` in two passes, as
``contour run`` reads it: the first checks every block
(:func:`contour.link.blocks.check_gcode`, against the protocol and the
machine's velocity limit) and collects the report; the second queues lines,
rapids (at the planner's v_max), arcs (the drive's own arc blocks) and dwells
as the drive accepts them. Reported: executed time (first tick with motion to the last
tick before idle), following error (|reference - table| per axis), contour
error = the distance of the true table position from the reference path
(the polyline of the reference positions of all ticks, searched in a window
around the current tick, extended along its first and last tangent so that an
overshoot at the end of the job counts as following error only), and faults.

Streaming: the host tops the drive's block queue up whenever half of it is
free (``sim_run_until_free``), as a host streaming over a link does, so the
drive's planner keeps its full look-ahead and each block is planned exactly
as the estimator plans it: :func:`estimate_job` runs the drive's planner
(host build, ``contour.planner``) over the same blocks, with the profile read
back from the simulated drive and the arcs cut into the drive's own chords
(``drive_arc_chords``), and gives the time the job takes on the drive.
"""

from __future__ import annotations

import math

import numpy as np

from contour import gcode
from contour.errors import UserError
from contour.link.blocks import DriveLimits, check_gcode
from contour.program import chunks
from contour.sim import core, machine

RAPID_M_S = 0.5


def machine_limits(m) -> DriveLimits:
    """What the simulated drive of machine `m` takes (no soft limits)."""
    v = int(round(m.planner["v_max"] * 1e9))
    return DriveLimits(max_velocity_nm_s=(v, v, v))


def _all_blocks(path, m, default_feed, tool_table=None) -> list:
    out = []
    for prog in chunks(path, default_feed=default_feed, tool_table=tool_table):
        out.extend(_blocks(prog, m))
    return out


def _blocks(prog, m) -> list:
    """(kind, target_nm, feed_nm_s, extra) tuples for the drive."""
    out = []
    rapid = min(RAPID_M_S, m.planner["v_max"])
    prev = np.array(prog.start[:3], dtype=float)
    for i in range(len(prog)):
        kind = int(prog.kind[i])
        end = np.array(prog.end[i, :3], dtype=float)
        tgt = tuple(int(round(v * 1e6)) for v in end)
        if kind == gcode.DWELL:
            out.append(("dwell", None, 0, int(round(prog.dwell_s[i] * 1000))))
            continue
        feed_mm_min = float(prog.feed[i]) if kind != gcode.RAPID else rapid * 60000
        if not math.isfinite(feed_mm_min) or feed_mm_min <= 0:
            raise UserError(f"{prog.path}:{int(prog.line[i])}: no feed for this move")
        feed = int(round(min(feed_mm_min / 60000.0, m.planner["v_max"]) * 1e9))
        stop = bool(prog.exact_stop[i])
        if kind in (gcode.ARC_CW, gcode.ARC_CCW):
            plane = int(prog.plane[i])
            u, v = {0: (0, 1), 1: (2, 0), 2: (1, 2)}[plane]
            c = prog.centre[i]
            sense = 1 if kind == gcode.ARC_CCW else -1
            cu, cv = int(round(c[u] * 1e6)), int(round(c[v] * 1e6))
            for _ in range(int(prog.turns[i])):
                start = tuple(int(round(x * 1e6)) for x in prev)
                out.append(("arc", start, feed, (plane, cu, cv, sense, False)))
            out.append(("arc", tgt, feed, (plane, cu, cv, sense, stop)))
        else:
            out.append(("line", tgt, feed, stop))
        prev = end
    return out


def _queue(b, tag: int) -> int:
    kind, tgt, feed, extra = b
    if kind == "dwell":
        return core.queue_dwell(max(1, extra), tag)
    if kind == "line":
        return core.queue_line(tgt, feed, tag, extra)
    plane, cu, cv, sense, _stop = extra
    return core.queue_arc(tgt, feed, plane, cu, cv, sense, tag)


def _polyline_distance(p: np.ndarray, a, dv, d2, open_start: bool, open_end: bool) -> float:
    """Distance of point p from the segments a[j] + t dv[j], t in [0, 1]
    (d2 = |dv|^2); open_start / open_end: the first / last segment goes on
    along its tangent (overshoot past a path's end is not contour error)."""
    t = ((p - a) * dv).sum(axis=1) / d2
    t_lo = np.zeros_like(t)
    t_hi = np.ones_like(t)
    if open_start:
        t_lo[0] = -np.inf
    if open_end:
        t_hi[-1] = np.inf
    t = np.clip(t, t_lo, t_hi)
    q = a + dv * t[:, None]
    return float(np.sqrt(((p - q) ** 2).sum(axis=1).min()))


def contour_errors(ref: np.ndarray, act: np.ndarray, window: int) -> np.ndarray:
    """Distance of each act point from the polyline ref[i - window .. i + window]."""
    n = ref.shape[0]
    out = np.empty(n)
    a = ref[:-1]
    d = ref[1:] - ref[:-1]
    dd = np.maximum((d * d).sum(axis=1), 1e-30)
    for i in range(n):
        lo, hi = max(0, i - window), min(n - 1, i + window)
        if hi <= lo:
            out[i] = float(np.linalg.norm(act[i] - ref[i]))
            continue
        out[i] = _polyline_distance(act[i], a[lo:hi], d[lo:hi], dd[lo:hi], lo == 0, hi == n - 1)
    return out


def path_errors(path: np.ndarray, act: np.ndarray) -> np.ndarray:
    """Distance of each act point from the whole polyline `path` (the
    programmed path, e.g. the blocks sent to a drive), extended along its
    first and last tangent as in contour_errors: the contour error of
    samples that carry no time index into the path (telemetry)."""
    keep = np.ones(path.shape[0], dtype=bool)
    keep[1:] = np.any(path[1:] != path[:-1], axis=1)  # repeated points: no segment
    path = path[keep]
    if path.shape[0] < 2:
        return np.linalg.norm(act - path[0], axis=1)
    a = path[:-1]
    d = path[1:] - path[:-1]
    dd = (d * d).sum(axis=1)
    return np.array([_polyline_distance(p, a, d, dd, True, True) for p in act])


def run_job(
    path: str,
    controller: str = "cec-exact",
    feedforward: str = "none",
    machine_file: str | None = None,
    tick_hz: float | None = None,
    default_feed: float | None = None,
    max_s: float = 600.0,
    contour_error: bool = True,
    encoder_model: str | None = None,
    tool_table=None,
) -> dict:
    m = machine.load(machine_file)
    checked = check_gcode(
        path, default_feed=default_feed, limits=machine_limits(m), tool_table=tool_table
    )
    blocks = _all_blocks(path, m, default_feed, tool_table)
    if not blocks:
        raise UserError(f"{path}: no motion blocks")
    machine.apply(
        m,
        tick_hz=tick_hz,
        feedforward=feedforward,
        controller=controller,
        encoder_model=encoder_model,
    )
    so = core.lib()
    hz = so.sim_tick_hz()
    if so.sim_enable(1) != 0:
        raise UserError("simulator: the drive refused to enable")
    core.run(2, trace=False)
    rows = []
    pending = list(blocks)
    tag = 1
    ticks = 0
    while True:
        while pending:
            res = _queue(pending[0], tag)
            if res == 1:
                break
            if res != 0:
                raise UserError(
                    f"{path}: block {tag} refused by the drive: {core.DRIVE_RESULT.get(res, res)}"
                )
            pending.pop(0)
            tag += 1
        if pending:  # top the queue up as soon as half of it is free
            chunk = core.run_until_free(max(1, hz // 20), core.DRIVE_QUEUE_DEPTH // 2)
        else:
            chunk = core.run(max(1, hz // 20), every=1)
        rows.append(chunk)
        ticks += chunk.shape[0]
        st = core.status()
        if st.faults or (not pending and st.state == 1):
            break
        if ticks > max_s * hz:
            raise UserError(f"{path}: the job did not finish within {max_s:g} s of machine time")
    full = np.vstack(rows)
    n_ax = m.axes
    ref = np.column_stack([full[:, 4 + 4 * i] for i in range(n_ax)])
    act = np.column_stack([full[:, 5 + 4 * i] for i in range(n_ax)])
    moving = np.nonzero(np.any(np.abs(np.diff(ref, axis=0)) > 0, axis=1))[0]
    if moving.size:
        t0, t1 = full[moving[0], 0], full[moving[-1] + 1, 0]
    else:
        t0 = t1 = 0.0
    # dwells before the first and after the last motion take time too
    lead = trail = 0.0
    for b in blocks:
        if b[0] != "dwell":
            break
        lead += max(1, b[3]) / 1000.0
    for b in reversed(blocks):
        if b[0] != "dwell":
            break
        trail += max(1, b[3]) / 1000.0
    if not moving.size:
        lead, trail = lead + trail, 0.0
    ferr = np.abs(ref - act).max(axis=1)
    speed = np.linalg.norm(np.diff(ref, axis=0), axis=1).max() * hz if ref.shape[0] > 1 else 0
    lag_ticks = int(ferr.max() / max(speed, 1e-9) * hz) if speed > 0 else 10
    window = int(min(4000, max(200, 4 * lag_ticks)))
    sel = slice(moving[0], moving[-1] + 2) if moving.size else slice(0, 0)
    if moving.size and contour_error:
        ec = contour_errors(ref[sel], act[sel], window)
    else:  # not asked for (contour_error=False): reported as 0
        ec = np.zeros(1)
    st = core.status()
    return {
        "file": str(path),
        "blocks": len(blocks),
        "executed_s": float(t1 - t0) + lead + trail,
        "dwell_s": sum(max(1, b[3]) / 1000.0 for b in blocks if b[0] == "dwell"),
        "end_mm": [float(v) * 1e3 for v in ref[-1]] if ref.shape[0] else [0.0] * n_ax,
        "max_contour_error_um": float(ec.max() * 1e6),
        "rms_contour_error_um": float(np.sqrt((ec**2).mean()) * 1e6),
        "max_following_error_um": float(ferr.max() * 1e6),
        "faults": core.fault_names(st.faults),
        "edge_mismatch_ticks": int(so.sim_edge_mismatches()),
        "tick_hz": float(hz),
        "controller": controller,
        "feedforward": feedforward,
        "machine": m.name,
        "skipped": checked.report.as_dicts(),
    }


CORNERS = {0: "junction-deviation", 1: "velocity-step", 2: "smoothed-corner", 3: "exact-stop"}


def drive_profile(axes: int, tick_hz: int):
    """The running simulated drive's planner profile as a
    :class:`contour.planner.PlannerProfile` (read with drive_param_get)."""
    from contour.planner import SHAPES, PlannerProfile

    shapes = {v: k for k, v in SHAPES.items()}

    def per_axis(name: str, scale: float) -> list:
        return [core.drive_param(name, min(i, axes - 1)) / scale for i in range(3)]

    window = core.drive_param("mbt_window")
    return PlannerProfile(
        v_max_mm_s=per_axis("v_max", 1e6),
        a_max_mm_s2=per_axis("a_max", 1e6),
        j_max_mm_s3=per_axis("j_max", 1e6),
        corner_dv_mm_s=per_axis("corner_dv", 1e6),
        corner_acc_mm_s2=per_axis("corner_acc", 1e6),
        shape=shapes[core.drive_param("shape")],
        corner=CORNERS[core.drive_param("corner")],
        junction_deviation_mm=core.drive_param("junction_dev") / 1e6,
        min_block_time_s=core.drive_param("min_block_ns") / 1e9,
        block_time_rule="cap" if window == 1 else "throughput",
        mbt_window=window,
        tick_hz=int(tick_hz),
        depth=64,
    )


def estimate_job(
    path: str,
    machine_file: str | None = None,
    tick_hz: float | None = None,
    default_feed: float | None = None,
    tool_table=None,
) -> dict:
    """The drive's planner estimate of `path` on the simulated machine: the
    blocks :func:`run_job` queues, arcs cut into the drive's chords, planned
    by the drive's planner (host build) with the drive's profile.

    ``executed_s`` is the time the drive's interpolator takes (the planned
    total rounded up to whole ticks); ``total_s`` the planned total."""
    from contour.planner import Planner

    m = machine.load(machine_file)
    check_gcode(path, default_feed=default_feed, limits=machine_limits(m), tool_table=tool_table)
    blocks = _all_blocks(path, m, default_feed, tool_table)
    if not blocks:
        raise UserError(f"{path}: no motion blocks")
    machine.apply(m, tick_hz=tick_hz)
    hz = int(core.lib().sim_tick_hz())
    prof = drive_profile(m.axes, hz)
    chord = core.drive_param("arc_chord")
    pos = np.zeros(3, dtype=np.int64)  # the simulated drive starts at the origin
    pts, feeds, stops, dwells, joins = [], [], [], [], []
    arc_open = None  # (plane, centre, sense) of the arc the last chord belongs to
    for kind, tgt, feed, extra in blocks:
        if kind == "dwell":
            pts.append(pos.copy())
            feeds.append(1.0)
            stops.append(True)
            dwells.append(max(1, extra) / 1000.0)
            joins.append(False)
            arc_open = None
            continue
        f_mm_min = feed * 60.0 / 1e6
        if kind == "line":
            ends = [np.array(tgt, dtype=np.int64)]
            flags = [bool(extra)]
            join = [False]
            arc_open = None
        else:
            plane, cu, cv, sense, _stop = extra
            ends = list(core.arc_chords(pos, tgt, feed, plane, cu, cv, sense, m.axes, hz, chord))
            flags = [False] * len(ends)  # arcs are queued without exact stop
            # as the drive's feed.c: every chord after the first joins the
            # arc; the first joins an arc about the same centre before it
            key = (plane, cu, cv, sense)
            join = [arc_open == key] + [True] * (len(ends) - 1)
            arc_open = key
        for e, fl, jn in zip(ends, flags, join):
            pts.append(e)
            feeds.append(f_mm_min)
            stops.append(fl)
            dwells.append(0.0)
            joins.append(jn)
        pos = np.array(ends[-1], dtype=np.int64)
    res = Planner(prof).estimate(
        np.array(pts, dtype=float) / 1e6,
        np.array(feeds),
        exact_stop=np.array(stops),
        dwell_s=np.array(dwells),
        arc_join=np.array(joins),
    )
    return {
        "file": str(path),
        "blocks": len(blocks),
        "planner_blocks": len(pts),
        "total_s": res.total_s,
        "executed_s": res.executed_s,
        "ticks": res.ticks,
        "tick_hz": hz,
    }
