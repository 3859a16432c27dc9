"""The simulated table's 2-D error field from measured lines (issue 22).

Input: lines of a 2-D reference (the thesis's Tables 5.6-5.9 and A.1-A.7,
``../shared/data/lacerda1998/encoder_calibration_kgm101.csv``), one row per
point: component (``X``/``Y``: which coordinate's error), moving axis,
line position (mm, the other coordinate), position (mm, along the moving
axis), ``mean_err_pos``, ``std_pos``, ``mean_err_neg``, ``std_neg`` (um).
Error = encoder - reference, so the table's true position is the nominal
one minus the error: e = -mean_err (per direction of approach).

How the field is interpolated between the measured lines (a Gordon-type
blend of the two families, docs/calibration.md "The 2-D field"):

- columns (lines moving Y at fixed X): per component, each column is linear
  in y between its points and held beyond its ends; between columns linear
  in x, beyond the outermost columns held. Direction: Y's (the column's
  moving axis). This is ``col`` on a regular grid whose x nodes are the
  columns and y nodes the points - exact, not an approximation.
- the row (the line moving X at Y = 0): per component, its deviation from
  the chord through its own values at the component's column positions,
  D(x) = R(x) - chord(x), is added everywhere (``row``). D is 0 on every
  column, so the columns are reproduced exactly; between columns the row
  adds its shape. Direction: X's. The row's own offset is not used: each
  line of the thesis was zeroed on its own setup (Table 5.9 gives +5 um
  of Y error at X = -60, Table A.2 +98 um at the same point), and the
  columns carry the field's X-dependence the issue is about.
- random spread: sigma = (std_pos + std_neg) / 2 from the columns, as
  ``col`` (the row's spread is of the same order and is not blended in).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

COMPONENTS = ("X", "Y")


@dataclass
class Field:
    """Regular grids, um and mm (sim_field2d takes them in m)."""

    xs: np.ndarray  # column x nodes, mm
    ys: np.ndarray  # y nodes, mm
    col: np.ndarray  # [comp][dir y (0: +, 1: -)][iy][ix], um
    sig: np.ndarray  # [comp][iy][ix], um
    rs: np.ndarray  # row x nodes, mm
    row: np.ndarray  # [comp][dir x][i], um

    def error(self, x: float, y: float, dir_x: int = 0, dir_y: int = 0) -> tuple[float, float]:
        """(e_X, e_Y) in um at (x, y) mm, as the simulator computes it."""
        out = []
        for c in range(2):
            g = self.col[c][dir_y]
            cx = [np.interp(y, self.ys, g[:, i]) for i in range(len(self.xs))]
            out.append(float(np.interp(x, self.xs, cx) + np.interp(x, self.rs, self.row[c][dir_x])))
        return out[0], out[1]


def read_csv(path: str | Path) -> list[list]:
    """The data file's rows as field lines."""
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            line = r["measurement_line"].split("=")
            rows.append(
                [
                    r["error_direction"],
                    r["moving_axis"],
                    float(line[1]),
                    float(r["position_mm"]),
                    *(
                        1000.0 * float(r[k])
                        for k in ("mean_err_pos_mm", "std_pos_mm", "mean_err_neg_mm", "std_neg_mm")
                    ),
                ]
            )
    return rows


def _regular(v: list[float], what: str) -> np.ndarray:
    a = np.array(sorted(set(v)), dtype=float)
    if len(a) < 2 or not np.allclose(np.diff(a), a[1] - a[0]):
        raise ValueError(f"the {what} are not evenly spaced: {a.tolist()}")
    return a


def build(lines: list[list]) -> Field:
    """The field from measured lines (module docstring)."""
    cols: dict[int, dict[float, list]] = {0: {}, 1: {}}
    rowpts: dict[int, list] = {0: [], 1: []}
    for comp, moving, at, pos, mp, sp, mn, sn in lines:
        c = COMPONENTS.index(comp)
        if moving == "Y":
            cols[c].setdefault(float(at), []).append((pos, -mp, -mn, 0.5 * (sp + sn)))
        elif moving == "X":
            if float(at) != 0.0:
                raise ValueError("only one row (moving X at Y = 0) is supported")
            rowpts[c].append((pos, -mp, -mn))
        else:
            raise ValueError(f"moving axis must be X or Y, got {moving!r}")
    if not cols[0] or not cols[1] or not rowpts[0] or not rowpts[1]:
        raise ValueError("the field needs column lines and the row for both components")
    xs = _regular([x for c in (0, 1) for x in cols[c]], "column positions")
    ys = _regular([p[0] for c in (0, 1) for pts in cols[c].values() for p in pts], "y points")
    rs = _regular([p[0] for c in (0, 1) for p in rowpts[c]], "row points")
    col = np.zeros((2, 2, len(ys), len(xs)))
    sig = np.zeros((2, len(ys), len(xs)))
    row = np.zeros((2, 2, len(rs)))
    for c in (0, 1):
        cx = np.array(sorted(cols[c]))
        # each column on the y nodes (linear, held)
        per = {}
        for x in cx:
            pts = sorted(cols[c][x])
            py = [p[0] for p in pts]
            per[x] = [np.interp(ys, py, [p[k] for p in pts]) for k in (1, 2, 3)]
        for k, target in ((0, col[c][0]), (1, col[c][1]), (2, sig[c])):
            for iy in range(len(ys)):
                target[iy, :] = np.interp(xs, cx, [per[x][k][iy] for x in cx])
        pts = sorted(rowpts[c])
        px = np.array([p[0] for p in pts])
        for d in (0, 1):
            r = np.interp(rs, px, [p[1 + d] for p in pts])
            chord = np.interp(rs, cx, np.interp(cx, px, [p[1 + d] for p in pts]))
            row[c][d] = r - chord
    return Field(xs=xs, ys=ys, col=col, sig=sig, rs=rs, row=row)


def apply(so, f: Field, band_um: float) -> int:
    """sim_field2d with the field (m); returns its status."""
    col = np.ascontiguousarray(f.col * 1e-6)
    sig = np.ascontiguousarray(f.sig * 1e-6)
    row = np.ascontiguousarray(f.row * 1e-6)
    return so.sim_field2d(
        len(f.xs),
        len(f.ys),
        f.xs[0] * 1e-3,
        (f.xs[1] - f.xs[0]) * 1e-3,
        f.ys[0] * 1e-3,
        (f.ys[1] - f.ys[0]) * 1e-3,
        col.ctypes.data,
        sig.ctypes.data,
        len(f.rs),
        f.rs[0] * 1e-3,
        (f.rs[1] - f.rs[0]) * 1e-3,
        row.ctypes.data,
        band_um * 1e-6,
    )
