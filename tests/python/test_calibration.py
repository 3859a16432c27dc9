"""Calibration, host side and end to end in process (docs/calibration.md):

- the analysis reproduces the thesis's own derived columns (Tables 5.6-5.9)
  from its means and standard deviations;
- the calibration machine file is Table 5.7, exactly;
- table files: CSV round trip, LinuxCNC COMP_FILE types 0 and 1, the
  compensation record accepted by the drive's own decoder (and refused when
  corrupted), the import CSV and its errors;
- the whole job against the simulated drive in this process (the firmware's
  link, calibration mode, flash store): before compensation the tool reports
  the configured errors, after it the residual systematic error is at most
  2 um everywhere on the range (re-measured on a grid of half the step), and
  the same run with 1 % of the frames dropped or corrupted gives the same
  table and says how many frames were repeated;
- a missing or corrupt sample is re-read, a faulted leg measured again: never
  skipped.
"""

from __future__ import annotations

import ctypes
import json
import math
import struct
import zlib
from pathlib import Path

import pytest
from contour import cli
from contour import protocol_gen as pg
from contour.calibration import analysis, inproc, run, tables
from contour.calibration.faults import FrameFaults
from contour.errors import UserError
from contour.link.client import Client, DriveError

REPO = Path(__file__).resolve().parents[2]
DATA = REPO.parent / "shared" / "data" / "lacerda1998" / "encoder_calibration_kgm101.csv"
MACHINE = "lacerda_y_calibration"
TARGETS_MM = [float(x) for x in range(-75, 76, 15)]


@pytest.fixture(autouse=True)
def _clean_flash():
    """Tables written by a test must not reach another test's simulator."""
    inproc.erase_flash()
    yield
    inproc.erase_flash()


# ---- analysis against the thesis's own numbers --------------------------------------


@pytest.mark.parametrize("table", ["5.6", "5.7", "5.8", "5.9"])
def test_analysis_reproduces_thesis_columns(table):
    rows = [r for _, r in tables._read_csv(str(DATA)) if r["table"] == table]
    assert len(rows) == 11
    for r in rows:
        p = analysis.from_summary(
            float(r["position_mm"]),
            float(r["mean_err_pos_mm"]),
            float(r["std_pos_mm"]),
            float(r["mean_err_neg_mm"]),
            float(r["std_neg_mm"]),
        )
        # the CSV rounds to 0.001 mm: one unit of rounding in each input
        assert abs(p.systematic_mm - float(r["systematic_mm"])) <= 0.0005 + 1e-9
        assert abs(p.hysteresis_mm - float(r["hysteresis_mm"])) <= 0.001 + 1e-9
        assert abs(p.random_95_mm - float(r["random_95_mm"])) <= 0.001 + 1e-9


def test_point_stats_from_readings():
    p = analysis.point_stats(10.0, [0.001, 0.003], [-0.002, -0.004, -0.006])
    assert p.mean_err_pos_mm == pytest.approx(0.002)
    assert p.mean_err_neg_mm == pytest.approx(-0.004)
    assert p.std_pos_mm == pytest.approx(math.sqrt(2e-6))  # n - 1
    assert p.std_neg_mm == pytest.approx(0.002)
    assert p.systematic_mm == pytest.approx(-0.001)
    assert p.hysteresis_mm == pytest.approx(0.006)
    assert p.random_95_mm == pytest.approx(math.sqrt(2e-6) + 0.002)
    assert p.correction_fwd_mm == pytest.approx(-0.002)
    with pytest.raises(UserError, match="approached moving -x"):
        analysis.point_stats(5.0, [0.001], [])
    with pytest.raises(UserError, match="direction must be"):
        analysis.analyse([(0.0, 0, 0.001)])


def test_machine_file_is_table_5_7():
    from contour.sim import machine

    m = machine.load(MACHINE)
    y = m.axis["y"]
    b = y["backlash_um"]
    exp = tables.read_thesis_table(str(DATA), "5.7")
    assert [r[0] for r in y["pitch_map"]] == exp.positions_mm()
    for (pos, e_fwd, e_rev), p in zip(y["pitch_map"], exp.points):
        # error = encoder - reference = +-b/2 - e(x, dir)
        assert b / 2 - e_fwd == pytest.approx(1000 * p.mean_err_pos_mm, abs=1e-9), pos
        assert -b / 2 - e_rev == pytest.approx(1000 * p.mean_err_neg_mm, abs=1e-9), pos
    sigma = math.hypot(1.25 * y["encoder_noise_counts"], y["ref_noise_nm"] / 1000)
    mean_random = sum(1000 * p.random_95_mm for p in exp.points) / len(exp.points)
    assert 2 * sigma == pytest.approx(mean_random, abs=0.1)


