"""The 2-D compensation map (contour.calibration.map2d over the drive's
comp2d.c): on the simulated thesis field (lacerda_xy_field), a map from
noise-free node corrections on a 15 mm grid leaves <= 0.01 um at points
between the grid lines in every direction of approach, both axes; maps that
do not fit the drive's memory or field are refused by name; the CSV file
reads back."""

from __future__ import annotations

import numpy as np
import pytest
from contour.calibration import map2d
from contour.errors import UserError
from contour.sim import machine

NODES = np.arange(-75.0, 75.1, 15.0)
FIELD_MM = ([-100.0, -100.0], [100.0, 100.0])


def _field_map():
    f = machine.load("lacerda_xy_field").field2d["field"]
    corr = np.zeros((2, 2, 2, len(NODES), len(NODES)))
    for sx in (0, 1):
        for sy in (0, 1):
            for iy, y in enumerate(NODES):
                for ix, x in enumerate(NODES):
                    # correction = reference - encoder = e (true = nominal + e)
                    corr[:, sx, sy, iy, ix] = f.error(x, y, sx, sy)
    return f, map2d.from_corrections(-75.0, 15.0, -75.0, 15.0, corr)


def test_residual_between_grid_lines():
    f, m = _field_map()
    cm = map2d.to_c(m)
    map2d.check(cm, *FIELD_MM)
    worst = before = 0.0
    for y in np.arange(-67.5, 68.0, 15.0):
        for x in np.arange(-67.5, 68.0, 15.0):
            for sx in (0, 1):
                for sy in (0, 1):
                    e = f.error(x, y, sx, sy)
                    cx, cy = map2d.correct(cm, x, y, 1 - 2 * sx, 1 - 2 * sy)
                    worst = max(worst, abs(cx - e[0]), abs(cy - e[1]))
                    before = max(before, abs(e[0]), abs(e[1]))
    assert before > 90.0  # the field's Y error at X = -60 (Table A.2)
    assert worst <= 0.01  # int16 nodes in 4 nm and the q16 fractions


def test_refusals():
    _, m = _field_map()
    with pytest.raises(UserError, match=r"refused \(field\)"):
        map2d.check(map2d.to_c(m), [-70.0, -100.0], [100.0, 100.0])
    big = map2d.Map2D(0.0, 15.0, 0.0, 15.0, np.zeros((2, 3, 12, 13)))
    with pytest.raises(UserError, match=r"refused \(memory\).*at most 144"):
        map2d.check(map2d.to_c(big), [-1e3, -1e3], [1e3, 1e3])
    fine = map2d.Map2D(0.0, 0.05, 0.0, 1.0, np.zeros((2, 3, 3, 3)))
    with pytest.raises(UserError, match=r"refused \(step\)"):
        map2d.check(map2d.to_c(fine), [-1e3, -1e3], [1e3, 1e3])


def test_csv_round_trip(tmp_path):
    _, m = _field_map()
    p = tmp_path / "map.csv"
    map2d.write_csv(m, str(p))
    text = p.read_text().splitlines()
    assert text[0].startswith("# comp2d v1 nx=11 ny=11")
    assert text[1] == map2d.HEADER
    back = map2d.read_csv(str(p))
    assert (back.nx, back.ny, back.x0, back.dx) == (11, 11, -75.0, 15.0)
    assert np.abs(back.g - m.g).max() <= 0.0005
    (tmp_path / "bad.csv").write_text(map2d.HEADER + "\n0,0,1,2,3\n")
    with pytest.raises(UserError, match="8 values"):
        map2d.read_csv(str(tmp_path / "bad.csv"))
