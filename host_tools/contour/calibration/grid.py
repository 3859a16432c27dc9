"""2-D calibration over a grid of lines (issue 22, docs/calibration.md
"Calibration over the field").

The drive's calibration run (calib.h) measures one axis: it approaches each
target moving + and moving -, and every sample carries that axis's encoder
and its reference scale. The grid is measured as lines of such runs:

- rows: for every Y of the grid, Y is brought to it approaching from below
  (+y) and, in a second pass, from above (-y); then X runs through the
  grid's X values both ways: X's error at every node for the four
  combinations of directions (X's own and Y's);
- columns: the same with the roles swapped: Y's error at every node for
  the four combinations.

Both coordinates are read at every stop, in the same sample, the way the
thesis read the KGM 101: the drive's sample carries the moving axis's
encoder and reference scale and the cross axis's (xenc, xcomp, xref,
calib.h), so every stop of a row gives X's error (positioning) and Y's
(straightness), every stop of a column Y's and X's. Error = encoder -
reference, mm here (um in reports).

Per node and coordinate (the thesis's measures, analysis.py), from the
readings of the line along that coordinate (positioning: the axis has just
approached the node): systematic = mean of the four direction
combinations; hysteresis = |mean approached moving + - mean approached
moving -| along the coordinate's own axis; random 95 % = 2 x mean of the
standard deviations of the two directions; plus <c>_cross_systematic_um,
the same coordinate's systematic error as read across the crossing line
(its axis held while the other one travelled). The map is made from the
positioning readings: on the simulated table the held axis's readings
differ from them by up to a few um (docs/calibration.md, "Cross-check").
Per line, ISO 230-2 figures (E, B, R, A, M; iso230_2 below) of
the positioning along the line, and the straightness (range along it of
the cross coordinate's systematic error measured on that line).

Cross-check (cross_check below): the cross coordinate measured at a stop
against what the crossing line read there as its own coordinate (the
method used before the drive read both coordinates) - the same node and
directions of approach, so they differ only by the random spread and what
the table does between the two visits.

Second pass: with the first map in use the standing axis of every line is
moved by the map's straightness correction while the other travels, and a
table whose error depends on that axis's direction of motion (the thesis
table's X error depends on Y's) is then in another state than when the
nodes were measured with the compensation off. So the nodes are measured
again with the map on and their residual errors are added to the
corrections (corrections(pass 2) = residual; map = map1 + residual): the
map then holds what the table does with the compensation working.
"""

from __future__ import annotations

import math
import re
import statistics
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from contour import protocol_gen as pg
from contour.calibration import map2d
from contour.calibration.run import FLAG_NO_XREF, Calibrator, RunConfig
from contour.errors import UsageError, UserError

AXES = "XY"


@dataclass
class Grid:
    xs: list  # mm, increasing
    ys: list


def _axis_range(text: str, name: str) -> list:
    m = re.fullmatch(r"\s*([XYxy])\s*:([^:]+):([^:]+):([^:]+)\s*", text)
    if not m:
        raise UsageError(f"--grid {name}: expected AXIS:FROM:TO:STEP, e.g. X:-60:60:15")
    try:
        lo, hi, step = (float(v) for v in m.group(2, 3, 4))
    except ValueError:
        raise UsageError(f"--grid {text!r}: not numbers") from None
    if not all(math.isfinite(v) for v in (lo, hi, step)) or step <= 0 or hi <= lo:
        raise UsageError(f"--grid {text!r}: needs FROM < TO and STEP > 0")
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    if abs(lo + (n - 1) * step - hi) > 1e-6:
        raise UsageError(f"--grid {text!r}: TO - FROM must be a whole number of steps")
    return [round(lo + i * step, 6) for i in range(n)]


