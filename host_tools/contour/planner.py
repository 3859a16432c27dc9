"""The drive's look-ahead planner, host build, through ctypes.

The job-time estimator and the simulator call the firmware's own planner
(``firmware/core/planner.c`` + ``estimator.c`` in ``build/host/libcontour.so``):
an estimate is the plan the drive's interpolator executes, block for block.

Usage::

    from contour.planner import Planner, PlannerProfile

    prof = PlannerProfile(v_max_mm_s=(500, 500, 500), a_max_mm_s2=(2000,) * 3,
                          j_max_mm_s3=(50000,) * 3, corner="smoothed-corner",
                          corner_acc_mm_s2=(300, 150, 300), min_block_time_s=0.00045)
    res = Planner(prof).estimate(points_mm, feed_mm_min=15000)
    res.total_s, res.blocks["t_total_s"]

Units at this interface: mm, mm/min (feed), mm/s, mm/s², mm/s³, s. The C side
works in integer nm, nm/s, nm/s², nm/s³ and ns (docs/planner.md); positions
are rounded to the nearest nm.

Profile options (see docs/planner.md for the rules):

- ``shape``: ``"s-curve"`` (jerk-limited, acceleration zero at block ends),
  ``"trapezoid"``, ``"s-curve-at-rest"`` (S-curve for a block whose entry or
  exit speed is 0, trapezoid for every other block) or ``"s-curve-continuous"``
  (jerk-limited with the path acceleration continuous across blocks: runs of
  blocks planned as one profile; not with ``"smoothed-corner"``).
- ``corner``: ``"junction-deviation"`` (the drive's default, with
  ``junction_deviation_mm``), ``"velocity-step"`` (per-axis ``corner_dv_mm_s``),
  ``"smoothed-corner"`` (per-axis ``corner_acc_mm_s2``: v = min_i sqrt(a_i l /
  |du_i|), and each block runs no faster than the larger of its two corner
  speeds: blocks["corner_capped"]) or ``"exact-stop"``. Every rule stops at an
  axis reversal.
- ``min_block_time_s`` with ``block_time_rule``: ``"throughput"`` (a block runs
  no faster than the mean length of its last ``mbt_window`` blocks per
  min_block_time: runs of short blocks take min_block_time each, a single
  short block between long ones is not slowed) or ``"cap"`` (window 1: every
  block takes at least min_block_time).
- ``depth``: look-ahead depth in blocks (the drive: 64).
- ``tick_hz``: interpolator tick rate; ``executed_s`` is the total rounded up to
  whole ticks, which is what the drive's interpolator takes.

``PlannerProfile()`` is a drive never configured: every default is the drive's
parameter default (the generated table ``protocol_gen.PARAM_BY_NAME``: the
continuous S-curve, junction deviation); ``PlannerProfile.from_params`` reads a
drive's parameters.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from contour import native
from contour import protocol_gen as pg
from contour.errors import UserError

AXES = 3
NM_PER_MM = 1_000_000
NS_PER_S = 1_000_000_000

SHAPES = {"s-curve": 0, "trapezoid": 1, "s-curve-at-rest": 2, "s-curve-continuous": 3}
CORNERS = {"junction-deviation": 0, "velocity-step": 1, "smoothed-corner": 2, "exact-stop": 3}
SHAPE_NAMES = {v: k for k, v in SHAPES.items()}
CORNER_NAMES = {v: k for k, v in CORNERS.items()}
BLOCK_TIME_RULES = ("throughput", "cap")

# limits of the C side (scurve.h)
V_LIMIT_NM_S = 4294967295
A_RANGE_NM_S2 = (1000, 1_000_000_000_000)
J_RANGE_NM_S3 = (1000, 100_000_000_000_000)
WINDOW_MAX = 64

# plan_result_t
_ERRORS = {
    -1: "planner ring full",
    -2: "nothing to pop",
    -3: "feed must be > 0 and at most 4294 mm/s",
    -4: "block too long (over 1.1 km) or position out of range",
    -5: "invalid profile value",
    -6: "invalid argument",
}

# flags
BF_EXACT_STOP = 0x01
BF_DWELL = 0x02
BF_MBT = 0x04
BF_CORNER = 0x10
EST_SKIPPED = 0x100
MOVE_EXACT_STOP = 0x01
MOVE_ARC_JOIN = 0x02


_Profile = native.PlanProfile  # plan_profile_t (firmware/core/planner.h)
MOVE_DTYPE = native.PLAN_MOVE_DTYPE  # plan_move_t
EST_DTYPE = native.PLAN_EST_DTYPE  # plan_est_t (firmware/core/estimator.h)


class BlockRefused(UserError):
    """The planner refused block `index` of an estimate (``reason``)."""

    def __init__(self, index: int, reason: str) -> None:
        super().__init__(f"block {index}: {reason}")
        self.index = index
        self.reason = reason


def _lib():
    return native.load()


def _triple(name: str, values, scale: float, low: float, high: float) -> list:
    vals = list(values) if isinstance(values, (list, tuple, np.ndarray)) else [values] * AXES
    if len(vals) != AXES:
        raise UserError(f"{name}: give {AXES} values (X, Y, Z), got {len(vals)}")
    out = []
    for v in vals:
        try:
            f = float(v)
        except (TypeError, ValueError) as exc:
            raise UserError(f"{name}: not a number: {v!r}") from exc
        if not math.isfinite(f):
            raise UserError(f"{name}: must be finite, got {v!r}")
        x = f * scale
        if not (math.isfinite(x) and low <= round(x) <= high):
            raise UserError(
                f"{name}: {f:g} is outside the planner's range [{low / scale:g}, {high / scale:g}]"
            )
        out.append(int(round(x)))
    return out


def _scalar(name: str, value, scale: float, low: float, high: float) -> int:
    return _triple(name, [value] * AXES, scale, low, high)[0]


def _drive_default(name: str) -> int:
    """The drive's default of parameter `name` (the generated parameter
    table, protocol/contour.toml): the one source of the defaults below."""
    return pg.PARAM_BY_NAME[name].default


def _named(table: dict, param: str, value: int) -> str:
    if value not in table:
        raise UserError(f"the drive's {param} is {value}, which this host tool does not know")
    return table[value]


@dataclass
class PlannerProfile:
    """Limits and rules of the planner, in mm and s (see module docstring).

    The defaults are the drive's parameter defaults (a drive that was never
    configured): its shape is the continuous S-curve."""

    v_max_mm_s: Sequence[float] = (_drive_default("max_velocity") / NM_PER_MM,) * AXES
    a_max_mm_s2: Sequence[float] = (_drive_default("max_acceleration") / NM_PER_MM,) * AXES
    j_max_mm_s3: Sequence[float] = (_drive_default("max_jerk") / NM_PER_MM,) * AXES
    shape: str = SHAPE_NAMES[_drive_default("velocity_profile")]
    corner: str = CORNER_NAMES[_drive_default("corner_rule")]
    junction_deviation_mm: float = _drive_default("junction_deviation") / NM_PER_MM
    corner_dv_mm_s: Sequence[float] = (_drive_default("corner_velocity_step") / NM_PER_MM,) * AXES
    corner_acc_mm_s2: Sequence[float] = (_drive_default("corner_acceleration") / NM_PER_MM,) * AXES
    min_block_time_s: float = _drive_default("min_block_time") / NS_PER_S
    block_time_rule: str = "throughput"
    mbt_window: int = _drive_default("min_block_window")
    tick_hz: int = 10000
    depth: int = 64

    @classmethod
    def from_params(cls, get, axes: int = AXES) -> PlannerProfile:
        """The profile of a drive whose parameter `name` (the protocol's
        names, per-axis ones as ``name.x``) reads ``get(name)`` in the
        drive's units (nm, ns): e.g. ``client.get_param``. A drive with
        fewer than 3 axes: the missing axes take the last one's limits."""

        def per_axis(name: str) -> tuple:
            return tuple(get(f"{name}.{'xyz'[min(i, axes - 1)]}") / NM_PER_MM for i in range(AXES))

        return cls(
            v_max_mm_s=per_axis("max_velocity"),
            a_max_mm_s2=per_axis("max_acceleration"),
            j_max_mm_s3=per_axis("max_jerk"),
            shape=_named(SHAPE_NAMES, "velocity_profile", get("velocity_profile")),
            corner=_named(CORNER_NAMES, "corner_rule", get("corner_rule")),
            junction_deviation_mm=get("junction_deviation") / NM_PER_MM,
            corner_dv_mm_s=per_axis("corner_velocity_step"),
            corner_acc_mm_s2=per_axis("corner_acceleration"),
            min_block_time_s=get("min_block_time") / NS_PER_S,
            mbt_window=get("min_block_window"),
        )

    def to_c(self) -> _Profile:
        p = _Profile()
        if self.shape not in SHAPES:
            raise UserError(f"shape must be one of {', '.join(SHAPES)}, got {self.shape!r}")
        if self.corner not in CORNERS:
            raise UserError(f"corner must be one of {', '.join(CORNERS)}, got {self.corner!r}")
        if self.shape == "s-curve-continuous" and self.corner == "smoothed-corner":
            raise UserError(
                "corner 'smoothed-corner' needs a per-block velocity profile: set "
                "motion.velocity_profile (e.g. 's-curve'); the default 's-curve-continuous' "
                "cannot use it (its block cap lowers a queued block's speed, which could "
                "cut a run under way)"
            )
        if self.block_time_rule not in BLOCK_TIME_RULES:
            raise UserError(
                f"block_time_rule must be one of {', '.join(BLOCK_TIME_RULES)}, "
                f"got {self.block_time_rule!r}"
            )
        p.v_max[:] = _triple("v_max_mm_s", self.v_max_mm_s, NM_PER_MM, 1, V_LIMIT_NM_S)
        p.a_max[:] = _triple("a_max_mm_s2", self.a_max_mm_s2, NM_PER_MM, *A_RANGE_NM_S2)
        p.j_max[:] = _triple("j_max_mm_s3", self.j_max_mm_s3, NM_PER_MM, *J_RANGE_NM_S3)
        p.corner_dv[:] = _triple("corner_dv_mm_s", self.corner_dv_mm_s, NM_PER_MM, 0, V_LIMIT_NM_S)
        p.corner_acc[:] = _triple(
            "corner_acc_mm_s2", self.corner_acc_mm_s2, NM_PER_MM, 0, A_RANGE_NM_S2[1]
        )
        p.junction_dev_nm = _scalar(
            "junction_deviation_mm", self.junction_deviation_mm, NM_PER_MM, 0, 1 << 40
        )
        p.min_block_ns = _scalar(
            "min_block_time_s", self.min_block_time_s, NS_PER_S, 0, 10 * NS_PER_S
        )
        window = 1 if self.block_time_rule == "cap" else int(self.mbt_window)
        if not 1 <= window <= WINDOW_MAX:
            raise UserError(f"mbt_window must be 1..{WINDOW_MAX}, got {self.mbt_window!r}")
        p.mbt_window = window
        p.corner = CORNERS[self.corner]
        p.shape = SHAPES[self.shape]
        if not (isinstance(self.tick_hz, int) and 1 <= self.tick_hz <= 1_000_000):
            raise UserError(f"tick_hz must be a whole number 1..1000000, got {self.tick_hz!r}")
        if NS_PER_S % self.tick_hz:
            raise UserError(f"tick_hz must divide 1e9 (a whole number of ns), got {self.tick_hz}")
        if not (isinstance(self.depth, int) and 2 <= self.depth <= 65535):
            raise UserError(f"depth must be a whole number 2..65535, got {self.depth!r}")
        return p