# ---- table files ------------------------------------------------------------------------


def _map():
    return tables.read_thesis_table(str(DATA), "5.7")


def test_table_csv_round_trip(tmp_path):
    em = _map()
    f = tmp_path / "t.csv"
    tables.write_table_csv(str(f), em)
    head = f.read_text().splitlines()[0].split(",")
    assert head == tables.TABLE_COLUMNS
    back = tables.read_table_csv(str(f))
    for a, b in zip(em.points, back.points):
        assert a.position_mm == b.position_mm
        assert a.mean_err_pos_mm == pytest.approx(b.mean_err_pos_mm, abs=1e-6)
        assert a.hysteresis_mm == pytest.approx(b.hysteresis_mm, abs=2e-6)
    bad = tmp_path / "bad.csv"
    bad.write_text("position_mm,mean_err_pos_mm,mean_err_neg_mm\n1,0,0\n0,0,0\n")
    with pytest.raises(UserError, match="must increase"):
        tables.read_table_csv(str(bad))


def test_linuxcnc_comp_file(tmp_path):
    em = _map()
    f0, f1 = tmp_path / "c0", tmp_path / "c1"
    tables.write_comp_file(str(f0), em, 0)
    tables.write_comp_file(str(f1), em, 1)
    l0 = [list(map(float, ln.split())) for ln in f0.read_text().splitlines()]
    l1 = [list(map(float, ln.split())) for ln in f1.read_text().splitlines()]
    assert [r[0] for r in l0] == sorted(r[0] for r in l0)  # increasing nominal
    # -75 mm: error -0.027 both ways -> true position -74.973 (type 0),
    # offset +0.027 (type 1)
    assert l0[0] == pytest.approx([-75.0, -74.973, -74.973])
    assert l1[0] == pytest.approx([-75.0, 0.027, 0.027])
    # -60 mm: +x -0.015, -x -0.025
    assert l1[1] == pytest.approx([-60.0, 0.015, 0.025])
    with pytest.raises(UserError, match="types 0 and 1"):
        tables.write_comp_file(str(f0), em, 2)


def _c_decode(record: bytes) -> int:
    from contour import native

    lib = native.load()
    out = ctypes.create_string_buffer(4096)
    return lib.comp_record_decode(record, len(record), out)


def test_record_matches_the_drive_decoder():
    em = _map()
    rec = tables.encode_record(tables.corrections_nm(em), axis=1, ramp_us=20000)
    assert len(rec) == 32 + 16 * 11
    assert _c_decode(rec) == 0  # COMP_OK
    d = tables.decode_record(rec)
    assert d["points"][1] == (-60_000_000, 15_000, 25_000)
    assert d["data_crc"] == zlib.crc32(rec[32:])
    for i in (0, 13, 31, 40, len(rec) - 1):
        bad = bytearray(rec)
        bad[i] ^= 0x10
        assert _c_decode(bytes(bad)) != 0
        with pytest.raises(UserError):
            tables.decode_record(bytes(bad))
    with pytest.raises(UserError, match="exceeds the drive's limit"):
        tables.corrections_nm(analysis.analyse([(0.0, 1, 2.0), (0.0, -1, 2.0)]))


