"""Error map of a calibration: per point, per direction of approach.

Definitions (``../shared/data/README.md``, Lacerda 1998, Tables 5.6-5.9)::

    error       = encoder - reference                      (one reading)
    mean_err_pos, std_pos   mean and sample standard deviation (n - 1) of the
                            errors at the point approached moving +x
    mean_err_neg, std_neg   the same approached moving -x
    systematic  = (mean_err_pos + mean_err_neg) / 2        ("mean of both directions")
    hysteresis  = |mean_err_pos - mean_err_neg|            ("|difference of the two directions|")
    random_95   = 2 * (std_pos + std_neg) / 2              ("95 % band": k = 2 times the
                                                            mean standard deviation)

The random band's factor and averaging are not spelled out in the thesis's
text; ``2 * mean(std_pos, std_neg)`` reproduces every row of Tables 5.6 to 5.9
within their 0.001 mm rounding (tests/python/test_calibration.py checks this
against the CSV), so it is what the thesis computed. (The appendix tables A.1
to A.7 fit a factor of 3 instead.)

The compensation table corrects a reading by the negative of the error:
``correction_fwd = -mean_err_pos``, ``correction_rev = -mean_err_neg`` (the
drive adds it to the encoder reading, firmware/core/comp.h).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Optional

from contour.errors import UserError

RANDOM_K = 2.0  # coverage factor of the 95 % band


@dataclass
class PointStats:
    position_mm: float
    n_pos: int
    n_neg: int
    mean_err_pos_mm: float
    std_pos_mm: float
    mean_err_neg_mm: float
    std_neg_mm: float
    systematic_mm: float
    hysteresis_mm: float
    random_95_mm: float

    @property
    def correction_fwd_mm(self) -> float:
        return -self.mean_err_pos_mm

    @property
    def correction_rev_mm(self) -> float:
        return -self.mean_err_neg_mm

    def as_dict(self) -> dict:
        d = asdict(self)
        d["correction_fwd_mm"] = self.correction_fwd_mm
        d["correction_rev_mm"] = self.correction_rev_mm
        return d


@dataclass
class ErrorMap:
    points: list  # PointStats, by increasing position
    axis: str = ""
    source: str = ""
    extra: dict = field(default_factory=dict)

    def positions_mm(self) -> list:
        return [p.position_mm for p in self.points]

    def max_abs(self, name: str) -> float:
        vals = [abs(getattr(p, name)) for p in self.points]
        return max(vals) if vals else 0.0

    def summary(self) -> dict:
        """Worst values over the points, in um."""
        return {
            "points": len(self.points),
            "max_systematic_um": 1000 * self.max_abs("systematic_mm"),
            "max_hysteresis_um": 1000 * self.max_abs("hysteresis_mm"),
            "max_random_95_um": 1000 * self.max_abs("random_95_mm"),
            "mean_random_95_um": 1000
            * (sum(p.random_95_mm for p in self.points) / len(self.points) if self.points else 0),
        }


def mean_std(values: list) -> tuple[float, float]:
    n = len(values)
    if n == 0:
        return math.nan, math.nan
    m = sum(values) / n
    if n < 2:
        return m, math.nan
    var = sum((v - m) ** 2 for v in values) / (n - 1)
    return m, math.sqrt(var)


def point_stats(position_mm: float, pos_errors: list, neg_errors: list) -> PointStats:
    """Statistics of one point from its readings (errors in mm) approached
    moving +x (pos_errors) and -x (neg_errors)."""
    if not pos_errors or not neg_errors:
        missing = "+x" if not pos_errors else "-x"
        raise UserError(
            f"point {position_mm:g} mm has no reading approached moving {missing}: "
            "both directions are needed (systematic error and hysteresis)"
        )
    mp, sp = mean_std(pos_errors)
    mn, sn = mean_std(neg_errors)
    return from_summary(position_mm, mp, sp, mn, sn, len(pos_errors), len(neg_errors))


def from_summary(
    position_mm: float,
    mean_pos: float,
    std_pos: float,
    mean_neg: float,
    std_neg: float,
    n_pos: int = 0,
    n_neg: int = 0,
) -> PointStats:
    """The derived columns from per-direction means and standard deviations."""
    if math.isnan(std_pos) or math.isnan(std_neg):
        rnd = math.nan
    else:
        rnd = RANDOM_K * (std_pos + std_neg) / 2
    return PointStats(
        position_mm=position_mm,
        n_pos=n_pos,
        n_neg=n_neg,
        mean_err_pos_mm=mean_pos,
        std_pos_mm=std_pos,
        mean_err_neg_mm=mean_neg,
        std_neg_mm=std_neg,
        systematic_mm=(mean_pos + mean_neg) / 2,
        hysteresis_mm=abs(mean_pos - mean_neg),
        random_95_mm=rnd,
    )


def analyse(readings: Iterable, axis: str = "", source: str = "") -> ErrorMap:
    """Error map from readings ``(position_mm, direction, error_mm)``,
    direction +1 (approached moving +x) or -1. Readings of one point share
    its position exactly (the target)."""
    by_pos: dict = {}
    for pos, direction, err in readings:
        if direction not in (1, -1):
            raise UserError(f"reading at {pos:g} mm: direction must be +1 or -1, got {direction}")
        if not (math.isfinite(pos) and math.isfinite(err)):
            raise UserError(f"reading at {pos} mm: not a finite number ({err})")
        slot = by_pos.setdefault(pos, ([], []))
        slot[0 if direction > 0 else 1].append(err)
    if not by_pos:
        raise UserError("no readings to analyse")
    pts = [point_stats(p, by_pos[p][0], by_pos[p][1]) for p in sorted(by_pos)]
    return ErrorMap(points=pts, axis=axis, source=source)


def residual(errmap: ErrorMap) -> dict:
    """The figures the --apply re-measurement reports (um)."""
    return {
        "residual_systematic_um": 1000 * errmap.max_abs("systematic_mm"),
        "residual_hysteresis_um": 1000 * errmap.max_abs("hysteresis_mm"),
        "residual_random_95_um": 1000 * errmap.max_abs("random_95_mm"),
    }


def compare(measured: ErrorMap, expected: ErrorMap, at: Optional[list] = None) -> dict:
    """Largest differences (um) of mean errors per direction, systematic and
    hysteresis between two maps at their common positions."""
    exp = {round(p.position_mm, 6): p for p in expected.points}
    worst = {"mean_err_pos": 0.0, "mean_err_neg": 0.0, "systematic": 0.0, "hysteresis": 0.0}
    n = 0
    for p in measured.points:
        q = exp.get(round(p.position_mm, 6))
        if q is None or (at is not None and p.position_mm not in at):
            continue
        n += 1
        for k in worst:
            d = abs(getattr(p, f"{k}_mm") - getattr(q, f"{k}_mm")) * 1000
            worst[k] = max(worst[k], d)
    return {"points_compared": n, **{f"max_diff_{k}_um": v for k, v in worst.items()}}
