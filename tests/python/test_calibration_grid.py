"""2-D calibration (issue 22, docs/calibration.md "Calibration over the
field"), in process against the simulated thesis table
(hil_sim/machines/lacerda_xy_field.toml):

- --grid parsing and its refusals; ISO 230-2's figures on numbers worked
  by hand;
- the 2-D map over the protocol: upload, read back, clear, kept in flash
  over a restart (versioned), and every refusal named (memory, field,
  record, CRC, drive enabled);
- `contour calibrate --grid ... --apply` end to end on a coarse grid: the
  field's errors found at the nodes, the map applied, the residual at the
  cell centres far below the error before.
"""

from __future__ import annotations

import json
import zlib

import numpy as np
import pytest
from contour import cli
from contour import protocol_gen as pg
from contour.calibration import grid, inproc, map2d
from contour.errors import UsageError, UserError
from contour.link.client import Client, DriveError

MACHINE = "hil_sim/machines/lacerda_xy_field.toml"


@pytest.fixture(autouse=True)
def _clean_flash():
    inproc.erase_flash()
    yield
    inproc.erase_flash()


def test_parse_grid():
    g = grid.parse_grid("X:-60:60:15,Y:-45:45:15")
    assert g.xs == [float(v) for v in range(-60, 61, 15)]
    assert g.ys == [float(v) for v in range(-45, 46, 15)]
    assert grid.midpoints(g).xs[0] == -52.5
    for bad in (
        "X:-60:60:15",
        "X:0:10:3,Y:0:10:5",
        "X:0:10:5,X:0:10:5",
        "X:10:0:5,Y:0:10:5",
        "X:-90:90:15,Y:-90:90:15",
        "Z:0:10:5,Y:0:10:5",
        "X:a:b:c,Y:0:10:5",
    ):
        with pytest.raises(UsageError):
            grid.parse_grid(bad)


def test_iso230_2_by_hand():
    # two targets; deviations (mm) up: [1, 3] um and [2, 2] um; down: [-1, -1], [0, 2]
    up = [[0.001, 0.003], [0.002, 0.002]]
    dn = [[-0.001, -0.001], [0.0, 0.002]]
    f = grid.iso230_2(up, dn)
    s = 2**0.5  # um: sample std of [1, 3] and of [0, 2]
    # means up 2, 2; down -1, 1: B_i = 3, 1
    assert f["B_um"] == pytest.approx(3.0)
    assert f["E_um"] == pytest.approx(2 - (-1))
    assert f["M_um"] == pytest.approx(1.5 - 0.5)
    # R_i = max(2 s_up + 2 s_down + |B_i|, 4 s_up, 4 s_down): 2s + 0 + 3, 0 + 2s + 1
    assert f["R_um"] == pytest.approx(2 * s + 3)
    # A = max(2 + 2s, 2 + 0, -1 + 0, 1 + 2s) - min(2 - 2s, 2, -1, 1 - 2s)
    assert f["A_um"] == pytest.approx((2 + 2 * s) - (1 - 2 * s))


# ---- the map over the protocol ------------------------------------------------


def _session():
    drive = inproc.SimDrive(machine=MACHINE, feedforward="full", keep_flash=True)
    t = drive.transport()
    client = Client(t, timeout=0.01, retries=10)
    client.enable(True)
    t.wait(0.05)
    return drive, t, client


def _map(nx=3, ny=3, x0=-30.0, step=30.0, v=5.0) -> map2d.Map2D:
    g = np.zeros((2, 3, ny, nx))
    g[0, 0] = v  # X's mean correction, um
    g[1, 1] = v / 5  # Y's hx
    return map2d.Map2D(x0, step, x0, step, g)


def _record(m: map2d.Map2D) -> bytes:
    return map2d.encode_record(map2d.to_c(m))


def _commit_error(client, record: bytes, crc=None) -> dict:
    client.request("comp2d_write", offset=0, data=record[:224])
    for off in range(224, len(record), 224):
        client.request("comp2d_write", offset=off, data=record[off : off + 224])
    with pytest.raises(DriveError) as exc:
        client.request(
            "comp2d_commit",
            length=len(record),
            crc=zlib.crc32(record) if crc is None else crc,
        )
    return exc.value.fields