@dataclass
class EstimateResult:
    """Per-block results (numpy structured array ``blocks``) and totals."""

    blocks: np.ndarray
    total_s: float  # sum of the planned block times
    ticks: int  # interpolator ticks the drive takes (rounded up)
    executed_s: float  # ticks / tick_hz
    t_acc_s: float = 0.0
    t_cruise_s: float = 0.0
    t_dec_s: float = 0.0
    t_mbt_s: float = 0.0
    raw: Optional[np.ndarray] = field(default=None, repr=False)


BLOCK_FIELDS = (
    "length_mm",
    "v_entry_mm_s",
    "v_peak_mm_s",
    "v_exit_mm_s",
    "v_max_mm_s",
    "t_acc_s",
    "t_cruise_s",
    "t_dec_s",
    "t_total_s",
    "t_mbt_s",
)


class Planner:
    """The drive's planner with one profile; ``estimate`` runs a whole program."""

    def __init__(self, profile: PlannerProfile):
        self.profile = profile
        self._c = profile.to_c()
        lib = _lib()
        rc = lib.plan_check_profile(ctypes.byref(self._c))
        if rc != 0:
            raise UserError(f"planner profile rejected: {_ERRORS.get(rc, rc)}")
        self._lib = lib

    def estimate(
        self,
        points_mm,
        feed_mm_min,
        exact_stop=None,
        dwell_s=None,
        start_mm=(0.0, 0.0, 0.0),
        tags=None,
        arc_join=None,
    ) -> EstimateResult:
        """Plan a program of absolute end points.

        points_mm: (n, 3) absolute end points in mm (a dwell row is ignored).
        feed_mm_min: scalar or n feeds (mm/min). exact_stop: n booleans (stop
        at the end of the block). dwell_s: n dwell times (> 0 marks a G4 row).
        arc_join: n booleans, True where a block and the one before it are
        chords of one arc (the drive's arc blocks): that join and the block's
        speed are limited by the arc's centripetal limits, not the corner rule.
        """
        pts = np.asarray(points_mm, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != AXES:
            raise UserError(f"points_mm must be an (n, {AXES}) array, got shape {pts.shape}")
        n = pts.shape[0]
        if not np.all(np.isfinite(pts)):
            raise UserError("points_mm contains a non-finite value")
        if np.any(np.abs(pts) > 1e9):
            raise UserError("points_mm: position out of range (over 1000 km)")
        feed = np.broadcast_to(np.asarray(feed_mm_min, dtype=float), (n,))
        moves = np.zeros(n, dtype=MOVE_DTYPE)
        moves["target"] = np.rint(pts * NM_PER_MM).astype(np.int64)
        dw = np.zeros(n) if dwell_s is None else np.broadcast_to(np.asarray(dwell_s, float), (n,))
        if not np.all(np.isfinite(dw)) or np.any(dw < 0) or np.any(dw > 1e6):
            raise UserError("dwell_s must be finite, >= 0 and at most 1e6 s")
        moves["dwell_ns"] = np.rint(dw * NS_PER_S).astype(np.int64)
        is_move = moves["dwell_ns"] == 0
        bad = is_move & ~(np.isfinite(feed) & (feed > 0))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise BlockRefused(i, f"feed must be a positive number, got {feed[i]!r}")
        fnm = np.where(is_move, np.rint(np.nan_to_num(feed) * NM_PER_MM / 60.0), 0)
        moves["feed"] = np.minimum(fnm, V_LIMIT_NM_S).astype(np.int64)
        moves["feed"][is_move & (moves["feed"] < 1)] = 1
        if exact_stop is not None:
            es = np.broadcast_to(np.asarray(exact_stop, dtype=bool), (n,))
            moves["flags"] = np.where(es, MOVE_EXACT_STOP, 0)
        if arc_join is not None:
            aj = np.broadcast_to(np.asarray(arc_join, dtype=bool), (n,))
            moves["flags"] |= np.where(aj, MOVE_ARC_JOIN, 0).astype(np.uint8)
        moves["tag"] = np.arange(n, dtype=np.uint32) if tags is None else np.asarray(tags)
        start = (ctypes.c_int64 * AXES)(*[int(round(float(v) * NM_PER_MM)) for v in start_mm])
        out = np.zeros(n, dtype=EST_DTYPE)
        depth = self.profile.depth
        storage = ctypes.create_string_buffer(depth * self._lib.plan_block_sizeof() + 64)
        base = (ctypes.addressof(storage) + 63) & ~63
        bad_idx = ctypes.c_uint32(0)
        rc = self._lib.plan_estimate(
            ctypes.byref(self._c),
            start,
            moves.ctypes.data,
            n,
            base,
            depth,
            out.ctypes.data,
            ctypes.byref(bad_idx),
        )
        if rc < 0:
            raise BlockRefused(bad_idx.value, _ERRORS.get(rc, f"planner error {rc}"))
        return self._result(out)

    def _result(self, out: np.ndarray) -> EstimateResult:
        blocks = np.zeros(
            out.shape[0],
            dtype=[(f, "f8") for f in BLOCK_FIELDS]
            + [("skipped", "?"), ("mbt_limited", "?"), ("corner_capped", "?")],
        )
        blocks["length_mm"] = out["len_nm"] / NM_PER_MM
        for src, dst in (
            ("v_entry", "v_entry_mm_s"),
            ("v_peak", "v_peak_mm_s"),
            ("v_exit", "v_exit_mm_s"),
            ("v_max", "v_max_mm_s"),
        ):
            blocks[dst] = out[src] / NM_PER_MM
        for src, dst in (
            ("t_acc_ns", "t_acc_s"),
            ("t_cruise_ns", "t_cruise_s"),
            ("t_dec_ns", "t_dec_s"),
            ("t_total_ns", "t_total_s"),
            ("t_mbt_ns", "t_mbt_s"),
        ):
            blocks[dst] = out[src] / NS_PER_S
        blocks["skipped"] = (out["flags"] & EST_SKIPPED) != 0
        blocks["mbt_limited"] = (out["flags"] & BF_MBT) != 0
        blocks["corner_capped"] = (out["flags"] & BF_CORNER) != 0
        total_ns = int(out["t_total_ns"].sum())
        tick_ns = NS_PER_S // self.profile.tick_hz
        ticks = -(-total_ns // tick_ns)
        return EstimateResult(
            blocks=blocks,
            total_s=total_ns / NS_PER_S,
            ticks=ticks,
            executed_s=ticks * tick_ns / NS_PER_S,
            t_acc_s=int(out["t_acc_ns"].sum()) / NS_PER_S,
            t_cruise_s=int(out["t_cruise_ns"].sum()) / NS_PER_S,
            t_dec_s=int(out["t_dec_ns"].sum()) / NS_PER_S,
            t_mbt_s=int(out["t_mbt_ns"].sum()) / NS_PER_S,
            raw=out,
        )
