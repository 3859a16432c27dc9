"""Model ``feed``: distance over programmed feed, what CAM systems print.

Every segment takes ``60 * length / F`` seconds (G0 at the profile's
``rapid_feed_mm_min``), plus its dwell. No acceleration, no cornering, no
block processing time: on short-segment finishing programs it is 2.5 to 4
times too optimistic (Camargo 2017), which is why the other models exist.
"""

from __future__ import annotations

import numpy as np

from contour.estimation.profile import Profile
from contour.estimation.result import Estimate, Moves

NAME = "feed"
OPTIONS = ()


def estimate(moves: Moves, profile: Profile, options: dict) -> Estimate:
    t = 60.0 * moves.length / moves.feed
    return Estimate(
        model=NAME,
        moves=moves,
        time_s=t + moves.dwell_s,
        min_time_s=np.zeros(len(moves)),
        options={},
    )