def test_map_upload_read_clear_and_restart():
    drive, t, client = _session()
    assert client.request("comp2d_get").fields["active"] == 0
    rec = _record(_map())
    info = grid.upload_map(client, rec, t.wait)
    assert info["active"] == 1 and (info["nx"], info["ny"]) == (3, 3)
    assert info["version"] == 1 and info["crc"] == zlib.crc32(rec)
    assert grid.read_map(client) == rec
    t.wait(0.01)
    assert client.status()["state"] == pg.State.READY  # enabled again
    # applied in the tick: at rest the position reads 5 um more (the map's
    # X correction), the servo moves the table by it
    t.wait(0.3)
    # a second upload is version 2; a restart keeps it (flash)
    info2 = grid.upload_map(client, _record(_map(v=7.0)), t.wait)
    assert info2["version"] == 2
    client.close()
    drive, t, client = _session()
    got = client.request("comp2d_get").fields
    assert got["active"] == 1 and got["version"] == 2
    assert map2d.decode_record(grid.read_map(client)).g[0][0][0] == round(7000 / 1)
    # clear: version 3, nothing in use, nothing to read
    client.enable(False)
    t.wait(0.01)
    c = client.request("comp2d_clear").fields
    assert c["active"] == 0 and c["version"] == 3 and c["length"] == 0
    assert grid.read_map(client) == b""


def test_map_refusals_are_named():
    drive, t, client = _session()
    # the drive is enabled: no flash write while the axes are powered
    f = _commit_error(client, _record(_map()))
    assert f["code"] == pg.ErrorCode.CALIB and f["arg"] == pg.CalibStatus.DRIVE_ENABLED
    client.enable(False)
    t.wait(0.01)
    # more nodes than the drive holds: 13 x 12
    cm = map2d.to_c(_map(3, 3))
    rec = bytearray(map2d.encode_record(cm))
    rec[6], rec[7] = 13, 12
    rec += bytes(12 * (13 * 12 - 9))
    f = _commit_error(client, bytes(rec[: map2d.RECORD_MAX]))  # fills the staging buffer
    assert f["arg"] == pg.CalibStatus.COMP2D_MEMORY and f["lo"] == 13 * 12
    # outside the drive's field: soft limits of X at +-50 mm, a map to +60
    client.set_param("soft_limit_min.x", -50_000_000)
    client.set_param("soft_limit_max.x", 50_000_000)
    f = _commit_error(client, _record(_map(3, 3, x0=-60.0, step=60.0)))
    assert f["arg"] == pg.CalibStatus.COMP2D_FIELD and f["lo"] == 1  # axis X
    # not a map, another version, a bad CRC
    rec = bytearray(_record(_map()))
    bad = bytes([rec[0] ^ 1]) + bytes(rec[1:])
    f = _commit_error(client, bad)
    assert f["arg"] == pg.CalibStatus.COMP2D_RECORD and f["lo"] == 5
    rec[4] = 2
    f = _commit_error(client, bytes(rec))
    assert f["arg"] == pg.CalibStatus.COMP2D_RECORD and f["lo"] == 1
    f = _commit_error(client, _record(_map()), crc=1234)
    assert f["arg"] == pg.CalibStatus.RECORD_CRC
    # nothing was stored by any of them
    assert client.request("comp2d_get").fields["version"] == 0
    # the host's own check names the same refusals before sending
    with pytest.raises(UserError, match="memory"):
        map2d.check(map2d.to_c(_map(13, 12)), (-1e3, -1e3), (1e3, 1e3))


def test_lost_replies_never_store_the_map_twice():
    from contour.calibration.faults import FrameFaults

    drive = inproc.SimDrive(machine=MACHINE, feedforward="full", keep_flash=True)
    faults = FrameFaults(0.3, seed=3)
    t = drive.transport(faults)
    client = Client(t, timeout=0.01, retries=30)
    client.enable(False)
    t.wait(0.01)
    rec = _record(_map())
    for _ in range(2):  # each upload is one version, however many resends
        info = grid.upload_map(client, rec, t.wait)
    assert faults.stats()["dropped"] + faults.stats()["corrupted"] > 0
    assert client.retried > 0
    assert info["version"] == 2 and grid.read_map(client) == rec


# ---- the command ------------------------------------------------------------------