def test_import_csv(tmp_path):
    f = tmp_path / "imp.csv"
    lines = ["# laser, 20 C", "position_mm,reading_mm,direction"]
    for p in (-10.0, 0.0, 10.0):
        for d, off in (("+", 0.004), ("-", -0.002)):
            for k in range(3):
                lines.append(f"{p},{p - off - 0.001 * (k - 1):.4f},{d}")
    f.write_text("\n".join(lines) + "\n")
    em = tables.import_errmap(str(f))
    assert em.positions_mm() == [-10.0, 0.0, 10.0]
    for pt in em.points:
        assert pt.mean_err_pos_mm == pytest.approx(0.004)
        assert pt.mean_err_neg_mm == pytest.approx(-0.002)
        assert pt.hysteresis_mm == pytest.approx(0.006)
        assert pt.random_95_mm == pytest.approx(0.002)
    bad = tmp_path / "bad.csv"
    bad.write_text("position_mm,reading_mm,direction\n1,1.001,up\n")
    with pytest.raises(UserError, match=r"bad.csv:2: direction 'up'"):
        tables.read_import_csv(str(bad))
    bad.write_text("position_mm,reading\n1,1.001\n")
    with pytest.raises(UserError, match="missing column"):
        tables.read_import_csv(str(bad))
    bad.write_text("position_mm,reading_mm,direction\n1,1.001,+\n")
    with pytest.raises(UserError, match="approached moving -x"):
        tables.import_errmap(str(bad))
    bad.write_text("position_mm,reading_mm,direction\n1,abc,+\n")
    with pytest.raises(UserError, match="must be numbers"):
        tables.read_import_csv(str(bad))


# ---- end to end in process -----------------------------------------------------------------


def _session(loss: float = 0.0, seed: int = 5):
    drive = inproc.SimDrive(machine=MACHINE, feedforward="full", keep_flash=True)
    faults = FrameFaults(loss, seed=seed) if loss else None
    t = drive.transport(faults)
    client = Client(t, timeout=0.01, retries=10)
    client.enable(True)
    t.wait(0.05)
    return drive, t, client, faults


def _cfg(pts_mm, samples=200):
    return run.RunConfig(axis=1, targets_nm=[round(p * 1e6) for p in pts_mm], samples=samples)


def _calibrate_and_apply(loss: float):
    drive, t, client, faults = _session(loss)
    cal = run.Calibrator(client, t.wait)
    res = cal.run(_cfg(TARGETS_MM))
    before = run.errmap_from_run(res, "enc", axis="Y")
    info = run.upload(client, 1, before, wait=t.wait)
    vpts = [x / 2 for x in range(-150, 151, 15)]
    res2 = cal.run(_cfg(vpts))
    after = run.errmap_from_run(res2, "comp", axis="Y")
    return before, after, info, res, res2, faults


def test_calibration_end_to_end_and_with_frame_loss():
    configured = tables.read_thesis_table(str(DATA), "5.7")
    before, after, info, res, res2, _ = _calibrate_and_apply(0.0)
    # before compensation: what the machine file configures (Table 5.7),
    # within the noise of 200 readings per direction (7 um / sqrt(200))
    d = analysis.compare(before, configured)
    assert d["points_compared"] == 11
    assert d["max_diff_mean_err_pos_um"] < 2.5, d
    assert d["max_diff_mean_err_neg_um"] < 2.5, d
    assert d["max_diff_systematic_um"] < 2.0, d
    s = before.summary()
    assert 25 < s["max_systematic_um"] < 29  # thesis: 27 um
    assert 8.5 < s["max_hysteresis_um"] < 13.5  # thesis: 11 um
    assert 12 < s["mean_random_95_um"] < 16  # thesis: 14 um
    # after: the residual systematic error everywhere on the range (21 points)
    assert len(after.points) == 21
    assert analysis.residual(after)["residual_systematic_um"] <= 2.0
    assert after.summary()["max_hysteresis_um"] < 3.5
    assert info["n"] == 11 and info["active"] == 1
    assert res.frames_repeated == 0 and res.reads_repeated == 0 and res.points_repeated == 0
    assert sum(len(v) for v in res.legs.values()) == 22 * 200

    # the same run with 1 % of the frames dropped or corrupted in transit
    inproc.erase_flash()
    before2, after2, info2, resl, resl2, faults = _calibrate_and_apply(0.01)
    st = faults.stats()
    assert st["dropped"] > 0 and st["corrupted"] > 0
    repeated = resl.frames_repeated + resl2.frames_repeated
    assert repeated > 0
    # every hit cost exactly one resend (a drop or a corruption of either
    # the request or its reply); the upload's share is not in the runs
    assert repeated <= st["dropped"] + st["corrupted"]
    assert info2["data_crc"] == info["data_crc"]  # the same table
    assert [p.as_dict() for p in before2.points] == [p.as_dict() for p in before.points]
    assert [p.as_dict() for p in after2.points] == [p.as_dict() for p in after.points]


