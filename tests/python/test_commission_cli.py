"""`contour tune --sim` (issue 23): a machine whose X axis is heavier,
softer, with friction and encoder noise, held by another machine's gains."""

import json

import pytest
from contour import cli
from contour.sim import machine
from test_commission_identify import true_resonance_hz

DETUNED = """
name = "detuned"
tick_hz = 10000
axes = 2
[axis.all]
model = "lacerda1998"
lead_mm = 5.0
encoder_lines = 1000
[axis.x]
I2 = 2.0e-5
K = 60.0
coulomb_motor = 0.01
coulomb_table = 10.0
encoder_noise_counts = 0.5
[axis.y]
I2 = 3.5e-6
[gains.axis]
kp = 1000.0
ki = 5000.0
kd = 8.0
d_tau = 1e-4
"""


@pytest.fixture
def detuned(tmp_path):
    path = tmp_path / "detuned.toml"
    path.write_text(DETUNED)
    return path


def test_tune_json(detuned, capsys):
    rc = cli.main(["tune", "--sim", str(detuned), "--axis", "X", "--json"])
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    r = rep["axes"]["X"]
    true = true_resonance_hz(machine.load(str(detuned)).axis["x"])
    assert abs(r["resonance_hz"] - true) <= 0.1 * true
    assert r["phase_margin_deg"] >= 30 and r["gain_margin_db"] >= 6
    assert set(r["gains"]) >= {"pid_kp", "pid_ki", "pid_kd", "velocity_feedforward"}
    v = r["verify"]
    assert v["max_following_error_um_after"] * 2 <= v["max_following_error_um_before"]


def test_tune_simplex_json(detuned, capsys):
    """--method simplex: the thesis's search, held to the same margins."""
    rc = cli.main(["tune", "--sim", str(detuned), "--axis", "X", "--method", "simplex", "--json"])
    assert rc == 0
    r = json.loads(capsys.readouterr().out)["axes"]["X"]
    assert r["method"] == "simplex" and r["stable"]
    assert r["sensitivity_peak"] <= 1.6 * 1.02 and r["phase_margin_deg"] >= 30
    v = r["verify"]
    assert v["max_following_error_um_after"] * 2 <= v["max_following_error_um_before"]


@pytest.mark.parametrize(
    "extra, code, text",
    [
        (["--axis", "W"], 2, "X, Y, Z or all"),
        (["--axis", "Z"], 2, "no axis Z"),
        (["--axis", "X", "--ms-target", "0.9"], 2, "ms-target"),
        (["--axis", "X", "--port", "/dev/null"], 2, "not both"),
        (["--axis", "X", "--apply"], 2, "not --sim"),
        (["--axis", "X", "--travel-mm", "0.01"], 1, "travel limit"),
    ],
)
def test_tune_refusals(detuned, capsys, extra, code, text):
    rc = cli.main(["tune", "--sim", str(detuned), *extra])
    assert rc == code
    assert text in capsys.readouterr().err


def test_help_lists_tune(capsys):
    with pytest.raises(SystemExit):
        cli.main(["tune", "--help"])
    assert "--ms-target" in capsys.readouterr().out