def test_cli_grid_end_to_end(tmp_path, capsys):
    out = tmp_path / "nodes.csv"
    mp = tmp_path / "map.csv"
    png = tmp_path / "field.png"
    rc = cli.main(
        [
            "calibrate", "--sim", MACHINE, "--grid", "X:-30:30:30,Y:-30:30:30",
            "--samples", "60", "--dwell-ms", "200", "--apply", "--json", "--no-progress",
            "--passes", "2",
            "--out", str(out), "--map-out", str(mp), "--plot", str(png),
        ]
    )  # fmt: skip
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    nodes = {(n["x_mm"], n["y_mm"]): n for n in rep["nodes"]}
    # the thesis's X-dependence of the Y error (Tables A.2, 5.7, A.5 at Y = 0:
    # +98, ..., -65 um at X = -60, 0, +30): the columns at -30 and +30 differ
    # by about 110 um, which a 1-D calibration cannot see
    assert nodes[(-30.0, 0.0)]["y_systematic_um"] - nodes[(30.0, 0.0)]["y_systematic_um"] > 80
    # ... and the row at Y = 0 sees it itself: Y read at its own stops
    # (the sample's cross axis), agreeing with the columns within the noise
    # of 60 readings (short lines: no held-axis direction flips, docs)
    assert (
        nodes[(-30.0, 0.0)]["y_cross_systematic_um"] - nodes[(30.0, 0.0)]["y_cross_systematic_um"]
        > 80
    )
    cc = rep["cross_check"]
    assert cc["x_compared"] == cc["y_compared"] == 4 * 9
    assert cc["x_systematic_max_um"] < 3.0 and cc["y_systematic_max_um"] < 3.0
    row0 = next(ln for ln in rep["lines"] if ln["line"] == "X at Y = 0 mm")
    assert row0["straightness_um"] > 80
    assert abs(row0["straightness_um"] - row0["straightness_crossing_um"]) < 3.0
    assert rep["before_um"] > 50
    assert len(rep["lines"]) == 6 and all("E_um" in ln for ln in rep["lines"])
    assert rep["applied"]["active"] == 1 and rep["applied"]["version"] == 2  # two passes
    assert len(rep["passes"]) == 1 and rep["passes"][0]["residual_at_nodes_um"] < 5.0
    assert rep["verify_grid"] == {"x_mm": [-15.0, 15.0], "y_mm": [-15.0, 15.0]}
    # a 30 mm grid does not follow the field's 15 mm knots exactly, and 60
    # readings leave ~1 um of noise: well below the error before all the same
    assert rep["residual_um"] < 4.0
    assert "residual_cross_um" in rep
    assert out.read_text().startswith("x_mm,y_mm,")
    assert map2d.read_csv(str(mp)).nx == 3
    assert png.stat().st_size > 10000


def test_cli_grid_refusals(capsys):
    for argv, msg in (
        (["--grid", "X:0:10:5,Y:0:10:5", "--axis", "X"], "no --axis"),
        (["--grid", "X:-90:90:10,Y:-90:90:10"], "at most 12 x 12"),
        (["--grid", "X:0:10:5"], "one X and one Y range"),
        (["--grid", "X:0:10:5,Y:0:10:5", "--passes", "0"], "--passes 0"),
    ):
        assert cli.main(["calibrate", "--sim", MACHINE, *argv]) == 2
        assert msg in capsys.readouterr().err


def test_a_leg_of_a_full_ring_of_samples_finishes():
    """--samples 512 (CALIB_RING): the drive starts a leg only when the whole
    ring is free, so the host must release the last batch it read (a read
    from seq_next); before, the run waited until its timeout."""
    from contour.calibration import run

    drive, t, client = _session()
    cal = run.Calibrator(client, t.wait, timeout_s=30.0)
    res = cal.run(run.RunConfig(axis=0, targets_nm=[-10_000_000, 10_000_000], samples=512))
    assert all(len(v) == 512 for v in res.legs.values()) and len(res.legs) == 4


# ---- the cross coordinate measured at the stop ------------------------------------


def _ex(i, j, dx, dy):
    """X error (um) of the fake table at node (i, j), directions of X, Y."""
    return 10.0 * i + j + 1.5 * dx + 0.25 * dy


def _ey(i, j, dx, dy):
    return 100.0 + 7.0 * j - 3.0 * i + 0.75 * dy - 0.5 * dx


