"""Model ``mrt``: feed limited by a minimum block time (Coelho et al. 2009).

Each segment runs at its programmed feed unless it is shorter than
``l_min = MRT * F / 60`` (MRT: the profile's ``min_block_time_s``), in
which case it takes MRT. It is Case 1 of camargo2017 applied to every
segment. The thesis measured it at -59 % to -75 % on real finishing
programs: it knows the control's block rate but nothing of its dynamics.
"""

from __future__ import annotations

import numpy as np

from contour.estimation.profile import Profile
from contour.estimation.result import Estimate, Moves

NAME = "mrt"
OPTIONS = ()


def estimate(moves: Moves, profile: Profile, options: dict) -> Estimate:
    mrt = float(profile.motion["min_block_time_s"])
    t_feed = 60.0 * moves.length / moves.feed
    moving = moves.length > 0
    capped = moving & (t_feed < mrt)
    t = np.where(capped, mrt, t_feed)
    return Estimate(
        model=NAME,
        moves=moves,
        time_s=t + moves.dwell_s,
        min_time_s=np.where(capped, mrt, 0.0),
        options={"min_block_time_s": mrt},
    )