class _Tamper:
    """A client that damages calib_samples replies on their way in."""

    def __init__(self, inner, mode: str):
        self.inner = inner
        self.mode = mode
        self.done = False

    @property
    def retried(self):
        return self.inner.retried

    def request(self, name, **fields):
        r = self.inner.request(name, **fields)
        if name != "calib_read" or self.done or r.fields["count"] < 3 or r.fields["from_seq"] < 50:
            return r
        f = dict(r.fields)
        data = bytearray(f["data"])
        self.done = True
        if self.mode == "crc":  # corrupted, CRC not matching
            data[run.SAMPLE.size + 5] ^= 0x40
        elif self.mode == "gap":  # a sample missing, CRC consistent
            del data[run.SAMPLE.size : 2 * run.SAMPLE.size]
            f["count"] -= 1
            f["crc"] = zlib.crc32(bytes(data))
        elif self.mode == "v3":  # a drive of protocol 3: 20-byte samples
            k = run.SAMPLE.size
            data = bytearray(b"".join(data[i * k : i * k + 20] for i in range(f["count"])))
            f["crc"] = zlib.crc32(bytes(data))
        elif self.mode == "fault":  # a sample the drive flagged
            data[7] |= run.FLAG_FAULT
            f["crc"] = zlib.crc32(bytes(data))
        f["data"] = bytes(data)
        return r._replace(fields=f)


@pytest.mark.parametrize("mode", ["crc", "gap", "fault"])
def test_missing_or_corrupt_sample_is_never_skipped(mode):
    drive, t, client, _ = _session()
    tc = _Tamper(client, mode)
    cal = run.Calibrator(tc, t.wait)
    res = cal.run(_cfg([-75.0, -60.0], samples=40))
    assert tc.done
    if mode == "fault":
        assert res.points_repeated == 1
    else:
        assert res.reads_repeated == 1 and res.points_repeated == 0
    for leg, ss in res.legs.items():
        assert len(ss) == 40, leg
        assert not any(s.flags & run.FLAG_FAULT for s in ss)
    assert sorted(res.legs) == sorted((p, d, 0) for p in (0, 1) for d in (1, -1))


def test_samples_of_the_old_layout_are_refused_by_name():
    """An intact calib_samples of protocol 3 (20-byte samples, no cross
    axis) is not taken for a transmission error and read again forever."""
    drive, t, client, _ = _session()
    cal = run.Calibrator(_Tamper(client, "v3"), t.wait)
    with pytest.raises(UserError, match="samples of 20 bytes \\(protocol 3\\)"):
        cal.run(_cfg([-75.0, -60.0], samples=40))


def test_drive_refusals_are_clear():
    drive, t, client, _ = _session()
    cal = run.Calibrator(client, t.wait)
    with pytest.raises(UserError, match="bad axis"):
        cal.run(run.RunConfig(axis=2, targets_nm=[0, 1000]))
    with pytest.raises(UserError, match="must increase"):
        cal.run(run.RunConfig(axis=1, targets_nm=[1000, 0]))
    em = analysis.analyse([(0.0, 1, 0.0), (0.0, -1, 0.0)])
    em.points[0].mean_err_pos_mm = 0.5  # 500 um: within the record, applied
    # an enabled drive refuses a table on the wire (a flash write would
    # stall a single-bank MCU's tick); upload disables it for the commit and
    # enables it again
    record = tables.encode_record(tables.corrections_nm(em), 1, ramp_us=20000)
    client.request("comp_write", axis=1, offset=0, data=record)
    with pytest.raises(DriveError) as exc:
        client.request("comp_commit", axis=1, length=len(record), crc=zlib.crc32(record))
    assert exc.value.fields["arg"] == pg.CalibStatus.DRIVE_ENABLED
    said: list[str] = []
    rec_ok = run.upload(client, 1, em, wait=t.wait, notify=said.append)
    assert rec_ok["n"] == 1
    assert len(said) == 1 and "unpowered" in said[0]  # the user is told first
    t.wait(0.01)
    assert client.status()["state"] == pg.State.READY
    # a drive the user disabled is written as it is and stays disabled
    client.enable(False)
    t.wait(0.01)
    em.points[0].mean_err_pos_mm = 0.4
    rec2 = run.upload(client, 1, em, wait=t.wait, notify=said.append)
    assert rec2["version"] == rec_ok["version"] + 1 and len(said) == 1
    t.wait(0.01)
    assert client.status()["state"] == pg.State.DISABLED
    client.enable(True)
    t.wait(0.01)
    # a faulted drive: refused before anything is sent, the table unchanged
    client.request("estop")
    t.wait(0.01)
    em.points[0].mean_err_pos_mm = 0.25
    with pytest.raises(UserError, match="reset the fault"):
        run.upload(client, 1, em, wait=t.wait)
    assert client.request("comp_get", axis=1).fields["data_crc"] == rec2["data_crc"]