class _FakeCal:
    """Stands for the drive's calibration runs: every sample carries the
    fake table's error of the moving axis (enc - ref) and of the cross axis
    (xenc - xref), from the node and the directions the runner set up. The
    columns' own Y readings are off by 0.1 um x column index (what the
    crossing-line method sees differently: the cross-check)."""

    def __init__(self, runner):
        self.runner = runner

    def run(self, rc):
        from types import SimpleNamespace

        from contour.calibration import run

        axis, idx, s = self.runner.line
        legs = {}
        for p in range(len(rc.targets_nm)):
            for d in (1, -1):
                if axis == 0:  # X moves on row idx; Y approached moving s
                    own, cross = _ex(p, idx, d, s), _ey(p, idx, d, s)
                else:  # Y moves on column idx; X approached moving s
                    own, cross = _ey(idx, p, s, d) + 0.1 * idx, _ex(idx, p, s, d)
                flags = run.FLAG_NEG if d < 0 else 0
                sm = run.Sample(0, p, 0, flags, round(own * 1000), 0, 0, round(cross * 1000), 0, 0)
                legs[(p, d, 0)] = [sm, sm]
        return SimpleNamespace(legs=legs, reads_repeated=0, points_repeated=0)


def _fake_measure():
    from contour.calibration.run import RunConfig

    g = grid.Grid([0.0, 10.0, 20.0], [0.0, 5.0])
    r = grid.GridRunner(None, lambda s: None, RunConfig(axis=0, targets_nm=[0]))
    r.cal = _FakeCal(r)

    def approach(axis, pos_mm, sign, other_nm):
        cross = g.ys if axis == 1 else g.xs
        r.line = (1 - axis, cross.index(pos_mm), sign)

    r._approach = approach
    return g, r.measure(g, "enc")


def test_grid_takes_the_cross_coordinate_from_the_same_stop():
    """Both errors of a stop come from its own sample: the cross coordinate
    of a row is Y at that node with those directions, of a column X; wrong
    axis, node or direction would not give the fake table's values."""
    g, m = _fake_measure()
    for i in range(len(g.xs)):
        for j in range(len(g.ys)):
            for dx in (1, -1):
                for dy in (1, -1):
                    # Y read on the row (key: Y's direction, then X's)
                    assert (
                        m.cross[(1, i, j, dy, dx)] == [pytest.approx(_ey(i, j, dx, dy) / 1000)] * 2
                    )
                    assert (
                        m.cross[(0, i, j, dx, dy)] == [pytest.approx(_ex(i, j, dx, dy) / 1000)] * 2
                    )
                    assert m.readings[(0, i, j, dx, dy)][0] == pytest.approx(
                        _ex(i, j, dx, dy) / 1000
                    )
    stats = grid.node_stats(m)
    lines = grid.line_figures(m, stats)
    # the row at Y = 0: Y's systematic error along it is 100 - 3 i (um), so
    # 6 um of straightness measured on the row; the columns' own readings
    # (0.1 um x i more) make 5.8 with the crossing-line method
    row0 = next(ln for ln in lines if ln["line"] == "X at Y = 0 mm")
    assert row0["straightness_um"] == pytest.approx(6.0)
    assert row0["straightness_crossing_um"] == pytest.approx(5.8)
    col = next(ln for ln in lines if ln["line"] == "Y at X = 20 mm")
    assert col["straightness_um"] == pytest.approx(1.0)  # X: 20 + j
    cc = grid.cross_check(m)
    assert cc["y_max_um"] == pytest.approx(0.2) and cc["x_max_um"] == pytest.approx(0.0)
    assert cc["y_compared"] == 4 * len(g.xs) * len(g.ys)
    # per node: the positioning reading (the column's own Y, 0.1 um x i
    # off) and the same coordinate read across the row at its stops
    n = next(r for r in stats if (r["x_mm"], r["y_mm"]) == (20.0, 5.0))
    assert n["y_systematic_um"] == pytest.approx(100 + 7 - 6 + 0.2)
    assert n["y_cross_systematic_um"] == pytest.approx(100 + 7 - 6)
    assert n["x_systematic_um"] == pytest.approx(21.0)
    assert n["x_cross_systematic_um"] == pytest.approx(21.0)