def parse_grid(text: str) -> Grid:
    """'X:-60:60:15,Y:-60:60:15' -> Grid; at most 12 x 12 nodes (the drive's
    map, comp2d.h)."""
    parts = [p for p in text.split(",") if p.strip()]
    got = {}
    for p in parts:
        got[p.strip()[0].upper()] = _axis_range(p, p)
    if sorted(got) != ["X", "Y"] or len(parts) != 2:
        raise UsageError(
            f"--grid {text!r}: give one X and one Y range, e.g. X:-60:60:15,Y:-60:60:15"
        )
    g = Grid(got["X"], got["Y"])
    if len(g.xs) * len(g.ys) > map2d.NODES_MAX or len(g.xs) < 2 or len(g.ys) < 2:
        raise UsageError(
            f"--grid {text!r}: {len(g.xs)} x {len(g.ys)} nodes; the drive's map holds"
            f" 2..{map2d.NODES_MAX} (at most 12 x 12)"
        )
    return g


def midpoints(g: Grid) -> Grid:
    """The points between the grid lines (cell centres): the residual check."""
    return Grid(
        [round((a + b) / 2, 6) for a, b in zip(g.xs, g.xs[1:])],
        [round((a + b) / 2, 6) for a, b in zip(g.ys, g.ys[1:])],
    )


@dataclass
class GridMeasurement:
    grid: Grid
    column: str  # 'enc' (before compensation) or 'comp' (after)
    # (coord, ix, iy, own_dir, cross_dir) -> [error mm]: coord's own lines
    readings: dict = field(default_factory=dict)
    # the same keys: coord read as the cross coordinate of the other lines
    cross: dict = field(default_factory=dict)
    runs: int = 0
    samples: int = 0
    frames_repeated: int = 0
    reads_repeated: int = 0
    points_repeated: int = 0
    simulated_s: float = 0.0


class GridRunner:
    """Runs the rows and columns (module doc) with a Calibrator."""

    def __init__(
        self,
        client,
        wait: Callable[[float], None],
        cfg: RunConfig,
        progress: Optional[Callable[[int, int], None]] = None,
        clock: Optional[Callable[[], float]] = None,
    ) -> None:
        self.c = client
        self.wait = wait
        self.cfg = cfg  # samples, cycles, dwell, overrun, feed (axis, targets per line)
        self.cal = Calibrator(client, wait, poll_s=0.02)
        self.progress = progress
        self.clock = clock
        self._seq = 1 << 20

    def _move(self, target_nm: list) -> None:
        """One exact-stop line to target (X, Y; the rest held), to rest."""
        st = self.c.status()
        done0 = st["blocks_done"]
        tgt = list(st["pos"])
        tgt[0], tgt[1] = int(target_nm[0]), int(target_nm[1])
        self._seq += 1
        self.c.request(
            "queue_block",
            block_seq=self._seq,
            kind=int(pg.BlockKind.LINE),
            flags=1 << int(pg.BlockFlag.EXACT_STOP),
            feed=self.cfg.feed_nm_s,
            target=tgt,
        )
        for _ in range(200000):
            st = self.c.status()
            if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
                raise UserError(f"the drive faulted while positioning (faults {st['faults']:#x})")
            if st["blocks_done"] > done0 and st["state"] == pg.State.READY:
                return
            self.wait(0.01)
        raise UserError("the drive did not reach the line's start")

    def _approach(self, axis: int, pos_mm: float, sign: int, other_nm: int) -> None:
        """Bring `axis` to pos approaching moving `sign` (from an overrun
        away), the other axis at other_nm."""
        p = round(pos_mm * 1e6)
        for v in (p - sign * self.cfg.overrun_nm, p):
            t = [other_nm, v] if axis == 1 else [v, other_nm]
            self._move(t)

    def measure(self, g: Grid, column: str = "enc") -> GridMeasurement:
        out = GridMeasurement(grid=g, column=column)
        retried0 = getattr(self.c, "retried", 0)
        t0 = self.clock() if self.clock else 0.0
        lines = [(0, j, s) for j in range(len(g.ys)) for s in (1, -1)]
        lines += [(1, i, s) for i in range(len(g.xs)) for s in (1, -1)]
        for k, (axis, idx, cross_dir) in enumerate(lines):
            if self.progress is not None:
                self.progress(k, len(lines))
            own = g.xs if axis == 0 else g.ys
            cross = g.ys if axis == 0 else g.xs
            start_nm = round((own[0] * 1e6) - self.cfg.overrun_nm)
            # the held axis first, approached from its side, then the line
            self._approach(1 - axis, cross[idx], cross_dir, start_nm)
            rc = RunConfig(**{**self.cfg.__dict__, "axis": axis})
            rc.targets_nm = [round(v * 1e6) for v in own]
            res = self.cal.run(rc)
            out.runs += 1
            out.reads_repeated += res.reads_repeated
            out.points_repeated += res.points_repeated
            for (p, d, _c), ss in res.legs.items():
                ix, iy = (p, idx) if axis == 0 else (idx, p)
                key = (axis, ix, iy, d, cross_dir)
                errs = out.readings.setdefault(key, [])
                errs += [(getattr(s, column) - s.ref) / 1e6 for s in ss]
                out.samples += len(ss)
                if any(s.flags & FLAG_NO_XREF for s in ss):
                    raise UserError(
                        f"the drive read no {AXES[1 - axis]} reference while {AXES[axis]}"
                        " moved: the grid needs a reference scale on both axes"
                    )
                # the cross coordinate: its own direction is how the held
                # axis was approached, the other one this leg's
                xkey = (1 - axis, ix, iy, cross_dir, d)
                xerrs = out.cross.setdefault(xkey, [])
                xerrs += [(getattr(s, "x" + column) - s.xref) / 1e6 for s in ss]
        if self.progress is not None:
            self.progress(len(lines), len(lines))
        out.frames_repeated = getattr(self.c, "retried", 0) - retried0
        out.simulated_s = (self.clock() - t0) if self.clock else 0.0
        return out