# ---- the command ------------------------------------------------------------------------------


def test_cli_in_process(tmp_path, capsys):
    out, comp, png = tmp_path / "t.csv", tmp_path / "t.comp", tmp_path / "t.png"
    rc = cli.main(
        [
            "calibrate", "--sim", MACHINE, "--axis", "Y", "--from", "-75", "--to", "-45",
            "--step", "15", "--samples", "60", "--apply", "--out", str(out),
            "--comp-file", str(comp), "--comp-type", "1", "--plot", str(png), "--json",
            "--no-progress", "--inject-loss", "0.02", "--seed", "3",
        ]
    )  # fmt: skip
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    assert [p["position_mm"] for p in rep["points"]] == [-75.0, -60.0, -45.0]
    assert len(rep["residual_points"]) == 5  # verify grid: half the step
    assert rep["applied"]["n"] == 3
    assert rep["injected"]["frames"] > 0
    assert rep["frames_repeated_total"] == rep["injected"]["dropped"] + rep["injected"]["corrupted"]
    assert out.read_text().startswith("position_mm,")
    assert len(comp.read_text().splitlines()) == 3
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_import_and_errors(tmp_path, capsys):
    f = tmp_path / "imp.csv"
    f.write_text("position_mm,reading_mm,direction\n0,-0.001,+\n0,0.002,-\n5,4.999,+\n5,5.003,-\n")
    rc = cli.main(["calibrate", "--import", str(f), "--out", str(tmp_path / "o.csv")])
    assert rc == 0
    text = capsys.readouterr().out
    assert "max |systematic|" in text
    assert (tmp_path / "o.csv").exists()
    # a file that cannot be read is a runtime failure (1), the rest usage errors (2)
    assert cli.main(["calibrate", "--import", str(tmp_path / "none.csv")]) == 1
    assert "cannot read" in capsys.readouterr().err
    for argv, msg in (
        (["calibrate", "--axis", "Q", "--sim", MACHINE], "--axis 'Q'"),
        (["calibrate", "--axis", "Y", "--from", "0", "--to", "10", "--step", "0"], "--step 0"),
        (["calibrate", "--axis", "Y", "--from", "0", "--to", "1000", "--step", "1"], "at most 126"),
        (["calibrate", "--axis", "Y", "--from", "0", "--to", "10", "--step", "5"], "--port PATH"),
        (["calibrate", "--import", str(f), "--apply"], "--apply needs --axis"),
        (["calibrate", "--axis", "Y", "--from", "0", "--to", "10", "--step", "5",
          "--feed", "-1"], "--feed"),
        # refused before the (simulated) axis moves, not after a run of minutes
        (["calibrate", "--axis", "Y", "--from", "0", "--to", "10", "--step", "5",
          "--sim", MACHINE, "--samples", "0"], "--samples 0"),
        (["calibrate", "--axis", "Y", "--from", "0", "--to", "10", "--step", "5",
          "--sim", MACHINE, "--out", str(tmp_path / "no" / "t.csv")], "no such directory"),
    ):  # fmt: skip
        assert cli.main(argv) == 2
        assert msg in capsys.readouterr().err


def test_targets_include_the_end():
    from contour.commands.calibrate import targets_mm

    assert targets_mm(-75, 75, 15) == TARGETS_MM
    assert targets_mm(10, 0, 4) == [0.0, 4.0, 8.0, 10.0]
    struct.pack("<q", round(targets_mm(-75, 75, 15)[0] * 1e6))  # fits i64
