"""Model ``camargo2017``: the empirical block-time model of Camargo (2017).

Implemented as specified in ``../shared/models/camargo2017.md`` (HERMLE
C1200V / iTNC530, coefficients fixed by the thesis; only the MRT, the
option ``mrt_s`` or else the profile's ``min_block_time_s``, is a machine
parameter). Each transition
between two consecutive segments gets a time TES, the maximum over the
axes X, Y, Z of:

- Case 1 (constant direction and sense, processing limit):
  ``TES1 = max(60 * l_med / F, MRT)``, written with per-segment feeds as
  ``max(30 * (l1 / F1 + l2 / F2), MRT)``, which is the thesis's formula when
  F1 = F2.
- Case 2 (direction change, sense constant) with ``S1``/``S2`` the larger and
  smaller absolute displacement of the axis: 2A ``a(S1) * S2 + b(S1)`` (Y, or
  X/Z coefficients) when the axis's displacements are smaller than every
  displacement of the other axes, else 2B (Y's fit, all axes).
- Case 3 (the axis reverses): ``(f(|s1|) + f(|s2|)) / 2``.

A segment's time is half the TES of each of its two transitions; the
program time is their sum plus the end segments (option ``end_segments``)
plus dwells. A dwell breaks the chain (the machine stops). A segment that
moves no linear axis (rotary only) is timed alone by Case 1 and also breaks
the chain. Exact stop (G60/G61) is not part of the model. A computed TES is
never negative.

The thesis's lost flowchart leaves seven choices open; each is an option
below (:data:`OPTIONS`), set in the profile's ``[camargo2017]`` table or with
``--option``, and every estimate reports the values it used.
"""

from __future__ import annotations

import math

import numpy as np

from contour.estimation.fields import Field
from contour.estimation.result import Estimate, Moves

NAME = "camargo2017"

OPTIONS = (
    Field(
        "mrt_s",
        "s",
        0.0,
        "MRT of the model (0.45 ms on the HERMLE/iTNC530); 0: use the profile's "
        "motion.min_block_time_s.",
        "",
        zero_ok=True,
    ),
    Field(
        "collinear_rule",
        "",
        "case1",
        "Open choice 1. Collinear segments of different lengths: 'case1' (all "
        "axes in Case 1, as Experiment 1 measured 0.45 ms for them) or 'case2' "
        "(only axes whose displacement is unchanged are Case 1).",
        "",
        choices=("case1", "case2"),
    ),
    Field(
        "collinear_tolerance_deg",
        "degree",
        0.1,
        "Two segments are collinear when their directions differ by less than this angle.",
        "",
    ),
    Field(
        "unchanged_axis_rule",
        "",
        "case1",
        "Open choice 2. An axis whose displacement does not change between the "
        "two segments: 'case1' (not limiting) or 'case2'.",
        "",
        choices=("case1", "case2"),
    ),
    Field(
        "unchanged_axis_tolerance_mm",
        "mm",
        0.0005,
        "Open choice 2. Displacements closer than this are 'unchanged' (CAM "
        "coordinates never repeat exactly); default half the 0.001 mm increment.",
        "",
    ),
    Field(
        "case2a_rule",
        "",
        "strict",
        "Open choice 3. When Case 2A applies: 'strict' (both displacements of "
        "the axis smaller than every displacement, in either segment, of the "
        "other axes that move in either segment) or 'below-max' (the larger "
        "displacement S1 smaller than the largest displacement of the other "
        "axes). Otherwise 2B.",
        "",
        choices=("strict", "below-max"),
    ),
    Field(
        "zero_axis_rule",
        "",
        "case2",
        "Open choice 4. An axis that is zero in one segment and moves in the "
        "other: 'case2' (a direction change with S2 = 0), 'case3' (half a "
        "reversal: f(S1)/2) or 'case1' (not limiting).",
        "",
        choices=("case2", "case3", "case1"),
    ),
    Field(
        "case2_max_mm",
        "mm",
        0.2,
        "Open choice 5. Case 2 was fitted for 0.001 <= S2 < S1 <= 0.2 mm and "
        "explodes beyond: an axis with S1 above this uses Case 1.",
        "",
    ),
    Field(
        "floor_at_case1",
        "",
        True,
        "Open choice 6. Floor every TES at TES1 (nothing runs faster than the "
        "programmed feed and the MRT allow).",
        "",
    ),
    Field(
        "end_segments",
        "",
        "half-case1",
        "Open choice 7. 'half-case1': add half of the first and last segment's "
        "Case 1 time; 'none': leave them out.",
        "",
        choices=("half-case1", "none"),
    ),
    Field(
        "case2b_s1_term",
        "",
        "+0.056",
        "The thesis prints the S1 term of 2B as -0.056 in one equation and "
        "+0.056 in the combined one; +0.056 reproduces its data.",
        "",
        choices=("+0.056", "-0.056"),
    ),
)

