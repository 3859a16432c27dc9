"""The simulated table's 2-D error field (issue 22, hil_sim/field2d.[ch],
contour.sim.field2d, hil_sim/machines/lacerda_xy_field.toml):

- the machine file's [field2d] lines are the data file's eleven tables;
- the field reproduces every column line's points exactly and a value
  between the lines computed by hand from the tables;
- the simulator's true table position is that field (X and Y), and a
  calibration of Y along X = 0 on the simulated table finds Table 5.7;
- a machine without [field2d] leaves the field off.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from contour import cli
from contour.calibration import inproc
from contour.errors import UserError
from contour.sim import core, field2d, machine

REPO = Path(__file__).resolve().parents[2]
DATA = REPO.parent / "shared" / "data" / "lacerda1998" / "encoder_calibration_kgm101.csv"
MACHINE = "lacerda_xy_field"


@pytest.fixture(autouse=True)
def _clean_flash():
    inproc.erase_flash()
    yield
    inproc.erase_flash()


def _field():
    return machine.load(MACHINE).field2d["field"]


@pytest.mark.skipif(not DATA.exists(), reason="the thesis's data file is not beside the repo")
def test_machine_lines_are_the_data_file():
    m = machine.load(MACHINE)
    rows = field2d.read_csv(DATA)
    want = field2d.build(rows)
    got = m.field2d["field"]
    assert len(rows) == 101
    for a in ("col", "sig", "row", "xs", "ys", "rs"):
        assert (getattr(got, a) == getattr(want, a)).all(), a


def test_field_reproduces_the_columns_and_a_hand_value():
    f = _field()
    # Table A.2 (Y error, X = -60, moving Y) at Y = 0: mean_err_pos 0.1015,
    # mean_err_neg 0.0945 mm -> e = -101.5 / -94.5 um (file rounded to 0.1)
    lines = {(r[0], r[1], r[2], r[3]): r for r in _lines()}
    r = lines[("Y", "Y", -60.0, 0.0)]
    assert f.error(-60.0, 0.0, 0, 0)[1] == pytest.approx(-r[4], abs=1e-9)
    assert f.error(-60.0, 0.0, 0, 1)[1] == pytest.approx(-r[6], abs=1e-9)
    # every column point, both components, both directions of Y
    for comp, moving, at, pos, mp, _sp, mn, _sn in _lines():
        if moving != "Y":
            continue
        c = 0 if comp == "X" else 1
        assert f.error(at, pos, 0, 0)[c] == pytest.approx(-mp, abs=1e-9)
        assert f.error(at, pos, 0, 1)[c] == pytest.approx(-mn, abs=1e-9)
    # by hand, Y error at (-45, 7.5) moving +x, +y: the columns X = -60 and
    # -30 at Y = 0 and 15 (A.2, A.4: -mean_err_pos), bilinear at the middle,
    # plus the row's deviation at X = -45 (Table 5.9, moving +x) from its
    # chord between X = -60 and -30.
    col = {(x, y): -lines[("Y", "Y", x, y)][4] for x in (-60.0, -30.0) for y in (0.0, 15.0)}
    mid = sum(col.values()) / 4.0
    row = {x: -lines[("Y", "X", 0.0, x)][4] for x in (-60.0, -45.0, -30.0)}
    dev = row[-45.0] - 0.5 * (row[-60.0] + row[-30.0])
    assert f.error(-45.0, 7.5, 0, 0)[1] == pytest.approx(mid + dev, abs=1e-9)
    # held beyond the outermost column and the column's last point
    assert f.error(-90.0, 100.0, 0, 0)[0] == pytest.approx(f.error(-75.0, 75.0, 0, 0)[0])


def _lines():
    return [r[:2] + [float(v) for v in r[2:]] for r in _toml_lines()]


def _toml_lines():
    import tomllib

    with open(REPO / "hil_sim" / "machines" / f"{MACHINE}.toml", "rb") as fh:
        return tomllib.load(fh)["field2d"]["lines"]


def test_simulator_table_is_the_field():
    f = _field()
    machine.apply(machine.load(MACHINE), feedforward="full")
    ex, ey = f.error(0.0, 0.0, 0, 0)
    # at rest at nominal (0, 0) after start: true position = the field
    assert core.lib().sim_table_pos(0) * 1e6 == pytest.approx(ex, abs=1e-6)
    assert core.lib().sim_table_pos(1) * 1e6 == pytest.approx(ey, abs=1e-6)
    machine.apply(machine.load("lacerda_y_calibration"), feedforward="full")
    assert core.lib().sim_table_pos(0) == 0.0  # no field: X true = nominal 0


def test_calibrating_y_on_the_field_finds_table_5_7(capsys):
    rc = cli.main(
        [
            "calibrate", "--sim", MACHINE, "--axis", "Y", "--from", "-75", "--to", "-45",
            "--step", "15", "--samples", "100", "--json", "--no-progress",
        ]
    )  # fmt: skip
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    want = {(r[3]): r for r in _lines() if r[0] == "Y" and r[1] == "Y" and r[2] == 0.0}
    for p in rep["points"]:
        r = want[p["position_mm"]]
        # 100 readings of sigma ~7 um per direction: the mean within 3 um
        assert p["mean_err_pos_mm"] * 1e3 == pytest.approx(r[4], abs=3.0)
        assert p["mean_err_neg_mm"] * 1e3 == pytest.approx(r[6], abs=3.0)


def test_field_refused():
    with pytest.raises(UserError, match="axes >= 2"):
        machine.from_dict({"axes": 1, "field2d": {"lines": []}})
    with pytest.raises(UserError, match="field2d.lines"):
        machine.from_dict({"axes": 2, "field2d": {"lines": [["Q", "Y", 0, 0, 0, 0, 0, 0]]}})
    with pytest.raises(UserError, match="evenly spaced"):
        machine.from_dict(
            {
                "axes": 2,
                "field2d": {
                    "lines": [
                        ["X", "Y", 0, 0, 1, 1, 1, 1], ["X", "Y", 0, 10, 1, 1, 1, 1],
                        ["X", "Y", 0, 25, 1, 1, 1, 1], ["Y", "Y", 0, 0, 1, 1, 1, 1],
                        ["X", "X", 0, 0, 1, 1, 1, 1], ["Y", "X", 0, 0, 1, 1, 1, 1],
                    ]
                },
            }
        )  # fmt: skip
