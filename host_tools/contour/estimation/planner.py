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
its own limit). Segments that move only rotary axes have no length for the
three-axis planner and take no time; their count is reported.
"""

from __future__ import annotations

import re

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


_BLOCK_ERR = re.compile(r"^block (\d+): (.*)$")


def run(moves: Moves, profile):
    """Raw :class:`contour.planner.EstimateResult` for prepared moves."""
    from contour.planner import Planner

    planner = Planner(planner_profile(profile))
    ends = np.cumsum(moves.delta, axis=0)
    try:
        return planner.estimate(
            ends,
            moves.feed,
            exact_stop=moves.exact_stop,
            dwell_s=moves.dwell_s,
            tags=np.asarray(moves.line, dtype=np.uint32),
        )
    except UserError as exc:
        m = _BLOCK_ERR.match(str(exc))
        if m and int(m.group(1)) < len(moves):
            line = int(moves.line[int(m.group(1))])
            raise UserError(f"line {line}: planner: {m.group(2)}") from None
        raise


def estimate(moves: Moves, profile, options: dict) -> Estimate:
    res = run(moves, profile)
    b = res.blocks
    rot_only = int(np.count_nonzero((moves.length > 0) & b["skipped"] & (moves.dwell_s == 0)))
    used = {
        "corner_rule": profile.motion["corner_rule"],
        "velocity_profile": profile.motion["velocity_profile"],
        "block_time_rule": profile.motion["block_time_rule"],
        "lookahead_blocks": profile.motion["lookahead_blocks"],
        "executed_s": res.executed_s,
    }
    if rot_only:
        used["rotary_only_segments_not_timed"] = rot_only
    return Estimate(
        model=NAME,
        moves=moves,
        time_s=b["t_total_s"].copy(),
        min_time_s=b["t_mbt_s"].copy(),
        accel_s=b["t_acc_s"].copy(),
        cruise_s=b["t_cruise_s"].copy(),
        decel_s=b["t_dec_s"].copy(),
        entry_mm_min=b["v_entry_mm_s"] * 60.0,
        peak_mm_min=b["v_peak_mm_s"] * 60.0,
        exit_mm_min=b["v_exit_mm_s"] * 60.0,
        options=used,
    )