# ---- analysis ------------------------------------------------------------------


def _mean_std(v: list) -> tuple:
    return statistics.fmean(v), (statistics.stdev(v) if len(v) > 1 else 0.0)


def _systematic_um(src: dict, c: int, ix: int, iy: int) -> float:
    """Mean of the four direction combinations of src, um."""
    return 1000 * statistics.fmean(
        statistics.fmean(src[(c, ix, iy, d, s)]) for d in (1, -1) for s in (1, -1)
    )


def node_stats(m: GridMeasurement) -> list:
    """Per node and coordinate: the thesis's measures, um."""
    out = []
    g = m.grid
    for iy, y in enumerate(g.ys):
        for ix, x in enumerate(g.xs):
            row = {"x_mm": x, "y_mm": y}
            for c in (0, 1):
                combos = {
                    (d, s): m.readings.get((c, ix, iy, d, s), []) for d in (1, -1) for s in (1, -1)
                }
                if any(len(v) == 0 for v in combos.values()):
                    raise UserError(f"node ({x:g}, {y:g}) mm: {AXES[c]} not measured both ways")
                means = {k: statistics.fmean(v) for k, v in combos.items()}
                pos = combos[(1, 1)] + combos[(1, -1)]
                neg = combos[(-1, 1)] + combos[(-1, -1)]
                mp, sp = _mean_std(pos)
                mn, sn = _mean_std(neg)
                a = AXES[c].lower()
                row[f"{a}_systematic_um"] = 1000 * statistics.fmean(means.values())
                row[f"{a}_hysteresis_um"] = 1000 * abs(mp - mn)
                row[f"{a}_random_95_um"] = 1000 * 2 * (sp + sn) / 2
                row[f"{a}_mean_pos_um"] = 1000 * mp
                row[f"{a}_mean_neg_um"] = 1000 * mn
                row[f"{a}_n"] = len(pos) + len(neg)
                if all((c, ix, iy, d, s) in m.cross for d in (1, -1) for s in (1, -1)):
                    row[f"{a}_cross_systematic_um"] = _systematic_um(m.cross, c, ix, iy)
            out.append(row)
    return out


