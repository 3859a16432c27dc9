"""Calibration over the real link: `contour calibrate` against `contour sim
serve --machine lacerda_y_calibration` (the drive in real time on a serial
pseudo-terminal, and on SLCAN through python-can and ISO-TP), with frames
dropped and corrupted in transit. A short range keeps it to seconds; the
full Table 5.7 run over the link is bench/bench-calibration.sh.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from contour import cli
from contour.calibration import tables
from contour.sim.serve import spawn

DATA = (
    Path(__file__).resolve().parents[3] / "shared" / "data" / "lacerda1998"
    / "encoder_calibration_kgm101.csv"
)  # fmt: skip
MACHINE = "lacerda_y_calibration"


@pytest.fixture(scope="module")
def server():
    with spawn(["--machine", MACHINE, "--feedforward", "full"]) as s:
        yield s


def test_calibrate_apply_over_serial_with_loss(server, capsys):
    rc = cli.main(
        [
            "calibrate", "--port", server.serial, "--timeout", "0.2", "--axis", "Y",
            "--from", "-75", "--to", "-45", "--step", "15", "--samples", "100",
            "--dwell-ms", "300", "--apply", "--verify-step", "15", "--json", "--no-progress",
            "--inject-loss", "0.03", "--seed", "11",
        ]
    )  # fmt: skip
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    configured = {p.position_mm: p for p in tables.read_thesis_table(str(DATA), "5.7").points}
    for p in rep["points"]:
        c = configured[p["position_mm"]]
        assert abs(p["mean_err_pos_mm"] - c.mean_err_pos_mm) < 0.0035, p
        assert abs(p["mean_err_neg_mm"] - c.mean_err_neg_mm) < 0.0035, p
    assert rep["applied"]["n"] == 3
    assert rep["residual"]["residual_systematic_um"] < 3.0
    inj = rep["injected"]
    assert inj["dropped"] + inj["corrupted"] > 0
    # every lost or damaged frame was noticed and its request repeated
    assert rep["frames_repeated_total"] >= 1
    assert rep["measure"]["samples"] == 3 * 2 * 100


def test_calibrate_over_slcan(server, capsys):
    rc = cli.main(
        [
            "calibrate", "--can", f"slcan:{server.slcan}@500000", "--node", "1",
            "--axis", "Y", "--from", "0", "--to", "15", "--step", "15", "--samples", "20",
            "--dwell-ms", "200", "--json", "--no-progress",
        ]
    )  # fmt: skip
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["measure"]["samples"] == 2 * 2 * 20
    assert [p["position_mm"] for p in rep["points"]] == [0.0, 15.0]


def _calib_run_in_subprocess(server):
    import subprocess
    import sys

    argv = [
        sys.executable, "-m", "contour", "calibrate", "--port", server.serial, "--axis", "Y",
        "--from", "-75", "--to", "75", "--step", "15", "--samples", "200", "--dwell-ms", "300",
        "--no-progress",
    ]  # fmt: skip
    return subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


@pytest.mark.parametrize("how", ["kill", "term"])
def test_host_gone_mid_calibration_stops_the_run(server, capsys, how):
    """kill -9 (the drive's watchdog / the next session ends the run) or
    SIGTERM (the host aborts it): the axes stop, nothing resumes, and the
    next calibration starts (not 'busy')."""
    import signal
    import time

    from contour import protocol_gen as pg
    from contour.link import connect

    p = _calib_run_in_subprocess(server)
    time.sleep(4.0)  # connected, set up, moving between the first points
    assert p.poll() is None, p.stderr.read().decode()
    p.send_signal(signal.SIGKILL if how == "kill" else signal.SIGTERM)
    p.wait(timeout=10)
    p.stderr.close()
    if how == "kill":
        time.sleep(0.5)
    with connect(port=server.serial) as c:
        st = c.request("calib_status").fields
        for _ in range(100):  # a SIGTERM'd host's abort, or this session's arrival
            if st["state"] == pg.CalibRunState.ERROR:
                break
            time.sleep(0.05)
            st = c.request("calib_status").fields
        assert st["state"] == pg.CalibRunState.ERROR, st
        want = {"kill": {pg.CalibStatus.NEW_SESSION, pg.CalibStatus.HOST_SILENT}}.get(
            how, {pg.CalibStatus.ABORTED}
        )
        assert st["reason"] in want, st
        for _ in range(100):  # the controlled stop comes to rest
            if c.status()["state"] == pg.State.READY:
                break
            time.sleep(0.05)
        y0 = c.status()["pos"][1]
        quiet = 0
        for _ in range(60):  # the axis settles on the stopped reference
            time.sleep(0.2)
            y1 = c.status()["pos"][1]
            # three quiet readings in a row: on a loaded machine the
            # simulator can stall for 0.2 s and then catch up
            quiet = quiet + 1 if abs(y1 - y0) < 2500 else 0
            y0 = y1
            if quiet >= 3:
                break
        time.sleep(1.0)
        for _ in range(5):  # reads do not resume the run
            c.request("calib_read", from_seq=st["seq_oldest"], max=5)
        time.sleep(1.0)
        # settling creeps by micrometres; a resumed run moves a 15 mm leg
        assert abs(c.status()["pos"][1] - y0) < 1_000_000, "the axis moved without a command"
        assert c.request("calib_status").fields["legs_done"] == st["legs_done"]
    rc = cli.main(
        [
            "calibrate", "--port", server.serial, "--axis", "Y", "--from", "0", "--to", "15",
            "--step", "15", "--samples", "20", "--dwell-ms", "100", "--json", "--no-progress",
        ]
    )  # fmt: skip
    assert rc == 0
    capsys.readouterr()
