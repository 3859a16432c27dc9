"""`contour estimate` reads and plans a file in chunks: the total and every
segment's time are those of the whole program planned at once (the chunks
overlap by four look-ahead depths), and rotary blocks are timed with the
profile's rotary limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from contour import program
from contour.estimation import estimate_file
from contour.estimation import profile as profiles


def _cam(path, n: int) -> None:
    with open(path, "w") as fh:
        fh.write("G21 G90 G17 G64\nG1 F3000\n")
        for i in range(n):
            a = i * 2e-3
            fh.write(f"X{50 * math.cos(a):.3f} Y{50 * math.sin(a):.3f} Z{(i % 97) * 1e-3:.3f}\n")
            if i % 1500 == 700:
                fh.write("G4 P0.1\n")


@pytest.mark.parametrize("model", ["planner", "camargo2017", "mrt", "feed"])
def test_chunked_estimate_equals_the_whole_program(tmp_path, monkeypatch, model):
    path = tmp_path / "cam.ngc"
    _cam(path, 6000)
    prof = profiles.load("profiles/generic.toml")
    whole_csv, chunk_csv = tmp_path / "whole.csv", tmp_path / "chunks.csv"
    whole, _ = estimate_file(str(path), prof, model, per_block_csv=str(whole_csv))
    monkeypatch.setattr(program, "CHUNK_ROWS", 1000)
    chunked, _ = estimate_file(str(path), prof, model, per_block_csv=str(chunk_csv))
    assert chunked["chunks"] >= 6
    assert chunked["blocks"] == whole["blocks"] and chunked["segments"] == whole["segments"]
    assert chunked["total_s"] == pytest.approx(whole["total_s"], rel=1e-12)
    a = np.genfromtxt(whole_csv, delimiter=",", names=True, dtype=None, encoding="utf-8")
    b = np.genfromtxt(chunk_csv, delimiter=",", names=True, dtype=None, encoding="utf-8")
    np.testing.assert_allclose(b["time_s"], a["time_s"], rtol=1e-9, atol=1e-12)
    assert list(b["segment"]) == list(range(len(a)))


def test_rotary_limits_time_mixed_and_rotary_only_blocks(tmp_path):
    prof = tmp_path / "p.toml"
    prof.write_text(
        "[motion]\nmin_block_time_s = 0\n"
        "[axes.C]\nmax_velocity_deg_min = 3600\nmax_acceleration_deg_s2 = 100\n"
    )
    p = profiles.load(prof)
    job = tmp_path / "rot.ngc"
    # X 10 mm with C 90 deg at F600 would turn C at 5400 deg/min: capped at 3600,
    # 90 deg in 1.5 s; X 10 mm with C 360 deg: 360 deg at 3600 deg/min, 6 s;
    # C 180 deg alone at F36000 deg/min: its limit 60 deg/s, 3 s at feed; the
    # planner adds a = 100 deg/s^2 rest to rest: 180/60 + 60/100 = 3.6 s
    job.write_text("G21 G90 G94\nG1 X10 C90 F600\nG1 X20 C450\nG1 C630 F36000\n")
    summary, report = estimate_file(str(job), p, "feed", per_block_csv=str(tmp_path / "f.csv"))
    t = np.genfromtxt(tmp_path / "f.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert t["time_s"][0] == pytest.approx(1.5)  # capped by C: 90 deg at 3600 deg/min
    assert t["time_s"][1] == pytest.approx(6.0)  # capped by C: 360 deg at 3600 deg/min
    assert t["time_s"][2] == pytest.approx(3.0)  # feed model: 180 deg at 3600 deg/min
    assert t["kind"][2] == "rotary"
    assert {"rotary+linear", "rotary only"} <= report.kinds()
    summary, _ = estimate_file(str(job), p, "planner", per_block_csv=str(tmp_path / "p.csv"))
    t = np.genfromtxt(tmp_path / "p.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert t["time_s"][2] == pytest.approx(180 / 60 + 60 / 100)  # rest to rest
    assert t["time_s"][1] >= 6.0
    assert summary["length_mm"] == pytest.approx(20.0)  # X Y Z path only