def iso230_2(dev_up: list, dev_down: list) -> dict:
    """ISO 230-2:2014 figures of one line, um, from the deviations
    (actual - target = reference - encoder, mm) at each target approached
    moving + (dev_up[i]: its readings) and moving - (docs/calibration.md).
    x_i = mean, s_i = sample standard deviation (n - 1) per target and
    direction; B_i = x_i_up - x_i_down; R_i = max(2 s_up + 2 s_down + |B_i|,
    4 s_up, 4 s_down); x_i_bar = (x_i_up + x_i_down) / 2; then
    E = max(x_up, x_down) - min(x_up, x_down); B = max |B_i|; R = max R_i;
    M = max x_i_bar - min x_i_bar;
    A = max(x_up + 2 s_up, x_down + 2 s_down) - min(x_up - 2 s_up, x_down - 2 s_down)."""
    up = [_mean_std(v) for v in dev_up]
    dn = [_mean_std(v) for v in dev_down]
    b = [u[0] - d[0] for u, d in zip(up, dn)]
    r = [max(2 * u[1] + 2 * d[1] + abs(bi), 4 * u[1], 4 * d[1]) for u, d, bi in zip(up, dn, b)]
    means = [u[0] for u in up] + [d[0] for d in dn]
    bar = [(u[0] + d[0]) / 2 for u, d in zip(up, dn)]
    hi = max([u[0] + 2 * u[1] for u in up] + [d[0] + 2 * d[1] for d in dn])
    lo = min([u[0] - 2 * u[1] for u in up] + [d[0] - 2 * d[1] for d in dn])
    k = 1000.0
    return {
        "E_um": k * (max(means) - min(means)),
        "B_um": k * max(abs(v) for v in b),
        "R_um": k * max(r),
        "A_um": k * (hi - lo),
        "M_um": k * (max(bar) - min(bar)),
    }


def line_figures(m: GridMeasurement, stats: list) -> list:
    """Per line (rows along X, columns along Y): ISO 230-2 of the
    positioning (both passes of the held axis pooled) and the straightness
    measured on the line (the cross coordinate of its own samples);
    straightness_crossing_um: the same from the crossing lines' own
    readings (cross-check)."""
    g = m.grid
    out = []
    for axis, own, cross in ((0, g.xs, g.ys), (1, g.ys, g.xs)):
        for j, cv in enumerate(cross):
            up, dn = [], []
            for i in range(len(own)):
                ix, iy = (i, j) if axis == 0 else (j, i)
                rd = [m.readings[(axis, ix, iy, d, s)] for d in (1, -1) for s in (1, -1)]
                up.append([-e for e in rd[0] + rd[1]])  # deviation = -error
                dn.append([-e for e in rd[2] + rd[3]])
            nodes = [(i, j) if axis == 0 else (j, i) for i in range(len(own))]
            st = [_systematic_um(m.cross, 1 - axis, ix, iy) for ix, iy in nodes]
            sc = [_systematic_um(m.readings, 1 - axis, ix, iy) for ix, iy in nodes]
            out.append(
                {
                    "line": f"{AXES[axis]} at {AXES[1 - axis]} = {cv:g} mm",
                    **iso230_2(up, dn),
                    "straightness_um": max(st) - min(st),
                    "straightness_crossing_um": max(sc) - min(sc),
                }
            )
    return out


def cross_check(m: GridMeasurement) -> dict:
    """The measured cross coordinate against the crossing line's reading of
    it (module doc), um: per coordinate the largest and the rms difference
    of the means over every node and combination of directions, and the
    largest difference of the nodes' systematic errors."""
    out = {}
    g = m.grid
    for c in (0, 1):
        diffs = [
            1000 * (statistics.fmean(v) - statistics.fmean(m.readings[k]))
            for k, v in m.cross.items()
            if k[0] == c and k in m.readings
        ]
        sys_d = [
            _systematic_um(m.cross, c, ix, iy) - _systematic_um(m.readings, c, ix, iy)
            for iy in range(len(g.ys))
            for ix in range(len(g.xs))
        ]
        a = AXES[c].lower()
        out[f"{a}_max_um"] = max(abs(d) for d in diffs)
        out[f"{a}_rms_um"] = math.sqrt(statistics.fmean(d * d for d in diffs))
        out[f"{a}_systematic_max_um"] = max(abs(d) for d in sys_d)
        out[f"{a}_compared"] = len(diffs)
    return out


