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
from contour.simserve import spawn

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