_ZERO = 1e-9
_CHUNK = 65536  # transitions per vectorised batch (bounds the memory)


def defaults() -> dict:
    return {f.name: f.default for f in OPTIONS}


def _case3(s, is_y):
    """f(S) of Case 3, seconds, for displacement magnitudes s (mm)."""
    s = np.maximum(s, 0.0)
    return np.where(is_y, 0.107 * s**0.394, 0.1015 * s**0.4966)


def _case2a(s1, s2, is_y):
    with np.errstate(divide="ignore", invalid="ignore"):
        ln = np.log(np.maximum(s1, 1e-300))
    a_y = np.where(s1 < 0.038, 0.2596 * ln + 0.3855, 1.6991 * s1 - 0.5266)
    b_y = 0.3844 * s1 + 0.0103
    a_x = np.where(s1 < 0.071, 0.1564 * ln + 0.2430, 1.014 * s1 - 0.2423)
    b_x = 0.1684 * s1 + 0.0066
    return np.where(is_y, a_y * s2 + b_y, a_x * s2 + b_x)


def _case2b(s1, s2, l_med, c):
    return (0.4 * s1 + 0.0017) * l_med + (-0.146 * s1 - 0.2289) * s2 + c * s1 + 0.027


def transitions(d1, d2, t1, t2, mrt, opts):
    """TES (s) and case labels of transitions between segments d1 -> d2.

    ``d1``, ``d2`` (m, 3) displacements in mm; ``t1``, ``t2`` the feed times
    60 * l / F of the two segments (s). Returns (tes, tes1, case) with
    ``case`` the limiting case per transition: 1, 2 (2A), 3 (2B) or 4 (3).
    """
    m = d1.shape[0]
    l1 = np.sqrt(np.einsum("ij,ij->i", d1, d1))
    l2 = np.sqrt(np.einsum("ij,ij->i", d2, d2))
    l_med = 0.5 * (l1 + l2)
    tes1 = np.maximum(0.5 * (t1 + t2), mrt)
    a1 = np.abs(d1)
    a2 = np.abs(d2)
    moves1 = a1 > _ZERO
    moves2 = a2 > _ZERO
    is_y = np.zeros((m, 3), dtype=bool)
    is_y[:, 1] = True

    with np.errstate(divide="ignore", invalid="ignore"):
        cosang = np.einsum("ij,ij->i", d1, d2) / (l1 * l2)
    collinear = cosang >= math.cos(math.radians(opts["collinear_tolerance_deg"]))

    reversal = moves1 & moves2 & (np.sign(d1) != np.sign(d2))
    both_zero = ~moves1 & ~moves2
    one_zero = moves1 ^ moves2
    unchanged = (
        moves1 & moves2 & ~reversal & (np.abs(a1 - a2) <= opts["unchanged_axis_tolerance_mm"])
    )
    s1 = np.maximum(a1, a2)
    s2 = np.minimum(a1, a2)

    # Which axes use which case (before the per-transition maximum).
    case1 = both_zero.copy()
    if opts["unchanged_axis_rule"] == "case1":
        case1 |= unchanged
    zr = opts["zero_axis_rule"]
    case3 = reversal.copy()
    if zr == "case1":
        case1 |= one_zero
    elif zr == "case3":
        case3 |= one_zero
    if opts["collinear_rule"] == "case1":
        case1 |= collinear[:, None] & ~reversal
    case2 = ~case1 & ~case3
    large = case2 & (s1 > opts["case2_max_mm"])
    case1 |= large
    case2 &= ~large

    # 2A or 2B: compare with the other axes that move in either segment.
    inf = np.inf
    moving_axis = moves1 | moves2
    other_min = np.empty((m, 3))
    other_max = np.empty((m, 3))
    for i in range(3):
        others = [j for j in range(3) if j != i]
        lo = np.full(m, inf)
        hi = np.full(m, -inf)
        for j in others:
            mj = moving_axis[:, j]
            lo = np.where(mj, np.minimum(lo, np.minimum(a1[:, j], a2[:, j])), lo)
            hi = np.where(mj, np.maximum(hi, np.maximum(a1[:, j], a2[:, j])), hi)
        other_min[:, i] = lo
        other_max[:, i] = hi
    if opts["case2a_rule"] == "strict":
        is_2a = s1 < other_min
    else:
        is_2a = s1 < other_max
    is_2a &= np.isfinite(other_min)

    c = 0.056 if opts["case2b_s1_term"] == "+0.056" else -0.056
    tes_axis = np.broadcast_to(tes1[:, None], (m, 3)).copy()
    lm = np.broadcast_to(l_med[:, None], (m, 3))
    t2a = _case2a(s1, s2, is_y)
    t2b = _case2b(s1, s2, lm, c)
    t3 = 0.5 * (_case3(a1, is_y) + _case3(a2, is_y))
    label = np.ones((m, 3), dtype=np.int8)
    sel = case2 & is_2a
    tes_axis[sel] = t2a[sel]
    label[sel] = 2
    sel = case2 & ~is_2a
    tes_axis[sel] = t2b[sel]
    label[sel] = 3
    tes_axis[case3] = t3[case3]
    label[case3] = 4
    tes_axis = np.maximum(tes_axis, 0.0)
    if opts["floor_at_case1"]:
        tes_axis = np.maximum(tes_axis, tes1[:, None])
    k = np.argmax(tes_axis, axis=1)
    rows = np.arange(m)
    tes = tes_axis[rows, k]
    case = label[rows, k]
    # A transition whose maximum equals TES1 is Case 1 whatever labels tie.
    case = np.where(tes <= tes1, 1, case).astype(np.int8)
    return tes, tes1, case