def corrections(m: GridMeasurement) -> np.ndarray:
    """corr[axis][sx][sy][iy][ix] = -(mean error), um, per node, coordinate
    and combination of directions (0: moving +)."""
    g = m.grid
    corr = np.zeros((2, 2, 2, len(g.ys), len(g.xs)))
    for (c, ix, iy, d, s), v in m.readings.items():
        sx = d if c == 0 else s  # direction of X
        sy = s if c == 0 else d  # direction of Y
        corr[c, 0 if sx > 0 else 1, 0 if sy > 0 else 1, iy, ix] = -1000 * statistics.fmean(v)
    return corr


def build_map(g: Grid, corr: np.ndarray) -> map2d.Map2D:
    """The 2-D map of the node corrections (map2d.from_corrections)."""
    return map2d.from_corrections(g.xs[0], g.xs[1] - g.xs[0], g.ys[0], g.ys[1] - g.ys[0], corr)


def worst(stats: list, name: str) -> float:
    """Largest |value| of x_<name> and y_<name> over the nodes, um."""
    return max(max(abs(r[f"x_{name}"]), abs(r[f"y_{name}"])) for r in stats)


# ---- the map on the drive --------------------------------------------------------

CHUNK = 224
COMMIT_TIMEOUT_S = 5.0


def _refusal(exc) -> UserError:
    from contour.calibration.run import reason_text

    f = exc.fields
    if f.get("code") == pg.ErrorCode.CALIB:
        return UserError(
            f"drive refused the 2-D map: {reason_text(f['arg'])} (detail {f['lo']});"
            " the previous map stays in use"
        )
    return UserError(str(exc))


def upload_map(client, record: bytes, wait, notify=None, timeout_s: float = 2.0) -> dict:
    """comp2d_write the record, comp2d_commit it (the drive checks it
    against its memory and field, stores it in flash, reads it back and
    uses it); a drive enabled at rest is disabled for the flash write and
    enabled again (as run.upload does). Returns comp2d_info, checked
    against what was sent."""
    import zlib

    from contour.calibration.run import _disable_for_write
    from contour.link.chunks import write_record
    from contour.link.client import DriveError

    state = pg.State(client.status()["state"])
    if state not in (pg.State.READY, pg.State.DISABLED):
        raise UserError(f"the drive is {state.name.lower()}: the map is written at rest")
    try:
        write_record(
            lambda name, **f: client.request(name, **f).fields, "comp2d_write", record, CHUNK
        )
    except DriveError as exc:
        raise _refusal(exc) from None
    was_enabled = state == pg.State.READY
    if was_enabled and notify is not None:
        notify("disabling the drive for the flash write of the 2-D map")
    try:
        if was_enabled:
            _disable_for_write(client, wait, timeout_s)
        info = client.request(
            "comp2d_commit", length=len(record), crc=zlib.crc32(record), timeout=COMMIT_TIMEOUT_S
        ).fields
    except DriveError as exc:
        err = _refusal(exc)
        if was_enabled:
            client.enable(True)
        raise err from None
    if was_enabled:
        client.enable(True)
    if not info["active"] or info["length"] != len(record) or info["crc"] != zlib.crc32(record):
        raise UserError(
            f"the drive's 2-D map ({info['length']} bytes, CRC {info['crc']:08X}) is not the"
            f" one sent ({len(record)} bytes, CRC {zlib.crc32(record):08X})"
        )
    return info


def read_map(client) -> bytes:
    """The record the drive holds in flash (comp2d_read), b'' when none."""
    data, total, off = b"", None, 0
    while total is None or off < total:
        r = client.request("comp2d_read", offset=off, max=CHUNK).fields
        total = r["total"]
        if r["offset"] != off or (off < total and not r["data"]):
            raise UserError("comp2d_read: the drive's reply does not continue the record")
        data += r["data"]
        off += len(r["data"])
        if total == 0:
            break
    return data
