"""Model ``planner``: the drive's own look-ahead planner, host build.

The segments go, in one call, through :mod:`contour.planner` (ctypes) into
``plan_estimate()`` of ``firmware/core/estimator.c``: the same C code that
plans the drive's motion, with the profile's limits. Nothing of the time law
is computed here; this module only converts units and names:

=============================  ==========================================
profile field                  planner (contour.planner.PlannerProfile)
=============================  ==========================================
axes.*.max_velocity_mm_min     v_max_mm_s (/ 60)
axes.*.max_acceleration_mm_s2  a_max_mm_s2
axes.*.max_jerk_mm_s3          j_max_mm_s3
axes.*.corner_acceleration..   corner_acc_mm_s2 (smoothed-corner rule)
axes.*.corner_velocity_step..  corner_dv_mm_s (/ 60, velocity-step rule)
motion.corner_rule             corner
motion.junction_deviation_mm   junction_deviation_mm
motion.velocity_profile        shape
motion.min_block_time_s        min_block_time_s
motion.block_time_rule         block_time_rule
motion.min_block_time_window.. mbt_window
motion.lookahead_blocks        depth
=============================  ==========================================

G0 moves run at ``rapid_feed_mm_min`` (the planner still holds each axis to
its own limit). Rotary axes (machine-axis kinematics, no tool-tip
transformation): a block that moves A/B/C with X/Y/Z is planned on its X Y Z
path with its feed capped by the rotary velocity limits
(:class:`~contour.estimation.result.Moves`; the rotary acceleration is not
a constraint of the three-axis planner); a block that moves only rotary axes
comes to rest before and after (the planner sees no motion) and is timed rest
to rest with the rotary velocity and acceleration limits.
"""

from __future__ import annotations

import numpy as np

from contour.errors import UserError
from contour.estimation.result import Estimate, Moves

NAME = "planner"
OPTIONS = ()


def planner_profile(profile):
    """The :class:`contour.planner.PlannerProfile` of a machine profile."""
    from contour.planner import PlannerProfile

    m = profile.motion
    return PlannerProfile(
        v_max_mm_s=[v / 60.0 for v in profile.axis_values("max_velocity_mm_min")],
        a_max_mm_s2=profile.axis_values("max_acceleration_mm_s2"),
        j_max_mm_s3=profile.axis_values("max_jerk_mm_s3"),
        shape=m["velocity_profile"],
        corner=m["corner_rule"],
        junction_deviation_mm=m["junction_deviation_mm"],
        corner_dv_mm_s=[v / 60.0 for v in profile.axis_values("corner_velocity_step_mm_min")],
        corner_acc_mm_s2=profile.axis_values("corner_acceleration_mm_s2"),
        min_block_time_s=m["min_block_time_s"],
        block_time_rule=m["block_time_rule"],
        mbt_window=m["min_block_time_window_blocks"],
        depth=m["lookahead_blocks"],
    )


def run(moves: Moves, profile):
    """Raw :class:`contour.planner.EstimateResult` for prepared moves."""
    from contour.planner import BlockRefused, Planner

    planner = Planner(planner_profile(profile))
    ends = np.cumsum(moves.delta, axis=0)
    stop = moves.exact_stop
    ro = moves.rotary_only
    if np.any(ro):  # the linear axes rest while only rotary axes move
        stop = stop | ro
        stop[:-1] |= ro[1:]
    try:
        return planner.estimate(
            ends,
            moves.feed,
            exact_stop=stop,
            dwell_s=moves.dwell_s,
            tags=np.asarray(moves.line, dtype=np.uint32),
        )
    except BlockRefused as exc:
        if exc.index < len(moves):
            raise UserError(f"line {int(moves.line[exc.index])}: planner: {exc.reason}") from None
        raise


def rest_to_rest_s(distance, v, a) -> np.ndarray:
    """Time of a rest-to-rest trapezoidal move (arrays, any unit)."""
    d = np.abs(np.asarray(distance, dtype=float))
    v = np.asarray(v, dtype=float)
    a = np.asarray(a, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d * a >= v * v, d / v + v / a, 2.0 * np.sqrt(d / a))
    return np.where(d > 0, t, 0.0)


def rotary_only_times(moves: Moves, profile) -> np.ndarray:
    """Rest-to-rest time of each segment that moves only rotary axes (0
    elsewhere): each rotary axis at its share of the feed (degrees/min along
    the rotary move) and its acceleration limit; the slowest axis counts."""
    out = np.zeros(len(moves))
    sel = moves.rotary_only
    if not np.any(sel):
        return out
    rot = np.abs(moves.rotary[sel])
    norm = np.sqrt(np.einsum("ij,ij->i", rot, rot))
    v = moves.feed[sel, None] / 60.0 * rot / norm[:, None]
    vmax = np.asarray(profile.rotary_values("max_velocity_deg_min"), dtype=float) / 60.0
    amax = np.asarray(profile.rotary_values("max_acceleration_deg_s2"), dtype=float)
    v = np.minimum(v, vmax)
    out[sel] = rest_to_rest_s(rot, np.maximum(v, 1e-12), amax).max(axis=1)
    return out


def estimate(moves: Moves, profile, options: dict) -> Estimate:
    res = run(moves, profile)
    b = res.blocks
    t_rot = rotary_only_times(moves, profile)
    used = {
        "corner_rule": profile.motion["corner_rule"],
        "velocity_profile": profile.motion["velocity_profile"],
        "block_time_rule": profile.motion["block_time_rule"],
        "lookahead_blocks": profile.motion["lookahead_blocks"],
        "executed_s": res.executed_s + float(t_rot.sum()),
    }
    return Estimate(
        model=NAME,
        moves=moves,
        time_s=b["t_total_s"] + t_rot,
        min_time_s=b["t_mbt_s"].copy(),
        accel_s=b["t_acc_s"].copy(),
        cruise_s=b["t_cruise_s"].copy(),
        decel_s=b["t_dec_s"].copy(),
        entry_mm_min=b["v_entry_mm_s"] * 60.0,
        peak_mm_min=b["v_peak_mm_s"] * 60.0,
        exit_mm_min=b["v_exit_mm_s"] * 60.0,
        options=used,
    )