def estimate(moves: Moves, profile, options: dict) -> Estimate:
    opts = dict(profile.options("camargo2017")) if profile is not None else defaults()
    opts.update(options)
    mrt = float(opts["mrt_s"]) or float(profile.motion["min_block_time_s"])
    n = len(moves)
    t_feed = 60.0 * moves.length / moves.feed
    t_case1 = np.where(moves.length > 0, np.maximum(t_feed, mrt), 0.0)
    xyz = np.sqrt(np.einsum("ij,ij->i", moves.delta, moves.delta)) > _ZERO
    time = np.zeros(n)
    min_time = np.zeros(n)
    # Rotary-only segments: Case 1 alone.
    rot_only = (moves.length > 0) & ~xyz
    time[rot_only] = t_case1[rot_only]
    min_time[rot_only] = np.where(t_feed[rot_only] < mrt, mrt, 0.0)

    idx = np.nonzero(xyz)[0]
    counts = {"case1": 0, "case2a": 0, "case2b": 0, "case3": 0}
    if idx.size:
        a = idx[:-1]
        b = idx[1:]
        # Chain breaks: a dwell after a (or on a row between a and b), or a
        # rotary-only segment between them.
        dw_cum = np.concatenate(([0.0], np.cumsum(moves.dwell_s)))
        dwell_between = (dw_cum[b] - dw_cum[a]) > 0
        ro_cum = np.concatenate(([0], np.cumsum(rot_only)))
        rot_between = (ro_cum[b] - ro_cum[a + 1]) > 0
        linked = ~(dwell_between | rot_between)
        la, lb = a[linked], b[linked]
        parts = [
            transitions(
                moves.delta[la[k : k + _CHUNK]],
                moves.delta[lb[k : k + _CHUNK]],
                t_feed[la[k : k + _CHUNK]],
                t_feed[lb[k : k + _CHUNK]],
                mrt,
                opts,
            )
            for k in range(0, la.size, _CHUNK)
        ] or [(np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int8))]
        tes, tes1, case = (np.concatenate(x) for x in zip(*parts))
        np.add.at(time, la, 0.5 * tes)
        np.add.at(time, lb, 0.5 * tes)
        at_mrt = (case == 1) & (tes1 <= mrt)
        np.add.at(min_time, la, np.where(at_mrt, 0.5 * tes, 0.0))
        np.add.at(min_time, lb, np.where(at_mrt, 0.5 * tes, 0.0))
        for name, code in (("case1", 1), ("case2a", 2), ("case2b", 3), ("case3", 4)):
            counts[name] = int(np.count_nonzero(case == code))
        # Chain ends get half of their Case 1 time.
        if opts["end_segments"] == "half-case1":
            has_prev = np.zeros(n, dtype=bool)
            has_next = np.zeros(n, dtype=bool)
            has_prev[lb] = True
            has_next[la] = True
            for mask in (~has_prev, ~has_next):
                ends = idx[mask[idx]]
                time[ends] += 0.5 * t_case1[ends]
                min_time[ends] += np.where(t_feed[ends] < mrt, 0.5 * mrt, 0.0)
    used = dict(opts)
    used["min_block_time_s"] = mrt
    used["transitions"] = counts
    return Estimate(
        model=NAME,
        moves=moves,
        time_s=time + moves.dwell_s,
        min_time_s=min_time,
        options=used,
    )
