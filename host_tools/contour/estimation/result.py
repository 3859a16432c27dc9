"""Inputs and outputs shared by the estimation models.

:class:`Moves` is what every model reads: the program's straight segments
with their lengths, feeds (rapids at the profile's rapid feed) and stops.
:class:`Estimate` is what every model returns: a time per segment and,
where the model knows it, the split into acceleration, cruise and
deceleration and the speeds at the block ends.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from contour.errors import UserError
from contour.gcode import Segments


@dataclass
class Moves:
    """Segments prepared for a model.

    ``delta`` (n, 3) mm; ``length`` mm (a segment that moves only rotary
    axes gets the length of its rotary move in degrees, as RS-274 does for
    its feed); ``feed`` mm/min (G0 at the profile's rapid feed); ``rapid``,
    ``exact_stop`` (the segment ends in a stop), ``dwell_s`` (after the
    segment), ``line`` (source line), ``block`` (program row), ``rotary``
    (n, 3) degrees moved on A B C (None: no rotary axes).

    Rotary axes (machine-axis kinematics, no tool-tip transformation): in a
    block that moves X Y Z the feed is the path speed of X Y Z and the rotary
    axes move in step; alone, the feed is in degrees/min. With rotary
    velocity limits the feed is capped so that every rotary axis keeps within
    its own limit (``feed <= length * v_k / |d_k|``).
    """

    delta: np.ndarray
    length: np.ndarray
    feed: np.ndarray
    rapid: np.ndarray
    exact_stop: np.ndarray
    dwell_s: np.ndarray
    line: np.ndarray
    block: np.ndarray
    rotary: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return int(self.length.shape[0])

    _ARRAYS = ("delta", "length", "feed", "rapid", "exact_stop", "dwell_s", "line", "block")

    def take(self, sl: slice) -> Moves:
        """The segments of slice `sl`."""
        kw = {k: getattr(self, k)[sl] for k in self._ARRAYS}
        return Moves(**kw, rotary=None if self.rotary is None else self.rotary[sl])

    @classmethod
    def concat(cls, parts: list) -> Moves:
        """Segments of `parts` one after the other."""
        kw = {k: np.concatenate([getattr(p, k) for p in parts]) for k in cls._ARRAYS}
        rot = None
        if any(p.rotary is not None for p in parts):
            rot = np.concatenate(
                [p.rotary if p.rotary is not None else np.zeros((len(p), 3)) for p in parts]
            )
        return cls(**kw, rotary=rot)

    @property
    def rotary_only(self) -> np.ndarray:
        """Segments that move rotary axes and no linear one."""
        if self.rotary is None:
            return np.zeros(len(self), dtype=bool)
        lin = np.einsum("ij,ij->i", self.delta, self.delta) > 0
        return ~lin & np.any(np.abs(self.rotary) > 1e-9, axis=1)

    @classmethod
    def from_segments(cls, seg: Segments, rapid_feed_mm_min: float, rotary_v_deg_min=None) -> Moves:
        # Rounded to the drive's nanometre: positions accumulated in floating
        # point must not make 0.2 mm steps 0.2000000000001 mm long.
        delta = np.round(seg.end - seg.start, 6)
        length = np.sqrt(np.einsum("ij,ij->i", delta, delta))
        rot = np.sqrt(np.einsum("ij,ij->i", seg.rotary, seg.rotary))
        length = np.where(length > 1e-12, length, rot)
        feed = np.where(seg.rapid, rapid_feed_mm_min, seg.feed)
        # Dwell rows have no feed; any positive value does for a row that does not move.
        feed = np.where((length == 0) & ~(feed > 0), rapid_feed_mm_min, feed)
        if np.any(~(feed > 0)):
            bad = int(np.nonzero(~(feed > 0))[0][0])
            raise UserError(f"line {int(seg.line[bad])}: feed move without a valid feed")
        rotary = None
        if np.any(np.abs(seg.rotary) > 1e-9):
            rotary = np.round(seg.rotary, 9)
            if rotary_v_deg_min is not None:
                v = np.asarray(rotary_v_deg_min, dtype=float)
                with np.errstate(divide="ignore", invalid="ignore"):
                    cap = np.where(
                        np.abs(rotary) > 1e-9, length[:, None] * v / np.abs(rotary), np.inf
                    )
                feed = np.minimum(feed, cap.min(axis=1))
        return cls(
            delta=delta,
            length=length,
            feed=feed,
            rapid=seg.rapid.copy(),
            exact_stop=seg.exact_stop.copy(),
            dwell_s=seg.dwell_s.copy(),
            line=seg.line.copy(),
            block=seg.block.copy(),
            rotary=rotary,
        )

    @classmethod
    def from_arrays(cls, delta, feed_mm_min) -> Moves:
        """Feed moves from an (n, 3) array of displacements (for tests and fits)."""
        delta = np.asarray(delta, dtype=float).reshape(-1, 3)
        n = delta.shape[0]
        return cls(
            delta=delta,
            length=np.sqrt(np.einsum("ij,ij->i", delta, delta)),
            feed=np.broadcast_to(np.asarray(feed_mm_min, dtype=float), (n,)).copy(),
            rapid=np.zeros(n, dtype=bool),
            exact_stop=np.zeros(n, dtype=bool),
            dwell_s=np.zeros(n),
            line=np.arange(1, n + 1),
            block=np.arange(n),
        )


@dataclass
class Estimate:
    """Per-segment times of one model on one program.

    ``time_s`` includes the dwell after the segment. ``min_time_s`` is the
    part of each segment's time spent at (or caused by) the minimum block
    time. ``accel_s``/``cruise_s``/``decel_s`` and the speeds (mm/min) are
    None for models that do not plan a speed profile.
    """

    model: str
    moves: Moves
    time_s: np.ndarray
    min_time_s: np.ndarray
    accel_s: Optional[np.ndarray] = None
    cruise_s: Optional[np.ndarray] = None
    decel_s: Optional[np.ndarray] = None
    entry_mm_min: Optional[np.ndarray] = None
    peak_mm_min: Optional[np.ndarray] = None
    exit_mm_min: Optional[np.ndarray] = None
    options: dict = field(default_factory=dict)

    @property
    def total_s(self) -> float:
        return float(self.time_s.sum())

    def take(self, sl: slice) -> Estimate:
        """The segments of slice `sl` with their times (planned in context)."""

        def cut(a):
            return None if a is None else a[sl]

        opts = dict(self.options)
        if "executed_s" in opts:  # the planner's whole-plan figure: this slice's time
            opts["executed_s"] = float(self.time_s[sl].sum())
        return Estimate(
            model=self.model,
            moves=self.moves.take(sl),
            time_s=self.time_s[sl],
            min_time_s=self.min_time_s[sl],
            accel_s=cut(self.accel_s),
            cruise_s=cut(self.cruise_s),
            decel_s=cut(self.decel_s),
            entry_mm_min=cut(self.entry_mm_min),
            peak_mm_min=cut(self.peak_mm_min),
            exit_mm_min=cut(self.exit_mm_min),
            options=opts,
        )

    def summary(self) -> dict:
        m = self.moves
        dwell = float(m.dwell_s.sum())
        total = self.total_s
        motion_t = self.time_s - m.dwell_s
        # X Y Z path length (a rotary-only segment's length is in degrees)
        lin = np.where(m.rotary_only, 0.0, m.length)
        cutting = (lin > 0) & ~m.rapid
        length = float(lin[cutting].sum())
        mt = float(motion_t[cutting].sum())
        with np.errstate(divide="ignore", invalid="ignore"):
            feeds = 60.0 * lin[cutting] / motion_t[cutting]
        feeds = feeds[np.isfinite(feeds)]

        def opt_sum(a):
            return None if a is None else float(a.sum())

        return {
            "model": self.model,
            "total_s": total,
            "motion_s": total - dwell,
            "dwell_s": dwell,
            "accel_s": opt_sum(self.accel_s),
            "cruise_s": opt_sum(self.cruise_s),
            "decel_s": opt_sum(self.decel_s),
            "min_block_time_s": float(self.min_time_s.sum()),
            "blocks": int(np.unique(m.block).size) if len(m) else 0,
            "segments": len(m),
            "length_mm": float(lin.sum()),
            "feed_length_mm": length,
            "feed_time_s": mt,
            "rapid_s": float(motion_t[m.rapid].sum()),
            "mean_feed_mm_min": 60.0 * length / mt if mt > 0 else 0.0,
            "min_feed_mm_min": float(feeds.min()) if feeds.size else 0.0,
            "options": dict(self.options),
        }

    def kinds(self) -> np.ndarray:
        """Per segment: rapid, feed, dwell (no motion) or rotary (only
        rotary axes move; its length is in degrees)."""
        m = self.moves
        k = np.where(m.rapid, "rapid", "feed").astype(object)
        k[(m.length == 0) & (m.dwell_s > 0)] = "dwell"
        k[m.rotary_only] = "rotary"
        return k

    def csv_columns(self, offset: int = 0) -> list:
        """(name, array) columns of the per-segment CSV; segments numbered
        from `offset` (a chunk of a longer program)."""
        m = self.moves
        cols = [
            ("segment", np.arange(offset, offset + len(m))),
            ("line", m.line),
            ("kind", self.kinds()),
            ("length_mm", m.length),
            ("feed_mm_min", m.feed),
            ("time_s", self.time_s),
            ("min_block_time_s", self.min_time_s),
            ("accel_s", self.accel_s),
            ("cruise_s", self.cruise_s),
            ("decel_s", self.decel_s),
            ("entry_mm_min", self.entry_mm_min),
            ("peak_mm_min", self.peak_mm_min),
            ("exit_mm_min", self.exit_mm_min),
            ("dwell_s", m.dwell_s),
        ]
        return [(name, a) for name, a in cols if a is not None]

    def write_csv(self, path) -> None:
        with CsvWriter(path) as w:
            w.write(self)


class CsvWriter:
    """The per-segment CSV of a program estimated chunk by chunk."""

    def __init__(self, path) -> None:
        self.path = path
        self.offset = 0
        self._fh = None
        self._w = None

    def __enter__(self) -> CsvWriter:
        try:
            self._fh = open(self.path, "w", newline="", encoding="utf-8")
        except OSError as exc:
            raise UserError(f"cannot write {self.path}: {exc.strerror}") from exc
        self._w = csv.writer(self._fh)
        return self

    def __exit__(self, *exc) -> None:
        self._fh.close()

    def write(self, est: Estimate) -> None:
        cols = est.csv_columns(self.offset)
        try:
            if self.offset == 0:
                self._w.writerow([name for name, _ in cols])
            for i in range(len(est.moves)):
                self._w.writerow([_cell(a[i]) for _, a in cols])
        except OSError as exc:
            raise UserError(f"cannot write {self.path}: {exc.strerror}") from exc
        self.offset += len(est.moves)


def merge_summaries(parts: list) -> dict:
    """One summary of a program estimated in chunks (in order)."""
    if len(parts) == 1:
        return parts[0]
    out = dict(parts[-1])
    for key in (
        "total_s",
        "motion_s",
        "dwell_s",
        "min_block_time_s",
        "blocks",
        "segments",
        "length_mm",
        "feed_length_mm",
        "feed_time_s",
        "rapid_s",
    ):
        out[key] = sum(p[key] for p in parts)
    for key in ("accel_s", "cruise_s", "decel_s"):
        vals = [p[key] for p in parts]
        out[key] = None if any(v is None for v in vals) else sum(vals)
    mt = out["feed_time_s"]
    out["mean_feed_mm_min"] = 60.0 * out["feed_length_mm"] / mt if mt > 0 else 0.0
    mins = [p["min_feed_mm_min"] for p in parts if p["min_feed_mm_min"] > 0]
    out["min_feed_mm_min"] = min(mins) if mins else 0.0
    opts = dict(parts[-1]["options"])
    for p in parts[:-1]:
        for k, v in p["options"].items():
            if isinstance(v, (int, float)) and not isinstance(v, bool) and k in opts:
                opts[k] = opts[k] + v
    out["options"] = opts
    out["chunks"] = len(parts)
    return out


def _cell(v) -> str:
    if isinstance(v, (str, np.str_)):
        return str(v)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    f = float(v)
    return "" if math.isnan(f) else f"{f:.9g}"
